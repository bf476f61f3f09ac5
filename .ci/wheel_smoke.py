"""The installed wheel's smoke test (.ci/wheel runs it in a fresh virtual environment, outside
the source tree): planarcal comes from the wheel, its extension is the abi3 one, and the main
paths work against the real OpenCV and NumPy installed beside it."""

from __future__ import annotations

import json
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

import cv2
import numpy as np

import planarcal
from planarcal import _core, synth

site = Path(sysconfig.get_paths()["purelib"]).resolve()
assert Path(planarcal.__file__).resolve().is_relative_to(site), planarcal.__file__
assert Path(_core.__file__).name.endswith(".abi3.so"), _core.__file__
print(f"planarcal {planarcal.__file__}, numpy {np.__version__}, OpenCV {cv2.__version__}")

# The drop-ins agree with OpenCV on a noisy grid, robustly too (30 % outliers).
rng = np.random.default_rng(0)
grid = np.stack(np.meshgrid(np.arange(14.0), np.arange(10.0)), -1).reshape(-1, 2) * 20
h_true = np.array([[2.1, 0.2, 310.0], [-0.1, 2.0, 150.0], [1e-4, 2e-4, 1.0]])
image = cv2.perspectiveTransform(grid[:, None], h_true)[:, 0] + rng.normal(0, 0.3, grid.shape)
h, _ = planarcal.findHomography(grid, image)
h_cv, _ = cv2.findHomography(grid, image, 0)
mine = planarcal.perspectiveTransform(grid[:, None], h)[:, 0]
theirs = cv2.perspectiveTransform(grid[:, None], h_cv)[:, 0]
assert np.abs(mine - theirs).max() < 0.05, np.abs(mine - theirs).max()
bad = rng.choice(len(grid), 42, replace=False)
noisy = image.copy()
noisy[bad] += rng.uniform(30, 200, (42, 2))
h_robust, mask = planarcal.findHomography(grid, noisy, planarcal.RANSAC, 2.0)
assert h_robust is not None and not mask[bad].any() and mask.sum() >= 90

# Bad input is a ValueError naming the problem, not a crash.
try:
    planarcal.estimate_homography(grid[:3], image[:3])
except ValueError as e:
    print(f"refused as expected: {e}")
else:
    raise AssertionError("3 points gave a homography")

# A calibration from a rendered board, saved, loaded and used.
scene = synth.paper_scene(objects=False).calibration
board = synth.PAPER_BOARD
cal = planarcal.Calibration.from_detection(planarcal.detect_board(scene.image, board))
with tempfile.TemporaryDirectory() as tmp:
    path = Path(tmp) / "calib.json"
    cal.save(path)
    again = planarcal.Calibration.load(path)
    assert json.loads(path.read_text())["format"]
    run = subprocess.run(
        [Path(sys.executable).parent / "planarcal", "board", "-o", str(Path(tmp) / "b.svg")],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0 and (Path(tmp) / "b.svg").stat().st_size > 0, run.stderr
px = np.array([[640.0, 360.0], [200.0, 500.0]])
assert np.allclose(again.image_to_world(px), cal.image_to_world(px), atol=1e-9)
print(f"calibrated: {cal.summary().rms_px:.4f} px RMS; the wheel works")
