"""planarcal.live.capture.Camera on real files written here: a short MJPG video, folders of PNGs,
corrupt and missing inputs, and loopback-only network sources (refused, silent, stalling) that
must fail within timeout_s plus a margin, never hang. No camera is needed: device 99 must
fail promptly."""

from __future__ import annotations

import contextlib
import gc
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from planarcal.errors import ArgumentError, ArgumentTypeError, CameraError
from planarcal.live.capture import BACKEND_GRACE_S, Camera

W, H = 80, 64
N_FRAMES = 12
SQUARE = 8
# Loopback only; nothing listens on the discard port.
REFUSED_URLS = ["rtsp://127.0.0.1:9/", "http://127.0.0.1:9/"]
TIMEOUT_S = 1.0
MARGIN_S = 1.5


def scene(i: int) -> np.ndarray:
    """Frame i of the test video: grey level 10 + 15 i, a white square at x = 4 + 5 i."""
    frame = np.full((H, W, 3), 10 + 15 * i, np.uint8)
    x = 4 + 5 * i
    frame[20 : 20 + SQUARE, x : x + SQUARE] = 255
    return frame


def square_x(frame: np.ndarray) -> float:
    """Centre column of the white square."""
    grey = frame if frame.ndim == 2 else frame.mean(axis=2)
    cols = np.nonzero((grey > 240).any(axis=0))[0]
    return float(cols.mean())


@pytest.fixture
def video(tmp_path: Path) -> Path:
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 10.0, (W, H))
    assert writer.isOpened(), "OpenCV cannot write MJPG .avi here"
    for i in range(N_FRAMES):
        writer.write(scene(i))
    writer.release()
    return path


def write_png(path: Path, image: np.ndarray) -> None:
    assert cv2.imwrite(str(path), image), path


def camera_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("planarcal-camera")]


def wait_threads_gone(before: set[threading.Thread], within_s: float) -> None:
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        if not set(camera_threads()) - before:
            return
        time.sleep(0.02)
    pytest.fail(f"worker threads still alive after {within_s} s: {camera_threads()}")


# -- video file -----------------------------------------------------------------------------------


def test_video_frames_in_order_with_content(video: Path) -> None:
    with Camera(video) as cam:
        assert cam.source == video
        assert cam.resolution == (W, H)
        assert cam.fps == pytest.approx(10.0)
        frames = list(cam.frames())
        assert cam.frames_read == N_FRAMES
    assert len(frames) == N_FRAMES
    for i, frame in enumerate(frames):
        assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
        # JPEG: approximately the frame written, and the square where it was drawn.
        assert np.abs(frame.astype(int) - scene(i)).mean() < 4, i
        assert square_x(frame) == pytest.approx(4 + 5 * i + (SQUARE - 1) / 2, abs=1.0)
    background = [float(np.median(f)) for f in frames]
    assert background == sorted(background)


def test_end_of_video_names_file_and_count(video: Path) -> None:
    with Camera(str(video)) as cam:
        for _ in range(N_FRAMES):
            cam.read()
        for _ in range(2):  # and stays ended
            with pytest.raises(CameraError, match=r"after 12 frames") as err:
                cam.read()
            assert str(video) in str(err.value) and "ended" in str(err.value)
        assert cam.frames_read == N_FRAMES


def test_frames_n_past_the_end_raises(video: Path) -> None:
    with Camera(video) as cam:
        assert len(list(cam.frames(5))) == 5
        with pytest.raises(CameraError, match="after 12 frames"):
            list(cam.frames(N_FRAMES))
        with pytest.raises(ArgumentError):  # a ValueError too
            cam.frames(-1)


def test_grayscale(video: Path, tmp_path: Path) -> None:
    with Camera(video, color=False) as cam:
        frame = cam.read()
    assert frame.shape == (H, W) and frame.dtype == np.uint8
    assert np.abs(frame.astype(int) - scene(0)[:, :, 0]).mean() < 4
    folder = tmp_path / "grey"
    folder.mkdir()
    write_png(folder / "a.png", scene(3))
    with Camera(folder, color=False) as cam:
        assert np.array_equal(cam.read(), scene(3)[:, :, 0])


def test_requested_resolution_must_match_file(video: Path, tmp_path: Path) -> None:
    with pytest.raises(CameraError) as err:
        Camera(video, width=640, height=480)
    message = str(err.value)
    assert "640x480" in message and f"{W}x{H}" in message and "rescaled" in message
    assert str(video) in message
    with pytest.raises(CameraError, match="width 100"):
        Camera(video, width=100)
    with Camera(video, width=W, height=H) as cam:  # the right size is fine
        assert cam.resolution == (W, H)
    folder = tmp_path / "imgs"
    folder.mkdir()
    write_png(folder / "a.png", scene(0))
    with pytest.raises(CameraError, match="rescaled"):
        Camera(folder, height=H + 1)


def test_not_a_video(tmp_path: Path) -> None:
    path = tmp_path / "notes.avi"
    path.write_bytes(b"this is not a video\n" * 100)
    with pytest.raises(CameraError, match="cannot read it as video") as err:
        Camera(path)
    assert str(path) in str(err.value)


def test_missing_path(tmp_path: Path) -> None:
    path = tmp_path / "nowhere" / "clip.avi"
    with pytest.raises(CameraError, match="does not exist") as err:
        Camera(path)
    assert str(path) in str(err.value)


def test_closed_camera(video: Path) -> None:
    cam = Camera(video)
    cam.read()
    cam.close()
    cam.close()  # idempotent
    assert cam.closed
    for use in (cam.read, lambda: cam.frames(), lambda: cam.average(2)):
        with pytest.raises(CameraError, match="is closed"):
            use()
    assert cam.frames_read == 1 and cam.resolution == (W, H)  # still answer
    with Camera(video) as cam2:
        pass
    with pytest.raises(CameraError, match="is closed"):
        cam2.read()


def test_worker_threads_end(video: Path) -> None:
    before = set(camera_threads())
    with Camera(video) as cam:
        cam.read()
    unclosed = Camera(video)  # never closed: collected, its thread must still exit
    del unclosed
    gc.collect()
    wait_threads_gone(before, within_s=2.0)


# -- averaging ------------------------------------------------------------------------------------


def test_average_reduces_noise_as_sqrt_n(tmp_path: Path) -> None:
    sigma, n, level = 8.0, 16, 128.0
    rng = np.random.default_rng(1)
    folder = tmp_path / "noisy"
    folder.mkdir()
    for i in range(n + 1):  # PNG: lossless, the noise is read back exactly
        noisy = np.clip(np.rint(level + rng.normal(0, sigma, (H, W, 3))), 0, 255)
        write_png(folder / f"f{i}.png", noisy.astype(np.uint8))
    with Camera(folder) as cam:
        single = cam.read().astype(np.float64)
        mean = cam.average(n)
        assert cam.frames_read == n + 1
    assert mean.dtype == np.float32 and mean.shape == (H, W, 3)
    assert np.std(single - level) == pytest.approx(sigma, rel=0.05)
    assert np.std(mean - level) == pytest.approx(sigma / np.sqrt(n), rel=0.1)
    assert float(mean.mean()) == pytest.approx(level, abs=0.2)


def test_average_of_video_and_past_the_end(video: Path) -> None:
    with Camera(video) as cam:
        one = cam.average(1)
        assert one.dtype == np.float32
        assert np.abs(one - scene(0)).mean() < 4
        with pytest.raises(CameraError, match=r"after 11 frames, nothing returned"):
            cam.average(N_FRAMES)  # only 11 left
        with pytest.raises(ArgumentError):  # a ValueError too
            cam.average(0)


# -- image folders --------------------------------------------------------------------------------


def test_folder_natural_order_ignores_other_files(tmp_path: Path) -> None:
    numbers = [10, 2, 1, 11, 3]
    for k in numbers:  # written out of order
        write_png(tmp_path / f"img{k}.png", np.full((H, W, 3), 20 * k, np.uint8))
    (tmp_path / "notes.txt").write_text("not an image")
    (tmp_path / ".hidden.png").write_bytes(b"junk")
    (tmp_path / "sub.png").mkdir()  # a folder with an image suffix
    with Camera(tmp_path) as cam:
        assert cam.fps is None
        levels = [int(f[0, 0, 0]) for f in cam.frames()]
        assert levels == [20 * k for k in sorted(numbers)]  # img1 img2 img3 img10 img11
        with pytest.raises(CameraError, match=r"all its images were read \(5 frames") as err:
            cam.read()
        assert str(tmp_path) in str(err.value)


def test_corrupt_image_in_folder(tmp_path: Path) -> None:
    write_png(tmp_path / "img1.png", scene(1))
    (tmp_path / "img2.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"garbage" * 50)
    write_png(tmp_path / "img3.png", scene(3))
    with Camera(tmp_path) as cam:
        assert np.array_equal(cam.read(), scene(1))
        with pytest.raises(CameraError, match="cannot decode") as err:
            cam.read()
        assert "img2.png" in str(err.value)
        assert np.array_equal(cam.read(), scene(3))  # goes on with the next image
        assert cam.frames_read == 2


def test_corrupt_first_image_fails_at_open(tmp_path: Path) -> None:
    (tmp_path / "a.jpg").write_bytes(b"")
    with pytest.raises(CameraError, match=r"cannot decode .*a\.jpg"):
        Camera(tmp_path)


def test_image_of_another_size_in_folder(tmp_path: Path) -> None:
    write_png(tmp_path / "a1.png", scene(0))
    write_png(tmp_path / "a2.png", np.zeros((H, W + 2, 3), np.uint8))
    with Camera(tmp_path) as cam:
        cam.read()
        with pytest.raises(CameraError, match=rf"{W + 2}x{H} frame.*a2\.png"):
            cam.read()


def test_empty_folder(tmp_path: Path) -> None:
    with pytest.raises(CameraError, match="holds no images") as err:
        Camera(tmp_path)
    assert str(tmp_path) in str(err.value)
    (tmp_path / "readme.txt").write_text("x")
    with pytest.raises(CameraError, match=r"holds no images \(1 other"):
        Camera(tmp_path)


# -- arguments ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "kwargs", "error"),
    [
        ((True,), {}, TypeError),
        ((1.5,), {}, TypeError),
        ((-1,), {}, ValueError),
        (("",), {}, TypeError),
        ((0,), {"width": 0}, ValueError),
        ((0,), {"height": 2.5}, TypeError),
        ((0,), {"timeout_s": 0}, ValueError),
        ((0,), {"timeout_s": float("nan")}, ValueError),
    ],
)
def test_bad_arguments(args: tuple[object, ...], kwargs: dict[str, object], error: type) -> None:
    with pytest.raises(error) as info:
        Camera(*args, **kwargs)  # type: ignore[arg-type]
    # planarcal's own (an ArgumentError), still the ValueError or TypeError Python code expects.
    assert isinstance(info.value, ArgumentError)
    if error is TypeError:
        assert isinstance(info.value, ArgumentTypeError)


# -- devices and streams (loopback only) ----------------------------------------------------------


def test_missing_device_fails_promptly() -> None:
    start = time.monotonic()
    with pytest.raises(CameraError, match="cannot open camera device 99") as err:
        Camera(99, timeout_s=TIMEOUT_S)
    assert time.monotonic() - start < TIMEOUT_S
    assert "/dev/video99" in str(err.value)


@pytest.mark.parametrize("url", REFUSED_URLS)
def test_refused_stream_fails_within_timeout(url: str) -> None:
    start = time.monotonic()
    with pytest.raises(CameraError) as err:
        Camera(url, timeout_s=TIMEOUT_S)
    assert time.monotonic() - start < TIMEOUT_S + MARGIN_S
    assert url in str(err.value)


def test_password_is_not_in_messages() -> None:
    with pytest.raises(CameraError) as err:
        Camera("http://user:secret@127.0.0.1:9/cam", timeout_s=TIMEOUT_S)
    assert "secret" not in str(err.value) and "user:***@127.0.0.1:9" in str(err.value)


@contextlib.contextmanager
def loopback_server(respond: bytes | None) -> Iterator[int]:
    """A TCP server on 127.0.0.1 that accepts connections, sends `respond` after the request
    (nothing if None), then says nothing more while keeping the connection open."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    server.settimeout(0.1)
    conns: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            conns.append(conn)
            if respond is not None:
                conn.settimeout(2.0)
                with contextlib.suppress(OSError):
                    conn.recv(65536)
                    conn.sendall(respond)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield server.getsockname()[1]
    finally:
        stop.set()
        thread.join()
        for conn in conns:
            conn.close()
        server.close()


def test_silent_stream_open_does_not_hang() -> None:
    before = set(camera_threads())
    with loopback_server(respond=None) as port:
        url = f"http://127.0.0.1:{port}/video"
        start = time.monotonic()
        with pytest.raises(CameraError, match=r"did not open within timeout_s=1 s") as err:
            Camera(url, timeout_s=TIMEOUT_S)
        elapsed = time.monotonic() - start
        assert TIMEOUT_S * 0.9 <= elapsed < TIMEOUT_S + MARGIN_S
        assert url in str(err.value)
        # The stuck open was left on the worker, which FFmpeg's own timeout then frees.
        wait_threads_gone(before, within_s=BACKEND_GRACE_S + 3.0)


def mjpeg_head(n: int) -> bytes:
    """An HTTP multipart MJPEG response carrying n frames (scene(0..n-1)), no end."""
    out = [b"HTTP/1.0 200 OK\r\nContent-Type: multipart/x-mixed-replace; boundary=frame\r\n\r\n"]
    for i in range(n):
        ok, jpg = cv2.imencode(".jpg", scene(i))
        assert ok
        data = jpg.tobytes()
        out.append(b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n" % len(data))
        out.append(data + b"\r\n")
    return b"".join(out)


def test_stalled_stream_read_does_not_hang() -> None:
    before = set(camera_threads())
    with loopback_server(respond=mjpeg_head(3)) as port:
        url = f"http://127.0.0.1:{port}/stream.mjpg"
        cam = Camera(url, timeout_s=TIMEOUT_S, width=W, height=H)
        assert cam.resolution == (W, H)
        for i in range(3):
            assert square_x(cam.read()) == pytest.approx(4 + 5 * i + (SQUARE - 1) / 2, abs=1.0)
        start = time.monotonic()
        with pytest.raises(CameraError, match=r"did not deliver a frame within") as err:
            cam.read()
        elapsed = time.monotonic() - start
        assert TIMEOUT_S * 0.9 <= elapsed < TIMEOUT_S + MARGIN_S
        assert url in str(err.value) and "after 3 frames" in str(err.value)
        assert cam.closed and cam.frames_read == 3
        with pytest.raises(CameraError, match="is closed"):
            cam.read()
        cam.close()
        wait_threads_gone(before, within_s=BACKEND_GRACE_S + 3.0)


def test_stream_resolution_must_match() -> None:
    with loopback_server(respond=mjpeg_head(3)) as port:
        url = f"http://127.0.0.1:{port}/stream.mjpg"
        start = time.monotonic()
        with pytest.raises(CameraError) as err:
            Camera(url, timeout_s=TIMEOUT_S, width=640, height=480)
        assert time.monotonic() - start < TIMEOUT_S
    message = str(err.value)
    assert "requested 640x480" in message and f"granted {W}x{H}" in message and url in message


def test_character_device_path_is_opened_as_a_camera() -> None:
    with pytest.raises(CameraError, match="cannot open camera device '/dev/null'"):
        Camera("/dev/null", timeout_s=TIMEOUT_S)
