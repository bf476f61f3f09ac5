"""The robot's frame: the calibrated plane (board mm) registered to a robot's base frame
(robot mm) from touch points.

``registration`` holds ``RobotFrame`` (the fit and what it reports), ``transform_fit`` the
closed-form rigid, similarity and affine fits and the checks that refuse too few or too
clustered points, ``handedness`` whether the touches fix the map's hand (touches on one line
do not) and the hand a user can state instead, ``outliers`` the leave-one-out errors (all at
once, in O(N)) and the touches they name (a bounded search),
``plane_height`` the plane's height and tilt from the robot's z, ``summary`` the fit in words,
``prediction_error`` the fitted map's own 1-sigma at any board point. Around the fit:
``touch_pairs`` turns point ids (dots, corners), board mm or N-point image px into board
points through a calibration, ``output_frame`` maps board positions (and their 1-sigma and
angles) into the robot's frame for ``Calibration.image_to_world(frame=...)``, the Tracker and
``locate``, ``touch_csv`` reads the touch-point CSV and ``register_command`` is ``planarcal
register``.
"""

from planarcal.robot.handedness import HANDEDNESS, Handedness
from planarcal.robot.plane_height import TILT_WARNING_MM, PlaneHeight
from planarcal.robot.registration import RobotFrame
from planarcal.robot.transform_fit import MINIMAL_POINTS, MODELS, Model

__all__ = [
    "HANDEDNESS",
    "MINIMAL_POINTS",
    "MODELS",
    "TILT_WARNING_MM",
    "Handedness",
    "Model",
    "PlaneHeight",
    "RobotFrame",
]
