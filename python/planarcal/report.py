"""The calibration report: the paper's tables and figures, and the honest accuracy figure.

* ``summary_text`` / ``summary_json``: mean, max, min and RMS reprojection error (px, Eq. 6-7),
  the leave-one-out error (mm), the largest deviations dX, dY (mm, Table 4).
* ``points_csv``: the per-point table (Tables 2-4 and the leave-one-out error, every point).
* ``deviation_figure``: the paper's Figure 5 (dX and dY per point) with a vector field of the
  deviations over the board, as PNG.
* ``write_report``: all of these (and the detection drawn on the image, Figure 4) into a
  directory, each file written atomically.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from planarcal.calibration import Calibration
from planarcal.files import atomic_write


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
    }
    if cal.board is not None:
        out["board"] = cal.board.to_dict()
    if cal.image_size is not None:
        out["image_size_px"] = list(cal.image_size)
    if detection is not None:
        out["detection"] = {
            "method": detection.method,
            "polarity": detection.polarity,
            "pitch_px": detection.pitch_px,
        }
    return {k: _finite_or_none(v) for k, v in out.items()}


def _finite_or_none(v: Any) -> Any:
    return None if isinstance(v, float) and not math.isfinite(v) else v


def summary_text(cal: Calibration, detection: Any = None) -> str:
    """A readable summary of the calibration."""
    s = cal.summary()
    lines = []
    if cal.board is not None:
        b = cal.board
        lines.append(
            f"Board: {b.cols} x {b.rows} dots, {b.diameter:g} mm across, {b.pitch:g} mm apart"
            + (", origin marker" if b.origin_marker else "")
        )
    if detection is not None:
        w, h = detection.image_size
        lines.append(
            f"Found all {s.n_points} dots in the {w} x {h} image ({detection.method} finder, "
            f"{detection.polarity} dots, {detection.pitch_px:.1f} px apart)"
        )
    fit = f"{s.solver}" + (" + Levenberg-Marquardt" if s.refine else "")
    lines += [
        f"Homography: {fit}, from {s.n_points} points",
        f"Lens: {cal.lens_note}",
        f"Reprojection error (px): mean {s.mean_px:.3f}, RMS {s.rms_px:.3f}, "
        f"max {s.max_px:.3f} (point {cal.stats.argmax + 1}), min {s.min_px:.3f}",
        f"World coordinates after calibration: |dX| <= {s.max_abs_dx_mm:.3f} mm, "
        f"|dY| <= {s.max_abs_dy_mm:.3f} mm",
        f"Leave-one-out error (mm): mean {s.loo_mean_mm:.3f}, RMS {s.loo_rms_mm:.3f}, "
        f"max {s.loo_max_mm:.3f}",
        "  (each point predicted by a fit made without it: the accuracy to expect at points",
        "  the calibration has not seen; the residuals above flatter the fit)",
    ]
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
)


def points_csv(cal: Calibration) -> str:
    """The per-point table as CSV: point (1-based), its row and column on the board (when
    known), world and image coordinates, reprojection (Table 3), world after calibration
    and deviations (Table 4), and the leave-one-out deviation and error."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    cols = cal.board.cols if cal.board is not None else None
    for i in range(len(cal.world_points)):
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
        ]
        writer.writerow(
            [i + 1, row, col, *(f"{v:.6f}" if math.isfinite(v) else "" for v in values)]
        )
    return buf.getvalue()


def deviation_figure(cal: Calibration) -> bytes:
    """The paper's Figure 5 (dX and dY per point, mm) and a vector field of the deviations
    over the board, as PNG bytes."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

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


def write_report(
    cal: Calibration,
    out_dir: str | os.PathLike[str],
    *,
    image: Any = None,
    detection: Any = None,
) -> list[Path]:
    """Writes points.csv, summary.json, deviations.png and (with an image and its detection)
    detection.png into `out_dir` (created if need be); returns the paths written."""
    from planarcal.drawing import draw_detection, png_bytes

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = [
        atomic_write(out / "points.csv", points_csv(cal)),
        atomic_write(
            out / "summary.json",
            json.dumps(summary_json(cal, detection), indent=2, allow_nan=False) + "\n",
        ),
        atomic_write(out / "deviations.png", deviation_figure(cal)),
    ]
    if image is not None and detection is not None:
        written.append(
            atomic_write(out / "detection.png", png_bytes(draw_detection(image, detection)))
        )
    return written
