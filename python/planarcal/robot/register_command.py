"""``planarcal register``: fit the registration of a calibrated board to a robot's base frame
from a touch-point CSV (see ``touch_csv``), print the residual table and the verdict, and
write the calibration with the registration (atomically).

A touch named as an outlier (on the wrong dot, a mistyped coordinate) is not averaged into a
saved registration: unless ``--drop-outliers`` leaves it out, nothing is written and the
command exits 1, naming the CSV line to touch again."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from planarcal.calib.calibration import Calibration
from planarcal.robot.summary import quality
from planarcal.robot.touch_csv import COLUMN_SETS, read_touch_csv
from planarcal.robot.transform_fit import MODELS


def add_parser(subcommands: Any) -> argparse.ArgumentParser:
    """Adds the ``register`` command to the CLI's subcommands (argparse's _SubParsersAction)."""
    p: argparse.ArgumentParser = subcommands.add_parser(
        "register",
        help="register the calibrated board to a robot's base frame from touch points",
        description="Fit the map from the board (or the image) to the robot's base frame from "
        "point pairs in a CSV, print each pair's residual and the fit's quality, and save the "
        "calibration with the registration: 'locate' and 'run' then give robot mm. The CSV "
        "has a header and one of the column sets " + "; ".join(COLUMN_SETS) + " (mm; image "
        "in px). A dot's index is k = row x cols + col, 0 the origin dot.",
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
        type=float,
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


def main(args: argparse.Namespace) -> int:
    """Runs ``planarcal register``: 0 when the registration was written, 1 when a named
    outlier kept it from being written; errors propagate (the CLI reports them)."""
    cal = Calibration.load(args.calibration)
    touches = read_touch_csv(args.points)
    registered = cal.register(
        touches.robot,
        dots=touches.dots,
        board_mm=touches.board if touches.kind == "board" else None,
        image_px=touches.board if touches.kind == "image" else None,
        robot_z=touches.robot_z,
        model=args.model,
        outlier_mm=args.outlier_mm,
        drop_outliers=args.drop_outliers,
    )
    frame = registered.robot_frame
    assert frame is not None
    refused = bool(frame.outliers) and not frame.dropped_outliers
    saved = None if refused else registered.save(args.output)
    where = [f"Point {i} is {args.points.name} {touches.describe(i)}." for i in frame.outliers]
    if args.json:
        out: dict[str, Any] = {
            "calibration_file": None if saved is None else str(saved),
            "points_file": str(args.points),
            "pairs": touches.kind,
            "lines": list(touches.lines),
            "quality": quality(frame),
            "written": saved is not None,
            "replaced_registration": cal.robot_frame is not None and saved is not None,
            "registration": _json_ready(frame.to_dict()),
        }
        print(json.dumps(out, allow_nan=False))
    else:
        print(frame.summary())
        for line in where:
            print(line)
        if saved is not None:
            replaced = " (replacing its earlier registration)" if cal.robot_frame else ""
            print(f"Saved the calibration with the registration to {saved}{replaced}.")
    if refused:
        names = "; ".join(f"point {i} on {touches.describe(i)}" for i in frame.outliers)
        print(
            f"planarcal register: nothing written: {args.points} has touches that look like "
            f"the wrong point ({names}); touch again and re-run, or give --drop-outliers to "
            "leave them out",
            file=sys.stderr,
        )
        return 1
    return 0


def _json_ready(value: Any) -> Any:
    """value with non-finite floats as None (JSON has no inf or NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json_ready(v) for v in value]
    return value
