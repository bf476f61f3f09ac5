"""The production loop: frames in, object positions in millimetres out, for hours.

``Tracker(calibration, source)`` reads frames from a camera, stream, video file or image
folder (``planarcal.Camera``), finds the objects in each (``detect_objects``), maps all of a
frame's centroids to the plane in one call into the Rust core (with their 1-sigma
uncertainty), and gives each object an ID that it keeps from frame to frame while it stays in
view. Iterating the tracker yields one ``FrameResult`` per frame.

It does not stop on a bad frame:

* a frame that cannot be decoded (a damaged stretch of a video file, a folder's corrupt
  image) is counted (``frames_undecodable``) and skipped, and so is one whose size differs
  from the source's (``frames_wrong_size``);
* a camera or stream that stops delivering (unplugged, a stalled network, a server that
  closes the connection), or that is not there yet when the tracker starts (still booting),
  is opened again with exponential back-off, from ``REOPEN_FIRST_S`` up to
  ``REOPEN_MAX_S`` between attempts, for as long as it takes unless ``max_reconnect_s``
  says otherwise (``camera_lost``, ``camera_reconnects``, ``camera_down_s``); a file or
  folder is never reopened: it ends at its end, and one that cannot be opened fails at once;
* a frame whose processing fails (a detector error) is counted (``failed``) and skipped.

Each fault is logged (logger ``planarcal.live.tracker``, a warning; repeated frame faults at
their 1st, 2nd, 4th, 8th, ... occurrence, so a stream of bad frames does not flood the log; a
camera that is down at each attempt to reopen it until the back-off reaches its maximum, then
once a minute).

It does stop on a source whose frames are not of the size the calibration was made on: that
is a mistake of setup, not a bad frame, and every frame would map to the wrong millimetres.
``FrameSizeError`` (naming both sizes) is raised by the constructor when the source is open,
else by the iteration at the first such frame (a camera that comes back at another
resolution).

Reading runs on its own thread, a couple of frames ahead, so decoding overlaps with
processing (OpenCV releases the GIL while it decodes and filters; the core releases it while
it measures a frame's outlines, the bulk of its work).
With a live source, frames that arrive while the loop is still busy with an older one are
dropped, the oldest first, and counted (``frames_dropped``): a robot wants the newest
positions.
With a file or folder nothing is dropped: the reader waits for the loop.

IDs: nearest-neighbour association in world coordinates. Each object of a frame takes the ID
of the nearest track of the previous frames within ``max_jump_mm``, closest pairs first;
objects left over start new tracks; a track unseen for more than ``max_missing`` frames ends.

Positions are in the board's frame or, with ``frame="robot"`` (the default once the
calibration has a registration), the robot's base frame. The association works in that
frame; ``max_jump_mm`` means the same in either, since a rigid registration keeps distances
(a similarity or affine one changes them by its scale, a fraction of a percent for a board
printed true).
"""

from __future__ import annotations

import dataclasses
import inspect
import logging
import math
import os
import queue
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal import _core, arguments
from planarcal.calib.calibration import Calibration
from planarcal.calib.object_settings import detect_options_with
from planarcal.errors import ArgumentError, CameraError, FrameSizeError, ImageError, StateError
from planarcal.live.capture import CLOSED_ADVICE, Camera, Frame
from planarcal.live.capture_sources import file_url_path
from planarcal.live.local_map import STEP_PX
from planarcal.live.objects import _detect, detect_objects
from planarcal.robot.output_frame import Coords, checked_frame

F64 = NDArray[np.float64]

__all__ = ["FrameResult", "LoopStats", "TrackedObject", "Tracker"]

_log = logging.getLogger("planarcal.live.tracker")

REOPEN_FIRST_S = 0.1
"""The wait before the first attempt to reopen a camera or stream that stopped, s; it doubles
after each failed attempt (and after a camera that failed again soon after it was reopened)."""

REOPEN_MAX_S = 5.0
"""The longest wait between two attempts to reopen a camera or stream, s."""

REOPEN_REPORT_S = 60.0
"""Once the wait is at its longest, a failed attempt is reported about this often, s (each
one before: a camera down for hours does not flood the log)."""

# The options detect_objects takes (its keyword arguments).
_DETECT_OPTIONS = frozenset(inspect.signature(detect_objects).parameters) - {"image"}


@dataclasses.dataclass(frozen=True, slots=True)
class TrackedObject:
    """One object in one frame."""

    id: int
    """Stable while the object stays in view (1, 2, ... in order of first appearance)."""
    centroid_px: tuple[float, float]
    world_mm: tuple[float, float]
    std_mm: float
    """The calibration's 1-sigma uncertainty of world_mm (RMS distance, mm)."""
    area_px: float
    angle_deg: float | None
    """The part's principal axis in the output frame, degrees in [-90, 90); None where the
    part is too round for an axis to mean anything."""


@dataclasses.dataclass(frozen=True, slots=True, eq=False)
class FrameResult:
    """One frame's objects: arrays with a row per object, in the detector's reading order
    (rows from the top); ``objects`` and the JSON line give them by ID."""

    index: int
    """0-based position of the frame in the source (skipped frames keep their numbers)."""
    timestamp: float
    """When the frame was read, seconds since the epoch (time.time())."""
    ids: NDArray[np.int64]
    centroids_px: F64
    """(n, 2) px."""
    world_mm: F64
    """(n, 2) mm on the plane."""
    std_mm: F64
    """The calibration's 1-sigma uncertainty of each world_mm (RMS distance, mm)."""
    areas_px: F64
    angles_deg: F64
    """Each part's principal axis in the output frame, degrees in [-90, 90); NaN where the
    part is too round for an axis to mean anything."""
    coords: str
    """The frame of reference of world_mm and angles_deg: "board" or "robot"."""

    @property
    def objects(self) -> tuple[TrackedObject, ...]:
        """The frame's objects, ordered by ID (built on each access: the loop itself, and
        to_json, work from the arrays)."""
        order = np.argsort(self.ids, kind="stable")
        return tuple(
            map(
                TrackedObject,
                self.ids[order].tolist(),
                map(tuple, self.centroids_px[order].tolist()),
                map(tuple, self.world_mm[order].tolist()),
                self.std_mm[order].tolist(),
                self.areas_px[order].tolist(),
                [a if math.isfinite(a) else None for a in self.angles_deg[order].tolist()],
            )
        )

    def to_json(self) -> str:
        """One compact JSON line (no newline): frame, t, coords (the frame of reference), and
        each object's id, px, mm, std_mm, angle_deg (null: too round), by ID (positions to
        1e-3 px and 1e-4 mm, angles to 1e-2 degree)."""
        return _core.frame_json(
            self.index,
            self.timestamp,
            self.ids,
            self.centroids_px,
            self.world_mm,
            self.std_mm,
            self.angles_deg,
            self.coords,
        )


@dataclasses.dataclass
class LoopStats:
    """What the loop did so far."""

    read: int = 0
    """Frames taken from the source: processed, failed, undecodable, of the wrong size or
    dropped."""
    frames: int = 0
    """Frames processed and yielded."""
    objects: int = 0
    """Objects located, over all frames."""
    frames_undecodable: int = 0
    """Frames that could not be decoded (skipped)."""
    frames_wrong_size: int = 0
    """Frames whose size differs from the source's first frame (skipped)."""
    failed: int = 0
    """Frames whose processing raised (counted, skipped)."""
    frames_dropped: int = 0
    """Frames of a live source dropped because the loop was busy."""
    frames_declared: int | None = None
    """The number of frames a video file's header declares (None: not a file, or unknown)."""
    frames_missing: int = 0
    """Frames a video file's header declares that it neither delivered nor counted as
    undecodable (lost in a damaged stretch, or to a truncated end): as exact as the header's
    count."""
    camera_lost: int = 0
    """Times the camera or stream stopped delivering (and was closed, to be reopened)."""
    camera_reconnects: int = 0
    """Times the camera or stream was reopened after it stopped delivering."""
    camera_down_s: float = 0.0
    """Seconds during which the camera or stream was not open: lost and being reopened, or
    not there yet at the start."""
    started: float = dataclasses.field(default_factory=time.monotonic)
    stage_s: dict[str, float] = dataclasses.field(
        default_factory=lambda: {"read": 0.0, "detect": 0.0, "map": 0.0, "track": 0.0}
    )
    """Seconds spent in each stage (read: waiting for the reader thread)."""

    @property
    def elapsed_s(self) -> float:
        return time.monotonic() - self.started

    @property
    def fps(self) -> float:
        e = self.elapsed_s
        return self.frames / e if e > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        out = {k: v for k, v in dataclasses.asdict(self).items() if k != "started"}
        out["camera_down_s"] = round(self.camera_down_s, 3)
        out["elapsed_s"] = round(self.elapsed_s, 3)
        out["fps"] = round(self.fps, 2)
        out["stage_s"] = {k: round(v, 4) for k, v in self.stage_s.items()}
        return out


class _End:
    """The reader's last word: the source ended, or gave up with `error`."""

    def __init__(self, error: BaseException | None = None) -> None:
        self.error = error


class Tracker:
    """Frames from ``source`` -> objects in millimetres, per frame; see the module docstring.

    Args:
        calibration: a Calibration (or a path to a calibration file).
        source: a device index, stream URL, video file, image folder, or an open Camera;
            None for a tracker fed only through ``process()`` (the live page's, whose
            frames come from its own reader).
        height_mm: the objects' height above the plane (their tops are located where they
            are; needs a calibration with intrinsics).
        max_jump_mm: the farthest an object may move between frames and keep its ID.
        max_missing: frames an object may go unseen and keep its ID.
        max_frames: stop after reading this many frames from the source, whatever became of
            them (processed, failed, undecodable, of the wrong size or dropped; None: until
            the source ends or stop()).
        max_reconnect_s: give up reopening a source that stopped after this long (None:
            never; a file or folder is never reopened).
        detect_options: passed to detect_objects (min_area_px, max_area_px, roi,
            blur_sigma, mask, ...), over the calibration's object settings
            (``calibration.object_settings``) field by field: an option given (None
            included) replaces the setting of its name, the others are the calibration's.
            ``tracker.detect_options`` is what each frame is detected with.
        timeout_s: the Camera's timeout for each blocking step.
        frame: "board" or "robot", the frame of reference of the positions (and of
            ``FrameResult.coords``); None (the default): "robot" if the calibration has a
            registration to the robot, else "board".

    Raises:
        FrameSizeError: the source's frames are not of the size the calibration was made on.
        IntrinsicsError: a height_mm with a calibration made without camera intrinsics.
        ArgumentError: frame="robot" with a calibration that has no registration; an
            unknown detect option, or options that with the calibration's settings are not
            valid ones (a negative area, a minimum above the maximum, an roi beyond the
            calibration's image).
    """

    def __init__(
        self,
        calibration: Calibration | str | os.PathLike[str],
        source: int | str | os.PathLike[str] | Camera | None,
        *,
        height_mm: float = 0.0,
        max_jump_mm: float = 25.0,
        max_missing: int = 5,
        max_frames: int | None = None,
        max_reconnect_s: float | None = None,
        detect_options: dict[str, Any] | None = None,
        timeout_s: float = 5.0,
        frame: Coords | None = None,
    ) -> None:
        if not isinstance(calibration, Calibration):
            calibration = Calibration.load(calibration)
        self.calibration = calibration
        for name, value in (("height_mm", height_mm), ("max_jump_mm", max_jump_mm)):
            # arguments.real: 10**400 is not finite either (float() would overflow).
            if not isinstance(value, int | float) or isinstance(value, bool):
                raise ArgumentError(f"{name} must be a finite number, got {value!r}")
            arguments.real(name, value)
        if max_jump_mm <= 0:
            raise ArgumentError(f"max_jump_mm must be > 0, got {max_jump_mm!r}")
        if (
            isinstance(max_missing, bool)
            or not isinstance(max_missing, int)
            or not 0 <= max_missing <= sys.maxsize  # the core counts frames in a usize
        ):
            raise ArgumentError(
                f"max_missing must be a whole number >= 0 and at most {sys.maxsize}, got "
                f"{max_missing!r}"
            )
        if max_frames is not None and (
            isinstance(max_frames, bool) or not isinstance(max_frames, int) or max_frames < 0
        ):
            raise ArgumentError(f"max_frames must be a whole number >= 0, got {max_frames!r}")
        self.height_mm = float(height_mm)
        self.max_jump_mm = float(max_jump_mm)
        self.max_missing = max_missing
        self.max_frames = max_frames
        self.max_reconnect_s = max_reconnect_s
        given = dict(detect_options or {})
        unknown = sorted(set(given) - _DETECT_OPTIONS)
        if unknown:
            raise ArgumentError(
                f"unknown detect_options {unknown}; detect_objects takes {sorted(_DETECT_OPTIONS)}"
            )
        self.detect_options = detect_options_with(
            calibration.object_settings, given, calibration.image_size
        )
        """detect_objects' options for every frame: the calibration's object settings with
        those given over them."""
        self.frame: Coords = checked_frame(frame, calibration.robot_frame)
        """The frame of reference of the positions: "board" or "robot"."""
        # Checked before the source is opened: a height needs the camera's pose, the robot's
        # frame a registration.
        self._map = calibration._frame_mapper(self.height_mm, self.frame)
        self._frame_size = calibration.image_size
        self.stats = LoopStats()
        self._timeout_s = timeout_s
        self._camera: Camera | None = None
        self._spec: int | str | os.PathLike[str] = ""
        if isinstance(source, Camera):
            self._camera = source
            self._spec = source.source
        elif source is not None:
            self._spec = source
            try:
                self._camera = Camera(source, timeout_s=timeout_s, color=False)
            except CameraError as e:
                if not _live_spec(source):
                    raise
                # A camera or stream that is not there yet: the reader waits for it as for
                # one that dropped out.
                _log.warning("camera down: %s; waiting for it", e)
                self._camera = None
        if self._camera is not None:
            self._check_source_size(self._camera, opened_here=not isinstance(source, Camera))
        self._live = _live_spec(self._spec) if self._camera is None else self._camera.live
        self._ever_opened = self._camera is not None
        # The camera's state for the reopening: since when it is down (monotonic; None while
        # it is open) and why, when it was last opened, the wait before the next attempt.
        self._down_since: float | None = None if self._camera is not None else time.monotonic()
        self._down_reason = "" if self._camera is not None else "not there yet"
        self._opened_at = time.monotonic()
        self._delay = REOPEN_FIRST_S
        # The camera's loss counters already added to the stats (the camera's own count).
        self._seen = (0, 0)
        self._stop = threading.Event()
        # Bounded: the reader runs at most this many frames ahead of the loop.
        self._queue: queue.Queue[tuple[int, float, Frame] | _End] = queue.Queue(maxsize=2)
        self._reader: threading.Thread | None = None
        self._tracks = _core.Tracks(self.max_jump_mm, max_missing)
        self._closed = False
        self.first_error: BaseException | None = None
        """The first frame-level fault (a corrupt frame, a detector error), for logs."""
        self.last_error: BaseException | None = None
        """The most recent frame-level fault (a corrupt frame, a detector error), for logs."""

    def _check_source_size(self, camera: Camera, *, opened_here: bool) -> None:
        """FrameSizeError at once if the source's frames are not the calibration's size (a
        camera this tracker opened is closed first)."""
        try:
            self.calibration.check_image_size(camera.resolution, what="frame")
        except FrameSizeError:
            if opened_here:
                camera.close()
            raise

    # -- the loop --------------------------------------------------------------------------

    def __iter__(self) -> Iterator[FrameResult]:
        if self._reader is not None:
            raise StateError("a Tracker can be iterated once")
        if self._spec == "":
            raise StateError("a Tracker made without a source is fed with process(), not iterated")
        self.stats = LoopStats()
        self._reader = threading.Thread(
            target=self._read_loop, name="planarcal-reader", daemon=True
        )
        self._reader.start()
        try:
            while not self._stop.is_set():
                t0 = time.perf_counter()
                item = self._next_item()
                self.stats.stage_s["read"] += time.perf_counter() - t0
                if item is None:
                    continue
                if isinstance(item, _End):
                    if item.error is not None:
                        raise item.error
                    break
                index, stamp, frame = item
                try:
                    result = self.process(frame, index, stamp)
                except FrameSizeError:
                    raise  # not a bad frame: the source does not match the calibration
                except (ValueError, ArithmeticError) as e:  # a frame the detector chokes on
                    self.stats.failed += 1
                    self._record_fault(e)
                    _log_fault("frame %d failed: %s", self.stats.failed, index, e)
                    continue
                self.stats.frames += 1
                self.stats.objects += len(result.objects)
                yield result
        finally:
            self.close()

    def process(self, frame: Frame, index: int = 0, timestamp: float | None = None) -> FrameResult:
        """One frame's objects, tracked against the frames before it. FrameSizeError if the
        frame is not of the size the calibration was made on."""
        if not isinstance(frame, np.ndarray) or frame.ndim not in (2, 3):
            what = f"shape {frame.shape}" if isinstance(frame, np.ndarray) else type(frame).__name__
            raise ImageError(f"frame must be an image array (H x W or H x W x 3), got {what}")
        size = (frame.shape[1], frame.shape[0])
        if self._frame_size is not None and size != self._frame_size:
            self.calibration.check_image_size(size, what="frame")
        stamp = time.time() if timestamp is None else timestamp
        stage = self.stats.stage_s
        t0 = time.perf_counter()
        found = _detect(frame, outlines=False, **self.detect_options)
        t1 = time.perf_counter()
        stage["detect"] += t1 - t0
        px = found.centroids
        # One call maps the whole frame (and its uncertainty) in the core, at each centroid
        # and the points round it that give the mapping's derivatives there (see
        # planarcal.live.local_map); one more gives each part's centroid on the plane and its
        # axis turned into the output frame (part_angle). The centroids' own 1-sigma is that
        # of the samples' first block, the only one that needs it.
        samples = _core.part_samples(px, STEP_PX)
        mapped, std = self._map(samples, len(px)) if len(px) else (samples, samples[:, 0])
        mm, _, angles, _, _, _ = _core.part_poses(mapped, found.moments, found.areas, STEP_PX)
        t2 = time.perf_counter()
        stage["map"] += t2 - t1
        ids = self._tracks.update(mm)
        result = FrameResult(index, stamp, ids, px, mm, std, found.areas, angles, self.frame)
        stage["track"] += time.perf_counter() - t2
        return result

    @property
    def tracks(self) -> dict[int, tuple[float, float]]:
        """The live tracks: each ID's last world position, mm (an object unseen for up to
        max_missing frames keeps its track)."""
        ids, mm = self._tracks.live()
        return dict(zip(ids.tolist(), map(tuple, mm.tolist()), strict=True))

    @property
    def source_lost(self) -> bool:
        """True while the source delivers nothing because it is not open: not there yet at
        start, or stopped and being reopened (safe from any thread)."""
        camera = self._camera
        return camera is None or camera.closed

    @property
    def source_down(self) -> str | None:
        """Why the source delivers nothing now, and for how long, while ``source_lost``;
        else None (safe from any thread)."""
        if not self.source_lost or self._stop.is_set():
            return None
        since = self._down_since
        down = f" for {time.monotonic() - since:.1f} s" if since is not None else ""
        return f"camera down{down}: not delivering frames ({self._down_reason})"

    def stop(self) -> None:
        """Ends the iteration after the frame in hand (safe from a signal handler or another
        thread)."""
        self._stop.set()

    def close(self) -> None:
        """Stops the reader and releases the source. Idempotent."""
        self._stop.set()
        if self._closed:
            return
        self._closed = True
        # Unblock a reader waiting to put a frame.
        while True:
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break
        if self._reader is not None:
            self._reader.join(timeout=self._timeout_s + 1.0)
        if self._camera is not None:
            self._camera.close()
        since, self._down_since = self._down_since, None
        if since is not None:  # still down at the end: that time counts too
            self.stats.camera_down_s += time.monotonic() - since

    def __enter__(self) -> Tracker:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- reading (on the reader thread) ------------------------------------------------------

    def _record_fault(self, error: BaseException) -> None:
        """Keeps the first and the latest frame-level fault (from either thread)."""
        if self.first_error is None:
            self.first_error = error
        self.last_error = error

    def _next_item(self) -> tuple[int, float, Frame] | _End | None:
        try:
            return self._queue.get(timeout=0.1)
        except queue.Empty:
            return None  # wake up to look at the stop flag

    def _put(self, item: tuple[int, float, Frame] | _End) -> None:
        """Hands a frame to the loop: a live source drops the oldest waiting frame when the
        loop is behind; a file waits (nothing is lost)."""
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.1)
                return
            except queue.Full:
                if self._live and not isinstance(item, _End):
                    try:
                        self._queue.get_nowait()
                        self.stats.frames_dropped += 1
                    except queue.Empty:
                        pass

    def _read_loop(self) -> None:
        index = 0  # frames read so far (the next frame's index)
        try:
            while not self._stop.is_set():
                if self.max_frames is not None and index >= self.max_frames:
                    self._put(_End())
                    return
                camera = self._camera
                if camera is None or camera.closed:
                    camera = self._reopen()
                    if camera is None:
                        return
                next_index = self._read_one(camera, index)
                if next_index is None:
                    return
                index = next_index
        except BaseException as e:  # never die silently: the loop re-raises it
            self._put(_End(e))

    def _read_one(self, camera: Camera, index: int) -> int | None:
        """Reads one frame and hands it to the loop, or counts why there is none; the next
        frame's index, or None at the end of a file or folder."""
        try:
            frame = camera.read()
        except CameraError as e:
            if camera.ended:
                index = self._count_skipped(camera, index, raised=False)
                self._file_ended(camera)
                self._put(_End())
                return None
            if camera.closed and not self._live:  # a file that hung: not reopened
                self._put(_End(e))
                return None
            if camera.closed:  # stopped delivering (and released): reopen with back-off
                self._lost(e)
                return index
            # A folder's image that cannot be decoded, or a frame of the wrong size.
            index = self._count_skipped(camera, index, raised=True)
            self.stats.read += 1
            self._record_fault(e)
            faults = self.stats.frames_undecodable + self.stats.frames_wrong_size
            _log_fault("frame %d skipped: %s", faults, index, e)
            return index + 1
        index = self._count_skipped(camera, index, raised=False)
        self.stats.read += 1
        self._put((index, time.time(), frame))
        return index + 1

    def _count_skipped(self, camera: Camera, index: int, *, raised: bool) -> int:
        """Adds the camera's new losses to the stats; the frames a video skipped without
        raising (undecodable) take their indices, so the next frame's index is returned."""
        undecodable, wrong = _losses(camera)
        new_u, new_w = undecodable - self._seen[0], wrong - self._seen[1]
        self._seen = (undecodable, wrong)
        self.stats.frames_undecodable += new_u
        self.stats.frames_wrong_size += new_w
        skipped = new_u + new_w - (1 if raised else 0)
        if skipped > 0:
            self.stats.read += skipped
            which = f"frames {index} to {index + skipped - 1}" if skipped > 1 else f"frame {index}"
            error = CameraError(
                f"{camera.label}: {skipped} frame{'s' if skipped > 1 else ''} could not be "
                f"decoded ({which}); skipped"
            )
            self._record_fault(error)
            _log.warning("%s (%d undecodable so far)", error, self.stats.frames_undecodable)
        return index + max(skipped, 0)

    def _file_ended(self, camera: Camera) -> None:
        """Says so when a video file ended before the frames its header declares."""
        declared: int | None = getattr(camera, "frames_declared", None)
        self.stats.frames_declared = declared
        got = getattr(camera, "frames_read", 0) + sum(_losses(camera))
        if declared is not None and got < declared:
            # FFmpeg may pass over several damaged frames in one failed read, and a truncated
            # file's last frames are never reached: the header's count tells how many.
            self.stats.frames_missing = declared - got
            _log.warning(
                "%s ended after %d of the %d frames its header declares: %d more were lost "
                "(passed over in a damaged stretch, or the file is truncated or damaged at "
                "its end)",
                camera.label,
                got,
                declared,
                declared - got,
            )

    def _lost(self, error: CameraError) -> None:
        """Counts and reports a camera or stream that stopped delivering (it is closed)."""
        now = time.monotonic()
        self.stats.camera_lost += 1
        reason = str(error).removesuffix(CLOSED_ADVICE)  # the tracker reopens it itself
        self._down_since, self._down_reason = now, reason
        # A camera that stayed up a while starts the back-off afresh; one that fails again
        # soon after it was reopened waits longer each time (no tight open-fail cycle).
        if now - self._opened_at >= REOPEN_MAX_S:
            self._delay = REOPEN_FIRST_S
        elif self.stats.camera_lost > 1:
            self._delay = min(2 * self._delay, REOPEN_MAX_S)
        _log.warning("camera lost: %s; reopening in %.1f s (attempt 1)", reason, self._delay)

    def _reopen(self) -> Camera | None:
        """Reopens the source with exponential back-off; None if stopped, out of time, or not
        a camera or stream (a file or folder is not reopened)."""
        if not self._live:
            self._put(_End())
            return None
        start = self._down_since if self._down_since is not None else time.monotonic()
        attempt = 0
        while not self._stop.wait(self._delay):
            attempt += 1
            try:
                camera = Camera(self._spec, timeout_s=self._timeout_s, color=False)
            except CameraError as e:
                if not self._reopen_failed(e, start, attempt):
                    return None
                continue
            now = time.monotonic()
            self._camera, self._seen, self._opened_at = camera, (0, 0), now
            self.stats.camera_reconnects += self._ever_opened
            self.stats.camera_down_s += now - start
            self._down_since = None
            again = "again " if self._ever_opened else ""
            self._ever_opened = True
            _log.warning(
                "camera back: %s open %safter %.1f s (attempt %d)",
                camera.label,
                again,
                now - start,
                attempt,
            )
            return camera
        return None

    def _reopen_failed(self, error: CameraError, start: float, attempt: int) -> bool:
        """Logs a failed attempt and lengthens the wait; False (after ending the loop with
        the reason) once ``max_reconnect_s`` has passed."""
        waited = time.monotonic() - start
        self._down_reason = str(error)
        if self.max_reconnect_s is not None and waited >= self.max_reconnect_s:
            why = (
                f"gave up reopening {self._spec!r} after {waited:.1f} s ({attempt} attempts): "
                f"{error}"
            )
            self._put(_End(CameraError(why)))
            return False
        growing = self._delay < REOPEN_MAX_S
        self._delay = min(2 * self._delay, REOPEN_MAX_S)
        if growing or attempt % max(1, round(REOPEN_REPORT_S / REOPEN_MAX_S)) == 0:
            _log.warning(
                "camera down for %.1f s: %s; reopening in %.1f s (attempt %d)",
                waited,
                error,
                self._delay,
                attempt + 1,
            )
        return True

    # -- tracking ----------------------------------------------------------------------------


def _live_spec(source: object) -> bool:
    """A camera device index or a stream's URL (as Camera tells them from paths; a file://
    URL is a file)."""
    if isinstance(source, bool):
        return False
    if isinstance(source, str):
        return "://" in source and file_url_path(source) is None
    return isinstance(source, int | np.integer)


def _losses(camera: Camera) -> tuple[int, int]:
    """The camera's frames_undecodable and frames_wrong_size; a Camera-like source without
    these counters (a wrapper around a Camera) counts none."""
    return getattr(camera, "frames_undecodable", 0), getattr(camera, "frames_wrong_size", 0)


def _log_fault(message: str, count: int, *args: object) -> None:
    """Logs the 1st, 2nd, 4th, 8th, ... fault of a kind (with how many so far)."""
    if count & (count - 1) == 0:
        _log.warning(message + " (%d so far)", *args, count)
