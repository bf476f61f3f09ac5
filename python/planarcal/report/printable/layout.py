"""The page laid out: the board's dots centred on it with the axis marks beside them, the
100 mm check bar and the text block placed where they fit inside the margins, the
orientation chosen, and, when nothing fits, the message that says why and which page would
do."""

from __future__ import annotations

import dataclasses
import math
import textwrap
from collections.abc import Callable
from typing import Literal

from planarcal.calib.board import CircleGridBoard
from planarcal.errors import BoardError
from planarcal.report.printable.pages import PAGE_SIZES, num, oriented, page_family
from planarcal.report.printable.shapes import (
    ASCENT,
    COURIER_ADVANCE,
    DESCENT,
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


def _dots_and_axes(
    board: CircleGridBoard, width: float, height: float
) -> tuple[list[Shape], tuple[float, float], Box]:
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

    # An L at the field's top-left corner: X shaft above the top row, Y shaft left of the
    # first column, ticks pointing at dot 0's row and column, arrows 20 mm past the origin.
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
        # The origin's ticks: from the shafts to just short of the field, on dot 0's centre.
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


def _board_lines(board: CircleGridBoard) -> list[str]:
    """The info block's description of the board (board.describe(), told for print): its
    dots, its layout, its origin. Lines may be long; the caller wraps them."""
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
    board: CircleGridBoard,
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
    lines = [(f"planarcal circle-grid board, {board.cols} x {board.rows} dots", _TITLE_TEXT, True)]
    page_line = f"page {page} {orientation} ({num(w)} x {num(h)} mm), margins {num(margin)} mm"
    for line in [*_board_lines(board), page_line]:
        lines += [(part, _BODY_TEXT, False) for part in textwrap.wrap(line, _WRAP)]
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
    board: CircleGridBoard,
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
    core, offset, field_box = _dots_and_axes(board, width, height)
    core_box = union(s.box() for s in core)
    if not inside(core_box, usable):
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
        info_box = union(s.box() for s in info)
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
            shapes = tuple(core) + tuple(shift(s, dx, dy) for s in info)
            return Drawing(
                page=page,
                size=(width, height),
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


def _room(board: CircleGridBoard, drawing: Drawing) -> float:
    """How much room the dot field leaves on the page: the smaller of the two slacks."""
    ex, ey = board.extent
    w, h = drawing.size
    return min(w - ex, h - ey)


def fit(
    board: CircleGridBoard,
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


def _smallest_page(board: CircleGridBoard, margin: float, family: str) -> str:
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


def _most_dots_at_pitch(
    board: CircleGridBoard, fits: Callable[[CircleGridBoard], bool]
) -> CircleGridBoard | None:
    """The board with the most dots, at most ``board.cols`` x ``board.rows`` and at the same
    pitch, that ``fits``; of equals, the one closest to ``board``'s proportions."""
    fewest_rows = 3 if board.layout == "asymmetric" else 2
    # An unmarked asymmetric grid with an odd number of rows fixes its own origin: keep that.
    step = 2 if board.layout == "asymmetric" and board.rows % 2 and not board.origin_marker else 1
    row_counts = range(board.rows, fewest_rows - 1, -step)
    proportions = math.log(board.cols / board.rows)
    best: CircleGridBoard | None = None
    best_key = (0, -math.inf)
    # More columns never allow more rows: walk the staircase of the largest fitting boards,
    # each candidate tried once.
    i = 0
    for cols in range(2, board.cols + 1):
        while i < len(row_counts) and not fits(
            dataclasses.replace(board, cols=cols, rows=row_counts[i])
        ):
            i += 1
        if i == len(row_counts):
            break
        rows = row_counts[i]
        key = (cols * rows, -abs(math.log(cols / rows) - proportions))
        if key > best_key:
            best, best_key = dataclasses.replace(board, cols=cols, rows=rows), key
    return best


def _all_dots_at_largest_pitch(
    board: CircleGridBoard, fits: Callable[[CircleGridBoard], bool]
) -> CircleGridBoard | None:
    """``board`` with every dot, at the largest pitch (a multiple of 0.5 mm, at least 2 mm)
    that ``fits``: the dots and the marker scaled with it, to 0.01 mm."""

    def scaled(steps: int) -> CircleGridBoard | None:
        pitch = steps * _PITCH_STEP_MM
        ratio = pitch / board.pitch
        diameter = None if board.diameter is None else round(board.diameter * ratio, 2)
        marker = board.marker_diameter
        if marker is not None:
            # Rounded, a marker as wide as the spacing, or 1.2 times the dots, can pass the
            # bound it was on: hold it inside.
            spacing = dataclasses.replace(
                board, pitch=pitch, diameter=None, marker_diameter=None
            ).neighbour_distance
            smallest = 0.0 if diameter is None else math.ceil(diameter * 120) / 100
            marker = min(max(round(marker * ratio, 2), smallest), math.floor(spacing * 100) / 100)
        try:
            return dataclasses.replace(
                board, pitch=pitch, diameter=diameter, marker_diameter=marker
            )
        except BoardError:  # dots too large for the spacing once rounded: not offered
            return None

    def scaled_fits(steps: int) -> bool:
        candidate = scaled(steps)
        return candidate is not None and fits(candidate)

    low = math.ceil(_MIN_PITCH_MM / _PITCH_STEP_MM)
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
    board: CircleGridBoard, size: tuple[float, float], orientation: str, margin: float
) -> CircleGridBoard | None:
    """A board like ``board`` that fits a page of ``size`` in ``orientation`` ('auto':
    either) when ``board`` does not (None when it does, or nothing does): the most dots at
    its pitch, or, when not even the smallest grid (2 x 2, asymmetric 2 x 3) fits at it, all
    its dots at the largest pitch that fits.

    The pitch is kept first: it keeps the dots as large in the camera's image and the board
    reaching as far across it, which is what the lens model needs. On the paper's setup
    (rendered, 4 seeds, the board centred in view) the 14 x 10 board at 20 mm maps its
    260 x 180 mm work area within 0.0030 mm on average (0.008 mm at worst), the A4 board
    offered for it, 9 x 10 at 20 mm, within 0.0034 mm (0.016 mm); 14 x 10 at 13.5 mm reaches
    too little of the image for a lens model and is off by 0.24 mm (1.4 mm)."""

    def fits(candidate: CircleGridBoard) -> bool:
        return fit(candidate, "", size, orientation, margin) is not None

    if fits(board):
        return None
    return _most_dots_at_pitch(board, fits) or _all_dots_at_largest_pitch(board, fits)


def in_words(board: CircleGridBoard) -> str:
    """A smaller board, as a refusal offers it to a caller of ``write_board``."""
    return f"CircleGridBoard({board.describe()})"


def refusal(
    board: CircleGridBoard,
    label: str,
    size: tuple[float, float],
    orientation: str,
    margin: float,
    offer: Callable[[CircleGridBoard], str] = in_words,
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
    message = (
        f"the board ({board.describe()}) does not fit on {label} {where}: its dots span "
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
