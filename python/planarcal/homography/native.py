"""The native API: fit a homography, map points through it, measure the fit.

Points are arrays of shape (N, 2), (N, 1, 2) or (1, N, 2), any real dtype, or nested lists;
everything is computed in float64. A homography H maps source points to destination points,
dst ~ H src. Matrices returned here are *oriented*: the points they were fitted on have
w > 0 (they are in front of the camera), and they are scaled so H[2, 2] = 1 (it is -1 only
when the source origin lies behind the horizon, and H is scaled to unit norm when H[2, 2] is
negligible). A point that maps to infinity, or behind the horizon, has no image: it is
reported (``PointAtInfinityError``), never silently turned into a number.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import _core

Solver = Literal["normalized_dlt", "svd", "a33"]
"""The linear solvers: Hartley-normalised DLT (default), plain SVD DLT, the paper's a33 = 1."""

SOLVERS: tuple[Solver, ...] = ("normalized_dlt", "svd", "a33")


def estimate_homography(
    src: ArrayLike,
    dst: ArrayLike,
    solver: Solver = "normalized_dlt",
    refine: bool = False,
) -> NDArray[np.float64]:
    """Fit H with dst ~ H src; returns H, a (3, 3) float64 array.

    ``solver`` picks the linear estimate: ``"normalized_dlt"`` (Hartley normalisation, the
    most accurate linear solver), ``"svd"`` (the plain DLT on raw coordinates, a baseline),
    or ``"a33"`` (the paper's least squares with a33 = 1). ``refine=True`` then minimises the
    transfer error in the destination by Levenberg-Marquardt: the maximum-likelihood
    estimate for Gaussian noise in ``dst``.

    Raises ``ArgumentError`` (a ``ValueError``) for malformed input: shapes, dtypes, sets of
    different lengths, an unknown solver, a NaN or infinite coordinate (its ``point_set``
    ``"src"`` or ``"dst"`` and ``index`` name it). Raises ``HomographyError`` (a
    ``ValueError``) when valid points give no homography: fewer than 4, or its subclass
    ``DegenerateError`` when their geometry does not determine one (collinear, too few
    distinct points, ...).
    """
    return _core.estimate_homography(src, dst, solver, refine)


def transform_points(
    H: ArrayLike,
    points: ArrayLike,
    *,
    inverse: bool = False,
    invalid: Literal["raise", "nan"] = "raise",
) -> NDArray[np.float64]:
    """Map points through H (or H^-1 with ``inverse=True``); returns (N, 2) float64.

    A point that maps to infinity or behind the horizon (w <= 0 under the oriented H) raises
    ``PointAtInfinityError`` naming it (its ``index`` is the first such point; a NaN or
    infinite input point counts as one); with ``invalid="nan"`` it becomes a NaN row instead.
    H is taken as oriented, as ``estimate_homography`` returns it. A matrix scaled by OpenCV's
    H[2,2] = 1 convention is oriented too unless the source origin lies beyond the horizon;
    then every point reports as behind it and the message says so (pass -H). For matrices of
    unknown sign, ``perspectiveTransform`` reports only points at infinity.
    """
    return _core.transform_points(H, points, inverse, invalid)


def reprojection_errors(
    H: ArrayLike,
    src: ArrayLike,
    dst: ArrayLike,
    *,
    invalid: Literal["raise", "inf"] = "raise",
) -> NDArray[np.float64]:
    """Per-point reprojection error ||dst_i - H src_i|| (the paper's Eq. 6); returns (N,).

    The errors are in destination units (pixels when dst is an image). A source point with
    no image raises ``PointAtInfinityError``, or gets an infinite error with ``invalid="inf"``.
    """
    return _core.reprojection_errors(H, src, dst, invalid)


class ReprojectionStats(NamedTuple):
    """Statistics of the reprojection errors, in destination units."""

    n: int
    """Number of points."""
    mean: float
    """Mean error, the paper's Eq. 7."""
    rms: float
    max: float
    min: float
    argmax: int
    """Index of the point with the largest error."""
    argmin: int


def reprojection_stats(H: ArrayLike, src: ArrayLike, dst: ArrayLike) -> ReprojectionStats:
    """Mean (Eq. 7), RMS, max and min of the reprojection errors of H on (src, dst)."""
    return error_stats(reprojection_errors(H, src, dst))


def error_stats(errors: ArrayLike) -> ReprojectionStats:
    """Mean, RMS, max and min (with their indices) of a 1-D array of errors."""
    return ReprojectionStats(*_core.error_stats(errors))
