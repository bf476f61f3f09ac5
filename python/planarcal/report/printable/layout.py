"""The page laid out: the board's marks (a circle grid's dots, a chessboard's or ChArUco
board's squares and markers: ``board.ink()``) centred on it with the axis marks beside them,
the 100 mm check bar and the text block placed where they fit inside the margins, and the
orientation chosen (refusal.py says why a board does not fit, and what would)."""

from __future__ import annotations

import dataclasses
import functools
import textwrap
from collections.abc import Iterator
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.report.printable.options import board_options
from planarcal.report.printable.pages import num, oriented
from planarcal.report.printable.shapes import (
    ASCENT,
    COURIER_ADVANCE,
    DESCENT,
    Area,
    Box,
    Circle,
    Line,
    Polygon,
    Shape,
    Text,
    inside,
    shift,
    union,
)

F64 = NDArray[np.float64]

CHECK_BAR_MM = 100.0
"""Length of the printed check bar in mm."""

MARGIN_MM = 10.0
"""The page margin a board is printed within unless told otherwise, in mm."""


CHECK_TICK_MM = 10.0
"""Spacing of the check bar's ticks in mm."""


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
_SURE = 1e-6  # a field this much wider than the page's room surely does not fit, mm


_Info = tuple[list[Shape], tuple[float, float], Box]
"""An info block drawn at (0, 0): its shapes, the check bar's start and the text's box."""


@dataclasses.dataclass(frozen=True)
class Drawing:
    """A laid-out page: its shapes and where things are."""

    page: str
    size: tuple[float, float]
    orientation: Literal["portrait", "landscape"]
    margin: float
    shapes: tuple[Shape, ...]
    offset: tuple[float, float]
    field_box: Box
    bar_start: tuple[float, float]
    text_box: Box
    content_box: Box


def _ink_field(board: ChessboardBoard | CharucoBoard) -> Box:
    """``board.ink().field`` without drawing the ink (a board of a million squares is tried
    on many pages): a chessboard's squares start one square before its first inner corner,
    a ChArUco board's at its origin. Tested equal to the ink's."""
    width, height = board.extent
    if isinstance(board, ChessboardBoard):
        s = float(board.square)
        return (-s, -s, width - s, height - s)
    return (0.0, 0.0, width, height)


@functools.lru_cache(maxsize=256)  # a board is tried on several pages, in both orientations
def _outer_dots(board: CircleGridBoard) -> tuple[F64, F64]:
    """The centres (world mm) and radii of the dots that can reach the dot field's edges:
    dot 0 (the marker, larger or smaller than the rest), its neighbours along the first row
    and column, and the other ends of the rows and columns, in either layout (a board of a
    million dots is tried on many pages; these few bound them all). The same numbers as
    ``board.world_points()`` and ``board.dot_diameters()`` give them (tested)."""
    cols, rows = board.cols, board.rows
    # The first and last dot of the first, second, third and last rows.
    ends = [r * cols + c for r in (0, 1, 2, rows - 1) if r < rows for c in (0, 1, cols - 1)]
    ids = np.unique(np.array(ends, dtype=np.int64))
    r, c = np.divmod(ids, cols)
    if board.layout == "asymmetric":
        c = 2 * c + r % 2
    pitch = float(board.pitch)
    centres = np.column_stack([c * pitch, r * pitch])
    diameters = np.full(len(ids), board.dots_mm())
    diameters[ids == 0] = board.origin_marker_diameter
    radii = diameters / 2
    centres.flags.writeable = radii.flags.writeable = False  # shared by the cache
    return centres, radii


def extent(board: Board) -> tuple[float, float]:
    """``board.extent``, a circle grid's from its outer dots (``_outer_dots``) rather than
    all of them: the same numbers (tested), in the same sums."""
    if not isinstance(board, CircleGridBoard):
        return board.extent
    span = _outer_dots(board)[0].max(axis=0)
    biggest = max(board.dots_mm(), board.origin_marker_diameter)
    return (float(span[0]) + biggest, float(span[1]) + biggest)


def _frame(board: Board, width: float, height: float) -> tuple[tuple[float, float], Box, Box]:
    """Where the board goes, centred on a page of this size: the page position of world
    (0, 0), the field's box (``board.extent``) and the box its marks cover, all without
    drawing them."""
    if isinstance(board, CircleGridBoard):
        points, radii = _outer_dots(board)
        # The centres span from dot 0 at (0, 0) to the largest X and Y of any dot (in the
        # asymmetric layout the last column's X is on a shifted row).
        span_x, span_y = (float(v) for v in points.max(axis=0))
        ox = (width - span_x) / 2
        oy = (height - span_y) / 2
        # board.extent: half the biggest dot (the origin marker, if larger) past the outer
        # centres on every side.
        ex, ey = extent(board)
        field_box = (
            ox + span_x / 2 - ex / 2,
            oy + span_y / 2 - ey / 2,
            ox + span_x / 2 + ex / 2,
            oy + span_y / 2 + ey / 2,
        )
        # The dots' own boxes, as _marks draws them (the same sums, so the same numbers).
        xs, ys = ox + points[:, 0], oy + points[:, 1]
        dots_box = (
            float((xs - radii).min()),
            float((ys - radii).min()),
            float((xs + radii).max()),
            float((ys + radii).max()),
        )
        return (ox, oy), field_box, dots_box
    fx0, fy0, fx1, fy1 = _ink_field(board)
    ox = width / 2 - (fx0 + fx1) / 2
    oy = height / 2 - (fy0 + fy1) / 2
    field_box = (ox + fx0, oy + fy0, ox + fx1, oy + fy1)
    # Black squares reach every edge of the field; the markers are inside it.
    return (ox, oy), field_box, field_box


def _marks(board: Board, origin: tuple[float, float]) -> list[Shape]:
    """The board's marks with world (0, 0) at ``origin`` on the page: a circle grid's dots;
    a chessboard's or ChArUco board's ink (``board.ink()``: its black squares and marker
    cells as one area, then a marker's dots)."""
    ox, oy = origin
    shapes: list[Shape] = []
    if isinstance(board, CircleGridBoard):
        points = board.world_points()
        diameters = board.dot_diameters()
        for k in range(board.n_points):
            is_origin = k == 0
            shapes.append(
                Circle(
                    cx=ox + float(points[k, 0]),
                    cy=oy + float(points[k, 1]),
                    r=float(diameters[k]) / 2,
                    group="dots",
                    id=f"dot-{k}",
                    cls="dot origin" if is_origin else "dot",
                )
            )
        return shapes
    ink = board.ink()
    rects = tuple(
        (ox + float(x0), oy + float(y0), ox + float(x1), oy + float(y1))
        for x0, y0, x1, y1 in ink.rects
    )
    shapes.append(Area(rects, "board", "ink", "ink"))
    for k, (cx, cy, r, black) in enumerate(ink.circles):
        shapes.append(
            Circle(
                cx=ox + float(cx),
                cy=oy + float(cy),
                r=float(r),
                group="board",
                id=f"marker-{k}",
                cls="marker origin" if k == 0 else "marker",
                white=not black,
            )
        )
    return shapes


def _axes(origin: tuple[float, float], field_box: Box) -> list[Shape]:
    """The axis marks: an L at the field's top-left corner, X shaft above the top row, Y
    shaft left of the first column, ticks pointing at the origin's row and column, arrows
    20 mm past it."""
    ox, oy = origin
    head_len, head_half = _ARROW_HEAD
    xa = field_box[0] - _AXIS_GAP - head_half
    ya = field_box[1] - _AXIS_GAP - head_half
    tip_x = ox + _AXIS_LENGTH
    tip_y = oy + _AXIS_LENGTH
    axis = "axes"
    return [
        Line(xa, ya, tip_x - head_len, ya, _AXIS_WIDTH, axis, "x-axis", "axis"),
        Polygon(
            ((tip_x, ya), (tip_x - head_len, ya - head_half), (tip_x - head_len, ya + head_half)),
            axis,
            "x-arrow",
            "arrow",
        ),
        Line(xa, ya, xa, tip_y - head_len, _AXIS_WIDTH, axis, "y-axis", "axis"),
        Polygon(
            ((xa, tip_y), (xa - head_half, tip_y - head_len), (xa + head_half, tip_y - head_len)),
            axis,
            "y-arrow",
            "arrow",
        ),
        # The origin's ticks: from the shafts to just short of the field, on the origin.
        Line(ox, ya, ox, field_box[1] - 0.5, _AXIS_WIDTH, axis, "origin-x-tick", "tick"),
        Line(xa, oy, field_box[0] - 0.5, oy, _AXIS_WIDTH, axis, "origin-y-tick", "tick"),
        Text(
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
        Text(
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
        Text(
            xa - _AXIS_WIDTH / 2,
            ya - head_half - 0.5 - DESCENT * _SMALL_TEXT,
            "origin (0, 0)",
            _SMALL_TEXT,
            "start",
            False,
            axis,
            "origin-label",
            "label",
        ),
    ]


def pitch_meaning(board: CircleGridBoard) -> str:
    """What the pitch measures on ``board``, in words: "dots 20 mm apart along rows and
    columns", or in the asymmetric layout "rows 15 mm apart, dots 30 mm apart along a row,
    every other row shifted 15 mm"."""
    pitch = num(board.pitch)
    if board.layout == "asymmetric":
        return (
            f"rows {pitch} mm apart, dots {num(2 * board.pitch)} mm apart along a row, "
            f"every other row shifted {pitch} mm"
        )
    return f"dots {pitch} mm apart along rows and columns"


def _board_lines(board: Board) -> list[str]:
    """The info block's description of the board (board.describe(), told for print) and, but
    for a circle grid (the commands' default), the options to calibrate with it. Lines may
    be long; the caller wraps them."""
    if isinstance(board, CircleGridBoard):
        return _dot_lines(board)
    ex, ey = board.extent
    field = f"{num(ex)} x {num(ey)} mm"
    axes = "X along rows, Y down columns"
    if isinstance(board, CharucoBoard):
        lines = [
            f"{num(board.square)} mm squares, {num(board.marker)} mm markers, {board.dictionary}",
            f"{field}, {board.n_points} corners, ids as OpenCV's CharucoBoard",
            f"origin: top-left outer corner; {axes}",
        ]
        if board.legacy:
            lines.append("legacy layout of OpenCV before 4.6")
        elif board.layouts_differ:
            # An even number of rows: the layouts differ by the top-left square's colour.
            lines.append("OpenCV 4.6+ layout: black top-left square (legacy: white)")
        return lines
    squares = f"{board.cols + 1} x {board.rows + 1} squares of {num(board.square)} mm"
    if board.origin_marker:
        marker = "marker: the three dots about the middle fix the reading"
    else:
        marker = "no marker: turned 180 degrees it reads the same"
    return [f"{squares}, {field}", f"origin: top-left inner corner; {axes}", marker]


def _calibrate_line(board: Board) -> list[str]:
    """What the user types to calibrate with the board (none for a circle grid: its page is
    as it always was, and its options are the defaults' names)."""
    if isinstance(board, CircleGridBoard):
        return []
    options = " ".join(board_options(board))
    return [f"calibrate with: planarcal calibrate PHOTO -o cal.json {options}"]


def _title(board: Board) -> str:
    """The info block's first line."""
    if isinstance(board, CircleGridBoard):
        return f"planarcal circle-grid board, {board.cols} x {board.rows} dots"
    if isinstance(board, CharucoBoard):
        return f"planarcal ChArUco board, {board.squares_x} x {board.squares_y} squares"
    return f"planarcal chessboard, {board.cols} x {board.rows} inner corners"


def document_title(board: Board) -> str:
    """The SVG's and the PDF's title: the board's kind and ``board.describe()``."""
    if isinstance(board, CircleGridBoard):
        return f"planarcal circle-grid board: {board.describe()}"
    return f"planarcal board: {board.describe()}"


def _dot_lines(board: CircleGridBoard) -> list[str]:
    """A circle grid's lines: its dots, its layout, its origin."""
    ex, ey = extent(board)
    if board.origin_marker:
        origin = f"origin: the {num(board.origin_marker_diameter)} mm dot"
    else:
        origin = "origin: dot 0, top left"
    # An asymmetric grid's columns zigzag, so its Y is better told by the rows.
    y_axis = "Y down a column" if board.layout == "symmetric" else "Y across the rows"
    return [
        f"dots {num(board.dots_mm())} mm, pitch {num(board.pitch)} mm, "
        f"field {num(ex)} x {num(ey)} mm",
        f"{board.layout} grid: {pitch_meaning(board)}",
        f"{origin}; X along a row, {y_axis}",
    ]


@functools.lru_cache(maxsize=1)
def _check_bar() -> tuple[tuple[Shape, ...], tuple[float, float], Box]:
    """The 100 mm check bar with its ticks and numbers, its 0 tick's top at (_BAR_INSET, 0):
    its shapes, its start and its box (the same on every page: made once)."""
    shapes: list[Shape] = []
    x0 = _BAR_INSET
    yb = _BAR_WIDTH / 2  # the bar's centre line
    group = "check-bar"
    shapes.append(Line(x0, yb, x0 + CHECK_BAR_MM, yb, _BAR_WIDTH, group, "bar", "bar"))
    n_ticks = round(CHECK_BAR_MM / CHECK_TICK_MM)
    for i in range(n_ticks + 1):
        x = x0 + i * CHECK_TICK_MM
        long = i % 5 == 0 or i == n_ticks
        length = _TICK_LONG if long else _TICK_SHORT
        shapes.append(Line(x, yb, x, yb + length, _TICK_WIDTH, group, f"tick-{i}", "tick"))
        number = num(i * CHECK_TICK_MM)
        baseline = yb + _TICK_LONG + 0.6 + ASCENT * _SMALL_TEXT
        if i < n_ticks:
            label = Text(x, baseline, number, _SMALL_TEXT, "middle", False, group, "", "")
        else:  # "100 mm", starting where a centred "100" would
            x -= len(number) / 2 * COURIER_ADVANCE * _SMALL_TEXT
            label = Text(x, baseline, f"{number} mm", _SMALL_TEXT, "start", False, group, "", "")
        shapes.append(dataclasses.replace(label, id=f"tick-label-{i}", cls="tick-label"))
    return tuple(shapes), (x0, yb), union(s.box() for s in shapes)


def _info_block(
    board: Board,
    page: str,
    size: tuple[float, float],
    orientation: str,
    margin: float,
    arrangement: Literal["stacked", "side"],
) -> tuple[list[Shape], tuple[float, float], Box]:
    """The check bar and the text, the bar over the text ("stacked") or beside it ("side"),
    with their top-left at (0, 0); also the bar's start and the text's box there."""
    bar, bar_start, bar_box = _check_bar()
    shapes: list[Shape] = list(bar)

    w, h = size
    bar_word = "above" if arrangement == "stacked" else "beside"
    lines = [(_title(board), _TITLE_TEXT, True)]
    page_line = f"page {page} {orientation} ({num(w)} x {num(h)} mm), margins {num(margin)} mm"
    for line in [*_board_lines(board), page_line]:
        lines += [(part, _BODY_TEXT, False) for part in textwrap.wrap(line, _WRAP)]
    for line in _calibrate_line(board):
        # Options are not split at their hyphens.
        parts = textwrap.wrap(line, _WRAP, break_on_hyphens=False, break_long_words=False)
        lines += [(part, _BODY_TEXT, False) for part in parts]
    lines += [
        ('PRINT AT 100% / "ACTUAL SIZE", not "fit to page";', _BODY_TEXT, True),
        (f"the bar {bar_word} must measure {num(CHECK_BAR_MM)} mm.", _BODY_TEXT, True),
    ]
    if arrangement == "stacked":
        left, y = 0.0, bar_box[3] + 3.0
    else:
        left, y = bar_box[2] + 6.0, 0.0
    text_shapes: list[Shape] = []
    for i, (text, font, bold) in enumerate(lines):
        y += (ASCENT if i == 0 else _LINE_SPACING) * font
        text_shapes.append(Text(left, y, text, font, "start", bold, "info", f"info-{i}", "info"))
    shapes += text_shapes
    text_box = union(s.box() for s in text_shapes)
    return shapes, bar_start, text_box


def lay_out(
    board: Board,
    page: str,
    size: tuple[float, float],
    orientation: Literal["portrait", "landscape"],
    margin: float,
    draw: bool,
) -> Drawing | None:
    """The page laid out, or None when something would cross the margins. The board's
    marks are placed by the box they cover, and drawn only when ``draw``: a fit is tested
    without them."""
    width, height = size
    usable = (margin, margin, width - margin, height - margin)
    if usable[2] - usable[0] <= 0 or usable[3] - usable[1] <= 0:
        return None
    ex, ey = extent(board)
    if ex > usable[2] - usable[0] + _SURE or ey > usable[3] - usable[1] + _SURE:
        return None  # the field alone is too large
    origin, field_box, marks_box = _frame(board, width, height)
    core = _Core(origin, field_box, marks_box)
    if not inside(core.box, usable):
        return None
    arrangements: tuple[Literal["stacked", "side"], ...] = ("stacked", "side")

    @functools.cache
    def info_block(arrangement: Literal["stacked", "side"]) -> _Info:
        return _info_block(board, page, size, orientation, margin, arrangement)

    def cores() -> Iterator[_Core]:
        # The board centred on the page, the bar and text beside it, as a circle grid
        # always is; a chessboard's or ChArUco board's longer text may need the board moved
        # off centre (the two centred together on the side that has room).
        yield core
        if not isinstance(board, CircleGridBoard):
            for arrangement in arrangements:
                info_box = union(s.box() for s in info_block(arrangement)[0])
                for dx, dy in _moves(core.box, info_box, usable):
                    yield core.moved(dx, dy)

    for candidate in cores():
        for arrangement in arrangements:
            info = info_block(arrangement)
            at = _placed(candidate, info, usable)
            if at is None:
                continue
            info_shapes = [shift(s, at[0], at[1]) for s in info[0]]
            marks = _marks(board, candidate.origin) if draw else []
            bar_start, text_box = info[1], info[2]
            return Drawing(
                page=page,
                size=(width, height),
                orientation=orientation,
                margin=margin,
                shapes=(*marks, *candidate.axes, *info_shapes),
                offset=candidate.origin,
                field_box=candidate.field_box,
                bar_start=(bar_start[0] + at[0], bar_start[1] + at[1]),
                text_box=(
                    text_box[0] + at[0],
                    text_box[1] + at[1],
                    text_box[2] + at[0],
                    text_box[3] + at[1],
                ),
                content_box=union(
                    [candidate.marks_box, *(s.box() for s in (*candidate.axes, *info_shapes))]
                ),
            )
    return None


@dataclasses.dataclass(frozen=True)
class _Core:
    """The board (its marks, by the box they cover) with its axis marks, where it is put."""

    origin: tuple[float, float]
    field_box: Box
    marks_box: Box

    @functools.cached_property
    def axes(self) -> list[Shape]:
        return _axes(self.origin, self.field_box)

    @functools.cached_property
    def box(self) -> Box:
        return union([self.marks_box, *(s.box() for s in self.axes)])

    def moved(self, dx: float, dy: float) -> _Core:
        def move(b: Box) -> Box:
            return (b[0] + dx, b[1] + dy, b[2] + dx, b[3] + dy)

        origin = (self.origin[0] + dx, self.origin[1] + dy)
        return _Core(origin, move(self.field_box), move(self.marks_box))


def _moves(core_box: Box, info_box: Box, usable: Box) -> list[tuple[float, float]]:
    """The shifts of the board (with its axis marks) that centre it and the info block
    together in the usable page, the block below, above, right or left of it."""
    cw, ch = core_box[2] - core_box[0], core_box[3] - core_box[1]
    iw, ih = info_box[2] - info_box[0], info_box[3] - info_box[1]
    top = usable[1] + (usable[3] - usable[1] - (ch + _BLOCK_GAP + ih)) / 2
    left = usable[0] + (usable[2] - usable[0] - (cw + _BLOCK_GAP + iw)) / 2
    return [
        (0.0, top - core_box[1]),
        (0.0, top + ih + _BLOCK_GAP - core_box[1]),
        (left - core_box[0], 0.0),
        (left + iw + _BLOCK_GAP - core_box[0], 0.0),
    ]


def _placed(core: _Core, info: _Info, usable: Box) -> tuple[float, float] | None:
    """Where the bar and text go beside the board: below it, above it, right of it or left
    of it, the first with room (the shift of the info block drawn at (0, 0)), or None."""
    if not inside(core.box, usable):
        return None
    field_cx = (core.field_box[0] + core.field_box[2]) / 2
    field_cy = (core.field_box[1] + core.field_box[3]) / 2

    def clamp(value: float, low: float, high: float) -> float:
        return max(low, min(value, high))

    # Each candidate lies wholly outside the core's box, so nothing overlaps.
    info_box = union(s.box() for s in info[0])
    iw = info_box[2] - info_box[0]
    ih = info_box[3] - info_box[1]
    across = clamp(field_cx - iw / 2, usable[0], usable[2] - iw)
    down = clamp(field_cy - ih / 2, usable[1], usable[3] - ih)
    candidates = [
        (across, core.box[3] + _BLOCK_GAP),
        (across, core.box[1] - _BLOCK_GAP - ih),
        (core.box[2] + _BLOCK_GAP, down),
        (core.box[0] - _BLOCK_GAP - iw, down),
    ]
    for left, top in candidates:
        dx, dy = left - info_box[0], top - info_box[1]
        placed_box = (info_box[0] + dx, info_box[1] + dy, info_box[2] + dx, info_box[3] + dy)
        if inside(placed_box, usable):
            return dx, dy
    return None


def _room(board: Board, drawing: Drawing) -> float:
    """How much room the board's field leaves on the page: the smaller of the two slacks."""
    ex, ey = extent(board)
    w, h = drawing.size
    return min(w - ex, h - ey)


def fit(
    board: Board,
    page: str,
    size: tuple[float, float],
    orientation: str,
    margin: float,
    *,
    draw: bool = False,
) -> Drawing | None:
    """The best layout for this orientation ('auto': the fitting one with more room,
    portrait on a tie), or None; its shapes include the board's marks when ``draw``."""
    drawings: list[Drawing] = []
    for candidate in ("portrait", "landscape"):
        if orientation in ("auto", candidate):
            o: Literal["portrait", "landscape"] = (
                "portrait" if candidate == "portrait" else "landscape"
            )
            drawing = lay_out(board, page, oriented(size, o), o, margin, draw)
            if drawing is not None:
                drawings.append(drawing)
    if not drawings:
        return None
    # max keeps the first of equals: portrait.
    return max(drawings, key=lambda d: _room(board, d))
