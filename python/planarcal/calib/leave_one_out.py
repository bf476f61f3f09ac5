"""Leave-one-out without a lens model: each point mapped by a homography fitted to all the
others (with a lens model the core's FittedPlane does this itself, PlaneFit.loo)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from planarcal.errors import HomographyError
from planarcal.homography import Solver, estimate_homography, transform_points

F64 = NDArray[np.float64]


def homography_leave_one_out(
    world: F64,
    ideal: F64,
    solver: Solver,
    refine: bool,
    distort: Callable[[F64], F64],
) -> tuple[F64, F64]:
    """(image px, world mm) of each point under a homography fitted without it: world (N, 2)
    mm, `ideal` its (undistorted) pixels, `distort` ideal pixels -> real ones. NaN where the
    rest cannot determine a homography."""
    n = len(world)
    nan = np.full((n, 2), np.nan)
    if n <= 4:
        # Without one point only 3 remain: no homography can be fitted.
        return nan, nan.copy()
    px, mm = nan.copy(), nan.copy()
    keep = np.ones(n, dtype=bool)
    for i in range(n):
        keep[i] = False
        try:
            h = estimate_homography(world[keep], ideal[keep], solver, refine)
            mm[i] = transform_points(h, ideal[i : i + 1], inverse=True)[0]
            px[i] = distort(transform_points(h, world[i : i + 1]))[0]
        except HomographyError:
            pass  # the rest cannot determine a homography
        keep[i] = True
    return px, mm
