"""The checks that turn what a caller passes into CameraIntrinsics' fields: a pinhole camera
matrix, an OpenCV distortion vector, an image size, counts and errors. Each returns the
checked value or raises IntrinsicsError saying what is wrong with it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.camera.distortion import DIST_COEFF_LENGTHS
from planarcal.errors import IntrinsicsError

F64 = NDArray[np.float64]


def camera_matrix(value: Any) -> F64:
    """A camera matrix as a read-only float64 (3, 3) array, or IntrinsicsError saying why not.

    K must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0: the skew s is allowed
    (and honoured by every mapping here), anything else in the lower rows would not be a
    pinhole camera."""
    try:
        k = np.array(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as e:  # Overflow: an integer like 10**400
        raise IntrinsicsError(f"the camera matrix must be a 3 x 3 array of numbers: {e}") from None
    if k.shape != (3, 3):
        raise IntrinsicsError(f"the camera matrix must be 3 x 3, got shape {k.shape}")
    if not np.isfinite(k).all():
        raise IntrinsicsError(f"the camera matrix has NaN or infinite entries: {k.tolist()}")
    if not (k[0, 0] > 0 and k[1, 1] > 0):
        raise IntrinsicsError(
            f"the camera matrix's focal lengths must be positive, got fx={k[0, 0]!r}, "
            f"fy={k[1, 1]!r}"
        )
    if k[1, 0] != 0 or k[2, 0] != 0 or k[2, 1] != 0 or k[2, 2] != 1:
        raise IntrinsicsError(
            f"the camera matrix must be [[fx, skew, cx], [0, fy, cy], [0, 0, 1]], got {k.tolist()}"
        )
    k.setflags(write=False)
    return k


def dist_coeffs(value: Any) -> F64:
    """A distortion vector as a read-only float64 (n,) array, n in DIST_COEFF_LENGTHS."""
    try:
        d = np.array(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as e:  # Overflow: an integer like 10**400
        raise IntrinsicsError(f"the distortion coefficients must be numbers: {e}") from None
    if d.ndim == 2 and 1 in d.shape:
        d = d.reshape(-1)
    if d.ndim != 1 or d.size not in DIST_COEFF_LENGTHS:
        raise IntrinsicsError(
            "the distortion coefficients must be a vector of 4, 5, 8, 12 or 14 numbers "
            f"(OpenCV's (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1..s4[, tauX, tauY]]]])), got "
            f"shape {d.shape}"
        )
    if not np.isfinite(d).all():
        raise IntrinsicsError(f"the distortion coefficients have NaN or infinite entries: {d}")
    d.setflags(write=False)
    return d


def whole_number(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise IntrinsicsError(f"{name} must be a whole number, got {value!r}")
    if value < minimum:
        raise IntrinsicsError(f"{name} must be at least {minimum}, got {value}")
    return int(value)


def nonnegative_number(name: str, value: Any) -> float:
    v = arguments.real(name, value, IntrinsicsError)
    if not v >= 0:
        raise IntrinsicsError(f"{name} must be a finite number >= 0, got {value!r}")
    return v


def image_size(value: Any) -> tuple[int, int]:
    try:
        items = list(value)
    except TypeError:
        items = []
    if len(items) != 2:
        raise IntrinsicsError(f"image_size must be (width, height) in pixels, got {value!r}")
    return (whole_number("image width", items[0], 1), whole_number("image height", items[1], 1))
