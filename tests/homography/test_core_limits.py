"""The core's limits under hostile input, in real subprocesses: Ctrl-C stops a long robust
search (single and batch), and an output NumPy cannot allocate is a MemoryError, not a
panic (which escapes ``except Exception``) or a crash."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap

import pytest

# A search over hopeless data with the largest budget runs for tens of seconds: only Ctrl-C
# can end it within the wait below.
HOPELESS = """
import numpy as np, planarcal, sys
rng = np.random.default_rng(0)
src, dst = rng.uniform(0, 1000, (2, 3000, 2))
options = dict(threshold=1.0, confidence=0.999999, max_iters=10**7)
if sys.argv[1] == "lmeds":  # millions of points: seconds of medians and concentration steps
    src, dst = rng.uniform(0, 1000, (2, 4_000_000, 2))
    options = dict(method="lmeds")
print("ready", flush=True)
try:
    if sys.argv[1] == "batch":
        planarcal.estimate_homography_robust_batch([(src, dst)] * 8, **options)
    else:
        planarcal.estimate_homography_robust(src, dst, **options)
except KeyboardInterrupt:
    print("interrupted", flush=True)
    sys.exit(3)
print("finished", flush=True)
"""


@pytest.mark.parametrize("mode", ["single", "batch", "lmeds"])
def test_ctrl_c_stops_a_long_robust_search(mode: str) -> None:
    child = subprocess.Popen(
        [sys.executable, "-c", HOPELESS, mode], stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None
        assert child.stdout.readline().strip() == "ready"
        # Let the search start (the GIL released), then Ctrl-C.
        subprocess.run([sys.executable, "-c", "import time; time.sleep(0.5)"], check=True)
        child.send_signal(signal.SIGINT)
        out, _ = child.communicate(timeout=20)
    finally:
        child.kill()
    assert child.returncode == 3 and out.strip() == "interrupted"


OUT_OF_MEMORY = """
import resource, numpy as np, planarcal

def vm_bytes():
    for line in open("/proc/self/status"):
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024

points = np.zeros((50_000_000, 2))  # 800 MB
# planarcal exports lazily: load what the calls use (OpenCV among it) before the limit, which
# is for their outputs, not for loading libraries.
planarcal.transform_points, planarcal.perspectiveTransform, planarcal.reprojection_errors
# Room for the input and a little more, not for an output as large as the input.
limit = vm_bytes() + 300 * 2**20
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
calls = {
    "transform_points": lambda: planarcal.transform_points(np.eye(3), points),
    "perspectiveTransform": lambda: planarcal.perspectiveTransform(points[:, None], np.eye(3)),
    "reprojection_errors": lambda: planarcal.reprojection_errors(
        np.eye(3), points, points, invalid="inf"
    ),
}
for name, call in calls.items():
    try:
        call()
        print(name, "returned")
    except MemoryError:
        print(name, "MemoryError")
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
def test_an_output_numpy_cannot_allocate_is_a_memory_error() -> None:
    run = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(OUT_OF_MEMORY)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.split("\n")[:3] == [
        "transform_points MemoryError",
        "perspectiveTransform MemoryError",
        "reprojection_errors MemoryError",
    ], run.stderr[-2000:]
