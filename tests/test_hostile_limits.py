"""Limits found by trying hostile input, each where no other test file owns it: a board too
large to compute, the mode of the production loop's appended output file, 10^7 points given
to the core's entry points under an address-space limit (MemoryError, not an abort), and
numbers beyond double precision (10**400, or 1e308 against 1e-308), which NumPy's
OverflowError and LinAlgError ("SVD did not converge") used to escape from."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest

import planarcal
from planarcal import synth
from planarcal.camera import plane_pose
from planarcal.errors import ArgumentError, BoardError, ImageError, IntrinsicsError
from planarcal.live.outputs import open_output

# An integer float() cannot hold: OverflowError, not a number NumPy or math can take.
HUGE = 10**400
K = np.array([[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]])
H = np.array([[2.0, 0.1, 100.0], [0.05, 2.0, 80.0], [1e-4, 2e-4, 1.0]])


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
calls["FittedPlane.predicted_loo_covariance"] = lambda s, d: fitted.predicted_loo_covariance()
calls["part_samples"] = lambda s, d: _core.part_samples(s, 1.0)
tracks = _core.Tracks(5.0, 3)
tracks.update(src[:3])
calls["Tracks.update"] = lambda s, d: tracks.update(s)
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
# The tracks are as they were before the frame that failed.
print("tracks", len(tracks), tracks.update(src[:3]).tolist())
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
            "FittedPlane.predicted_loo_covariance",
            "part_samples",
            "Tracks.update",
        ]
    ] + ["tracks 3 [1, 2, 3]"], run.stderr[-2000:]


@pytest.mark.parametrize("huge", [HUGE, -HUGE], ids=["10**400", "-10**400"])
@pytest.mark.parametrize("name", ["pitch", "diameter", "marker_diameter"])
def test_a_board_length_beyond_double_precision_is_a_board_error(name: str, huge: int) -> None:
    options = {"origin_marker": True} if name == "marker_diameter" else {}
    with pytest.raises(BoardError, match=f"{name} must be a positive length in mm"):
        planarcal.CircleGridBoard(cols=5, rows=4, **{name: huge}, **options)  # type: ignore[arg-type]


@pytest.mark.parametrize("entry", [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2)])
def test_a_camera_matrix_entry_beyond_double_precision_is_an_intrinsics_error(
    entry: tuple[int, int],
) -> None:
    k = K.tolist()
    k[entry[0]][entry[1]] = HUGE
    with pytest.raises(IntrinsicsError, match="camera matrix"):
        planarcal.CameraIntrinsics(k, np.zeros(5), (640, 480))
    with pytest.raises(IntrinsicsError, match="camera matrix"):
        plane_pose(k, H)


@pytest.mark.parametrize("index", [0, 4, 13])
def test_a_distortion_coefficient_beyond_double_precision_is_an_intrinsics_error(
    index: int,
) -> None:
    d: list[object] = [0.0] * 14
    d[index] = HUGE
    with pytest.raises(IntrinsicsError, match="distortion coefficients"):
        planarcal.CameraIntrinsics(K, d, (640, 480))  # type: ignore[arg-type]


@pytest.mark.parametrize("field", ["rms_px", "per_view_rms_px"])
def test_a_calibration_figure_beyond_double_precision_is_an_intrinsics_error(field: str) -> None:
    value = (HUGE,) if field == "per_view_rms_px" else HUGE
    with pytest.raises(IntrinsicsError, match="rms_px"):
        planarcal.CameraIntrinsics(K, np.zeros(5), (640, 480), **{field: value})  # type: ignore[arg-type]


def test_a_pose_whose_numbers_overflow_is_an_intrinsics_error() -> None:
    h = H.tolist()
    h[1][2] = HUGE
    with pytest.raises(IntrinsicsError, match="H must be a 3 x 3 array"):
        plane_pose(K, h)
    # Finite, but K^-1 H overflows: NumPy's SVD said "SVD did not converge".
    k = np.array([[1e308, 1e-154, 1e-308], [0.0, 1e308, -1e308], [0.0, 0.0, 1.0]])
    h_far = np.array([[5e-324, 5e-324, 3.0], [0.0, 1.0, -1e308], [1e308, 1e154, 1.0]])
    with pytest.raises(IntrinsicsError, match="overflows double precision"):
        plane_pose(k, h_far)


@pytest.fixture(scope="module")
def scene() -> synth.PaperScene:
    return synth.paper_scene(seed=0)


@pytest.fixture(scope="module")
def cal(scene: synth.PaperScene) -> planarcal.Calibration:
    assert scene.calibration.board is not None
    return planarcal.Calibration.from_detection(
        planarcal.detect_board(scene.calibration.image, scene.calibration.board)
    )


def test_points_and_heights_beyond_double_precision_are_argument_errors(
    cal: planarcal.Calibration,
) -> None:
    with pytest.raises(ArgumentError, match="points_px"):
        cal.image_to_world([[HUGE, 100.0]])
    with pytest.raises(ArgumentError, match="height"):
        cal.image_to_world([[100.0, 100.0]], height=HUGE)
    with pytest.raises(ArgumentError, match="points_mm"):
        cal.world_to_image([[10.0, HUGE]])


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("min_area_px", HUGE),
        ("max_area_px", -HUGE),
        ("canny", (HUGE, 100.0)),
        ("blur_sigma", HUGE),
        ("blur_sigma", 1e308),  # OpenCV's kernel size overflowed: a cv2.error
    ],
    ids=["min_area_px", "max_area_px", "canny", "blur_sigma", "blur_sigma 1e308"],
)
def test_detection_options_beyond_double_precision_are_image_errors(
    scene: synth.PaperScene, option: str, value: object
) -> None:
    with pytest.raises(ImageError, match=option):
        planarcal.detect_objects(scene.objects.image, **{option: value})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("height_mm", HUGE),
        ("max_jump_mm", -HUGE),
        ("max_missing", 2**64),  # the core's usize
        ("timeout_s", HUGE),
        ("timeout_s", 1e308),  # its milliseconds overflowed round()
        ("timeout_s", 2**63),  # threading's wait overflowed
    ],
    ids=["height_mm", "max_jump_mm", "max_missing", "timeout_s", "timeout_s 1e308", "2**63"],
)
def test_tracker_options_beyond_their_range_are_argument_errors(
    scene: synth.PaperScene,
    cal: planarcal.Calibration,
    tmp_path: Path,
    option: str,
    value: object,
) -> None:
    folder = tmp_path / "frames"
    folder.mkdir()
    cv2.imwrite(str(folder / "0.png"), scene.objects.image)
    with pytest.raises(ArgumentError, match=option):
        planarcal.Tracker(cal, str(folder), **{option: value})  # type: ignore[arg-type]
    if option == "timeout_s":
        with pytest.raises(ArgumentError, match=option):
            planarcal.Camera(str(folder), timeout_s=value)  # type: ignore[arg-type]


NO_THREAD_TO_SPAWN = """
import resource, threading
import numpy as np, planarcal

def vm_bytes():
    for line in open("/proc/self/status"):
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024

rng = np.random.default_rng(0)
src = rng.uniform(0, 100, (60, 2))
problems = [(src, src * 2.0 + 3.0)] * 4
# The thread pool started by a large transform (a batch would leave a thread stack cached).
planarcal.transform_points(np.eye(3), rng.uniform(0, 1, (10**6, 2)))
# Room for the small problems, not for a new thread's stack.
limit = vm_bytes() + 2**20
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
try:
    threading.Thread(target=print).start()
except RuntimeError:
    print("no thread")
print([r.n_inliers for r in planarcal.estimate_homography_robust_batch(problems, threshold=1.0)])
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
def test_a_batch_without_a_thread_to_spawn_runs_on_the_callers() -> None:
    """The batch's watcher thread could not be spawned: its problems are solved one by one on
    the calling thread (std's spawn() panicked)."""
    run = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(NO_THREAD_TO_SPAWN)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.splitlines() == ["no thread", "[60, 60, 60, 60]"], run.stderr[-2000:]
