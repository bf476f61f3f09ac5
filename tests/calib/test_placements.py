"""Calibration from several placements of one board (issue 23): rendered cells whose work area
is several boards wide, the board laid at several places and angles, one image each."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal import (
    BoardDetection,
    Calibration,
    ChessboardBoard,
    CircleGridBoard,
    detect_board,
)
from planarcal.calib.boards import Board
from planarcal.calib.calibration_file import calibration_to_dict
from planarcal.errors import (
    ArgumentError,
    BoardError,
    CalibrationFileError,
    FrameSizeError,
    PlacementError,
)
from planarcal.live.objects import locate_objects
from planarcal.synth import CameraModel, PlanePose, SceneObject, render_scene
from planarcal.synth.copies import render_copies

F64 = NDArray[np.float64]

CAMERA = CameraModel(1280, 960, focal_px=1000.0, k1=-0.12, k2=0.03)
POSE = PlanePose(distance_mm=480.0, tilt_deg=8, tilt_axis_deg=30, look_at_mm=(180.0, 150.0))
# (origin on the table mm, angle deg): the corners of a 360 x 300 mm area, then its middle.
PLACES = [((0.0, 0.0), 0.0), ((240.0, 0.0), 10.0), ((0.0, 220.0), -5.0), ((240.0, 220.0), 95.0)]
MIDDLE = ((120.0, 110.0), 45.0)
CIRCLES = CircleGridBoard(7, 6, 20.0)
CHESS = ChessboardBoard(7, 6, 18.0, origin_marker=True)


def render(board: Board, place: tuple[tuple[float, float], float], seed: int, **kw: object) -> F64:
    pose = kw.pop("pose", POSE)
    scene = render_scene(
        CAMERA,
        pose,  # type: ignore[arg-type]
        board=board,
        board_origin_mm=place[0],
        board_angle_deg=place[1],
        blur_sigma_px=0.8,
        noise_sigma=2.0,
        supersample=4,
        seed=seed,
    )
    return np.asarray(scene.image)


def work_area_pixels() -> tuple[F64, F64]:
    """Table points over the whole work area (beyond every placement) and their exact pixels."""
    xs, ys = np.meshgrid(np.linspace(-20, 380, 31), np.linspace(-20, 340, 28))
    table = np.stack([xs.ravel(), ys.ravel()], axis=1)
    px = CAMERA.project(table, POSE)
    inside = (px[:, 0] > 0) & (px[:, 0] < 1279) & (px[:, 1] > 0) & (px[:, 1] < 959)
    return table[inside], px[inside]


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    folder = tmp_path_factory.mktemp("cell")
    paths = []
    for k, place in enumerate([*PLACES, MIDDLE]):
        path = folder / f"place{k}.png"
        cv2.imwrite(str(path), render(CIRCLES, place, k))
        paths.append(path)
    return paths


@pytest.fixture(scope="module")
def joint(cell: list[Path]) -> Calibration:
    return Calibration.from_images(cell, CIRCLES)


def test_the_poses_are_the_placements(joint: Calibration) -> None:
    placements = joint.placements
    assert [p.name for p in placements] == [f"place{k}.png" for k in range(5)]
    assert placements[0].reference and not any(p.reference for p in placements[1:])
    for p, (origin, angle) in zip(placements, [*PLACES, MIDDLE], strict=True):
        # A plain circle grid turned by more than 90 degrees is read from its other corner
        # (the turn is the pose's): compare where the board's points lie, not the pose.
        truth = _table_points(CIRCLES, origin, angle)[p.ids]
        assert np.abs(p.plane_mm - truth).max() < 0.02
        assert p.rms_px < 0.05
        assert 0 < p.offset_std_mm < 0.02 or p.reference
    assert len(joint.world_points) == 5 * CIRCLES.n_points
    assert "5 placements" in str(joint.summary())


def test_the_whole_work_area_maps_within_the_issues_limits(
    joint: Calibration, cell: list[Path]
) -> None:
    table, px = work_area_pixels()
    mm, std = joint.image_to_world(px, return_std=True, pixel_sigma=0.0)
    err = np.hypot(*(mm - table).T)
    assert err.mean() <= 0.02 and err.max() <= 0.1
    # Honest error bars over the whole area, beyond every placement too.
    ratio = np.sqrt(np.mean(err**2) / np.mean(std**2))
    assert 0.67 <= ratio <= 1.5, ratio
    # One placement alone, extrapolated: far worse, which is why placements exist.
    one = Calibration.from_image(cell[0], CIRCLES)
    err_one = np.hypot(*(one.image_to_world(px) - table).T)
    assert err_one.mean() > 3 * err.mean() and err_one.max() > 0.1


def test_the_file_records_the_placements_and_loads_to_the_same_bytes(
    joint: Calibration, tmp_path: Path
) -> None:
    path = joint.save(tmp_path / "cal.json")
    data = json.loads(path.read_text())
    assert data["version"] == 7
    stored = data["placements"]
    assert stored["reference"] == 0 and len(stored["items"]) == 5
    assert stored["items"][1]["name"] == "place1.png"
    assert stored["items"][1]["image_size_px"] == [1280, 960]
    assert len(stored["point_placement"]) == len(joint.world_points)
    back = Calibration.load(path)
    assert back.save(tmp_path / "again.json").read_bytes() == path.read_bytes()
    _, px = work_area_pixels()
    a = joint.image_to_world(px, return_std=True)
    b = back.image_to_world(px, return_std=True)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_allclose(a[1], b[1], rtol=1e-9)
    assert [p.angle_deg for p in back.placements] == [p.angle_deg for p in joint.placements]


def test_an_edited_pose_is_refused_even_when_trusted(joint: Calibration, tmp_path: Path) -> None:
    data = joint.to_dict()
    data["placements"]["items"][2]["offset_mm"][0] += 0.5
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CalibrationFileError, match="placements"):
        Calibration.load(path)
    with pytest.raises(CalibrationFileError, match="pose"):
        Calibration.load(path, trust_edits=True)


def test_a_version_5_file_of_one_view_still_loads(cell: list[Path], tmp_path: Path) -> None:
    one = Calibration.from_image(cell[0], CIRCLES)
    path = tmp_path / "v5.json"
    path.write_text(json.dumps(calibration_to_dict(one, version=5)))
    back = Calibration.load(path)
    assert len(back.placements) == 1 and back.placements[0].reference
    np.testing.assert_array_equal(back.H, one.H)


def test_origin_makes_another_placement_the_plane_frame(cell: list[Path]) -> None:
    cal = Calibration.from_images(cell[:4], CIRCLES, reference=2)
    assert cal.placements[2].reference and cal.placements[2].offset_mm == (0.0, 0.0)
    # The first placement is then where the third lies in its frame.
    table, px = work_area_pixels()
    origin, angle = PLACES[2]
    c, s = np.cos(np.radians(-angle)), np.sin(np.radians(-angle))
    rel = (table - origin) @ np.array([[c, s], [-s, c]])
    assert np.abs(cal.image_to_world(px) - rel).max() < 0.1


def test_rescaled_and_for_frame_size_keep_the_placements(joint: Calibration) -> None:
    bigger = joint.rescaled(20.2)
    p = bigger.placements[3]
    assert abs(np.hypot(*p.offset_mm) / np.hypot(*joint.placements[3].offset_mm) - 1.01) < 1e-4
    half = joint.for_frame_size(640, 480)
    _, px = work_area_pixels()
    np.testing.assert_allclose(
        half.image_to_world(px / 2 - 0.25), joint.image_to_world(px), atol=1e-6
    )
    assert len(half.placements) == 5


def test_a_chessboard_calibrates_from_placements_too() -> None:
    dets = [detect_board(render(CHESS, place, 10 + k), CHESS) for k, place in enumerate(PLACES)]
    cal = Calibration.from_detections(dets)
    table, px = work_area_pixels()
    err = np.hypot(*(cal.image_to_world(px) - table).T)
    assert err.mean() <= 0.02 and err.max() <= 0.1


# -- what the fit refuses ------------------------------------------------------------------


def _detections(cell: list[Path]) -> list[BoardDetection]:
    return [detect_board(p, CIRCLES, turned=k > 0) for k, p in enumerate(cell[:4])]


def test_a_board_lying_on_a_part_is_named_not_averaged_in(cell: list[Path]) -> None:
    flat = _detections(cell)
    # Placement 2 on a 10 mm part: the table 10 mm nearer the camera for that image.
    raised_pose = dataclasses.replace(POSE, distance_mm=POSE.distance_mm - 10.0)
    lifted = detect_board(render(CIRCLES, PLACES[2], 2, pose=raised_pose), CIRCLES, turned=True)
    with pytest.raises(PlacementError, match=r"placement 2 .*larger.*not flat") as e:
        Calibration.from_detections([flat[0], flat[1], lifted, flat[3]])
    assert e.value.placement == 2


def test_a_wrong_detection_is_named(cell: list[Path]) -> None:
    dets = _detections(cell)
    # Placement 1 read mirrored: its columns' ids reversed.
    cols, rows = CIRCLES.cols, CIRCLES.rows
    order = np.arange(cols * rows).reshape(rows, cols)[:, ::-1].ravel()
    mirrored = dataclasses.replace(dets[1], image_points=dets[1].image_points[order])
    with pytest.raises(PlacementError, match=r"placement 1 .*mirrored") as e:
        Calibration.from_detections([dets[0], mirrored, dets[2], dets[3]])
    assert e.value.placement == 1


def test_placements_of_other_boards_or_cameras_are_refused(cell: list[Path]) -> None:
    dets = _detections(cell)
    other = CircleGridBoard(7, 6, 25.0)
    with pytest.raises(BoardError, match=r"placement 1 .*another board"):
        Calibration.from_detections([dets[0], dataclasses.replace(dets[1], board=other)])
    with pytest.raises(FrameSizeError, match=r"placement 1 .*one fixed camera"):
        Calibration.from_detections([dets[0], dataclasses.replace(dets[1], image_size=(640, 480))])
    with pytest.raises(ArgumentError, match="reference"):
        Calibration.from_detections(dets, reference=4)
    with pytest.raises(ArgumentError, match="names"):
        Calibration.from_detections(dets, names=["a", "b"])
    with pytest.raises(ArgumentError, match="non-empty"):
        Calibration.from_detections([])


def test_the_cli_calibrates_from_several_images(cell: list[Path], tmp_path: Path) -> None:
    out = tmp_path / "cal.json"
    run = subprocess.run(
        [sys.executable, "-m", "planarcal", "calibrate", *map(str, cell), "--cols", "7",
         "--rows", "6", "--pitch", "20", "-o", str(out), "--json", "--max-error-mm", "0.01"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert [p["name"] for p in summary["placements"]] == [p.name for p in cell]
    assert summary["coverage"]["limit_mm"] == 0.01
    assert Calibration.load(out).placements[4].name == "place4.png"
    check = subprocess.run(
        [sys.executable, "-m", "planarcal", "check", str(out)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert check.returncode == 0, check.stderr
    assert "from 5 placements of the board" in check.stdout
    assert "placement 4 (place4.png)" in check.stdout
    wrong = subprocess.run(
        [sys.executable, "-m", "planarcal", "calibrate", *map(str, cell[:2]), "--cols", "7",
         "--rows", "6", "--pitch", "20", "-o", str(out), "--origin", "2"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert wrong.returncode == 2 and "--origin 2 is not a placement" in wrong.stderr


def _table_points(board: Board, origin: tuple[float, float], angle: float) -> F64:
    c, s = np.cos(np.radians(angle)), np.sin(np.radians(angle))
    out: F64 = board.world_points() @ np.array([[c, s], [-s, c]]) + np.asarray(origin)
    return out


def test_locate_and_register_work_unchanged_over_the_whole_area(joint: Calibration) -> None:
    # Parts (the board taken away) over the whole work area, far from the reference too.
    parts = [
        SceneObject("disc", (340.0, 300.0), size_mm=14.0),
        SceneObject("nut", (330.0, 20.0), angle_deg=10.0, size_mm=10.0),
        SceneObject("washer", (10.0, 310.0), size_mm=12.0),
    ]
    scene = render_scene(
        CAMERA, POSE, board=None, objects=parts, blur_sigma_px=0.8, noise_sigma=2.0, seed=7
    )
    found = locate_objects(scene.image, joint)
    assert len(found) == len(parts)
    got = np.array(sorted((np.asarray(o.world_mm) for o in found), key=lambda p: p[0] + 2 * p[1]))
    truth = scene.object_centroids_mm
    want = truth[np.argsort(truth[:, 0] + 2 * truth[:, 1])]
    assert np.abs(got - want).max() < 0.1
    # A registration from touched corners of the board where the reference lay: robot mm.
    turn = np.array([[0.0, -1.0], [1.0, 0.0]])
    dots = [0, 6, 35, 41]
    robot = CIRCLES.world_points()[dots] @ turn.T + np.array([500.0, 100.0])
    registered = joint.register(robot, dots=dots)
    at, std = registered.image_to_world(scene.object_centroids_px, frame="robot", return_std=True)
    np.testing.assert_allclose(at, truth @ turn.T + np.array([500.0, 100.0]), atol=0.1)
    assert (std > 0).all() and (std < 0.2).all()


def test_copies_laid_out_at_once_are_placements_too(tmp_path: Path) -> None:
    # Two images: three copies of a marked chessboard at once, then one more copy alone.
    board = ChessboardBoard(5, 4, 20.0, origin_marker=True)
    together = render_copies(
        board, [(80.0, 70.0, 0.0), (270.0, 110.0, 30.0), (110.0, 250.0, -20.0)]
    )
    alone = render_copies(board, [(300.0, 280.0, 90.0)], pose=together.pose)
    paths = [tmp_path / "three.png", tmp_path / "one.png"]
    cv2.imwrite(str(paths[0]), together.image)
    cv2.imwrite(str(paths[1]), alone.image)
    cal = Calibration.from_images(paths, board, copies=True, turned=True)
    names = [p.name for p in cal.placements]
    assert names == ["three.png copy 1", "three.png copy 2", "three.png copy 3", "one.png copy 1"]
    copies = [*together.copies, *alone.copies]
    # Every copy's points where it lay, in the first copy's frame.
    for placement, copy in zip(cal.placements, copies, strict=True):
        first = together.copies[0]
        c, s = np.cos(np.radians(first.angle_deg)), np.sin(np.radians(first.angle_deg))
        rel = (copy.points_mm[placement.ids] - first.origin_mm) @ np.array([[c, -s], [s, c]])
        assert np.abs(placement.plane_mm - rel).max() < 0.05
    run = subprocess.run(
        [sys.executable, "-m", "planarcal", "calibrate", *map(str, paths), "--copies",
         "--turned", "--type", "chessboard", "--cols", "5", "--rows", "4", "--square", "20",
         "--origin-marker", "-o", str(tmp_path / "c.json"), "--json"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert len(json.loads(run.stdout)["placements"]) == 4


@pytest.mark.parametrize(
    ("edit", "says"),
    [
        (lambda p: p.update(reference=9), "reference must be a placement's index"),
        (lambda p: p.update(point_placement=p["point_placement"][:-1]), "point_placement"),
        (lambda p: p["items"][1].update(image_size_px=[640, 480]), "image size"),
        (lambda p: p["items"][1].update(angle_rad=float("nan")), "finite"),
        (lambda p: p["items"][0].update(points=999), "1 to the board's 42"),
        (lambda p: p.update(items=p["items"][:1]), "two placements or more"),
        (lambda p: p.pop("items"), "must be an object with reference, items"),
    ],
)
def test_a_malformed_placements_field_is_named(
    joint: Calibration, tmp_path: Path, edit: Callable[[dict[str, Any]], object], says: str
) -> None:
    data = joint.to_dict()
    edit(data["placements"])
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(data, allow_nan=True))
    with pytest.raises(CalibrationFileError, match=says):
        Calibration.load(path, trust_edits=True)
