"""When the board is not found: the image with what the search saw (the blobs, each candidate
grid and why it was refused) and the error, as a figure and as text.

Any board's detector may fail, and each keeps its own record of what it saw: the circle
grid's (planarcal.calib.detect.DetectionDiagnostics) its blobs and refused candidate grids,
the chessboard's (planarcal.calib.detect_chessboard.ChessboardDiagnostics) the finders tried
and the largest grid of corners seen. A record is drawn as far as it has these parts (its
``board``, ``image_size``, ``blobs``, ``candidates``, ``grid_points_px`` with
``grid_shape``, ``attempts``), whatever its class; none at all (None) leaves the image and
the message."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from planarcal.files import atomic_write
from planarcal.report.drawing import rgb_image
from planarcal.report.figure import new_figure, png
from planarcal.report.point_names import is_circle_grid

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


F64 = NDArray[np.float64]

DETECTION_FAILED_PNG = "detection_failed.png"
"""The failure figure's name in the report directory."""


_BLOB_COLOURS = {"dark": "tab:blue", "light": "tab:orange"}


_CANDIDATE_COLOURS = ("tab:red", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:cyan")


def detection_failure_figure(image: Any, diagnostics: Any, message: str) -> bytes:
    """The failure figure (see detection_failure_axes) as PNG bytes."""
    return png(detection_failure_axes(image, diagnostics, message))


def detection_failure_axes(image: Any, diagnostics: Any, message: str) -> Figure:
    """What a failed search saw, as a matplotlib Figure (its texts can be measured): the
    image with the blobs of each polarity (circles of their diameter), each candidate grid
    (its points joined in order, numbered and labelled with its finder and polarity), and
    beside it the error message and why each candidate was refused. `diagnostics`: a
    DetectionDiagnostics, or None (the image and the message alone; a record of another
    kind, as far as it has the parts drawn)."""
    picture = rgb_image(image)
    h, w = picture.shape[:2]
    # The image panel is about 10 in wide: a height that fits its aspect, room for the text.
    fig = new_figure(16, min(12.0, max(6.5, 10.0 * h / w + 1.5)))
    grid = fig.add_gridspec(1, 2, width_ratios=(1.8, 1))
    ax = fig.add_subplot(grid[0, 0])
    ax.imshow(picture, interpolation="nearest")
    if diagnostics is not None:
        _draw_seen_blobs(ax, _blobs(diagnostics))
        _draw_candidates(ax, _candidates(diagnostics))
        _draw_grid_seen(ax, _grid_seen(diagnostics))
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
    return fig


def _blobs(diagnostics: Any) -> list[tuple[str, F64, F64]]:
    """The record's blobs as (polarity, centres (N, 2) px, diameters (N,) px), those it
    holds in that shape; none when it has no blobs."""
    out = []
    for seen in _sequence(getattr(diagnostics, "blobs", None)):
        centres = _array(getattr(seen, "centres_px", None))
        diameters = _array(getattr(seen, "diameters_px", None))
        if centres is None or diameters is None or centres.size != 2 * diameters.size:
            continue
        out.append((str(getattr(seen, "polarity", "")), centres.reshape(-1, 2), diameters))
    return out


def _candidates(diagnostics: Any) -> list[tuple[str, str, F64, str]]:
    """The record's refused candidates as (method, polarity, points (K, 2) px, reason);
    none when it has none."""
    out = []
    for cand in _sequence(getattr(diagnostics, "candidates", None)):
        points = _array(getattr(cand, "points_px", None))
        if points is None or points.size % 2:
            continue
        out.append(
            (
                str(getattr(cand, "method", "?")),
                str(getattr(cand, "polarity", "")),
                points.reshape(-1, 2),
                str(getattr(cand, "reason", "")),
            )
        )
    return out


def _grid_seen(diagnostics: Any) -> tuple[F64, tuple[int, int] | None] | None:
    """The largest grid of points the record saw (K, 2) px, with its shape (across, down)
    when it gives one that fits; None when it saw none."""
    points = _array(getattr(diagnostics, "grid_points_px", None))
    if points is None or not points.size or points.size % 2:
        return None
    shape: Any = getattr(diagnostics, "grid_shape", None)
    try:
        across, down = (int(v) for v in shape)
    except (TypeError, ValueError):
        return points.reshape(-1, 2), None
    fits = across > 0 and down > 0 and across * down * 2 == points.size
    return points.reshape(-1, 2), (across, down) if fits else None


def _draw_grid_seen(ax: Axes, grid: tuple[F64, tuple[int, int] | None] | None) -> None:
    """The largest grid of points seen: its rows joined, in the legend with its size."""
    if grid is None:
        return
    points, shape = grid
    rows = [points] if shape is None else list(points.reshape(shape[1], shape[0], 2))
    label = f"largest grid seen: {len(points)} points"
    if shape is not None:
        label = f"largest grid seen: {shape[0]} x {shape[1]}"
    for k, row in enumerate(rows):
        ax.plot(
            row[:, 0],
            row[:, 1],
            "o-" if shape is not None else "o",
            color="tab:red",
            lw=1.0,
            ms=3,
            alpha=0.85,
            label=label if k == 0 else None,
        )


def _attempts(diagnostics: Any) -> list[str]:
    """What the record says each finder tried did, as text."""
    return [str(a) for a in _sequence(getattr(diagnostics, "attempts", None))]


def _sequence(value: Any) -> tuple[Any, ...]:
    return tuple(value) if isinstance(value, list | tuple) else ()


def _array(value: Any) -> F64 | None:
    """A finite float array of `value`, or None when it is not one."""
    try:
        out = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        return None
    return out if np.isfinite(out).all() else None


def _draw_seen_blobs(ax: Axes, blobs: list[tuple[str, F64, F64]]) -> None:
    """Each polarity's blobs as circles of their diameter, one colour per polarity."""
    from matplotlib.collections import PatchCollection  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)
    from matplotlib.lines import Line2D  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)
    from matplotlib.patches import Circle  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)

    for polarity, centres, diameters in blobs:
        colour = _BLOB_COLOURS.get(polarity, "tab:gray")
        circles = [
            Circle((float(x), float(y)), 0.5 * float(d))
            for (x, y), d in zip(centres, diameters, strict=True)
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
                label=f"{len(circles)} {_word(polarity)}blobs seen",
            )
        )


def _draw_candidates(ax: Axes, candidates: list[tuple[str, str, F64, str]]) -> None:
    """Each refused candidate grid: its points joined in order, its number at its first
    point, its finder and polarity in the legend."""
    for k, (method, polarity, pts, _) in enumerate(candidates):
        colour = _CANDIDATE_COLOURS[k % len(_CANDIDATE_COLOURS)]
        ax.plot(
            pts[:, 0],
            pts[:, 1],
            "o-",
            color=colour,
            lw=1.0,
            ms=2.5,
            alpha=0.85,
            label=f"{k + 1}: {method}{_polarity(polarity)} ({len(pts)} points)",
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
    looking = _looking_for(diagnostics)
    if looking:
        paragraphs.append(textwrap.fill(looking, width))
    blobs, candidates = _blobs(diagnostics), _candidates(diagnostics)
    for polarity, _, d in blobs:
        size = f", about {float(np.median(d)):.0f} px across" if d.size else ""
        paragraphs.append(f"Blobs seen: {len(d)}{' ' * bool(polarity)}{polarity}{size}")
    grid = _grid_seen(diagnostics)
    if grid is not None:
        points, shape = grid
        size = f"{shape[0]} x {shape[1]} points" if shape is not None else f"{len(points)} points"
        paragraphs.append(f"Largest grid seen: {size}")
    attempts = _attempts(diagnostics)
    if attempts:
        paragraphs += ["", "Tried:"]
        paragraphs += [
            textwrap.fill(f"- {a}", width, subsequent_indent="  ") for a in attempts[:most]
        ]
        if len(attempts) > most:
            paragraphs.append(f"... and {len(attempts) - most} more")
    if not hasattr(diagnostics, "candidates"):
        return "\n".join(paragraphs)  # a record that keeps no candidates: nothing to add
    paragraphs.append("")
    if not candidates:
        paragraphs.append("No candidate grid was put forward.")
    else:
        paragraphs.append("Candidate grids refused:")
        for k, (method, polarity, _, reason) in enumerate(candidates[:most]):
            paragraphs.append(
                textwrap.fill(
                    f"{k + 1}. {method}{_polarity(polarity, ' (', ')')}: {reason}",
                    width,
                    subsequent_indent="   ",
                )
            )
        if len(candidates) > most:
            paragraphs.append(f"... and {len(candidates) - most} more")
    return "\n".join(paragraphs)


def _polarity(polarity: str, before: str = ", ", after: str = "") -> str:
    """ "dark dots" as a candidate's label says it, or nothing for a record without one."""
    return f"{before}{polarity} dots{after}" if polarity else ""


def _word(polarity: str) -> str:
    """ "dark " before "blobs", nothing for a record without a polarity."""
    return f"{polarity} " if polarity else ""


def _looking_for(diagnostics: Any) -> str:
    """What the search looked for, where: "Looking for 14 x 10 dots in the 1280 x 720
    image." (a circle grid), the board's own description for another; empty when the record
    says neither."""
    board: Any = getattr(diagnostics, "board", None)
    if is_circle_grid(board):
        what = f"{board.cols} x {board.rows} dots"
    elif hasattr(board, "describe"):
        what = f"a {board.describe()}"
    else:
        what = "the board"
    size: Any = getattr(diagnostics, "image_size", None)
    try:
        w, h = (int(v) for v in size)
    except (TypeError, ValueError):
        return "" if board is None else f"Looking for {what}."
    return f"Looking for {what} in the {w} x {h} image."


def write_detection_failure(
    out_dir: str | os.PathLike[str], image: Any, diagnostics: Any, message: str
) -> Path:
    """Writes ``detection_failure_figure`` as detection_failed.png into `out_dir` (created if
    need be), atomically; returns its path. Without matplotlib (the extra ``planarcal[report]``)
    raises MissingDependencyError, and creates nothing."""
    figure = detection_failure_figure(image, diagnostics, message)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return atomic_write(out / DETECTION_FAILED_PNG, figure)
