"""Frames from a camera, a video file, a network stream or a folder of images, one API.

``Camera(source)`` opens any of:

* a device index (``int``): a camera attached to this machine (V4L2 on Linux);
* a stream URL (a ``str`` containing ``"://"``: ``rtsp://``, ``http://``, ...), read with
  OpenCV's FFmpeg backend;
* a video file path (``str`` or ``os.PathLike``); a character device path such as
  ``/dev/video0`` is opened as a camera;
* a folder of images, read in natural sort order (``img2.png`` before ``img10.png``); files
  without an image suffix (see ``IMAGE_SUFFIXES``) and hidden files are ignored.

``read()`` returns the next frame (H x W x 3 BGR ``uint8``, or H x W ``uint8`` with
``color=False``) and never returns None: the end of a file or folder, a camera or stream that
stops delivering, and an image that cannot be decoded all raise ``CameraError`` naming the
source and how many frames were read. Every frame has the resolution reported by
``resolution``; a frame of another size raises ``CameraError``.

No call blocks for longer than ``timeout_s``, even with a camera or stream that stops
answering: every blocking call (opening, reading and decoding a frame, releasing) runs on a
worker thread owned by the ``Camera``, and the caller waits for it at most ``timeout_s``. On
a timeout the caller gets a ``CameraError`` and the ``Camera`` is closed; the call that hung
cannot be interrupted from Python, so it is left running on its daemon thread, which releases
the capture and exits as soon as the call returns, and never keeps the process from exiting.
With a stream or a file, OpenCV's FFmpeg backend is also given its own open and read timeouts
(``CAP_PROP_OPEN_TIMEOUT_MSEC``, ``CAP_PROP_READ_TIMEOUT_MSEC``) of ``timeout_s`` plus
``BACKEND_GRACE_S``, so a stuck call gives up on its own shortly after the caller was told; a
camera backend that does not honour them (they are set, and ignored by V4L2, which has its
own select timeout) may keep its thread longer. The device stays held until that thread has
released it. ``close()`` too waits at most ``timeout_s`` for the release.

Opening reads the first frame (each step bounded by ``timeout_s``), so that the resolution is
that of real frames and a source that opens but delivers nothing fails at once.

A ``Camera`` can be shared between threads (calls are serialised) but is meant for one
consumer: two threads reading it get alternate frames.
"""

from __future__ import annotations

import glob
import math
import os
import queue
import re
import stat
import sys
import threading
import urllib.parse
from collections.abc import Callable, Iterator
from types import TracebackType
from typing import Any, Generic, Literal, TypeVar, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.errors import CameraError, ImageError

__all__ = ["BACKEND_GRACE_S", "IMAGE_SUFFIXES", "Camera", "Frame"]

Frame = NDArray[np.uint8]
"""A frame: H x W x 3 BGR, or H x W grey, uint8."""

IMAGE_SUFFIXES = frozenset(
    {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm", ".pnm", ".jp2"}
)
"""The suffixes (case-insensitive) of the files read from an image folder."""

BACKEND_GRACE_S = 1.0
"""How much longer than ``timeout_s`` OpenCV's own timeouts are: the caller's guard fires
first, and the backend then frees the stuck worker thread shortly after."""

_Kind = Literal["device", "stream", "file", "folder"]
_T = TypeVar("_T")


# ----------------------------------------------------------------------------------------------
# The worker thread: runs blocking calls so that the caller can stop waiting.


class _WorkerTimeoutError(Exception):
    """The worker did not finish a call within the caller's timeout."""


class _Job(Generic[_T]):
    """One call for the worker thread, and its outcome."""

    __slots__ = ("done", "error", "fn", "result")

    def __init__(self, fn: Callable[[], _T]) -> None:
        self.fn = fn
        self.done = threading.Event()
        self.result: _T | None = None
        self.error: BaseException | None = None


class _Worker:
    """A daemon thread that runs jobs in order. ``call`` waits for a job at most ``timeout``;
    ``stop`` queues a last job and the order to exit, without waiting: a job that hangs keeps
    the thread (never the caller) until it returns, and the last job runs after it."""

    def __init__(self, name: str) -> None:
        self._jobs: queue.SimpleQueue[_Job[Any] | None] = queue.SimpleQueue()
        self.stopped = False
        # The thread references the queue only, never the Camera, so an unclosed Camera can
        # still be collected (its __del__ stops the worker).
        self.thread = threading.Thread(target=_Worker._run, args=(self._jobs,), name=name)
        self.thread.daemon = True
        self.thread.start()

    @staticmethod
    def _run(jobs: queue.SimpleQueue[_Job[Any] | None]) -> None:
        while True:
            job = jobs.get()
            if job is None:
                return
            try:
                job.result = job.fn()
            except BaseException as e:  # handed to the caller, who re-raises it
                job.error = e
            finally:
                job.done.set()
            # Hold nothing while waiting for the next job: the last job's function may be a
            # method of the Camera, which must stay collectable.
            del job

    def call(self, fn: Callable[[], _T], timeout: float) -> _T:
        """Run ``fn`` on the worker thread; its result, or its exception re-raised here, or
        ``_WorkerTimeoutError`` if it has not finished after ``timeout`` seconds."""
        job = _Job(fn)
        self._jobs.put(job)
        if not job.done.wait(timeout):
            raise _WorkerTimeoutError
        if job.error is not None:
            error, job.error = job.error, None  # no reference cycle through the traceback
            raise error
        return cast(_T, job.result)

    def stop(self, last: Callable[[], None] | None = None) -> None:
        """Queue ``last`` (run when every queued job is done) and the order to exit."""
        if self.stopped:
            return
        self.stopped = True
        if last is not None:
            self._jobs.put(_Job(last))
        self._jobs.put(None)


# ----------------------------------------------------------------------------------------------
# Backends: run on the worker thread only.


class _Backend:
    """What a Camera reads from: ``read`` returns a raw frame, or None at the end."""

    kind: _Kind
    label: str
    fps: float | None = None

    def read(self) -> NDArray[Any] | None:
        raise NotImplementedError

    def where(self) -> str:
        """Which frame the last ``read`` returned, for messages."""
        return ""

    def release(self) -> None:
        """Free the device, connection or file. Idempotent."""


class _VideoBackend(_Backend):
    """A cv2.VideoCapture: camera, stream or video file."""

    def __init__(self, kind: _Kind, label: str, cap: Any) -> None:
        self.kind = kind
        self.label = label
        self.cap: Any = cap
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        self.fps = fps if math.isfinite(fps) and fps > 0 else None

    def read(self) -> NDArray[Any] | None:
        ok, frame = self.cap.read()
        if not ok or frame is None or frame.size == 0:
            return None
        return cast(NDArray[Any], frame)

    def release(self) -> None:
        cap, self.cap = self.cap, None
        if cap is not None:
            cap.release()


class _FolderBackend(_Backend):
    """The images of a folder, in the given order."""

    def __init__(self, label: str, files: list[str], color: bool) -> None:
        self.kind = "folder"
        self.label = label
        self.files = files
        self.flag = cv2.IMREAD_COLOR if color else cv2.IMREAD_GRAYSCALE
        self.next = 0

    def read(self) -> NDArray[Any] | None:
        if self.next >= len(self.files):
            return None
        path = self.files[self.next]
        self.next += 1
        position = f"image {self.next} of {len(self.files)} in {self.label}"
        try:
            data = np.fromfile(path, dtype=np.uint8)
        except OSError as e:
            raise CameraError(f"cannot read {path!r} ({position}): {e}") from e
        image: NDArray[Any] | None = None
        if data.size:
            try:
                image = cv2.imdecode(data, self.flag)
            except cv2.error:
                image = None
        if image is None or image.size == 0:
            raise CameraError(
                f"cannot decode {path!r} ({position}): it is corrupt, truncated or not an "
                "image. Replace or remove it; the next read() goes on with the next image"
            )
        return image

    def where(self) -> str:
        return f" ({self.files[self.next - 1]!r})" if self.next else ""


class _Slot:
    """Holds the backend so that a job queued after a stuck one can still release it."""

    backend: _Backend | None = None

    def release(self) -> None:
        backend, self.backend = self.backend, None
        if backend is not None:
            backend.release()


def _natural_key(name: str) -> tuple[tuple[int | str, ...], str]:
    """Sort key: runs of digits compare as numbers (img2 < img10), the rest case-blind."""
    parts = re.split(r"(\d+)", name.casefold())
    return tuple(int(p) if i % 2 else p for i, p in enumerate(parts)), name


def _redact(url: str) -> str:
    """The URL with its password, if any, replaced by ***: fit for messages and logs."""
    try:
        parts = urllib.parse.urlsplit(url)
        if parts.password is None:
            return url
        user = parts.username or ""
        host = parts.netloc.rpartition("@")[2]
        return urllib.parse.urlunsplit(parts._replace(netloc=f"{user}:***@{host}"))
    except ValueError:
        return url


def _ffmpeg_params(timeout_ms: int) -> list[int]:
    return [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, timeout_ms, cv2.CAP_PROP_READ_TIMEOUT_MSEC, timeout_ms]


def _has_ffmpeg() -> bool:
    try:
        return bool(cv2.videoio_registry.hasBackend(cv2.CAP_FFMPEG))
    except (AttributeError, cv2.error):
        return False


def _video_capture(target: int | str, api: int, params: list[int] | None) -> Any:
    """cv2.VideoCapture(...), or None where OpenCV raises instead of failing quietly."""
    try:
        if params is None:
            return cv2.VideoCapture(target, api)
        return cv2.VideoCapture(target, api, params)
    except cv2.error:
        return None


def _opened(cap: Any) -> bool:
    return cap is not None and bool(cap.isOpened())


def _video_devices() -> str:
    """The /dev/video* present, for the message of a device that cannot be opened."""
    if not sys.platform.startswith("linux"):
        return ""
    found = sorted(glob.glob("/dev/video*"), key=_natural_key)
    return f"; present: {', '.join(found)}" if found else "; no /dev/video* is present"


def _open_device(
    target: int | str, label: str, timeout_ms: int, width: int | None, height: int | None
) -> _Backend:
    cap = _video_capture(target, cv2.CAP_ANY, None)
    if not _opened(cap):
        if cap is not None:
            cap.release()
        node = f"/dev/video{target}" if isinstance(target, int) else target
        raise CameraError(
            f"cannot open {label}: no camera answered. Check that the camera is plugged in "
            f"and powered, that the index or path is right ({node}{_video_devices()}), that no "
            "other program is using it, and that this user may open it (on Linux: the "
            "'video' group)"
        )
    # Backends that do not know these properties ignore them (set() returns False).
    cap.set(cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, timeout_ms)
    cap.set(cv2.CAP_PROP_READ_TIMEOUT_MSEC, timeout_ms)
    # V4L2 changes the mode only once both are set: a size given alone goes with the other
    # as it is now. What was granted is checked on the first frame.
    if width is not None or height is not None:
        if width is None:
            width = round(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        if height is None:
            height = round(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        cap.set(cv2.CAP_PROP_FRAME_WIDTH, width)
        cap.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
    return _VideoBackend("device", label, cap)


def _open_stream(url: str, label: str, timeout_ms: int) -> _Backend:
    # FFmpeg honours the timeouts; without it, CAP_ANY (with OpenCV's default timeouts: the
    # worker thread still bounds the caller's wait).
    if _has_ffmpeg():
        cap = _video_capture(url, cv2.CAP_FFMPEG, _ffmpeg_params(timeout_ms))
    else:
        cap = _video_capture(url, cv2.CAP_ANY, None)
    if not _opened(cap):
        if cap is not None:
            cap.release()
        raise CameraError(
            f"cannot open {label}: OpenCV got no video from it (connection refused, unknown "
            "host, wrong path or credentials, or not a video stream). Check the URL (scheme, "
            "host, port, path), that the camera or server is running and reachable from this "
            "machine (network, firewall), and the user name and password"
        )
    return _VideoBackend("stream", label, cap)


def _open_file(path: str, label: str, timeout_ms: int) -> _Backend:
    if not os.access(path, os.R_OK):
        raise CameraError(f"cannot open {label}: permission denied. Check the file's permissions")
    cap = None
    if _has_ffmpeg():
        cap = _video_capture(path, cv2.CAP_FFMPEG, _ffmpeg_params(timeout_ms))
    if not _opened(cap):
        if cap is not None:
            cap.release()
        # The other file backends (OpenCV's own MJPEG reader, image sequences).
        cap = _video_capture(path, cv2.CAP_ANY, None)
    if not _opened(cap):
        if cap is not None:
            cap.release()
        raise CameraError(
            f"cannot open {label}: OpenCV cannot read it as video. Check that it is a video "
            "file, that it is complete (not truncated or still being written), and that its "
            f"codec is one this OpenCV build decodes (ffprobe {path!r} tells the codec); for "
            "a folder of images, pass the folder"
        )
    return _VideoBackend("file", label, cap)


def _open_folder(path: str, label: str, color: bool) -> _Backend:
    try:
        names = os.listdir(path)
    except OSError as e:
        raise CameraError(f"cannot list {label}: {e}. Check the folder's permissions") from e
    images: list[str] = []
    others = 0
    for name in names:
        full = os.path.join(path, name)
        if (
            not name.startswith(".")
            and os.path.splitext(name)[1].lower() in IMAGE_SUFFIXES
            and os.path.isfile(full)
        ):
            images.append(name)
        else:
            others += 1
    if not images:
        raise CameraError(
            f"{label} holds no images ({others} other entries ignored). Check the path, and "
            f"that the images have one of the suffixes {', '.join(sorted(IMAGE_SUFFIXES))}"
        )
    images.sort(key=_natural_key)
    return _FolderBackend(label, [os.path.join(path, name) for name in images], color)


def _open_path(
    path: str, timeout_ms: int, width: int | None, height: int | None, color: bool
) -> _Backend:
    """Open a path by what it is: folder, character device, or (anything else) video file."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        hint = ""
        if path.strip().isdigit():
            hint = f"; to open camera device {path.strip()}, pass the int {int(path)}"
        raise CameraError(
            f"{path!r} does not exist: no such file or folder. Check the path (relative paths "
            f"start from {os.getcwd()!r}){hint}"
        ) from None
    except OSError as e:
        raise CameraError(f"cannot open {path!r}: {e}. Check the path and its permissions") from e
    if stat.S_ISDIR(mode):
        return _open_folder(path, f"image folder {path!r}", color)
    if stat.S_ISCHR(mode):
        return _open_device(path, f"camera device {path!r}", timeout_ms, width, height)
    return _open_file(path, f"video file {path!r}", timeout_ms)


def _as_frame(frame: NDArray[Any], color: bool, where: str) -> Frame:
    """A backend's frame as BGR (or grey) uint8."""
    if frame.dtype != np.uint8:
        raise ImageError(
            f"{where} delivered a {frame.dtype} frame; planarcal needs 8-bit frames (set the "
            "camera to an 8-bit pixel format)"
        )
    if frame.ndim == 3 and frame.shape[2] == 1:
        frame = frame[:, :, 0]
    if frame.ndim == 2:
        return cast(Frame, cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)) if color else frame
    if frame.ndim == 3 and frame.shape[2] in (3, 4):
        if frame.shape[2] == 4:
            code = cv2.COLOR_BGRA2BGR if color else cv2.COLOR_BGRA2GRAY
            return cast(Frame, cv2.cvtColor(frame, code))
        return frame if color else cast(Frame, cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
    raise ImageError(f"{where} delivered a frame of shape {frame.shape}, not an image")


def _size_text(width: int | None, height: int | None) -> str:
    if width is not None and height is not None:
        return f"{width}x{height}"
    return f"width {width}" if width is not None else f"height {height}"


def _check_positive_int(value: object, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise TypeError(f"{name} must be an int, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be at least {minimum}, got {value}")
    return int(value)


# ----------------------------------------------------------------------------------------------


class Camera:
    """Frames from a camera, a stream, a video file or an image folder; see the module doc.

    Args:
        source: a device index (int), a stream URL (str containing ``"://"``), a video file
            path, or a folder of images. Kept as given in ``source``.
        width, height: the resolution wanted. A camera is asked for it; a stream's resolution
            is set by its server and a file or folder cannot be rescaled on request. In every
            case the frames delivered must have it, or ``CameraError`` says what was requested
            and what was granted. Either may be given alone.
        timeout_s: the longest any blocking step (open, first frame, each read, release) may
            take before ``CameraError``.
        color: True for H x W x 3 BGR frames, False for H x W grey frames.

    Raises:
        CameraError: the source cannot be opened, does not answer within ``timeout_s``,
            delivers no frame, or does not have the requested resolution.
        TypeError, ValueError: arguments of the wrong type or range.

    Use as a context manager, or call ``close()``.
    """

    def __init__(
        self,
        source: int | str | os.PathLike[str],
        *,
        width: int | None = None,
        height: int | None = None,
        timeout_s: float = 5.0,
        color: bool = True,
    ) -> None:
        self._closed = True  # until opened: __del__ and close() of a failed __init__ are no-ops
        self._source = source
        if width is not None:
            width = _check_positive_int(width, "width", 1)
        if height is not None:
            height = _check_positive_int(height, "height", 1)
        if (
            isinstance(timeout_s, bool)
            or not isinstance(timeout_s, int | float)
            or not (math.isfinite(timeout_s) and timeout_s > 0)
        ):
            raise ValueError(f"timeout_s must be a positive number of seconds, got {timeout_s!r}")
        self._timeout_s = float(timeout_s)
        self._color = bool(color)
        timeout_ms = round((self._timeout_s + BACKEND_GRACE_S) * 1000)

        opener: Callable[[], _Backend]
        self._kind: _Kind = "file"  # until opened: a path may turn out to be a folder
        if isinstance(source, bool):
            raise TypeError(f"source must be a device index, a URL or a path, got {source!r}")
        if isinstance(source, int | np.integer):
            index = _check_positive_int(source, "a device index", 0)
            self._kind = "device"
            self._label = f"camera device {index}"
            label = self._label

            def opener() -> _Backend:
                return _open_device(index, label, timeout_ms, width, height)

        elif isinstance(source, str) and "://" in source:
            self._kind = "stream"
            self._label = f"stream {_redact(source)!r}"
            label = self._label

            def opener() -> _Backend:
                return _open_stream(source, label, timeout_ms)

        elif isinstance(source, str | os.PathLike):
            path = os.fspath(source)
            if not isinstance(path, str) or not path:
                raise TypeError(f"source must be a non-empty str path, got {source!r}")
            self._label = repr(path)  # "video file ..." or "image folder ..." once opened
            color_ = self._color

            def opener() -> _Backend:
                return _open_path(path, timeout_ms, width, height, color_)

        else:
            raise TypeError(f"source must be a device index, a URL or a path, got {source!r}")

        self._lock = threading.Lock()
        self._slot = _Slot()
        self._worker = _Worker(name=f"planarcal-camera {self._label}")
        self._frames_read = 0
        self._ended = False
        self._closed_because = ""
        self._fps: float | None = None
        self._resolution = (0, 0)
        self._pending: Frame | None = None
        self._closed = False
        slot = self._slot

        def open_job() -> _Backend:
            backend = opener()
            slot.backend = backend
            return backend

        try:
            backend = self._call(open_job, "open")
            self._label = backend.label
            self._kind = backend.kind
            self._fps = backend.fps
            got = self._call(self._read_job, "deliver its first frame")
            if got is None:
                raise CameraError(self._no_first_frame_message())
            first = got[0]
            self._resolution = (int(first.shape[1]), int(first.shape[0]))
            if (width is not None and width != self._resolution[0]) or (
                height is not None and height != self._resolution[1]
            ):
                raise CameraError(self._resolution_message(width, height))
        except BaseException:
            self.close()
            raise
        self._pending = first

    # -- properties ----------------------------------------------------------------------------

    @property
    def source(self) -> int | str | os.PathLike[str]:
        """The source, as given."""
        return self._source

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of every frame, in pixels."""
        return self._resolution

    @property
    def fps(self) -> float | None:
        """The frame rate the backend reports, or None if unknown (always None for a folder).
        A camera or stream may deliver at another rate."""
        return self._fps

    @property
    def frames_read(self) -> int:
        """How many frames ``read`` (and so ``frames`` and ``average``) has returned."""
        return self._frames_read

    @property
    def closed(self) -> bool:
        """True after ``close()``, or after a timeout closed the Camera."""
        return self._closed

    @property
    def ended(self) -> bool:
        """True once a file or folder has delivered its last frame (never for a camera or a
        stream, which can only stop delivering)."""
        return self._ended

    @property
    def live(self) -> bool:
        """True for a camera or stream (frames come at their own pace and are lost if not
        read), False for a file or folder (read at the reader's pace, nothing lost)."""
        return self._kind in ("device", "stream")

    @property
    def label(self) -> str:
        """What the camera reads, for messages ("camera device 0", a stream's URL with any
        password hidden, a file's path)."""
        return self._label

    def __repr__(self) -> str:
        state = "closed" if self._closed else "open"
        w, h = self._resolution
        return f"<Camera {self._label} {w}x{h} frames_read={self._frames_read} {state}>"

    # -- reading -------------------------------------------------------------------------------

    def read(self) -> Frame:
        """The next frame: H x W x 3 BGR uint8, or H x W uint8 with ``color=False``.

        Raises:
            CameraError: the camera is closed; the file or folder has ended; the camera or
                stream stopped delivering or did not deliver within ``timeout_s`` (which also
                closes the Camera); an image of the folder cannot be decoded (the next
                ``read`` goes on with the image after it); a frame of another resolution.
            ImageError: the backend delivers frames that are not 8-bit images.
        """
        with self._lock:
            self._check_open()
            if self._pending is not None:
                frame, self._pending = self._pending, None
            else:
                if self._ended:
                    raise CameraError(self._end_message())
                got = self._call(self._read_job, "deliver a frame")
                if got is None:
                    if self._kind in ("file", "folder"):
                        self._ended = True
                        raise CameraError(self._end_message())
                    raise CameraError(
                        f"{self._label} stopped delivering after {self._frames_read} frames "
                        "(unplugged, connection lost, or the stream ended). Check the cable, "
                        "power or network; open a new Camera to try again"
                    )
                frame, where = got
                if (frame.shape[1], frame.shape[0]) != self._resolution:
                    w, h = self._resolution
                    raise CameraError(
                        f"{self._label} delivered a {frame.shape[1]}x{frame.shape[0]} frame"
                        f"{where} after {self._frames_read} frames of {w}x{h}: every frame "
                        "must have the same resolution"
                    )
            self._frames_read += 1
            return frame

    def frames(self, n: int | None = None) -> Iterator[Frame]:
        """An iterator over the next ``n`` frames, or with ``n=None`` over every frame.

        With ``n=None`` the iteration stops at the end of a file or folder and never ends for
        a camera or stream; with ``n`` given, a source that ends before ``n`` frames raises
        ``CameraError``. Any other error of ``read`` is raised as it happens.
        """
        if n is not None:
            n = _check_positive_int(n, "n", 0)
        self._check_open()
        return self._iterate(n)

    def _iterate(self, n: int | None) -> Iterator[Frame]:
        if n is not None:
            for _ in range(n):
                yield self.read()
            return
        while True:
            self._check_open()
            if self._ended:
                return
            try:
                frame = self.read()
            except CameraError:
                if self._ended and not self._closed:
                    return
                raise
            yield frame

    def average(self, n: int) -> NDArray[np.float32]:
        """The mean of the next ``n`` frames (n >= 1), accumulated in float64: a low-noise
        image for calibration (noise falls as 1 / sqrt(n) on a still scene). Same shape as the
        frames, float32, on the 0..255 scale.

        Raises:
            CameraError: the source ended or failed before ``n`` frames; nothing partial is
                returned, and the frames read so far are consumed (``frames_read`` counts
                them).
        """
        n = _check_positive_int(n, "n", 1)
        self._check_open()
        total: NDArray[np.float64] | None = None
        for i in range(n):
            try:
                frame = self.read()
            except CameraError as e:
                raise CameraError(
                    f"average of {n} frames failed after {i} frames, nothing returned: {e}"
                ) from e
            if total is None:
                total = frame.astype(np.float64)
            else:
                total += frame
        assert total is not None
        return (total / n).astype(np.float32)

    # -- closing -------------------------------------------------------------------------------

    def close(self) -> None:
        """Release the camera, stream, file or folder. Idempotent. Waits at most ``timeout_s``
        for the release; one that hangs is finished on the worker thread."""
        lock = getattr(self, "_lock", None)
        if lock is None:  # __init__ failed before the worker existed
            self._closed = True
            return
        with lock:
            if self._closed and self._worker.stopped:
                return
            self._closed = True
            self._pending = None
            if not self._worker.stopped:
                try:
                    self._worker.call(self._slot.release, self._timeout_s)
                except _WorkerTimeoutError:
                    self._worker.stop(self._slot.release)
                finally:
                    self._worker.stop()

    def __enter__(self) -> Camera:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __del__(self) -> None:
        # Never blocks: an unclosed Camera's worker releases the capture and exits.
        worker: _Worker | None = getattr(self, "_worker", None)
        if worker is not None:
            worker.stop(self._slot.release)

    # -- internals -----------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise CameraError(f"{self._label} is closed{self._closed_because}")

    def _read_job(self) -> tuple[Frame, str] | None:
        """On the worker: the next frame, converted, and where it came from; None at the end."""
        backend = self._slot.backend
        if backend is None:
            raise CameraError(f"{self._label} is closed")
        raw = backend.read()
        if raw is None:
            return None
        where = backend.where()
        return _as_frame(raw, self._color, f"{self._label}{where}"), where

    def _call(self, fn: Callable[[], _T], action: str) -> _T:
        """Run ``fn`` on the worker, waiting at most timeout_s; on a timeout, close."""
        try:
            return self._worker.call(fn, self._timeout_s)
        except _WorkerTimeoutError:
            self._closed = True
            self._closed_because = (
                f" (it did not {action} within {self._timeout_s:g} s after "
                f"{self._frames_read} frames)"
            )
            # The stuck call keeps the worker; the capture is released when it returns.
            self._worker.stop(self._slot.release)
            raise CameraError(
                f"{self._label} did not {action} within timeout_s={self._timeout_s:g} s "
                f"(after {self._frames_read} frames). Check that it is connected and "
                "delivering (for a stream: the server, the network), or raise timeout_s. The "
                "Camera is now closed: open a new one to retry; the stuck call was left on a "
                "background thread, which releases the source when it returns"
            ) from None

    def _end_message(self) -> str:
        if self._kind == "folder":
            return (
                f"{self._label} has ended: all its images were read ({self._frames_read} "
                "frames returned)"
            )
        return (
            f"{self._label} has ended after {self._frames_read} frames (the end of the file, "
            "or a frame that could not be decoded)"
        )

    def _no_first_frame_message(self) -> str:
        if self._kind == "file":
            return (
                f"{self._label} opened but has no frame OpenCV can decode. Check that it is "
                "complete and plays (ffprobe/ffplay)"
            )
        return (
            f"{self._label} opened but delivered no frame. Check that it is not in use by "
            "another program and is streaming video"
        )

    def _resolution_message(self, width: int | None, height: int | None) -> str:
        w, h = self._resolution
        wanted = _size_text(width, height)
        if self._kind in ("file", "folder"):
            what = "the video's frames are" if self._kind == "file" else "its images are"
            return (
                f"{self._label}: requested {wanted}, but {what} {w}x{h}, and a file cannot be "
                "rescaled on request. Drop width/height, or resize the frames yourself "
                "(cv2.resize) if you mean to"
            )
        if self._kind == "stream":
            return (
                f"{self._label}: requested {wanted}, granted {w}x{h}: a stream's resolution is "
                "set by its camera or server, not by the reader. Configure it there, or drop "
                "width/height"
            )
        return (
            f"{self._label}: requested {wanted}, granted {w}x{h}: the camera or driver does "
            "not offer that mode (on Linux, `v4l2-ctl --list-formats-ext` lists the modes). "
            "Ask for one it offers, or drop width/height to take its default"
        )
