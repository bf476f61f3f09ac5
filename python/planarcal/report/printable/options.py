"""A board as the command line's options spell it (``--type chessboard --cols 9 ...``): what
a printed page tells the user to type to calibrate with it, and what ``planarcal board``
offers for a board that fits a smaller page. The options are those of
``planarcal.commands.board_arguments``; ``board_from`` of the parsed words is the board
again (tested)."""

from __future__ import annotations

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board
from planarcal.calib.charuco import CharucoBoard

LEGACY_WORDS: dict[str, bool | None] = {"auto": None, "yes": True, "no": False}
"""``--legacy``'s words and the CharucoBoard ``legacy`` each means."""


def exact_mm(value: float) -> str:
    """A length as short as it reads back exactly: a marker held at the dots' spacing must
    not be rounded past it."""
    short = f"{value:.10g}"
    return short if float(short) == value else repr(float(value))


def board_options(board: Board, *, for_printing: bool = False) -> list[str]:
    """The options that describe ``board`` to ``planarcal calibrate`` (``for_printing``:
    to ``planarcal board``, whose origin marker is on unless told otherwise). A circle grid
    needs no ``--type``, the default; an option left at its default is still written where
    it is a size, so the words read whole."""
    if isinstance(board, CircleGridBoard):
        words = ["--cols", str(board.cols), "--rows", str(board.rows)]
        words += ["--pitch", exact_mm(board.pitch)]
        if board.diameter is not None:
            words += ["--diameter", exact_mm(board.diameter)]
        if board.layout != "symmetric":
            words += ["--layout", board.layout]
        words += _marker_words(board.origin_marker, for_printing)
        if board.origin_marker and board.marker_diameter is not None:
            words += ["--marker-diameter", exact_mm(board.marker_diameter)]
        if board.fiducials:
            words += ["--fiducials", ",".join(str(k) for k in board.fiducials)]
            if board.fiducial_diameter is not None:
                words += ["--fiducial-diameter", exact_mm(board.fiducial_diameter)]
        return words
    if isinstance(board, CharucoBoard):
        words = ["--type", "charuco", "--squares-x", str(board.squares_x)]
        words += ["--squares-y", str(board.squares_y), "--square", exact_mm(board.square)]
        words += ["--marker", exact_mm(board.marker), "--dictionary", board.dictionary]
        if board.legacy is not None:
            words += ["--legacy", "yes" if board.legacy else "no"]
        return words
    words = ["--type", "chessboard", "--cols", str(board.cols), "--rows", str(board.rows)]
    words += ["--square", exact_mm(board.square)]
    return words + _marker_words(board.origin_marker, for_printing)


def _marker_words(marked: bool, for_printing: bool) -> list[str]:
    """The marker option, where it differs from the command's default."""
    if marked and not for_printing:
        return ["--origin-marker"]
    if for_printing and not marked:
        return ["--no-origin-marker"]
    return []
