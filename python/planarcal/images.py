"""Images in: reading files and converting to grey, with clear errors instead of OpenCV's
silent None.

``grey_levels`` is the one place an image becomes grey levels on the 0..255 scale: 8-bit
as is, 16-bit full range scaled (65535 is white), a float image in 0..1 scaled by 255, a
float or integer image already in 0..255 as is, bool as 0 and 255; anything else (NaN,
infinite, negative, above 255) is an ImageError that names the range expected. detect_board,
detect_objects, locate_objects and the reports all read images through it.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.errors import ImageError

# The paper's Eq. 9 (ITU-R BT.601), in OpenCV's BGR channel order.
GREY_WEIGHTS_BGR = (0.114, 0.587, 0.299)

# Rows converted at a time: whole-image conversions keep their float temporaries this small.
ROWS_PER_CHUNK = 256


def load_image(path: str | os.PathLike[str]) -> NDArray[np.uint8]:
    """The image at `path` as stored (BGR or grey, 8-bit); ImageError if it cannot be read."""
    p = Path(path)
    if not p.is_file():
        raise ImageError(f"no image file at {str(p)!r}")
    try:
        data = np.fromfile(p, dtype=np.uint8)  # also reads non-ASCII paths, unlike imread
    except OSError as e:
        raise ImageError(f"cannot read {str(p)!r}: {e}") from None
    if data.size == 0:
        raise ImageError(f"{str(p)!r} is empty (0 bytes)")
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    if image is None or image.size == 0:
        raise ImageError(f"{str(p)!r} is not an image OpenCV can decode (corrupt or truncated?)")
    if image.dtype != np.uint8:
        image = _to_uint8(image)
    if image.ndim == 3 and image.shape[2] == 4:
        image = image[:, :, :3]
    return np.ascontiguousarray(image)


def _to_uint8(image: NDArray[Any]) -> NDArray[np.uint8]:
    if image.dtype == np.uint16:
        return (image >> 8).astype(np.uint8)
    scaled = np.clip(image.astype(np.float64), 0, 255)
    return scaled.astype(np.uint8)


def as_grey(image: Any, name: str = "image") -> NDArray[np.float32]:
    """A grey float32 copy of an image (H x W, or H x W x 3 BGR / x 4 BGRA, of the dtypes
    ``grey_levels`` takes), on the 0..255 scale, grey by the paper's Eq. 9. ImageError for
    anything else."""
    grey = grey_levels(image, name)
    if grey.dtype == np.uint8:
        return grey.astype(np.float32)
    return cast(NDArray[np.float32], grey)


def grey_levels(image: Any, name: str = "image") -> NDArray[np.uint8] | NDArray[np.float32]:
    """The image as grey levels on the 0..255 scale, H x W: an 8-bit grey image as it is (not
    copied when contiguous), anything else as float32 (BGR by the paper's Eq. 9).

    Takes a path, or an H x W, H x W x 1, H x W x 3 (BGR) or H x W x 4 (BGRA) array of:
    uint8 (as is); uint16 (full range: 65535 is white, divided by 257); bool (0 and 255);
    other integers with values in 0..255; floats with finite values, in 0..1 (scaled by 255)
    or else in 0..255 (as is). ImageError, naming what is expected, for anything else."""
    if isinstance(image, str | os.PathLike):
        image = load_image(image)
    if not isinstance(image, np.ndarray):
        raise ImageError(f"{name} must be a NumPy array or a path, got {type(image).__name__}")
    if image.size == 0:
        raise ImageError(f"{name} is empty (shape {image.shape})")
    if image.dtype.kind not in "buif":
        raise ImageError(f"{name} must hold numbers, got dtype {image.dtype}")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (3, 4))):
        raise ImageError(
            f"{name} must be H x W (grey), H x W x 3 (BGR) or H x W x 4 (BGRA), got shape "
            f"{image.shape}"
        )
    if min(image.shape[:2]) < 8:
        raise ImageError(
            f"{name} is too small to show a board ({image.shape[1]} x {image.shape[0]})"
        )
    if image.dtype == np.bool_:
        image = image.view(np.uint8) * np.uint8(255)
    scale = _scale_to_255(image if image.ndim == 2 else image[:, :, :3], name)
    if image.ndim == 2:
        if image.dtype == np.uint8:
            return cast(NDArray[np.uint8], np.ascontiguousarray(image))
        grey: NDArray[np.float32] = image.astype(np.float32)
    else:
        grey = np.empty(image.shape[:2], dtype=np.float32)
        weights = np.asarray(GREY_WEIGHTS_BGR, dtype=np.float32)
        # Row by row, as one product over the whole image would do it (the same values),
        # without a float copy of all three channels.
        for top in range(0, image.shape[0], ROWS_PER_CHUNK):
            rows = slice(top, top + ROWS_PER_CHUNK)
            grey[rows] = image[rows, :, :3].astype(np.float32) @ weights
    if scale != 1.0:
        grey *= np.float32(scale)
    return grey


def _scale_to_255(image: NDArray[Any], name: str) -> float:
    """The factor that puts `image`'s values on the 0..255 scale; ImageError if they fit none
    of the ranges ``grey_levels`` takes."""
    if image.dtype == np.uint8:
        return 1.0
    if image.dtype == np.uint16:
        return 255.0 / 65535.0
    # min and max see a NaN or an infinity without a full-size temporary.
    lo, hi = float(image.min()), float(image.max())
    if image.dtype.kind == "f":
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise ImageError(
                f"{name} has NaN or infinite pixels; a float image must hold finite grey "
                "levels in 0..1 or 0..255"
            )
        if lo >= 0.0 and hi <= 1.0:
            return 255.0
        if lo >= 0.0 and hi <= 255.0:
            return 1.0
        raise ImageError(
            f"{name} holds values from {lo:g} to {hi:g}; a float image must hold grey levels "
            "in 0..1 (scaled by 255) or 0..255"
        )
    if lo < 0 or hi > 255:
        raise ImageError(
            f"{name} ({image.dtype}) holds values from {lo:g} to {hi:g}; an integer image must "
            "be uint8, uint16 (full range) or hold grey levels in 0..255"
        )
    return 1.0
