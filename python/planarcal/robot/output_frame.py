"""The frame of reference positions are given in: "board" (the calibration board's mm, the
calibration's own world frame) or "robot" (the robot's base frame, through the calibration's
registration), and the mapping of board positions and their 1-sigma into the robot's.

Asking for "robot" from a calibration without a registration is an ArgumentError (a
ValueError): the call is well formed but the calibration given cannot answer it, the same
fault as a file that lacks what the call needs; it is reported by the command line in one
line like every other input error, which a StateError (a RuntimeError) would not be."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any, Literal, Protocol, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from planarcal.errors import ArgumentError
from planarcal.robot.registration import RobotFrame
from planarcal.robot.transform_fit import F64

Coords = Literal["board", "robot"]
FRAMES: tuple[Coords, ...] = ("board", "robot")


class Located(Protocol):
    """A located object (live.objects.DetectedObject): its board position and 1-sigma."""

    @property
    def world_mm(self) -> tuple[float, float] | None: ...

    @property
    def world_std_mm(self) -> float | None: ...


T = TypeVar("T", bound=Located)


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


def angle_to_robot(registration: RobotFrame, angle_deg: F64) -> F64:
    """Axis angles (degrees, from the board's x axis towards its y axis) as angles in the
    robot frame, in [-90, 90): each axis turned through the map's linear part (a mirror
    reverses the sense of the angle). Exact for rigid and similarity maps; for an affine one
    it is the board axis's image, which a shear turns slightly off the principal axis of the
    mapped area. NaN (no axis) stays NaN."""
    a = np.radians(np.asarray(angle_deg, dtype=np.float64))
    direction = np.stack([np.cos(a), np.sin(a)], axis=-1) @ registration.plane_to_robot[:2, :2].T
    turned = np.degrees(np.arctan2(direction[..., 1], direction[..., 0]))
    out: F64 = (turned + 90.0) % 180.0 - 90.0
    return out


def objects_in_frame(objects: Sequence[T], calibration: Any, frame: Coords) -> list[T]:
    """Located objects (``locate_objects``'s, in board mm) with their positions, 1-sigma and
    any axis angle (``angle_deg``) in ``frame`` (a checked Coords) of ``calibration``: the same
    as mapping their pixels with image_to_world(frame=frame)."""
    registration = calibration.robot_frame
    if frame == "board" or not objects:
        return list(objects)
    if registration is None:  # the caller checked the frame; this keeps mypy and readers sure
        checked_frame(frame, registration)
    board = np.array([o.world_mm for o in objects], dtype=np.float64)
    board_std = np.array([o.world_std_mm for o in objects], dtype=np.float64)
    robot, robot_std = board_to_robot(registration, board, board_std)
    assert robot_std is not None
    out = []
    for o, (x, y), s in zip(objects, robot.tolist(), robot_std.tolist(), strict=True):
        changes: dict[str, Any] = {"world_mm": (x, y), "world_std_mm": s}
        angle = getattr(o, "angle_deg", None)
        if angle is not None and math.isfinite(angle):
            changes["angle_deg"] = float(angle_to_robot(registration, np.array(angle)))
        out.append(dataclasses.replace(o, **changes))  # type: ignore[type-var]
    return out
