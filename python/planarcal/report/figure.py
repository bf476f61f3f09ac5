"""What every figure of the report shares: the one check that matplotlib (the optional extra
``planarcal[report]``) is there, a matplotlib figure drawn without choosing a backend, its PNG
bytes, and the board's outline on the plane."""

from __future__ import annotations

import io
from typing import TYPE_CHECKING

import numpy as np

from planarcal.arguments import F64
from planarcal.calib.calibration import Calibration
from planarcal.errors import MissingDependencyError

if TYPE_CHECKING:
    from matplotlib.figure import Figure

MATPLOTLIB_MISSING = (
    "the report's figures need matplotlib, which is not installed: pip install 'planarcal[report]'"
)
"""What drawing a figure says when matplotlib is not installed (`planarcal calibrate --report`
says it before any work)."""


def require_matplotlib() -> None:
    """Loads matplotlib for the report's figures, or raises MissingDependencyError saying how
    to install it. Every figure is drawn after this check; it is cheap once matplotlib is
    loaded."""
    try:
        import matplotlib.figure  # noqa: F401, PLC0415 (loaded only when a figure is drawn)
    except ImportError as e:
        if not (isinstance(e, ModuleNotFoundError) and e.name == "matplotlib"):
            # Installed but broken (a dependency of its own missing, a binary that does not
            # load): say what failed.
            raise MissingDependencyError(
                f"the report's figures need matplotlib, which is installed but cannot be "
                f"imported ({e}): pip install --force-reinstall matplotlib",
                name="matplotlib",
            ) from e
        raise MissingDependencyError(MATPLOTLIB_MISSING, name="matplotlib") from e


def new_figure(width: float, height: float) -> Figure:
    """A figure `width` x `height` inches at 100 dpi, laid out by matplotlib's constrained
    layout. Raises MissingDependencyError without matplotlib."""
    require_matplotlib()
    # The OO API alone: savefig renders through Agg without a backend being chosen, and
    # choosing one (matplotlib.use) would change the backend of the user's own plots.
    from matplotlib.figure import Figure  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)

    return Figure(figsize=(width, height), dpi=100, layout="constrained")


def png(fig: Figure) -> bytes:
    """The figure rendered as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def outline_mm(cal: Calibration, per_edge: int = 60) -> F64:
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
