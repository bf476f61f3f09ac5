"""planarcal: camera pixels to millimetres on a work plane.

A Rust core (homography solvers, refinement, batch transforms) with two Python faces:

* the native API: ``estimate_homography``, ``transform_points``, ``reprojection_errors``,
  ``reprojection_stats``, raising ``HomographyError`` / ``DegenerateError`` /
  ``PointAtInfinityError`` (all ``ValueError``) with messages that name the problem;
* drop-ins for OpenCV: ``findHomography`` and ``perspectiveTransform`` with cv2's signatures,
  shapes, dtypes and method constants, computed in float64.
"""

import os as _os

from planarcal import _core
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
