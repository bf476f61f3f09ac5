"""The robot's frame: the calibrated plane (board mm) registered to a robot's base frame
(robot mm) from touch points.

``registration`` holds ``RobotFrame`` (the fit and what it reports), ``transform_fit`` the
closed-form rigid, similarity and affine fits and the checks that refuse too few or too
clustered points, ``outliers`` the leave-one-out errors and the touches they name,
``plane_height`` the plane's height and tilt from the robot's z, ``summary`` the fit in words.
"""

from planarcal.robot.plane_height import TILT_WARNING_MM, PlaneHeight
from planarcal.robot.registration import RobotFrame
from planarcal.robot.transform_fit import MINIMAL_POINTS, MODELS, Model

__all__ = [
    "MINIMAL_POINTS",
    "MODELS",
    "TILT_WARNING_MM",
    "Model",
    "PlaneHeight",
    "RobotFrame",
]
