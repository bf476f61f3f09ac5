"""Calibration of every board type and of partial views: the points' ids, the file (version 5
with a typed board; version 4 still read), the coverage warning and its predicted error, the
lens model's coverage, the printer-scale correction, the camera's intrinsics from partial
views, the board's region in the image, and the layers' imports.

The points are the renderer's exact projections (planarcal.synth) with noise added, so that
the truth is known everywhere in the image; the command-line tests render an image and let the
board's own detector find it."""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board
from planarcal.calib.calibration import Calibration
from planarcal.calib.calibration_file import FILE_VERSION, SUMMARY_SINCE_5, field_digests
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.calib.detection import BoardDetection
from planarcal.camera import calibrate_camera
from planarcal.errors import ArgumentError, BoardError, CalibrationFileError, IntrinsicsError
from planarcal.live.objects import board_region_px

BOARDS: list[Board] = [
    CircleGridBoard(14, 10, 20.0, 10.0),
    ChessboardBoard(9, 6, 25.0),
    CharucoBoard(7, 5, 30.0, 22.0, "DICT_5X5_100"),
]
CAMERA = synth.CameraModel()  # 1280 x 720, no distortion: the homography is the truth
SIZE = (CAMERA.width, CAMERA.height)
NOISE_PX = 0.05


def _scene(board: Board, look_at: tuple[float, float], distance: float = 500.0) -> Any:
    pose = synth.PlanePose(distance_mm=distance, tilt_deg=15.0, look_at_mm=look_at)
    return synth.render_scene(CAMERA, pose, board=board)


def _points(scene: Any, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ids, world mm, image px with noise) of the board points in view."""
    ids = np.flatnonzero(scene.points_in_view(2.0))
    rng = np.random.default_rng(seed)
    image = scene.points_px[ids] + rng.normal(0.0, NOISE_PX, (len(ids), 2))
    return ids, scene.board.world_points()[ids], image


def _centred(board: Board) -> tuple[float, float]:
    x0, y0, x1, y1 = board.ink().field
    return ((x0 + x1) / 2.0, (y0 + y1) / 2.0)


def _corner_view(board: Board) -> Any:
    """The board seen with its centre near the image's top-left corner: a partial view of
    its bottom-right quarter, in that corner of the image."""
    x0, _, x1, _ = board.ink().field
    distance = 1.4 * (x1 - x0) * CAMERA.focal_px / CAMERA.width
    half = 0.5 * distance / CAMERA.focal_px * np.array([CAMERA.width, CAMERA.height])
    cx, cy = _centred(board)
    return _scene(board, (cx + 0.95 * half[0], cy + 0.95 * half[1]), distance)


# -- 1. any board, any subset of its points ---------------------------------------------------


@pytest.mark.parametrize("board", BOARDS, ids=lambda b: b.kind)
def test_every_board_calibrates_whole_and_in_part_with_its_point_ids(
    board: Board, tmp_path: Path
) -> None:
    whole = _scene(board, _centred(board))
    ids, world, image = _points(whole, 1)
    assert len(ids) == board.n_points
    cal = Calibration(world, image, board=board, image_size=SIZE)
    assert cal.point_ids is not None and list(cal.point_ids) == list(range(board.n_points))
    # Maps the truth: a pixel between the points lands where the board point is.
    probe = whole.points_px[ids]
    assert np.abs(cal.image_to_world(probe) - world).max() < 0.1

    part = _corner_view(board)
    ids, world, image = _points(part, 2)
    assert 6 <= len(ids) < board.n_points
    shuffled = np.random.default_rng(3).permutation(len(ids))  # any order of the points
    cal = Calibration(world[shuffled], image[shuffled], board=board, image_size=SIZE)
    assert cal.point_ids is not None
    assert np.array_equal(_ids(cal), ids[shuffled])
    assert np.abs(cal.image_to_world(part.points_px[ids]) - world).max() < 0.2

    # The file keeps the board's type and the ids, loads, and saves again byte for byte.
    path = cal.save(tmp_path / "cal.json")
    data = json.loads(path.read_text())
    assert data["version"] == FILE_VERSION == 7
    assert data["board"]["type"] == board.kind
    assert data["points"]["ids"] == [int(i) for i in ids[shuffled]]
    back = Calibration.load(path)
    assert back.board == board and np.array_equal(_ids(back), _ids(cal))
    again = back.save(tmp_path / "again.json")
    assert again.read_bytes() == path.read_bytes()


def test_a_detection_of_part_of_a_board_calibrates_from_the_points_it_found() -> None:
    board = BOARDS[2]
    part = _corner_view(board)
    ids, _, image = _points(part, 4)
    detection = BoardDetection(board, image, SIZE, "test", 0.0, ids=ids)
    assert detection.partial
    cal = Calibration.from_detection(detection)
    assert np.array_equal(_ids(cal), ids) and cal.board is board
    with pytest.raises(Exception, match="BoardDetection"):
        Calibration.from_detection(object())


def test_points_that_are_not_the_boards_are_refused_naming_the_point() -> None:
    board = BOARDS[1]
    world = board.world_points()[:8].copy()
    image = world * 3.0 + 100.0
    world[5] += (3.0, 0.0)
    with pytest.raises(BoardError, match=r"world point 5 .* is not a corner of the board"):
        Calibration(world, image, board=board)
    twice = board.world_points()[[0, 1, 2, 3, 4, 4]]
    with pytest.raises(BoardError, match="falls on the corner of another point"):
        Calibration(twice, np.arange(12.0).reshape(6, 2) ** 1.5, board=board)
    with pytest.raises(BoardError, match="board must be one of"):
        Calibration(world, image, board="chessboard")  # type: ignore[arg-type]


# -- 2. partial views: coverage, the predicted error beyond the points ------------------------


@pytest.mark.parametrize("board", BOARDS[1:], ids=lambda b: b.kind)
def test_a_corner_of_the_image_warns_with_an_honest_predicted_error(board: Board) -> None:
    part = _corner_view(board)
    _, world, image = _points(part, 5)
    cal = Calibration(world, image, board=board, image_size=SIZE, lens="none")
    ex = cal.extrapolation
    assert ex is not None and ex.warning is not None
    assert "extrapolated" in ex.warning and not ex.covers_centre
    assert ex.covered_share < 0.15
    s = cal.summary()
    assert (s.covered_share, s.image_std_mm) == (ex.covered_share, ex.image_std_mm)
    assert ex.image_std_mm > 5 * ex.covered_std_mm
    assert "Warning: the calibration's points cover" in str(s)
    # The worst is at the image's far side, and the real error there is what was predicted:
    # the board frame's truth at the image's four corners, through the true view.
    far = np.array(
        [[0.0, 0.0], [SIZE[0] - 1.0, 0.0], [0.0, SIZE[1] - 1.0], [*np.subtract(SIZE, 1)]]
    )
    truth = _unproject(part, far)
    mm, std = cal.image_to_world(far, return_std=True, pixel_sigma=0.0)
    error = np.hypot(*(mm - truth).T)
    assert std.max() == pytest.approx(ex.image_std_mm, rel=0.05)
    assert (error < 4.0 * std).all(), (error, std)


def _unproject(scene: Any, px: np.ndarray) -> np.ndarray:
    """Board mm of pixels, through the true (distortion-free) view: H^-1."""
    h = scene.view.homography()
    out = np.c_[px, np.ones(len(px))] @ np.linalg.inv(h).T
    table = out[:, :2] / out[:, 2:]
    return np.asarray(table - np.asarray(scene.board_origin_mm), np.float64)


def _ids(cal: Calibration) -> np.ndarray:
    assert cal.point_ids is not None
    return cal.point_ids


def test_a_board_in_the_middle_of_the_view_is_not_warned_about() -> None:
    board = BOARDS[0]
    whole = _scene(board, _centred(board), 450.0)
    _, world, image = _points(whole, 6)
    cal = Calibration(world, image, board=board, image_size=SIZE)
    ex = cal.extrapolation
    assert ex is not None and ex.covers_centre and ex.covered_share > 0.15
    assert ex.warning is None and "Warning" not in str(cal.summary())
    assert ex.grid_std_mm.shape == ex.grid_covered.shape == (len(ex.grid_px),)
    assert ex.grid_covered.any() and not ex.grid_covered.all()
    # No image size, no image to cover.
    assert Calibration(world, image, board=board).extrapolation is None


def test_a_lens_model_needs_the_points_to_span_the_radii_not_only_reach_the_corner() -> None:
    # A small patch in the image's corner reaches it, but spans few radii from the centre:
    # its distortion would be a scale the homography takes, and no lens model is fitted.
    board = ChessboardBoard(5, 4, 10.0)
    lens_camera = synth.CameraModel(k1=-0.1)
    pose = synth.PlanePose(distance_mm=900.0)  # the image's centre on the table's origin
    scene = synth.render_scene(lens_camera, pose, board=board, board_origin_mm=(468.0, 243.0))
    ids = np.flatnonzero(scene.points_in_view(2.0))
    assert len(ids) == board.n_points
    px = scene.points_px[ids]
    assert px.min() > 0 and np.hypot(*(px - np.array([639.5, 359.5])).T).max() > 0.7 * 734
    cal = Calibration(board.world_points()[ids], px, board=board, image_size=SIZE)
    assert cal.lens_model == "none" and "reaches only" in cal.lens_note


# -- 3. the file: typed boards, ids, version 4, edits -----------------------------------------


@pytest.fixture(scope="module")
def chess_file() -> dict[str, Any]:
    board = BOARDS[1]
    _, world, image = _points(_corner_view(board), 7)
    return Calibration(world, image, board=board, image_size=SIZE, lens="none").to_dict()


def _redigest(data: dict[str, Any]) -> dict[str, Any]:
    data["digest"] = {"sha256": field_digests(data)}
    return data


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda d: d["board"].update(square_mm=26.0), r"not a corner of the board"),
        (lambda d: d["board"].update(square_mm="25"), r"board.square_mm must be a number"),
        (lambda d: d["board"].update(type="checkers"), r"board.type must be one of"),
        (lambda d: d["board"].pop("type"), r"board\.(cols|pitch_mm)|not a dot"),
        (lambda d: d["points"]["ids"].__setitem__(0, 40), r"points.ids\[0\] is 40"),
        (lambda d: d["points"]["ids"].__setitem__(0, 0.0), r"points.ids"),
        (lambda d: d["points"].pop("ids"), r"points.ids"),
        (lambda d: d.update(board=None), r"points.ids .* without a board"),
        (lambda d: d["summary"].pop("covered_share"), r"summary.covered_share"),
    ],
    ids=["square", "square str", "type", "no type", "id", "id float", "no ids", "no board", "sum"],
)
def test_an_edited_typed_file_is_refused_naming_what(
    chess_file: dict[str, Any], edit: Any, match: str
) -> None:
    data = copy.deepcopy(chess_file)
    edit(data)
    with pytest.raises(CalibrationFileError, match=match):
        Calibration.from_dict(_redigest(data))  # a recomputed digest hides no edit
    Calibration.from_dict(chess_file)  # the file as saved loads


def _as_version_4(data: dict[str, Any]) -> dict[str, Any]:
    old = copy.deepcopy(data)
    old["version"] = 4
    old.pop("object_settings")  # (version 7's)
    old["board"].pop("type")
    old["points"].pop("ids")
    for key in SUMMARY_SINCE_5:
        old["summary"].pop(key)
    return _redigest(old)


def test_a_version_4_file_of_a_circle_grid_still_loads_and_saves_as_version_5() -> None:
    board = BOARDS[0]
    _, world, image = _points(_scene(board, _centred(board)), 8)
    cal = Calibration(world, image, board=board, image_size=SIZE)
    old = _as_version_4(cal.to_dict())
    back = Calibration.from_dict(old)
    assert back.board == board and np.array_equal(_ids(back), _ids(cal))
    assert back.to_dict() == cal.to_dict()  # the same calibration, written as version 5
    # A version 4 file's board is a circle grid: a typed one is an edited version.
    typed = copy.deepcopy(old)
    typed["board"]["type"] = "circles"
    with pytest.raises(CalibrationFileError, match=r"unknown field board\.type"):
        Calibration.from_dict(_redigest(typed))


def test_a_version_4_file_cannot_hold_another_board_type(chess_file: dict[str, Any]) -> None:
    old = copy.deepcopy(chess_file)
    old["version"] = 4
    old.pop("object_settings")  # (version 7's)
    with pytest.raises(CalibrationFileError, match="version 4 file's board is a circle grid"):
        Calibration.from_dict(_redigest(old))


# -- 4. the printer's scale, for squares too ---------------------------------------------------


@pytest.mark.parametrize("board", BOARDS[1:], ids=lambda b: b.kind)
def test_a_measured_square_corrects_the_printers_scale(board: Board) -> None:
    scene = _scene(board, _centred(board))
    ids, world, image = _points(scene, 9)
    # Printed 1.2 % too large: the points are where the true (scaled) board puts them.
    printed = 1.012
    cal = Calibration(world, image / 1.0, board=board, image_size=SIZE, lens="none")
    true_world = world * printed
    truth = Calibration(true_world, image, image_size=SIZE, lens="none")
    fixed = cal.rescaled(board.pitch * printed)
    probe = np.array([[640.0, 360.0], [500.0, 300.0]])
    assert np.abs(fixed.image_to_world(probe) - truth.image_to_world(probe)).max() < 1e-6
    assert np.array_equal(_ids(fixed), ids)
    assert fixed.world_scale == (printed, printed)
    assert Calibration.from_dict(fixed.to_dict()).world_scale == (printed, printed)


# -- 5. the camera's intrinsics from partial views of any board ------------------------------


def test_intrinsics_from_partial_views_of_a_chessboard() -> None:
    board = ChessboardBoard(11, 8, 20.0)
    camera = synth.CameraModel(focal_px=1100.0, k1=-0.08)
    centre = _centred(board)
    views, counts = [], []
    poses = [
        (0.0, 0.0, 0.0),
        (30.0, 0.0, 60.0),
        (30.0, 90.0, -50.0),
        (35.0, 45.0, 70.0),
        (30.0, 135.0, -60.0),
        (25.0, 200.0, 80.0),
    ]
    rng = np.random.default_rng(10)
    for tilt, axis, shift in poses:
        pose = synth.PlanePose(
            distance_mm=300.0,
            tilt_deg=tilt,
            tilt_axis_deg=axis,
            look_at_mm=(centre[0] + shift, centre[1] + 0.5 * shift),
        )
        scene = synth.render_scene(camera, pose, board=board)
        ids = np.flatnonzero(scene.points_in_view(2.0))
        image = scene.points_px[ids] + rng.normal(0.0, 0.05, (len(ids), 2))
        views.append(BoardDetection(board, image, SIZE, "test", 0.0, ids=ids))
        counts.append(len(ids))
    assert min(counts) < board.n_points and len(set(counts)) > 1  # partial, of many sizes
    cam = calibrate_camera(views, board)
    assert cam.fx == pytest.approx(1100.0, rel=0.01)
    assert cam.dist_coeffs[0] == pytest.approx(-0.08, abs=0.02)
    # A view of too few points is named.
    few = BoardDetection(board, views[0].image_points[:5], SIZE, "test", 0.0, ids=views[0].ids[:5])
    with pytest.raises(IntrinsicsError, match=r"view 2 shows 5 corners"):
        calibrate_camera([views[0], views[1], few], board)


# -- 6. the board's region in the image --------------------------------------------------------


@pytest.mark.parametrize("board", BOARDS, ids=lambda b: b.kind)
def test_the_boards_region_covers_its_printed_field_even_from_a_partial_view(
    board: Board,
) -> None:
    import cv2  # noqa: PLC0415

    scene = _scene(board, _centred(board), 700.0)
    ids = np.flatnonzero(scene.points_in_view(2.0))
    part = ids[: max(6, len(ids) // 3)]  # a detection of the first rows only
    detection = BoardDetection(board, scene.points_px[part], SIZE, "test", 0.0, ids=part)
    region = board_region_px(detection).astype(np.float32)
    x0, y0, x1, y1 = board.ink().field
    field = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    corners = scene.project(field + np.asarray(scene.board_origin_mm))
    for p in (*scene.points_px, *corners):
        assert cv2.pointPolygonTest(region, (float(p[0]), float(p[1])), True) > 0
    # Not the whole image: half a pitch beyond the field.
    assert cv2.contourArea(region) < 0.5 * SIZE[0] * SIZE[1]


# -- 7. the layers import downward --------------------------------------------------------------


def test_the_calibration_imports_no_report_and_the_robot_no_calibration() -> None:
    code = (
        "import sys\n"
        "import planarcal.calib.calibration\n"
        "assert 'planarcal.report.summary' not in sys.modules, 'report'\n"
        "for m in list(sys.modules):\n"
        "    if m.startswith('planarcal.'):\n"
        "        del sys.modules[m]\n"
        "import planarcal.robot.touch_pairs\n"
        "assert 'planarcal.calib.calibration' not in sys.modules, 'touch_pairs'\n"
        "import planarcal.calib.plane_fit\n"
        "assert 'planarcal.calib.lens_choice' not in sys.modules, 'plane_fit'\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, done.stderr


# -- 8. the command line -----------------------------------------------------------------------


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "planarcal", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


CHESS_ARGS = ("--type", "chessboard", "--cols", "9", "--rows", "6", "--square", "25")
CHARUCO_ARGS = (
    "--type",
    "charuco",
    "--squares-x",
    "7",
    "--squares-y",
    "5",
    "--square",
    "30",
    "--marker",
    "22",
    "--dictionary",
    "DICT_5X5_100",
)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    import cv2  # noqa: PLC0415

    folder = tmp_path_factory.mktemp("renders")
    out = {}
    for board in BOARDS[1:]:
        scene = _scene(board, _centred(board), 450.0)
        path = folder / f"{board.kind}.png"
        cv2.imwrite(str(path), scene.image)
        out[board.kind] = path
    return out


def test_calibrate_and_check_a_chessboard_from_the_command_line(
    rendered: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "chess.json"
    done = _run("calibrate", rendered["chessboard"], *CHESS_ARGS, "-o", out, "--json")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["n_points"] == 54 and summary["board"]["type"] == "chessboard"
    data = json.loads(out.read_text())
    assert data["board"]["type"] == "chessboard" and data["points"]["ids"] == list(range(54))
    checked = _run("check", out)
    assert checked.returncode == 0, checked.stderr
    assert "board (chessboard): chessboard of 9 x 6 inner corners" in checked.stdout
    assert "points: 54 of its 54 corners (the whole board)" in checked.stdout
    assert "coverage: the points cover" in checked.stdout
    # The check bar corrects a chessboard's squares too.
    bar = tmp_path / "bar.json"
    done = _run("calibrate", rendered["chessboard"], *CHESS_ARGS, "-o", bar, "--check-bar", "101")
    assert done.returncode == 0, done.stderr
    assert json.loads(bar.read_text())["world_scale"] == [1.01, 1.01]


def test_calibrate_a_charuco_board_and_refuse_options_its_detector_does_not_take(
    rendered: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "charuco.json"
    done = _run("calibrate", rendered["charuco"], *CHARUCO_ARGS, "-o", out)
    assert done.returncode == 0, done.stderr
    assert json.loads(out.read_text())["board"]["type"] == "charuco"
    for option in ("--polarity", "--turned"):
        extra = (option, "dark") if option == "--polarity" else (option,)
        refused = _run("calibrate", rendered["charuco"], *CHARUCO_ARGS, *extra, "-o", out)
        assert refused.returncode == 2
        assert f"{option} does not apply to --type charuco" in refused.stderr
    refused = _run(
        "calibrate", rendered["chessboard"], *CHESS_ARGS, "--polarity", "dark", "-o", out
    )
    assert refused.returncode == 2 and "--polarity does not apply" in refused.stderr


def test_intrinsics_from_the_command_line_with_a_chessboard(tmp_path: Path) -> None:
    import cv2  # noqa: PLC0415

    board = ChessboardBoard(9, 6, 25.0)
    centre = _centred(board)
    paths = []
    tilts = [
        (0, 0, 0, 0),
        (30, 0, 40, 20),
        (30, 90, -40, 20),
        (30, 45, 40, -20),
        (30, 135, -40, -20),
    ]
    for k, (tilt, axis, dx, dy) in enumerate(tilts):
        pose = synth.PlanePose(
            distance_mm=380.0,
            tilt_deg=tilt,
            tilt_axis_deg=axis,
            look_at_mm=(centre[0] + dx, centre[1] + dy),
        )
        scene = synth.render_scene(CAMERA, pose, board=board)
        paths.append(tmp_path / f"view{k}.png")
        cv2.imwrite(str(paths[-1]), scene.image)
    out = tmp_path / "camera.yaml"
    done = _run("intrinsics", *paths, *CHESS_ARGS, "-o", out, "--json")
    assert done.returncode == 0, done.stderr
    fx = json.loads(done.stdout)["camera_matrix"][0][0]
    assert fx == pytest.approx(CAMERA.focal_px, rel=0.01)


@pytest.mark.parametrize("board", BOARDS, ids=lambda b: b.kind)
def test_from_image_finds_and_calibrates_every_board_type(board: Board) -> None:
    scene = _scene(board, _centred(board), 450.0)
    cal = Calibration.from_image(scene.image, board)
    assert cal.board == board and len(_ids(cal)) == board.n_points
    truth = scene.points_px
    assert np.abs(cal.image_to_world(truth) - board.world_points()).max() < 0.1
    if board.kind != "circles":
        with pytest.raises(ArgumentError, match=r"no option 'polarity'|no options, got polarity"):
            Calibration.from_image(scene.image, board, polarity="dark")
    with pytest.raises(BoardError, match="board must be one of"):
        Calibration.from_image(scene.image, "board")  # type: ignore[arg-type]


def test_pixels_beyond_the_planes_horizon_have_no_predicted_error() -> None:
    # A view so oblique that the plane's horizon crosses the image (x = 500 px here): the
    # pixels beyond it see no point of the plane, and no error bar is made up for them.
    board = ChessboardBoard(9, 6, 25.0)
    h = np.array([[2.0, 0.0, 20.0], [0.0, 2.0, 20.0], [0.004, 0.0, 1.0]])
    world = board.world_points()
    ideal = np.c_[world, np.ones(len(world))] @ h.T
    image = ideal[:, :2] / ideal[:, 2:] + np.random.default_rng(11).normal(0, 0.05, world.shape)
    cal = Calibration(world, image, board=board, image_size=(640, 480), lens="none")
    ex = cal.extrapolation
    assert ex is not None and ex.image_std_mm == np.inf
    beyond = ex.grid_px[:, 0] > 501.0
    assert np.isinf(ex.grid_std_mm[beyond]).all() and np.isfinite(ex.grid_std_mm[~beyond]).all()
    assert ex.warning is not None and "has no place on the plane" in ex.warning
    data = cal.to_dict()
    assert data["summary"]["image_std_mm"] is None
    assert Calibration.from_dict(data).summary().image_std_mm == np.inf
