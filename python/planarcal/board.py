"""A printed circle-grid calibration board: its geometry in millimetres.

World coordinates are those of the board: the origin is the centre of the origin circle
(point 0), X runs along a row (across the columns), Y down a column (across the rows), both
in millimetres, as printed and seen from the front. Point k = r * cols + c is at
(c * pitch, r * pitch): row-major order from the origin circle.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal.errors import BoardError


@dataclasses.dataclass(frozen=True)
class CircleGridBoard:
    """A symmetric grid of `cols` x `rows` dark dots of `diameter` mm, `pitch` mm apart.

    The defaults are the paper's board (14 x 10 dots, 10 mm, 20 mm apart). With
    ``origin_marker=True`` the origin circle is printed larger (``marker_diameter``, by default
    1.5 times the others), as on common industrial boards: it fixes the board's orientation.
    """

    cols: int = 14
    rows: int = 10
    pitch: float = 20.0
    diameter: float = 10.0
    origin_marker: bool = False
    marker_diameter: float | None = None

    def __post_init__(self) -> None:
        for name in ("cols", "rows"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise BoardError(f"{name} must be a whole number of dots, got {value!r}")
            if value < 2:
                raise BoardError(f"{name} must be at least 2, got {value}")
        for name in ("pitch", "diameter"):
            value = getattr(self, name)
            if not isinstance(value, int | float | np.floating | np.integer) or not (
                math.isfinite(value) and value > 0
            ):
                raise BoardError(f"{name} must be a positive length in mm, got {value!r}")
        if self.diameter >= self.pitch:
            raise BoardError(
                f"dots of {self.diameter} mm do not fit {self.pitch} mm apart: "
                "the diameter must be smaller than the pitch"
            )
        if self.marker_diameter is not None and not self.origin_marker:
            raise BoardError("marker_diameter is given but origin_marker is False")
        if self.origin_marker:
            marker = self.origin_marker_diameter
            if not (math.isfinite(marker) and self.diameter * 1.2 <= marker < self.pitch):
                raise BoardError(
                    f"the origin marker ({marker} mm) must be at least 1.2 times the dots "
                    f"({self.diameter} mm), to be told apart, and smaller than the pitch "
                    f"({self.pitch} mm)"
                )

    @property
    def origin_marker_diameter(self) -> float:
        """Diameter of the origin circle in mm (the other dots' when there is no marker)."""
        if not self.origin_marker:
            return float(self.diameter)
        if self.marker_diameter is None:
            return min(1.5 * self.diameter, 0.5 * (self.diameter + self.pitch))
        return float(self.marker_diameter)

    @property
    def n_points(self) -> int:
        return self.cols * self.rows

    @property
    def extent(self) -> tuple[float, float]:
        """Width and height of the dot field in mm, from outer edge to outer edge."""
        biggest = max(self.diameter, self.origin_marker_diameter)
        return (
            (self.cols - 1) * self.pitch + biggest,
            (self.rows - 1) * self.pitch + biggest,
        )

    def world_points(self) -> NDArray[np.float64]:
        """Centres of the dots in mm, (rows * cols, 2), row-major from the origin circle."""
        r, c = np.divmod(np.arange(self.n_points), self.cols)
        return np.column_stack([c * float(self.pitch), r * float(self.pitch)])

    def dot_diameters(self) -> NDArray[np.float64]:
        """Diameter of each dot in mm, in the order of world_points()."""
        d = np.full(self.n_points, float(self.diameter))
        d[0] = self.origin_marker_diameter
        return d

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready description (see from_dict)."""
        return {
            "cols": int(self.cols),
            "rows": int(self.rows),
            "pitch_mm": float(self.pitch),
            "diameter_mm": float(self.diameter),
            "origin_marker": bool(self.origin_marker),
            "marker_diameter_mm": None
            if self.marker_diameter is None
            else float(self.marker_diameter),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CircleGridBoard:
        """The board described by to_dict(); BoardError if the description is not one."""
        try:
            return cls(
                cols=data["cols"],
                rows=data["rows"],
                pitch=data["pitch_mm"],
                diameter=data["diameter_mm"],
                origin_marker=data.get("origin_marker", False),
                marker_diameter=data.get("marker_diameter_mm"),
            )
        except (KeyError, TypeError, AttributeError) as e:
            raise BoardError(f"not a board description ({e!r}): {data!r}") from None
