"""A printed circle-grid calibration board: its geometry in millimetres.

World coordinates are those of the board: the origin is the centre of the origin circle
(point 0), X runs along a row (across the columns), Y down a column (across the rows), both
in millimetres, as printed and seen from the front. Point k = r * cols + c is at
(c * pitch, r * pitch): row-major order from the origin circle.

Two layouts, OpenCV's two:

* ``"symmetric"``: dot (c, r) at (c * pitch, r * pitch).
* ``"asymmetric"`` (OpenCV's ``CALIB_CB_ASYMMETRIC_GRID``, the same world coordinates as its
  documentation's ``((2 c + r % 2) * s, r * s)``): every other row is shifted by half a
  row's spacing, so dot (c, r) is at ((2 c + r % 2) * pitch, r * pitch). ``pitch`` is OpenCV's
  square size: the distance between rows, half the distance between dots along a row; the
  nearest neighbours are the diagonal ones, pitch * sqrt(2) apart.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.calib.board_ink import BoardInk
from planarcal.errors import BoardError

MAX_BOARD_DOTS_PER_SIDE = 1000
"""The most dots a board may have a side: a 1000-dot row is a metre long at a 1 mm pitch, and
its dots' positions (cols x rows of them) are computed whole."""

Layout = Literal["symmetric", "asymmetric"]
LAYOUTS: tuple[Layout, ...] = ("symmetric", "asymmetric")


@dataclasses.dataclass(frozen=True)
class CircleGridBoard:
    """A grid of `cols` x `rows` dark dots of `diameter` mm, `pitch` mm apart.

    The defaults are the paper's board (14 x 10 dots, 20 mm apart, 10 mm across). With
    ``origin_marker=True`` the origin circle is printed larger (``marker_diameter``, by default
    1.5 times the others, at most the distance to its nearest neighbour), as on common
    industrial boards: it fixes the board's orientation. ``diameter`` is what the user states:
    detection measures the dots and refuses a stated size the image contradicts
    (BoardMismatchError). Left out (None, the default) it is not a statement: detection
    measures it without judging, and printing and rendering draw dots half the distance
    between neighbouring dots (the paper's 10 mm at 20 mm, what ``planarcal board`` prints).
    ``layout`` is ``"symmetric"`` or ``"asymmetric"`` (see the module's docstring).

    ``fiducials``: the ids (0-based, as in world_points()) of dots printed larger anywhere in
    the grid, ``fiducial_diameter`` mm across (by default as an origin marker would be), like
    the four enlarged dots inside the UCL metal plate's grid. They tell which part of the
    board is in view, so a view with part of the board cut off, covered or lost to glare is
    read from the dots seen; where they break the grid's symmetry they also fix its
    orientation (``orientation_fixed``).
    """

    cols: int = 14
    rows: int = 10
    pitch: float = 20.0
    # None, not the paper's 10 mm: a default is no statement, so a board described in code
    # without its dots' size is never refused for the size of dots it did not give.
    diameter: float | None = None
    origin_marker: bool = False
    marker_diameter: float | None = None
    layout: Layout = "symmetric"
    fiducials: tuple[int, ...] = ()
    fiducial_diameter: float | None = None

    kind: ClassVar[str] = "circles"
    point_name: ClassVar[str] = "dot"

    def __post_init__(self) -> None:
        for name in ("cols", "rows"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise BoardError(f"{name} must be a whole number of dots, got {value!r}")
            if not 2 <= value <= MAX_BOARD_DOTS_PER_SIDE:
                raise BoardError(
                    f"{name} must be between 2 and {MAX_BOARD_DOTS_PER_SIDE} dots, got {value}"
                )
        if self.layout not in LAYOUTS:
            raise BoardError(f"layout must be 'symmetric' or 'asymmetric', got {self.layout!r}")
        if self.layout == "asymmetric" and self.rows < 3:
            raise BoardError(f"an asymmetric grid needs at least 3 rows, got {self.rows}")
        self._check_fiducials()
        for name in ("pitch", "diameter", "marker_diameter", "fiducial_diameter"):
            value = getattr(self, name)
            if value is None and name != "pitch":
                continue
            try:
                arguments.positive(name, value, BoardError)
            except BoardError:
                raise BoardError(f"{name} must be a positive length in mm, got {value!r}") from None
        spacing = self.neighbour_distance
        if self.diameter is not None and self.diameter >= spacing:
            raise BoardError(
                f"dots of {self.diameter} mm do not fit {spacing:g} mm apart: the diameter "
                "must be smaller than the distance between neighbouring dots"
            )
        if self.marker_diameter is not None and not self.origin_marker:
            raise BoardError("marker_diameter is given but origin_marker is False")
        if self.origin_marker and self.diameter is not None:
            marker = self.origin_marker_diameter
            if not (self.diameter * 1.2 <= marker <= spacing):
                raise BoardError(
                    f"the origin marker ({marker:g} mm) must be at least 1.2 times the dots "
                    f"({self.diameter:g} mm), to be told apart, and at most the distance to "
                    f"its neighbours ({spacing:g} mm)"
                )
        elif (
            self.origin_marker
            and self.marker_diameter is not None
            and self.marker_diameter > spacing
        ):
            raise BoardError(
                f"the origin marker ({self.marker_diameter:g} mm) must be at most the "
                f"distance to its neighbours ({spacing:g} mm)"
            )

        self._check_fiducial_size()

    def _check_fiducial_size(self) -> None:
        """BoardError for fiducials too small to be told apart or wider than their spacing."""
        spacing = self.neighbour_distance
        if self.fiducials and self.diameter is not None:
            fiducial = self.fiducial_diameter_mm
            if not (self.diameter * 1.2 <= fiducial <= spacing):
                raise BoardError(
                    f"the fiducial dots ({fiducial:g} mm) must be at least 1.2 times the dots "
                    f"({self.diameter:g} mm), to be told apart, and at most the distance to "
                    f"their neighbours ({spacing:g} mm)"
                )
        elif self.fiducial_diameter is not None and self.fiducial_diameter > spacing:
            raise BoardError(
                f"the fiducial dots ({self.fiducial_diameter:g} mm) must be at most the "
                f"distance to their neighbours ({spacing:g} mm)"
            )

    def _check_fiducials(self) -> None:
        """Normalises ``fiducials`` to sorted distinct ids (BoardError for anything else)."""
        given = self.fiducials
        if isinstance(given, str | bytes) or not hasattr(given, "__iter__"):
            raise BoardError(f"fiducials must be a sequence of dot ids, got {given!r}")
        ids: list[int] = []
        n = self.cols * self.rows
        for value in given:
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise BoardError(f"fiducials: {value!r} is not a dot id (a whole number)")
            if not 0 <= int(value) < n:
                raise BoardError(
                    f"fiducials: dot {value} does not exist (the board's dots are 0 to {n - 1})"
                )
            ids.append(int(value))
        if len(set(ids)) != len(ids):
            raise BoardError(f"fiducials: a dot is named twice in {sorted(ids)}")
        if self.origin_marker and 0 in ids:
            raise BoardError("fiducials: dot 0 is the origin marker, not a fiducial")
        if self.fiducial_diameter is not None and not ids:
            raise BoardError("fiducial_diameter is given but the board has no fiducials")
        object.__setattr__(self, "fiducials", tuple(sorted(ids)))

    @property
    def neighbour_distance(self) -> float:
        """Distance between nearest neighbouring dots in mm (the pitch, or pitch * sqrt(2)
        in the asymmetric layout, whose nearest neighbours are diagonal)."""
        if self.layout == "asymmetric":
            return float(self.pitch) * math.sqrt(2.0)
        return float(self.pitch)

    def dots_mm(self) -> float:
        """The dots' diameter in mm to print or render: the stated one, else half the
        distance between neighbouring dots (``planarcal board``'s default)."""
        if self.diameter is None:
            return 0.5 * self.neighbour_distance
        return float(self.diameter)

    @property
    def origin_marker_diameter(self) -> float:
        """Diameter of the origin circle in mm (the other dots' when there is no marker);
        BoardError when it depends on an unknown dot diameter."""
        if self.origin_marker and self.marker_diameter is not None:
            return float(self.marker_diameter)
        d = self.dots_mm()
        if not self.origin_marker:
            return d
        return min(1.5 * d, 0.5 * (d + self.neighbour_distance))

    @property
    def fiducial_diameter_mm(self) -> float:
        """Diameter of the fiducial dots in mm (as an origin marker's would be unless given);
        BoardError when it depends on an unknown dot diameter."""
        if self.fiducial_diameter is not None:
            return float(self.fiducial_diameter)
        d = self.dots_mm()
        return min(1.5 * d, 0.5 * (d + self.neighbour_distance))

    def dot_kinds(self) -> NDArray[np.int8]:
        """Each dot's kind, in the order of world_points(): 0 a regular dot, 1 a fiducial,
        2 the origin marker (dot 0 where the board has one). The enlarged dots (kinds 1 and 2)
        are what tells one part of the board from another."""
        kinds = np.zeros(self.n_points, dtype=np.int8)
        kinds[list(self.fiducials)] = 1
        if self.origin_marker:
            kinds[0] = 2
        return kinds

    def reading_symmetries(self) -> list[NDArray[np.intp]]:
        """The turns of the board in its plane (by 90, 180 or 270 degrees, never a mirror)
        that map its dots and their kinds onto themselves, as permutations of the dot ids
        (``perm[k]`` is where dot k lands), the identity first: views the board's print cannot
        tell apart. One (the identity) when the board fixes its own orientation."""
        world = self.world_points()
        # Integer lattice coordinates (both layouts put dots at whole pitches).
        cells = np.rint(world / float(self.pitch)).astype(np.int64)
        kinds = self.dot_kinds()
        span = int(cells.max()) + 1
        keys = cells[:, 0] * span + cells[:, 1]
        order = np.argsort(keys)
        out = [np.arange(self.n_points, dtype=np.intp)]
        for turn in ((0, -1, 1, 0), (-1, 0, 0, -1), (0, 1, -1, 0)):
            m = np.array(turn, dtype=np.int64).reshape(2, 2)
            turned = cells @ m.T
            turned -= turned.min(axis=0)
            if int(turned.max()) >= span:
                continue
            turned_keys = turned[:, 0] * span + turned[:, 1]
            place = np.searchsorted(keys[order], turned_keys)
            place = np.minimum(place, len(keys) - 1)
            perm = order[place]
            if np.array_equal(keys[perm], turned_keys) and np.array_equal(kinds[perm], kinds):
                out.append(perm.astype(np.intp))
        return out

    @property
    def n_points(self) -> int:
        return self.cols * self.rows

    @property
    def orientation_fixed(self) -> bool:
        """Whether the printed board fixes its own reading: an origin marker, an asymmetric
        grid with an odd number of rows (whose pattern has one unmirrored reading), or
        fiducial dots placed without the grid's symmetry."""
        if self.origin_marker or (self.layout == "asymmetric" and self.rows % 2 == 1):
            return True
        return bool(self.fiducials) and len(self.reading_symmetries()) == 1

    def ink(self) -> BoardInk:
        """The dots as black discs (see planarcal.calib.board_ink)."""
        pts = self.world_points()
        d = self.dot_diameters()
        circles = np.column_stack([pts, 0.5 * d, np.ones(len(d))])
        big = 0.5 * float(d.max())
        x1, y1 = pts.max(axis=0)
        return BoardInk(np.zeros((0, 4)), circles, (-big, -big, float(x1) + big, float(y1) + big))

    @property
    def extent(self) -> tuple[float, float]:
        """Width and height of the dot field in mm, from outer edge to outer edge."""
        biggest = max(self.dots_mm(), self.origin_marker_diameter)
        if self.fiducials:
            biggest = max(biggest, self.fiducial_diameter_mm)
        span = self.world_points().max(axis=0)
        return (float(span[0]) + biggest, float(span[1]) + biggest)

    def world_points(self) -> NDArray[np.float64]:
        """Centres of the dots in mm, (rows * cols, 2), row-major from the origin circle."""
        r, c = np.divmod(np.arange(self.n_points), self.cols)
        if self.layout == "asymmetric":
            c = 2 * c + r % 2
        return np.column_stack([c * float(self.pitch), r * float(self.pitch)])

    def dot_diameters(self) -> NDArray[np.float64]:
        """Diameter of each dot in mm, in the order of world_points()."""
        d = np.full(self.n_points, self.dots_mm())
        d[0] = self.origin_marker_diameter
        if self.fiducials:
            d[list(self.fiducials)] = self.fiducial_diameter_mm
        return d

    def describe(self) -> str:
        """One line for people: '10 x 8 dots of 15 mm, 25 mm apart, origin marker', or for
        the asymmetric layout '4 x 11 dots of 15 mm in an asymmetric grid: rows 20 mm apart,
        dots 40 mm apart along a row'."""
        size = "" if self.diameter is None else f" of {self.diameter:g} mm"
        if self.layout == "asymmetric":
            text = (
                f"{self.cols} x {self.rows} dots{size} in an asymmetric grid: rows "
                f"{self.pitch:g} mm apart, dots {2 * self.pitch:g} mm apart along a row"
            )
        else:
            text = f"{self.cols} x {self.rows} dots{size}, {self.pitch:g} mm apart"
        if self.origin_marker:
            text += ", origin marker"
        if self.fiducials:
            size = "" if self.fiducial_diameter is None else f" of {self.fiducial_diameter:g} mm"
            ids = ", ".join(str(k) for k in self.fiducials)
            text += f", {len(self.fiducials)} fiducial dot(s){size} (ids {ids})"
        return text

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready description (see from_dict); the fiducials' keys only where the board
        has fiducials (a board without them is described as before they existed)."""
        data: dict[str, Any] = {
            "cols": int(self.cols),
            "rows": int(self.rows),
            "pitch_mm": float(self.pitch),
            "diameter_mm": None if self.diameter is None else float(self.diameter),
            "origin_marker": bool(self.origin_marker),
            "marker_diameter_mm": None
            if self.marker_diameter is None
            else float(self.marker_diameter),
            "layout": self.layout,
        }
        if self.fiducials:
            data["fiducials"] = [int(k) for k in self.fiducials]
            data["fiducial_diameter_mm"] = (
                None if self.fiducial_diameter is None else float(self.fiducial_diameter)
            )
        return data

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
                layout=data.get("layout", "symmetric"),
                fiducials=tuple(data.get("fiducials", ())),
                fiducial_diameter=data.get("fiducial_diameter_mm"),
            )
        except (KeyError, TypeError, AttributeError) as e:
            raise BoardError(f"not a board description ({e!r}): {data!r}") from None
