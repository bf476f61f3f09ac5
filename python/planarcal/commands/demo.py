"""`planarcal demo`: the whole pipeline on a rendered scene of the paper's setup."""

from __future__ import annotations

import argparse
import shlex
import time
from pathlib import Path

from planarcal.calib.boards import BOARD_TYPES
from planarcal.report.figure import require_matplotlib
from planarcal.report.printable.options import board_options
from planarcal.synth import demo
from planarcal.synth.live_video import LiveVideo, write_live_video

DESCRIPTION = (
    "Render the paper's setup (board, lens, blur, noise; then bolts and nuts at known "
    "places), calibrate, locate the objects, and say how far each is from the truth. Needs "
    "no camera and no files. --board chessboard or charuco puts a board of that type in the "
    "paper's circle grid's place. --placements N renders a work area three boards wide "
    "instead, the board photographed at N places on it, and calibrates from all the images "
    "together. --video PATH films that work cell instead (the board held at 3 places, then "
    "parts on a conveyor) for planarcal live --source PATH."
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
    mode = p.add_mutually_exclusive_group()
    mode.add_argument(
        "--placements",
        type=_placement_count,
        default=None,
        metavar="N",
        help="a work area three boards wide: the board laid at N places (2-9: the middle, the "
        "corners, the sides), one image each, calibrated together; the mapping's and the "
        "parts' errors over the whole area against the truth, beside one placement alone",
    )
    mode.add_argument(
        "--video",
        type=Path,
        default=None,
        metavar="PATH",
        help="write a video (.avi, Motion JPEG, 1280 x 720) of a work area three boards wide "
        "filmed by a fixed camera: the board held still at 3 places, then parts (nuts, bolts, "
        "washers) on a conveyor; then say the planarcal live command that sets it up",
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
    if args.video is not None:
        if args.report is not None:
            raise argparse.ArgumentError(
                None, "--video writes only the video: leave out --report (or --video)"
            )
        if args.video.suffix.lower() != ".avi":
            raise argparse.ArgumentError(
                None, f"--video {args.video}: give a file name ending in .avi (Motion JPEG)"
            )
        start = time.perf_counter()
        video = write_live_video(args.video, board=args.board)
        print(video_text(video, args.video, time.perf_counter() - start))
        return 0
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


def video_text(video: LiveVideo, path: Path, seconds: float) -> str:
    """What ``planarcal demo --video`` wrote, and the command that sets the cell up from it
    (with the board's options, so that a user copying it gets the right board)."""
    width, height = video.size
    w, h = video.cell.area_mm
    stills = ", ".join(
        f"{p.name} (frames {p.frames.start}-{p.frames.stop - 1})" for p in video.placements
    )
    options = board_options(video.board)
    if "--type" not in options:
        options = ["--type", video.board.kind, *options]
    size_mb = path.stat().st_size / 1e6
    return "\n".join(
        [
            f"planarcal demo --video: a work cell filmed by a fixed {width} x {height} camera "
            "(rendered with exact ground truth, planarcal.synth)",
            f"  Wrote {path}: {video.frame_count} frames at {video.fps:g} fps "
            f"({video.duration_s:.1f} s, Motion JPEG, {size_mb:.1f} MB) in {seconds:.1f} s.",
            f"  The board ({video.board.describe()}) held still at {len(video.placements)} "
            f"places on a {w:g} x {h:g} mm work area: {stills}; then nuts, bolts and washers "
            f"ride a conveyor across it from frame {video.parts.first_frame} to the end.",
            "",
            "Set the cell up from it (capture the board at each still, calibrate, register, "
            "watch the parts; the video plays in a loop):",
            f"  planarcal live --source {shlex.quote(str(path))} --calibration cell.json "
            f"{' '.join(options)}",
        ]
    )
