"""Why a board does not fit a page, and what would: the smallest page it fits, and the
smaller board that fits this one (``smaller_board``: the most dots, corners or squares at
the board's pitch, else all of them at a finer pitch)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import TypeVar

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.errors import BoardError
from planarcal.report.printable.layout import CHECK_BAR_MM, extent, fit, lay_out
from planarcal.report.printable.pages import PAGE_SIZES, num, oriented, page_family


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
    huge = 4.0 * (sum(extent(board)) + 1000.0 + margin)
    for _ in range(4):
        drawing = lay_out(board, "custom", (huge, huge), "landscape", margin, False)
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
    ex, ey = extent(board)
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
