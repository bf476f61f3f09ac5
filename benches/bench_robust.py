"""Benchmark planarcal's robust homography estimation against OpenCV's robust flags.

Every contender runs in the same process, on the same correspondences (float64 (N, 2)
arrays), with the same options: inlier threshold 3 px, confidence 0.999, at most 10,000
samples. The contenders are ``planarcal.estimate_homography_robust`` (seed = trial number),
the drop-in ``planarcal.findHomography(..., planarcal.RANSAC, ...)``, and
``cv2.findHomography`` with each of RANSAC, RHO, USAC_DEFAULT, USAC_FAST, USAC_ACCURATE,
USAC_MAGSAC and USAC_PARALLEL (LMEDS too, but only where outliers are under 50%: least median
of squares breaks down at 50%). In each trial every contender is timed the same number of
times (the trial's time is the median of those calls), interleaved in an order shuffled
afresh for every round of calls (seeded), so that drift on a shared machine hits all alike
and no contender always runs first or always right after the same other one (a fixed
rotation would keep each one's predecessor), with the garbage collector off. Each call is
timed on its own: a single cold call, as in a program that does other work between fits,
not a warm loop. The reported time is the median over trials.

Synthetic problems: source points uniform over a 1280 x 720 image; a random plausible
homography about the image centre (rotation within +-30 deg, scale 0.8-1.2, translation up
to 100 x 60 px, perspective terms up to 1e-4 / px); destination = H src + Gaussian noise,
sigma 0.5 px; then the outliers' destinations are replaced by points uniform over the image.

  (a) 1,000 points, 50% outliers. Targets: planarcal's median time at most half the fastest
      OpenCV flag's; its median error no worse than the most accurate flag's.
  (b) 1,000 points, 80% outliers. Targets: median time under 1 ms; error as in (a).
  (c) 5,000 points, 90% outliers. Targets: success in every one of 100 trials; median time
      under 10 ms.

"Error" is the error to the truth: per trial, the mean distance between H_est(p) and
H_true(p) over the true inliers' source points p. A trial fails when no H is returned or
the error exceeds 5 px. "No worse than the most accurate flag" compares planarcal's median
error with the smallest median error of any OpenCV flag, with 1% slack. The gold standard
(``planarcal.estimate_homography(src[inliers], dst[inliers], refine=True)``, knowing the
inliers) is printed as a reference row: no robust method should beat it by much. The batch
row times ``estimate_homography_robust_batch`` on all the scenario's problems in one call
(divided by their number; not interleaved: one call per repeat, after the trials).

(d) Real correspondences, no targets: the six photographs of a 10 x 8 circle-grid board in
``../shared/data/real/boofcv-circle-regular`` (or ``$PLANARCAL_SHARED/data/real/...``;
skipped with a note when absent). The board is detected in each (``planarcal.detect_board``);
the ground truth of the pair (i, j) is the homography fitted to the dot centres, centre k of
image i to centre k of image j (``estimate_homography(..., refine=True)``). For each of the
15 unordered pairs, SIFT features (then ORB, as a second table) are matched with Lowe's ratio
test at 0.8; every contender fits those matches, and its error is the mean distance between
H_est(c_i) and c_j over the 80 dot centres. A pair fails when no H is returned or the error
exceeds 10 px. Extra rows here: planarcal with ``scores`` = 1 - d1/d2 (the ratio-test margin;
PROSAC order) and its OpenCV counterpart USAC_PROSAC on the matches sorted by that margin.
The dots all look alike, so most ratio-test survivors are wrong or lie off the board's plane
(carpet, clip): a hard outlier structure. The per-pair table says how many matches agree with
the truth (within 3 px), which bounds what any estimator can do.

Ratios are contender time / planarcal time: above 1, planarcal is faster. Targets are
reported as PASS/FAIL; the script never fails on them (exit status 0). An exception raised by
planarcal is not caught: it is a bug to report. A ``cv2.error`` counts as that flag's failure.

Run from the repository root::

    python benches/bench_robust.py             # full run, about 2-3 minutes
    python benches/bench_robust.py --quick     # smoke run, a few seconds
    python benches/bench_robust.py --markdown  # as Markdown, for docs/benchmarks/robust.md

Set ``RAYON_NUM_THREADS`` to limit the threads planarcal uses.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import gc
import hashlib
import math
import os
import platform
import random
import statistics
import sys
import time
from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray
from reporting import cpu_model, load_average, table_lines

import planarcal as pc

Array = NDArray[np.float64]
Homography = Array | None
"""A 3 x 3 estimate, or None when the contender found none."""

# What every contender is asked for.
THRESHOLD_PX = 3.0
CONFIDENCE = 0.999
MAX_ITERS = 10_000

# The synthetic problems.
IMAGE_WIDTH, IMAGE_HEIGHT = 1280.0, 720.0
NOISE_SIGMA_PX = 0.5
MAX_ROTATION_RAD = math.radians(30.0)
SCALE_RANGE = (0.8, 1.2)
MAX_TRANSLATION_PX = (100.0, 60.0)
MAX_PERSPECTIVE_PER_PX = 1e-4
SEED = 20_251_122

# How results are judged.
SYNTHETIC_FAILURE_PX = 5.0
REAL_FAILURE_PX = 10.0
ERROR_SLACK = 1.01
"""planarcal's median error may exceed the most accurate flag's by this factor (1%)."""
LMEDS_MAX_OUTLIER_FRACTION = 0.5
"""LMEDS runs only where the outlier fraction is strictly below this (its breakdown point)."""

OPENCV_FLAGS = (
    "RANSAC",
    "RHO",
    "USAC_DEFAULT",
    "USAC_FAST",
    "USAC_ACCURATE",
    "USAC_MAGSAC",
    "USAC_PARALLEL",
)

# The real photographs.
REAL_FOLDER = Path("data") / "real" / "boofcv-circle-regular"
REAL_IMAGES = tuple(f"image0000{i}.jpg" for i in range(6))
REAL_BOARD = pc.CircleGridBoard(cols=10, rows=8, pitch=25.0, diameter=15.0)
LOWE_RATIO = 0.8
ON_TRUTH_PX = 3.0
"""A real match "agrees with the truth" when the ground-truth H maps it within this."""
ORB_FEATURES = 2000


@dataclasses.dataclass(frozen=True)
class Settings:
    """How many trials, and how many timed calls per contender in each."""

    name: str
    trials: dict[str, int]
    """Trials per synthetic scenario, by key."""
    calls_per_trial: int
    calls_per_real_pair: int
    batch_repeats: int


FULL = Settings(
    "full",
    trials={"a": 100, "b": 100, "c": 100},
    calls_per_trial=3,
    calls_per_real_pair=5,
    batch_repeats=3,
)
QUICK = Settings(
    "quick",
    trials={"a": 10, "b": 10, "c": 4},
    calls_per_trial=1,
    calls_per_real_pair=1,
    batch_repeats=1,
)


@dataclasses.dataclass(frozen=True)
class Scenario:
    """One synthetic problem family and its targets."""

    key: str
    n_points: int
    outlier_fraction: float
    min_speedup_vs_fastest_flag: float | None = None
    max_median_ms: float | None = None
    error_no_worse_than_best_flag: bool = False
    must_always_succeed: bool = False

    @property
    def title(self) -> str:
        return (
            f"({self.key}) {self.n_points:,} points, {self.outlier_fraction:.0%} outliers, "
            f"noise sigma {NOISE_SIGMA_PX:g} px"
        )


SCENARIOS = (
    Scenario("a", 1_000, 0.5, min_speedup_vs_fastest_flag=2.0, error_no_worse_than_best_flag=True),
    Scenario("b", 1_000, 0.8, max_median_ms=1.0, error_no_worse_than_best_flag=True),
    Scenario("c", 5_000, 0.9, max_median_ms=10.0, must_always_succeed=True),
)


@dataclasses.dataclass(frozen=True)
class Problem:
    """Correspondences src[k] -> dst[k] to fit, and what is known about them."""

    src: Array
    dst: Array
    scores: Array | None = None
    """Match quality, higher is better (real matches only)."""


@dataclasses.dataclass(frozen=True)
class Contender:
    """Something that fits a homography to a problem; ``seed`` is the trial number."""

    name: str
    estimate: Callable[[Problem, int], Homography]


@dataclasses.dataclass
class Tally:
    """A contender's results over all trials (or pairs) of one scenario."""

    name: str
    times_ms: list[float] = dataclasses.field(default_factory=list)
    errors_px: list[float] = dataclasses.field(default_factory=list)
    """Per trial; inf where no H was returned."""
    timed: bool = True

    def add(self, error_px: float, time_ms: float | None = None) -> None:
        self.errors_px.append(error_px)
        if time_ms is not None:
            self.times_ms.append(time_ms)

    @property
    def median_time_ms(self) -> float:
        return statistics.median(self.times_ms) if self.times_ms else math.nan

    @property
    def median_error_px(self) -> float:
        return statistics.median(self.errors_px)

    @property
    def max_error_px(self) -> float:
        return max(self.errors_px)

    @property
    def n_none(self) -> int:
        return sum(math.isinf(e) for e in self.errors_px)

    def n_failures(self, failure_px: float) -> int:
        return sum(not e <= failure_px for e in self.errors_px)


@dataclasses.dataclass(frozen=True)
class Target:
    description: str
    measured: str
    passed: bool


@dataclasses.dataclass(frozen=True)
class Table:
    headers: tuple[str, ...]
    right_aligned: tuple[bool, ...]
    rows: list[tuple[str, ...]]


@dataclasses.dataclass
class Section:
    """One titled block of the report: tables and notes."""

    title: str
    tables: list[Table] = dataclasses.field(default_factory=list)
    notes: list[str] = dataclasses.field(default_factory=list)
    targets: list[Target] = dataclasses.field(default_factory=list)


# --------------------------------------------------------------------------------------------
# Contenders


def planarcal_robust(
    problem: Problem, seed: int, with_scores: bool = False, max_iters: int = MAX_ITERS
) -> Homography:
    return pc.estimate_homography_robust(
        problem.src,
        problem.dst,
        threshold=THRESHOLD_PX,
        confidence=CONFIDENCE,
        max_iters=max_iters,
        seed=seed,
        scores=problem.scores if with_scores else None,
    ).H


def planarcal_robust_with_scores(problem: Problem, seed: int) -> Homography:
    return planarcal_robust(problem, seed, with_scores=True)


def planarcal_drop_in(problem: Problem, seed: int) -> Homography:
    H, _mask = pc.findHomography(
        problem.src,
        problem.dst,
        pc.RANSAC,
        ransacReprojThreshold=THRESHOLD_PX,
        maxIters=MAX_ITERS,
        confidence=CONFIDENCE,
    )
    return H


def opencv_find_homography(src: Array, dst: Array, flag: int) -> Homography:
    """cv2.findHomography with the common options; None on failure (or a cv2.error)."""
    try:
        H, _mask = cv2.findHomography(
            src,
            dst,
            method=flag,
            ransacReprojThreshold=THRESHOLD_PX,
            maxIters=MAX_ITERS,
            confidence=CONFIDENCE,
        )
    except cv2.error:
        return None
    if H is None or np.size(H) != 9:
        return None
    return np.asarray(H, dtype=np.float64)


def opencv_contender(flag_name: str) -> Contender:
    flag = int(getattr(cv2, flag_name))

    def estimate(problem: Problem, seed: int) -> Homography:
        return opencv_find_homography(problem.src, problem.dst, flag)

    return Contender(f"cv2 {flag_name}", estimate)


def opencv_prosac(problem: Problem, seed: int) -> Homography:
    """USAC_PROSAC takes the matches ordered best first: sort them by score."""
    assert problem.scores is not None
    best_first = np.argsort(-problem.scores, kind="stable")
    return opencv_find_homography(
        problem.src[best_first], problem.dst[best_first], int(cv2.USAC_PROSAC)
    )


PLANARCAL = Contender("planarcal estimate_homography_robust", planarcal_robust)
PLANARCAL_WITH_SCORES = Contender(
    "planarcal estimate_homography_robust, scores (PROSAC)", planarcal_robust_with_scores
)
PLANARCAL_DROP_IN = Contender("planarcal.findHomography(RANSAC) drop-in", planarcal_drop_in)


def opencv_contenders(include_lmeds: bool) -> list[Contender]:
    names = [*OPENCV_FLAGS, "LMEDS"] if include_lmeds else list(OPENCV_FLAGS)
    return [opencv_contender(name) for name in names]


# --------------------------------------------------------------------------------------------
# Timing and errors


def time_contenders(
    contenders: Sequence[Contender], problem: Problem, seed: int, calls: int
) -> tuple[dict[str, float], dict[str, Homography]]:
    """Each contender's median time (ms) over ``calls`` interleaved calls, and its estimate.

    The order is shuffled afresh (seeded by ``seed``) for each round of calls, so that drift
    hits all contenders alike and none is always run first (cold caches, sleeping threads)
    or always right after the same other one. A fixed rotation would keep each contender's
    predecessor: the drop-in would nearly always follow the native call on the same data.
    """
    order_rng = random.Random(f"{SEED}-{seed}")
    samples: dict[str, list[float]] = {c.name: [] for c in contenders}
    estimates: dict[str, Homography] = {}
    gc.disable()
    try:
        for _call in range(calls):
            for contender in order_rng.sample(list(contenders), len(contenders)):
                start = time.perf_counter_ns()
                H = contender.estimate(problem, seed)
                elapsed_ns = time.perf_counter_ns() - start
                samples[contender.name].append(elapsed_ns / 1e6)
                estimates.setdefault(contender.name, H)
    finally:
        gc.enable()
    return {name: statistics.median(values) for name, values in samples.items()}, estimates


def project(H: Array, points: Array) -> Array:
    """H applied to (N, 2) points; rows of points at infinity come out inf or nan."""
    homogeneous = points @ H[:, :2].T + H[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        projected: Array = homogeneous[:, :2] / homogeneous[:, 2:]
    return projected


def mean_distance(H: Homography, points: Array, expected: Array) -> float:
    """Mean distance between H(points) and expected (inf without H, or if any is not finite)."""
    if H is None:
        return math.inf
    distances = np.linalg.norm(project(H, points) - expected, axis=1)
    mean = float(distances.mean())
    return mean if math.isfinite(mean) else math.inf


# --------------------------------------------------------------------------------------------
# Synthetic problems


def random_homography(rng: np.random.Generator) -> Array:
    """A plausible camera-to-camera homography about the image centre."""
    centre = np.array([IMAGE_WIDTH / 2, IMAGE_HEIGHT / 2])
    angle = rng.uniform(-MAX_ROTATION_RAD, MAX_ROTATION_RAD)
    scale = rng.uniform(*SCALE_RANGE)
    shift = rng.uniform(-1.0, 1.0, 2) * np.array(MAX_TRANSLATION_PX)
    perspective = rng.uniform(-1.0, 1.0, 2) * MAX_PERSPECTIVE_PER_PX

    def translation(offset: Array) -> Array:
        return np.array([[1.0, 0.0, offset[0]], [0.0, 1.0, offset[1]], [0.0, 0.0, 1.0]])

    cos, sin = scale * math.cos(angle), scale * math.sin(angle)
    similarity = np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [perspective[0], perspective[1], 1.0]])
    H: Array = translation(centre + shift) @ similarity @ tilt @ translation(-centre)
    normalised: Array = H / H[2, 2]
    return normalised


@dataclasses.dataclass(frozen=True)
class SyntheticTrial:
    problem: Problem
    true_homography: Array
    is_inlier: NDArray[np.bool_]


def synthetic_trial(scenario: Scenario, trial: int) -> SyntheticTrial:
    """Trial ``trial`` of the scenario: the same on every run."""
    rng = np.random.default_rng((SEED, ord(scenario.key), trial))
    n = scenario.n_points
    image_size = np.array([IMAGE_WIDTH, IMAGE_HEIGHT])
    H = random_homography(rng)
    src = rng.uniform(0.0, 1.0, (n, 2)) * image_size
    dst = project(H, src) + rng.normal(0.0, NOISE_SIGMA_PX, (n, 2))
    n_outliers = round(scenario.outlier_fraction * n)
    outliers = rng.permutation(n)[:n_outliers]
    dst[outliers] = rng.uniform(0.0, 1.0, (n_outliers, 2)) * image_size
    is_inlier = np.ones(n, dtype=bool)
    is_inlier[outliers] = False
    return SyntheticTrial(Problem(src, dst), H, is_inlier)


def bench_scenario(scenario: Scenario, settings: Settings) -> Section:
    """Run every contender on every trial of the scenario; the section of the report."""
    n_trials = settings.trials[scenario.key]
    include_lmeds = scenario.outlier_fraction < LMEDS_MAX_OUTLIER_FRACTION
    flags = opencv_contenders(include_lmeds)
    contenders = [PLANARCAL, PLANARCAL_DROP_IN, *flags]
    tallies = {c.name: Tally(c.name) for c in contenders}
    batch_name = "planarcal estimate_homography_robust_batch (per problem)"
    gold_name = "reference: gold standard on the true inliers"
    tallies[batch_name] = Tally(batch_name)
    tallies[gold_name] = Tally(gold_name, timed=False)
    iterations: list[int] = []
    stop_reasons: Counter[str] = Counter()

    warm_up = synthetic_trial(scenario, n_trials)  # not one of the trials
    for contender in contenders:
        contender.estimate(warm_up.problem, 0)

    trials = [synthetic_trial(scenario, trial) for trial in range(n_trials)]
    for trial_number, trial in enumerate(trials):
        times, estimates = time_contenders(
            contenders, trial.problem, trial_number, settings.calls_per_trial
        )
        inlier_src = trial.problem.src[trial.is_inlier]
        truth = project(trial.true_homography, inlier_src)
        for contender in contenders:
            error = mean_distance(estimates[contender.name], inlier_src, truth)
            tallies[contender.name].add(error, times[contender.name])
        gold = pc.estimate_homography(inlier_src, trial.problem.dst[trial.is_inlier], refine=True)
        tallies[gold_name].add(mean_distance(gold, inlier_src, truth))
        result = pc.estimate_homography_robust(
            trial.problem.src,
            trial.problem.dst,
            threshold=THRESHOLD_PX,
            confidence=CONFIDENCE,
            max_iters=MAX_ITERS,
            seed=trial_number,
        )
        iterations.append(result.iterations)
        stop_reasons[result.stop_reason] += 1

    # The batch: all problems in one call (the same seed for each, as the API takes one).
    pairs = [(t.problem.src, t.problem.dst) for t in trials]
    batch_times: list[float] = []
    batch_results: list[pc.RobustResult] = []
    for _ in range(settings.batch_repeats):
        gc.disable()
        try:
            start = time.perf_counter_ns()
            batch_results = pc.estimate_homography_robust_batch(
                pairs, THRESHOLD_PX, CONFIDENCE, MAX_ITERS, seed=0
            )
            batch_times.append((time.perf_counter_ns() - start) / 1e6 / len(trials))
        finally:
            gc.enable()
    for trial, result in zip(trials, batch_results, strict=True):
        inlier_src = trial.problem.src[trial.is_inlier]
        truth = project(trial.true_homography, inlier_src)
        tallies[batch_name].add(mean_distance(result.H, inlier_src, truth))
    tallies[batch_name].times_ms = [statistics.median(batch_times)]

    section = Section(f"{scenario.title}, {n_trials} trials")
    ordered = [
        tallies[PLANARCAL.name],
        tallies[PLANARCAL_DROP_IN.name],
        tallies[batch_name],
        *(tallies[c.name] for c in flags),
        tallies[gold_name],
    ]
    ours = tallies[PLANARCAL.name]
    section.tables.append(synthetic_table(ordered, ours, n_trials))
    flag_tallies = [tallies[c.name] for c in flags]
    section.notes += synthetic_notes(scenario, ours, flag_tallies, iterations, stop_reasons)
    section.targets += synthetic_targets(scenario, ours, flag_tallies, n_trials)
    return section


def synthetic_table(tallies: Sequence[Tally], ours: Tally, n_trials: int) -> Table:
    headers = (
        "contender",
        "median time (ms)",
        "time / planarcal",
        "median error (px)",
        "max error (px)",
        f"failures (of {n_trials})",
    )
    rows: list[tuple[str, ...]] = []
    for tally in tallies:
        rows.append(
            (
                tally.name,
                format_ms(tally.median_time_ms) if tally.timed else "-",
                format_ratio(tally.median_time_ms / ours.median_time_ms) if tally.timed else "-",
                format_px(tally.median_error_px),
                format_px(tally.max_error_px),
                format_failures(tally, SYNTHETIC_FAILURE_PX),
            )
        )
    return Table(headers, (False, True, True, True, True, True), rows)


def fastest(tallies: Sequence[Tally]) -> Tally:
    return min(tallies, key=lambda t: t.median_time_ms)


def most_accurate(tallies: Sequence[Tally]) -> Tally:
    return min(tallies, key=lambda t: t.median_error_px)


def synthetic_notes(
    scenario: Scenario,
    ours: Tally,
    flags: Sequence[Tally],
    iterations: Sequence[int],
    stop_reasons: Counter[str],
) -> list[str]:
    quickest = fastest(flags)
    best = most_accurate(flags)
    failing = [
        f"{t.name.removeprefix('cv2 ')} {t.n_failures(SYNTHETIC_FAILURE_PX)}"
        f"/{len(t.errors_px)}" + (f" ({t.n_none} None)" if t.n_none else "")
        for t in flags
        if t.n_failures(SYNTHETIC_FAILURE_PX)
    ]
    notes = [
        f"fastest OpenCV flag: {quickest.name.removeprefix('cv2 ')}, "
        f"{format_ms(quickest.median_time_ms)} ms; best OpenCV time / planarcal time = "
        f"{format_ratio(quickest.median_time_ms / ours.median_time_ms)}"
        + (
            f" (it failed {quickest.n_failures(SYNTHETIC_FAILURE_PX)} trials)"
            if quickest.n_failures(SYNTHETIC_FAILURE_PX)
            else ""
        ),
        f"most accurate OpenCV flag: {best.name.removeprefix('cv2 ')}, median error "
        f"{format_px(best.median_error_px)} px; planarcal's {format_px(ours.median_error_px)} px",
        "OpenCV flags failing (no H, or error > "
        f"{SYNTHETIC_FAILURE_PX:g} px): " + (", ".join(failing) if failing else "none"),
        "planarcal iterations (samples passing the checks): median "
        f"{statistics.median(iterations):g}, max {max(iterations)}; stop reasons: "
        + ", ".join(f"{reason} {count}" for reason, count in stop_reasons.most_common()),
    ]
    notes.append(
        "the batch row is one call on all the trials' problems (seed 0 for each), warm and "
        "spread over the cores; the other rows are single cold calls"
    )
    if scenario.outlier_fraction >= LMEDS_MAX_OUTLIER_FRACTION:
        notes.append(
            f"LMEDS not run: it needs under {LMEDS_MAX_OUTLIER_FRACTION:.0%} outliers "
            f"(here {scenario.outlier_fraction:.0%})"
        )
    return notes


def synthetic_targets(
    scenario: Scenario, ours: Tally, flags: Sequence[Tally], n_trials: int
) -> list[Target]:
    key = f"({scenario.key})"
    targets = []
    if scenario.min_speedup_vs_fastest_flag is not None:
        quickest = fastest(flags)
        speedup = quickest.median_time_ms / ours.median_time_ms
        targets.append(
            Target(
                f"{key} planarcal >= {scenario.min_speedup_vs_fastest_flag:g}x faster than "
                "the fastest OpenCV flag (median time)",
                f"{format_ratio(speedup)} ({format_ms(ours.median_time_ms)} ms vs "
                f"{quickest.name.removeprefix('cv2 ')} {format_ms(quickest.median_time_ms)} ms)",
                speedup >= scenario.min_speedup_vs_fastest_flag,
            )
        )
    if scenario.max_median_ms is not None:
        targets.append(
            Target(
                f"{key} planarcal median time < {scenario.max_median_ms:g} ms",
                f"{format_ms(ours.median_time_ms)} ms",
                ours.median_time_ms < scenario.max_median_ms,
            )
        )
    if scenario.error_no_worse_than_best_flag:
        best = most_accurate(flags)
        targets.append(
            Target(
                f"{key} planarcal median error <= most accurate flag's (+{ERROR_SLACK - 1:.0%})",
                f"{format_px(ours.median_error_px)} px vs {best.name.removeprefix('cv2 ')} "
                f"{format_px(best.median_error_px)} px",
                ours.median_error_px <= ERROR_SLACK * best.median_error_px,
            )
        )
    if scenario.must_always_succeed:
        failures = ours.n_failures(SYNTHETIC_FAILURE_PX)
        targets.append(
            Target(
                f"{key} planarcal succeeds (error <= {SYNTHETIC_FAILURE_PX:g} px) in every "
                f"one of {n_trials} trials",
                f"{n_trials - failures}/{n_trials}",
                failures == 0,
            )
        )
    return targets


# --------------------------------------------------------------------------------------------
# Real correspondences


@dataclasses.dataclass(frozen=True)
class RealPair:
    """Matches from image i to image j, with the dot centres as the truth."""

    i: int
    j: int
    problem: Problem
    true_homography: Array
    centres_i: Array
    centres_j: Array

    @property
    def n_on_truth(self) -> int:
        """Matches that the ground truth maps within ON_TRUTH_PX of their partner."""
        if len(self.problem.src) == 0:
            return 0
        distances = np.linalg.norm(
            project(self.true_homography, self.problem.src) - self.problem.dst, axis=1
        )
        return int(np.sum(distances <= ON_TRUTH_PX))


def shared_folder() -> Path:
    """../shared beside the checkout, or wherever PLANARCAL_SHARED points (as the tests)."""
    default = Path(__file__).resolve().parents[1].parent / "shared"
    return Path(os.environ.get("PLANARCAL_SHARED", default))


@dataclasses.dataclass(frozen=True)
class Features:
    points: Array
    descriptors: NDArray[Any]


def detect_features(grey: NDArray[np.uint8], kind: Literal["SIFT", "ORB"]) -> Features:
    detector = cv2.SIFT.create() if kind == "SIFT" else cv2.ORB.create(nfeatures=ORB_FEATURES)
    keypoints, descriptors = detector.detectAndCompute(grey, None)
    points = np.array([k.pt for k in keypoints], dtype=np.float64).reshape(-1, 2)
    return Features(points, descriptors)


def ratio_test_matches(
    a: Features, b: Features, kind: Literal["SIFT", "ORB"]
) -> tuple[Array, Array, Array]:
    """(src, dst, scores): Lowe's ratio test; score = 1 - d1 / d2, higher is better."""
    norm = cv2.NORM_L2 if kind == "SIFT" else cv2.NORM_HAMMING
    matcher = cv2.BFMatcher(norm)
    src, dst, scores = [], [], []
    if a.descriptors is not None and b.descriptors is not None and len(b.descriptors) >= 2:
        for candidates in matcher.knnMatch(a.descriptors, b.descriptors, k=2):
            if len(candidates) < 2:
                continue
            best, second = candidates
            if best.distance < LOWE_RATIO * second.distance:
                src.append(a.points[best.queryIdx])
                dst.append(b.points[best.trainIdx])
                scores.append(1.0 - best.distance / second.distance)
    return (
        np.array(src, dtype=np.float64).reshape(-1, 2),
        np.array(dst, dtype=np.float64).reshape(-1, 2),
        np.array(scores, dtype=np.float64),
    )


def bench_real(settings: Settings) -> list[Section]:
    """Section (d): real SIFT and ORB matches between the six photographs."""
    folder = shared_folder() / REAL_FOLDER
    title = "(d) real correspondences: six photographs of a 10 x 8 circle-grid board"
    paths = [folder / name for name in REAL_IMAGES]
    missing = [p for p in paths if not p.exists()]
    if missing:
        return [Section(title, notes=[f"skipped: {missing[0]} is absent (set PLANARCAL_SHARED)"])]

    centres: dict[int, Array] = {}
    notes = []
    for index, path in enumerate(paths):
        try:
            centres[index] = pc.detect_board(str(path), REAL_BOARD).image_points
        except pc.BoardNotFoundError as error:
            notes.append(f"{path.name}: board not detected, its pairs skipped ({error})")
    greys: dict[int, NDArray[np.uint8]] = {
        index: np.asarray(cv2.imread(str(paths[index]), cv2.IMREAD_GRAYSCALE), dtype=np.uint8)
        for index in sorted(centres)
    }
    sections = []
    for kind in ("SIFT", "ORB"):
        features = {index: detect_features(grey, kind) for index, grey in greys.items()}
        pairs = []
        for i in sorted(centres):
            for j in sorted(centres):
                if i < j:
                    src, dst, scores = ratio_test_matches(features[i], features[j], kind)
                    pairs.append(
                        RealPair(
                            i,
                            j,
                            Problem(src, dst, scores),
                            pc.estimate_homography(centres[i], centres[j], refine=True),
                            centres[i],
                            centres[j],
                        )
                    )
        section = bench_real_pairs(pairs, settings)
        section.title = f"{title}; {kind} matches, ratio test {LOWE_RATIO:g}"
        section.notes = notes + section.notes
        sections.append(section)
    return sections


def bench_real_pairs(pairs: Sequence[RealPair], settings: Settings) -> Section:
    """Every contender on every pair: the summary table and the per-pair table."""
    outlier_fractions = [1.0 - p.n_on_truth / max(len(p.problem.src), 1) for p in pairs]
    include_lmeds = all(f < LMEDS_MAX_OUTLIER_FRACTION for f in outlier_fractions)
    flags = opencv_contenders(include_lmeds)
    prosac = Contender("cv2 USAC_PROSAC (matches sorted by score)", opencv_prosac)
    contenders = [PLANARCAL, PLANARCAL_WITH_SCORES, PLANARCAL_DROP_IN, *flags, prosac]
    tallies = {c.name: Tally(c.name) for c in contenders}
    truth_name = "reference: the ground truth (fitted to the centres)"
    oracle_name = f"reference: refit of the matches within {ON_TRUTH_PX:g} px of the truth"
    tallies[truth_name] = Tally(truth_name, timed=False)
    tallies[oracle_name] = Tally(oracle_name, timed=False)

    pair_rows: list[tuple[str, ...]] = []
    for pair_number, pair in enumerate(pairs):
        problem = pair.problem
        if len(problem.src) >= 4:
            times, estimates = time_contenders(
                contenders, problem, pair_number, settings.calls_per_real_pair
            )
        else:  # too few matches for anyone: every contender fails this pair
            times, estimates = {}, {c.name: None for c in contenders}
        errors = {
            c.name: mean_distance(estimates[c.name], pair.centres_i, pair.centres_j)
            for c in contenders
        }
        for contender in contenders:
            tallies[contender.name].add(errors[contender.name], times.get(contender.name))
        tallies[truth_name].add(mean_distance(pair.true_homography, pair.centres_i, pair.centres_j))
        tallies[oracle_name].add(mean_distance(oracle_refit(pair), pair.centres_i, pair.centres_j))
        flag_errors = {c.name: errors[c.name] for c in [*flags, prosac]}
        best_flag = min(flag_errors, key=lambda name: flag_errors[name])
        n_solving = sum(errors[c.name] <= REAL_FAILURE_PX for c in contenders)
        pair_rows.append(
            (
                f"{pair.i}-{pair.j}",
                str(len(problem.src)),
                str(pair.n_on_truth),
                format_px(errors[PLANARCAL.name]),
                format_px(errors[PLANARCAL_WITH_SCORES.name]),
                f"{format_px(flag_errors[best_flag])} ({best_flag.removeprefix('cv2 ')})",
                f"{n_solving}/{len(contenders)}",
            )
        )

    section = Section("")
    ours = tallies[PLANARCAL.name]
    ordered = [tallies[c.name] for c in contenders] + [tallies[truth_name], tallies[oracle_name]]
    headers = (
        "contender",
        "median time (ms)",
        "time / planarcal",
        "median error (px)",
        f"failures (of {len(pairs)} pairs)",
    )
    section.tables.append(
        Table(
            headers,
            (False, True, True, True, True),
            [
                (
                    t.name,
                    format_ms(t.median_time_ms) if t.timed else "-",
                    format_ratio(t.median_time_ms / ours.median_time_ms) if t.timed else "-",
                    format_px(t.median_error_px),
                    format_failures(t, REAL_FAILURE_PX),
                )
                for t in ordered
            ],
        )
    )
    section.tables.append(
        Table(
            (
                "pair",
                "matches",
                f"within {ON_TRUTH_PX:g} px of truth",
                "planarcal error (px)",
                "planarcal + scores error (px)",
                "best OpenCV error (px)",
                f"contenders within {REAL_FAILURE_PX:g} px",
            ),
            (False, True, True, True, True, True, True),
            pair_rows,
        )
    )
    section.notes += [
        f"error: mean distance between H_est(c_i) and c_j over the {len(pairs[0].centres_i)} "
        f"dot centres; a failure is no H or an error > {REAL_FAILURE_PX:g} px",
        f"matches agreeing with the truth: {sum(p.n_on_truth for p in pairs)} of "
        f"{sum(len(p.problem.src) for p in pairs)} over the {len(pairs)} pairs "
        f"(outliers {min(outlier_fractions):.0%}-{max(outlier_fractions):.0%} per pair)",
        "the refit reference knows which matches are right: where it fails too, the right "
        "matches are too few or too bunched to fix H over the board, and no estimator can",
    ]
    if not include_lmeds:
        n_over = sum(f >= LMEDS_MAX_OUTLIER_FRACTION for f in outlier_fractions)
        section.notes.append(
            f"LMEDS not run: {n_over} of {len(pairs)} pairs have "
            f">= {LMEDS_MAX_OUTLIER_FRACTION:.0%} outliers"
        )
    return section


def oracle_refit(pair: RealPair) -> Homography:
    """The gold-standard fit of the matches that agree with the truth (None if too few)."""
    src, dst = pair.problem.src, pair.problem.dst
    if len(src) < 4:
        return None
    agree = np.linalg.norm(project(pair.true_homography, src) - dst, axis=1) <= ON_TRUTH_PX
    if agree.sum() < 4:
        return None
    try:
        return pc.estimate_homography(src[agree], dst[agree], refine=True)
    except pc.DegenerateError:
        return None


# --------------------------------------------------------------------------------------------
# Report


def format_ms(value: float) -> str:
    if math.isnan(value):
        return "-"
    if value >= 100:
        return f"{value:,.0f}"
    if value >= 10:
        return f"{value:.1f}"
    if value >= 1:
        return f"{value:.2f}"
    return f"{value:.3f}"


def format_px(value: float) -> str:
    if math.isinf(value):
        return "none"
    if value >= 1000:
        return f"{value:.2g}"
    return f"{value:.4g}"


def format_ratio(ratio: float) -> str:
    if not math.isfinite(ratio):
        return "-"
    if ratio >= 100:
        return f"{ratio:.0f}x"
    return f"{ratio:.2f}x"


def format_failures(tally: Tally, failure_px: float) -> str:
    failures = tally.n_failures(failure_px)
    return f"{failures}" + (f" ({tally.n_none} no H)" if tally.n_none else "")


def environment(settings: Settings) -> list[tuple[str, str]]:
    return [
        ("planarcal", pc.__version__),
        ("OpenCV", f"{cv2.__version__} (cv2.getNumThreads() = {cv2.getNumThreads()})"),
        ("numpy", np.__version__),
        ("Python", f"{platform.python_version()} ({platform.python_implementation()})"),
        ("CPU", f"{cpu_model()}, os.cpu_count() = {os.cpu_count()}"),
        ("parallel throughput", parallel_throughput()),
        ("RAYON_NUM_THREADS", os.environ.get("RAYON_NUM_THREADS", "unset")),
        ("load average", load_average()),
        (
            "mode",
            f"{settings.name}: per trial, each contender's median of "
            f"{settings.calls_per_trial} interleaved call(s); "
            f"{settings.calls_per_real_pair} per real pair",
        ),
        (
            "options",
            f"threshold {THRESHOLD_PX:g} px, confidence {CONFIDENCE:g}, max iterations "
            f"{MAX_ITERS:,}; planarcal seed = trial number",
        ),
    ]


def parallel_throughput() -> str:
    """How much more work all cores do than one, measured (hashlib releases the GIL).

    On a shared or throttled machine the cores counted may not all be there; this says how
    much the batch API and OpenCV's USAC_PARALLEL can gain from threads at all.
    """
    n_threads = os.cpu_count() or 1
    if n_threads < 2:
        return "1 core"
    data = bytes(16 << 20)

    def work(_: int) -> None:
        for _round in range(4):
            hashlib.sha256(data).digest()

    start = time.perf_counter()
    work(0)
    one = time.perf_counter() - start
    with concurrent.futures.ThreadPoolExecutor(n_threads) as pool:
        start = time.perf_counter()
        list(pool.map(work, range(n_threads)))
        many = time.perf_counter() - start
    return f"{n_threads} threads do {n_threads * one / many:.2f}x the work of one (hashlib test)"


def render_table(table: Table, markdown: bool) -> list[str]:
    """The table's lines: Markdown, or plain text with aligned columns."""
    return table_lines(table.headers, table.right_aligned, table.rows, markdown)


def print_report(
    env: Sequence[tuple[str, str]], sections: Sequence[Section], elapsed_s: float, markdown: bool
) -> None:
    if markdown:
        for key, value in env:
            print(f"- {key}: {value}")
    else:
        width = max(len(key) for key, _ in env)
        for key, value in env:
            print(f"{key:<{width}} : {value}")
    for section in sections:
        print()
        print(f"### {section.title}" if markdown else section.title)
        print()
        for table in section.tables:
            print("\n".join(render_table(table, markdown)))
            print()
        for note in section.notes:
            print(f"- {note}" if markdown else f"  {note}")

    targets = [t for s in sections for t in s.targets]
    print()
    print("### Targets" if markdown else "Targets")
    print()
    target_rows: list[tuple[str, ...]] = [
        (t.description, t.measured, "PASS" if t.passed else "FAIL") for t in targets
    ]
    target_table = Table(("target", "measured", "PASS/FAIL"), (False,) * 3, target_rows)
    print("\n".join(render_table(target_table, markdown)))
    n_passed = sum(t.passed for t in targets)
    print()
    print(
        f"{n_passed} targets passed, {len(targets) - n_passed} failed; "
        f"time / planarcal > 1: planarcal faster; total {elapsed_s:.0f} s"
    )


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a fast smoke run (a few seconds)")
    parser.add_argument("--markdown", action="store_true", help="print the tables as Markdown")
    args = parser.parse_args(argv)
    settings = QUICK if args.quick else FULL

    start = time.perf_counter()
    sections: list[Section] = []
    for scenario in SCENARIOS:
        print(
            f"[{time.perf_counter() - start:5.1f} s] {scenario.title} ...",
            file=sys.stderr,
            flush=True,
        )
        sections.append(bench_scenario(scenario, settings))
    print(f"[{time.perf_counter() - start:5.1f} s] (d) real ...", file=sys.stderr, flush=True)
    sections += bench_real(settings)

    print_report(environment(settings), sections, time.perf_counter() - start, args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
