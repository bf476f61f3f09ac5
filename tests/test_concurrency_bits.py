"""The same bits however the parallel core is driven: 8 Python threads at once against one,
and 1, 2 or 8 rayon threads (RAYON_NUM_THREADS, a fresh process each) against this process.

The calls: robust estimation (estimate_homography_robust, MSAC and LMedS, two seeds, PROSAC
scores; its batch; findHomography with RANSAC, LMEDS, RHO, USAC_MAGSAC and USAC_PROSAC), the
batch transforms (transform_points, perspectiveTransform, reprojection_errors and the
reductions of reprojection_stats, on 200,000 points, clean and with points that have no
image) and board detection (detect_board on boards rendered by planarcal.synth and read from
PNG files). Each answer is reduced to its bits (array bytes with dtype and shape, floats
packed, so 0.0 and -0.0 differ, as do two NaN payloads) and hashed; answers are compared call
by call, so a difference names the call and its inputs.

test_concurrency.py covers the least-squares fits and the transforms from threads, and
homography/test_robust.py the MSAC estimator under RAYON_NUM_THREADS 1 and 2.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import struct
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

import planarcal as pc
from planarcal import synth
from planarcal.calib.detect import BoardDetection
from test_concurrency import BIG, H_HORIZON, H, big_points, check_concurrent, outcome, project

Task = Callable[[], Any]

RAYON_SETTINGS = ("1", "2", "8")
"""RAYON_NUM_THREADS of the fresh processes: serial, this machine's cores, oversubscribed
(more, smaller pieces of each batch, finishing in any order)."""

MARKER_BOARD = pc.CircleGridBoard(9, 6, 25.0, 12.0, origin_marker=True)


def write_boards(folder: Path) -> None:
    """Two rendered boards as PNG files in `folder`: the paper's 14 x 10 plain grid (read
    by the rule for an ambiguous board) and a 9 x 6 grid with an origin marker, tilted."""
    camera = synth.CameraModel(width=640, height=480, focal_px=600.0)
    views = {
        "paper.png": (
            synth.PAPER_BOARD,
            synth.PlanePose(distance_mm=480, tilt_deg=15, tilt_axis_deg=30, look_at_mm=(130, 90)),
        ),
        "marker.png": (
            MARKER_BOARD,
            synth.PlanePose(distance_mm=450, tilt_deg=12, roll_deg=100.0, look_at_mm=(100, 62)),
        ),
    }
    for name, (board, pose) in views.items():
        scene = synth.render_scene(
            camera, pose, board=board, blur_sigma_px=0.8, noise_sigma=1.5, seed=4
        )
        assert cv2.imwrite(str(folder / name), scene.image)


def contaminated(seed: int, n: int, outlier_share: float) -> tuple[np.ndarray, np.ndarray]:
    """n correspondences under H with 0.3 px of noise, about `outlier_share` of them
    replaced by uniform destinations over the inliers' extent."""
    rng = np.random.default_rng(seed)
    src = rng.uniform(0, 1000, (n, 2))
    dst = project(H, src) + rng.normal(0, 0.3, (n, 2))
    wrong = rng.random(n) < outlier_share
    dst[wrong] = rng.uniform(dst.min(axis=0), dst.max(axis=0), (int(wrong.sum()), 2))
    return src, dst


# (seed, points, share of outliers): a few points to many; LMedS only below half outliers
# (its breakdown point).
PROBLEMS = ((1, 40, 0.25), (2, 400, 0.5), (3, 3000, 0.8), (4, 20_000, 0.3))
FLAGS = {
    "RANSAC": pc.RANSAC,
    "LMEDS": pc.LMEDS,
    "RHO": pc.RHO,
    "USAC_MAGSAC": pc.USAC_MAGSAC,
    "USAC_PROSAC": pc.USAC_PROSAC,
}


def robust_tasks() -> dict[str, Task]:
    tasks: dict[str, Task] = {}
    pairs = []
    for seed, n, share in PROBLEMS:
        src, dst = contaminated(seed, n, share)
        pairs.append((src, dst))
        name = f"problem(seed={seed}, n={n}, outliers={share})"
        methods: tuple[pc.RobustMethod, ...] = ("msac", "lmeds") if share < 0.5 else ("msac",)
        for method in methods:
            for rng_seed in (0, 99):
                tasks[f"estimate_homography_robust({name}, {method}, seed={rng_seed})"] = (
                    functools.partial(
                        pc.estimate_homography_robust, src, dst, 2.0, seed=rng_seed, method=method
                    )
                )
        for flag_name, flag in FLAGS.items():
            if flag != pc.LMEDS or share < 0.5:
                tasks[f"findHomography({name}, {flag_name}, 2.0)"] = functools.partial(
                    pc.findHomography, src, dst, flag, 2.0
                )
    src, dst = pairs[1]
    scores = np.random.default_rng(5).uniform(0, 1, len(src))
    tasks["estimate_homography_robust(problem(seed=2), scores=uniform(seed=5))"] = (
        functools.partial(pc.estimate_homography_robust, src, dst, 2.0, scores=scores)
    )
    tasks["estimate_homography_robust_batch(every problem, seed=7)"] = functools.partial(
        pc.estimate_homography_robust_batch, pairs, 2.0, seed=7
    )
    noise = np.random.default_rng(6).uniform(0, 1000, (2, 500, 2))
    tasks["estimate_homography_robust(500 unrelated points: no consensus)"] = functools.partial(
        pc.estimate_homography_robust, noise[0], noise[1], 2.0
    )
    return tasks


def transform_tasks() -> dict[str, Task]:
    clean = big_points(70)
    dirty = big_points(71, bad=40)  # NaN rows, and rows past H_HORIZON's horizon
    image = project(H, clean) + np.random.default_rng(72).normal(0, 0.5, clean.shape)
    p3d = np.random.default_rng(73).uniform(-5, 5, (BIG // 2, 1, 3))
    m4 = np.array([[1, 0.1, 0, 2], [0, 1, 0.2, 1], [0.1, 0, 1, 0], [0.01, 0.02, 0.03, 1.0]])
    n = f"{BIG} points"
    return {
        f"transform_points(H, {n})": lambda: pc.transform_points(H, clean),
        f"transform_points(H, {n}, inverse)": lambda: pc.transform_points(H, image, inverse=True),
        f"transform_points(H_HORIZON, {n} with 40 bad, nan)": lambda: pc.transform_points(
            H_HORIZON, dirty, invalid="nan"
        ),
        f"transform_points(H_HORIZON, {n} with 40 bad): raises": lambda: pc.transform_points(
            H_HORIZON, dirty
        ),
        f"perspectiveTransform(float64 {n}, H)": lambda: pc.perspectiveTransform(
            clean.reshape(-1, 1, 2), H
        ),
        f"perspectiveTransform(float32 {n}, H)": lambda: pc.perspectiveTransform(
            clean.astype(np.float32).reshape(1, -1, 2), H
        ),
        f"perspectiveTransform({BIG // 2} 3-D points, 4 x 4)": lambda: pc.perspectiveTransform(
            p3d, m4
        ),
        f"reprojection_errors(H, {n})": lambda: pc.reprojection_errors(H, clean, image),
        f"reprojection_errors(H_HORIZON, {n} with 40 bad, inf)": lambda: pc.reprojection_errors(
            H_HORIZON, dirty, image, invalid="inf"
        ),
        f"reprojection_stats(H, {n})": lambda: pc.reprojection_stats(H, clean, image),
    }


def detection_tasks(boards: Path) -> dict[str, Task]:
    return {
        "detect_board(paper.png, PAPER_BOARD)": functools.partial(
            pc.detect_board, boards / "paper.png", synth.PAPER_BOARD
        ),
        "detect_board(marker.png, 9 x 6 with marker)": functools.partial(
            pc.detect_board, boards / "marker.png", MARKER_BOARD
        ),
    }


def all_tasks(boards: Path) -> dict[str, Task]:
    """Every call, by a name that says its inputs."""
    return {**robust_tasks(), **transform_tasks(), **detection_tasks(boards)}


ROBUST_FIELDS = (
    "H",
    "inliers",
    "n_inliers",
    "iterations",
    "stop_reason",
    "rms_inlier_error",
    "threshold",
    "local_optimizations",
)
DETECTION_FIELDS = (
    "image_points",
    "image_size",
    "method",
    "polarity",
    "dot_diameters_px",
    "residual_rms_px",
    "refined",
    "enlarged",
    "orientation",
    "warnings",
)


def _bits(value: Any, out: Any) -> None:
    """Feeds `value`'s exact bits (and its structure) to the hash `out`."""
    if value is None:
        out.update(b"N")
    elif isinstance(value, pc.RobustResult):
        _bits(tuple(getattr(value, name) for name in ROBUST_FIELDS), out)
    elif isinstance(value, BoardDetection):
        _bits(tuple(getattr(value, name) for name in DETECTION_FIELDS), out)
    elif isinstance(value, np.ndarray | np.generic):
        a = np.ascontiguousarray(value)
        out.update(f"A{a.dtype.str}{a.shape}".encode())
        out.update(a.tobytes())
    elif isinstance(value, tuple | list):
        out.update(f"T{len(value)}".encode())
        for item in value:
            _bits(item, out)
    elif isinstance(value, float):
        out.update(b"F" + struct.pack("<d", value))
    elif isinstance(value, bool | int | str):
        out.update(f"{type(value).__name__}:{value!r}".encode())
    else:
        raise TypeError(f"no bits for a {type(value).__name__}")


def fingerprint_of(answer: Any) -> str:
    """The hash of an answer's bits (a value, or the error raised, as ``outcome`` gives)."""
    digest = hashlib.sha256()
    _bits(answer, digest)
    return digest.hexdigest()


def fingerprint(task: Task) -> str:
    """The hash of a task's answer's bits."""
    return fingerprint_of(outcome(task))


def fingerprints(boards: Path) -> dict[str, str]:
    """Every call's fingerprint, in one thread."""
    return {name: fingerprint(task) for name, task in all_tasks(boards).items()}


def rayon_workers() -> int:
    """The threads the core's pool starts: counted around the process's first parallel call
    (Linux), so that a test sees RAYON_NUM_THREADS really applied."""
    before = len(os.listdir("/proc/self/task"))
    pc.transform_points(H, big_points(80))
    return len(os.listdir("/proc/self/task")) - before


CHILD = textwrap.dedent(
    """
    import json, sys
    sys.path.insert(0, sys.argv[1])
    from test_concurrency_bits import fingerprints, rayon_workers
    from pathlib import Path
    workers = rayon_workers()
    print(json.dumps({"workers": workers, "fingerprints": fingerprints(Path(sys.argv[2]))}))
    """
)


@pytest.fixture(scope="module")
def boards(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("boards")
    write_boards(folder)
    return folder


@pytest.fixture(scope="module")
def answers(boards: Path) -> dict[str, Any]:
    """Every call's answer, in one thread."""
    return {name: outcome(task) for name, task in all_tasks(boards).items()}


def test_the_calls_answer_what_they_should(answers: dict[str, Any]) -> None:
    # The inputs are what the names say: models found, boards found, faults where planted.
    outcomes = answers
    corners = np.array([[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0], [1000.0, 1000.0]])
    for name, answer in outcomes.items():
        if name.startswith(("estimate_homography_robust(problem", "findHomography")):
            h = answer.H if isinstance(answer, pc.RobustResult) else answer[0]
            assert h is not None, name
            gap = np.linalg.norm(project(h, corners) - project(H, corners), axis=1)
            assert gap.max() < 2.0, (name, gap)
    batch = outcomes["estimate_homography_robust_batch(every problem, seed=7)"]
    assert len(batch) == len(PROBLEMS) and all(r.success for r in batch)
    hopeless = outcomes["estimate_homography_robust(500 unrelated points: no consensus)"]
    assert hopeless.H is None and hopeless.stop_reason == "no_consensus"
    raised = outcomes[f"transform_points(H_HORIZON, {BIG} points with 40 bad): raises"]
    assert raised[:2] == ("raised", "PointAtInfinityError") and "40 of 200000" in raised[3]
    marked = outcomes["detect_board(marker.png, 9 x 6 with marker)"]
    assert marked.orientation == "marker" and len(marked.image_points) == 54
    assert len(outcomes["detect_board(paper.png, PAPER_BOARD)"].image_points) == 140


def test_eight_threads_at_once_give_the_bits_of_one(boards: Path) -> None:
    tasks = list(all_tasks(boards).values())
    check_concurrent([functools.partial(fingerprint, task) for task in tasks], rounds=1)


@pytest.mark.skipif(sys.platform != "linux", reason="counts the pool's threads in /proc")
def test_every_rayon_thread_count_gives_the_same_bits(
    boards: Path, answers: dict[str, Any]
) -> None:
    here = {name: fingerprint_of(answer) for name, answer in answers.items()}
    tests = str(Path(__file__).parent)
    children = {
        threads: subprocess.Popen(
            [sys.executable, "-c", CHILD, tests, str(boards)],
            env=dict(os.environ, RAYON_NUM_THREADS=threads),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for threads in RAYON_SETTINGS
    }
    differences = []
    for threads, child in children.items():
        out, err = child.communicate(timeout=120)
        assert child.returncode == 0, err
        report = json.loads(out)
        assert report["workers"] == int(threads), report["workers"]
        theirs = report["fingerprints"]
        assert theirs.keys() == here.keys()
        differences += [f"{name} with {threads}" for name in here if theirs[name] != here[name]]
    assert not differences, "bits differ between thread counts: " + "; ".join(differences)
