"""The lens figure: the residuals before the lens model (a homography alone) and after it,
drawn as arrows over the image at one scale, the distortion it found as a map of how far it
moves each pixel, and the lens models tried."""

from __future__ import annotations

import math
import textwrap
from typing import TYPE_CHECKING, Any

import numpy as np

from planarcal.arguments import F64
from planarcal.calib.calibration import Calibration
from planarcal.images import as_grey
from planarcal.report.figure import new_figure, outline_mm, png
from planarcal.report.fits import fitted_parameters, homography_alone
from planarcal.report.mapping import displacement, masked
from planarcal.report.point_names import plural, point_name

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


_GREEN = "tab:green"


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
    # The key inside the frame's top-right corner (above the axes it met a long title).
    qk = ax.quiverkey(q, 0.84, 0.95, key * scale, f"{key:g} px", labelpos="E", coordinates="axes")
    qk.text.set_bbox({"facecolor": "w", "alpha": 0.85, "linewidth": 0, "pad": 1.5})
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


def _displacement_panel(ax: Axes, fig: Figure, cal: Calibration) -> None:
    """|real - ideal| over the image (px), arrows for its direction, the board's outline and
    the lens centre."""
    _draw_frame(ax, cal, None)
    left, right, bottom, top = _frame_px(cal)
    nx = 161
    ny = max(2, round(nx * (bottom - top) / (right - left)))
    gx, gy = np.meshgrid(np.linspace(left, right, nx), np.linspace(top, bottom, ny))
    disp = displacement(cal, np.column_stack([gx.ravel(), gy.ravel()])).reshape(ny, nx, 2)
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
    outline = masked(cal.world_to_image, outline_mm(cal), 2)
    names = plural(point_name(cal.board), 2)
    ax.plot(outline[:, 0], outline[:, 1], color="tab:cyan", lw=1.8, label=f"board (outer {names})")
    if cal.lens is not None:
        (cx, cy), (sx, sy) = cal.lens.centre_px, cal.lens.centre_std_px
        what = (
            f"lens centre ({cx:.1f} +/- {sx:.1f}, {cy:.1f} +/- {sy:.1f}) px"
            if "centre" in fitted_parameters(cal.lens)
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
    # Below the map, where it covers neither the contours' labels nor the arrows.
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, fontsize=8, facecolor="0.8")
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
    """The lens model, as PNG bytes: the figure `lens_axes` draws."""
    return png(lens_axes(cal, image=image))


def lens_axes(cal: Calibration, *, image: Any = None) -> Figure:
    """The lens model, as a matplotlib figure: the residuals (px) before it (a homography alone) and
    after it, drawn as arrows over the image at one scale, the distortion it found as a map
    of how far it moves each pixel (with the board's outline and the lens centre), and the
    models tried. Without a lens model, the residuals and why there is none (the note).
    `image`: the picture the calibration was made from, drawn faintly behind (optional)."""
    if cal.lens_model == "none":
        has_candidates = bool(cal.lens_candidates)
        fig = new_figure(17 if has_candidates else 10, 6.5)
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
        return fig
    before = homography_alone(cal)
    res_before = before.image_points - before.reprojected_px
    scale, key = _arrow_scale(cal, res_before)
    fig = new_figure(17, 11.5)
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
    return fig
