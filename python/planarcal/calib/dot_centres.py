"""Sub-pixel centres of a board's dots from their grey levels.

Each dot's centre is the centroid of its darkness: (background - pixel) / (background -
ink), clipped to [0, 1], over a disc around the dot, where the background is a plane fitted
(robustly) to a ring of paper around it and the ink level is the dot's darkest quarter. Edge
pixels count by how much ink they see, so the estimate is sub-pixel without thresholds. On a
photograph the ink's light need not be the paper's scaled (flare, the camera's black level,
the ink's sheen); where a dot's solid pixels show it beyond their noise, the ink gets a plane
of its own and the coverage is (paper - pixel) / (paper - ink). Three passes: each sizes the
dot and re-centres the disc on it.

The windows follow each dot's own size, not the grid's pitch, so an origin marker as wide as
the pitch is measured like a small dot; pixels near the other dots (their measured size and
a margin for blur) are left out of both the disc and the ring, so dots that nearly touch do
not pull each other. A dot that cannot be measured (cut by the image's border, no paper
around it, no contrast) keeps the centre it came with and is flagged, instead of sinking the
board.

The measurement is the core's (planarcal_core::dot_centres, every dot in one call, in
parallel, the GIL released); tests/calib/test_dot_centres.py keeps the NumPy algorithm it was
ported from as its reference.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from planarcal._core import refine_dot_centres

F64 = NDArray[np.float64]

# Why a dot was not refined, by the core's status code (0: refined).
_REASONS = (
    "refined",
    "cut by the image border",
    "no paper around it",
    "too small to measure",
    "no contrast with its background",
    "no ink",
    "its grey levels lead away from it",
)


@dataclasses.dataclass(frozen=True)
class DotCentres:
    centres: F64
    """(N, 2) px."""
    areas: F64
    """(N,) ink area, px^2 (coverage-weighted); pi r^2 of the starting size where not refined."""
    refined: NDArray[np.bool_]
    """(N,) False where the dot kept its starting centre."""
    why_not: tuple[str, ...]
    """For each dot not refined, why (in the order of the dots)."""
    status: NDArray[np.int64] = dataclasses.field(
        default_factory=lambda: np.zeros(0, dtype=np.int64)
    )
    """(N,) the core's code of why each dot was not refined (0: refined); see
    not_refined_reasons."""


def not_refined_reasons(status: NDArray[np.int64]) -> tuple[str, ...]:
    """ "dot k: why" for each dot whose `status` is not 0, k its position in `status` (the
    dots' index once `status` is in the board's order)."""
    return tuple(f"dot {k}: {_REASONS[code]}" for k, code in enumerate(status.tolist()) if code)


def refine_centres(ink_dark: NDArray[np.float32], points: F64, diameters: F64) -> DotCentres:
    """Sub-pixel centres and ink areas of the dark dots starting at `points` (N, 2) with
    approximate `diameters` (N,) px (a blob's size is enough).

    ValueError for an image that is not H x W, points that are not N x 2 or not finite, or
    diameters that are not one finite number >= 0 per point."""
    centres, areas, status = refine_dot_centres(
        ink_dark, np.asarray(points, dtype=np.float64), np.asarray(diameters, dtype=np.float64)
    )
    codes = np.asarray(status, dtype=np.int64)
    return DotCentres(centres, areas, codes == 0, not_refined_reasons(codes), codes)
