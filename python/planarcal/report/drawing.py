"""Pictures of what was found, drawn on the image: the board's detection (the paper's
Figure 4) and the located objects (its Figure 6). PNG bytes out, for atomic writing."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.errors import ImageError
from planarcal.images import as_grey

U8 = NDArray[np.uint8]


def _canvas(image: Any) -> U8:
    """A BGR 8-bit copy of the image to draw on."""
    if (
        isinstance(image, np.ndarray)
        and image.ndim == 3
        and image.shape[2] >= 3
        and image.dtype == np.uint8
    ):
        return np.array(image[:, :, :3], dtype=np.uint8, order="C", copy=True)
    grey = np.clip(np.rint(as_grey(image)), 0, 255).astype(np.uint8)
    return np.asarray(cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR), dtype=np.uint8)


def _scale(canvas: U8) -> float:
    """Line and text size relative to a 1280-pixel-wide image."""
    return max(0.5, float(max(canvas.shape[:2])) / 1280.0)


def rgb_image(image: Any) -> U8:
    """The image as 8-bit RGB (matplotlib's channel order), grey or BGR in."""
    return np.ascontiguousarray(_canvas(image)[:, :, ::-1])


def dot_flags(detection: Any, name: str) -> NDArray[np.bool_] | None:
    """The per-dot flag `name` ("refined", "enlarged") of a detection, one bool per dot, or
    None when the detection does not carry it (older detections have no such field)."""
    flags = getattr(detection, name, None)
    if flags is None:
        return None
    out = np.asarray(flags, dtype=bool).reshape(-1)
    return out if len(out) == len(detection.image_points) else None


# Colours (BGR) of the marks on dots the detection flags.
UNREFINED_BGR = (0, 0, 255)
ENLARGED_BGR = (255, 0, 255)


def homography_residual_note(residual_rms_px: float) -> str:
    """What the detection's own residual is: the homography alone, no lens model."""
    return f"residual of the homography alone through the centres: {residual_rms_px:.3f} px RMS"


def detection_label(detection: Any, residual_note: str | None = None) -> list[str]:
    """The lines written on the detection figure: the board and finder, what the residual is
    (`residual_note`, by default the detection's own: the homography alone), when the
    detection flags dots, what their marks mean, and, when it measured them, the dots' size
    (with what the labels number)."""
    board = detection.board
    lines = [
        f"{board.cols} x {board.rows} board, {detection.method} finder, {detection.polarity} dots",
        residual_note or homography_residual_note(detection.residual_rms_px),
    ]
    refined = dot_flags(detection, "refined")
    if refined is not None and not refined.all():
        n = int((~refined).sum())
        lines.append(f"red cross: {n} dot(s) not refined (a coarser centre kept)")
    enlarged = dot_flags(detection, "enlarged")
    if enlarged is not None and enlarged.any():
        lines.append(f"magenta ring: {int(enlarged.sum())} enlarged dot(s)")
    sizes = getattr(detection, "sizes", None)
    if sizes is not None:
        lines.append(
            f"dots {sizes.diameter_mm:.3g} mm across at the stated pitch of {board.pitch:g} mm "
            f"({sizes.diameter_to_pitch(board):.2f} of the pitch); labels: dot index k = row x "
            "cols + col"
        )
    return lines


def draw_detection(image: Any, detection: Any, *, residual_note: str | None = None) -> U8:
    """The image with every found dot centre marked and labelled with its index k = row x
    cols + col (0 the origin dot: the numbering of the CSV files, the API and the summary),
    the grid drawn through them, the board's origin and X / Y directions, the dots the
    detection flags (not refined: a red cross; enlarged: a magenta ring) and the lines of
    `detection_label` (`residual_note`: which model the residual quoted comes from)."""
    canvas = _canvas(image)
    s = _scale(canvas)
    board = detection.board
    pts = detection.image_points
    grid = pts.reshape(board.rows, board.cols, 2)
    shift = 4  # sub-pixel drawing: coordinates in 1/16 px
    f = float(1 << shift)

    def ip(p: NDArray[np.float64]) -> tuple[int, int]:
        return round(p[0] * f), round(p[1] * f)

    for r in range(board.rows):
        cv2.polylines(
            canvas,
            [np.rint(grid[r] * f).astype(np.int32)],
            False,
            (255, 160, 0),
            max(1, int(s)),
            cv2.LINE_AA,
            shift,
        )
    for c in range(board.cols):
        cv2.polylines(
            canvas,
            [np.rint(grid[:, c] * f).astype(np.int32)],
            False,
            (255, 160, 0),
            max(1, int(s)),
            cv2.LINE_AA,
            shift,
        )
    radius = max(2.0, 0.12 * detection.pitch_px)
    for k, p in enumerate(pts):
        cv2.circle(canvas, ip(p), int(radius * f), (0, 0, 255), max(1, int(s)), cv2.LINE_AA, shift)
        cv2.putText(
            canvas,
            str(k),
            (int(p[0] + radius), int(p[1] - radius)),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.35 * s,
            (0, 200, 0),
            max(1, int(s)),
            cv2.LINE_AA,
        )
    origin = grid[0, 0]
    for end, label, colour in ((grid[0, 1], "X", (0, 0, 255)), (grid[1, 0], "Y", (0, 160, 0))):
        tip = origin + 1.8 * (end - origin)
        cv2.arrowedLine(
            canvas, ip(origin), ip(tip), colour, max(2, int(2 * s)), cv2.LINE_AA, shift, 0.2
        )
        cv2.putText(
            canvas,
            label,
            (int(tip[0] + 4), int(tip[1] + 4)),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.7 * s,
            colour,
            max(2, int(2 * s)),
            cv2.LINE_AA,
        )
    _mark_flagged_dots(canvas, detection, s)
    lines = _fitting_lines(detection_label(detection, residual_note), canvas.shape[1] - 20, s)
    for k, line in enumerate(lines):
        _label(canvas, line, (10, int((25 + 20 * k) * s)), s)
    return canvas


def _mark_flagged_dots(canvas: U8, detection: Any, s: float) -> None:
    """A red cross on each dot not refined, a magenta ring round each enlarged one."""
    pts = detection.image_points
    refined = dot_flags(detection, "refined")
    enlarged = dot_flags(detection, "enlarged")
    size = max(8, int(0.5 * detection.pitch_px))
    if refined is not None:
        for x, y in pts[~refined]:
            cv2.drawMarker(
                canvas,
                (round(x), round(y)),
                UNREFINED_BGR,
                cv2.MARKER_TILTED_CROSS,
                size,
                max(2, int(2 * s)),
                cv2.LINE_AA,
            )
    if enlarged is not None:
        for x, y in pts[enlarged]:
            cv2.circle(
                canvas, (round(x), round(y)), size, ENLARGED_BGR, max(2, int(2 * s)), cv2.LINE_AA
            )


def _fitting_lines(lines: list[str], width: int, s: float) -> list[str]:
    """The lines, each too wide for the image split after its "; " (a long residual note
    names two models: one per line then)."""
    out = []
    for line in lines:
        if _text_width(line, s) <= width or "; " not in line:
            out.append(line)
        else:
            head, tail = line.split("; ", 1)
            out += [head + ";", *_fitting_lines(["  " + tail], width, s)]
    return out


def _text_width(text: str, s: float) -> int:
    (w, _), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.5 * s, max(1, int(s)))
    return int(w)


# The colour (BGR) of a part's axis.
AXIS_BGR = (255, 0, 200)


def draw_objects(image: Any, objects: Sequence[Any], title: str | None = None) -> U8:
    """The image with each object's outline, centroid, ID and (when located) its position in
    mm, and, where it has one, its axis: a line through the centroid along the image
    direction of its principal axis (``axis_px``), a little longer than the part, and its
    angle (``angle_deg``, in the frame of its position) in the label. ``title``, written in
    the top-left corner, says what the numbers are (which frame the mm are in)."""
    canvas = _canvas(image)
    s = _scale(canvas)
    if title:
        _label(canvas, title, (int(8 * s), int(22 * s)), s)
    for o in objects:
        contour = np.rint(o.contour_px).astype(np.int32).reshape(-1, 1, 2)
        cv2.drawContours(canvas, [contour], -1, (0, 200, 255), max(1, int(s)), cv2.LINE_AA)
        cx, cy = o.centroid_px
        axis = getattr(o, "axis_px", None)
        if axis is not None:
            _draw_axis(canvas, o.contour_px, (cx, cy), axis, s)
        cv2.drawMarker(
            canvas,
            (round(cx), round(cy)),
            (0, 0, 255),
            cv2.MARKER_CROSS,
            int(14 * s),
            max(1, int(s)),
            cv2.LINE_AA,
        )
        text = f"ID:{o.id}"
        if o.world_mm is not None:
            text += f" ({o.world_mm[0]:.1f}, {o.world_mm[1]:.1f}) mm"
        angle = getattr(o, "angle_deg", None)
        if angle is not None:
            text += f" {angle:.1f} deg"
        x, y, _, _ = o.bbox_px
        _label(canvas, text, (x, max(int(15 * s), y - int(6 * s))), s)
    return canvas


def _draw_axis(
    canvas: U8,
    contour_px: Any,
    centre: tuple[float, float],
    axis: tuple[float, float],
    s: float,
) -> None:
    """A line through `centre` along the unit image direction `axis`, reaching 15 % beyond
    the outline's farthest point along it on either side."""
    c = np.array(centre, dtype=np.float64)
    d = np.array(axis, dtype=np.float64)
    outline = np.asarray(contour_px, dtype=np.float64).reshape(-1, 2)
    reach = 1.15 * float(np.abs((outline - c) @ d).max()) if len(outline) else 10.0 * s
    f = 16.0  # sub-pixel drawing: coordinates in 1/16 px
    ends = [np.rint((c + k * reach * d) * f).astype(int) for k in (-1.0, 1.0)]
    cv2.line(
        canvas,
        (int(ends[0][0]), int(ends[0][1])),
        (int(ends[1][0]), int(ends[1][1])),
        AXIS_BGR,
        max(1, int(s)),
        cv2.LINE_AA,
        4,
    )


def _label(canvas: U8, text: str, org: tuple[int, int], s: float) -> None:
    scale = 0.5 * s
    thick = max(1, int(s))
    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
    x, y = org
    cv2.rectangle(canvas, (x - 2, y - th - 3), (x + tw + 2, y + base), (255, 255, 255), -1)
    cv2.putText(
        canvas, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, scale, (20, 20, 20), thick, cv2.LINE_AA
    )


def png_bytes(image: U8) -> bytes:
    """The image encoded as PNG."""
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise ImageError("could not encode the image as PNG")
    return bytes(buf.tobytes())
