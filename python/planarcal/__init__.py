"""planarcal: camera pixels to millimetres on a work plane.

The pipeline: print a ``CircleGridBoard`` (``planarcal board``), take a picture of it
(``Camera``), find it (``detect_board``), calibrate (``Calibration``: the plane's homography,
its lens model chosen by leave-one-out, its uncertainty and its report, saved as JSON), then
locate objects in millimetres (``locate_objects``). ``calibrate_camera`` estimates full camera
intrinsics from several board views, for objects of known height above the plane.
``RobotFrame`` registers the plane to a robot's base frame from touch points.
``planarcal.synth`` renders scenes with exact truth to test a setup.

Underneath, a Rust core (homography solvers, refinement, batch transforms) with two faces:

* the native API: ``estimate_homography``, ``estimate_homography_robust`` (outliers),
  ``transform_points``, ``reprojection_errors``,
  ``reprojection_stats``, raising ``ArgumentError`` (bad input) or ``HomographyError`` /
  ``DegenerateError`` / ``PointAtInfinityError`` (no homography), all ``ValueError``, with
  messages and attributes (``index``, ``point_set``) that name the problem;
* drop-ins for OpenCV: ``findHomography`` and ``perspectiveTransform`` with cv2's signatures,
  shapes, dtypes and method constants, computed in float64.

Every exception planarcal raises derives from ``planarcal.Error`` (see ``planarcal.errors``).
"""

import importlib as _importlib
import importlib.util as _importlib_util
import os as _os
from typing import TYPE_CHECKING

from planarcal import _core
from planarcal._core import __version__

# The names below are imported when first used (PEP 562): `import planarcal`, and so the
# command line's `--help`, stays free of numpy, OpenCV and SciPy until a name needs them.
# The static imports are for type checkers; _EXPORTS says where each name lives at run
# time (tests/test_lazy_exports.py keeps the two and __all__ the same).
if TYPE_CHECKING:
    from planarcal.calib.board import CircleGridBoard
    from planarcal.calib.board_copies import detect_board_copies
    from planarcal.calib.boards import Board
    from planarcal.calib.calibration import (
        Calibration,
        CalibrationSummary,
        LensCandidate,
        LensModel,
    )
    from planarcal.calib.charuco import CharucoBoard
    from planarcal.calib.chessboard import ChessboardBoard
    from planarcal.calib.detection import BoardDetection, detect_board
    from planarcal.camera import CameraIntrinsics, calibrate_camera
    from planarcal.errors import (
        ArgumentError,
        ArgumentTypeError,
        BoardError,
        BoardMismatchError,
        BoardNotFoundError,
        BoardTurnedError,
        BusyError,
        CalibrationFileError,
        CameraError,
        DegenerateError,
        Error,
        FrameSizeError,
        HomographyError,
        ImageError,
        IntrinsicsError,
        LensModelError,
        MissingDependencyError,
        NotFoundError,
        OpenCVCompatibleArgumentError,
        OpenCVCompatibleError,
        OpenCVCompatiblePointAtInfinityError,
        OutputError,
        PlacementError,
        PointAtInfinityError,
        RegistrationError,
        StateError,
    )
    from planarcal.homography import (
        SOLVERS,
        ReprojectionStats,
        Solver,
        error_stats,
        estimate_homography,
        reprojection_errors,
        reprojection_stats,
        transform_points,
    )
    from planarcal.homography.opencv import (
        LMEDS,
        RANSAC,
        RHO,
        USAC_ACCURATE,
        USAC_DEFAULT,
        USAC_FAST,
        USAC_FM_8PTS,
        USAC_MAGSAC,
        USAC_PARALLEL,
        USAC_PROSAC,
        findHomography,
        perspectiveTransform,
    )
    from planarcal.homography.robust import (
        RobustMethod,
        RobustResult,
        StopReason,
        estimate_homography_robust,
        estimate_homography_robust_batch,
    )
    from planarcal.images import load_image
    from planarcal.live.capture import Camera
    from planarcal.live.objects import DetectedObject, detect_objects, locate_objects
    from planarcal.live.tracker import FrameResult, TrackedObject, Tracker
    from planarcal.robot import RobotFrame

_EXPORTS: dict[str, tuple[str, ...]] = {
    "planarcal.calib.board": ("CircleGridBoard",),
    "planarcal.calib.board_copies": ("detect_board_copies",),
    "planarcal.calib.boards": ("Board",),
    "planarcal.calib.charuco": ("CharucoBoard",),
    "planarcal.calib.chessboard": ("ChessboardBoard",),
    "planarcal.calib.calibration": (
        "Calibration",
        "CalibrationSummary",
        "LensCandidate",
        "LensModel",
    ),
    "planarcal.calib.detection": ("BoardDetection", "detect_board"),
    "planarcal.camera": ("CameraIntrinsics", "calibrate_camera"),
    "planarcal.errors": (
        "ArgumentError",
        "ArgumentTypeError",
        "BoardError",
        "BoardMismatchError",
        "BoardNotFoundError",
        "BoardTurnedError",
        "BusyError",
        "CalibrationFileError",
        "CameraError",
        "DegenerateError",
        "Error",
        "FrameSizeError",
        "HomographyError",
        "ImageError",
        "IntrinsicsError",
        "LensModelError",
        "MissingDependencyError",
        "NotFoundError",
        "OpenCVCompatibleArgumentError",
        "OpenCVCompatibleError",
        "OpenCVCompatiblePointAtInfinityError",
        "OutputError",
        "PlacementError",
        "PointAtInfinityError",
        "RegistrationError",
        "StateError",
    ),
    "planarcal.homography": (
        "SOLVERS",
        "ReprojectionStats",
        "Solver",
        "error_stats",
        "estimate_homography",
        "reprojection_errors",
        "reprojection_stats",
        "transform_points",
    ),
    "planarcal.homography.opencv": (
        "LMEDS",
        "RANSAC",
        "RHO",
        "USAC_ACCURATE",
        "USAC_DEFAULT",
        "USAC_FAST",
        "USAC_FM_8PTS",
        "USAC_MAGSAC",
        "USAC_PARALLEL",
        "USAC_PROSAC",
        "findHomography",
        "perspectiveTransform",
    ),
    "planarcal.homography.robust": (
        "RobustMethod",
        "RobustResult",
        "StopReason",
        "estimate_homography_robust",
        "estimate_homography_robust_batch",
    ),
    "planarcal.images": ("load_image",),
    "planarcal.live.capture": ("Camera",),
    "planarcal.live.objects": ("DetectedObject", "detect_objects", "locate_objects"),
    "planarcal.live.tracker": ("FrameResult", "TrackedObject", "Tracker"),
    "planarcal.robot": ("RobotFrame",),
}
_MODULE_OF = {name: module for module, names in _EXPORTS.items() for name in names}


def __getattr__(name: str) -> object:
    """A public name, imported from its module on first use (then kept in the package);
    otherwise a subpackage or module of planarcal not yet imported (``planarcal.synth``)."""
    module = _MODULE_OF.get(name)
    if module is not None:
        value = getattr(_importlib.import_module(module), name)
        globals()[name] = value
        return value
    if not name.startswith("_") and _importlib_util.find_spec(f"{__name__}.{name}") is not None:
        return _importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


# A child forked after the thread pool started must not use it (its threads did not survive
# the fork): the core then runs every batch on the calling thread.
if hasattr(_os, "register_at_fork"):
    _os.register_at_fork(after_in_child=_core._after_fork_in_child)

__all__ = [
    "LMEDS",
    "RANSAC",
    "RHO",
    "SOLVERS",
    "USAC_ACCURATE",
    "USAC_DEFAULT",
    "USAC_FAST",
    "USAC_FM_8PTS",
    "USAC_MAGSAC",
    "USAC_PARALLEL",
    "USAC_PROSAC",
    "ArgumentError",
    "ArgumentTypeError",
    "Board",
    "BoardDetection",
    "BoardError",
    "BoardMismatchError",
    "BoardNotFoundError",
    "BoardTurnedError",
    "BusyError",
    "Calibration",
    "CalibrationFileError",
    "CalibrationSummary",
    "Camera",
    "CameraError",
    "CameraIntrinsics",
    "CharucoBoard",
    "ChessboardBoard",
    "CircleGridBoard",
    "DegenerateError",
    "DetectedObject",
    "Error",
    "FrameResult",
    "FrameSizeError",
    "HomographyError",
    "ImageError",
    "IntrinsicsError",
    "LensCandidate",
    "LensModel",
    "LensModelError",
    "MissingDependencyError",
    "NotFoundError",
    "OpenCVCompatibleArgumentError",
    "OpenCVCompatibleError",
    "OpenCVCompatiblePointAtInfinityError",
    "OutputError",
    "PlacementError",
    "PointAtInfinityError",
    "RegistrationError",
    "ReprojectionStats",
    "RobotFrame",
    "RobustMethod",
    "RobustResult",
    "Solver",
    "StateError",
    "StopReason",
    "TrackedObject",
    "Tracker",
    "__version__",
    "calibrate_camera",
    "detect_board",
    "detect_board_copies",
    "detect_objects",
    "error_stats",
    "estimate_homography",
    "estimate_homography_robust",
    "estimate_homography_robust_batch",
    "findHomography",
    "load_image",
    "locate_objects",
    "perspectiveTransform",
    "reprojection_errors",
    "reprojection_stats",
    "transform_points",
]
