"""The scene renderer (planarcal.synth) is ground truth: its projections agree with OpenCV's,
its homography with the undistorted projection, its silhouettes' centroids with the positions
given, and its pixels with its own geometry to well under a hundredth of a pixel."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
from collections.abc import Callable

import cv2
import numpy as np
import pytest

import planarcal
from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.errors import BoardError, ImageError
from planarcal.live.objects import detect_objects
from planarcal.synth import CameraModel, PlanePose, SceneObject, render_scene

SMALL_BOARD = CircleGridBoard(cols=4, rows=3, pitch=20.0, diameter=10.0)
SMALL_CAMERA = CameraModel(width=320, height=240, focal_px=1070.0)
SMALL_POSE = PlanePose(500.0, look_at_mm=(30.0, 20.0))

CAMERAS = [
    CameraModel(),
    CameraModel(focal_px=900.0, principal=(650.3, 349.1), k1=-0.2, k2=0.05),
    CameraModel(width=640, height=480, focal_px=600.0, k1=0.1, k2=-0.01),
]
POSES = [
    PlanePose(500.0),
    PlanePose(620.0, tilt_deg=8.0, tilt_axis_deg=30.0, roll_deg=-3.0, look_at_mm=(130.0, 90.0)),
    PlanePose(400.0, tilt_deg=-25.0, tilt_axis_deg=110.0, roll_deg=40.0, look_at_mm=(-5, 12)),
]


def world_points_in_view(camera: CameraModel, pose: PlanePose, n: int = 200) -> np.ndarray:
    """Table points seen by every part of the image (random pixels traced to the plane)."""
    rng = np.random.default_rng(7)
    pixels = rng.uniform([0, 0], [camera.width - 1, camera.height - 1], (n, 2))
    return camera.image_to_plane(pixels, pose)


def opencv_project(camera: CameraModel, pose: PlanePose, world: np.ndarray) -> np.ndarray:
    rvec, tvec = pose.rvec_tvec()
    obj = np.c_[world, np.zeros(len(world))].reshape(-1, 1, 3)
    px, _ = cv2.projectPoints(obj, rvec, tvec, camera.matrix(), camera.dist_coeffs())
    return px.reshape(-1, 2)


def weighted_centroid(
    image: np.ndarray, background: float, box: tuple[int, int, int, int]
) -> tuple[np.ndarray, float]:
    """Centroid of |image - background| over box (x0, y0, x1, y1 inclusive), and its mass."""
    x0, y0, x1, y1 = box
    w = np.abs(image[y0 : y1 + 1, x0 : x1 + 1].astype(np.float64) - background)
    ys, xs = np.mgrid[y0 : y1 + 1, x0 : x1 + 1]
    return np.array([(w * xs).sum(), (w * ys).sum()]) / w.sum(), float(w.sum())


def polygon_area_centroid(poly: np.ndarray) -> tuple[float, np.ndarray]:
    """Signed area and area centroid of a simple polygon (shoelace)."""
    x, y = poly[:, 0], poly[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = cross.sum() / 2.0
    return area, np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * area)


def segments_intersect(p: np.ndarray) -> bool:
    """Whether any two non-adjacent edges of the closed polygon p cross or touch."""
    n = len(p)
    edges = [(p[i], p[(i + 1) % n]) for i in range(n)]

    def orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
        return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            a, b = edges[i]
            c, d = edges[j]
            if (
                orient(a, b, c) * orient(a, b, d) <= 0
                and orient(c, d, a) * orient(c, d, b) <= 0
                and max(min(a[0], b[0]), min(c[0], d[0])) <= min(max(a[0], b[0]), max(c[0], d[0]))
                and max(min(a[1], b[1]), min(c[1], d[1])) <= min(max(a[1], b[1]), max(c[1], d[1]))
            ):
                return True
    return False


def boundary_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Smallest distance between the outlines of closed polygons a and b."""

    def point_to_edges(pts: np.ndarray, poly: np.ndarray) -> float:
        s, e = poly, np.roll(poly, -1, axis=0)
        d = e - s
        t = np.clip(
            np.einsum("pek,ek->pe", pts[:, None, :] - s[None], d) / np.sum(d * d, axis=1), 0, 1
        )
        closest = s[None] + t[..., None] * d[None]
        return float(np.min(np.linalg.norm(pts[:, None, :] - closest, axis=2)))

    return min(point_to_edges(a, b), point_to_edges(b, a))


# ----------------------------------------------------------------------------- geometry


@pytest.mark.parametrize("camera", CAMERAS)
@pytest.mark.parametrize("pose", POSES)
def test_project_agrees_with_opencv(camera: CameraModel, pose: PlanePose) -> None:
    world = world_points_in_view(camera, pose)
    np.testing.assert_allclose(
        camera.project(world, pose), opencv_project(camera, pose, world), atol=1e-7, rtol=0
    )


@pytest.mark.parametrize("camera", CAMERAS)
@pytest.mark.parametrize("pose", POSES)
def test_homography_is_the_undistorted_projection(camera: CameraModel, pose: PlanePose) -> None:
    world = world_points_in_view(camera, pose)
    h = camera.homography(pose)
    assert h[2, 2] == pytest.approx(1.0)
    ideal = dataclasses.replace(camera, k1=0.0, k2=0.0)
    via_h = planarcal.transform_points(h, world)
    np.testing.assert_allclose(via_h, opencv_project(ideal, pose, world), atol=1e-7, rtol=0)
    # ... which is the distorted pixel, undistorted.
    px = camera.project(world, pose)
    normalised = (px - [camera.cx, camera.cy]) / camera.focal_px
    undistorted = camera.undistort(normalised) * camera.focal_px + [camera.cx, camera.cy]
    np.testing.assert_allclose(via_h, undistorted, atol=1e-7, rtol=0)
    # Without distortion it is the projection itself.
    np.testing.assert_allclose(via_h, ideal.project(world, pose), atol=1e-7, rtol=0)


@pytest.mark.parametrize("camera", CAMERAS)
@pytest.mark.parametrize("pose", POSES)
def test_image_to_plane_inverts_project(camera: CameraModel, pose: PlanePose) -> None:
    world = world_points_in_view(camera, pose)
    back = camera.image_to_plane(camera.project(world, pose), pose)
    np.testing.assert_allclose(back, world, atol=1e-9, rtol=0)
    xy = np.random.default_rng(1).uniform(-0.6, 0.6, (500, 2))
    np.testing.assert_allclose(camera.distort(camera.undistort(xy)), xy, atol=1e-14, rtol=0)


def test_view_is_camera_and_pose() -> None:
    camera, pose = CAMERAS[1], POSES[1]
    view = synth.View(camera, pose)
    world = world_points_in_view(camera, pose, 20)
    np.testing.assert_array_equal(view.project(world), camera.project(world, pose))
    np.testing.assert_array_equal(view.homography(), camera.homography(pose))
    np.testing.assert_allclose(view.image_to_plane(view.project(world)), world, atol=1e-9)
    assert view.project([1.0, 2.0]).shape == (2,)
    assert view.project(world.reshape(4, 5, 2)).shape == (4, 5, 2)


def test_pose_means_what_it_says() -> None:
    camera = CameraModel(principal=(600.0, 400.0))
    look = (37.0, -12.0)
    pose = PlanePose(550.0, tilt_deg=20.0, tilt_axis_deg=60.0, roll_deg=10.0, look_at_mm=look)
    # The look-at point is on the optical axis, distance_mm from the camera centre.
    np.testing.assert_allclose(camera.project(look, pose), [600.0, 400.0], atol=1e-9)
    centre = pose.camera_centre_mm()
    assert np.linalg.norm(centre - [*look, 0.0]) == pytest.approx(550.0)
    assert centre[2] < 0  # above the table (table Z points away from the camera)
    # The plane is tilted by tilt_deg to the image plane.
    assert math.degrees(math.acos(pose.rotation()[2, 2])) == pytest.approx(20.0)
    # Untilted: table X runs right, Y down; a positive roll turns the image clockwise.
    for roll in (0.0, 15.0):
        p = PlanePose(500.0, roll_deg=roll)
        o, x, y = camera.project([[0, 0], [10, 0], [0, 10]], p)
        ex = (x - o) / np.linalg.norm(x - o)
        a = math.radians(roll)
        np.testing.assert_allclose(ex, [math.cos(a), math.sin(a)], atol=1e-12)
        np.testing.assert_allclose((y - o) / np.linalg.norm(y - o), [-ex[1], ex[0]], atol=1e-12)
        # Scale: focal / distance pixels per mm.
        assert np.linalg.norm(x - o) == pytest.approx(10 * 1070.0 / 500.0)


def test_world_to_image_is_exact_without_distortion() -> None:
    pose = PlanePose(520.0, tilt_deg=6.0, tilt_axis_deg=20.0, roll_deg=2.0, look_at_mm=(40, 25))
    scene = render_scene(
        SMALL_CAMERA,
        pose,
        board=SMALL_BOARD,
        board_origin_mm=(12.0, 7.0),
        board_angle_deg=4.0,
    )
    a = math.radians(4.0)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    expected_mm = SMALL_BOARD.world_points() @ rot.T + [12.0, 7.0]
    np.testing.assert_allclose(scene.dot_centres_mm, expected_mm, atol=1e-12)
    np.testing.assert_allclose(
        planarcal.transform_points(scene.world_to_image, scene.dot_centres_mm),
        scene.dot_centres_px,
        atol=1e-8,
    )
    assert scene.board_to_image is not None
    np.testing.assert_allclose(
        planarcal.transform_points(scene.board_to_image, SMALL_BOARD.world_points()),
        scene.dot_centres_px,
        atol=1e-8,
    )
    truth = scene.truth()
    np.testing.assert_array_equal(truth["dot_centres_px"], scene.dot_centres_px)
    np.testing.assert_array_equal(truth["dot_centres_mm"], scene.dot_centres_mm)


# ----------------------------------------------------------------------------- objects


@pytest.mark.parametrize("kind", synth.OBJECT_KINDS)
@pytest.mark.parametrize("angle", [0.0, 33.0, -120.0, 271.5])
@pytest.mark.parametrize("size", [3.0, 8.0, 12.5])
def test_silhouette_centroid_is_the_position(
    kind: synth.ObjectKind, angle: float, size: float
) -> None:
    length = 17.0 if kind in ("bolt", "rectangle") else None
    obj = SceneObject(kind, (123.456, -78.9), angle_deg=angle, size_mm=size, length_mm=length)
    outer, holes = obj.silhouette()
    assert not segments_intersect(outer)
    area, centroid = polygon_area_centroid(outer)
    assert area > 0
    moment = area * centroid
    for hole in holes:
        a, c = polygon_area_centroid(hole)
        assert a > 0
        area, moment = area - a, moment - a * c
    np.testing.assert_allclose(moment / area, obj.position_mm, atol=1e-9, rtol=0)
    # The polygons' area is the exact one (circles as 360-gons: within 1e-4).
    assert area == pytest.approx(obj.area_mm2, rel=1e-4)
    if kind in ("bolt", "rectangle", "nut") and not holes:
        assert area == pytest.approx(obj.area_mm2, rel=1e-12)


def test_object_sizes() -> None:
    nut = SceneObject("nut", (0, 0), size_mm=8.0)
    hexagon = nut.silhouette().outer
    across_flats = 2 * np.min(np.linalg.norm((hexagon + np.roll(hexagon, -1, axis=0)) / 2, axis=1))
    assert across_flats == pytest.approx(12.8)
    bolt = SceneObject("bolt", (0, 0), size_mm=6.0, length_mm=30.0)
    outer = bolt.silhouette().outer
    assert np.ptp(outer[:, 0]) == pytest.approx(9.6 + 30.0)  # head across flats + shank
    washer = SceneObject("washer", (0, 0), size_mm=8.0)
    assert washer.area_mm2 == pytest.approx(math.pi * (8.0**2 - 4.2**2))
    assert washer.hole_diameter_mm == pytest.approx(8.4) and bolt.hole_diameter_mm is None
    assert nut.hole_diameter_mm == pytest.approx(6.8)


def test_rendered_objects_are_where_the_truth_says() -> None:
    """In a sharp, undistorted, untilted render, each object's image centroid (by intensity)
    is its projected centroid and its image area is its area."""
    camera = CameraModel(width=480, height=320, focal_px=1070.0)
    pose = PlanePose(500.0, roll_deg=11.0, look_at_mm=(0.3, 0.7))
    objects = [
        SceneObject("bolt", (-45.0, -20.0), angle_deg=25.0, size_mm=6.0, length_mm=30.0),
        SceneObject("nut", (10.0, -25.0), angle_deg=-17.0),
        SceneObject("washer", (55.0, -22.0), size_mm=6.0),
        SceneObject("disc", (-40.0, 30.0), size_mm=15.0),
        SceneObject("rectangle", (20.0, 30.0), angle_deg=64.0, size_mm=9.0, length_mm=24.0),
    ]
    scene = render_scene(camera, pose, board=None, objects=objects, table_grey=60.0)
    image = scene.image.astype(np.float64)
    scale = 1070.0 / 500.0  # px per mm
    for obj, truth in zip(objects, scene.object_centroids_px, strict=True):
        outline = scene.project(obj.silhouette().outer)
        x0, y0 = np.floor(outline.min(axis=0)).astype(int) - 3
        x1, y1 = np.ceil(outline.max(axis=0)).astype(int) + 3
        centroid, mass = weighted_centroid(image, 60.0, (x0, y0, x1, y1))
        assert np.linalg.norm(centroid - truth) < 0.01, (obj.kind, centroid - truth)
        area_px = mass / (170.0 - 60.0)
        assert area_px == pytest.approx(obj.area_mm2 * scale**2, rel=2e-3), obj.kind


# ----------------------------------------------------------------------------- pixels


@pytest.mark.parametrize(
    ("roll", "look"), [(0.0, (130.31, 90.17)), (7.3, (131.12, 88.43))], ids=["roll0", "roll7"]
)
def test_dot_centroid_bias_is_below_a_hundredth_of_a_pixel(
    roll: float, look: tuple[float, float]
) -> None:
    """The renderer's own bias: in a sharp, noise-free, distortion-free, untilted render of
    the paper's board (dots 21 px across), the intensity-weighted centroid of every dot lies
    within 0.01 px of the projected centre (measured: at most 0.0018 px, 0.0006 px on average,
    uint8 rounding and the centroid's own sampling bias included)."""
    camera = CameraModel(width=700, height=500, focal_px=1070.0)
    pose = PlanePose(500.0, roll_deg=roll, look_at_mm=look)
    scene = render_scene(camera, pose, board=CircleGridBoard())
    assert scene.dots_in_view(margin_px=5).all()
    image = scene.image.astype(np.float64)
    r = 5.0 * 1070.0 / 500.0 + 3
    errors = []
    for c in scene.dot_centres_px:
        box = (int(c[0] - r), int(c[1] - r), int(c[0] + r) + 1, int(c[1] + r) + 1)
        centroid, _ = weighted_centroid(image, 225.0, box)
        errors.append(np.linalg.norm(centroid - c))
    assert max(errors) < 0.01, max(errors)
    assert np.mean(errors) < 0.003


def test_pixels_match_a_brute_force_reference() -> None:
    """Through strong distortion and a steep tilt, every pixel's value is the fraction of its
    area covered, as 32 x 32 point samples per pixel, each traced to the plane, measure it."""
    camera = CameraModel(width=40, height=36, focal_px=500.0, principal=(-160.0, -120.0))
    camera = dataclasses.replace(camera, k1=-0.25, k2=0.05)
    pose = PlanePose(300.0, tilt_deg=30.0, tilt_axis_deg=20.0, roll_deg=15.0, look_at_mm=(0, 0))
    centre = camera.image_to_plane([19.5, 17.5], pose)
    nut = SceneObject("nut", (centre[0] - 4.0, centre[1]), angle_deg=10.0, size_mm=12.0)
    disc = SceneObject("disc", (centre[0] + 10.0, centre[1] + 6.0), size_mm=9.0)
    scene = render_scene(
        camera,
        pose,
        board=None,
        objects=[nut, disc],
        table_grey=0.0,
        metal_grey=250.0,
        supersample=4,
    )
    m = 32
    o = (np.arange(m) + 0.5) / m - 0.5
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    su = (u[..., None, None] + o[None, None, None, :]).repeat(m, axis=2)
    sv = (v[..., None, None] + o[None, None, :, None]).repeat(m, axis=3)
    plane = camera.image_to_plane(np.stack([su, sv], axis=-1).reshape(-1, 2), pose)
    inside = np.zeros(len(plane), bool)
    # The nut: a convex hexagon minus a round hole; the disc: a circle.
    hexagon = nut.silhouette().outer
    edges = np.roll(hexagon, -1, axis=0) - hexagon
    rel = plane[:, None, :] - hexagon[None]
    in_hex = (edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0] >= 0).all(axis=1)
    assert nut.hole_diameter_mm == pytest.approx(0.85 * 12.0)
    assert nut.hole_diameter_mm is not None
    hole = np.linalg.norm(plane - nut.position_mm, axis=1) < nut.hole_diameter_mm / 2
    inside |= in_hex & ~hole
    inside |= np.linalg.norm(plane - disc.position_mm, axis=1) < disc.size_mm / 2
    reference = 250.0 * inside.reshape(camera.height, camera.width, m * m).mean(axis=2)
    assert 0.05 < (reference > 0).mean() < 0.8  # both objects are in the picture
    # The renderer's values are rounded to whole grey levels (0.5 of 250); the reference's
    # point sampling is itself good to about 1 / 32 of an edge pixel.
    error = np.abs(scene.image - reference)
    assert error.max() < 0.02 * 250, error.max()
    assert error.mean() < 0.002 * 250


def test_dots_follow_the_lens_and_the_tilt() -> None:
    """With strong distortion and a steep tilt each dot's image is where project() puts its
    centre (within the small bias of perspective on a 10 mm dot)."""
    camera = CameraModel(width=800, height=600, focal_px=700.0, k1=-0.3, k2=0.08)
    pose = PlanePose(420.0, tilt_deg=25.0, tilt_axis_deg=70.0, roll_deg=5.0, look_at_mm=(130, 90))
    scene = render_scene(camera, pose, board=CircleGridBoard())
    visible = scene.dots_in_view(margin_px=5)
    assert visible.sum() > 100
    image = scene.image.astype(np.float64)
    undistorted = planarcal.transform_points(scene.world_to_image, scene.dot_centres_mm)
    assert np.linalg.norm(undistorted - scene.dot_centres_px, axis=1).max() > 10  # strong lens
    for c in scene.dot_centres_px[visible]:
        box = (int(c[0] - 12), int(c[1] - 12), int(c[0] + 12) + 1, int(c[1] + 12) + 1)
        centroid, _ = weighted_centroid(image, 225.0, box)
        assert np.linalg.norm(centroid - c) < 0.05


def test_dots_are_dark_and_the_paper_light(paper: synth.PaperScene) -> None:
    scene = paper.calibration
    assert scene.board is not None and scene.image.dtype == np.uint8
    assert scene.image.shape == (720, 1280)
    assert scene.dots_in_view(margin_px=10).all()
    img = scene.image.astype(np.float64)
    centres = np.rint(scene.dot_centres_px).astype(int)
    dot_values = img[centres[:, 1], centres[:, 0]]
    assert dot_values.max() < 70
    board = scene.board
    between = board.world_points()[board.cols :] - [0, board.pitch / 2]  # paper between rows
    gaps = np.rint(scene.project(between)).astype(int)
    assert img[gaps[:, 1], gaps[:, 0]].min() > 170
    corners = img[[5, 5, -6, -6], [5, -6, 5, -6]]  # the table
    assert corners.max() < 110
    # Dot diameters in the image: 15 to 25 px.
    ring = np.c_[np.cos(np.linspace(0, 2 * np.pi, 65)), np.sin(np.linspace(0, 2 * np.pi, 65))]
    for centre in board.world_points()[[0, 13, 70, 126, 139]]:
        outline = scene.project(centre + 5.0 * ring)
        assert 15 < np.ptp(outline[:, 0]) < 25


def test_light_on_dark_inverts_the_board() -> None:
    render = functools.partial(
        render_scene, SMALL_CAMERA, SMALL_POSE, board=SMALL_BOARD, paper_margin_mm=10.0
    )
    normal = render().image.astype(int)
    inverse = render(light_on_dark=True).image.astype(int)
    # Inside the paper every pixel is inverted (paper <-> ink), outside nothing changes.
    corners = SMALL_CAMERA.project([[-13.0, -13.0], [73.0, 53.0]], SMALL_POSE)
    (x0, y0), (x1, y1) = np.ceil(corners[0]).astype(int), np.floor(corners[1]).astype(int)
    inside = (slice(y0, y1 + 1), slice(x0, x1 + 1))
    assert np.abs(normal[inside] + inverse[inside] - (225 + 35)).max() <= 1
    assert (normal[inside] < 100).mean() > 0.1  # the dots are in there
    # The paper reaches 10 mm beyond the dots' outer edges: (-15, -15) to (75, 55) mm.
    paper = SMALL_CAMERA.project([[-16.0, -16.0], [76.0, 56.0]], SMALL_POSE)
    (x0, y0), (x1, y1) = np.floor(paper[0]).astype(int), np.ceil(paper[1]).astype(int)
    outside = np.ones(normal.shape, bool)
    outside[y0 : y1 + 1, x0 : x1 + 1] = False
    assert (normal[outside] == 100).all() and (inverse[outside] == 100).all()


def test_same_seed_same_image_other_seed_other_noise() -> None:
    render = functools.partial(
        render_scene,
        SMALL_CAMERA,
        SMALL_POSE,
        board=SMALL_BOARD,
        noise_sigma=3.0,
        blur_sigma_px=0.7,
        vignette=0.2,
    )
    a = render(seed=5).image
    b = render(seed=5).image
    c = render(seed=6).image
    np.testing.assert_array_equal(a, b)
    assert (a != c).mean() > 0.5
    assert np.abs(a.astype(int) - c.astype(int)).mean() < 5  # only the noise differs


def test_noise_has_the_requested_std() -> None:
    for sigma in (1.5, 4.0, 10.0):
        img = render_scene(SMALL_CAMERA, SMALL_POSE, board=None, noise_sigma=sigma, seed=3).image
        # uint8 rounding adds a uniform error of variance 1/12.
        assert img.std() == pytest.approx(math.sqrt(sigma**2 + 1 / 12), rel=0.02)
        assert img.mean() == pytest.approx(100.0, abs=0.1)
    flat = render_scene(SMALL_CAMERA, SMALL_POSE, board=None).image
    assert (flat == 100).all()


@pytest.mark.parametrize("sigma", [0.0, 0.8, 1.5, 3.0])
def test_blur_has_the_requested_width(sigma: float) -> None:
    """Across a straight edge the image is the edge's area-sampled profile blurred by a
    Gaussian of the requested sigma: within one grey level of the continuous model."""
    wall = SceneObject("rectangle", (30.0, 0.0), size_mm=100.0, length_mm=60.0, grey=220.0)
    pose = PlanePose(500.0, look_at_mm=(0.13, 0.0))
    img = render_scene(
        SMALL_CAMERA, pose, board=None, objects=[wall], blur_sigma_px=sigma
    ).image.astype(np.float64)
    edge = SMALL_CAMERA.project([0.0, 0.0], pose)[0]  # the wall's left edge, x = 159.22 px
    j = np.arange(int(edge) - 20, int(edge) + 21)
    x = j[:, None] + (np.arange(400) + 0.5) / 400 - 0.5  # points across each pixel
    if sigma == 0.0:
        covered = (x > edge).mean(axis=1)
    else:
        z = ((x - edge) / (sigma * math.sqrt(2))).ravel()
        covered = (0.5 * (1 + np.array([math.erf(v) for v in z]))).reshape(x.shape).mean(axis=1)
    expected = 100.0 + 120.0 * covered
    for row in (60, 120, 180):
        assert np.abs(img[row, j] - expected).max() <= 1.0
    if sigma == 0.0:
        assert np.count_nonzero(np.diff(img[120, j])) == 2  # one pixel partly covered: sharp


def test_uneven_lighting() -> None:
    img = render_scene(
        SMALL_CAMERA, SMALL_POSE, board=None, lighting_gradient=0.4, lighting_angle_deg=0.0
    ).image.astype(np.float64)
    assert img[:, -1].mean() / img[:, 0].mean() == pytest.approx(1.2 / 0.8, rel=0.01)
    assert (np.diff(img[100]) >= 0).all()
    vignetted = render_scene(SMALL_CAMERA, SMALL_POSE, board=None, vignette=0.3).image
    assert vignetted[0, 0] == round(100 * 0.7) and vignetted[119, 159] == 100


def test_color() -> None:
    grey = render_scene(SMALL_CAMERA, SMALL_POSE, board=SMALL_BOARD).image
    color = render_scene(SMALL_CAMERA, SMALL_POSE, board=SMALL_BOARD, color=True).image
    assert color.shape == (240, 320, 3) and color.dtype == np.uint8
    assert np.abs(color.astype(int).mean(axis=2) - grey).max() <= 10
    assert color[0, 0, 2] > color[0, 0, 0]  # a warm table


# ----------------------------------------------------------------------------- objects with height

# A raised disc 20 mm across and 20 mm tall, 117 mm from the nadir of a camera 500 mm above
# the table looking straight down: its top is 22.3 px in radius, 10.4 px further out than
# its base, and its wall a band 11.3 px wide on the nadir's side.
TALL_CAMERA = CameraModel(width=640, height=480, focal_px=1070.0)
TALL_POSE = PlanePose(500.0, look_at_mm=(0.0, 0.0))
TALL_DISC = SceneObject("disc", (100.0, 60.0), size_mm=20.0, height_mm=20.0)


@pytest.mark.parametrize(("camera", "pose"), list(zip(CAMERAS, POSES, strict=True)))
def test_raised_truth_is_the_projection_of_the_top_centroid(
    camera: CameraModel, pose: PlanePose
) -> None:
    """object_centroids_px is cv2.projectPoints of (X, Y, -h): the top face's centroid."""
    centre = camera.image_to_plane([camera.width / 2, camera.height / 2], pose)
    objects = [
        SceneObject("nut", (centre[0] - 20, centre[1]), size_mm=8.0, height_mm=6.5),
        SceneObject("disc", (centre[0] + 15, centre[1] + 10), size_mm=10.0, height_mm=40.0),
        SceneObject("washer", (centre[0], centre[1] - 25), size_mm=6.0),
    ]
    scene = render_scene(camera, pose, board=None, objects=objects, supersample=2)
    xyz = np.c_[scene.object_centroids_mm, -scene.object_heights_mm]
    rvec, tvec = pose.rvec_tvec()
    expected, _ = cv2.projectPoints(xyz, rvec, tvec, camera.matrix(), camera.dist_coeffs())
    np.testing.assert_allclose(scene.object_centroids_px, expected.reshape(-1, 2), atol=1e-7)
    truth = scene.truth()
    np.testing.assert_array_equal(truth["object_heights_mm"], [6.5, 40.0, 0.0])
    np.testing.assert_array_equal(truth["object_centroids_px"], scene.object_centroids_px)
    # The same through every projection entry point; heights broadcast over the points.
    np.testing.assert_array_equal(
        scene.project(scene.object_centroids_mm, scene.object_heights_mm),
        scene.object_centroids_px,
    )
    np.testing.assert_array_equal(
        scene.view.project(scene.object_centroids_mm, scene.object_heights_mm),
        scene.object_centroids_px,
    )
    grid = np.stack(np.meshgrid(np.arange(4.0), np.arange(3.0)), axis=-1) * 5 + centre
    heights = np.arange(12.0).reshape(3, 4)
    px = camera.project(grid, pose, heights)
    assert px.shape == (3, 4, 2)
    one = camera.project(grid[1, 2], pose, heights[1, 2])
    np.testing.assert_allclose(px[1, 2], one, atol=1e-9, rtol=0)
    np.testing.assert_allclose(
        camera.project(grid, pose, 7.0), camera.project(grid, pose, np.full((3, 4), 7.0)), atol=0
    )
    # Height 0 is the plane itself, bit for bit.
    np.testing.assert_array_equal(camera.project(grid, pose, 0.0), camera.project(grid, pose))


def test_raised_top_centroid_bias_is_below_a_hundredth_of_a_pixel() -> None:
    """The top face's image, read off a sharp render, is where the truth says: its
    area-weighted centroid (anti-aliased edge pixels by their coverage) is within 0.005 px
    of the projected (X, Y, -h) (measured: 0.001 px) and its area is the top's."""

    def render(top: float) -> synth.RenderedScene:
        disc = dataclasses.replace(TALL_DISC, grey=top)
        return render_scene(TALL_CAMERA, TALL_POSE, board=None, objects=[disc], side_grey=60.0)

    bright, dark = render(250.0), render(50.0)
    # Only the top's grey differs between the two: their difference is its coverage, pixel
    # by pixel, whatever the walls and the table around it.
    coverage = (bright.image.astype(np.float64) - dark.image) / 200.0
    assert coverage.min() >= -0.01 and coverage.max() <= 1.0
    ys, xs = np.mgrid[0 : TALL_CAMERA.height, 0 : TALL_CAMERA.width]
    centroid = np.array([(coverage * xs).sum(), (coverage * ys).sum()]) / coverage.sum()
    truth = bright.object_centroids_px[0]
    assert np.linalg.norm(centroid - truth) < 0.005, centroid - truth
    radius_px = 10.0 * 1070.0 / (500.0 - 20.0)
    assert coverage.sum() == pytest.approx(math.pi * radius_px**2, rel=1e-4)
    # The base's centre is 10 px away: the truth is the top's, not the base's.
    base = bright.project(bright.object_centroids_mm)[0]
    assert np.linalg.norm(base - truth) > 10.0


def test_walls_show_on_the_side_facing_the_camera() -> None:
    """The wall that faces the camera shows between the base's outline and the top's, on the
    side towards the camera's nadir; on the far side the top overhangs the base and hides
    what is there (board dots included); the top and the walls are flat tones."""
    board = CircleGridBoard(cols=8, rows=5, pitch=20.0, diameter=10.0)
    scene = render_scene(TALL_CAMERA, TALL_POSE, board=board, objects=[TALL_DISC])
    assert scene.effects["side_grey"] == pytest.approx(60.0)  # 0.6 x the table's 100
    image = scene.image.astype(np.float64)
    top = scene.object_centroids_px[0]
    nadir = scene.project(TALL_POSE.camera_centre_mm()[:2])
    u = (top - nadir) / np.linalg.norm(top - nadir)  # away from the nadir
    radius = 10.0 * 1070.0 / 480.0

    def at(offset: float) -> float:
        x, y = np.rint(top + offset * u).astype(int)
        return float(image[y, x])

    # Towards the nadir: the top, then the wall (11.3 px wide here), then the paper.
    assert at(-(radius - 2)) == 170.0
    assert at(-(radius + 2)) == at(-(radius + 9)) == 60.0
    assert at(-(radius + 14)) == 225.0
    # Away from it: the top, then straight onto the paper, no wall.
    assert at(radius - 2) == 170.0 and at(radius + 2) == 225.0
    wall = np.argwhere(image == 60.0)[:, ::-1]
    wall = wall[np.linalg.norm(wall - top, axis=1) < radius + 15]  # not a dot's edge
    assert len(wall) > 300
    assert ((wall - top) @ u < -5.0).all()  # all on the nadir's side
    # Everything inside the top's outline is the top, though dots lie under part of it.
    xs, ys = np.meshgrid(np.arange(640), np.arange(480))
    inside = np.hypot(xs - top[0], ys - top[1]) < radius - 1.5
    assert (image[inside] == 170.0).all()
    seen = TALL_CAMERA.image_to_plane(np.c_[xs[inside], ys[inside]], TALL_POSE)
    dots = board.world_points()
    in_dot = np.linalg.norm(seen[:, None] - dots[None], axis=2).min(axis=1) < 5.0
    assert in_dot.mean() > 0.1  # ink under the object, hidden by its top


# An object for the ray tracer: (polygon or None, outer disc or None, hole or None), discs as
# (x, y, radius).
Shapes = tuple[
    np.ndarray | None, tuple[float, float, float] | None, tuple[float, float, float] | None
]


def _shapes(obj: SceneObject) -> Shapes:
    """The object as its polygon or its disc, and its hole."""
    x, y = obj.position_mm
    hole = None if obj.hole_diameter_mm is None else (x, y, obj.hole_diameter_mm / 2)
    if obj.kind == "disc":
        return None, (x, y, obj.size_mm / 2), hole
    if obj.kind == "washer":
        return None, (x, y, obj.size_mm), hole
    return obj.silhouette().outer, None, hole


def _inside(p: np.ndarray, shapes: Shapes) -> np.ndarray:
    """Whether each point (N, 2) lies in the object (even-odd rule, discs by distance)."""
    poly, circle, hole = shapes
    if poly is not None:
        a, b = poly[None], np.roll(poly, -1, axis=0)[None]
        py = p[:, None, 1]
        crosses = (a[..., 1] > py) != (b[..., 1] > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = a[..., 0] + (py - a[..., 1]) * (b[..., 0] - a[..., 0]) / (b[..., 1] - a[..., 1])
        inside = np.count_nonzero(crosses & (p[:, None, 0] < x), axis=1) % 2 == 1
    else:
        assert circle is not None
        inside = np.hypot(p[:, 0] - circle[0], p[:, 1] - circle[1]) < circle[2]
    if hole is not None:
        inside &= np.hypot(p[:, 0] - hole[0], p[:, 1] - hole[1]) >= hole[2]
    return np.asarray(inside)


def _crossings(p: np.ndarray, q: np.ndarray, shapes: Shapes) -> np.ndarray:
    """(N, K): the parameters s in [0, 1] at which p + s (q - p) crosses the object's
    outline (NaN: no crossing)."""
    poly, circle, hole = shapes
    d = q - p
    columns = []
    if poly is not None:
        a, f = poly[None], (np.roll(poly, -1, axis=0) - poly)[None]
        w = a - p[:, None, :]
        den = d[:, None, 0] * f[..., 1] - d[:, None, 1] * f[..., 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (w[..., 0] * f[..., 1] - w[..., 1] * f[..., 0]) / den
            t = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / den
        columns.append(np.where((s >= 0) & (s <= 1) & (t >= 0) & (t <= 1), s, np.nan))
    for c in (circle, hole):
        if c is not None:
            e = p - c[:2]
            aa, bb, cc = (d * d).sum(1), (e * d).sum(1), (e * e).sum(1) - c[2] ** 2
            disc = bb * bb - aa * cc
            root = np.sqrt(np.maximum(disc, 0.0))
            for s in ((-bb - root) / aa, (-bb + root) / aa):
                columns.append(np.where((disc >= 0) & (s >= 0) & (s <= 1), s, np.nan)[:, None])
    return np.concatenate(columns, axis=1)


def ray_traced(
    camera: CameraModel,
    pose: PlanePose,
    objects: list[SceneObject],
    tops: list[float],
    side: float,
    m: int = 16,
) -> np.ndarray:
    """What each pixel sees, as the mean of m x m jittered rays, each followed from the
    camera down to the table through every object (a prism: first hit from above wins)."""
    rng = np.random.default_rng(0)
    grid = (np.arange(m) + 0.5) / m - 0.5
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    jitter = rng.uniform(-0.5 / m, 0.5 / m, (2, camera.height, camera.width, m, m))
    su = u[..., None, None] + grid[None, None, None, :] + jitter[0]
    sv = v[..., None, None] + grid[None, None, :, None] + jitter[1]
    p0 = camera.image_to_plane(np.stack([su, sv], axis=-1).reshape(-1, 2), pose)
    centre = pose.camera_centre_mm()
    foot, distance = centre[:2], -centre[2]
    nearest = np.full(len(p0), -np.inf)  # the height of what each ray sees
    value = np.zeros(len(p0))  # the table: black
    for obj, top_grey in zip(objects, tops, strict=True):
        shapes, h = _shapes(obj), float(obj.height_mm)
        if h == 0:
            height = np.where(_inside(p0, shapes), 0.0, -np.inf)
            seen = np.full(len(p0), top_grey)
        else:
            ph = p0 + (h / distance) * (foot - p0)  # where the ray crosses the top's plane
            on_top = _inside(ph, shapes)
            # Going down from there, the first crossing into the object is a wall.
            entry = np.where(on_top, 0.0, np.inf)
            for s in _crossings(ph, p0, shapes).T:
                after = ph + np.clip(np.nan_to_num(s) + 1e-9, 0, 1)[:, None] * (p0 - ph)
                enters = ~np.isnan(s) & _inside(after, shapes)
                entry = np.where(enters & (s < entry), s, entry)
            height = np.where(np.isfinite(entry), h * (1 - entry), -np.inf)
            seen = np.where(on_top, top_grey, side)
        front = np.isfinite(height) & (height >= nearest)
        value = np.where(front, seen, value)
        nearest = np.where(front, height, nearest)
    return np.asarray(value.reshape(camera.height, camera.width, m * m).mean(axis=2))


def test_raised_pixels_match_a_ray_traced_reference() -> None:
    """Through strong distortion and a steep tilt, raised objects look as rays followed
    through the prisms say: a nut (its hole's far inner wall in view), a washer, a 30 mm
    tall disc whose wall and top hide part of a 12 mm tall block, which hides part of a flat
    disc. Within the reference's own sampling noise (12 x 12 jittered rays per pixel: 0.03
    of the contrast; measured 0.024, and 0.0096 against 32 x 32 rays), 0.002 on average."""
    camera = CameraModel(width=40, height=32, focal_px=220.0, principal=(-60.0, -40.0))
    camera = dataclasses.replace(camera, k1=-0.25, k2=0.05)
    pose = PlanePose(300.0, tilt_deg=25.0, tilt_axis_deg=20.0, roll_deg=15.0, look_at_mm=(0, 0))
    at = [tuple(p) for p in camera.image_to_plane([[9, 9], [22, 9], [31, 19], [32, 27]], pose)]
    objects = [
        SceneObject("disc", at[3], size_mm=8.0, grey=180.0),
        SceneObject("nut", at[0], angle_deg=10.0, size_mm=12.0, height_mm=8.0),
        SceneObject("disc", at[1], size_mm=12.0, height_mm=30.0, grey=220.0),
        SceneObject("rectangle", at[2], 30.0, 6.0, length_mm=16.0, grey=120.0, height_mm=12.0),
        SceneObject("washer", tuple(camera.image_to_plane([35, 6], pose)), 0.0, 6.0, height_mm=2),
    ]
    scene = render_scene(
        camera, pose, board=None, objects=objects, table_grey=0.0, metal_grey=250.0, side_grey=60.0
    )
    tops = [180.0, 250.0, 220.0, 120.0, 250.0]
    reference = ray_traced(camera, pose, objects, tops, side=60.0, m=12)
    for tone in (60.0, 120.0, 180.0, 220.0, 250.0):  # each surface shows
        assert (np.abs(reference - tone) < 0.5).sum() >= 5, tone
    error = np.abs(scene.image - reference)
    assert error.max() < 0.03 * 250, error.max()
    assert error.mean() < 0.002 * 250, error.mean()


# The image of a scene with flat objects of every kind, a board, a tilt and lens
# distortion, as rendered before objects had a height (its SHA-256).
FLAT_SCENE_SHA256 = "d01471826492a4b3b4529f383fc840f5839650c4385294c605ff7b80abcfc425"


def test_height_zero_renders_as_before() -> None:
    """Flat objects (height 0, the default or given) render bit for bit as before heights
    existed, and their truth is the projection of their centroid on the table."""
    camera = CameraModel(width=160, height=120, focal_px=300.0, k1=-0.2, k2=0.05)
    pose = PlanePose(330.0, tilt_deg=12.0, tilt_axis_deg=30.0, roll_deg=5.0, look_at_mm=(30, 20))
    objects = [
        SceneObject("bolt", (-40.0, -25.0), angle_deg=25.0, size_mm=6.0, length_mm=30.0),
        SceneObject("nut", (95.0, -15.0), angle_deg=-17.0),
        SceneObject("washer", (100.0, 40.0), size_mm=6.0),
        SceneObject("disc", (-40.0, 60.0), size_mm=15.0, grey=210.0),
        SceneObject("rectangle", (40.0, 75.0), angle_deg=64.0, size_mm=9.0, length_mm=24.0),
    ]
    render = functools.partial(
        render_scene,
        camera,
        pose,
        board=SMALL_BOARD,
        board_origin_mm=(5.0, 3.0),
        board_angle_deg=4.0,
    )
    scene = render(objects=objects)
    assert hashlib.sha256(scene.image.tobytes()).hexdigest() == FLAT_SCENE_SHA256
    given = [dataclasses.replace(o, height_mm=0.0) for o in objects]
    again = render(objects=given)
    np.testing.assert_array_equal(again.image, scene.image)
    np.testing.assert_array_equal(again.object_centroids_px, scene.object_centroids_px)
    np.testing.assert_array_equal(scene.object_heights_mm, np.zeros(5))
    np.testing.assert_array_equal(
        scene.object_centroids_px, camera.project(scene.object_centroids_mm, pose)
    )


# Images of symmetric boards with origin markers (one as wide as the pitch), tilted, through
# lens distortion, as rendered before layouts, enlarged dots, marks and textures existed.
MARKER_SCENES_SHA256 = (
    "79ef640709f0271e265553db02fd0141fddd42e53834d184f080c29feb402ce2",
    "8ee59fc960fd84d0ac38a5ad5446235acdb26ff3b0b94b4d90db62e658150051",
)


def test_symmetric_boards_render_as_before() -> None:
    """The renderer's general board (layouts, per-dot sizes) draws the symmetric boards it
    drew before bit for bit, and the new options at their defaults change nothing."""
    camera = CameraModel(width=160, height=120, focal_px=300.0, k1=-0.2, k2=0.05)
    pose = PlanePose(330.0, tilt_deg=12.0, tilt_axis_deg=30.0, roll_deg=5.0, look_at_mm=(40, 30))
    wide = CircleGridBoard(5, 4, 20.0, 8.0, origin_marker=True, marker_diameter=20.0)
    first = render_scene(camera, pose, board=wide, board_origin_mm=(5.0, 3.0), board_angle_deg=4.0)
    second = render_scene(
        camera,
        pose,
        board=CircleGridBoard(6, 5, 15.0, 9.0, origin_marker=True),
        board_angle_deg=-20.0,
        light_on_dark=True,
        noise_sigma=2.0,
        blur_sigma_px=0.7,
        seed=4,
        color=True,
        supersample=5,
    )
    digests = tuple(hashlib.sha256(s.image.tobytes()).hexdigest() for s in (first, second))
    assert digests == MARKER_SCENES_SHA256
    defaults = render_scene(
        camera,
        pose,
        board=wide,
        board_origin_mm=(5.0, 3.0),
        board_angle_deg=4.0,
        enlarged_dots={},
        marks=(),
        table_texture=0.0,
        paper_texture=0.0,
    )
    np.testing.assert_array_equal(defaults.image, first.image)
    np.testing.assert_array_equal(first.dot_diameters_mm, wide.dot_diameters())


@pytest.mark.parametrize("side_grey", [None, 95.0], ids=["dark-walls", "walls-like-table"])
def test_detection_finds_the_top_of_a_raised_object(side_grey: float | None) -> None:
    """The paper's detection chain outlines a raised object's top, not its base or its wall:
    its centroid is the top's (the walls, darker than the table by default or nearly its
    tone, add no outline of their own around it)."""
    nut = SceneObject("nut", (-90.0, -40.0), angle_deg=20.0, size_mm=8.0, height_mm=6.5)
    scene = render_scene(
        TALL_CAMERA,
        TALL_POSE,
        board=None,
        objects=[TALL_DISC, nut],
        side_grey=side_grey,
        blur_sigma_px=0.8,
        noise_sigma=1.0,
        seed=1,
    )
    found = detect_objects(scene.image)
    assert len(found) == 2
    tops = scene.object_centroids_px
    bases = scene.project(scene.object_centroids_mm)
    assert np.linalg.norm(tops - bases, axis=1).min() > 2.5  # the nut's top is 2.8 px out
    for o in found:
        c = np.array(o.centroid_px)
        assert np.linalg.norm(tops - c, axis=1).min() < 0.5
        assert np.linalg.norm(bases - c, axis=1).min() > 2.0


# ----------------------------------------------------------------------------- the demo scene


@pytest.fixture(scope="module")
def paper() -> synth.PaperScene:
    return synth.paper_scene(0)


def test_paper_scene(paper: synth.PaperScene) -> None:
    calibration, objects = paper
    assert calibration.camera == objects.camera and calibration.pose == objects.pose
    assert calibration.objects == () and objects.board is None
    assert calibration.board == CircleGridBoard(cols=14, rows=10, pitch=20.0, diameter=10.0)
    kinds = [o.kind for o in objects.objects]
    assert kinds.count("bolt") == 3 and kinds.count("nut") == 7
    assert 500 <= calibration.pose.distance_mm <= 700
    assert 0 < abs(calibration.pose.tilt_deg) <= 5
    # Mild barrel distortion: dot centres 1-6 px from the homography's prediction.
    ideal = planarcal.transform_points(calibration.world_to_image, calibration.dot_centres_mm)
    shift = np.linalg.norm(ideal - calibration.dot_centres_px, axis=1).max()
    assert 1.0 < shift < 6.0
    # The objects lie inside the calibrated area (the dots' hull), apart from each other.
    outlines = [o.silhouette().outer for o in objects.objects]
    for outline in outlines:
        assert outline.min() > 3.0 and outline[:, 0].max() < 257.0 and outline[:, 1].max() < 177
    for i in range(len(outlines)):
        for j in range(i):
            assert boundary_distance(outlines[i], outlines[j]) > 5.0
    np.testing.assert_allclose(
        objects.object_centroids_px, objects.project(objects.object_centroids_mm), atol=0
    )
    # Each object is visible: metal over the table at its centroid's pixel (not for nuts:
    # their hole is there), the table elsewhere.
    img = objects.image
    for obj, c in zip(objects.objects, objects.object_centroids_px, strict=True):
        if obj.kind == "bolt":
            assert img[round(c[1]), round(c[0])] > 130
    assert np.median(img) < 110


def test_paper_scene_options() -> None:
    calibration, objects = synth.paper_scene(3, distortion=False, objects=False)
    assert objects.objects == ()
    assert calibration.camera.k1 == 0 and calibration.camera.k2 == 0
    np.testing.assert_allclose(
        planarcal.transform_points(calibration.world_to_image, calibration.dot_centres_mm),
        calibration.dot_centres_px,
        atol=1e-8,
    )


# ----------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    ("make", "error", "words"),
    [
        (lambda: PlanePose(0.0), ValueError, "behind the camera"),
        (lambda: PlanePose(-100.0), ValueError, "behind the camera"),
        (lambda: PlanePose(500.0, tilt_deg=90.0), ValueError, "edge-on"),
        (lambda: PlanePose(500.0, look_at_mm=(1.0,)), ValueError, "pair"),  # type: ignore[arg-type]
        (lambda: PlanePose(float("nan")), ValueError, "finite"),
        (lambda: CameraModel(focal_px=0.0), ValueError, "focal_px must be positive"),
        (lambda: CameraModel(width=0), ImageError, "width"),
        (lambda: CameraModel(width=640.0), ImageError, "whole number"),  # type: ignore[arg-type]
        (lambda: CameraModel(k1=-0.6), ValueError, "folds over"),
        (lambda: SceneObject("nut", (0, 0), size_mm=0.0), ValueError, "size_mm must be positive"),
        (lambda: SceneObject("nut", (0, 0), size_mm=-3.0), ValueError, "size_mm"),
        (lambda: SceneObject("screw", (0, 0)), ValueError, "kind must be one of"),  # type: ignore[arg-type]
        (lambda: SceneObject("nut", (0, 0), length_mm=3.0), ValueError, "length_mm"),
        (lambda: SceneObject("bolt", (0, 0), length_mm=-3.0), ValueError, "length_mm"),
        (lambda: SceneObject("disc", (0, float("inf"))), ValueError, "finite"),
        (lambda: SceneObject("disc", (0, 0), grey=300), ValueError, "grey"),
        (lambda: SceneObject("disc", (0, 0), height_mm=-1.0), ValueError, "height_mm must be >= 0"),
        (lambda: SceneObject("disc", (0, 0), height_mm=math.nan), ValueError, "height_mm.*finite"),
        (lambda: SceneObject("disc", (0, 0), height_mm="2"), ValueError, "height_mm.*number"),  # type: ignore[arg-type]
        (
            lambda: render_scene(
                SMALL_CAMERA, SMALL_POSE, objects=[SceneObject("disc", (0, 0), height_mm=500.0)]
            ),
            ValueError,
            r"objects\[0\]\.height_mm .* reaches the camera",
        ),
        (
            lambda: render_scene(SMALL_CAMERA, SMALL_POSE, side_grey=300.0),
            ImageError,
            "side_grey",
        ),
        (
            lambda: CameraModel().project([[0, 0], [1, 1]], PlanePose(500.0), height_mm=[1, 2, 3]),
            ValueError,
            "height_mm must be a scalar or one height per point",
        ),
        (
            lambda: CameraModel().project([0, 0], PlanePose(500.0), height_mm=math.inf),
            ValueError,
            "height_mm: height 0 is not finite",
        ),
        (
            lambda: CameraModel().project([[0, 0]], PlanePose(500.0), height_mm=600.0),
            ValueError,
            "at height 600.0 mm is behind the camera",
        ),
        (lambda: render_scene(SMALL_CAMERA, SMALL_POSE, noise_sigma=-1), ImageError, "noise"),
        (lambda: render_scene(SMALL_CAMERA, SMALL_POSE, paper_grey=256), ImageError, "paper"),
        (lambda: render_scene(SMALL_CAMERA, SMALL_POSE, blur_sigma_px=-1), ImageError, "blur"),
        (lambda: render_scene(SMALL_CAMERA, SMALL_POSE, vignette=1.0), ImageError, "vignette"),
        (lambda: render_scene(SMALL_CAMERA, SMALL_POSE, supersample=0), ImageError, "supersample"),
        (lambda: render_scene(SMALL_CAMERA, SMALL_POSE, seed=-1), ImageError, "seed"),
        (lambda: render_scene(SMALL_CAMERA, SMALL_POSE, paper_margin_mm=-1), BoardError, "margin"),
        (lambda: render_scene(SMALL_CAMERA, SMALL_POSE, board="14x10"), BoardError, "board"),  # type: ignore[arg-type]
        (
            lambda: render_scene(SMALL_CAMERA, SMALL_POSE, board_origin_mm=(0, float("nan"))),
            BoardError,
            "board_origin_mm",
        ),
        (
            lambda: render_scene(CameraModel(), PlanePose(500.0, tilt_deg=80.0)),
            ValueError,
            "horizon",
        ),
        (
            lambda: CameraModel().project([[0, 0], [0, -2000]], PlanePose(500.0, tilt_deg=30.0)),
            ValueError,
            "point 1 .* behind the camera",
        ),
        (lambda: CameraModel().project([[0, 0, 0]], PlanePose(500.0)), ValueError, "shape"),
        (lambda: SceneObject("nut", (0, 0)).silhouette(arc_vertices=3), ValueError, "at least 8"),
    ],
)
def test_invalid_parameters_raise_clear_errors(
    make: Callable[[], object], error: type[Exception], words: str
) -> None:
    with pytest.raises(error, match=words):
        make()
