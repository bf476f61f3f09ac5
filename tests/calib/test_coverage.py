"""The coverage view (calib.coverage): the predicted error over the whole image, the
placements' outlines and the largest region above a limit, on calibrations of rendered boards
found by the board's own detector; and, for what a calibration cannot easily show (several
placements' union, pixels with no place), the function itself with a predicted error given."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from planarcal import synth
from planarcal.arguments import F64
from planarcal.calib.calibration import Calibration
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.calib.coverage import (
    DEFAULT_LIMIT_FACTOR,
    MAP_NODES,
    Coverage,
    calibration_coverage,
    coverage,
    map_grid,
)
from planarcal.calib.detection import detect_board
from planarcal.calib.extrapolation import convex_hull, inside_hull
from planarcal.errors import ArgumentError

BOARD = ChessboardBoard(9, 6, 20.0)
CAMERA = synth.CameraModel(k1=-0.05)  # 1280 x 720, a little barrel distortion
SIZE = (CAMERA.width, CAMERA.height)


def _render(origin_mm: tuple[float, float] = (0.0, 0.0)) -> Any:
    """The board seen from 700 mm, the camera looking 230 mm right and 120 mm down of the
    board's middle: with the board at the origin it lies in the image's top-left corner."""
    x0, y0, x1, y1 = BOARD.ink().field
    look = ((x0 + x1) / 2 + 230.0, (y0 + y1) / 2 + 120.0)
    pose = synth.PlanePose(distance_mm=700.0, tilt_deg=10.0, look_at_mm=look)
    return synth.render_scene(
        CAMERA,
        pose,
        board=BOARD,
        board_origin_mm=origin_mm,
        noise_sigma=1.0,
        blur_sigma_px=0.7,
        supersample=4,
        seed=1,
    )


@pytest.fixture(scope="module")
def corner() -> Calibration:
    """A calibration from the board found in the image's top-left corner."""
    detection = detect_board(_render().image, BOARD)
    pts = detection.image_points
    assert pts[:, 0].max() < SIZE[0] / 3 and pts[:, 1].max() < SIZE[1] / 2  # the premise
    return Calibration.from_detection(detection)


def _exact_std(cal: Calibration, px: F64) -> F64:
    _, std = cal.image_to_world(px, return_std=True, pixel_sigma=0.0)
    return np.asarray(std, np.float64)


# -- one placement in a corner ---------------------------------------------------------------


def test_a_board_in_the_top_left_leaves_the_bottom_right_above_the_limit(
    corner: Calibration,
) -> None:
    full = calibration_coverage(corner)
    # A limit that only the worst fifth of the image is above.
    limit = float(np.quantile(full.std_mm, 0.8))
    cov = calibration_coverage(corner, limit)
    r = cov.region
    assert r is not None and cov.limit_mm == limit and cov.limit_given
    w, h = SIZE
    # On the far side: a strip down the right edge, widest at the bottom, where the board
    # goes next.
    assert r.bbox_px[2:] == (w, h) and r.bbox_px[1] == 0 and r.bbox_px[0] > w / 2
    assert r.centroid_px[0] > w / 2 and r.centroid_px[1] > h / 2
    assert r.name == "right edge" and r.part == "bottom-right corner"
    tx, ty = r.target_px
    assert tx > 2 * w / 3 and ty > 2 * h / 3
    # The target is in the region, and far enough in for a board like the one laid.
    assert cov.std_at([r.target_px])[0] > limit
    assert r.worst_std_mm == pytest.approx(cov.image_std_mm)
    assert r.worst_at_px == (w - 1.0, h - 1.0)
    assert 0.1 < r.share < 0.3
    # Nowhere near the board: no node inside its outline is in the region.
    xs, ys = np.meshgrid(cov.grid_x, cov.grid_y)
    inside = inside_hull(cov.outlines_px[0], np.column_stack([xs.ravel(), ys.ravel()]))
    assert inside.any() and not r.mask.ravel()[inside].any()
    # Every node of the region is above the limit; the largest other region (none here).
    assert (cov.std_mm[r.mask] > limit).all()
    assert (cov.std_mm > limit).sum() == r.mask.sum()
    # The sentence says where, how large, how bad, against which limit.
    x0, y0, x1, y1 = r.bbox_px
    assert cov.sentence.startswith(
        f"the right edge of the image (x {x0}-{x1} px, y {y0}-{y1} px, "
        f"{100 * r.share:.0f} % of the image): predicted error up to "
    )
    assert (
        f"{float(f'{limit:.2g}'):g} mm limit; put the board in its bottom-right corner next"
        in cov.sentence
    )
    assert f"centred near ({tx:.0f}, {ty:.0f}) px" in cov.sentence


def test_the_default_limit_is_twice_the_error_at_the_points(corner: Calibration) -> None:
    cov = calibration_coverage(corner)
    at_points = _exact_std(corner, corner.image_points).max()
    assert cov.points_std_mm == pytest.approx(at_points, rel=1e-9)
    assert cov.limit_mm == pytest.approx(DEFAULT_LIMIT_FACTOR * at_points, rel=1e-9)
    assert not cov.limit_given and "(2 x the error at the points)" in cov.sentence
    # A board in one corner leaves most of the image worse than that.
    r = cov.region
    assert r is not None and r.share > 0.5 and r.part == "bottom-right corner"
    assert cov.sentence.startswith("most of the image (x 0-1280 px, y 0-720 px, ")
    assert "put the board in its bottom-right corner next" in cov.sentence
    json.dumps(cov.to_dict(), allow_nan=False)
    assert cov.to_dict()["region"]["part"] == "bottom-right corner"


def test_a_limit_above_every_error_leaves_no_region(corner: Calibration) -> None:
    worst = calibration_coverage(corner).image_std_mm
    assert math.isfinite(worst)
    cov = calibration_coverage(corner, 1.01 * worst)
    assert cov.region is None
    assert cov.sentence.startswith(f"the predicted error is within the {1.01 * worst:.2g} mm")
    assert "over the whole image" in cov.sentence
    assert cov.to_dict()["region"] is None


def test_the_map_is_the_calibrations_error_bars(corner: Calibration) -> None:
    cov = calibration_coverage(corner)
    w, h = SIZE
    # A grid finer than extrapolation's, the image's corners among its nodes.
    assert len(cov.grid_x) == MAP_NODES and cov.std_mm.shape == (len(cov.grid_y), MAP_NODES)
    assert (cov.grid_x[0], cov.grid_x[-1], cov.grid_y[0], cov.grid_y[-1]) == (0, w - 1, 0, h - 1)
    # At the nodes: image_to_world's own 1-sigma, the pixel exact.
    rng = np.random.default_rng(7)
    rows = rng.integers(0, len(cov.grid_y), 40)
    cols = rng.integers(0, len(cov.grid_x), 40)
    nodes = np.column_stack([cov.grid_x[cols], cov.grid_y[rows]])
    expected = _exact_std(corner, nodes)
    np.testing.assert_allclose(cov.std_mm[rows, cols], expected, rtol=1e-9)
    np.testing.assert_allclose(cov.std_at(nodes), expected, rtol=1e-9)
    # Between them, interpolated to well under 1 %.
    px = rng.uniform([0.0, 0.0], [w - 1.0, h - 1.0], (200, 2))
    np.testing.assert_allclose(cov.std_at(px), _exact_std(corner, px), rtol=0.005)
    # The full-resolution map is the same interpolation.
    image = cov.std_image()
    assert image.shape == (h, w)
    ij = np.rint(px).astype(int)
    np.testing.assert_allclose(image[ij[:, 1], ij[:, 0]], cov.std_at(ij.astype(float)))


def test_the_outline_and_covered_share_are_the_points(corner: Calibration) -> None:
    cov = calibration_coverage(corner)
    assert len(cov.outlines_px) == 1
    np.testing.assert_array_equal(cov.outlines_px[0], convex_hull(corner.image_points))
    ex = corner.extrapolation
    assert ex is not None
    assert cov.covered_share == pytest.approx(ex.covered_share, abs=0.002)


# -- several placements ----------------------------------------------------------------------


def test_several_placements_each_outlined_their_union_covered() -> None:
    dets = [detect_board(_render(o).image, BOARD) for o in ((0.0, 0.0), (330.0, 170.0))]
    cal = Calibration.from_detections(dets, names=["corner", "middle"])
    cov = calibration_coverage(cal)
    assert len(cov.outlines_px) == 2
    for outline, det in zip(cov.outlines_px, dets, strict=True):
        np.testing.assert_array_equal(outline, convex_hull(det.image_points))
    one = [calibration_coverage(Calibration.from_detection(d)).covered_share for d in dets]
    assert cov.covered_share == pytest.approx(sum(one), abs=0.002)  # apart: their sum
    # The second placement brings the error down far from the first.
    single = calibration_coverage(Calibration.from_detection(dets[0]))
    assert cov.image_std_mm < single.image_std_mm / 2
    # The same points twice cover no more than once.
    twice = coverage(cal.mapping_std_mm, SIZE, [dets[0].image_points] * 2)
    assert twice.covered_share == pytest.approx(one[0], abs=1e-12)


def _distance_std(placements: list[F64], per_px: float = 0.001) -> Callable[[F64], F64]:
    """A predicted error growing with the distance to the nearest placement's point."""
    points = np.concatenate(placements)

    def std(px: F64) -> F64:
        d = np.hypot(*(px[:, None, :] - points[None, :, :]).transpose(2, 0, 1))
        return np.asarray(0.01 + per_px * d.min(axis=1), np.float64)

    return std


def _square(cx: float, cy: float, half: float = 60.0) -> F64:
    t = np.linspace(-half, half, 5)
    gx, gy = np.meshgrid(cx + t, cy + t)
    return np.column_stack([gx.ravel(), gy.ravel()])


def test_placements_at_the_four_corners_leave_the_centre() -> None:
    w, h = 1280, 720
    placements = [_square(x, y) for x in (100.0, w - 101.0) for y in (100.0, h - 101.0)]
    cov = coverage(_distance_std(placements), (w, h), placements, 0.3)
    r = cov.region
    assert r is not None and r.part == "centre"
    assert abs(r.target_px[0] - (w - 1) / 2) < 20 and abs(r.target_px[1] - (h - 1) / 2) < 20
    assert r.bbox_px[0] > 0 and r.bbox_px[2] < w  # inside the image, not at its edges
    assert cov.sentence.startswith("the centre of the image (")


# Regions above a 1 mm limit, each made of the pixels (x, y) where its test holds, a little
# worse downwards and rightwards so that the board's target lies in a corner of a strip.
REGIONS: list[tuple[str, Callable[[F64, F64], Any], str, str]] = [
    ("left strip", lambda x, y: x < 220, "left edge", "bottom-left corner"),
    ("bottom strip", lambda x, y: y > 560, "bottom edge", "bottom-right corner"),
    (
        "right patch",
        lambda x, y: (x > 1100) & (y > 200) & (y < 600),
        "right edge",
        "bottom-right corner",
    ),
    ("corner", lambda x, y: np.hypot(x, y - 720) < 250, "bottom-left corner", "bottom-left corner"),
    # Along two sides, short of the far corners (else it reaches around the placements).
    (
        "L",
        lambda x, y: (x < 200) & (y > 40) | (y > 560) & (x < 1100),
        "bottom and left edges",
        "bottom-right corner",
    ),
    ("middle", lambda x, y: np.hypot(x - 640, y - 360) < 200, "centre", "centre"),
]


@pytest.mark.parametrize(
    ("above", "name", "part"), [r[1:] for r in REGIONS], ids=[r[0] for r in REGIONS]
)
def test_a_region_is_named_by_its_shape_and_the_board_sent_to_its_target(
    above: Callable[[F64, F64], Any], name: str, part: str
) -> None:
    # A strip down the left side was "the bottom-left corner" (its target's third).
    placement = [_square(700.0, 100.0)]

    def std(px: F64) -> F64:
        x, y = px[:, 0], px[:, 1]
        return np.asarray(np.where(above(x, y), 2.0 + 1e-3 * (x + y), 0.2), np.float64)

    r = coverage(std, (1280, 720), placement, 1.0).region
    assert r is not None and not r.spread
    assert (r.name, r.part) == (name, part)
    assert r.where().startswith(f"the {name} of the image (")
    where = "there" if name == part else f"{'at' if part.endswith('edge') else 'in'} its {part}"
    assert r.advice().startswith(f"put the board {where} next")


def test_pixels_with_no_place_count_as_above_any_limit() -> None:
    w, h = 640, 480
    placement = [_square(150.0, 240.0)]
    base = _distance_std(placement)

    def std(px: F64) -> F64:
        out = base(px)
        out[px[:, 0] > 560] = np.inf  # beyond the horizon
        out[(px[:, 0] > 540) & (px[:, 0] <= 560)] = np.nan  # NaN: no place either
        return out

    cov = coverage(std, (w, h), placement, 1e6)  # a limit nothing finite reaches
    r = cov.region
    assert r is not None and math.isinf(r.worst_std_mm)
    assert r.bbox_px[0] == pytest.approx(541, abs=4) and r.bbox_px[2] == w
    assert r.part == "right edge" and "no place on the plane" in cov.sentence
    assert math.isinf(cov.image_std_mm) and cov.to_dict()["image_std_mm"] is None
    json.dumps(cov.to_dict(), allow_nan=False)


def test_the_grid_keeps_a_fine_step_at_every_size() -> None:
    for size, step in (((640, 480), 4.0), ((1280, 720), 4.0), ((3840, 2160), 12.0)):
        xs, ys = map_grid(size)
        assert np.diff(xs).max() <= step + 1e-9 and np.diff(ys).max() <= step + 1e-9
        assert (xs[-1], ys[-1]) == (size[0] - 1, size[1] - 1)
    assert [len(a) for a in map_grid((1, 1))] == [1, 1]
    cov = coverage(lambda px: np.full(len(px), 0.5), (1, 1), [np.zeros((1, 2))], 1.0)
    assert cov.std_mm.shape == (1, 1) and cov.region is None
    assert cov.std_at([[0.0, 0.0], [5.0, 5.0]]).tolist() == [0.5, 0.5]


# -- bad arguments -----------------------------------------------------------------------------


def _flat(px: F64) -> F64:
    return np.full(len(px), 0.1)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((None, SIZE, [np.zeros((3, 2))]), "std_mm_at must be a function"),
        ((_flat, (1280,), [np.zeros((3, 2))]), "image_size must be"),
        ((_flat, (0, 720), [np.zeros((3, 2))]), "image_size must be two positive"),
        ((_flat, SIZE, []), "placements_px is empty"),
        ((_flat, SIZE, np.zeros((3, 2))), "placements_px must be a sequence"),
        ((_flat, SIZE, [np.zeros((0, 2))]), r"placements_px\[0\] has no points"),
        ((_flat, SIZE, [np.zeros((3, 2)), [[1.0, np.nan]]]), r"placements_px\[1\]: point 0"),
        ((_flat, SIZE, [np.zeros((3, 3))]), r"placements_px\[0\] must have shape"),
        ((_flat, SIZE, [np.zeros((3, 2))], 0.0), "max_error_mm must be positive"),
        ((_flat, SIZE, [np.zeros((3, 2))], "0.1"), "max_error_mm must be a number"),
        ((_flat, SIZE, [np.zeros((3, 2))], math.inf), "max_error_mm must be finite"),
        ((lambda px: np.zeros(3), SIZE, [np.zeros((3, 2))]), "one value per pixel"),
        ((lambda px: -_flat(px), SIZE, [np.zeros((3, 2))]), "a negative error"),
    ],
)
def test_bad_arguments_are_refused_naming_them(args: tuple[Any, ...], match: str) -> None:
    with pytest.raises(ArgumentError, match=match):
        coverage(*args)


def test_a_calibration_without_an_image_size_has_no_coverage(corner: Calibration) -> None:
    bare = Calibration(corner.world_points, corner.image_points)
    with pytest.raises(ArgumentError, match="no image size"):
        calibration_coverage(bare)
    with pytest.raises(ArgumentError, match="max_error_mm must be positive"):
        calibration_coverage(corner, -1.0)


def test_a_calibration_without_error_bars_finds_no_region(corner: Calibration) -> None:
    """Four points fit exactly: no error bars anywhere, nothing to compare with a limit."""
    pts = corner.image_points
    four = [int(np.argmin(pts.sum(1))), int(np.argmax(pts.sum(1)))]
    four += [int(np.argmin(pts[:, 0] - pts[:, 1])), int(np.argmax(pts[:, 0] - pts[:, 1]))]
    exact = Calibration(corner.world_points[four], pts[four], image_size=SIZE, lens="none")
    cov: Coverage = calibration_coverage(exact, 0.1)
    assert cov.region is None and math.isinf(cov.points_std_mm)
    assert cov.sentence.startswith("no predicted error")
    json.dumps(cov.to_dict(), allow_nan=False)
