"""Leave-one-out errors of a registration and the touches that do not belong: each point's
error under the fit of the others, and the points named as outliers by that error.

A touch on the wrong dot pulls a least-squares fit towards itself, so its own residual
understates it; refitted without it, the others show how far off it is. The search removes
the worst point while its leave-one-out error exceeds the threshold and recomputes the others'
errors without it (a wrong touch also inflates its neighbours' errors), one point at a time,
so the result depends on nothing but the data. The default threshold is set by the others'
leave-one-out errors without the suspect, so a wrong touch cannot raise its own bar."""

from __future__ import annotations

import dataclasses

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
    fit_affine,
    fit_hand,
)

# The default threshold: this many times the median leave-one-out error, and never below
# OUTLIER_FLOOR_MM (exact data would otherwise call a rounding error an outlier).
OUTLIER_MEDIAN_FACTOR = 5.0
OUTLIER_FLOOR_MM = 1.0

# The most touches the outlier search removes: each removal refits everything, and a set
# with more wrong touches than this is mispaired as a whole (the order, the origin), which no
# search mends; the result says when the search stopped here.
MAX_OUTLIERS = 20


@dataclasses.dataclass(frozen=True)
class OutlierSearch:
    """What the outlier search found: ``outliers`` (indices, ascending), the ``threshold_mm``
    it ended on, and ``capped``: it stopped at MAX_OUTLIERS with a touch still above it."""

    outliers: tuple[int, ...]
    threshold_mm: float
    capped: bool


def leave_one_out(plane_mm: F64, robot_mm: F64, model: Model, reflected: bool) -> F64:
    """Each point's error (mm) under the fit of the other points, with the handedness given;
    inf where the others alone are too few, clustered or collinear to fix the model.

    All N at once, in O(N): rigid and similarity from the sums that fix a fit (the means, the
    scatter and the cross-covariance), each with its own point taken out, and the 2-D
    rotation's closed form; affine from the full fit's residuals and the hat matrix's diagonal
    h (a linear least-squares point's leave-one-out residual is its residual / (1 - h)). The
    same numbers as refitting without each point (a test compares them)."""
    n = len(plane_mm)
    if n - 1 < MINIMAL_POINTS[model]:
        return np.full(n, np.inf)
    # Centred on the whole set's means: the sums then lose no digits to an offset of hundreds
    # of mm.
    p = plane_mm - plane_mm.mean(axis=0)
    q = robot_mm - robot_mm.mean(axis=0)
    m = n - 1
    mean_p = (p.sum(axis=0) - p) / m  # (N, 2): the others' means
    mean_q = (q.sum(axis=0) - q) / m
    scatter_p = _others(p.T @ p, p, p, mean_p, mean_p, m)  # (N, 2, 2)
    determined = _spread_ok(scatter_p, m) & _spread_ok(_others(q.T @ q, q, q, mean_q, mean_q, m), m)
    if model == "affine":
        determined &= _width_ok(scatter_p)
        errors = _affine_leave_one_out(plane_mm, robot_mm)
    else:
        cross = _others(q.T @ p, q, p, mean_q, mean_p, m)  # robot x board
        errors = _umeyama_leave_one_out(p, q, mean_p, mean_q, scatter_p, cross, model, reflected)
    out: F64 = np.where(determined & np.isfinite(errors), errors, np.inf)
    return out


def _others(total: F64, a: F64, b: F64, mean_a: F64, mean_b: F64, m: int) -> F64:
    """sum over j != i of (a_j - mean_a_i)(b_j - mean_b_i)^T, for each i: (N, 2, 2)."""
    out: F64 = (
        total[None] - a[:, :, None] * b[:, None, :] - m * mean_a[:, :, None] * mean_b[:, None, :]
    )
    return out


def _spread_ok(scatter: F64, m: int) -> NDArray[np.bool_]:
    spread = np.sqrt(np.maximum(np.trace(scatter, axis1=1, axis2=2), 0.0) / m)
    ok: NDArray[np.bool_] = spread >= MIN_SPREAD_MM
    return ok


def _width_ok(scatter: F64) -> NDArray[np.bool_]:
    # The centred points' singular values are the roots of the scatter's eigenvalues.
    half_trace = (scatter[:, 0, 0] + scatter[:, 1, 1]) / 2
    gap = np.hypot((scatter[:, 0, 0] - scatter[:, 1, 1]) / 2, scatter[:, 0, 1])
    large, small = half_trace + gap, np.maximum(half_trace - gap, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.sqrt(small / large)
    ok: NDArray[np.bool_] = np.nan_to_num(ratio) >= MIN_WIDTH_RATIO
    return ok


def _umeyama_leave_one_out(
    p: F64,
    q: F64,
    mean_p: F64,
    mean_q: F64,
    scatter_p: F64,
    cross: F64,
    model: Model,
    reflected: bool,
) -> F64:
    # The rotation R maximising trace(R^T C D) (D the mirror, or 1) is the angle of
    # (C'00 + C'11, C'10 - C'01) with C' = C D; the similarity's scale is that vector's length
    # over the board points' scatter (Umeyama's s1 +- s2 in 2-D).
    c = cross.copy()
    if reflected:
        c[:, :, 1] *= -1.0
    a = c[:, 0, 0] + c[:, 1, 1]
    b = c[:, 1, 0] - c[:, 0, 1]
    length = np.hypot(a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos, sin = np.where(length > 0, a / length, 1.0), np.where(length > 0, b / length, 0.0)
        scale = (
            length / np.trace(scatter_p, axis1=1, axis2=2)
            if model == "similarity"
            else np.ones(len(p))
        )
    d = p - mean_p
    if reflected:
        d = d * np.array([1.0, -1.0])
    turned = np.c_[cos * d[:, 0] - sin * d[:, 1], sin * d[:, 0] + cos * d[:, 1]]
    predicted = mean_q + scale[:, None] * turned
    out: F64 = np.hypot(*(predicted - q).T)
    return out


def _affine_leave_one_out(plane_mm: F64, robot_mm: F64) -> F64:
    residuals = robot_mm - apply(fit_affine(plane_mm, robot_mm), plane_mm)
    design = np.c_[plane_mm - plane_mm.mean(axis=0), np.ones(len(plane_mm))]
    gram = design.T @ design
    try:
        leverage = np.einsum("ij,jk,ik->i", design, np.linalg.inv(gram), design)
    except np.linalg.LinAlgError:  # collinear: no point's error is determined
        return np.full(len(plane_mm), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        out: F64 = np.hypot(*residuals.T) / (1.0 - leverage)
    return np.where(1.0 - leverage > 1e-12, out, np.inf)


def default_threshold(errors_mm: F64) -> float:
    """max(OUTLIER_FLOOR_MM, OUTLIER_MEDIAN_FACTOR x the median finite leave-one-out error)."""
    finite = errors_mm[np.isfinite(errors_mm)]
    median = float(np.median(finite)) if finite.size else 0.0
    return max(OUTLIER_FLOOR_MM, OUTLIER_MEDIAN_FACTOR * median)


def find_outliers(
    plane_mm: F64,
    robot_mm: F64,
    model: Model,
    outlier_mm: float | None,
    mirrored: bool | None = None,
) -> OutlierSearch:
    """The points whose leave-one-out error exceeds the threshold, and the threshold (mm) the
    search ended on: ``outlier_mm``, or by default default_threshold of the other points'
    leave-one-out errors without the suspect (a wrong touch inflates the errors of the fits
    that include it, so its own presence must not set the bar). The worst point goes first;
    the search stops while the rest still fix the model with a residual, and after
    MAX_OUTLIERS removals. ``mirrored``: the hand of every fit (None: the better one)."""

    def bar(keep: NDArray[np.intp]) -> float:
        if outlier_mm is not None:
            return outlier_mm
        p, q = plane_mm[keep], robot_mm[keep]
        _, reflected = fit_hand(p, q, model, mirrored)
        return default_threshold(leave_one_out(p, q, model, reflected))

    active = np.arange(len(plane_mm))
    removed: list[int] = []
    threshold: float | None = None
    capped = False
    while len(active) > MINIMAL_POINTS[model] + 1:
        p, q = plane_mm[active], robot_mm[active]
        _, reflected = fit_hand(p, q, model, mirrored)
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
        if len(removed) == MAX_OUTLIERS:
            capped = True
            break
        removed.append(int(active[worst]))
        active = rest
    return OutlierSearch(
        tuple(sorted(removed)), bar(active) if threshold is None else threshold, capped
    )
