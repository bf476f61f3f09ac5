"""What the live page draws on a frame: the board's points, ids, origin and axes; the
placements captured so far; the picked and touched points; the parts located. Drawn with
OpenCV on a copy of the frame, in a few milliseconds (the page redraws every frame), with
lines and text scaled to the frame's size."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.calib.detection import BoardDetection

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]

POINT = (0, 200, 255)  # BGR: amber points
X_AXIS = (40, 40, 230)  # red
Y_AXIS = (40, 190, 40)  # green
PLACEMENT = (230, 160, 0)  # blue outlines
PICKED = (255, 0, 255)
TOUCHED = (0, 230, 0)
OUTLIER = (0, 0, 255)
PART = (0, 255, 255)
ROI = (255, 255, 0)
LABEL_EVERY_PX = 22.0
"""Ids are written on every point only when neighbours are at least this far apart (px);
closer, on every few, so that labels never pile up."""


def _scale(image: U8) -> float:
    return max(0.5, float(image.shape[1]) / 1280.0)


def _pt(p: Sequence[float] | F64) -> tuple[int, int]:
    return round(float(p[0])), round(float(p[1]))


def _text(
    canvas: U8, text: str, at: tuple[int, int], s: float, color: Any = (255, 255, 255)
) -> None:
    """Text with a dark halo, readable on any background."""
    size, thick = 0.5 * s, max(1, round(s))
    cv2.putText(canvas, text, at, cv2.FONT_HERSHEY_SIMPLEX, size, (0, 0, 0), thick + 2, cv2.LINE_AA)
    cv2.putText(canvas, text, at, cv2.FONT_HERSHEY_SIMPLEX, size, color, thick, cv2.LINE_AA)


def board_axes_px(detection: BoardDetection) -> tuple[F64, F64, F64] | None:
    """The board's origin and the ends of its x and y axes (two pitches long) in the image,
    through the homography of the detected points; None with too few points."""
    world = detection.world_points()
    if len(world) < 4:
        return None
    h, _ = cv2.findHomography(world, detection.image_points, 0)
    if h is None:
        return None
    pitch = 2.0 * float(detection.board.pitch)
    ends = np.array([[[0.0, 0.0], [pitch, 0.0], [0.0, pitch]]])
    o, x, y = cv2.perspectiveTransform(ends, h)[0]
    return o, x, y


def draw_board(
    canvas: U8,
    detection: BoardDetection,
    *,
    picked: int | None = None,
    touched: Sequence[int] = (),
    outliers: Sequence[int] = (),
) -> None:
    """The detection's points with their ids, the origin and axes; the picked point, the
    touched ones and the outliers among them ringed."""
    s = _scale(canvas)
    pts, ids = detection.image_points, detection.ids
    radius = max(2, round(3 * s))
    for p in pts:
        cv2.circle(canvas, _pt(p), radius, POINT, -1, cv2.LINE_AA)
    step = _label_step(detection)
    marked = {int(i): c for c, group in ((TOUCHED, touched), (OUTLIER, outliers)) for i in group}
    if picked is not None:
        marked[int(picked)] = PICKED
    for p, i in zip(pts, ids.tolist(), strict=True):
        ring = marked.get(i)
        if ring is not None:
            cv2.circle(canvas, _pt(p), round(9 * s), ring, max(2, round(2 * s)), cv2.LINE_AA)
        if ring is not None or i % step == 0:
            _text(canvas, str(i), (round(p[0] + 5 * s), round(p[1] - 5 * s)), s)
    axes = board_axes_px(detection)
    if axes is not None:
        o, x, y = axes
        width = max(2, round(3 * s))
        cv2.arrowedLine(canvas, _pt(o), _pt(x), X_AXIS, width, cv2.LINE_AA, tipLength=0.2)
        cv2.arrowedLine(canvas, _pt(o), _pt(y), Y_AXIS, width, cv2.LINE_AA, tipLength=0.2)
        _text(canvas, "x", _pt(x + 8 * s), s, X_AXIS)
        _text(canvas, "y", _pt(y + 8 * s), s, Y_AXIS)


def _label_step(detection: BoardDetection) -> int:
    """Every how many ids to write one: 1 when the points are far enough apart."""
    pitch = float(detection.pitch_px) if len(detection.image_points) > 1 else LABEL_EVERY_PX
    if not np.isfinite(pitch) or pitch <= 0:
        return 5
    return 1 if pitch >= LABEL_EVERY_PX else 5 if pitch >= LABEL_EVERY_PX / 3 else 10


def draw_placements(canvas: U8, outlines: Sequence[F64]) -> None:
    """Each captured placement's outline, numbered from 1."""
    s = _scale(canvas)
    for k, outline in enumerate(outlines):
        poly = np.round(outline).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(canvas, [poly], True, PLACEMENT, max(2, round(2 * s)), cv2.LINE_AA)
        centre = outline.mean(axis=0)
        _text(canvas, str(k + 1), _pt(centre), 1.6 * s, PLACEMENT)


def draw_parts(canvas: U8, parts: Sequence[dict[str, Any]], roi: Sequence[int] | None) -> None:
    """Each part's centre, id and position (mm); the region of interest, when one is set."""
    s = _scale(canvas)
    if roi is not None:
        x, y, w, h = roi
        cv2.rectangle(canvas, (x, y), (x + w, y + h), ROI, max(1, round(s)), cv2.LINE_AA)
    for part in parts:
        p = _pt(part["image_px"])
        arm = round(8 * s)
        cv2.line(canvas, (p[0] - arm, p[1]), (p[0] + arm, p[1]), PART, max(1, round(2 * s)))
        cv2.line(canvas, (p[0], p[1] - arm), (p[0], p[1] + arm), PART, max(1, round(2 * s)))
        label = f"{part['id']}: {part['x']:.1f}, {part['y']:.1f}"
        _text(canvas, label, (p[0] + arm + 2, p[1] - arm), s, PART)


def jpeg(canvas: U8, quality: int = 80) -> bytes:
    ok, buf = cv2.imencode(".jpg", canvas, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:  # pragma: no cover - OpenCV encodes any 8-bit BGR image
        raise RuntimeError("OpenCV could not encode the frame as JPEG")
    return buf.tobytes()
