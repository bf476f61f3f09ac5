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

Both formats are written by hand from one list of shapes (shapes.py), so what is drawn is
exactly what is computed here, numbers written with 9 decimals (1e-9 mm):

* pages.py: the paper sizes, by name or ``"WxH"`` in mm.
* layout.py: where the dots, the axis marks, the check bar and the text go; why a board
  that does not fit does not, and the smaller board that would (``smaller_board``: the
  most dots at the board's pitch).
* svg.py, pdf.py: the two formats (one SVG user unit is one mm; the PDF scales its content
  to mm with one ``cm`` operator and asks viewers not to scale when printing).
* write.py: ``write_board`` and the ``PrintLayout`` it returns; ``page_refusal``: whether a
  board fits a page, and if not, why and what would.

Files are written atomically (``planarcal.files.atomic_write``): the whole file is rendered
in memory, then appears complete under its name or not at all, an existing target left as it
was on any failure.
"""

from planarcal.report.printable.layout import (
    CHECK_BAR_MM,
    CHECK_TICK_MM,
    MARGIN_MM,
    pitch_meaning,
    smaller_board,
)
from planarcal.report.printable.pages import PAGE_SIZES, Orientation, page_size
from planarcal.report.printable.pdf import PT_PER_MM
from planarcal.report.printable.write import PrintLayout, page_refusal, write_board

__all__ = [
    "CHECK_BAR_MM",
    "CHECK_TICK_MM",
    "MARGIN_MM",
    "PAGE_SIZES",
    "PT_PER_MM",
    "Orientation",
    "PrintLayout",
    "page_refusal",
    "page_size",
    "pitch_meaning",
    "smaller_board",
    "write_board",
]
