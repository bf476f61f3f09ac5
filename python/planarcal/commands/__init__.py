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
from planarcal.calib.boards import BOARD_TYPES, Board
from planarcal.calib.calibration import Calibration
from planarcal.calib.charuco import DICTIONARIES, CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.calib.frame_size import size_text
from planarcal.errors import (
    ArgumentError,
    BoardError,
    FrameSizeError,
    ImageError,
    IntrinsicsError,
)
from planarcal.report.printable.options import LEGACY_WORDS
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

BOARD_GIVEN = "board_options_given"
"""The namespace attribute where the board's options note which were typed: {dest: option}."""

# Which board types each option describes (by its dest); the others refuse it.
_OPTION_TYPES: dict[str, tuple[str, ...]] = {
    "cols": ("circles", "chessboard"),
    "rows": ("circles", "chessboard"),
    "origin_marker": ("circles", "chessboard"),
    "pitch": ("circles",),
    "diameter": ("circles",),
    "layout": ("circles",),
    "marker_diameter": ("circles",),
    "fiducials": ("circles",),
    "fiducial_diameter": ("circles",),
    "square": ("chessboard", "charuco"),
    "squares_x": ("charuco",),
    "squares_y": ("charuco",),
    "marker": ("charuco",),
    "dictionary": ("charuco",),
    "legacy": ("charuco",),
}

# What a board of each type is told with, for a refusal to name.
_TYPE_OPTIONS = {
    "circles": "--cols, --rows, --pitch, --diameter, --layout, --origin-marker, "
    "--marker-diameter, --fiducials and --fiducial-diameter",
    "chessboard": "--cols and --rows (inner corners), --square and --origin-marker",
    "charuco": "--squares-x, --squares-y, --square, --marker, --dictionary and --legacy",
}

# The option another type's user most likely meant instead, by (type, dest).
_INSTEAD = {
    ("charuco", "cols"): "--squares-x (a ChArUco board is counted in squares)",
    ("charuco", "rows"): "--squares-y (a ChArUco board is counted in squares)",
    ("chessboard", "pitch"): "--square",
    ("charuco", "pitch"): "--square",
    ("circles", "square"): "--pitch",
    ("chessboard", "squares_x"): "--cols (a chessboard is counted in inner corners)",
    ("chessboard", "squares_y"): "--rows (a chessboard is counted in inner corners)",
    ("circles", "squares_x"): "--cols",
    ("circles", "squares_y"): "--rows",
}


class _Noted(argparse.Action):
    """Stores a board option as argparse's own actions do (a flag stores ``const``) and
    notes that it was typed, so that an option of another board type is refused rather than
    ignored, and a type's own defaults are used where nothing was typed."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: object,
        option_string: str | None = None,
    ) -> None:
        setattr(namespace, self.dest, self.const if self.nargs == 0 else values)
        given = dict(getattr(namespace, BOARD_GIVEN, None) or {})
        given[self.dest] = option_string or self.dest
        setattr(namespace, BOARD_GIVEN, given)


def _dictionary_name(text: str) -> str:
    """One of OpenCV's predefined ArUco dictionaries, any case (``dict_4x4_50``)."""
    for name in DICTIONARIES:
        if name.lower() == text.strip().lower():
            return name
    raise argparse.ArgumentTypeError(
        f"{text!r} is not one of OpenCV's predefined ArUco dictionaries: {', '.join(DICTIONARIES)}"
    )


def board_arguments(p: argparse.ArgumentParser, *, for_printing: bool = False) -> None:
    """The board's arguments: ``--type`` (circles, the default, chessboard or charuco) and
    each type's own. A board `for_printing` (`planarcal board`) gets an origin marker unless
    told otherwise (a circle grid's larger dot, a chessboard's three dots), and a circle
    grid a diameter when none is given; a board to be found in an image has no marker unless
    told (detection recognises an enlarged corner dot by itself), and its diameter, when
    none is given, is measured from the image. An option of another type than the one
    chosen is refused by ``board_from``."""
    g = p.add_argument_group("board (millimetres; the defaults are the paper's board)")
    # One source for every command's defaults: a board printed with them is found with them.
    default = CircleGridBoard()
    chess = ChessboardBoard()
    charuco = CharucoBoard()
    g.add_argument(
        "--type",
        choices=BOARD_TYPES,
        default="circles",
        help="circles (default): a circle grid, the paper's board; chessboard: OpenCV's "
        "chessboard; charuco: OpenCV's ChArUco board",
    )
    g.add_argument(
        "--cols",
        type=int,
        default=default.cols,
        action=_Noted,
        help=f"dots along a row (default {default.cols}); a chessboard's inner corners "
        f"along a row (default {chess.cols})",
    )
    g.add_argument(
        "--rows",
        type=int,
        default=default.rows,
        action=_Noted,
        help=f"dots down a column (default {default.rows}); a chessboard's inner corners "
        f"down a column (default {chess.rows})",
    )
    marker = g.add_mutually_exclusive_group()
    marker.add_argument(
        "--origin-marker",
        dest="origin_marker",
        action=_Noted,
        nargs=0,
        const=True,
        help="the origin dot is larger and fixes the orientation; on a chessboard, three dots "
        "about the middle" + (" (the default)" if for_printing else ""),
    )
    marker.add_argument(
        "--no-origin-marker",
        dest="origin_marker",
        action=_Noted,
        nargs=0,
        const=False,
        help="all dots the same size; a chessboard without dots"
        + ("" if for_printing else " (the default)"),
    )
    p.set_defaults(origin_marker=for_printing)

    dots = p.add_argument_group("circle grid (--type circles)")
    dots.add_argument(
        "--pitch",
        type=positive,
        default=default.pitch,
        action=_Noted,
        help=f"centre-to-centre distance ({default.pitch:g}); in the asymmetric layout the "
        "distance between rows, half that between dots along a row",
    )
    dots.add_argument(
        "--diameter",
        type=positive,
        default=None,
        action=_Noted,
        help="dot diameter (default: half the distance between neighbouring dots)"
        if for_printing
        else "dot diameter (default: measured from the image)",
    )
    dots.add_argument(
        "--layout",
        choices=LAYOUTS,
        default="symmetric",
        action=_Noted,
        help="symmetric (default): a square grid; asymmetric: OpenCV's asymmetric circle grid, "
        "every other row shifted by a pitch",
    )
    dots.add_argument(
        "--marker-diameter",
        type=positive,
        default=None,
        action=_Noted,
        help="diameter of the origin marker, at most the distance to its neighbours "
        "(default 1.5 x the dots, or less where that would crowd them)",
    )
    dots.add_argument(
        "--fiducials",
        type=_dot_ids,
        default=(),
        action=_Noted,
        metavar="K,K,...",
        help="dots printed larger anywhere in the grid, by id (0-based, k = row x cols + "
        "column): they identify every dot, so a board partly out of view is read",
    )
    dots.add_argument(
        "--fiducial-diameter",
        type=positive,
        default=None,
        action=_Noted,
        help="the fiducial dots' diameter (default: an origin marker's)",
    )

    squares = p.add_argument_group("chessboard and ChArUco board (--type chessboard, charuco)")
    squares.add_argument(
        "--square",
        type=positive,
        default=None,
        action=_Noted,
        help=f"side of a square (default {chess.square:g} for a chessboard, "
        f"{charuco.square:g} for a ChArUco board)",
    )
    squares.add_argument(
        "--squares-x",
        type=int,
        default=charuco.squares_x,
        action=_Noted,
        help=f"a ChArUco board's squares along a row (default {charuco.squares_x})",
    )
    squares.add_argument(
        "--squares-y",
        type=int,
        default=charuco.squares_y,
        action=_Noted,
        help=f"a ChArUco board's squares down a column (default {charuco.squares_y})",
    )
    squares.add_argument(
        "--marker",
        type=positive,
        default=charuco.marker,
        action=_Noted,
        help=f"side of a ChArUco marker, smaller than the square (default {charuco.marker:g})",
    )
    squares.add_argument(
        "--dictionary",
        type=_dictionary_name,
        default=charuco.dictionary,
        action=_Noted,
        metavar="DICT",
        help=f"the markers' ArUco dictionary, one of OpenCV's predefined ones (default "
        f"{charuco.dictionary}): DICT_4X4_50 ... DICT_7X7_1000, DICT_ARUCO_ORIGINAL, "
        "DICT_APRILTAG_16h5 ...",
    )
    squares.add_argument(
        "--legacy",
        choices=tuple(LEGACY_WORDS),
        default="auto",
        action=_Noted,
        help="which of OpenCV's ChArUco layouts (they differ for an even number of rows): "
        "yes, OpenCV before 4.6; no, 4.6 and later; auto (default): "
        + ("the current one" if for_printing else "either, found from the image"),
    )


def _dot_ids(text: str) -> tuple[int, ...]:
    """'69,74,149' as dot ids; the board checks they are its."""
    try:
        ids = tuple(int(w) for w in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected dot ids separated by commas (69,74,149), got {text!r}"
        ) from None
    if any(k < 0 for k in ids):
        raise argparse.ArgumentTypeError(f"dot ids start at 0, got {text!r}")
    return ids


def _refuse_other_types(kind: str, given: dict[str, str]) -> None:
    """ArgumentError naming the first typed option that does not describe a board of
    ``kind``, and what does."""
    for dest, option in given.items():
        if kind in _OPTION_TYPES.get(dest, (kind,)):
            continue
        instead = _INSTEAD.get((kind, dest))
        hint = f"; did you mean {instead}?" if instead else ""
        raise argparse.ArgumentError(
            None,
            f"{option} does not apply to --type {kind}: a {_KIND_WORDS[kind]} is told with "
            f"{_TYPE_OPTIONS[kind]}{hint}",
        )


_KIND_WORDS = {"circles": "circle grid", "chessboard": "chessboard", "charuco": "ChArUco board"}


def board_from(args: argparse.Namespace) -> Board:
    """The board the arguments describe (any type, ``--type``; circles when absent); one
    that cannot be (a dot wider than the pitch, a row of one dot) or an option of another
    type is a malformed command line. A type's own defaults stand for what was not typed."""
    kind = getattr(args, "type", "circles")
    given: dict[str, str] = getattr(args, BOARD_GIVEN, None) or {}
    _refuse_other_types(kind, given)
    with command_line(BoardError):
        if kind == "chessboard":
            chess = ChessboardBoard()
            cols = args.cols if "cols" in given else chess.cols
            rows = args.rows if "rows" in given else chess.rows
            return ChessboardBoard(
                cols=cols,
                rows=rows,
                square=chess.square if args.square is None else args.square,
                origin_marker=args.origin_marker,
            )
        if kind == "charuco":
            charuco = CharucoBoard()
            return CharucoBoard(
                squares_x=args.squares_x,
                squares_y=args.squares_y,
                square=charuco.square if args.square is None else args.square,
                marker=args.marker,
                dictionary=args.dictionary,
                legacy=LEGACY_WORDS[args.legacy],
            )
        return CircleGridBoard(
            cols=args.cols,
            rows=args.rows,
            pitch=args.pitch,
            diameter=args.diameter,
            origin_marker=args.origin_marker,
            marker_diameter=args.marker_diameter,
            layout=args.layout,
            fiducials=args.fiducials,
            fiducial_diameter=args.fiducial_diameter,
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
