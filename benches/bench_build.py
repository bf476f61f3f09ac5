"""Per-call cost of two builds of planarcal side by side: the abi3 wheel (one wheel for every
Python >= 3.10) against a build for one interpreter (``pip install .`` without the abi3
feature, or an older wheel), each in its own interpreter, interleaved, OpenCV timed in both
as the common reference.

Small calls are where the stable ABI could cost (argument parsing, array checks); large ones
are the kernels, the same machine code either way. Each figure is the best of 40 batches (the
minimum is what the code costs; a shared machine only adds to it).

    python benches/bench_build.py PYTHON_A PYTHON_B [--rounds 3]

where PYTHON_A and PYTHON_B are interpreters (virtual environments) with the two builds.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from collections.abc import Callable

CALLS = ("transform_points", "perspectiveTransform", "reprojection_errors", "estimate_homography")


def measure() -> dict[str, float]:
    """Best per-call time (us) of each call, and of OpenCV's perspectiveTransform, here."""
    import cv2  # noqa: PLC0415 (imported in the measuring interpreter only)
    import numpy as np  # noqa: PLC0415

    import planarcal  # noqa: PLC0415

    h = np.array([[2.1, 0.2, 310.0], [-0.1, 2.0, 150.0], [1e-4, 2e-4, 1.0]])
    src = np.random.default_rng(0).uniform(0, 300, (140, 2))
    src3 = src[:, None].copy()
    dst = planarcal.transform_points(h, src)

    def best(f: Callable[[], object], n: int = 2000, batches: int = 40) -> float:
        least = float("inf")
        for _ in range(batches):
            t = time.perf_counter()
            for _ in range(n):
                f()
            least = min(least, (time.perf_counter() - t) / n)
        return least * 1e6

    return {
        "transform_points": best(lambda: planarcal.transform_points(h, src)),
        "perspectiveTransform": best(lambda: planarcal.perspectiveTransform(src3, h)),
        "reprojection_errors": best(lambda: planarcal.reprojection_errors(h, src, dst)),
        "estimate_homography": best(lambda: planarcal.estimate_homography(src, dst), n=200),
        "cv2.perspectiveTransform": best(lambda: cv2.perspectiveTransform(src3, h)),
        "_core": planarcal._core.__file__,  # type: ignore[dict-item]
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("python_a")
    parser.add_argument("python_b")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    best: dict[str, dict[str, float]] = {}
    files: dict[str, str] = {}
    for _ in range(args.rounds):
        for python in (args.python_a, args.python_b):
            out = subprocess.run(
                [python, __file__, "--measure"], capture_output=True, text=True, check=True
            ).stdout
            figures = json.loads(out)
            files[python] = figures.pop("_core")
            mine = best.setdefault(python, {})
            for name, value in figures.items():
                mine[name] = min(mine.get(name, float("inf")), value)
    a, b = best[args.python_a], best[args.python_b]
    print(f"A: {files[args.python_a]}\nB: {files[args.python_b]}\n")
    print("| call, 140 points | A (us) | B (us) | B / A |")
    print("|---|---:|---:|---:|")
    for name in (*CALLS, "cv2.perspectiveTransform"):
        print(f"| {name} | {a[name]:.3f} | {b[name]:.3f} | {b[name] / a[name]:.2f} |")


if __name__ == "__main__":
    if sys.argv[1:] == ["--measure"]:
        print(json.dumps(measure()))
    else:
        main()
