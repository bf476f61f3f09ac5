"""The calibration's summary, as text for people and as one JSON-ready object: the
reprojection and leave-one-out errors (in the image, px, which no wrong description of the
board can flatter, and on the plane, mm, which scale with the stated pitch), the verdict
(from the pixels), the lens model (its parameters, the models tried and why this one, the
figures before and after it), the uncertainty the covariance predicts against the measured
one, the printer-scale correction, and what the detection reported (the dots' measured
sizes among it); and the residual line the detection figure carries. Whatever the board:
its type, how many of its points were seen (a partial view) and, when the calibration
reaches well beyond them, what the rest of the image is predicted at.

Points are named by the board's word for them (a circle grid's dots, a chessboard's or
ChArUco board's corners) and their ids, on a grid k = row x cols + col, 0 the origin: the
numbering of the CSV files, the API and the detection figure."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.calibration import Calibration, CalibrationSummary
from planarcal.calib.coverage import calibration_coverage
from planarcal.calib.json_number import json_ready
from planarcal.calib.placements import Placement
from planarcal.report.drawing import dot_flags, homography_residual_note
from planarcal.report.fits import fitted_parameters, homography_alone
from planarcal.report.mapping import max_displacement_px
from planarcal.report.point_names import (
    calibration_ids,
    detection_ids,
    id_list,
    is_circle_grid,
    layout_phrase,
    missing_ids,
    plural,
    point_name,
)


def summary_json(
    cal: Calibration, detection: Any = None, *, max_error_mm: float | None = None
) -> dict[str, Any]:
    """The summary as one JSON-ready object (NaN becomes null). With a board: ``board``
    (its description as the calibration file holds it), ``board_type``,
    ``board_description``, ``point_name`` ("dot", "corner"), ``n_board_points``,
    ``partial`` and, for a partial view, ``point_ids`` (the order of points.csv) and
    ``not_seen_ids``; ``extrapolation``: the points' coverage of the image and the error
    predicted beyond them, with its ``warning`` (Calibration.extrapolation); ``coverage``:
    the largest region of the image predicted worse than ``max_error_mm`` (calib.coverage);
    ``placements``: each placement's pose and residuals, for a calibration from several;
    ``detection``: what the detection found (see summary_text)."""
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
        out.update(_board_json(cal.board, calibration_ids(cal, detection)))
    extrapolation = _extrapolation_json(cal)
    if extrapolation is not None:
        out["extrapolation"] = extrapolation
    if cal.image_size is not None:
        out["image_size_px"] = list(cal.image_size)
        out["coverage"] = calibration_coverage(cal, max_error_mm).to_dict()
    if len(cal.placements) > 1:
        out["placements"] = [_placement_json(p) for p in cal.placements]
    if detection is not None:
        out["detection"] = _detection_json(detection)
    return {k: json_ready(v) for k, v in out.items()}


def _placement_json(p: Placement) -> dict[str, Any]:
    return {
        "index": p.index,
        "name": p.name,
        "reference": p.reference,
        "points": len(p.ids),
        "partial": p.partial,
        "angle_deg": p.angle_deg,
        "offset_mm": list(p.offset_mm),
        "angle_std_deg": p.angle_std_deg,
        "offset_std_mm": p.offset_std_mm,
        "rms_error_px": p.rms_px,
    }


def _board_json(board: Any, ids: NDArray[np.intp]) -> dict[str, Any]:
    """The board (its description, type and words), how many of its points the calibration
    holds (`ids`) and, for a partial view, their ids (the order of points.csv) and those not
    seen."""
    out: dict[str, Any] = {
        "board": board.to_dict(),
        "board_type": board.kind,
        "board_description": board.describe(),
        "point_name": point_name(board),
        "n_board_points": int(board.n_points),
        "partial": len(ids) < board.n_points,
    }
    if out["partial"]:
        out["point_ids"] = [int(k) for k in ids]
        out["not_seen_ids"] = [int(k) for k in missing_ids(board, ids)]
    return out


def _extrapolation(cal: Calibration) -> Any:
    """The calibration's word on the image beyond its points (``Calibration.extrapolation``),
    or None where it has none."""
    try:
        return getattr(cal, "extrapolation", None)
    except (ValueError, ArithmeticError):  # a model that cannot map the image at all
        return None


def _extrapolation_json(cal: Calibration) -> dict[str, Any] | None:
    ex = _extrapolation(cal)
    if ex is None:
        return None
    if hasattr(ex, "to_dict"):
        out: dict[str, Any] = dict(ex.to_dict())
    else:
        out = {
            name: getattr(ex, name)
            for name in ("covered_share", "covered_std_mm", "image_std_mm", "warning")
            if hasattr(ex, name)
        }
    return out


def _detection_json(detection: Any) -> dict[str, Any]:
    """The finder, a circle grid's polarity, and the pitch; and, when the detection carries
    them, how many of the board's points it found, the printed layout it found (ChArUco), the
    dots not refined and the enlarged ones (their ids, k = row x cols + col on a grid, 0 the
    origin, as in the CSV files and the API), the orientation and the warnings."""
    board = detection.board
    out: dict[str, Any] = {"method": detection.method}
    if is_circle_grid(board):
        out["polarity"] = detection.polarity
    out["pitch_px"] = detection.pitch_px
    out["residual_rms_px"] = detection.residual_rms_px
    ids = detection_ids(detection)
    if getattr(detection, "ids", None) is not None:
        out["n_points_found"] = len(ids)
        out["partial"] = len(ids) < board.n_points
    layout = getattr(detection, "layout", None)
    if layout is not None:
        out["layout"] = str(layout)
    refined = dot_flags(detection, "refined")
    if refined is not None:
        out["n_not_refined"] = int((~refined).sum())
        out["not_refined_dots"] = _dot_indices(ids, ~refined)
    enlarged = dot_flags(detection, "enlarged")
    if enlarged is not None:
        out["enlarged_dots"] = _dot_indices(ids, enlarged)
    orientation = _orientation(detection)
    if orientation is not None:
        out["orientation"] = orientation
        out["orientation_rule"] = getattr(detection, "orientation_rule", None)
    warnings = _warnings(detection)
    if warnings is not None:
        out["warnings"] = list(warnings)
    sizes = getattr(detection, "sizes", None)
    if sizes is not None and is_circle_grid(board):
        out["dot_sizes"] = sizes.to_dict(board)
    return out


def _dot_indices(ids: NDArray[np.intp], flags: NDArray[np.bool_]) -> list[int]:
    """The ids of the flagged points: k = row x cols + col on a grid, 0 the origin (the one
    numbering of the CSV files, the API, the text and the detection figure)."""
    return [int(k) for k in ids[flags]]


def _orientation(detection: Any) -> str | None:
    """How point 0 was chosen: "origin marker", "ambiguous: <the rule applied>", or None
    when the detection does not say."""
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
    """The detection's printed layout, orientation, points not refined, enlarged dots and
    warnings, as far as it carries them."""
    lines = []
    name = point_name(detection.board)
    ids = detection_ids(detection)
    layout = layout_phrase(getattr(detection, "layout", None))
    if layout is not None:
        lines.append(f"Printed layout found: {layout}")
    orientation = _orientation(detection)
    if orientation is not None:
        lines.append(f"Orientation (which {name} is the origin): {orientation}")
    refined = dot_flags(detection, "refined")
    if refined is not None:
        n = len(refined)
        if refined.all():
            lines.append(f"Centres refined: all {n} {plural(name, n)}")
        else:
            lines.append(
                f"Centres refined: {int(refined.sum())} of {n} {plural(name, n)}; not refined "
                f"(a coarser centre kept): {id_list(ids[~refined], name)}"
            )
    enlarged = dot_flags(detection, "enlarged")
    if enlarged is not None and enlarged.any():
        lines.append(f"Enlarged {plural(name, 2)}: {id_list(ids[enlarged], name)}")
    lines += [f"Warning: {w}" for w in _warnings(detection) or ()]
    return lines


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
    "excellent": "the model fits every {name} it has not seen to a tenth of a pixel or better",
    "good": "the model fits the {names} it has not seen to a few tenths of a pixel",
    "fair": (
        "the {names} stray from the model by up to a pixel: a paper that is not flat, a lens "
        "the model does not capture, or {names} mislocated (see the deviations figure)"
    ),
    "poor": (
        "the {names} stray from the model by more than a pixel: the board is not flat, moved, "
        "or is not the board described; calibrate again"
    ),
    "unknown": "too few points to leave one out",
}


def _verdict_text(s: CalibrationSummary, name: str = "dot") -> str:
    word = verdict(s)
    figure = f" (leave-one-out RMS {s.loo_rms_px:.3f} px)" if math.isfinite(s.loo_rms_px) else ""
    text = _VERDICT_TEXT[word].format(name=name, names=plural(name, 2))
    return f"Verdict: {word}{figure}: {text}"


def _sizes_text(detection: Any) -> list[str]:
    """The dots' measured size against the stated one (and the marker's), as far as the
    detection carries them."""
    sizes = getattr(detection, "sizes", None)
    board = detection.board
    if sizes is None or not is_circle_grid(board):
        return []
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


def _budget_text(cal: Calibration, name: str = "dot") -> list[str]:
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
        f"coordinate: the {plural(name, 2)}' lens bias {b.dot_bias_px:.4f} px, the lens model's "
        f"{b.lens_bias_px:.4f} px; and a part's centroid error, {b.detector_px:g} px)",
    ]


def summary_text(
    cal: Calibration, detection: Any = None, *, max_error_mm: float | None = None
) -> str:
    """A readable summary of the calibration: the board and how much of it was seen (each
    placement's pose, for a calibration from several), the detection's findings, the fit,
    its errors and uncertainty, what the image beyond the points is predicted at and the
    largest region predicted worse than ``max_error_mm`` (calib.coverage)."""
    s = cal.summary()
    name = point_name(cal.board if cal.board is not None else getattr(detection, "board", None))
    names = plural(name, 2)
    ids = calibration_ids(cal, detection)
    lines = []
    if cal.board is not None:
        b = cal.board
        lines.append(f"Board: {b.describe()}")
    placements = cal.placements
    if len(placements) > 1:
        lines.append(
            f"Placements: {len(placements)}, fitted together (the plane's frame is placement "
            f"{next(p.index for p in placements if p.reference)}'s board frame; the detection "
            "below is its)"
        )
        lines += [f"  {p.describe()}" for p in placements]
    if detection is not None:
        lines += _found_text(detection)
        lines += _detection_text(detection)
        lines += _sizes_text(detection)
    elif cal.board is not None and len(ids) < cal.board.n_points:
        lines += _seen_text(cal.board, ids)
    fit = f"{s.solver}" + (" + Levenberg-Marquardt" if s.refine else "")
    worst = f"{name} {ids[cal.stats.argmax]}" if len(ids) else "-"
    pitch = "square" if hasattr(cal.board, "square") else "pitch"
    lines += [
        f"Homography: {fit}, from {s.n_points} points",
        f"Lens: {cal.lens_note}",
        *_lens_text(cal),
        f"Reprojection error (px), {_model_phrase(cal)}: mean {s.mean_px:.3f}, "
        f"RMS {s.rms_px:.3f}, max {s.max_px:.3f} ({worst}), "
        f"min {s.min_px:.3f}",
        f"Leave-one-out error (px): mean {s.loo_mean_px:.3f}, RMS {s.loo_rms_px:.3f}, "
        f"max {s.loo_max_px:.3f}",
        f"  (each {name} predicted in the image by a fit made without it: the accuracy to expect",
        "  at points the calibration has not seen; the residuals above flatter the fit)",
        _verdict_text(s, name),
        f"World coordinates after calibration: |dX| <= {s.max_abs_dx_mm:.3f} mm, "
        f"|dY| <= {s.max_abs_dy_mm:.3f} mm",
        f"Leave-one-out error (mm): mean {s.loo_mean_mm:.3f}, RMS {s.loo_rms_mm:.3f}, "
        f"max {s.loo_max_mm:.3f}",
        f"  (millimetres at the board's stated {pitch}: a wrong {pitch} scales every one of them,",
        "  these errors too; the figures in px above do not depend on it)",
    ]
    ratio = _ratio(s.loo_rms_mm, s.predicted_loo_rms_mm)
    if math.isfinite(ratio):
        lines += [
            f"Uncertainty: the fit's covariance predicts a leave-one-out RMS of "
            f"{s.predicted_loo_rms_mm:.4f} mm, measured {s.loo_rms_mm:.4f} mm "
            f"(ratio {ratio:.2f})",
            "  (near 1: the residuals are the noise the fit assumes; well above 1: the model",
            f"  misses something they do not show as noise; neither sees a bias all the {names}",
            "  share, which the error bars below add)",
        ]
    lines += _budget_text(cal, name)
    lines += _extrapolation_text(cal)
    if cal.image_size is not None:
        lines.append(f"Error map: {calibration_coverage(cal, max_error_mm).sentence}")
    if tuple(cal.world_scale) != (1.0, 1.0):
        sx, sy = cal.world_scale
        lines.append(
            f"World scale (printer's scale corrected): X x {sx:.5f}, Y x {sy:.5f} "
            f"({100 * (sx - 1):+.2f} %, {100 * (sy - 1):+.2f} %)"
        )
    return "\n".join(lines)


def _found_text(detection: Any) -> list[str]:
    """What the detection found: all of the board or how much of it, where, by which finder
    (with a circle grid's polarity), and for a partial view which points were not seen."""
    board = detection.board
    name = point_name(board)
    ids = detection_ids(detection)
    seen, total = len(ids), int(board.n_points)
    w, h = detection.image_size
    how = [f"{detection.method} finder"]
    if is_circle_grid(board):
        how.append(f"{detection.polarity} dots")
    how.append(f"{detection.pitch_px:.1f} px apart")
    if seen >= total:
        found = f"all {seen} {plural(name, seen)}"
    else:
        found = f"{seen} of the board's {total} {plural(name, total)} (a partial view)"
    lines = [f"Found {found} in the {w} x {h} image ({', '.join(how)})"]
    if seen < total:
        lines.append(f"  not seen: {id_list(missing_ids(board, ids), name)}")
    return lines


def _seen_text(board: Any, ids: NDArray[np.intp]) -> list[str]:
    """A partial view's points, without its detection: how many of the board's, and which
    were not seen."""
    name = point_name(board)
    total = int(board.n_points)
    return [
        f"Calibrated from {len(ids)} of the board's {total} {plural(name, total)} (a partial view)",
        f"  not seen: {id_list(missing_ids(board, ids), name)}",
    ]


def _extrapolation_text(cal: Calibration) -> list[str]:
    """How much of the image the calibration's points cover and what it predicts beyond
    them, with its warning when the rest is extrapolated (``Calibration.extrapolation``)."""
    ex = _extrapolation(cal)
    if ex is None:
        return []
    share = getattr(ex, "covered_share", math.nan)
    at_points = getattr(ex, "covered_std_mm", math.nan)
    anywhere = getattr(ex, "image_std_mm", math.nan)
    warning = getattr(ex, "warning", None)
    if warning:  # it gives the figures
        return [f"Warning: {warning}"]
    lines = []
    if all(isinstance(v, float) and math.isfinite(v) for v in (share, at_points, anywhere)):
        lines.append(
            f"Coverage: the points' outline covers {100 * share:.0f} % of the image; the "
            f"mapping's 1-sigma is up to {at_points:.3g} mm at the points, {anywhere:.3g} mm "
            "at worst elsewhere in the image (an exact pixel)"
        )
    return lines
