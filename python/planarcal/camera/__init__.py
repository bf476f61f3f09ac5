"""The camera itself: OpenCV intrinsics from several board views, their file formats, the
pose of the plane and heights above it. Separate from ``calib`` because a plane's
calibration needs none of it; only objects of known height do.

``intrinsics`` is the model (K and OpenCV's distortion), ``distortion`` the lens maths it
runs on, ``validation`` the checks of its fields, ``file_storage`` OpenCV's YAML/XML/JSON
files, ``calibrate`` the fit from board views and ``pose`` the plane's pose and heights.
"""

from planarcal.camera.calibrate import MAX_FOCAL_REL_STD, calibrate_camera
from planarcal.camera.distortion import DIST_COEFF_LENGTHS
from planarcal.camera.intrinsics import CameraIntrinsics
from planarcal.camera.pose import PlanePoseEstimate, plane_pose, points_at_height

__all__ = [
    "DIST_COEFF_LENGTHS",
    "MAX_FOCAL_REL_STD",
    "CameraIntrinsics",
    "PlanePoseEstimate",
    "calibrate_camera",
    "plane_pose",
    "points_at_height",
]
