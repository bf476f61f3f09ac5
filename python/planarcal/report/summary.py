"""The calibration's summary, as text for people and as one JSON-ready object: the
reprojection and leave-one-out errors (in the image, px, which no wrong description of the
board can flatter, and on the plane, mm, which scale with the stated pitch), the verdict
(from the pixels), the lens model (its parameters, the models tried and why this one, the
figures before and after it), the uncertainty the covariance predicts against the measured
one, the printer-scale correction, and what the detection reported (the dots' measured
sizes among it); and the residual line the detection figure carries.

Dots are named by their index k = row x cols + col, 0 the origin dot: the numbering of the
CSV files, the API and the detection figure."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.calibration import Calibration, CalibrationSummary
from planarcal.report.drawing import dot_flags, homography_residual_note
from planarcal.report.fits import fitted_parameters, homography_alone
from planarcal.report.mapping import max_displacement_px


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
        "loo_rms_error_px": s.loo_rms_px,
        "loo_max_error_px": s.loo_max_px,
        "verdict": verdict(s),
        "predicted_loo_rms_error_mm": s.predicted_loo_rms_mm,
        "loo_rms_measured_over_predicted": _ratio(s.loo_rms_mm, s.predicted_loo_rms_mm),
        "lens_model": cal.lens_model,
        "lens": _lens_json(cal),
        "lens_note": cal.lens_note,
        "lens_candidates": [c.to_dict() for c in cal.lens_candidates],
        "lens_max_displacement_px": max_displacement_px(cal),
        "error_budget": cal.error_budget.to_dict(),
    }
    if cal.intrinsics is not None:
        out["intrinsics"] = cal.intrinsics.to_dict()
    if tuple(cal.world_scale) != (1.0, 1.0):
        out["world_scale"] = list(cal.world_scale)
    if cal.lens_model != "none":
        before = homography_alone(cal)
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
    dots not refined and the enlarged ones (their indices k = row x cols + col, 0 the origin
    dot, as in the CSV files and the API), the orientation and the warnings."""
    out: dict[str, Any] = {
        "method": detection.method,
        "polarity": detection.polarity,
        "pitch_px": detection.pitch_px,
        "residual_rms_px": detection.residual_rms_px,
    }
    refined = dot_flags(detection, "refined")
    if refined is not None:
        out["n_not_refined"] = int((~refined).sum())
        out["not_refined_dots"] = _dot_indices(~refined)
    enlarged = dot_flags(detection, "enlarged")
    if enlarged is not None:
        out["enlarged_dots"] = _dot_indices(enlarged)
    orientation = _orientation(detection)
    if orientation is not None:
        out["orientation"] = orientation
        out["orientation_rule"] = getattr(detection, "orientation_rule", None)
    warnings = _warnings(detection)
    if warnings is not None:
        out["warnings"] = list(warnings)
    sizes = getattr(detection, "sizes", None)
    if sizes is not None:
        out["dot_sizes"] = sizes.to_dict(detection.board)
    return out


def _dot_indices(flags: NDArray[np.bool_]) -> list[int]:
    """The indices of the flagged dots: k = row x cols + col, 0 the origin dot (the one
    numbering of the CSV files, the API, the text and the detection figure)."""
    return [int(k) for k in np.flatnonzero(flags)]


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


def _lens_json(cal: Calibration) -> dict[str, Any] | None:
    lens = cal.lens
    if lens is None:
        return None
    out = lens.to_dict()
    out["fitted"] = fitted_parameters(lens)
    return out


def _lens_text(cal: Calibration) -> list[str]:
    """The lens model's parameters, the models tried and the before / after figures."""
    lines = []
    lens = cal.lens
    if lens is not None:
        fitted = fitted_parameters(lens)
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
    reach = max_displacement_px(cal)
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
        before, after = homography_alone(cal).summary(), cal.summary()
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
                f"centre kept): {_dot_list(~refined)}"
            )
    enlarged = dot_flags(detection, "enlarged")
    if enlarged is not None and enlarged.any():
        lines.append(f"Enlarged dots: {_dot_list(enlarged)}")
    lines += [f"Warning: {w}" for w in _warnings(detection) or ()]
    return lines


def _dot_list(flags: NDArray[np.bool_], most: int = 20) -> str:
    """ "dot 3" or "dots 3, 17, 40" (indices, 0 the origin dot), the first `most` of a long
    list."""
    numbers = _dot_indices(flags)
    shown = ", ".join(str(k) for k in numbers[:most])
    more = f" and {len(numbers) - most} more" if len(numbers) > most else ""
    return f"dot{'s' if len(numbers) > 1 else ''} {shown}{more}"


# Leave-one-out RMS in the image (px) up to which a calibration is called excellent, good,
# fair; beyond the last, poor. In pixels, not mm: mm scale with the board's stated pitch, so
# a pitch stated too small would flatter them. A rendered board's dots give about 0.01 px;
# real photographs of a printed board 0.3-0.6 px (the paper is not flat, the lens not quite
# the model).
VERDICT_PX = (("excellent", 0.1), ("good", 0.3), ("fair", 1.0))


def verdict(s: CalibrationSummary) -> str:
    """The calibration in a word, by its RMS leave-one-out error in the image (px):
    "excellent", "good", "fair", "poor", or "unknown" where there is none (too few points)."""
    if not math.isfinite(s.loo_rms_px):
        return "unknown"
    return next((word for word, px in VERDICT_PX if s.loo_rms_px <= px), "poor")


_VERDICT_TEXT = {
    "excellent": "the model fits every dot it has not seen to a tenth of a pixel or better",
    "good": "the model fits the dots it has not seen to a few tenths of a pixel",
    "fair": (
        "the dots stray from the model by up to a pixel: a paper that is not flat, a lens "
        "the model does not capture, or dots mislocated (see the deviations figure)"
    ),
    "poor": (
        "the dots stray from the model by more than a pixel: the board is not flat, moved, "
        "or is not the board described; calibrate again"
    ),
    "unknown": "too few points to leave one out",
}


def _verdict_text(s: CalibrationSummary) -> str:
    word = verdict(s)
    figure = f" (leave-one-out RMS {s.loo_rms_px:.3f} px)" if math.isfinite(s.loo_rms_px) else ""
    return f"Verdict: {word}{figure}: {_VERDICT_TEXT[word]}"


def _sizes_text(detection: Any) -> list[str]:
    """The dots' measured size against the stated one (and the marker's), as far as the
    detection carries them."""
    sizes = getattr(detection, "sizes", None)
    if sizes is None:
        return []
    board = detection.board
    pitch = float(board.pitch)
    measured = (
        f"Dot size: {sizes.diameter_mm:.3g} mm measured at the stated pitch of {pitch:g} mm "
        f"({sizes.diameter_to_pitch(board):.2f} of the pitch, {sizes.dot_px:.1f} px across)"
    )
    if sizes.marker_mm is not None:
        measured += f"; origin marker {sizes.marker_mm:.3g} mm"
    if board.diameter is None:
        check = "no diameter stated: compare it with the board (a ruler)"
    elif sizes.tolerance is None:
        check = f"the stated {board.diameter:g} mm is not checked: {sizes.unchecked}"
    else:
        check = (
            f"the stated {board.diameter:g} mm agrees (within the {100 * sizes.tolerance:.0f} % "
            "the measurement allows)"
        )
    marker_checked = sizes.tolerance is not None and board.marker_diameter is not None
    if marker_checked and sizes.marker_mm is not None:
        check += f"; the stated marker of {board.marker_diameter:g} mm agrees too"
    return [measured, f"  {check}"]


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
    alone = cal if cal.lens_model == "none" else homography_alone(cal)
    note = homography_residual_note(alone.stats.rms)
    if cal.lens_model == "none":
        return note + " (no lens model)"
    return f"{note}; {_model_phrase(cal)}: {cal.stats.rms:.3f} px RMS"


def _budget_text(cal: Calibration) -> list[str]:
    """What std_mm covers, and how big it is at the board's centre."""
    b = cal.error_budget
    try:
        centre = cal.world_to_image(0.5 * (cal.world_points.min(0) + cal.world_points.max(0)))
        _, exact = cal.image_to_world(centre, return_std=True, pixel_sigma=0.0)
        _, part = cal.image_to_world(centre, return_std=True)
    except ValueError:
        return []
    return [
        f"Error bars (std_mm): {exact:.4f} mm at the board's centre for an exact pixel, "
        f"{part:.4f} mm for a located part",
        f"  (the fit's covariance, the model's bias of {b.model_sigma_px:.4f} px per "
        f"coordinate: the dots' lens bias {b.dot_bias_px:.4f} px, the lens model's "
        f"{b.lens_bias_px:.4f} px; and a part's centroid error, {b.detector_px:g} px)",
    ]


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
        lines += _sizes_text(detection)
    fit = f"{s.solver}" + (" + Levenberg-Marquardt" if s.refine else "")
    lines += [
        f"Homography: {fit}, from {s.n_points} points",
        f"Lens: {cal.lens_note}",
        *_lens_text(cal),
        f"Reprojection error (px), {_model_phrase(cal)}: mean {s.mean_px:.3f}, "
        f"RMS {s.rms_px:.3f}, max {s.max_px:.3f} (dot {cal.stats.argmax}), "
        f"min {s.min_px:.3f}",
        f"Leave-one-out error (px): mean {s.loo_mean_px:.3f}, RMS {s.loo_rms_px:.3f}, "
        f"max {s.loo_max_px:.3f}",
        "  (each dot predicted in the image by a fit made without it: the accuracy to expect",
        "  at points the calibration has not seen; the residuals above flatter the fit)",
        _verdict_text(s),
        f"World coordinates after calibration: |dX| <= {s.max_abs_dx_mm:.3f} mm, "
        f"|dY| <= {s.max_abs_dy_mm:.3f} mm",
        f"Leave-one-out error (mm): mean {s.loo_mean_mm:.3f}, RMS {s.loo_rms_mm:.3f}, "
        f"max {s.loo_max_mm:.3f}",
        "  (millimetres at the board's stated pitch: a wrong pitch scales every one of them,",
        "  these errors too; the figures in px above do not depend on it)",
    ]
    ratio = _ratio(s.loo_rms_mm, s.predicted_loo_rms_mm)
    if math.isfinite(ratio):
        lines += [
            f"Uncertainty: the fit's covariance predicts a leave-one-out RMS of "
            f"{s.predicted_loo_rms_mm:.4f} mm, measured {s.loo_rms_mm:.4f} mm "
            f"(ratio {ratio:.2f})",
            "  (near 1: the residuals are the noise the fit assumes; well above 1: the model",
            "  misses something they do not show as noise; neither sees a bias all the dots",
            "  share, which the error bars below add)",
        ]
    lines += _budget_text(cal)
    if tuple(cal.world_scale) != (1.0, 1.0):
        sx, sy = cal.world_scale
        lines.append(
            f"World scale (printer's scale corrected): X x {sx:.5f}, Y x {sy:.5f} "
            f"({100 * (sx - 1):+.2f} %, {100 * (sy - 1):+.2f} %)"
        )
    return "\n".join(lines)
