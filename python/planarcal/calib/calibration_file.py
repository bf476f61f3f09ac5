"""The calibration file: the versioned JSON form of a Calibration (what ``to_dict`` writes and
``from_dict`` reads), which versions this planarcal reads, and the checks that turn a corrupt,
truncated or foreign file into a CalibrationFileError rather than a wrong calibration.

Version 3 adds ``robot_frame``: the registration to the robot (RobotFrame.to_dict: the model,
the point pairs, the residuals), or null; refitted from its pairs on load and refused if the
stored transform is not theirs. Versions 1 and 2 have none and load without one."""

from __future__ import annotations

import dataclasses
import datetime
import json
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from planarcal import _core
from planarcal._core import RadialLens
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.json_number import json_number
from planarcal.calib.lens_choice import LensCandidate
from planarcal.calib.lens_model import LENS_MODELS
from planarcal.calib.plane_fit import PlaneFit, plane_at
from planarcal.camera import CameraIntrinsics
from planarcal.errors import (
    ArgumentError,
    BoardError,
    CalibrationFileError,
    HomographyError,
    IntrinsicsError,
    LensModelError,
)
from planarcal.files import atomic_write
from planarcal.homography import SOLVERS, Solver
from planarcal.robot.registration import RobotFrame

if TYPE_CHECKING:
    # Only a type here: calibration imports this module to read and write itself.
    from planarcal.calib.calibration import Calibration

F64 = NDArray[np.float64]

FILE_FORMAT = "planarcal-calibration"
FILE_VERSION = 3
READS_VERSIONS = (1, 2, 3)


@dataclasses.dataclass(frozen=True)
class FileContents:
    """A calibration file's contents, checked: what Calibration is built from."""

    world: F64
    image: F64
    fit: PlaneFit
    solver: Solver
    refine: bool
    board: CircleGridBoard | None
    image_size: tuple[int, int] | None
    intrinsics: CameraIntrinsics | None
    world_scale: tuple[float, float]
    robot_frame: RobotFrame | None = None


def calibration_to_dict(cal: Calibration) -> dict[str, Any]:
    """The versioned, JSON-ready form of `cal` (Calibration.to_dict)."""
    summary = cal.summary().to_dict()
    return {
        "format": FILE_FORMAT,
        "version": FILE_VERSION,
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "planarcal_version": _core.__version__,
        "solver": cal.solver,
        "refine": cal.refine,
        "homography_world_mm_to_image_px": cal.H.tolist(),
        "lens_model": cal.lens_model,
        "lens": None if cal.lens is None else cal.lens.to_dict(),
        "lens_note": cal.lens_note,
        "lens_candidates": [c.to_dict() for c in cal.lens_candidates],
        "intrinsics": None if cal.intrinsics is None else cal.intrinsics.to_dict(),
        "world_scale": list(cal.world_scale),
        "image_size_px": None if cal.image_size is None else list(cal.image_size),
        "board": None if cal.board is None else cal.board.to_dict(),
        "points": {
            "world_mm": cal.world_points.tolist(),
            "image_px": cal.image_points.tolist(),
        },
        "summary": {k: json_number(v) for k, v in summary.items()},
        "robot_frame": None if cal.robot_frame is None else cal.robot_frame.to_dict(),
    }


def contents_from_dict(data: Any, source: str) -> FileContents:
    """The calibration a file's parsed JSON holds; CalibrationFileError if it is not one
    (`source` names it in the messages)."""
    if not isinstance(data, dict):
        raise CalibrationFileError(f"{source} is not a calibration (not a JSON object)")
    if data.get("format") != FILE_FORMAT:
        raise CalibrationFileError(
            f"{source} is not a planarcal calibration (format {data.get('format')!r})"
        )
    version = data.get("version")
    if version not in READS_VERSIONS or isinstance(version, bool):
        raise CalibrationFileError(
            f"{source} is calibration file version {version!r}; this planarcal "
            f"({_core.__version__}) reads versions "
            f"{', '.join(str(v) for v in READS_VERSIONS)}"
        )
    try:
        h = np.array(data["homography_world_mm_to_image_px"], dtype=np.float64)
        world = np.array(data["points"]["world_mm"], dtype=np.float64)
        image = np.array(data["points"]["image_px"], dtype=np.float64)
        solver = data["solver"]
        refine = data["refine"]
        size = data.get("image_size_px")
        board_data = data.get("board")
    except (KeyError, TypeError, ValueError) as e:
        raise CalibrationFileError(f"{source} is missing or mangles a field: {e!r}") from None
    if h.shape != (3, 3) or not np.isfinite(h).all():
        raise CalibrationFileError(f"{source}: the homography is not a finite 3 x 3 matrix")
    if abs(np.linalg.det(h)) == 0:
        raise CalibrationFileError(f"{source}: the homography is singular")
    for name, pts in (("world_mm", world), ("image_px", image)):
        if pts.ndim != 2 or pts.shape[1:] != (2,) or not np.isfinite(pts).all():
            raise CalibrationFileError(f"{source}: points.{name} is not a list of (x, y)")
    if len(world) != len(image) or len(world) < 4:
        raise CalibrationFileError(
            f"{source}: {len(world)} world and {len(image)} image points (need 4 or more, "
            "as many of each)"
        )
    if solver not in SOLVERS or not isinstance(refine, bool):
        raise CalibrationFileError(f"{source}: unknown solver {solver!r} / refine {refine!r}")
    try:
        board = None if board_data is None else CircleGridBoard.from_dict(board_data)
    except BoardError as e:
        raise CalibrationFileError(f"{source}: {e}") from None
    if size is not None and (
        not isinstance(size, list) or len(size) != 2 or not all(isinstance(v, int) for v in size)
    ):
        raise CalibrationFileError(f"{source}: image_size_px must be [width, height]")
    image_size = None if size is None else (size[0], size[1])
    fit, intrinsics, world_scale = _fit_from_dict(data, h, world, image, image_size, source)
    robot_data = data.get("robot_frame")
    robot_frame = (
        None
        if robot_data is None
        else RobotFrame.from_dict(robot_data, f"{source}: its registration to the robot")
    )
    return FileContents(
        world, image, fit, solver, refine, board, image_size, intrinsics, world_scale, robot_frame
    )


def write_file(path: str | os.PathLike[str], data: dict[str, Any]) -> Path:
    """Writes `data` (calibration_to_dict's) as human-readable JSON, atomically."""
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    return atomic_write(path, text)


def read_file(path: str | os.PathLike[str]) -> Any:
    """The parsed JSON of the file at `path`; CalibrationFileError if it cannot be read or is not
    JSON."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CalibrationFileError(f"no calibration file at {str(p)!r}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise CalibrationFileError(f"cannot read {str(p)!r}: {e}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise CalibrationFileError(
            f"{str(p)!r} is not valid JSON (corrupt or truncated?): {e}"
        ) from None
    return data


def _fit_from_dict(
    data: dict[str, Any],
    h: F64,
    world: F64,
    image: F64,
    size: tuple[int, int] | None,
    source: str,
) -> tuple[PlaneFit, CameraIntrinsics | None, tuple[float, float]]:
    """The fit a file describes, checked against its points; CalibrationFileError if not."""
    lens = data.get("lens_model", "none")
    lens_data = data.get("lens")
    intr_data = data.get("intrinsics")
    scale = data.get("world_scale", [1.0, 1.0])
    note = data.get("lens_note", "no lens model")
    cand_data = data.get("lens_candidates", [])
    try:
        world_scale = (float(scale[0]), float(scale[1]))
        if len(scale) != 2 or not all(math.isfinite(v) and v > 0 for v in world_scale):
            raise ValueError(scale)
        candidates = [
            LensCandidate(
                str(c["model"]),
                math.nan if c["loo_mean_px"] is None else float(c["loo_mean_px"]),
                math.nan if c["sigma_px"] is None else float(c["sigma_px"]),
                str(c["verdict"]),
            )
            for c in cand_data
        ]
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise CalibrationFileError(f"{source}: bad world_scale or lens_candidates: {e!r}") from None
    intrinsics = None
    radial = None  # a lens model's own
    try:
        if lens == "intrinsics":
            intrinsics = CameraIntrinsics.from_dict(intr_data)
        elif lens in LENS_MODELS[1:]:
            if size is None or not isinstance(lens_data, dict):
                raise CalibrationFileError(
                    f"{source}: lens model {lens!r} without its parameters or the image size"
                )
            cx, cy = (float(v) for v in lens_data["centre_px"])
            radial = RadialLens(
                (cx, cy),
                float(lens_data["scale_px"]),
                float(lens_data["k1"]),
                float(lens_data["k2"]),
            )
        elif lens != "none":
            raise CalibrationFileError(f"{source}: unknown lens model {lens!r}")
        plane = plane_at(h, world, image, size, str(lens), radial, intrinsics)
    except (ArgumentError, IntrinsicsError, LensModelError, HomographyError) as e:
        raise CalibrationFileError(f"{source}: {e}") from None
    except (KeyError, TypeError, ValueError) as e:
        raise CalibrationFileError(
            f"{source}: the lens is missing or mangles a field: {e!r}"
        ) from None
    return PlaneFit(plane, h, str(lens), candidates, str(note)), intrinsics, world_scale
