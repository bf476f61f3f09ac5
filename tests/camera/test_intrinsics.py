"""Camera intrinsics: calibration from rendered board views, the distortion model and its
inverse, the plane's pose from K and H, heights above the table, and OpenCV's files.

The truth comes from planarcal.synth (its camera model is OpenCV's radial model, its renders
exact); OpenCV itself (projectPoints, FileStorage) is the reference for the lens model and
the file format.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pickle
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.detect import BoardDetection, detect_board
from planarcal.camera import (
    CameraIntrinsics,
    PlanePoseEstimate,
    calibrate_camera,
    plane_pose,
    points_at_height,
)
from planarcal.errors import BoardNotFoundError, IntrinsicsError

CAMERA = synth.PAPER_CAMERA
BOARD = synth.PAPER_BOARD
TRUTH = CameraIntrinsics(CAMERA.matrix(), CAMERA.dist_coeffs(), (CAMERA.width, CAMERA.height))

# OpenCV's calibration tutorial's webcam (its out_camera_data.yml): a strong barrel with a k3
# that folds the model over just outside the 640 x 480 image's corners. Given as lists: the
# constructor takes any array-like, though the fields are typed as the arrays they become.
WEBCAM = CameraIntrinsics(
    [[657.46697944293521, 0.0, 319.5], [0.0, 657.46697944293521, 239.5], [0.0, 0.0, 1.0]],  # type: ignore[arg-type]
    [-0.41802327176423804, 0.50715244063187526, 0.0, 0.0, -0.57843597214487474],  # type: ignore[arg-type]
    (640, 480),
)
# Every term of OpenCV's 14-coefficient model (rational, tangential, thin prism, tilt).
FULL_MODEL = CameraIntrinsics(
    np.array([[800.0, 0.0, 330.0], [0.0, 805.0, 250.0], [0.0, 0.0, 1.0]]),
    np.array(
        [-0.3, 0.1, 1e-3, -5e-4, -0.01, 0.05, 0.02, 0.001, 1e-3, -2e-4, 5e-4, 1e-4, 0.01, -0.005]
    ),
    (640, 480),
)

# Seven views, tilted 18-32 degrees about different axes, the board spread over the image.
POSES = (
    synth.PlanePose(430.0, tilt_deg=30.0, tilt_axis_deg=0.0, look_at_mm=(130.0, 60.0)),
    synth.PlanePose(430.0, -30.0, 0.0, roll_deg=5.0, look_at_mm=(130.0, 120.0)),
    synth.PlanePose(430.0, 32.0, 90.0, roll_deg=-4.0, look_at_mm=(170.0, 90.0)),
    synth.PlanePose(430.0, -32.0, 90.0, roll_deg=3.0, look_at_mm=(90.0, 90.0)),
    synth.PlanePose(430.0, 25.0, 45.0, roll_deg=10.0, look_at_mm=(110.0, 70.0)),
    synth.PlanePose(430.0, 25.0, 135.0, roll_deg=-8.0, look_at_mm=(150.0, 110.0)),
    synth.PlanePose(470.0, 18.0, -60.0, roll_deg=20.0, look_at_mm=(130.0, 90.0)),
)


def _render(pose: synth.PlanePose, seed: int) -> synth.RenderedScene:
    scene = synth.render_scene(
        CAMERA, pose, board=BOARD, blur_sigma_px=0.8, noise_sigma=2.0, seed=seed
    )
    assert scene.dots_in_view(margin_px=3.0).all(), f"pose {pose} does not show the whole board"
    return scene


@pytest.fixture(scope="module")
def scenes() -> list[synth.RenderedScene]:
    return [_render(pose, seed) for seed, pose in enumerate(POSES)]


@pytest.fixture(scope="module")
def detections(scenes: list[synth.RenderedScene]) -> list[BoardDetection]:
    return [detect_board(s.image, BOARD) for s in scenes]


@pytest.fixture(scope="module")
def calibrated(detections: list[BoardDetection]) -> CameraIntrinsics:
    return calibrate_camera(detections, BOARD)


def _grid(width: int, height: int, step: float) -> np.ndarray:
    xs, ys = np.meshgrid(np.arange(0.0, width, step), np.arange(0.0, height, step))
    # The image's outermost pixel centres too.
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    edge = np.array([[0, 0], [width - 1, 0], [0, height - 1], [width - 1, height - 1]], float)
    return np.vstack([pts, edge])


# ------------------------------------------------------------------------------------------
# Calibration


def test_calibration_recovers_the_camera(
    calibrated: CameraIntrinsics, detections: list[BoardDetection]
) -> None:
    assert calibrated.fx == pytest.approx(CAMERA.focal_px, rel=0.005)
    assert calibrated.fy == pytest.approx(CAMERA.focal_px, rel=0.005)
    assert abs(calibrated.cx - CAMERA.cx) < 3.0
    assert abs(calibrated.cy - CAMERA.cy) < 3.0
    assert calibrated.skew == 0.0
    assert calibrated.image_size == (CAMERA.width, CAMERA.height)
    assert calibrated.dist_coeffs.shape == (5,)
    assert calibrated.n_views == len(detections)
    assert calibrated.per_view_rms_px is not None
    assert len(calibrated.per_view_rms_px) == len(detections)
    # The overall RMS is the per-view RMS pooled over the views' equal point counts.
    assert calibrated.rms_px == pytest.approx(
        math.sqrt(np.mean(np.square(calibrated.per_view_rms_px))), rel=1e-6
    )
    assert calibrated.rms_px is not None and calibrated.rms_px < 0.1


def test_calibration_recovers_the_distortion_field(
    calibrated: CameraIntrinsics, scenes: list[synth.RenderedScene]
) -> None:
    # The coefficients trade off against each other (k3 especially); the displacement each
    # pixel undergoes is what matters, and it is only known where the board has been.
    dots = np.vstack([s.dot_centres_px for s in scenes]).astype(np.float32)
    hull = cv2.convexHull(dots)
    grid = _grid(CAMERA.width, CAMERA.height, 8.0)
    inside = np.array(
        [cv2.pointPolygonTest(hull, (float(x), float(y)), False) >= 0 for x, y in grid]
    )
    pts = grid[inside]
    assert len(pts) > 0.4 * len(grid)  # the views cover a good part of the image
    true_shift = TRUTH.undistort_points(pts) - pts
    est_shift = calibrated.undistort_points(pts) - pts
    assert np.abs(true_shift).max() > 5.0  # there is a distortion to recover
    assert np.linalg.norm(est_shift - true_shift, axis=1).max() < 0.2
    # The fitted model can be inverted over the whole image.
    calibrated.check_invertible_over_image()


@pytest.mark.parametrize(
    "flags",
    [
        {"fix_aspect_ratio": True},
        {"zero_tangent": True},
        {"fix_aspect_ratio": True, "zero_tangent": True},
    ],
    ids=["fix_aspect_ratio", "zero_tangent", "both"],
)
def test_calibration_flags(detections: list[BoardDetection], flags: dict[str, bool]) -> None:
    result = calibrate_camera(detections, BOARD, **flags)
    assert result.fx == pytest.approx(CAMERA.focal_px, rel=0.005)
    if flags.get("fix_aspect_ratio"):
        assert result.fx == result.fy
    if flags.get("zero_tangent"):
        assert result.dist_coeffs[2] == result.dist_coeffs[3] == 0.0
    assert result.dist_coeffs.shape == (5,)
    pts = np.vstack([d.image_points for d in detections])
    true_shift = TRUTH.undistort_points(pts) - pts
    assert np.abs(result.undistort_points(pts) - pts - true_shift).max() < 0.2


def test_the_rational_model_is_accepted_only_with_a_determined_focal_length(
    detections: list[BoardDetection],
) -> None:
    # With the board in the middle of the image the rational model's k1 and k4 can both grow
    # large, which turns its radial factor into a near-constant scale: a stand-in for the
    # focal length. Whether OpenCV's optimiser (it differs between OpenCV 4 and 5) lands
    # there or not, a focal length is never returned wrong: the fit is right, or refused.
    try:
        result = calibrate_camera(detections, BOARD, rational=True)
    except IntrinsicsError as e:
        assert "do not determine the focal length" in str(e)
        assert "rational" in str(e)
        return
    assert result.dist_coeffs.shape == (8,)
    assert result.fx == pytest.approx(CAMERA.focal_px, rel=0.005)
    pts = np.vstack([d.image_points for d in detections])
    true_shift = TRUTH.undistort_points(pts) - pts
    assert np.abs(result.undistort_points(pts) - pts - true_shift).max() < 0.2


def test_calibration_accepts_paths_arrays_and_detections(
    scenes: list[synth.RenderedScene],
    detections: list[BoardDetection],
    calibrated: CameraIntrinsics,
    tmp_path: Path,
) -> None:
    path = tmp_path / "view0.png"
    assert cv2.imwrite(str(path), scenes[0].image)
    views = [path, scenes[2].image, detections[4], detections[6]]
    result = calibrate_camera(views, BOARD)
    assert result.n_views == 4
    assert result.fx == pytest.approx(calibrated.fx, rel=0.005)


def test_a_view_without_the_board_is_named(detections: list[BoardDetection]) -> None:
    blank = np.full((CAMERA.height, CAMERA.width), 200, np.uint8)
    with pytest.raises(BoardNotFoundError, match=r"^view 2: no 14 x 10 circle grid"):
        calibrate_camera([detections[0], detections[1], blank, detections[3]], BOARD)


def test_calibration_refuses_too_few_or_mixed_views(detections: list[BoardDetection]) -> None:
    with pytest.raises(IntrinsicsError, match="at least 3 views"):
        calibrate_camera(detections[:2], BOARD)
    with pytest.raises(IntrinsicsError, match="a list of images"):
        calibrate_camera(detections[0].board.world_points(), BOARD)  # type: ignore[arg-type]
    smaller = dataclasses.replace(detections[2], image_size=(640, 480))
    with pytest.raises(IntrinsicsError, match=r"view 2 is 640 x 480 px but view 0 is 1280 x 720"):
        calibrate_camera([detections[0], detections[1], smaller, detections[3]], BOARD)
    other = CircleGridBoard(cols=14, rows=10, pitch=25.0, diameter=10.0)
    with pytest.raises(IntrinsicsError, match="another board"):
        calibrate_camera(detections[:4], other)


def test_fronto_parallel_views_leave_the_focal_length_undetermined() -> None:
    # Squarely facing views: their images are similar to the board whatever the focal length
    # (OpenCV still returns one, with a tiny standard deviation).
    poses = [
        synth.PlanePose(500.0, roll_deg=roll, look_at_mm=look)
        for roll, look in ((0.0, (130.0, 90.0)), (12.0, (110.0, 75.0)), (-15.0, (150.0, 105.0)))
    ]
    flat = [detect_board(_render(p, seed).image, BOARD) for seed, p in enumerate(poses)]
    with pytest.raises(IntrinsicsError, match="need more tilt"):
        calibrate_camera(flat, BOARD)


# ------------------------------------------------------------------------------------------
# The lens model and its inverse


@pytest.mark.parametrize("intr", [TRUTH, WEBCAM, FULL_MODEL], ids=["paper", "webcam", "full"])
def test_undistort_inverts_distort_across_the_image(intr: CameraIntrinsics) -> None:
    px = _grid(*intr.image_size, 3.0)
    ideal = intr.undistort_points(px)
    assert np.abs(ideal - px).max() > 30.0  # strong enough to matter
    assert np.abs(intr.distort_points(ideal) - px).max() < 1e-6
    # Shapes are kept: one point, and OpenCV's (N, 1, 2).
    assert intr.undistort_points(px[5]).shape == (2,)
    assert np.array_equal(intr.undistort_points(px[:7].reshape(-1, 1, 2)).reshape(-1, 2), ideal[:7])


@pytest.mark.parametrize("intr", [TRUTH, WEBCAM, FULL_MODEL], ids=["paper", "webcam", "full"])
def test_distort_is_opencvs_model(intr: CameraIntrinsics) -> None:
    rng = np.random.default_rng(7)
    w, h = intr.image_size
    ideal = rng.uniform([0.0, 0.0], [w - 1.0, h - 1.0], (500, 2))
    rays = np.column_stack([ideal, np.ones(len(ideal))]) @ np.linalg.inv(intr.matrix).T
    expected, _ = cv2.projectPoints(
        rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), intr.matrix, intr.dist_coeffs
    )
    assert np.abs(intr.distort_points(ideal) - expected.reshape(-1, 2)).max() < 1e-9


def test_skew_is_honoured() -> None:
    # OpenCV's point functions ignore K's skew; here it is part of K^-1 and K.
    k = np.array([[900.0, 4.0, 320.0], [0.0, 905.0, 240.0], [0.0, 0.0, 1.0]])
    d = np.array([-0.2, 0.05, 1e-3, -1e-3, 0.0])
    intr = CameraIntrinsics(k, d, (640, 480))
    ideal = _grid(640, 480, 37.0)
    rays = np.column_stack([ideal, np.ones(len(ideal))]) @ np.linalg.inv(k).T
    normalised, _ = cv2.projectPoints(
        rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), np.eye(3), d
    )
    n = np.column_stack([normalised.reshape(-1, 2), np.ones(len(ideal))])
    expected = (n @ k.T)[:, :2]
    assert np.abs(intr.distort_points(ideal) - expected).max() < 1e-9
    assert np.abs(intr.undistort_points(expected) - ideal).max() < 1e-6
    # Without distortion both are the identity, skew or not.
    plain = CameraIntrinsics(k, np.zeros(5), (640, 480))
    assert np.allclose(plain.undistort_points(ideal), ideal, rtol=0, atol=1e-9)


def test_undistorted_dots_are_the_pinhole_projection(scenes: list[synth.RenderedScene]) -> None:
    # synth's exact (distorted) dot centres, undistorted with the true K and distortion, are
    # the ideal pinhole image: the scene's world_to_image homography of the dots.
    for scene in scenes[:3]:
        ideal = TRUTH.undistort_points(scene.dot_centres_px)
        world = np.column_stack([scene.dot_centres_mm, np.ones(BOARD.n_points)])
        h = world @ scene.world_to_image.T
        expected = h[:, :2] / h[:, 2:]
        assert np.abs(ideal - expected).max() < 1e-6


def test_points_past_the_fold_are_refused() -> None:
    # The tutorial webcam's model folds over just outside its image: its corners are fine,
    # points further out have no (or only a spurious) preimage.
    WEBCAM.check_invertible_over_image()
    corners = WEBCAM.undistort_points([[0.0, 0.0], [639.0, 479.0]])
    assert np.abs(WEBCAM.distort_points(corners) - [[0.0, 0.0], [639.0, 479.0]]).max() < 1e-6
    with pytest.raises(
        IntrinsicsError, match=r"pixel 1 \[-150\.0, -120\.0\] cannot be undistorted"
    ):
        WEBCAM.undistort_points([[320.0, 240.0], [-150.0, -120.0]])
    with pytest.raises(IntrinsicsError, match=r"ideal pixel 0 .* beyond the fold-over"):
        WEBCAM.distort_points([[-600.0, -450.0]])
    # A model that folds inside its image is refused as a whole.
    folding = CameraIntrinsics(
        np.array([[500.0, 0, 319.5], [0, 500.0, 239.5], [0, 0, 1]]),
        np.array([-0.5, 0, 0, 0], dtype=np.float64),
        (640, 480),
    )
    with pytest.raises(IntrinsicsError, match="cannot be inverted over the whole 640 x 480 image"):
        folding.check_invertible_over_image()
    assert np.isfinite(folding.undistort_points([[320.0, 240.0], [400.0, 300.0]])).all()


def test_bad_points_are_refused() -> None:
    with pytest.raises(IntrinsicsError, match=r"point 1 is not finite"):
        TRUTH.undistort_points([[1.0, 2.0], [np.nan, 3.0]])
    with pytest.raises(IntrinsicsError, match=r"shape \(\.\.\., 2\)"):
        TRUTH.distort_points(np.zeros((4, 3)))
    assert TRUTH.undistort_points(np.zeros((0, 2))).shape == (0, 2)


# ------------------------------------------------------------------------------------------
# Validation, identity, JSON


@pytest.mark.parametrize(
    ("matrix", "dist", "size", "message"),
    [
        (np.eye(2), np.zeros(5), (640, 480), "must be 3 x 3"),
        ([[500, 0, 320], [0, 500, 240], [0, 0, 2]], np.zeros(5), (640, 480), r"\[0, 0, 1\]"),
        ([[500, 0, 320], [1, 500, 240], [0, 0, 1]], np.zeros(5), (640, 480), r"\[0, fy, cy\]"),
        ([[-500, 0, 320], [0, 500, 240], [0, 0, 1]], np.zeros(5), (640, 480), "positive"),
        ([[np.nan, 0, 320], [0, 500, 240], [0, 0, 1]], np.zeros(5), (640, 480), "NaN"),
        ("not a matrix", np.zeros(5), (640, 480), "3 x 3"),
        (np.eye(3), np.zeros(3), (640, 480), "4, 5, 8, 12 or 14"),
        (np.eye(3), np.zeros(6), (640, 480), "4, 5, 8, 12 or 14"),
        (np.eye(3), np.zeros((2, 5)), (640, 480), "4, 5, 8, 12 or 14"),
        (np.eye(3), [0.1, np.inf, 0, 0, 0], (640, 480), "NaN or infinite"),
        (np.eye(3), np.zeros(5), (640,), "width, height"),
        (np.eye(3), np.zeros(5), (640, 0), "at least 1"),
        (np.eye(3), np.zeros(5), (640.5, 480), "whole number"),
    ],
)
def test_malformed_intrinsics_are_refused(
    matrix: object, dist: object, size: object, message: str
) -> None:
    with pytest.raises(IntrinsicsError, match=message):
        CameraIntrinsics(matrix, dist, size)  # type: ignore[arg-type]


def test_intrinsics_are_immutable_values() -> None:
    k = CAMERA.matrix()
    row = CameraIntrinsics(k, CAMERA.dist_coeffs().reshape(1, 5), (1280, 720))
    col = CameraIntrinsics(k, CAMERA.dist_coeffs().reshape(5, 1), (1280, 720))
    assert row == col == TRUTH and hash(row) == hash(TRUTH)
    assert row.dist_coeffs.shape == (5,)
    k[0, 0] = 1.0  # the instance holds its own copy
    assert row.fx == CAMERA.focal_px
    with pytest.raises(ValueError, match="read-only"):
        row.matrix[0, 0] = 2.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        row.rms_px = 1.0  # type: ignore[misc]
    copy = pickle.loads(pickle.dumps(TRUTH))
    assert copy == TRUTH and not copy.matrix.flags.writeable
    assert dataclasses.replace(TRUTH, rms_px=0.1) != TRUTH
    with pytest.raises(IntrinsicsError, match="per_view_rms_px has 2 values for n_views=3"):
        dataclasses.replace(TRUTH, n_views=3, per_view_rms_px=(0.1, 0.2))
    with pytest.raises(IntrinsicsError, match="rms_px"):
        dataclasses.replace(TRUTH, rms_px=-1.0)


def test_json_round_trip(calibrated: CameraIntrinsics) -> None:
    text = json.dumps(calibrated.to_dict(), allow_nan=False)
    assert CameraIntrinsics.from_dict(json.loads(text)) == calibrated
    assert CameraIntrinsics.from_dict(TRUTH.to_dict()) == TRUTH


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"camera_matrix": None}, "camera_matrix must be"),
        ({"camera_matrix": [[1, 0, 0], [0, 1, 0]]}, "3 x 3"),
        ({"camera_matrix": [["a", 0, 0], [0, 1, 0], [0, 0, 1]]}, "camera_matrix must be"),
        ({"dist_coeffs": [True, 0, 0, 0, 0]}, "dist_coeffs must be"),
        ({"dist_coeffs": [0, 0]}, "4, 5, 8, 12 or 14"),
        ({"image_size_px": "1280x720"}, r"\[width, height\]"),
        ({"image_size_px": [1280]}, "width, height"),
        ({"rms_px": "small"}, "rms_px must be a number"),
        ({"n_views": 2.5}, "n_views must be a whole number"),
        ({"per_view_rms_px": 0.1}, "per_view_rms_px must be a list"),
    ],
)
def test_malformed_json_is_refused(change: dict[str, object], message: str) -> None:
    data = {**TRUTH.to_dict(), **change}
    with pytest.raises(IntrinsicsError, match=message):
        CameraIntrinsics.from_dict(data)


def test_json_without_required_fields_is_refused() -> None:
    data = TRUTH.to_dict()
    del data["dist_coeffs"]
    with pytest.raises(IntrinsicsError, match="lack dist_coeffs"):
        CameraIntrinsics.from_dict(data)
    with pytest.raises(IntrinsicsError, match="JSON object"):
        CameraIntrinsics.from_dict([1, 2, 3])


# ------------------------------------------------------------------------------------------
# The plane's pose and heights


@pytest.mark.parametrize(
    "pose",
    [
        synth.PAPER_POSE,
        *POSES[:3],
        synth.PlanePose(800.0, 55.0, 200.0, roll_deg=-30.0, look_at_mm=(-40.0, 300.0)),
    ],
)
def test_plane_pose_recovers_the_camera(pose: synth.PlanePose) -> None:
    h = CAMERA.homography(pose)
    for scale in (1.0, -3.7):  # H is known up to scale, its sign included
        est = plane_pose(TRUTH.matrix, scale * h)
        assert isinstance(est, PlanePoseEstimate)
        assert np.abs(est.camera_centre_mm - pose.camera_centre_mm()).max() < 1e-6
        assert np.abs(est.rotation - pose.rotation()).max() < 1e-9
        assert np.abs(est.translation - pose.translation()).max() < 1e-6
        # Z points into the table, so the camera is on its negative side.
        assert np.array_equal(est.up, [0.0, 0.0, -1.0])
        assert est.distance_mm == pytest.approx(-pose.camera_centre_mm()[2], abs=1e-6)
        rvec, tvec = est.rvec_tvec()
        ref_r, ref_t = pose.rvec_tvec()
        assert np.allclose(rvec, ref_r, atol=1e-9) and np.allclose(tvec, ref_t, atol=1e-6)
    # The CameraIntrinsics itself can stand for K.
    assert np.array_equal(
        plane_pose(TRUTH, h).camera_centre_mm, plane_pose(TRUTH.matrix, h).camera_centre_mm
    )


def test_plane_pose_computes_which_side_is_up() -> None:
    # With the table's Y axis flipped (a mirrored reading), X x Y points towards the camera.
    pose = POSES[4]
    flip = np.diag([1.0, -1.0, 1.0])
    est = plane_pose(TRUTH.matrix, CAMERA.homography(pose) @ flip)
    assert np.array_equal(est.up, [0.0, 0.0, 1.0])
    centre = pose.camera_centre_mm()
    assert np.abs(est.camera_centre_mm - [centre[0], -centre[1], -centre[2]]).max() < 1e-6


def test_plane_pose_refuses_bad_input() -> None:
    h = CAMERA.homography(synth.PAPER_POSE)
    with pytest.raises(IntrinsicsError, match="singular"):
        plane_pose(TRUTH.matrix, np.outer(h[:, 0], [1.0, 2.0, 3.0]))
    with pytest.raises(IntrinsicsError, match="finite 3 x 3"):
        plane_pose(TRUTH.matrix, np.full((3, 3), np.nan))
    with pytest.raises(IntrinsicsError, match="3 x 3"):
        plane_pose(TRUTH.matrix, h[:2])
    with pytest.raises(IntrinsicsError, match="positive"):
        plane_pose(np.diag([-1.0, 1.0, 1.0]), h)
    good = plane_pose(TRUTH.matrix, h)
    with pytest.raises(IntrinsicsError, match=r"rotation must be finite, of shape \(3, 3\)"):
        dataclasses.replace(good, rotation=np.eye(2))
    with pytest.raises(IntrinsicsError, match="distance_mm must be a finite distance > 0"):
        dataclasses.replace(good, distance_mm=-1.0)


def test_points_at_height_finds_the_top_of_a_post(scenes: list[synth.RenderedScene]) -> None:
    rng = np.random.default_rng(3)
    for scene in (scenes[1], scenes[4]):
        pose = scene.pose
        est = plane_pose(TRUTH.matrix, scene.world_to_image)
        posts = rng.uniform([20.0, 20.0], [240.0, 160.0], (6, 2))
        heights = np.array([20.0, 20.0, 5.0, 35.0, 0.0, -3.0])
        rvec, tvec = pose.rvec_tvec()
        tops = np.column_stack([posts, -heights])  # height above the table is -Z
        pixels, _ = cv2.projectPoints(tops, rvec, tvec, TRUTH.matrix, TRUTH.dist_coeffs)
        ideal = TRUTH.undistort_points(pixels.reshape(-1, 2))
        # Where each pixel's ray meets the table, through the ideal image's homography.
        hom = np.column_stack([ideal, np.ones(len(ideal))]) @ np.linalg.inv(scene.world_to_image).T
        on_table = hom[:, :2] / hom[:, 2:]
        assert np.linalg.norm(on_table - posts, axis=1)[:2].min() > 5.0  # parallax is large
        assert np.abs(points_at_height(on_table, est, heights) - posts).max() < 1e-6
        # A scalar height applies to every point, and a single point keeps its shape.
        at_20 = points_at_height(on_table[:2], est, 20.0)
        assert np.abs(at_20 - posts[:2]).max() < 1e-6
        assert points_at_height(on_table[0], est, 20.0).shape == (2,)
        assert np.array_equal(points_at_height(on_table, est, 0.0), on_table)


def test_points_at_height_refuses_heights_at_the_camera() -> None:
    est = plane_pose(TRUTH.matrix, CAMERA.homography(synth.PAPER_POSE))
    xy = np.array([[10.0, 20.0], [30.0, 40.0]])
    with pytest.raises(IntrinsicsError, match=r"reaches the camera"):
        points_at_height(xy, est, [10.0, est.distance_mm])
    with pytest.raises(IntrinsicsError, match="not finite"):
        points_at_height(xy, est, [10.0, np.nan])
    with pytest.raises(IntrinsicsError, match="one per point"):
        points_at_height(xy, est, [1.0, 2.0, 3.0])
    with pytest.raises(IntrinsicsError, match="PlanePoseEstimate"):
        points_at_height(xy, "pose", 1.0)  # type: ignore[arg-type]


def test_height_from_calibrated_intrinsics(
    calibrated: CameraIntrinsics,
    detections: list[BoardDetection],
    scenes: list[synth.RenderedScene],
) -> None:
    # End to end: the calibrated intrinsics, the homography of one view's undistorted dots,
    # its pose, and a 20 mm post seen in that view.
    scene, det = scenes[2], detections[2]
    ideal = calibrated.undistort_points(det.image_points)
    h, _ = cv2.findHomography(det.world_points(), ideal, 0)
    est = plane_pose(calibrated, h)
    assert np.abs(est.camera_centre_mm - scene.pose.camera_centre_mm()).max() < 0.5
    post = np.array([[140.0, 70.0]])
    rvec, tvec = scene.pose.rvec_tvec()
    pixel, _ = cv2.projectPoints(
        np.array([[140.0, 70.0, -20.0]]), rvec, tvec, CAMERA.matrix(), CAMERA.dist_coeffs()
    )
    table = cv2.perspectiveTransform(
        calibrated.undistort_points(pixel.reshape(1, 1, 2)), np.linalg.inv(h)
    )
    found = points_at_height(table.reshape(1, 2), est, 20.0)
    assert np.linalg.norm(found - post) < 0.03


# ------------------------------------------------------------------------------------------
# OpenCV's calibration files


@pytest.mark.parametrize("suffix", [".yaml", ".yml", ".xml", ".json"])
def test_file_round_trip(calibrated: CameraIntrinsics, tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"camera{suffix}"
    assert calibrated.save_yaml(path) == path
    assert CameraIntrinsics.load_yaml(path) == calibrated  # exactly: 17 significant digits
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary debris
    # OpenCV reads it under the calibration sample's names.
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert np.array_equal(fs.getNode("camera_matrix").mat(), calibrated.matrix)
    assert np.array_equal(
        fs.getNode("distortion_coefficients").mat().ravel(), calibrated.dist_coeffs
    )
    assert int(fs.getNode("image_width").real()) == calibrated.image_size[0]
    fs.release()
    bare = CameraIntrinsics(TRUTH.matrix, TRUTH.dist_coeffs, TRUTH.image_size)
    bare.save_yaml(path)
    assert CameraIntrinsics.load_yaml(path) == bare


def test_loads_opencv_samples_file(tmp_path: Path) -> None:
    # Written by cv2.FileStorage with the node names of OpenCV's calibration sample.
    k = WEBCAM.matrix
    d = WEBCAM.dist_coeffs.reshape(-1, 1)
    path = tmp_path / "out_camera_data.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("calibration_time", "Thu 19 Nov 2026 10:00:00")
    fs.write("nr_of_frames", 3)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("board_width", 9)
    fs.write("board_height", 6)
    fs.write("square_size", 50.0)
    fs.write("flags", 0)
    fs.write("camera_matrix", k)
    fs.write("distortion_coefficients", d)
    fs.write("avg_reprojection_error", 0.3925)
    fs.write("per_view_reprojection_errors", np.array([[0.31], [0.42], [0.44]], np.float32))
    fs.write("extrinsic_parameters", np.zeros((3, 6)))
    fs.release()
    got = CameraIntrinsics.load_yaml(path)
    assert np.array_equal(got.matrix, k) and np.array_equal(got.dist_coeffs, d.ravel())
    assert got.image_size == (640, 480) and got.n_views == 3
    assert got.rms_px == 0.3925
    assert got.per_view_rms_px == pytest.approx((0.31, 0.42, 0.44), abs=1e-6)


def test_loads_the_common_variants(tmp_path: Path) -> None:
    k, d = WEBCAM.matrix, WEBCAM.dist_coeffs
    for k_name, d_name, d_shape in (
        ("cameraMatrix", "distCoeffs", (1, -1)),
        ("K", "D", (-1,)),
        ("camera_matrix", "dist_coeffs", (1, -1)),
    ):
        path = tmp_path / f"{k_name}.xml"
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        fs.write(k_name, k)
        fs.write(d_name, d.reshape(d_shape))
        fs.write("imageSize", np.array([[640], [480]]))
        fs.release()
        got = CameraIntrinsics.load_yaml(path)
        assert np.array_equal(got.matrix, k) and np.array_equal(got.dist_coeffs, d), k_name
        assert got.image_size == (640, 480)
    # OpenCV 4's header and ROS's camera_info layout (plain maps with rows, cols, data).
    ros = tmp_path / "ros.yaml"
    ros.write_text(
        "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n"
        f"  cols: 3\n  data: {k.ravel().tolist()}\ndistortion_coefficients:\n  rows: 1\n"
        f"  cols: 5\n  data: {d.tolist()}\n"
    )
    assert CameraIntrinsics.load_yaml(ros) == WEBCAM


def test_unreadable_files_are_refused(tmp_path: Path) -> None:
    with pytest.raises(IntrinsicsError, match="no intrinsics file at"):
        CameraIntrinsics.load_yaml(tmp_path / "missing.yaml")
    cases = {
        "empty.yaml": b"",
        "binary.yaml": bytes(range(256)) * 4,
        "garbage.yaml": b"%YAML:1.0\n---\ncamera_matrix: [ 1, 2,\n  ]] }}} :\n",
        "broken.xml": b'<?xml version="1.0"?>\n<opencv_storage>\n<camera_matrix type_id=',
    }
    for name, data in cases.items():
        path = tmp_path / name
        path.write_bytes(data)
        with pytest.raises(IntrinsicsError, match=name):
            CameraIntrinsics.load_yaml(path)


def test_missing_nodes_are_named(tmp_path: Path) -> None:
    path = tmp_path / "partial.yaml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("camera_matrix", WEBCAM.matrix)
    fs.write("image_width", 640)
    fs.release()
    with pytest.raises(
        IntrinsicsError, match=r"lacks the node\(s\) distortion_coefficients / .*; image_height"
    ):
        CameraIntrinsics.load_yaml(path)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("camera_matrix", np.eye(2))
    fs.write("distortion_coefficients", np.zeros(5))
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.release()
    with pytest.raises(IntrinsicsError, match=r"partial\.yaml.*3 x 3"):
        CameraIntrinsics.load_yaml(path)


@pytest.mark.parametrize("suffix", [".yaml", ".xml"])
def test_truncated_files_are_refused(
    calibrated: CameraIntrinsics, tmp_path: Path, suffix: str
) -> None:
    # Cut anywhere, a saved file is refused, never read with a shortened number.
    full = tmp_path / f"full{suffix}"
    calibrated.save_yaml(full)
    data = full.read_bytes()
    cut = tmp_path / f"cut{suffix}"
    start = time.perf_counter()
    for n in range(len(data)):
        cut.write_bytes(data[:n])
        if data[:n].rstrip() == data.rstrip():
            assert CameraIntrinsics.load_yaml(cut) == calibrated
            continue
        with pytest.raises(IntrinsicsError):
            CameraIntrinsics.load_yaml(cut)
    assert time.perf_counter() - start < 20.0
