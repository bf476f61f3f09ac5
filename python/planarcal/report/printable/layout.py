"""The page laid out: the board's marks (a circle grid's dots, a chessboard's or ChArUco
board's squares and markers: ``board.ink()``) centred on it with the axis marks beside them,
the 100 mm check bar and the text block placed where they fit inside the margins, the
orientation chosen, and, when nothing fits, the message that says why and which page would
do."""

from __future__ import annotations

import dataclasses
import math
import textwrap
from collections.abc import Callable
from typing import Literal, TypeVar

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.errors import BoardError
from planarcal.report.printable.options import board_options
from planarcal.report.printable.pages import PAGE_SIZES, num, oriented, page_family
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


def _dots(
    board: CircleGridBoard, width: float, height: float
) -> tuple[list[Shape], tuple[float, float], Box]:
    """A circle grid's dots, centred on a page of this size; also the page position of
    world (0, 0) and the dot field's box."""
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

    shapes: list[Shape] = []
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
    return shapes, (ox, oy), field_box


def _squares(
    board: ChessboardBoard | CharucoBoard, width: float, height: float
) -> tuple[list[Shape], tuple[float, float], Box]:
    """A chessboard's or ChArUco board's ink (``board.ink()``: its black squares and marker
    cells as one area, then a marker's dots), its field centred on a page of this size; also
    the page position of world (0, 0) and the field's box."""
    ink = board.ink()
    fx0, fy0, fx1, fy1 = ink.field
    ox = width / 2 - (fx0 + fx1) / 2
    oy = height / 2 - (fy0 + fy1) / 2
    field_box = (ox + fx0, oy + fy0, ox + fx1, oy + fy1)
    rects = tuple(
        (ox + float(x0), oy + float(y0), ox + float(x1), oy + float(y1))
        for x0, y0, x1, y1 in ink.rects
    )
    shapes: list[Shape] = [Area(rects, "board", "ink", "ink")]
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
    return shapes, (ox, oy), field_box


def _marks_and_axes(
    board: Board, width: float, height: float
) -> tuple[list[Shape], tuple[float, float], Box]:
    """The board's marks, centred on a page of this size, and the axis marks beside them."""
    if isinstance(board, CircleGridBoard):
        shapes, (ox, oy), field_box = _dots(board, width, height)
    else:
        shapes, (ox, oy), field_box = _squares(board, width, height)

    # An L at the field's top-left corner: X shaft above the top row, Y shaft left of the
    # first column, ticks pointing at the origin's row and column, arrows 20 mm past it.
    head_len, head_half = _ARROW_HEAD
    xa = field_box[0] - _AXIS_GAP - head_half
    ya = field_box[1] - _AXIS_GAP - head_half
    tip_x = ox + _AXIS_LENGTH
    tip_y = oy + _AXIS_LENGTH
    axis = "axes"
    shapes += [
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
    return shapes, (ox, oy), field_box


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
            f"{num(board.square)} mm squares, {num(board.marker)} mm markers "
            f"({board.dictionary}), {field}",
            f"{board.n_points} corners as OpenCV's CharucoBoard numbers them",
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
    ex, ey = board.extent
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
    bar_box = union(s.box() for s in shapes)

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
    return shapes, (x0, yb), text_box


def _layout(
    board: Board,
    page: str,
    size: tuple[float, float],
    orientation: Literal["portrait", "landscape"],
    margin: float,
) -> Drawing | None:
    """The page laid out, or None when something would cross the margins."""
    width, height = size
    usable = (margin, margin, width - margin, height - margin)
    if usable[2] - usable[0] <= 0 or usable[3] - usable[1] <= 0:
        return None
    ex, ey = board.extent
    if ex > usable[2] - usable[0] + _SURE or ey > usable[3] - usable[1] + _SURE:
        return None  # the field alone is too large: said before its marks are made
    core, offset, field_box = _marks_and_axes(board, width, height)
    core_box = union(s.box() for s in core)
    if not inside(core_box, usable):
        return None
    arrangements: tuple[Literal["stacked", "side"], ...] = ("stacked", "side")
    infos = [_info_block(board, page, size, orientation, margin, a) for a in arrangements]
    frame = (page, (width, height), orientation, margin)
    # The board centred on the page, the bar and text beside it, as a circle grid always
    # was; a chessboard's or ChArUco board's longer text may need the board moved off centre
    # (the two centred together on the side that has room).
    for info in infos:
        drawing = _placed(frame, core, offset, field_box, info, usable)
        if drawing is not None:
            return drawing
    if isinstance(board, CircleGridBoard):
        return None
    for info in infos:
        info_box = union(s.box() for s in info[0])
        for dx, dy in _moves(core_box, info_box, usable):
            moved = [shift(s, dx, dy) for s in core]
            drawing = _placed(
                frame,
                moved,
                (offset[0] + dx, offset[1] + dy),
                (field_box[0] + dx, field_box[1] + dy, field_box[2] + dx, field_box[3] + dy),
                info,
                usable,
            )
            if drawing is not None:
                return drawing
    return None


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


def _placed(
    frame: tuple[str, tuple[float, float], Literal["portrait", "landscape"], float],
    core: list[Shape],
    offset: tuple[float, float],
    field_box: Box,
    info: tuple[list[Shape], tuple[float, float], Box],
    usable: Box,
) -> Drawing | None:
    """The page with the board's ``core`` (its marks and axes) where it is and the bar and
    text below it, above it, right of it or left of it: the first with room, or None."""
    page, size, orientation, margin = frame
    core_box = union(s.box() for s in core)
    if not inside(core_box, usable):
        return None
    field_cx = (field_box[0] + field_box[2]) / 2
    field_cy = (field_box[1] + field_box[3]) / 2

    def clamp(value: float, low: float, high: float) -> float:
        return max(low, min(value, high))

    # Each candidate lies wholly outside the core's box, so nothing overlaps.
    shapes_info, bar_start, text_box = info
    info_box = union(s.box() for s in shapes_info)
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
        if not inside(placed_box, usable):
            continue
        shapes = tuple(core) + tuple(shift(s, dx, dy) for s in shapes_info)
        return Drawing(
            page=page,
            size=size,
            orientation=orientation,
            margin=margin,
            shapes=shapes,
            offset=offset,
            field_box=field_box,
            bar_start=(bar_start[0] + dx, bar_start[1] + dy),
            text_box=(text_box[0] + dx, text_box[1] + dy, text_box[2] + dx, text_box[3] + dy),
            content_box=union(s.box() for s in shapes),
        )
    return None


def _room(board: Board, drawing: Drawing) -> float:
    """How much room the board's field leaves on the page: the smaller of the two slacks."""
    ex, ey = board.extent
    w, h = drawing.size
    return min(w - ex, h - ey)


def fit(
    board: Board,
    page: str,
    size: tuple[float, float],
    orientation: str,
    margin: float,
) -> Drawing | None:
    """The best layout for this orientation ('auto': the fitting one with more room,
    portrait on a tie), or None."""
    drawings: list[Drawing] = []
    for candidate in ("portrait", "landscape"):
        if orientation in ("auto", candidate):
            o: Literal["portrait", "landscape"] = (
                "portrait" if candidate == "portrait" else "landscape"
            )
            drawing = _layout(board, page, oriented(size, o), o, margin)
            if drawing is not None:
                drawings.append(drawing)
    if not drawings:
        return None
    # max keeps the first of equals: portrait.
    return max(drawings, key=lambda d: _room(board, d))


def _smallest_page(board: Board, margin: float, family: str) -> str:
    """The smallest standard page the board fits on, of the same family as the page asked
    for (ISO A or US) when one is, or else a custom size that fits."""
    fitting: list[tuple[str, str]] = []  # (name, orientation), smallest first
    for name, size in sorted(PAGE_SIZES.items(), key=lambda item: item[1][0] * item[1][1]):
        drawing = fit(board, name, size, "auto", margin)
        if drawing is not None:
            fitting.append((name, drawing.orientation))
    if fitting:
        same = [f for f in fitting if page_family(f[0]) == family]
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
        if fit(board, label, (float(w), float(h)), "auto", margin) is not None:
            return (
                f"no standard page is large enough: use a custom page of at least {label} mm "
                f"(page='{label}')"
            )
        huge *= 2
    return "no standard page is large enough"  # pragma: no cover


# The finest pitch a smaller board is offered at: dots of 1 mm are hard to print and to see.
_MIN_PITCH_MM = 2.0
_PITCH_STEP_MM = 0.5  # smaller boards' pitches are whole multiples of it, for people to type

# A ChArUco board offered smaller has at least 3 x 3 squares (4 corners, a homography's
# least); its finest square gives the markers' cells at least this much, mm.
_MIN_CHARUCO_SQUARES = 3
_MIN_MARKER_CELL_MM = 0.5

AnyBoard = TypeVar("AnyBoard", bound=Board)


def _counts(board: Board) -> tuple[int, int]:
    """How many points or squares the board has across and down, as its type counts them."""
    if isinstance(board, CharucoBoard):
        return board.squares_x, board.squares_y
    return board.cols, board.rows


def _with_counts(board: AnyBoard, across: int, down: int) -> AnyBoard:
    """``board`` with ``across`` x ``down`` of what ``_counts`` counts, at the same pitch."""
    if isinstance(board, CharucoBoard):
        return dataclasses.replace(board, squares_x=across, squares_y=down)
    return dataclasses.replace(board, cols=across, rows=down)


def _fewest(board: Board) -> int:
    """The fewest of ``_counts`` a smaller board may have on a side."""
    if isinstance(board, CharucoBoard):
        return _MIN_CHARUCO_SQUARES
    if isinstance(board, ChessboardBoard):
        return 3 if board.origin_marker else 2  # the marker's dots need 3 x 3 corners
    return 2


def _most_dots_at_pitch(board: AnyBoard, fits: Callable[[AnyBoard], bool]) -> AnyBoard | None:
    """The board with the most dots (squares, corners), at most ``board``'s on each side and
    at the same pitch, that ``fits``; of equals, the one closest to ``board``'s proportions."""
    cols, rows = _counts(board)
    fewest = _fewest(board)
    fewest_rows = fewest
    step = 1
    if isinstance(board, CircleGridBoard) and board.layout == "asymmetric":
        fewest_rows = 3
        # An unmarked asymmetric grid with an odd number of rows fixes its own origin: keep
        # that.
        step = 2 if board.rows % 2 and not board.origin_marker else 1
    row_counts = range(rows, fewest_rows - 1, -step)
    proportions = math.log(cols / rows)
    best: AnyBoard | None = None
    best_key = (0, -math.inf)
    # More columns never allow more rows: walk the staircase of the largest fitting boards,
    # each candidate tried once.
    i = 0
    for across in range(fewest, cols + 1):
        while i < len(row_counts) and not fits(_with_counts(board, across, row_counts[i])):
            i += 1
        if i == len(row_counts):
            break
        down = row_counts[i]
        key = (across * down, -abs(math.log(across / down) - proportions))
        if key > best_key:
            best, best_key = _with_counts(board, across, down), key
    return best


def _scaled(board: AnyBoard, pitch: float) -> AnyBoard | None:
    """``board`` at ``pitch`` (a chessboard's or ChArUco board's square), its other sizes
    scaled with it to 0.01 mm; None where rounding leaves a board that cannot be."""
    ratio = pitch / board.pitch
    try:
        if isinstance(board, ChessboardBoard):
            return dataclasses.replace(board, square=pitch)
        if isinstance(board, CharucoBoard):
            # Rounded, a marker nearly as wide as its square must stay inside it.
            marker = min(round(board.marker * ratio, 2), math.ceil(pitch * 100 - 1) / 100)
            return dataclasses.replace(board, square=pitch, marker=marker)
        diameter = None if board.diameter is None else round(board.diameter * ratio, 2)
        marker_d = board.marker_diameter
        if marker_d is not None:
            # Rounded, a marker as wide as the spacing, or 1.2 times the dots, can pass the
            # bound it was on: hold it inside.
            spacing = dataclasses.replace(
                board, pitch=pitch, diameter=None, marker_diameter=None
            ).neighbour_distance
            smallest = 0.0 if diameter is None else math.ceil(diameter * 120) / 100
            marker_d = min(
                max(round(marker_d * ratio, 2), smallest), math.floor(spacing * 100) / 100
            )
        return dataclasses.replace(board, pitch=pitch, diameter=diameter, marker_diameter=marker_d)
    except BoardError:  # sizes too large for the spacing once rounded: not offered
        return None


def _finest_pitch(board: Board) -> float:
    """The finest pitch a smaller board is offered at."""
    if isinstance(board, CharucoBoard):
        # A marker's cells (its bits and border) no finer than _MIN_MARKER_CELL_MM.
        cells = int(board.opencv_dictionary().markerSize) + 2
        finest_marker = cells * _MIN_MARKER_CELL_MM
        return max(_MIN_PITCH_MM, finest_marker * board.square / board.marker)
    return _MIN_PITCH_MM


def _all_dots_at_largest_pitch(
    board: AnyBoard, fits: Callable[[AnyBoard], bool]
) -> AnyBoard | None:
    """``board`` with every dot (square), at the largest pitch (a multiple of 0.5 mm, at
    least 2 mm) that ``fits``: the dots and the marker scaled with it, to 0.01 mm."""

    def scaled(steps: int) -> AnyBoard | None:
        return _scaled(board, steps * _PITCH_STEP_MM)

    def scaled_fits(steps: int) -> bool:
        candidate = scaled(steps)
        return candidate is not None and fits(candidate)

    low = math.ceil(_finest_pitch(board) / _PITCH_STEP_MM)
    high = math.ceil(board.pitch / _PITCH_STEP_MM) - 1  # strictly finer than the board's
    if high < low or not scaled_fits(low):
        return None
    while low < high:  # the largest that fits, a finer pitch fitting whenever a coarser one does
        mid = (low + high + 1) // 2
        if scaled_fits(mid):
            low = mid
        else:
            high = mid - 1
    return scaled(low)


def smaller_board(
    board: AnyBoard, size: tuple[float, float], orientation: str, margin: float
) -> AnyBoard | None:
    """A board like ``board`` that fits a page of ``size`` in ``orientation`` ('auto':
    either) when ``board`` does not (None when it does, or nothing does): the most dots
    (a chessboard's corners, a ChArUco board's squares) at its pitch, or, when not even the
    smallest board (2 x 2, asymmetric 2 x 3; a chessboard with a marker 3 x 3 corners, a
    ChArUco board 3 x 3 squares) fits at it, all its dots at the largest pitch that fits.

    The pitch is kept first: it keeps the dots as large in the camera's image and the board
    reaching as far across it, which is what the lens model needs. On the paper's setup
    (rendered, 4 seeds, the board centred in view) the 14 x 10 board at 20 mm maps its
    260 x 180 mm work area within 0.0030 mm on average (0.008 mm at worst), the A4 board
    offered for it, 9 x 10 at 20 mm, within 0.0034 mm (0.016 mm); 14 x 10 at 13.5 mm reaches
    too little of the image for a lens model and is off by 0.24 mm (1.4 mm)."""

    def fits(candidate: AnyBoard) -> bool:
        return fit(candidate, "", size, orientation, margin) is not None

    if fits(board):
        return None
    return _most_dots_at_pitch(board, fits) or _all_dots_at_largest_pitch(board, fits)


def in_words(board: Board) -> str:
    """A smaller board, as a refusal offers it to a caller of ``write_board``."""
    if isinstance(board, CircleGridBoard):
        return f"CircleGridBoard({board.describe()})"
    if isinstance(board, CharucoBoard):
        return (
            f"CharucoBoard({board.squares_x}, {board.squares_y}, square={num(board.square)}, "
            f"marker={num(board.marker)}, dictionary={board.dictionary!r})"
        )
    marker = ", origin_marker=True" if board.origin_marker else ""
    return f"ChessboardBoard({board.cols}, {board.rows}, square={num(board.square)}{marker})"


def refusal(
    board: AnyBoard,
    label: str,
    size: tuple[float, float],
    orientation: str,
    margin: float,
    offer: Callable[[AnyBoard], str] = in_words,
) -> str:
    """Why ``board`` does not fit the page: its size, the page's room, the smallest page
    that fits, and the smaller board that fits this page (``smaller_board``), written by
    ``offer``."""
    ex, ey = board.extent
    tried = ("portrait", "landscape") if orientation == "auto" else (orientation,)
    usable = []
    for o in tried:
        w, h = oriented(size, o)
        usable.append(f"{num(max(w - 2 * margin, 0))} x {num(max(h - 2 * margin, 0))} mm ({o})")
    where = "in either orientation" if orientation == "auto" else f"in {orientation}"
    marks = "dots" if isinstance(board, CircleGridBoard) else "squares"
    message = (
        f"the board ({board.describe()}) does not fit on {label} {where}: its {marks} span "
        f"{num(ex)} x {num(ey)} mm, and the axis marks, the "
        f"{num(CHECK_BAR_MM)} mm check bar and the text need room beside them, but the page "
        f"leaves {' or '.join(usable)} inside {num(margin)} mm margins"
    )
    if orientation != "auto" and fit(board, label, size, "auto", margin) is not None:
        other = "landscape" if orientation == "portrait" else "portrait"
        return f"{message}; it fits in {other} (orientation='{other}' or 'auto')"
    message += f"; use a larger page: {_smallest_page(board, margin, page_family(label))}"
    smaller = smaller_board(board, size, orientation, margin)
    if smaller is not None:
        message += f"; or a smaller board that fits {label}: {offer(smaller)}"
    return message
