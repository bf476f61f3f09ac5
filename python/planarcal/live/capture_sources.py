"""What a Camera reads from, opened by what the source is: a camera device, a stream URL, a
video file (all three through cv2.VideoCapture, with OpenCV's own timeouts where the backend
has them), or a folder of images read in natural order. Everything here runs on the Camera's
worker thread, so it may block; every failure is a ``CameraError`` that says what to check.
"""

from __future__ import annotations

import glob
import math
import os
import re
import stat
import sys
import urllib.parse
from typing import Any, Literal, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.errors import CameraError

__all__ = [
    "IMAGE_SUFFIXES",
    "MAX_UNDECODABLE_RUN",
    "Backend",
    "BackendSlot",
    "SourceKind",
    "file_url_path",
    "open_device",
    "open_path",
    "open_stream",
    "redact",
]

IMAGE_SUFFIXES = frozenset(
    {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm", ".pnm", ".jp2"}
)
"""The suffixes (case-insensitive) of the files read from an image folder."""

MAX_UNDECODABLE_RUN = 500
"""How many frames in a row of a video file may fail to decode before the file counts as
ended. FFmpeg's read fails at a damaged stretch and goes on after it (a damaged packet is
consumed by each failed read), so stopping at the first failure would end the run at the
damage; at the true end every read fails at once, so the retries cost well under a second."""

SourceKind = Literal["device", "stream", "file", "folder"]
"""What a source is: a device and a stream are live (frames are lost if not read), a file and
a folder are read at the reader's pace."""


class Backend:
    """What a Camera reads from: ``read`` returns a raw frame, or None at the end."""

    kind: SourceKind
    label: str
    fps: float | None = None
    declared: int | None = None
    """The number of frames a video file's header declares (None: unknown, or not a file)."""
    undecodable: int = 0
    """Frames of a video file that could not be decoded and were skipped so far."""

    def read(self) -> NDArray[Any] | None:
        raise NotImplementedError

    def where(self) -> str:
        """Which frame the last ``read`` returned, for messages."""
        return ""

    def release(self) -> None:
        """Free the device, connection or file. Idempotent."""


class _VideoBackend(Backend):
    """A cv2.VideoCapture: camera, stream or video file."""

    def __init__(self, kind: SourceKind, label: str, cap: Any) -> None:
        self.kind = kind
        self.label = label
        self.cap: Any = cap
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        self.fps = fps if math.isfinite(fps) and fps > 0 else None
        count = float(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if kind == "file" else math.nan
        self.declared = int(count) if math.isfinite(count) and count > 0 else None
        self.undecodable = 0

    def read(self) -> NDArray[Any] | None:
        # A camera or stream that fails a read has stopped (the caller closes it); a file
        # is read past a damaged stretch, whose frames are counted in `undecodable`.
        failed = 0
        while True:
            ok, frame = self.cap.read()
            if ok and frame is not None and frame.size:
                self.undecodable += failed
                return cast(NDArray[Any], frame)
            failed += 1
            if self.kind != "file" or failed >= MAX_UNDECODABLE_RUN:
                return None

    def release(self) -> None:
        cap, self.cap = self.cap, None
        if cap is not None:
            cap.release()


class _FolderBackend(Backend):
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
                "image. Replace or remove it; reading goes on with the next image"
            )
        return image

    def where(self) -> str:
        return f" ({self.files[self.next - 1]!r})" if self.next else ""


class BackendSlot:
    """Holds the backend so that a job queued after a stuck one can still release it."""

    backend: Backend | None = None

    def release(self) -> None:
        backend, self.backend = self.backend, None
        if backend is not None:
            backend.release()


def file_url_path(source: str) -> str | None:
    """The path a ``file://`` URL names (``file:///abs/clip.mp4``, ``file://clip.mp4`` relative
    to the working directory, ``file://localhost/abs/clip.mp4``), or None for any other
    source: a file is read to its end, not reopened like a stream."""
    if source[:7].lower() != "file://":
        return None
    parts = urllib.parse.urlsplit(source)
    host = "" if parts.netloc.lower() == "localhost" else parts.netloc
    return urllib.parse.unquote(host + parts.path)


def _natural_key(name: str) -> tuple[tuple[int | str, ...], str]:
    """Sort key: runs of digits compare as numbers (img2 < img10), the rest case-blind."""
    parts = re.split(r"(\d+)", name.casefold())
    return tuple(int(p) if i % 2 else p for i, p in enumerate(parts)), name


def redact(url: str) -> str:
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


def open_device(
    target: int | str, label: str, timeout_ms: int, width: int | None, height: int | None
) -> Backend:
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


def open_stream(url: str, label: str, timeout_ms: int) -> Backend:
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


def _open_file(path: str, label: str, timeout_ms: int) -> Backend:
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


def _open_folder(path: str, label: str, color: bool) -> Backend:
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


def open_path(
    path: str, timeout_ms: int, width: int | None, height: int | None, color: bool
) -> Backend:
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
        return open_device(path, f"camera device {path!r}", timeout_ms, width, height)
    return _open_file(path, f"video file {path!r}", timeout_ms)
