"""`planarcal check`: is this calibration file what planarcal saved, and what does it hold?
With ``--accept-edits``, keep a deliberate edit: the file is loaded with every check but its
digest's and saved again with a digest of its own.

A file whose fields are not what they were saved with is refused on load everywhere
(``Calibration.load``: "edited by hand?"); this command is the command line's way to look at
a file before a robot acts on it, and to accept an edit made on purpose (a note, the image
size after a camera setting changed, a registration removed). An edit the file's other values
contradict (a point, the board's pitch, a touch pair) is refused even so: calibrate or
register again."""

from __future__ import annotations

import argparse
from pathlib import Path

from planarcal.calib.calibration import Calibration
from planarcal.errors import CalibrationFileError
from planarcal.report.summary import verdict
from planarcal.robot.summary import quality

DESCRIPTION = (
    "Check a calibration file: it loads only if all of it is consistent and as planarcal "
    "saved it. Prints what it holds. --accept-edits keeps a deliberate edit: the file is "
    "saved again with a new digest (only if every value still agrees with the others)."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = DESCRIPTION
    p.add_argument("calibration", type=Path, help="file from 'calibrate' or 'register'")
    p.add_argument(
        "--accept-edits",
        action="store_true",
        help="the file was changed on purpose: check everything but the digest, then save it "
        "with a digest of its own",
    )


def main(args: argparse.Namespace) -> int:
    path: Path = args.calibration
    edited = False
    try:
        cal = Calibration.load(path)
    except CalibrationFileError as e:
        if not args.accept_edits or "its digest does not match" not in str(e):
            raise
        edited = True
        cal = Calibration.load(path, trust_edits=True)  # every other check still made
    for line in _description(cal):
        print(line)
    if not edited:
        print(f"{path}: consistent and as saved.")
        return 0
    cal.save(path)
    print(f"{path}: consistent; the edit was kept and the file saved with a new digest.")
    return 0


def _description(cal: Calibration) -> list[str]:
    """What a user checks before trusting the file: what it calibrates, how well, and where
    its millimetres go."""
    s = cal.summary()
    lines = [f"created {cal.created}"]
    board = cal.board
    if board is not None:
        lines.append(f"board ({board.kind}): {board.describe()}")
        placements = cal.placements
        if len(placements) > 1:
            reference = next(p for p in placements if p.reference)
            lines.append(
                f"points: {s.n_points} {board.point_name}s from {len(placements)} placements "
                f"of the board, fitted together (the plane's frame is placement "
                f"{reference.index}'s board frame)"
            )
            lines += [f"  {p.describe()}" for p in placements]
        else:
            whole = "the whole board" if s.n_points == board.n_points else "a partial view"
            lines.append(
                f"points: {s.n_points} of its {board.n_points} {board.point_name}s ({whole})"
            )
    if cal.image_size is not None:
        lines.append(f"image: {cal.image_size[0]} x {cal.image_size[1]} px")
    lines.append(
        f"leave-one-out error: {s.loo_rms_px:.3g} px RMS ({verdict(s)}), {s.n_points} points"
    )
    ex = cal.extrapolation
    if ex is not None:
        lines.append(
            f"coverage: the points cover {ex.covered_share:.0%} of the image; predicted 1-sigma "
            f"{ex.covered_std_mm:.3g} mm at them, {ex.image_std_mm:.3g} mm at worst in the image"
            + (" (extrapolated)" if ex.warning is not None else "")
        )
    frame = cal.robot_frame
    if frame is None:
        lines.append("frame: the board's (no robot registration)")
    else:
        lines.append(
            f"frame: the robot's ({frame.model} registration from {len(frame.plane_mm)} "
            f"touches, {quality(frame)})"
        )
    return lines
