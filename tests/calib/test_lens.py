"""Lens distortion from the one board image, the automatic model choice, uncertainty, the
printer-scale correction, and their files: on rendered scenes with exact truth."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.errors import BoardError, CalibrationFileError, LensModelError

BOARD = synth.PAPER_BOARD


def _world_error(cal: Calibration, scene: synth.RenderedScene, rng: np.random.Generator) -> float:
    """Mean mapping error (mm) at random points over the board, against the truth."""
    span = np.array([(BOARD.cols - 1) * BOARD.pitch, (BOARD.rows - 1) * BOARD.pitch])
    truth = rng.uniform(0.0, 1.0, (2000, 2)) * span
    return float(np.hypot(*(cal.image_to_world(scene.project(truth)) - truth).T).mean())


# The scenes fixture: each view, calibrated with the automatic lens model and without one.
Scenes = list[tuple[synth.RenderedScene, Calibration, Calibration]]


@pytest.fixture(scope="module")
def scenes() -> Scenes:
    """Three random views of the paper's setup, each calibrated with the automatic lens
    model and with a homography alone."""
    out = []
    for seed in (11, 12, 13):
        scene = synth.random_paper_scene(seed)
        det = detect_board(scene.image, BOARD)
        out.append(
            (scene, Calibration.from_detection(det), Calibration.from_detection(det, lens="none"))
        )
    return out


def test_the_lens_model_is_chosen_and_maps_to_a_hundredth_of_a_millimetre(scenes: Scenes) -> None:
    rng = np.random.default_rng(0)
    for scene, cal, plain in scenes:
        assert cal.lens_model in ("k1", "k1k2", "k1k2c"), cal.lens_note
        chosen = [c for c in cal.lens_candidates if c.verdict == "chosen"]
        assert [c.model for c in chosen] == [cal.lens_model]
        none = next(c for c in cal.lens_candidates if c.model == "none")
        assert chosen[0].loo_mean_px < 0.2 * none.loo_mean_px
        with_lens, alone = _world_error(cal, scene, rng), _world_error(plain, scene, rng)
        assert with_lens < 0.02, with_lens
        assert alone > 5 * with_lens
        # The lens found predicts the real pixels of the dots (distortion included) to a
        # few hundredths of a pixel, where the distortion moves them by pixels.
        lens = cal.lens
        assert lens is not None and lens.k1 < 0  # barrel
        pts = scene.project(scene.dot_centres_mm)
        assert np.abs(cal.world_to_image(scene.dot_centres_mm) - pts).max() < 0.05
        ideal = cal.ideal_points(pts)
        assert np.abs(lens.displacement_px(ideal)).max() > 1.0
        assert np.allclose(ideal + lens.displacement_px(ideal), pts, atol=1e-9)


def test_predicted_uncertainty_agrees_with_leave_one_out(scenes: Scenes) -> None:
    for _, cal, _ in scenes:
        s = cal.summary()
        ratio = s.loo_rms_mm / s.predicted_loo_rms_mm
        assert 1 / 1.5 < ratio < 1.5, (s.loo_rms_mm, s.predicted_loo_rms_mm)


def test_uncertainty_grows_away_from_the_board_and_with_pixel_noise(scenes: Scenes) -> None:
    scene, cal, _ = scenes[0]
    centre = scene.project(np.array([[130.0, 90.0]]))
    corner = scene.project(np.array([[0.0, 0.0]]))
    outside = scene.project(np.array([[-80.0, -60.0]]))
    stds = [cal.image_to_world(p, return_std=True)[1][0] for p in (centre, corner, outside)]
    assert 0 < stds[0] < stds[1] < stds[2]
    mm, sd = cal.image_to_world(centre[0], return_std=True)
    assert mm.shape == (2,) and isinstance(sd, float)
    _, noisy = cal.image_to_world(centre, return_std=True, pixel_sigma=0.1)
    assert noisy[0] > stds[0]
    cov = cal.world_covariance(centre)
    assert cov.shape == (1, 2, 2) and math.isclose(math.sqrt(np.trace(cov[0])), stds[0])


def test_a_small_board_gets_no_lens_model_and_says_why() -> None:
    board = CircleGridBoard(cols=6, rows=5, pitch=10.0, diameter=5.0)
    camera = synth.PAPER_CAMERA
    pose = synth.PlanePose(distance_mm=500.0, tilt_deg=2.0, look_at_mm=(25.0, 20.0))
    scene = synth.render_scene(camera, pose, board=board, blur_sigma_px=0.8, noise_sigma=2.0)
    cal = Calibration.from_detection(detect_board(scene.image, board))
    assert cal.lens_model == "none" and cal.lens is None
    assert "too little" in cal.lens_note and "reaches only" in cal.lens_note


def test_lens_options_are_checked(scenes: Scenes) -> None:
    _, cal, _ = scenes[0]
    w, i = cal.world_points, cal.image_points
    with pytest.raises(LensModelError, match="lens must be"):
        Calibration(w, i, lens="k3", image_size=(1280, 720))  # type: ignore[arg-type]
    with pytest.raises(LensModelError, match="image_size"):
        Calibration(w, i, lens="k1")
    with pytest.raises(LensModelError, match="Levenberg-Marquardt"):
        Calibration(w, i, lens="k1", solver="a33", refine=False, image_size=(1280, 720))
    # The paper's estimator fits no lens, whatever auto would choose.
    assert Calibration(w, i, solver="a33", refine=False, image_size=(1280, 720)).lens is None
    forced = Calibration(w, i, lens="k1", image_size=(1280, 720))
    assert forced.lens_model == "k1" and forced.lens is not None and forced.lens.k2 == 0.0


def test_pixels_beyond_the_lens_model_are_refused_not_mapped(scenes: Scenes) -> None:
    _, cal, _ = scenes[0]
    lens = cal.lens
    assert lens is not None
    far = np.array([[lens.centre_px[0] + 1e5, lens.centre_px[1]]])
    with pytest.raises(ValueError, match=r"beyond|horizon"):
        cal.image_to_world(far)
    with pytest.raises(ValueError, match="non-finite"):
        cal.image_to_world([[np.nan, 3.0]])
    with pytest.raises(ValueError, match="height"):
        cal.image_to_world(far, height=[1.0, 2.0])


def test_files_keep_the_lens_and_read_version_one(scenes: Scenes, tmp_path: Path) -> None:
    scene, cal, plain = scenes[0]
    back = Calibration.load(cal.save(tmp_path / "c.json"))
    px = scene.project(np.array([[10.0, 10.0], [250.0, 170.0]]))
    assert np.allclose(back.image_to_world(px), cal.image_to_world(px), atol=1e-9)
    assert back.lens is not None and cal.lens is not None
    assert back.lens.k1 == cal.lens.k1 and back.lens.centre_px == cal.lens.centre_px
    assert back.lens.k1_std == pytest.approx(cal.lens.k1_std, rel=1e-9)
    assert back.lens_candidates == cal.lens_candidates
    assert np.allclose(
        back.image_to_world(px, return_std=True)[1], cal.image_to_world(px, return_std=True)[1]
    )
    data = json.loads((tmp_path / "c.json").read_text())
    data["lens"]["k1"] = "strong"
    with pytest.raises(CalibrationFileError, match="lens"):
        Calibration.from_dict(data)
    # A file of the first version (a homography alone) still loads.
    old = plain.to_dict()
    old["version"] = 1
    for key in ("lens_model", "lens", "lens_note", "lens_candidates", "intrinsics", "world_scale"):
        del old[key]
    del old["digest"], old["object_settings"]  # versions 4's and 7's
    v1 = Calibration.from_dict(json.loads(json.dumps(old)))
    assert v1.lens_model == "none" and np.array_equal(v1.H, plain.H)


def test_a_printer_scale_error_is_corrected_by_the_measured_pitch(scenes: Scenes) -> None:
    scene, cal, _ = scenes[0]
    # The board was "printed" 1.5 % too large in X and 0.8 % too small in Y: the true
    # positions are the nominal ones scaled. The calibration, not knowing, is off by that much.
    sx, sy = 1.015, 0.992
    true_world = cal.world_points * [sx, sy]
    px = scene.project(cal.world_points)
    assert np.abs(cal.image_to_world(px) - true_world).max() > 1.0
    fixed = cal.rescaled(BOARD.pitch * sx, BOARD.pitch * sy)
    assert fixed.world_scale == pytest.approx((sx, sy))
    assert np.abs(fixed.image_to_world(px) - true_world).max() < 0.05
    assert fixed.lens_model == cal.lens_model
    with pytest.raises(BoardError, match="not a printer's scale error"):
        cal.rescaled(BOARD.pitch * 1.5)
    with pytest.raises(BoardError, match="positive"):
        cal.rescaled(-20.0)
    with pytest.raises(BoardError, match="board"):
        Calibration(cal.world_points, cal.image_points, image_size=(1280, 720)).rescaled(20.1)
