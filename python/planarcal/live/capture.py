"""Frames from a camera, a video file, a network stream or a folder of images, one API.

``Camera(source)`` opens any of:

* a device index (``int``): a camera attached to this machine (V4L2 on Linux);
* a stream URL (a ``str`` containing ``"://"``: ``rtsp://``, ``http://``, ...), read with
  OpenCV's FFmpeg backend;
* a video file path (``str`` or ``os.PathLike``, or a ``file://`` URL); a character device
  path such as ``/dev/video0`` is opened as a camera;
* a folder of images, read in natural sort order (``img2.png`` before ``img10.png``); files
  without an image suffix (see ``IMAGE_SUFFIXES``) and hidden files are ignored.

``read()`` returns the next frame (H x W x 3 BGR ``uint8``, or H x W ``uint8`` with
``color=False``) and never returns None: the end of a file or folder, a camera or stream that
stops delivering, and a folder's image that cannot be decoded all raise ``CameraError`` naming
the source and how many frames were read. A camera or stream that stops delivering is closed
at once (the device released): the caller opens a new ``Camera`` to retry, as
``planarcal.Tracker`` does with back-off. A video file's frames that cannot be decoded (a
damaged stretch) are skipped, and counted in ``frames_undecodable``: reading goes on after
the damage, and the file ends only after ``MAX_UNDECODABLE_RUN`` failed reads in a row. Every
frame has the resolution reported by ``resolution``; a frame of another size raises
``CameraError`` (counted in ``frames_wrong_size``).

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
that of real frames and a source that opens but delivers nothing fails at once. A folder's
images that cannot be decoded before its first good one do not stop the opening: the first
``read()`` calls raise their ``CameraError`` one by one, as for a bad image later on, and the
opening fails only when no image of the folder can be decoded.

A ``Camera`` can be shared between threads (calls are serialised) but is meant for one
consumer: two threads reading it get alternate frames.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator
from types import TracebackType
from typing import Any, TypeVar, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.errors import ArgumentError, ArgumentTypeError, CameraError, ImageError
from planarcal.live.capture_sources import (
    IMAGE_SUFFIXES,
    Backend,
    BackendSlot,
    SourceKind,
    file_url_path,
    open_device,
    open_path,
    open_stream,
    redact,
)
from planarcal.live.capture_worker import Worker, WorkerTimeoutError

__all__ = ["BACKEND_GRACE_S", "IMAGE_SUFFIXES", "Camera", "Frame"]

Frame = NDArray[np.uint8]
"""A frame: H x W x 3 BGR, or H x W grey, uint8."""

# What a caller of Camera.read() is told to do after a loss; the Tracker, which reopens the
# camera itself, leaves it out of its own warnings.
CLOSED_ADVICE = " The Camera is now closed: open a new one to try again"

BACKEND_GRACE_S = 1.0
"""How much longer than ``timeout_s`` OpenCV's own timeouts are: the caller's guard fires
first, and the backend then frees the stuck worker thread shortly after."""

MAX_TIMEOUT_S = 1e6
"""The longest ``timeout_s`` (11.6 days): OpenCV takes its timeouts in milliseconds as a
32-bit int (2**31 ms is 24.8 days), and a wait much longer overflows threading's own limit."""

_T = TypeVar("_T")


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
        raise ArgumentTypeError(f"{name} must be an int, got {value!r}")
    if value < minimum:
        raise ArgumentError(f"{name} must be at least {minimum}, got {value}")
    return int(value)


def _check_options(
    width: object, height: object, timeout_s: object
) -> tuple[int | None, int | None, float]:
    """Camera's width, height and timeout_s, checked: TypeError for a width or height that is
    not an int, ArgumentError for one below 1 or a timeout that is not a positive number."""
    if width is not None:
        width = _check_positive_int(width, "width", 1)
    if height is not None:
        height = _check_positive_int(height, "height", 1)
    if (
        isinstance(timeout_s, bool)
        or not isinstance(timeout_s, int | float)
        or not (0 < arguments.real("timeout_s", timeout_s) <= MAX_TIMEOUT_S)
    ):
        raise ArgumentError(
            f"timeout_s must be a positive number of seconds, at most {MAX_TIMEOUT_S:g}, got "
            f"{timeout_s!r}"
        )
    return width, height, float(timeout_s)


def _opener(
    source: object, timeout_ms: int, width: int | None, height: int | None, color: bool
) -> tuple[SourceKind, str, Callable[[], Backend]]:
    """What ``source`` names, by its type: the kind (a path counts as a file until it is
    opened, since it may turn out to be a folder), the label for messages, and the function
    that opens it on the worker. TypeError for a source that is none of them."""
    if isinstance(source, bool):
        raise ArgumentTypeError(f"source must be a device index, a URL or a path, got {source!r}")
    if isinstance(source, int | np.integer):
        index = _check_positive_int(source, "a device index", 0)
        label = f"camera device {index}"
        return "device", label, lambda: open_device(index, label, timeout_ms, width, height)
    if isinstance(source, str) and "://" in source:
        local = file_url_path(source)
        if local is None:
            url = source
            label = f"stream {redact(url)!r}"
            return "stream", label, lambda: open_stream(url, label, timeout_ms)
        source = local  # a file:// URL is a file: read to its end, never reopened
    if isinstance(source, str | os.PathLike):
        path = os.fspath(source)
        if not isinstance(path, str) or not path:
            raise ArgumentTypeError(f"source must be a non-empty str path, got {source!r}")
        # "video file ..." or "image folder ..." once opened
        return "file", repr(path), lambda: open_path(path, timeout_ms, width, height, color)
    raise ArgumentTypeError(f"source must be a device index, a URL or a path, got {source!r}")


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
        TypeError: an argument of the wrong type (a source that is no index, URL or path;
            a width or height that is not an int).
        ArgumentError: an argument out of range (a ValueError).

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
        width, height, self._timeout_s = _check_options(width, height, timeout_s)
        self._color = bool(color)
        timeout_ms = round((self._timeout_s + BACKEND_GRACE_S) * 1000)
        self._kind, self._label, opener = _opener(source, timeout_ms, width, height, self._color)

        self._lock = threading.Lock()
        self._slot = BackendSlot()
        self._worker = Worker(name=f"planarcal-camera {self._label}")
        self._frames_read = 0
        self._undecodable = 0
        self._skipped = 0  # the backend's count of a video's undecodable frames
        self._wrong_size = 0
        self._ended = False
        self._closed_because = ""
        self._fps: float | None = None
        self._declared: int | None = None
        self._resolution = (0, 0)
        self._pending: Frame | None = None
        # A folder's undecodable images before its first good one, raised by read() in turn.
        self._pending_errors: list[CameraError] = []
        self._closed = False
        try:
            self._pending = self._open(opener, width, height)
        except BaseException:
            self.close()
            raise

    def _open(self, opener: Callable[[], Backend], width: int | None, height: int | None) -> Frame:
        """Opens the source on the worker and reads its first frame, which sets the
        resolution (and must have the one requested); returns that frame."""
        slot = self._slot

        def open_job() -> Backend:
            backend = opener()
            slot.backend = backend
            return backend

        backend = self._call(open_job, "open")
        self._label = backend.label
        self._kind = backend.kind
        self._fps = backend.fps
        self._declared = backend.declared
        got = self._first_frame()
        if got is None:
            message = self._no_first_frame_message()
            if self._pending_errors:
                message += f"; the first: {self._pending_errors[0]}"
            raise CameraError(message)
        first = got[0]
        self._resolution = (int(first.shape[1]), int(first.shape[0]))
        if (width is not None and width != self._resolution[0]) or (
            height is not None and height != self._resolution[1]
        ):
            raise CameraError(self._resolution_message(width, height))
        return first

    def _first_frame(self) -> tuple[Frame, str] | None:
        """The source's first frame; a folder's images that cannot be decoded are skipped
        (kept for read() to raise) until one can."""
        while True:
            try:
                return self._call(self._read_job, "deliver its first frame")
            except CameraError as e:
                if self._kind != "folder" or self._closed:
                    raise
                self._pending_errors.append(e)

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
    def frames_undecodable(self) -> int:
        """Frames lost because they could not be decoded: a video file's damaged frames,
        skipped by ``read``, and a folder's images that ``read`` raised for."""
        return self._undecodable + self._skipped

    @property
    def frames_wrong_size(self) -> int:
        """Frames ``read`` raised for because their size differs from ``resolution``."""
        return self._wrong_size

    @property
    def frames_declared(self) -> int | None:
        """How many frames a video file's header declares (None if it does not say, and for
        any other source): a file that ends before it has delivered them, undecodable ones
        included, is truncated or damaged at its end."""
        return self._declared

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

        Frames of a video file that cannot be decoded are skipped (``frames_undecodable``
        counts them): the next frame that decodes is returned.

        Raises:
            CameraError: the camera is closed; the file or folder has ended; the camera or
                stream stopped delivering or did not deliver within ``timeout_s`` (either
                closes the Camera, releasing the device: open a new one to retry); an image
                of the folder cannot be decoded (the next ``read`` goes on with the image
                after it); a frame of another resolution.
            ImageError: the backend delivers frames that are not 8-bit images.
        """
        with self._lock:
            self._check_open()
            if self._pending_errors:
                self._undecodable += 1
                raise self._pending_errors.pop(0)
            if self._pending is not None:
                frame, self._pending = self._pending, None
            else:
                frame = self._next_frame()
            self._frames_read += 1
            return frame

    def _next_frame(self) -> Frame:
        """read()'s frame from the backend (the lock held)."""
        if self._ended:
            raise CameraError(self._end_message())
        try:
            got = self._call(self._read_job, "deliver a frame")
        except CameraError:
            if self._kind == "folder" and not self._closed:
                self._undecodable += 1  # an image that cannot be read or decoded
            raise
        if got is None:
            if self._kind in ("file", "folder"):
                self._ended = True
                raise CameraError(self._end_message())
            # Released at once: the device is free for the reopening (and for other
            # programs), and a caller that reads on gets "closed", not a spin of failures.
            because = f" (it stopped delivering after {self._frames_read} frames)"
            self._close_locked(because)
            raise CameraError(
                f"{self._label} stopped delivering after {self._frames_read} frames "
                "(unplugged, connection lost, or the stream ended). Check the cable, "
                "power or network." + CLOSED_ADVICE
            )
        frame, where = got
        if (frame.shape[1], frame.shape[0]) != self._resolution:
            w, h = self._resolution
            self._wrong_size += 1
            raise CameraError(
                f"{self._label} delivered a {frame.shape[1]}x{frame.shape[0]} frame"
                f"{where} after {self._frames_read} frames of {w}x{h}: every frame "
                "must have the same resolution"
            )
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
            self._close_locked("")

    def _close_locked(self, because: str) -> None:
        """close() with the lock held; ``because`` is said by later calls' errors."""
        if self._closed and self._worker.stopped:
            return
        self._closed = True
        self._closed_because = self._closed_because or because
        self._pending = None
        self._pending_errors.clear()
        if not self._worker.stopped:
            try:
                self._worker.call(self._slot.release, self._timeout_s)
            except WorkerTimeoutError:
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
        worker: Worker | None = getattr(self, "_worker", None)
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
        self._skipped = backend.undecodable
        if raw is None:
            return None
        where = backend.where()
        return _as_frame(raw, self._color, f"{self._label}{where}"), where

    def _call(self, fn: Callable[[], _T], action: str) -> _T:
        """Run ``fn`` on the worker, waiting at most timeout_s; on a timeout, close."""
        try:
            return self._worker.call(fn, self._timeout_s)
        except WorkerTimeoutError:
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
        if self._kind == "folder":
            return f"{self._label}: none of its {len(self._pending_errors)} images can be decoded"
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
