"""The work plane's height and tilt in the robot frame, from the z of the touch points: the
least-squares plane z = a x + b y + c through them, its height at their centroid, its tilt
and the height it changes by across them (a tilted board maps to the wrong place off its
touched height, and says the table or the fixture is not level)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from planarcal.robot.transform_fit import F64, width_ratio

# A height change across the touched points above which a registration warns (mm).
TILT_WARNING_MM = 0.5

# Robot points this thin across their line fix no tilt across it.
MIN_TILT_WIDTH_RATIO = 0.02


@dataclasses.dataclass(frozen=True)
class PlaneHeight:
    """The plane through the touch points in the robot frame: ``height_mm`` at the points'
    centroid, the slopes ``dz_dx`` and ``dz_dy`` (mm/mm), ``tilt_deg`` from level,
    ``tilt_mm`` the plane's height range over the points, ``rms_mm`` the points' RMS distance
    from it in z."""

    height_mm: float
    dz_dx: float
    dz_dy: float
    tilt_deg: float
    tilt_mm: float
    rms_mm: float

    def to_dict(self) -> dict[str, Any]:
        """The fields as a JSON-ready dict."""
        return dataclasses.asdict(self)


def fit_plane_height(robot_xy: F64, robot_z: F64) -> PlaneHeight | None:
    """The plane z = a x + b y + c through the points (robot mm), None where they lie too
    nearly on a line to fix its tilt."""
    if len(robot_xy) < 3 or width_ratio(robot_xy) < MIN_TILT_WIDTH_RATIO:
        return None
    centroid = robot_xy.mean(axis=0)
    design = np.c_[robot_xy - centroid, np.ones(len(robot_xy))]
    (a, b, c), *_ = np.linalg.lstsq(design, robot_z, rcond=None)
    on_plane = design @ np.array([a, b, c])
    return PlaneHeight(
        height_mm=float(c),
        dz_dx=float(a),
        dz_dy=float(b),
        tilt_deg=math.degrees(math.atan(math.hypot(a, b))),
        tilt_mm=float(on_plane.max() - on_plane.min()),
        rms_mm=float(np.sqrt(np.mean((robot_z - on_plane) ** 2))),
    )


def tilt_warnings(plane: PlaneHeight | None, z_given: bool) -> tuple[str, ...]:
    """The warnings a plane's height gives: a tilt over TILT_WARNING_MM across the points, or
    heights given on points that cannot show one."""
    if plane is None:
        if z_given:
            return (
                "z given, but the touch points lie (nearly) on a line: the plane's tilt is "
                "not measured; touch points spread in both directions",
            )
        return ()
    if plane.tilt_mm > TILT_WARNING_MM:
        return (
            f"the plane is tilted by {plane.tilt_deg:.2f} deg in the robot frame: its height "
            f"changes by {plane.tilt_mm:.2f} mm across the touch points (more than "
            f"{TILT_WARNING_MM:g} mm); level the board or the table, or expect errors off "
            "the touched height",
        )
    return ()
