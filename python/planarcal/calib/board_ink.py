"""What a board's page shows, as shapes in board millimetres: the one description that the
printed page (planarcal.report.printable) and the renderer (planarcal.synth) both draw, so a
board prints and renders alike whatever its type.

Coordinates are the board's world frame (mm, X along a row, Y down a column, as printed and
seen from the front). Drawn in order on white paper: the black rectangles, then the circles,
each black or white (an origin marker's dot on a square of the other colour).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class BoardInk:
    """A board's printed marks in board mm.

    ``rects``: (N, 4) black axis-aligned rectangles (x0, y0, x1, y1); rectangles may share
    edges (a chessboard's squares touch at their corners, an ArUco marker's cells at their
    sides) but never overlap. ``circles``: (M, 4) discs (cx, cy, radius, black) with black 1.0
    for ink and 0.0 for a white dot on black. ``field``: (x0, y0, x1, y1), the extent of the
    pattern (its outer edges), which the paper's margin is measured from.
    """

    rects: F64
    circles: F64
    field: tuple[float, float, float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "rects", np.asarray(self.rects, np.float64).reshape(-1, 4))
        object.__setattr__(self, "circles", np.asarray(self.circles, np.float64).reshape(-1, 4))


def cell_runs(bits: NDArray[np.bool_], x0: float, y0: float, cell: float) -> F64:
    """The True cells of a bit grid (rows down, columns across) as rectangles, each row's runs
    of neighbouring True cells merged into one: (N, 4) x0, y0, x1, y1 in mm, the grid's
    top-left corner at (x0, y0), cells `cell` mm wide."""
    out: list[tuple[float, float, float, float]] = []
    for r, row in enumerate(np.asarray(bits, bool)):
        c = 0
        n = len(row)
        while c < n:
            if not row[c]:
                c += 1
                continue
            start = c
            while c < n and row[c]:
                c += 1
            out.append((x0 + start * cell, y0 + r * cell, x0 + c * cell, y0 + (r + 1) * cell))
    return np.array(out, np.float64).reshape(-1, 4)
