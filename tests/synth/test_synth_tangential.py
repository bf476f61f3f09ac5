"""The synthetic camera's tangential lens terms (p1, p2) are OpenCV's: its projection agrees
with cv2.projectPoints, its undistortion with cv2.undistortPoints and with its own distortion
to machine precision, and a camera without them renders bit for bit as before they existed."""

from __future__ import annotations

import hashlib

import cv2
import numpy as np
import pytest

from planarcal.calib.board import CircleGridBoard
from planarcal.errors import ArgumentError
from planarcal.synth import CameraModel, PlanePose, SceneObject, render_scene

TANGENTIAL_CAMERAS = [
    # A webcam: the distortion centre 40 px off the image centre, |p| up to 1e-3.
    CameraModel(principal=(667.8, 330.6), k1=-0.12, k2=0.03, p1=1e-3, p2=-8e-4),
    CameraModel(width=640, height=480, focal_px=600.0, k1=0.1, k2=-0.01, p1=-5e-4, p2=2e-3),
    # Tangential terms alone.
    CameraModel(width=800, height=600, focal_px=700.0, principal=(390.0, 310.0), p2=3e-3),
]
POSES = [
    PlanePose(500.0),
    PlanePose(620.0, tilt_deg=8.0, tilt_axis_deg=30.0, roll_deg=-3.0, look_at_mm=(130.0, 90.0)),
    PlanePose(400.0, tilt_deg=-25.0, tilt_axis_deg=110.0, roll_deg=40.0, look_at_mm=(-5, 12)),
]


def image_pixels(camera: CameraModel, n: int = 400) -> np.ndarray:
    """Random pixels over the whole image, its outer pixel corners included."""
    rng = np.random.default_rng(3)
    px = rng.uniform([-0.5, -0.5], [camera.width - 0.5, camera.height - 0.5], (n, 2))
    corners = [[-0.5, -0.5], [camera.width - 0.5, camera.height - 0.5]]
    return np.vstack([px, corners, [[-0.5, camera.height - 0.5], [camera.width - 0.5, -0.5]]])


@pytest.mark.parametrize("camera", TANGENTIAL_CAMERAS)
@pytest.mark.parametrize("pose", POSES)
def test_tangential_projection_is_opencvs(camera: CameraModel, pose: PlanePose) -> None:
    world = camera.image_to_plane(image_pixels(camera), pose)
    rvec, tvec = pose.rvec_tvec()
    obj = np.c_[world, np.zeros(len(world))].reshape(-1, 1, 3)
    expected, _ = cv2.projectPoints(obj, rvec, tvec, camera.matrix(), camera.dist_coeffs())
    np.testing.assert_allclose(camera.project(world, pose), expected.reshape(-1, 2), atol=1e-7)
    # And the rays traced back land where they started (image_to_plane inverts project).
    np.testing.assert_allclose(
        camera.image_to_plane(camera.project(world, pose), pose), world, atol=1e-9, rtol=0
    )


@pytest.mark.parametrize("camera", TANGENTIAL_CAMERAS)
def test_tangential_undistortion_is_opencvs_and_exact(camera: CameraModel) -> None:
    px = image_pixels(camera)
    normalised = (px - [camera.cx, camera.cy]) / camera.focal_px
    ours = camera.undistort(normalised)
    # Exact inverse of distort within the image.
    np.testing.assert_allclose(camera.distort(ours), normalised, atol=1e-14, rtol=0)
    # OpenCV's iterative undistortion, run to convergence, finds the same points.
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-16)
    args = (px.reshape(-1, 1, 2), camera.matrix(), camera.dist_coeffs(), None, None)
    if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4 names the criteria's variant apart
        theirs = cv2.undistortPointsIter(*args, criteria).reshape(-1, 2)
    else:
        theirs = cv2.undistortPoints(*args, criteria=criteria).reshape(-1, 2)
    np.testing.assert_allclose(ours, theirs, atol=1e-11, rtol=0)
    # OpenCV's distortion of our undistorted points gives the pixels back.
    obj = np.c_[ours, np.ones(len(ours))].reshape(-1, 1, 3)
    zero = np.zeros(3)
    back, _ = cv2.projectPoints(obj, zero, zero, camera.matrix(), camera.dist_coeffs())
    np.testing.assert_allclose(back.reshape(-1, 2), px, atol=1e-8, rtol=0)


def test_tangential_terms_move_the_image_as_opencvs_sign_convention_says() -> None:
    """p2 > 0 pushes points right of the centre further right (x_d += p2 (r^2 + 2 x^2)); p1 >
    0 pushes points below it further down."""
    base = CameraModel()
    for name, axis in (("p1", 1), ("p2", 0)):
        camera = CameraModel(**{name: 2e-3})  # type: ignore[arg-type]
        point = np.zeros(2)
        point[axis] = 0.3
        moved = camera.distort(point) - base.distort(point)
        assert moved[axis] == pytest.approx(2e-3 * 3 * 0.3**2)
        assert moved[1 - axis] == pytest.approx(0.0, abs=1e-18)
    assert list(CameraModel(p1=1e-3, p2=-2e-3).dist_coeffs()) == [0.0, 0.0, 1e-3, -2e-3, 0.0]
    assert CameraModel(p1=1e-3).distorted and CameraModel(p1=1e-3).tangential
    assert not CameraModel(k1=-0.1).tangential


def test_tangential_fold_over_inside_the_image_is_refused() -> None:
    with pytest.raises(ArgumentError, match=r"p1=0\.2.*folds over"):
        CameraModel(k1=-0.12, p1=0.2)
    with pytest.raises(ArgumentError, match="p2"):
        CameraModel(p2=float("nan"))
    with pytest.raises(ArgumentError, match="beyond the lens's reach"):
        CameraModel(k1=-0.3, p1=1e-3).undistort([[5.0, 5.0]])


# Images rendered before the tangential terms existed (their SHA-256): small scenes with a
# board, a nut, a tilt, blur, noise and radial distortion (or none), the distortion centre on
# and off the image centre.
RADIAL_SCENES = [
    (
        CameraModel(width=160, height=120, focal_px=300.0, k1=-0.2, k2=0.05),
        PlanePose(330.0, tilt_deg=12.0, tilt_axis_deg=30.0, roll_deg=5.0, look_at_mm=(30, 20)),
        "57bedc08c458a945a43885179c3f491f269338a810cfc271fc048f88c7a73c77",
    ),
    (
        CameraModel(
            width=200, height=150, focal_px=260.0, principal=(110.3, 70.8), k1=0.08, k2=-0.01
        ),
        PlanePose(300.0, tilt_deg=-7.0, tilt_axis_deg=200.0, look_at_mm=(25, 15)),
        "724034a4a3ed8ae36748f56f5ac5cde5eca47fb391ee603b38668130e25f0b9f",
    ),
    (
        CameraModel(width=180, height=120, focal_px=300.0, principal=(80.0, 66.0)),
        PlanePose(310.0, tilt_deg=3.0, look_at_mm=(30, 20)),
        "8ad95456e216c34d2d4e57db10c4974606676288c2d4833c0518c21e43335924",
    ),
]


@pytest.mark.parametrize(("camera", "pose", "sha256"), RADIAL_SCENES)
def test_without_tangential_terms_scenes_render_as_before(
    camera: CameraModel, pose: PlanePose, sha256: str
) -> None:
    scene = render_scene(
        camera,
        pose,
        board=CircleGridBoard(cols=4, rows=3, pitch=20.0, diameter=10.0),
        objects=[SceneObject("nut", (70.0, 40.0), angle_deg=10.0, size_mm=8.0)],
        seed=3,
        blur_sigma_px=0.8,
        noise_sigma=2.0,
    )
    assert hashlib.sha256(scene.image.tobytes()).hexdigest() == sha256


def test_tangential_scene_dots_are_where_the_truth_says() -> None:
    """A render through a tangential lens puts each dot's darkness centroid on its projected
    centre (the renderer traces every pixel through the full model)."""
    camera = CameraModel(
        width=240, height=180, focal_px=300.0, principal=(130.0, 80.0), k1=-0.1, p1=3e-3, p2=-3e-3
    )
    board = CircleGridBoard(cols=4, rows=3, pitch=20.0, diameter=10.0)
    scene = render_scene(
        camera,
        PlanePose(300.0, look_at_mm=(30, 20)),
        board=board,
        paper_grey=255.0,
        ink_grey=0.0,
        table_grey=255.0,
    )
    image = scene.image.astype(np.float64)
    for centre in scene.dot_centres_px:
        x0, y0 = (np.floor(centre) - 12).astype(int)
        w = 255.0 - image[y0 : y0 + 25, x0 : x0 + 25]
        ys, xs = np.mgrid[y0 : y0 + 25, x0 : x0 + 25]
        found = np.array([(w * xs).sum(), (w * ys).sum()]) / w.sum()
        # A dot's centroid is not its centre's projection under perspective and the lens:
        # within 0.02 px for 10 px dots here; a lens ignored would be 0.1-0.5 px off.
        assert np.hypot(*(found - centre)) < 0.02
