"""The source's newest frame, read on its own thread: the page shows what the camera sees
now, so frames the page is too slow for are skipped (counted), never queued.

A video file or an image folder is played at its own frame rate, from its start again at its
end (a recorded cell is set up as a live one). A camera or stream that stops delivering is
reported (``error``) while it is down and reopened, waiting longer each time up to
``REOPEN_MAX_S``, never in a busy loop."""

from __future__ import annotations

import dataclasses
import os
import threading
import time

import numpy as np
from numpy.typing import NDArray

from planarcal.errors import CameraError, ImageError
from planarcal.live.capture import Camera

REOPEN_FIRST_S = 0.5
REOPEN_MAX_S = 5.0
FILE_FPS = 30.0
"""The pace of a folder of images, or of a video file that does not say its rate."""


@dataclasses.dataclass(frozen=True)
class Frame:
    """One frame as read: its number (from 1, over the pump's life), when it was read
    (time.monotonic()) and the image (H x W x 3 BGR uint8)."""

    number: int
    read_at: float
    image: NDArray[np.uint8]


class FramePump:
    """Reads ``source`` (a camera index, video file, stream URL or image folder) on a thread
    and keeps the newest frame. Opens the source at once: CameraError if it cannot."""

    def __init__(self, source: int | str | os.PathLike[str], *, timeout_s: float = 5.0) -> None:
        self.source = source
        self._timeout_s = timeout_s
        self._camera: Camera | None = Camera(source, timeout_s=timeout_s, color=True)
        self.size = self._camera.resolution
        self.label = self._camera.label
        self.live = self._camera.live
        fps = self._camera.fps
        self._period = 0.0 if self.live else 1.0 / (fps if fps and 0 < fps <= 240 else FILE_FPS)
        self._newest: Frame | None = None
        self._changed = threading.Condition()
        self._stop = threading.Event()
        self.frames_read = 0
        self.frames_skipped = 0
        """Frames replaced by a newer one before anybody took them."""
        self.restarts = 0
        """Times a file or folder was played again from its start."""
        self.reopenings = 0
        self.error: str | None = None
        """Why no frames come now (the source lost, being reopened), or None."""
        self._taken = 0
        self._thread = threading.Thread(target=self._run, name="planarcal-live-reader", daemon=True)
        self._thread.start()

    def newest(self, after: int = 0, timeout_s: float = 1.0) -> Frame | None:
        """The newest frame if it is newer than frame number ``after``, waiting up to
        ``timeout_s`` for one; None when none came."""
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while self._newest is None or self._newest.number <= after:
                left = deadline - time.monotonic()
                if left <= 0 or self._stop.is_set():
                    return None
                self._changed.wait(left)
            self._taken = max(self._taken, self._newest.number)
            return self._newest

    def close(self) -> None:
        self._stop.set()
        with self._changed:
            self._changed.notify_all()
        self._thread.join(timeout=self._timeout_s + 1.0)
        if self._camera is not None:
            self._camera.close()

    def _run(self) -> None:
        due = time.monotonic()
        delay = REOPEN_FIRST_S
        while not self._stop.is_set():
            camera = self._camera
            if camera is None:
                camera = self._reopen(delay)
                delay = min(2 * delay, REOPEN_MAX_S) if camera is None else REOPEN_FIRST_S
                continue
            try:
                image = camera.read()
            except CameraError as e:
                self._lost(camera, e)
                continue
            except ImageError as e:  # a frame that is not an 8-bit image: skipped, said
                self.error = f"{self.label}: a frame could not be used: {e}"
                continue
            if self._period:
                due = max(due + self._period, time.monotonic() - self._period)
                self._stop.wait(max(0.0, due - time.monotonic()))
            self._publish(image)

    def _publish(self, image: NDArray[np.uint8]) -> None:
        with self._changed:
            if self._newest is not None and self._newest.number > self._taken:
                self.frames_skipped += 1
            self.frames_read += 1
            self._newest = Frame(self.frames_read, time.monotonic(), image)
            self.error = None
            self._changed.notify_all()

    def _lost(self, camera: Camera, error: CameraError) -> None:
        """A read failed: a file or folder at its end starts again; a camera or stream that
        stopped is closed and reopened; a folder's unreadable image is skipped."""
        if camera.ended:
            self.restarts += 1
        elif not camera.closed:
            self.error = f"{self.label}: {error}"  # one bad image of a folder: read on
            return
        else:
            self.error = f"{self.label} is lost ({error}); reopening it"
        camera.close()
        self._camera = None

    def _reopen(self, delay: float) -> Camera | None:
        """The source opened again, or None (after waiting ``delay``) when it still cannot be."""
        try:
            camera = Camera(self.source, timeout_s=self._timeout_s, color=True)
        except CameraError as e:
            if not self.restarts or self.live:
                self.error = f"{self.label} is lost: {e}; trying again in {delay:.1f} s"
            self._stop.wait(delay)
            return None
        if camera.resolution != self.size:
            w, h = camera.resolution
            self.error = (
                f"{self.label} came back at {w}x{h}, not {self.size[0]}x{self.size[1]}: "
                "restart planarcal live"
            )
            camera.close()
            self._stop.wait(delay)
            return None
        if self.live:
            self.reopenings += 1
        self._camera = camera
        return camera
