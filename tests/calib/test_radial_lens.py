"""The core's radial lens as a Python class (planarcal._core.RadialLens): distort and
undistort against an independent NumPy statement of the model, its fold and valid radius,
the failures beyond them, and the class's behaviour (frozen, equality, pickling)."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from planarcal._core import FittedPlane, LensStd, RadialLens
from planarcal.calib.lens_model import LensKind
from planarcal.errors import ArgumentError, LensModelError

CENTRE = (644.0, 355.0)
SCALE = 734.0


def _distort(u: np.ndarray, k1: float, k2: float) -> np.ndarray:
    """d = c + (u - c) (1 + k1 rho^2 + k2 rho^4), rho = |u - c| / scale, in NumPy."""
    q = (u - np.array(CENTRE)) / SCALE
    rho2 = np.sum(q * q, axis=1, keepdims=True)
    d = np.array(CENTRE) + (u - np.array(CENTRE)) * (1.0 + rho2 * (k1 + k2 * rho2))
    return np.asarray(d, dtype=np.float64)


def _grid() -> np.ndarray:
    x, y = np.meshgrid(np.linspace(0.0, 1279.0, 41), np.linspace(0.0, 719.0, 23))
    return np.column_stack([x.ravel(), y.ravel()])


@pytest.mark.parametrize("k1, k2", [(-0.26, 0.14), (0.1, 0.0), (-0.12, -0.03), (0.0, 0.0)])
def test_distort_is_the_radial_model_and_undistort_its_inverse(k1: float, k2: float) -> None:
    lens = RadialLens(CENTRE, SCALE, k1, k2)
    u = _grid()
    d = lens.distort(u)
    assert d.shape == u.shape and d.dtype == np.float64
    np.testing.assert_allclose(d, _distort(u, k1, k2), atol=1e-9, rtol=0)
    np.testing.assert_allclose(lens.undistort(d), u, atol=1e-9, rtol=0)
    assert (lens.centre_px, lens.scale_px, lens.k1, lens.k2) == (CENTRE, SCALE, k1, k2)


def test_large_batches_match_small_ones() -> None:
    # Large batches run with the GIL released: the same numbers either way.
    lens = RadialLens(CENTRE, SCALE, -0.26, 0.14)
    u = np.random.default_rng(1).uniform(0.0, 1280.0, (20_000, 2))
    d = lens.distort(u)
    np.testing.assert_array_equal(d[:100], lens.distort(u[:100]))
    np.testing.assert_array_equal(lens.undistort(d)[:100], lens.undistort(d[:100]))


@pytest.mark.parametrize("k1, k2", [(-0.3, 0.0), (-0.5, 0.1), (0.2, -0.3), (-0.1, -0.05)])
def test_fold_radius_is_where_the_radial_map_stops_rising(k1: float, k2: float) -> None:
    lens = RadialLens(CENTRE, SCALE, k1, k2)
    fold = lens.fold_radius

    def slope(r: float) -> float:
        return 1.0 + 3.0 * k1 * r * r + 5.0 * k2 * r**4

    assert slope(0.999 * fold) > 0.0 > slope(1.001 * fold)
    # The valid radius is the fold seen in the image, px.
    assert lens.valid_radius == pytest.approx(SCALE * fold * (1 + k1 * fold**2 + k2 * fold**4))


def test_a_lens_that_never_folds_is_valid_everywhere() -> None:
    lens = RadialLens(CENTRE, SCALE, 0.1, 0.05)
    assert math.isinf(lens.fold_radius) and math.isinf(lens.valid_radius)


def test_points_beyond_the_valid_radius_raise_or_are_nan() -> None:
    lens = RadialLens(CENTRE, SCALE, -0.5)
    far = [CENTRE[0] + 1.01 * lens.valid_radius, CENTRE[1]]
    px = np.array([[700.0, 400.0], far])
    with pytest.raises(LensModelError, match=r"point 1 .* beyond the lens model's valid radius"):
        lens.undistort(px)
    out = lens.undistort(px, invalid="nan")
    assert np.isfinite(out[0]).all() and np.isnan(out[1]).all()
    with pytest.raises(ArgumentError, match="not finite"):
        lens.undistort([[np.nan, 1.0]])
    with pytest.raises(ArgumentError, match="invalid"):
        lens.undistort(px, invalid="drop")


def test_bad_parameters_and_points_are_refused() -> None:
    with pytest.raises(LensModelError, match="scale"):
        RadialLens(CENTRE, 0.0)
    with pytest.raises(LensModelError, match="k1"):
        RadialLens(CENTRE, SCALE, math.nan)
    with pytest.raises(ArgumentError, match="ideal_px"):
        RadialLens(CENTRE, SCALE).distort(np.zeros((3, 3)))


def test_the_identity_is_centred_on_the_image() -> None:
    lens = RadialLens.identity(1280, 720)
    assert lens.centre_px == (639.5, 359.5) and lens.scale_px == pytest.approx(
        0.5 * math.hypot(1280, 720)
    )
    u = _grid()
    np.testing.assert_allclose(lens.distort(u), u, atol=1e-9, rtol=0)


def test_the_class_is_frozen_compares_by_value_and_pickles() -> None:
    lens = RadialLens(CENTRE, SCALE, -0.26, 0.14)
    with pytest.raises(AttributeError):
        lens.k1 = 0.0  # type: ignore[misc]
    assert lens == RadialLens(CENTRE, SCALE, -0.26, 0.14) != RadialLens(CENTRE, SCALE, -0.26)
    assert pickle.loads(pickle.dumps(lens)) == lens
    assert repr(lens) == "RadialLens(centre_px=(644.0, 355.0), scale_px=734.0, k1=-0.26, k2=0.14)"


def test_a_fitted_plane_hands_its_lens_and_uncertainty_over_as_classes() -> None:
    frame = RadialLens.identity(1288, 710)  # "k1" keeps the image's centre and unit
    truth = RadialLens(frame.centre_px, frame.scale_px, -0.1)
    world = np.array([[x, y] for x in range(0, 260, 20) for y in range(0, 180, 20)], float)
    ideal = world * 4.0 + [110.0, 20.0]
    plane = FittedPlane.fit(world, truth.distort(ideal), LensKind.K1, (1288.0, 710.0))
    lens, std = plane.lens, plane.lens_std
    assert isinstance(lens, RadialLens) and isinstance(std, LensStd)
    assert lens.k1 == pytest.approx(-0.1, abs=1e-9) and lens.k2 == 0.0
    # k2 and the centre are held fixed with "k1": no uncertainty.
    assert std.k2 == 0.0 and std.centre_px == (0.0, 0.0) and std.k1 >= 0.0
    # A plane at those parameters reproduces the fit.
    again = FittedPlane.at(
        plane.homography, lens, world, truth.distort(ideal), LensKind.K1, (1288.0, 710.0)
    )
    assert again.lens == lens
    assert pickle.loads(pickle.dumps(std)) == std
    with pytest.raises(AttributeError):
        std.k1 = 1.0  # type: ignore[misc]
