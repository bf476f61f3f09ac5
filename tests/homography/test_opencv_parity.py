"""Accuracy against the truth and parity with OpenCV, on random problems (hypothesis).

OpenCV's findHomography rounds the points to float32 before solving; planarcal stays in
float64, so on exact data it recovers H to rounding level where OpenCV cannot.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import planarcal
from synthetic import (
    F64,
    OPENCV_ROBUST_METHODS,
    Problem,
    exact_problems,
    examples,
    frame,
    project,
    relative_h_error,
)


def _cv_homography(src: F64, dst: F64) -> F64 | None:
    """OpenCV's H (method 0) as float64, or None where it finds none (its stubs leave the None
    out and type H as any numeric array)."""
    h, _ = cv2.findHomography(src, dst)
    return None if h is None else np.asarray(h, dtype=np.float64)


@given(exact_problems())
@settings(max_examples=examples(150))
def test_exact_data_recovers_the_true_homography(p: Problem) -> None:
    """4 to 10,000 points, spreads 1e-3 .. 1e5, offsets up to 100x: H to 1e-9 relative."""
    h_native = planarcal.estimate_homography(p.src, p.dst)
    h_refined = planarcal.estimate_homography(p.src, p.dst, refine=True)
    h_dropin, mask = planarcal.findHomography(p.src, p.dst)
    assert h_dropin is not None
    assert mask.shape == (len(p.src), 1) and mask.dtype == np.uint8 and mask.all()
    for h in (h_native, h_refined, h_dropin):
        assert h.shape == (3, 3) and h.dtype == np.float64
        assert relative_h_error(h, p.truth) < 1e-9
    assert h_dropin[2, 2] == 1.0


@given(exact_problems())
@settings(max_examples=examples(100))
def test_agrees_with_opencv_within_opencvs_own_error(p: Problem) -> None:
    """Where OpenCV finds H, ours differs from its H by no more than OpenCV differs from the
    truth (plus our own 1e-9)."""
    h_cv = _cv_homography(p.src, p.dst)
    h_ours, _ = planarcal.findHomography(p.src, p.dst)
    assert h_ours is not None
    if h_cv is None:
        return  # OpenCV failed (float32 cannot resolve this scale); ours did not.
    cv_error = relative_h_error(h_cv, p.truth)
    assert relative_h_error(h_ours, h_cv) <= cv_error + 1e-9


@pytest.mark.parametrize("seed", range(10))
def test_large_offsets_reproject_to_a_micropixel(seed: int) -> None:
    """Points spread over 1,000 px at an offset of 1e6 px: ours reproject within 1e-6 px;
    OpenCV's float32 path is off by about 0.01-0.1 px."""
    rng = np.random.default_rng(seed)
    p = Problem(rng, 140, frame(1000.0, 1e6), frame(1000.0, 1e6))
    h_ours, _ = planarcal.findHomography(p.src, p.dst)
    h_cv = _cv_homography(p.src, p.dst)
    assert h_ours is not None and h_cv is not None
    # perspectiveTransform, like OpenCV's, ignores H's sign: OpenCV's H[2,2] = 1 scaling can
    # reverse it when the source origin (here 1e6 px away) lies beyond the horizon.
    mapped = planarcal.perspectiveTransform(p.src.reshape(-1, 1, 2), h_ours)
    assert mapped is not None
    ours = np.abs(mapped.reshape(-1, 2) - p.dst).max()
    theirs = np.abs(project(h_cv, p.src) - p.dst).max()
    # The native estimate is oriented, so transform_points accepts it.
    h_native = planarcal.estimate_homography(p.src, p.dst, refine=True)
    native = np.abs(planarcal.transform_points(h_native, p.src) - p.dst).max()
    assert native < 1e-6
    assert ours < 1e-6
    assert theirs > 100 * ours  # the float32 loss is real, and ours does not have it


@st.composite
def noisy_problems(draw: st.DrawFn) -> tuple[Problem, np.ndarray]:
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(6, 400))
    s = 10 ** draw(st.floats(0.0, 3.5))
    p = Problem(rng, n, frame(s, draw(st.floats(0.0, 5.0)) * s), frame(800.0, 100.0))
    sigma = draw(st.sampled_from([0.1, 0.5, 2.0]))
    return p, p.dst + rng.normal(0.0, sigma, p.dst.shape)


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e**2)))


@given(noisy_problems())
@settings(max_examples=examples(200))
def test_refined_fit_is_at_least_as_good_as_opencvs(problem: tuple[Problem, np.ndarray]) -> None:
    """The refined estimate minimises the sum of squared transfer errors, the maximum-
    likelihood criterion that OpenCV's method 0 also minimises (in float32, with at most 10
    Levenberg-Marquardt steps). So its RMS error is never above OpenCV's. Its mean error
    (Eq. 7) is no larger either, except by what least squares allows: for any other H, the
    sum of squares exceeds the optimum's by the squared distance between the two fits'
    predictions (Pythagoras), and the mean can differ by at most that distance. So
        mean_ours <= mean_opencv + sqrt(rms_opencv^2 - rms_ours^2),
    which holds only if ours is the optimum; a lower mean on OpenCV's side is then paid for
    by a larger RMS. The mean of distances is not what either estimator minimises."""
    p, noisy = problem
    h_cv = _cv_homography(p.src, noisy)
    h_ours = planarcal.estimate_homography(p.src, noisy, refine=True)
    assert h_cv is not None
    ours = planarcal.reprojection_errors(h_ours, p.src, noisy)
    theirs = np.linalg.norm(project(h_cv, p.src) - noisy, axis=1)
    rms_ours, rms_theirs = _rms(ours), _rms(theirs)
    assert rms_ours <= rms_theirs * (1 + 1e-12)
    # Pythagoras holds to first order for this nonlinear problem: allow 10% on the margin.
    margin = np.sqrt(max(rms_theirs**2 - rms_ours**2, 0.0))
    assert ours.mean() <= theirs.mean() + 1.1 * margin + 1e-12 * rms_ours
    # The drop-in does the same refinement.
    h_dropin, _ = planarcal.findHomography(p.src, noisy)
    assert h_dropin is not None
    assert relative_h_error(h_dropin, h_ours) < 1e-12


def _truth_errors(
    rng: np.random.Generator, problems: int, offset: float, sigma: float
) -> tuple[np.ndarray, np.ndarray]:
    """Mean distance of each fitted mapping from the true one: (ours, OpenCV's)."""
    ours, theirs = [], []
    for _ in range(problems):
        p = Problem(rng, 140, frame(1000.0, offset), frame(1000.0, offset))
        noisy = p.dst + rng.normal(0.0, sigma, p.dst.shape)
        h_cv = _cv_homography(p.src, noisy)
        h_ours = planarcal.estimate_homography(p.src, noisy, refine=True)
        assert h_cv is not None
        ours.append(np.linalg.norm(project(h_ours, p.src) - p.dst, axis=1).mean())
        theirs.append(np.linalg.norm(project(h_cv, p.src) - p.dst, axis=1).mean())
    return np.array(ours), np.array(theirs)


def test_refined_fit_matches_opencvs_accuracy_on_ordinary_data() -> None:
    """Against the true mapping, on image-sized coordinates, both are the same maximum-
    likelihood estimate: equally accurate to well within the noise."""
    ours, theirs = _truth_errors(np.random.default_rng(7), 100, 300.0, 0.5)
    assert abs(ours.mean() / theirs.mean() - 1) < 1e-4


def test_refined_fit_beats_opencv_where_float32_rounding_bites() -> None:
    """With coordinates around 1e5 px and 0.01 px of noise, OpenCV's float32 rounding (about
    0.004 px there) adds to the noise; planarcal's float64 fit does not suffer it."""
    ours, theirs = _truth_errors(np.random.default_rng(11), 100, 1e5, 0.01)
    assert ours.mean() < 0.97 * theirs.mean()


@given(exact_problems())
@settings(max_examples=examples(60))
def test_transforms_match_opencv(p: Problem) -> None:
    """perspectiveTransform agrees with cv2's (same shapes and dtypes), and transform_points
    with its inverse round-trips."""
    src = p.src.reshape(-1, 1, 2)
    ours = planarcal.perspectiveTransform(src, p.truth)
    theirs = cv2.perspectiveTransform(src, p.truth)
    assert ours is not None
    assert ours.shape == theirs.shape and ours.dtype == theirs.dtype
    np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-12 * p.dst_scale)
    f32 = planarcal.perspectiveTransform(src.astype(np.float32), p.truth)
    assert f32 is not None and f32.dtype == np.float32
    np.testing.assert_allclose(
        f32, cv2.perspectiveTransform(src.astype(np.float32), p.truth), rtol=1e-6
    )
    # H^-1 brings the images back (the oriented truth: src points are in front).
    h = planarcal.estimate_homography(p.src, p.dst)
    back = planarcal.transform_points(h, planarcal.transform_points(h, p.src), inverse=True)
    scale = float(np.abs(p.src).max())
    np.testing.assert_allclose(back, p.src, rtol=0, atol=1e-8 * scale)


def test_method_constants_carry_opencvs_values() -> None:
    for name in OPENCV_ROBUST_METHODS:
        assert getattr(planarcal, name) == getattr(cv2, name), name
