"""What chessboards and ChArUco boards share: their points are the inner corners of a grid of
squares, one square apart, numbered row-major (k = r * cols + c) as OpenCV numbers them."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


class SquareCorners:
    """Inner corners ``cols`` x ``rows``, ``square`` mm apart, corner 0
    ``first_corner_squares`` squares from the board's origin along both axes (0 on a
    chessboard, whose origin is corner 0; 1 on a ChArUco board, whose origin is its outer
    corner)."""

    first_corner_squares: ClassVar[int] = 0

    # The board's own (fields or properties).
    if TYPE_CHECKING:

        @property
        def cols(self) -> int: ...
        @property
        def rows(self) -> int: ...
        @property
        def square(self) -> float: ...

    @property
    def pitch(self) -> float:
        """Distance between neighbouring corners in mm (the square's side)."""
        return float(self.square)

    @property
    def neighbour_distance(self) -> float:
        return float(self.square)

    @property
    def n_points(self) -> int:
        return self.cols * self.rows

    def world_points(self) -> F64:
        """The inner corners in mm, (rows * cols, 2), row-major from corner 0."""
        r, c = np.divmod(np.arange(self.n_points), self.cols)
        start = self.first_corner_squares * self.pitch
        return np.column_stack([start + c * self.pitch, start + r * self.pitch])
