"""Locating objects: the paper's chain (grey by its Eq. 9, Gaussian blur, Canny edges,
contours, centroid from image moments), with the filters a real scene needs, and the pixel ->
millimetre step through a calibration (its Table 5).

An object is a closed outline: its centroid is that of the area the outline encloses, from the
contour's moments (holes, such as a nut's, are symmetric on common parts and do not move it),
and its angle the principal axis of that area's second moments, in the frame its position is
given in (``part_angle``: None for a part too round for an axis). IDs follow reading order:
rows of objects from the top of the image, left to right in a row.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import TYPE_CHECKING, Any, NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal import _core, arguments
from planarcal.calib.object_settings import ObjectSettings, detect_options_with
from planarcal.errors import ArgumentError, ImageError
from planarcal.homography import estimate_homography, transform_points
from planarcal.images import as_grey
from planarcal.live.local_map import STEP_PX, centre_block
from planarcal.live.part_angle import PartAxes, part_axes

if TYPE_CHECKING:
    from planarcal.calib.calibration import Calibration
    from planarcal.robot.output_frame import Coords

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
    angle_deg: float | None = None
    """The part's principal axis in the frame of its position, degrees in [-90, 90), from that
    frame's +x towards its +y: on the board (world_mm's frame) from locate_objects, in the
    image (from +x, right, towards +y, down) from detect_objects, which has no plane to turn
    it onto. None where the part is too round for an axis (discs, nuts, squares: see
    planarcal.live.part_angle)."""
    axis_px: tuple[float, float] | None = None
    """The unit direction in the image along which that axis lies (for drawing it); None
    with angle_deg."""


def detect_objects(
    image: Any,
    *,
    min_area_px: float | None = None,
    max_area_px: float | None = None,
    blur_sigma: float = 1.5,
    canny: tuple[float, float] | None = None,
    mask: Any = None,
    roi: tuple[int, int, int, int] | None = None,
    exclude_polygons: list[Any] | None = None,
    keep_border: bool = False,
    subpixel: bool = True,
) -> list[DetectedObject]:
    """Objects in `image` (an array, grey or BGR, or a path), by the paper's chain.

    * ``min_area_px`` / ``max_area_px``: outline area limits (default: from 1/5000 of the
      image up to a quarter of it) that drop specks and the table's own edges.
    * ``blur_sigma``: the Gaussian blur before Canny, px (0 to the image's larger side).
    * ``canny``: the two Canny thresholds; by default from the image's median grey level.
    * ``mask``: an array of the image's size; objects are kept only where it is non-zero.
    * ``roi``: x, y, width, height of a rectangle of the image (whole px); objects are kept
      only where their centroid lies in it (as with a mask of that rectangle, without one).
    * ``exclude_polygons``: pixel polygons (e.g. the board's region, from
      ``board_region_px``) whose objects are ignored.
    * ``keep_border``: objects cut by the image border are dropped unless True (their
      centroid would not be the object's).
    * ``subpixel``: each outline point is moved to the grey-level edge (the steepest point
      across the outline, to a fraction of a pixel) before the centroid is taken; the
      paper's chain (``False``) takes the centroid of the traced edge pixels, which sit a
      pixel or so outside the edge and are quantised to whole pixels (0.1-0.3 px off).

    Each object's ``angle_deg`` is its axis in the image (see DetectedObject);
    locate_objects gives it on the plane.
    """
    found = _detect(
        image,
        min_area_px=min_area_px,
        max_area_px=max_area_px,
        blur_sigma=blur_sigma,
        canny=canny,
        mask=mask,
        roi=roi,
        exclude_polygons=exclude_polygons,
        keep_border=keep_border,
        subpixel=subpixel,
    )
    return _objects(found, part_axes(found.moments, found.areas))


def _objects(found: Found, axes: PartAxes) -> list[DetectedObject]:
    """Found's rows as objects, with their axes."""
    out = []
    for i, b in enumerate(found.bboxes):
        angle = float(axes.angles_deg[i])
        defined = math.isfinite(angle)
        out.append(
            DetectedObject(
                i + 1,
                (float(found.centroids[i, 0]), float(found.centroids[i, 1])),
                float(found.areas[i]),
                found.outlines[i],
                (int(b[0]), int(b[1]), int(b[2]), int(b[3])),
                angle_deg=angle if defined else None,
                axis_px=(float(axes.axes_px[i, 0]), float(axes.axes_px[i, 1])) if defined else None,
            )
        )
    return out


class Found(NamedTuple):
    """A frame's objects as arrays, in reading order (the production loop's form: no object
    per object)."""

    centroids: F64
    """(n, 2) px."""
    areas: F64
    bboxes: NDArray[np.int64]
    """(n, 4): x, y, width, height."""
    outlines: list[F64]
    moments: F64
    """(n, 3): the central second moments of each outline's enclosed area over that area,
    [mu20, mu11, mu02] / area, px^2 (the part's principal axis: see part_angle)."""


def _detect(
    image: Any,
    *,
    min_area_px: float | None = None,
    max_area_px: float | None = None,
    blur_sigma: float = 1.5,
    canny: tuple[float, float] | None = None,
    mask: Any = None,
    roi: tuple[int, int, int, int] | None = None,
    exclude_polygons: list[Any] | None = None,
    keep_border: bool = False,
    subpixel: bool = True,
    outlines: bool = True,
) -> Found:
    """detect_objects' work, its objects as arrays (``outlines=False``: without their
    outlines, an empty list)."""
    u8 = _grey_u8(image)
    h, w = u8.shape
    # 10**400 is refused here, where float() would raise OverflowError.
    real = functools.partial(arguments.real, exc=ImageError)
    # A blur wider than the image blurs it flat (and OpenCV's kernel size overflows).
    if not (0 <= real("blur_sigma", blur_sigma) <= max(w, h)):
        raise ImageError(
            f"blur_sigma must be >= 0 and at most the image's size ({max(w, h)} px), got "
            f"{blur_sigma!r}"
        )
    min_area = (w * h) / 5000.0 if min_area_px is None else real("min_area_px", min_area_px)
    max_area = (w * h) / 4.0 if max_area_px is None else real("max_area_px", max_area_px)
    keep_mask = _mask(mask, (h, w))
    # Checked as the settings check it (four whole numbers, a width and height of 1 or more).
    rect = None if roi is None else ObjectSettings(roi=roi).roi
    blurred = cv2.GaussianBlur(u8, (0, 0), blur_sigma) if blur_sigma > 0 else u8
    if canny is None:
        # The median grey level of a 1-in-32 sample (every 2nd pixel of every 16th row), from
        # its histogram: the whole image's to a grey level, at a fraction of sorting's cost.
        median = float(_core.median_grey(blurred, 16, 2))
        lo, hi = max(5.0, 0.33 * median), max(15.0, 0.66 * median)
    else:
        lo, hi = arguments.pair("canny", canny, ImageError)
    edges = cv2.Canny(blurred, lo, hi, L2gradient=True)
    # Close small gaps so each outline is one closed contour.
    edges = cv2.morphologyEx(edges, cv2.MORPH_CLOSE, _CLOSE_KERNEL)
    contours, _ = cv2.findContours(edges, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    # Area and border filters, sub-pixel outlines and centroids, in reading order: one call
    # into the core.
    _, areas, centroids, bboxes, traced, moments = _core.measure_contours(
        u8, contours, min_area, max_area, keep_border, subpixel, outlines
    )
    if keep_mask is None and rect is None and not exclude_polygons:
        return Found(centroids, areas, bboxes, traced, moments)
    keep = np.ones(len(areas), dtype=bool)
    if keep_mask is not None and len(areas):
        col = np.clip(centroids[:, 0].astype(np.int64), 0, w - 1)
        row = np.clip(centroids[:, 1].astype(np.int64), 0, h - 1)
        keep &= keep_mask[row, col]
    if rect is not None:
        # The mask's pixels: column x covers centroids from x to x + 1.
        x, y, rw, rh = rect
        cx, cy = centroids[:, 0], centroids[:, 1]
        keep &= (cx >= x) & (cx < x + rw) & (cy >= y) & (cy < y + rh)
    for polygon in exclude_polygons or []:
        p = np.asarray(polygon, dtype=np.float32).reshape(-1, 1, 2)
        for i in np.flatnonzero(keep):
            centre = (float(centroids[i, 0]), float(centroids[i, 1]))
            if cv2.pointPolygonTest(p, centre, False) >= 0:
                keep[i] = False
    # The rows of the objects left.
    kept = np.flatnonzero(keep)
    kept = kept[_core.reading_order(centroids[kept], bboxes[kept, 3])]
    kept_outlines = [traced[i] for i in kept] if outlines else []
    return Found(centroids[kept], areas[kept], bboxes[kept], kept_outlines, moments[kept])


# The closing that joins an outline's small gaps.
_CLOSE_KERNEL = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=np.uint8)


def _grey_u8(image: Any) -> NDArray[np.uint8]:
    """The image as 8-bit grey (the paper's Eq. 9 for BGR): camera frames (uint8) go straight
    through OpenCV; anything else through as_grey's checks and conversions."""
    if isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.size:
        if image.ndim == 2:
            return image
        if image.ndim == 3 and image.shape[2] == 3:
            return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    grey = as_grey(image)
    return np.clip(np.rint(grey), 0, 255).astype(np.uint8)


def _mask(mask: Any, shape: tuple[int, int]) -> NDArray[np.bool_] | None:
    if mask is None:
        return None
    arr = np.asarray(mask)
    if arr.shape[:2] != shape:
        raise ImageError(f"mask must be {shape[1]} x {shape[0]} like the image, got {arr.shape}")
    flat = arr.any(axis=2) if arr.ndim == 3 else arr
    return np.asarray(flat, dtype=bool)


def locate_objects(
    image: Any,
    calibration: Calibration,
    *,
    height_mm: float = 0.0,
    frame: Coords = "board",
    **options: Any,
) -> list[DetectedObject]:
    """detect_objects, with each part located on the plane in mm through `calibration` (the
    paper's Table 5): its centroid on the plane (the image centroid's image corrected to
    second order for the mapping's stretch across the part, see planarcal.live.local_map),
    its 1-sigma uncertainty (``world_std_mm``), and its angle (``angle_deg``: its axis's
    second moments turned through the local Jacobian of the whole mapping, see
    planarcal.live.part_angle), in ``frame``: "board" (the board's mm) or "robot" (the
    robot's base frame, through the calibration's registration; an ArgumentError without
    one). Objects whose outlines are ``height_mm`` above the plane (the top face of parts of
    that height) are located where they really are, which needs a calibration with camera
    intrinsics. Options are those of detect_objects; the calibration's object settings
    (``calibration.object_settings``: area limits, roi, blur) are used where they name none
    (an option given, None included, replaces the setting of its name). ArgumentError for
    settings that are not valid together (a minimum area above the maximum).

    FrameSizeError, before any detection, if the image is not of the size the calibration
    was made on (see ``Calibration.check_image_size``)."""
    grey = _grey_u8(image)
    size = (grey.shape[1], grey.shape[0])
    calibration.check_image_size(size)
    found = _detect(grey, **detect_options_with(calibration.object_settings, options, size))
    if not len(found.areas):
        return []
    px = found.centroids

    def to_frame(points: F64) -> tuple[F64, F64]:
        return calibration.image_to_world(  # type: ignore[no-any-return]
            points, height=height_mm, return_std=True, frame=frame
        )

    # Each part's centroid on the plane (not the image of its image centroid: see
    # planarcal.live.local_map) and its axis, from one mapping of the points round it and
    # one core call.
    samples = _core.part_samples(px, STEP_PX)
    mapped, std = to_frame(samples)
    poses = _core.part_poses(mapped, found.moments, found.areas, STEP_PX)
    mm, axes, std = poses[0], PartAxes(*poses[2:]), centre_block(std, len(px))
    return [
        dataclasses.replace(o, world_mm=(float(x), float(y)), world_std_mm=float(s))
        for o, (x, y), s in zip(_objects(found, axes), mm, std, strict=True)
    ]


def board_region_px(detection: Any, margin_pitch: float = 0.5) -> F64:
    """The board's region in the image, for exclude_polygons: the printed pattern's outline
    (``board.ink().field``: a circle grid's dots, a chessboard's or ChArUco board's squares)
    pushed out by `margin_pitch` pitches, through the homography of the points found (a
    partial view's too: the whole board's outline, where it would be). (4, 2) px."""
    board = detection.board
    margin = arguments.real("margin_pitch", margin_pitch)
    if margin < 0:
        raise ArgumentError(f"margin_pitch must be 0 or more, got {margin_pitch!r}")
    m = margin * board.pitch
    x0, y0, x1, y1 = board.ink().field
    corners = np.array([[x0 - m, y0 - m], [x1 + m, y0 - m], [x1 + m, y1 + m], [x0 - m, y1 + m]])
    hom = estimate_homography(detection.world_points(), detection.image_points)
    return transform_points(hom, corners)
