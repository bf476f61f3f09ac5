"""A Calibration's placements: checking the detections given as placements (one camera, one
board, a reference among them), laying them out for the joint fit, and the ``Placement``
records a calibration shows for them (calib.placements holds the fit's side)."""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from planarcal.calib.board_copies import detect_board_copies
from planarcal.calib.boards import Board, is_board
from planarcal.calib.detection import detect_board
from planarcal.calib.detector_options import detector_options
from planarcal.calib.placements import (
    Placement,
    PlacementLayout,
    placement_label,
    residual_rms,
    start_poses,
)
from planarcal.errors import ArgumentError, BoardError, BoardNotFoundError, FrameSizeError

if TYPE_CHECKING:
    from planarcal.calib.calibration import Calibration


def placement_names(names: Sequence[str] | None, count: int) -> tuple[str, ...]:
    """The placements' labels: `names` checked (one string per placement), or "placement k"."""
    if names is None:
        return tuple(f"placement {k}" for k in range(count))
    if isinstance(names, str) or not isinstance(names, Sequence):
        raise ArgumentError(f"names must be a sequence of strings, got {type(names).__name__}")
    labels = tuple(names)
    if len(labels) != count or not all(isinstance(n, str) for n in labels):
        raise ArgumentError(
            f"names must be one string per placement ({count}), got {len(labels)} "
            f"({', '.join(type(n).__name__ for n in labels[:3])}...)"
        )
    return labels


def checked_reference(reference: Any, count: int) -> int:
    """The reference placement's index, checked against the count."""
    try:
        k = operator.index(reference)
    except TypeError:
        raise ArgumentError(
            f"reference must be a placement's index (0 to {count - 1}), got {reference!r}"
        ) from None
    if not 0 <= k < count:
        raise ArgumentError(
            f"reference must be a placement's index (0 to {count - 1}), got {reference!r}"
        )
    return int(k)


def same_camera_and_board(
    detections: Sequence[Any], names: Sequence[str]
) -> tuple[Board, tuple[int, int]]:
    """The one board and image size of the placements' detections; BoardError or
    FrameSizeError naming the first placement that differs (placements are one board laid
    at several places, seen by one fixed camera)."""
    for k, d in enumerate(detections):
        if not is_board(getattr(d, "board", None)) or not hasattr(d, "world_points"):
            raise ArgumentError(
                f"{placement_label(k, names[k])} must be a BoardDetection "
                f"(planarcal.detect_board's result), got {type(d).__name__}"
            )
    board: Board = detections[0].board
    size = (int(detections[0].image_size[0]), int(detections[0].image_size[1]))
    for k, d in enumerate(detections[1:], start=1):
        if d.board != board:
            raise BoardError(
                f"{placement_label(k, names[k])} is of another board ({d.board.describe()}) than "
                f"placement 0 ({board.describe()}): placements are one board laid at several "
                "places"
            )
        other = (int(d.image_size[0]), int(d.image_size[1]))
        if other != size:
            raise FrameSizeError(
                f"{placement_label(k, names[k])} is a {other[0]} x {other[1]} image, placement 0 "
                f"a {size[0]} x {size[1]} one: placements are seen by one fixed camera at one "
                "resolution",
                other,
                size,
            )
    return board, size


def detect_placement(
    image: Any, board: Board, k: int, reference: int, name: str, options: dict[str, Any]
) -> Any:
    """Placement k's detection of `board` in `image`: a placement other than the reference may
    lie at any angle, its pose takes the board's turn, so a turned board is accepted there
    unless the options say otherwise (the reference's frame is the plane's: its orientation
    stays the user's to settle). BoardNotFoundError names the placement."""
    options = dict(options)
    if k != reference and "turned" not in options and "turned" in detector_options(board.kind):
        options["turned"] = True
    try:
        return detect_board(image, board, **options)
    except BoardNotFoundError as e:
        raise type(e)(f"{placement_label(k, name)}: {e}", e.diagnostics) from None


def detect_copies(
    image: Any, board: Board, k: int, name: str, options: dict[str, Any]
) -> tuple[list[Any], list[str]]:
    """Every copy of `board` in image k (calib.board_copies: several boards laid out at once,
    each a placement), with their names ("A.png copy 1", ...); BoardNotFoundError names the
    image."""
    try:
        found = detect_board_copies(image, board, **options)
    except BoardNotFoundError as e:
        raise type(e)(f"image {k} ({name}): {e}", e.diagnostics) from None
    return found, [f"{name} copy {j + 1}" for j in range(len(found))]


def placement_layout(detections: Sequence[Any], reference: int) -> PlacementLayout:
    """The detections laid out for the joint fit, with start poses."""
    board_mm = np.ascontiguousarray(np.concatenate([d.world_points() for d in detections]))
    image = np.ascontiguousarray(np.concatenate([d.image_points for d in detections]))
    placement = np.concatenate(
        [np.full(len(d.image_points), k, np.intp) for k, d in enumerate(detections)]
    )
    count = len(detections)
    poses = start_poses(board_mm, image, placement, count, reference)
    return PlacementLayout(board_mm, placement, reference, poses, np.zeros((count, 3, 3)))


def calibration_placements(cal: Calibration) -> tuple[Placement, ...]:
    """The Placement records of a calibration: its layout's (several placements), one for a
    calibration from one board view (its ids and points, the identity pose), none without a
    board."""
    layout = cal._fit.placements
    names = cal._placement_names
    partial = cal._placement_partial
    ids = cal.point_ids
    size = cal.image_size or (0, 0)
    if layout is None:
        if ids is None or cal.board is None:
            return ()
        rms = residual_rms(cal.image_points, cal.reprojected_px, np.zeros(len(ids), np.intp), 1)
        seen = len(np.unique(ids)) < cal.board.n_points
        return (
            Placement(
                0,
                names[0] if names else "placement 0",
                size,
                ids,
                cal.world_points,
                cal.image_points,
                cal.world_points,
                0.0,
                (0.0, 0.0),
                0.0,
                0.0,
                float(rms[0]),
                partial[0] if partial else seen,
                True,
            ),
        )
    assert ids is not None
    rms = residual_rms(cal.image_points, cal.reprojected_px, layout.placement, layout.count)
    out = []
    for k in range(layout.count):
        mine = layout.placement == k
        cov = layout.pose_covariance[k]
        out.append(
            Placement(
                k,
                names[k] if k < len(names) else f"placement {k}",
                size,
                ids[mine],
                layout.board_mm[mine],
                cal.image_points[mine],
                cal.world_points[mine],
                math.degrees(float(layout.poses[k, 0])),
                (float(layout.poses[k, 1]), float(layout.poses[k, 2])),
                math.degrees(math.sqrt(max(float(cov[0, 0]), 0.0))),
                math.sqrt(max(float(cov[1, 1] + cov[2, 2]), 0.0)),
                float(rms[k]),
                partial[k] if k < len(partial) else False,
                k == layout.reference,
            )
        )
    return tuple(out)
