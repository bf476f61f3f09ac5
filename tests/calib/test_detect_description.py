"""The board's description checked against the image (issue 21): the dots' diameter against
the pitch, and an origin marker against the dots, measured on rendered boards with exact
truth (tilt, blur, noise, lens, JPEG, resolution) and on the real photographs; and the
accuracy in pixels, which no wrong description can flatter."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from conftest import SHARED
from planarcal import report
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import BoardDetection, detect_board
from planarcal.errors import BoardError, BoardMismatchError
from planarcal.report import drawing
from planarcal.report.summary import verdict
from planarcal.synth import CameraModel, PlanePose, jpeg, render_scene

# The board: dots 12 mm across, 20 mm apart (0.6 of the pitch).
TRUE = CircleGridBoard(8, 6, 20.0, 12.0)

# (name, dots across in the image (px), tilt (deg), blur sigma (px), noise, lens k1, JPEG
# quality, gamma of the camera's response (0.45: sRGB's encoding)).
SCENES = {
    "front_sharp": (30.0, 0.0, 0.5, 2.0, 0.0, None, 1.0),
    "tilted_40_barrel": (24.0, 40.0, 1.0, 3.0, -0.25, None, 1.0),
    "webcam_jpeg_srgb": (14.0, 20.0, 1.2, 4.0, -0.15, 70, 0.45),
    "small_dots_blurred": (12.0, 25.0, 1.5, 2.0, -0.1, None, 1.0),
    "large_dots_srgb": (60.0, 30.0, 1.5, 3.0, -0.05, 85, 0.45),
    "dark_response": (20.0, 15.0, 1.0, 2.0, 0.0, None, 1.6),
}


def _render(name: str, board: CircleGridBoard = TRUE) -> NDArray[np.uint8]:
    dots_px, tilt, blur, noise, k1, quality, gamma = SCENES[name]
    pitch_px = dots_px * board.pitch / board.dots_mm()
    span = (max(board.cols, board.rows) + 1.5) * pitch_px
    width = int(np.clip(span * 1.2, 320, 2400)) // 4 * 4
    camera = CameraModel(width, width * 3 // 4, 0.9 * width, k1=k1)
    centre = board.world_points().max(axis=0) / 2
    pose = PlanePose(
        distance_mm=camera.focal_px * board.pitch / pitch_px,
        tilt_deg=tilt,
        tilt_axis_deg=35.0,
        roll_deg=3.0,
        look_at_mm=(float(centre[0]), float(centre[1])),
    )
    scene = render_scene(
        camera, pose, board=board, blur_sigma_px=blur, noise_sigma=noise, supersample=3, seed=7
    )
    image = np.rint(255.0 * (scene.image / 255.0) ** gamma).astype(np.uint8)
    return image if quality is None else jpeg(image, quality)


@pytest.fixture(scope="module")
def images() -> dict[str, NDArray[np.uint8]]:
    return {name: _render(name) for name in SCENES}


def _detect(image: NDArray[np.uint8], **board: object) -> BoardDetection:
    return detect_board(image, dataclasses.replace(TRUE, **board))  # type: ignore[arg-type]


@pytest.mark.parametrize("name", SCENES)
def test_the_right_description_passes_and_the_dots_are_measured(
    name: str, images: dict[str, NDArray[np.uint8]]
) -> None:
    det = _detect(images[name])
    sizes = det.sizes
    assert sizes is not None and sizes.tolerance is not None, sizes
    # Within the tolerance it claims, and within 10 % here.
    assert abs(sizes.diameter_mm / 12.0 - 1.0) < min(0.1, sizes.tolerance)
    assert isinstance(det.board, CircleGridBoard)
    assert sizes.diameter_to_pitch(det.board) == pytest.approx(0.6, rel=0.1)
    # The size is measured whether or not the board states it.
    unstated = _detect(images[name], diameter=None).sizes
    assert unstated is not None and unstated.diameter_mm == pytest.approx(sizes.diameter_mm)


@pytest.mark.parametrize("name", SCENES)
def test_15_mm_dots_stated_for_12_mm_ones_are_refused(
    name: str, images: dict[str, NDArray[np.uint8]]
) -> None:
    with pytest.raises(BoardMismatchError) as err:
        _detect(images[name], diameter=15.0)
    message = str(err.value)
    assert "the board says 15 mm (0.75)" in message and "the diameter or the pitch" in message
    assert "(0.6" in message or "(0.5" in message  # the measured ratio, near 0.60
    assert isinstance(err.value, BoardError) and isinstance(err.value, ValueError)


@pytest.mark.parametrize("name", ["front_sharp", "tilted_40_barrel", "small_dots_blurred"])
def test_a_wrong_pitch_with_the_right_diameter_is_refused(
    name: str, images: dict[str, NDArray[np.uint8]]
) -> None:
    # 12 mm dots 25 mm apart would be 0.48 of the pitch; these measure 0.6.
    with pytest.raises(BoardMismatchError, match="at the stated pitch of 25 mm"):
        _detect(images[name], pitch=25.0)
    # A tenth of the pitch scales the diameter too: consistent, so it cannot be seen here
    # (the pixel figures below show it instead).
    _detect(images[name], pitch=2.0, diameter=1.2)


def test_an_overexposed_image_is_not_judged(images: dict[str, NDArray[np.uint8]]) -> None:
    # Blown-out paper shrinks dark dots by up to 45 %: the sizes are reported, not checked.
    image = np.clip(images["tilted_40_barrel"].astype(np.float64) * 1.5, 0, 255).astype(np.uint8)
    det = _detect(image, diameter=15.0)
    assert det.sizes is not None and det.sizes.tolerance is None
    assert "overexposed" in str(det.sizes.unchecked)
    cal = Calibration.from_detection(det)
    text = report.summary_text(cal, det)
    assert "the stated 15 mm is not checked: the paper is overexposed" in text


def test_the_origin_marker_is_checked_against_the_dots() -> None:
    # Dots of 10 mm, 20 mm apart, with a marker as wide as the pitch (2 x the dots).
    board = CircleGridBoard(7, 5, 20.0, 10.0, origin_marker=True, marker_diameter=20.0)
    camera = CameraModel(1280, 960, 1100.0, k1=-0.1)
    pose = PlanePose(600.0, tilt_deg=20.0, tilt_axis_deg=60.0, look_at_mm=(60.0, 40.0))
    image = render_scene(camera, pose, board=board, blur_sigma_px=0.8, noise_sigma=2.0).image
    det = detect_board(image, board)
    assert det.orientation == "marker" and det.sizes is not None
    assert det.sizes.marker_mm == pytest.approx(20.0, rel=0.05)
    text = report.summary_text(Calibration.from_detection(det), det)
    assert "the stated 10 mm agrees" in text and "the stated marker of 20 mm agrees too" in text
    # The marker stated 1.5 x the dots, the size of the default one: refused.
    with pytest.raises(
        BoardMismatchError, match=r"origin marker measures (1\.9|2\.0)\d times the dots"
    ):
        detect_board(image, dataclasses.replace(board, marker_diameter=15.0))
    # Without the dots' diameter, the marker against the pitch.
    with pytest.raises(BoardMismatchError, match="the marker's diameter or the pitch"):
        detect_board(image, dataclasses.replace(board, diameter=None, marker_diameter=14.0))
    detect_board(image, dataclasses.replace(board, diameter=None))  # unstated: nothing to check


REAL = SHARED / "data" / "real" / "boofcv-circle-regular"


def _photo(name: str) -> Path:
    path = REAL / name
    if not path.exists():
        pytest.skip(f"the real photographs are not here ({REAL}): ../shared is absent")
    return path


@pytest.mark.parametrize("index", range(6))
def test_real_photographs_pass_their_description_and_refuse_a_wrong_pitch(index: int) -> None:
    path = _photo(f"image0000{index}.jpg")
    board = CircleGridBoard(10, 8, 25.0, 15.0)
    det = detect_board(path, board)
    assert det.sizes is not None and det.sizes.tolerance is not None
    assert det.sizes.diameter_mm == pytest.approx(15.0, rel=0.03)
    with pytest.raises(BoardMismatchError):
        detect_board(path, dataclasses.replace(board, pitch=20.0))  # 15 / 20 = 0.75, not 0.6
    with pytest.raises(BoardMismatchError):
        detect_board(path, dataclasses.replace(board, diameter=12.0))


def test_the_pixel_figures_do_not_scale_with_a_wrong_pitch(
    images: dict[str, NDArray[np.uint8]],
) -> None:
    det = _detect(images["tilted_40_barrel"])
    right = Calibration.from_detection(det)
    # The same dots with a pitch stated ten times too small (and a diameter to match).
    wrong = Calibration.from_detection(_detect(images["tilted_40_barrel"], pitch=2.0, diameter=1.2))
    r, w = right.summary(), wrong.summary()
    assert w.loo_rms_mm == pytest.approx(r.loo_rms_mm / 10.0, rel=0.05)  # flattered tenfold
    assert w.loo_rms_px == pytest.approx(r.loo_rms_px, rel=0.05)  # not flattered
    assert w.loo_max_px == pytest.approx(r.loo_max_px, rel=0.05)
    assert r.loo_mean_px <= r.loo_rms_px <= r.loo_max_px
    assert verdict(w) == verdict(r)
    for s, cal in ((r, right), (w, wrong)):
        out = report.summary_json(cal, det)
        assert out["loo_rms_error_px"] == pytest.approx(s.loo_rms_px)
        assert out["loo_max_error_px"] == pytest.approx(s.loo_max_px)
        assert out["verdict"] == verdict(s)
        text = report.summary_text(cal)
        assert f"Leave-one-out error (px): mean {s.loo_mean_px:.3f}, RMS {s.loo_rms_px:.3f}" in text
        assert f"Verdict: {verdict(s)} (leave-one-out RMS" in text


def test_the_verdict_is_in_pixels() -> None:
    world = CircleGridBoard(6, 5, 20.0, 10.0).world_points()
    rng = np.random.default_rng(3)
    image = 4.0 * world + np.array([100.0, 80.0])
    for noise, word in ((0.02, "excellent"), (0.15, "good"), (0.5, "fair"), (3.0, "poor")):
        noisy = image + rng.normal(0.0, noise, image.shape)
        s = Calibration(world, noisy, lens="none").summary()
        assert verdict(s) == word, (noise, s.loo_rms_px)
        # A millimetre scale ten times smaller leaves the verdict as it is.
        assert verdict(Calibration(world / 10, noisy, lens="none").summary()) == word


def test_the_detection_figure_gives_the_measured_size(
    images: dict[str, NDArray[np.uint8]],
) -> None:
    det = _detect(images["front_sharp"])
    label = drawing.detection_label(det)
    assert any(
        "dots 12 mm across at the stated pitch of 20 mm (0.60 of the pitch)" in line
        for line in label
    ), label


def test_a_board_described_without_its_diameter_is_measured_not_refused() -> None:
    # Dots of 12 mm, 20 mm apart (0.6 of the pitch), described in code as a user would who
    # never measured them: the default states no size, so nothing is refused.
    truth = CircleGridBoard(7, 5, 20.0, 12.0)
    camera = CameraModel(1280, 960, 1100.0)
    pose = PlanePose(600.0, tilt_deg=15.0, look_at_mm=(60.0, 40.0))
    image = render_scene(camera, pose, board=truth, blur_sigma_px=0.8).image
    det = detect_board(image, CircleGridBoard(7, 5, 20.0))
    assert det.sizes is not None and det.sizes.diameter_mm == pytest.approx(12.0, rel=0.05)
    with pytest.raises(BoardMismatchError):
        detect_board(image, CircleGridBoard(7, 5, 20.0, 10.0))  # 10 mm stated: refused
