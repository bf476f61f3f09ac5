"""The `planarcal` command line: board, intrinsics, calibrate, register, locate, run, demo.

Exit status: 0 on success, 1 when the job fails (no board in view, a file that cannot be read
or written: one clear line on stderr, no traceback), 2 for a malformed command line or one
asking for what is not installed (`--report` without matplotlib: one line naming the extra).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import os
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from planarcal import __version__
from planarcal.calib.board import LAYOUTS, CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.camera import CameraIntrinsics, calibrate_camera
from planarcal.errors import ArgumentError, BoardError, BoardNotFoundError, MissingDependencyError
from planarcal.files import atomic_write
from planarcal.homography import SOLVERS
from planarcal.images import load_image
from planarcal.live import run
from planarcal.live.capture import Camera
from planarcal.live.objects import locate_objects
from planarcal.report import summary_json, summary_text, write_detection_failure, write_report
from planarcal.report.drawing import draw_objects, png_bytes
from planarcal.report.figure import require_matplotlib
from planarcal.report.printable import (
    CHECK_BAR_MM,
    MARGIN_MM,
    PrintLayout,
    page_refusal,
    page_size,
    pitch_meaning,
    smaller_board,
    write_board,
)
from planarcal.robot import register_command
from planarcal.robot.output_frame import FRAMES, checked_frame
from planarcal.synth import demo

# Errors the commands report in one line; anything else is a bug and keeps its traceback.
_EXPECTED: tuple[type[BaseException], ...] = (ValueError, OSError)


def _board_arguments(p: argparse.ArgumentParser, *, for_printing: bool = False) -> None:
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
        type=float,
        default=default.pitch,
        help=f"centre-to-centre distance ({default.pitch:g}); in the asymmetric layout the "
        "distance between rows, half that between dots along a row",
    )
    g.add_argument(
        "--diameter",
        type=float,
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
        type=float,
        default=None,
        help="diameter of the origin marker, at most the distance to its neighbours "
        "(default 1.5 x the dots, or less where that would crowd them)",
    )


def _board(args: argparse.Namespace) -> CircleGridBoard:
    return CircleGridBoard(
        cols=args.cols,
        rows=args.rows,
        pitch=args.pitch,
        diameter=args.diameter,
        origin_marker=args.origin_marker,
        marker_diameter=args.marker_diameter,
        layout=args.layout,
    )


# The pages `--page auto` tries, smallest first.
AUTO_PAGES = ("A4", "A3", "A2", "A1", "A0")


def _cmd_board(args: argparse.Namespace) -> int:
    board = _board(args)
    if board.diameter is None:
        # A printed dot needs a size: half the neighbour distance, dots as wide as the gaps.
        board = dataclasses.replace(board, diameter=board.neighbour_distance / 2)
    auto = args.page.lower() == "auto"
    layout: PrintLayout | None = None
    refused: str | None = None
    for page in AUTO_PAGES if auto else (args.page,):
        refused = page_refusal(
            board,
            page,
            orientation=args.orientation,
            margin_mm=args.margin,
            offer=functools.partial(_offer, args, page),
        )
        if refused is None:
            layout = write_board(
                board, args.output, page=page, orientation=args.orientation, margin_mm=args.margin
            )
            break
    if layout is None:
        # The board fits no page tried: the message names a page that would, and the
        # command for a board that fits the last one.
        raise BoardError(refused)
    print(f"wrote {args.output}: {board.describe()}, on {layout.page} {layout.orientation}.")
    print(f"{board.layout.capitalize()} grid: {pitch_meaning(board)}.")
    if args.diameter is None:
        print(
            f"Dot diameter {board.diameter:g} mm: half the distance between neighbouring dots "
            "(no --diameter given)."
        )
    print("Print it at 100% (actual size, no fit-to-page) and check the bar measures 100 mm.")
    if auto and layout.page != AUTO_PAGES[0]:
        # Most printers take A4 or letter only: say which board each holds.
        print(f"It needs {layout.page} paper.")
        for small in ("A4", "letter"):
            other = smaller_board(board, page_size(small), args.orientation, args.margin)
            if other is not None:
                print(f"On {small}: {_offer(args, small, other)}.")
    return 0


def _board_command(args: argparse.Namespace, page: str, board: CircleGridBoard) -> str:
    """The `planarcal board` command line that prints `board` on `page`, with the options of
    `args` it keeps (output, orientation, margin, layout, marker)."""
    words = ["planarcal board", "-o", shlex.quote(str(args.output)), "--page", shlex.quote(page)]
    if args.orientation != "auto":
        words += ["--orientation", args.orientation]
    if args.margin != MARGIN_MM:
        words += ["--margin", f"{args.margin:g}"]
    words += ["--cols", str(board.cols), "--rows", str(board.rows), "--pitch", f"{board.pitch:g}"]
    # Sizes the user chose are kept, scaled with the pitch; unchosen ones follow it anyway.
    if args.diameter is not None:
        words += ["--diameter", _exact_mm(board.dots_mm())]
    if board.layout != "symmetric":
        words += ["--layout", board.layout]
    if not board.origin_marker:
        words.append("--no-origin-marker")
    elif board.marker_diameter is not None:
        words += ["--marker-diameter", _exact_mm(board.marker_diameter)]
    return " ".join(words)


def _exact_mm(value: float) -> str:
    """A length as short as it reads back exactly: a marker held at the dots' spacing must
    not be rounded past it."""
    short = f"{value:.10g}"
    return short if float(short) == value else repr(float(value))


def _offer(args: argparse.Namespace, page: str, board: CircleGridBoard) -> str:
    """A smaller board that fits `page`, offered as its command line."""
    return (
        f"`{_board_command(args, page, board)}` ({_dots_and_pitch(board)}; calibrate with the "
        "same --cols, --rows and --pitch)"
    )


def _dots_and_pitch(board: CircleGridBoard) -> str:
    return f"{board.cols} x {board.rows} dots, {board.pitch:g} mm apart"


def _cmd_calibrate(args: argparse.Namespace) -> int:
    if args.report is not None:
        require_matplotlib()  # before the work: the figures cannot be drawn without it
    board = _board(args)
    intrinsics = None
    if args.intrinsics is not None:
        intrinsics = CameraIntrinsics.load_yaml(args.intrinsics)
    image = _read_image(args)
    try:
        detection = detect_board(image, board, polarity=args.polarity, turned=args.turned)
    except BoardNotFoundError as e:
        if args.report is not None:
            # What the search saw is what it takes to fix the picture: draw it, then fail.
            try:
                drawn = write_detection_failure(args.report, image, e.diagnostics, str(e))
            except OSError as why:
                print(f"planarcal calibrate: could not draw what was seen: {why}", file=sys.stderr)
            else:
                print(f"planarcal calibrate: drew what the search saw in {drawn}", file=sys.stderr)
        raise
    lens = args.lens
    if intrinsics is not None and lens == "auto":
        lens = "none"
    cal = Calibration.from_detection(
        detection,
        solver=args.solver,
        refine=not args.no_refine,
        lens=lens,
        intrinsics=intrinsics,
    )
    if args.measured_pitch is not None:
        cal = cal.rescaled(*args.measured_pitch)
    elif args.check_bar is not None:
        pitch = board.pitch * args.check_bar / CHECK_BAR_MM
        cal = cal.rescaled(pitch)
    saved = cal.save(args.output)
    written = []
    if args.report is not None:
        written = write_report(cal, args.report, image=image, detection=detection)
    if args.json:
        out = summary_json(cal, detection)
        out["calibration_file"] = str(saved)
        if written:
            out["report_files"] = [str(p) for p in written]
        print(json.dumps(out, allow_nan=False))
    else:
        print(summary_text(cal, detection))
        print(f"Saved the calibration to {saved}")
        for p in written:
            print(f"Wrote {p}")
    return 0


def _cmd_intrinsics(args: argparse.Namespace) -> int:
    board = _board(args)
    if len(args.images) < 3:
        raise ArgumentError(
            f"give at least 3 images of the board, tilted differently ({len(args.images)} given)"
        )
    cam = calibrate_camera(
        [str(p) for p in args.images],
        board,
        fix_aspect_ratio=args.fix_aspect_ratio,
        zero_tangent=args.zero_tangent,
    )
    saved = cam.save_yaml(args.output)
    if args.json:
        out = cam.to_dict()
        out["file"] = str(saved)
        print(json.dumps(out, allow_nan=False))
        return 0
    print(
        f"Camera intrinsics from {cam.n_views} views ({cam.image_size[0]} x {cam.image_size[1]}):"
    )
    print(f"  focal length fx {cam.fx:.2f} px, fy {cam.fy:.2f} px")
    print(f"  principal point ({cam.cx:.2f}, {cam.cy:.2f}) px")
    print("  distortion " + ", ".join(f"{v:+.5f}" for v in cam.dist_coeffs))
    if cam.rms_px is not None:
        print(f"  RMS reprojection error {cam.rms_px:.4f} px")
    print(f"Saved to {saved}")
    return 0


def _pitches(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X or X,Y in mm, got {text!r}") from None
    if len(values) not in (1, 2):
        raise argparse.ArgumentTypeError(f"expected X or X,Y in mm, got {text!r}")
    return values


def _read_image(args: argparse.Namespace) -> Any:
    """The calibration image: a file, or the average of frames from a camera source."""
    if args.camera is None:
        if args.image is None:
            raise ArgumentError("give an IMAGE file or --camera SOURCE")
        return load_image(args.image)

    source: int | str = int(args.camera) if args.camera.isdigit() else args.camera
    with Camera(source) as camera:
        return camera.average(args.frames)


def _cmd_locate(args: argparse.Namespace) -> int:
    cal = Calibration.load(args.calibration)
    frame = checked_frame(args.frame, cal.robot_frame)
    image = load_image(args.image)
    objects = locate_objects(
        image, cal, height_mm=args.height, frame=frame, min_area_px=args.min_area
    )
    if args.annotate is not None:
        atomic_write(args.annotate, png_bytes(draw_objects(image, objects)))
    if args.json:
        print(
            json.dumps(
                {
                    "calibration_file": str(args.calibration),
                    "coords": frame,
                    "objects": [
                        {
                            "id": o.id,
                            "image_px": list(o.centroid_px),
                            "world_mm": None if o.world_mm is None else list(o.world_mm),
                            "world_std_mm": o.world_std_mm,
                            "area_px": o.area_px,
                            "angle_deg": o.angle_deg,
                        }
                        for o in objects
                    ],
                }
            )
        )
        return 0
    if not objects:
        print("No objects found.")
    else:
        print(
            f"{'object':<8}{'image x':>10}{'image y':>10}{'X (mm)':>12}{'Y (mm)':>12}"
            f"{'1-sigma (mm)':>14}{'angle (deg)':>13}"
        )
        for o in objects:
            wx, wy = o.world_mm if o.world_mm is not None else (float("nan"),) * 2
            sd = float("nan") if o.world_std_mm is None else o.world_std_mm
            # "-": too round for an axis.
            angle = "-" if o.angle_deg is None else f"{o.angle_deg:.2f}"
            print(
                f"ID:{o.id:<5}{o.centroid_px[0]:>10.1f}{o.centroid_px[1]:>10.1f}"
                f"{wx:>12.3f}{wy:>12.3f}{sd:>14.4f}{angle:>13}"
            )
    if args.annotate is not None:
        print(f"Wrote {args.annotate}")
    return 0


def _frame_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--frame",
        choices=FRAMES,
        default=None,
        help="the positions' frame of reference: board (mm on the board) or robot (the "
        "robot's base frame, from 'planarcal register'); default robot once the calibration "
        "has a registration, else board",
    )


def _cmd_run(args: argparse.Namespace) -> int:
    return run.main(args)


def _cmd_demo(args: argparse.Namespace) -> int:
    if args.report is not None:
        require_matplotlib()  # before the work: the figures cannot be drawn without it
        args.report.mkdir(parents=True, exist_ok=True)  # before the work, a bad place fails now
    print(demo.run(report=args.report))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="planarcal",
        description="Camera pixels to millimetres on a work plane: print a circle-grid board, "
        "calibrate from a picture of it, then locate objects in millimetres.",
    )
    parser.add_argument("--version", action="version", version=f"planarcal {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = commands.add_parser(
        "board",
        help="write a printable board (SVG or PDF) at exact scale",
        description="Write a circle-grid board to print at 100%, with a "
        "100 mm check bar and its parameters.",
    )
    _board_arguments(p, for_printing=True)
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
        type=float,
        default=MARGIN_MM,
        help=f"page margin in mm ({MARGIN_MM:g})",
    )
    p.set_defaults(run=_cmd_board)

    p = commands.add_parser(
        "calibrate",
        help="calibrate from an image of the board",
        description="Find the board in IMAGE, fit the plane's homography, "
        "save it, and report its accuracy.",
    )
    p.add_argument("image", nargs="?", type=Path, help="image of the board")
    p.add_argument(
        "--camera",
        default=None,
        help="instead of IMAGE: a camera index, video file, stream URL or image "
        "folder, whose frames are averaged",
    )
    p.add_argument("--frames", type=int, default=10, help="frames to average with --camera (10)")
    _board_arguments(p)
    p.add_argument("-o", "--output", required=True, type=Path, help="calibration file (JSON)")
    p.add_argument(
        "--solver",
        default="normalized_dlt",
        choices=SOLVERS,
        help="linear solver (a33 reproduces the paper)",
    )
    p.add_argument(
        "--no-refine",
        action="store_true",
        help="skip the Levenberg-Marquardt refinement (the paper's method has none)",
    )
    p.add_argument(
        "--polarity",
        default="auto",
        choices=("auto", "dark", "light"),
        help="dark dots on light paper, light on dark, or try both",
    )
    p.add_argument(
        "--turned",
        action="store_true",
        help="accept a board without an origin marker that lies turned by 90 degrees in the "
        "image (refused by default: usually --cols and --rows are swapped)",
    )
    p.add_argument(
        "--lens",
        default="auto",
        choices=("auto", "none", "k1", "k1k2", "k1k2c"),
        help="lens-distortion model fitted with the homography: auto (default) keeps the one "
        "with the lowest leave-one-out error; none is the paper's homography alone",
    )
    p.add_argument(
        "--intrinsics",
        type=Path,
        default=None,
        help="camera intrinsics (OpenCV YAML, e.g. from 'planarcal intrinsics'): undistort "
        "with them and allow heights above the plane",
    )
    scale = p.add_mutually_exclusive_group()
    scale.add_argument(
        "--measured-pitch",
        type=_pitches,
        default=None,
        metavar="X[,Y]",
        help="the board's pitch in mm as measured with a rule (X along a row, Y down a "
        "column): corrects the printer's scale",
    )
    scale.add_argument(
        "--check-bar",
        type=float,
        default=None,
        metavar="MM",
        help="the printed 100 mm check bar's length as measured: corrects the printer's scale",
    )
    p.add_argument(
        "--report", type=Path, default=None, help="directory for the tables (CSV) and figures (PNG)"
    )
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(run=_cmd_calibrate)

    p = commands.add_parser(
        "intrinsics",
        help="estimate camera intrinsics from several board images",
        description="Find the board in each IMAGE (3 or more, tilted differently: 15-35 degrees "
        "about different axes), estimate the camera matrix and lens distortion "
        "(cv2.calibrateCamera) and save them as OpenCV YAML for 'calibrate --intrinsics'.",
    )
    p.add_argument("images", nargs="+", type=Path, help="images of the board")
    _board_arguments(p)
    p.add_argument("-o", "--output", required=True, type=Path, help="intrinsics file (.yaml)")
    p.add_argument("--fix-aspect-ratio", action="store_true", help="fx = fy")
    p.add_argument("--zero-tangent", action="store_true", help="no tangential distortion")
    p.add_argument("--json", action="store_true", help="print the intrinsics as one JSON object")
    p.set_defaults(run=_cmd_intrinsics)

    register_command.add_parser(commands)

    p = commands.add_parser(
        "locate",
        help="locate objects in mm with a calibration",
        description="Find the objects in IMAGE and give each one's position on the plane in mm.",
    )
    p.add_argument("image", type=Path, help="image of the objects")
    p.add_argument("--calibration", required=True, type=Path, help="file from 'calibrate'")
    p.add_argument(
        "--min-area", type=float, default=None, help="smallest object outline area in px^2"
    )
    p.add_argument(
        "--height",
        type=float,
        default=0.0,
        help="the objects' height in mm: their tops are located where they really are "
        "(needs a calibration made with --intrinsics)",
    )
    p.add_argument("--annotate", type=Path, default=None, help="write the annotated image here")
    p.add_argument("--json", action="store_true", help="print the objects as one JSON object")
    _frame_argument(p)
    p.set_defaults(run=_cmd_locate)

    p = commands.add_parser(
        "run",
        help="the production loop: objects in mm, frame after frame",
        description="Read frames from SOURCE, locate the objects in each in mm (board or "
        "robot frame) with their angles, keep their IDs from frame to frame, and write one "
        "line per frame (JSON, CSV or a template) to the output, or serve it to controllers "
        "(tcp-listen://, on request with --trigger). Survives bad frames and a camera that "
        "drops out; Ctrl-C or SIGTERM end it cleanly with a summary on stderr. Exits 1 if "
        "every frame failed, and at once if the frames are not of the size the calibration "
        "was made on.",
    )
    p.add_argument(
        "--source",
        required=True,
        help="camera index (0), video file, image folder or stream URL",
    )
    p.add_argument("--calibration", required=True, type=Path, help="file from 'calibrate'")
    run.add_output_arguments(p)
    p.add_argument(
        "--max-frames",
        type=int,
        default=None,
        metavar="N",
        help="stop after reading N frames from the source (failed and skipped ones count too)",
    )
    p.add_argument(
        "--fps-report",
        action="store_true",
        help="print the time per frame of each stage at the end",
    )
    p.add_argument("--height", type=float, default=0.0, help="the objects' height in mm")
    p.add_argument(
        "--min-area", type=float, default=None, help="smallest object outline area in px^2"
    )
    _frame_argument(p)
    p.add_argument(
        "--max-reconnect",
        type=float,
        default=None,
        metavar="S",
        help="give up on a camera or stream that stays away this many seconds (default: never)",
    )
    p.set_defaults(run=_cmd_run)

    p = commands.add_parser(
        "demo",
        help="the whole pipeline on a rendered scene of the paper's setup",
        description="Render the paper's setup (board, lens, blur, noise; then bolts and nuts at "
        "known places), calibrate, locate the objects, and say how far each is from the truth. "
        "Needs no camera and no files.",
    )
    p.add_argument(
        "--report",
        type=Path,
        default=None,
        metavar="DIR",
        help="write here what a real run writes: the calibration report's figures and tables, "
        "the calibration file, the rendered images and the objects located, drawn on theirs",
    )
    p.set_defaults(run=_cmd_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        code: int = args.run(args)
        sys.stdout.flush()
    except BrokenPipeError:
        # The reader went away (e.g. `| head`): not an error of ours. Python would complain
        # again when it flushes stdout at exit, so point stdout at nothing first.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except MissingDependencyError as e:
        # The command line asks for what this installation lacks: a usage error.
        print(f"planarcal {args.command}: error: {e}", file=sys.stderr)
        return 2
    except _EXPECTED as e:
        print(f"planarcal {args.command}: error: {e}", file=sys.stderr)
        return 1
    return code


if __name__ == "__main__":
    sys.exit(main())
