"""The coverage figure (report/coverage.py): the image dimmed under the predicted error, the
placements outlined, the largest region above the limit outlined in red where the predicted
error crosses the limit; at the image's own size from 640 x 480 to 4K, and in the report."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from conftest import decode_png
from planarcal import report, synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.calib.coverage import Coverage, calibration_coverage, coverage
from planarcal.calib.detection import detect_board
from planarcal.calib.extrapolation import inside_hull
from planarcal.report.coverage import (
    REGION_BGR,
    coverage_figure,
    draw_coverage,
    placement_labels,
)

BOARD = ChessboardBoard(9, 6, 20.0)


def _seen(width: int, height: int, origin_mm: tuple[float, float] = (0.0, 0.0)) -> Any:
    """The board in the top-left of a `width` x `height` view (the same field of view)."""
    camera = synth.CameraModel(width=width, height=height, focal_px=1070.0 * width / 1280)
    x0, y0, x1, y1 = BOARD.ink().field
    look = ((x0 + x1) / 2 + 230.0, (y0 + y1) / 2 + 120.0)
    pose = synth.PlanePose(distance_mm=700.0, tilt_deg=10.0, look_at_mm=look)
    return synth.render_scene(
        camera, pose, board=BOARD, board_origin_mm=origin_mm, noise_sigma=1.0, supersample=4
    )


@pytest.fixture(scope="module")
def views() -> dict[tuple[int, int], tuple[Calibration, Any]]:
    """Calibrations and their images at 640 x 480, 1280 x 720 and 4K (the 1280 x 720 one
    made for a 3840 x 2160 camera, its image enlarged: rendering 4K takes seconds)."""
    out = {}
    for size in ((640, 480), (1280, 720)):
        scene = _seen(*size)
        out[size] = (Calibration.from_detection(detect_board(scene.image, BOARD)), scene.image)
    cal, image = out[(1280, 720)]
    big = cv2.resize(image, (3840, 2160), interpolation=cv2.INTER_CUBIC)
    out[(3840, 2160)] = (cal.for_frame_size(3840, 2160), big)
    return out


def _red(picture: Any) -> Any:
    """Where the figure is the region's colour, exactly."""
    return (picture == np.array(REGION_BGR, np.uint8)).all(axis=2)


@pytest.mark.parametrize("size", [(640, 480), (1280, 720), (3840, 2160)], ids=str)
def test_the_figure_outlines_the_region_where_the_error_crosses_the_limit(
    views: dict[tuple[int, int], tuple[Calibration, Any]], size: tuple[int, int]
) -> None:
    cal, image = views[size]
    w, h = size
    full = calibration_coverage(cal)
    limit = float(np.quantile(full.std_mm, 0.75))  # a quarter of the image above it
    cov = calibration_coverage(cal, limit)
    region = cov.region
    assert region is not None and region.part == "bottom-right corner"
    picture = decode_png(coverage_figure(cal, image, max_error_mm=limit))
    assert picture.shape == (h, w, 3)
    red = _red(picture)
    ys, xs = np.nonzero(red)
    x0, y0, x1, y1 = region.bbox_px
    inside = (xs >= x0) & (xs < x1) & (ys >= y0) & (ys < y1)
    s = max(w, h) / 1280
    assert inside.sum() > 300 * s  # the outline, a few px thick, across the region
    # The red pixels away from the cross at the target and the scale's limit mark lie on
    # the limit's contour: the predicted error there is the limit.
    tx, ty = region.target_px
    on_map = inside & (np.hypot(xs - tx, ys - ty) > 30 * s)
    px = np.column_stack([xs[on_map], ys[on_map]]).astype(float)
    ratio = cov.std_at(px) / limit
    assert np.median(np.abs(ratio - 1)) < 0.03 and np.quantile(np.abs(ratio - 1), 0.95) < 0.1
    # None on the board, where the error is smallest.
    assert not inside_hull(cov.outlines_px[0], np.column_stack([xs, ys]).astype(float)).any()
    # The board shows through, dimmed: its squares are there under the map (inside its
    # outline, away from the outline and the label's panel).
    hull = np.zeros((h, w), np.uint8)
    cv2.fillConvexPoly(hull, np.rint(cov.outlines_px[0]).astype(np.int32), 1)
    board = cv2.erode(hull, np.ones((3, 3), np.uint8), iterations=int(6 * s)).astype(bool)
    rows, cols = np.nonzero(board & (picture == 255).all(axis=2))
    label = np.zeros_like(board)
    label[rows.min() - int(6 * s) : rows.max() + int(6 * s), cols.min() : cols.max() + 1] = True
    board &= ~label
    grey = cv2.cvtColor(picture, cv2.COLOR_BGR2GRAY)[board].astype(float)
    source = np.asarray(image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY))
    assert board.sum() > 2000 * s**2
    assert np.corrcoef(grey, source[board].astype(float))[0, 1] > 0.8


def test_without_a_region_nothing_is_outlined_and_text_scales_with_the_image(
    views: dict[tuple[int, int], tuple[Calibration, Any]],
) -> None:
    heights = {}
    for size, (cal, image) in views.items():
        cov = calibration_coverage(cal, 2.0 * calibration_coverage(cal).image_std_mm)
        assert cov.region is None
        picture = decode_png(coverage_figure(cal, image, max_error_mm=cov.limit_mm))
        assert picture.shape == (size[1], size[0], 3)
        # Only the scale's limit mark is red (the limit is beyond the scale: none).
        assert _red(picture).sum() == 0
        heights[size] = _title_height(picture)
    # The title's panel grows with the image (its text scaled to it).
    assert heights[(3840, 2160)] > 2.5 * heights[(1280, 720)]
    assert heights[(640, 480)] >= 0.8 * heights[(1280, 720)]  # no smaller than legible


def _title_height(picture: Any) -> int:
    """The height of the white panel at the top-left (the title), px."""
    h, w = picture.shape[:2]
    white = (picture == 255).all(axis=2).astype(np.uint8)
    _, _, stats, _ = cv2.connectedComponentsWithStats(white, connectivity=8)
    x, y, _, height, area = stats[1:].T  # the panels' white, around their dark text
    at_top_left = (x < w / 10) & (y < h / 10)
    assert at_top_left.any()
    return int(height[at_top_left][np.argmax(area[at_top_left])])


def test_placements_are_numbered_with_short_names() -> None:
    scenes = [_seen(1280, 720, o) for o in ((0.0, 0.0), (330.0, 170.0))]
    dets = [detect_board(s.image, BOARD) for s in scenes]
    named = Calibration.from_detections(dets, names=["corner", "a-name-far-too-long-to-draw"])
    assert placement_labels(named) == ["0 corner", "1"]
    assert placement_labels(Calibration.from_detections(dets)) == ["0", "1"]
    bare = Calibration(named.world_points, named.image_points, image_size=(1280, 720))
    assert placement_labels(bare) == ["0"]
    # Both placements outlined in white, each with its label on a white panel.
    picture = decode_png(coverage_figure(named, scenes[1].image))
    white = (picture == 255).all(axis=2)
    for det in dets:
        (x0, y0), (x1, y1) = det.image_points.min(axis=0), det.image_points.max(axis=0)
        assert white[int(y0) - 5 : int(y1) + 5, int(x0) - 5 : int(x1) + 5].sum() > 500


def test_a_coverage_drawn_on_no_image_and_with_no_place() -> None:
    """Without an image, on grey; the part with no place on the plane left uncoloured."""
    w, h = 640, 480
    square = np.array([[100.0, 100.0], [220.0, 100.0], [220.0, 220.0], [100.0, 220.0]])

    def std(px: Any) -> Any:
        out = 0.01 + 0.001 * np.hypot(px[:, 0] - 160, px[:, 1] - 160)
        out[px[:, 0] > 560] = np.inf
        return out

    cov: Coverage = coverage(std, (w, h), [square], 0.3)
    picture = draw_coverage(None, cov)
    assert picture.shape == (h, w, 3) and picture.dtype == np.uint8
    # Beyond x = 560: the grey background, dimmed, uncoloured (b = g = r).
    right = picture[300:400, 580:600].astype(int)
    assert (right[:, :, 0] == right[:, :, 1]).all() and (right[:, :, 1] == right[:, :, 2]).all()
    left = picture[300:400, 300:320].astype(int)
    assert (left[:, :, 0] != left[:, :, 2]).any()  # coloured


def test_the_report_writes_the_coverage_figure(
    views: dict[tuple[int, int], tuple[Calibration, Any]], tmp_path: Path
) -> None:
    cal, image = views[(640, 480)]
    written = report.write_report(cal, tmp_path / "r", image=image, max_error_mm=0.2)
    path = tmp_path / "r" / "coverage.png"
    assert path in written
    picture = cv2.imread(str(path))
    assert picture is not None and picture.shape == (480, 640, 3)
    bare = Calibration(cal.world_points, cal.image_points)  # no image size: no image to cover
    names = {p.name for p in report.write_report(bare, tmp_path / "bare")}
    assert "coverage.png" not in names and "uncertainty.png" in names
