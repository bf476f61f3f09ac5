"""Benchmark planarcal against OpenCV, side by side in one process.

What it measures (every time is the median over repeats; in each repeat the contenders run
interleaved, in a rotating order, so that drift on a shared machine hits them all alike; small
problems are timed as loops of many calls per sample, after a warm-up, with the garbage
collector off):

1. Estimation on 140 points (a 14 x 10 grid, 20 mm pitch, mapped by a fixed homography plus
   Gaussian pixel noise, sigma 0.4 px): ``cv2.findHomography(src, dst, 0)`` against
   ``planarcal.estimate_homography`` (normalised DLT), the same with ``refine=True``
   (Levenberg-Marquardt) and the drop-in ``planarcal.findHomography``.
2. Point transforms of 140, 10 000 and 1 000 000 points: ``cv2.perspectiveTransform`` against
   the drop-in ``planarcal.perspectiveTransform`` (same (N, 1, 2) input, float64 and float32)
   and ``planarcal.transform_points`` on the (N, 2) view of the same float64 points.
3. Per-call overhead: time(N) = a + b * N fitted by least squares over N in
   ``OVERHEAD_SIZES``; the intercept a is what one Python -> Rust call costs beyond the work.
4. Accuracy, as a side note: mean reprojection error on the noisy 140-point problem, and the
   max reprojection error on a noise-free problem whose image points sit near 1e6 px (OpenCV
   fits in float32 there; planarcal in float64).

Ratios are OpenCV time / planarcal time (OpenCV error / planarcal error for the accuracy
rows): above 1 means planarcal is faster (more accurate). Targets are reported as PASS/FAIL;
the script never fails on them (exit status 0).

Run from the repository root::

    python benches/bench_core.py             # full run, about a minute
    python benches/bench_core.py --quick     # smoke run, a few seconds
    python benches/bench_core.py --markdown  # as Markdown, for docs/benchmarks/speed.md

Set ``RAYON_NUM_THREADS`` to limit the threads planarcal uses for large batches.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import os
import platform
import statistics
import sys
import time
import timeit
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from reporting import cpu_model, load_average, table_lines

import planarcal as pc

Array = NDArray[Any]

# The homography of the calibration problem: grid millimetres -> image pixels.
H_TRUE = np.array(
    [
        [1.878, -0.0429, 195.67],
        [0.00277, 1.8507, 144.23],
        [-1.9e-5, -5.66e-5, 1.0],
    ]
)
GRID_COLS, GRID_ROWS, PITCH_MM = 14, 10, 20.0
NOISE_PX = 0.4
SEED = 20_251_121
IMAGE_SIZE = (1280.0, 1024.0)  # the range of the points fed to the transforms, in px

TRANSFORM_SIZES = (140, 10_000, 1_000_000)
OVERHEAD_SIZES = (4, 16, 64, 140, 256, 512, 1024)  # must hold 140: its plain time is reported

ESTIMATE_SPEEDUP_TARGET = 20.0
REFINE_SPEEDUP_TARGET = 1.0
TRANSFORM_SPEEDUP_TARGET = 1.0
LARGE_TRANSFORM_SPEEDUP_TARGET = 1.5  # at 10^6 points, where planarcal uses all cores
OVERHEAD_TARGET_US = 2.0


@dataclasses.dataclass(frozen=True)
class Settings:
    """How long and how often each contender is timed."""

    name: str
    repeats: int
    """Samples per contender; the reported time is their median."""
    sample_ms: float
    """Target duration of one sample (a loop of calls), which sets the loop count."""
    warmup_calls: int


FULL = Settings("full", repeats=101, sample_ms=15.0, warmup_calls=20)
QUICK = Settings("quick", repeats=15, sample_ms=3.0, warmup_calls=3)


@dataclasses.dataclass(frozen=True)
class Row:
    """One line of the result table."""

    operation: str
    opencv: float
    planarcal: float
    unit: str = "us"
    target: str = "-"
    passed: bool | None = None

    @property
    def ratio(self) -> float | None:
        """OpenCV / planarcal; None when it has no meaning (a non-positive value)."""
        if self.opencv <= 0 or self.planarcal <= 0:
            return None
        return self.opencv / self.planarcal


# --------------------------------------------------------------------------------------------
# Timing


def time_interleaved(
    statements: Mapping[str, str], namespace: dict[str, Any], settings: Settings
) -> dict[str, float]:
    """Median time per call, in microseconds, of each statement (keyed as given).

    Each statement is compiled by ``timeit`` into a bare loop, so the harness adds only the
    loop's own ~10 ns per call. Every repeat times every statement once, in an order rotated
    by one at each repeat.
    """
    timers = {
        key: timeit.Timer(stmt, timer=time.perf_counter_ns, globals=namespace)
        for key, stmt in statements.items()
    }
    for t in timers.values():
        t.timeit(settings.warmup_calls)
    loops = {key: _loops_for(t, settings.sample_ms * 1e6) for key, t in timers.items()}

    keys = list(timers)
    samples: dict[str, list[float]] = {key: [] for key in keys}
    gc.collect()
    gc.disable()
    try:
        for r in range(settings.repeats):
            shift = r % len(keys)
            for key in keys[shift:] + keys[:shift]:
                elapsed_ns = timers[key].timeit(loops[key])
                samples[key].append(elapsed_ns / loops[key] / 1e3)
    finally:
        gc.enable()
    return {key: statistics.median(values) for key, values in samples.items()}


def _loops_for(timer: timeit.Timer, sample_ns: float) -> int:
    """The number of calls that takes about ``sample_ns``."""
    loops = 1
    while True:
        elapsed = max(float(timer.timeit(loops)), 1.0)
        if elapsed >= sample_ns / 8 or loops >= 1 << 20:
            return max(1, round(loops * sample_ns / elapsed))
        loops *= 4


# --------------------------------------------------------------------------------------------
# Problems


def grid_problem(rng: np.random.Generator, noise_px: float = NOISE_PX) -> tuple[Array, Array]:
    """The 14 x 10 calibration grid (mm) and its noisy image (px), both (140, 2) float64."""
    xs, ys = np.meshgrid(np.arange(GRID_COLS) * PITCH_MM, np.arange(GRID_ROWS) * PITCH_MM)
    src = np.column_stack([xs.ravel(), ys.ravel()])
    dst = pc.transform_points(H_TRUE, src) + rng.normal(0.0, noise_px, src.shape)
    return src, dst


def random_problem(rng: np.random.Generator, n: int) -> tuple[Array, Array]:
    """n random plane points (mm) in the grid's extent and their noisy image (px)."""
    extent = np.array([(GRID_COLS - 1) * PITCH_MM, (GRID_ROWS - 1) * PITCH_MM])
    src = rng.uniform(0.0, 1.0, (n, 2)) * extent
    dst = pc.transform_points(H_TRUE, src) + rng.normal(0.0, NOISE_PX, src.shape)
    return src, dst


def image_points(rng: np.random.Generator, n: int) -> Array:
    """n points spread over the image, shape (n, 1, 2) float64, as cv2 wants them."""
    points: Array = rng.uniform(0.0, 1.0, (n, 1, 2)) * np.array(IMAGE_SIZE)
    return points


def _warn_unless_close(what: str, a: Array | None, b: Array | None, rtol: float) -> None:
    """Benchmarks of different answers mean nothing: say so (without failing the run)."""
    if a is None or b is None or not np.allclose(a, b, rtol=rtol, atol=0.0):
        print(f"WARNING: {what}: planarcal and OpenCV disagree", file=sys.stderr)


# --------------------------------------------------------------------------------------------
# Sections


def bench_estimation(settings: Settings, src: Array, dst: Array) -> list[Row]:
    """Section 1: fitting H to the 140 noisy grid points."""
    ns = {"cv2": cv2, "pc": pc, "src": src, "dst": dst}
    H_cv, _ = cv2.findHomography(src, dst, 0)
    _warn_unless_close("findHomography", pc.findHomography(src, dst)[0], H_cv, rtol=1e-3)

    t = time_interleaved(
        {
            "opencv": "cv2.findHomography(src, dst, 0)",
            "dlt": "pc.estimate_homography(src, dst)",
            "refine": "pc.estimate_homography(src, dst, refine=True)",
            "dropin": "pc.findHomography(src, dst)",
        },
        ns,
        settings,
    )
    n = len(src)
    return [
        _speedup_target(
            Row(
                f"estimate_homography, {n} pts (vs findHomography method=0)", t["opencv"], t["dlt"]
            ),
            ESTIMATE_SPEEDUP_TARGET,
            strict=False,
        ),
        _speedup_target(
            Row(f"estimate_homography(refine=True), {n} pts", t["opencv"], t["refine"]),
            REFINE_SPEEDUP_TARGET,
            strict=True,
        ),
        Row(f"findHomography drop-in, {n} pts", t["opencv"], t["dropin"]),
    ]


def bench_transforms(settings: Settings, rng: np.random.Generator) -> list[Row]:
    """Section 2: mapping points through H, float64 and float32, at each size.

    Each size is timed as its own interleaved group, so that the 10^6-point calls (which
    flush the caches) do not land between the small ones.
    """
    rows = []
    for n in TRANSFORM_SIZES:
        p64 = image_points(rng, n)
        p32 = p64.astype(np.float32)
        ns = {"cv2": cv2, "pc": pc, "H": H_TRUE, "p64": p64, "q64": p64.reshape(n, 2), "p32": p32}
        expected = cv2.perspectiveTransform(p64, H_TRUE).reshape(n, 2)
        _warn_unless_close(
            f"f64 transform, N={n}", pc.transform_points(H_TRUE, p64), expected, 1e-12
        )
        _warn_unless_close(
            f"f32 transform, N={n}",
            pc.perspectiveTransform(p32, H_TRUE),
            cv2.perspectiveTransform(p32, H_TRUE),
            1e-6,
        )
        t = time_interleaved(
            {
                "cv64": "cv2.perspectiveTransform(p64, H)",
                "pt64": "pc.perspectiveTransform(p64, H)",
                "tp64": "pc.transform_points(H, q64)",
                "cv32": "cv2.perspectiveTransform(p32, H)",
                "pt32": "pc.perspectiveTransform(p32, H)",
            },
            ns,
            settings,
        )
        target = LARGE_TRANSFORM_SPEEDUP_TARGET if n >= 1_000_000 else TRANSFORM_SPEEDUP_TARGET
        size = f"N={n:,}"
        for row in (
            Row(f"perspectiveTransform drop-in, f64, {size}", t["cv64"], t["pt64"]),
            Row(f"transform_points (N,2), f64, {size}", t["cv64"], t["tp64"]),
            Row(f"perspectiveTransform drop-in, f32, {size}", t["cv32"], t["pt32"]),
        ):
            rows.append(_speedup_target(row, target, strict=False))
    return rows


def bench_overhead(settings: Settings, rng: np.random.Generator) -> list[Row]:
    """Section 3: per-call overhead, the intercept of time(N) = a + b * N."""
    statements: dict[str, str] = {}
    ns: dict[str, Any] = {"cv2": cv2, "pc": pc, "H": H_TRUE}
    for n in OVERHEAD_SIZES:
        src, dst = random_problem(rng, n)
        pts = image_points(rng, n)
        ns |= {f"src_{n}": src, f"dst_{n}": dst, f"p_{n}": pts, f"q_{n}": pts.reshape(n, 2)}
        statements |= {
            f"cvpt_{n}": f"cv2.perspectiveTransform(p_{n}, H)",
            f"tp_{n}": f"pc.transform_points(H, q_{n})",
            f"cvfh_{n}": f"cv2.findHomography(src_{n}, dst_{n}, 0)",
            f"est_{n}": f"pc.estimate_homography(src_{n}, dst_{n})",
        }
    t = time_interleaved(statements, ns, settings)

    def intercept(prefix: str) -> float:
        sizes = np.array(OVERHEAD_SIZES, dtype=float)
        times = np.array([t[f"{prefix}_{n}"] for n in OVERHEAD_SIZES])
        a, _b = np.polynomial.polynomial.polyfit(sizes, times, 1)
        return float(a)

    def overhead_row(what: str, opencv: float, planarcal: float) -> Row:
        return Row(
            f"per-call overhead: {what} (fit a + b*N)",
            opencv,
            planarcal,
            target=f"< {OVERHEAD_TARGET_US:g} us",
            passed=planarcal < OVERHEAD_TARGET_US,
        )

    # The intercept of estimate_homography also holds the fixed work of a fit (normalisation,
    # the 9 x 9 eigenproblem), not only the cost of crossing from Python into Rust.
    return [
        overhead_row("transform_points", intercept("cvpt"), intercept("tp")),
        overhead_row("estimate_homography", intercept("cvfh"), intercept("est")),
        Row("transform_points, 140 pts, plain call", t["cvpt_140"], t["tp_140"]),
    ]


def accuracy(src: Array, dst: Array) -> list[Row]:
    """Section 4: reprojection errors of the fitted matrices (px), for the record."""

    def mean_error(H: Array) -> float:
        return float(pc.reprojection_errors(H, src, dst).mean())

    H_cv, _ = cv2.findHomography(src, dst, 0)
    rows = [
        Row(
            f"mean reproj. error, {len(src)} pts noisy: estimate_homography",
            mean_error(H_cv),
            mean_error(pc.estimate_homography(src, dst)),
            unit="px",
        ),
        Row(
            f"mean reproj. error, {len(src)} pts noisy: estimate_homography(refine=True)",
            mean_error(H_cv),
            mean_error(pc.estimate_homography(src, dst, refine=True)),
            unit="px",
        ),
    ]

    # Noise-free, image points around (1e6, 1e6) px spread over about 1000 px.
    to_far = np.array([[2.0, 0.0, 1e6], [0.0, 2.0, 1e6], [0.0, 0.0, 1.0]])
    far = pc.transform_points(to_far @ H_TRUE, src)
    H_cv_far, _ = cv2.findHomography(src, far, 0)
    H_pc_far, _ = pc.findHomography(src, far)
    assert H_pc_far is not None, "planarcal.findHomography failed on a noise-free problem"
    rows.append(
        Row(
            "max reproj. error, noise-free, offset 1e6 px: findHomography",
            float(pc.reprojection_errors(H_cv_far, src, far).max()),
            float(pc.reprojection_errors(H_pc_far, src, far).max()),
            unit="px",
        )
    )
    return rows


def _speedup_target(row: Row, target: float, *, strict: bool) -> Row:
    """The row with a target on its ratio: >= target, or > target when strict."""
    ratio = row.ratio
    passed = ratio is not None and (ratio > target if strict else ratio >= target)
    label = f"{'>' if strict else '>='} {target:g}x"
    return dataclasses.replace(row, target=label, passed=passed)


# --------------------------------------------------------------------------------------------
# Report


def environment(settings: Settings) -> list[tuple[str, str]]:
    """What the numbers were measured with."""
    return [
        ("planarcal", pc.__version__),
        ("OpenCV", f"{cv2.__version__} (cv2.getNumThreads() = {cv2.getNumThreads()})"),
        ("numpy", np.__version__),
        ("Python", f"{platform.python_version()} ({platform.python_implementation()})"),
        ("CPU", f"{cpu_model()}, os.cpu_count() = {os.cpu_count()}"),
        ("RAYON_NUM_THREADS", os.environ.get("RAYON_NUM_THREADS", "unset")),
        ("load average", load_average()),
        (
            "mode",
            f"{settings.name}: median of {settings.repeats} interleaved samples of "
            f"~{settings.sample_ms:g} ms each",
        ),
    ]


def format_value(value: float, unit: str) -> str:
    if unit == "px":
        return f"{value:.4g} px"
    magnitude = abs(value)
    if magnitude >= 100:
        return f"{value:,.0f}"
    if magnitude >= 10:
        return f"{value:.1f}"
    if magnitude >= 1:
        return f"{value:.2f}"
    return f"{value:.3f}"


def format_ratio(ratio: float | None) -> str:
    if ratio is None:
        return "n/a"
    if ratio >= 1000:
        return f"{ratio:.2g}x"
    if ratio >= 100:
        return f"{ratio:.0f}x"
    return f"{ratio:.2f}x"


HEADERS = ("operation", "OpenCV (us)", "planarcal (us)", "ratio", "target", "PASS/FAIL")
RIGHT_ALIGNED = (False, True, True, True, False, False)


def table_cells(rows: Sequence[Row]) -> list[tuple[str, ...]]:
    return [
        (
            r.operation,
            format_value(r.opencv, r.unit),
            format_value(r.planarcal, r.unit),
            format_ratio(r.ratio),
            r.target,
            "" if r.passed is None else ("PASS" if r.passed else "FAIL"),
        )
        for r in rows
    ]


def print_report(
    env: Sequence[tuple[str, str]], rows: Sequence[Row], elapsed_s: float, markdown: bool
) -> None:
    cells = table_cells(rows)
    failures = sum(r.passed is False for r in rows)
    summary = (
        f"{sum(r.passed is not None for r in rows) - failures} targets passed, "
        f"{failures} failed; ratio = OpenCV / planarcal (> 1: planarcal faster or more "
        f"accurate); total {elapsed_s:.0f} s"
    )
    if markdown:
        for key, value in env:
            print(f"- {key}: {value}")
        print()
        print("\n".join(table_lines(HEADERS, RIGHT_ALIGNED, cells, markdown=True)))
        print()
        print(summary)
        return

    width = max(len(key) for key, _ in env)
    for key, value in env:
        print(f"{key:<{width}} : {value}")
    print()
    print("\n".join(table_lines(HEADERS, RIGHT_ALIGNED, cells, markdown=False)))
    print()
    print(summary)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a fast smoke run (a few seconds)")
    parser.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    args = parser.parse_args(argv)
    settings = QUICK if args.quick else FULL

    start = time.perf_counter()
    rng = np.random.default_rng(SEED)
    src, dst = grid_problem(rng)
    sections: list[tuple[str, Callable[[], list[Row]]]] = [
        ("estimation", lambda: bench_estimation(settings, src, dst)),
        ("point transforms", lambda: bench_transforms(settings, rng)),
        ("per-call overhead", lambda: bench_overhead(settings, rng)),
        ("accuracy", lambda: accuracy(src, dst)),
    ]
    rows: list[Row] = []
    for title, run in sections:
        print(f"[{time.perf_counter() - start:5.1f} s] {title} ...", file=sys.stderr, flush=True)
        rows += run()

    print_report(environment(settings), rows, time.perf_counter() - start, args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
