"""The work cell's video (planarcal.synth.live_video, `planarcal demo --video`): written to a
real file, read back as `planarcal live` reads it, the board found where it is held, a
calibration from those frames checked against the video's own truth."""

from __future__ import annotations

import functools
import itertools
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from planarcal import cli
from planarcal.calib.calibration import Calibration
from planarcal.calib.detection import detect_board
from planarcal.calib.placement_set import detect_placement
from planarcal.errors import ArgumentError, BoardNotFoundError, CameraError
from planarcal.live.capture import Camera
from planarcal.live.objects import detect_objects
from planarcal.synth.live_video import BELT_SPEED_MM_S, LiveVideo, write_live_video

# Short holds keep the suite quick; the parts long enough for the conveyor to move them.
HOLD_S, PARTS_S = 0.3, 1.2


@pytest.fixture(scope="module")
def video(tmp_path_factory: pytest.TempPathFactory) -> tuple[LiveVideo, list[np.ndarray]]:
    path = tmp_path_factory.mktemp("live_video") / "cell.avi"
    made = write_live_video(path, hold_s=HOLD_S, parts_s=PARTS_S, seed=3)
    with Camera(path, width=1280, height=720) as camera:
        assert camera.resolution == (1280, 720)
        assert camera.frames_declared == made.frame_count
        frames = [camera.read() for _ in range(made.frame_count)]
        with pytest.raises(CameraError, match="ended"):
            camera.read()
    return made, frames


def test_the_video_has_the_frames_it_says(video: tuple[LiveVideo, list[np.ndarray]]) -> None:
    made, frames = video
    assert made.size == (1280, 720) and made.fps == 10.0
    assert all(f.shape == (720, 1280, 3) for f in frames)
    held = [p.frames for p in made.placements]
    assert [len(r) for r in held] == [3, 3, 3]
    # In order, apart (the board moves between them), and all before the parts.
    assert all(a.stop < b.start for a, b in itertools.pairwise(held))
    assert held[-1].stop < made.parts.first_frame
    assert made.frame_count - made.parts.first_frame == round(PARTS_S * made.fps)
    assert made.parts.table_mm.shape == (round(PARTS_S * made.fps), made.parts.count, 2)


def test_the_board_is_found_on_every_held_frame(
    video: tuple[LiveVideo, list[np.ndarray]],
) -> None:
    made, frames = video
    for p in made.placements:
        for f in p.frames:
            detection = detect_board(frames[f], made.board, turned=True)
            ids = np.asarray(detection.ids, np.intp)
            assert len(ids) == made.board.n_points
            err = np.hypot(*(detection.image_points - p.points_px[ids]).T)
            # Through the noise and Motion JPEG, each dot within a few hundredths of a pixel.
            assert np.sqrt(np.mean(err**2)) < 0.05, (p.name, f)


def test_no_board_while_the_parts_ride(video: tuple[LiveVideo, list[np.ndarray]]) -> None:
    made, frames = video
    for f in (made.parts.first_frame, made.frame_count - 1):
        with pytest.raises(BoardNotFoundError):
            detect_board(frames[f], made.board)


def test_a_calibration_from_the_held_frames_maps_the_parts_within_a_tenth_of_a_mm(
    video: tuple[LiveVideo, list[np.ndarray]],
) -> None:
    made, frames = video
    detections = [
        detect_placement(frames[p.frames[1]], made.board, p.index, 0, p.name, {})
        for p in made.placements
    ]
    cal = Calibration.from_detections(detections, reference=0)
    for p, fitted in zip(made.placements, cal.placements, strict=True):
        angle, offset = p.pose
        assert abs(fitted.angle_deg - angle) < 0.02
        assert np.hypot(*(np.array(fitted.offset_mm) - offset)) < 0.1
    parts = made.parts
    where = parts.in_area
    assert where.sum() >= 5 * len(parts.table_mm)  # parts in the work area on every frame
    mm = cal.image_to_world(parts.pixels_px[where])
    err = np.hypot(*(mm - parts.plane_mm[where]).T)
    assert err.max() < 0.1


def test_the_parts_move_and_are_where_the_truth_says(
    video: tuple[LiveVideo, list[np.ndarray]],
) -> None:
    made, frames = video
    parts = made.parts
    first, last = parts.first_frame, made.frame_count - 1
    # The conveyor moves them along the table's x (away from where it wraps round).
    step = parts.table_mm[parts.row(last)] - parts.table_mm[parts.row(first)]
    moved = np.abs(step[:, 0]) < 200.0
    assert np.allclose(step[moved, 1], 0.0)
    assert np.allclose(step[moved, 0], step[moved, 0][0]) and step[moved, 0][0] > 0.0
    assert step[moved, 0][0] <= BELT_SPEED_MM_S * PARTS_S
    # Each part wholly in view is found in its frame's image at the pixel the truth says, and
    # nothing is found where no part lies (a part cut by the image's edge is found off-centre).
    for f in (first, last):
        i = parts.row(f)
        found = np.array([o.centroid_px for o in detect_objects(frames[f])])
        whole = parts.pixels_px[i][parts.in_view[i]]
        assert len(whole) > 10
        assert np.linalg.norm(found[None] - whole[:, None], axis=2).min(axis=1).max() < 0.5
        everywhere = parts.pixels_px[i]
        assert np.linalg.norm(found[:, None] - everywhere[None], axis=2).min(axis=1).max() < 30


def test_the_arguments_are_checked(tmp_path: Path) -> None:
    with pytest.raises(ArgumentError, match=r"\.avi"):
        write_live_video(tmp_path / "cell.mp4")
    with pytest.raises(ArgumentError, match="placements"):
        write_live_video(tmp_path / "cell.avi", placements=0)
    with pytest.raises(ArgumentError, match="fps"):
        write_live_video(tmp_path / "cell.avi", fps=0.5)
    with pytest.raises(ArgumentError, match="hold_s"):
        write_live_video(tmp_path / "cell.avi", hold_s=-1.0)
    assert not (tmp_path / "cell.avi").exists()


def test_demo_video_writes_it_and_says_the_live_command(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # The demo's own video, shorter: the command's words and file are what is tested.
    short = functools.partial(write_live_video, hold_s=0.2, parts_s=0.3)
    monkeypatch.setattr("planarcal.commands.demo.write_live_video", short)
    path = tmp_path / "demo cell.avi"
    assert cli.main(["demo", "--video", str(path), "--board", "chessboard"]) == 0
    out = capsys.readouterr().out
    assert f"Wrote {path}" in out
    command = re.search(r"^  planarcal live (.*)$", out, re.MULTILINE)
    assert command, out
    assert command.group(1) == (
        f"--source '{path}' --calibration cell.json --type chessboard --cols 9 --rows 6 --square 20"
    )
    with Camera(path) as camera:
        assert camera.resolution == (1280, 720)
        still = camera.read()  # the board held at the middle
    # The options printed give the board that is in the video: calibrate finds it with them.
    image = tmp_path / "still.png"
    cv2.imwrite(str(image), still)
    options = command.group(1).split("cell.json ")[1].split()
    assert cli.main(["calibrate", str(image), "-o", str(tmp_path / "c.json"), *options]) == 0


def test_demo_video_refuses_what_it_cannot_write(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["demo", "--video", str(tmp_path / "cell.mp4")]) == 2
    assert ".avi" in capsys.readouterr().err
    video = str(tmp_path / "cell.avi")
    assert cli.main(["demo", "--video", video, "--report", str(tmp_path / "r")]) == 2
    assert "--report" in capsys.readouterr().err
    assert not (tmp_path / "cell.avi").exists()
