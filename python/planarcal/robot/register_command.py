"""``planarcal register``: fit the registration of a calibrated board to a robot's base frame
from a touch-point CSV (see ``touch_csv``), print the residual table and the verdict, and
write the calibration with the registration (atomically).

A touch named as an outlier (on the wrong dot, a mistyped coordinate) is not averaged into a
saved registration: unless ``--drop-outliers`` leaves it out, nothing is written and the
command exits 1, naming the point ("dot 7" on a circle grid, "corner 7" on a chessboard or a
ChArUco board: the table and the messages use the board's word) and the CSV line to touch
again. A CSV whose id column names the other kind of point than the calibration's board has
is refused (``touch_csv.check_point_name``). A registration judged poor
(by its leave-one-out error or by the map's own error at the board's corners) is not written
either unless ``--force`` asks for it; touches on one line with no hand given
(``--handedness``, ``--no-mirror``) are refused before a fit."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from planarcal.calib.calibration import Calibration
from planarcal.calib.json_number import json_ready
from planarcal.commands import positive
from planarcal.robot.handedness import HANDEDNESS, Handedness
from planarcal.robot.registration import RobotFrame
from planarcal.robot.summary import USABLE_MM, judged_mm, quality
from planarcal.robot.touch_csv import (
    COLUMN_SETS,
    TouchPoints,
    check_point_name,
    read_touch_csv,
)
from planarcal.robot.touch_pairs import DEFAULT_POINT_NAME
from planarcal.robot.transform_fit import MODELS, Model


def add_parser(subcommands: Any) -> argparse.ArgumentParser:
    """Adds the ``register`` command to the CLI's subcommands (argparse's _SubParsersAction)."""
    p: argparse.ArgumentParser = subcommands.add_parser(
        "register",
        help="register the calibrated board to a robot's base frame from touch points",
        description="Fit the map from the board (or the image) to the robot's base frame from "
        "point pairs in a CSV, print each pair's residual and the fit's quality, and save the "
        "calibration with the registration: 'locate' and 'run' then give robot mm. The CSV "
        "has a header and one of the column sets " + "; ".join(COLUMN_SETS) + " (mm; image "
        "in px): the id column is 'dot' for a circle grid, 'corner' for a chessboard or a "
        "ChArUco board, its id k = row x cols + col, 0 the origin point. Touches on one line "
        "need the hand given (--handedness, --no-mirror); a poor registration is written "
        "only with --force.",
    )
    p.add_argument("--calibration", required=True, type=Path, help="file from 'calibrate'")
    p.add_argument("--points", required=True, type=Path, help="the touch-point CSV")
    p.add_argument(
        "--model",
        default="rigid",
        choices=MODELS,
        help="rigid (default: rotation, offset and the mirror the points show), similarity "
        "(plus a scale), affine (plus shear)",
    )
    p.add_argument(
        "--outlier-mm",
        type=positive,
        default=None,
        metavar="MM",
        help="leave-one-out error above which a touch is named an outlier (default: 1 mm or "
        "5 x the others' median, whichever is larger)",
    )
    p.add_argument(
        "--drop-outliers",
        action="store_true",
        help="leave named outliers out of the fit (otherwise nothing is written)",
    )
    hand = p.add_mutually_exclusive_group()
    hand.add_argument(
        "--handedness",
        choices=HANDEDNESS,
        default=None,
        help="the robot frame's hand with z up from the table: right (the usual; the map "
        "mirrors the board) or left; default: from the touches, which must then not lie on "
        "one line",
    )
    hand.add_argument(
        "--no-mirror",
        dest="handedness",
        action="store_const",
        const="left",
        help="the map does not mirror the board (the same as --handedness left)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="write a registration judged poor (otherwise nothing is written)",
    )
    p.add_argument(
        "-o",
        "--output",
        required=True,
        type=Path,
        help="calibration file to write (may be --calibration itself)",
    )
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.set_defaults(run=main)
    return p


@dataclasses.dataclass(frozen=True)
class Registered:
    """A registration fitted from touch points: the frame (named with the board's word for
    its points), the calibration carrying it, and why it must not be written (a named
    outlier, a poor judgement without ``force``), or None."""

    frame: RobotFrame
    calibration: Calibration
    refusal: str | None


def register_touches(
    cal: Calibration,
    touches: TouchPoints,
    points_file: str,
    *,
    calibration_file: str | None = None,
    model: Model = "rigid",
    outlier_mm: float | None = None,
    drop_outliers: bool = False,
    handedness: Handedness | None = None,
    force: bool = False,
) -> Registered:
    """The registration ``planarcal register`` fits from ``touches`` (read from
    ``points_file``, named in the messages, as ``calibration_file`` is), with its rules for
    writing it. The live page registers with this too."""
    point_name = DEFAULT_POINT_NAME if cal.board is None else cal.board.point_name
    if cal.board is not None:
        check_point_name(touches, point_name, cal.board.describe(), points_file, calibration_file)
    fitted = cal.register(
        touches.robot,
        dots=touches.dots,
        board_mm=touches.board if touches.kind == "board" else None,
        image_px=touches.board if touches.kind == "image" else None,
        robot_z=touches.robot_z,
        model=model,
        outlier_mm=outlier_mm,
        drop_outliers=drop_outliers,
        handedness=handedness,
    ).robot_frame
    assert fitted is not None
    # The board's word for pairs given as positions too: "touch corners nearer ...".
    frame = fitted.with_point_name(point_name)
    refusal = _refusal(frame, touches, points_file, force)
    return Registered(frame, cal.with_robot_frame(frame), refusal)


def main(args: argparse.Namespace) -> int:
    """Runs ``planarcal register``: 0 when the registration was written, 1 when a named
    outlier or a poor judgement (without --force) kept it from being written; errors
    propagate (the CLI reports them)."""
    cal = Calibration.load(args.calibration)
    touches = read_touch_csv(args.points)
    done = register_touches(
        cal,
        touches,
        str(args.points),
        calibration_file=str(args.calibration),
        model=args.model,
        outlier_mm=args.outlier_mm,
        drop_outliers=args.drop_outliers,
        handedness=args.handedness,
        force=args.force,
    )
    frame, refusal = done.frame, done.refusal
    saved = None if refusal else done.calibration.save(args.output)
    if args.json:
        out: dict[str, Any] = {
            "calibration_file": None if saved is None else str(saved),
            "points_file": str(args.points),
            "pairs": touches.kind,
            "lines": list(touches.lines),
            "quality": quality(frame),
            "written": saved is not None,
            "refused": refusal,
            "replaced_registration": cal.robot_frame is not None and saved is not None,
            "registration": json_ready(frame.to_dict()),
        }
        print(json.dumps(out, allow_nan=False))
    else:
        print(frame.summary(lines=touches.lines))
        for i in frame.outliers:
            print(f"Touch again: {touches.describe(i)} of {args.points.name}.")
        if saved is not None:
            replaced = " (replacing its earlier registration)" if cal.robot_frame else ""
            print(f"Saved the calibration with the registration to {saved}{replaced}.")
    if refusal:
        print(f"planarcal register: nothing written: {refusal}", file=sys.stderr)
        return 1
    return 0


def _refusal(frame: RobotFrame, touches: TouchPoints, points_file: str, force: bool) -> str | None:
    """Why the registration must not be written, or None."""
    if frame.outliers and not frame.dropped_outliers:
        names = "; ".join(touches.describe(i) for i in frame.outliers)
        return (
            f"{points_file} has touches that look like the wrong point ({names}); touch again "
            "and re-run, or give --drop-outliers to leave them out"
        )
    if quality(frame) == "poor" and not force:
        return (
            f"the registration is poor ({judged_mm(frame):.3g} mm: leave-one-out RMS "
            f"{frame.leave_one_out_rms_mm:.3g} mm, the map's own 1-sigma "
            f"{frame.corner_std_mm:.3g} mm at the board's corners, more than {USABLE_MM:g} "
            "mm); check the pairing and touch again, or give --force to write it all the same"
        )
    return None
