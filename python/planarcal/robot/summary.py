"""A registration in words: the residual table, point by point, and the fit's quality with
what a user should do when it is poor (touch again, add points, check the pairing)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    # Only a type here: registration imports this module to describe itself.
    from planarcal.robot.registration import RobotFrame

# Leave-one-out RMS (mm) up to which a registration is called excellent, good, usable.
EXCELLENT_MM = 0.1
GOOD_MM = 0.3
USABLE_MM = 1.0
# A similarity's scale further than this from 1 says the two millimetres disagree.
SCALE_WARNING = 0.005


def quality(frame: RobotFrame) -> str:
    """The fit in a word, by its leave-one-out RMS: "excellent", "good", "usable", "poor", or
    "unchecked" (too few points for a leave-one-out error)."""
    loo = frame.leave_one_out_rms_mm
    if not math.isfinite(loo):
        return "unchecked"
    if loo <= EXCELLENT_MM:
        return "excellent"
    if loo <= GOOD_MM:
        return "good"
    return "usable" if loo <= USABLE_MM else "poor"


def registration_summary(frame: RobotFrame) -> str:
    """The residual table and the quality in words."""
    lines = [_headline(frame), "", *_table(frame), "", *_verdict(frame)]
    lines += [f"warning: {w}" for w in frame.warnings]
    return "\n".join(lines)


def _headline(frame: RobotFrame) -> str:
    used = int(frame.used.sum())
    parts = [f"{frame.model} registration from {used} of {len(frame.plane_mm)} point pairs"]
    parts.append(
        "mirrored (board and robot frames of opposite handedness)"
        if frame.reflected
        else "not mirrored"
    )
    if frame.rotation_deg is not None:
        parts.append(f"rotation {frame.rotation_deg:.3f} deg")
    if frame.model == "similarity" and frame.scale is not None:
        parts.append(f"scale {frame.scale:.6f}")
    if frame.plane is not None:
        parts.append(
            f"plane at z = {frame.plane.height_mm:.3f} mm, tilted {frame.plane.tilt_deg:.3f} deg "
            f"({frame.plane.tilt_mm:.3f} mm across the points)"
        )
    return "; ".join(parts)


def _table(frame: RobotFrame) -> list[str]:
    rows = [
        f"{'point':>5} {'board x':>9} {'board y':>9} {'robot x':>9} {'robot y':>9} "
        f"{'resid mm':>9} {'l-o-o mm':>9}"
    ]
    outliers = set(frame.outliers)
    for i, ((bx, by), (rx, ry), r, loo) in enumerate(
        zip(frame.plane_mm, frame.robot_mm, frame.residuals_mm, frame.leave_one_out_mm, strict=True)
    ):
        mark = ""
        if i in outliers:
            mark = "  outlier (dropped)" if frame.dropped_outliers else "  outlier"
        loo_text = f"{loo:9.3f}" if math.isfinite(loo) else f"{'-':>9}"
        rows.append(f"{i:5d} {bx:9.2f} {by:9.2f} {rx:9.2f} {ry:9.2f} {r:9.3f} {loo_text}{mark}")
    rows.append(
        f"RMS {frame.rms_mm:.3f} mm, max {frame.max_mm:.3f} mm, "
        f"leave-one-out RMS {frame.leave_one_out_rms_mm:.3f} mm"
    )
    # The map's own error where it is best known and at the edge of what was touched: what
    # it adds to every position's 1-sigma in the robot frame.
    used = frame.plane_mm[frame.used]
    own = frame.std_mm(used)
    centre = float(frame.std_mm(used.mean(axis=0)))
    rows.append(
        f"The map's own 1-sigma: {centre:.3f} mm at the touched points' centre, up to "
        f"{float(own.max()):.3f} mm at the touched points (touch noise "
        f"{frame.noise_mm:.3f} mm per axis); it grows beyond them"
    )
    return rows


def _verdict(frame: RobotFrame) -> list[str]:
    out: list[str] = []
    if frame.outliers:
        names = ", ".join(str(i) for i in frame.outliers)
        action = (
            "left out of the fit"
            if frame.dropped_outliers
            else "kept in the fit (--drop-outliers, or drop_outliers=True, leaves them out)"
        )
        out.append(
            f"Point(s) {names}: leave-one-out error above {frame.outlier_threshold_mm:.3g} mm, "
            f"a touch on the wrong dot or a mistyped coordinate; {action}. Touch them again."
        )
    loo = frame.leave_one_out_rms_mm
    if not math.isfinite(loo):
        out.append("Too few points for a leave-one-out check: add touch points across the board.")
    elif loo <= EXCELLENT_MM:
        out.append(f"Excellent: {loo:.3f} mm leave-one-out RMS, about a robot's repeatability.")
    elif loo <= GOOD_MM:
        out.append(f"Good: {loo:.3f} mm leave-one-out RMS.")
    elif loo <= USABLE_MM:
        out.append(
            f"Usable but coarse: {loo:.3f} mm leave-one-out RMS. Check the tool centre point, "
            "touch each dot at its centre, and add points spread across the board."
        )
    else:
        out.append(
            f"Poor: {loo:.3f} mm leave-one-out RMS. Check that each robot point pairs with its "
            "dot (the order, the board's origin), that both are in mm, and the tool centre "
            "point; then touch again."
        )
    used = int(frame.used.sum())
    if used < 5:
        out.append(f"Only {used} points: 5 or more, spread across the board, show a bad touch.")
    if (
        frame.model == "similarity"
        and frame.scale is not None
        and abs(frame.scale - 1) > SCALE_WARNING
    ):
        out.append(
            f"The scale is {frame.scale:.4f}: the board's and the robot's millimetres differ "
            f"by {abs(frame.scale - 1) * 100:.2f} %. Check the printed board's scale."
        )
    return out
