"""Printable circle-grid boards at exact physical scale, as SVG or PDF.

``write_board(board, "board.pdf", page="A4")`` writes one page of exactly the paper's size
with the board's dots centred on it, each a filled black circle of its exact diameter at its
exact position (``board.world_points()`` in either layout, ``board.dot_diameters()`` with
the origin marker's); small arrows and labels beside the dot field show the origin (the
centre of dot 0) and how X (along a row) and Y (down a column) run; a 100 mm check bar with
10 mm ticks and a text block with the board's parameters (its dots, what its pitch measures
in its layout, its origin) and the instruction to print at 100 % ("actual size") and measure
the bar sit below (or beside) it, all inside the margins.

Page coordinates, here and in ``PrintLayout``, are millimetres from the page's top-left
corner, x to the right, y down: a world point (X, Y) of the board is printed at
``(X, Y) + PrintLayout.field_offset_mm``.

Both formats are written by hand from one list of shapes, so what is drawn is exactly what
is computed here, numbers written with 9 decimals (1e-9 mm):

* SVG: ``width``/``height`` in mm and a ``viewBox`` in mm, so one user unit is one mm;
  dots are ``<circle>`` elements (exact circles).
* PDF: the MediaBox is the page in points (mm * 72 / 25.4); one ``cm`` operator scales the
  content to mm (72 / 25.4 written to 12 decimals) and flips y; dots are the usual four
  cubic Bezier arcs, exact at their four extreme points and within 0.03 % of the radius
  between them (2 micrometres on a 15 mm dot). Text uses the standard Courier fonts (no
  embedding, widths exactly 0.6 em), and the catalog asks viewers not to scale when
  printing (``/PrintScaling /None``).

Text widths are budgeted at 0.66 em per character (Courier's 0.6 plus 10 % for an SVG
viewer that substitutes another monospace font), heights at 0.8 em above and 0.25 em below
the baseline, so the text stays inside the margins whatever font is substituted.

Files are written atomically (``planarcal.files.atomic_write``): the whole file is rendered
in memory, then appears complete under its name or not at all, an existing target left as it
was on any failure.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import textwrap
import zlib
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Literal
from xml.sax.saxutils import escape, quoteattr

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal.calib.board import CircleGridBoard
from planarcal.errors import BoardError
from planarcal.files import atomic_write

__all__ = [
    "CHECK_BAR_MM",
    "CHECK_TICK_MM",
    "PAGE_SIZES",
    "PT_PER_MM",
    "Orientation",
    "PrintLayout",
    "page_size",
    "pitch_meaning",
    "write_board",
]

Orientation = Literal["auto", "portrait", "landscape"]

PT_PER_MM = 72.0 / 25.4
"""PDF points per millimetre (a point is 1/72 inch, an inch 25.4 mm)."""

CHECK_BAR_MM = 100.0
"""Length of the printed check bar in mm."""

CHECK_TICK_MM = 10.0
"""Spacing of the check bar's ticks in mm."""

PAGE_SIZES: dict[str, tuple[float, float]] = {
    "A0": (841.0, 1189.0),
    "A1": (594.0, 841.0),
    "A2": (420.0, 594.0),
    "A3": (297.0, 420.0),
    "A4": (210.0, 297.0),
    "A5": (148.0, 210.0),
    "A6": (105.0, 148.0),
    "letter": (215.9, 279.4),
    "legal": (215.9, 355.6),
    "tabloid": (279.4, 431.8),
}
"""Standard paper sizes in mm, (width, height) in portrait. ``page_size`` looks names up
case-insensitively and also accepts a custom ``"WxH"`` in mm."""

# Drawing parameters, all in mm.
_AXIS_GAP = 2.0  # between the dot field's outer edge and the axis arrows' shafts
_AXIS_LENGTH = 20.0  # from the origin's tick to the arrow's tip
_ARROW_HEAD = (2.5, 1.0)  # length, half width
_AXIS_WIDTH = 0.3  # stroke of the axis shafts and origin ticks
_AXIS_LABEL = 3.5  # font size of "X" and "Y"
_SMALL_TEXT = 2.5  # font size of the origin label and the bar's numbers
_BAR_WIDTH = 0.3  # stroke of the check bar
_TICK_WIDTH = 0.2  # stroke of its ticks
_TICK_LONG, _TICK_SHORT = 3.5, 2.0  # tick lengths at 0, 50, 100 mm and elsewhere
_BAR_INSET = 3.0  # from the info block's left edge to the bar's 0 tick
_TITLE_TEXT = 3.2  # font size of the info block's first line
_BODY_TEXT = 2.6  # font size of its other lines
_LINE_SPACING = 1.45  # baseline to baseline, in font sizes
_BLOCK_GAP = 5.0  # between the dot field (with its axes) and the info block
_WRAP = 60  # characters per line of the info block's body: about the check bar's width

# Text metrics, in font sizes (em). Courier's advance is exactly 0.6 em; the budget adds 10 %
# for a substituted monospace font in SVG viewers.
_COURIER_ADVANCE = 0.6
_ADVANCE_BUDGET = 0.66
_ASCENT, _DESCENT = 0.8, 0.25
_EPS = 1e-9  # tolerance of the fit tests, mm

_FONT_FAMILY = "Courier, 'Courier New', 'Liberation Mono', 'DejaVu Sans Mono', monospace"

Box = tuple[float, float, float, float]
"""(x0, y0, x1, y1) in page mm, y down."""


# --------------------------------------------------------------------------- page sizes


_CUSTOM_PAGE = re.compile(
    r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*[x\u00d7*]\s*(\d+(?:\.\d*)?|\.\d+)\s*(?:mm)?\s*$",
    re.IGNORECASE,
)


def page_size(name: str) -> tuple[float, float]:
    """The size (width, height) in mm of a paper named ``name``.

    Standard names (``PAGE_SIZES``: A0 to A6, letter, legal, tabloid) are matched
    case-insensitively and given in portrait. A custom size is ``"WxH"`` in mm (``"300x400"``,
    ``"297.5 x 420 mm"``), returned as written. Anything else is a ValueError listing the
    names.
    """
    return _parse_page(name)[1]


def _parse_page(name: str) -> tuple[str, tuple[float, float]]:
    """(canonical label, (width, height) in mm) of a page name; ValueError if it is none."""
    if not isinstance(name, str):
        raise ValueError(f"a page is a name like 'A4' or a size like '300x400' (mm), got {name!r}")
    key = name.strip().lower()
    for standard, size in PAGE_SIZES.items():
        if standard.lower() == key:
            return standard, size
    match = _CUSTOM_PAGE.match(name)
    if match is not None:
        width, height = float(match.group(1)), float(match.group(2))
        if width > 0 and height > 0 and math.isfinite(width) and math.isfinite(height):
            return f"{_num(width)}x{_num(height)}", (width, height)
        raise ValueError(f"a custom page must have a positive width and height, got {name!r}")
    raise ValueError(
        f"unknown page {name!r}: use one of {', '.join(PAGE_SIZES)} (any case) "
        "or a custom size 'WxH' in mm, e.g. '300x400'"
    )


def _num(value: float) -> str:
    """A length for people to read: 10.0 -> '10', 215.9 -> '215.9', 0.1 + 0.2 -> '0.3'."""
    return f"{float(value):.10g}"


def _fmt(value: float) -> str:
    """A coordinate for SVG or PDF: fixed point, 9 decimals, no exponent, no trailing zeros."""
    text = f"{float(value):.9f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


# --------------------------------------------------------------------------- the layout


@dataclasses.dataclass(frozen=True)
class PrintLayout:
    """Where ``write_board`` put everything, in page mm (from the top-left corner, y down).

    ``field_offset_mm`` is the page position of world (0, 0), the centre of dot 0: a world
    point (X, Y) of the board is printed at (X, Y) + field_offset_mm (see ``to_page``). In a
    PDF, whose y runs up from the bottom in points, a page point (x, y) is at
    (x * PT_PER_MM, (page height - y) * PT_PER_MM).
    """

    path: Path
    """The file written."""
    format: Literal["svg", "pdf"]
    board: CircleGridBoard
    page: str
    """The page's name ("A4", "letter") or custom size ("300x400")."""
    page_size_mm: tuple[float, float]
    """(width, height) of the page as laid out, i.e. after ``orientation``."""
    orientation: Literal["portrait", "landscape"]
    margin_mm: float
    field_offset_mm: tuple[float, float]
    """Page position of world (0, 0), the centre of dot 0."""
    field_box_mm: Box
    """The dot field, outer edge to outer edge (``board.extent``), centred on the page."""
    bar_start_mm: tuple[float, float]
    """Left end of the check bar: the centre of its 0 tick on the bar's centre line."""
    bar_end_mm: tuple[float, float]
    """Right end of the check bar (its 100 mm tick), CHECK_BAR_MM to the right."""
    text_box_mm: Box
    """The text block with the board's parameters and the printing instructions."""
    content_box_mm: Box
    """Everything drawn (strokes and the text's budgeted extent included)."""

    @property
    def page_size_pt(self) -> tuple[float, float]:
        """(width, height) of the page in PDF points: the PDF's MediaBox."""
        return (self.page_size_mm[0] * PT_PER_MM, self.page_size_mm[1] * PT_PER_MM)

    @property
    def usable_box_mm(self) -> Box:
        """The page inside its margins: ``content_box_mm`` lies within it."""
        w, h = self.page_size_mm
        m = self.margin_mm
        return (m, m, w - m, h - m)

    @property
    def bar_length_mm(self) -> float:
        return self.bar_end_mm[0] - self.bar_start_mm[0]

    def to_page(self, world_points: ArrayLike) -> NDArray[np.float64]:
        """Page positions in mm of world points (N, 2) in mm."""
        points = np.asarray(world_points, dtype=np.float64).reshape(-1, 2)
        return points + np.asarray(self.field_offset_mm, dtype=np.float64)


@dataclasses.dataclass(frozen=True)
class _Circle:
    cx: float
    cy: float
    r: float
    group: str
    id: str
    cls: str

    def box(self) -> Box:
        return (self.cx - self.r, self.cy - self.r, self.cx + self.r, self.cy + self.r)


@dataclasses.dataclass(frozen=True)
class _Line:
    x1: float
    y1: float
    x2: float
    y2: float
    width: float
    group: str
    id: str
    cls: str

    def box(self) -> Box:
        # Butt caps: the stroke reaches w/2 to either side; w/2 along is a safe bound too.
        h = self.width / 2
        return (
            min(self.x1, self.x2) - h,
            min(self.y1, self.y2) - h,
            max(self.x1, self.x2) + h,
            max(self.y1, self.y2) + h,
        )


@dataclasses.dataclass(frozen=True)
class _Polygon:
    points: tuple[tuple[float, float], ...]
    group: str
    id: str
    cls: str

    def box(self) -> Box:
        xs = [p[0] for p in self.points]
        ys = [p[1] for p in self.points]
        return (min(xs), min(ys), max(xs), max(ys))


@dataclasses.dataclass(frozen=True)
class _Text:
    x: float
    y: float  # baseline
    text: str
    size: float
    anchor: Literal["start", "middle", "end"]
    bold: bool
    group: str
    id: str
    cls: str

    def _left(self, width: float) -> float:
        if self.anchor == "middle":
            return self.x - width / 2
        if self.anchor == "end":
            return self.x - width
        return self.x

    def pdf_x(self) -> float:
        """Where the text starts with Courier's exact advance."""
        return self._left(_COURIER_ADVANCE * self.size * len(self.text))

    def box(self) -> Box:
        width = _ADVANCE_BUDGET * self.size * len(self.text)
        left = self._left(width)
        return (left, self.y - _ASCENT * self.size, left + width, self.y + _DESCENT * self.size)


_Shape = _Circle | _Line | _Polygon | _Text


def _union(boxes: Iterable[Box]) -> Box:
    x0s, y0s, x1s, y1s = zip(*boxes, strict=True)
    return (min(x0s), min(y0s), max(x1s), max(y1s))


def _shift(shape: _Shape, dx: float, dy: float) -> _Shape:
    if isinstance(shape, _Circle):
        return dataclasses.replace(shape, cx=shape.cx + dx, cy=shape.cy + dy)
    if isinstance(shape, _Line):
        return dataclasses.replace(
            shape, x1=shape.x1 + dx, y1=shape.y1 + dy, x2=shape.x2 + dx, y2=shape.y2 + dy
        )
    if isinstance(shape, _Polygon):
        return dataclasses.replace(shape, points=tuple((x + dx, y + dy) for x, y in shape.points))
    return dataclasses.replace(shape, x=shape.x + dx, y=shape.y + dy)


def _inside(box: Box, frame: Box) -> bool:
    return (
        box[0] >= frame[0] - _EPS
        and box[1] >= frame[1] - _EPS
        and box[2] <= frame[2] + _EPS
        and box[3] <= frame[3] + _EPS
    )


@dataclasses.dataclass(frozen=True)
class _Drawing:
    """A laid-out page: its shapes and where things are."""

    page: str
    size: tuple[float, float]
    orientation: Literal["portrait", "landscape"]
    margin: float
    shapes: tuple[_Shape, ...]
    offset: tuple[float, float]
    field_box: Box
    bar_start: tuple[float, float]
    text_box: Box
    content_box: Box


def _dots_and_axes(
    board: CircleGridBoard, width: float, height: float
) -> tuple[list[_Shape], tuple[float, float], Box]:
    """The dots, centred on a page of this size, and the axis marks beside them."""
    points = board.world_points()
    diameters = board.dot_diameters()
    # The centres span from dot 0 at (0, 0) to the largest X and Y of any dot (in the
    # asymmetric layout the last column's X is on a shifted row).
    span_x, span_y = (float(v) for v in points.max(axis=0))
    ox = (width - span_x) / 2
    oy = (height - span_y) / 2
    # board.extent: half the biggest dot (the origin marker, if larger) past the outer
    # centres on every side.
    ex, ey = board.extent
    field_box = (
        ox + span_x / 2 - ex / 2,
        oy + span_y / 2 - ey / 2,
        ox + span_x / 2 + ex / 2,
        oy + span_y / 2 + ey / 2,
    )

    shapes: list[_Shape] = []
    for k in range(board.n_points):
        is_origin = k == 0
        shapes.append(
            _Circle(
                cx=ox + float(points[k, 0]),
                cy=oy + float(points[k, 1]),
                r=float(diameters[k]) / 2,
                group="dots",
                id=f"dot-{k}",
                cls="dot origin" if is_origin else "dot",
            )
        )

    # An L at the field's top-left corner: X shaft above the top row, Y shaft left of the
    # first column, ticks pointing at dot 0's row and column, arrows 20 mm past the origin.
    head_len, head_half = _ARROW_HEAD
    xa = field_box[0] - _AXIS_GAP - head_half
    ya = field_box[1] - _AXIS_GAP - head_half
    tip_x = ox + _AXIS_LENGTH
    tip_y = oy + _AXIS_LENGTH
    axis = "axes"
    shapes += [
        _Line(xa, ya, tip_x - head_len, ya, _AXIS_WIDTH, axis, "x-axis", "axis"),
        _Polygon(
            ((tip_x, ya), (tip_x - head_len, ya - head_half), (tip_x - head_len, ya + head_half)),
            axis,
            "x-arrow",
            "arrow",
        ),
        _Line(xa, ya, xa, tip_y - head_len, _AXIS_WIDTH, axis, "y-axis", "axis"),
        _Polygon(
            ((xa, tip_y), (xa - head_half, tip_y - head_len), (xa + head_half, tip_y - head_len)),
            axis,
            "y-arrow",
            "arrow",
        ),
        # The origin's ticks: from the shafts to just short of the field, on dot 0's centre.
        _Line(ox, ya, ox, field_box[1] - 0.5, _AXIS_WIDTH, axis, "origin-x-tick", "tick"),
        _Line(xa, oy, field_box[0] - 0.5, oy, _AXIS_WIDTH, axis, "origin-y-tick", "tick"),
        _Text(
            tip_x + 1.0,
            ya + 0.3 * _AXIS_LABEL,
            "X",
            _AXIS_LABEL,
            "start",
            True,
            axis,
            "x-label",
            "label",
        ),
        _Text(
            xa,
            tip_y + 1.0 + 0.7 * _AXIS_LABEL,
            "Y",
            _AXIS_LABEL,
            "middle",
            True,
            axis,
            "y-label",
            "label",
        ),
        _Text(
            xa - _AXIS_WIDTH / 2,
            ya - head_half - 0.5 - _DESCENT * _SMALL_TEXT,
            "origin (0, 0)",
            _SMALL_TEXT,
            "start",
            False,
            axis,
            "origin-label",
            "label",
        ),
    ]
    return shapes, (ox, oy), field_box


def pitch_meaning(board: CircleGridBoard) -> str:
    """What the pitch measures on ``board``, in words: "dots 20 mm apart along rows and
    columns", or in the asymmetric layout "rows 15 mm apart, dots 30 mm apart along a row,
    every other row shifted 15 mm"."""
    pitch = _num(board.pitch)
    if board.layout == "asymmetric":
        return (
            f"rows {pitch} mm apart, dots {_num(2 * board.pitch)} mm apart along a row, "
            f"every other row shifted {pitch} mm"
        )
    return f"dots {pitch} mm apart along rows and columns"


def _board_lines(board: CircleGridBoard) -> list[str]:
    """The info block's description of the board (board.describe(), told for print): its
    dots, its layout, its origin. Lines may be long; the caller wraps them."""
    ex, ey = board.extent
    if board.origin_marker:
        origin = f"origin: the {_num(board.origin_marker_diameter)} mm dot"
    else:
        origin = "origin: dot 0, top left"
    # An asymmetric grid's columns zigzag, so its Y is better told by the rows.
    y_axis = "Y down a column" if board.layout == "symmetric" else "Y across the rows"
    return [
        f"dots {_num(board.dots_mm())} mm, pitch {_num(board.pitch)} mm, "
        f"field {_num(ex)} x {_num(ey)} mm",
        f"{board.layout} grid: {pitch_meaning(board)}",
        f"{origin}; X along a row, {y_axis}",
    ]


def _info_block(
    board: CircleGridBoard,
    page: str,
    size: tuple[float, float],
    orientation: str,
    margin: float,
    arrangement: Literal["stacked", "side"],
) -> tuple[list[_Shape], tuple[float, float], Box]:
    """The check bar and the text, the bar over the text ("stacked") or beside it ("side"),
    with their top-left at (0, 0); also the bar's start and the text's box there."""
    shapes: list[_Shape] = []
    x0 = _BAR_INSET
    yb = _BAR_WIDTH / 2  # the bar's centre line
    group = "check-bar"
    shapes.append(_Line(x0, yb, x0 + CHECK_BAR_MM, yb, _BAR_WIDTH, group, "bar", "bar"))
    n_ticks = round(CHECK_BAR_MM / CHECK_TICK_MM)
    for i in range(n_ticks + 1):
        x = x0 + i * CHECK_TICK_MM
        long = i % 5 == 0 or i == n_ticks
        length = _TICK_LONG if long else _TICK_SHORT
        shapes.append(_Line(x, yb, x, yb + length, _TICK_WIDTH, group, f"tick-{i}", "tick"))
        number = _num(i * CHECK_TICK_MM)
        baseline = yb + _TICK_LONG + 0.6 + _ASCENT * _SMALL_TEXT
        if i < n_ticks:
            label = _Text(x, baseline, number, _SMALL_TEXT, "middle", False, group, "", "")
        else:  # "100 mm", starting where a centred "100" would
            x -= len(number) / 2 * _COURIER_ADVANCE * _SMALL_TEXT
            label = _Text(x, baseline, f"{number} mm", _SMALL_TEXT, "start", False, group, "", "")
        shapes.append(dataclasses.replace(label, id=f"tick-label-{i}", cls="tick-label"))
    bar_box = _union(s.box() for s in shapes)

    w, h = size
    bar_word = "above" if arrangement == "stacked" else "beside"
    lines = [(f"planarcal circle-grid board, {board.cols} x {board.rows} dots", _TITLE_TEXT, True)]
    page_line = f"page {page} {orientation} ({_num(w)} x {_num(h)} mm), margins {_num(margin)} mm"
    for line in [*_board_lines(board), page_line]:
        lines += [(part, _BODY_TEXT, False) for part in textwrap.wrap(line, _WRAP)]
    lines += [
        ('PRINT AT 100% / "ACTUAL SIZE", not "fit to page";', _BODY_TEXT, True),
        (f"the bar {bar_word} must measure {_num(CHECK_BAR_MM)} mm.", _BODY_TEXT, True),
    ]
    if arrangement == "stacked":
        left, y = 0.0, bar_box[3] + 3.0
    else:
        left, y = bar_box[2] + 6.0, 0.0
    text_shapes: list[_Shape] = []
    for i, (text, font, bold) in enumerate(lines):
        y += (_ASCENT if i == 0 else _LINE_SPACING) * font
        text_shapes.append(_Text(left, y, text, font, "start", bold, "info", f"info-{i}", "info"))
    shapes += text_shapes
    text_box = _union(s.box() for s in text_shapes)
    return shapes, (x0, yb), text_box


def _layout(
    board: CircleGridBoard,
    page: str,
    size: tuple[float, float],
    orientation: Literal["portrait", "landscape"],
    margin: float,
) -> _Drawing | None:
    """The page laid out, or None when something would cross the margins."""
    width, height = size
    usable = (margin, margin, width - margin, height - margin)
    if usable[2] - usable[0] <= 0 or usable[3] - usable[1] <= 0:
        return None
    core, offset, field_box = _dots_and_axes(board, width, height)
    core_box = _union(s.box() for s in core)
    if not _inside(core_box, usable):
        return None
    field_cx = (field_box[0] + field_box[2]) / 2
    field_cy = (field_box[1] + field_box[3]) / 2

    def clamp(value: float, low: float, high: float) -> float:
        return max(low, min(value, high))

    # The bar and text below the field, above it, right of it, left of it, stacked or side by
    # side: the first with room. Each candidate lies wholly outside the core's box, so
    # nothing overlaps.
    arrangements: tuple[Literal["stacked", "side"], ...] = ("stacked", "side")
    for arrangement in arrangements:
        info, bar_start, text_box = _info_block(board, page, size, orientation, margin, arrangement)
        info_box = _union(s.box() for s in info)
        iw = info_box[2] - info_box[0]
        ih = info_box[3] - info_box[1]
        across = clamp(field_cx - iw / 2, usable[0], usable[2] - iw)
        down = clamp(field_cy - ih / 2, usable[1], usable[3] - ih)
        candidates = [
            (across, core_box[3] + _BLOCK_GAP),
            (across, core_box[1] - _BLOCK_GAP - ih),
            (core_box[2] + _BLOCK_GAP, down),
            (core_box[0] - _BLOCK_GAP - iw, down),
        ]
        for left, top in candidates:
            dx, dy = left - info_box[0], top - info_box[1]
            placed_box = (info_box[0] + dx, info_box[1] + dy, info_box[2] + dx, info_box[3] + dy)
            if not _inside(placed_box, usable):
                continue
            shapes = tuple(core) + tuple(_shift(s, dx, dy) for s in info)
            return _Drawing(
                page=page,
                size=(width, height),
                orientation=orientation,
                margin=margin,
                shapes=shapes,
                offset=offset,
                field_box=field_box,
                bar_start=(bar_start[0] + dx, bar_start[1] + dy),
                text_box=(text_box[0] + dx, text_box[1] + dy, text_box[2] + dx, text_box[3] + dy),
                content_box=_union(s.box() for s in shapes),
            )
    return None


def _oriented(size: tuple[float, float], orientation: str) -> tuple[float, float]:
    short, long = sorted(size)
    return (short, long) if orientation == "portrait" else (long, short)


def _room(board: CircleGridBoard, drawing: _Drawing) -> float:
    """How much room the dot field leaves on the page: the smaller of the two slacks."""
    ex, ey = board.extent
    w, h = drawing.size
    return min(w - ex, h - ey)


def _fit(
    board: CircleGridBoard,
    page: str,
    size: tuple[float, float],
    orientation: str,
    margin: float,
) -> _Drawing | None:
    """The best layout for this orientation ('auto': the fitting one with more room,
    portrait on a tie), or None."""
    drawings: list[_Drawing] = []
    for candidate in ("portrait", "landscape"):
        if orientation in ("auto", candidate):
            o: Literal["portrait", "landscape"] = (
                "portrait" if candidate == "portrait" else "landscape"
            )
            drawing = _layout(board, page, _oriented(size, o), o, margin)
            if drawing is not None:
                drawings.append(drawing)
    if not drawings:
        return None
    # max keeps the first of equals: portrait.
    return max(drawings, key=lambda d: _room(board, d))


def _family(name: str) -> str:
    return "ISO A" if re.fullmatch(r"A\d", name) else "US" if name in PAGE_SIZES else "custom"


def _smallest_page(board: CircleGridBoard, margin: float, family: str) -> str:
    """The smallest standard page the board fits on, of the same family as the page asked
    for (ISO A or US) when one is, or else a custom size that fits."""
    fitting: list[tuple[str, str]] = []  # (name, orientation), smallest first
    for name, size in sorted(PAGE_SIZES.items(), key=lambda item: item[1][0] * item[1][1]):
        drawing = _fit(board, name, size, "auto", margin)
        if drawing is not None:
            fitting.append((name, drawing.orientation))
    if fitting:
        same = [f for f in fitting if _family(f[0]) == family]
        name, orientation = same[0] if same else fitting[0]
        if name == fitting[0][0]:
            return f"the smallest that fits is {name}, in {orientation}"
        return (
            f"the smallest {family} page that fits is {name}, in {orientation} "
            f"({fitting[0][0]}, in {fitting[0][1]}, is the smallest standard page that does)"
        )
    # None does: lay it out on a huge page and measure what it takes around the centred field.
    huge = 4.0 * (sum(board.extent) + 1000.0 + margin)
    for _ in range(4):
        drawing = _layout(board, "custom", (huge, huge), "landscape", margin)
        if drawing is None:  # pragma: no cover - the huge page fits by construction
            break
        cx, cy = huge / 2, huge / 2
        box = drawing.content_box
        w = math.ceil(2 * max(cx - box[0], box[2] - cx) + 2 * margin + 1.0)
        h = math.ceil(2 * max(cy - box[1], box[3] - cy) + 2 * margin + 1.0)
        label = f"{w}x{h}"
        if _fit(board, label, (float(w), float(h)), "auto", margin) is not None:
            return (
                f"no standard page is large enough: use a custom page of at least {label} mm "
                f"(page='{label}')"
            )
        huge *= 2
    return "no standard page is large enough"  # pragma: no cover


# --------------------------------------------------------------------------- writers


def _svg(drawing: _Drawing, board: CircleGridBoard) -> bytes:
    w, h = drawing.size
    title = f"planarcal circle-grid board: {board.describe()}; {drawing.page} {drawing.orientation}"
    out = [
        '<?xml version="1.0" encoding="UTF-8" standalone="no"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{_fmt(w)}mm" '
        f'height="{_fmt(h)}mm" viewBox="0 0 {_fmt(w)} {_fmt(h)}">',
        f"<title>{escape(title)}</title>",
        "<desc>Print at 100% (actual size); one user unit is one millimetre. World point "
        f"(X, Y) of the board is at page ({_fmt(drawing.offset[0])} + X, "
        f"{_fmt(drawing.offset[1])} + Y).</desc>",
        f'<rect id="page" x="0" y="0" width="{_fmt(w)}" height="{_fmt(h)}" fill="#ffffff"/>',
    ]
    groups: dict[str, list[str]] = {}
    for shape in drawing.shapes:
        attrs = f'id="{shape.id}" class="{shape.cls}"'
        if isinstance(shape, _Circle):
            element = (
                f'<circle {attrs} cx="{_fmt(shape.cx)}" cy="{_fmt(shape.cy)}" r="{_fmt(shape.r)}"/>'
            )
        elif isinstance(shape, _Line):
            element = (
                f'<line {attrs} x1="{_fmt(shape.x1)}" y1="{_fmt(shape.y1)}" '
                f'x2="{_fmt(shape.x2)}" y2="{_fmt(shape.y2)}" '
                f'stroke="#000000" stroke-width="{_fmt(shape.width)}" stroke-linecap="butt"/>'
            )
        elif isinstance(shape, _Polygon):
            points = " ".join(f"{_fmt(x)},{_fmt(y)}" for x, y in shape.points)
            element = f'<polygon {attrs} points="{points}"/>'
        else:
            weight = ' font-weight="bold"' if shape.bold else ""
            element = (
                f'<text {attrs} x="{_fmt(shape.x)}" y="{_fmt(shape.y)}" '
                f'font-size="{_fmt(shape.size)}" text-anchor="{shape.anchor}"{weight}>'
                f"{escape(shape.text)}</text>"
            )
        groups.setdefault(shape.group, []).append(element)
    for group, elements in groups.items():
        # Only lines are stroked (each says so); everything else is filled black.
        has_text = any(e.startswith("<text") for e in elements)
        font = f" font-family={quoteattr(_FONT_FAMILY)}" if has_text else ""
        out.append(f'<g id="{group}" fill="#000000" stroke="none"{font}>')
        out += elements
        out.append("</g>")
    out.append("</svg>")
    return ("\n".join(out) + "\n").encode("utf-8")


_KAPPA = 4.0 * (math.sqrt(2.0) - 1.0) / 3.0  # Bezier control distance of a quarter circle


def _pdf_string(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace("(", "\\(").replace(")", "\\)")
    return f"({escaped})"


def _pdf_content(drawing: _Drawing) -> bytes:
    h = drawing.size[1]
    k = f"{PT_PER_MM:.12f}"
    ops = [
        "% planarcal board: user units are mm from the top-left corner, y down",
        f"q {k} 0 0 -{k} 0 {_fmt(h * PT_PER_MM)} cm",
        "0 g 0 G 0 J 0 j",
    ]
    for shape in drawing.shapes:
        if isinstance(shape, _Circle):
            cx, cy, r = shape.cx, shape.cy, shape.r
            c = _KAPPA * r
            f = _fmt
            ops.append(
                f"{f(cx + r)} {f(cy)} m "
                f"{f(cx + r)} {f(cy + c)} {f(cx + c)} {f(cy + r)} {f(cx)} {f(cy + r)} c "
                f"{f(cx - c)} {f(cy + r)} {f(cx - r)} {f(cy + c)} {f(cx - r)} {f(cy)} c "
                f"{f(cx - r)} {f(cy - c)} {f(cx - c)} {f(cy - r)} {f(cx)} {f(cy - r)} c "
                f"{f(cx + c)} {f(cy - r)} {f(cx + r)} {f(cy - c)} {f(cx + r)} {f(cy)} c h f"
            )
        elif isinstance(shape, _Line):
            ops.append(
                f"{_fmt(shape.width)} w {_fmt(shape.x1)} {_fmt(shape.y1)} m "
                f"{_fmt(shape.x2)} {_fmt(shape.y2)} l S"
            )
        elif isinstance(shape, _Polygon):
            (x0, y0), *rest = shape.points
            path = " ".join(f"{_fmt(x)} {_fmt(y)} l" for x, y in rest)
            ops.append(f"{_fmt(x0)} {_fmt(y0)} m {path} h f")
        else:
            font = "/F2" if shape.bold else "/F1"
            ops.append(
                f"BT {font} {_fmt(shape.size)} Tf 1 0 0 -1 {_fmt(shape.pdf_x())} "
                f"{_fmt(shape.y)} Tm {_pdf_string(shape.text)} Tj ET"
            )
    ops.append("Q")
    return ("\n".join(ops) + "\n").encode("latin-1")


def _pdf(drawing: _Drawing, board: CircleGridBoard) -> bytes:
    w, h = drawing.size
    content = zlib.compress(_pdf_content(drawing), 9)
    title = f"planarcal circle-grid board: {board.describe()}"
    objects: list[bytes] = [
        b"<< /Type /Catalog /Pages 2 0 R "
        b"/ViewerPreferences << /PrintScaling /None /PickTrayByPDFSize true >> >>",
        b"<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
        (
            f"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {_fmt(w * PT_PER_MM)} "
            f"{_fmt(h * PT_PER_MM)}] /Resources << /Font << /F1 5 0 R /F2 6 0 R >> >> "
            "/Contents 4 0 R >>"
        ).encode("latin-1"),
        f"<< /Length {len(content)} /Filter /FlateDecode >>\nstream\n".encode("latin-1")
        + content
        + b"\nendstream",
        b"<< /Type /Font /Subtype /Type1 /BaseFont /Courier /Encoding /WinAnsiEncoding >>",
        b"<< /Type /Font /Subtype /Type1 /BaseFont /Courier-Bold /Encoding /WinAnsiEncoding >>",
        f"<< /Title {_pdf_string(title)} /Producer (planarcal) >>".encode("latin-1"),
    ]
    out = bytearray(b"%PDF-1.7\n%\xe2\xe3\xcf\xd3\n")
    offsets = []
    for number, body in enumerate(objects, start=1):
        offsets.append(len(out))
        out += f"{number} 0 obj\n".encode("latin-1") + body + b"\nendobj\n"
    xref = len(out)
    out += f"xref\n0 {len(objects) + 1}\n".encode("latin-1")
    out += b"0000000000 65535 f \n"
    for offset in offsets:
        out += f"{offset:010d} 00000 n \n".encode("latin-1")
    out += (
        f"trailer\n<< /Size {len(objects) + 1} /Root 1 0 R /Info {len(objects)} 0 R >>\n"
        f"startxref\n{xref}\n%%EOF\n"
    ).encode("latin-1")
    return bytes(out)


# --------------------------------------------------------------------------- the entry point


def write_board(
    board: CircleGridBoard,
    path: str | os.PathLike[str],
    *,
    page: str | Sequence[float] = "A4",
    orientation: Orientation = "auto",
    margin_mm: float = 10.0,
) -> PrintLayout:
    """Write ``board`` to ``path`` as a printable page at exact scale; returns the layout.

    The format follows the suffix: ``.svg`` or ``.pdf`` (any case); anything else is a
    ValueError. ``page`` is a name from ``PAGE_SIZES`` (any case), a custom ``"WxH"`` in mm,
    or a (width, height) pair in mm; custom sizes are turned like standard ones.
    ``orientation`` is ``"portrait"`` (the short side across), ``"landscape"`` or ``"auto"``:
    whichever fits, and if both do, the one that leaves the dot field more room (the larger
    of the two orientations' smaller slack around it), portrait on a tie. ``margin_mm`` is
    kept clear on every side.

    Raises BoardError when the board, with its axis marks, check bar and text, does not fit
    inside the margins (in the orientation asked for, or in either for ``"auto"``): the
    message gives the dot field's extent, the page's usable size, and the smallest standard
    page that fits, and when the board leaves its dots' diameter unknown (``diameter=None``):
    a printed dot needs a size. An unwritable path raises OSError naming it; the file is
    written atomically (see the module's docstring).
    """
    target = Path(os.fspath(path))
    suffix = target.suffix.lower()
    if suffix not in (".svg", ".pdf"):
        raise ValueError(
            f"cannot tell the format of {str(target)!r} from its suffix "
            f"{target.suffix or '(none)'!r}: use .svg or .pdf"
        )
    fmt: Literal["svg", "pdf"] = "svg" if suffix == ".svg" else "pdf"
    if orientation not in ("auto", "portrait", "landscape"):
        raise ValueError(
            f"orientation must be 'auto', 'portrait' or 'landscape', got {orientation!r}"
        )
    if isinstance(margin_mm, bool) or not isinstance(margin_mm, int | float | np.number):
        raise ValueError(f"margin_mm must be a length in mm, got {margin_mm!r}")
    margin = float(margin_mm)
    if not (math.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin_mm must be a finite length >= 0 in mm, got {margin_mm!r}")
    if isinstance(page, str):
        label, size = _parse_page(page)
    else:
        try:
            pw, ph = (float(v) for v in page)
        except (TypeError, ValueError):
            raise ValueError(
                f"a page is a name like 'A4', a size like '300x400' or (width, height) in mm, "
                f"got {page!r}"
            ) from None
        if not (pw > 0 and ph > 0 and math.isfinite(pw) and math.isfinite(ph)):
            raise ValueError(f"a page must have a positive width and height, got {page!r}")
        label, size = f"{_num(pw)}x{_num(ph)}", (pw, ph)

    board.dots_mm()  # BoardError when the dots' size is unknown: it cannot be printed
    drawing = _fit(board, label, size, orientation, margin)
    if drawing is None:
        raise BoardError(_refusal(board, label, size, orientation, margin))

    data = _svg(drawing, board) if fmt == "svg" else _pdf(drawing, board)
    atomic_write(target, data)
    return PrintLayout(
        path=target,
        format=fmt,
        board=board,
        page=drawing.page,
        page_size_mm=drawing.size,
        orientation=drawing.orientation,
        margin_mm=margin,
        field_offset_mm=drawing.offset,
        field_box_mm=drawing.field_box,
        bar_start_mm=drawing.bar_start,
        bar_end_mm=(drawing.bar_start[0] + CHECK_BAR_MM, drawing.bar_start[1]),
        text_box_mm=drawing.text_box,
        content_box_mm=drawing.content_box,
    )


def _refusal(
    board: CircleGridBoard, label: str, size: tuple[float, float], orientation: str, margin: float
) -> str:
    ex, ey = board.extent
    tried = ("portrait", "landscape") if orientation == "auto" else (orientation,)
    usable = []
    for o in tried:
        w, h = _oriented(size, o)
        usable.append(f"{_num(max(w - 2 * margin, 0))} x {_num(max(h - 2 * margin, 0))} mm ({o})")
    where = "in either orientation" if orientation == "auto" else f"in {orientation}"
    message = (
        f"the board ({board.describe()}) does not fit on {label} {where}: its dots span "
        f"{_num(ex)} x {_num(ey)} mm, and the axis marks, the "
        f"{_num(CHECK_BAR_MM)} mm check bar and the text need room beside them, but the page "
        f"leaves {' or '.join(usable)} inside {_num(margin)} mm margins"
    )
    if orientation != "auto" and _fit(board, label, size, "auto", margin) is not None:
        other = "landscape" if orientation == "portrait" else "portrait"
        return f"{message}; it fits in {other} (orientation='{other}' or 'auto')"
    return f"{message}; use a larger page: {_smallest_page(board, margin, _family(label))}"
