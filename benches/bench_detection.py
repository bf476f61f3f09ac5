"""Centre accuracy of planarcal.detect_board against OpenCV's findCirclesGrid, on rendered
images with exact truth (planarcal.synth): the paper's 14 x 10 board, 1280 x 720, tilted by
0, 15 and 30 degrees, blurred (0.7 and 1.5 px), with and without sensor noise (3 grey levels)
and a lighting gradient, plus the paper's own scene (barrel distortion, vignetting). The error
of a centre is its distance from the projection of the dot's true centre.

Run from the repository root::

    python benches/bench_detection.py             # the full table (about 30 s)
    python benches/bench_detection.py --markdown  # as Markdown, for the README
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal import synth
from planarcal.detect import detect_board


def errors_against(points: NDArray[np.float64], truth: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each found centre's distance from the nearest true centre (orders may differ)."""
    d = np.linalg.norm(points[:, None] - truth[None], axis=2)
    result: NDArray[np.float64] = d.min(axis=1)
    return result


def opencv_centres(image: NDArray[np.uint8], cols: int, rows: int) -> NDArray[np.float64] | None:
    for flags in (
        cv2.CALIB_CB_SYMMETRIC_GRID,
        cv2.CALIB_CB_SYMMETRIC_GRID | cv2.CALIB_CB_CLUSTERING,
    ):
        found, centres = cv2.findCirclesGrid(image, (cols, rows), flags=flags)
        if found:
            return np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    return None


def scenes() -> list[tuple[str, synth.RenderedScene]]:
    board = synth.PAPER_BOARD
    out = []
    for tilt, blur, noise, light in itertools.product(
        (0, 15, 30), (0.7, 1.5), (0.0, 3.0), (0.0, 0.4)
    ):
        pose = synth.PlanePose(
            distance_mm=500 if tilt < 25 else 560,
            tilt_deg=tilt,
            tilt_axis_deg=20,
            look_at_mm=(130, 90),
        )
        scene = synth.render_scene(
            synth.CameraModel(),
            pose,
            board=board,
            blur_sigma_px=blur,
            noise_sigma=noise,
            lighting_gradient=light,
            vignette=0.2 if light else 0.0,
            seed=1,
        )
        label = f"tilt {tilt:>2} deg, blur {blur} px, noise {noise:g}, light {light:g}"
        out.append((label, scene))
    for seed in range(3):
        out.append(
            (f"the paper's scene (distortion), seed {seed}", synth.paper_scene(seed).calibration)
        )
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    rows = []
    for label, scene in scenes():
        truth = scene.dot_centres_px
        ours = errors_against(detect_board(scene.image, scene.board).image_points, truth)
        cv_pts = opencv_centres(scene.image, scene.board.cols, scene.board.rows)
        theirs = None if cv_pts is None else errors_against(cv_pts, truth)
        rows.append((label, ours, theirs))
        print(f"  {label}", file=sys.stderr)
    rms = lambda e: float(np.sqrt(np.mean(e**2)))  # noqa: E731
    header = ("scene", "planarcal RMS", "planarcal max", "OpenCV RMS", "OpenCV max", "ratio")
    lines = []
    better = 0
    for label, ours, theirs in rows:
        if theirs is None:
            lines.append((label, f"{rms(ours):.4f}", f"{ours.max():.4f}", "failed", "failed", "-"))
            better += 1
            continue
        ratio = rms(theirs) / rms(ours)
        better += ratio >= 1.0
        lines.append(
            (
                label,
                f"{rms(ours):.4f}",
                f"{ours.max():.4f}",
                f"{rms(theirs):.4f}",
                f"{theirs.max():.4f}",
                f"{ratio:.1f}x",
            )
        )
    if args.markdown:
        print("| " + " | ".join(header) + " |")
        print("|---|" + "---:|" * (len(header) - 1))
        for line in lines:
            print("| " + " | ".join(line) + " |")
    else:
        widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(header)]
        print("  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)))
        for line in lines:
            print("  ".join(v.ljust(w) for v, w in zip(line, widths, strict=True)))
    print(
        f"\nCentre errors in px. planarcal at least as accurate (RMS) in {better} of {len(rows)} "
        f"scenes; ratio = OpenCV RMS / planarcal RMS; {time.perf_counter() - start:.0f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
