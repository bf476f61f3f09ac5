"""`planarcal demo`: the whole pipeline on a rendered scene of the paper's setup."""

from __future__ import annotations

import argparse
from pathlib import Path

from planarcal.calib.boards import BOARD_TYPES
from planarcal.report.figure import require_matplotlib
from planarcal.synth import demo

DESCRIPTION = (
    "Render the paper's setup (board, lens, blur, noise; then bolts and nuts at known "
    "places), calibrate, locate the objects, and say how far each is from the truth. Needs "
    "no camera and no files. --board chessboard or charuco puts a board of that type in the "
    "paper's circle grid's place. --placements N renders a work area three boards wide "
    "instead, the board photographed at N places on it, and calibrates from all the images "
    "together."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = DESCRIPTION
    p.add_argument(
        "--board",
        choices=BOARD_TYPES,
        default="circles",
        help="the board in the scene: the paper's circle grid (circles, the default), an "
        "11 x 8 chessboard of 24 mm squares or a 12 x 9 ChArUco board of 24 mm squares",
    )
    p.add_argument(
        "--placements",
        type=_placement_count,
        default=None,
        metavar="N",
        help="a work area three boards wide: the board laid at N places (2-9: the middle, the "
        "corners, the sides), one image each, calibrated together; the mapping's and the "
        "parts' errors over the whole area against the truth, beside one placement alone",
    )
    p.add_argument(
        "--report",
        type=Path,
        default=None,
        metavar="DIR",
        help="write here what a real run writes: the calibration report's figures and tables, "
        "the calibration file, the rendered images and the objects located, drawn on theirs",
    )


def main(args: argparse.Namespace) -> int:
    if args.report is not None:
        if args.report.exists() and not args.report.is_dir():
            raise argparse.ArgumentError(
                None, f"--report {args.report}: it is a file; give a directory (new or not)"
            )
        require_matplotlib()  # before the work: the figures cannot be drawn without it
        args.report.mkdir(parents=True, exist_ok=True)  # before the work, a bad place fails now
    if args.placements is not None:
        print(demo.run_placements(args.placements, report=args.report, board=args.board))
    else:
        print(demo.run(report=args.report, board=args.board))
    return 0


def _placement_count(text: str) -> int:
    """--placements: a whole number from 2 to 9."""
    try:
        count = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 2 <= count <= 9:
        raise argparse.ArgumentTypeError(f"{count} placements: give 2 to 9")
    return count
