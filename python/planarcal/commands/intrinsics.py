"""`planarcal intrinsics`: the camera matrix and lens distortion from several tilted views
of the board (cv2.calibrateCamera), saved as OpenCV YAML for `calibrate --intrinsics`."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from planarcal.camera import calibrate_camera
from planarcal.commands import board_arguments, board_from, not_a_folder

DESCRIPTION = (
    "Find the board in each IMAGE (3 or more, tilted differently: 15-35 degrees about "
    "different axes), estimate the camera matrix and lens distortion (cv2.calibrateCamera) "
    "and save them as OpenCV YAML for 'calibrate --intrinsics'."
)

MIN_VIEWS = 3


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = DESCRIPTION
    p.add_argument("images", nargs="+", type=Path, help="images of the board")
    board_arguments(p)
    p.add_argument("-o", "--output", required=True, type=Path, help="intrinsics file (.yaml)")
    p.add_argument("--fix-aspect-ratio", action="store_true", help="fx = fy")
    p.add_argument("--zero-tangent", action="store_true", help="no tangential distortion")
    p.add_argument("--json", action="store_true", help="print the intrinsics as one JSON object")


def main(args: argparse.Namespace) -> int:
    board = board_from(args)
    if len(args.images) < MIN_VIEWS:
        raise argparse.ArgumentError(
            None,
            f"give at least {MIN_VIEWS} images of the board, tilted differently "
            f"({len(args.images)} given)",
        )
    folder = "give the images in it one by one (a shell's DIR/*.png does)"
    images = [str(not_a_folder(p, folder)) for p in args.images]
    cam = calibrate_camera(
        images, board, fix_aspect_ratio=args.fix_aspect_ratio, zero_tangent=args.zero_tangent
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
