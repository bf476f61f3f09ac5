"""Concurrent calls from many Python threads give bit-identical answers to serial calls, and
large work really runs with the GIL released.

Each test computes every answer serially first, then lets 8 threads (started together behind a
barrier) run every task, each thread in its own shuffled order and several rounds over, and
compares every concurrent answer to the serial one with ``np.array_equal``. Errors are part of
the answer: the same input must raise the same exception with the same message.
"""

from __future__ import annotations

import functools
import multiprocessing
import pickle
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import cv2
import numpy as np
import pytest

import planarcal as pc
from synthetic import identical

N_THREADS = 8
BIG = 200_000

Task = Callable[[], Any]


def outcome(task: Task) -> Any:
    """The answer of a task: its value, or ("raised", class name, cv2.error?, message)."""
    try:
        return task()
    except pc.Error as e:
        return ("raised", type(e).__name__, isinstance(e, cv2.error), str(e))


def check_concurrent(tasks: Sequence[Task], rounds: int) -> None:
    """Runs every task serially, then from 8 threads at once; all answers must be identical."""
    serial = [outcome(t) for t in tasks]
    barrier = threading.Barrier(N_THREADS)

    def worker(k: int) -> list[tuple[int, Any]]:
        order = np.random.default_rng(1000 + k)
        results = []
        barrier.wait()
        for _ in range(rounds):
            for i in order.permutation(len(tasks)):
                results.append((int(i), outcome(tasks[i])))
        return results

    with ThreadPoolExecutor(max_workers=N_THREADS) as pool:
        futures = [pool.submit(worker, k) for k in range(N_THREADS)]
        per_thread = [f.result(timeout=120) for f in futures]

    assert [len(r) for r in per_thread] == [rounds * len(tasks)] * N_THREADS
    mismatches = [
        (k, i)
        for k, results in enumerate(per_thread)
        for i, got in results
        if not identical(got, serial[i])
    ]
    assert not mismatches, f"{len(mismatches)} concurrent answers differ, e.g. {mismatches[:5]}"


def random_homography(rng: np.random.Generator, scale: float) -> np.ndarray:
    h = np.eye(3) + rng.normal(0, 0.2, (3, 3))
    h[2, :2] = rng.normal(0, 0.3 / scale, 2)
    h[2, 2] = 1.0
    return h


def project(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    q = np.c_[pts, np.ones(len(pts))] @ h.T
    return np.asarray(q[:, :2] / q[:, 2:], dtype=np.float64)


def problems(count: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Noisy correspondences of assorted sizes (both sides of the 256-point GIL threshold)."""
    rng = np.random.default_rng(seed)
    sizes = [4, 5, 8, 30, 100, 255, 256, 300, 700, 1500]
    out = []
    for k in range(count):
        n = sizes[k % len(sizes)]
        scale = float(rng.choice([1.0, 100.0, 2000.0]))
        src = rng.uniform(0, scale, (n, 2))
        dst = project(random_homography(rng, scale), src)
        if n > 4:
            dst = dst + rng.normal(0, 1e-3 * scale, dst.shape)
        out.append((src, dst))
    if count >= 5:
        line = np.c_[np.arange(10.0), 2 * np.arange(10.0) + 1]
        out.append((line, out[3][0][:10]))  # collinear: DegenerateError
        nan_dst = out[4][1].copy()
        nan_dst[17, 1] = np.nan
        out.append((out[4][0], nan_dst))  # ArgumentError naming destination point 17
    return out


H = np.array([[1.2, 0.1, 5.0], [-0.05, 0.9, 3.0], [1e-3, 2e-3, 1.0]])
# w = 1 - x / 1000: the points with x >= 1000 have no image.
H_HORIZON = np.array([[1.0, 0, 0], [0, 1, 0], [-1e-3, 0, 1]])


def big_points(seed: int, n: int = BIG, bad: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    pts = rng.uniform(0, 900, (n, 2))
    if bad:
        rows = rng.choice(n, bad, replace=False)
        pts[rows[: bad // 2], 0] = np.nan
        pts[rows[bad // 2 :], 0] = 1000 + rng.uniform(0, 10, bad - bad // 2)
    return pts


# ------------------------------------------------------------------------------------------


def test_estimate_homography_concurrent() -> None:
    tasks = [
        functools.partial(pc.estimate_homography, s, d, sv, r)
        for s, d in problems(24, seed=1)
        for sv in pc.SOLVERS
        for r in (False, True)
    ]
    check_concurrent(tasks, rounds=2)


def test_find_homography_concurrent() -> None:
    tasks: list[Task] = [functools.partial(pc.findHomography, s, d) for s, d in problems(30, 2)]
    # Few points: an error that is a cv2.error too.
    tasks.append(lambda: pc.findHomography(np.zeros((3, 2)), np.zeros((3, 2))))
    check_concurrent(tasks, rounds=3)


def test_transform_points_large_concurrent() -> None:
    clean = [big_points(s) for s in range(3)]
    dirty = big_points(10, bad=40)
    tasks: list[Task] = [functools.partial(pc.transform_points, H, p) for p in clean]
    tasks += [
        lambda: pc.transform_points(H, project(H, clean[0]), inverse=True),
        lambda: pc.transform_points(H, clean[1].reshape(1, -1, 2)),
        lambda: pc.transform_points(H_HORIZON, dirty, invalid="nan"),
        # Raises, naming the first bad point: must not depend on which rayon chunk ends first.
        lambda: pc.transform_points(H_HORIZON, dirty),
        lambda: pc.transform_points(H, clean[2][:5000]),
    ]
    serial_nan = pc.transform_points(H_HORIZON, dirty, invalid="nan")
    assert np.isnan(serial_nan).any(axis=1).sum() == 40  # the test data are what they claim
    check_concurrent(tasks, rounds=2)


def test_reprojection_errors_large_concurrent() -> None:
    src = big_points(20)
    dst = project(H, src) + np.random.default_rng(21).normal(0, 0.5, src.shape)
    dirty = big_points(22, bad=30)
    tasks: list[Task] = [
        lambda: pc.reprojection_errors(H, src, dst),
        lambda: pc.reprojection_errors(H_HORIZON, dirty, dst, invalid="inf"),
        lambda: pc.reprojection_errors(H_HORIZON, dirty, dst),
        lambda: tuple(pc.reprojection_stats(H, src, dst)),
        lambda: pc.reprojection_errors(H, src[:3000], dst[:3000]),
    ]
    check_concurrent(tasks, rounds=2)


def test_perspective_transform_large_concurrent() -> None:
    p64 = big_points(30).reshape(-1, 1, 2)
    p32 = big_points(31).astype(np.float32).reshape(1, -1, 2)
    p3d = np.random.default_rng(32).uniform(-5, 5, (BIG // 2, 1, 3))
    m4 = np.array([[1, 0.1, 0, 2], [0, 1, 0.2, 1], [0.1, 0, 1, 0], [0.01, 0.02, 0.03, 1.0]])
    at_infinity = p64.copy()
    at_infinity[123_456, 0] = [1000.0, 5.0]  # w = 0 exactly under H_HORIZON
    tasks: list[Task] = [
        lambda: pc.perspectiveTransform(p64, H),
        lambda: pc.perspectiveTransform(p32, H),
        lambda: pc.perspectiveTransform(p3d, m4),
        lambda: pc.perspectiveTransform(p3d.astype(np.float32), m4),
        lambda: pc.perspectiveTransform(at_infinity, H_HORIZON),
        lambda: pc.perspectiveTransform(p64[:100], H),
    ]
    check_concurrent(tasks, rounds=2)


def test_all_functions_mixed_concurrent() -> None:
    s, d = problems(9, seed=40)[8]
    pts = big_points(41)
    image = project(H, pts)
    tasks: list[Task] = [
        lambda: pc.estimate_homography(s, d, "a33", True),
        lambda: pc.findHomography(s, d),
        lambda: pc.transform_points(H, pts),
        lambda: pc.transform_points(H, image, inverse=True),
        lambda: pc.reprojection_errors(H, pts, pts),
        lambda: pc.perspectiveTransform(pts.astype(np.float32), H),
    ]
    check_concurrent(tasks, rounds=3)


# ------------------------------------------------------------------------------------------
# The GIL is released during large work
# ------------------------------------------------------------------------------------------


def counter_advance(work: Callable[[], Any], repeats: int) -> int:
    """How far a busy Python thread's counter advances while `work` runs, summed over repeats.

    The switch interval is made huge, so the interpreter never forces the GIL away from the
    thread running `work`: the counter thread can run during `work` only if `work` releases the
    GIL itself. (The counter thread sleeps briefly every few increments, which hands the GIL
    back between repeats.)
    """
    count = [0]
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            for _ in range(50):
                count[0] += 1
            time.sleep(1e-5)

    old = sys.getswitchinterval()
    sys.setswitchinterval(30.0)
    thread = threading.Thread(target=spin, daemon=True)
    try:
        thread.start()
        while count[0] == 0:
            time.sleep(1e-3)
        advanced = 0
        for _ in range(repeats):
            before = count[0]
            work()
            advanced += count[0] - before
        return advanced
    finally:
        stop.set()
        thread.join(timeout=30)
        sys.setswitchinterval(old)


@functools.cache
def huge() -> tuple[np.ndarray, np.ndarray]:
    """3 million points, and their images (where H^-1 maps points back in front)."""
    pts = big_points(50, n=3_000_000)
    return pts, project(H, pts)


def test_gil_measurement_sees_a_gil_holder() -> None:
    # Control: pure Python work holds the GIL, so the counter must not move at all.
    assert counter_advance(lambda: sum(range(2_000_000)), repeats=2) == 0


@pytest.mark.parametrize(
    "work",
    [
        pytest.param(lambda p, q: pc.transform_points(H, p), id="transform_points"),
        pytest.param(lambda p, q: pc.transform_points(H, q, inverse=True), id="inverse"),
        pytest.param(lambda p, q: pc.reprojection_errors(H, p, q), id="reprojection_errors"),
        pytest.param(
            lambda p, q: pc.perspectiveTransform(p.reshape(-1, 1, 2), H), id="perspectiveTransform"
        ),
    ],
)
def test_large_work_releases_the_gil(work: Callable[[np.ndarray, np.ndarray], Any]) -> None:
    pts, image = huge()
    assert counter_advance(lambda: work(pts, image), repeats=4) > 0


# ------------------------------------------------------------------------------------------
# Errors across threads and processes
# ------------------------------------------------------------------------------------------


def test_drop_in_errors_pickle() -> None:
    for call in (
        lambda: pc.findHomography(np.zeros((3, 2)), np.zeros((3, 2))),
        lambda: pc.perspectiveTransform(np.full((1, 1, 2), np.nan), H),
    ):
        with pytest.raises(pc.HomographyError) as info:
            call()
        back = pickle.loads(pickle.dumps(info.value))
        assert isinstance(back, pc.HomographyError)
        assert isinstance(back, cv2.error)
        assert str(back) == str(info.value)


_FIRST_ERRORS = textwrap.dedent(
    """
    import sys, threading
    import numpy as np
    import planarcal as pc
    barrier = threading.Barrier(8)
    kinds = []
    def work():
        barrier.wait()
        try:
            pc.findHomography(np.zeros((3, 2)), np.zeros((3, 2)))
        except pc.HomographyError as e:
            kinds.append(id(type(e)))
    threads = [threading.Thread(target=work) for _ in range(8)]
    for t in threads: t.start()
    for t in threads: t.join()
    print(len(kinds), len(set(kinds)))
    """
)


def test_first_errors_from_many_threads_share_one_type() -> None:
    # A fresh interpreter each time: the race is on the very first error of a process.
    for _ in range(3):
        run = subprocess.run(
            [sys.executable, "-c", _FIRST_ERRORS],
            capture_output=True,
            text=True,
            timeout=60,
            check=True,
        )
        raised, distinct = map(int, run.stdout.split())
        assert raised == 8
        assert distinct == 1


def _child_transform(queue: Any, pts: np.ndarray) -> None:
    queue.put(pc.transform_points(H, pts))


@pytest.mark.skipif(sys.platform != "linux", reason="fork start method")
def test_transform_in_forked_child_after_parallel_use() -> None:
    pts = big_points(60, n=100_000)
    expected = pc.transform_points(H, pts)  # starts rayon's pool in this process
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_child_transform, args=(queue, pts), daemon=True)
    child.start()
    try:
        got = queue.get(timeout=3)
    except Exception:
        got = None
    finally:
        child.join(timeout=0.5)
        if child.is_alive():
            child.kill()
            child.join(timeout=5)
    assert got is not None, "the forked child did not finish a 100_000-point transform in 3 s"
    assert identical(got, expected)
