"""A printed chessboard: its inner corners' geometry in millimetres.

``cols`` x ``rows`` inner corners (OpenCV's ``patternSize``), ``square`` mm apart. Corner
k = r * cols + c is at (c * square, r * square): row-major from the top-left inner corner as
printed, X along a row, Y down a column, as OpenCV's ``findChessboardCorners`` orders them
on a board seen from the front. The board has (cols + 1) x (rows + 1) squares; the top-left
one is black (OpenCV's ``pattern.png``).

A plain chessboard looks the same turned by 180 degrees (and, when square, by 90), so its
orientation is a guess unless ``origin_marker=True``: three dots in the squares about the
board's middle, as OpenCV's ``CALIB_CB_MARKER`` boards have them (``gen_pattern.py -T
radon_checkerboard -m ...``): a white dot in a black square, the L's corner, and black dots in
the white squares right of it and below it. OpenCV's ``findChessboardCornersSB`` with
``CALIB_CB_MARKER`` reads such a board (checked on renders) with its corner 0 at planarcal's
corner 0 (its order is planarcal's transposed: it runs down the columns first). The marker
fixes the reading, and so a part of the board in view identifies itself.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.calib.board_ink import BoardInk
from planarcal.calib.square_corners import SquareCorners
from planarcal.errors import BoardError

F64 = NDArray[np.float64]

MIN_CORNERS_PER_SIDE = 3
"""The fewest inner corners a side may have: OpenCV's chessboard finders need 3."""
MAX_CORNERS_PER_SIDE = 1000
"""The most inner corners a side may have (as a circle grid's dots)."""

MARKER_DOT = 0.4
"""The marker dots' diameter, in squares (OpenCV's gen_pattern.py draws 0.34): small enough
to stay clear of the windows the corners are refined in (0.42 of a square about each
corner), large enough to be read at a few pixels across."""


@dataclasses.dataclass(frozen=True)
class ChessboardBoard(SquareCorners):
    """A chessboard of `cols` x `rows` inner corners, squares `square` mm wide; with
    ``origin_marker=True`` three marker dots fix its orientation (see the module)."""

    cols: int = 9
    rows: int = 6
    square: float = 25.0
    origin_marker: bool = False

    kind: ClassVar[str] = "chessboard"
    point_name: ClassVar[str] = "corner"

    def __post_init__(self) -> None:
        for name in ("cols", "rows"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise BoardError(f"{name} must be a whole number of inner corners, got {value!r}")
            if not MIN_CORNERS_PER_SIDE <= value <= MAX_CORNERS_PER_SIDE:
                raise BoardError(
                    f"{name} must be between {MIN_CORNERS_PER_SIDE} and {MAX_CORNERS_PER_SIDE} "
                    f"inner corners, got {value}"
                )
        try:
            arguments.positive("square", self.square, BoardError)
        except BoardError:
            raise BoardError(
                f"square must be a positive length in mm, got {self.square!r}"
            ) from None
        if not isinstance(self.origin_marker, bool):
            raise BoardError(f"origin_marker must be True or False, got {self.origin_marker!r}")

    @property
    def orientation_fixed(self) -> bool:
        """Whether the printed board fixes its own reading (its marker)."""
        return bool(self.origin_marker)

    @property
    def extent(self) -> tuple[float, float]:
        """Width and height of the squares' field in mm."""
        return ((self.cols + 1) * float(self.square), (self.rows + 1) * float(self.square))

    def square_is_black(self, i: int, j: int) -> bool:
        """Square (i, j), i in 0..cols across and j in 0..rows down, spans x from (i - 1) *
        square to i * square and y likewise; the top-left one is black."""
        return (i + j) % 2 == 0

    def marker_cells(self) -> tuple[tuple[int, int], ...]:
        """The squares (i, j) of the marker's three dots, the origin's first: a black square
        about the board's middle with a white dot, and the white squares right of it and below
        it with black dots (an L opening along the board's X and Y, as OpenCV's
        ``CALIB_CB_MARKER`` boards; empty without a marker)."""
        if not self.origin_marker:
            return ()
        i0, j0 = self.cols // 2, self.rows // 2
        if not self.square_is_black(i0, j0):
            i0 -= 1 if i0 > 0 else -1
        return ((i0, j0), (i0 + 1, j0), (i0, j0 + 1))

    def ink(self) -> BoardInk:
        s = float(self.square)
        rects = [
            ((i - 1) * s, (j - 1) * s, i * s, j * s)
            for j in range(self.rows + 1)
            for i in range(self.cols + 1)
            if self.square_is_black(i, j)
        ]
        # Each marker dot is the colour its square is not.
        circles = [
            (
                (i - 0.5) * s,
                (j - 0.5) * s,
                0.5 * MARKER_DOT * s,
                float(not self.square_is_black(i, j)),
            )
            for i, j in self.marker_cells()
        ]
        w, h = self.extent
        return BoardInk(np.array(rects), np.array(circles), (-s, -s, w - s, h - s))

    def describe(self) -> str:
        """One line for people: '9 x 6 inner corners, squares of 25 mm, origin marker'."""
        text = (
            f"chessboard of {self.cols} x {self.rows} inner corners, squares of {self.square:g} mm"
        )
        if self.origin_marker:
            text += ", origin marker"
        return text

    def to_dict(self) -> dict[str, Any]:
        return {
            "type": self.kind,
            "cols": int(self.cols),
            "rows": int(self.rows),
            "square_mm": float(self.square),
            "origin_marker": bool(self.origin_marker),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ChessboardBoard:
        try:
            return cls(
                cols=data["cols"],
                rows=data["rows"],
                square=data["square_mm"],
                origin_marker=data.get("origin_marker", False),
            )
        except (KeyError, TypeError, AttributeError) as e:
            raise BoardError(f"not a chessboard description ({e!r}): {data!r}") from None
