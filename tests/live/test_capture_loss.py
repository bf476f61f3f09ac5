"""Sources that lose frames, read through Camera, Tracker and `planarcal run`: video files
damaged in their first third (MJPEG in AVI and MPEG-4 in MP4, written by cv2.VideoWriter and
overwritten in place), a file truncated while it is read, a file given as a file:// URL, and
a real MJPEG stream on loopback whose server closes the connection (and then stops
listening). Every loss is counted under its own name, said on stderr while it happens, and a
run that delivered nothing exits 1."""

from __future__ import annotations

import contextlib
import json
import logging
import queue
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import cv2
import numpy as np
import pytest
from test_tracker import _run as run_command
from test_tracker import render_moving

import planarcal.live.tracker as tracker_module
from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.errors import CameraError
from planarcal.live.capture import Camera
from planarcal.live.capture_sources import MAX_UNDECODABLE_RUN
from planarcal.live.tracker import Tracker

# Every wait in these tests is bounded by this (s): a source that never ends fails the test.
WAIT_S = 60.0


@pytest.fixture(scope="module")
def calibration() -> Calibration:
    """The paper's camera calibrated from a rendered view of its board (1280 x 720)."""
    scene = synth.paper_scene(0).calibration
    return Calibration.from_detection(detect_board(scene.image, synth.PAPER_BOARD))


@pytest.fixture(scope="module")
def calibration_file(calibration: Calibration, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return calibration.save(tmp_path_factory.mktemp("calib") / "calib.json")


@pytest.fixture(scope="module")
def scenes() -> list[np.ndarray]:
    """Four frames of three parts, 1280 x 720 grey (repeated to make longer videos)."""
    return [render_moving(k).image for k in range(4)]


def small_frame(i: int) -> np.ndarray:
    """Frame i of a small test clip: a grey level and a white bar that move with i."""
    frame = np.full((120, 160, 3), (7 * i) % 200, np.uint8)
    frame[40:60, i % 140 : i % 140 + 20] = 255
    return frame


def write_video(path: Path, frames: list[np.ndarray], fourcc: str) -> Path:
    color = frames[0].ndim == 3
    height, width = frames[0].shape[:2]
    writer = cv2.VideoWriter(
        str(path), cv2.VideoWriter.fourcc(*fourcc), 30.0, (width, height), color
    )
    assert writer.isOpened(), f"OpenCV cannot write {fourcc} here"
    for frame in frames:
        writer.write(frame)
    writer.release()
    return path


def damage(path: Path, at: float, size: int) -> None:
    """Zeroes `size` bytes of the file in place: in an MJPEG file from the header of the
    JPEG at `at` (a fraction) of the frames on, which its decoder cannot get past; in any
    other from `at` of the file's length on."""
    data = bytearray(path.read_bytes())
    starts = [m.start() + 2 for m in re.finditer(b"\xff\xd8\xff", data)]
    start = starts[int(len(starts) * at)] if starts else int(len(data) * at)
    data[start : start + size] = bytes(size)
    path.write_bytes(bytes(data))


def opencv_count(path: Path) -> int:
    """The frames OpenCV itself decodes from the file when it retries grab() past failures
    (as many times in a row as Camera does): the reference for a damaged file."""
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    decoded = failed = 0
    while failed < MAX_UNDECODABLE_RUN:
        ok, frame = cap.read()
        if ok and frame is not None:
            decoded, failed = decoded + 1, 0
        else:
            failed += 1
    cap.release()
    return decoded


def plain_count(path: Path) -> int:
    """The frames cv2.VideoCapture.read() gives before its first failure."""
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    return n


def summary(stderr: str) -> dict[str, Any]:
    line = next(x for x in reversed(stderr.splitlines()) if x.startswith("planarcal run: {"))
    figures: dict[str, Any] = json.loads(line.split("planarcal run: ", 1)[1])
    return figures


# -- damaged and truncated files ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("fourcc", "suffix", "size"), [("MJPG", ".avi", 512), ("mp4v", ".mp4", 4096)]
)
def test_a_video_damaged_in_its_first_third_is_read_past_the_damage(
    tmp_path: Path, fourcc: str, suffix: str, size: int
) -> None:
    n = 300
    path = write_video(tmp_path / f"clip{suffix}", [small_frame(i) for i in range(n)], fourcc)
    damage(path, 0.1, size)
    reference = opencv_count(path)
    # The damage stops a plain read() loop in the first third; OpenCV can go on past it.
    assert plain_count(path) < n // 3 < n - 20 < reference
    with Camera(path) as cam:
        frames = list(cam.frames())
        assert cam.ended and cam.frames_declared == n
        assert len(frames) == cam.frames_read == reference
        assert 1 <= cam.frames_undecodable <= n - reference
    # The frames after the damage are the video's own, up to its last.
    for k in (1, 2, 3):
        gap = np.abs(frames[-k].astype(int) - small_frame(n - k)).mean()
        assert gap < 8, (k, gap)


def test_run_on_a_damaged_video_processes_what_opencv_decodes_and_says_what_it_skipped(
    calibration_file: Path, scenes: list[np.ndarray], tmp_path: Path
) -> None:
    n = 120
    path = write_video(tmp_path / "parts.avi", [scenes[k % 4] for k in range(n)], "MJPG")
    damage(path, 0.2, 4096)
    reference = opencv_count(path)
    assert plain_count(path) < n // 3 and reference > n - 10
    out = tmp_path / "out.jsonl"
    result = run_command("--source", path, "--calibration", calibration_file, "--output", out)
    assert result.returncode == 0, result.stderr
    figures = summary(result.stderr)
    assert figures["frames"] == reference == len(out.read_text().splitlines())
    assert figures["frames_undecodable"] >= 1 and figures["frames_declared"] == n
    assert figures["read"] == figures["frames"] + figures["frames_undecodable"]
    # What FFmpeg passed over without a failed read for each frame is counted at the end.
    assert figures["read"] + figures["frames_missing"] == n
    # Said while it happened, with the frames' numbers.
    assert re.search(r"could not be decoded \(frames? \d+", result.stderr), result.stderr
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert all(len(x["objects"]) == 3 for x in lines)
    # The frame numbers skip the undecodable ones and keep their places in the file.
    numbers = [x["frame"] for x in lines]
    assert numbers == sorted(numbers) and numbers[-1] == figures["read"] - 1


def test_a_file_url_is_a_file_read_to_its_end(
    calibration_file: Path, scenes: list[np.ndarray], tmp_path: Path
) -> None:
    path = write_video(tmp_path / "parts.avi", [scenes[k % 4] for k in range(12)], "MJPG")
    with Camera(path.as_uri()) as cam:
        assert not cam.live and cam.label == f"video file {str(path)!r}"
        assert len(list(cam.frames())) == 12 and cam.ended
    result = subprocess.run(
        [
            *(sys.executable, "-m", "planarcal", "run"),
            *("--source", path.as_uri(), "--calibration", str(calibration_file)),
        ],
        capture_output=True,
        text=True,
        timeout=WAIT_S,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    figures = summary(result.stderr)
    assert figures["frames"] == 12 and figures["read"] == 12
    assert figures["camera_lost"] == 0 and figures["frames_undecodable"] == 0
    assert len(result.stdout.splitlines()) == 12


def test_a_video_truncated_while_it_is_read_ends_and_says_so(
    calibration: Calibration,
    scenes: list[np.ndarray],
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
) -> None:
    n = 60
    path = write_video(tmp_path / "parts.avi", [scenes[k % 4] for k in range(n)], "MJPG")
    size = path.stat().st_size
    results = []
    with (
        caplog.at_level(logging.WARNING, logger="planarcal.live.tracker"),
        Tracker(calibration, path) as t,
    ):
        for r in t:
            results.append(r)
            if len(results) == 3:
                with path.open("r+b") as f:  # cut to its first 40 %, under the reader
                    f.truncate(int(size * 0.4))
    assert 3 <= len(results) < n and t.stats.frames_declared == n
    assert t.stats.read + t.stats.frames_missing == n and t.stats.frames_missing > 0
    assert f"of the {n} frames its header declares: {t.stats.frames_missing} more" in caplog.text
    assert "truncated" in caplog.text


# -- a stream whose server goes away -------------------------------------------------------------


def mjpeg_part(image: np.ndarray) -> bytes:
    ok, jpg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert ok
    data = jpg.tobytes()
    head = b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n" % len(data)
    return head + data + b"\r\n"


class StreamServer:
    """An MJPEG-over-HTTP camera on 127.0.0.1: each of its first `sessions` connections
    gets `per_session` frames, then the server closes it; after those it stops listening
    (connection refused), as a camera that was unplugged."""

    def __init__(self, images: list[np.ndarray], per_session: int, sessions: int) -> None:
        self.parts = [mjpeg_part(image) for image in images]
        self.per_session, self.sessions = per_session, sessions
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.settimeout(0.1)
        self.port = self.listener.getsockname()[1]
        self.url = f"http://127.0.0.1:{self.port}/video.mjpg"
        self.served = 0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while not self.stop.is_set() and self.served < self.sessions:
            try:
                conn, _ = self.listener.accept()
            except OSError:
                continue
            with conn, contextlib.suppress(OSError):
                conn.settimeout(WAIT_S)
                conn.recv(65536)
                conn.sendall(
                    b"HTTP/1.0 200 OK\r\n"
                    b"Content-Type: multipart/x-mixed-replace; boundary=frame\r\n\r\n"
                )
                for k in range(self.per_session):
                    conn.sendall(self.parts[k % len(self.parts)])
            self.served += 1
        self.listener.close()

    def close(self) -> None:
        self.stop.set()
        self.thread.join(WAIT_S)


@contextlib.contextmanager
def stream_server(
    images: list[np.ndarray], per_session: int, sessions: int
) -> Iterator[StreamServer]:
    server = StreamServer(images, per_session, sessions)
    try:
        yield server
    finally:
        server.close()


def test_a_stream_whose_server_closes_is_closed_and_reopened_with_back_off(
    calibration: Calibration,
    scenes: list[np.ndarray],
    caplog: pytest.LogCaptureFixture,
) -> None:
    with stream_server(scenes, per_session=5, sessions=1) as server:
        cam = Camera(server.url, timeout_s=5.0)
        got = [cam.read() for _ in range(5)]
        assert len(got) == 5
        # The server closed the connection: the Camera says so, and is closed (released).
        with pytest.raises(CameraError, match="stopped delivering after 5 frames"):
            cam.read()
        assert cam.closed
        with pytest.raises(CameraError, match="is closed"):
            cam.read()
    with (
        stream_server(scenes, per_session=4, sessions=3) as server,
        caplog.at_level(logging.WARNING, logger="planarcal.live.tracker"),
        Tracker(calibration, server.url, max_frames=10) as t,
    ):
        results = list(t)
    s = t.stats
    # 4 frames from each of three connections: lost twice, reopened twice; no frame was
    # counted as corrupt while the stream was down.
    assert (s.read, s.camera_lost, s.camera_reconnects) == (10, 2, 2)
    assert len(results) + s.frames_dropped == 10
    assert s.frames_undecodable == s.frames_wrong_size == s.failed == 0
    assert s.camera_down_s > 0
    assert all(len(r.objects) == 3 for r in results)
    assert (
        caplog.text.count("camera lost: ") == 2 and "reopening in 0.1 s (attempt 1)" in caplog.text
    )
    assert caplog.text.count("open again after") == 2
    # The tracker reopens the camera itself: its warnings do not tell the user to.
    assert "open a new one" not in caplog.text


class Stderr:
    """A subprocess's stderr, line by line, read on a thread (every wait bounded)."""

    def __init__(self, stream: IO[str]) -> None:
        self.lines: queue.Queue[str] = queue.Queue()
        self.text: list[str] = []
        self.thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self.thread.start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            self.lines.put(line)

    def wait_for(self, needle: str) -> str:
        """The first line (from here on) that holds `needle`; queue.Empty if none comes
        within WAIT_S."""
        deadline = time.monotonic() + WAIT_S
        while True:
            line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            self.text.append(line)
            if needle in line:
                return line

    def rest(self) -> str:
        self.thread.join(WAIT_S)
        while not self.lines.empty():
            self.text.append(self.lines.get())
        return "".join(self.text)


def start_run(*args: object) -> tuple[subprocess.Popen[str], Stderr]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "planarcal", "run", *map(str, args)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stderr is not None
    return proc, Stderr(proc.stderr)


def stop_run(proc: subprocess.Popen[str], stderr: Stderr) -> str:
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=WAIT_S)
    return stderr.rest()


def test_a_trigger_while_the_camera_is_down_is_answered_at_once(
    calibration_file: Path, scenes: list[np.ndarray]
) -> None:
    with stream_server(scenes, per_session=6, sessions=1) as server:
        proc, stderr = start_run(
            "--source",
            server.url,
            "--calibration",
            calibration_file,
            "-o",
            "tcp-listen://127.0.0.1:0",
            "--trigger",
            "--trigger-timeout",
            3600,
        )
        try:
            address = stderr.wait_for("listening on").split("listening on ")[1].split(";")[0]
            host, port = address.rsplit(":", 1)
            # The stream closes after its 6 frames and the server stops listening.
            lost = stderr.wait_for("camera lost: ")
            assert "stopped delivering after 6 frames" in lost and "reopening in" in lost
            stderr.wait_for("reopening in")  # an attempt failed: it is down for good
            with socket.create_connection((host, int(port)), timeout=WAIT_S) as robot:
                robot.sendall(b"TRIGGER\n")
                answer = robot.makefile().readline()
        finally:
            text = stop_run(proc, stderr)
    # Not after the trigger timeout (an hour): at once, saying why.
    assert "camera down for " in answer and "not delivering frames" in answer, answer
    assert "reopening it" in answer
    assert proc.returncode == 0, text  # 6 frames were delivered
    figures = summary(text)
    assert figures["frames"] + figures["frames_dropped"] == figures["read"] == 6
    assert figures["camera_lost"] == 1 and figures["camera_reconnects"] == 0
    assert figures["camera_down_s"] > 0 and figures["frames_undecodable"] == 0


def test_a_run_that_delivered_nothing_exits_1(calibration_file: Path) -> None:
    # Nothing listens on that port: the camera never comes; the run is stopped.
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    proc, stderr = start_run(
        "--source", f"http://127.0.0.1:{port}/video", "--calibration", calibration_file
    )
    try:
        stderr.wait_for("camera down: ")
        line = stderr.wait_for("reopening in")
        assert "(attempt 2)" in line
    finally:
        text = stop_run(proc, stderr)
    assert proc.returncode == 1, text
    figures = summary(text)
    assert figures["frames"] == 0 and figures["camera_down_s"] > 0
    assert "error: no frame was delivered: 0 frames read; the camera was down" in text


def free_port() -> int:
    """A loopback port that nothing listens on."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
    return port


def reopen_waits(log: str) -> list[float]:
    """The waits announced by 'reopening in X s' warnings, in order."""
    return [float(x) for x in re.findall(r"reopening in ([0-9.]+) s", log)]


def test_the_back_off_doubles_up_to_its_maximum_and_max_reconnect_gives_up(
    calibration: Calibration, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tracker_module, "REOPEN_MAX_S", 0.4)
    monkeypatch.setattr(tracker_module, "REOPEN_REPORT_S", 0.0)  # report every attempt
    t = Tracker(calibration, f"http://127.0.0.1:{free_port()}/video", max_reconnect_s=2.0)
    with (
        caplog.at_level(logging.WARNING, logger="planarcal.live.tracker"),
        pytest.raises(CameraError, match="gave up reopening") as gave_up,
    ):
        list(t)
    # The wait doubles to its maximum and stays there: 0.1, 0.2, 0.4, 0.4, ... s.
    waits = reopen_waits(caplog.text)
    assert waits[:2] == [0.2, 0.4] and set(waits[2:]) == {0.4}, waits
    attempts = int(re.findall(r"\((\d+) attempts\)", str(gave_up.value))[0])
    assert attempts == len(waits) + 1 >= 4, gave_up.value
    assert t.stats.frames == 0 and t.stats.camera_down_s >= 2.0


def test_a_stream_that_fails_again_at_once_is_reopened_ever_more_slowly(
    calibration: Calibration, scenes: list[np.ndarray], caplog: pytest.LogCaptureFixture
) -> None:
    # Each connection gives one frame and closes: without a growing wait this would be a
    # tight open-fail cycle.
    with (
        stream_server(scenes, per_session=1, sessions=5) as server,
        caplog.at_level(logging.WARNING, logger="planarcal.live.tracker"),
        Tracker(calibration, server.url, max_frames=5) as t,
    ):
        results = list(t)
    assert len(results) + t.stats.frames_dropped == 5
    assert (t.stats.camera_lost, t.stats.camera_reconnects) == (4, 4)
    assert reopen_waits(caplog.text) == [0.1, 0.2, 0.4, 0.8]
