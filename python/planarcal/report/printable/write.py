"""``write_board``: the board laid out on a page and written as SVG or PDF (by the file's
suffix), atomically; ``PrintLayout``: where it put everything."""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal.calib.boards import Board
from planarcal.errors import ArgumentError, BoardError
from planarcal.files import atomic_write
from planarcal.report.printable.layout import CHECK_BAR_MM, MARGIN_MM, fit
from planarcal.report.printable.pages import Orientation, num, parse_page
from planarcal.report.printable.pdf import PT_PER_MM, pdf_bytes
from planarcal.report.printable.refusal import AnyBoard, in_words, refusal
from planarcal.report.printable.shapes import Box
from planarcal.report.printable.svg import svg_bytes


@dataclasses.dataclass(frozen=True)
class PrintLayout:
    """Where ``write_board`` put everything, in page mm (from the top-left corner, y down).

    ``field_offset_mm`` is the page position of world (0, 0) (a circle grid's dot 0, a
    chessboard's top-left inner corner, a ChArUco board's top-left outer corner): a world
    point (X, Y) of the board is printed at (X, Y) + field_offset_mm (see ``to_page``). In a
    PDF, whose y runs up from the bottom in points, a page point (x, y) is at
    (x * PT_PER_MM, (page height - y) * PT_PER_MM).
    """

    path: Path
    """The file written."""
    format: Literal["svg", "pdf"]
    board: Board
    page: str
    """The page's name ("A4", "letter") or custom size ("300x400")."""
    page_size_mm: tuple[float, float]
    """(width, height) of the page as laid out, i.e. after ``orientation``."""
    orientation: Literal["portrait", "landscape"]
    margin_mm: float
    field_offset_mm: tuple[float, float]
    """Page position of world (0, 0)."""
    field_box_mm: Box
    """The board's field, outer edge to outer edge (``board.extent``), centred on the page."""
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


def write_board(
    board: Board,
    path: str | os.PathLike[str],
    *,
    page: str | Sequence[float] = "A4",
    orientation: Orientation = "auto",
    margin_mm: float = MARGIN_MM,
) -> PrintLayout:
    """Write ``board`` (any type: a circle grid, a chessboard, a ChArUco board) to ``path``
    as a printable page at exact scale; returns the layout. What is drawn is ``board.ink()``
    (a circle grid's dots as each dot's circle).

    The format follows the suffix: ``.svg`` or ``.pdf`` (any case); anything else is a
    ValueError. ``page`` is a name from ``PAGE_SIZES`` (any case), a custom ``"WxH"`` in mm,
    or a (width, height) pair in mm; custom sizes are turned like standard ones.
    ``orientation`` is ``"portrait"`` (the short side across), ``"landscape"`` or ``"auto"``:
    whichever fits, and if both do, the one that leaves the board's field more room (the larger
    of the two orientations' smaller slack around it), portrait on a tie. ``margin_mm`` is
    kept clear on every side.

    Raises BoardError when the board, with its axis marks, check bar and text, does not fit
    inside the margins (in the orientation asked for, or in either for ``"auto"``): the
    message gives the field's extent, the page's usable size, the smallest standard
    page that fits and the smaller board that fits this page (``smaller_board``). A board
    that states no diameter (``diameter=None``) is printed with dots half the distance
    between neighbouring dots (``CircleGridBoard.dots_mm``). An unwritable path raises
    OSError naming it; the file is written atomically (see the module's docstring).
    """
    target = Path(os.fspath(path))
    suffix = target.suffix.lower()
    if suffix not in (".svg", ".pdf"):
        raise ArgumentError(
            f"cannot tell the format of {str(target)!r} from its suffix "
            f"{target.suffix or '(none)'!r}: use .svg or .pdf"
        )
    fmt: Literal["svg", "pdf"] = "svg" if suffix == ".svg" else "pdf"
    label, size, margin = _checked_page(page, orientation, margin_mm)

    drawing = fit(board, label, size, orientation, margin, draw=True)
    if drawing is None:
        raise BoardError(refusal(board, label, size, orientation, margin))

    data = svg_bytes(drawing, board) if fmt == "svg" else pdf_bytes(drawing, board)
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


def _checked_page(
    page: str | Sequence[float], orientation: str, margin_mm: float
) -> tuple[str, tuple[float, float], float]:
    """(the page's label, its (width, height) in mm, the margin) of ``write_board``'s page
    arguments; ArgumentError naming the one that is not valid."""
    if orientation not in ("auto", "portrait", "landscape"):
        raise ArgumentError(
            f"orientation must be 'auto', 'portrait' or 'landscape', got {orientation!r}"
        )
    if isinstance(margin_mm, bool) or not isinstance(margin_mm, int | float | np.number):
        raise ArgumentError(f"margin_mm must be a length in mm, got {margin_mm!r}")
    margin = float(margin_mm)
    if not (math.isfinite(margin) and margin >= 0):
        raise ArgumentError(f"margin_mm must be a finite length >= 0 in mm, got {margin_mm!r}")
    if isinstance(page, str):
        label, size = parse_page(page)
        return label, size, margin
    try:
        pw, ph = (float(v) for v in page)
    except (TypeError, ValueError):
        raise ArgumentError(
            f"a page is a name like 'A4', a size like '300x400' or (width, height) in mm, "
            f"got {page!r}"
        ) from None
    if not (pw > 0 and ph > 0 and math.isfinite(pw) and math.isfinite(ph)):
        raise ArgumentError(f"a page must have a positive width and height, got {page!r}")
    return f"{num(pw)}x{num(ph)}", (pw, ph), margin


def fits_page(
    board: Board,
    page: str | Sequence[float] = "A4",
    *,
    orientation: Orientation = "auto",
    margin_mm: float = MARGIN_MM,
) -> bool:
    """Whether ``board`` fits the page as ``write_board`` lays it out (same arguments):
    ``page_refusal`` without the search for what would fit."""
    label, size, margin = _checked_page(page, orientation, margin_mm)
    return fit(board, label, size, orientation, margin) is not None


def page_refusal(
    board: AnyBoard,
    page: str | Sequence[float] = "A4",
    *,
    orientation: Orientation = "auto",
    margin_mm: float = MARGIN_MM,
    offer: Callable[[AnyBoard], str] = in_words,
) -> str | None:
    """None when ``board`` fits the page as ``write_board`` lays it out (same arguments),
    else the message ``write_board`` would raise, with the smaller board that fits this page
    (``smaller_board``) written by ``offer``: ``planarcal board`` offers it as a command
    line."""
    label, size, margin = _checked_page(page, orientation, margin_mm)
    if fit(board, label, size, orientation, margin) is not None:
        return None
    return refusal(board, label, size, orientation, margin, offer)
