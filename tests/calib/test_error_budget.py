"""The error budget (planarcal.calib.error_budget): std_mm covers what really moves a mapped
point, against the truth of rendered scenes whose lens has its distortion centre off the
image centre and tangential terms; and each term of the budget measures what it says."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.calib.error_budget import (
    dot_centroid_shift_px,
    error_budget,
    shared_residual_sigma_px,
)
from planarcal.errors import ArgumentError
from planarcal.synth.webcam import random_webcam_scene

BOARD = synth.PAPER_BOARD
SPAN = np.array([(BOARD.cols - 1) * BOARD.pitch, (BOARD.rows - 1) * BOARD.pitch])


def rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(a))))


def board_ratio(cal: Calibration, scene: synth.RenderedScene, plane: object = None) -> float:
    """RMS actual error / RMS predicted 1-sigma at 2,000 random exact pixels over the board
    (through `plane`, a FittedPlane, instead of the calibration's own when given)."""
    truth = np.random.default_rng(0).uniform(0.0, 1.0, (2000, 2)) * SPAN
    px = scene.project(truth)
    if plane is None:
        mm, std = cal.image_to_world(px, return_std=True, pixel_sigma=0.0)
    else:
        mm, std = plane.image_to_world_std(px, 0.0)  # type: ignore[attr-defined]
    return rms(np.hypot(*(mm - truth).T)) / rms(std)


@pytest.fixture(scope="module")
def webcam() -> list[tuple[synth.PaperScene, Calibration]]:
    """Two small webcam scenes (640 x 480): distortion centres 20 and 32 px off the image
    centre, k2 and tangential terms, the paper scene's blur, noise and lighting."""
    out = []
    for seed in (1, 5):
        pair = random_webcam_scene(seed, size=(640, 480))
        out.append((pair, Calibration.from_detection(detect_board(pair.calibration.image, BOARD))))
    return out


def test_board_points_error_bars_cover_the_actual_error(
    webcam: list[tuple[synth.PaperScene, Calibration]],
) -> None:
    for pair, cal in webcam:
        ratio = board_ratio(cal, pair.calibration)
        # Measured: 0.98 and 1.06 (the fit's covariance alone: 1.93 and 1.72).
        assert 0.67 <= ratio <= 1.5, (ratio, cal.error_budget)
        alone = board_ratio(cal, pair.calibration, cal._fit.plane.with_model_sigma(0.0))
        assert alone > 1.5 and alone > 1.4 * ratio


def test_located_parts_error_bars_cover_the_actual_error(
    webcam: list[tuple[synth.PaperScene, Calibration]],
) -> None:
    from planarcal.live.objects import locate_objects  # noqa: PLC0415 (live is above calib)

    actual, predicted = [], []
    for pair, cal in webcam:
        truth = pair.objects.object_centroids_mm
        for o in locate_objects(pair.objects.image, cal):
            assert o.world_mm is not None and o.world_std_mm is not None
            gap = np.hypot(*(truth - np.array(o.world_mm)).T)
            assert gap.min() < 1.0
            actual.append(gap.min())
            predicted.append(o.world_std_mm)
    # 23 parts; measured 1.14 (with the fit's covariance alone it was about 20).
    ratio = rms(np.array(actual)) / rms(np.array(predicted))
    assert 0.67 <= ratio <= 1.5, ratio


def test_the_budget_is_in_the_production_path_and_survives_a_file(
    webcam: list[tuple[synth.PaperScene, Calibration]], tmp_path: Path
) -> None:
    pair, cal = webcam[0]
    budget = cal.error_budget
    assert budget.model_sigma_px > 0
    assert cal._fit.plane.model_sigma_px == budget.model_sigma_px
    px = pair.calibration.dot_centres_px
    mm, std = cal.image_to_world(px, return_std=True)
    loop_mm, loop_std = cal._frame_mapper()(px, len(px))
    np.testing.assert_array_equal(loop_mm, mm)
    np.testing.assert_array_equal(loop_std, std)
    # Recomputed from the stored points on load: the same budget, the same bars.
    path = cal.save(tmp_path / "calib.json")
    again = Calibration.load(path)
    assert again.error_budget.to_dict() == pytest.approx(budget.to_dict(), rel=1e-9)
    np.testing.assert_allclose(again.image_to_world(px, return_std=True)[1], std, rtol=1e-12)
    with pytest.raises(ArgumentError, match="model_sigma_px"):
        cal._fit.plane.with_model_sigma(-1.0)


def _exact_points(camera: synth.CameraModel, pose: synth.PlanePose) -> tuple[np.ndarray, ...]:
    world = BOARD.world_points()
    return world, camera.project(world, pose)


POSE = synth.PlanePose(560.0, tilt_deg=3.0, tilt_axis_deg=40.0, look_at_mm=(130.0, 90.0))


def test_a_lens_the_model_can_follow_has_no_lens_bias() -> None:
    """Exact dot centres through a lens the model fits (k1, k2, centred): the residuals are
    rounding, the lens model's bias nothing; with detector-like white noise added, it stays
    a small fraction of the noise (the noise is not shared by neighbours)."""
    camera = synth.CameraModel(k1=-0.12, k2=0.03)
    world, image = _exact_points(camera, POSE)
    exact = Calibration(world, image, lens="k1k2", image_size=(1280, 720), board=BOARD)
    assert exact.error_budget.lens_bias_px < 1e-6
    noisy_image = image + np.random.default_rng(3).normal(0.0, 0.02, image.shape)
    noisy = Calibration(world, noisy_image, lens="k1k2", image_size=(1280, 720), board=BOARD)
    assert noisy.error_budget.lens_bias_px < 0.005


def test_an_unmodellable_lens_gives_a_bias_near_the_actual_error() -> None:
    """Exact dot centres through a lens the forced model cannot follow (its centre 40 px
    off, tangential terms; the model k1 assumes the image centre): the lens model's bias
    term is what makes the error bars cover the actual error."""
    camera = synth.CameraModel(principal=(668.0, 387.0), k1=-0.15, k2=0.03, p1=1e-3, p2=-1e-3)
    world, image = _exact_points(camera, POSE)
    cal = Calibration(world, image, lens="k1", image_size=(1280, 720), board=BOARD)
    budget = cal.error_budget
    assert budget.lens_bias_px > 10 * budget.dot_bias_px
    truth = np.random.default_rng(1).uniform(0.0, 1.0, (2000, 2)) * SPAN
    mm, std = cal.image_to_world(camera.project(truth, POSE), return_std=True, pixel_sigma=0.0)
    ratio = rms(np.hypot(*(mm - truth).T)) / rms(std)
    assert 0.67 <= ratio <= 1.5, (ratio, budget)
    # The fit's covariance alone flatters (the residuals are the bias, not noise).
    _, alone = cal._fit.plane.with_model_sigma(0.0).image_to_world_std(camera.project(truth, POSE))
    assert rms(np.hypot(*(mm - truth).T)) / rms(alone) > 2.0


def test_the_dots_lens_bias_is_the_detectors_error() -> None:
    """On a sharp, noiseless render through a strong lens, the detected dot centres differ
    from the true projections of the dots' centres by the shift the budget computes (the
    lens's uneven magnification of each dot), in size and direction."""
    camera = synth.CameraModel(width=640, height=480, focal_px=560.0, k1=-0.3, k2=0.08)
    board = CircleGridBoard(cols=9, rows=6, pitch=25.0, diameter=15.0)
    pose = synth.PlanePose(250.0, look_at_mm=(100.0, 62.5))
    scene = synth.render_scene(camera, pose, board=board)
    detection = detect_board(scene.image, board)
    world = detection.world_points()
    error = detection.image_points - camera.project(world, pose)
    centre, f = np.array([camera.cx, camera.cy]), camera.focal_px
    shift = dot_centroid_shift_px(
        camera.homography(pose),
        lambda p: camera.distort((p - centre) / f) * f + centre,
        world,
        board.dot_diameters(),
    )
    assert rms(shift) > 0.01  # the effect is there to be seen
    cos = np.sum(error * shift) / np.sqrt(np.sum(error**2) * np.sum(shift**2))
    assert cos > 0.8, cos
    assert 0.7 < rms(error) / rms(shift) < 1.4
    # Without distortion there is no such shift (perspective is the detector's to correct).
    flat = dataclasses.replace(camera, k1=0.0, k2=0.0)
    none = dot_centroid_shift_px(flat.homography(pose), lambda p: p, world, board.dot_diameters())
    assert rms(none) < 1e-9


def test_shared_residuals_are_the_field_not_the_noise() -> None:
    grid = np.mgrid[0:14, 0:10].reshape(2, -1).T * 20.0
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 0.1, grid.shape)
    assert shared_residual_sigma_px(grid, noise) < 0.03
    field = np.column_stack([np.sin(grid[:, 0] / 60.0), np.cos(grid[:, 1] / 50.0)]) * 0.1
    both = shared_residual_sigma_px(grid, field + 0.5 * noise)
    assert both == pytest.approx(rms(field), rel=0.25)
    assert shared_residual_sigma_px(grid[:2], field[:2]) == 0.0


def test_bare_points_guess_the_dot_size_from_their_spacing() -> None:
    camera = synth.CameraModel(k1=-0.12, k2=0.03)
    world, image = _exact_points(camera, POSE)
    with_board = Calibration(world, image, lens="k1k2", image_size=(1280, 720), board=BOARD)
    bare = Calibration(world, image, lens="k1k2", image_size=(1280, 720))
    # The paper board's dots are half its pitch: the guess is the board's own size.
    assert bare.error_budget.dot_bias_px == pytest.approx(
        with_board.error_budget.dot_bias_px, rel=1e-9
    )
    assert error_budget(bare._fit, world, image, None, None) == bare.error_budget
