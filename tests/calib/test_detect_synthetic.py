"""Board detection on rendered scenes with exact truth (planarcal.synth)."""

from __future__ import annotations

import dataclasses
import re

import cv2
import numpy as np
import pytest

import planarcal
from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.detect import conic_centre_offset, detect_board
from planarcal.errors import BoardNotFoundError, BoardTurnedError

BOARD = synth.PAPER_BOARD


def _errors(points: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.asarray(
        np.linalg.norm(points[:, None] - truth[None], axis=2).min(axis=1), dtype=np.float64
    )


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e**2)))


@pytest.mark.parametrize(
    ("tilt", "blur", "noise", "light"),
    [(0, 0.7, 0.0, 0.0), (0, 1.5, 3.0, 0.4), (30, 0.7, 0.0, 0.0), (30, 1.5, 3.0, 0.4)],
)
def test_centres_are_at_least_as_accurate_as_findcirclesgrid(
    tilt: float, blur: float, noise: float, light: float
) -> None:
    """Tilt up to 30 degrees, blur, noise, uneven lighting: every centre within a few
    hundredths of a pixel of the truth, and no worse than OpenCV's (benches/
    bench_detection.py runs the whole table)."""
    pose = synth.PlanePose(distance_mm=520, tilt_deg=tilt, tilt_axis_deg=20, look_at_mm=(130, 90))
    scene = synth.render_scene(
        synth.CameraModel(),
        pose,
        board=BOARD,
        blur_sigma_px=blur,
        noise_sigma=noise,
        lighting_gradient=light,
        vignette=0.2 if light else 0.0,
        seed=3,
    )
    ours = _errors(detect_board(scene.image, BOARD).image_points, scene.dot_centres_px)
    found, cv_pts = cv2.findCirclesGrid(scene.image, (14, 10), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
    assert found
    theirs = _errors(cv_pts.reshape(-1, 2).astype(np.float64), scene.dot_centres_px)
    assert _rms(ours) <= _rms(theirs)
    assert _rms(ours) < 0.02 and ours.max() < 0.05


def test_the_papers_scene_through_a_distorting_lens() -> None:
    scene = synth.paper_scene(seed=0).calibration
    det = detect_board(scene.image, BOARD)
    errors = _errors(det.image_points, scene.dot_centres_px)
    assert _rms(errors) < 0.02
    # The lens bends the grid, which no homography follows: residuals like the paper's.
    assert 0.3 < det.residual_rms_px < 1.0


def test_conic_offset_is_the_centre_of_the_projected_circle() -> None:
    """Against brute force: the centroid of the polygon of many projected circle points."""
    h = np.array([[1.9, 0.2, 150.0], [-0.1, 1.7, 120.0], [8e-4, 5e-4, 1.0]])
    centres = np.array([[0.0, 0.0], [120.0, 40.0], [260.0, 180.0]])
    offsets = conic_centre_offset(h, centres, np.array([10.0, 10.0, 16.0]))
    t = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    for (cx, cy), d, off in zip(centres, (10.0, 10.0, 16.0), offsets, strict=True):
        ring = np.column_stack([cx + d / 2 * np.cos(t), cy + d / 2 * np.sin(t)])
        img = planarcal.transform_points(h, ring)
        x, y = img[:, 0], img[:, 1]
        cross = x * np.roll(y, -1) - np.roll(x, -1) * y
        area = cross.sum() / 2
        centroid = np.array(
            [((x + np.roll(x, -1)) * cross).sum(), ((y + np.roll(y, -1)) * cross).sum()]
        ) / (6 * area)
        projected = planarcal.transform_points(h, np.array([[cx, cy]]))[0]
        assert np.allclose(off, centroid - projected, atol=1e-6)
        assert np.hypot(*off) > 1e-3  # the bias is real under perspective
    # No perspective, no bias.
    affine = np.array([[2.0, 0.3, 5.0], [0.1, 1.5, 7.0], [0.0, 0.0, 1.0]])
    assert np.abs(conic_centre_offset(affine, centres, np.full(3, 10.0))).max() < 1e-12


def test_origin_marker_fixes_the_order_whatever_the_view() -> None:
    board = CircleGridBoard(9, 6, 25.0, 12.0, origin_marker=True)
    for roll in (0.0, 100.0, 200.0, 290.0):
        pose = synth.PlanePose(distance_mm=450, tilt_deg=12, roll_deg=roll, look_at_mm=(100, 62))
        scene = synth.render_scene(
            synth.CameraModel(), pose, board=board, blur_sigma_px=0.8, noise_sigma=1.0, seed=2
        )
        det = detect_board(scene.image, board)
        # With the marker the order is the board's own: compare point by point.
        assert np.abs(det.image_points - scene.dot_centres_px).max() < 0.05, roll


def test_a_mirrored_marker_board_is_refused() -> None:
    board = CircleGridBoard(9, 6, 25.0, 12.0, origin_marker=True)
    pose = synth.PlanePose(distance_mm=450, tilt_deg=5, look_at_mm=(100, 62))
    scene = synth.render_scene(synth.CameraModel(), pose, board=board, blur_sigma_px=0.8, seed=2)
    with pytest.raises(BoardNotFoundError, match="mirrored"):
        detect_board(scene.image[:, ::-1], board)


def test_a_board_turned_a_quarter_is_refused_unless_accepted() -> None:
    """A 14 x 10 board without a marker seen turned by 90 degrees: the usual cause is --cols
    and --rows swapped, so it is refused with the command line that reads it as given;
    turned=True accepts it and reads it the board's way."""
    pose = synth.PlanePose(distance_mm=560, roll_deg=90, look_at_mm=(130, 90))
    scene = synth.render_scene(synth.CameraModel(), pose, board=BOARD, blur_sigma_px=0.8, seed=4)
    with pytest.raises(BoardTurnedError, match="Did you mean --cols 10 --rows 14") as err:
        detect_board(scene.image, BOARD)
    assert isinstance(err.value, BoardNotFoundError) and isinstance(err.value, ValueError)
    assert err.value.diagnostics is not None
    swapped = detect_board(scene.image, CircleGridBoard(10, 14, 20.0, 10.0))
    assert swapped.orientation == "ambiguous"
    det = detect_board(scene.image, BOARD, turned=True)
    assert any("turned" in w for w in det.warnings)
    assert _errors(det.image_points, scene.dot_centres_px).max() < 0.03
    grid = det.image_points.reshape(10, 14, 2)
    # Rows of 14 dots: along a row, neighbouring dots are one pitch apart in the world.
    world = det.world_points().reshape(10, 14, 2)
    h = planarcal.estimate_homography(det.world_points(), det.image_points)
    assert (
        np.abs(planarcal.transform_points(h, world.reshape(-1, 2)) - grid.reshape(-1, 2)).max()
        < 0.05
    )


def test_light_dots_on_a_dark_board() -> None:
    pose = synth.PlanePose(distance_mm=520, tilt_deg=10, look_at_mm=(130, 90))
    scene = synth.render_scene(
        synth.CameraModel(),
        pose,
        board=BOARD,
        light_on_dark=True,
        blur_sigma_px=0.8,
        noise_sigma=1.0,
        seed=5,
    )
    det = detect_board(scene.image, BOARD)
    assert det.polarity == "light"
    assert _rms(_errors(det.image_points, scene.dot_centres_px)) < 0.02


def test_a_board_partly_out_of_view_is_refused() -> None:
    pose = synth.PlanePose(distance_mm=420, look_at_mm=(300, 90))  # 110 of 140 dots in view
    scene = synth.render_scene(synth.CameraModel(), pose, board=BOARD, blur_sigma_px=0.8, seed=6)
    assert scene.dots_in_view(margin_px=0).sum() < BOARD.n_points
    with pytest.raises(BoardNotFoundError, match="fewer dots than the board has"):
        detect_board(scene.image, BOARD)


def test_a_board_without_the_origin_marker_described_is_refused_for_its_marker() -> None:
    # The paper's board has no marker: described with one, its whole grid is seen and only
    # the marker is missing, so the refusal says so, not "check the board's size".
    scene = synth.paper_scene(seed=7, objects=False).calibration
    marked = dataclasses.replace(BOARD, origin_marker=True)
    with pytest.raises(BoardNotFoundError) as refused:
        detect_board(scene.image, marked)
    message = str(refused.value)
    assert message.startswith(
        "the 14 x 10 circle grid (140 dots) was found in the 1280 x 720 image, but not its "
        "origin marker (an enlarged corner dot)."
    ), message
    assert "Try: if the board has no origin marker, use --no-origin-marker" in message
    assert "origin_marker=False in Python" in message
    assert "board's size" not in message and "no 14 x 10 circle grid" not in message


def test_dots_that_cannot_be_measured_are_named_by_their_index_on_the_board() -> None:
    """The paper's board turned by 180 degrees in the image, cut just past its leftmost dot:
    the dots the border cuts keep a coarser centre, and the warning names them by their index
    in the board's reading (k = row x cols + col, as every output numbers them), the dots at
    the left edge of the image; it named them in the order the finder met them (issue 21)."""
    scene = synth.paper_scene(seed=0, objects=False).calibration
    turned = np.ascontiguousarray(scene.image[::-1, ::-1])
    whole = detect_board(turned, BOARD)
    left = int(np.argmin(whole.image_points[:, 0]))
    edge = whole.image_points[left, 0] - 0.5 * whole.dot_diameters_px[left]
    cut = np.ascontiguousarray(turned[:, int(edge - 1.5) :])
    det = detect_board(cut, BOARD)
    (warning,) = [w for w in det.warnings if "could not be measured" in w]
    named = [int(k) for k in re.findall(r"dot (\d+): cut by the image border", warning)]
    assert named and set(named) <= set(np.flatnonzero(~det.refined).tolist())
    pitch = det.pitch_px
    for k in named:
        assert det.image_points[k, 0] < pitch, (k, det.image_points[k])  # at the left edge
