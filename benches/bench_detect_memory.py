"""Peak memory and time of detect_board on large images it finds no board in.

Each case runs in a fresh subprocess: the image is made first, then the peak resident set
(ru_maxrss, which sees OpenCV's and NumPy's native allocations that tracemalloc does not) is
read before and after detect_board; the difference is what detection needed beyond the
image. Cases, 8-bit grey: white, dark squares on white (a component every 1600 px) and
uniform noise (a million components a level per 16 Mpx), at 4000^2, 8000^2 and 16000^2 px.

    PYTHONPATH=python python benches/bench_detect_memory.py [--sides 4000 8000 16000]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

CHILD = r"""
import json, resource, sys, time
import numpy as np
from planarcal import synth
from planarcal.calib.detect import detect_board
from planarcal.errors import BoardNotFoundError

side, kind = int(sys.argv[1]), sys.argv[2]
if kind == "white":
    image = np.full((side, side), 255, np.uint8)
elif kind == "dots":  # dark 12 px squares 40 px apart on white: a component every 1600 px
    image = np.full((side, side), 255, np.uint8)
    inked = np.flatnonzero(np.arange(side) % 40 < 12)
    image[np.ix_(inked, inked)] = 30
else:
    image = np.random.default_rng(0).integers(0, 256, (side, side), dtype=np.uint8)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
try:
    detect_board(image, synth.PAPER_BOARD)
    outcome = "found"
except BoardNotFoundError:
    outcome = "BoardNotFoundError"
seconds = time.perf_counter() - t0
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"extra_kib": after - before, "seconds": seconds, "outcome": outcome}))
"""


def run_case(side: int, kind: str) -> dict[str, object]:
    done = subprocess.run(
        [sys.executable, "-c", CHILD, str(side), kind],
        capture_output=True,
        text=True,
        check=False,
        timeout=3600,
    )
    if done.returncode != 0:
        return {"error": done.stderr.strip().splitlines()[-1:]}
    result: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sides", type=int, nargs="+", default=[4000, 8000, 16000])
    parser.add_argument("--kinds", nargs="+", default=["white", "dots", "noise"])
    args = parser.parse_args()
    print(f"{'image':>16} {'input MB':>9} {'extra peak MB':>14} {'x input':>8} {'s':>7}  outcome")
    for side in args.sides:
        for kind in args.kinds:
            r = run_case(side, kind)
            size_mb = side * side / 2**20
            if "error" in r:
                print(f"{side}^2 {kind:>6} {size_mb:9.0f}  failed: {r['error']}")
                continue
            extra_mb = float(str(r["extra_kib"])) / 1024
            print(
                f"{side:>7}^2 {kind:>6} {size_mb:9.0f} {extra_mb:14.0f} "
                f"{extra_mb / size_mb:8.2f} {float(str(r['seconds'])):7.1f}  {r['outcome']}",
                flush=True,
            )


if __name__ == "__main__":
    main()
