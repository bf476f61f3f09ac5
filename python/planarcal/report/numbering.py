"""A picture of how a board's points are numbered: the board as printed (its ``board.ink()``,
the shapes the printed page and the renderer both draw) seen from the front, each dot or
corner marked and labelled with its id (k = row x cols + col, the order of
``board.world_points()``), and the board's origin and X / Y axes drawn. For the documentation
(docs/numbering.py writes one per board type) and for users with a board of their own."""

from __future__ import annotations

import dataclasses
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planarcal.errors import ImageError
from planarcal.report.labels import Box, Layout, Style, around, point_box

U8 = NDArray[np.uint8]
F64 = NDArray[np.float64]

SUPERSAMPLE = 4  # the board is drawn this many times larger, then shrunk: smooth edges
MARK_BGR = (0, 0, 230)
X_BGR = (0, 0, 220)
Y_BGR = (0, 150, 0)
LABEL_BGR = (150, 40, 0)


@dataclasses.dataclass(frozen=True)
class Numbering:
    """The drawn picture and where things are in it: ``board_image`` the board alone (no
    marks), the point of world (x, y) mm at ``origin_px + px_per_mm * (x, y)``, ``labels``
    each point id's text box, ``text_boxes`` every text's box (labels, axes, caption)."""

    image: U8
    board_image: U8
    px_per_mm: float
    origin_px: tuple[float, float]
    labels: dict[int, Box]
    text_boxes: list[Box]

    def world_px(self, world_mm: F64) -> F64:
        """Pixels of world points (mm)."""
        return np.asarray(self.origin_px) + self.px_per_mm * np.asarray(world_mm, np.float64)


def _caption(board: Any) -> list[str]:
    name = board.point_name
    kind = {
        "circles": f"{getattr(board, 'layout', 'symmetric')} circle grid",
        "chessboard": "chessboard",
        "charuco": "ChArUco board",
    }.get(board.kind, board.kind)
    origin = (
        "the board's outer corner"
        if getattr(board, "first_corner_squares", 0)
        else f"{name} 0's centre"
        if board.kind == "circles"
        else f"{name} 0"
    )
    return [
        f"{kind[0].upper()}{kind[1:]}, {board.cols} x {board.rows} {name}s: "
        f"{name} k = row x cols + col ({board.cols} cols)",
        f"Origin (0, 0) at {origin}; X along a row, Y down a column (mm, seen from the front)",
    ]


def _draw_ink(board: Any, s: float, origin: tuple[float, float], size: tuple[int, int]) -> U8:
    """The board's ink on white at `s` px per mm, world (0, 0) at `origin` px (BGR)."""
    w, h = size
    k = SUPERSAMPLE
    big = np.full((h * k, w * k), 255, np.uint8)
    ink = board.ink()
    ox, oy = origin

    def px(x: float, y: float) -> tuple[int, int]:
        # `origin` counts pixel centres as whole numbers (OpenCV's convention): an edge at
        # u is at u + 0.5 on the pixels' grid of edges.
        return round((ox + s * x + 0.5) * k), round((oy + s * y + 0.5) * k)

    for x0, y0, x1, y1 in ink.rects:
        a, b = px(x0, y0), px(x1, y1)
        big[a[1] : b[1], a[0] : b[0]] = 0
    f = 16
    for cx, cy, r, black in ink.circles:
        cx_big, cy_big = (ox + s * cx + 0.5) * k - 0.5, (oy + s * cy + 0.5) * k - 0.5
        centre = (round(cx_big * f), round(cy_big * f))
        colour = 0 if black else 255
        cv2.circle(big, centre, round(s * r * k * f), colour, -1, cv2.LINE_AA, 4)
    small = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA)
    return np.asarray(cv2.cvtColor(small, cv2.COLOR_GRAY2BGR), np.uint8)


def draw_numbering(board: Any, width: int = 1000) -> Numbering:
    """The numbering picture of `board` (any board planarcal reads), `width` px wide."""
    x0, y0, x1, y1 = (float(v) for v in board.ink().field)
    pitch = float(board.pitch)
    margin = 1.1 * pitch  # room for the axes' letters and the outer labels
    s = width / (x1 - x0 + 2 * margin)
    header = Style(max(12.0, 0.02 * width), bold=False)
    layout0 = Layout(np.zeros((10, width, 3), np.uint8))
    lines = layout0.wrap(_caption(board), header, width - 4 * header.pad - 8)
    step = round(1.5 * header.height) + 2 * header.pad
    top = step * len(lines) + round(header.height)
    height = top + round(s * (y1 - y0 + 2 * margin))
    origin = (s * (margin - x0), top + s * (margin - y0))
    plain = _draw_ink(board, s, origin, (width, height))
    canvas = plain.copy()
    world = board.world_points()
    pts = np.asarray(origin) + s * world
    layout = Layout(canvas)
    for k, text in enumerate(lines):
        _, h, _ = header.size(text)
        layout.place(text, header, [(4 + header.pad, k * step + header.pad + h + 4)])

    # What labels keep clear of: the dots (or a mark at each corner) and ChArUco markers.
    if board.kind == "circles":
        radii = 0.5 * s * board.dot_diameters()
    else:
        radii = np.full(len(pts), 0.06 * s * pitch)
    mark = max(2.0, 0.05 * s * pitch)
    layout.reserve(point_box(x, y, r / 0.8 + 1) for (x, y), r in zip(pts, radii, strict=True))
    if board.kind == "charuco":
        for q in board.marker_corners():
            a, b = np.asarray(origin) + s * q.min(axis=0), np.asarray(origin) + s * q.max(axis=0)
            layout.reserve([Box(round(a[0]), round(a[1]), round(b[0]), round(b[1]))])

    # Every id first (on the side clearest of the other points, one side for all), then
    # the axes' words where room is left.
    small = Style(max(10.0, 0.2 * s * pitch), colour=LABEL_BGR)
    labels: dict[int, Box] = {}
    order = _side_order(pts, radii + 3 + small.pad, *small.size(str(len(pts) - 1))[:2])
    q = 0.3 * s * pitch
    for k, ((x, y), r) in enumerate(zip(pts, radii, strict=True)):
        text = str(k)
        w, h, _ = small.size(text)
        origins = around(float(x), float(y), r + 3 + small.pad, w, h)
        tries = order
        if board.kind == "charuco":
            # Between the markers: in the black square right of the corner (up or down).
            up_black = plain[round(y - q), round(x + q), 0] < 128
            tries = [0 if up_black else 2] + [j for j in order if j != (0 if up_black else 2)]
        box = layout.place(text, small, [origins[j] for j in tries])
        if box is not None:
            labels[k] = box

    # The axes from the origin to beyond the board's far edges, their letters past the tips.
    o = np.asarray(origin)
    thick = max(2, round(0.012 * s * pitch))
    letter = Style(1.4 * small.height, bold=True)
    for axis, name, colour in ((0, "X", X_BGR), (1, "Y", Y_BGR)):
        tip = o.copy()
        tip[axis] = origin[axis] + s * ((x1, y1)[axis] + 0.55 * margin)
        cv2.arrowedLine(
            canvas,
            (round(o[0]), round(o[1])),
            (round(tip[0]), round(tip[1])),
            colour,
            thick,
            cv2.LINE_AA,
            0,
            0.25 * s * pitch / max(float(np.hypot(*(tip - o))), 1.0),
        )
        w, h, _ = letter.size(name)
        st = dataclasses.replace(letter, colour=colour)
        gap = 0.25 * s * pitch
        at = (
            [(round(tip[0] + gap), round(tip[1] + h / 2))]
            if axis == 0
            else [(round(tip[0] - w / 2), round(tip[1] + gap + h))]
        )
        layout.place(name, st, at + around(float(tip[0]), float(tip[1]), gap, w, h))
    word = "(0, 0)"
    w, h, _ = small.size(word)
    g = round(radii[0] + 3 + small.pad) if board.kind == "circles" else round(0.2 * s * pitch)
    layout.place(
        word,
        dataclasses.replace(small, colour=(20, 20, 20)),
        [(round(o[0]) - g - w, round(o[1]) - g), *around(float(o[0]), float(o[1]), g, w, h)],
    )
    cv2.circle(canvas, (round(o[0]), round(o[1])), round(1.6 * mark), (20, 20, 20), -1)
    for x, y in pts:
        cv2.circle(canvas, (round(x * 16), round(y * 16)), round(mark * 16), MARK_BGR, -1, 16, 4)

    boxes = layout.finish()
    return Numbering(canvas, plain, s, (float(origin[0]), float(origin[1])), labels, boxes)


def _side_order(pts: F64, gaps: F64, w: int, h: int) -> list[int]:
    """The sides of `around` (indices) in the order every label tries them: those whose
    label (`w` x `h`) lies nearest its own point relative to the nearest other point first,
    by the median over the board's points. A label is read as naming the point it is
    closest to; one order for all keeps a regular grid's labels on one side."""
    if len(pts) < 2:
        return list(range(6))
    tree = cKDTree(pts)
    scores = np.zeros((len(pts), 6))
    for k, (x, y) in enumerate(pts):
        for j, org in enumerate(around(float(x), float(y), float(gaps[k]), w, h)):
            c = (org[0] + 0.5 * w, org[1] - 0.5 * h)
            d, i = tree.query(c, k=2)
            own = float(np.hypot(c[0] - x, c[1] - y))
            near = float(d[1] if i[0] == k else d[0])
            scores[k, j] = own / max(near, 1e-9)
    return [int(j) for j in np.argsort(np.median(scores, axis=0), kind="stable")]


def numbering_figure(board: Any, width: int = 1000) -> bytes:
    """The numbering picture of `board` as PNG bytes (see draw_numbering)."""
    ok, buf = cv2.imencode(
        ".png", draw_numbering(board, width).image, [cv2.IMWRITE_PNG_COMPRESSION, 9]
    )
    if not ok:
        raise ImageError("could not encode the numbering picture as PNG")
    return bytes(buf.tobytes())
