"""`planarcal board`: a printable board of any type (a circle grid, a chessboard, a ChArUco
board: ``--type``) as SVG or PDF at exact scale, on the smallest ISO A page it fits
(``--page auto``) or on the page asked for, with the commands for boards that fit A4 and
letter when it needs a larger page."""

from __future__ import annotations

import argparse
import dataclasses
import functools
import shlex
from pathlib import Path

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board
from planarcal.calib.charuco import CharucoBoard
from planarcal.commands import board_arguments, board_from, command_line, non_negative
from planarcal.errors import ArgumentError, BoardError
from planarcal.report.printable import (
    MARGIN_MM,
    PrintLayout,
    board_options,
    exact_mm,
    fits_page,
    page_refusal,
    page_size,
    pitch_meaning,
    smaller_board,
    write_board,
)

# The pages `--page auto` tries, smallest first.
AUTO_PAGES = ("A4", "A3", "A2", "A1", "A0")

DESCRIPTION = (
    "Write a board to print at 100% (a circle grid, or with --type a chessboard or a ChArUco "
    "board), with a 100 mm check bar and its parameters."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = DESCRIPTION
    board_arguments(p, for_printing=True)
    p.add_argument("-o", "--output", required=True, type=Path, help="board.svg or board.pdf")
    p.add_argument(
        "--page",
        default="auto",
        help="A4, A3, letter, ..., WxH in mm, or auto: the smallest ISO A page "
        "the board fits (default)",
    )
    p.add_argument("--orientation", default="auto", choices=("auto", "portrait", "landscape"))
    p.add_argument(
        "--margin",
        type=non_negative,
        default=MARGIN_MM,
        help=f"page margin in mm ({MARGIN_MM:g})",
    )


def main(args: argparse.Namespace) -> int:
    board = board_from(args)
    if isinstance(board, CircleGridBoard) and board.diameter is None:
        # A printed dot needs a size: half the neighbour distance, dots as wide as the gaps.
        board = dataclasses.replace(board, diameter=board.neighbour_distance / 2)
    auto = args.page.lower() == "auto"
    layout: PrintLayout | None = None
    refused: str | None = None
    # An unknown page, a bad margin or an output that is neither .svg nor .pdf is the command
    # line's fault (ArgumentError); a board too large for the page is not (BoardError).
    pages = AUTO_PAGES if auto else (args.page,)
    with command_line(ArgumentError):
        for page in pages:
            if fits_page(board, page, orientation=args.orientation, margin_mm=args.margin):
                layout = write_board(
                    board,
                    args.output,
                    page=page,
                    orientation=args.orientation,
                    margin_mm=args.margin,
                )
                break
        else:
            # The board fits no page tried: the message names a page that would, and the
            # command for a board that fits the last one.
            refused = page_refusal(
                board,
                pages[-1],
                orientation=args.orientation,
                margin_mm=args.margin,
                offer=functools.partial(_offer, args, pages[-1]),
            )
    if layout is None:
        raise BoardError(refused)
    print(f"wrote {args.output}: {board.describe()}, on {layout.page} {layout.orientation}.")
    if isinstance(board, CircleGridBoard):
        print(f"{board.layout.capitalize()} grid: {pitch_meaning(board)}.")
        if args.diameter is None:
            print(
                f"Dot diameter {board.diameter:g} mm: half the distance between neighbouring "
                "dots (no --diameter given)."
            )
    else:
        if isinstance(board, CharucoBoard) and board.legacy is None and board.layouts_differ:
            print(
                "Printed in OpenCV's current layout (4.6 and later); --legacy yes prints the "
                "layout of older versions."
            )
        print(f"Calibrate with: planarcal calibrate PHOTO -o cal.json {_board_words(board)}")
    print("Print it at 100% (actual size, no fit-to-page) and check the bar measures 100 mm.")
    if auto and layout.page != AUTO_PAGES[0]:
        # Most printers take A4 or letter only: say which board each holds.
        print(f"It needs {layout.page} paper.")
        for small in ("A4", "letter"):
            other = smaller_board(board, page_size(small), args.orientation, args.margin)
            if other is not None:
                print(f"On {small}: {_offer(args, small, other)}.")
    return 0


def board_command(args: argparse.Namespace, page: str, board: Board) -> str:
    """The `planarcal board` command line that prints `board` on `page`, with the options of
    `args` it keeps (output, orientation, margin, layout, marker)."""
    words = ["planarcal board", "-o", shlex.quote(str(args.output)), "--page", shlex.quote(page)]
    if args.orientation != "auto":
        words += ["--orientation", args.orientation]
    if args.margin != MARGIN_MM:
        words += ["--margin", f"{args.margin:g}"]
    if not isinstance(board, CircleGridBoard):
        return " ".join([*words, *board_options(board, for_printing=True)])
    words += ["--cols", str(board.cols), "--rows", str(board.rows), "--pitch", f"{board.pitch:g}"]
    # Sizes the user chose are kept, scaled with the pitch; unchosen ones follow it anyway.
    if args.diameter is not None:
        words += ["--diameter", exact_mm(board.dots_mm())]
    if board.layout != "symmetric":
        words += ["--layout", board.layout]
    if not board.origin_marker:
        words.append("--no-origin-marker")
    elif board.marker_diameter is not None:
        words += ["--marker-diameter", exact_mm(board.marker_diameter)]
    return " ".join(words)


def _board_words(board: Board) -> str:
    """The options that describe ``board`` to planarcal calibrate, quoted for a shell."""
    return " ".join(shlex.quote(w) for w in board_options(board))


def _offer(args: argparse.Namespace, page: str, board: Board) -> str:
    """A smaller board that fits `page`, offered as its command line."""
    if isinstance(board, CircleGridBoard):
        return (
            f"`{board_command(args, page, board)}` ({_dots_and_pitch(board)}; calibrate with "
            "the same --cols, --rows and --pitch)"
        )
    if isinstance(board, CharucoBoard):
        what = f"{board.squares_x} x {board.squares_y} squares of {board.square:g} mm"
    else:
        what = f"{board.cols} x {board.rows} inner corners, squares of {board.square:g} mm"
    return f"`{board_command(args, page, board)}` ({what}; calibrate with the same options)"


def _dots_and_pitch(board: CircleGridBoard) -> str:
    return f"{board.cols} x {board.rows} dots, {board.pitch:g} mm apart"
