"""Frames must match the calibration. A calibration made on 640 x 480 frames refuses
1280 x 720 ones wherever pixels become millimetres (image_to_world, locate_objects, the
Tracker, `planarcal run`), naming both sizes; a deliberate change of resolution goes through
Calibration.for_frame_size, checked on one scene rendered by planarcal.synth at two
resolutions."""

from __future__ import annotations

import json
import pickle
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from test_tracker import LateCamera, render_moving, write_video
from test_tracker import _run as run_command

import planarcal
import planarcal.live.tracker as tracker_module
from planarcal import cli, synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.camera.intrinsics import CameraIntrinsics
from planarcal.errors import FrameSizeError
from planarcal.live.objects import locate_objects
from planarcal.live.tracker import Tracker
from scene_effects import SceneEffects

# One camera at two resolutions of the same view: 640 x 480, and the same sensor read out at
# 1280 x 960 (the focal length in pixels doubles; the lens is the same).
SMALL = synth.CameraModel(width=640, height=480, focal_px=535.0, k1=-0.12, k2=0.03)
LARGE = synth.CameraModel(width=1280, height=960, focal_px=1070.0, k1=-0.12, k2=0.03)
POSE = synth.PlanePose(
    distance_mm=320.0, tilt_deg=3.0, tilt_axis_deg=35.0, roll_deg=0.8, look_at_mm=(130.0, 90.0)
)
PARTS = [
    synth.SceneObject("nut", (60.0, 50.0), angle_deg=10.0, size_mm=10.0),
    synth.SceneObject("disc", (200.0, 70.0), size_mm=14.0),
    synth.SceneObject("washer", (120.0, 140.0), size_mm=12.0),
]
EFFECTS: SceneEffects = {"blur_sigma_px": 0.7, "noise_sigma": 1.0}


def pixel_scaling(s: float, px: np.ndarray) -> np.ndarray:
    """Where a pixel of an image lands in the same image scaled by s (pixel centres at whole
    numbers, as in synth and OpenCV)."""
    return s * px + (s - 1.0) / 2.0


@pytest.fixture(scope="module")
def cal_640() -> Calibration:
    """Calibrated from a rendered 640 x 480 photograph of the paper's board (lens chosen)."""
    scene = synth.render_scene(SMALL, POSE, board=synth.PAPER_BOARD, seed=1, **EFFECTS)
    return Calibration.from_detection(detect_board(scene.image, synth.PAPER_BOARD))


@pytest.fixture(scope="module")
def parts() -> dict[str, synth.RenderedScene]:
    """The same parts seen at both resolutions."""
    return {
        "640": synth.render_scene(SMALL, POSE, board=None, objects=PARTS, seed=2, **EFFECTS),
        "1280": synth.render_scene(LARGE, POSE, board=None, objects=PARTS, seed=3, **EFFECTS),
    }


@pytest.fixture(scope="module")
def video_1280x720(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real 1280 x 720 video file of moving parts (test_tracker's)."""
    frames = [render_moving(k).image for k in range(3)]
    return write_video(tmp_path_factory.mktemp("video") / "wide.avi", frames)


# ------------------------------------------------------------------------------------------
# the calibration records its size


def test_the_image_size_is_recorded_saved_and_pickled(cal_640: Calibration, tmp_path: Path) -> None:
    assert cal_640.image_size == (640, 480)
    back = Calibration.load(cal_640.save(tmp_path / "calib.json"))
    assert back.image_size == (640, 480)
    assert pickle.loads(pickle.dumps(cal_640)).image_size == (640, 480)
    with pytest.raises(FrameSizeError):
        back.image_to_world([[320.0, 240.0]], image_size=(1280, 720))


def test_a_calibration_without_a_recorded_size_accepts_any(cal_640: Calibration) -> None:
    # A file of the first version (a homography alone, no image size) still loads, and
    # cannot check: it maps as it always did.
    # (A homography alone: a fit without a lens model, whose stored residuals it reproduces.)
    old = Calibration(cal_640.world_points, cal_640.image_points, lens="none").to_dict()
    old["version"] = 1
    for key in ("lens_model", "lens", "lens_note", "lens_candidates", "intrinsics", "digest"):
        del old[key]
    del old["world_scale"], old["image_size_px"], old["object_settings"]
    v1 = Calibration.from_dict(json.loads(json.dumps(old)))
    assert v1.image_size is None
    px = np.array([[300.0, 200.0]])
    assert np.array_equal(v1.image_to_world(px, image_size=(1280, 720)), v1.image_to_world(px))
    bare = Calibration(cal_640.world_points, cal_640.image_points)
    assert bare.image_size is None
    bare.check_image_size((1280, 720))


# ------------------------------------------------------------------------------------------
# frames of another size are refused


def test_image_to_world_refuses_pixels_of_another_frame_size(cal_640: Calibration) -> None:
    px = np.array([[320.0, 240.0], [100.0, 50.0]])
    with pytest.raises(FrameSizeError) as caught:
        cal_640.image_to_world(px, image_size=(1280, 720))
    e = caught.value
    assert isinstance(e, ValueError)
    assert (e.frame_size, e.calibration_size) == ((1280, 720), (640, 480))
    message = str(e)
    assert message.startswith(
        "this image is 1280 x 720 px but the calibration was made on 640 x 480 px images"
    )
    # Another aspect ratio cannot be a rescaled view: the message says so.
    assert "16:9 against 4:3" in message and "Calibrate again at 1280 x 720" in message
    # The same aspect ratio may be a deliberate change of resolution: the message says how.
    with pytest.raises(FrameSizeError, match=r"use cal\.for_frame_size\(1280, 960\)"):
        cal_640.image_to_world(px, image_size=(1280, 960))
    # The error travels (to a worker process, a log) with its sizes.
    copy = pickle.loads(pickle.dumps(e))
    assert str(copy) == message and copy.frame_size == (1280, 720)
    # The right size, or none given, maps as before.
    mapped = cal_640.image_to_world(px)
    assert np.array_equal(cal_640.image_to_world(px, image_size=(640, 480)), mapped)
    with pytest.raises(ValueError, match="image_size"):
        cal_640.image_to_world(px, image_size=(640, 0))
    with pytest.raises(ValueError, match="image_size"):
        cal_640.image_to_world(px, image_size=(640.5, 480))  # type: ignore[arg-type]


def test_locate_objects_refuses_an_image_of_another_size(
    cal_640: Calibration, parts: dict[str, synth.RenderedScene], tmp_path: Path
) -> None:
    wide = render_moving(0).image  # 1280 x 720, three parts in view
    with pytest.raises(FrameSizeError, match=r"1280 x 720 px .* 640 x 480 px"):
        locate_objects(wide, cal_640)
    # Refused before detection: an image with nothing in it too, and a file.
    with pytest.raises(FrameSizeError, match="1280 x 720"):
        locate_objects(np.full((720, 1280), 100, np.uint8), cal_640)
    path = tmp_path / "wide.png"
    cv2.imwrite(str(path), wide)
    with pytest.raises(FrameSizeError, match="1280 x 720"):
        locate_objects(path, cal_640)
    # The calibration's own size is located.
    _assert_located(locate_objects(parts["640"].image, cal_640), parts["640"], 0.1)


def test_locate_command_refuses_an_image_of_another_size(
    cal_640: Calibration, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    calib = cal_640.save(tmp_path / "calib.json")
    image = tmp_path / "wide.png"
    cv2.imwrite(str(image), render_moving(0).image)
    assert cli.main(["locate", str(image), "--calibration", str(calib)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("planarcal locate: error: this image is 1280 x 720 px")
    assert "640 x 480 px images" in err


# ------------------------------------------------------------------------------------------
# the production loop refuses them at once


def test_tracker_refuses_a_source_of_another_size(
    cal_640: Calibration, video_1280x720: Path
) -> None:
    with pytest.raises(FrameSizeError, match=r"this frame is 1280 x 720 px .* 640 x 480 px"):
        Tracker(cal_640, video_1280x720)
    # An open Camera handed over is refused too, and left open for its owner.
    camera = planarcal.Camera(video_1280x720, color=False)
    with pytest.raises(FrameSizeError):
        Tracker(cal_640, camera)
    assert not camera.closed
    # Every frame is checked: process() of a frame of another size.
    frame = camera.read()
    camera.close()
    small = synth.render_scene(SMALL, POSE, board=None, objects=PARTS, seed=4).image
    path = write_video(video_1280x720.parent / "small.avi", [small] * 3)
    with Tracker(cal_640, path) as t:
        assert len(t.process(small).ids) == 3
        with pytest.raises(FrameSizeError, match="1280 x 720"):
            t.process(frame)


def test_a_stream_that_comes_up_at_another_size_stops_the_tracker(
    cal_640: Calibration, video_1280x720: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Not there when the tracker starts (so nothing to check yet), then delivering
    # 1280 x 720 frames: the first one stops the loop; it is not counted as a bad frame.
    LateCamera.opened, LateCamera.target = 0, str(video_1280x720)
    monkeypatch.setattr(LateCamera, "absent", 1)
    monkeypatch.setattr(tracker_module, "Camera", LateCamera)
    t = Tracker(cal_640, "rtsp://camera.invalid/parts", max_frames=3)
    with pytest.raises(FrameSizeError, match=r"1280 x 720 px .* 640 x 480 px"):
        list(t)
    assert (t.stats.frames, t.stats.failed, t.stats.frames_wrong_size) == (0, 0, 0)


def test_run_refuses_frames_of_another_size_at_once(
    cal_640: Calibration,
    video_1280x720: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    calib = cal_640.save(tmp_path / "calib.json")
    out = tmp_path / "out.jsonl"
    args = ["run", "--source", str(video_1280x720), "--calibration", str(calib)]
    assert cli.main([*args, "--output", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("planarcal run: error: this frame is 1280 x 720 px")
    assert "640 x 480 px frames" in err
    assert not out.exists()  # refused before the output was opened
    # As a user runs it: exit status 1, the message, and no line on stdout.
    result = run_command("--source", video_1280x720, "--calibration", calib)
    assert result.returncode == 1 and result.stdout == ""
    assert "this frame is 1280 x 720 px but the calibration was made on 640 x 480 px" in (
        result.stderr
    )


# ------------------------------------------------------------------------------------------
# a deliberate change of resolution: for_frame_size


def test_for_frame_size_maps_the_same_scene_point_to_the_same_millimetres(
    cal_640: Calibration, parts: dict[str, synth.RenderedScene]
) -> None:
    cal_1280 = cal_640.for_frame_size(1280, 960)
    assert cal_1280.image_size == (1280, 960) and cal_1280.lens_model == cal_640.lens_model
    # Exactly the same mapping: pixel u of the 640 x 480 frame and its place in the
    # 1280 x 960 frame go to the same millimetres, with the same uncertainty.
    rng = np.random.default_rng(0)
    u = rng.uniform([60.0, 40.0], [580.0, 440.0], (500, 2))
    # (Exact pixels: a located part's own error, by default in the bars, is in each frame's
    # pixels, half as many mm in the larger frame.)
    mm, std = cal_640.image_to_world(u, return_std=True, pixel_sigma=0.0)
    mm2, std2 = cal_1280.image_to_world(pixel_scaling(2.0, u), return_std=True, pixel_sigma=0.0)
    assert np.abs(mm2 - mm).max() < 1e-9
    assert np.allclose(std2, std, rtol=1e-9)
    assert np.allclose(cal_1280.world_to_image(mm), pixel_scaling(2.0, u), atol=1e-7)
    # On the rendered scene: the parts located in the 1280 x 960 frame are where they are.
    _assert_located(locate_objects(parts["1280"].image, cal_1280), parts["1280"], 0.05)
    # Exact projections of points over the board: as accurate as at 640 x 480 ...
    world = rng.uniform([0.0, 0.0], [260.0, 180.0], (300, 2))
    at_1280 = cal_1280.image_to_world(LARGE.project(world, POSE))
    at_640 = cal_640.image_to_world(SMALL.project(world, POSE))
    assert np.hypot(*(at_1280 - world).T).max() < 0.03
    assert np.abs(at_1280 - at_640).max() < 1e-9
    # ... where the 640 x 480 calibration applied blindly to those inside its 640 x 480 px
    # (it refuses the others: beyond its lens model's image) puts them centimetres off.
    px = LARGE.project(world, POSE)
    inside = (px < [639.0, 479.0]).all(axis=1)
    assert inside.sum() > 10
    assert np.hypot(*(cal_640.image_to_world(px[inside]) - world[inside]).T).min() > 20
    # Back down again, and the size it was made on (itself).
    back = cal_1280.for_frame_size(640, 480)
    assert np.allclose(back.H, cal_640.H, rtol=1e-12, atol=1e-12)
    assert cal_640.for_frame_size(640, 480) is cal_640
    # The scaled calibration reports in its own pixels, and its millimetres are unchanged.
    s640, s1280 = cal_640.summary(), cal_1280.summary()
    assert s1280.rms_px == pytest.approx(2.0 * s640.rms_px, rel=1e-6)
    assert s1280.loo_rms_mm == pytest.approx(s640.loo_rms_mm, rel=1e-6)
    assert "rescaled from 640 x 480 px frames" in cal_1280.lens_note


def test_a_rescaled_calibration_is_saved_with_its_new_size(
    cal_640: Calibration, tmp_path: Path
) -> None:
    cal_320 = cal_640.for_frame_size(320, 240)
    loaded = Calibration.load(cal_320.save(tmp_path / "calib_320.json"))
    assert loaded.image_size == (320, 240)
    assert cal_640.lens is not None and loaded.lens is not None
    assert loaded.lens.scale_px == pytest.approx(cal_640.lens.scale_px / 2, rel=1e-12)
    px = np.array([[100.0, 80.0], [250.0, 200.0]])
    assert np.allclose(
        loaded.image_to_world(px, image_size=(320, 240)),
        cal_640.image_to_world(pixel_scaling(2.0, px)),
        atol=1e-9,
    )


def test_for_frame_size_scales_the_camera_intrinsics() -> None:
    world = synth.PAPER_BOARD.world_points()
    intrinsics = CameraIntrinsics(SMALL.matrix(), SMALL.dist_coeffs(), (640, 480))
    cal = Calibration(world, SMALL.project(world, POSE), intrinsics=intrinsics)
    big = cal.for_frame_size(1280, 960)
    assert big.intrinsics is not None and big.intrinsics.image_size == (1280, 960)
    assert np.allclose(big.intrinsics.matrix, LARGE.matrix(), rtol=1e-12)
    assert np.array_equal(big.intrinsics.dist_coeffs, intrinsics.dist_coeffs)
    rng = np.random.default_rng(1)
    points = rng.uniform([0.0, 0.0], [260.0, 180.0], (200, 2))
    assert np.abs(big.image_to_world(LARGE.project(points, POSE)) - points).max() < 1e-6
    # The camera's pose, and so the heights, are unchanged.
    assert big.camera_pose.distance_mm == pytest.approx(cal.camera_pose.distance_mm, rel=1e-9)
    top = LARGE.project(points[:5], POSE, height_mm=20.0)
    assert np.abs(big.image_to_world(top, height=20.0) - points[:5]).max() < 1e-6


def test_for_frame_size_refuses_what_is_not_a_rescaled_view(cal_640: Calibration) -> None:
    with pytest.raises(FrameSizeError, match=r"aspect ratio differs \(16:9 against 4:3\)") as e:
        cal_640.for_frame_size(1280, 720)
    assert (e.value.frame_size, e.value.calibration_size) == ((1280, 720), (640, 480))
    bare = Calibration(cal_640.world_points, cal_640.image_points)
    with pytest.raises(FrameSizeError, match="records no image size"):
        bare.for_frame_size(1280, 960)
    for width, height in ((0, 480), (-640, 480), (640.0, 480), (True, 480)):
        with pytest.raises(ValueError, match="image_size"):
            cal_640.for_frame_size(width, height)  # type: ignore[arg-type]


def _assert_located(found: Any, scene: Any, tolerance_mm: float) -> None:
    """The scene's three parts, each within `tolerance_mm` of its true centroid."""
    truth = scene.object_centroids_mm
    assert len(found) == 3
    for o in found:
        assert o.world_mm is not None
        assert np.hypot(*(truth - np.array(o.world_mm)).T).min() < tolerance_mm
