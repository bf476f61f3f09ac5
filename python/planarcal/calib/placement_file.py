"""The ``placements`` field of a calibration file (version 6): what a calibration from several
placements of its board records of them, and the checks that read it back (calib.
calibration_file holds the rest of the format)::

    "placements": {
      "reference": 0,
      "items": [{"name": "A.png", "image_size_px": [1280, 960], "points": 42,
                 "partial": false, "angle_rad": 0.0, "offset_mm": [0.0, 0.0]}, ...],
      "point_placement": [0, 0, ..., 1, ...]
    }

null for a calibration from one view. The poses are the fit's; loading rebuilds the layout
from the board's points (``points.ids``) and these poses, and calibration_file holds the
world points, homography and lens to them."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.boards import Board
from planarcal.calib.json_number import is_json_int, is_json_real
from planarcal.calib.placements import PlacementLayout
from planarcal.errors import CalibrationFileError

if TYPE_CHECKING:
    from planarcal.calib.calibration import Calibration

ITEM_FIELDS = ("name", "image_size_px", "points", "partial", "angle_rad", "offset_mm")


@dataclasses.dataclass(frozen=True)
class StoredPlacements:
    """A file's placements, checked."""

    reference: int
    names: tuple[str, ...]
    partial: tuple[bool, ...]
    poses: NDArray[np.float64]
    placement: NDArray[np.intp]
    ids: NDArray[np.intp]

    def layout(self, board: Board, world_scale: tuple[float, float]) -> PlacementLayout:
        """The fit's layout: each point's board position (scaled as the file says) with the
        stored poses."""
        board_mm = board.world_points()[self.ids] * np.asarray(world_scale)
        return PlacementLayout(
            np.ascontiguousarray(board_mm),
            self.placement,
            self.reference,
            self.poses,
            np.zeros((len(self.poses), 3, 3)),
        )


def placements_to_dict(cal: Calibration) -> dict[str, Any] | None:
    """The file's ``placements`` of `cal` (None for a calibration from one view)."""
    layout = cal._fit.placements
    if layout is None:
        return None
    items = []
    for p in cal.placements:
        pose = layout.poses[p.index]
        items.append(
            {
                "name": p.name,
                "image_size_px": list(p.image_size),
                "points": len(p.ids),
                "partial": p.partial,
                "angle_rad": float(pose[0]),
                "offset_mm": [float(pose[1]), float(pose[2])],
            }
        )
    return {
        "reference": int(layout.reference),
        "items": items,
        "point_placement": [int(k) for k in layout.placement],
    }


def placements_from_dict(
    data: Any,
    board: Board | None,
    ids: Any,
    n_points: int,
    image_size: tuple[int, int] | None,
    source: str,
) -> StoredPlacements | None:
    """The placements a file records (None for null); CalibrationFileError naming what is
    malformed or disagrees with the rest of the file (the points' count, ids, image size)."""
    if data is None:
        return None
    where = f"{source}: placements"
    if not isinstance(data, dict) or set(data) != {"reference", "items", "point_placement"}:
        raise CalibrationFileError(
            f"{where} must be an object with reference, items and point_placement"
        )
    if board is None:
        raise CalibrationFileError(f"{where} without a board (board is null)")
    items = data["items"]
    if not isinstance(items, list) or len(items) < 2:
        raise CalibrationFileError(f"{where}.items must list two placements or more")
    reference = data["reference"]
    if not is_json_int(reference) or not 0 <= reference < len(items):
        raise CalibrationFileError(f"{where}.reference must be a placement's index")
    names, partial, poses, counts = [], [], [], []
    for k, item in enumerate(items):
        at = f"{where}.items[{k}]"
        if not isinstance(item, dict) or set(item) != set(ITEM_FIELDS):
            raise CalibrationFileError(f"{at} must have the fields {', '.join(ITEM_FIELDS)}")
        if not isinstance(item["name"], str) or not isinstance(item["partial"], bool):
            raise CalibrationFileError(f"{at}: name must be a string, partial true or false")
        if image_size is None or item["image_size_px"] != list(image_size):
            raise CalibrationFileError(
                f"{at}.image_size_px {item['image_size_px']!r} is not the calibration's "
                f"image size {None if image_size is None else list(image_size)}"
            )
        pose = [item["angle_rad"], *_pair(item["offset_mm"], f"{at}.offset_mm")]
        if not all(is_json_real(v) for v in pose):
            raise CalibrationFileError(f"{at}: angle_rad and offset_mm must be finite numbers")
        if not is_json_int(item["points"]) or not 1 <= item["points"] <= board.n_points:
            raise CalibrationFileError(
                f"{at}.points must be a count of points, 1 to the board's {board.n_points}"
            )
        names.append(item["name"])
        partial.append(item["partial"])
        poses.append([float(v) for v in pose])
        counts.append(int(item["points"]))
    placement = data["point_placement"]
    if (
        not isinstance(placement, list)
        or len(placement) != n_points
        or not all(is_json_int(k) and 0 <= k < len(items) for k in placement)
    ):
        raise CalibrationFileError(
            f"{where}.point_placement must give each of the {n_points} points its placement "
            f"(0 to {len(items) - 1})"
        )
    placed = np.asarray(placement, np.intp)
    seen = np.bincount(placed, minlength=len(items))
    if seen.tolist() != counts:
        raise CalibrationFileError(
            f"{where}: the placements' point counts {counts} are not point_placement's "
            f"{seen.tolist()}"
        )
    n_board = board.n_points
    if (
        not isinstance(ids, list)
        or len(ids) != n_points
        or not all(is_json_int(i) and 0 <= i < n_board for i in ids)
    ):
        raise CalibrationFileError(
            f"{source}: points.ids must give each of the {n_points} points its board id (0 to "
            f"{n_board - 1})"
        )
    return StoredPlacements(
        int(reference),
        tuple(names),
        tuple(partial),
        np.asarray(poses, np.float64),
        placed,
        np.asarray(ids, np.intp),
    )


def _pair(value: Any, where: str) -> list[Any]:
    if not isinstance(value, list) or len(value) != 2:
        raise CalibrationFileError(f"{where} must be two numbers")
    return value
