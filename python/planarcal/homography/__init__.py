"""Homographies: the core's solvers and transforms with three faces.

``native`` is planarcal's own API (fit, map, measure), ``robust`` fits through outliers, and
``opencv`` holds the drop-ins for ``cv2.findHomography`` / ``cv2.perspectiveTransform``. They
are one subpackage because they are one idea, H, over one Rust core, with nothing of boards,
cameras or images in them.
"""

from planarcal.homography.native import (
    SOLVERS,
    ReprojectionStats,
    Solver,
    error_stats,
    estimate_homography,
    reprojection_errors,
    reprojection_stats,
    transform_points,
)
from planarcal.homography.opencv import findHomography, perspectiveTransform
from planarcal.homography.robust import (
    RobustResult,
    estimate_homography_robust,
    estimate_homography_robust_batch,
)

__all__ = [
    "SOLVERS",
    "ReprojectionStats",
    "RobustResult",
    "Solver",
    "error_stats",
    "estimate_homography",
    "estimate_homography_robust",
    "estimate_homography_robust_batch",
    "findHomography",
    "perspectiveTransform",
    "reprojection_errors",
    "reprojection_stats",
    "transform_points",
]
