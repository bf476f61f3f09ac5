"""Each part's angle (planarcal.live.part_angle) on rendered scenes with known part angles:
steep perspective and lens distortion (where the axis measured in pixels is degrees off), round
parts without an axis, mirrored frames, the [-90, 90) range, and the angle through
locate_objects, the production loop and the annotated picture."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.errors import ArgumentError
from planarcal.live import part_angle
from planarcal.live.objects import _detect, detect_objects, locate_objects
from planarcal.live.tracker import Tracker
from planarcal.report.drawing import AXIS_BGR, draw_objects

F64 = NDArray[np.float64]

# A webcam's barrel distortion with a decentring term, the paper scene's blur and noise.
CAMERA = synth.CameraModel(
    width=1280, height=720, focal_px=1070.0, principal=(644.0, 355.0), k1=-0.12, k2=0.03, p1=5e-4
)
CENTRE = (135.0, 92.0)


def turn_deg(a: float, b: float) -> float:
    """The smallest turn between two axes, degrees (an axis at a is the one at a + 180)."""
    return abs((a - b + 90.0) % 180.0 - 90.0)


def elongated(rng: np.random.Generator) -> list[synth.SceneObject]:
    """Twelve parts of aspect 2 : 1 or more (rectangles 2 : 1 and 3 : 1, M6 bolts) in a grid
    about CENTRE, at random angles."""
    out = []
    for k in range(12):
        x = CENTRE[0] + 50.0 * (k % 4 - 1.5) + rng.uniform(-3, 3)
        y = CENTRE[1] + 50.0 * (k // 4 - 1.0) + rng.uniform(-3, 3)
        angle = float(rng.uniform(-180.0, 180.0))
        if k % 3 == 2:
            out.append(synth.SceneObject("bolt", (x, y), angle, size_mm=6.0, length_mm=30.0))
        else:
            length = 16.0 if k % 3 == 0 else 24.0
            out.append(synth.SceneObject("rectangle", (x, y), angle, 8.0, length_mm=length))
    return out


def round_parts(rng: np.random.Generator) -> list[synth.SceneObject]:
    """Discs, squares, nuts and washers (no second-moment axis), and 1.5 : 1 rectangles (an
    axis), in turn."""
    out = []
    for k in range(15):
        x = CENTRE[0] + 45.0 * (k % 5 - 2) + rng.uniform(-3, 3)
        y = CENTRE[1] + 50.0 * (k // 5 - 1.0) + rng.uniform(-3, 3)
        angle = float(rng.uniform(-180.0, 180.0))
        kind = k % 5
        if kind == 0:
            out.append(synth.SceneObject("disc", (x, y), angle, size_mm=14.0))
        elif kind == 1:
            out.append(synth.SceneObject("rectangle", (x, y), angle, 12.0))
        elif kind == 2:
            out.append(synth.SceneObject("nut", (x, y), angle, size_mm=8.0))
        elif kind == 3:
            out.append(synth.SceneObject("washer", (x, y), angle, size_mm=8.0))
        else:
            out.append(synth.SceneObject("rectangle", (x, y), angle, 10.0, length_mm=15.0))
    return out


def render(
    objects: list[synth.SceneObject], tilt_deg: float, seed: int
) -> tuple[synth.RenderedScene, synth.PlanePose]:
    rng = np.random.default_rng(seed)
    pose = synth.PlanePose(
        distance_mm=500.0,
        tilt_deg=tilt_deg,
        tilt_axis_deg=float(rng.uniform(0.0, 360.0)),
        roll_deg=float(rng.uniform(-3.0, 3.0)),
        look_at_mm=CENTRE,
    )
    return photograph(pose, objects, seed), pose


def photograph(
    pose: synth.PlanePose, objects: list[synth.SceneObject], seed: int, board: bool = False
) -> synth.RenderedScene:
    """The scene through CAMERA, with the paper scene's blur and sensor noise."""
    return synth.render_scene(
        CAMERA,
        pose,
        board=synth.PAPER_BOARD if board else None,
        objects=objects,
        table_grey=100.0,
        metal_grey=170.0,
        blur_sigma_px=0.8,
        noise_sigma=2.5,
        seed=seed,
    )


def matched(view: synth.RenderedScene, centroids_px: F64) -> list[int]:
    """The placed object each found centroid belongs to (within 2 px of its image)."""
    out = []
    for c in centroids_px:
        gaps = np.hypot(*(view.object_centroids_px - c).T)
        assert gaps.min() < 2.0
        out.append(int(np.argmin(gaps)))
    return out


@pytest.fixture(scope="module")
def steep() -> tuple[synth.RenderedScene, synth.PlanePose, list[synth.SceneObject]]:
    """Elongated parts seen from 500 mm under a 30 degree tilt, through a distorting lens."""
    things = elongated(np.random.default_rng(7))
    view, pose = render(things, 30.0, seed=7)
    return view, pose, things


def test_elongated_parts_are_within_half_a_degree_under_steep_perspective(
    steep: tuple[synth.RenderedScene, synth.PlanePose, list[synth.SceneObject]],
) -> None:
    view, pose, things = steep
    found = _detect(view.image)
    assert len(found.areas) == len(things)

    def to_plane(px: F64) -> F64:
        return CAMERA.image_to_plane(px, pose)

    jac = part_angle.jacobians(to_plane, found.centroids)
    axes = part_angle.part_axes(found.moments, found.areas, jac)
    pixel_errors = []
    for i, j in enumerate(matched(view, found.centroids)):
        truth = things[j].angle_deg
        assert -90.0 <= axes.angles_deg[i] < 90.0
        assert turn_deg(axes.angles_deg[i], truth) < 0.5, (i, axes.angles_deg[i], truth)
        # The axis measured in pixels, its direction carried onto the plane through the same
        # Jacobian: right only for a conformal mapping.
        m = found.moments[i]
        a = 0.5 * math.atan2(2.0 * m[1], m[0] - m[2])
        d = jac[i] @ [math.cos(a), math.sin(a)]
        pixel_errors.append(turn_deg(math.degrees(math.atan2(d[1], d[0])), truth))
    # The tensor must be turned, not the pixel axis: that is degrees off here.
    assert max(pixel_errors) > 2.0, pixel_errors
    # The loop's path gives the same angles.
    same = part_angle.part_angles_deg(
        found.moments, found.areas, part_angle.jacobians(to_plane, found.centroids)
    )
    np.testing.assert_allclose(same, axes.angles_deg, rtol=0, atol=1e-9)


def test_round_parts_have_no_axis_and_a_one_and_a_half_to_one_part_has_one() -> None:
    things = round_parts(np.random.default_rng(11))
    view, pose = render(things, 40.0, seed=11)
    found = _detect(view.image)
    assert len(found.areas) == len(things)
    angles = part_angle.part_angles_deg(
        found.moments,
        found.areas,
        part_angle.jacobians(lambda p: CAMERA.image_to_plane(p, pose), found.centroids),
    )
    for i, j in enumerate(matched(view, found.centroids)):
        o = things[j]
        if o.kind == "rectangle" and o.length_mm is not None:  # 1.5 : 1
            assert turn_deg(angles[i], o.angle_deg) < 1.0, (o, angles[i])
        else:  # disc, square, nut, washer
            assert math.isnan(angles[i]), (o, angles[i])


def test_a_mirrored_frame_negates_the_angle(
    steep: tuple[synth.RenderedScene, synth.PlanePose, list[synth.SceneObject]],
) -> None:
    """A robot's base frame seen from above is often the board's mirror image: y flipped."""
    view, pose, _ = steep
    found = _detect(view.image)

    def board(px: F64) -> F64:
        return np.asarray(CAMERA.image_to_plane(px, pose), dtype=np.float64)

    def mirrored(px: F64) -> F64:
        return np.asarray(board(px) * [1.0, -1.0] + [400.0, 250.0], dtype=np.float64)

    def angles(mapping: part_angle.Mapping) -> F64:
        jac = part_angle.jacobians(mapping, found.centroids)
        return part_angle.part_angles_deg(found.moments, found.areas, jac)

    a, b = angles(board), angles(mirrored)
    assert np.isfinite(a).all()
    np.testing.assert_allclose(b, part_angle.wrap_deg(-a), atol=1e-9)
    # A rotation of the frame by 30 degrees subtracts 30 from every angle.
    turn = np.radians(30.0)
    rot = np.array([[math.cos(turn), math.sin(turn)], [-math.sin(turn), math.cos(turn)]])
    c = angles(lambda p: board(p) @ rot.T)
    np.testing.assert_allclose(c, part_angle.wrap_deg(a - 30.0), atol=1e-9)


def rectangle_moments(length: float, width: float, angle_deg: float) -> list[float]:
    """A length x width rectangle's [mu20, mu11, mu02] / area at angle_deg."""
    t = math.radians(angle_deg)
    big, small = length * length / 12.0, width * width / 12.0
    c, s = math.cos(t), math.sin(t)
    return [big * c * c + small * s * s, (big - small) * s * c, big * s * s + small * c * c]


def test_angles_are_within_minus_90_and_90() -> None:
    truths = [-90.0, -89.9, -45.0, 0.0, 45.0, 89.9, 90.0, 135.0, 180.0, 270.0]
    moments = [rectangle_moments(40.0, 10.0, t) for t in truths]
    axes = part_angle.part_axes(moments, [400.0] * len(truths))
    assert ((axes.angles_deg >= -90.0) & (axes.angles_deg < 90.0)).all()
    assert all(turn_deg(a, t) < 1e-9 for a, t in zip(axes.angles_deg, truths, strict=True))
    # Either side of the wrap, and on it: +90 is given as -90.
    np.testing.assert_allclose(axes.angles_deg[:8], [-90, -89.9, -45, 0, 45, 89.9, -90, -45])
    np.testing.assert_allclose(part_angle.wrap_deg([90.0, -90.0, 179.0, -91.0]), [-90, -90, -1, 89])
    # The image directions of the axes (no Jacobian: the image's own).
    np.testing.assert_allclose(np.abs(axes.axes_px[4]), [math.sqrt(0.5)] * 2, atol=1e-12)


def test_the_jacobian_of_an_affine_mapping_is_its_matrix() -> None:
    a = np.array([[0.4, -0.1], [0.05, -0.45]])
    centres = np.array([[10.0, 20.0], [640.0, 360.0], [1200.0, 700.0]])
    jac = part_angle.jacobians(lambda p: p @ a.T + [3.0, -7.0], centres)
    np.testing.assert_allclose(jac, np.broadcast_to(a, (3, 2, 2)), atol=1e-12)
    # A square stays without an axis whatever the frame; a shear alone does not make one.
    square = [rectangle_moments(20.0, 20.0, 0.0)] * 3
    assert np.isnan(part_angle.part_axes(square, [400.0] * 3).angles_deg).all()
    # A 2 : 1 rectangle turned through the mapping: its axis is the image of its moments.
    moments = [rectangle_moments(30.0, 15.0, 20.0)] * 3
    axes = part_angle.part_axes(moments, [450.0] * 3, jac)
    c = np.array([[moments[0][0], moments[0][1]], [moments[0][1], moments[0][2]]])
    _, v = np.linalg.eigh(a @ c @ a.T)
    want = math.degrees(math.atan2(v[1, 1], v[0, 1]))
    assert turn_deg(axes.angles_deg[0], want) < 1e-9


def test_a_small_part_needs_more_elongation_than_a_large_one() -> None:
    """The noise rule: the same 1.3 : 1 shape has an axis at 40 px long, none at 6 px."""
    big = rectangle_moments(40.0, 40.0 / 1.3, 10.0)
    small = rectangle_moments(6.0, 6.0 / 1.3, 10.0)
    axes = part_angle.part_axes([big, small], [40.0 * 40.0 / 1.3, 6.0 * 6.0 / 1.3])
    assert math.isfinite(axes.angles_deg[0]) and math.isnan(axes.angles_deg[1])
    assert axes.anisotropy[0] == pytest.approx(axes.anisotropy[1])
    assert axes.sigma_deg[1] > part_angle.MAX_ANGLE_SIGMA_DEG > axes.sigma_deg[0]


def test_bad_input_is_refused_by_name() -> None:
    with pytest.raises(ArgumentError, match="moments_px"):
        part_angle.part_axes(np.zeros((3, 2)), np.ones(3))
    with pytest.raises(ArgumentError, match="areas_px"):
        part_angle.part_axes(np.zeros((3, 3)), np.ones(2))
    with pytest.raises(ArgumentError, match="jacobian"):
        part_angle.part_axes(np.zeros((3, 3)), np.ones(3), np.zeros((2, 2, 2)))
    with pytest.raises(ArgumentError, match="centroids_px"):
        part_angle.jacobians(lambda p: p, np.zeros((3, 3)))
    with pytest.raises(ArgumentError, match="step_px"):
        part_angle.jacobians(lambda p: p, np.zeros((3, 2)), step_px=0.0)
    with pytest.raises(ArgumentError, match="one 2-D position per pixel"):
        part_angle.jacobians(lambda p: p[:, 0], np.zeros((3, 2)))

    # A mapping that has no image for a point: no angle, not a wrong one.
    def nowhere(p: F64) -> F64:
        return np.full_like(p, np.nan)

    jac = part_angle.jacobians(nowhere, [[5.0, 5.0]])
    angles = part_angle.part_angles_deg([rectangle_moments(40, 10, 5)], [400.0], jac)
    assert np.isnan(angles).all()
    none = part_angle.jacobians(nowhere, np.zeros((0, 2)))
    assert part_angle.part_angles_deg(np.zeros((0, 3)), [], none).shape == (0,)


# ------------------------------------------------------------------------------------------
# Through a calibration: locate_objects, the production loop, the picture


@pytest.fixture(scope="module")
def calibrated() -> tuple[Calibration, synth.RenderedScene, list[synth.SceneObject]]:
    """A calibration from the board at a 20 degree tilt, and parts (elongated and round) in
    the same view with the board taken away."""
    rng = np.random.default_rng(5)
    pose = synth.PlanePose(
        distance_mm=500.0, tilt_deg=20.0, tilt_axis_deg=60.0, roll_deg=2.0, look_at_mm=CENTRE
    )
    cal = Calibration.from_image(photograph(pose, [], 1, board=True).image, synth.PAPER_BOARD)
    things = [
        *elongated(rng)[:8],
        synth.SceneObject("nut", (CENTRE[0] - 60.0, CENTRE[1] + 80.0), 10.0, 8.0),
        synth.SceneObject("disc", (CENTRE[0] + 60.0, CENTRE[1] + 80.0), 0.0, 14.0),
    ]
    view = photograph(pose, things, 2)
    return cal, view, things


def test_located_parts_carry_their_angle_on_the_board(
    calibrated: tuple[Calibration, synth.RenderedScene, list[synth.SceneObject]],
) -> None:
    cal, view, things = calibrated
    located = locate_objects(view.image, cal)
    assert len(located) == len(things)
    for o, j in zip(
        located, matched(view, np.array([o.centroid_px for o in located])), strict=True
    ):
        placed = things[j]
        if placed.kind in ("nut", "disc"):
            assert o.angle_deg is None and o.axis_px is None
            continue
        assert o.angle_deg is not None and o.axis_px is not None
        assert turn_deg(o.angle_deg, placed.angle_deg) < 0.5, (o.angle_deg, placed)
        assert math.hypot(*o.axis_px) == pytest.approx(1.0)
        # The image direction points along the part: the outline reaches farther along it
        # than across it.
        d = np.array(o.axis_px)
        rel = o.contour_px - np.array(o.centroid_px)
        assert np.abs(rel @ d).max() > 1.5 * np.abs(rel @ [-d[1], d[0]]).max()
    # detect_objects has no plane: its angles are the image's, from +x towards +y (down),
    # where a tilted view makes a disc an ellipse (an axis in the image, none on the plane).
    for d_o in detect_objects(view.image):
        assert (d_o.angle_deg is None) == (d_o.axis_px is None)
        if d_o.axis_px is not None:
            a = math.degrees(math.atan2(d_o.axis_px[1], d_o.axis_px[0]))
            assert d_o.angle_deg is not None and turn_deg(a, d_o.angle_deg) < 1e-6


def test_the_production_loop_gives_each_part_its_angle(
    calibrated: tuple[Calibration, synth.RenderedScene, list[synth.SceneObject]], tmp_path: Path
) -> None:
    cal, view, _ = calibrated
    cv2.imwrite(str(tmp_path / "frame.png"), view.image)
    located = locate_objects(view.image, cal)
    with Tracker(cal, tmp_path) as t:
        results = list(t)
    assert len(results) == 1
    r = results[0]
    want = [math.nan if o.angle_deg is None else o.angle_deg for o in located]
    np.testing.assert_allclose(r.angles_deg, want, atol=1e-6)
    by_id = {o.id: o.angle_deg for o in r.objects}
    assert sum(a is None for a in by_id.values()) == 2
    assert '"angle_deg":null' in r.to_json()


def test_the_picture_shows_each_axis(
    calibrated: tuple[Calibration, synth.RenderedScene, list[synth.SceneObject]],
) -> None:
    cal, view, _ = calibrated
    located = locate_objects(view.image, cal)
    picture = draw_objects(view.image, located)
    colour = np.all(np.abs(picture.astype(int) - AXIS_BGR) < 60, axis=2)
    for o in located:
        c = np.array(o.centroid_px)
        rel = o.contour_px - c
        if o.axis_px is None:
            continue
        # Beyond the part's end along its axis, the line is drawn.
        reach = np.abs(rel @ np.array(o.axis_px)).max()
        tip = np.rint(c + 1.08 * reach * np.array(o.axis_px)).astype(int)
        patch = colour[tip[1] - 1 : tip[1] + 2, tip[0] - 1 : tip[0] + 2]
        assert patch.any(), o.id
    # Nothing of the axis colour without the axes.
    plain = draw_objects(view.image, [dataclasses.replace(o, axis_px=None) for o in located])
    assert not np.all(np.abs(plain.astype(int) - AXIS_BGR) < 60, axis=2).any()


def test_the_loop_in_a_mirrored_robot_frame_gives_the_mirrored_angle(
    calibrated: tuple[Calibration, synth.RenderedScene, list[synth.SceneObject]], tmp_path: Path
) -> None:
    """A robot's base frame that is the board's mirror image turned by 30 degrees: a board
    axis at phi is the robot's axis at 30 - phi."""
    cal, view, _ = calibrated
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    mirror = np.array([[c, s], [s, -c]])  # a reflection: det -1
    board = np.array([[0, 0], [260, 0], [260, 180], [0, 180], [130, 90], [60, 140]], float)
    robot = board @ mirror.T + [400.0, -120.0]
    registered = cal.register(robot, board_mm=board)
    cv2.imwrite(str(tmp_path / "frame.png"), view.image)
    with Tracker(registered, tmp_path, frame="robot") as t:
        (result,) = list(t)
    assert result.coords == "robot"
    on_board = [
        math.nan if o.angle_deg is None else o.angle_deg for o in locate_objects(view.image, cal)
    ]
    want = part_angle.wrap_deg(30.0 - np.array(on_board))
    np.testing.assert_allclose(result.angles_deg, want, atol=1e-6)
    assert np.isnan(result.angles_deg).sum() == 2
