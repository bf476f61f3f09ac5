"""Dot centres (planarcal.calib.dot_centres, measured by the core's refine_dot_centres) against the
NumPy implementation they were ported from, kept here as the reference: the same centres to
1e-6 px and areas to 1e-9 (relative), the same dots refused for the same reasons, on a rendered
board, real photographs, dots cut by the border, blank paper and 4 px dots; bad input refused
as ValueError.

The reference smooths with cv2.GaussianBlur, whose SIMD build (FMA) may differ from the core's
plain float32 sums in the last bit of the smoothed coverage; the coverage's thresholds (0.2,
0.8) would have to fall within that bit for a centre to differ.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from planarcal import _core, synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.dot_centres import DotCentres, refine_centres
from planarcal.images import as_grey

F64 = NDArray[np.float64]

CENTRE_TOL_PX = 1e-6
AREA_RTOL = 1e-9
REAL = "/work/shared/data/real/boofcv-circle-regular/image{:05d}.jpg"


# ------------------------------------------------------------------------------------------
# The reference: planarcal.calib.dot_centres as it was in NumPy (one dot at a time).

NEIGHBOUR_MARGIN_PX = 1.5
MIN_INK_PLANE_PIXELS = 12
INK_PLANE_CHI2 = 13.82


class _UnmeasurableError(Exception):
    """A dot whose grey levels give no centre (the reason is the message)."""


def reference_refine_centres(
    ink_dark: NDArray[np.float32], points: F64, diameters: F64
) -> DotCentres:
    pts = np.array(points, dtype=np.float64, copy=True)
    radius = 0.5 * np.asarray(diameters, dtype=np.float64)
    n = len(pts)
    centres = pts.copy()
    areas = np.pi * radius**2
    refined = np.zeros(n, dtype=bool)
    why: list[str] = []
    for k in range(n):
        d = np.hypot(*(pts - pts[k]).T)
        d[k] = np.inf
        others = np.flatnonzero(d < 3.0 * radius[k] + 2.0 * radius + 8.0)
        try:
            (cx, cy), area = _refine_one(
                ink_dark, pts[k], radius[k], pts[others], radius[others] * 1.1
            )
        except _UnmeasurableError as e:
            why.append(f"dot {k}: {e}")
            continue
        centres[k] = (cx, cy)
        areas[k] = area
        refined[k] = True
    return DotCentres(centres, areas, refined, tuple(why))


def _refine_one(
    ink_dark: NDArray[np.float32],
    start: F64,
    radius: float,
    other_centres: F64,
    other_radii: F64,
) -> tuple[tuple[float, float], float]:
    h, w = ink_dark.shape[:2]
    cx, cy = float(start[0]), float(start[1])
    radius = max(float(radius), 1.0)
    total = 0.0
    for _ in range(3):
        ring_in = radius + max(2.0, 0.3 * radius)
        ring_out = ring_in + max(2.5, 0.3 * radius)
        if cx - ring_in < 0 or cy - ring_in < 0 or cx + ring_in > w - 1 or cy + ring_in > h - 1:
            raise _UnmeasurableError("cut by the image border")
        x0, x1 = max(0, int(np.floor(cx - ring_out))), min(w, int(np.ceil(cx + ring_out)) + 1)
        y0, y1 = max(0, int(np.floor(cy - ring_out))), min(h, int(np.ceil(cy + ring_out)) + 1)
        patch = ink_dark[y0:y1, x0:x1].astype(np.float64)
        yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
        r = np.hypot(xx - cx, yy - cy)
        free = np.ones(patch.shape, dtype=bool)
        for (ox, oy), orad in zip(other_centres, other_radii, strict=True):
            free &= np.hypot(xx - ox, yy - oy) > orad + NEIGHBOUR_MARGIN_PX
        ring = (r >= ring_in) & (r <= ring_out) & free
        inside = (r < ring_in) & free
        if ring.sum() < 6:
            raise _UnmeasurableError("no paper around it")
        if inside.sum() < 4:
            raise _UnmeasurableError("too small to measure")
        background = _ring_plane(patch, xx - cx, yy - cy, ring)
        weight = _ink_weights(patch, background, xx - cx, yy - cy, inside)
        if weight is None:
            raise _UnmeasurableError("no contrast with its background")
        total = float(weight.sum())
        if total <= 0:
            raise _UnmeasurableError("no ink")
        cx = float((weight * xx).sum() / total)
        cy = float((weight * yy).sum() / total)
        radius = float(np.sqrt(total / np.pi))
    if not (np.isfinite(cx) and np.isfinite(cy)) or np.hypot(cx - start[0], cy - start[1]) > max(
        2.0, 0.75 * radius
    ):
        raise _UnmeasurableError("its grey levels lead away from it")
    return (cx, cy), total


def _ink_weights(
    patch: F64, background: F64, dx: F64, dy: F64, inside: NDArray[np.bool_]
) -> F64 | None:
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(background > 0, patch / background, 1.0)
    darkness = 1.0 - ratio
    inner = darkness[inside]
    core = float(np.median(inner[inner >= np.percentile(inner, 75)]))
    if not core > 0.05:
        return None
    cover = np.clip(darkness / core, 0.0, 1.0)
    smooth = cv2.GaussianBlur(cover.astype(np.float32), (0, 0), 1.0).astype(np.float64)
    solid = smooth > 0.8
    ink = _ink_plane(patch, background, dx, dy, solid & inside, core)
    if ink is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            cover = np.nan_to_num(np.clip((background - patch) / (background - ink), 0.0, 1.0))
        smooth = cv2.GaussianBlur(cover.astype(np.float32), (0, 0), 1.0).astype(np.float64)
        solid = smooth > 0.8
    clear = smooth < 0.2
    band = ~(solid | clear)
    band = cv2.dilate(band.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    weight = np.where(band, cover, np.where(solid, 1.0, 0.0))
    weight_in: F64 = weight * inside
    return weight_in


def _ring_plane(patch: F64, dx: F64, dy: F64, ring: NDArray[np.bool_]) -> F64:
    values = patch[ring]
    design = np.column_stack([np.ones(values.size), dx[ring], dy[ring]])
    keep = np.ones(values.size, dtype=bool)
    coef: F64 = np.zeros(3)
    for _ in range(3):
        coef = np.asarray(np.linalg.lstsq(design[keep], values[keep], rcond=None)[0], np.float64)
        resid = values - design @ coef
        spread = 1.4826 * float(np.median(np.abs(resid[keep]))) + 1e-6
        new_keep = resid > -3.0 * spread
        if new_keep.sum() < 6 or (new_keep == keep).all():
            break
        keep = new_keep
    plane: F64 = coef[0] + coef[1] * dx + coef[2] * dy
    return plane


def _ink_plane(
    patch: F64, background: F64, dx: F64, dy: F64, solid: NDArray[np.bool_], core: float
) -> F64 | None:
    """The plane through the solid pixels' grey levels, where its slope differs from the
    paper's scaled by the ink (1 - core) beyond chance (chi-square, 2 dof, p = 0.001)."""
    count = int(solid.sum())
    if count < MIN_INK_PLANE_PIXELS:
        return None
    design = np.column_stack([np.ones(count), dx[solid], dy[solid]])
    coef = np.asarray(np.linalg.lstsq(design, patch[solid], rcond=None)[0], np.float64)
    paper = np.asarray(
        np.linalg.lstsq(
            np.column_stack([np.ones(dx.size), dx.ravel(), dy.ravel()]),
            background.ravel(),
            rcond=None,
        )[0],
        np.float64,
    )
    resid = patch[solid] - design @ coef
    variance = float(resid @ resid) / (count - 3)
    gap = coef[1:] - (1.0 - core) * paper[1:]
    try:  # a singular covariance (no noise at all) makes any gap significant
        slope_cov = np.linalg.inv(design.T @ design)[1:, 1:] * variance
        chi2 = float(gap @ np.linalg.solve(slope_cov, gap))
    except np.linalg.LinAlgError:
        chi2 = np.inf
    if not chi2 > INK_PLANE_CHI2:
        return None
    plane: F64 = coef[0] + coef[1] * dx + coef[2] * dy
    return plane


# ------------------------------------------------------------------------------------------
# Images


def render_discs(
    shape: tuple[int, int],
    discs: list[tuple[float, float, float]],
    blur: float = 0.8,
    noise: float = 0.0,
    gradient: float = 0.0,
    seed: int = 0,
) -> NDArray[np.float32]:
    """Paper (200, darkening by `gradient` per px to the right) with dark discs (x, y, r) of
    ink (40), each pixel's ink its area over it (8 x 8 samples), blurred and noisy."""
    h, w = shape
    s = 8
    ys, xs = np.mgrid[0 : h * s, 0 : w * s]
    fx = (xs + 0.5) / s - 0.5
    fy = (ys + 0.5) / s - 0.5
    ink = np.zeros((h * s, w * s), bool)
    for x, y, r in discs:
        ink |= np.hypot(fx - x, fy - y) < r
    cover = ink.reshape(h, s, w, s).mean(axis=(1, 3))
    paper = 200.0 - gradient * np.arange(w)[None, :]
    image = paper - (paper - 40.0) * cover
    if blur > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur)
    image = image + np.random.default_rng(seed).normal(0.0, noise, image.shape)
    out: NDArray[np.float32] = np.asarray(image, dtype=np.float32)
    return out


def nearest_spacing(points: F64) -> F64:
    d = np.hypot(*(points[:, None, :] - points[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    spacing: F64 = d.min(axis=1)
    return spacing


def assert_agree(image: NDArray[np.floating], points: F64, diameters: F64) -> float:
    """The core and the reference give the same result; returns the largest centre difference."""
    ours = refine_centres(image, points, diameters)
    want = reference_refine_centres(image, points, diameters)
    np.testing.assert_array_equal(ours.refined, want.refined)
    assert ours.why_not == want.why_not
    assert ours.centres.shape == (len(points), 2) and ours.centres.dtype == np.float64
    assert ours.refined.dtype == np.bool_
    diff = float(np.abs(ours.centres - want.centres).max(initial=0.0))
    assert diff <= CENTRE_TOL_PX
    np.testing.assert_allclose(ours.areas, want.areas, rtol=AREA_RTOL)
    # Unrefined dots keep their start exactly.
    np.testing.assert_array_equal(ours.centres[~ours.refined], points[~ours.refined])
    return diff


# ------------------------------------------------------------------------------------------
# Agreement


def test_a_rendered_board_agrees_with_the_reference() -> None:
    scene = synth.render_scene(board=CircleGridBoard(), blur_sigma_px=1.0, noise_sigma=2.0, seed=1)
    grey = as_grey(scene.image)
    truth = scene.dot_centres_px
    rng = np.random.default_rng(5)
    start = truth + rng.uniform(-0.7, 0.7, truth.shape)
    # Blob-like sizes: half the spacing, give or take a fifth.
    diameters = 0.5 * nearest_spacing(start) * rng.uniform(0.8, 1.2, len(start))
    assert_agree(grey, start, diameters)
    measured = refine_centres(grey, start, diameters)
    assert measured.refined.all()
    assert np.hypot(*(measured.centres - truth).T).max() < 0.05


@pytest.mark.parametrize("index", range(6))
def test_real_photographs_agree_with_the_reference(index: int) -> None:
    grey = as_grey(REAL.format(index))
    u8 = np.clip(np.rint(grey), 0, 255).astype(np.uint8)
    found, centres = cv2.findCirclesGrid(
        u8, (10, 8), flags=cv2.CALIB_CB_SYMMETRIC_GRID | cv2.CALIB_CB_CLUSTERING
    )
    assert found
    start = centres.reshape(-1, 2).astype(np.float64)
    spacing = nearest_spacing(start)
    for diameters in (0.5 * spacing, 0.7 * spacing):
        assert_agree(grey, start, diameters)
    assert refine_centres(grey, start, 0.5 * spacing).refined.all()


def test_dots_cut_by_the_border_keep_their_start_and_say_why() -> None:
    discs = [(4.0, 40.0, 7.0), (60.3, 45.6, 8.0), (116.0, 8.0, 6.0), (60.0, 87.0, 5.0)]
    image = render_discs((90, 120), discs, noise=1.0)
    start = np.array([[d[0] + 0.3, d[1] - 0.2] for d in discs])
    diameters = np.array([2 * d[2] for d in discs])
    assert_agree(image, start, diameters)
    measured = refine_centres(image, start, diameters)
    assert measured.refined.tolist() == [False, True, False, False]
    assert measured.why_not == (
        "dot 0: cut by the image border",
        "dot 2: cut by the image border",
        "dot 3: cut by the image border",
    )
    np.testing.assert_array_equal(
        measured.areas[[0, 2, 3]], np.pi * (diameters[[0, 2, 3]] / 2) ** 2
    )


def test_blank_paper_has_no_contrast() -> None:
    for noise in (0.0, 2.0):
        image = render_discs((60, 60), [], noise=noise, gradient=0.5)
        start = np.array([[30.0, 30.0], [20.5, 35.2]])
        assert_agree(image, start, np.array([12.0, 6.0]))
        measured = refine_centres(image, start, np.array([12.0, 6.0]))
        assert measured.why_not == (
            "dot 0: no contrast with its background",
            "dot 1: no contrast with its background",
        )


def test_dots_walled_in_or_swallowed_by_neighbours_say_why() -> None:
    # A dot ringed by twelve others (its ring is all theirs), and a small dot inside a large
    # neighbour's margin (its disc is all the neighbour's).
    ring = [(40.0 + 9.0 * np.cos(t), 35.0 + 9.0 * np.sin(t)) for t in np.arange(12) * np.pi / 6]
    image = render_discs((70, 100), [(40.0, 35.0, 4.0), *[(x, y, 3.0) for x, y in ring]], noise=1.0)
    start = np.array([[40.0, 35.0], *ring, [80.0, 35.0], [81.0, 35.0]])
    diameters = np.array([8.0, *[6.0] * 12, 1.0, 6.0])
    assert_agree(image, start, diameters)
    measured = refine_centres(image, start, diameters)
    assert measured.why_not[0] == "dot 0: no paper around it"
    assert "dot 13: too small to measure" in measured.why_not


def test_dots_of_4_px_agree_with_the_reference() -> None:
    rng = np.random.default_rng(2)
    discs = [
        (12.0 + 9.0 * c + rng.uniform(0, 1), 12.0 + 9.0 * r + rng.uniform(0, 1), 2.0)
        for r in range(6)
        for c in range(8)
    ]
    image = render_discs((70, 90), discs, blur=0.7, noise=1.5)
    truth = np.array([d[:2] for d in discs])
    start = truth + rng.uniform(-0.5, 0.5, truth.shape)
    assert_agree(image, start, np.full(len(start), 4.0))
    assert_agree(image, start, rng.uniform(2.5, 6.0, len(start)))
    measured = refine_centres(image, start, np.full(len(start), 4.0))
    assert measured.refined.all()
    assert np.hypot(*(measured.centres - truth).T).max() < 0.1


def test_dots_that_nearly_touch_and_a_large_marker_agree() -> None:
    # Neighbours 1.3 diameters apart (their pixels masked out of each other's windows), and
    # a marker as wide as the pitch.
    discs = [
        (20.0 + 26.0 * c + 0.2 * r, 20.0 + 26.0 * r + 0.1 * c, 10.0)
        for r in range(3)
        for c in range(4)
    ]
    discs[5] = (discs[5][0], discs[5][1], 13.0)
    image = render_discs((90, 120), discs, blur=1.0, noise=2.0, gradient=0.3)
    start = np.array([[d[0] - 0.4, d[1] + 0.5] for d in discs])
    diameters = np.array([2 * d[2] for d in discs])
    assert_agree(image, start, diameters)
    assert refine_centres(image, start, diameters).refined.all()


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    x=st.floats(15.0, 45.0),
    y=st.floats(15.0, 35.0),
    r=st.floats(1.5, 9.0),
    blur=st.floats(0.3, 1.5),
    noise=st.floats(0.5, 4.0),
    gradient=st.floats(-1.0, 1.0),
    offset=st.tuples(st.floats(-1.5, 1.5), st.floats(-1.5, 1.5)),
    size=st.floats(0.0, 2.0),
    seed=st.integers(0, 1000),
)
def test_random_dots_agree_with_the_reference(
    x: float,
    y: float,
    r: float,
    blur: float,
    noise: float,
    gradient: float,
    offset: tuple[float, float],
    size: float,
    seed: int,
) -> None:
    # A dot, a neighbour close by, and a start anywhere near (cut, unmeasurable or refined).
    # Some blur and noise, as in any photograph: on an exact, noise-free rendering, paper
    # pixels tie exactly with the 75th percentile, and which of them count then turns on the
    # last bit of the background plane (LAPACK's lstsq there, normal equations here).
    discs = [(x, y, r), (x + 2.6 * r + 3.0, y + 0.5, 0.8 * r)]
    image = render_discs((50, 60), discs, blur=blur, noise=noise, gradient=gradient, seed=seed)
    start = np.array([[x + offset[0], y + offset[1]], [discs[1][0], discs[1][1]]])
    assert_agree(image, start, np.array([2 * r * size, 1.6 * r]))


def test_float64_and_uint8_images_give_the_float32_answers() -> None:
    image = np.rint(render_discs((60, 60), [(30.3, 29.6, 8.0)], noise=2.0))
    start = np.array([[30.0, 30.0]])
    as32 = refine_centres(image.astype(np.float32), start, np.array([16.0]))
    others: list[NDArray[Any]] = [
        image.astype(np.float64),
        image.astype(np.uint8),
        image.astype(np.float32).T.copy().T,  # Fortran order: copied by the binding
    ]
    for other in others:
        got = refine_centres(other, start, np.array([16.0]))
        np.testing.assert_array_equal(got.centres, as32.centres)
        np.testing.assert_array_equal(got.areas, as32.areas)
    assert_agree(image.astype(np.float64), start, np.array([16.0]))


def test_no_dots_give_empty_results() -> None:
    measured = refine_centres(np.zeros((5, 5), np.float32), np.zeros((0, 2)), np.zeros(0))
    assert measured.centres.shape == (0, 2) and measured.areas.shape == (0,)
    assert measured.refined.shape == (0,) and measured.why_not == ()


# ------------------------------------------------------------------------------------------
# Bad input


GOOD_IMAGE = np.full((20, 20), 100.0, np.float32)
GOOD_POINTS = np.array([[10.0, 10.0], [5.0, 5.0]])
GOOD_DIAMETERS = np.array([4.0, 4.0])


@pytest.mark.parametrize(
    ("image", "points", "diameters", "message"),
    [
        (np.zeros((0, 0), np.float32), GOOD_POINTS, GOOD_DIAMETERS, "ink_dark"),
        (np.zeros(20, np.float32), GOOD_POINTS, GOOD_DIAMETERS, "ink_dark"),
        (np.zeros((20, 20, 3), np.float32), GOOD_POINTS, GOOD_DIAMETERS, "ink_dark"),
        (GOOD_IMAGE, np.zeros((2, 3)), GOOD_DIAMETERS, "points"),
        (GOOD_IMAGE, np.zeros(4), GOOD_DIAMETERS, "points"),
        (GOOD_IMAGE, GOOD_POINTS, np.array([4.0]), "diameters"),
        (GOOD_IMAGE, GOOD_POINTS, np.array([[4.0, 4.0]]), "diameters"),
        (GOOD_IMAGE, np.array([[10.0, np.nan], [5.0, 5.0]]), GOOD_DIAMETERS, "point 0"),
        (GOOD_IMAGE, np.array([[10.0, 10.0], [np.inf, 5.0]]), GOOD_DIAMETERS, "point 1"),
        (GOOD_IMAGE, GOOD_POINTS, np.array([4.0, -1.0]), "diameter 1"),
        (GOOD_IMAGE, GOOD_POINTS, np.array([np.nan, 4.0]), "diameter 0"),
        (GOOD_IMAGE, GOOD_POINTS, np.array([4.0, np.inf]), "diameter 1"),
        (np.full((20, 20), "a"), GOOD_POINTS, GOOD_DIAMETERS, "ink_dark"),
    ],
)
def test_bad_input_is_a_value_error(
    image: NDArray[np.generic], points: F64, diameters: F64, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        refine_centres(image, points, diameters)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=message):
        _core.refine_dot_centres(image, points, diameters)
