"""`planarcal register` from a touch-point CSV (its three column sets, the forgiving and the
refused variants), the calibration it writes, and `locate` / `run` / the Tracker giving
positions in the robot's frame once it is there."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

import planarcal as pc
from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.cli import main
from planarcal.live.tracker import Tracker
from planarcal.robot.touch_csv import read_touch_csv

F64 = NDArray[np.float64]

OLD_FILE = Path(__file__).parent / "data" / "calibration_v2.json"

# The board-to-robot truth: the board mirrored, turned by -127 degrees, 412 and -233 mm off.
ANGLE = math.radians(-127.0)
LINEAR = np.array([[math.cos(ANGLE), -math.sin(ANGLE)], [math.sin(ANGLE), math.cos(ANGLE)]])
LINEAR = LINEAR @ np.diag([1.0, -1.0])
OFFSET = np.array([412.0, -233.0])
DOTS = [0, 13, 126, 139, 46, 93]
TOUCH_NOISE_MM = 0.05
# Dots on the board's first row: they leave the map's hand free.
ROW_DOTS = [0, 4, 9, 13]


def _robot(board_mm: F64) -> F64:
    out: F64 = np.asarray(board_mm) @ LINEAR.T + OFFSET
    return out


def _touches(seed: int = 1) -> F64:
    board = pc.CircleGridBoard().world_points()[DOTS]
    noise = np.random.default_rng(seed).normal(0, TOUCH_NOISE_MM, (len(DOTS), 2))
    return _robot(board) + noise


def _write(path: Path, text: str, encoding: str = "utf-8") -> Path:
    path.write_text(text, encoding=encoding)
    return path


def _dot_csv(robot: F64, *, z: float | None = None, dots: list[int] = DOTS) -> str:
    header = "dot,robot_x,robot_y" + (",robot_z" if z is not None else "")
    rows = [
        f"{d},{x:.4f},{y:.4f}" + (f",{z}" if z is not None else "")
        for d, (x, y) in zip(dots, robot, strict=True)
    ]
    return "\n".join([header, *rows]) + "\n"


@pytest.fixture(scope="module")
def parts_png(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, F64]:
    """The paper's parts image (the scene of the calibration in OLD_FILE) and the parts'
    true board positions."""
    scene = synth.paper_scene(0).objects
    path = tmp_path_factory.mktemp("parts") / "parts.png"
    cv2.imwrite(str(path), scene.image)
    return path, scene.object_centroids_mm


# -- reading the CSV --------------------------------------------------------------------------


def test_the_three_column_sets(tmp_path: Path) -> None:
    robot = _touches()
    dots = read_touch_csv(_write(tmp_path / "a.csv", _dot_csv(robot, z=12.5)))
    assert dots.kind == "dot" and dots.dots == DOTS and dots.board is None
    np.testing.assert_allclose(dots.robot, robot, atol=1e-4)
    assert dots.robot_z is not None and np.all(dots.robot_z == 12.5)
    assert dots.lines == (2, 3, 4, 5, 6, 7)

    board = read_touch_csv(
        _write(tmp_path / "b.csv", "board_x,board_y,robot_x,robot_y\n0,0,1,2\n20,0,3,4\n")
    )
    assert board.kind == "board" and board.robot_z is None
    np.testing.assert_array_equal(board.board, [[0, 0], [20, 0]])
    np.testing.assert_array_equal(board.robot, [[1, 2], [3, 4]])

    image = read_touch_csv(
        _write(tmp_path / "c.csv", "robot_y,image_x,robot_x,image_y\n2,600.5,1,300.25\n")
    )
    assert image.kind == "image"
    np.testing.assert_array_equal(image.board, [[600.5, 300.25]])  # any column order
    np.testing.assert_array_equal(image.robot, [[1, 2]])


def test_what_cannot_be_misread_is_forgiven(tmp_path: Path) -> None:
    # Excel's byte-order mark, capitals and spaces, comments, blank lines, a semicolon.
    text = (
        "\ufeff# touched 25 Nov, tool 3\n Dot ; ROBOT_X ; Robot_Y \n\n"
        "0 ; 412.0 ; -233.0\n# redone:\n13 ; 255.5 ; -440.7\n"
    )
    t = read_touch_csv(_write(tmp_path / "t.csv", text))
    assert t.dots == [0, 13] and t.lines == (4, 6)
    np.testing.assert_array_equal(t.robot, [[412.0, -233.0], [255.5, -440.7]])
    tab = read_touch_csv(_write(tmp_path / "tab.csv", "dot\trobot_x\trobot_y\n7.0\t1\t2\n"))
    assert tab.dots == [7]


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("", r"empty: give a header"),
        ("# only a comment\n\n", r"empty"),
        ("dot,robot_x,robot_y\n", r"a header but no points \(line 1\)"),
        ("dot,robot_x,robot_y,speed\n1,2,3,4\n", r"line 1: unknown column\(s\) 'speed'"),
        ("dot,robot_x\n1,2\n", r"line 1: missing column\(s\) robot_y"),
        ("board_x,robot_x,robot_y\n1,2,3\n", r"missing column\(s\) board_y"),
        ("robot_x,robot_y\n1,2\n", r"no board side"),
        (
            "dot,board_x,board_y,robot_x,robot_y\n1,0,0,2,3\n",
            r"more than one board side \(dot and board columns\)",
        ),
        ("dot,dot,robot_x,robot_y\n1,1,2,3\n", r"dot given twice"),
        ("image_x,image_y,robot_x,robot_y,robot_z\n1,2,3,4,5\n", r"robot_z is not used"),
        ("dot,robot_x,robot_y\n1,2,3\n2,3\n", r"line 3: 2 fields, the header has 3"),
        ("dot,robot_x,robot_y\n1,2,3,\n", r"line 2: 4 fields"),
        ("dot,robot_x,robot_y\n1,2,abc\n", r"line 2: robot_y 'abc' is not a number"),
        ("dot,robot_x,robot_y\n1,2,\n", r"line 2: robot_y '' is not a number"),
        ("dot;robot_x;robot_y\n1;2,5;3\n", r"line 2: robot_x '2,5' .*decimal comma"),
        ("dot,robot_x,robot_y\n1,nan,3\n", r"line 2: robot_x 'nan' is not a finite number"),
        ("dot,robot_x,robot_y\n1.5,2,3\n", r"line 2: dot 1.5 is not a dot index"),
    ],
)
def test_malformed_csv_is_refused_naming_the_line(tmp_path: Path, text: str, match: str) -> None:
    with pytest.raises(pc.ArgumentError, match=match):
        read_touch_csv(_write(tmp_path / "t.csv", text))


def test_a_file_that_is_not_text_or_not_there_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_bytes(b"dot,robot_x,robot_y\n\xff\xfe1,2,3\n")
    with pytest.raises(pc.ArgumentError, match="not a UTF-8 text file"):
        read_touch_csv(path)
    with pytest.raises(pc.ArgumentError, match="no touch-point file at"):
        read_touch_csv(tmp_path / "missing.csv")
    # What is not a file of a few lines is refused at once: a folder, a FIFO (which would
    # wait for a writer for ever), a device, a file of megabytes.
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    for not_a_file in (tmp_path, fifo, Path("/dev/zero")):
        with pytest.raises(pc.ArgumentError, match="is not a regular file"):
            read_touch_csv(not_a_file)
    huge = tmp_path / "huge.csv"
    huge.write_bytes(b"dot,robot_x,robot_y\n" + b"0,1,2\n" * 200_000)
    with pytest.raises(pc.ArgumentError, match="is over 1 MiB"):
        read_touch_csv(huge)
    unreadable = tmp_path / "locked.csv"
    unreadable.write_text("dot,robot_x,robot_y\n")
    unreadable.chmod(0)
    if not os.access(unreadable, os.R_OK):  # root reads it all the same
        with pytest.raises(pc.ArgumentError, match="cannot read the touch-point file"):
            read_touch_csv(unreadable)


# -- the command ------------------------------------------------------------------------------


def test_register_writes_the_registration_and_locate_gives_robot_mm(
    tmp_path: Path, parts_png: tuple[Path, F64], capsys: pytest.CaptureFixture[str]
) -> None:
    points = _write(tmp_path / "touch.csv", _dot_csv(_touches(), z=12.5))
    out = tmp_path / "calib.json"
    assert (
        main(["register", "--calibration", str(OLD_FILE), "--points", str(points), "-o", str(out)])
        == 0
    )
    text = capsys.readouterr().out
    assert "rigid registration from 6 of 6 point pairs; mirrored" in text
    assert "Excellent" in text and f"Saved the calibration with the registration to {out}" in text
    cal = Calibration.load(out)
    assert cal.robot_frame is not None and cal.robot_frame.plane is not None
    assert cal.robot_frame.plane.height_mm == pytest.approx(12.5)

    image, truth_board = parts_png
    # locate: robot mm by default once registered, board mm on request; the JSON names it.
    for frame, expected in ((None, "robot"), ("board", "board"), ("robot", "robot")):
        argv = ["locate", str(image), "--calibration", str(out), "--json"]
        assert main(argv + ([] if frame is None else ["--frame", frame])) == 0
        result = json.loads(capsys.readouterr().out)
        assert result["coords"] == expected
        mm = np.array([o["world_mm"] for o in result["objects"]])
        truth = _robot(truth_board) if expected == "robot" else truth_board
        gap = np.hypot(*(mm[:, None, :] - truth[None, :, :]).transpose(2, 0, 1)).min(axis=1)
        assert len(mm) == len(truth) and gap.max() < 0.25, gap
    # The robot-frame 1-sigma includes the registration's own error.
    assert main(["locate", str(image), "--calibration", str(out), "--json"]) == 0
    robot_std = [o["world_std_mm"] for o in json.loads(capsys.readouterr().out)["objects"]]
    assert min(robot_std) >= 0.01


def test_a_wrong_touch_is_named_and_nothing_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    robot = _touches()
    robot[2] = _robot(pc.CircleGridBoard().world_points()[DOTS[2] + 1])  # the next dot
    points = _write(tmp_path / "touch.csv", _dot_csv(robot))
    out = tmp_path / "calib.json"
    argv = ["register", "--calibration", str(OLD_FILE), "--points", str(points), "-o", str(out)]
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert "Touch again: dot 126 (line 4) of touch.csv." in captured.out
    assert "nothing written" in captured.err and "(dot 126 (line 4))" in captured.err
    assert not out.exists()
    # Left out on request: written, the outlier recorded.
    assert main([*argv, "--drop-outliers", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["written"] and result["quality"] == "excellent"
    assert result["registration"]["outliers"] == [2] and result["lines"][2] == 4
    again = Calibration.load(out).robot_frame
    assert again is not None and again.outliers == (2,) and again.dropped_outliers


def test_n_point_and_board_mm_csvs_register(
    tmp_path: Path, parts_png: tuple[Path, F64], capsys: pytest.CaptureFixture[str]
) -> None:
    image, truth_board = parts_png
    cal = Calibration.load(OLD_FILE)
    found = pc.locate_objects(cv2.imread(str(image), cv2.IMREAD_GRAYSCALE), cal)
    px = np.array([o.centroid_px for o in found])
    seen = np.array([o.world_mm for o in found])
    nearest = [int(np.argmin(np.hypot(*(truth_board - s).T))) for s in seen]
    robot = _robot(truth_board[nearest]) + np.random.default_rng(3).normal(0, 0.05, seen.shape)
    rows = [f"{u},{v},{x},{y}" for (u, v), (x, y) in zip(px, robot, strict=True)]
    points = _write(tmp_path / "npoint.csv", "image_x,image_y,robot_x,robot_y\n" + "\n".join(rows))
    out = tmp_path / "calib.json"
    argv = ["register", "--calibration", str(OLD_FILE), "--points", str(points), "-o", str(out)]
    assert main([*argv, "--model", "similarity", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["pairs"] == "image" and result["registration"]["model"] == "similarity"
    assert result["registration"]["scale"] == pytest.approx(1.0, abs=1e-3)
    assert result["registration"]["plane_std_mm"] is not None

    board = pc.CircleGridBoard().world_points()[DOTS]
    rows = [f"{bx},{by},{x},{y}" for (bx, by), (x, y) in zip(board, _touches(), strict=True)]
    points = _write(tmp_path / "board.csv", "board_x,board_y,robot_x,robot_y\n" + "\n".join(rows))
    assert (
        main(["register", "--calibration", str(out), "--points", str(points), "-o", str(out)]) == 0
    )
    text = capsys.readouterr().out
    assert "(replacing its earlier registration)" in text
    frame = Calibration.load(out).robot_frame
    assert frame is not None and frame.model == "rigid"


@pytest.mark.parametrize(
    ("csv_text", "match"),
    [
        ("dot,robot_x,robot_y\n0,1,2\n140,3,4\n13,5,6\n", r"dot 1: index 140 is off the board"),
        ("dot,robot_x,robot_y\n0,1,2\n13,3,4\n", r"at least 3 point pairs"),
        ("dot,robot_x,robot_y,extra\n0,1,2,3\n", r"unknown column"),
        # Issue 21: a field over the csv module's limit, a coordinate beyond any cell, and
        # touches on one row of the board (which leave the map's hand free).
        (
            "dot,robot_x,robot_y\n0,1," + "2" * 200_000 + "\n",
            r"line 2: not a CSV row \(field larger than field limit",
        ),
        ("dot,robot_x,robot_y\n0,1e300,2\n13,3,4\n126,5,6\n", r"point 0 is 1e\+300 mm"),
        (
            "dot,robot_x,robot_y\n"
            + "".join(
                f"{d},{x:.3f},{y:.3f}\n"
                for d, (x, y) in zip(
                    ROW_DOTS, _robot(pc.CircleGridBoard().world_points()[ROW_DOTS]), strict=True
                )
            ),
            r"one line.*off the line through dot 0 and dot 13.*--handedness",
        ),
    ],
)
def test_unusable_input_exits_1_with_one_line(tmp_path: Path, csv_text: str, match: str) -> None:
    points = _write(tmp_path / "touch.csv", csv_text)
    out = tmp_path / "calib.json"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "planarcal",
            "register",
            "--calibration",
            str(OLD_FILE),
            "--points",
            str(points),
            "-o",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 1, done
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("planarcal register: error:"), done.stderr
    assert re.search(match, lines[0]), lines[0]
    assert not out.exists()


def _register(argv: list[str]) -> subprocess.CompletedProcess[str]:
    """``planarcal register`` with argv, in a child process."""
    return subprocess.run(
        [sys.executable, "-m", "planarcal", "register", "--calibration", str(OLD_FILE), *argv],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_the_text_output_gives_the_transform_and_each_touch_by_dot_and_line(
    tmp_path: Path,
) -> None:
    points = _write(tmp_path / "touch.csv", "# touched today\n" + _dot_csv(_touches()))
    out = tmp_path / "calib.json"
    done = _register(["--points", str(points), "-o", str(out)])
    assert done.returncode == 0, done.stderr
    text = done.stdout
    assert re.search(r"translation \(41[12]\.\d{3}, -23[23]\.\d{3}\) mm", text), text
    assert re.search(r"rotation -12[67]\.\d{3} deg, scale 1\.000000", text)
    assert "the board's y axis mirrored" in text and "right-handed (z up)" in text
    header = next(line for line in text.splitlines() if "board x" in line)
    assert header.split()[:2] == ["dot", "line"]
    rows = {line.split()[0]: line.split() for line in text.splitlines() if line[:5].strip()}
    # Dot 126 is the CSV's line 5 (a comment and the header above), at (0, 180) mm.
    assert rows["126"][1:4] == ["5", "0.00", "180.00"]


def test_a_row_of_touches_registers_with_the_hand_given(
    tmp_path: Path, parts_png: tuple[Path, F64], capsys: pytest.CaptureFixture[str]
) -> None:
    board = pc.CircleGridBoard().world_points()[ROW_DOTS]
    noise = np.random.default_rng(4).normal(0, TOUCH_NOISE_MM, board.shape)
    points = _write(tmp_path / "row.csv", _dot_csv(_robot(board) + noise, dots=ROW_DOTS))
    out = tmp_path / "calib.json"
    argv = ["register", "--calibration", str(OLD_FILE), "--points", str(points), "-o", str(out)]
    assert main(argv) == 1
    assert "through dot 0 and dot 13" in capsys.readouterr().err
    assert not out.exists()
    assert main([*argv, "--handedness", "right", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["registration"]["handedness"] == "right"
    assert result["registration"]["reflected"] is True
    # The parts, off the row, land where the robot finds them.
    image, truth_board = parts_png
    assert main(["locate", str(image), "--calibration", str(out), "--json"]) == 0
    mm = np.array([o["world_mm"] for o in json.loads(capsys.readouterr().out)["objects"]])
    truth = _robot(truth_board)
    gap = np.hypot(*(mm[:, None, :] - truth[None, :, :]).transpose(2, 0, 1)).min(axis=1)
    assert gap.max() < 0.5, gap
    # --no-mirror states the other hand: fitted as stated (the row cannot tell).
    assert main([*argv, "--no-mirror", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["registration"]["handedness"] == "left"
    assert result["registration"]["reflected"] is False
    frame = Calibration.load(out).robot_frame
    assert frame is not None and frame.handedness == "left" and frame.dots == tuple(ROW_DOTS)


def test_a_poor_registration_is_written_only_with_force(tmp_path: Path) -> None:
    # Touches 3 mm off (a wrong tool centre point): poor, and nothing written without --force.
    board = pc.CircleGridBoard().world_points()[DOTS]
    noise = np.random.default_rng(9).normal(0, 3.0, board.shape)
    points = _write(tmp_path / "touch.csv", _dot_csv(_robot(board) + noise))
    out = tmp_path / "calib.json"
    done = _register(["--points", str(points), "-o", str(out)])
    assert done.returncode == 1, done
    assert "Poor:" in done.stdout and "Saved" not in done.stdout
    err = done.stderr.strip().splitlines()
    assert len(err) == 1 and "nothing written: the registration is poor" in err[0]
    assert "--force" in err[0]
    assert not out.exists()
    forced = _register(["--points", str(points), "-o", str(out), "--force", "--json"])
    assert forced.returncode == 0, forced.stderr
    result = json.loads(forced.stdout)
    assert result["quality"] == "poor" and result["written"] and out.exists()


def test_locate_and_run_robot_frame_need_a_registration(
    tmp_path: Path, parts_png: tuple[Path, F64], capfd: pytest.CaptureFixture[str]
) -> None:
    image, _ = parts_png
    assert main(["locate", str(image), "--calibration", str(OLD_FILE), "--frame", "robot"]) == 1
    assert "--frame robot needs a calibration registered" in capfd.readouterr().err
    folder = tmp_path / "frames"
    folder.mkdir()
    (folder / "0.png").write_bytes(image.read_bytes())
    argv = ["run", "--source", str(folder), "--calibration", str(OLD_FILE)]
    assert main([*argv, "--frame", "robot"]) == 1
    assert "--frame robot needs a calibration registered" in capfd.readouterr().err
    assert main(argv) == 0
    assert json.loads(capfd.readouterr().out.splitlines()[0])["coords"] == "board"


def test_run_gives_robot_mm_once_registered(
    tmp_path: Path, parts_png: tuple[Path, F64], capfd: pytest.CaptureFixture[str]
) -> None:
    image, truth_board = parts_png
    registered = Calibration.load(OLD_FILE).register(_touches(), dots=DOTS)
    path = registered.save(tmp_path / "calib.json")
    folder = tmp_path / "frames"
    folder.mkdir()
    (folder / "0.png").write_bytes(image.read_bytes())
    argv = ["run", "--source", str(folder), "--calibration", str(path)]
    for frame, expected in ((None, "robot"), ("board", "board")):
        assert main(argv + ([] if frame is None else ["--frame", frame])) == 0
        line = json.loads(capfd.readouterr().out.splitlines()[0])
        assert line["coords"] == expected
        mm = np.array([o["mm"] for o in line["objects"]])
        truth = _robot(truth_board) if expected == "robot" else truth_board
        gap = np.hypot(*(mm[:, None, :] - truth[None, :, :]).transpose(2, 0, 1)).min(axis=1)
        assert gap.max() < 0.25, gap


# -- the Tracker ------------------------------------------------------------------------------


def test_the_tracker_maps_to_the_frame_asked_for(
    tmp_path: Path, parts_png: tuple[Path, F64]
) -> None:
    image, _ = parts_png
    cal = Calibration.load(OLD_FILE)
    registered = cal.register(_touches(), dots=DOTS)
    frame = np.asarray(cv2.imread(str(image), cv2.IMREAD_GRAYSCALE), dtype=np.uint8)
    source = image.parent
    with pytest.raises(pc.ArgumentError, match="needs a registration"):
        Tracker(cal, source, frame="robot")
    with pytest.raises(pc.ArgumentError, match="frame must be 'board' or 'robot'"):
        Tracker(registered, source, frame="base")  # type: ignore[arg-type]
    results = {}
    for name, calibration, asked in (
        ("board", cal, None),
        ("robot", registered, None),
        ("board_asked", registered, "board"),
    ):
        with Tracker(calibration, source, frame=asked) as t:  # type: ignore[arg-type]
            results[name] = t.process(frame)
    assert results["board"].coords == "board" == results["board_asked"].coords
    assert results["robot"].coords == "robot"
    np.testing.assert_array_equal(results["board"].world_mm, results["board_asked"].world_mm)
    assert registered.robot_frame is not None
    # The robot frame's positions are the board frame's mapped (a part's centroid on the
    # plane is carried by an affine map as it is).
    board_mm = results["board"].world_mm
    np.testing.assert_allclose(
        results["robot"].world_mm, registered.robot_frame.to_robot(board_mm), rtol=0, atol=1e-9
    )
    # The 1-sigma: the board's and the registration's own, at the image centroid's image.
    at, board_std = cal.image_to_world(results["robot"].centroids_px, return_std=True)
    np.testing.assert_allclose(results["board"].std_mm, board_std)
    np.testing.assert_allclose(
        results["robot"].std_mm, np.hypot(board_std, registered.robot_frame.std_mm(at))
    )
