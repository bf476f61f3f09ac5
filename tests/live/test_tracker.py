"""The production loop: a real video file of a rendered scene with moving objects at known
positions, an image folder with a corrupt frame, a camera that drops out (fault injection
around a real Camera), stopping from another thread, and 10,000 frames without memory
growth."""

from __future__ import annotations

import gc
import json
import logging
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

import planarcal.live.tracker as tracker_module
from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.errors import ArgumentError, CameraError, IntrinsicsError, StateError
from planarcal.homography import transform_points
from planarcal.live.capture import Camera
from planarcal.live.tracker import FrameResult, Tracker
from scene_effects import PAPER_EFFECTS

N_FRAMES = 24

# The video fixture: the file, each frame's truth (frames x 3 x 2, mm), the frames.
Video = tuple[Path, np.ndarray, list[np.ndarray]]


def moving_objects(k: int) -> list[synth.SceneObject]:
    """Three parts moving across the table, frame k."""
    return [
        synth.SceneObject("nut", (40.0 + 2.0 * k, 40.0), angle_deg=3.0 * k, size_mm=8.0),
        synth.SceneObject("washer", (200.0, 60.0 + 1.5 * k), size_mm=8.0),
        synth.SceneObject("disc", (130.0 - 1.0 * k, 150.0), size_mm=12.0),
    ]


def write_video(path: Path, frames: list[np.ndarray]) -> Path:
    """A real video file (MJPEG in AVI, near-lossless, grey) of `frames`."""
    height, width = frames[0].shape[:2]
    writer = cv2.VideoWriter(
        str(path), cv2.VideoWriter.fourcc(*"MJPG"), 30.0, (width, height), False
    )
    writer.set(cv2.VIDEOWRITER_PROP_QUALITY, 100)
    for frame in frames:
        writer.write(frame)
    writer.release()
    return path


def render_moving(k: int) -> synth.RenderedScene:
    """Frame k of the moving parts, seen by the paper's camera (1280 x 720)."""
    return synth.render_scene(
        synth.PAPER_CAMERA,
        synth.PAPER_POSE,
        board=None,
        objects=moving_objects(k),
        seed=k,
        **PAPER_EFFECTS,
    )


@pytest.fixture(scope="module")
def calibration() -> Calibration:
    scene = synth.paper_scene(0).calibration
    return Calibration.from_detection(detect_board(scene.image, synth.PAPER_BOARD))


@pytest.fixture(scope="module")
def video(tmp_path_factory: pytest.TempPathFactory) -> Video:
    """A real video file (MJPEG in AVI, near-lossless) of the moving parts, the truth of each
    frame (frames x 3 x 2, mm) and the frames themselves."""
    scenes = [render_moving(k) for k in range(N_FRAMES)]
    frames = [scene.image for scene in scenes]
    path = write_video(tmp_path_factory.mktemp("video") / "moving.avi", frames)
    return path, np.array([scene.object_centroids_mm for scene in scenes]), frames


def check_tracks(results: list[FrameResult], truth: np.ndarray, tol_mm: float) -> None:
    """Every object within tol of a true one, and each ID always the same true object."""
    owner: dict[int, int] = {}
    for r in results:
        assert len(r.objects) == 3, r
        for o in r.objects:
            gap = np.hypot(*(truth[r.index] - np.array(o.world_mm)).T)
            j = int(gap.argmin())
            assert gap[j] < tol_mm, (r.index, o)
            assert owner.setdefault(o.id, j) == j, f"ID {o.id} jumped objects at {r.index}"
    assert sorted(owner) == [1, 2, 3]


def test_objects_are_tracked_in_millimetres_through_a_video(
    calibration: Calibration, video: Video
) -> None:
    path, truth, _ = video
    with Tracker(calibration, path) as t:
        results = list(t)
    assert [r.index for r in results] == list(range(N_FRAMES))
    check_tracks(results, truth, 0.15)
    s = t.stats
    assert (s.frames, s.objects, s.frames_undecodable, s.failed, s.frames_dropped) == (
        N_FRAMES,
        3 * N_FRAMES,
        0,
        0,
        0,
    )
    # 1-sigma of a located part: the outline's centroid error (0.03 px, about 0.02 mm here)
    # with the calibration's own.
    assert all(0.01 < o.std_mm < 0.05 for r in results for o in r.objects)
    assert set(s.stage_s) == {"read", "detect", "map", "track"}
    # Each frame's JSON line parses back to what it says.
    line = json.loads(results[3].to_json())
    assert line["frame"] == 3 and [o["id"] for o in line["objects"]] == [1, 2, 3]


def test_max_frames_and_a_tracker_iterates_once(calibration: Calibration, video: Video) -> None:
    path, _, _ = video
    t = Tracker(calibration, path, max_frames=5)
    assert len(list(t)) == 5
    with pytest.raises(StateError, match="once"):
        list(t)
    with pytest.raises(ArgumentError, match="max_jump_mm"):
        Tracker(calibration, path, max_jump_mm=0)
    with pytest.raises(ArgumentError, match=r"unknown detect_options \['min_aera'\]"):
        Tracker(calibration, path, detect_options={"min_aera": 5})
    # Live tracks after the run: the three parts, at their last positions.
    assert sorted(t.tracks) == [1, 2, 3]
    assert all(len(p) == 2 for p in t.tracks.values())


def test_a_height_without_intrinsics_is_refused_before_the_first_frame(
    calibration: Calibration, video: Video
) -> None:
    path, _, _ = video
    # Not counted frame after frame as a failure: no frame could ever succeed.
    with pytest.raises(IntrinsicsError, match="needs camera intrinsics"):
        Tracker(calibration, path, height_mm=20.0)


def test_a_corrupt_frame_in_a_folder_is_counted_and_skipped(
    calibration: Calibration, video: Video, tmp_path: Path
) -> None:
    _, truth, frames = video
    for k, frame in enumerate(frames[:8]):
        cv2.imwrite(str(tmp_path / f"frame{k:03d}.png"), frame)
    # Frame 4 is damaged on disk: a truncated PNG.
    damaged = tmp_path / "frame004.png"
    damaged.write_bytes(damaged.read_bytes()[:2000])
    with Tracker(calibration, tmp_path) as t:
        results = list(t)
    assert [r.index for r in results] == [0, 1, 2, 3, 5, 6, 7]
    assert t.stats.frames_undecodable == 1 and t.last_error is not None
    check_tracks(results, truth, 0.15)


def test_max_frames_counts_the_frames_read_failed_ones_too(
    calibration: Calibration, video: Video, tmp_path: Path
) -> None:
    _, truth, frames = video
    for k, frame in enumerate(frames[:8]):
        cv2.imwrite(str(tmp_path / f"frame{k:03d}.png"), frame)
    for k in (2, 3):  # damaged on disk: truncated PNGs
        damaged = tmp_path / f"frame{k:03d}.png"
        damaged.write_bytes(damaged.read_bytes()[:2000])
    with Tracker(calibration, tmp_path, max_frames=5) as t:
        results = list(t)
    # The first five frames of the source, not five good ones.
    assert [r.index for r in results] == [0, 1, 4]
    s = t.stats
    assert (s.read, s.frames, s.frames_undecodable, s.failed) == (5, 3, 2, 0)
    assert t.first_error is not None and "frame003" not in str(t.first_error)
    assert t.last_error is not None and "frame003" in str(t.last_error)
    check_tracks(results, truth, 0.15)


class FlakyCamera:
    """A real Camera on a video file that behaves like a live camera which is unplugged after
    `fail_after` frames (its reads then raise and it closes), and whose first `refuse`
    reopenings fail: fault injection around the real capture path."""

    opened = 0
    refuse = 2

    def __init__(self, source: Any, *, timeout_s: float = 5.0, color: bool = True) -> None:
        FlakyCamera.opened += 1
        if 1 < FlakyCamera.opened <= 1 + FlakyCamera.refuse:
            raise CameraError(f"{source}: no such device (injected)")
        self.inner = Camera(source, timeout_s=timeout_s, color=color)
        self.resolution = self.inner.resolution
        self.source = source
        self.label = str(source)
        self.live = True
        self.ended = False
        self.closed = False
        self.fail_after = 6 if FlakyCamera.opened == 1 else 10**9
        self.reads = 0

    def read(self) -> Any:
        if self.reads >= self.fail_after:
            self.closed = True
            self.inner.close()
            raise CameraError("camera stopped delivering (injected)")
        self.reads += 1
        try:
            return self.inner.read()
        except CameraError:
            self.ended = self.inner.ended
            raise

    def close(self) -> None:
        self.closed = True
        self.inner.close()


def test_a_camera_that_drops_out_is_reopened_with_back_off(
    calibration: Calibration, video: Video, monkeypatch: pytest.MonkeyPatch
) -> None:
    path, truth, _ = video
    FlakyCamera.opened = 0
    monkeypatch.setattr(tracker_module, "Camera", FlakyCamera)
    # max_frames counts the frames read: those a live source drops when the loop is behind
    # (the reader decodes this file faster than the loop takes frames) count too.
    with Tracker(calibration, str(path), max_frames=20) as t:
        results = list(t)
    assert t.stats.camera_reconnects == 1 and FlakyCamera.opened == 4
    assert t.stats.read == 20 and len(results) + t.stats.frames_dropped == 20
    # The reopened camera starts its video from the beginning: indices go on counting.
    assert [r.index for r in results[:6]] == list(range(6))
    for r in results:
        gaps = [np.hypot(*(truth - np.array(o.world_mm)).T.reshape(2, -1)).min() for o in r.objects]
        assert max(gaps) < 0.15


def test_giving_up_on_a_source_that_stays_away(
    calibration: Calibration, video: Video, monkeypatch: pytest.MonkeyPatch
) -> None:
    path, _, _ = video
    FlakyCamera.opened = 0
    monkeypatch.setattr(FlakyCamera, "refuse", 10**6)
    monkeypatch.setattr(tracker_module, "Camera", FlakyCamera)
    t = Tracker(calibration, str(path), max_reconnect_s=0.5)
    with pytest.raises(CameraError, match="gave up reopening"):
        list(t)
    assert t.stats.frames == 6


class LateCamera(FlakyCamera):
    """A live stream that is not there for its first `absent` openings, then is (and stays):
    a real Camera on the test video behind a made-up URL (fault injection at start)."""

    absent = 3
    target = ""

    def __init__(self, source: Any, *, timeout_s: float = 5.0, color: bool = True) -> None:
        LateCamera.opened += 1
        if LateCamera.opened <= LateCamera.absent:
            raise CameraError(f"{source}: connection refused (injected)")
        self.inner = Camera(LateCamera.target, timeout_s=timeout_s, color=color)
        self.resolution = self.inner.resolution
        self.source = self.label = source
        self.live = True
        self.ended = self.closed = False
        self.fail_after, self.reads = 10**9, 0


def test_a_stream_absent_at_start_is_waited_for(
    calibration: Calibration,
    video: Video,
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
    tmp_path: Path,
) -> None:
    path, truth, _ = video
    LateCamera.opened, LateCamera.target = 0, str(path)
    monkeypatch.setattr(tracker_module, "Camera", LateCamera)
    source = "rtsp://camera.invalid/parts"
    with (
        caplog.at_level(logging.WARNING, logger="planarcal.live.tracker"),
        Tracker(calibration, source, max_frames=5) as t,
    ):
        results = list(t)
    assert len(results) == 5 and LateCamera.opened == 4
    # Waiting at start is not a reconnection; each failed attempt is logged.
    assert t.stats.camera_reconnects == 0
    assert "camera down: " in caplog.text and "waiting for it" in caplog.text
    assert caplog.text.count("reopening in") == 2 and "(attempt 3)" in caplog.text
    assert "open after" in caplog.text and t.stats.camera_down_s > 0
    for r in results:
        gaps = [np.hypot(*(truth - np.array(o.world_mm)).T.reshape(2, -1)).min() for o in r.objects]
        assert max(gaps) < 0.15
    # A file that is not there is a mistake, not a camera still booting: it fails at once.
    monkeypatch.undo()
    with pytest.raises(CameraError):
        Tracker(calibration, tmp_path / "missing.mp4")


def test_stop_from_another_thread_ends_the_loop_cleanly(
    calibration: Calibration, video: Video
) -> None:
    path, _, _ = video
    t = Tracker(calibration, path)
    seen = []
    for r in t:
        seen.append(r.index)
        if r.index == 2:
            threading.Thread(target=t.stop).start()
            threading.Event().wait(0.3)
    assert 3 <= len(seen) <= 5 and seen == list(range(len(seen)))


def _rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc (Linux)")
def test_ten_thousand_frames_without_memory_growth(tmp_path: Path) -> None:
    # A small camera keeps the run short: 160 x 120, two parts, a 20-frame clip looped to
    # 10,000 frames in the video file.
    cam = synth.CameraModel(width=160, height=120, focal_px=150.0)
    pose = synth.PlanePose(500.0, look_at_mm=(130.0, 90.0))
    board = synth.PAPER_BOARD
    world = board.world_points()
    cal = Calibration(world, cam.project(world, pose), image_size=(160, 120), lens="none")
    clip = []
    for k in range(20):
        objs = [
            synth.SceneObject("disc", (60.0 + 3 * k, 60.0), size_mm=40.0),
            synth.SceneObject("disc", (200.0, 40.0 + 3 * k), size_mm=40.0),
        ]
        clip.append(synth.render_scene(cam, pose, board=None, objects=objs, seed=k).image)
    path = tmp_path / "long.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 30.0, (160, 120), False)
    for k in range(10_000):
        writer.write(clip[k % 20])
    writer.release()
    samples = []
    with Tracker(cal, path, detect_options={"min_area_px": 50.0}) as t:
        for r in t:
            if r.index in (1_000, 5_000, 9_999):
                gc.collect()
                samples.append(_rss_bytes())
    assert t.stats.frames == 10_000 and t.stats.objects == 20_000
    assert len(t.tracks) <= 2 + 2 * (t.max_missing + 1)
    growth = samples[-1] - samples[0]
    assert growth < 4 * 2**20, [s / 2**20 for s in samples]


# ------------------------------------------------------------------------------------------
# planarcal run: the command, its outputs, and its signals


def _run(*args: Any, **kwargs: Any) -> Any:
    return subprocess.run(
        [sys.executable, "-m", "planarcal", "run", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        **kwargs,
    )


def _lines(text: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def _check_lines(lines: list[dict[str, Any]], truth: np.ndarray, tol_mm: float) -> None:
    owner: dict[int, int] = {}
    for line in lines:
        k = line["frame"]
        assert len(line["objects"]) == 3
        for o in line["objects"]:
            gap = np.hypot(*(truth[k] - np.array(o["mm"])).T)
            j = int(gap.argmin())
            assert gap[j] < tol_mm and owner.setdefault(o["id"], j) == j
            assert 0.01 < o["std_mm"] < 0.05


def test_run_writes_one_line_per_frame_to_a_file_and_stdout(
    calibration: Calibration, video: Video, tmp_path: Path
) -> None:
    path, truth, _ = video
    calib = calibration.save(tmp_path / "calib.json")
    out = tmp_path / "positions.jsonl"
    result = _run("--source", path, "--calibration", calib, "--output", out, "--fps-report")
    assert result.returncode == 0, result.stderr
    lines = _lines(out.read_text())
    assert [line["frame"] for line in lines] == list(range(N_FRAMES))
    _check_lines(lines, truth, 0.15)
    assert "fps" in result.stderr and "detect" in result.stderr  # the stage report
    summary = result.stderr.split("planarcal run: ", 1)[1]

    figures = json.loads(summary)
    assert figures["frames"] == N_FRAMES and figures["output"]["sent"] == N_FRAMES
    assert figures["output"]["dropped"] == 0
    # stdout, limited to 5 frames; the progress line stays off when stderr is not a terminal.
    result = _run("--source", path, "--calibration", calib, "--max-frames", 5)
    assert result.returncode == 0, result.stderr
    _check_lines(_lines(result.stdout), truth, 0.15)
    assert len(_lines(result.stdout)) == 5 and "\r" not in result.stderr


def test_run_sends_to_a_tcp_controller_on_loopback(
    calibration: Calibration, video: Video, tmp_path: Path
) -> None:
    path, truth, _ = video
    calib = calibration.save(tmp_path / "calib.json")
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    received: list[bytes] = []

    def controller() -> None:
        conn, _ = server.accept()
        with conn:
            while chunk := conn.recv(65536):
                received.append(chunk)

    reader = threading.Thread(target=controller, daemon=True)
    reader.start()
    result = _run("--source", path, "--calibration", calib, "--output", f"tcp://127.0.0.1:{port}")
    assert result.returncode == 0, result.stderr
    reader.join(timeout=10)
    server.close()
    lines = _lines(b"".join(received).decode())
    # The controller connects while the first frames go out: those are dropped, not queued
    # (a robot wants fresh positions); every line that arrives is whole and in order.
    assert len(lines) >= N_FRAMES // 2
    first = lines[0]["frame"]
    assert [line["frame"] for line in lines] == list(range(first, first + len(lines)))
    _check_lines(lines, truth, 0.15)

    figures = json.loads(result.stderr.split("planarcal run: ", 1)[1])
    assert figures["output"]["sent"] + figures["output"]["dropped"] == N_FRAMES


def test_run_stops_cleanly_on_sigterm_and_bad_arguments_are_named(
    calibration: Calibration, tmp_path: Path
) -> None:
    calib = calibration.save(tmp_path / "calib.json")
    # A long source: 3,000 frames of one rendered scene.
    scene = synth.render_scene(
        synth.PAPER_CAMERA,
        synth.PAPER_POSE,
        board=None,
        objects=moving_objects(0),
        **PAPER_EFFECTS,
    )
    path = tmp_path / "long.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 30.0, (1280, 720), False)
    for _ in range(3000):
        writer.write(scene.image)
    writer.release()
    out = tmp_path / "out.jsonl"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "planarcal",
            "run",
            "--source",
            str(path),
            "--calibration",
            str(calib),
            "--output",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and (not out.exists() or out.stat().st_size < 2000):
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 0, stderr
    figures = json.loads(stderr.split("planarcal run: ", 1)[1])
    assert figures["stopped_by"] == "SIGTERM" and 0 < figures["frames"] < 3000
    lines = _lines(out.read_text())  # every line complete: the file was flushed
    assert len(lines) == figures["frames"] == figures["output"]["sent"]
    bad = _run("--source", path, "--calibration", calib, "--output", "tcp://nohost")
    assert bad.returncode == 2 and "port" in bad.stderr  # 2: a malformed command line
    bad = _run("--source", tmp_path / "missing.mp4", "--calibration", calib)
    assert bad.returncode == 1 and "missing.mp4" in bad.stderr


def test_run_max_frames_counts_the_frames_read(
    calibration: Calibration, video: Video, tmp_path: Path
) -> None:
    _, truth, frames = video
    folder = tmp_path / "frames"
    folder.mkdir()
    for k, frame in enumerate(frames[:8]):
        cv2.imwrite(str(folder / f"frame{k:03d}.png"), frame)
    damaged = folder / "frame001.png"
    damaged.write_bytes(damaged.read_bytes()[:2000])
    calib = calibration.save(tmp_path / "calib.json")
    result = _run("--source", folder, "--calibration", calib, "--max-frames", 4)
    assert result.returncode == 0, result.stderr
    lines = _lines(result.stdout)
    assert [line["frame"] for line in lines] == [0, 2, 3]
    _check_lines(lines, truth, 0.15)
    figures = json.loads(result.stderr.rsplit("planarcal run: ", 1)[1])
    assert (figures["read"], figures["frames"], figures["frames_undecodable"]) == (4, 3, 1)
    assert "frame001.png" in figures["first_fault"]


def test_run_whose_every_frame_fails_exits_1_with_the_reason(video: Video, tmp_path: Path) -> None:
    path, _, _ = video
    # A calibration from another camera position: its horizon crosses these frames at
    # y = 400 px, and one of the parts is always below it (it sees no point of the plane
    # there), so every frame fails.
    h = np.array([[2.0, 0.0, 400.0], [0.0, 2.0, 100.0], [0.0, 0.005, 1.0]])
    world = synth.PAPER_BOARD.world_points()
    wrong = Calibration(world, transform_points(h, world), image_size=(1280, 720), lens="none")
    calib = wrong.save(tmp_path / "wrong.json")
    result = _run("--source", path, "--calibration", calib, "--max-frames", 6)
    assert result.returncode == 1, result.stderr
    assert result.stdout == ""
    error = result.stderr.strip().splitlines()[-1]
    assert error.startswith("planarcal run: error: every frame failed: 6 of the 6 frames read")
    assert "0 undecodable, 0 of the wrong size, 6 failed in detection" in error
    assert "first fault: " in error and "horizon" in error
    summary = next(
        line for line in result.stderr.splitlines() if line.startswith("planarcal run: {")
    )
    figures = json.loads(summary.split("planarcal run: ", 1)[1])
    assert (figures["read"], figures["frames"], figures["failed"]) == (6, 0, 6)
    # Without --max-frames the file is read to its end: the same verdict.
    result = _run("--source", path, "--calibration", calib)
    assert result.returncode == 1
    assert f"every frame failed: {N_FRAMES} of the {N_FRAMES} frames read" in result.stderr
