"""Drop-in replacements for OpenCV's ``findHomography`` and ``perspectiveTransform``.

Same signatures, shapes, dtypes and return conventions as ``cv2``: H is float64 3 x 3 with
H[2, 2] = 1, the mask uint8 N x 1, ``None`` where OpenCV returns None for a failure. Where
OpenCV raises ``cv2.error``, these raise an error that is both a ``cv2.error`` (so existing
``except cv2.error`` code still catches it) and a ``planarcal.Error``: an ``ArgumentError`` for
a bad argument (shape, dtype, NaN, option), a ``HomographyError`` for data that give no
homography (both ValueErrors). The classes are defined in ``planarcal.errors``.

Computed in float64 end to end (OpenCV rounds to float32 inside findHomography). Deliberate
differences, all where OpenCV returns a wrong answer silently: NaN or infinite input raises
instead of producing a NaN matrix; collinear or duplicate points give None instead of an
arbitrary matrix; a point that maps to infinity raises instead of becoming (0, 0).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import _core
from planarcal.errors import (
    ArgumentError,
    Error,
    HomographyError,
    OpenCVCompatibleArgumentError,
    OpenCVCompatibleError,
    OpenCVCompatiblePointAtInfinityError,
    PointAtInfinityError,
)
from planarcal.homography.robust import RobustMethod

# OpenCV's method constants (cv2.LMEDS, ...), with its integer values.
LMEDS = 4
RANSAC = 8
RHO = 16
USAC_DEFAULT = 32
USAC_PARALLEL = 33
USAC_FM_8PTS = 34
USAC_FAST = 35
USAC_ACCURATE = 36
USAC_PROSAC = 37
USAC_MAGSAC = 38

ROBUST_METHODS = {
    LMEDS: "LMEDS",
    RANSAC: "RANSAC",
    RHO: "RHO",
    USAC_DEFAULT: "USAC_DEFAULT",
    USAC_PARALLEL: "USAC_PARALLEL",
    USAC_FM_8PTS: "USAC_FM_8PTS",
    USAC_FAST: "USAC_FAST",
    USAC_ACCURATE: "USAC_ACCURATE",
    USAC_PROSAC: "USAC_PROSAC",
    USAC_MAGSAC: "USAC_MAGSAC",
}


__all__ = [
    "LMEDS",
    "RANSAC",
    "RHO",
    "USAC_ACCURATE",
    "USAC_DEFAULT",
    "USAC_FAST",
    "USAC_FM_8PTS",
    "USAC_MAGSAC",
    "USAC_PARALLEL",
    "USAC_PROSAC",
    "OpenCVCompatibleArgumentError",
    "OpenCVCompatibleError",
    "OpenCVCompatiblePointAtInfinityError",
    "findHomography",
    "perspectiveTransform",
]


def _as_cv_error(error: ArgumentError | HomographyError) -> Error:
    """The same error (message and attributes) as one that is also a cv2.error."""
    cls: type[ArgumentError | HomographyError]
    if isinstance(error, ArgumentError):
        cls = OpenCVCompatibleArgumentError
    elif isinstance(error, PointAtInfinityError):
        cls = OpenCVCompatiblePointAtInfinityError
    else:
        cls = OpenCVCompatibleError
    return cls(str(error), error.index, error.point_set)


def findHomography(
    srcPoints: ArrayLike,
    dstPoints: ArrayLike,
    method: int = 0,
    ransacReprojThreshold: float = 3,
    mask: NDArray[np.uint8] | None = None,
    maxIters: int = 2000,
    confidence: float = 0.995,
) -> tuple[NDArray[np.float64] | None, NDArray[np.uint8]]:
    """OpenCV's ``findHomography``: returns ``(H, mask)``, H None when no homography fits.

    ``method=0`` fits all points (normalised DLT, then Levenberg-Marquardt on the transfer
    error, as OpenCV does), in float64. Every robust flag (``RANSAC``, ``RHO``, ``USAC_*``)
    runs planarcal's robust estimator (``estimate_homography_robust``: MSAC with PROSAC,
    SPRT and local optimisation, then a refit of the inliers) with OpenCV's meaning of
    ``ransacReprojThreshold`` (px), ``maxIters`` and ``confidence``; the mask marks the
    inliers of the returned H (1) and the rest (0). ``USAC_PROSAC`` takes the points as
    ordered best first, as OpenCV does. ``LMEDS`` is least median of squares and ignores the
    threshold. ``mask``, if given as a uint8 array of N elements, is filled in place and
    returned, as OpenCV does with an output array.

    Differences from OpenCV, where it would silently go on: a threshold <= 0 or
    ``maxIters`` outside [1, 10**7] raises (OpenCV substitutes values or returns None,
    depending on the flag, and runs any budget), and so does a confidence outside (0, 1), as
    OpenCV's RANSAC does. A robust search stops on Ctrl-C.
    """
    try:
        if method == 0:
            H, out_mask = _core.find_homography(srcPoints, dstPoints)
        elif method in ROBUST_METHODS:
            H, out_mask = _find_robust(
                srcPoints, dstPoints, method, ransacReprojThreshold, maxIters, confidence
            )
        else:
            raise ArgumentError(
                f"unknown estimation method {method!r}; expected 0 or one of OpenCV's robust "
                f"flags ({', '.join(f'{n} = {v}' for v, n in ROBUST_METHODS.items())})"
            )
    except (ArgumentError, HomographyError) as e:
        raise _as_cv_error(e) from None
    return H, _fill_output(mask, out_mask)


def _find_robust(
    src: ArrayLike,
    dst: ArrayLike,
    method: int,
    threshold: float,
    max_iters: int,
    confidence: float,
) -> tuple[NDArray[np.float64] | None, NDArray[np.uint8]]:
    kind: RobustMethod = "lmeds" if method == LMEDS else "msac"
    # The binding checks the options (an ArgumentError naming planarcal's argument, e.g.
    # max_iters); findHomography turns it into a cv2.error.
    return _core.find_homography_robust(
        src, dst, kind, threshold, max_iters, confidence, method == USAC_PROSAC
    )


def perspectiveTransform(
    src: ArrayLike, m: ArrayLike, dst: NDArray[Any] | None = None
) -> NDArray[Any] | None:
    """OpenCV's ``perspectiveTransform``: points through a 3 x 3 (or 4 x 4, 3 x 4, 4 x 3) matrix.

    Returns an array of the shape and float dtype of ``src`` (float32 stays float32); for an
    empty input what the installed OpenCV returns (``None`` up to OpenCV 4, an empty array of
    the input's shape from OpenCV 5). A point that maps to infinity raises
    ``PointAtInfinityError`` (OpenCV writes (0, 0) there). ``dst``, if given with the
    output's shape and dtype, is filled in place and returned.
    """
    try:
        out = _core.perspective_transform(src, m)
    except (ArgumentError, HomographyError) as e:
        raise _as_cv_error(e) from None
    if out is None:
        return None if _opencv_empty_is_none() else _empty_like(src)
    if dst is None:
        return out
    return _fill_output(dst, out)


@functools.cache
def _opencv_empty_is_none() -> bool:
    """Whether the installed OpenCV's perspectiveTransform returns None for no points (4.x)
    rather than an empty array (5.x)."""
    import cv2  # noqa: PLC0415 (only here: the drop-ins need OpenCV for nothing else)

    return cv2.perspectiveTransform(np.zeros((0, 1, 2), np.float64), np.eye(3)) is None


def _empty_like(src: ArrayLike) -> NDArray[Any]:
    arr = np.asarray(src)
    dtype = np.float32 if arr.dtype == np.float32 else np.float64
    return np.zeros(arr.shape, dtype)


def _fill_output(given: NDArray[Any] | None, computed: NDArray[Any]) -> NDArray[Any]:
    """OpenCV's output-argument convention: reuse `given` when it fits, else return new."""
    if (
        isinstance(given, np.ndarray)
        and given.dtype == computed.dtype
        and given.size == computed.size
        and given.flags.writeable
    ):
        given.reshape(-1)[...] = computed.reshape(-1)
        if np.shares_memory(given.reshape(-1), given):
            return given
    return computed
