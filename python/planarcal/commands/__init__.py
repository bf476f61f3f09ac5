"""The `planarcal` commands, one module each: ``board``, ``calibrate``, ``intrinsics``,
``locate``, ``run`` and ``demo`` here, ``register`` in ``planarcal.robot.register_command``.
Each has ``add_arguments(parser)`` and ``main(args) -> int``. ``planarcal.cli`` imports a
command's module only when that command runs or its help is asked for: they load numpy,
OpenCV, SciPy and the core, which ``planarcal --help`` and ``--version`` do without.

Here, what several commands share: the board's arguments, the number types that refuse a
malformed value while the command line is parsed, ``command_line`` (API errors that mean the
command line is malformed leave as ``argparse.ArgumentError``, exit status 2), and the checks
that say what the CLI user can do in the CLI's words (commands and options, not Python calls).
"""

from __future__ import annotations

import argparse
import contextlib
import math
from collections.abc import Iterator
from pathlib import Path

from planarcal.calib.board import LAYOUTS, CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.frame_size import size_text
from planarcal.errors import (
    ArgumentError,
    BoardError,
    FrameSizeError,
    ImageError,
    IntrinsicsError,
)
from planarcal.robot.output_frame import FRAMES, Coords, checked_frame

# -- numbers, checked while the command line is parsed (argparse names the option) ----------


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def finite(text: str) -> float:
    """A finite number (not nan or inf, which float() would take)."""
    return _number(text)


def positive(text: str) -> float:
    """A finite number > 0."""
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def non_negative(text: str) -> float:
    """A finite number >= 0."""
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text!r}")
    return value


def count(text: str) -> int:
    """A whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be 1 or more, got {text!r}")
    return value


@contextlib.contextmanager
def command_line(*errors: type[Exception]) -> Iterator[None]:
    """An error of the classes ``errors`` raised inside says the command line is malformed
    (a board that cannot be, a page that does not exist): it leaves as argparse's own
    ArgumentError, which the CLI reports as it reports argparse's (exit status 2)."""
    try:
        yield
    except errors as e:
        raise argparse.ArgumentError(None, str(e)) from e


# -- the board -------------------------------------------------------------------------------


def board_arguments(p: argparse.ArgumentParser, *, for_printing: bool = False) -> None:
    """The board's arguments. A board `for_printing` (`planarcal board`) gets an origin
    marker unless told otherwise, and a diameter when none is given; a board to be found in
    an image has no marker unless told (detection recognises an enlarged corner dot by
    itself), and its diameter, when none is given, is measured from the image."""
    g = p.add_argument_group("board (millimetres; the defaults are the paper's board)")
    # One source for every command's defaults: a board printed with them is found with them.
    default = CircleGridBoard()
    g.add_argument(
        "--cols", type=int, default=default.cols, help=f"dots along a row (default {default.cols})"
    )
    g.add_argument(
        "--rows",
        type=int,
        default=default.rows,
        help=f"dots down a column (default {default.rows})",
    )
    g.add_argument(
        "--pitch",
        type=positive,
        default=default.pitch,
        help=f"centre-to-centre distance ({default.pitch:g}); in the asymmetric layout the "
        "distance between rows, half that between dots along a row",
    )
    g.add_argument(
        "--diameter",
        type=positive,
        default=None,
        help="dot diameter (default: half the distance between neighbouring dots)"
        if for_printing
        else "dot diameter (default: measured from the image)",
    )
    g.add_argument(
        "--layout",
        choices=LAYOUTS,
        default="symmetric",
        help="symmetric (default): a square grid; asymmetric: OpenCV's asymmetric circle grid, "
        "every other row shifted by a pitch",
    )
    marker = g.add_mutually_exclusive_group()
    marker.add_argument(
        "--origin-marker",
        dest="origin_marker",
        action="store_true",
        help="the origin dot is larger and fixes the orientation"
        + (" (the default)" if for_printing else ""),
    )
    marker.add_argument(
        "--no-origin-marker",
        dest="origin_marker",
        action="store_false",
        help="all dots the same size" + ("" if for_printing else " (the default)"),
    )
    p.set_defaults(origin_marker=for_printing)
    g.add_argument(
        "--marker-diameter",
        type=positive,
        default=None,
        help="diameter of the origin marker, at most the distance to its neighbours "
        "(default 1.5 x the dots, or less where that would crowd them)",
    )


def board_from(args: argparse.Namespace) -> CircleGridBoard:
    """The board the arguments describe; one that cannot be (a dot wider than the pitch, a
    row of one dot) is a malformed command line."""
    with command_line(BoardError):
        return CircleGridBoard(
            cols=args.cols,
            rows=args.rows,
            pitch=args.pitch,
            diameter=args.diameter,
            origin_marker=args.origin_marker,
            marker_diameter=args.marker_diameter,
            layout=args.layout,
        )


# -- locating (locate, run) ------------------------------------------------------------------


def frame_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--frame",
        choices=FRAMES,
        default=None,
        help="the positions' frame of reference: board (mm on the board) or robot (the "
        "robot's base frame, from 'planarcal register'); default robot once the calibration "
        "has a registration, else board",
    )


def frame_words(frame: Coords) -> str:
    """Which frame positions are in, for a header, a legend or a title."""
    if frame == "robot":
        return "robot frame (mm in the robot's base frame)"
    return "board frame (mm on the board, from its origin dot)"


def locating_with(args: argparse.Namespace, cal: Calibration) -> Coords:
    """The frame to give positions in, after checking that the calibration can honour
    ``--frame`` and ``--height``; the refusals say what to run instead (the API's own
    messages name Python calls)."""
    if args.frame == "robot" and cal.robot_frame is None:
        raise ArgumentError(
            f"--frame robot needs a calibration registered to the robot, and "
            f"{str(args.calibration)!r} has none: register it first with 'planarcal register "
            f"--calibration {args.calibration} --points touch.csv -o {args.calibration}'"
        )
    if args.height != 0 and cal.intrinsics is None:
        raise IntrinsicsError(
            f"--height {args.height:g} needs a calibration made with camera intrinsics, and "
            f"{str(args.calibration)!r} has none: estimate them with 'planarcal intrinsics' "
            "(3 or more tilted views of the board), then calibrate with 'planarcal calibrate "
            "--intrinsics camera.yaml'"
        )
    return checked_frame(args.frame, cal.robot_frame)


def frame_size_in_words(e: FrameSizeError, what: str) -> FrameSizeError:
    """A FrameSizeError reworded for the command line: calibrate again at the new size (the
    API's message offers ``Calibration.for_frame_size``, which has no command)."""
    if e.actual is None or e.expected is None:
        return e
    size = size_text(e.actual)
    return FrameSizeError(
        f"this {what} is {size} but the calibration was made on {size_text(e.expected)} "
        f"{what}s: its pixels would map to the wrong millimetres. Calibrate again on a "
        f"picture of the board taken at {size} ('planarcal calibrate')",
        e.actual,
        e.expected,
    )


def not_a_folder(path: Path, instead: str) -> Path:
    """``path``, refused when it is a folder (``load_image`` would say there is no image
    file): ``instead`` says what reads a folder."""
    if path.is_dir():
        raise ImageError(f"{str(path)!r} is a directory, not an image file: {instead}")
    return path
