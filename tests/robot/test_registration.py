"""RobotFrame: the board-to-robot registration recovers known transforms (rigid, similarity,
affine, mirrored or not, with and without a robot's touch noise), names a touch on the wrong
dot, refuses points that cannot fix the transform, maps both ways, survives its dict form,
and warns of a tilted plane."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

import planarcal as pc
from planarcal.robot import MINIMAL_POINTS, MODELS, Model, RobotFrame
from planarcal.robot.outliers import MAX_OUTLIERS, leave_one_out
from planarcal.robot.transform_fit import (
    MIN_SPREAD_MM,
    MIN_WIDTH_RATIO,
    fit,
    spread_mm,
    width_ratio,
)
from synthetic import examples

F64 = NDArray[np.float64]

# A robot's repeatability (mm): the noise of a touch.
TOUCH_NOISE_MM = 0.05


def _grid(cols: int = 5, rows: int = 4, pitch: float = 15.0) -> F64:
    """Dot centres of a board (mm): x along a row, y down a column."""
    xs, ys = np.meshgrid(np.arange(cols) * pitch, np.arange(rows) * pitch)
    out: F64 = np.c_[xs.ravel(), ys.ravel()]
    return out


def _transform(rng: np.random.Generator, model: Model, reflected: bool) -> F64:
    """A random plane-to-robot matrix of the model, mirrored as asked."""
    angle = rng.uniform(-math.pi, math.pi)
    c, s = math.cos(angle), math.sin(angle)
    linear = np.array([[c, -s], [s, c]]) @ np.diag([1.0, -1.0 if reflected else 1.0])
    if model == "similarity":
        linear = rng.uniform(0.8, 1.25) * linear
    elif model == "affine":
        # A shear and unequal scales, keeping the handedness.
        linear = linear @ np.array(
            [[rng.uniform(0.8, 1.25), rng.uniform(-0.2, 0.2)], [0.0, rng.uniform(0.8, 1.25)]]
        )
    m = np.eye(3)
    m[:2, :2] = linear
    m[:2, 2] = rng.uniform(-600, 600, 2)
    return m


def _map(m: F64, points: F64) -> F64:
    out: F64 = points @ m[:2, :2].T + m[:2, 2]
    return out


def _scene(seed: int, model: Model, reflected: bool, noise: float) -> tuple[F64, F64, F64]:
    """Board points (a random layout), their robot points with touch noise, and the truth."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(MINIMAL_POINTS[model] + 4, 20))
    plane = rng.uniform([0, 0], [250, 180], (n, 2)) + rng.uniform(-300, 300, 2)
    truth = _transform(rng, model, reflected)
    robot = _map(truth, plane) + rng.normal(0, noise, (n, 2))
    return plane, robot, truth


cases = given(
    seed=st.integers(0, 2**32 - 1),
    model=st.sampled_from(MODELS),
    reflected=st.booleans(),
)


@settings(max_examples=examples(60))
@cases
def test_exact_pairs_recover_the_transform(seed: int, model: Model, reflected: bool) -> None:
    plane, robot, truth = _scene(seed, model, reflected, 0.0)
    frame = RobotFrame.fit(plane, robot, model=model)
    assert frame.reflected is reflected
    assert frame.model == model
    assert frame.max_mm < 1e-9
    np.testing.assert_allclose(frame.plane_to_robot, truth, atol=1e-9)
    np.testing.assert_allclose(frame.plane_to_robot @ frame.robot_to_plane, np.eye(3), atol=1e-12)
    assert frame.outliers == ()
    if model == "affine":
        assert frame.rotation_deg is None and frame.scale is None
    else:
        assert frame.rotation_deg is not None and frame.scale is not None
        # The stated angle and scale rebuild the matrix: scale R(angle) diag(1, +-1).
        a = math.radians(frame.rotation_deg)
        rebuilt = (
            frame.scale
            * np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
            @ np.diag([1.0, -1.0 if reflected else 1.0])
        )
        np.testing.assert_allclose(rebuilt, truth[:2, :2], atol=1e-9)
        if model == "rigid":
            assert frame.scale == 1.0


@settings(max_examples=examples(60))
@cases
def test_noisy_touches_give_residuals_of_the_noise(
    seed: int, model: Model, reflected: bool
) -> None:
    plane, robot, truth = _scene(seed, model, reflected, TOUCH_NOISE_MM)
    frame = RobotFrame.fit(plane, robot, model=model)
    assert frame.reflected is reflected
    assert 0.2 * TOUCH_NOISE_MM < frame.rms_mm < 2.5 * TOUCH_NOISE_MM
    # The fit is better than one touch where the touches were.
    assert np.abs(frame.to_robot(plane) - _map(truth, plane)).max() < 4 * TOUCH_NOISE_MM
    # A point left out is predicted worse than it is fitted.
    assert frame.leave_one_out_rms_mm > frame.rms_mm
    if model == "affine":
        # Linear least squares: each point's leave-one-out error is its residual / (1 - h).
        assert np.all(frame.leave_one_out_mm >= frame.residuals_mm - 1e-12)
    assert frame.outliers == ()


@settings(max_examples=examples(40))
@given(
    seed=st.integers(0, 2**32 - 1),
    model=st.sampled_from(MODELS),
    reflected=st.booleans(),
    data=st.data(),
)
def test_a_touch_on_the_wrong_dot_is_named(
    seed: int, model: Model, reflected: bool, data: st.DataObject
) -> None:
    rng = np.random.default_rng(seed)
    plane = _grid()
    truth = _transform(rng, model, reflected)
    robot = _map(truth, plane) + rng.normal(0, TOUCH_NOISE_MM, plane.shape)
    wrong = data.draw(st.integers(0, len(plane) - 1))
    neighbour = wrong + 1 if (wrong + 1) % 5 else wrong - 1  # the next dot in its row
    robot[wrong] = _map(truth, plane[neighbour : neighbour + 1])[0]

    kept = RobotFrame.fit(plane, robot, model=model)
    assert kept.outliers == (wrong,)
    assert "outlier" in kept.summary() and f"Outlier(s) touch {wrong}:" in kept.summary()
    assert kept.used.all()

    dropped = RobotFrame.fit(plane, robot, model=model, drop_outliers=True)
    assert dropped.outliers == (wrong,)
    assert not dropped.used[wrong] and dropped.used.sum() == len(plane) - 1
    assert dropped.rms_mm < 2.5 * TOUCH_NOISE_MM
    # The dropped point's error is its distance from the fit of the others: a dot's pitch.
    assert dropped.residuals_mm[wrong] == pytest.approx(15.0 * (kept.scale or 1.0), rel=0.3)


@pytest.mark.parametrize("model", ["rigid", "similarity"])
def test_a_wrong_touch_among_few_points_is_named(model: Model) -> None:
    # Five touches, one on the next dot: every fit that includes it is pulled, so the bar is
    # set by the others' errors without it.
    rng = np.random.default_rng(11)
    plane = _grid()[[0, 4, 10, 15, 19]]
    truth = _transform(rng, model, True)
    robot = _map(truth, plane) + rng.normal(0, TOUCH_NOISE_MM, plane.shape)
    robot[2] = _map(truth, plane[2:3] + np.array([15.0, 0.0]))[0]
    frame = RobotFrame.fit(plane, robot, model=model)
    assert frame.outliers == (2,)
    assert frame.outlier_threshold_mm == 1.0
    clean = RobotFrame.fit(
        plane, _map(truth, plane) + rng.normal(0, TOUCH_NOISE_MM, (5, 2)), model=model
    )
    assert clean.outliers == ()


def test_two_swapped_touches_are_both_named() -> None:
    rng = np.random.default_rng(7)
    plane = _grid()
    truth = _transform(rng, "rigid", True)
    robot = _map(truth, plane) + rng.normal(0, TOUCH_NOISE_MM, plane.shape)
    robot[[3, 12]] = robot[[12, 3]]
    frame = RobotFrame.fit(plane, robot, drop_outliers=True)
    assert frame.outliers == (3, 12)
    assert frame.rms_mm < 2.5 * TOUCH_NOISE_MM


def test_an_explicit_outlier_threshold_is_used() -> None:
    rng = np.random.default_rng(3)
    plane = _grid()
    robot = _map(_transform(rng, "rigid", True), plane)
    robot[4] += [0.4, 0.0]  # a 0.4 mm slip: below the default floor of 1 mm
    assert RobotFrame.fit(plane, robot).outliers == ()
    frame = RobotFrame.fit(plane, robot, outlier_mm=0.2)
    assert frame.outliers == (4,)
    assert frame.outlier_threshold_mm == 0.2


# -- refusals --------------------------------------------------------------------------------


@pytest.mark.parametrize("model", MODELS)
def test_too_few_points_are_refused_saying_how_many(model: Model) -> None:
    n = MINIMAL_POINTS[model]
    plane = _grid()[[0, 6, 13, 19]][:n]
    with pytest.raises(pc.RegistrationError, match=rf"at least {n + 1} point pairs.*got {n}"):
        RobotFrame.fit(plane, plane + 100.0, model=model)
    RobotFrame.fit(
        _grid()[[0, 6, 13, 19]][: n + 1], _grid()[[0, 6, 13, 19]][: n + 1] + 100.0, model=model
    )


@pytest.mark.parametrize("model", MODELS)
def test_nearly_coincident_points_are_refused(model: Model) -> None:
    rng = np.random.default_rng(0)
    plane = np.array([50.0, 40.0]) + rng.uniform(-0.5, 0.5, (6, 2))
    with pytest.raises(pc.RegistrationError, match="too clustered"):
        RobotFrame.fit(plane, plane + 200.0, model=model)
    # Robot points that do not move are as bad.
    with pytest.raises(pc.RegistrationError, match="robot points are too clustered"):
        RobotFrame.fit(_grid(), np.full((20, 2), 300.0) + rng.normal(0, 0.01, (20, 2)), model=model)


def test_collinear_points_are_refused_unless_the_hand_is_given() -> None:
    plane = np.c_[np.arange(6) * 20.0, np.arange(6) * 10.0 + 5.0]
    robot = plane @ np.array([[0.0, -1.0], [-1.0, 0.0]]) + [400.0, 100.0]
    with pytest.raises(pc.RegistrationError, match="collinear"):
        RobotFrame.fit(plane, robot, model="affine")
    # A line fixes a rotation and a scale, not the hand: refused unless it is given.
    for model in ("rigid", "similarity"):
        with pytest.raises(pc.RegistrationError, match=r"near one line.*touch 0 and touch 5"):
            RobotFrame.fit(plane, robot, model=model)
        frame = RobotFrame.fit(plane, robot, model=model, handedness="right")
        assert frame.max_mm < 1e-9 and frame.reflected and frame.handedness == "right"
        # A point off the line lands where the truth puts it, not at its mirror image.
        np.testing.assert_allclose(frame.to_robot([[0.0, 100.0]]), [[300.0, 100.0]], atol=1e-9)


def test_bad_arguments_are_argument_errors() -> None:
    plane = _grid()
    robot = plane + 100.0
    bad = robot.copy()
    bad[7, 1] = np.nan
    with pytest.raises(pc.ArgumentError, match="point 7") as info:
        RobotFrame.fit(plane, bad)
    assert info.value.index == 7
    bad_plane = plane.copy()
    bad_plane[2, 0] = np.inf
    with pytest.raises(pc.ArgumentError, match="point 2"):
        RobotFrame.fit(bad_plane, robot)
    with pytest.raises(pc.ArgumentError, match="pair up"):
        RobotFrame.fit(plane, robot[:-1])
    with pytest.raises(pc.ArgumentError, match="z of point 3"):
        RobotFrame.fit(plane, robot, robot_z=np.r_[np.zeros(3), np.nan, np.zeros(16)])
    with pytest.raises(pc.ArgumentError, match="z given twice"):
        RobotFrame.fit(plane, np.c_[robot, np.zeros(20)], robot_z=np.zeros(20))
    with pytest.raises(pc.ArgumentError, match="model"):
        RobotFrame.fit(plane, robot, model="projective")  # type: ignore[arg-type]
    with pytest.raises(pc.ArgumentError, match="outlier_mm"):
        RobotFrame.fit(plane, robot, outlier_mm=-1.0)
    with pytest.raises(pc.ArgumentError, match=r"\(N, 2\) or \(N, 3\)"):
        RobotFrame.fit(plane, np.ones((20, 4)))
    with pytest.raises(ValueError):
        RobotFrame.fit(plane, robot[:-1])


# -- mapping both ways -----------------------------------------------------------------------


@settings(max_examples=examples(40))
@cases
def test_to_robot_and_to_plane_are_inverse(seed: int, model: Model, reflected: bool) -> None:
    plane, robot, _ = _scene(seed, model, reflected, TOUCH_NOISE_MM)
    frame = RobotFrame.fit(plane, robot, model=model)
    queries = np.random.default_rng(seed).uniform(-500, 500, (7, 2))
    there = frame.to_robot(queries)
    assert there.shape == (7, 2)
    np.testing.assert_allclose(frame.to_plane(there), queries, atol=1e-9)
    one = frame.to_robot(queries[3])
    assert one.shape == (2,)
    np.testing.assert_allclose(one, there[3], atol=1e-12)
    np.testing.assert_allclose(frame.to_robot(plane), _map(frame.plane_to_robot, plane))
    with pytest.raises(pc.ArgumentError):
        frame.to_robot([[1.0, np.nan]])


# -- the dict form ---------------------------------------------------------------------------


def _fields(frame: RobotFrame) -> dict[str, Any]:
    values = {f.name: getattr(frame, f.name) for f in dataclasses.fields(frame)}
    return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in values.items()}


@settings(max_examples=examples(20))
@cases
def test_the_dict_form_round_trips(seed: int, model: Model, reflected: bool) -> None:
    plane, robot, _ = _scene(seed, model, reflected, TOUCH_NOISE_MM)
    robot[0] += [5.0, 0.0]
    z = np.random.default_rng(seed).normal(20.0, 0.02, len(plane))
    frame = RobotFrame.fit(plane, np.c_[robot, z], model=model, drop_outliers=True)
    text = json.dumps(frame.to_dict(), allow_nan=False)
    back = RobotFrame.from_dict(json.loads(text))
    assert _fields(back) == _fields(frame)


def test_a_bad_dict_is_a_calibration_file_error() -> None:
    plane = _grid()
    good = RobotFrame.fit(plane, plane @ np.diag([1.0, -1.0]) + 50.0).to_dict()
    edited = json.loads(json.dumps(good))
    edited["plane_to_robot"][0][2] += 0.5
    for data, message in (
        ([1, 2], "not a JSON object"),
        ({**good, "version": 99}, "version"),
        ({k: v for k, v in good.items() if k != "robot_mm"}, "missing the field 'robot_mm'"),
        (
            {**good, "plane_mm": good["plane_mm"][:2], "robot_mm": good["robot_mm"][:2]},
            "at least 3",
        ),
        ({**good, "model": "projective"}, "model"),
        ({**good, "robot_mm": [[None, 1.0]] * 20}, "point 0"),
        (edited, "not those of its point pairs"),
        ({**good, "reflected": False}, "not those of its point pairs"),
    ):
        with pytest.raises(pc.CalibrationFileError, match=message):
            RobotFrame.from_dict(data)


# -- the plane's height ----------------------------------------------------------------------


def test_a_tilted_plane_is_a_warning_with_its_size() -> None:
    plane = _grid(6, 5, 40.0)  # 200 x 160 mm
    robot = plane @ np.diag([1.0, -1.0]) + [300.0, 200.0]
    tilt = math.radians(0.5)
    z = 12.0 + math.tan(tilt) * (robot[:, 0] - robot[:, 0].mean())
    frame = RobotFrame.fit(plane, np.c_[robot, z])
    assert frame.plane is not None
    assert frame.plane.tilt_deg == pytest.approx(0.5, abs=1e-9)
    assert frame.plane.tilt_mm == pytest.approx(200.0 * math.tan(tilt), abs=1e-9)
    assert frame.plane.height_mm == pytest.approx(12.0, abs=1e-9)
    assert len(frame.warnings) == 1 and "1.75 mm" in frame.warnings[0]
    assert "1.75 mm" in frame.summary()
    # The same heights as robot_z; a level plane gives none.
    again = RobotFrame.fit(plane, robot, robot_z=z)
    assert again.plane == frame.plane
    level = RobotFrame.fit(
        plane, robot, robot_z=12.0 + np.random.default_rng(0).normal(0, 0.01, 30)
    )
    assert level.plane is not None and level.plane.tilt_mm < 0.5 and level.warnings == ()
    assert RobotFrame.fit(plane, robot).plane is None


def test_heights_on_a_line_do_not_claim_a_tilt() -> None:
    plane = np.c_[np.arange(6) * 20.0, np.zeros(6)]
    frame = RobotFrame.fit(plane, plane + 100.0, robot_z=np.arange(6.0), handedness="left")
    assert frame.plane is None
    assert "line" in frame.warnings[0]


def test_the_summary_reads_the_quality() -> None:
    rng = np.random.default_rng(1)
    plane = _grid()
    robot = _map(_transform(rng, "rigid", True), plane) + rng.normal(0, 0.02, plane.shape)
    text = RobotFrame.fit(plane, robot).summary()
    assert "Excellent" in text and "mirrored" in text
    assert len(text.splitlines()) >= len(plane) + 4
    poor = RobotFrame.fit(plane, robot + rng.normal(0, 2.0, plane.shape)).summary()
    assert "Poor" in poor


# -- the hand (issue 21) ---------------------------------------------------------------------

# The paper's 14 x 10 board (20 mm pitch): dots 0, 4, 9 and 13 lie on its first row.
BOARD = pc.CircleGridBoard().world_points()
ROW_DOTS = [0, 4, 9, 13]


def _mirrored_robot(rng: np.random.Generator) -> F64:
    return _transform(rng, "rigid", True)


@pytest.mark.parametrize("model", ["rigid", "similarity"])
@pytest.mark.parametrize("dots", [ROW_DOTS, [0, 13, 0, 13]])
def test_touches_on_one_line_are_refused_naming_the_dots(model: Model, dots: list[int]) -> None:
    # Both hands fit a line equally well: the old fit took the proper one ("Excellent",
    # residuals of 0.05 mm) and put parts off the row up to 360 mm from their places.
    rng = np.random.default_rng(21)
    truth = _mirrored_robot(rng)
    robot = _map(truth, BOARD[dots]) + rng.normal(0, TOUCH_NOISE_MM, (len(dots), 2))
    with pytest.raises(
        pc.RegistrationError, match=r"one line.*off the line through dot 0 and dot 13"
    ):
        RobotFrame.fit(BOARD[dots], robot, model=model, dots=dots)
    with pytest.raises(pc.RegistrationError, match=r"off the line through touch \d and touch \d"):
        RobotFrame.fit(BOARD[dots], robot, model=model)
    # The hand given: the map is right across the whole board.
    frame = RobotFrame.fit(BOARD[dots], robot, model=model, dots=dots, handedness="right")
    assert frame.reflected and frame.handedness == "right"
    assert np.abs(frame.to_robot(BOARD) - _map(truth, BOARD)).max() < 0.5
    assert "as given" in frame.summary()
    # ... and it is kept in the dict form, which refits the same.
    back = RobotFrame.from_dict(json.loads(json.dumps(frame.to_dict())))
    assert back.handedness == "right" and back.dots == tuple(dots)
    np.testing.assert_array_equal(back.plane_to_robot, frame.plane_to_robot)


def test_the_hand_given_is_checked() -> None:
    with pytest.raises(pc.ArgumentError, match="handedness must be 'right', 'left' or None"):
        RobotFrame.fit(_grid(), _grid(), handedness="mirrored")  # type: ignore[arg-type]
    rng = np.random.default_rng(4)
    plane = _grid()
    truth = _mirrored_robot(rng)
    robot = _map(truth, plane) + rng.normal(0, TOUCH_NOISE_MM, plane.shape)
    # Touches that show the hand, with the other one given: fitted as asked, and a warning.
    wrong = RobotFrame.fit(plane, robot, handedness="left")
    assert not wrong.reflected and "the touches show the other hand" in wrong.summary()
    assert RobotFrame.fit(plane, robot, handedness="right").warnings == ()
    # An affine map's hand is its points': a different one given is refused.
    with pytest.raises(pc.RegistrationError, match="affine map that mirrors"):
        RobotFrame.fit(plane, robot, model="affine", handedness="left")


def test_near_collinear_touches_never_give_the_wrong_hand() -> None:
    # Touches within 0.05 mm of a line with a robot's touch noise: the old fit picked the
    # wrong hand in 15 of 200 such sets. Now each is refused (or, were its width to show
    # the hand, right).
    rng = np.random.default_rng(2121)
    wrong = refused = 0
    for _ in range(200):
        n = int(rng.integers(3, 9))
        angle = rng.uniform(-math.pi, math.pi)
        direction = np.array([math.cos(angle), math.sin(angle)])
        normal = np.array([-direction[1], direction[0]])
        plane = (
            rng.uniform(0.0, 250.0, (n, 1)) * direction
            + rng.uniform(-0.05, 0.05, (n, 1)) * normal
            + rng.uniform(0.0, 100.0, 2)
        )
        truth = _mirrored_robot(rng)
        robot = _map(truth, plane) + rng.normal(0, TOUCH_NOISE_MM, (n, 2))
        try:
            frame = RobotFrame.fit(plane, robot)
        except pc.RegistrationError as e:
            assert "one line" in str(e)
            refused += 1
            continue
        wrong += not frame.reflected
    assert wrong == 0
    assert refused == 200


def test_a_wrong_touch_off_the_line_does_not_fix_the_hand() -> None:
    # Dots on one row and one touch off it that is an outlier: the hand would rest on it.
    rng = np.random.default_rng(8)
    dots = [0, 3, 6, 9, 13, 2, 11, 60]
    truth = _mirrored_robot(rng)
    robot = _map(truth, BOARD[dots]) + rng.normal(0, TOUCH_NOISE_MM, (len(dots), 2))
    robot[-1] = _map(truth, BOARD[61:62])[0]  # dot 61 touched for dot 60
    with pytest.raises(pc.RegistrationError, match="through dot 0 and dot 13"):
        RobotFrame.fit(BOARD[dots], robot, dots=dots)


def test_spread_touches_with_a_wrong_pair_are_not_called_collinear() -> None:
    # Three board corners, 118 mm from their main line, one pair 30 mm off: the fit's noise
    # hides the hand, but the layout is fine, so the refusal blames the pairs, not a line.
    rng = np.random.default_rng(26)
    dots = [0, 13, 126]
    truth = _mirrored_robot(rng)
    robot = _map(truth, BOARD[dots]) + rng.normal(0, TOUCH_NOISE_MM, (3, 2))
    robot[1, 0] += 30.0
    with pytest.raises(pc.RegistrationError) as refused:
        RobotFrame.fit(BOARD[dots], robot, dots=dots)
    message = str(refused.value)
    assert "one line" not in message
    assert re.search(r"the touches disagree .* touch noise of 1\d\.\d mm", message), message
    assert re.search(r"\b11\d mm from their main line", message), message
    assert "check the pairs" in message
    # The same touches without the wrong pair register.
    robot[1, 0] -= 30.0
    assert RobotFrame.fit(BOARD[dots], robot, dots=dots).reflected


# -- the judgement covers the layout (issue 21) --------------------------------------------


def test_the_quality_covers_the_board_not_only_the_touches() -> None:
    # Four touches on a 20 mm square in the board's corner agree with each other to a robot's
    # repeatability, and turn the map by their noise over the 260 x 180 mm board.
    rng = np.random.default_rng(1)
    dots = [0, 1, 14, 15]
    truth = _mirrored_robot(rng)
    robot = _map(truth, BOARD[dots]) + rng.normal(0, TOUCH_NOISE_MM, (4, 2))
    alone = RobotFrame.fit(BOARD[dots], robot, dots=dots)
    assert alone.leave_one_out_rms_mm < 0.1
    assert alone.summary().count("Excellent") == 1  # judged where it was touched
    board = RobotFrame.fit(BOARD[dots], robot, dots=dots, work_area_mm=BOARD)
    np.testing.assert_array_equal(board.work_area_mm, [[0.0, 0.0], [260.0, 180.0]])
    assert board.corner_std_mm > 0.3
    assert board.corner_std_mm == pytest.approx(float(board.std_mm(BOARD).max()))
    text = board.summary()
    assert "Excellent" not in text and "at the board's corners" in text
    assert "touch dots nearer the board's corners" in text
    # The same number of touches at the board's corners: excellent.
    corners = [0, 13, 126, 139]
    robot = _map(truth, BOARD[corners]) + rng.normal(0, TOUCH_NOISE_MM, (4, 2))
    spread = RobotFrame.fit(BOARD[corners], robot, dots=corners, work_area_mm=BOARD)
    assert spread.corner_std_mm < 0.05 and "Excellent" in spread.summary()


def test_the_summary_gives_the_transform_and_names_pairs_by_dot() -> None:
    rng = np.random.default_rng(6)
    dots = [0, 13, 126, 139, 46, 93]
    truth = _mirrored_robot(rng)
    robot = _map(truth, BOARD[dots]) + rng.normal(0, TOUCH_NOISE_MM, (6, 2))
    frame = RobotFrame.fit(BOARD[dots], robot, dots=dots)
    assert frame.rotation_deg is not None
    text = frame.summary(lines=[3, 4, 5, 6, 8, 9])
    tx, ty = frame.plane_to_robot[:2, 2]
    assert f"translation ({tx:.3f}, {ty:.3f}) mm" in text
    assert f"rotation {frame.rotation_deg:.3f} deg" in text and "scale 1.000000" in text
    assert "right-handed (z up)" in text
    header = next(line for line in text.splitlines() if "board x" in line)
    assert header.split()[:2] == ["dot", "line"]
    row = next(line for line in text.splitlines() if line.split()[:2] == ["126", "5"])
    assert row.split()[2:4] == ["0.00", "180.00"]
    affine = RobotFrame.fit(BOARD[dots], robot, model="affine").summary()
    assert "robot = A board + t: A = [[" in affine and affine.split("\n")[3].split()[0] == "touch"


# -- leave-one-out in O(N) and a bounded outlier search (issue 21) ---------------------------


def _reference_leave_one_out(plane: F64, robot: F64, model: Model, reflected: bool) -> F64:
    """Each point refitted without it, one fit at a time: what leave_one_out must equal."""
    n = len(plane)
    out = np.empty(n)
    for i in range(n):
        keep = np.arange(n) != i
        p, q = plane[keep], robot[keep]
        if (
            len(p) < MINIMAL_POINTS[model]
            or min(spread_mm(p), spread_mm(q)) < MIN_SPREAD_MM
            or (model == "affine" and width_ratio(p) < MIN_WIDTH_RATIO)
        ):
            out[i] = np.inf
            continue
        m = fit(p, q, model, reflected)
        out[i] = float(np.hypot(*(_map(m, plane[i : i + 1])[0] - robot[i])))
    return out


@settings(max_examples=examples(80))
@given(
    seed=st.integers(0, 2**32 - 1),
    model=st.sampled_from(MODELS),
    reflected=st.booleans(),
    layout=st.sampled_from(["spread", "clustered pair", "thin"]),
)
def test_leave_one_out_equals_refitting_without_each_point(
    seed: int, model: Model, reflected: bool, layout: str
) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(MINIMAL_POINTS[model] + 1, 25))
    plane = rng.uniform([0, 0], [250, 180], (n, 2)) + rng.uniform(-400, 400, 2)
    if layout == "clustered pair":  # without one point, the rest may be too clustered
        plane[1:] = plane[1] + rng.uniform(-0.8, 0.8, (n - 1, 2))
    elif layout == "thin":  # without one point, the rest may be collinear for affine
        plane[1:, 1] = plane[1:, 0] * 0.5 + rng.normal(0, 0.3, n - 1)
    robot = _map(_transform(rng, model, reflected), plane) + rng.normal(0, 0.3, (n, 2))
    fast = leave_one_out(plane, robot, model, reflected)
    slow = _reference_leave_one_out(plane, robot, model, reflected)
    np.testing.assert_array_equal(np.isinf(fast), np.isinf(slow))
    finite = np.isfinite(slow)
    np.testing.assert_allclose(fast[finite], slow[finite], rtol=1e-9, atol=1e-9)


def test_the_outlier_search_is_bounded_and_says_so() -> None:
    rng = np.random.default_rng(12)
    plane = rng.uniform([0, 0], [260, 180], (400, 2))
    truth = _mirrored_robot(rng)
    robot = _map(truth, plane) + rng.normal(0, TOUCH_NOISE_MM, plane.shape)
    bad = rng.choice(400, 60, replace=False)
    robot[bad] += rng.uniform(5.0, 20.0, (60, 2))  # 60 touches far off
    frame = RobotFrame.fit(plane, robot)
    assert frame.outlier_search_capped and len(frame.outliers) == MAX_OUTLIERS
    assert set(frame.outliers) <= set(bad.tolist())
    assert any("stopped after naming 20 touches" in w for w in frame.warnings)
    assert frame.to_dict()["outlier_search_capped"] is True
    # A few wrong touches among many: all named, the search not capped.
    robot = _map(truth, plane) + rng.normal(0, TOUCH_NOISE_MM, plane.shape)
    robot[bad[:5]] += 10.0
    few = RobotFrame.fit(plane, robot)
    assert few.outliers == tuple(sorted(bad[:5].tolist())) and not few.outlier_search_capped


def test_thousands_of_pairs_register_and_refit_from_their_dict() -> None:
    # Quadratic before (20k pairs took 237 s to load): now each step is linear.
    rng = np.random.default_rng(13)
    plane = rng.uniform([0, 0], [260, 180], (20_000, 2))
    truth = _mirrored_robot(rng)
    robot = _map(truth, plane) + rng.normal(0, TOUCH_NOISE_MM, plane.shape)
    frame = RobotFrame.fit(plane, robot)
    assert frame.outliers == () and frame.reflected
    assert frame.leave_one_out_rms_mm == pytest.approx(TOUCH_NOISE_MM * math.sqrt(2), rel=0.05)
    back = RobotFrame.from_dict(frame.to_dict())
    np.testing.assert_array_equal(back.leave_one_out_mm, frame.leave_one_out_mm)


# -- what is not a number (issue 21) --------------------------------------------------------


@pytest.mark.parametrize(
    ("robot", "match"),
    [
        ([["412.5", "-233"], ["255", "-440"], ["268", "-124"]], r"got '412.5' \(a str\)"),
        ([[412.5 + 0j, -233], [255, -440], [268, -124]], r"got \(412.5\+0j\) \(a complex\)"),
        (np.array([[412.5 + 1j, -233], [255, -440], [268, -124]]), r"a complex128"),
        ([[True, -233.0], [255.0, -440.0], [268.0, -124.0]], r"got True \(a bool\)"),
        ([[b"412", -233.0], [255.0, -440.0], [268.0, -124.0]], r"got b'412' \(a bytes\)"),
        ([[1e300, -233.0], [255.0, -440.0], [268.0, -124.0]], r"point 0 is 1e\+300 mm"),
    ],
)
def test_robot_points_that_are_not_real_numbers_are_refused(robot: Any, match: str) -> None:
    plane = BOARD[[0, 13, 126]]
    with pytest.raises(pc.ArgumentError, match=match):
        RobotFrame.fit(plane, robot)
    with pytest.raises(pc.ArgumentError, match=match.replace("robot", "plane")):
        RobotFrame.fit(robot, plane + 100.0)
    with pytest.raises(pc.ArgumentError, match="robot_z must hold real numbers"):
        RobotFrame.fit(plane, plane + 100.0, robot_z=["1", "2", "3"])


@pytest.mark.parametrize("model", MODELS)
def test_robot_points_on_a_line_under_a_board_area_are_refused(model: Model) -> None:
    # An affine fit flattens the board onto the line (a singular map, whose inverse raised
    # numpy's LinAlgError); rigid and similarity fit it so badly that no hand shows.
    plane = _grid()
    robot = np.c_[plane[:, 0] + plane[:, 1], np.zeros(len(plane))] + 300.0
    with pytest.raises(pc.RegistrationError, match=r"flattens the board|mirror image"):
        RobotFrame.fit(plane, robot, model=model)


def test_a_dict_from_before_the_hand_option_still_refits() -> None:
    rng = np.random.default_rng(14)
    truth = _mirrored_robot(rng)
    dots = [0, 13, 126, 139, 46]
    robot = _map(truth, BOARD[dots]) + rng.normal(0, TOUCH_NOISE_MM, (5, 2))
    frame = RobotFrame.fit(BOARD[dots], robot)
    old = frame.to_dict()
    for key in ("handedness", "dots", "work_area_mm", "outlier_search_capped", "corner_std_mm"):
        del old[key]
    assert _fields(RobotFrame.from_dict(old)) == _fields(frame)
    # One saved from touches on a line (the hand then guessed) is refused, saying why.
    row = RobotFrame.fit(BOARD[ROW_DOTS], _map(truth, BOARD[ROW_DOTS]), handedness="left")
    guessed = {**row.to_dict(), "handedness": None}
    with pytest.raises(pc.CalibrationFileError, match="one line"):
        RobotFrame.from_dict(guessed)
    with pytest.raises(pc.CalibrationFileError, match="handedness must be"):
        RobotFrame.from_dict({**row.to_dict(), "handedness": "mirrored"})


def test_calibration_register_refuses_what_is_not_a_real_number() -> None:
    cal = pc.Calibration.load(Path(__file__).parent / "data" / "calibration_v2.json")
    dots = [0, 13, 126, 139]
    robot = _map(_mirrored_robot(np.random.default_rng(2)), BOARD[dots])
    as_text = [[str(x) for x in row] for row in robot]
    with pytest.raises(pc.ArgumentError, match="robot_mm must hold real numbers, got '"):
        cal.register(as_text, dots=dots)
    with pytest.raises(pc.ArgumentError, match=r"robot_mm must hold real numbers.*complex"):
        cal.register(robot + 0j, dots=dots)
    with pytest.raises(pc.ArgumentError, match="board_mm must hold real numbers, got True"):
        cal.register(robot, board_mm=[[True, 0.0], *BOARD[dots[1:]].tolist()])
    with pytest.raises(pc.ArgumentError, match="image_px must hold real numbers"):
        cal.register(robot, image_px=np.array([["1", "2"]] * 4))
    assert cal.register(robot.tolist(), dots=dots).robot_frame is not None
