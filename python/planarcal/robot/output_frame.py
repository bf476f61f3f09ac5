"""The frame of reference positions are given in: "board" (the calibration board's mm, the
calibration's own world frame) or "robot" (the robot's base frame, through the calibration's
registration), and the mapping of board positions and their 1-sigma into the robot's.

Asking for "robot" from a calibration without a registration is an ArgumentError (a
ValueError): the call is well formed but the calibration given cannot answer it, the same
fault as a file that lacks what the call needs; it is reported by the command line in one
line like every other input error, which a StateError (a RuntimeError) would not be."""

from __future__ import annotations

from typing import Literal

from numpy.typing import ArrayLike

from planarcal.errors import ArgumentError
from planarcal.robot.registration import RobotFrame
from planarcal.robot.transform_fit import F64

Coords = Literal["board", "robot"]
FRAMES: tuple[Coords, ...] = ("board", "robot")


def default_frame(registration: RobotFrame | None) -> Coords:
    """ "robot" where a registration exists, else "board"."""
    return "board" if registration is None else "robot"


def checked_frame(frame: object, registration: RobotFrame | None) -> Coords:
    """``frame`` as a Coords, or the default one for None; ArgumentError for another value,
    or for "robot" with no registration."""
    if frame is None:
        return default_frame(registration)
    if frame not in FRAMES:
        raise ArgumentError(f"frame must be 'board' or 'robot', got {frame!r}")
    if frame == "robot" and registration is None:
        raise ArgumentError(
            "frame='robot' needs a registration of the board to the robot, and this "
            "calibration has none: register it first (planarcal register --calibration ... "
            "--points touch.csv, or Calibration.register)"
        )
    return "robot" if frame == "robot" else "board"


def board_to_robot(
    registration: RobotFrame, board_mm: F64, board_std_mm: ArrayLike | None = None
) -> tuple[F64, F64 | None]:
    """Board positions (N, 2) as robot positions, with their robot-frame 1-sigma when the
    board's is given (RobotFrame.robot_std_mm)."""
    robot = registration.to_robot(board_mm)
    if board_std_mm is None:
        return robot, None
    return robot, registration.robot_std_mm(board_mm, board_std_mm)
