"""The package's pixel -> plane mapping: FittedPlane.image_to_world, image_to_world_std and
world_covariance (what Calibration.image_to_world and the Tracker call) run the core's fast
mapper, whose lens inverse is a checked polynomial. Here, through that path: the answers
against an independent reference (the lens's Newton inverse, then H^-1 in NumPy) and the
model's own forward map, the failures and their errors, the uncertainty beside the positions,
odd inputs, and the same bits whatever the thread count. (planarcal-core's mapper tests hold
the kernel to the Rust reference, InversePlane::map, point by point.)"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal._core import FittedPlane, RadialLens
from planarcal.calib.calibration import Calibration
from planarcal.calib.lens_model import LensKind
from planarcal.errors import ArgumentError, LensModelError, PointAtInfinityError

SIZE = (1280.0, 720.0)
CENTRE = np.array([639.5, 359.5])
SCALE = 0.5 * np.hypot(*SIZE)
# The plane_model tests' scene: world mm -> ideal px.
H = np.array([[2.0, 0.05, 330.0], [-0.03, 2.02, 160.0], [2e-5, -3e-5, 1.0]])
# Pixel -> world for a camera whose horizon crosses the image (pixels left of x ~ 400 see
# no plane).
H_INV_HORIZON = np.array([[0.5, 0.01, -100.0], [0.02, 0.6, -50.0], [1e-3, 2e-4, -0.4]])

F64 = NDArray[np.float64]


def _project(h: F64, pts: F64) -> F64:
    v = np.c_[pts, np.ones(len(pts))] @ h.T
    return np.asarray(v[:, :2] / v[:, 2:], dtype=np.float64)


def _distort(u: F64, k1: float) -> F64:
    q = (u - CENTRE) / SCALE
    return np.asarray(
        CENTRE + SCALE * q * (1.0 + k1 * (q * q).sum(axis=1, keepdims=True)), dtype=np.float64
    )


def _grid() -> F64:
    return np.array([[c * 20.0, r * 20.0] for r in range(10) for c in range(14)])


def _noisy(px: F64) -> F64:
    """About 0.1 px of noise, so that the fits have an uncertainty."""
    return px + np.random.default_rng(0).normal(0.0, 0.1, px.shape)


def _horizon_inputs() -> tuple[F64, F64, F64, F64]:
    """FittedPlane.at's h, lens (centre x, centre y, scale, k1, k2), world and image points
    for a camera whose horizon crosses the image, with a k1 = -0.05 lens."""
    h = np.linalg.inv(H_INV_HORIZON)
    # Ideal pixels in front of the horizon, their world points, and what the lens shows.
    ideal = np.array([[x, y] for x in np.linspace(600, 1200, 14) for y in np.linspace(50, 650, 10)])
    lens = np.array([CENTRE[0], CENTRE[1], SCALE, -0.05, 0.0])
    return h, lens, _project(H_INV_HORIZON, ideal), _distort(ideal, -0.05)


def _at(h: F64, lens: F64, world: F64, image: F64) -> FittedPlane:
    cx, cy, scale, k1, k2 = (float(v) for v in lens)
    radial = RadialLens((cx, cy), scale, k1, k2)
    return FittedPlane.at(h, radial, world, image, LensKind.K1, SIZE)


@pytest.fixture(scope="module")
def planes() -> dict[str, FittedPlane]:
    """A plain homography, the paper-strength lens (k1 = -0.06), and a lens with k2 and a
    free centre; plus a model whose horizon crosses the image."""
    world = _grid()
    horizon = _at(*_horizon_inputs())
    return {
        "none": FittedPlane.fit(world, _noisy(_project(H, world)), LensKind.NONE, SIZE),
        "k1": FittedPlane.fit(
            world, _noisy(_distort(_project(H, world), -0.06)), LensKind.K1, SIZE
        ),
        "k1k2c": FittedPlane.fit(
            world, _noisy(_distort(_project(H, world), -0.08)), LensKind.K1K2C, SIZE
        ),
        "horizon": horizon,
    }


def _pixels(rng: np.random.Generator, n: int, margin: float = 0.0) -> F64:
    lo = -margin * np.array(SIZE)
    return rng.uniform(lo, np.array(SIZE) - lo, (n, 2))


def _odd_pixels() -> F64:
    """Non-finite pixels, pixels far beyond the image, at the lens centre."""
    return np.array(
        [
            [np.nan, 10.0],
            [10.0, np.inf],
            [-np.inf, np.nan],
            [-3000.0, -3000.0],
            [5000.0, 360.0],
            [1e300, 1e300],
            CENTRE,
        ]
    )


def _reference(plane: FittedPlane, px: F64) -> F64:
    """The mapping written out: the lens's Newton inverse (RadialLens.undistort), refused 5 %
    beyond the image's farthest corner from the lens centre, then H^-1; NaN where refused or
    at or beyond the horizon."""
    (cx, cy), k1, k2 = plane.lens.centre_px, plane.lens.k1, plane.lens.k2
    ideal = plane.lens.undistort(px, invalid="nan")
    if k1 != 0.0 or k2 != 0.0:
        reach = np.hypot(max(cx + 0.5, SIZE[0] - 0.5 - cx), max(cy + 0.5, SIZE[1] - 0.5 - cy))
        with np.errstate(invalid="ignore"):
            ideal[~(np.hypot(px[:, 0] - cx, px[:, 1] - cy) <= 1.05 * reach)] = np.nan
    v = np.c_[ideal, np.ones(len(ideal))] @ np.linalg.inv(plane.homography).T
    with np.errstate(invalid="ignore", divide="ignore"):
        world = v[:, :2] / v[:, 2:]
        world[~(v[:, 2] > 0.0)] = np.nan
    return np.asarray(world, dtype=np.float64)


@pytest.mark.parametrize("name", ["none", "k1", "k1k2c", "horizon"])
def test_maps_what_the_reference_maps_and_refuses_what_it_refuses(
    planes: dict[str, FittedPlane], name: str
) -> None:
    plane = planes[name]
    rng = np.random.default_rng(1)
    px = np.vstack([_pixels(rng, 20_000, margin=0.3), _odd_pixels()])
    fast = plane.image_to_world(px, invalid="nan")
    exact = _reference(plane, px)
    # The same pixels fail ...
    np.testing.assert_array_equal(np.isnan(fast), np.isnan(exact))
    assert np.isnan(fast).any() and np.isfinite(fast).any()
    if name == "horizon":
        assert np.isnan(fast[:, 0]).sum() > 1000  # pixels beyond the horizon
    ok = np.isfinite(fast).all(axis=1)
    # ... the rest agree (to rounding, amplified where the ray meets the plane at a grazing
    # angle: hence relative to the answer's size) ...
    scale = np.maximum(np.hypot(*exact[ok].T), 1.0)
    assert (np.hypot(*(fast[ok] - exact[ok]).T) / scale).max() <= 1e-9
    # ... and the model sends each answer back to its pixel (but the one at 1e300 px, which
    # an ideal lens maps and the forward map overflows on).
    ok &= (np.abs(px) < 1e6).all(axis=1)
    back = plane.world_to_image(fast[ok])
    assert np.abs(back - px[ok]).max() <= 1e-8


@pytest.mark.parametrize(
    ("name", "bad", "error", "why"),
    [
        ("k1", [-3000.0, -3000.0], LensModelError, "beyond the image the lens model"),
        ("none", [np.nan, 3.0], PointAtInfinityError, "non-finite"),
        ("horizon", [100.0, 300.0], PointAtInfinityError, "horizon"),
    ],
)
def test_raises_naming_the_first_failure(
    planes: dict[str, FittedPlane],
    name: str,
    bad: list[float],
    error: type[LensModelError | PointAtInfinityError],
    why: str,
) -> None:
    plane = planes[name]
    px = np.array([[700.0, 400.0], [800.0, 500.0], bad, [900.0, 300.0], bad])
    with pytest.raises(error) as positions:
        plane.image_to_world(px)
    message = str(positions.value)
    assert message.startswith("2 of 5 pixels have no place on the plane; the first is point 2")
    assert why in message and positions.value.index == 2
    # With the uncertainty asked for too: the same error.
    for call in (plane.image_to_world_std, plane.world_covariance):
        with pytest.raises(error) as with_std:
            call(px)
        assert str(with_std.value) == message
    # invalid="nan" marks the same two points and maps the rest.
    out = plane.image_to_world(px, invalid="nan")
    assert np.isnan(out[[2, 4]]).all() and np.isfinite(out[[0, 1, 3]]).all()


def test_the_lens_inverse_is_a_checked_polynomial(planes: dict[str, FittedPlane]) -> None:
    assert planes["none"].lens_inverse.startswith("none")
    for name in ("k1", "k1k2c", "horizon"):
        described = planes[name].lens_inverse
        assert described.startswith("polynomial"), described
        found = re.search(r"max error ([0-9.e+-]+) px", described)
        assert found is not None and 0.0 < float(found.group(1)) <= 1e-10


@pytest.mark.parametrize("name", ["none", "k1k2c", "horizon"])
def test_the_uncertainty_comes_with_the_same_positions(
    planes: dict[str, FittedPlane], name: str
) -> None:
    plane = planes[name]
    px = np.array([[700.0, 400.0], [900.0, 300.0], [1100.0, 600.0]])
    mm, std = plane.image_to_world_std(px)
    np.testing.assert_array_equal(mm, plane.image_to_world(px))
    cov = plane.world_covariance(px)
    assert cov.shape == (3, 2, 2) and np.allclose(cov, cov.transpose(0, 2, 1))
    np.testing.assert_array_equal(std, np.sqrt(cov[:, 0, 0] + cov[:, 1, 1]))
    assert (std >= 0).all()
    # The pixels' own noise adds to the fit's.
    _, noisy = plane.image_to_world_std(px, 0.5)
    assert (noisy > std).all()
    np.testing.assert_array_equal(plane.world_covariance(px, 0.5)[:, 0, 0] > cov[:, 0, 0], True)


def test_the_uncertainty_needs_noise_it_can_use_and_spare_points(
    planes: dict[str, FittedPlane],
) -> None:
    plane = planes["k1"]
    for bad in (-0.1, np.nan, np.inf):
        with pytest.raises(ArgumentError, match="pixel_sigma"):
            plane.image_to_world_std([[600.0, 300.0]], bad)
        with pytest.raises(ArgumentError, match="pixel_sigma"):
            plane.world_covariance([[600.0, 300.0]], bad)
    # Four points determine a homography exactly: no residuals to estimate the noise from.
    world = _grid()[[0, 13, 126, 139]]
    exact = FittedPlane.fit(world, _project(H, world), LensKind.NONE, SIZE)
    assert exact.dof == 0
    with pytest.raises(LensModelError, match="degrees of freedom"):
        exact.image_to_world_std([[600.0, 300.0]])
    # Checked before the pixels, as it always was.
    with pytest.raises(LensModelError, match="degrees of freedom"):
        exact.world_covariance([[600.0]])
    assert np.isfinite(exact.image_to_world([[600.0, 300.0]])).all()


def test_other_dtypes_and_layouts_are_copied(planes: dict[str, FittedPlane]) -> None:
    plane = planes["k1"]
    px = np.round(_pixels(np.random.default_rng(5), 64))
    expected = plane.image_to_world(px)
    for variant in (
        px.astype(np.float32).astype(np.float64),
        px.astype(np.int32),
        np.asfortranarray(px),
        px[:, None, :],
        px[None, :, :],
        px.tolist(),
    ):
        np.testing.assert_array_equal(plane.image_to_world(variant), expected)
        np.testing.assert_array_equal(plane.image_to_world_std(variant)[0], expected)
    assert plane.image_to_world(np.empty((0, 2))).shape == (0, 2)
    mm, std = plane.image_to_world_std(np.empty((0, 2)))
    assert mm.shape == (0, 2) and std.shape == (0,)
    for bad in (np.empty((5, 3)), np.empty(4), [["a", "b"]]):
        with pytest.raises(ArgumentError, match="px"):
            plane.image_to_world(bad)
    with pytest.raises(ArgumentError, match="invalid"):
        plane.image_to_world(px, invalid="ignore")


def test_a_calibration_maps_through_the_same_path(planes: dict[str, FittedPlane]) -> None:
    world = _grid()
    image = _noisy(_distort(_project(H, world), -0.06))
    cal = Calibration(world, image, lens="k1", image_size=(1280, 720))
    px = _pixels(np.random.default_rng(8), 500)
    mm, std = cal.image_to_world(px, return_std=True)
    # The production loop's mapper gives the same bits, and the model sends them back.
    loop_mm, loop_std = cal._frame_mapper()(px, len(px))
    np.testing.assert_array_equal(loop_mm, mm)
    np.testing.assert_array_equal(loop_std, std)
    assert np.abs(cal.world_to_image(mm) - px).max() <= 1e-8
    np.testing.assert_allclose(mm, _reference(cal._fit.plane, px), rtol=0, atol=1e-9)


_CHILD = textwrap.dedent(
    """
    import sys
    import numpy as np
    from planarcal._core import FittedPlane, RadialLens
    h, lens, world, image, px = (np.load(name) for name in sys.argv[1:6])
    cx, cy, scale, k1, k2 = (float(v) for v in lens)
    radial = RadialLens((cx, cy), scale, k1, k2)
    plane = FittedPlane.at(h, radial, world, image, "k1", (1280.0, 720.0))
    np.save(sys.argv[6], plane.image_to_world(px, invalid="nan"))
    """
)


def test_a_million_points_give_the_same_bits_on_any_thread_count(
    planes: dict[str, FittedPlane], tmp_path: Path
) -> None:
    plane = planes["horizon"]
    rng = np.random.default_rng(7)
    px = np.vstack([_pixels(rng, 1_000_000, margin=0.3), _odd_pixels()])
    big = plane.image_to_world(px, invalid="nan")
    assert np.isnan(big).any() and np.isfinite(big).any()
    # The concatenation of small calls (each on the calling thread) ...
    small = np.vstack(
        [plane.image_to_world(px[i : i + 1000], invalid="nan") for i in range(0, len(px), 1000)]
    )
    np.testing.assert_array_equal(big.view(np.uint64), small.view(np.uint64))
    # ... the uncertainty of a large batch (on the thread pool) and of small ones ...
    ok = px[np.isfinite(big).all(axis=1)][:50_000]
    mm, std = plane.image_to_world_std(ok)
    pieces = [plane.image_to_world_std(ok[i : i + 1000]) for i in range(0, len(ok), 1000)]
    np.testing.assert_array_equal(mm, np.vstack([m for m, _ in pieces]))
    np.testing.assert_array_equal(
        std.view(np.uint64), np.hstack([s for _, s in pieces]).view(np.uint64)
    )
    # ... and a process restricted to one thread give the same bits.
    files = []
    for k, value in enumerate([*_horizon_inputs(), px]):
        files.append(tmp_path / f"{k}.npy")
        np.save(files[-1], value)
    result = tmp_path / "one.npy"
    env = {**os.environ, "RAYON_NUM_THREADS": "1"}
    subprocess.run(
        [sys.executable, "-c", _CHILD, *map(str, files), str(result)],
        check=True,
        env=env,
        timeout=120,
    )
    np.testing.assert_array_equal(big.view(np.uint64), np.load(result).view(np.uint64))
