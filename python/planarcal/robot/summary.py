"""A registration in words: the transform, the residual table, point by point, and the fit's
quality with what a user should do when it is poor (touch again, add points, check the
pairing).

The quality is judged on two figures, the worse deciding: the leave-one-out RMS (how well the
touches agree with each other) and the map's own 1-sigma at the worst corner of the area it
serves, the board (how well their layout fixes the map where the parts will be: touches in a
cluster or along one edge fit each other well and still turn the map at the far corner).

The registration is anything with a fitted map's figures (``Registration``, which
planarcal.robot.RobotFrame has): this module reads them and imports no registration, so
``RobotFrame.summary`` describes itself through it without a loop of imports."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


class PlaneHeightFigures(Protocol):
    """What the headline reads of the plane's height and tilt (planarcal.robot.PlaneHeight)."""

    @property
    def height_mm(self) -> float: ...

    @property
    def tilt_deg(self) -> float: ...

    @property
    def tilt_mm(self) -> float: ...


class Registration(Protocol):
    """What the summary reads of a registration (planarcal.robot.RobotFrame has it all)."""

    @property
    def model(self) -> str: ...

    @property
    def reflected(self) -> bool: ...

    @property
    def handedness(self) -> str | None: ...

    @property
    def plane_to_robot(self) -> F64: ...

    @property
    def rotation_deg(self) -> float | None: ...

    @property
    def scale(self) -> float | None: ...

    @property
    def plane_mm(self) -> F64: ...

    @property
    def robot_mm(self) -> F64: ...

    @property
    def residuals_mm(self) -> F64: ...

    @property
    def leave_one_out_mm(self) -> F64: ...

    @property
    def rms_mm(self) -> float: ...

    @property
    def max_mm(self) -> float: ...

    @property
    def leave_one_out_rms_mm(self) -> float: ...

    @property
    def outliers(self) -> tuple[int, ...]: ...

    @property
    def dropped_outliers(self) -> bool: ...

    @property
    def outlier_threshold_mm(self) -> float: ...

    @property
    def plane(self) -> PlaneHeightFigures | None: ...

    @property
    def warnings(self) -> tuple[str, ...]: ...

    @property
    def dots(self) -> tuple[int, ...] | None: ...

    @property
    def point_name(self) -> str: ...

    @property
    def work_area_mm(self) -> F64 | None: ...

    @property
    def used(self) -> NDArray[np.bool_]: ...

    @property
    def noise_mm(self) -> float: ...

    @property
    def corner_std_mm(self) -> float: ...

    def std_mm(self, points_mm: Any) -> F64: ...

    def pair_name(self, index: int) -> str: ...


# Leave-one-out RMS (mm) up to which a registration is called excellent, good, usable.
EXCELLENT_MM = 0.1
GOOD_MM = 0.3
USABLE_MM = 1.0
# A similarity's scale further than this from 1 says the two millimetres disagree.
SCALE_WARNING = 0.005


def judged_mm(frame: Registration) -> float:
    """The figure the quality is read from (mm): the larger of the leave-one-out RMS and the
    map's own 1-sigma at the worst corner of the area it serves (``corner_std_mm``)."""
    return max(frame.leave_one_out_rms_mm, frame.corner_std_mm)


def quality(frame: Registration) -> str:
    """The fit in a word, by ``judged_mm``: "excellent", "good", "usable", "poor", or
    "unchecked" (too few points for a leave-one-out error)."""
    judged = judged_mm(frame)
    if not math.isfinite(frame.leave_one_out_rms_mm):
        return "unchecked"
    if judged <= EXCELLENT_MM:
        return "excellent"
    if judged <= GOOD_MM:
        return "good"
    return "usable" if judged <= USABLE_MM else "poor"


def registration_summary(frame: Registration, lines: Sequence[int] | None = None) -> str:
    """The transform, the residual table (with each pair's file line, if given) and the
    quality in words."""
    lines_out = [_headline(frame), _transform(frame), "", *_table(frame, lines), ""]
    lines_out += [*_verdict(frame)]
    lines_out += [f"warning: {w}" for w in frame.warnings]
    return "\n".join(lines_out)


def _headline(frame: Registration) -> str:
    used = int(frame.used.sum())
    parts = [f"{frame.model} registration from {used} of {len(frame.plane_mm)} point pairs"]
    source = "as given" if frame.handedness is not None else "from the touches"
    parts.append(
        f"mirrored (board and robot frames of opposite handedness, {source})"
        if frame.reflected
        else f"not mirrored ({source})"
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


def _transform(frame: Registration) -> str:
    """The fitted map in numbers: robot = linear x board + translation."""
    tx, ty = frame.plane_to_robot[:2, 2]
    translation = f"translation ({tx:.3f}, {ty:.3f}) mm"
    if frame.rotation_deg is None or frame.scale is None:
        (a, b), (c, d) = frame.plane_to_robot[:2, :2]
        return f"robot = A board + t: A = [[{a:.6f}, {b:.6f}], [{c:.6f}, {d:.6f}]], {translation}"
    mirror = "the board's y axis mirrored, then " if frame.reflected else ""
    return (
        f"robot = scale x rotation x board + t: {mirror}rotation {frame.rotation_deg:.3f} deg, "
        f"scale {frame.scale:.6f}, {translation}; the robot frame {_hand(frame)}"
    )


def _hand(frame: Registration) -> str:
    # A board seen from the front has y clockwise from x: a mirrored map is a robot frame
    # that is right-handed with z up.
    return "right-handed (z up)" if frame.reflected else "left-handed (z up)"


def _table(frame: Registration, lines: Sequence[int] | None) -> list[str]:
    name_column = frame.point_name if frame.dots is not None else "touch"
    width = max(5, len(name_column))  # "corner" is a letter wider than the numbers
    line_head = "" if lines is None else f" {'line':>5}"
    rows = [
        f"{name_column:>{width}}{line_head} {'board x':>9} {'board y':>9} {'robot x':>9} "
        f"{'robot y':>9} {'resid mm':>9} {'l-o-o mm':>9}"
    ]
    outliers = set(frame.outliers)
    for i, ((bx, by), (rx, ry), r, loo) in enumerate(
        zip(frame.plane_mm, frame.robot_mm, frame.residuals_mm, frame.leave_one_out_mm, strict=True)
    ):
        mark = ""
        if i in outliers:
            mark = "  outlier (dropped)" if frame.dropped_outliers else "  outlier"
        loo_text = f"{loo:9.3f}" if math.isfinite(loo) else f"{'-':>9}"
        label = frame.dots[i] if frame.dots is not None else i
        line = "" if lines is None else f" {lines[i]:5d}"
        rows.append(
            f"{label:{width}d}{line} {bx:9.2f} {by:9.2f} {rx:9.2f} {ry:9.2f} {r:9.3f} "
            f"{loo_text}{mark}"
        )
    rows.append(
        f"RMS {frame.rms_mm:.3f} mm, max {frame.max_mm:.3f} mm, "
        f"leave-one-out RMS {frame.leave_one_out_rms_mm:.3f} mm"
    )
    # The map's own error where it is best known, at the edge of what was touched and at the
    # corners of the area it serves: what it adds to every position's 1-sigma there.
    used = frame.plane_mm[frame.used]
    own = frame.std_mm(used)
    centre = float(frame.std_mm(used.mean(axis=0)))
    area = "the board's corners" if frame.work_area_mm is not None else "the touched area's corners"
    rows.append(
        f"The map's own 1-sigma: {centre:.3f} mm at the touched points' centre, up to "
        f"{float(own.max()):.3f} mm at the touched points and {frame.corner_std_mm:.3f} mm at "
        f"{area} (touch noise {frame.noise_mm:.3f} mm per axis)"
    )
    return rows


def _verdict(frame: Registration) -> list[str]:
    out: list[str] = []
    if frame.outliers:
        names = ", ".join(frame.pair_name(i) for i in frame.outliers)
        action = (
            "left out of the fit"
            if frame.dropped_outliers
            else "kept in the fit (--drop-outliers, or drop_outliers=True, leaves them out)"
        )
        out.append(
            f"Outlier(s) {names}: leave-one-out error above {frame.outlier_threshold_mm:.3g} "
            f"mm, a touch on the wrong {frame.point_name} or a mistyped coordinate; {action}. "
            "Touch them again."
        )
    out.append(_rating(frame))
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


def _rating(frame: Registration) -> str:
    """The quality in a sentence: the figure that decided it and what to do about it."""
    loo, corner = frame.leave_one_out_rms_mm, frame.corner_std_mm
    if not math.isfinite(loo):
        return "Too few points for a leave-one-out check: add touch points across the board."
    word = quality(frame)
    figures = f"{loo:.3f} mm leave-one-out RMS, {corner:.3f} mm 1-sigma at the " + (
        "board's corners" if frame.work_area_mm is not None else "touched area's corners"
    )
    if corner > loo and word != "excellent":
        return (
            f"{word.capitalize()}: {figures}. The touches fix the map poorly away from them: "
            f"touch {frame.point_name}s nearer the board's corners, spread over the board."
        )
    if word == "excellent":
        return f"Excellent: {figures}, about a robot's repeatability."
    if word == "good":
        return f"Good: {figures}."
    if word == "usable":
        return (
            f"Usable but coarse: {figures}. Check the tool centre point, touch each "
            f"{_touch_spot(frame.point_name)}, and add points spread across the board."
        )
    return (
        f"Poor: {figures}. Check that each robot point pairs with its {frame.point_name} (the "
        "order, the board's origin), that both are in mm, and the tool centre point; then "
        "touch again."
    )


def _touch_spot(point_name: str) -> str:
    """Where on a board point the tool must touch: a dot's centre, a corner's crossing."""
    if point_name == "corner":
        return "corner exactly where its squares meet"
    return f"{point_name} at its centre"
