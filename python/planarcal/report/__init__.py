"""The calibration report: the paper's tables and figures, and the honest accuracy figure.

* ``summary_text`` / ``summary_json``: mean, max, min and RMS reprojection error (px, Eq. 6-7),
  the leave-one-out error (mm), the largest deviations dX, dY (mm, Table 4); the lens model
  (its parameters, the models tried and why this one), the figures before and after it (a
  homography alone against the chosen model), the leave-one-out error the covariance
  predicts against the measured one, and the printer-scale correction.
* ``points_csv``: the per-point table (Tables 2-4 and the leave-one-out error, every point).
* ``deviation_figure``: the paper's Figure 5 (dX and dY per point) with a vector field of the
  deviations over the board, as PNG.
* ``lens_figure``: the residuals before and after the lens model over the image, and the
  distortion it found, as PNG.
* ``uncertainty_figure``: the 1-sigma position uncertainty (mm) as a heat map over the
  working area, with where it doubles relative to the board's centre, as PNG.
* ``write_report``: all of these (and the detection drawn on the image, Figure 4) into a
  directory, each file written atomically.
* ``detection_failure_figure`` / ``write_detection_failure``: when the board is not found,
  the image with what the search saw (the blobs, each candidate grid and why it was refused)
  and the error, as PNG.
"""

from __future__ import annotations

import collections
import csv
import functools
import io
import json
import math
import os
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.calibration import Calibration, LensModel
from planarcal.errors import HomographyError, IntrinsicsError, LensModelError
from planarcal.files import atomic_write
from planarcal.images import as_grey
from planarcal.report.drawing import (
    dot_flags,
    draw_detection,
    homography_residual_note,
    png_bytes,
    rgb_image,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from planarcal.camera.intrinsics import CameraIntrinsics

F64 = NDArray[np.float64]


def summary_json(cal: Calibration, detection: Any = None) -> dict[str, Any]:
    """The summary as one JSON-ready object (NaN becomes null)."""
    s = cal.summary()
    out: dict[str, Any] = {
        "n_points": s.n_points,
        "solver": s.solver,
        "refine": s.refine,
        "mean_error_px": s.mean_px,
        "max_error_px": s.max_px,
        "min_error_px": s.min_px,
        "rms_error_px": s.rms_px,
        "loo_mean_error_mm": s.loo_mean_mm,
        "loo_rms_error_mm": s.loo_rms_mm,
        "loo_max_error_mm": s.loo_max_mm,
        "max_abs_dx_mm": s.max_abs_dx_mm,
        "max_abs_dy_mm": s.max_abs_dy_mm,
        "loo_mean_error_px": s.loo_mean_px,
        "predicted_loo_rms_error_mm": s.predicted_loo_rms_mm,
        "loo_rms_measured_over_predicted": _ratio(s.loo_rms_mm, s.predicted_loo_rms_mm),
        "lens_model": cal.lens_model,
        "lens": _lens_json(cal),
        "lens_note": cal.lens_note,
        "lens_candidates": [c.to_dict() for c in cal.lens_candidates],
        "lens_max_displacement_px": _max_displacement_px(cal),
    }
    if cal.intrinsics is not None:
        out["intrinsics"] = cal.intrinsics.to_dict()
    if tuple(cal.world_scale) != (1.0, 1.0):
        out["world_scale"] = list(cal.world_scale)
    if cal.lens_model != "none":
        before = _homography_alone(cal)
        out["before_after"] = {"before": _figures(before), "after": _figures(cal)}
    if cal.board is not None:
        out["board"] = cal.board.to_dict()
    if cal.image_size is not None:
        out["image_size_px"] = list(cal.image_size)
    if detection is not None:
        out["detection"] = _detection_json(detection)
    return {k: _finite_or_none(v) for k, v in out.items()}


def _detection_json(detection: Any) -> dict[str, Any]:
    """The finder, the polarity and the pitch; and, when the detection carries them, the
    dots not refined and the enlarged ones (1-based point numbers, as in the CSV), the
    orientation and the warnings."""
    out: dict[str, Any] = {
        "method": detection.method,
        "polarity": detection.polarity,
        "pitch_px": detection.pitch_px,
        "residual_rms_px": detection.residual_rms_px,
    }
    refined = dot_flags(detection, "refined")
    if refined is not None:
        out["n_not_refined"] = int((~refined).sum())
        out["not_refined_points"] = _point_numbers(~refined)
    enlarged = dot_flags(detection, "enlarged")
    if enlarged is not None:
        out["enlarged_points"] = _point_numbers(enlarged)
    orientation = _orientation(detection)
    if orientation is not None:
        out["orientation"] = orientation
        out["orientation_rule"] = getattr(detection, "orientation_rule", None)
    warnings = _warnings(detection)
    if warnings is not None:
        out["warnings"] = list(warnings)
    return out


def _point_numbers(flags: NDArray[np.bool_]) -> list[int]:
    """The 1-based numbers of the flagged points (the CSV's and the text's numbering)."""
    return [int(k) + 1 for k in np.flatnonzero(flags)]


def _orientation(detection: Any) -> str | None:
    """How dot 0 was chosen: "origin marker", "ambiguous: <the rule applied>", or None when
    the detection does not say."""
    orientation = getattr(detection, "orientation", None)
    if orientation is None:
        return None
    if orientation == "marker":
        return "origin marker"
    rule = getattr(detection, "orientation_rule", None)
    return f"{orientation}: {rule}" if rule else str(orientation)


def _warnings(detection: Any) -> tuple[str, ...] | None:
    warnings = getattr(detection, "warnings", None)
    return None if warnings is None else tuple(str(w) for w in warnings)


def _finite_or_none(v: Any) -> Any:
    """`v` with every non-finite float in it (nested in dicts, lists and tuples) as None,
    and numpy numbers as Python ones."""
    if isinstance(v, dict):
        return {k: _finite_or_none(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_finite_or_none(x) for x in v]
    if isinstance(v, np.generic):
        v = v.item()
    return None if isinstance(v, float) and not math.isfinite(v) else v


def _ratio(a: float, b: float) -> float:
    return a / b if math.isfinite(a) and math.isfinite(b) and b > 0 else math.nan


def _homography_alone(cal: Calibration) -> Calibration:
    """The "before" fit: a homography alone on the same points (no lens, no intrinsics)."""
    return Calibration(
        cal.world_points,
        cal.image_points,
        solver=cal.solver,
        refine=cal.refine,
        lens="none",
        board=cal.board,
        image_size=cal.image_size,
    )


def _figures(cal: Calibration) -> dict[str, Any]:
    """The before / after figures of one fit."""
    s = cal.summary()
    return {
        "lens_model": cal.lens_model,
        "mean_error_px": s.mean_px,
        "max_error_px": s.max_px,
        "rms_error_px": s.rms_px,
        "loo_mean_error_px": s.loo_mean_px,
        "loo_mean_error_mm": s.loo_mean_mm,
        "loo_rms_error_mm": s.loo_rms_mm,
        "loo_max_error_mm": s.loo_max_mm,
    }


def _fitted(lens: LensModel) -> list[str]:
    """Which of the lens's parameters were fitted (the others are fixed: k2 = 0, the centre
    at the image's)."""
    return {"k1": ["k1"], "k1k2": ["k1", "k2"]}.get(lens.model, ["k1", "k2", "centre"])


def _lens_json(cal: Calibration) -> dict[str, Any] | None:
    lens = cal.lens
    if lens is None:
        return None
    out = lens.to_dict()
    out["fitted"] = _fitted(lens)
    return out


def _max_displacement_px(cal: Calibration) -> float:
    """The most the lens moves a pixel of the image (at its border, for a radial model), px;
    NaN without an image size or a lens model."""
    if cal.lens_model == "none" or cal.image_size is None:
        return math.nan
    w, h = cal.image_size
    t = np.linspace(0.0, 1.0, 201)
    x, y = t * w - 0.5, t * h - 0.5  # the image's outer edge, pixel centres at integers
    border = np.concatenate(
        [
            np.column_stack([x, np.full_like(t, -0.5)]),
            np.column_stack([x, np.full_like(t, h - 0.5)]),
            np.column_stack([np.full_like(t, -0.5), y]),
            np.column_stack([np.full_like(t, w - 0.5), y]),
        ]
    )
    moved = np.hypot(*_displacement(cal, border).T)
    moved = moved[np.isfinite(moved)]
    return float(moved.max()) if moved.size else math.nan


def _lens_text(cal: Calibration) -> list[str]:
    """The lens model's parameters, the models tried and the before / after figures."""
    lines = []
    lens = cal.lens
    if lens is not None:
        fitted = _fitted(lens)
        parts = [f"k1 = {lens.k1:.5f} +/- {lens.k1_std:.5f}"]
        if "k2" in fitted:
            parts.append(f"k2 = {lens.k2:.5f} +/- {lens.k2_std:.5f}")
        cx, cy = lens.centre_px
        if "centre" in fitted:
            sx, sy = lens.centre_std_px
            parts.append(f"centre ({cx:.2f} +/- {sx:.2f}, {cy:.2f} +/- {sy:.2f}) px")
        else:
            parts.append(f"centre ({cx:.1f}, {cy:.1f}) px (the image's, not fitted)")
        lines.append(f"Lens model {lens.model}: " + ", ".join(parts))
        lines.append(f"  (radius unit {lens.scale_px:.1f} px, the image's half-diagonal)")
    elif cal.intrinsics is not None:
        k = cal.intrinsics
        coeffs = ", ".join(f"{v:.5g}" for v in k.dist_coeffs)
        lines.append(
            f"Lens: camera intrinsics, fx {k.fx:.1f} px, fy {k.fy:.1f} px, principal point "
            f"({k.cx:.1f}, {k.cy:.1f}) px, distortion ({coeffs})"
        )
    reach = _max_displacement_px(cal)
    if math.isfinite(reach):
        lines.append(
            f"  the lens moves the image's pixels by up to {reach:.1f} px (at its border) from "
            "where a pinhole camera would show them"
        )
    if cal.lens_candidates:
        lines.append("Lens models tried (mean leave-one-out error in the image, px):")
        for c in cal.lens_candidates:
            loo = f"{c.loo_mean_px:8.4f}" if math.isfinite(c.loo_mean_px) else "       -"
            lines.append(f"  {c.model:<6} {loo}  {c.verdict}")
    if cal.lens_model != "none":
        before, after = _homography_alone(cal).summary(), cal.summary()
        rows = (
            ("reprojection error, mean (px)", before.mean_px, after.mean_px, ".3f"),
            ("reprojection error, RMS (px)", before.rms_px, after.rms_px, ".3f"),
            ("reprojection error, max (px)", before.max_px, after.max_px, ".3f"),
            ("leave-one-out error, mean (mm)", before.loo_mean_mm, after.loo_mean_mm, ".4f"),
            ("leave-one-out error, RMS (mm)", before.loo_rms_mm, after.loo_rms_mm, ".4f"),
        )
        lines.append(
            f"Before / after the lens model: {'homography alone':>18} {cal.lens_model:>12}"
        )
        for name, b, a, fmt in rows:
            lines.append(f"  {name:<31}{b:>18{fmt}} {a:>12{fmt}}")
    return lines


def _detection_text(detection: Any) -> list[str]:
    """The detection's orientation, dots not refined, enlarged dots and warnings, as far as
    it carries them."""
    lines = []
    orientation = _orientation(detection)
    if orientation is not None:
        lines.append(f"Orientation (which dot is the origin): {orientation}")
    refined = dot_flags(detection, "refined")
    if refined is not None:
        n = len(refined)
        if refined.all():
            lines.append(f"Centres refined: all {n} dots")
        else:
            lines.append(
                f"Centres refined: {int(refined.sum())} of {n} dots; not refined (a coarser "
                f"centre kept): {_point_list(~refined)}"
            )
    enlarged = dot_flags(detection, "enlarged")
    if enlarged is not None and enlarged.any():
        lines.append(f"Enlarged dots: {_point_list(enlarged)}")
    lines += [f"Warning: {w}" for w in _warnings(detection) or ()]
    return lines


def _point_list(flags: NDArray[np.bool_], most: int = 20) -> str:
    """ "point 3" or "points 3, 17, 40" (1-based), the first `most` of a long list."""
    numbers = _point_numbers(flags)
    shown = ", ".join(str(k) for k in numbers[:most])
    more = f" and {len(numbers) - most} more" if len(numbers) > most else ""
    return f"point{'s' if len(numbers) > 1 else ''} {shown}{more}"


def _model_phrase(cal: Calibration) -> str:
    """Which model a calibration's residuals come from, as the report words it."""
    if cal.lens_model == "none":
        return "of the homography alone"
    if cal.lens_model == "intrinsics":
        return "with the camera intrinsics"
    return f"with the lens model {cal.lens_model}"


def residual_note(cal: Calibration) -> str:
    """The detection figure's residual line: the homography alone's RMS residual through the
    centres and, with a lens model, the chosen model's, each named (the same figures as the
    summary's reprojection errors)."""
    alone = cal if cal.lens_model == "none" else _homography_alone(cal)
    note = homography_residual_note(alone.stats.rms)
    if cal.lens_model == "none":
        return note + " (no lens model)"
    return f"{note}; {_model_phrase(cal)}: {cal.stats.rms:.3f} px RMS"


def summary_text(cal: Calibration, detection: Any = None) -> str:
    """A readable summary of the calibration."""
    s = cal.summary()
    lines = []
    if cal.board is not None:
        b = cal.board
        lines.append(f"Board: {b.describe()}")
    if detection is not None:
        w, h = detection.image_size
        lines.append(
            f"Found all {s.n_points} dots in the {w} x {h} image ({detection.method} finder, "
            f"{detection.polarity} dots, {detection.pitch_px:.1f} px apart)"
        )
        lines += _detection_text(detection)
    fit = f"{s.solver}" + (" + Levenberg-Marquardt" if s.refine else "")
    lines += [
        f"Homography: {fit}, from {s.n_points} points",
        f"Lens: {cal.lens_note}",
        *_lens_text(cal),
        f"Reprojection error (px), {_model_phrase(cal)}: mean {s.mean_px:.3f}, "
        f"RMS {s.rms_px:.3f}, max {s.max_px:.3f} (point {cal.stats.argmax + 1}), "
        f"min {s.min_px:.3f}",
        f"World coordinates after calibration: |dX| <= {s.max_abs_dx_mm:.3f} mm, "
        f"|dY| <= {s.max_abs_dy_mm:.3f} mm",
        f"Leave-one-out error (mm): mean {s.loo_mean_mm:.3f}, RMS {s.loo_rms_mm:.3f}, "
        f"max {s.loo_max_mm:.3f}",
        "  (each point predicted by a fit made without it: the accuracy to expect at points",
        "  the calibration has not seen; the residuals above flatter the fit)",
    ]
    ratio = _ratio(s.loo_rms_mm, s.predicted_loo_rms_mm)
    if math.isfinite(ratio):
        lines += [
            f"Uncertainty: the fit's covariance predicts a leave-one-out RMS of "
            f"{s.predicted_loo_rms_mm:.4f} mm, measured {s.loo_rms_mm:.4f} mm "
            f"(ratio {ratio:.2f})",
            "  (near 1: the 1-sigma uncertainties reported are to be trusted; well above 1:",
            "  the model misses something the residuals do not show as noise)",
        ]
    if tuple(cal.world_scale) != (1.0, 1.0):
        sx, sy = cal.world_scale
        lines.append(
            f"World scale (printer's scale corrected): X x {sx:.5f}, Y x {sy:.5f} "
            f"({100 * (sx - 1):+.2f} %, {100 * (sy - 1):+.2f} %)"
        )
    return "\n".join(lines)


CSV_COLUMNS = (
    "point",
    "row",
    "col",
    "world_x_mm",
    "world_y_mm",
    "image_x_px",
    "image_y_px",
    "reprojected_x_px",
    "reprojected_y_px",
    "error_px",
    "world_after_x_mm",
    "world_after_y_mm",
    "dx_mm",
    "dy_mm",
    "loo_dx_mm",
    "loo_dy_mm",
    "loo_error_mm",
    "loo_error_px",
    "predicted_loo_std_mm",
    "refined",
    "enlarged",
)


def points_csv(cal: Calibration, detection: Any = None) -> str:
    """The per-point table as CSV: point (1-based), its row and column on the board (when
    known), world and image coordinates, reprojection (Table 3), world after calibration
    and deviations (Table 4), the leave-one-out deviation and error (mm, and px in the
    image), the leave-one-out error the fit's covariance predicts (1-sigma, mm), and whether
    the detection refined the dot's centre and found it enlarged (1 / 0; empty when the
    detection does not say)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    cols = cal.board.cols if cal.board is not None else None
    n = len(cal.world_points)
    refined = _flag_column(detection, "refined", n)
    enlarged = _flag_column(detection, "enlarged", n)
    for i in range(n):
        row, col = ("", "") if cols is None else divmod(i, cols)
        values = [
            *cal.world_points[i],
            *cal.image_points[i],
            *cal.reprojected_px[i],
            cal.reprojection_errors_px[i],
            *cal.world_after_mm[i],
            *cal.deviations_mm[i],
            *cal.loo_deviations_mm[i],
            cal.loo_errors_mm[i],
            cal.loo_errors_px[i],
            cal.predicted_loo_std_mm[i],
        ]
        writer.writerow(
            [
                i + 1,
                row,
                col,
                *(f"{v:.6f}" if math.isfinite(v) else "" for v in values),
                refined[i],
                enlarged[i],
            ]
        )
    return buf.getvalue()


def _flag_column(detection: Any, name: str, n: int) -> list[str]:
    """A per-dot flag as a CSV column of "1" / "0", or of "" when there is none for these
    `n` points."""
    flags = None if detection is None else dot_flags(detection, name)
    if flags is None or len(flags) != n:
        return [""] * n
    return ["1" if f else "0" for f in flags]


def deviation_figure(cal: Calibration) -> bytes:
    """The paper's Figure 5 (dX and dY per point, mm) and a vector field of the deviations
    over the board, as PNG bytes."""
    from matplotlib.figure import Figure  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)

    dev = cal.deviations_mm
    loo = cal.loo_deviations_mm
    n = len(dev)
    idx = np.arange(1, n + 1)
    fig = Figure(figsize=(12, 8), dpi=100, layout="constrained")
    grid = fig.add_gridspec(2, 2, width_ratios=(1.15, 1))
    ax_dx = fig.add_subplot(grid[0, 0])
    ax_dy = fig.add_subplot(grid[1, 0], sharex=ax_dx)
    for ax, k, name in ((ax_dx, 0, "dX"), (ax_dy, 1, "dY")):
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.plot(idx, dev[:, k], "o-", ms=3, lw=0.8, label=f"{name} after calibration")
        if np.isfinite(loo[:, k]).any():
            ax.plot(idx, loo[:, k], ".", ms=4, color="tab:red", alpha=0.7, label="leave-one-out")
        ax.set_ylabel(f"{name} (mm)")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    ax_dy.set_xlabel("point")
    ax_dx.set_title("Calibration deviation per point (the paper's Figure 5)")
    ax_v = fig.add_subplot(grid[:, 1])
    world = cal.world_points
    length = np.hypot(dev[:, 0], dev[:, 1])
    spread = float(np.ptp(world, axis=0).max()) or 1.0
    biggest = float(length.max()) or 1.0
    scale = 0.08 * spread / biggest  # the longest arrow is 8% of the board
    q = ax_v.quiver(
        world[:, 0],
        world[:, 1],
        dev[:, 0] * scale,
        dev[:, 1] * scale,
        length,
        angles="xy",
        scale_units="xy",
        scale=1.0,
        cmap="viridis",
        width=0.004,
    )
    fig.colorbar(q, ax=ax_v, label="|deviation| (mm)", shrink=0.8)
    ax_v.scatter(world[:, 0], world[:, 1], s=4, color="0.3")
    ax_v.set_aspect("equal")
    ax_v.invert_yaxis()  # Y runs down the board, as printed
    ax_v.set_xlabel("X (mm)")
    ax_v.set_ylabel("Y (mm)")
    ax_v.set_title(f"Deviations over the board (arrows x{scale:.0f})")
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


# -- the lens and uncertainty figures ---------------------------------------------------------

_MAP_ERRORS = (HomographyError, LensModelError, IntrinsicsError)
"""What mapping a pixel raises where it has no answer (beyond a lens model's valid radius, on
or past the plane's horizon)."""


def _figure(width: float, height: float) -> Figure:
    # The OO API alone: savefig renders through Agg without a backend being chosen, and
    # choosing one (matplotlib.use) would change the backend of the user's own plots.
    from matplotlib.figure import Figure  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)

    return Figure(figsize=(width, height), dpi=100, layout="constrained")


def _png(fig: Figure) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _masked(f: Callable[[F64], F64], points: F64, width: int, budget: int = 32) -> F64:
    """f applied to the points (N, 2) -> (N, width), NaN where f cannot map a point.

    f maps all or raises: a batch that raises is halved, breadth first, until the points
    that fail are found. The callers rule out beforehand what they can (``_mappable``), so
    this is a safety net; as a failure can cost a model tens of ms, after `budget` of them
    the batches still failing are left NaN whole rather than searched point by point."""
    out = np.full((len(points), width), np.nan)
    todo = collections.deque([(0, len(points))])
    failures = 0
    while todo:
        a, b = todo.popleft()
        if a == b:
            continue
        try:
            out[a:b] = np.asarray(f(points[a:b]), dtype=np.float64).reshape(b - a, width)
        except _MAP_ERRORS:
            failures += 1
            if b - a > 1 and failures < budget:
                m = (a + b) // 2
                todo += [(a, m), (m, b)]
    out[~np.isfinite(out).all(axis=1)] = np.nan
    return out


@functools.lru_cache(maxsize=16)
def _intrinsics_fold(intrinsics: CameraIntrinsics) -> float:
    """The largest radius (normalised: tan of the angle off the optical axis) out to which
    the camera's lens model maps every direction without folding over (bisected with its
    own check), or infinity when it does not fold within 76 degrees."""

    def maps(r: float) -> bool:
        try:
            intrinsics.distort_points(_normalised_circle(intrinsics, r))
        except IntrinsicsError:
            return False
        return True

    lo, hi = 0.0, 4.0
    if maps(hi):
        return math.inf
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if maps(mid) else (lo, mid)
    return lo


def _normalised_circle(intrinsics: CameraIntrinsics, r: float, n: int = 720) -> F64:
    """The ideal pixels at normalised radius r about the optical axis (n, 2)."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    rays = np.column_stack([r * np.cos(t), r * np.sin(t), np.ones(n)])
    px = rays @ intrinsics.matrix.T
    return np.asarray(px[:, :2] / px[:, 2:], dtype=np.float64)


def _normalised_radius(intrinsics: CameraIntrinsics, ideal_px: F64) -> F64:
    rays = np.column_stack([ideal_px, np.ones(len(ideal_px))]) @ np.linalg.inv(intrinsics.matrix).T
    return np.asarray(np.hypot(rays[:, 0], rays[:, 1]) / rays[:, 2], dtype=np.float64)


def _fold_radius(lens: LensModel) -> float:
    """The normalised radius where the radial map r (1 + k1 r^2 + k2 r^4) stops increasing
    (beyond it the lens model folds over and cannot be inverted), or infinity."""
    # d/dr = 1 + 3 k1 r^2 + 5 k2 r^4: its smallest positive root in r^2.
    a, b = 5.0 * lens.k2, 3.0 * lens.k1
    if a == 0.0:
        roots = [-1.0 / b] if b < 0.0 else []
    else:
        disc = b * b - 4.0 * a
        roots = (
            []
            if disc < 0.0
            else [(-b - math.sqrt(disc)) / (2 * a), (-b + math.sqrt(disc)) / (2 * a)]
        )
    positive = [t for t in roots if t > 0.0]
    return math.sqrt(min(positive)) if positive else math.inf


def _before_fold(lens: LensModel, ideal_px: F64) -> NDArray[np.bool_]:
    """Which ideal pixels lie inside the lens model's fold (where it is one to one)."""
    rho = np.hypot(*((ideal_px - np.array(lens.centre_px)) / lens.scale_px).T)
    return np.asarray(rho < (1.0 - 1e-6) * _fold_radius(lens), dtype=np.bool_)


def _mappable(cal: Calibration, px: F64) -> NDArray[np.bool_]:
    """Which pixels have a place on the plane: inside the lens model's valid radius (its fold
    seen in the image), and on the plane's side of the horizon."""
    ok = np.asarray(np.isfinite(px).all(axis=1), dtype=np.bool_)
    lens = cal.lens
    if lens is not None:
        fold = _fold_radius(lens)
        if math.isfinite(fold):
            valid = lens.scale_px * fold * (1.0 + fold**2 * (lens.k1 + lens.k2 * fold**2))
            ok &= np.hypot(*(px - np.array(lens.centre_px)).T) < (1.0 - 1e-6) * valid
    elif cal.intrinsics is not None:
        fold = _intrinsics_fold(cal.intrinsics)
        if math.isfinite(fold):
            from matplotlib.path import Path as Outline  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)

            # The pixels the lens shows the unfolded directions at: inside the fold's image
            # (less a margin: at the fold itself the mapping's slope goes to zero).
            edge = cal.intrinsics.distort_points(_normalised_circle(cal.intrinsics, 0.97 * fold))
            ok[ok] = Outline(edge).contains_points(px[ok])
    ideal = np.full_like(px, np.nan)
    ideal[ok] = _masked(cal.ideal_points, px[ok], 2)
    # H^-1 is oriented: the third homogeneous coordinate is positive in front of the camera.
    row = cal.H_inv[2]
    v = ideal @ row[:2] + row[2]
    scale = np.abs(row).sum() * (1.0 + np.abs(ideal).sum(axis=1))
    return np.asarray(np.isfinite(v) & (v > 1e-9 * scale), dtype=np.bool_)


def _displacement(cal: Calibration, ideal_px: F64) -> F64:
    """How far the lens moves each ideal pixel (N, 2), px (real minus ideal); NaN beyond the
    model's fold, or without a lens model."""
    out = np.full_like(ideal_px, np.nan)
    if cal.lens is not None:
        ok = _before_fold(cal.lens, ideal_px)
        out[ok] = cal.lens.displacement_px(ideal_px[ok])
    elif cal.intrinsics is not None:
        intr = cal.intrinsics
        ok = np.asarray(np.isfinite(ideal_px).all(axis=1), dtype=np.bool_)
        ok[ok] = _normalised_radius(intr, ideal_px[ok]) < _intrinsics_fold(intr)
        out[ok] = _masked(lambda u: intr.distort_points(u) - u, ideal_px[ok], 2)
    return out


def _nice(x: float) -> float:
    """The largest of 1, 2, 3, 5 x 10^k not above x (x > 0)."""
    e = 10.0 ** math.floor(math.log10(x))
    return next(m * e for m in (5.0, 3.0, 2.0, 1.0) if m * e <= x * (1 + 1e-9))


def _frame_px(cal: Calibration) -> tuple[float, float, float, float]:
    """(left, right, bottom, top) of the image in px for imshow-like axes; around the points
    without an image size."""
    if cal.image_size is not None:
        w, h = cal.image_size
        return -0.5, w - 0.5, h - 0.5, -0.5
    lo, hi = cal.image_points.min(axis=0), cal.image_points.max(axis=0)
    pad = 0.1 * (hi - lo).max() + 1.0
    return lo[0] - pad, hi[0] + pad, hi[1] + pad, lo[1] - pad


def _outline_mm(cal: Calibration, per_edge: int = 60) -> F64:
    """The board's outline through its outer dot centres (the points' bounding box on the
    plane), as a closed polyline (M, 2) in mm."""
    (x0, y0), (x1, y1) = cal.world_points.min(axis=0), cal.world_points.max(axis=0)
    t = np.linspace(0.0, 1.0, per_edge, endpoint=False)
    return np.concatenate(
        [
            np.column_stack([x0 + t * (x1 - x0), np.full_like(t, y0)]),
            np.column_stack([np.full_like(t, x1), y0 + t * (y1 - y0)]),
            np.column_stack([x1 - t * (x1 - x0), np.full_like(t, y1)]),
            np.column_stack([np.full_like(t, x0), y1 - t * (y1 - y0)]),
            [[x0, y0]],
        ]
    )


def _draw_frame(ax: Axes, cal: Calibration, image: Any) -> None:
    """Axes in image pixels (y down), the picture faintly behind when given, the frame."""
    left, right, bottom, top = _frame_px(cal)
    if image is not None and cal.image_size is not None:
        grey = as_grey(image)
        if grey.shape[::-1] == tuple(cal.image_size):
            ax.imshow(grey, cmap="gray", alpha=0.35, extent=(left, right, bottom, top))
    if cal.image_size is not None:
        ax.plot(
            [left, right, right, left, left], [top, top, bottom, bottom, top], color="0.5", lw=0.8
        )
    ax.set_xlim(left, right)
    ax.set_ylim(bottom, top)
    ax.set_aspect("equal")
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")


def _residual_panel(
    ax: Axes,
    cal: Calibration,
    fit: Calibration,
    scale: float,
    key: float,
    title: str,
    image: Any,
) -> None:
    """The residuals (measured minus reprojected, px) of `fit` as arrows `scale` times their
    length over the image, with an arrow of `key` px for reference."""
    _draw_frame(ax, cal, image)
    pts = fit.image_points
    res = pts - fit.reprojected_px
    ax.scatter(pts[:, 0], pts[:, 1], s=3, color="0.35", zorder=2)
    q = ax.quiver(
        pts[:, 0],
        pts[:, 1],
        res[:, 0] * scale,
        res[:, 1] * scale,
        angles="xy",
        scale_units="xy",
        scale=1.0,
        color="tab:red",
        width=0.003,
        zorder=3,
    )
    ax.quiverkey(q, 0.8, 1.015, key * scale, f"{key:g} px", labelpos="E", coordinates="axes")
    ax.set_title(title, fontsize=10, loc="left")


def _arrow_scale(cal: Calibration, residuals: F64) -> tuple[float, float]:
    """(scale, key): a round magnification that draws the longest residual about one and a
    half dot spacings long (at most x10000: rounding noise is not magnified into arrows),
    and a round residual length for the reference arrow."""
    pts = cal.image_points
    area = float(np.prod(np.ptp(pts, axis=0))) or float(np.ptp(pts, axis=0).max() ** 2) or 1.0
    spacing = math.sqrt(area / max(len(pts), 1))
    biggest = float(np.hypot(*residuals.T).max())
    scale = _nice(min(1.5 * spacing / max(biggest, 1e-300), 1e4))
    return scale, _nice(max(biggest, 0.5 * spacing / scale))


def _stats_line(fit: Calibration) -> str:
    s = fit.stats
    return f"mean {s.mean:.3f} px, max {s.max:.3f} px"


def _candidates_panel(ax: Axes, cal: Calibration) -> None:
    """The lens models tried: their mean leave-one-out errors (px), the chosen one marked."""
    cands = cal.lens_candidates
    y = np.arange(len(cands))[::-1]
    finite = [c.loo_mean_px for c in cands if math.isfinite(c.loo_mean_px) and c.loo_mean_px > 0]
    lo = min(finite) if finite else 1.0
    hi = max(finite) if finite else 1.0
    base = lo / 3.0
    for yi, c in zip(y, cands, strict=True):
        chosen = c.model == cal.lens_model
        if math.isfinite(c.loo_mean_px) and c.loo_mean_px > 0:
            ax.barh(
                yi, c.loo_mean_px - base, left=base, height=0.6, color=_GREEN if chosen else "0.7"
            )
            x, label = c.loo_mean_px * 1.15, f"{c.loo_mean_px:.4f} px: {c.verdict}"
        else:
            x, label = base * 1.15, c.verdict
        ax.text(
            x,
            yi,
            textwrap.fill(label, 45),
            va="center",
            fontsize=8,
            fontweight="bold" if chosen else "normal",
        )
    ax.set_xscale("log")
    ax.set_xlim(base, hi * 60.0)
    ax.set_ylim(-0.6, len(cands) - 0.4)
    ax.set_yticks(y, [c.model for c in cands])
    ax.set_xlabel("mean leave-one-out error in the image (px, log scale)")
    ax.set_title(
        "Lens models tried: a richer one is chosen only if it\nlowers the leave-one-out error "
        "clearly",
        fontsize=10,
        loc="left",
    )
    ax.grid(True, axis="x", alpha=0.3)


_GREEN = "tab:green"


def _displacement_panel(ax: Axes, fig: Figure, cal: Calibration) -> None:
    """|real - ideal| over the image (px), arrows for its direction, the board's outline and
    the lens centre."""
    _draw_frame(ax, cal, None)
    left, right, bottom, top = _frame_px(cal)
    nx = 161
    ny = max(2, round(nx * (bottom - top) / (right - left)))
    gx, gy = np.meshgrid(np.linspace(left, right, nx), np.linspace(top, bottom, ny))
    disp = _displacement(cal, np.column_stack([gx.ravel(), gy.ravel()])).reshape(ny, nx, 2)
    mag = np.hypot(disp[..., 0], disp[..., 1])
    valid = np.isfinite(mag)
    biggest = float(mag[valid].max()) if valid.any() else 0.0
    if biggest > 0:
        shown = np.ma.masked_invalid(mag)
        cf = ax.contourf(gx, gy, shown, levels=12, cmap="magma")
        fig.colorbar(cf, ax=ax, label="|displacement| (px)", shrink=0.9)
        cs = ax.contour(
            gx, gy, shown, levels=np.asarray(cf.levels)[2:-1:2], colors="w", linewidths=0.6
        )
        ax.clabel(cs, fmt="%.3g px", fontsize=7)
    if not valid.all():
        ax.contourf(
            gx, gy, (~valid).astype(float), levels=[0.5, 1.5], colors="none", hatches=["//"]
        )
        ax.text(
            0.01,
            0.01,
            "hatched: beyond the lens model's fold-over (where it cannot be inverted)",
            transform=ax.transAxes,
            fontsize=8,
            color="k",
            backgroundcolor="w",
        )
    # Arrows on a coarse grid, at true size when the distortion is big enough to see.
    step = max(1, nx // 16)
    sub = (slice(step // 2, None, step), slice(step // 2, None, step))
    cell = (right - left) / 16
    arrow = 1.0 if biggest >= 0.5 * cell or biggest == 0 else _nice(0.8 * cell / biggest)
    ax.quiver(
        gx[sub],
        gy[sub],
        disp[sub][..., 0] * arrow,
        disp[sub][..., 1] * arrow,
        angles="xy",
        scale_units="xy",
        scale=1.0,
        color="w",
        width=0.0035,
    )
    outline = _masked(cal.world_to_image, _outline_mm(cal), 2)
    ax.plot(outline[:, 0], outline[:, 1], color="tab:cyan", lw=1.8, label="board (outer dots)")
    if cal.lens is not None:
        (cx, cy), (sx, sy) = cal.lens.centre_px, cal.lens.centre_std_px
        what = (
            f"lens centre ({cx:.1f} +/- {sx:.1f}, {cy:.1f} +/- {sy:.1f}) px"
            if "centre" in _fitted(cal.lens)
            else f"lens centre ({cx:.1f}, {cy:.1f}) px, fixed"
        )
    elif cal.intrinsics is not None:
        cx, cy = cal.intrinsics.cx, cal.intrinsics.cy
        what = f"principal point ({cx:.1f}, {cy:.1f}) px"
    else:
        cx, cy, what = math.nan, math.nan, ""
    if cal.image_size is not None:
        w, h = cal.image_size
        ax.plot([(w - 1) / 2], [(h - 1) / 2], "x", color="w", ms=9, mew=1.5, label="image centre")
    if what:
        ax.plot([cx], [cy], "+", color=_GREEN, ms=16, mew=2.5, label=what)
    ax.legend(loc="upper right", fontsize=8, framealpha=0.85)
    scale_note = "at true size" if arrow == 1.0 else f"x{arrow:g}"
    ax.set_title(
        f"The distortion found ({cal.lens_model}): how far the lens moves each pixel of a "
        f"pinhole camera,\nup to {biggest:.2f} px in the image (arrows {scale_note})",
        fontsize=10,
        loc="left",
    )


def _no_lens_title(note: str) -> str:
    return note[0].upper() + note[1:] if note.startswith("no lens model") else f"No lens: {note}"


def lens_figure(cal: Calibration, *, image: Any = None) -> bytes:
    """The lens model, as PNG bytes: the residuals (px) before it (a homography alone) and
    after it, drawn as arrows over the image at one scale, the distortion it found as a map
    of how far it moves each pixel (with the board's outline and the lens centre), and the
    models tried. Without a lens model, the residuals and why there is none (the note).
    `image`: the picture the calibration was made from, drawn faintly behind (optional)."""
    if cal.lens_model == "none":
        has_candidates = bool(cal.lens_candidates)
        fig = _figure(17 if has_candidates else 10, 6.5)
        grid = fig.add_gridspec(1, 2, width_ratios=(1.6, 1)) if has_candidates else None
        ax = fig.add_subplot(grid[0, 0]) if grid is not None else fig.add_subplot()
        scale, key = _arrow_scale(cal, cal.image_points - cal.reprojected_px)
        _residual_panel(
            ax,
            cal,
            cal,
            scale,
            key,
            f"Residuals of the homography alone (arrows x{scale:g})\n{_stats_line(cal)}",
            image,
        )
        if grid is not None:
            _candidates_panel(fig.add_subplot(grid[0, 1]), cal)
        fig.suptitle(textwrap.fill(_no_lens_title(cal.lens_note), 110), fontsize=11)
        return _png(fig)
    before = _homography_alone(cal)
    res_before = before.image_points - before.reprojected_px
    scale, key = _arrow_scale(cal, res_before)
    fig = _figure(17, 11.5)
    rows = fig.add_gridspec(2, 1, height_ratios=(1, 1.1))
    top = rows[0].subgridspec(1, 2)
    _residual_panel(
        fig.add_subplot(top[0, 0]),
        cal,
        before,
        scale,
        key,
        f"Before: residuals of a homography alone, arrows x{scale:g} (the same scale in "
        f"both)\n{_stats_line(before)}",
        image,
    )
    shrink = before.stats.mean / cal.stats.mean if cal.stats.mean > 0 else math.inf
    _residual_panel(
        fig.add_subplot(top[0, 1]),
        cal,
        cal,
        scale,
        key,
        f"After: residuals with the lens model {cal.lens_model}, arrows x{scale:g} (the same "
        f"scale in both)\n{_stats_line(cal)}: {shrink:.3g} times smaller on average",
        image,
    )
    if cal.lens_candidates:
        bottom = rows[1].subgridspec(1, 2, width_ratios=(1.6, 1))
        _displacement_panel(fig.add_subplot(bottom[0, 0]), fig, cal)
        _candidates_panel(fig.add_subplot(bottom[0, 1]), cal)
    else:
        _displacement_panel(fig.add_subplot(rows[1]), fig, cal)
    fig.suptitle(textwrap.fill(f"Lens: {cal.lens_note}", 140), fontsize=12)
    return _png(fig)


def _working_region_px(cal: Calibration) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1): the image region around the board, extended by half the board's
    size each way, clipped to the image."""
    lo, hi = cal.image_points.min(axis=0), cal.image_points.max(axis=0)
    half = 0.5 * (hi - lo)
    lo, hi = lo - half, hi + half
    if cal.image_size is not None:
        w, h = cal.image_size
        lo = np.maximum(lo, 0.0)
        hi = np.minimum(hi, [w - 1.0, h - 1.0])
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


_DEGRADATION = (1.5, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0, 256.0)
"""The multiples of the board centre's uncertainty drawn as contour lines."""


def uncertainty_figure(cal: Calibration) -> bytes:
    """The 1-sigma position uncertainty (mm, from the fit's covariance) as a heat map over
    the working area (the image region around the board, extended by half the board's size
    each way and clipped to the image) on the plane, in mm, with the board's dots, contour
    lines at multiples of the uncertainty at the board's centre and the line where it
    doubles marked; as PNG bytes. Pixels with no place on the plane (beyond the lens
    model's valid radius, past the horizon) are left blank."""
    from matplotlib.colors import LogNorm, Normalize  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)
    from matplotlib.tri import Triangulation  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)

    fig = _figure(11, 8.5)
    ax = fig.add_subplot()
    world = cal.world_points
    centre_mm = 0.5 * (world.min(axis=0) + world.max(axis=0))
    try:
        _, centre_std = cal.image_to_world(cal.world_to_image(centre_mm), return_std=True)
    except _MAP_ERRORS as e:
        ax.text(
            0.5,
            0.5,
            textwrap.fill(f"No uncertainty map: {e}", 70),
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
        ax.set_axis_off()
        return _png(fig)
    x0, x1, y0, y1 = _working_region_px(cal)
    nx = 201
    ny = max(2, round(nx * (y1 - y0) / max(x1 - x0, 1e-9)))
    gx, gy = np.meshgrid(np.linspace(x0, x1, nx), np.linspace(y0, y1, ny))
    px = np.column_stack([gx.ravel(), gy.ravel()])

    def mapped(p: F64) -> F64:
        mm, std = cal.image_to_world(p, return_std=True)
        return np.column_stack([mm, std])

    out = np.full((len(px), 3), np.nan)
    ok = _mappable(cal, px)
    out[ok] = _masked(mapped, px[ok], 3)
    # Near the plane's horizon a pixel maps ever farther away: keep the neighbourhood.
    reach = 10.0 * max(float(np.ptp(world, axis=0).max()), 1.0)
    out[np.hypot(*(out[:, :2] - centre_mm).T) > reach] = np.nan
    valid = np.asarray(np.isfinite(out).all(axis=1), dtype=bool)
    k = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
    tris = np.concatenate(
        [np.column_stack([k, k + 1, k + nx]), np.column_stack([k + 1, k + nx + 1, k + nx])]
    )
    tris = tris[valid[tris].all(axis=1)]
    if not len(tris):
        ax.text(
            0.5,
            0.5,
            "No pixel of the working area maps onto the plane",
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
        ax.set_axis_off()
        return _png(fig)
    xy = np.where(valid[:, None], out[:, :2], centre_mm)
    std = np.where(valid, out[:, 2], 0.0)
    tri = Triangulation(xy[:, 0], xy[:, 1], tris)
    used = std[np.unique(tris)]
    lo, hi = float(used.min()), float(used.max())
    norm = LogNorm(lo, hi) if lo > 0 and hi > 8 * lo else Normalize(lo, hi)
    pc = ax.tripcolor(tri, std, shading="gouraud", cmap="viridis", norm=norm)
    bar = fig.colorbar(pc, ax=ax, label="1-sigma position uncertainty (mm)", shrink=0.85)
    if isinstance(norm, LogNorm):
        from matplotlib.ticker import FuncFormatter, LogLocator  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)

        bar.ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        bar.ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        bar.ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _: ""))
    c = float(centre_std)
    if c > 0 and hi > lo:
        levels = [m * c for m in _DEGRADATION if lo < m * c < hi]
        if levels:
            lines = ax.tricontour(tri, std, levels=levels, colors="w", linewidths=0.7)
            ax.clabel(lines, fmt={v: f"x{v / c:g}" for v in levels}, fontsize=8)
        if lo < 2 * c < hi:
            ax.tricontour(tri, std, levels=[2 * c], colors="tab:red", linewidths=2.5)
            ax.plot([], [], color="tab:red", lw=2.5, label=f"twice the centre's: {2 * c:.3g} mm")
            where = "the red line marks where it doubles"
        else:
            where = f"it stays under twice that here (at most x{hi / c:.2f})"
    else:
        where = "no residual error to scale it by"
    outline = _outline_mm(cal)
    ax.plot(outline[:, 0], outline[:, 1], color="w", lw=1.0, ls="--", label="board (outer dots)")
    ax.scatter(
        world[:, 0],
        world[:, 1],
        s=6,
        color="k",
        edgecolors="w",
        linewidths=0.4,
        label="board's dots",
        zorder=3,
    )
    ax.plot(
        [centre_mm[0]],
        [centre_mm[1]],
        "+",
        color="tab:red",
        ms=14,
        mew=2,
        label=f"board centre: {c:.3g} mm",
        zorder=4,
    )
    ax.legend(
        loc="upper center",
        bbox_to_anchor=(0.5, -0.08),
        ncols=4,
        fontsize=9,
        facecolor="0.75",
        markerscale=1.5,
    )
    ax.set_aspect("equal")
    ax.invert_yaxis()  # Y runs down the board, as printed
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    clipped = ", clipped to the image" if cal.image_size is not None else ""
    ax.set_title(
        "1-sigma position uncertainty on the plane, from the fit's covariance (a measured "
        "pixel's own noise adds to it)\n"
        f"Working area: the board's image region extended by half its size each way{clipped}."
        f"\n{c:.3g} mm at the board's centre; white contours at multiples of it; {where}",
        fontsize=10,
    )
    return _png(fig)


def write_report(
    cal: Calibration,
    out_dir: str | os.PathLike[str],
    *,
    image: Any = None,
    detection: Any = None,
) -> list[Path]:
    """Writes points.csv, summary.json, deviations.png, lens.png, uncertainty.png and (with an
    image and its detection) detection.png into `out_dir` (created if need be), each
    atomically; returns the paths written."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = [
        atomic_write(out / "points.csv", points_csv(cal, detection)),
        atomic_write(
            out / "summary.json",
            json.dumps(summary_json(cal, detection), indent=2, allow_nan=False) + "\n",
        ),
        atomic_write(out / "deviations.png", deviation_figure(cal)),
        atomic_write(out / "lens.png", lens_figure(cal, image=image)),
        atomic_write(out / "uncertainty.png", uncertainty_figure(cal)),
    ]
    if image is not None and detection is not None:
        drawn = draw_detection(image, detection, residual_note=residual_note(cal))
        written.append(atomic_write(out / "detection.png", png_bytes(drawn)))
    return written


# -- when the board is not found ------------------------------------------------------------

DETECTION_FAILED_PNG = "detection_failed.png"
"""The failure figure's name in the report directory."""

_BLOB_COLOURS = {"dark": "tab:blue", "light": "tab:orange"}
_CANDIDATE_COLOURS = ("tab:red", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:cyan")


def detection_failure_figure(image: Any, diagnostics: Any, message: str) -> bytes:
    """What a failed search saw, as PNG bytes: the image with the blobs of each polarity
    (circles of their diameter), each candidate grid (its points joined in order, numbered
    and labelled with its finder and polarity), and beside it the error message and why each
    candidate was refused. `diagnostics`: a DetectionDiagnostics, or None (the image and the
    message alone)."""
    picture = rgb_image(image)
    h, w = picture.shape[:2]
    # The image panel is about 10 in wide: a height that fits its aspect, room for the text.
    fig = _figure(16, min(12.0, max(6.5, 10.0 * h / w + 1.5)))
    grid = fig.add_gridspec(1, 2, width_ratios=(1.8, 1))
    ax = fig.add_subplot(grid[0, 0])
    ax.imshow(picture, interpolation="nearest")
    if diagnostics is not None:
        _draw_seen_blobs(ax, diagnostics.blobs)
        _draw_candidates(ax, diagnostics.candidates)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper right", fontsize=8, framealpha=0.85)
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)  # the image's way up: row 0 at the top
    ax.set_title("What the search saw", fontsize=11, loc="left")
    text = fig.add_subplot(grid[0, 1])
    text.set_axis_off()
    text.text(
        0.0,
        1.0,
        detection_failure_text(diagnostics, message),
        va="top",
        ha="left",
        fontsize=8.5,
        family="monospace",
        transform=text.transAxes,
    )
    fig.suptitle("Board not found", fontsize=13, color="tab:red")
    return _png(fig)


def _draw_seen_blobs(ax: Axes, blobs: Any) -> None:
    """Each polarity's blobs as circles of their diameter, one colour per polarity."""
    from matplotlib.collections import PatchCollection  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)
    from matplotlib.lines import Line2D  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)
    from matplotlib.patches import Circle  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)

    for seen in blobs:
        colour = _BLOB_COLOURS.get(seen.polarity, "tab:gray")
        circles = [
            Circle((float(x), float(y)), 0.5 * float(d))
            for (x, y), d in zip(seen.centres_px, seen.diameters_px, strict=True)
        ]
        ax.add_collection(
            PatchCollection(circles, facecolor="none", edgecolor=colour, linewidth=1.2)
        )
        # A collection of circles has no legend entry of its own: a stand-in marker.
        ax.add_line(
            Line2D(
                [],
                [],
                ls="",
                marker="o",
                mfc="none",
                mec=colour,
                label=f"{len(circles)} {seen.polarity} blobs seen",
            )
        )


def _draw_candidates(ax: Axes, candidates: Any) -> None:
    """Each refused candidate grid: its points joined in order, its number at its first
    point, its finder and polarity in the legend."""
    for k, cand in enumerate(candidates):
        colour = _CANDIDATE_COLOURS[k % len(_CANDIDATE_COLOURS)]
        pts = np.asarray(cand.points_px, dtype=np.float64).reshape(-1, 2)
        ax.plot(
            pts[:, 0],
            pts[:, 1],
            "o-",
            color=colour,
            lw=1.0,
            ms=2.5,
            alpha=0.85,
            label=f"{k + 1}: {cand.method}, {cand.polarity} dots ({len(pts)} points)",
        )
        if len(pts):
            ax.annotate(
                str(k + 1),
                pts[0],
                xytext=(-6, -6),
                textcoords="offset points",
                ha="right",
                color="w",
                fontsize=9,
                fontweight="bold",
                bbox={"boxstyle": "round,pad=0.2", "fc": colour, "ec": "none"},
            )


def detection_failure_text(diagnostics: Any, message: str, width: int = 62, most: int = 10) -> str:
    """The failure figure's text panel: the error, the blobs seen and why each candidate
    grid was refused (the first `most` of them: the panel holds no more)."""
    paragraphs = [textwrap.fill(f"Error: {message}", width), ""]
    if diagnostics is None:
        paragraphs.append("(no record of what the search saw)")
        return "\n".join(paragraphs)
    b = diagnostics.board
    w, h = diagnostics.image_size
    paragraphs.append(f"Looking for {b.cols} x {b.rows} dots in the {w} x {h} image.")
    for seen in diagnostics.blobs:
        d = np.asarray(seen.diameters_px, dtype=np.float64)
        size = f", about {float(np.median(d)):.0f} px across" if d.size else ""
        paragraphs.append(f"Blobs seen: {len(d)} {seen.polarity}{size}")
    paragraphs.append("")
    if not diagnostics.candidates:
        paragraphs.append("No candidate grid was put forward.")
    else:
        paragraphs.append("Candidate grids refused:")
        for k, cand in enumerate(diagnostics.candidates[:most]):
            paragraphs.append(
                textwrap.fill(
                    f"{k + 1}. {cand.method} ({cand.polarity} dots): {cand.reason}",
                    width,
                    subsequent_indent="   ",
                )
            )
        if len(diagnostics.candidates) > most:
            paragraphs.append(f"... and {len(diagnostics.candidates) - most} more")
    return "\n".join(paragraphs)


def write_detection_failure(
    out_dir: str | os.PathLike[str], image: Any, diagnostics: Any, message: str
) -> Path:
    """Writes ``detection_failure_figure`` as detection_failed.png into `out_dir` (created if
    need be), atomically; returns its path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figure = detection_failure_figure(image, diagnostics, message)
    return atomic_write(out / DETECTION_FAILED_PNG, figure)
