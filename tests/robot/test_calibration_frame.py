"""A Calibration carries its registration to the robot: attached from dots, board mm or
N-point image pairs, saved in the file (version 3) and checked on load, older files still
loading without one; image_to_world(frame="robot") maps through it with the registration's
own error added to the 1-sigma; an N-point registration on a rendered scene recovers a known
board-to-robot transform."""

from __future__ import annotations

import json
import math
import pickle
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

import planarcal as pc
from planarcal import synth
from planarcal.calib.calibration import FILE_VERSION, Calibration
from planarcal.live.objects import locate_objects
from planarcal.robot.prediction_error import TOUCH_NOISE_FLOOR_MM

F64 = NDArray[np.float64]

# The calibration of synth.paper_scene(0), saved by the planarcal before registrations
# (calibration file version 2): the old file that must still load.
OLD_FILE = Path(__file__).parent / "data" / "calibration_v2.json"

# A robot's repeatability (mm, 1-sigma per axis).
TOUCH_NOISE_MM = 0.05

# Touched dots spread over the paper's 14 x 10 board: the corners and two inside.
DOTS = [0, 13, 126, 139, 46, 93]


def _truth(angle_deg: float, offset: tuple[float, float], mirrored: bool) -> F64:
    """A board-to-robot matrix: a rotation after an optional mirror of y, then an offset."""
    a = math.radians(angle_deg)
    m = np.eye(3)
    m[:2, :2] = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]) @ np.diag(
        [1.0, -1.0 if mirrored else 1.0]
    )
    m[:2, 2] = offset
    return m


def _map(m: F64, points: F64) -> F64:
    out: F64 = np.asarray(points, dtype=np.float64) @ m[:2, :2].T + m[:2, 2]
    return out


TRUTH = _truth(-127.0, (412.0, -233.0), True)


@pytest.fixture(scope="module")
def cal() -> Calibration:
    return Calibration.load(OLD_FILE)


@pytest.fixture(scope="module")
def registered(cal: Calibration) -> Calibration:
    assert cal.board is not None
    rng = np.random.default_rng(5)
    robot = _map(TRUTH, cal.board.world_points()[DOTS]) + rng.normal(0, TOUCH_NOISE_MM, (6, 2))
    return cal.register(robot, dots=DOTS)


# -- the old file, the new file -----------------------------------------------------------


def test_a_file_of_the_previous_version_loads_without_a_registration(cal: Calibration) -> None:
    assert json.loads(OLD_FILE.read_text())["version"] == 2
    assert cal.robot_frame is None
    assert cal.default_frame == "board"
    assert cal.to_dict()["version"] == FILE_VERSION == 7
    assert cal.to_dict()["robot_frame"] is None
    px = cal.image_points[:5]
    np.testing.assert_allclose(cal.image_to_world(px), cal.world_points[:5], atol=0.05)


def test_robot_frame_without_a_registration_is_a_clear_argument_error(cal: Calibration) -> None:
    with pytest.raises(pc.ArgumentError, match=r"needs a registration.*planarcal register"):
        cal.image_to_world([640.0, 360.0], frame="robot")
    with pytest.raises(pc.ArgumentError, match="needs a registration"):
        cal._frame_mapper(0.0, "robot")
    with pytest.raises(pc.ArgumentError, match="frame must be 'board' or 'robot'"):
        cal.image_to_world([640.0, 360.0], frame="tool")  # type: ignore[arg-type]


def test_register_by_dots_uses_the_dots_centres(cal: Calibration, registered: Calibration) -> None:
    frame = registered.robot_frame
    assert frame is not None and cal.board is not None
    np.testing.assert_array_equal(frame.plane_mm, cal.board.world_points()[DOTS])
    assert frame.plane_std_mm is None
    assert frame.reflected and frame.outliers == ()
    assert frame.rotation_deg == pytest.approx(-127.0, abs=0.05)
    assert cal.robot_frame is None  # the calibration registered is a new one
    assert registered.default_frame == "robot"


def test_the_registration_survives_the_file_and_pickling(
    registered: Calibration, tmp_path: Path
) -> None:
    frame = registered.robot_frame
    assert frame is not None
    path = registered.save(tmp_path / "calib.json")
    data = json.loads(path.read_text())
    assert data["version"] == FILE_VERSION
    assert data["robot_frame"]["model"] == "rigid"
    assert len(data["robot_frame"]["residuals_mm"]) == len(DOTS)
    for again in (Calibration.load(path), pickle.loads(pickle.dumps(registered))):
        assert again.robot_frame is not None
        np.testing.assert_array_equal(again.robot_frame.plane_to_robot, frame.plane_to_robot)
        px = registered.image_points[::7]
        np.testing.assert_array_equal(
            again.image_to_world(px, frame="robot"), registered.image_to_world(px, frame="robot")
        )


def test_a_registration_that_does_not_match_its_pairs_is_refused_on_load(
    registered: Calibration, tmp_path: Path
) -> None:
    data = registered.to_dict()
    data["robot_frame"]["robot_mm"][2][0] += 5.0  # an edited touch: the stored fit is not its
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(data))
    with pytest.raises(pc.CalibrationFileError, match=r"registration to the robot.*not those"):
        Calibration.load(path)
    data["robot_frame"] = {"format": "planarcal.robot_frame", "version": 1}
    path.write_text(json.dumps(data))
    with pytest.raises(pc.CalibrationFileError, match="missing the field"):
        Calibration.load(path)


# -- mapping to the robot -----------------------------------------------------------------


def test_robot_frame_is_the_registration_of_the_board_position(registered: Calibration) -> None:
    frame = registered.robot_frame
    assert frame is not None
    px = registered.image_points[::5] + 3.0
    board = registered.image_to_world(px)
    np.testing.assert_allclose(registered.image_to_world(px, frame="robot"), frame.to_robot(board))
    np.testing.assert_array_equal(registered.image_to_world(px, frame="board"), board)
    one = registered.image_to_world(px[0], frame="robot")
    assert one.shape == (2,)
    np.testing.assert_allclose(one, frame.to_robot(board[0]))


def test_the_robot_std_adds_the_registrations_own_error(registered: Calibration) -> None:
    frame = registered.robot_frame
    assert frame is not None
    px = registered.image_points[::5]
    board, board_std = registered.image_to_world(px, return_std=True)
    robot, robot_std = registered.image_to_world(px, return_std=True, frame="robot")
    own = frame.std_mm(board)
    # A rigid map keeps distances: the board's 1-sigma passes unchanged, the map's adds.
    np.testing.assert_allclose(robot_std, np.sqrt(board_std**2 + own**2))
    assert np.all(robot_std > board_std)
    assert np.all(own > 0)
    # The production loop's mapper gives the same (the 1-sigma of the rows asked for).
    mm, std = registered._frame_mapper(0.0, "robot")(px, len(px))
    np.testing.assert_allclose(mm, robot)
    np.testing.assert_allclose(std, robot_std)
    mm, std = registered._frame_mapper(0.0, "robot")(px, 3)
    np.testing.assert_allclose(mm, robot)
    np.testing.assert_allclose(std, robot_std[:3])
    # Worse far from the touched points than at their centroid.
    centre = frame.plane_mm.mean(axis=0)
    assert frame.std_mm(centre + np.array([600.0, 0.0])) > 3 * frame.std_mm(centre)


def test_three_perfect_touches_do_not_claim_an_exact_map(cal: Calibration) -> None:
    assert cal.board is not None
    dots = [0, 13, 139]
    exact = cal.register(_map(TRUTH, cal.board.world_points()[dots]), dots=dots)
    frame = exact.robot_frame
    assert frame is not None
    assert frame.max_mm < 1e-9
    assert frame.noise_mm == TOUCH_NOISE_FLOOR_MM
    assert np.all(frame.std_mm(cal.world_points) >= TOUCH_NOISE_FLOOR_MM / 2)


def test_the_predicted_registration_error_matches_the_actual_one(cal: Calibration) -> None:
    # Over many sets of noisy touches, the map's actual error at other board points against
    # the 1-sigma it predicts there.
    assert cal.board is not None
    rng = np.random.default_rng(2)
    board = cal.board.world_points()
    actual, predicted = [], []
    for _ in range(200):
        robot = _map(TRUTH, board[DOTS]) + rng.normal(0, TOUCH_NOISE_MM, (len(DOTS), 2))
        frame = pc.RobotFrame.fit(board[DOTS], robot)
        actual.append(np.sum((frame.to_robot(board) - _map(TRUTH, board)) ** 2, axis=1))
        predicted.append(frame.std_mm(board) ** 2)
    ratio = math.sqrt(float(np.mean(actual)) / float(np.mean(predicted)))
    assert 0.8 < ratio < 1.25, ratio


def test_a_similarity_scales_the_board_std(cal: Calibration) -> None:
    assert cal.board is not None
    truth = TRUTH.copy()
    truth[:2, :2] *= 1.02
    reg = cal.register(_map(truth, cal.board.world_points()[DOTS]), dots=DOTS, model="similarity")
    frame = reg.robot_frame
    assert frame is not None and frame.distance_gain == pytest.approx(1.02)
    px = cal.image_points[:3]
    board, board_std = cal.image_to_world(px, return_std=True)
    _, std = reg.image_to_world(px, return_std=True, frame="robot")
    np.testing.assert_allclose(std, np.hypot(1.02 * board_std, frame.std_mm(board)))


# -- the board side of the pairs ----------------------------------------------------------


def test_board_mm_pairs_equal_dot_pairs(cal: Calibration, registered: Calibration) -> None:
    frame = registered.robot_frame
    assert frame is not None and cal.board is not None
    again = cal.register(frame.robot_mm, board_mm=cal.board.world_points()[DOTS]).robot_frame
    assert again is not None
    np.testing.assert_array_equal(again.plane_to_robot, frame.plane_to_robot)


@pytest.mark.parametrize(
    ("dots", "match"),
    [
        ([0, 13, 140], r"dot 2: index 140 is off the board: a 14 x 10 board has dots 0 to 139"),
        ([0, -1, 13], r"dot 1: index -1 is off the board"),
        ([0, 1.5, 13], r"dot 1: 1.5 is not a dot index"),
        ([0, True, 13], r"dot 1: True is not a dot index"),
        ([[0, 1], [2, 3]], r"dots must be a list of dot indices \(N,\)"),
    ],
)
def test_a_bad_dot_index_is_named(cal: Calibration, dots: object, match: str) -> None:
    with pytest.raises(pc.ArgumentError, match=match):
        cal.register(np.zeros((3, 2)), dots=dots)  # type: ignore[arg-type]


def test_the_board_side_is_given_exactly_once(cal: Calibration) -> None:
    robot = np.zeros((3, 2))
    with pytest.raises(pc.ArgumentError, match=r"exactly one of.*got none"):
        cal.register(robot)
    with pytest.raises(pc.ArgumentError, match="got dots and board_mm"):
        cal.register(robot, dots=[0, 1, 2], board_mm=np.zeros((3, 2)))


def test_dots_need_a_board(cal: Calibration) -> None:
    bare = Calibration(cal.world_points, cal.image_points)
    with pytest.raises(pc.BoardError, match="records no board"):
        bare.register(np.zeros((3, 2)), dots=[0, 1, 2])


def test_a_rescaled_calibration_drops_the_registration_a_resized_one_keeps_it(
    registered: Calibration,
) -> None:
    # Rescaling changes the board's millimetres the registration was fitted in.
    assert registered.rescaled(20.02).robot_frame is None
    assert registered.image_size is not None
    w, h = registered.image_size
    bigger = registered.for_frame_size(2 * w, 2 * h)
    assert bigger.robot_frame is registered.robot_frame
    # The same point of the scene, in the bigger frame's pixels, lands in the same place.
    np.testing.assert_allclose(
        bigger.image_to_world([2 * 640.0 + 0.5, 2 * 360.0 + 0.5], frame="robot"),
        registered.image_to_world([640.0, 360.0], frame="robot"),
        atol=1e-6,
    )


# -- N-point on a rendered scene ----------------------------------------------------------


@pytest.mark.parametrize(
    ("angle_deg", "offset", "mirrored"),
    [(-127.0, (412.0, -233.0), True), (33.0, (-150.0, 640.0), False)],
)
def test_n_point_pairs_recover_a_known_transform_on_a_rendered_scene(
    cal: Calibration, angle_deg: float, offset: tuple[float, float], mirrored: bool
) -> None:
    # The paper's scene: its board lies at the table's origin, so the parts' true positions
    # are in board mm. The robot put a part at the first six places; the camera saw it there.
    scene = parts_scene()
    truth_board = scene.object_centroids_mm
    found = locate_objects(scene.image, cal)
    assert len(found) == len(truth_board)
    px = np.array([o.centroid_px for o in found])
    board_seen = np.array([o.world_mm for o in found])
    # Each part found is the true part nearest to it.
    order = [int(np.argmin(np.hypot(*(truth_board - b).T))) for b in board_seen]
    truth_board = truth_board[order]
    truth = _truth(angle_deg, offset, mirrored)
    rng = np.random.default_rng(8)
    robot = _map(truth, truth_board) + rng.normal(0, TOUCH_NOISE_MM, truth_board.shape)
    placed = slice(0, 6)
    reg = cal.register(robot[placed], image_px=px[placed])
    frame = reg.robot_frame
    assert frame is not None
    assert frame.reflected is mirrored
    assert frame.rotation_deg == pytest.approx(angle_deg, abs=0.1)
    assert frame.plane_std_mm is not None and np.all(frame.plane_std_mm > 0)
    # The parts not placed: where the calibration and the registration put them in the
    # robot's frame, against the truth, within a few touch noises.
    others = slice(6, None)
    mm, std = reg.image_to_world(px[others], frame="robot", return_std=True)
    error = np.hypot(*(mm - _map(truth, truth_board[others])).T)
    assert error.max() < 4 * TOUCH_NOISE_MM, error
    assert np.all(std > frame.std_mm(board_seen[others]) - 1e-12)


_SCENE: list[synth.RenderedScene] = []


def parts_scene() -> synth.RenderedScene:
    """The paper's parts image (rendered once per test run)."""
    if not _SCENE:
        _SCENE.append(synth.paper_scene(0).objects)
    return _SCENE[0]


# -- located objects and their angles in the robot frame ----------------------------------


def _axis_through(m: F64, angle_deg: float) -> float:
    """The angle in [-90, 90) of a board axis at angle_deg once mapped through m's linear part."""
    a = math.radians(angle_deg)
    d = m[:2, :2] @ np.array([math.cos(a), math.sin(a)])
    return (math.degrees(math.atan2(d[1], d[0])) + 90.0) % 180.0 - 90.0


@pytest.mark.parametrize("model", ["rigid", "similarity"])
def test_parts_located_in_the_robot_frame_are_the_board_ones_mapped(
    cal: Calibration, model: str
) -> None:
    assert cal.board is not None
    truth = TRUTH.copy()
    if model == "similarity":
        truth[:2, :2] *= 1.02
    board = cal.board.world_points()
    frame = pc.RobotFrame.fit(board[DOTS], _map(truth, board[DOTS]), model=model)  # type: ignore[arg-type]
    registered = cal.with_robot_frame(frame)
    image = synth.paper_scene(seed=0).objects.image
    on_board = locate_objects(image, registered, frame="board")
    in_robot = locate_objects(image, registered, frame="robot")
    assert len(on_board) == len(in_robot) >= 5
    with_axis = 0
    for b, r in zip(on_board, in_robot, strict=True):
        assert b.world_mm is not None and r.world_mm is not None
        np.testing.assert_allclose(r.world_mm, frame.to_robot(np.array(b.world_mm)), atol=1e-9)
        # (the 1-sigma is taken at the image centroid's image, a fraction of a mm away)
        assert r.world_std_mm == pytest.approx(
            float(frame.robot_std_mm(np.array([b.world_mm]), np.array([b.world_std_mm]))[0]),
            rel=1e-3,
        )
        assert (b.angle_deg is None) == (r.angle_deg is None)
        if b.angle_deg is not None and r.angle_deg is not None:
            with_axis += 1
            # A rigid or similar map turns every axis alike: the mapped board axis.
            expected = _axis_through(frame.plane_to_robot, b.angle_deg)
            turn = (r.angle_deg - expected + 90.0) % 180.0 - 90.0
            assert abs(turn) < 1e-4
    assert with_axis >= 2
