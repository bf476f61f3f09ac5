"""`planarcal run`: the production loop (``planarcal.live.run``), its arguments, and the
checks that refuse a malformed command line (exit status 2) before the camera is opened."""

from __future__ import annotations

import argparse
from pathlib import Path

from planarcal.calib.calibration import Calibration
from planarcal.commands import (
    command_line,
    count,
    finite,
    frame_argument,
    frame_size_in_words,
    locating_with,
    non_negative,
)
from planarcal.commands.locate import add_detection_arguments, checked_detection
from planarcal.errors import FrameSizeError, OutputError
from planarcal.live import run

DESCRIPTION = (
    "Read frames from SOURCE, locate the objects in each in mm (board or robot frame) with "
    "their angles, keep their IDs from frame to frame, and write one line per frame (JSON, "
    "CSV or a template) to the output, or serve it to controllers (tcp-listen://, on request "
    "with --trigger). Survives bad frames and a camera that drops out; Ctrl-C or SIGTERM end "
    "it cleanly with a summary on stderr. Exits 1 if no frame was delivered (every frame "
    "failed, or the camera never came), and at once if the frames are not of the size the "
    "calibration was made on."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = DESCRIPTION
    p.add_argument(
        "--source",
        required=True,
        help="camera index (0), video file (a path or file://), image folder or stream URL",
    )
    p.add_argument("--calibration", required=True, type=Path, help="file from 'calibrate'")
    run.add_output_arguments(p)
    p.add_argument(
        "--max-frames",
        type=count,
        default=None,
        metavar="N",
        help="stop after reading N frames from the source (failed and skipped ones count too)",
    )
    p.add_argument(
        "--fps-report",
        action="store_true",
        help="print the time per frame of each stage at the end",
    )
    p.add_argument("--height", type=finite, default=0.0, help="the objects' height in mm")
    add_detection_arguments(p)
    frame_argument(p)
    p.add_argument(
        "--max-reconnect",
        type=non_negative,
        default=None,
        metavar="S",
        help="give up on a camera or stream that stays away this many seconds (default: never)",
    )


def main(args: argparse.Namespace) -> int:
    # A malformed output spec, template or trigger option is the command line's fault.
    with command_line(OutputError):
        run.output_plan(args)
    # What the calibration cannot honour is said in the CLI's words before the loop starts.
    cal = Calibration.load(args.calibration)
    locating_with(args, cal)
    detect = checked_detection(args, cal)
    try:
        return run.main(args, detect)
    except FrameSizeError as e:
        raise frame_size_in_words(e, "frame") from e
