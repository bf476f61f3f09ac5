"""Locating objects: the paper's chain (grey by its Eq. 9, Gaussian blur, Canny edges,
contours, centroid from image moments), with the filters a real scene needs, and the pixel ->
millimetre step through a calibration (its Table 5).

An object is a closed outline: its centroid is that of the area the outline encloses, from the
contour's moments (holes, such as a nut's, are symmetric on common parts and do not move it).
IDs follow reading order: rows of objects from the top of the image, left to right in a row.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal.errors import ImageError
from planarcal.images import as_grey

F64 = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class DetectedObject:
    """One object found in an image."""

    id: int
    """1-based, in reading order (rows from the top, left to right)."""
    centroid_px: tuple[float, float]
    """Centroid of the enclosed area, px (the paper's cx, cy from image moments)."""
    area_px: float
    contour_px: F64
    """The outline, (K, 2) pixel positions."""
    bbox_px: tuple[int, int, int, int]
    """x, y, width, height of the outline's bounding box."""
    world_mm: tuple[float, float] | None = None
    """The centroid on the plane, mm, when located through a calibration."""
    world_std_mm: float | None = None
    """The calibration's 1-sigma uncertainty of world_mm (RMS distance, mm)."""


def detect_objects(
    image: Any,
    *,
    min_area_px: float | None = None,
    max_area_px: float | None = None,
    blur_sigma: float = 1.5,
    canny: tuple[float, float] | None = None,
    mask: Any = None,
    exclude_polygons: list[Any] | None = None,
    keep_border: bool = False,
    subpixel: bool = True,
) -> list[DetectedObject]:
    """Objects in `image` (an array, grey or BGR, or a path), by the paper's chain.

    * ``min_area_px`` / ``max_area_px``: outline area limits (default: from 1/5000 of the
      image up to a quarter of it) that drop specks and the table's own edges.
    * ``blur_sigma``: the Gaussian blur before Canny, px.
    * ``canny``: the two Canny thresholds; by default from the image's median grey level.
    * ``mask``: an array of the image's size; objects are kept only where it is non-zero.
    * ``exclude_polygons``: pixel polygons (e.g. the board's region, from
      ``board_region_px``) whose objects are ignored.
    * ``keep_border``: objects cut by the image border are dropped unless True (their
      centroid would not be the object's).
    * ``subpixel``: each outline point is moved to the grey-level edge (the steepest point
      across the outline, to a fraction of a pixel) before the centroid is taken; the
      paper's chain (``False``) takes the centroid of the traced edge pixels, which sit a
      pixel or so outside the edge and are quantised to whole pixels (0.1-0.3 px off).
    """
    import cv2

    u8 = _grey_u8(image)
    h, w = u8.shape
    if not (blur_sigma >= 0):
        raise ImageError(f"blur_sigma must be >= 0, got {blur_sigma!r}")
    min_area = (w * h) / 5000.0 if min_area_px is None else float(min_area_px)
    max_area = (w * h) / 4.0 if max_area_px is None else float(max_area_px)
    blurred = cv2.GaussianBlur(u8, (0, 0), blur_sigma) if blur_sigma > 0 else u8
    if canny is None:
        # The median grey level of a 1-in-16 sample (OpenCV's nearest-neighbour resize), from
        # its histogram: the whole image's to a grey level, at a fraction of sorting's cost.
        small = cv2.resize(
            blurred, (max(1, w // 4), max(1, h // 4)), interpolation=cv2.INTER_NEAREST
        )
        counts = np.bincount(small.ravel(), minlength=256)
        median = float(np.searchsorted(np.cumsum(counts), 0.5 * small.size))
        lo, hi = max(5.0, 0.33 * median), max(15.0, 0.66 * median)
    else:
        lo, hi = float(canny[0]), float(canny[1])
    edges = cv2.Canny(blurred, lo, hi, L2gradient=True)
    # Close small gaps so each outline is one closed contour.
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    edges = cv2.morphologyEx(edges, cv2.MORPH_CLOSE, kernel)
    contours, _ = cv2.findContours(edges, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)

    keep_mask = _mask(mask, (h, w))
    polygons = [np.asarray(p, dtype=np.float32).reshape(-1, 1, 2) for p in exclude_polygons or []]
    found = []
    # A closed outline of n chain points has a perimeter of at most n * sqrt(2), and no shape
    # encloses more than perimeter^2 / (4 pi): shorter outlines cannot reach min_area.
    shortest = math.sqrt(4.0 * math.pi * min_area) / math.sqrt(2.0)
    for contour in contours:
        if len(contour) < shortest:
            continue
        m = cv2.moments(contour)
        area = float(m["m00"])
        if not (min_area <= area <= max_area):
            continue
        x, y, bw, bh = cv2.boundingRect(contour)
        if not keep_border and (x <= 0 or y <= 0 or x + bw >= w or y + bh >= h):
            continue
        cx, cy = m["m10"] / area, m["m01"] / area
        outline = contour.reshape(-1, 2).astype(np.float64)
        if subpixel:
            refined = _edge_outline(u8, outline, (x, y, bw, bh))
            if refined is not None:
                outline, area, (cx, cy) = refined
        if keep_mask is not None and not keep_mask[min(h - 1, int(cy)), min(w - 1, int(cx))]:
            continue
        if any(cv2.pointPolygonTest(p, (cx, cy), False) >= 0 for p in polygons):
            continue
        found.append((cx, cy, area, outline, (x, y, bw, bh)))
    return [
        DetectedObject(i + 1, (cx, cy), area, contour, bbox)
        for i, (cx, cy, area, contour, bbox) in enumerate(_reading_order(found))
    ]


def _grey_u8(image: Any) -> NDArray[np.uint8]:
    """The image as 8-bit grey (the paper's Eq. 9 for BGR): camera frames (uint8) go straight
    through OpenCV; anything else through as_grey's checks and conversions."""
    import cv2

    if isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.size:
        if image.ndim == 2:
            return image
        if image.ndim == 3 and image.shape[2] == 3:
            return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    grey = as_grey(image)
    return np.clip(np.rint(grey), 0, 255).astype(np.uint8)


# The edge search reads the object's own region, widened by the search's reach (3 px) and
# the smoothing's support, lightly smoothed: sigma 1 px steadies the gradient against sensor
# noise without merging neighbouring edges.
_EDGE_PAD = 8
_EDGE_KERNEL = np.exp(-0.5 * np.arange(-4.0, 5.0) ** 2)
_EDGE_KERNEL /= _EDGE_KERNEL.sum()


def _edge_outline(
    u8: NDArray[np.uint8], outline: F64, bbox: tuple[int, int, int, int]
) -> tuple[F64, float, tuple[float, float]] | None:
    """The outline with each point moved along its normal to the steepest grey-level change
    (planarcal_core::outline, sub-pixel), with the area and centroid it encloses; None if
    the outline is too short for normals."""
    import cv2

    from planarcal import _core

    if len(outline) < 12:
        return None
    h, w = u8.shape
    x, y, bw, bh = bbox
    x0, y0 = max(0, x - _EDGE_PAD), max(0, y - _EDGE_PAD)
    x1, y1 = min(w, x + bw + _EDGE_PAD), min(h, y + bh + _EDGE_PAD)
    # Smoothed to float32 in one OpenCV call (the separable Gaussian of sigma 1 px).
    region = cv2.sepFilter2D(u8[y0:y1, x0:x1], cv2.CV_32F, _EDGE_KERNEL, _EDGE_KERNEL)
    refined, area, cx, cy = _core.refine_outline_px(region, outline, (float(x0), float(y0)))
    return refined, float(area), (float(cx), float(cy))


def _reading_order(found: list[Any]) -> list[Any]:
    """Rows of objects from the top (an object joins a row when its centre is within half the
    typical object height of the row's first), left to right within a row."""
    if not found:
        return []
    typical = float(np.median([f[4][3] for f in found]))
    by_y = sorted(found, key=lambda f: f[1])
    rows: list[list[Any]] = []
    for f in by_y:
        if rows and abs(f[1] - rows[-1][0][1]) <= 0.5 * typical:
            rows[-1].append(f)
        else:
            rows.append([f])
    return [f for row in rows for f in sorted(row, key=lambda f: f[0])]


def _mask(mask: Any, shape: tuple[int, int]) -> NDArray[np.bool_] | None:
    if mask is None:
        return None
    arr = np.asarray(mask)
    if arr.shape[:2] != shape:
        raise ImageError(f"mask must be {shape[1]} x {shape[0]} like the image, got {arr.shape}")
    flat = arr.any(axis=2) if arr.ndim == 3 else arr
    return np.asarray(flat, dtype=bool)


def locate_objects(
    image: Any, calibration: Any, *, height_mm: float = 0.0, **options: Any
) -> list[DetectedObject]:
    """detect_objects, with each centroid mapped to the plane in mm through `calibration`
    (the paper's Table 5), with its 1-sigma uncertainty (``world_std_mm``). Objects whose
    outlines are ``height_mm`` above the plane (the top face of parts of that height) are
    located where they really are, which needs a calibration with camera intrinsics.
    Options are those of detect_objects."""
    objects = detect_objects(image, **options)
    if not objects:
        return []
    px = np.array([o.centroid_px for o in objects])
    mm, std = calibration.image_to_world(px, height=height_mm, return_std=True)
    return [
        dataclasses.replace(o, world_mm=(float(x), float(y)), world_std_mm=float(s))
        for o, (x, y), s in zip(objects, mm, std, strict=True)
    ]


def board_region_px(detection: Any, margin_pitch: float = 0.75) -> F64:
    """The board's region in the image, for exclude_polygons: the dot grid's outline pushed
    out by `margin_pitch` dot pitches (through the board's own homography)."""
    from planarcal.homography import estimate_homography, transform_points

    board = detection.board
    m = margin_pitch * board.pitch
    w, h = (board.cols - 1) * board.pitch, (board.rows - 1) * board.pitch
    corners = np.array([[-m, -m], [w + m, -m], [w + m, h + m], [-m, h + m]])
    hom = estimate_homography(detection.world_points(), detection.image_points)
    return transform_points(hom, corners)
