"""How the report names a board's points, whatever the board: by the board's own word for
them (a circle grid's "dot", a chessboard's or ChArUco board's "corner") and by their ids,
indices into ``board.world_points()`` (0-based), which on a grid board are k = row x cols +
col. A partial view holds some of the ids only: the report never takes its n-th point to be
id n, nor a board to have cols and rows without asking it."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.board import CircleGridBoard

Ids = NDArray[np.intp]

NO_BOARD_POINT_NAME = "dot"
"""What points are called without a board: the paper's points are a circle grid's dots."""


def point_name(board: Any) -> str:
    """The board's word for its points ("dot", "corner"); "dot" without a board."""
    name = getattr(board, "point_name", None)
    return name if isinstance(name, str) and name else NO_BOARD_POINT_NAME


def plural(name: str, n: int) -> str:
    """ "dot" or "dots", as `n` asks."""
    return name if n == 1 else f"{name}s"


def is_circle_grid(board: Any) -> bool:
    """Whether the board is a circle grid: only its detections carry the dots' polarity, sizes
    and diameters."""
    return isinstance(board, CircleGridBoard)


def grid_shape(board: Any) -> tuple[int, int] | None:
    """(cols, rows) of a board whose point ids run row by row, k = row x cols + col (every
    board type planarcal has: a circle grid's dots, a chessboard's or ChArUco board's inner
    corners); None for a board that is no such grid."""
    cols, rows, n = (_whole(getattr(board, k, None)) for k in ("cols", "rows", "n_points"))
    if cols is None or rows is None or n is None or min(cols, rows) < 1 or cols * rows != n:
        return None
    return cols, rows


def _whole(value: Any) -> int | None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        return None
    return int(value)


def numbering(board: Any) -> str:
    """How the ids are numbered, for the labels' captions."""
    if board is None or grid_shape(board) is not None:
        return "k = row x cols + col"
    return "as the board numbers them"


def _valid_ids(ids: Any, n: int, board: Any) -> Ids | None:
    """`ids` as an index array when it is one id per point, each on the board; else None."""
    if ids is None:
        return None
    try:
        out = np.asarray(ids).reshape(-1)
    except (TypeError, ValueError):
        return None
    if len(out) != n or (n and not np.issubdtype(out.dtype, np.integer)):
        return None
    out = out.astype(np.intp)
    total = _whole(getattr(board, "n_points", None))
    if n and (out.min() < 0 or (total is not None and out.max() >= total)):
        return None
    return out


def detection_ids(detection: Any) -> Ids:
    """The ids of a detection's points (``detection.ids``), one per image point; a
    detection that carries none (or not one per point) is taken as the board's points in
    order."""
    n = len(detection.image_points)
    ids = _valid_ids(getattr(detection, "ids", None), n, getattr(detection, "board", None))
    return np.arange(n, dtype=np.intp) if ids is None else ids


def calibration_ids(cal: Any, detection: Any = None) -> Ids:
    """The ids of a calibration's points, in the order of its world and image points: the
    calibration's own (``point_ids``), else its detection's, else their row numbers (points
    given without a board)."""
    n = len(cal.world_points)
    board = getattr(cal, "board", None)
    ids = _valid_ids(getattr(cal, "point_ids", None), n, board)
    if ids is None and detection is not None:
        ids = _valid_ids(getattr(detection, "ids", None), n, board)
    return np.arange(n, dtype=np.intp) if ids is None else ids


def id_list(ids: Any, name: str, most: int = 20) -> str:
    """ "dot 3" or "corners 3, 17, 40" (their ids), the first `most` of a long list."""
    numbers = [int(k) for k in np.asarray(ids).reshape(-1)]
    shown = ", ".join(str(k) for k in numbers[:most])
    more = f" and {len(numbers) - most} more" if len(numbers) > most else ""
    return f"{plural(name, len(numbers))} {shown}{more}"


def missing_ids(board: Any, ids: Ids) -> Ids:
    """The board's ids not among `ids` (a partial view's points not seen), ascending."""
    total = _whole(getattr(board, "n_points", None))
    if total is None or total <= len(ids):
        return np.zeros(0, dtype=np.intp)
    return np.setdiff1d(np.arange(total, dtype=np.intp), ids).astype(np.intp)


LAYOUT_NAMES = {
    "legacy": "legacy (OpenCV's before 4.6)",
    "current": "current (OpenCV 4.6 and later)",
}
"""A ChArUco detection's printed layouts, for people."""


def layout_phrase(layout: Any) -> str | None:
    """The printed layout a detection found, for people; None when it does not say."""
    if layout is None:
        return None
    return LAYOUT_NAMES.get(str(layout), str(layout))
