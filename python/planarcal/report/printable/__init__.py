"""Printable boards of every type at exact physical scale, as SVG or PDF.

``write_board(board, "board.pdf", page="A4")`` writes one page of exactly the paper's size
with the board centred on it. A circle grid's dots are each a filled black circle of its
exact diameter at its exact position (``board.world_points()`` in either layout,
``board.dot_diameters()`` with the origin marker's); a chessboard or a ChArUco board is its
``board.ink()``: the black squares and the markers' black cells as one filled path of
rectangles, then a chessboard's marker dots (white on black, black on white). Small arrows
and labels beside the field show the origin (world (0, 0): the centre of dot 0, a
chessboard's top-left inner corner, a ChArUco board's top-left outer corner) and how X
(along a row) and Y (down a column) run; a 100 mm check bar with 10 mm ticks and a text
block with the board's parameters (its dots, what its pitch measures in its layout, its
origin; for a chessboard or a ChArUco board, the options to calibrate with it) and the
instruction to print at 100 % ("actual size") and measure the bar sit below (or beside)
it, all inside the margins.

Page coordinates, here and in ``PrintLayout``, are millimetres from the page's top-left
corner, x to the right, y down: a world point (X, Y) of the board is printed at
``(X, Y) + PrintLayout.field_offset_mm``.

Both formats are written by hand from one list of shapes (shapes.py), so what is drawn is
exactly what is computed here, numbers written with 9 decimals (1e-9 mm):

* pages.py: the paper sizes, by name or ``"WxH"`` in mm.
* layout.py: where the board's marks, the axis marks, the check bar and the text go.
* refusal.py: why a board that does not fit does not, and the smaller board that would
  (``smaller_board``: the most dots, corners or squares at the board's pitch).
* options.py: a board as the command line's options spell it (``board_options``).
* svg.py, pdf.py: the two formats (one SVG user unit is one mm; the PDF scales its content
  to mm with one ``cm`` operator and asks viewers not to scale when printing).
* write.py: ``write_board`` and the ``PrintLayout`` it returns; ``fits_page``: whether a
  board fits a page; ``page_refusal``: if not, why and what would.

Files are written atomically (``planarcal.files.atomic_write``): the whole file is rendered
in memory, then appears complete under its name or not at all, an existing target left as it
was on any failure.
"""

from planarcal.report.printable.layout import CHECK_BAR_MM, CHECK_TICK_MM, MARGIN_MM, pitch_meaning
from planarcal.report.printable.options import LEGACY_WORDS, board_options, exact_mm
from planarcal.report.printable.pages import PAGE_SIZES, Orientation, page_size
from planarcal.report.printable.pdf import PT_PER_MM
from planarcal.report.printable.refusal import smaller_board
from planarcal.report.printable.write import PrintLayout, fits_page, page_refusal, write_board

__all__ = [
    "CHECK_BAR_MM",
    "CHECK_TICK_MM",
    "LEGACY_WORDS",
    "MARGIN_MM",
    "PAGE_SIZES",
    "PT_PER_MM",
    "Orientation",
    "PrintLayout",
    "board_options",
    "exact_mm",
    "fits_page",
    "page_refusal",
    "page_size",
    "pitch_meaning",
    "smaller_board",
    "write_board",
]
