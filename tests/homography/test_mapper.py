"""PlaneMapper, the production loop's pixel -> plane mapping: the same answers and the same
failures as FittedPlane.image_to_world (the exact, Newton path), out= semantics, odd inputs,
and the same bits whatever the thread count."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal._core import FittedPlane, PlaneMapper
from planarcal.errors import (
    ArgumentError,
    HomographyError,
    LensModelError,
    PointAtInfinityError,
)

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


def _plane(lens: str, k1: float) -> FittedPlane:
    world = _grid()
    return FittedPlane.fit(world, _distort(_project(H, world), k1), lens, SIZE)


@pytest.fixture(scope="module")
def planes() -> dict[str, FittedPlane]:
    """A plain homography, the paper-strength lens (k1 = -0.06), and a lens with k2 and a
    free centre; plus a model whose horizon crosses the image."""
    world = _grid()
    h = np.linalg.inv(H_INV_HORIZON)
    # Ideal pixels in front of the horizon, their world points, and what the lens shows.
    ideal = np.array([[x, y] for x in np.linspace(600, 1200, 14) for y in np.linspace(50, 650, 10)])
    horizon = FittedPlane.at(
        h,
        tuple(CENTRE),
        SCALE,
        -0.05,
        0.0,
        _project(H_INV_HORIZON, ideal),
        _distort(ideal, -0.05),
        "k1",
        SIZE,
    )
    return {
        "none": _plane("none", 0.0),
        "k1": _plane("k1", -0.06),
        "k1k2c": FittedPlane.fit(world, _distort(_project(H, world), -0.08), "k1k2c", SIZE),
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


def _relative(a: F64, b: F64) -> float:
    ok = np.isfinite(b).all(axis=1)
    scale = np.maximum(np.hypot(*b[ok].T), 1.0)
    return float((np.hypot(*(a[ok] - b[ok]).T) / scale).max())


@pytest.mark.parametrize("name", ["none", "k1", "k1k2c", "horizon"])
def test_agrees_with_the_exact_path_on_every_pixel(
    planes: dict[str, FittedPlane], name: str
) -> None:
    plane = planes[name]
    mapper = PlaneMapper(plane, SIZE)
    rng = np.random.default_rng(1)
    px = np.vstack([_pixels(rng, 20_000, margin=0.3), _odd_pixels()])
    fast = mapper.image_to_world(px, invalid="nan")
    exact = plane.image_to_world(px, invalid="nan")
    # The same pixels fail ...
    np.testing.assert_array_equal(np.isnan(fast), np.isnan(exact))
    assert np.isnan(exact).any()
    # ... and the rest agree to far better than 1e-9 of their size.
    assert _relative(fast, exact) <= 1e-10
    if name == "horizon":
        assert np.isnan(exact[:, 0]).sum() > 1000  # pixels beyond the horizon
    # One by one, the same again (a block of one point takes the same arithmetic).
    for p, f in zip(px[:50], fast[:50], strict=True):
        np.testing.assert_array_equal(mapper.image_to_world(p[None], invalid="nan"), f[None])


@pytest.mark.parametrize(
    ("name", "bad", "error"),
    [
        ("k1", [-3000.0, -3000.0], LensModelError),
        ("none", [np.nan, 3.0], PointAtInfinityError),
        ("horizon", [100.0, 300.0], PointAtInfinityError),
    ],
)
def test_raises_what_the_exact_path_raises_naming_the_first_failure(
    planes: dict[str, FittedPlane], name: str, bad: list[float], error: type[Exception]
) -> None:
    plane = planes[name]
    px = np.array([[700.0, 400.0], [800.0, 500.0], bad, [900.0, 300.0], bad])
    with pytest.raises(error) as fast:
        PlaneMapper(plane, SIZE).image_to_world(px)
    with pytest.raises(error) as exact:
        plane.image_to_world(px)
    assert str(fast.value) == str(exact.value)
    assert "2 of 5 pixels" in str(fast.value) and "point 2" in str(fast.value)
    # invalid="nan" marks the same two points and maps the rest.
    out = PlaneMapper(plane, SIZE).image_to_world(px, invalid="nan")
    assert np.isnan(out[[2, 4]]).all() and np.isfinite(out[[0, 1, 3]]).all()


def test_the_lens_inverse_is_a_checked_polynomial(planes: dict[str, FittedPlane]) -> None:
    plain, lens = PlaneMapper(planes["none"], SIZE), PlaneMapper(planes["k1"], SIZE)
    assert plain.approximation.startswith("none") and plain.max_error_px == 0.0
    assert lens.approximation.startswith("polynomial")
    assert 0.0 < lens.max_error_px <= 1e-10
    assert "polynomial" in repr(lens)


def test_out_is_filled_and_returned_without_allocating(planes: dict[str, FittedPlane]) -> None:
    mapper = PlaneMapper(planes["k1"], SIZE)
    px = _pixels(np.random.default_rng(2), 100_000)
    out = np.empty((len(px), 2))
    expected = mapper.image_to_world(px)
    assert mapper.image_to_world(px, out=out) is out
    np.testing.assert_array_equal(out, expected)
    # No new array: nothing near the 1.6 MB a fresh result takes is allocated.
    mapper.image_to_world(px, out=out)
    tracemalloc.start()
    try:
        mapper.image_to_world(px, out=out)
        _, with_out = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        mapper.image_to_world(px)
        _, without = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert with_out < 10_000 < out.nbytes <= without
    # (N, 1, 2) pixels go into an (N, 2) out.
    assert mapper.image_to_world(px[:, None, :], out=out) is out
    np.testing.assert_array_equal(out, expected)


def test_out_with_nan_fills_failures_in_place(planes: dict[str, FittedPlane]) -> None:
    mapper = PlaneMapper(planes["k1"], SIZE)
    px = np.vstack([[[700.0, 400.0]], _odd_pixels()])
    out = np.zeros((len(px), 2))
    assert mapper.image_to_world(px, out=out, invalid="nan") is out
    assert np.isfinite(out[0]).all() and np.isnan(out[1:-1]).all()
    # With "raise" out is still written before the error.
    out[:] = 0.0
    with pytest.raises(PointAtInfinityError):
        mapper.image_to_world(px, out=out)
    assert np.isnan(out[1]).all()


@pytest.mark.parametrize(
    ("make_out", "message"),
    [
        (lambda n: np.empty((n + 1, 2)), "shape"),
        (lambda n: np.empty((n, 3)), "shape"),
        (lambda n: np.empty(2 * n), "shape"),
        (lambda n: np.empty((n, 2), dtype=np.float32), "float64"),
        (lambda n: [[0.0, 0.0]] * n, "float64"),
        (lambda n: np.empty((n, 4))[:, ::2], "C-contiguous"),
        (lambda n: np.empty((2, n)).T, "C-contiguous"),
        (lambda n: np.broadcast_to(np.empty(2), (n, 2)), "C-contiguous"),
    ],
)
def test_a_wrong_out_is_refused_clearly(
    planes: dict[str, FittedPlane], make_out: Callable[[int], object], message: str
) -> None:
    mapper = PlaneMapper(planes["none"], SIZE)
    px = _pixels(np.random.default_rng(3), 10)
    with pytest.raises(ArgumentError, match=message):
        mapper.image_to_world(px, out=make_out(len(px)))  # type: ignore[arg-type]


def test_a_read_only_or_aliased_out_is_refused(planes: dict[str, FittedPlane]) -> None:
    mapper = PlaneMapper(planes["none"], SIZE)
    px = _pixels(np.random.default_rng(4), 10)
    frozen = np.empty((10, 2))
    frozen.flags.writeable = False
    with pytest.raises(ArgumentError, match="writeable"):
        mapper.image_to_world(px, out=frozen)
    with pytest.raises(ArgumentError, match="share memory"):
        mapper.image_to_world(px, out=px)


def test_other_dtypes_and_layouts_are_copied(planes: dict[str, FittedPlane]) -> None:
    mapper = PlaneMapper(planes["k1"], SIZE)
    px = np.round(_pixels(np.random.default_rng(5), 64))
    expected = mapper.image_to_world(px)
    for variant in (
        px.astype(np.float32).astype(np.float64),
        px.astype(np.int32),
        np.asfortranarray(px),
        px[:, None, :],
        px[None, :, :],
        px.tolist(),
    ):
        np.testing.assert_array_equal(mapper.image_to_world(variant), expected)
    assert mapper.image_to_world(np.empty((0, 2))).shape == (0, 2)
    for bad in (np.empty((5, 3)), np.empty(4), [["a", "b"]]):
        with pytest.raises(ArgumentError, match="px"):
            mapper.image_to_world(bad)
    with pytest.raises(ArgumentError, match="invalid"):
        mapper.image_to_world(px, invalid="ignore")


def test_constructors(planes: dict[str, FittedPlane]) -> None:
    plane = planes["k1k2c"]
    cx, cy, s, k1, k2 = plane.lens
    a = PlaneMapper(plane, SIZE)
    b = PlaneMapper.from_parameters(plane.homography, (cx, cy), s, k1, k2, SIZE)
    px = _pixels(np.random.default_rng(6), 1000)
    np.testing.assert_array_equal(a.image_to_world(px), b.image_to_world(px))
    assert a.lens == plane.lens and a.image_size == SIZE
    np.testing.assert_array_equal(a.homography, plane.homography)
    with pytest.raises(LensModelError, match="image size"):
        PlaneMapper(plane, (0.0, 720.0))
    with pytest.raises(HomographyError, match="singular"):
        PlaneMapper.from_parameters(np.zeros((3, 3)), (cx, cy), s, k1, k2, SIZE)
    with pytest.raises(TypeError):
        PlaneMapper(plane.homography, SIZE)  # type: ignore[arg-type]


_CHILD = textwrap.dedent(
    """
    import sys
    import numpy as np
    from planarcal._core import PlaneMapper
    h, lens, size, px = (np.load(name) for name in sys.argv[1:5])
    m = PlaneMapper.from_parameters(h, tuple(lens[:2]), *lens[2:], tuple(size))
    np.save(sys.argv[5], m.image_to_world(px, invalid="nan"))
    """
)


def test_a_million_points_give_the_same_bits_on_any_thread_count(
    planes: dict[str, FittedPlane], tmp_path: Path
) -> None:
    plane = planes["horizon"]
    mapper = PlaneMapper(plane, SIZE)
    rng = np.random.default_rng(7)
    px = np.vstack([_pixels(rng, 1_000_000, margin=0.3), _odd_pixels()])
    big = mapper.image_to_world(px, invalid="nan")
    assert np.isnan(big).any() and np.isfinite(big).any()
    # The concatenation of small calls (each on the calling thread) ...
    small = np.vstack(
        [mapper.image_to_world(px[i : i + 1000], invalid="nan") for i in range(0, len(px), 1000)]
    )
    np.testing.assert_array_equal(big.view(np.uint64), small.view(np.uint64))
    # ... and a process restricted to one thread give the same bits.
    files = []
    for name, value in [
        ("h", plane.homography),
        ("lens", np.array(plane.lens)),
        ("size", np.array(SIZE)),
        ("px", px),
    ]:
        files.append(tmp_path / f"{name}.npy")
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
