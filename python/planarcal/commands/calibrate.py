"""`planarcal calibrate`: find the board in an image (or in the average of a camera's, a
video's or a folder's frames of one still view), or in several images of the board laid at
several places on the plane (placements, fitted together), fit the plane's homography, save
it, and report its accuracy and where in the image it is predicted worse than a limit."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.boards import Board
from planarcal.calib.calibration import Calibration, LensChoice
from planarcal.calib.detection import detect_board
from planarcal.calib.detector_options import detector_options
from planarcal.calib.placement_set import detect_copies, detect_placement
from planarcal.camera import CameraIntrinsics
from planarcal.commands import board_arguments, board_from, count, not_a_folder, positive
from planarcal.errors import BoardNotFoundError, ImageError
from planarcal.homography import SOLVERS, Solver
from planarcal.images import load_image
from planarcal.live.capture import Camera
from planarcal.live.capture_sources import open_path
from planarcal.progress import progress
from planarcal.report import summary_json, summary_text, write_detection_failure, write_report
from planarcal.report.figure import require_matplotlib
from planarcal.report.printable import CHECK_BAR_MM

DESCRIPTION = (
    "Find the board in IMAGE, fit the plane's homography, save it, and report its accuracy. "
    "Several IMAGEs are placements: the board laid flat at another place on the plane in "
    "each (the camera fixed), fitted together so that the calibration holds over the whole "
    "work area; lay it at the corners of the work area, then in the middle."
)

FRAMES = 10
"""The frames ``--camera`` averages unless ``--frames`` says."""
MOVED_LEVEL = 64
"""A pixel that differs from the first frame's by more than this (of 255) has changed: far
beyond a camera's noise and compression, the edge of a dot that moved."""
MOVED_SHARE = 0.02
"""Frames with more than this share of changed pixels show another view: averaged, the board
would be a ghost of both."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = DESCRIPTION
    p.add_argument(
        "image",
        nargs="*",
        type=Path,
        help="image of the board; several: one per placement of the board on the plane",
    )
    p.add_argument(
        "--copies",
        action="store_true",
        help="each IMAGE may show several copies of the board laid out at once: each copy is "
        "a placement (in reading order; add --turned for copies lying at any angle)",
    )
    p.add_argument(
        "--origin",
        type=int,
        default=0,
        metavar="K",
        help="with several placements: the one (0-based, in the order given; with --copies "
        "counting the copies) whose board frame is the plane's (0, the first)",
    )
    p.add_argument(
        "--max-error-mm",
        type=positive,
        default=None,
        metavar="MM",
        help="the largest predicted 1-sigma error (mm) acceptable anywhere in the image: the "
        "summary names the largest region above it (default: twice the error at the "
        "calibration's points)",
    )
    p.add_argument(
        "--camera",
        default=None,
        help="instead of IMAGE: a camera index, video file, stream URL or image "
        "folder, whose frames (of one still view) are averaged",
    )
    p.add_argument(
        "--frames", type=count, default=None, help=f"frames to average with --camera ({FRAMES})"
    )
    board_arguments(p)
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
    add_detector_arguments(p)
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
        help="the board's pitch in mm as measured with a rule (the dots' or the squares', X "
        "along a row, Y down a column): corrects the printer's scale",
    )
    scale.add_argument(
        "--check-bar",
        type=positive,
        default=None,
        metavar="MM",
        help="the printed 100 mm check bar's length as measured: corrects the printer's scale",
    )
    p.add_argument(
        "--report", type=Path, default=None, help="directory for the tables (CSV) and figures (PNG)"
    )
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")


def add_detector_arguments(p: argparse.ArgumentParser) -> None:
    """The board detector's options, ``--polarity`` and ``--turned`` (see
    ``detector_options_of``)."""
    p.add_argument(
        "--polarity",
        default=None,
        choices=("auto", "dark", "light"),
        help="circle grids: dark dots on light paper, light on dark, or try both (auto, the "
        "default)",
    )
    p.add_argument(
        "--turned",
        action="store_true",
        default=None,
        help="circle grids and chessboards: accept a board without an origin marker that lies "
        "turned by 90 degrees in the image (refused by default: usually --cols and --rows "
        "are swapped)",
    )


def detector_options_of(args: argparse.Namespace, board: Board) -> dict[str, object]:
    """``--polarity`` and ``--turned`` for the detector of the board's type, where it takes
    them; typed for a board whose detector does not, a malformed command line (exit 2)."""
    takes = detector_options(board.kind)
    options: dict[str, object] = {}
    for name, option in (("polarity", "--polarity"), ("turned", "--turned")):
        value = getattr(args, name)
        if value is None:
            continue
        if name not in takes:
            applies = ", ".join(f"--{o}" for o in takes) or "none of these options"
            raise argparse.ArgumentError(
                None,
                f"{option} does not apply to --type {board.kind} (its detector takes {applies})",
            )
        options[name] = value
    return options


def _pitches(text: str) -> tuple[float, ...]:
    words = text.split(",")
    if len(words) not in (1, 2):
        raise argparse.ArgumentTypeError(f"expected X or X,Y in mm, got {text!r}")
    try:
        return tuple(positive(w) for w in words)
    except argparse.ArgumentTypeError as e:
        raise argparse.ArgumentTypeError(f"expected X or X,Y in mm: {e}") from None


def main(args: argparse.Namespace) -> int:
    if args.report is not None:
        require_matplotlib()  # before the work: the figures cannot be drawn without it
    board = board_from(args)
    intrinsics = None
    if args.intrinsics is not None:
        intrinsics = CameraIntrinsics.load_yaml(args.intrinsics)
    options = detector_options_of(args, board)
    images = _read_images(args)
    names = [p.name for p in args.image] if args.image else ["camera"]
    detections, shown, names, reference = _detect(args, board, options, images, names)
    if len(detections) > 1 and (args.solver != "normalized_dlt" or args.no_refine):
        raise argparse.ArgumentError(
            None,
            "--solver and --no-refine are the paper's single-view estimators: placements "
            "are fitted jointly by Levenberg-Marquardt (leave them out)",
        )
    cal = fit_calibration(
        detections,
        reference,
        names,
        lens=args.lens,
        intrinsics=intrinsics,
        solver=args.solver,
        refine=not args.no_refine,
    )
    detection = detections[reference]
    image = shown[reference]
    if args.measured_pitch is not None:
        cal = cal.rescaled(*args.measured_pitch)
    elif args.check_bar is not None:
        pitch = board.pitch * args.check_bar / CHECK_BAR_MM
        cal = cal.rescaled(pitch)
    saved = cal.save(args.output)
    written = []
    if args.report is not None:
        written = write_report(
            cal,
            args.report,
            image=image,
            detection=detection,
            max_error_mm=args.max_error_mm,
            placement_images=images,
        )
    if args.json:
        out = summary_json(cal, detection, max_error_mm=args.max_error_mm)
        out["calibration_file"] = str(saved)
        if written:
            out["report_files"] = [str(p) for p in written]
        print(json.dumps(out, allow_nan=False))
    else:
        print(summary_text(cal, detection, max_error_mm=args.max_error_mm))
        print(f"Saved the calibration to {saved}")
        for p in written:
            print(f"Wrote {p}")
    return 0


def fit_calibration(
    detections: list[Any],
    reference: int,
    names: list[str],
    *,
    lens: LensChoice = "auto",
    intrinsics: CameraIntrinsics | None = None,
    solver: Solver = "normalized_dlt",
    refine: bool = True,
) -> Calibration:
    """The calibration the command fits from its detections: one view's homography (with
    ``solver``, ``refine``), or several placements fitted jointly (the placements' names
    are recorded in the file). The live page fits with this too, so that it saves the same
    file, to the bit, as the command given the same images."""
    if intrinsics is not None and lens == "auto":
        lens = "none"
    if len(detections) > 1:
        return Calibration.from_detections(
            detections, reference=reference, lens=lens, intrinsics=intrinsics, names=names
        )
    return Calibration.from_detection(
        detections[0], solver=solver, refine=refine, lens=lens, intrinsics=intrinsics
    )


def detect_image(
    image: Any,
    board: Board,
    k: int,
    count: int,
    reference: int,
    name: str,
    options: dict[str, object],
) -> Any:
    """Image k's detection among ``count`` images: a placement's when there are several (a
    placement other than the reference may lie turned), else the one view's."""
    if count > 1:
        return detect_placement(image, board, k, reference, name, options)
    return detect_board(image, board, **options)


def _detect(
    args: argparse.Namespace,
    board: Board,
    options: dict[str, object],
    images: list[Any],
    names: list[str],
) -> tuple[list[Any], list[Any], list[str], int]:
    """Every placement's detection (each image's, or with --copies each copy's), the image
    each was found in, their names and the reference placement; with --report, what the
    search saw where the board was not found is drawn before the error propagates."""
    detections: list[Any] = []
    shown: list[Any] = []  # each detection's image
    found_names: list[str] = []
    reference = 0 if args.copies else _origin(args, len(images))
    k = 0
    try:
        for k, image in enumerate(progress(images, desc="Finding the board", unit="image")):
            if args.copies:
                found, called = detect_copies(image, board, k, names[k], options)
                detections += found
                shown += [image] * len(found)
                found_names += called
            else:
                detections.append(
                    detect_image(image, board, k, len(images), reference, names[k], options)
                )
                shown.append(image)
    except BoardNotFoundError as e:
        # Drawn once the loop has ended and its bar is erased: the message gets its own line.
        _draw_failure(args, images[k], e)
        raise
    if args.copies:
        names = found_names
        reference = _origin(args, len(detections))
    return detections, shown, names, reference


def _draw_failure(args: argparse.Namespace, image: Any, e: BoardNotFoundError) -> None:
    """With --report, what the search saw in the image where the board was not found: what it
    takes to fix the picture."""
    if args.report is None:
        return
    try:
        drawn = write_detection_failure(args.report, image, e.diagnostics, str(e))
    except OSError as why:
        print(f"planarcal calibrate: could not draw what was seen: {why}", file=sys.stderr)
    else:
        print(f"planarcal calibrate: drew what the search saw in {drawn}", file=sys.stderr)


def _origin(args: argparse.Namespace, count: int) -> int:
    if not 0 <= args.origin < count:
        raise argparse.ArgumentError(
            None,
            f"--origin {args.origin} is not a placement: give 0 to {count - 1} (the images in "
            "the order given)",
        )
    return int(args.origin)


def _read_images(args: argparse.Namespace) -> list[Any]:
    """The calibration images: files (one per placement), or the average of frames from a
    camera source."""
    if args.image and args.camera is not None:
        raise argparse.ArgumentError(None, "give IMAGE files or --camera SOURCE, not both")
    if args.camera is None:
        if not args.image:
            raise argparse.ArgumentError(None, "give an IMAGE file or --camera SOURCE")
        if args.frames is not None:
            raise argparse.ArgumentError(None, "--frames goes with --camera (an IMAGE is one)")
        images = []
        for path in args.image:
            instead = f"to average the images in it, give --camera {path}"
            images.append(load_image(not_a_folder(path, instead)))
        return images
    source: int | str = int(args.camera) if args.camera.isdigit() else args.camera
    with Camera(source) as camera:
        return [still_average(camera, FRAMES if args.frames is None else args.frames)]


def still_average(camera: Camera, n: int) -> NDArray[np.float32]:
    """The mean of the camera's next ``n`` frames, which must show one still view: frames
    that differ from the first (the board moved, a folder of several views) are refused
    (ImageError naming them), not averaged into a ghost of the board."""
    first: NDArray[np.uint8] | None = None
    total: NDArray[np.float64] | None = None
    moved: list[tuple[int, float]] = []
    frames = progress(camera.frames(n), desc="Averaging frames", total=n, unit="frame")
    for k, frame in enumerate(frames, start=1):
        if first is None or total is None:
            first, total = frame, frame.astype(np.float64)
            continue
        changed = np.abs(frame.astype(np.int16) - first) > MOVED_LEVEL
        share = float(np.count_nonzero(changed)) / changed.size
        if share > MOVED_SHARE:
            moved.append((k, share))
        total += frame
    if moved:
        raise ImageError(_views_differ(camera, moved))
    assert total is not None
    return (total / n).astype(np.float32)


def _views_differ(camera: Camera, moved: list[tuple[int, float]]) -> str:
    names = _frame_names(camera)
    which = ", ".join(
        f"frame {k}{names(k)} ({100 * share:.0f} % of its pixels changed)" for k, share in moved
    )
    return (
        f"the frames of {camera.label} do not show one still view: {which} differ from frame "
        f"1{names(1)}; their average would blur the board into a ghost of both. Give "
        "--camera a still view (a folder of pictures of one pose), or calibrate from one IMAGE"
    )


def _frame_names(camera: Camera) -> Callable[[int], str]:
    """Frame k's file name, for an image folder (in the order the Camera reads it)."""
    files: list[str] = []
    source = camera.source
    if isinstance(source, str | Path) and Path(source).is_dir():
        backend = open_path(str(source), 1000, None, None, False)
        files = list(getattr(backend, "files", []))
        backend.release()

    def name(k: int) -> str:
        return f" ({Path(files[k - 1]).name})" if k <= len(files) else ""

    return name
