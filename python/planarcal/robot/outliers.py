"""Leave-one-out errors of a registration and the touches that do not belong: each point's
error under the fit of the others, and the points named as outliers by that error.

A touch on the wrong dot pulls a least-squares fit towards itself, so its own residual
understates it; refitted without it, the others show how far off it is. The search removes
the worst point while its leave-one-out error exceeds the threshold and recomputes the others'
errors without it (a wrong touch also inflates its neighbours' errors), one point at a time,
so the result depends on nothing but the data. The default threshold is set by the others'
leave-one-out errors without the suspect, so a wrong touch cannot raise its own bar."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planarcal.errors import RegistrationError
from planarcal.robot.transform_fit import (
    F64,
    MIN_SPREAD_MM,
    MIN_WIDTH_RATIO,
    MINIMAL_POINTS,
    Model,
    apply,
    check_geometry,
    fit,
    fit_either_hand,
    spread_mm,
    width_ratio,
)

# The default threshold: this many times the median leave-one-out error, and never below
# OUTLIER_FLOOR_MM (exact data would otherwise call a rounding error an outlier).
OUTLIER_MEDIAN_FACTOR = 5.0
OUTLIER_FLOOR_MM = 1.0


def leave_one_out(plane_mm: F64, robot_mm: F64, model: Model, reflected: bool) -> F64:
    """Each point's error (mm) under the fit of the other points, with the handedness given;
    inf where the others alone are too clustered or collinear to fix the model."""
    n = len(plane_mm)
    out = np.empty(n)
    for i in range(n):
        keep = np.arange(n) != i
        p, q = plane_mm[keep], robot_mm[keep]
        if not _determined(p, q, model):
            out[i] = np.inf
            continue
        m = fit(p, q, model, reflected)
        out[i] = float(np.hypot(*(apply(m, plane_mm[i : i + 1])[0] - robot_mm[i])))
    return out


def default_threshold(errors_mm: F64) -> float:
    """max(OUTLIER_FLOOR_MM, OUTLIER_MEDIAN_FACTOR x the median finite leave-one-out error)."""
    finite = errors_mm[np.isfinite(errors_mm)]
    median = float(np.median(finite)) if finite.size else 0.0
    return max(OUTLIER_FLOOR_MM, OUTLIER_MEDIAN_FACTOR * median)


def find_outliers(
    plane_mm: F64, robot_mm: F64, model: Model, outlier_mm: float | None
) -> tuple[tuple[int, ...], float]:
    """The indices (ascending) of the points whose leave-one-out error exceeds the threshold,
    and the threshold (mm) the search ended on: ``outlier_mm``, or by default
    default_threshold of the other points' leave-one-out errors without the suspect (a wrong
    touch inflates the errors of the fits that include it, so its own presence must not set
    the bar). The worst point goes first; the search stops while the rest still fix the
    model with a residual."""

    def bar(keep: NDArray[np.intp]) -> float:
        if outlier_mm is not None:
            return outlier_mm
        p, q = plane_mm[keep], robot_mm[keep]
        _, reflected = fit_either_hand(p, q, model)
        return default_threshold(leave_one_out(p, q, model, reflected))

    active = np.arange(len(plane_mm))
    removed: list[int] = []
    threshold: float | None = None
    while len(active) > MINIMAL_POINTS[model] + 1:
        p, q = plane_mm[active], robot_mm[active]
        _, reflected = fit_either_hand(p, q, model)
        errors = leave_one_out(p, q, model, reflected)
        errors[~np.isfinite(errors)] = -1.0  # undetermined is not evidence of a wrong touch
        worst = int(np.argmax(errors))
        rest = np.delete(active, worst)
        try:
            check_geometry(plane_mm[rest], robot_mm[rest], model)
        except RegistrationError:
            break
        threshold = bar(rest)
        if errors[worst] <= threshold:
            break
        removed.append(int(active[worst]))
        active = rest
    return tuple(sorted(removed)), bar(active) if threshold is None else threshold


def _determined(plane_mm: F64, robot_mm: F64, model: Model) -> bool:
    if len(plane_mm) < MINIMAL_POINTS[model]:
        return False
    if min(spread_mm(plane_mm), spread_mm(robot_mm)) < MIN_SPREAD_MM:
        return False
    return model != "affine" or width_ratio(plane_mm) >= MIN_WIDTH_RATIO
