"""planarcal as a drop-in for OpenCV's findHomography and perspectiveTransform.

What it shows: an existing OpenCV script, unchanged but for one line, run on planarcal. The
script (``find_sheet``) matches SIFT features between two views of a work table, fits the
homography between them with RANSAC (``findHomography``) and maps the first view's outline
into the second (``perspectiveTransform``), as OpenCV's feature-matching tutorial does. Its
geometry calls go through one name, ``geometry``. In your own script the one-line change is
``import planarcal as geometry`` in place of ``import cv2 as geometry``, or
``from planarcal import findHomography, perspectiveTransform`` in place of cv2's names.

Here both run side by side on a pair with exact truth: the first view is rendered by
planarcal.synth (the paper's board, parts and a lightly textured table), the second is that
view warped by a known homography, with fresh sensor noise. The board's dots all look alike,
so about half of the matches are wrong: the robust estimator has work to do. Each answer is
compared with the truth: the mean distance, over a grid of the whole image, between where it
and the true homography put each pixel. Then the shapes and dtypes of the two libraries'
answers are compared, and a failure is caught by the script's own ``except cv2.error``.

Run it from the repository root (about 3 s)::

    python examples/opencv_dropin.py
    python examples/opencv_dropin.py --seed 4 --tolerance-px 0.5

It exits with status 1 when planarcal's homography is further than ``--tolerance-px`` from
the truth, or its answers differ from OpenCV's in shape or dtype.
"""

from __future__ import annotations

import argparse
import sys
from types import ModuleType
from typing import Any

import cv2
import numpy as np

import planarcal
from planarcal import synth

LOWE_RATIO = 0.75
"""Lowe's ratio test, as in OpenCV's tutorial."""


def find_sheet(view_a: np.ndarray, view_b: np.ndarray, geometry: ModuleType) -> dict[str, Any]:
    """The existing OpenCV script: where view A's outline lies in view B. ``geometry`` is the
    module its homography calls go to (cv2, or planarcal after the one-line change)."""
    sift = cv2.SIFT.create(nfeatures=3000)
    keys_a, desc_a = sift.detectAndCompute(view_a, None)
    keys_b, desc_b = sift.detectAndCompute(view_b, None)
    pairs = cv2.BFMatcher(cv2.NORM_L2).knnMatch(desc_a, desc_b, k=2)
    good = [m for m, n in pairs if m.distance < LOWE_RATIO * n.distance]
    src = np.array([keys_a[m.queryIdx].pt for m in good], np.float32).reshape(-1, 1, 2)
    dst = np.array([keys_b[m.trainIdx].pt for m in good], np.float32).reshape(-1, 1, 2)

    H, mask = geometry.findHomography(src, dst, geometry.RANSAC, 3.0)
    outline_in_b = geometry.perspectiveTransform(outline_of(view_a), H)
    return {"H": H, "mask": mask, "outline": outline_in_b, "matches": len(good)}


def outline_of(view: np.ndarray) -> np.ndarray:
    """The image's four corners (px), N x 1 x 2 float32 as OpenCV's scripts give them."""
    h, w = view.shape[:2]
    return np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], np.float32).reshape(-1, 1, 2)


def rendered_pair(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(view A, view B, the true homography from A to B): A rendered with the paper's board
    and parts, B that image warped by a known perspective, with its own sensor noise."""
    scene = synth.render_scene(
        synth.PAPER_CAMERA,
        synth.PAPER_POSE,
        board=synth.PAPER_BOARD,
        objects=synth.PAPER_OBJECTS,
        table_texture=6.0,
        blur_sigma_px=0.8,
        noise_sigma=2.0,
        seed=seed,
        supersample=2,
    )
    view_a = scene.image
    h, w = view_a.shape
    corners = np.array([[0, 0], [w, 0], [w, h], [0, h]], np.float32)
    # The second camera: the image's corners moved by up to a tenth of its size.
    moved = corners + np.array([[90, 40], [-30, 110], [-140, -20], [20, -90]], np.float32)
    truth = cv2.getPerspectiveTransform(corners, moved).astype(np.float64)
    warped = cv2.warpPerspective(view_a, truth, (w, h), flags=cv2.INTER_LINEAR)
    noise = np.random.default_rng(seed + 1).normal(0.0, 2.0, warped.shape)
    view_b = np.clip(warped + noise, 0, 255).astype(np.uint8)
    return view_a, view_b, truth


def error_from_truth(H: np.ndarray, truth: np.ndarray, size: tuple[int, int]) -> float:
    """The mean distance (px) between where H and the true homography put the pixels of a
    20 x 15 grid over the whole image."""
    w, h = size
    grid = np.mgrid[0 : w - 1 : 20j, 0 : h - 1 : 15j].reshape(2, -1).T.reshape(-1, 1, 2)
    gaps = cv2.perspectiveTransform(grid, H) - cv2.perspectiveTransform(grid, truth)
    return float(np.linalg.norm(gaps, axis=2).mean())


def same_types(ours: dict[str, Any], theirs: dict[str, Any]) -> list[str]:
    """How planarcal's answers differ from OpenCV's in shape or dtype (none: a drop-in)."""
    return [
        f"{name}: planarcal {ours[name].dtype} {ours[name].shape}, OpenCV "
        f"{theirs[name].dtype} {theirs[name].shape}"
        for name in ("H", "mask", "outline")
        if (ours[name].dtype, ours[name].shape) != (theirs[name].dtype, theirs[name].shape)
    ]


def points_text(points: np.ndarray) -> str:
    return " ".join(f"({x:7.1f}, {y:5.1f})" for x, y in points)


def too_few_matches(geometry: ModuleType) -> str:
    """What the script's own error handling sees with 3 matches: the exception it catches."""
    three = np.array([[0, 0], [100, 0], [0, 100]], np.float32).reshape(-1, 1, 2)
    try:
        geometry.findHomography(three, three, geometry.RANSAC, 3.0)
    except cv2.error as error:  # planarcal's errors are cv2.error too
        return f"caught {type(error).__module__}.{type(error).__name__}"
    return "no error raised"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=1, help="the rendered view and its noise")
    parser.add_argument(
        "--tolerance-px",
        type=float,
        default=1.0,
        help="the largest mean error from the true homography that passes (default 1 px)",
    )
    args = parser.parse_args(argv)

    view_a, view_b, truth = rendered_pair(args.seed)
    size = (view_a.shape[1], view_a.shape[0])
    results = {module.__name__: find_sheet(view_a, view_b, module) for module in (cv2, planarcal)}
    print(f"{results['cv2']['matches']} SIFT matches between the two views.")
    print(f"{'library':<10} {'inliers':>8} {'error from truth':>17}")
    errors = {}
    for name, result in results.items():
        errors[name] = error_from_truth(result["H"], truth, size)
        print(f"{name:<10} {int(result['mask'].sum()):>8} {errors[name]:>14.3f} px")
    true_outline = cv2.perspectiveTransform(outline_of(view_a).astype(np.float64), truth)
    print("View A's corners in view B (px):")
    for name, result in results.items():
        corners = result["outline"].reshape(-1, 2)
        worst = np.linalg.norm(corners - true_outline.reshape(-1, 2), axis=1).max()
        print(f"  {name:<10} {points_text(corners)}  worst {worst:.2f} px off")
    print(f"  {'truth':<10} {points_text(true_outline.reshape(-1, 2))}")

    mismatches = same_types(results["planarcal"], results["cv2"])
    for line in mismatches:
        print(f"FAIL: not a drop-in: {line}")
    for module in (cv2, planarcal):
        print(f"With 3 matches, {module.__name__}: {too_few_matches(module)}")
    passed = not mismatches and errors["planarcal"] <= args.tolerance_px
    if errors["planarcal"] > args.tolerance_px:
        print(f"FAIL: planarcal's homography is {errors['planarcal']:.3f} px from the truth.")
    print("PASS" if passed else "FAIL")
    return 0 if passed else 1


if __name__ == "__main__":
    sys.exit(main())
