"""Mapping alone: a frame's pixels to millimetres in one call (issue 6's targets).

The production loop maps each frame's object centroids, 10 to 1,000 points, from pixels to
the plane in one call into the Rust core. This times that call. ``FittedPlane.image_to_world``
runs the core's fast mapper (``PlaneMapper``: the lens inverse precomputed as a checked
polynomial plus one Newton step, one division a point); ``image_to_world_std`` adds each
point's 1-sigma error from the fit's covariance (what the Tracker calls); and
``Calibration.image_to_world`` is the package's call end to end. The models are fitted with
``FittedPlane.fit`` (and ``Calibration``) to the plane_model tests' scene (a 14 x 10 grid at
20 mm seen through a homography, 1280 x 720 image):

* "homography": a plain homography (lens "none");
* "lens k1": the paper-strength lens, radial k1 = -0.06 about the image centre (lens "k1").

Side by side, in the same run and on the same points:

* the exact path, which the mapper must agree with: the lens inverted by Newton's method
  per point (``FittedPlane.undistort``), then H^-1 (in NumPy);
* OpenCV: ``cv2.perspectiveTransform`` with H^-1 (homography), or ``cv2.undistortPoints``
  (with the lens as a camera matrix f = the lens scale, centre = the lens centre, and
  distortion (k1, k2, 0, 0)) then ``cv2.perspectiveTransform`` (lens).

1. Per call, 10, 100 and 1,000 points over the image: the median and the 99th percentile of
   single calls (each timed alone with time.perf_counter_ns, the contenders interleaved in a
   rotating order, the garbage collector off). Ratio: contender / image_to_world.
2. 10^6 points per call: the median time, and the effective memory throughput (16 MB of
   pixels read + 16 MB of millimetres written, per second), against plain NumPy copies of the
   same array, the memory-speed references: into a preallocated array (``np.copyto``), and
   into a new one (``px.copy()``), which like ``image_to_world`` pays for its fresh 16 MB
   (the page faults of first touching it).

The "max |d| mm" column is each contender's largest difference from the exact path on the
timed points. Targets, reported PASS/FAIL (the script never fails on them):
``FittedPlane.image_to_world`` under 5 us a call for 10 to 1,000 points (median); 10^6 points
within 2x of the time of the NumPy copy into a new array.

Run from the repository root::

    python benches/bench_mapping.py             # about half a minute
    python benches/bench_mapping.py --quick     # a smoke run
    python benches/bench_mapping.py --markdown  # tables as Markdown

Set ``RAYON_NUM_THREADS`` to limit the threads the 10^6-point calls use.
"""

from __future__ import annotations

import argparse
import gc
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

sys.path.insert(0, str(Path(__file__).resolve().parent))

from reporting import cpu_model, load_average, table_lines

from planarcal._core import FittedPlane
from planarcal.calib.calibration import Calibration

F64 = NDArray[np.float64]

SIZE = (1280.0, 720.0)
H_SCENE = np.array([[2.0, 0.05, 330.0], [-0.03, 2.02, 160.0], [2e-5, -3e-5, 1.0]])
K1 = -0.06
SMALL_SIZES = (10, 100, 1_000)
LARGE_SIZE = 1_000_000
CALL_TARGET_US = 5.0
COPY_RATIO_TARGET = 2.0


def scene(lens: str) -> tuple[F64, F64]:
    """The scene's world points and their exact pixels (k1 = -0.06 distortion for a lens)."""
    world = np.array([[c * 20.0, r * 20.0] for r in range(10) for c in range(14)])
    v = np.c_[world, np.ones(len(world))] @ H_SCENE.T
    ideal = v[:, :2] / v[:, 2:]
    centre = np.array([(SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2])
    scale = 0.5 * np.hypot(*SIZE)
    q = (ideal - centre) / scale
    k1 = 0.0 if lens == "none" else K1
    return world, centre + scale * q * (1.0 + k1 * (q * q).sum(axis=1, keepdims=True))


def fitted_plane(lens: str) -> FittedPlane:
    """The model fitted to the scene's exact points."""
    return FittedPlane.fit(*scene(lens), lens, SIZE)


def calibration(lens: str) -> Calibration:
    """A calibration on the scene's exact points, with the lens model named."""
    size = (int(SIZE[0]), int(SIZE[1]))
    return Calibration(*scene(lens), lens=lens, image_size=size)  # type: ignore[arg-type]


def exact_mapping(plane: FittedPlane) -> Callable[[F64], F64]:
    """The exact path: Newton's method per point for the lens, then H^-1."""
    h_inv = np.linalg.inv(plane.homography)

    def undistort_then_map(px: F64) -> F64:
        v = np.c_[plane.lens.undistort(px, invalid="nan"), np.ones(len(px))] @ h_inv.T
        return np.asarray(v[:, :2] / v[:, 2:], dtype=np.float64)

    return undistort_then_map


def opencv_mapping(plane: FittedPlane) -> Callable[[F64], F64]:
    """The same mapping by OpenCV, on (N, 1, 2) float64 pixels."""
    h_inv = np.linalg.inv(plane.homography)
    (cx, cy), s, k1, k2 = plane.lens.centre_px, plane.lens.scale_px, plane.lens.k1, plane.lens.k2
    if k1 == 0.0 and k2 == 0.0:
        return lambda px: cv2.perspectiveTransform(px, h_inv)
    camera = np.array([[s, 0.0, cx], [0.0, s, cy], [0.0, 0.0, 1.0]])
    dist = np.array([k1, k2, 0.0, 0.0])

    def undistort_then_map(px: F64) -> F64:
        ideal = cv2.undistortPoints(px, camera, dist, P=camera)
        return cv2.perspectiveTransform(ideal, h_inv)

    return undistort_then_map


def time_calls(
    calls: dict[str, Callable[[], object]], samples: int, warmup: int
) -> dict[str, list[float]]:
    """Each call's duration (us), every contender timed once per round in a rotating order."""
    for call in calls.values():
        for _ in range(warmup):
            call()
    keys = list(calls)
    times: dict[str, list[float]] = {k: [] for k in keys}
    clock = time.perf_counter_ns
    gc.collect()
    gc.disable()
    try:
        for r in range(samples):
            shift = r % len(keys)
            for key in keys[shift:] + keys[:shift]:
                call = calls[key]
                t0 = clock()
                call()
                times[key].append((clock() - t0) / 1e3)
    finally:
        gc.enable()
    return times


def timer_cost_us() -> float:
    """What timing an empty call costs (included in every per-call time below)."""
    times = time_calls({"empty": lambda: None}, 20_000, 100)["empty"]
    return statistics.median(times)


def p99(values: list[float]) -> float:
    return float(np.percentile(values, 99))


def max_diff(a: Any, exact: F64) -> float:
    a = np.asarray(a).reshape(-1, 2)
    ok = np.isfinite(exact).all(axis=1)
    return float(np.abs(a[ok] - exact[ok]).max())


def us(v: float) -> str:
    return f"{v:.2f}" if v < 100 else f"{v:.0f}"


MAPPER = "image_to_world"
EXACT = "exact (Newton + H^-1)"
NEW_COPY = "numpy copy (px.copy())"


def bench_small(
    models: dict[str, tuple[FittedPlane, Calibration]], samples: int, rng: np.random.Generator
) -> tuple[list[list[str]], list[tuple[str, bool]]]:
    rows: list[list[str]] = []
    verdicts: list[tuple[str, bool]] = []
    for name, (plane, cal) in models.items():
        exact_map = exact_mapping(plane)
        cv_map = opencv_mapping(plane)
        cv_name = "cv2.perspectiveTransform" if name == "homography" else "cv2.undistortPoints+pT"
        for n in SMALL_SIZES:
            px = rng.uniform(0.0, 1.0, (n, 2)) * np.array(SIZE) - 0.5
            px_cv = px.reshape(-1, 1, 2)
            exact = exact_map(px)
            calls: dict[str, Callable[[], object]] = {
                MAPPER: lambda px=px, p=plane: p.image_to_world(px),
                "image_to_world_std": lambda px=px, p=plane: p.image_to_world_std(px),
                "Calibration.image_to_world": lambda px=px, c=cal: c.image_to_world(px),
                EXACT: lambda px=px, f=exact_map: f(px),
                cv_name: lambda px=px_cv, f=cv_map: f(px),
            }
            answers = {
                MAPPER: plane.image_to_world(px),
                "image_to_world_std": plane.image_to_world_std(px)[0],
                "Calibration.image_to_world": cal.image_to_world(px),
                EXACT: exact,
                cv_name: cv_map(px_cv),
            }
            times = time_calls(calls, samples, warmup=50)
            base = statistics.median(times[MAPPER])
            for key, values in times.items():
                med = statistics.median(values)
                rows.append(
                    [
                        name,
                        f"{n:,}",
                        key,
                        us(med),
                        us(p99(values)),
                        f"{med * 1e3 / n:.1f}",
                        f"{med / base:.2f}",
                        f"{max_diff(answers[key], exact):.1e}",
                    ]
                )
                if key == MAPPER:
                    verdicts.append(
                        (f"{name}, {n:,} points, {key}: {us(med)} us", med < CALL_TARGET_US)
                    )
    return rows, verdicts


def bench_large(
    models: dict[str, tuple[FittedPlane, Calibration]], samples: int, rng: np.random.Generator
) -> tuple[list[list[str]], list[tuple[str, bool]]]:
    n = LARGE_SIZE
    px = rng.uniform(0.0, 1.0, (n, 2)) * np.array(SIZE) - 0.5
    px_cv = px.reshape(-1, 1, 2)
    buffer = np.empty((n, 2))
    moved = 2 * px.nbytes
    rows: list[list[str]] = []
    verdicts: list[tuple[str, bool]] = []
    for name, (plane, _) in models.items():
        exact_map = exact_mapping(plane)
        cv_map = opencv_mapping(plane)
        cv_name = "cv2.perspectiveTransform" if name == "homography" else "cv2.undistortPoints+pT"
        exact = exact_map(px)
        calls: dict[str, Callable[[], object]] = {
            "numpy copy (np.copyto)": lambda: np.copyto(buffer, px),
            NEW_COPY: px.copy,
            MAPPER: lambda p=plane: p.image_to_world(px),
            cv_name: lambda f=cv_map: f(px_cv),
        }
        answers = {
            "numpy copy (np.copyto)": None,
            NEW_COPY: None,
            MAPPER: plane.image_to_world(px),
            cv_name: cv_map(px_cv),
        }
        times = {k: statistics.median(v) for k, v in time_calls(calls, samples, 3).items()}
        copy = times[NEW_COPY]
        for key, t in times.items():
            answer = answers[key]
            rows.append(
                [
                    name,
                    key,
                    f"{t / 1e3:.2f}",
                    f"{moved / (t * 1e-6) / 1e9:.1f}",
                    f"{t / copy:.2f}",
                    "-" if answer is None else f"{max_diff(answer, exact):.1e}",
                ]
            )
        ratio = times[MAPPER] / copy
        verdicts.append(
            (
                f"{name}, 10^6 points, {MAPPER}: {ratio:.2f} x the numpy copy (new array)",
                ratio <= COPY_RATIO_TARGET,
            )
        )
    return rows, verdicts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a smoke run, a few seconds")
    parser.add_argument("--markdown", action="store_true", help="tables as Markdown")
    args = parser.parse_args()
    small_samples, large_samples = (300, 5) if args.quick else (5_000, 31)
    rng = np.random.default_rng(20_260_512)
    models = {
        "homography": (fitted_plane("none"), calibration("none")),
        "lens k1": (fitted_plane("k1"), calibration("k1")),
    }

    out: list[str] = []
    out.append(
        f"CPU: {cpu_model()} ({os.cpu_count()} logical), Python {platform.python_version()}, "
        f"NumPy {np.__version__}, OpenCV {cv2.__version__}, "
        f"RAYON_NUM_THREADS={os.environ.get('RAYON_NUM_THREADS', 'unset')}"
    )
    out.append(f"Lens inverse: {models['lens k1'][0].lens_inverse}")
    out.append(f"Timer: an empty call times as {timer_cost_us() * 1e3:.0f} ns (included below)")
    out.append("")

    small, small_verdicts = bench_small(models, small_samples, rng)
    out.append(f"Per call (us; ratio: time / {MAPPER}; max |d|: against the exact path):")
    out += table_lines(
        ["model", "points", "contender", "median us", "p99 us", "ns/pt", "ratio", "max |d| mm"],
        [False, True, False, True, True, True, True, True],
        small,
        args.markdown,
    )
    out.append("")

    large, large_verdicts = bench_large(models, large_samples, rng)
    out.append(
        "10^6 points per call (16 MB read + 16 MB written; ratio: time / the numpy copy into a "
        "new array):"
    )
    out += table_lines(
        ["model", "contender", "ms", "GB/s", "ratio", "max |d| mm"],
        [False, False, True, True, True, True],
        large,
        args.markdown,
    )
    out.append("")
    out.append(f"Targets: under {CALL_TARGET_US:g} us a call (median), 10 to 1,000 points")
    out += [f"  {'PASS' if ok else 'FAIL'}  {what}" for what, ok in small_verdicts]
    out.append(
        f"Targets: 10^6 points within {COPY_RATIO_TARGET:g}x of the time of the numpy copy "
        "into a new array"
    )
    out += [f"  {'PASS' if ok else 'FAIL'}  {what}" for what, ok in large_verdicts]
    out.append(f"Load: {load_average()}")
    print("\n".join(out))


if __name__ == "__main__":
    main()
