"""The native API's documented behaviour: solvers, conventions, transforms, errors, stats."""

from __future__ import annotations

import numpy as np
import pytest

import planarcal
from synthetic import Problem, frame, project, relative_h_error

H = np.array([[1.2, 0.1, 30.0], [-0.05, 0.9, 20.0], [2e-4, -1e-4, 1.0]])


def _problem(n: int = 50, seed: int = 0) -> Problem:
    return Problem(np.random.default_rng(seed), n, frame(400.0, 50.0), frame(600.0, 80.0))


def test_exception_hierarchy_lets_users_catch_valueerror() -> None:
    assert issubclass(planarcal.HomographyError, ValueError)
    assert issubclass(planarcal.DegenerateError, planarcal.HomographyError)
    assert issubclass(planarcal.PointAtInfinityError, planarcal.HomographyError)
    for cls in (planarcal.HomographyError, planarcal.DegenerateError):
        assert cls.__module__ == "planarcal.errors"


@pytest.mark.parametrize("solver", planarcal.SOLVERS)
def test_minimal_four_point_problem_is_exact(solver: planarcal.Solver) -> None:
    src = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 80.0], [0.0, 80.0]])
    dst = project(H, src)
    h = planarcal.estimate_homography(src, dst, solver)
    assert relative_h_error(h, H) < 1e-12
    np.testing.assert_allclose(planarcal.transform_points(h, src), dst, atol=1e-9)


def test_default_solver_is_the_normalised_dlt() -> None:
    p = _problem()
    noisy = p.dst + np.random.default_rng(1).normal(0, 0.5, p.dst.shape)
    default = planarcal.estimate_homography(p.src, noisy)
    assert np.array_equal(default, planarcal.estimate_homography(p.src, noisy, "normalized_dlt"))
    # The three solvers are different estimators: on noisy data their answers differ.
    others = [planarcal.estimate_homography(p.src, noisy, s) for s in ("svd", "a33")]
    assert all(relative_h_error(default, o) > 1e-12 for o in others)


def test_refinement_lowers_the_rms_error_of_every_linear_solver() -> None:
    p = _problem(200, seed=3)
    noisy = p.dst + np.random.default_rng(4).normal(0, 1.0, p.dst.shape)
    gold = planarcal.reprojection_stats(
        planarcal.estimate_homography(p.src, noisy, refine=True), p.src, noisy
    )
    for solver in planarcal.SOLVERS:
        linear = planarcal.reprojection_stats(
            planarcal.estimate_homography(p.src, noisy, solver), p.src, noisy
        )
        assert gold.rms < linear.rms
        refined = planarcal.estimate_homography(p.src, noisy, solver, refine=True)
        assert planarcal.reprojection_stats(refined, p.src, noisy).rms == pytest.approx(
            gold.rms, rel=1e-10
        )


def test_returned_h_is_oriented_and_scaled() -> None:
    """H[2,2] = 1 and the fit's points in front (w > 0)."""
    p = _problem()
    h = planarcal.estimate_homography(p.src, p.dst)
    assert h[2, 2] == 1.0
    w = np.c_[p.src, np.ones(len(p.src))] @ h[2]
    assert (w > 0).all()


def test_source_origin_behind_the_horizon_gives_h33_minus_one() -> None:
    """w = x - 1: the data (x > 1) are in front, the origin behind. The native H keeps the
    orientation (H[2,2] = -1); the OpenCV drop-in scales to H[2,2] = 1 as OpenCV does."""
    truth = np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, -1.0]])
    src = np.random.default_rng(5).uniform(2.0, 4.0, (30, 2))
    dst = project(truth, src)
    h = planarcal.estimate_homography(src, dst)
    assert h[2, 2] == -1.0
    np.testing.assert_allclose(planarcal.transform_points(h, src), dst, rtol=1e-10)
    h_cv, _ = planarcal.findHomography(src, dst)
    assert h_cv is not None and h_cv[2, 2] == 1.0
    np.testing.assert_allclose(h_cv, -h, rtol=1e-10, atol=1e-12)
    # Through the un-oriented drop-in, every point is "behind": the message says why.
    with pytest.raises(planarcal.PointAtInfinityError, match="sign of H is probably reversed"):
        planarcal.transform_points(h_cv, src)
    mapped = planarcal.perspectiveTransform(src.reshape(-1, 1, 2), h_cv)
    assert mapped is not None
    np.testing.assert_allclose(mapped.reshape(-1, 2), dst, rtol=1e-10)


def test_transform_points_shapes_and_inverse() -> None:
    pts = np.random.default_rng(6).uniform(0, 500, (40, 2))
    out = planarcal.transform_points(H, pts)
    assert out.shape == (40, 2) and out.dtype == np.float64
    np.testing.assert_allclose(out, project(H, pts), rtol=1e-14)
    for shape in ((40, 1, 2), (1, 40, 2)):
        assert np.array_equal(planarcal.transform_points(H, pts.reshape(shape)), out)
    back = planarcal.transform_points(H, out, inverse=True)
    np.testing.assert_allclose(back, pts, rtol=1e-12, atol=1e-10)
    empty = planarcal.transform_points(H, np.zeros((0, 2)))
    assert empty.shape == (0, 2)


def test_points_without_an_image_are_reported_not_zeroed() -> None:
    # w = 1 - x / 100: x = 100 is the horizon, x > 100 behind it.
    h = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-0.01, 0.0, 1.0]])
    pts = np.array([[10.0, 5.0], [100.0, 5.0], [150.0, 5.0], [20.0, 1.0]])
    with pytest.raises(planarcal.PointAtInfinityError) as err:
        planarcal.transform_points(h, pts)
    message = str(err.value)
    assert "2 of 4 points" in message and "point 1" in message
    assert "maps to infinity" in message and "behind the horizon" in message
    out = planarcal.transform_points(h, pts, invalid="nan")
    assert np.isnan(out[1:3]).all() and np.isfinite(out[[0, 3]]).all()
    np.testing.assert_allclose(out[0], [10.0 / 0.9, 5.0 / 0.9])
    errors = planarcal.reprojection_errors(h, pts, pts, invalid="inf")
    assert np.isinf(errors[1:3]).all() and np.isfinite(errors[[0, 3]]).all()
    with pytest.raises(planarcal.PointAtInfinityError, match="2 of 4 source points"):
        planarcal.reprojection_errors(h, pts, pts)
    with pytest.raises(planarcal.PointAtInfinityError):
        planarcal.reprojection_stats(h, pts, pts)


def test_reprojection_errors_and_stats() -> None:
    src = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    dst = project(H, src) + np.array([[3.0, 4.0], [0.0, 0.0], [0.0, -1.0], [1.0, 0.0]])
    e = planarcal.reprojection_errors(H, src, dst)
    np.testing.assert_allclose(e, [5.0, 0.0, 1.0, 1.0], atol=1e-12)
    s = planarcal.reprojection_stats(H, src, dst)
    assert s.n == 4
    assert s.mean == pytest.approx(7.0 / 4)
    assert s.rms == pytest.approx(np.sqrt(27.0 / 4))
    assert s.max == pytest.approx(5.0)
    assert (s.argmax, s.argmin) == (0, 1)
    assert s.min == pytest.approx(0.0, abs=1e-12)
    assert planarcal.error_stats([2.0, 4.0]) == (2, 3.0, np.sqrt(10.0), 4.0, 2.0, 1, 0)
    with pytest.raises(planarcal.ArgumentError, match="empty"):
        planarcal.error_stats([])


def test_large_problems() -> None:
    """10^5 correspondences: exact recovery, and the drop-in agrees."""
    p = _problem(100_000, seed=9)
    h = planarcal.estimate_homography(p.src, p.dst, refine=True)
    assert relative_h_error(h, p.truth) < 1e-10
    h_cv, mask = planarcal.findHomography(p.src, p.dst)
    assert h_cv is not None and mask.shape == (100_000, 1)
    assert relative_h_error(h_cv, p.truth) < 1e-10
