"""Robust estimation: known truth and known outliers (hypothesis), parity with OpenCV's robust
flags, determinism across runs, threads and batching, PROSAC scores, LMedS, and bad input."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import planarcal
from synthetic import F64, OPENCV_ROBUST_METHODS, examples, project, seeds

W, H = 1280.0, 720.0
SIGMA = 0.5
THRESHOLD = 3.0
OutlierKind = Literal["uniform", "clustered", "second_plane"]


def view(rng: np.random.Generator) -> F64:
    """A camera-like homography of the image: rotation, scale, translation, perspective."""
    a, s = rng.uniform(-0.4, 0.4), rng.uniform(0.8, 1.2)
    h = np.array(
        [
            [s * np.cos(a), -s * np.sin(a), rng.uniform(-50, 50)],
            [s * np.sin(a), s * np.cos(a), rng.uniform(-50, 50)],
            [rng.uniform(-2e-4, 2e-4), rng.uniform(-2e-4, 2e-4), 1.0],
        ]
    )
    return h


@dataclass
class Outlying:
    """A problem with known truth and known outliers (shuffled among the inliers)."""

    src: F64
    dst: F64
    truth: F64
    inlier: np.ndarray

    def error(self, h: F64 | None) -> float:
        """Mean distance between h's and the truth's images of the true inliers (px)."""
        if h is None:
            return float("inf")
        s = self.src[self.inlier]
        return float(np.linalg.norm(project(h, s) - project(self.truth, s), axis=1).mean())

    def gold(self) -> F64:
        """The gold-standard fit on the true inliers."""
        return planarcal.estimate_homography(
            self.src[self.inlier], self.dst[self.inlier], refine=True
        )


def outlying(seed: int, n: int, inlier_fraction: float, kind: OutlierKind) -> Outlying:
    rng = np.random.default_rng(seed)
    truth = view(rng)
    src = rng.uniform((0, 0), (W, H), (n, 2))
    ideal = project(truth, src)
    dst = ideal + rng.normal(0, SIGMA, (n, 2))
    inliers = int(np.ceil(inlier_fraction * n))
    inlier = np.arange(n) < inliers
    outliers = n - inliers
    if kind == "uniform":
        dst[inliers:] = rng.uniform((0, 0), (W, H), (outliers, 2))
    elif kind == "clustered":
        # Wrong matches in a few blobs (repeated texture): sources in one small region paired
        # at random with destinations in another.
        centres = rng.uniform((0, 0), (W, H), (4, 2, 2))
        which = rng.integers(0, 4, outliers)
        src[inliers:] = centres[which, 0] + rng.normal(0, 30, (outliers, 2))
        dst[inliers:] = centres[which, 1] + rng.normal(0, 30, (outliers, 2))
    else:
        # A second plane, smaller than the true one, then uniform outliers.
        second = min(outliers, inliers * 7 // 10)
        other = view(rng) @ np.array([[0.7, 0.2, 300.0], [-0.1, 1.1, -200.0], [0, 0, 1]])
        part = slice(inliers, inliers + second)
        dst[part] = project(other, src[part]) + rng.normal(0, SIGMA, (second, 2))
        dst[inliers + second :] = rng.uniform((0, 0), (W, H), (outliers - second, 2))
    # An outlier is inconsistent with the truth: one that lands within a few thresholds of
    # it (where the planes meet, say) is drawn again.
    ideal = project(truth, src)
    close = ~inlier & (np.linalg.norm(dst - ideal, axis=1) <= 10.0)
    while close.any():
        dst[close] = rng.uniform((0, 0), (W, H), (int(close.sum()), 2))
        close = ~inlier & (np.linalg.norm(dst - ideal, axis=1) <= 10.0)
    order = rng.permutation(n)
    return Outlying(src[order], dst[order], truth, inlier[order])


def mask_agrees_with_h(r: planarcal.RobustResult, p: Outlying) -> None:
    assert r.H is not None
    residuals = np.linalg.norm(project(r.H, p.src) - p.dst, axis=1)
    np.testing.assert_array_equal(r.inliers, residuals <= r.threshold)
    assert r.n_inliers == int(r.inliers.sum())


kinds = st.sampled_from(["uniform", "clustered", "second_plane"])


@given(seeds, st.integers(40, 600), st.floats(0.2, 0.9), kinds)
@settings(max_examples=examples(120))
def test_outliers_do_not_capture_the_model(
    seed: int, n: int, fraction: float, kind: OutlierKind
) -> None:
    """At least 20% inliers: within 10% of the gold-standard fit on the true inliers."""
    p = outlying(seed, n, fraction, kind)
    r = planarcal.estimate_homography_robust(p.src, p.dst, THRESHOLD, seed=seed)
    assert r.success and r.stop_reason in ("converged", "max_iterations")
    assert p.error(r.H) <= 1.1 * p.error(p.gold()) + 1e-9
    mask_agrees_with_h(r, p)
    # The mask is the truth's, but for an inlier whose noise crosses the threshold.
    assert (p.inlier & ~r.inliers).sum() <= 1
    assert not (~p.inlier & r.inliers).any()


@given(seeds, st.integers(1000, 2000), st.floats(0.1, 0.15), kinds)
@settings(max_examples=examples(12))
def test_many_points_with_ten_percent_inliers(
    seed: int, n: int, fraction: float, kind: OutlierKind
) -> None:
    """At least 10% inliers among 1,000+ points: the same."""
    p = outlying(seed, n, fraction, kind)
    r = planarcal.estimate_homography_robust(p.src, p.dst, THRESHOLD, seed=seed)
    assert p.error(r.H) <= 1.1 * p.error(p.gold()) + 1e-9
    mask_agrees_with_h(r, p)


def msac_cost(h: F64, src: F64, dst: F64) -> float:
    e2 = np.sum((project(h, src) - dst) ** 2, axis=1)
    return float(np.minimum(e2, THRESHOLD**2).sum())


def plane_and_offset_patch(
    seed: int, shift: float, outliers: int = 200
) -> tuple[F64, F64, F64, F64]:
    """300 matches of a plane; 130 in its bottom-left corner displaced by `shift` px (a patch
    just off the plane); `outliers` outliers. A compromise between plane and patch fits most of
    both within the threshold, but costs more than the plane's own fit: (src, dst, that fit,
    the true H)."""
    rng = np.random.default_rng(seed)
    truth = view(rng)
    plane = rng.uniform((0, 0), (W, H), (300, 2))
    patch = rng.uniform((0, 500), (400, H), (130, 2))
    src = np.vstack([plane, patch, rng.uniform((0, 0), (W, H), (outliers, 2))])
    dst = project(truth, src) + rng.normal(0, 0.7, (430 + outliers, 2))
    dst[300:430] += (shift, -0.6 * shift)
    dst[430:] = rng.uniform((0, 0), (W, H), (outliers, 2))
    return src, dst, planarcal.estimate_homography(src[:300], dst[:300], refine=True), truth


@pytest.mark.parametrize(("shift", "at_least"), [(8.0, 14), (10.0, 18)])
def test_the_search_prefers_the_plane_to_a_compromise_with_a_patch_off_it(
    shift: float, at_least: int
) -> None:
    """The search finds the lower-cost structure: no compromise costlier than the plane's fit
    in at least `at_least` of 20 problems (16 and 20 are found; local optimisation polishing at
    twice the threshold, without rivals of another structure, found 9 and 15)."""
    found = 0
    for seed in range(20):
        src, dst, plane, _ = plane_and_offset_patch(seed, shift)
        r = planarcal.estimate_homography_robust(src, dst, THRESHOLD, seed=seed)
        assert r.H is not None
        found += msac_cost(r.H, src, dst) <= 1.005 * msac_cost(plane, src, dst)
    assert found >= at_least


@pytest.mark.parametrize("shift", [5.0, 6.0])
def test_lmeds_keeps_to_the_plane_beside_a_patch_just_off_it(shift: float) -> None:
    """LMedS on a plane (300 matches), a patch of 130 displaced by 5-6 px and 80 outliers:
    within 1.5x the error of the plane's own fit in at least 17 of 20 problems (18 and 19 are;
    one start and the classical threshold, 2.5 robust sigma of all points, gave 0 and 9, a
    compromise with the patch; OpenCV's LMEDS 0 and 0)."""
    within = 0
    for seed in range(20):
        src, dst, plane, truth = plane_and_offset_patch(seed, shift, outliers=80)
        r = planarcal.estimate_homography_robust(src, dst, THRESHOLD, seed=seed, method="lmeds")
        assert r.H is not None
        on_plane = project(truth, src[:300])
        errors = [
            np.linalg.norm(project(h, src[:300]) - on_plane, axis=1).mean() for h in (r.H, plane)
        ]
        within += errors[0] <= 1.5 * errors[1]
    assert within >= 17


def parity_problem(seed: int, fraction: float) -> Outlying:
    return outlying(seed, 500, fraction, "uniform")


@pytest.mark.parametrize("name", OPENCV_ROBUST_METHODS)
def test_every_flag_is_at_least_as_accurate_as_opencvs(name: str) -> None:
    method = getattr(planarcal, name)
    assert method == getattr(cv2, name)
    # LMedS breaks down at 50% outliers; the others get 40%.
    fraction = 0.65 if name == "LMEDS" else 0.6
    for seed in range(12):
        p = parity_problem(seed, fraction)
        src, dst, inlier = p.src, p.dst, p.inlier
        if name == "USAC_PROSAC":  # PROSAC's contract: the points come best first
            first = np.argsort(~p.inlier, kind="stable")
            src, dst, inlier = src[first], dst[first], inlier[first]
        ours, mask = planarcal.findHomography(src, dst, method, THRESHOLD, None, 2000, 0.995)
        theirs, their_mask = cv2.findHomography(src, dst, method, THRESHOLD, None, 2000, 0.995)
        assert ours is not None
        assert ours.dtype == np.float64 and ours.shape == (3, 3) and ours[2, 2] == 1.0
        assert mask.shape == their_mask.shape == (len(src), 1)
        assert mask.dtype == their_mask.dtype == np.uint8
        assert set(np.unique(mask)) <= {0, 1}
        # 1 = inlier of the returned H (LMedS derives its own threshold).
        residuals = np.linalg.norm(project(ours, src) - dst, axis=1)
        if name != "LMEDS":
            np.testing.assert_array_equal(mask[:, 0] == 1, residuals <= THRESHOLD)
        q = Outlying(src, dst, p.truth, inlier)
        # As accurate as OpenCV's fit, or as the gold-standard fit on the true inliers (the
        # best an estimator can do by design: on one problem another may land closer to the
        # truth by chance).
        # OpenCV's H as float64, None where it found none (its stubs leave the None out).
        their_h = None if theirs is None else np.asarray(theirs, dtype=np.float64)
        error, theirs_error, gold_error = q.error(ours), q.error(their_h), q.error(q.gold())
        assert error <= 1.02 * max(theirs_error, gold_error) + 1e-6, (name, seed)


@pytest.mark.parametrize("threshold", [0.7, 1.0, 3.0, 12.5])
def test_the_result_reports_the_callers_threshold(threshold: float) -> None:
    p = outlying(25, 300, 0.6, "uniform")
    r = planarcal.estimate_homography_robust(p.src, p.dst, threshold)
    assert r.threshold == threshold
    mask_agrees_with_h(r, p)


def test_the_given_mask_is_filled_in_place() -> None:
    p = parity_problem(1, 0.6)
    mask = np.full((len(p.src), 1), 7, np.uint8)
    h, out = planarcal.findHomography(p.src, p.dst, planarcal.RANSAC, THRESHOLD, mask)
    assert out is mask and h is not None
    assert set(np.unique(mask)) == {0, 1}


def robust_fields(r: planarcal.RobustResult) -> tuple[object, ...]:
    h = None if r.H is None else r.H.tobytes()
    return (h, r.inliers.tobytes(), r.n_inliers, r.iterations, r.stop_reason, r.threshold)


def test_the_same_seed_gives_the_same_bits() -> None:
    p = outlying(3, 3000, 0.15, "uniform")
    first = planarcal.estimate_homography_robust(p.src, p.dst, seed=7)
    for _ in range(3):
        again = planarcal.estimate_homography_robust(p.src, p.dst, seed=7)
        assert robust_fields(again) == robust_fields(first)
    other = planarcal.estimate_homography_robust(p.src, p.dst, seed=8)
    assert other.success and p.error(other.H) < 0.5


DETERMINISM_SCRIPT = textwrap.dedent(
    """
    import hashlib, sys
    sys.path[:0] = [{here!r}, {tests!r}]
    import planarcal
    from test_robust import outlying
    digest = hashlib.sha256()
    for seed, n, fraction in [(1, 5000, 0.12), (2, 20000, 0.5), (3, 3000, 0.3)]:
        p = outlying(seed, n, fraction, "uniform")
        for r in [planarcal.estimate_homography_robust(p.src, p.dst, seed=seed)] + (
            planarcal.estimate_homography_robust_batch([(p.src, p.dst)] * 3, seed=seed)
        ):
            digest.update(r.H.tobytes() + r.inliers.tobytes() + str(r.iterations).encode())
    print(digest.hexdigest())
    """
)


def test_results_do_not_depend_on_the_thread_count() -> None:
    here = os.path.dirname(__file__)
    script = DETERMINISM_SCRIPT.format(here=here, tests=os.path.dirname(here))
    digests = set()
    for threads in ("1", "2"):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        done = subprocess.run(
            [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300
        )
        assert done.returncode == 0, done.stderr
        digests.add(done.stdout.strip())
    assert len(digests) == 1


def test_calls_from_many_threads_give_what_one_thread_gives() -> None:
    # The search runs with the GIL released: concurrent calls share nothing.
    problems = [outlying(s, 2000, 0.2 + 0.1 * (s % 3), "uniform") for s in range(6)]
    alone = [robust_fields(planarcal.estimate_homography_robust(p.src, p.dst)) for p in problems]
    with ThreadPoolExecutor(6) as pool:
        together = list(
            pool.map(
                lambda p: robust_fields(planarcal.estimate_homography_robust(p.src, p.dst)),
                problems * 3,
            )
        )
    assert together == alone * 3


def test_a_batch_gives_what_single_calls_give() -> None:
    problems = [outlying(s, 300 + 100 * s, 0.3 + 0.05 * s, "uniform") for s in range(8)]
    pairs = [(p.src, p.dst) for p in problems]
    batch = planarcal.estimate_homography_robust_batch(pairs, seed=5)
    assert len(batch) == len(problems)
    for (src, dst), r in zip(pairs, batch, strict=True):
        single = planarcal.estimate_homography_robust(src, dst, seed=5)
        assert robust_fields(r) == robust_fields(single)
    bad = [*pairs[:3], (pairs[3][0][:3], pairs[3][1][:3]), *pairs[4:]]
    with pytest.raises(planarcal.HomographyError, match=r"problems\[3\].*at least 4"):
        planarcal.estimate_homography_robust_batch(bad)


def test_good_scores_cut_the_search_and_bad_ones_do_not_mislead_it() -> None:
    # Too few points for the estimator's own neighbourhood ranking: without scores it samples
    # uniformly.
    p = outlying(11, 400, 0.15, "uniform")
    rng = np.random.default_rng(0)
    # Match scores that favour the inliers, as a descriptor ratio test does, with overlap.
    good = p.inlier * 1.0 + rng.uniform(0, 0.6, len(p.src))
    plain = planarcal.estimate_homography_robust(p.src, p.dst, max_iters=100_000)
    guided = planarcal.estimate_homography_robust(p.src, p.dst, scores=good, max_iters=100_000)
    inverted = planarcal.estimate_homography_robust(p.src, p.dst, scores=-good, max_iters=100_000)
    gold = p.error(p.gold())
    for r in (plain, guided, inverted):
        assert p.error(r.H) <= 1.1 * gold + 1e-9
    assert guided.iterations < plain.iterations


@pytest.mark.parametrize("threshold", [0.0, -1.0, 3.0])
def test_lmeds_is_least_median_without_a_threshold(threshold: float) -> None:
    for seed in range(4):
        p = outlying(seed, 400, 0.6, "uniform")
        r = planarcal.estimate_homography_robust(p.src, p.dst, threshold, method="lmeds")
        assert r.success and 0 < r.threshold < 10
        assert not (~p.inlier & r.inliers).any()
        assert p.error(r.H) <= 1.5 * p.error(p.gold()) + 1e-9
        h, mask = planarcal.findHomography(p.src, p.dst, planarcal.LMEDS, threshold)
        assert h is not None and mask.sum() == r.n_inliers


def test_four_exact_points_give_the_exact_homography() -> None:
    rng = np.random.default_rng(4)
    truth = view(rng)
    src = np.array([[100.0, 80.0], [1100.0, 120.0], [1000.0, 650.0], [150.0, 600.0]])
    r = planarcal.estimate_homography_robust(src, project(truth, src))
    assert r.success and r.n_inliers == 4
    assert r.H is not None
    np.testing.assert_allclose(r.H, truth / truth[2, 2], rtol=1e-9, atol=1e-12)


def test_pure_outliers_give_no_model() -> None:
    rng = np.random.default_rng(8)
    src = rng.uniform((0, 0), (W, H), (300, 2))
    dst = rng.uniform((0, 0), (W, H), (300, 2))
    r = planarcal.estimate_homography_robust(src, dst)
    assert r.H is None and not r.success
    assert r.stop_reason == "no_consensus"
    assert r.inliers.shape == (300,) and not r.inliers.any()
    assert np.isnan(r.rms_inlier_error)
    for name in OPENCV_ROBUST_METHODS:
        h, mask = planarcal.findHomography(src, dst, getattr(planarcal, name))
        assert h is None, name
        assert mask.shape == (300, 1) and not mask.any()


@pytest.mark.parametrize(
    "src",
    [
        np.c_[np.arange(30.0), 2 * np.arange(30.0)],  # collinear
        np.ones((30, 2)),  # one point
    ],
)
def test_degenerate_points_are_refused_before_any_sample(src: F64) -> None:
    # No sample of such a set can fit: refused at once, however large the budget (the whole
    # budget of invalid samples used to be drawn first: 6 s for 10^7).
    dst = np.random.default_rng(1).uniform(0, 500, (30, 2))
    for s, d in ((src, dst), (dst, src)):
        with pytest.raises(planarcal.DegenerateError, match=r"one line|distinct"):
            planarcal.estimate_homography_robust(s, d, max_iters=10**7)
        with pytest.raises(planarcal.DegenerateError):
            planarcal.estimate_homography_robust_batch([(dst, dst), (s, d)], max_iters=10**7)
        for method in (planarcal.RANSAC, planarcal.LMEDS):
            # OpenCV's answer to such a set: no homography, an empty mask.
            h, mask = planarcal.findHomography(s, d, method, maxIters=10**7)
            assert h is None and mask.shape == (30, 1) and not mask.any()


GOOD = outlying(0, 50, 0.8, "uniform")


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"threshold": 0.0}, "threshold must be a positive, finite"),
        ({"threshold": -2.0}, "threshold must be a positive, finite"),
        ({"threshold": float("nan")}, "threshold must be a positive, finite"),
        ({"threshold": float("inf")}, "threshold must be a positive, finite"),
        ({"threshold": "3"}, "threshold must be a number"),
        ({"confidence": 0.0}, "confidence must be strictly between 0 and 1"),
        ({"confidence": 1.0}, "confidence must be strictly between 0 and 1"),
        ({"confidence": 1.5}, "confidence must be strictly between 0 and 1"),
        ({"confidence": float("nan")}, "confidence must be strictly between 0 and 1"),
        ({"max_iters": 0}, "max_iters must be at least 1"),
        ({"max_iters": -5}, "max_iters must be between 1 and 10000000"),
        ({"max_iters": 10.5}, "max_iters must be an integer"),
        ({"seed": -1}, "seed must be an integer in"),
        ({"seed": 2**64}, "seed must be an integer in"),
        ({"method": "ransac"}, 'method must be "msac" or "lmeds"'),
        ({"scores": np.ones(49)}, "scores must hold one number per correspondence: 50 points, 49"),
        ({"scores": np.ones((50, 1))}, "scores must be a 1-D array"),
        ({"scores": np.r_[np.ones(49), np.nan]}, "scores must be finite numbers"),
        ({"scores": ["a"] * 50}, "scores must hold real numbers"),
    ],
)
def test_bad_options_are_named(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(planarcal.ArgumentError, match=match) as info:
        planarcal.estimate_homography_robust(GOOD.src, GOOD.dst, **kwargs)  # type: ignore[arg-type]
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize(
    ("src", "dst", "match", "error"),
    [
        (
            GOOD.src[:3],
            GOOD.dst[:3],
            "at least 4 point correspondences, got 3",
            planarcal.HomographyError,
        ),
        (GOOD.src, GOOD.dst[:40], "same number of points, got 50 and 40", planarcal.ArgumentError),
        (GOOD.src[:, :1], GOOD.dst, r"src must have shape \(N, 2\)", planarcal.ArgumentError),
        (
            np.r_[GOOD.src[:9], [[np.nan, 1.0]]],
            GOOD.dst[:10],
            "source point 9 is not finite",
            planarcal.ArgumentError,
        ),
        (
            GOOD.src[:10],
            np.r_[GOOD.dst[:9], [[1.0, np.inf]]],
            "destination point 9 is not",
            planarcal.ArgumentError,
        ),
    ],
)
def test_bad_points_are_named(src: F64, dst: F64, match: str, error: type[Exception]) -> None:
    with pytest.raises(error, match=match):
        planarcal.estimate_homography_robust(src, dst)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((planarcal.RANSAC, 0.0), "threshold must be a positive"),
        ((planarcal.USAC_MAGSAC, -1.0), "threshold must be a positive"),
        ((planarcal.RHO, 3.0, None, 0), "max_iters must be at least 1"),
        ((planarcal.USAC_DEFAULT, 3.0, None, 2000, 1.0), "confidence must be strictly"),
        ((planarcal.LMEDS, 3.0, None, 2000, 0.0), "confidence must be strictly"),
    ],
)
def test_the_drop_in_raises_what_cv2_code_catches(args: tuple[object, ...], match: str) -> None:
    with pytest.raises(cv2.error, match=match) as info:
        planarcal.findHomography(GOOD.src, GOOD.dst, *args)  # type: ignore[arg-type]
    assert isinstance(info.value, planarcal.ArgumentError)
