"""The board side of a registration's point pairs, in the calibration's board mm, from what a
user can give: the board points the robot touched by their ids (a circle grid's dots, a
chessboard's or ChArUco board's corners), board positions in mm, or, N-point, the image
positions (px) where the camera saw the part the robot placed, mapped through the calibration
(their own 1-sigma then goes with them).

A point's id is the board's own, 0-based, as ``board.world_points()`` numbers them (a circle
grid's dot k = row x cols + col, 0 the origin dot; a chessboard's or ChArUco board's inner
corner likewise, OpenCV's ids); its position is the point in the calibration's world frame
(the board's nominal coordinates times the printer-scale correction, if any).

The calibration is anything with a board, a world scale and an image-to-world mapping
(``PlaneCalibration``): the robot layer is above the calibration's and does not import it."""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal.errors import ArgumentError, BoardError
from planarcal.robot.transform_fit import F64

DEFAULT_POINT_NAME = "dot"
"""What a registration calls the board's points when nothing says: a circle grid's word, the
board planarcal read first (``board.point_name`` says it for every board)."""


def checked_point_name(point_name: Any) -> str:
    """``point_name`` ("dot", "corner": a board's ``point_name``), checked: one lower-case
    word, as messages put it before an id ("corner 12"); ArgumentError otherwise."""
    if not isinstance(point_name, str) or not re.fullmatch(r"[a-z]+", point_name):
        raise ArgumentError(
            f"point_name must be one lower-case word, a board's point_name such as 'dot' or "
            f"'corner', got {point_name!r}"
        )
    return point_name


class PointIds(tuple[int, ...]):
    """Board point ids (0-based, into ``board.world_points()``) that know what the board
    calls its points (``point_name``): what ``plane_points`` gives for ids, so that the
    registration fitted from them names a chessboard's pairs "corner k" and a circle grid's
    "dot k" without another argument on the way."""

    point_name: str

    def __new__(cls, ids: Iterable[int], point_name: str) -> PointIds:
        out = super().__new__(cls, ids)
        out.point_name = checked_point_name(point_name)
        return out


class PlaneCalibration(Protocol):
    """What the pairs need of a calibration (planarcal.Calibration has it)."""

    @property
    def board(self) -> Any: ...

    @property
    def world_scale(self) -> tuple[float, float]: ...

    def image_to_world(self, points_px: Any, *, return_std: bool = ...) -> Any: ...


def plane_points(
    calibration: PlaneCalibration,
    *,
    dots: ArrayLike | None = None,
    board_mm: ArrayLike | None = None,
    image_px: ArrayLike | None = None,
) -> tuple[F64, F64 | None, tuple[int, ...] | None]:
    """The board points (N, 2) in mm of exactly one of ``dots`` (N,), ``board_mm`` (N, 2) or
    ``image_px`` (N, 2), their own 1-sigma errors (N,) for image points (None for dots and
    board mm, which are exact by definition of the board's frame), and the point ids (N,)
    when given as ids (``dots``: a circle grid's dots, a chessboard's corners), as PointIds
    carrying the board's ``point_name``."""
    given = [
        name
        for name, v in (("dots", dots), ("board_mm", board_mm), ("image_px", image_px))
        if v is not None
    ]
    if len(given) != 1:
        raise ArgumentError(
            "give the board side of the pairs as exactly one of dots, board_mm or image_px, "
            f"got {' and '.join(given) if given else 'none'}"
        )
    if dots is not None:
        index = dot_indices(calibration, dots)
        assert calibration.board is not None  # dot_indices checked
        ids = PointIds(index.tolist(), calibration.board.point_name)
        return dot_positions(calibration, index), None, ids
    if board_mm is not None:
        flat, lead = arguments.points("board_mm", board_mm)
        if len(lead) != 1:
            raise ArgumentError(f"board_mm must have shape (N, 2), got {np.shape(board_mm)}")
        return flat, None, None
    assert image_px is not None  # exactly one was given
    flat, lead = arguments.points("image_px", image_px)
    if len(lead) != 1:
        raise ArgumentError(f"image_px must have shape (N, 2), got {np.shape(image_px)}")
    mm, std = calibration.image_to_world(flat, return_std=True)
    return np.asarray(mm, dtype=np.float64), np.asarray(std, dtype=np.float64), None


def board_extent(calibration: PlaneCalibration) -> F64 | None:
    """The corners ((x0, y0), (x1, y1)) in board mm of the calibration's board's dots and of
    the points it was calibrated on (the area a registration serves: a calibration from
    several placements serves all of them), or None for a calibration that records no
    board."""
    board = calibration.board
    if board is None:
        return None
    dots = board.world_points() * np.asarray(calibration.world_scale, dtype=np.float64)
    calibrated = getattr(calibration, "world_points", None)
    if calibrated is not None and len(calibrated):
        dots = np.concatenate([dots, np.asarray(calibrated, dtype=np.float64)])
    out: F64 = np.array([dots.min(axis=0), dots.max(axis=0)])
    return out


def dot_positions(calibration: PlaneCalibration, dots: ArrayLike) -> F64:
    """The centres (N, 2) in the calibration's board mm of the dots numbered ``dots`` (N,);
    ArgumentError for an index that is not a whole number or is off the board, BoardError for
    a calibration that records no board."""
    index = dot_indices(calibration, dots)
    assert calibration.board is not None  # dot_indices checked
    scale = np.asarray(calibration.world_scale, dtype=np.float64)
    out: F64 = calibration.board.world_points()[index] * scale
    return out


def dot_indices(calibration: PlaneCalibration, dots: ArrayLike) -> NDArray[np.int64]:
    """The point ids ``dots`` (N,) checked against the calibration's board (its dots or
    corners, 0-based into ``board.world_points()``): ArgumentError for an id that is not a
    whole number or is off the board, naming the board's points by its ``point_name``;
    BoardError for a calibration that records no board."""
    board = calibration.board
    if board is None:
        raise BoardError(
            "this calibration records no board (made from bare points), so a board point's "
            "id (a dot's, a corner's) has no position: give the touch points as board mm "
            "instead"
        )
    name = checked_point_name(getattr(board, "point_name", DEFAULT_POINT_NAME))
    try:
        # As objects: an int array would turn True into dot 1.
        raw = dots if isinstance(dots, np.ndarray) else np.asarray(dots, dtype=object)
    except (TypeError, ValueError):
        raise ArgumentError(f"dots must be a list of {name} indices") from None
    if raw.ndim != 1 or raw.size == 0:
        raise ArgumentError(f"dots must be a list of {name} indices (N,), got shape {raw.shape}")
    n = board.n_points
    index = np.empty(len(raw), dtype=np.int64)
    for i, value in enumerate(raw.tolist()):
        whole = isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)
        if isinstance(value, float | np.floating) and float(value).is_integer():
            whole, value = True, int(value)
        if not whole:
            raise ArgumentError(f"{name} {i}: {value!r} is not a {name} index (a whole number)", i)
        if not 0 <= value < n:
            raise ArgumentError(
                f"{name} {i}: index {value} is off the board: {_grid(board, name)} has "
                f"{name}s 0 to {n - 1} (k = row x {board.cols} + column, 0 the origin {name})",
                i,
            )
        index[i] = value
    return index


def _grid(board: Any, point_name: str) -> str:
    """The board's grid of points in words: "a 14 x 10 board" of dots; a chessboard's or a
    ChArUco board's grid of corners named as such, not to be read as its squares."""
    if point_name == DEFAULT_POINT_NAME:
        return f"a {board.cols} x {board.rows} board"
    return f"a board of {board.cols} x {board.rows} inner {point_name}s"
