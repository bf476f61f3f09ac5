"""`planarcal locate`: the objects in one image, each one's position on the plane in mm (in
the board's frame or, once registered, the robot's), its 1-sigma and its angle; and the
detection options it shares with `planarcal run` (--min-area, --max-area, --roi, --blur), which
override the calibration file's object settings for the run."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from planarcal.calib.calibration import Calibration
from planarcal.calib.object_settings import ObjectSettings, detect_options_with
from planarcal.commands import (
    finite,
    frame_argument,
    frame_size_in_words,
    frame_words,
    locating_with,
    non_negative,
    not_a_folder,
    positive,
)
from planarcal.errors import ArgumentError, FrameSizeError
from planarcal.files import atomic_write
from planarcal.images import load_image
from planarcal.live.objects import DetectedObject, locate_objects
from planarcal.report.drawing import draw_objects, png_bytes

DESCRIPTION = "Find the objects in IMAGE and give each one's position on the plane in mm."


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = DESCRIPTION
    p.add_argument("image", type=Path, help="image of the objects")
    p.add_argument("--calibration", required=True, type=Path, help="file from 'calibrate'")
    add_detection_arguments(p)
    p.add_argument(
        "--height",
        type=finite,
        default=0.0,
        help="the objects' height in mm: their tops are located where they really are "
        "(needs a calibration made with --intrinsics)",
    )
    p.add_argument(
        "--annotate", type=Path, default=None, help="write the annotated image here (.png)"
    )
    p.add_argument("--json", action="store_true", help="print the objects as one JSON object")
    frame_argument(p)


# Each detection option's dest and the object setting it overrides.
DETECTION_OPTIONS = {
    "min_area": "min_area_px",
    "max_area": "max_area_px",
    "roi": "roi",
    "blur": "blur_sigma",
}


def add_detection_arguments(p: argparse.ArgumentParser) -> None:
    """The detection options of `locate` and `run`: each, given, overrides the calibration
    file's object setting of its name for this run (the others are the file's)."""
    g = p.add_argument_group(
        "detection (each overrides the calibration file's object setting for this run)"
    )
    g.add_argument(
        "--min-area",
        type=non_negative,
        default=None,
        metavar="PX",
        help="smallest object outline area in px^2",
    )
    g.add_argument(
        "--max-area",
        type=positive,
        default=None,
        metavar="PX",
        help="largest object outline area in px^2",
    )
    g.add_argument(
        "--roi",
        type=roi_argument,
        default=None,
        metavar="X,Y,W,H",
        help="keep only the objects whose centre lies in this rectangle of the image (px: "
        "left, top, width, height)",
    )
    g.add_argument(
        "--blur",
        type=non_negative,
        default=None,
        metavar="SIGMA",
        help="Gaussian blur before the edges are traced, px (default 1.5)",
    )


def roi_argument(text: str) -> tuple[int, int, int, int]:
    """--roi's X,Y,W,H: four whole numbers of px, as ObjectSettings takes them."""
    parts = [t.strip() for t in text.split(",")]
    try:
        if len(parts) != 4:
            raise ValueError
        values = [int(t) for t in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected X,Y,W,H, four whole numbers of px (left, top, width, height), got {text!r}"
        ) from None
    try:
        roi = ObjectSettings(roi=(values[0], values[1], values[2], values[3])).roi
    except ArgumentError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    assert roi is not None
    return roi


def detection_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """detect_objects' options the command line gives (those typed only)."""
    return {
        field: getattr(args, dest)
        for dest, field in DETECTION_OPTIONS.items()
        if getattr(args, dest, None) is not None
    }


def checked_detection(args: argparse.Namespace, cal: Calibration) -> dict[str, Any]:
    """The command line's detection options, checked with the calibration's settings they
    override (exit status 2 for a minimum area above the maximum, one from each, or an roi
    beyond the calibration's image)."""
    overrides = detection_overrides(args)
    try:
        detect_options_with(cal.object_settings, overrides, cal.image_size)
    except ArgumentError as e:
        held = cal.object_settings
        said = "" if held.is_default else f" (the calibration's object settings: {held.describe()})"
        # The CLI reports argparse's error as a malformed command line: exit status 2.
        raise argparse.ArgumentError(None, f"{e}{said}") from e
    return overrides


def main(args: argparse.Namespace) -> int:
    if args.annotate is not None and args.annotate.suffix.lower() != ".png":
        raise argparse.ArgumentError(
            None, f"--annotate {args.annotate}: the annotated image is a PNG; give a .png path"
        )
    folder = (
        f"to locate the objects in each of its images, use 'planarcal run --source {args.image}'"
    )
    image_path = not_a_folder(args.image, folder)
    cal = Calibration.load(args.calibration)
    frame = locating_with(args, cal)
    detect = checked_detection(args, cal)
    image = load_image(image_path)
    try:
        objects = locate_objects(image, cal, height_mm=args.height, frame=frame, **detect)
    except FrameSizeError as e:
        raise frame_size_in_words(e, "image") from e
    where = frame_words(frame)
    if args.annotate is not None:
        picture = draw_objects(image, objects, title=f"Positions in the {where}")
        atomic_write(args.annotate, png_bytes(picture))
    if args.json:
        print(json.dumps(_as_json(args, frame, objects)))
        return 0
    if not objects:
        print("No objects found.")
    else:
        _print_table(objects, where)
    if args.annotate is not None:
        print(f"Wrote {args.annotate}")
    return 0


def _as_json(args: argparse.Namespace, frame: str, objects: list[DetectedObject]) -> object:
    return {
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


def _print_table(objects: list[DetectedObject], where: str) -> None:
    print(f"Positions in the {where}:")
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
