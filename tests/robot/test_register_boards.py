"""A registration speaks the calibration's board's language: a chessboard's or a ChArUco
board's touch points are corners ("corner 12" in the table, the messages and the errors), a
circle grid's stay dots; the touch CSV's id column is `corner` or `dot` as the board's points
are, the other kind refused; the saved registration keeps its fields ("dots") whatever the
board. Calibrations come from rendered, detected boards and from ids projected through a
homography."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

import planarcal as pc
from planarcal.calib.calibration import Calibration
from planarcal.cli import main
from planarcal.robot import RobotFrame
from planarcal.robot.touch_csv import read_touch_csv
from planarcal.synth import render_scene

F64 = NDArray[np.float64]

TOUCH_NOISE_MM = 0.05
# The board-to-robot truth: the board mirrored, turned by 63 degrees, 350 and 120 mm off.
ANGLE = math.radians(63.0)
LINEAR = np.array([[math.cos(ANGLE), -math.sin(ANGLE)], [math.sin(ANGLE), math.cos(ANGLE)]])
LINEAR = LINEAR @ np.diag([1.0, -1.0])
OFFSET = np.array([350.0, 120.0])


def _robot(board_mm: F64, seed: int = 3) -> F64:
    noise = np.random.default_rng(seed).normal(0, TOUCH_NOISE_MM, np.shape(board_mm))
    out: F64 = np.asarray(board_mm) @ LINEAR.T + OFFSET + noise
    return out


def _spread_ids(board: pc.Board) -> list[int]:
    """Six ids over the board: its four corner points and two inside, off any one line."""
    c, r = board.cols, board.rows
    return [0, c - 1, (r - 1) * c, r * c - 1, c + 1, (r - 2) * c + c - 2]


def _projected(board: pc.Board) -> Calibration:
    """A calibration of ``board`` from its points projected through a homography (a camera
    looking down at a slant), every point seen."""
    h = np.array([[3.1, 0.4, 210.0], [-0.3, 2.9, 160.0], [1.2e-4, 2.0e-4, 1.0]])
    world = board.world_points()
    projected = np.c_[world, np.ones(len(world))] @ h.T
    image = projected[:, :2] / projected[:, 2:]
    detection = pc.BoardDetection(
        board=board,
        image_points=image,
        image_size=(1280, 960),
        method="synthetic",
        residual_rms_px=0.0,
    )
    return Calibration.from_detection(detection)


@pytest.fixture(scope="module")
def chessboard_cal() -> Calibration:
    """A 9 x 6 chessboard (25 mm squares) rendered by the synth camera and detected."""
    board = pc.ChessboardBoard(9, 6, 25.0)
    scene = render_scene(board=board, seed=4)
    return Calibration.from_detection(pc.detect_board(scene.image, board))


@pytest.fixture(scope="module")
def charuco_cal() -> Calibration:
    """A 7 x 5 squares ChArUco board (30 mm squares, 22 mm markers) rendered and detected."""
    board = pc.CharucoBoard(7, 5, 30.0, 22.0, "DICT_4X4_50")
    scene = render_scene(board=board, seed=5)
    return Calibration.from_detection(pc.detect_board(scene.image, board))


@pytest.fixture(scope="module", params=["chessboard", "charuco"])
def corner_cal(
    request: pytest.FixtureRequest, chessboard_cal: Calibration, charuco_cal: Calibration
) -> Calibration:
    return chessboard_cal if request.param == "chessboard" else charuco_cal


# -- the API --------------------------------------------------------------------------------


def test_a_corner_boards_registration_names_its_pairs_corners(corner_cal: Calibration) -> None:
    board = corner_cal.board
    assert board is not None and board.point_name == "corner"
    ids = _spread_ids(board)
    registered = corner_cal.register(_robot(board.world_points()[ids]), dots=ids)
    frame = registered.robot_frame
    assert frame is not None
    assert frame.point_name == "corner" and frame.dots == tuple(ids)
    assert [frame.pair_name(i) for i in range(len(ids))] == [f"corner {k}" for k in ids]
    text = frame.summary()
    table = text.splitlines()[3:]
    assert table[0].split()[0] == "corner"
    assert [int(row.split()[0]) for row in table[1 : 1 + len(ids)]] == ids
    assert not re.search(r"\bdots?\b", text), text
    # The fit is the truth's: the map's residuals are the touch noise.
    assert frame.rms_mm < 4 * TOUCH_NOISE_MM


def test_a_wrong_corner_is_named_as_a_corner(chessboard_cal: Calibration) -> None:
    board = chessboard_cal.board
    assert board is not None
    ids = [*_spread_ids(board), 2 * board.cols + 4, 3 * board.cols + 2]
    truth = board.world_points()[ids]
    touched = truth.copy()
    touched[-1] = board.world_points()[ids[-1] + 1]  # the robot touched the next corner
    frame = chessboard_cal.register(_robot(touched), dots=ids).robot_frame
    assert frame is not None and frame.outliers == (len(ids) - 1,)
    text = frame.summary()
    assert f"Outlier(s) corner {ids[-1]}:" in text
    assert "a touch on the wrong corner" in text


def test_touches_on_one_line_are_refused_naming_corners(charuco_cal: Calibration) -> None:
    board = charuco_cal.board
    assert board is not None
    row = [0, 2, board.cols - 1]  # the first row of corners
    with pytest.raises(pc.RegistrationError, match=rf"corner 0 and corner {board.cols - 1}") as e:
        charuco_cal.register(_robot(board.world_points()[row]), dots=row)
    assert "touch at least one corner off the line" in str(e.value)


@pytest.mark.parametrize("kind", ["chessboard", "charuco"])
def test_an_id_off_a_corner_board_names_its_corners(kind: str) -> None:
    board: pc.Board = (
        pc.ChessboardBoard(7, 5, 20.0)
        if kind == "chessboard"
        else pc.CharucoBoard(6, 4, 20.0, 15.0, "DICT_4X4_50")
    )
    cal = _projected(board)
    n = board.n_points
    ids = [0, 3, n]
    with pytest.raises(pc.ArgumentError) as info:
        cal.register(_robot(np.zeros((3, 2))), dots=ids)
    message = str(info.value)
    assert f"corner 2: index {n} is off the board" in message
    assert f"{board.cols} x {board.rows} inner corners has corners 0 to {n - 1}" in message
    assert "dot" not in message


def test_a_circle_grid_still_speaks_of_dots() -> None:
    cal = _projected(pc.CircleGridBoard(8, 6, 15.0))
    assert cal.board is not None
    ids = _spread_ids(cal.board)
    frame = cal.register(_robot(cal.board.world_points()[ids]), dots=ids).robot_frame
    assert frame is not None and frame.point_name == "dot"
    assert frame.summary().splitlines()[3].split()[0] == "dot"
    assert frame.pair_name(0) == "dot 0"
    with pytest.raises(pc.ArgumentError, match="dot 1: index 48 is off the board: a 8 x 6 board"):
        cal.register(_robot(np.zeros((2, 2))), dots=[0, 48])


def test_fit_takes_the_point_name_and_refuses_a_malformed_one() -> None:
    board = pc.ChessboardBoard(9, 6, 25.0)
    ids = _spread_ids(board)
    plane = board.world_points()[ids]
    frame = RobotFrame.fit(plane, _robot(plane), dots=ids, point_name="corner")
    assert frame.pair_name(2) == f"corner {ids[2]}"
    assert RobotFrame.fit(plane, _robot(plane), dots=ids).pair_name(2) == f"dot {ids[2]}"
    assert frame.with_point_name("dot").pair_name(2) == f"dot {ids[2]}"
    np.testing.assert_array_equal(frame.with_point_name("dot").plane_to_robot, frame.plane_to_robot)
    for bad in ("", "Corner", "corner 1", 3, b"dot"):
        with pytest.raises(pc.ArgumentError, match="point_name"):
            RobotFrame.fit(plane, _robot(plane), dots=ids, point_name=bad)  # type: ignore[arg-type]


def test_the_saved_registration_keeps_its_fields(tmp_path: Path, corner_cal: Calibration) -> None:
    board = corner_cal.board
    assert board is not None
    ids = _spread_ids(board)
    registered = corner_cal.register(_robot(board.world_points()[ids]), dots=ids)
    saved = registered.save(tmp_path / "registered.json")
    stored = json.loads(saved.read_text())["robot_frame"]
    assert stored["dots"] == ids and "point_name" not in stored
    # The same fields as a circle grid's registration (written before corner boards were).
    plane = board.world_points()[ids]
    assert set(stored) == set(RobotFrame.fit(plane, _robot(plane), dots=ids).to_dict())
    loaded = Calibration.load(saved)
    assert loaded.robot_frame is not None and loaded.robot_frame.dots == tuple(ids)
    # The loaded file names them by its board: corners.
    assert loaded.robot_frame.pair_name(0) == f"corner {ids[0]}"
    assert registered.robot_frame is not None
    np.testing.assert_allclose(
        loaded.robot_frame.plane_to_robot, registered.robot_frame.plane_to_robot, atol=1e-9
    )
    # The file does not store the word: from_dict takes it from whoever knows the board.
    again = RobotFrame.from_dict(stored, point_name=board.point_name)
    assert again.pair_name(0) == "corner 0"


# -- the CSV and the command ----------------------------------------------------------------


def _csv(column: str, ids: list[int], robot: F64) -> str:
    rows = [f"{k},{x:.4f},{y:.4f}" for k, (x, y) in zip(ids, robot, strict=True)]
    return "\n".join([f"{column},robot_x,robot_y", *rows]) + "\n"


def test_the_csv_reads_a_corner_column(tmp_path: Path) -> None:
    path = tmp_path / "touch.csv"
    path.write_text("# touched on the chessboard\n Corner ;robot_x;robot_y\n12;1,5;2\n7;3;4\n")
    with pytest.raises(pc.ArgumentError, match="decimal comma"):
        read_touch_csv(path)
    path.write_text("# touched on the chessboard\n Corner ;robot_x;robot_y\n12;1.5;2\n7;3;4\n")
    touches = read_touch_csv(path)
    assert touches.kind == "corner" and touches.point_name == "corner"
    assert touches.dots == [12, 7] and touches.header_line == 2
    assert touches.describe(1) == "corner 7 (line 4)"
    path.write_text("corner,robot_x,robot_y\n1.5,1,2\n")
    with pytest.raises(pc.ArgumentError, match=r"line 2: corner 1.5 is not a corner index"):
        read_touch_csv(path)
    path.write_text("dot,corner,robot_x,robot_y\n1,1,1,2\n")
    with pytest.raises(pc.ArgumentError, match=r"more than one board side \(dot and corner"):
        read_touch_csv(path)


def _save(cal: Calibration, tmp_path: Path) -> Path:
    return cal.save(tmp_path / "calib.json")


def test_register_on_a_corner_board_from_the_cli(
    tmp_path: Path, corner_cal: Calibration, capsys: pytest.CaptureFixture[str]
) -> None:
    board = corner_cal.board
    assert board is not None
    calib = _save(corner_cal, tmp_path)
    ids = _spread_ids(board)
    points = tmp_path / "touch.csv"
    points.write_text(_csv("corner", ids, _robot(board.world_points()[ids])))
    out_file = tmp_path / "registered.json"
    args = ["register", "--calibration", str(calib), "--points", str(points)]
    assert main([*args, "-o", str(out_file)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^\s*corner\s+line\s+board x", out, re.MULTILINE), out
    assert re.search(rf"^\s*{ids[3]}\s+5\s", out, re.MULTILINE), out
    assert not re.search(r"\bdots?\b", out), out
    stored = json.loads(out_file.read_text())["robot_frame"]
    assert stored["dots"] == ids
    assert main([*args, "-o", str(out_file), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["pairs"] == "corner" and result["registration"]["dots"] == ids


def test_the_cli_names_a_wrong_corner_and_its_line(
    tmp_path: Path, chessboard_cal: Calibration, capsys: pytest.CaptureFixture[str]
) -> None:
    board = chessboard_cal.board
    assert board is not None
    calib = _save(chessboard_cal, tmp_path)
    ids = [*_spread_ids(board), 2 * board.cols + 4, 3 * board.cols + 2]
    touched = board.world_points()[ids].copy()
    touched[-1] = board.world_points()[ids[-1] + 1]
    points = tmp_path / "touch.csv"
    points.write_text(_csv("corner", ids, _robot(touched)))
    out_file = tmp_path / "out.json"
    code = main(
        ["register", "--calibration", str(calib), "--points", str(points), "-o", str(out_file)]
    )
    captured = capsys.readouterr()
    assert code == 1 and not out_file.exists()
    assert f"Touch again: corner {ids[-1]} (line {len(ids) + 1}) of touch.csv." in captured.out
    assert f"look like the wrong point (corner {ids[-1]} (line {len(ids) + 1}))" in captured.err


@pytest.mark.parametrize(
    ("board", "column", "expected"),
    [
        (pc.ChessboardBoard(7, 5, 20.0), "dot", "corner"),
        (pc.CharucoBoard(6, 4, 20.0, 15.0, "DICT_4X4_50"), "dot", "corner"),
        (pc.CircleGridBoard(8, 6, 15.0), "corner", "dot"),
    ],
    ids=["chessboard", "charuco", "circles"],
)
def test_a_csv_naming_the_other_kind_of_point_is_refused(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    board: pc.Board,
    column: str,
    expected: str,
) -> None:
    calib = _save(_projected(board), tmp_path)
    ids = _spread_ids(board)
    points = tmp_path / "touch.csv"
    points.write_text(_csv(column, ids, _robot(board.world_points()[ids])))
    out_file = tmp_path / "out.json"
    args = ["register", "--calibration", str(calib), "--points", str(points)]
    code = main([*args, "-o", str(out_file)])
    err = capsys.readouterr().err
    assert code != 0 and not out_file.exists()
    assert f"touch.csv line 1: its '{column}' column gives {column} ids" in err
    assert f"({board.describe()}) has {expected}s, not {column}s" in err
    assert f"name the column '{expected}'" in err
    # Renamed, the same ids register.
    points.write_text(_csv(expected, ids, _robot(board.world_points()[ids])))
    assert main([*args, "-o", str(out_file)]) == 0
    assert out_file.exists()


def test_board_mm_pairs_on_a_corner_board_speak_of_corners(
    tmp_path: Path, chessboard_cal: Calibration, capsys: pytest.CaptureFixture[str]
) -> None:
    # Four touches in one cluster: the verdict tells where to touch, in the board's word.
    board = chessboard_cal.board
    assert board is not None
    ids = [0, 1, board.cols, board.cols + 1]
    plane = board.world_points()[ids]
    points = tmp_path / "touch.csv"
    rows = [
        f"{bx:g},{by:g},{rx:.4f},{ry:.4f}"
        for (bx, by), (rx, ry) in zip(plane, _robot(plane), strict=True)
    ]
    points.write_text("\n".join(["board_x,board_y,robot_x,robot_y", *rows]) + "\n")
    calib = _save(chessboard_cal, tmp_path)
    out_file = tmp_path / "out.json"
    main(
        [
            "register",
            "--calibration",
            str(calib),
            "--points",
            str(points),
            "--force",
            "-o",
            str(out_file),
        ]
    )
    out = capsys.readouterr().out
    assert "touch corners nearer the board's corners" in out, out
    assert not re.search(r"\bdots?\b", out), out
