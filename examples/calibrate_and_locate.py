"""Calibrate a camera and locate parts in millimetres, from Python.

What it shows: planarcal's Python API from a board image to parts in mm, on a scene it
renders itself with exact ground truth (planarcal.synth: the paper's board and 1280 x 720
webcam, barrel distortion, blur, noise, uneven light). It finds the board in the first image
(``detect_board``) and calibrates (``Calibration.from_detection``: the plane's homography and
a lens model chosen by leave-one-out). It saves the calibration file and loads it back, as a
second program would. Then it locates the three bolts and seven nuts of the second image
(``locate_objects``), each with its 1-sigma error bar and angle, and compares every position
with the truth.

Run it from the repository root (about 5 s)::

    python examples/calibrate_and_locate.py
    python examples/calibrate_and_locate.py --board charuco --save calib.json
    python examples/calibrate_and_locate.py --seed 3 --tolerance-mm 0.1

It exits with status 1 when a part is missed, or lies further than ``--tolerance-mm`` from
the truth. On your own camera, use ``planarcal.load_image("board.png")`` and your printed
board's description in place of the rendered images and ``BOARDS``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

import planarcal
from planarcal import synth

# The boards a user describes from the printed page (``planarcal board`` prints each): the
# paper's circle grid, and a chessboard and a ChArUco board of the same extent.
BOARDS: dict[str, planarcal.Board] = {
    "circles": planarcal.CircleGridBoard(cols=14, rows=10, pitch=20.0, diameter=10.0),
    "chessboard": planarcal.ChessboardBoard(cols=11, rows=8, square=24.0),
    "charuco": planarcal.CharucoBoard(
        squares_x=12, squares_y=9, square=24.0, marker=18.0, dictionary="DICT_5X5_100"
    ),
}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--board", choices=BOARDS, default="circles", help="the board's type")
    parser.add_argument("--seed", type=int, default=0, help="the rendered images' noise")
    parser.add_argument(
        "--save", type=Path, default=None, help="keep the calibration file here (.json)"
    )
    parser.add_argument(
        "--tolerance-mm",
        type=float,
        default=0.15,
        help="the largest error from the truth that passes (default 0.15 mm)",
    )
    return parser.parse_args(argv)


def calibrate(image: np.ndarray, board: planarcal.Board) -> planarcal.Calibration:
    """The calibration of one image of the board lying on the work plane."""
    detection = planarcal.detect_board(image, board)
    calibration = planarcal.Calibration.from_detection(detection)
    print(calibration.summary())
    return calibration


def saved_and_loaded(calibration: planarcal.Calibration, path: Path) -> planarcal.Calibration:
    """The calibration as another program reads it: written to ``path``, loaded back."""
    written = calibration.save(path)
    print(f"Saved {written}; loaded back for locating.")
    return planarcal.Calibration.load(written)


def locate_and_check(
    image: np.ndarray,
    calibration: planarcal.Calibration,
    truth_mm: np.ndarray,
    kinds: list[str],
    tolerance_mm: float,
) -> bool:
    """Locates the parts, prints each beside its true position; True when every part was
    found once, within ``tolerance_mm`` of the truth."""
    parts = planarcal.locate_objects(image, calibration)
    print(f"\n{len(parts)} parts located ({len(truth_mm)} placed):")
    print(f"{'id':>3} {'kind':<5} {'x mm':>9} {'y mm':>9} {'1-sigma':>8} {'angle':>6}   error")
    matched: list[int] = []
    errors: list[float] = []
    sigmas: list[float] = []
    for part in parts:
        # locate_objects fills world_mm and world_std_mm; their type also covers
        # detect_objects' results, which have no plane.
        assert part.world_mm is not None and part.world_std_mm is not None
        gaps = np.hypot(*(truth_mm - np.asarray(part.world_mm)).T)
        nearest = int(gaps.argmin())
        matched.append(nearest)
        errors.append(float(gaps[nearest]))
        sigmas.append(part.world_std_mm)
        angle = "-" if part.angle_deg is None else f"{part.angle_deg:.1f}"
        print(
            f"{part.id:>3} {kinds[nearest]:<5} {part.world_mm[0]:>9.3f} {part.world_mm[1]:>9.3f}"
            f" {part.world_std_mm:>8.4f} {angle:>6}   {errors[-1]:.4f} mm"
        )
    if not errors:
        print("No part found.")
        return False
    print(
        f"Errors from the truth: mean {np.mean(errors):.4f} mm, worst {max(errors):.4f} mm "
        f"(RMS {np.sqrt(np.mean(np.square(errors))):.4f} mm; the 1-sigma said "
        f"{np.sqrt(np.mean(np.square(sigmas))):.4f} mm RMS)."
    )
    every_part_once = sorted(matched) == list(range(len(truth_mm)))
    if not every_part_once:
        print("FAIL: the parts located are not the parts placed, one for one.")
    if max(errors) > tolerance_mm:
        print(f"FAIL: a part lies {max(errors):.4f} mm from the truth (> {tolerance_mm} mm).")
    return every_part_once and max(errors) <= tolerance_mm


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    board = BOARDS[args.board]
    # Two images from one fixed camera: the board lying on the table, then parts in its
    # place (board and table coordinates agree: the truth is in the board's mm).
    scene = synth.paper_scene(seed=args.seed, board=board)
    print(f"Rendered {board.describe()} and 10 parts seen by a 1280 x 720 webcam.\n")
    calibration = calibrate(scene.calibration.image, board)
    with tempfile.TemporaryDirectory(prefix="planarcal-example-") as folder:
        path = args.save if args.save is not None else Path(folder) / "calib.json"
        calibration = saved_and_loaded(calibration, path)
    passed = locate_and_check(
        scene.objects.image,
        calibration,
        scene.objects.object_centroids_mm,
        [part.kind for part in scene.objects.objects],
        args.tolerance_mm,
    )
    print("PASS" if passed else "FAIL")
    return 0 if passed else 1


if __name__ == "__main__":
    sys.exit(main())
