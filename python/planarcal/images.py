"""Images in: reading files and converting to grey, with clear errors instead of OpenCV's
silent None."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.errors import ImageError

# The paper's Eq. 9 (ITU-R BT.601), in OpenCV's BGR channel order.
GREY_WEIGHTS_BGR = (0.114, 0.587, 0.299)


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
    """A grey float32 copy of an image (H x W, or H x W x 3 BGR / x 4 BGRA, any real dtype;
    uint16 is scaled to 0..255), grey by the paper's Eq. 9. ImageError for anything else."""
    if isinstance(image, str | os.PathLike):
        image = load_image(image)
    if not isinstance(image, np.ndarray):
        raise ImageError(f"{name} must be a NumPy array or a path, got {type(image).__name__}")
    if image.size == 0:
        raise ImageError(f"{name} is empty (shape {image.shape})")
    if image.dtype.kind not in "uif":
        raise ImageError(f"{name} must hold numbers, got dtype {image.dtype}")
    if image.ndim == 3 and image.shape[2] in (3, 4):
        bgr = image[:, :, :3].astype(np.float32)
        grey = bgr @ np.asarray(GREY_WEIGHTS_BGR, dtype=np.float32)
    elif image.ndim == 3 and image.shape[2] == 1:
        grey = image[:, :, 0].astype(np.float32)
    elif image.ndim == 2:
        grey = image.astype(np.float32)
    else:
        raise ImageError(f"{name} must be H x W (grey) or H x W x 3 (BGR), got shape {image.shape}")
    if image.dtype == np.uint16:
        grey *= np.float32(255.0 / 65535.0)
    if not np.isfinite(grey).all():
        raise ImageError(f"{name} has NaN or infinite pixels")
    if min(grey.shape) < 8:
        raise ImageError(f"{name} is too small to show a board ({grey.shape[1]} x {grey.shape[0]})")
    return np.ascontiguousarray(grey)
