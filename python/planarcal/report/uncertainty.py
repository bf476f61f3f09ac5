"""The uncertainty figure: the 1-sigma position uncertainty of an exact pixel (mm, from the
fit's covariance and the model's bias, calib.error_budget) as a heat map over the working
area on the plane, with where it doubles relative to the board's centre; the title says
what a located part's own centroid error adds. When the points cover only part of the image
(a partial view, a board in one corner) the working area is the whole image, and the title
carries the calibration's warning that the rest is extrapolated."""

from __future__ import annotations

import textwrap
from typing import TYPE_CHECKING

import numpy as np

from planarcal.arguments import F64
from planarcal.calib.calibration import Calibration
from planarcal.calib.error_budget import OUTLINE_CENTROID_SIGMA_PX
from planarcal.report.figure import new_figure, outline_mm, png
from planarcal.report.mapping import MAP_ERRORS, mappable, masked
from planarcal.report.point_names import calibration_ids, plural, point_name

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _extrapolation_warning(cal: Calibration) -> str | None:
    """The calibration's warning that most of the image is extrapolated, if it gives one."""
    try:
        ex = getattr(cal, "extrapolation", None)
    except (ValueError, ArithmeticError):
        return None
    warning = getattr(ex, "warning", None)
    return warning if isinstance(warning, str) and warning else None


def _partial(cal: Calibration) -> bool:
    """Whether the calibration holds only some of its board's points."""
    board = cal.board
    return board is not None and len(calibration_ids(cal)) < board.n_points


def _whole_image(cal: Calibration) -> bool:
    """Whether the working area is the whole image: the points cover only part of what the
    camera will be used for (a partial view, or the calibration warns of extrapolation)."""
    return cal.image_size is not None and (_partial(cal) or _extrapolation_warning(cal) is not None)


def _working_region_px(cal: Calibration) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1): the image region around the board, extended by half the board's
    size each way, clipped to the image; the whole image when the points cover only part of
    it (``_whole_image``)."""
    if cal.image_size is not None and _whole_image(cal):
        w, h = cal.image_size
        return 0.0, w - 1.0, 0.0, h - 1.0
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
    """The uncertainty map (see uncertainty_axes) as PNG bytes."""
    return png(uncertainty_axes(cal))


def uncertainty_axes(cal: Calibration) -> Figure:
    """The 1-sigma position uncertainty of an exact pixel (mm, from the fit's covariance and
    the model's bias) as a heat map over
    the working area (the image region around the board, extended by half the board's size
    each way and clipped to the image) on the plane, in mm, with the board's dots, contour
    lines at multiples of the uncertainty at the board's centre and the line where it
    doubles marked, as a matplotlib Figure (its texts can be measured). Pixels with no place
    on the plane (beyond the lens model's valid radius, past the horizon) are left blank."""
    fig = new_figure(11, 8.5)  # first: it checks that matplotlib is installed
    from matplotlib.colors import LogNorm, Normalize  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)
    from matplotlib.tri import Triangulation  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)

    ax = fig.add_subplot()
    world = cal.world_points
    centre_mm = 0.5 * (world.min(axis=0) + world.max(axis=0))
    try:
        _, centre_std = cal.image_to_world(
            cal.world_to_image(centre_mm), return_std=True, pixel_sigma=0.0
        )
        _, part_std = cal.image_to_world(cal.world_to_image(centre_mm), return_std=True)
    except MAP_ERRORS as e:
        ax.text(
            0.5,
            0.5,
            textwrap.fill(f"No uncertainty map: {e}", 70),
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
        ax.set_axis_off()
        return fig
    x0, x1, y0, y1 = _working_region_px(cal)
    nx = 201
    ny = max(2, round(nx * (y1 - y0) / max(x1 - x0, 1e-9)))
    gx, gy = np.meshgrid(np.linspace(x0, x1, nx), np.linspace(y0, y1, ny))
    px = np.column_stack([gx.ravel(), gy.ravel()])

    def mapped(p: F64) -> F64:
        mm, std = cal.image_to_world(p, return_std=True, pixel_sigma=0.0)
        return np.column_stack([mm, std])

    out = np.full((len(px), 3), np.nan)
    ok = mappable(cal, px)
    out[ok] = masked(mapped, px[ok], 3)
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
        return fig
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
    name = point_name(cal.board)
    names = plural(name, 2)
    partial = _partial(cal)
    outline = outline_mm(cal)
    seen = f"{names} seen" if partial else names
    ax.plot(outline[:, 0], outline[:, 1], color="w", lw=1.0, ls="--", label=f"board (outer {seen})")
    if partial and cal.board is not None:
        whole = cal.board.world_points() * np.asarray(cal.world_scale, dtype=np.float64)
        (bx0, by0), (bx1, by1) = whole.min(axis=0), whole.max(axis=0)
        ax.plot(
            [bx0, bx1, bx1, bx0, bx0],
            [by0, by0, by1, by1, by0],
            color="tab:orange",
            lw=1.2,
            ls=":",
            label=f"whole board (outer {names}, not all seen)",
        )
    ax.scatter(
        world[:, 0],
        world[:, 1],
        s=6,
        color="k",
        edgecolors="w",
        linewidths=0.4,
        label=f"board's {seen}",
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
        ncols=3 if partial else 4,  # a partial view's fifth entry: two rows of three
        fontsize=9,
        facecolor="0.75",
        markerscale=1.5,
    )
    ax.set_aspect("equal")
    ax.invert_yaxis()  # Y runs down the board, as printed
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    clipped = ", clipped to the image" if cal.image_size is not None else ""
    area = (
        f"the whole image (the {names} seen cover only part of it)"
        if _whole_image(cal)
        else f"the board's image region extended by half its size each way{clipped}"
    )
    warning = _extrapolation_warning(cal)
    title = (
        "1-sigma position uncertainty on the plane of an exact pixel, from the fit's covariance "
        "and the model's bias\n"
        f"(a located part's centroid error, {OUTLINE_CENTROID_SIGMA_PX:g} px, makes it "
        f"{part_std:.3g} mm at the board's centre)\n"
        f"Working area: {area}."
        f"\n{c:.3g} mm at the board's centre; white contours at multiples of it; {where}"
        + ("" if warning is None else "\n" + textwrap.fill(f"Warning: {warning}", 110))
    )
    ax.set_title(title, fontsize=10, color="k" if warning is None else "tab:red")
    # A warning's lines make the title taller: the figure grows with it, or the layout
    # pushes the title off the top and the legend off the bottom (measured at 8.5 in).
    fig.set_size_inches(11, 8.5 + 0.3 * max(0, title.count("\n") + 1 - 4))
    return fig
