"""The deviation figure: the paper's Figure 5 (dX and dY per point, mm) and a vector field of
the deviations over the board."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planarcal.calib.calibration import Calibration
from planarcal.report.figure import new_figure, png
from planarcal.report.point_names import calibration_ids, numbering, point_name

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def deviation_figure(cal: Calibration) -> bytes:
    """The paper's Figure 5 (dX and dY per point, mm, over the points' ids) and a vector
    field of the deviations over the board, as PNG bytes."""
    return png(deviation_axes(cal))


def deviation_axes(cal: Calibration) -> Figure:
    """The deviation figure (a matplotlib Figure, see deviation_figure), so that its texts
    can be measured."""
    dev = cal.deviations_mm
    loo = cal.loo_deviations_mm
    idx = calibration_ids(cal)  # the points' ids, 0 the origin, as everywhere
    point = point_name(cal.board)
    fig = new_figure(12, 8)
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
    ax_dy.set_xlabel(f"{point} ({numbering(cal.board)})")
    s = cal.summary()
    # Both units: the mm scale with the stated pitch, the px do not. Two lines: one ran
    # past the figure's left edge.
    ax_dx.set_title(
        f"Calibration deviation per {point} (the paper's Figure 5)\nleave-one-out RMS "
        f"{s.loo_rms_mm:.3f} mm, {s.loo_rms_px:.3f} px in the image"
    )
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
    return fig
