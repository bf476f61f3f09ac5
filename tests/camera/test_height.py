"""Objects of known height above the plane, on rendered scenes with exact truth: full
intrinsics from several board views (calibrate_camera), a calibration made with them, and
the tops of raised parts located where they really are."""

from __future__ import annotations

import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.camera import CameraIntrinsics, calibrate_camera
from planarcal.errors import IntrinsicsError
from planarcal.live.objects import detect_objects, locate_objects
from scene_effects import PAPER_EFFECTS

BOARD = synth.PAPER_BOARD
# Parts all over the working area, the board's corners and beyond included: the parallax of
# a raised top grows with its distance from the camera's foot.
PLACES = [(-30, -20), (290, -20), (130, 90), (-30, 200), (290, 200), (60, 40), (200, 150)]


@pytest.fixture(scope="module")
def intrinsics() -> CameraIntrinsics:
    views = []
    for tilt, axis in ((25, 0), (25, 90), (30, 45), (30, 200), (20, 300), (28, 150)):
        pose = synth.PlanePose(600.0, tilt_deg=tilt, tilt_axis_deg=axis, look_at_mm=(130, 90))
        scene = synth.render_scene(synth.PAPER_CAMERA, pose, blur_sigma_px=0.8, noise_sigma=2.5)
        views.append(scene.image)
    return calibrate_camera(views, BOARD)


def _raised_scene(calib: synth.RenderedScene, height: float, seed: int) -> synth.RenderedScene:
    objects = [
        synth.SceneObject("disc", (float(x), float(y)), size_mm=16.0, height_mm=height)
        for x, y in PLACES
    ]
    return synth.render_scene(
        synth.PAPER_CAMERA,
        calib.pose,
        board=None,
        objects=objects,
        seed=seed,
        **PAPER_EFFECTS,
    )


@pytest.mark.parametrize("seed", [0, 1])
def test_raised_tops_are_located_within_a_tenth_of_a_millimetre(
    intrinsics: CameraIntrinsics, seed: int
) -> None:
    calib = synth.random_paper_scene(100 + seed)
    cal = Calibration.from_detection(detect_board(calib.image, BOARD), intrinsics=intrinsics)
    assert cal.lens_model == "intrinsics"
    scene = _raised_scene(calib, 20.0, seed)
    truth = scene.object_centroids_mm
    with_height = locate_objects(scene.image, cal, height_mm=20.0)
    flat = locate_objects(scene.image, cal)
    assert len(with_height) == len(flat) == len(PLACES)
    gaps = []
    for found, ignored in zip(with_height, flat, strict=True):
        assert found.world_mm is not None and ignored.world_mm is not None
        gap = np.hypot(*(truth - np.array(found.world_mm)).T)
        j = int(gap.argmin())
        gaps.append(gap[j])
        # Without the height the top is where its ray meets the table: millimetres off,
        # more so far from the camera's foot.
        assert np.hypot(*(truth[j] - np.array(ignored.world_mm))) > 0.4
        assert found.world_std_mm is not None and 0.01 < found.world_std_mm < 0.05
    # Within a tenth of a millimetre on average; the worst part (a thin wall beside its top's
    # outline, near the camera's foot) is the object detector's 0.2 px.
    assert np.mean(gaps) < 0.07 and np.max(gaps) < 0.15, gaps
    # The geometry alone (the true pixels of the tops), to a few hundredths of a millimetre.
    exact = cal.image_to_world(scene.object_centroids_px, height=20.0)
    assert np.abs(exact - truth).max() < 0.04


def test_per_point_heights_and_what_cannot_be_done(intrinsics: CameraIntrinsics) -> None:
    calib = synth.random_paper_scene(7)
    det = detect_board(calib.image, BOARD)
    cal = Calibration.from_detection(det, intrinsics=intrinsics)
    pts = np.array([[20.0, 20.0], [250.0, 160.0], [130.0, 90.0]])
    heights = np.array([0.0, 12.5, 30.0])
    px = calib.project(pts, height_mm=heights)
    assert np.abs(cal.image_to_world(px, height=heights) - pts).max() < 0.04
    pose = cal.camera_pose
    assert pose.distance_mm == pytest.approx(calib.pose.distance_mm, rel=2e-3)
    with pytest.raises(ValueError, match="height"):
        cal.image_to_world(px, height=[1.0, 2.0])
    with pytest.raises(IntrinsicsError):
        cal.image_to_world(px, height=pose.distance_mm + 1.0)
    auto = Calibration.from_detection(det)
    with pytest.raises(IntrinsicsError, match="intrinsics"):
        auto.image_to_world(px, height=10.0)
    with pytest.raises(ValueError, match="lens must be"):
        Calibration.from_detection(det, intrinsics=intrinsics, lens="k1")


def test_subpixel_outlines_locate_raised_tops_better_than_the_papers_chain() -> None:
    # The walls of raised parts add edges next to the top's outline: the traced edge pixels
    # wander between them, the grey-level edge search does not.
    errors: dict[bool, list[float]] = {True: [], False: []}
    for seed in (1, 5):
        scene = _raised_scene(synth.random_paper_scene(100 + seed), 20.0, seed)
        truth = scene.object_centroids_px
        for subpixel in (True, False):
            found = detect_objects(scene.image, subpixel=subpixel)
            assert len(found) == len(truth)
            errors[subpixel] += [
                float(np.hypot(*(truth - np.array(o.centroid_px)).T).min()) for o in found
            ]
    sub, paper = np.array(errors[True]), np.array(errors[False])
    assert sub.mean() < 0.7 * paper.mean(), (sub, paper)
    assert sub.max() < 0.2 < paper.max()
