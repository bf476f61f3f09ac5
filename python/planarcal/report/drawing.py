"""Pictures of what was found, drawn on the image: the board's detection (the paper's
Figure 4) and the located objects (its Figure 6). PNG bytes out, for atomic writing."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planarcal.errors import ArgumentError, HomographyError, ImageError
from planarcal.homography import estimate_homography, transform_points
from planarcal.images import as_grey
from planarcal.report.labels import Box, Layout, Style, around, point_box, text_height
from planarcal.report.mapping import masked
from planarcal.report.point_names import (
    detection_ids,
    grid_shape,
    is_circle_grid,
    missing_ids,
    numbering,
    plural,
    point_name,
)

U8 = NDArray[np.uint8]
F64 = NDArray[np.float64]


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
# A partial view's points not seen, where the fit puts them: orange diamonds, unlabelled.
NOT_SEEN_BGR = (0, 140, 255)
# The most points not seen drawn (evenly spread over their ids): a board of a million
# corners seen in part would otherwise bury the image.
MAX_NOT_SEEN_DRAWN = 5000


def homography_residual_note(residual_rms_px: float) -> str:
    """What the detection's own residual is: the homography alone, no lens model."""
    return f"residual of the homography alone through the centres: {residual_rms_px:.3f} px RMS"


def detection_label(
    detection: Any, residual_note: str | None = None, *, not_seen_drawn: int | None = None
) -> list[str]:
    """The lines written on the detection figure: the board and finder (a ChArUco board's
    printed layout), what the residual is (`residual_note`, by default the detection's own:
    the homography alone), for a partial view how many of the board's points were seen (and,
    `not_seen_drawn` of the others drawn, what their marks mean), when the detection flags
    dots, what their marks mean, and, when it measured them, the dots' size (with what the
    labels number)."""
    board = detection.board
    name = point_name(board)
    if is_circle_grid(board):
        first = (
            f"{board.cols} x {board.rows} board, {detection.method} finder, "
            f"{detection.polarity} dots"
        )
    else:
        first = f"{board.describe()}, {detection.method} finder"
        layout = getattr(detection, "layout", None)
        if layout is not None:
            first += f", {layout} layout"
    lines = [first, residual_note or homography_residual_note(detection.residual_rms_px)]
    seen, total = len(detection.image_points), int(board.n_points)
    partial = seen < total
    if partial:
        line = f"partial view: {seen} of the board's {total} {plural(name, total)} seen"
        if not_seen_drawn:
            line += (
                f"; orange diamonds: {not_seen_drawn} not seen, where the fit through those "
                "seen puts them"
            )
        lines.append(line)
    refined = dot_flags(detection, "refined")
    if refined is not None and not refined.all():
        n = int((~refined).sum())
        lines.append(f"red cross: {n} {name}(s) not refined (a coarser centre kept)")
    enlarged = dot_flags(detection, "enlarged")
    if enlarged is not None and enlarged.any():
        lines.append(f"magenta ring: {int(enlarged.sum())} enlarged {name}(s)")
    sizes = getattr(detection, "sizes", None)
    if sizes is not None and is_circle_grid(board):
        lines.append(
            f"dots {sizes.diameter_mm:.3g} mm across at the stated pitch of {board.pitch:g} mm "
            f"({sizes.diameter_to_pitch(board):.2f} of the pitch); labels: dot index "
            f"{numbering(board)}"
        )
    elif partial or not is_circle_grid(board):
        lines.append(f"labels: each {name}'s id, {numbering(board)}")
    return lines


def draw_detection(
    image: Any,
    detection: Any,
    *,
    residual_note: str | None = None,
    calibration: Any = None,
    text_boxes: list[Box] | None = None,
) -> U8:
    """The image with every point found marked and labelled with its id (a grid board's
    k = row x cols + col, 0 the origin: the numbering of the CSV files, the API and the
    summary), the board's rows and columns drawn through them, the board's origin and X / Y
    directions, the dots the detection flags (not refined: a red cross; enlarged: a magenta
    ring) and the lines of `detection_label` (`residual_note`: which model the residual
    quoted comes from). For a partial view, the board's other points in the image are drawn
    where the fit through the points seen puts them (orange diamonds, unlabelled: not seen):
    `calibration`'s (with its lens model) when given, else a homography through the points.
    Every text is sized to the image and placed where it overlaps no other text and covers
    no point (a point's label that finds no room is left out, and the caption says how
    many are); `text_boxes`, when given, receives the boxes of the texts written."""
    canvas = _canvas(image)
    s = _scale(canvas)
    board = detection.board
    pts = np.asarray(detection.image_points, dtype=np.float64).reshape(-1, 2)
    ids = detection_ids(detection)
    shift = 4  # sub-pixel drawing: coordinates in 1/16 px
    f = float(1 << shift)

    def ip(p: NDArray[np.float64]) -> tuple[int, int]:
        return round(p[0] * f), round(p[1] * f)

    for polyline in _lattice_lines(board, ids, pts):
        cv2.polylines(
            canvas,
            [np.rint(polyline * f).astype(np.int32)],
            False,
            (255, 160, 0),
            max(1, int(s)),
            cv2.LINE_AA,
            shift,
        )
    pitch = _pitch_px(detection)
    radius = max(2.0, 0.12 * pitch)
    project = _projector(board, ids, pts, calibration)
    not_seen = _not_seen_in_image(board, ids, project, canvas.shape[:2])
    for p in not_seen:
        cv2.drawMarker(
            canvas,
            (round(p[0]), round(p[1])),
            NOT_SEEN_BGR,
            cv2.MARKER_DIAMOND,
            max(4, int(2.5 * radius)),
            max(1, int(s)),
            cv2.LINE_AA,
        )
    for p in pts:
        cv2.circle(canvas, ip(p), int(radius * f), (0, 0, 255), max(1, int(s)), cv2.LINE_AA, shift)
    axes = _axes_px(board, ids, pts, project)
    tips: list[tuple[F64, F64, str, tuple[int, int, int]]] = []
    if axes is not None:
        origin, x_end, y_end = axes
        for end, label, colour in ((x_end, "X", (0, 0, 255)), (y_end, "Y", (0, 160, 0))):
            tip = origin + 1.8 * (end - origin)
            cv2.arrowedLine(
                canvas, ip(origin), ip(tip), colour, max(2, int(2 * s)), cv2.LINE_AA, shift, 0.2
            )
            tips.append((origin, tip, label, colour))
    _mark_flagged_dots(canvas, detection, s)
    layout = Layout(canvas)
    layout.reserve(point_box(x, y, radius) for x, y in pts)
    header = Style(text_height(canvas.shape))
    caption = detection_label(detection, residual_note, not_seen_drawn=len(not_seen))
    block = layout.block(caption, header, pts)
    for origin, tip, label, colour in tips:
        _place_axis_letter(layout, origin, tip, label, colour)
    small = Style(text_height(canvas.shape, small=True), colour=(0, 130, 0))
    shown, stride, edges = _label_points(layout, small, board, ids, pts, radius)
    if shown < len(ids):
        names = plural(point_name(board), len(ids))
        note = f"{shown} of the {len(ids)} {names} labelled"
        every = f"every {_ordinal(stride)} " if stride > 1 else ""
        if edges:
            note += f": {every}one of the first row and column ({numbering(board)})"
        elif stride > 1:
            note += f": {every}row and column (the others' labels would overlap)"
        else:
            note += " (the others' labels would overlap)"
        below = block[-1].y1 + round(1.5 * header.height) if block else round(2 * header.height)
        margin = max(2, round(0.4 * header.height)) + header.pad
        layout.place(
            note,
            header,
            [(margin, below), (margin, layout.height - margin - header.pad)],
            check_reserved=False,
        )
    boxes = layout.finish()
    if text_boxes is not None:
        text_boxes.extend(boxes)
    return canvas


def _place_axis_letter(
    layout: Layout, origin: F64, tip: F64, label: str, colour: tuple[int, int, int]
) -> None:
    """The axis letter beyond the arrow's tip, or a little farther out along it, where it
    covers no text and no point."""
    style = Style(1.6 * text_height(layout.canvas.shape, small=True), colour=colour, bold=True)
    w, h, _ = style.size(label)
    d = tip - origin
    d = d / max(float(np.hypot(*d)), 1e-9)
    for reach in (0.6, 1.2, 2.0, 3.0):
        centre = tip + reach * max(w, h) * d
        origins = [(round(centre[0] - w / 2), round(centre[1] + h / 2))]
        origins += around(float(centre[0]), float(centre[1]), 0.3 * h, w, h)
        if layout.place(label, style, origins) is not None:
            return


def _label_points(
    layout: Layout, style: Style, board: Any, ids: NDArray[np.intp], pts: F64, radius: float
) -> tuple[int, int, bool]:
    """Each point's id beside it where it has room (up and right as always, else on another
    side). On a grid too dense for every label, those of every 2nd, 3rd, 5th... row and
    column (the first stride at which nine in ten fit), so that the labels left form an
    even lattice; where even that does not fit, only the first row's and column's, outside
    the grid (every stride-th), a legend from which k = row x cols + col gives the others.
    (How many were written, the stride, whether only the edges are.)"""
    shape = grid_shape(board)
    cols_n = max(shape[0], 1) if shape is not None else 1
    rows, cols = np.divmod(ids, cols_n) if shape is not None else (ids, ids)
    longest = max(shape) if shape is not None else 1
    strides = [k for k in (1, 2, 3, 4, 5, 10, 20, 50, 100, 200, 500) if k < longest] or [1]
    centre = pts.mean(axis=0) if len(pts) else np.zeros(2)
    tries = [(k, False) for k in strides if k <= 5 or shape is None]
    if shape is not None:
        tries += [(k, True) for k in strides]
    for n, (stride, edges) in enumerate(tries):
        on = (rows % stride == 0) & (cols % stride == 0)
        if edges:
            on = (rows == 0) & (cols % stride == 0) | (cols == 0) & (rows % stride == 0)
        subset = np.flatnonzero(on)
        trial = layout.fork()
        shown = 0
        for j in subset:
            text = str(int(ids[j]))
            w, h, _ = style.size(text)
            x, y = float(pts[j][0]), float(pts[j][1])
            origins = around(x, y, radius + style.pad, w, h)
            if edges:  # outwards from the grid first
                ox, oy = x - centre[0], y - centre[1]
                score = [(o[0] + w / 2 - x) * ox + (o[1] - h / 2 - y) * oy for o in origins]
                origins = [origins[k] for k in np.argsort(score)[::-1]]
            if trial.place(text, style, origins) is not None:
                shown += 1
        if shown >= 0.9 * len(subset) or n == len(tries) - 1:
            layout.adopt(trial)
            return shown, stride, edges
    return 0, 1, False


def _ordinal(k: int) -> str:
    return {2: "2nd", 3: "3rd"}.get(k, f"{k}th")


def _pitch_px(detection: Any) -> float:
    """The points' spacing in the image (px), 10 px when it cannot be measured (one point)."""
    pitch = float(detection.pitch_px)
    return pitch if math.isfinite(pitch) and pitch > 0 else 10.0


def _lattice_lines(board: Any, ids: NDArray[np.intp], pts: F64) -> list[F64]:
    """The polylines drawn through the points found: on a grid board each row and column of
    ids through its points, broken where a point was not seen; on another board each pair of
    neighbouring points (the board's closest spacing apart) found."""
    shape = grid_shape(board)
    if shape is not None:
        cols, rows = shape
        flat = np.full((rows * cols, 2), np.nan)
        flat[ids] = pts
        grid = flat.reshape(rows, cols, 2)
        return [
            run
            for line in (*(grid[r] for r in range(rows)), *(grid[:, c] for c in range(cols)))
            for run in _finite_runs(line)
        ]
    world = np.asarray(board.world_points(), dtype=np.float64)[ids]
    if len(world) < 2:
        return []
    spacing = float(cKDTree(world).query(world, k=2)[0][:, 1].min())
    pairs = cKDTree(world).query_pairs(1.01 * spacing, output_type="ndarray")
    return [pts[[a, b]] for a, b in pairs]


def _finite_runs(line: F64) -> list[F64]:
    """The stretches of two or more consecutive finite points of a polyline."""
    ok = np.isfinite(line).all(axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
    return [line[a:b] for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a >= 2]


Projection = Callable[[F64], F64]


def _projector(board: Any, ids: NDArray[np.intp], pts: F64, calibration: Any) -> Projection | None:
    """Board mm -> image px through the fit (NaN where a point has no place in the image):
    the calibration's, lens model and all, when given; else a homography through the points
    found (None with fewer than four, or in a line)."""
    if calibration is not None:
        scale = np.asarray(calibration.world_scale, dtype=np.float64)
        return lambda world: masked(calibration.world_to_image, world * scale, 2)
    if len(pts) < 4:
        return None
    try:
        h = estimate_homography(np.asarray(board.world_points(), dtype=np.float64)[ids], pts)
    except (HomographyError, ArgumentError):
        return None
    return lambda world: transform_points(h, world, invalid="nan")


def _not_seen_in_image(
    board: Any, ids: NDArray[np.intp], project: Projection | None, shape: tuple[int, ...]
) -> F64:
    """Where the fit puts the board's points not seen (at most MAX_NOT_SEEN_DRAWN of them),
    those inside the image, px (K, 2)."""
    missing = missing_ids(board, ids)
    if project is None or not len(missing):
        return np.zeros((0, 2))
    if len(missing) > MAX_NOT_SEEN_DRAWN:
        missing = missing[np.linspace(0, len(missing) - 1, MAX_NOT_SEEN_DRAWN).astype(np.intp)]
    px = project(np.asarray(board.world_points(), dtype=np.float64)[missing])
    h, w = shape
    with np.errstate(invalid="ignore"):
        inside = (px[:, 0] >= -0.5) & (px[:, 0] < w - 0.5) & (px[:, 1] >= -0.5)
        inside &= px[:, 1] < h - 0.5
    return np.asarray(px[inside], dtype=np.float64)


def _axes_px(
    board: Any, ids: NDArray[np.intp], pts: F64, project: Projection | None
) -> tuple[F64, F64, F64] | None:
    """The board's origin (point 0) and its next points along X and Y (on a grid, ids 1 and
    cols; else a pitch along each axis), px: where they were found, else where the fit puts
    them; None when neither says."""
    world = np.asarray(board.world_points(), dtype=np.float64)
    shape = grid_shape(board)
    step = float(getattr(board, "pitch", 0.0) or 1.0)
    anchors: list[tuple[int | None, F64]] = [(0, world[0])]
    for axis, along in ((0, 1), (1, shape[0] if shape is not None else 0)):
        if shape is not None and 0 < along < len(world) and shape[axis] > 1:
            anchors.append((along, world[along]))
        else:
            offset = np.zeros(2)
            offset[axis] = step
            anchors.append((None, world[0] + offset))
    out = []
    for point_id, mm in anchors:
        found = np.flatnonzero(ids == (-1 if point_id is None else point_id))
        if len(found):
            out.append(pts[int(found[0])])
        elif project is not None:
            out.append(project(mm.reshape(1, 2))[0])
        else:
            return None
    if not np.isfinite(out).all():
        return None
    return out[0], out[1], out[2]


def _mark_flagged_dots(canvas: U8, detection: Any, s: float) -> None:
    """A red cross on each dot not refined, a magenta ring round each enlarged one."""
    pts = detection.image_points
    refined = dot_flags(detection, "refined")
    enlarged = dot_flags(detection, "enlarged")
    size = max(8, int(0.5 * _pitch_px(detection)))
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


# The colour (BGR) of a part's axis.
AXIS_BGR = (255, 0, 200)


def draw_objects(
    image: Any,
    objects: Sequence[Any],
    title: str | None = None,
    *,
    text_boxes: list[Box] | None = None,
) -> U8:
    """The image with each object's outline, centroid, ID and (when located) its position in
    mm, and, where it has one, its axis: a line through the centroid along the image
    direction of its principal axis (``axis_px``), a little longer than the part, and its
    angle (``angle_deg``, in the frame of its position) in the label. ``title``, written in
    the top-left corner, says what the numbers are (which frame the mm are in).

    Labels cover no part and no other label: each goes beside its part, else farther out
    with a leader line to its centroid, else the part is marked with its ID alone and its
    numbers listed in a legend where there is room. `text_boxes`, when given, receives the
    boxes of the texts written."""
    canvas = _canvas(image)
    s = _scale(canvas)
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
    layout = Layout(canvas)
    header = Style(text_height(canvas.shape))
    if title:
        outlines = [np.asarray(o.contour_px, dtype=np.float64).reshape(-1, 2) for o in objects]
        layout.block([title], header, np.concatenate([np.zeros((0, 2)), *outlines]))
    layout.reserve(_part_box(o) for o in objects)
    style = Style(text_height(canvas.shape, small=True) * 1.2)
    legend: list[str] = []
    order = sorted(objects, key=lambda o: (o.centroid_px[1], o.centroid_px[0]))
    # Every part's full label beside it where there is room, then, for those left, farther
    # out on a leader line, then their ID alone (their numbers in the legend).
    left = [o for o in order if not _place_part_label(layout, style, _object_text(o), o, 0)]
    left = [o for o in left if not _place_part_label(layout, style, _object_text(o), o, 3)]
    for o in left:
        if _place_part_label(layout, style, f"{o.id}", o, 4):
            legend.append(_object_text(o))
    _legend(layout, style, legend)
    boxes = layout.finish()
    if text_boxes is not None:
        text_boxes.extend(boxes)
    return canvas


def _object_text(o: Any) -> str:
    text = f"ID:{o.id}"
    if o.world_mm is not None:
        text += f" ({o.world_mm[0]:.1f}, {o.world_mm[1]:.1f}) mm"
    angle = getattr(o, "angle_deg", None)
    if angle is not None:
        text += f" {angle:.1f} deg"
    return text


def _part_box(o: Any) -> Box:
    """The part's outline's bounding box (px), which no label may cover."""
    c = np.asarray(o.contour_px, dtype=np.float64).reshape(-1, 2)
    if not len(c):
        x, y = o.centroid_px
        return Box(round(x) - 7, round(y) - 7, round(x) + 8, round(y) + 8)
    lo, hi = np.floor(c.min(axis=0)), np.ceil(c.max(axis=0))
    return Box(int(lo[0]), int(lo[1]), int(hi[0]) + 1, int(hi[1]) + 1)


def _place_part_label(layout: Layout, style: Style, text: str, o: Any, rings: int) -> bool:
    """The part's label just above or below it, else beside it, else (`rings` > 0) farther
    out on up to `rings` rings of places round it with a leader line to its centroid;
    False when there is no room."""
    part = _part_box(o)
    w, h, base = style.size(text)
    p = style.pad
    near = [
        (part.x0 + p, part.y0 - base - p - 1),
        (part.x0 + p, part.y1 + h + p + 1),
        (part.x1 + p + 1, (part.y0 + part.y1 + h) // 2),
        (part.x0 - w - p - 1, (part.y0 + part.y1 + h) // 2),
    ]
    if layout.place(text, style, near) is not None:
        return True
    cx, cy = (float(v) for v in o.centroid_px)
    size = max(part.x1 - part.x0, part.y1 - part.y0)
    for ring in range(1, rings + 1):
        reach = 0.5 * size + ring * 1.6 * (h + base + 2 * p)
        for k in range(16):
            a = 2 * math.pi * k / 16
            bx, by = cx + reach * math.cos(a), cy + reach * math.sin(a)
            org = (round(bx - w / 2), round(by + h / 2))
            box = layout.box_at(text, style, org)
            if layout.free(box):
                ex = min(max(cx, box.x0), box.x1 - 1)
                ey = min(max(cy, box.y0), box.y1 - 1)
                thick = max(1, round(style.height / 12))
                layout.leader((round(ex), round(ey)), (round(cx), round(cy)), thick)
                layout.draw(text, style, org, box)
                return True
    return False


def _legend(layout: Layout, style: Style, lines: list[str]) -> None:
    """The numbers of the parts marked with their ID alone, one line each, stacked from the
    image's bottom-right corner up and leftwards where they cover no part and no text; the
    last line says how many found no room."""
    if not lines:
        return
    step = round(1.5 * style.height) + 2 * style.pad
    margin = max(2, round(0.4 * style.height)) + style.pad
    widest = max(style.size(t)[0] for t in lines) + 2 * style.pad
    columns = range(layout.width - margin - widest, margin - 1, -(widest + margin))
    rows = range(layout.height - margin, margin + step - 1, -step)
    slots = [(x, y) for x in columns for y in rows]
    left = list(lines)
    while left and slots:
        text = left[0]
        for j, org in enumerate(slots):
            box = layout.box_at(text, style, org)
            if layout.free(box):
                layout.draw(text, style, org, box)
                left.pop(0)
                slots = slots[j + 1 :]
                break
        else:
            break
    if left:
        note = f"{len(left)} more parts: see the positions file"
        layout.place(note, style, slots)


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


def png_bytes(image: U8) -> bytes:
    """The image encoded as PNG."""
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise ImageError("could not encode the image as PNG")
    return bytes(buf.tobytes())
