"""When the board is not found: the image with what the search saw (the blobs, each candidate
grid and why it was refused) and the error, as a figure and as text."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from planarcal.files import atomic_write
from planarcal.report.drawing import rgb_image
from planarcal.report.figure import new_figure, png

if TYPE_CHECKING:
    from matplotlib.axes import Axes


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
    fig = new_figure(16, min(12.0, max(6.5, 10.0 * h / w + 1.5)))
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
    return png(fig)


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
    need be), atomically; returns its path. Without matplotlib (the extra ``planarcal[report]``)
    raises MissingDependencyError, and creates nothing."""
    figure = detection_failure_figure(image, diagnostics, message)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return atomic_write(out / DETECTION_FAILED_PNG, figure)
