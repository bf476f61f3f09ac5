"""RobustResult, the compiled module's frozen result class: its attributes, repr, pickling and
constructor, and the options the binding converts (numpy scalars, huge integers)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import planarcal
from planarcal.homography import RobustResult

RNG = np.random.default_rng(3)
SRC = RNG.uniform(0, 500, (40, 2))
DST = SRC * 1.2 + (5.0, -3.0)
DST[:10] = RNG.uniform(0, 500, (10, 2))  # a quarter of outliers


def test_the_result_is_the_public_class_and_frozen() -> None:
    r = planarcal.estimate_homography_robust(SRC, DST)
    assert type(r) is planarcal.RobustResult is RobustResult
    assert RobustResult.__module__ == "planarcal"
    assert r.success and r.H is not None and r.H.shape == (3, 3) and r.H[2, 2] == 1.0
    assert r.inliers.dtype == np.bool_ and r.inliers.shape == (40,)
    assert r.n_inliers == int(r.inliers.sum()) == 30
    assert r.inlier_ratio == 0.75
    assert r.H is r.H  # an attribute, not a new array on each access
    with pytest.raises(AttributeError):
        r.n_inliers = 3  # type: ignore[misc]


def test_the_repr_summarises_the_fit() -> None:
    r = planarcal.estimate_homography_robust(SRC, DST, threshold=2.5)
    assert repr(r) == (
        f"RobustResult(success=True, n_inliers=30 of 40, iterations={r.iterations}, "
        f"stop_reason='converged', rms_inlier_error={r.rms_inlier_error:.4g}, threshold=2.5)"
    )


def test_a_result_survives_pickling() -> None:
    for r in (
        planarcal.estimate_homography_robust(SRC, DST),
        planarcal.estimate_homography_robust(SRC, RNG.uniform(0, 500, (40, 2))),  # no H
    ):
        back = pickle.loads(pickle.dumps(r))
        assert type(back) is RobustResult and repr(back) == repr(r)
        assert (back.H is None) == (r.H is None)
        if r.H is not None:
            assert back.H is not None
            np.testing.assert_array_equal(back.H, r.H)
        np.testing.assert_array_equal(back.inliers, r.inliers)
        assert (back.stop_reason, back.local_optimizations, back.poorly_constrained) == (
            r.stop_reason,
            r.local_optimizations,
            r.poorly_constrained,
        )


def test_the_constructor_takes_the_fields_and_checks_the_stop_reason() -> None:
    inliers = np.zeros(5, bool)
    r = RobustResult(None, inliers, 0, 7, "no_consensus", float("nan"), 3.0, 0)
    assert not r.success and r.inlier_ratio == 0.0 and r.iterations == 7
    assert not r.poorly_constrained
    assert RobustResult(None, inliers, 0, 7, "no_consensus", 0.0, 3.0, 0, True).poorly_constrained
    with pytest.raises(planarcal.ArgumentError, match="stop_reason must be"):
        RobustResult(None, inliers, 0, 7, "gave_up", 0.0, 3.0, 0)  # type: ignore[arg-type]


def test_numpy_scalars_and_huge_integers_are_options() -> None:
    plain = planarcal.estimate_homography_robust(SRC, DST, 3.0, 0.99, 500, 4)
    numpy = planarcal.estimate_homography_robust(
        SRC, DST, np.float32(3.0), np.float64(0.99), np.int32(500), np.uint64(4)
    )
    assert repr(numpy) == repr(plain)
    assert planarcal.estimate_homography_robust(SRC, DST, max_iters=10**7).success
    assert planarcal.estimate_homography_robust(SRC, DST, seed=2**64 - 1).success


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"max_iters": True}, "max_iters must be an integer, got True"),
        ({"max_iters": -(10**30)}, "max_iters must be between 1 and 10000000 .*, got -1000000"),
        ({"max_iters": 0}, "max_iters must be at least 1, got 0"),
        # An absurd budget is refused, not run for ever (2**200 used to be clamped to 2**62).
        ({"max_iters": 2**200}, "max_iters must be between 1 and 10000000"),
        ({"max_iters": 10**7 + 1}, "max_iters must be at most 10000000"),
        ({"seed": np.int32(-1)}, r"seed must be an integer in \[0, 2\*\*64\), got -1"),
        ({"threshold": None}, "threshold must be a number, got None"),
        ({"method": None}, 'method must be "msac" or "lmeds", got None'),
    ],
)
def test_options_are_checked_before_the_points_and_for_an_empty_batch(
    kwargs: dict[str, object], match: str
) -> None:
    with pytest.raises(planarcal.ArgumentError, match=match):
        planarcal.estimate_homography_robust(SRC[:3], DST[:3], **kwargs)  # type: ignore[arg-type]
    with pytest.raises(planarcal.ArgumentError, match=match):
        planarcal.estimate_homography_robust_batch([], **kwargs)  # type: ignore[arg-type]


def test_a_model_resting_on_a_small_patch_is_flagged() -> None:
    rng = np.random.default_rng(11)
    H = np.array([[1.1, 0.05, 20.0], [-0.04, 0.95, -10.0], [1e-5, -2e-5, 1.0]])

    def problem(patch: float) -> tuple[np.ndarray, np.ndarray]:
        # 60 inliers over a patch x patch square of a 1280 x 720 image; 40 outliers everywhere.
        src = np.vstack(
            [rng.uniform(600, 600 + patch, (60, 2)), rng.uniform(0, 1, (40, 2)) * (1280, 720)]
        )
        w = src @ H[2, :2] + H[2, 2]
        dst = (src @ H[:2, :2].T + H[:2, 2]) / w[:, None] + rng.normal(0, 0.2, src.shape)
        dst[60:] = rng.uniform(0, 1, (40, 2)) * (1280, 720)
        return src, dst

    spread = planarcal.estimate_homography_robust(*problem(700.0))
    assert spread.success and spread.n_inliers >= 60 and not spread.poorly_constrained
    patch = planarcal.estimate_homography_robust(*problem(40.0))
    assert patch.success and patch.n_inliers >= 60 and patch.poorly_constrained
    # A model on fewer than 10 inliers is flagged however they spread; 10 are enough.
    few = planarcal.estimate_homography_robust(SRC[10:19], DST[10:19])
    assert few.success and few.n_inliers == 9 and few.poorly_constrained
    ten = planarcal.estimate_homography_robust(SRC[10:20], DST[10:20])
    assert ten.success and ten.n_inliers == 10 and not ten.poorly_constrained
