"""Which of a board's points a calibration's world points are: their ids (indices into
``board.world_points()``), found by matching each world point to the board point it lies on,
whatever the board's type and however few of its points were seen."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planarcal.calib.boards import Board

F64 = NDArray[np.float64]
Ids = NDArray[np.intp]

POINT_TOLERANCE_REL = 1e-9
"""How closely a world point must lie on its board point, relative to the board's extent
(the points are the board's positions times world_scale: rounding is some 1e-16)."""


def match_board_points(
    board: Board, world: F64, world_scale: tuple[float, float] = (1.0, 1.0)
) -> tuple[Ids | None, str | None]:
    """(ids, None) with the id of the board point each world point lies on (scaled by
    `world_scale`, see Calibration.rescaled), to POINT_TOLERANCE_REL of the board's extent;
    or (None, what is wrong): a point on no board point, or two on the same one. A board
    described otherwise than the points (another pitch, layout or size) is another
    calibration."""
    with np.errstate(all="ignore"):  # a huge pitch overflows: its points are then no points'
        ref = board.world_points()
        nominal = world / np.asarray(world_scale, dtype=np.float64)
    tolerance = POINT_TOLERANCE_REL * max(1.0, float(np.abs(ref).max()))
    n = len(nominal)
    if n <= len(ref) and np.all(np.abs(nominal - ref[:n]) <= tolerance):
        return np.arange(n, dtype=np.intp), None  # the first n points in order: a whole board
    if np.isfinite(ref).all() and np.isfinite(nominal).all():
        distance, index = cKDTree(ref).query(nominal)
    else:  # a scale or pitch that overflows: no point is a board point
        distance, index = np.full(n, np.inf), np.arange(n)
    bad = np.flatnonzero(~(distance <= tolerance))
    scale = "" if world_scale == (1.0, 1.0) else f" scaled by {list(world_scale)}"
    what = board.point_name
    if bad.size:
        k = int(bad[0])
        return None, (
            f"world point {k} ({world[k][0]:g}, {world[k][1]:g}) mm is not a {what} of the "
            f"board ({board.describe()}{scale})"
        )
    # Each on its own point: a scale of 1e300 would put them all on the first.
    _, first = np.unique(index, return_index=True)
    if len(first) < n:
        k = int(np.setdiff1d(np.arange(n), first)[0])
        return None, (
            f"world point {k} ({world[k][0]:g}, {world[k][1]:g}) mm falls on the {what} of "
            f"another point of the board ({board.describe()}{scale})"
        )
    return np.asarray(index, dtype=np.intp), None
