"""planarcal: camera pixels to millimetres on a work plane.

A Rust core (homography solvers, refinement, batch transforms) with two Python faces:

* the native API: ``estimate_homography``, ``transform_points``, ``reprojection_errors``,
  ``reprojection_stats``, raising ``HomographyError`` / ``DegenerateError`` /
  ``PointAtInfinityError`` (all ``ValueError``) with messages that name the problem;
* drop-ins for OpenCV: ``findHomography`` and ``perspectiveTransform`` with cv2's signatures,
  shapes, dtypes and method constants, computed in float64.
"""

from planarcal._core import (
    DegenerateError,
    HomographyError,
    PointAtInfinityError,
    __version__,
)
from planarcal.cv import (
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
    "DegenerateError",
    "HomographyError",
    "PointAtInfinityError",
    "ReprojectionStats",
    "Solver",
    "__version__",
    "error_stats",
    "estimate_homography",
    "findHomography",
    "perspectiveTransform",
    "reprojection_errors",
    "reprojection_stats",
    "transform_points",
]
