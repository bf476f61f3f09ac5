"""The dots' sizes measured on the board, and the board's description checked against them.

One image of a plane cannot measure its pitch (a board twice as large, twice as far away,
looks the same), but it does measure every size relative to the pitch: each dot's ink area,
taken through the homography's local scale onto the board, is its diameter in the board's
millimetres at the *stated* pitch. A stated diameter that disagrees with it, beyond what the
measurement allows, means the diameter or the pitch is wrong, and a wrong pitch scales every
millimetre the calibration reports (its errors included: a pitch stated ten times too small
reports errors ten times too small). So does an origin marker whose stated size, relative to
the dots, disagrees with the measured one.

What the measurement allows was measured on rendered boards with exact truth (tilt to 45
degrees, blur 0.1-2.5 px, noise, JPEG, barrel distortion, a camera response of gamma 0.45 (sRGB)
to 1.6, dot to pitch ratios 0.12 to 0.85, 320 x 180 to 1600 x 1200) and on the real
photographs: the regular dots' median diameter strays from the printed one by at most about
1.0 times the edges' blur (sigma) over the dots' size in the image, 2 % on the real
photographs; the tolerance is 4 % plus 1.5 times that ratio (7-9 % on the real photographs,
6-13 % on sharp renders). Over 348 random renders no right description was refused (the worst
used 75 % of its tolerance) and a diameter stated 25 % too large was refused in 121 of the 126
that could be checked (the other five: small, blurred dots, where the measurement allows
more). An overexposed image (the paper clipped at the top grey level) shrinks dark dots by up
to 45 %, and dots under 10 px across are swollen by blur by up to 35 % (their windows too
small to measure the blur): there the sizes are reported but not checked.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planarcal.calib.board import CircleGridBoard
from planarcal.errors import BoardMismatchError

F64 = NDArray[np.float64]

# The relative disagreement between a stated size and the measured one that the measurement
# allows: SIZE_TOLERANCE plus SIZE_TOLERANCE_PER_BLUR times the edges' blur (sigma) over the
# dots' diameter in the image. Measured bias on rendered boards: at most 1.0 times that
# ratio (blur 0.3-2.5 px, gamma 0.45-1.6, tilt to 40 degrees, JPEG), 2 % on real photographs.
SIZE_TOLERANCE = 0.04
SIZE_TOLERANCE_PER_BLUR = 1.5
# Dots smaller than this in the image (px across) are not checked: blur swells them by up to
# 35 % (at 6-8 px), and their windows are too small to measure the blur.
MIN_CHECKED_DOT_PX = 10.0
# A tolerance beyond this checks nothing worth checking.
MAX_SIZE_TOLERANCE = 0.4
# The paper counts as overexposed when this share of the points midway between neighbouring
# dots is at the top grey level (an 8-bit image's 255).
CLIPPED_PAPER_SHARE = 0.25
TOP_GREY = 254.5


@dataclasses.dataclass(frozen=True)
class DotSizes:
    """The dots' sizes measured on the board (mm at the stated pitch) and how far the
    measurement can be trusted."""

    diameter_mm: float
    """The regular dots' diameter: the median over them, mm at the board's stated pitch."""
    marker_mm: float | None
    """The origin marker's diameter (dot 0's, when the reading found the marker), mm."""
    dot_px: float
    """The regular dots' median diameter in the image, px."""
    tolerance: float | None
    """The relative disagreement with a stated size the measurement allows; None where the
    sizes cannot be checked (``unchecked`` says why)."""
    unchecked: str | None = None
    blur_px: float = math.nan
    """The blur of the dots' edges (a Gaussian's sigma, px), from which the tolerance
    follows."""

    def diameter_to_pitch(self, board: CircleGridBoard) -> float:
        """The measured diameter over the pitch: what one image can measure."""
        return self.diameter_mm / float(board.pitch)

    def to_dict(self, board: CircleGridBoard) -> dict[str, object]:
        """The JSON-ready form (the summary's ``detection.dot_sizes``)."""
        return {
            "diameter_mm": self.diameter_mm,
            "diameter_to_pitch": self.diameter_to_pitch(board),
            "marker_mm": self.marker_mm,
            "dot_px": self.dot_px,
            "tolerance": self.tolerance,
            "unchecked": self.unchecked,
            "blur_px": self.blur_px,
        }


def measured_sizes(
    board: CircleGridBoard,
    diameters_mm: F64,
    enlarged: NDArray[np.bool_],
    diameters_px: F64,
    marker: bool,
    ink_dark: NDArray[np.float32],
    points: F64,
    ids: NDArray[np.intp] | None = None,
) -> DotSizes:
    """The sizes of a detection: each dot's diameter on the board (mm), which dots are
    enlarged, their diameters in the image (px), whether dot 0 is the origin marker, and the
    ink image (dots dark) with the dots' centres, which say how far the sizes can be trusted.
    The dots are board points ``ids`` (ascending; every dot in board order when None: a
    partial view measures the dots it found)."""
    ids = np.arange(board.n_points) if ids is None else np.asarray(ids, dtype=np.intp)
    regular = ~enlarged if (~enlarged).any() else np.ones(len(enlarged), dtype=bool)
    diameter = float(np.median(diameters_mm[regular]))
    dot_px = float(np.median(diameters_px[regular]))
    marker_mm = float(diameters_mm[0]) if marker and len(ids) and ids[0] == 0 else None
    clipped = clipped_paper_share(ink_dark, points, board, ids)
    blur = edge_blur_px(ink_dark, points, diameters_px, regular)
    tolerance = SIZE_TOLERANCE + SIZE_TOLERANCE_PER_BLUR * blur / dot_px
    unchecked = None
    if clipped >= CLIPPED_PAPER_SHARE:
        unchecked = (
            f"the paper is overexposed ({100 * clipped:.0f} % of it at the top grey level), "
            "which shrinks the dots in the image"
        )
    elif dot_px < MIN_CHECKED_DOT_PX:
        unchecked = (
            f"the dots are {dot_px:.1f} px across in the image, too few to size them (blur "
            "swells small dots)"
        )
    elif not math.isfinite(blur):
        unchecked = "the dots' edges could not be measured"
    elif not tolerance <= MAX_SIZE_TOLERANCE:
        unchecked = f"the dots' edges are too blurred ({blur:.1f} px) to size them"
    return DotSizes(diameter, marker_mm, dot_px, None if unchecked else tolerance, unchecked, blur)


def clipped_paper_share(
    ink_dark: NDArray[np.float32],
    points: F64,
    board: CircleGridBoard,
    ids: NDArray[np.intp] | None = None,
) -> float:
    """The share of the points midway between neighbours along a row (paper, whatever the
    dots' size) that are at the top grey level of the ink image (paper light); `points` are
    the board points `ids` (ascending; all of them when None)."""
    ids = np.arange(board.n_points) if ids is None else np.asarray(ids, dtype=np.intp)
    # Pairs of found dots next to each other along a row.
    at = np.searchsorted(ids, ids + 1)
    at = np.minimum(at, max(len(ids) - 1, 0))
    pair = (ids % board.cols != board.cols - 1) & (ids[at] == ids + 1) if len(ids) else ids > 0
    left = np.flatnonzero(pair)
    middle = np.rint(0.5 * (points[left] + points[at[left]])).astype(np.int64)
    h, w = ink_dark.shape[:2]
    inside = (middle[:, 0] >= 0) & (middle[:, 0] < w) & (middle[:, 1] >= 0) & (middle[:, 1] < h)
    if not inside.any():
        return 0.0
    values = ink_dark[middle[inside, 1], middle[inside, 0]]
    return float(np.mean(values >= TOP_GREY))


def check_description(board: CircleGridBoard, sizes: DotSizes) -> None:
    """BoardMismatchError where the board's stated diameter (against its pitch) or its
    stated origin marker (against its dots) disagrees with the measured sizes beyond
    ``sizes.tolerance``; nothing where the board states neither or the sizes cannot be
    checked."""
    tol = sizes.tolerance
    if tol is None:
        return
    pitch = float(board.pitch)
    if board.diameter is not None and _disagree(sizes.diameter_mm, board.diameter, tol):
        raise BoardMismatchError(
            f"the board's dots measure {sizes.diameter_mm:.3g} mm across at the stated pitch of "
            f"{pitch:g} mm ({sizes.diameter_mm / pitch:.2f} of the pitch), but the board says "
            f"{board.diameter:g} mm ({board.diameter / pitch:.2f}): the diameter or the pitch is "
            f"wrong (the measurement allows {100 * tol:.0f} %). Measure both with a rule: a "
            "wrong pitch scales every millimetre the calibration reports, its errors too. If "
            "both are right (an overexposed or badly blurred image misleads the measurement), "
            "leave the diameter out (no --diameter; diameter=None) to calibrate without this check."
        )
    if board.marker_diameter is None or sizes.marker_mm is None:
        return
    if board.diameter is not None:
        stated = board.marker_diameter / board.diameter
        measured = sizes.marker_mm / sizes.diameter_mm
        if _disagree(measured, stated, tol):
            raise BoardMismatchError(
                f"the origin marker measures {measured:.2f} times the dots' diameter, but the "
                f"board says {stated:.2f} ({board.marker_diameter:g} mm to {board.diameter:g} "
                f"mm; the measurement allows {100 * tol:.0f} %): check --marker-diameter and "
                "--diameter"
            )
    elif _disagree(sizes.marker_mm, board.marker_diameter, tol):
        raise BoardMismatchError(
            f"the origin marker measures {sizes.marker_mm:.3g} mm across at the stated pitch of "
            f"{pitch:g} mm, but the board says {board.marker_diameter:g} mm: the marker's "
            f"diameter or the pitch is wrong (the measurement allows {100 * tol:.0f} %)"
        )


def _disagree(measured: float, stated: float, tolerance: float) -> bool:
    """Whether two positive sizes differ by more than the relative `tolerance`, either way."""
    if not (math.isfinite(measured) and measured > 0):
        return False
    return max(measured / stated, stated / measured) > 1.0 + tolerance


# Dots sampled for the edge's blur, and how far beyond a dot's edge its window reaches (px:
# beyond 3 sigma of the blurs that leave a dot measurable).
BLUR_SAMPLE = 40
BLUR_REACH_PX = 8.0


def edge_blur_px(
    ink_dark: NDArray[np.float32], points: F64, diameters_px: F64, regular: NDArray[np.bool_]
) -> float:
    """The blur of the dots' edges, px: a Gaussian's sigma, the median over up to
    BLUR_SAMPLE regular dots. Within BLUR_REACH_PX of its edge and half the distance to its
    nearest neighbour (paper all round, whatever the dots' size), a dot's coverage c =
    (paper - pixel) / (paper - ink) (paper its window's 90th percentile, ink its 3rd) sums
    c (1 - c) to sigma / sqrt(pi) along each unit of its edge, whose length is that of the
    circle of the dot's coverage. Pixels within 5 % of paper or ink are left out, so noise
    on them adds nothing; what noise is left makes the blur err large."""
    nearest, _ = cKDTree(points).query(points, k=2)
    h, w = ink_dark.shape[:2]
    chosen = np.flatnonzero(regular)
    chosen = chosen[np.linspace(0, len(chosen) - 1, min(BLUR_SAMPLE, len(chosen))).astype(int)]
    blurs = []
    for k in chosen:
        (x, y) = points[k]
        r = min(0.5 * float(nearest[k, 1]), 0.5 * float(diameters_px[k]) + BLUR_REACH_PX)
        x0, x1 = max(0, int(x - r)), min(w, int(x + r) + 2)
        y0, y1 = max(0, int(y - r)), min(h, int(y + r) + 2)
        if x1 - x0 < 3 or y1 - y0 < 3:
            continue
        yy, xx = np.mgrid[y0:y1, x0:x1]
        values = ink_dark[y0:y1, x0:x1][(xx - x) ** 2 + (yy - y) ** 2 <= r * r]
        if values.size < 9:
            continue
        paper, ink = np.percentile(values, (90.0, 3.0))
        if paper - ink <= 0:
            continue
        c = np.clip((paper - values) / (paper - ink), 0.0, 1.0)
        perimeter = 2.0 * np.pi * np.sqrt(float(c.sum()) / np.pi)
        edge = c[(c > 0.05) & (c < 0.95)]
        if perimeter > 0:
            blurs.append(np.sqrt(np.pi) * float((edge * (1.0 - edge)).sum()) / perimeter)
    return float(np.median(blurs)) if blurs else math.nan
