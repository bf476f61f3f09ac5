"""Limits found by trying hostile input, each where no other test file owns it: a board too
large to compute, the mode of the production loop's appended output file, and 10^7 points
given to the core's entry points under an address-space limit (MemoryError, not an abort)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import planarcal
from planarcal.live.outputs import open_output


@pytest.mark.parametrize(("cols", "rows"), [(10**9, 10**9), (1001, 10), (10, 1001)])
def test_a_board_too_large_to_compute_is_refused_when_made(cols: int, rows: int) -> None:
    # It used to be accepted, and detection then asked NumPy for exabytes (MemoryError).
    with pytest.raises(planarcal.BoardError, match="between 2 and 1000 dots"):
        planarcal.CircleGridBoard(cols=cols, rows=rows)
    assert planarcal.CircleGridBoard(cols=1000, rows=2).world_points().shape == (2000, 2)


@pytest.mark.parametrize("umask", [0o002, 0o022, 0o077])
def test_the_loops_output_file_gets_the_umasks_mode(tmp_path: Path, umask: int) -> None:
    path = tmp_path / "parts.jsonl"
    old = os.umask(umask)
    try:
        output = open_output(str(path))
        output.close()
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


TEN_MILLION_POINTS = """
import resource
import cv2, numpy as np, planarcal
from planarcal import _core

def vm_bytes():
    for line in open("/proc/self/status"):
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024

n = 10**7
rng = np.random.default_rng(0)
src = rng.uniform(0, 1000, (n, 2))
dst = src * 1.5 + 20.0
chain = np.stack([np.arange(n) % 2000, np.arange(n) // 5000], axis=1).astype(np.int32)
grey = np.zeros((2100, 2100), np.uint8)
calls = {
    "findHomography RANSAC": lambda s, d: planarcal.findHomography(s, d, cv2.RANSAC, 3.0),
    "findHomography LMEDS": lambda s, d: planarcal.findHomography(s, d, cv2.LMEDS),
    "findHomography USAC_MAGSAC": lambda s, d: planarcal.findHomography(
        s, d, cv2.USAC_MAGSAC, 3.0
    ),
    "findHomography 0": lambda s, d: planarcal.findHomography(s, d, 0),
    "estimate_homography_robust": lambda s, d: planarcal.estimate_homography_robust(
        s, d, threshold=3.0
    ),
    "estimate_homography_robust_batch": lambda s, d: planarcal.estimate_homography_robust_batch(
        [(s, d)], threshold=3.0
    ),
    "estimate_homography svd": lambda s, d: planarcal.estimate_homography(s, d, solver="svd"),
    "estimate_homography a33": lambda s, d: planarcal.estimate_homography(s, d, solver="a33"),
    "estimate_homography refine": lambda s, d: planarcal.estimate_homography(
        s, d, refine=True
    ),
}
# Each once on a small problem first, so that the thread pool and whatever else loads lazily
# is in place before the limit.
for call in calls.values():
    call(src[:500], dst[:500])
_core.measure_contours(grey, [chain[:1000]], 0.0, 1e12)
fitted = _core.FittedPlane.fit(src, dst, "none", (4000.0, 4000.0))
calls["measure_contours"] = lambda s, d: _core.measure_contours(grey, [chain], 0.0, 1e12)
calls["FittedPlane.leave_one_out"] = lambda s, d: fitted.leave_one_out()
# Room for a tenth of the points' size beyond what the process holds: not for the work on
# all of them (the robust search alone needs 80 bytes a point).
limit = vm_bytes() + 16 * n
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
for name, call in calls.items():
    try:
        call(src, dst)
        print(name, "returned", flush=True)
    except MemoryError:
        print(name, "MemoryError", flush=True)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
def test_ten_million_points_without_the_memory_are_a_memory_error() -> None:
    """The core's buffers proportional to the points are allocated fallibly: Rust's abort
    (SIGABRT, the whole process gone) used to end the first of these calls."""
    run = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(TEN_MILLION_POINTS)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.splitlines() == [
        f"{name} MemoryError"
        for name in [
            "findHomography RANSAC",
            "findHomography LMEDS",
            "findHomography USAC_MAGSAC",
            "findHomography 0",
            "estimate_homography_robust",
            "estimate_homography_robust_batch",
            "estimate_homography svd",
            "estimate_homography a33",
            "estimate_homography refine",
            "measure_contours",
            "FittedPlane.leave_one_out",
        ]
    ], run.stderr[-2000:]
