"""The live page's state and its actions: one session per server, shared by every browser.

Two threads work on the source's newest frame (``frames.FramePump``): the *analysis* finds
the board (set-up and register views: ``live_detection``, focus and exposure on it) or the
parts (watch view: the production loop's ``Tracker.process``), as fast as it can; the
*display* draws the newest analysis on every new frame and encodes it as JPEG, so the image
keeps the source's pace even when an analysis takes longer than a frame.

The actions (capture, calibrate, save, pick, touches, register, settings) are the CLI's own
code: a calibration is fitted by ``commands.calibrate.fit_calibration`` from the captured
frames (so the file saved is, to the bit, the one ``planarcal calibrate`` writes from those
frames as PNG files), a registration by ``robot.register_command.register_touches`` from the
touch CSV (as ``planarcal register``). Changes are made one at a time (``_writing``); the
only file written is the calibration file the session was given, atomically."""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import functools
import math
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.board_focus import board_focus
from planarcal.calib.boards import Board
from planarcal.calib.calibration import Calibration
from planarcal.calib.coverage import Coverage, calibration_coverage
from planarcal.calib.detection import BoardDetection
from planarcal.calib.extrapolation import convex_hull
from planarcal.calib.json_number import json_ready
from planarcal.calib.object_settings import ObjectSettings
from planarcal.commands.calibrate import detect_image, fit_calibration
from planarcal.errors import (
    ArgumentError,
    BoardNotFoundError,
    BusyError,
    Error,
    FrameSizeError,
    NotFoundError,
    StateError,
)
from planarcal.files import atomic_write
from planarcal.live.line_format import LineFormat
from planarcal.live.output_server import ServerOutput
from planarcal.live.output_server_stats import ServerStats
from planarcal.live.output_sink import Output
from planarcal.live.tracker import FrameResult, Tracker
from planarcal.report.drawing import png_bytes
from planarcal.robot.handedness import HANDEDNESS, Handedness
from planarcal.robot.register_command import Registered, register_touches
from planarcal.robot.summary import quality
from planarcal.robot.touch_csv import read_touch_csv
from planarcal.web import overlay
from planarcal.web.frames import Frame, FramePump
from planarcal.web.live_detection import LiveDetector, points_text

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]

MODES = ("setup", "register", "watch")
WRITE_WAIT_S = 30.0
"""How long a change waits for the one before it (a calibration takes a second or two)."""
FRAME_WAIT_S = 2.0
"""How long an action waits for a frame (capture, pick)."""
STALE_S = 1.0
"""An analysis older than this is not drawn (the view changed, the source stalled)."""
RATE_WINDOW_S = 2.0
"""Frame rates are counted over this last stretch of time."""
PICK_PITCHES = 0.6
"""A click picks the nearest board point within this many pitches of it."""
TOUCHES_FILE = "touches.csv"
SAME_PLACE_PITCHES = 0.5
"""A board whose points lie within this many pitches of a placement's lies at its place."""


@dataclasses.dataclass(frozen=True)
class Captured:
    """A placement captured from the live image."""

    name: str
    """Its image's name ("placement-1.png"), recorded in the calibration file as the
    command records its IMAGE names."""
    image: U8
    detection: BoardDetection

    @property
    def outline_px(self) -> F64:
        return convex_hull(self.detection.image_points)


@dataclasses.dataclass(frozen=True)
class Feed:
    """The watch view's frames as ``planarcal run`` writes them: its output (opened from
    ``run.output_plan``), the line format, and whether controllers ask for each frame
    (trigger mode)."""

    output: Output
    format: LineFormat
    trigger: bool = False

    def feed(self, result: FrameResult) -> None:
        if self.trigger and isinstance(self.output, ServerOutput):
            self.output.answer(result.timestamp, functools.partial(self.format.frame, result))
        else:
            self.output.send(self.format.frame(result))

    def state(self) -> dict[str, Any]:
        """Where the lines go, how many got there and were lost; a server's controllers."""
        stats = self.output.stats
        out: dict[str, Any] = {
            "spec": str(getattr(self.output, "spec", "")),
            "sent": stats.sent,
            "dropped": stats.dropped,
        }
        if isinstance(stats, ServerStats):
            out["address"] = stats.address
            out["controllers"] = [
                {"peer": c.peer, "sent": c.sent, "dropped": c.dropped}
                for c in stats.per_client
                if c.connected
            ]
        return out

    def close(self) -> None:
        self.output.close()


@dataclasses.dataclass(frozen=True)
class Analysis:
    """What the analysis found in one frame."""

    number: int
    done_at: float
    mode: str
    detection: BoardDetection | None = None
    message: str | None = None
    focus: dict[str, Any] | None = None
    parts: tuple[dict[str, Any], ...] = ()


class Rate:
    """Events per second over the last RATE_WINDOW_S, and the mean of a figure per event."""

    def __init__(self) -> None:
        self._events: collections.deque[tuple[float, float]] = collections.deque()

    def add(self, value: float = 0.0) -> None:
        now = time.monotonic()
        self._events.append((now, value))
        while self._events and now - self._events[0][0] > RATE_WINDOW_S:
            self._events.popleft()

    @property
    def per_s(self) -> float:
        now = time.monotonic()
        recent = [t for t, _ in self._events if now - t <= RATE_WINDOW_S]
        if len(recent) < 2:
            return 0.0
        return (len(recent) - 1) / max(recent[-1] - recent[0], 1e-9)

    @property
    def mean(self) -> float | None:
        values = [v for _, v in self._events]
        return sum(values) / len(values) if values else None


class LiveSession:
    """The page's state over ``pump``'s frames.

    Args:
        pump: the source.
        board: the board to set up with (default: the calibration file's board).
        calibration_path: the calibration file, loaded when it exists; the only file the
            session writes. None: calibrations can be made and downloaded, not saved.
        recalibrate: start in the set-up view even though the file exists.
        max_error_mm: the limit the error map outlines (None: the map's default).
        detector_options: the board detector's options (``--polarity``, ``--turned``).
        settings: object-detection settings that override the file's for this session.
        output: where the watch view's frames go as lines too (``planarcal run``'s outputs:
            controllers connected to a tcp-listen server, a file, a TCP or UDP peer).
        workdir: a private folder for the report's figures and the touch CSV.
    """

    def __init__(
        self,
        pump: FramePump,
        *,
        board: Board | None,
        calibration_path: Path | None,
        workdir: Path,
        recalibrate: bool = False,
        max_error_mm: float | None = None,
        detector_options: dict[str, Any] | None = None,
        settings: dict[str, Any] | None = None,
        output: Feed | None = None,
    ) -> None:
        self.pump = pump
        self.output = output
        self.path = calibration_path
        self.workdir = workdir
        self.max_error_mm = max_error_mm
        self.options = dict(detector_options or {})
        self.calibration: Calibration | None = None
        self.saved = False
        if calibration_path is not None and calibration_path.exists():
            self.calibration = Calibration.load(calibration_path)
            self.saved = True
        if board is None:
            board = self.calibration.board if self.calibration is not None else None
        if board is None:
            raise ArgumentError(
                f"{calibration_path} records no board: give the board's options (--type ...)"
            )
        self.board: Board = board
        if self.calibration is not None:
            try:
                self.calibration.check_image_size(pump.size, what="the source's frames")
            except FrameSizeError as e:
                if not recalibrate:
                    raise FrameSizeError(
                        f"{e} (to set the cell up anew at this size, give --recalibrate)",
                        e.frame_size,
                        e.calibration_size,
                    ) from None
                # Set up anew: the file's mapping is of another size, its board still serves.
                self.calibration, self.saved = None, False
        base = self.calibration.object_settings if self.calibration else ObjectSettings()
        self.settings = base.with_(**(settings or {}))
        self.mode = "watch" if self.calibration is not None and not recalibrate else "setup"
        self.version = 1
        self.placements: list[Captured] = []
        self.coverage: Coverage | None = None
        self.coverage_png: bytes | None = None
        self.report: dict[str, Any] | None = None
        self.figures: dict[str, Path] = {}
        self.touches: dict[int, tuple[float, ...]] = {}
        self.registered: Registered | None = None
        self.registration_error: str | None = None
        self.handedness: Handedness | None = None
        self.picked: int | None = None
        self.error: str | None = None
        self._state = threading.RLock()
        self._writer = threading.Lock()
        self._stop = threading.Event()
        self._detector = LiveDetector(self.board, self.options)
        self._tracker: Tracker | None = None
        self._analysis: Analysis | None = None
        # The newest frame the board was not found in, with the detector's record of it.
        self._failure: tuple[U8, BoardNotFoundError] | None = None
        self._jpeg: tuple[int, bytes] = (0, b"")
        self._shown = threading.Condition()
        self.display_rate = Rate()
        self.analysis_rate = Rate()
        self._threads = [
            threading.Thread(
                target=self._analyse_loop, name="planarcal-live-analysis", daemon=True
            ),
            threading.Thread(target=self._display_loop, name="planarcal-live-display", daemon=True),
        ]
        for t in self._threads:
            t.start()

    # -- the threads ---------------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        return self._stop.is_set()

    def close(self) -> None:
        """Stops the threads and the source (a change being made finishes first)."""
        self._stop.set()
        with self._shown:
            self._shown.notify_all()
        with self._writer:
            pass
        for t in self._threads:
            t.join(timeout=10.0)
        self.pump.close()
        if self.output is not None:
            self.output.close()

    def _new_frames(self) -> Iterator[Frame]:
        """Each frame newer than the one before, until the session closes (frames that came
        meanwhile are skipped: the newest is what the page must show)."""
        last = 0
        while not self._stop.is_set():
            frame = self.pump.newest(last, timeout_s=0.5)
            if frame is not None:
                last = frame.number
                yield frame

    def _analyse_loop(self) -> None:
        for frame in self._new_frames():
            try:
                analysis = self._analyse(frame)
            except Exception as e:  # the page shows it; the loop goes on
                analysis = Analysis(frame.number, time.monotonic(), self.mode, message=str(e))
            self._analysis = analysis
            self.analysis_rate.add(analysis.done_at - frame.read_at)

    def _analyse(self, frame: Frame) -> Analysis:
        mode = self.mode
        if mode == "watch":
            return self._watch(frame)
        try:
            found = self._detector.detect(frame.image)
        except BoardNotFoundError as e:
            self._failure = (frame.image, e)
            return Analysis(frame.number, time.monotonic(), mode, message=str(e))
        self._failure = None
        focus = board_focus(frame.image, found).to_dict()
        return Analysis(frame.number, time.monotonic(), mode, found, None, focus)

    def _watch(self, frame: Frame) -> Analysis:
        tracker = self._tracker
        if tracker is None:
            tracker = self._new_tracker()
        if tracker is None:
            message = "no calibration yet: set up and calibrate first"
            return Analysis(frame.number, time.monotonic(), "watch", message=message)
        result = tracker.process(frame.image, frame.number)
        if self.output is not None:
            self.output.feed(result)
        parts = tuple(
            {
                "id": o.id,
                "x": o.world_mm[0],
                "y": o.world_mm[1],
                "angle_deg": o.angle_deg,
                "std_mm": o.std_mm,
                "image_px": list(o.centroid_px),
            }
            for o in result.objects
        )
        return Analysis(frame.number, time.monotonic(), "watch", parts=parts)

    def _new_tracker(self) -> Tracker | None:
        with self._state:
            if self.calibration is None:
                return None
            # The session's settings, whole: where one is None, detect_objects' default
            # (not the file's, which the page may have changed).
            cal = self.calibration.with_object_settings(self.settings)
            self._tracker = Tracker(cal, None)
            return self._tracker

    def _display_loop(self) -> None:
        for frame in self._new_frames():
            data = overlay.jpeg(self._drawn(frame))
            with self._shown:
                self._jpeg = (frame.number, data)
                self._shown.notify_all()
            self.display_rate.add(time.monotonic() - frame.read_at)

    def _drawn(self, frame: Frame) -> U8:
        canvas: U8 = frame.image.copy()
        analysis = self._analysis
        fresh = (
            analysis is not None
            and analysis.mode == self.mode
            and time.monotonic() - analysis.done_at <= STALE_S
        )
        if self.mode == "setup":
            overlay.draw_placements(canvas, [p.outline_px for p in self.placements])
        if fresh and analysis is not None and analysis.detection is not None:
            outliers = self._outlier_ids() if self.mode == "register" else []
            overlay.draw_board(
                canvas,
                analysis.detection,
                picked=self.picked if self.mode == "register" else None,
                touched=list(self.touches) if self.mode == "register" else [],
                outliers=outliers,
            )
        if self.mode == "watch":
            parts = analysis.parts if fresh and analysis is not None else ()
            overlay.draw_parts(canvas, parts, self.settings.roi)
        return canvas

    def jpeg(self, after: int = 0, timeout_s: float = 2.0) -> tuple[int, bytes] | None:
        """The newest drawn frame (its number and JPEG) newer than ``after``, waiting up to
        ``timeout_s``; None when none came."""
        deadline = time.monotonic() + timeout_s
        with self._shown:
            while self._jpeg[0] <= after:
                left = deadline - time.monotonic()
                if left <= 0 or self._stop.is_set():
                    return None
                self._shown.wait(left)
            return self._jpeg

    # -- changes -------------------------------------------------------------------------------

    @contextlib.contextmanager
    def _writing(self) -> Iterator[None]:
        """One change at a time: BusyError when the one before does not end in time."""
        if not self._writer.acquire(timeout=WRITE_WAIT_S):
            raise BusyError(f"another change is being made (waited {WRITE_WAIT_S:g} s): try again")
        try:
            with self._state:
                yield
                self.version += 1
        finally:
            self._writer.release()

    def set_mode(self, mode: Any) -> None:
        if mode not in MODES:
            raise ArgumentError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
        with self._writing():
            self.mode = mode
            self.picked = None

    def _frame_now(self) -> Frame:
        frame = self.pump.newest(0, timeout_s=FRAME_WAIT_S)
        if frame is None:
            raise StateError(f"no frame from {self.pump.label}: {self.pump.error or 'none came'}")
        return frame

    def capture(self) -> None:
        """The board as it is now becomes a placement (detected at full resolution);
        StateError (409) when it is not found, with the detector's words."""
        with self._writing():
            image = self._frame_now().image
            k = len(self.placements)
            name = f"placement-{k + 1}.png"
            try:
                found = detect_image(image, self.board, k, max(2, k + 1), 0, name, self.options)
            except BoardNotFoundError as e:
                raise StateError(f"the board is not in view: {e}") from None
            same = self._same_place(found)
            if same is not None:
                raise StateError(
                    f"the board lies where it lay for placement {same + 1}: move it to a new "
                    "place (the error map shows where it is needed)"
                )
            self.placements.append(Captured(name, image, found))
            self._refit()

    def _same_place(self, found: BoardDetection) -> int | None:
        """The placement whose board lay where ``found``'s lies (its points within
        SAME_PLACE_PITCHES of the same points of that placement), or None: a second capture
        of one place adds nothing but weight."""
        reach = SAME_PLACE_PITCHES * found.pitch_px
        for k, p in enumerate(self.placements):
            ids, here, there = np.intersect1d(found.ids, p.detection.ids, return_indices=True)
            if not len(ids):
                continue
            moved = found.image_points[here] - p.detection.image_points[there]
            if np.median(np.hypot(*moved.T)) < reach:
                return k
        return None

    def drop_placement(self, index: int) -> None:
        with self._writing():
            if not 0 <= index < len(self.placements):
                raise NotFoundError(f"no placement {index} (there are {len(self.placements)})")
            del self.placements[index]
            self.placements = [
                dataclasses.replace(p, name=f"placement-{k + 1}.png")
                for k, p in enumerate(self.placements)
            ]
            self._refit()

    def _refit(self) -> None:
        """The error map of the placements captured so far (a provisional fit of them)."""
        self.coverage, self.coverage_png = None, None
        if not self.placements:
            return
        try:
            cal = fit_calibration(
                [p.detection for p in self.placements], 0, [p.name for p in self.placements]
            )
            self.coverage = calibration_coverage(cal, self.max_error_mm)
        except Error as e:
            self.error = f"the placements cannot be fitted yet: {e}"
            return
        self.error = None
        from planarcal.report.coverage import draw_coverage, placements_under  # noqa: PLC0415

        under = placements_under([p.image for p in self.placements])
        labels = [str(k + 1) for k in range(len(self.placements))]
        self.coverage_png = png_bytes(draw_coverage(under, self.coverage, labels))

    def diagnostics_png(self) -> bytes:
        """What the search saw in the newest frame the board was not found in (the figure
        ``planarcal calibrate --report`` draws when it fails)."""
        from planarcal.report.failure import detection_failure_figure  # noqa: PLC0415

        failure = self._failure
        if failure is None:
            raise NotFoundError("the board is found: nothing to diagnose")
        image, error = failure
        return detection_failure_figure(image, error.diagnostics, str(error))

    def placement_png(self, index: int) -> bytes:
        with self._state:
            if not 0 <= index < len(self.placements):
                raise NotFoundError(f"no placement {index} (there are {len(self.placements)})")
            return png_bytes(self.placements[index].image)

    def calibrate(self, max_error_mm: float | None = None) -> None:
        """Calibrates from the placements as ``planarcal calibrate`` does from their images
        (detected again, as the command would), and writes the report's figures."""
        from planarcal.report import summary_text, write_report  # noqa: PLC0415

        with self._writing():
            if not self.placements:
                raise StateError("no placement captured yet: capture the board first")
            images = [p.image for p in self.placements]
            names = [p.name for p in self.placements]
            detections = [
                detect_image(im, self.board, k, len(images), 0, names[k], self.options)
                for k, im in enumerate(images)
            ]
            cal = fit_calibration(detections, 0, names)
            limit = self.max_error_mm if max_error_mm is None else max_error_mm
            written = write_report(
                cal,
                self.workdir / "report",
                image=images[0],
                detection=detections[0],
                max_error_mm=limit,
                placement_images=images,
            )
            self.figures = {p.name: p for p in written if p.suffix == ".png"}
            self.report = {
                "summary": summary_text(cal, detections[0], max_error_mm=limit),
                "figures": sorted(self.figures),
            }
            cal.save(self.workdir / "calibration.json")
            self.calibration, self.saved = cal, False
            self._tracker = None
            self.registered, self.touches = None, {}

    def figure(self, name: str) -> bytes:
        with self._state:
            path = self.figures.get(name)
            if path is None:
                raise NotFoundError(f"no figure {name!r}: the report has {sorted(self.figures)}")
            return path.read_bytes()

    def save(self) -> Path:
        """Writes the calibration (with its registration and settings) to the file."""
        with self._writing():
            path = self._file()
            saved = self._calibration().save(path)
            self.saved = True
            return saved

    def calibration_bytes(self) -> bytes:
        with self._state:
            if self.path is not None and self.saved:
                return self.path.read_bytes()
            self._calibration().save(self.workdir / "calibration.json")
            return (self.workdir / "calibration.json").read_bytes()

    def _calibration(self) -> Calibration:
        if self.calibration is None:
            raise StateError("no calibration yet: capture placements and calibrate first")
        return self.calibration

    def _file(self) -> Path:
        if self.path is None:
            raise StateError(
                "no calibration file to save to: start planarcal live with --calibration FILE "
                "(download the calibration instead)"
            )
        return self.path

    # -- registration --------------------------------------------------------------------------

    def pick(self, x: Any, y: Any) -> dict[str, Any]:
        """The board point nearest image point (x, y) in the newest analysis."""
        at = np.array([_number("x", x), _number("y", y)])
        analysis = self._analysis
        if analysis is None or analysis.detection is None:
            raise StateError("the board is not in view: no point to pick")
        found = analysis.detection
        distance = np.hypot(*(found.image_points - at).T)
        k = int(np.argmin(distance))
        if distance[k] > PICK_PITCHES * found.pitch_px:
            raise NotFoundError(
                f"no {self.board.point_name} within {PICK_PITCHES:g} pitch of ({at[0]:.0f}, "
                f"{at[1]:.0f}) px: click on one"
            )
        point = int(found.ids[k])
        with self._writing():
            self.picked = point
        board_mm = self.board.world_points()[point]
        return {
            "id": point,
            "name": f"{self.board.point_name} {point}",
            "image_px": found.image_points[k].tolist(),
            "board_mm": board_mm.tolist(),
        }

    def add_touch(self, point: Any, robot: Any) -> None:
        if isinstance(point, bool) or not isinstance(point, int):
            raise ArgumentError(f"id must be a whole number, got {point!r}")
        if not 0 <= point < self.board.n_points:
            raise ArgumentError(
                f"{self.board.point_name} {point} is not on the board (0 to "
                f"{self.board.n_points - 1})"
            )
        if not isinstance(robot, list) or len(robot) not in (2, 3):
            raise ArgumentError(f"robot must be [x, y] or [x, y, z] in mm, got {robot!r}")
        values = tuple(_number(f"robot[{k}]", v) for k, v in enumerate(robot))
        with self._writing():
            self._calibration()
            if self.touches and len(next(iter(self.touches.values()))) != len(values):
                raise ArgumentError("give z for every touch or for none")
            self.touches[point] = values
            self._refit_registration()

    def set_handedness(self, handedness: Any) -> None:
        """The robot frame's hand for the fit (``planarcal register --handedness``): needed
        when the touches lie near one line; None: from the touches."""
        if handedness not in (None, *HANDEDNESS):
            raise ArgumentError(
                f"handedness must be one of {', '.join(HANDEDNESS)} or null, got {handedness!r}"
            )
        with self._writing():
            self.handedness = handedness
            if self.calibration is not None:
                self._refit_registration()

    def drop_touch(self, point: int) -> None:
        with self._writing():
            if point not in self.touches:
                raise NotFoundError(f"no touch at {self.board.point_name} {point}")
            del self.touches[point]
            self._refit_registration()

    def touches_csv(self) -> str:
        """The touches as the CSV ``planarcal register`` reads."""
        name = self.board.point_name
        with self._state:
            has_z = bool(self.touches) and len(next(iter(self.touches.values()))) == 3
            head = f"{name},robot_x,robot_y" + (",robot_z" if has_z else "")
            rows = [",".join([str(k), *(repr(v) for v in xyz)]) for k, xyz in self.touches.items()]
        return "\n".join([head, *rows]) + "\n"

    def put_touches_csv(self, text: str) -> None:
        """Replaces the touches with those of an uploaded CSV (ids, as the page picks them)."""
        path = self.workdir / "uploaded.csv"
        atomic_write(path, text)
        touches = read_touch_csv(path)
        if touches.dots is None:
            raise ArgumentError(
                "the uploaded CSV gives positions, not point ids: the page registers by "
                f"{self.board.point_name} ids (use planarcal register for position pairs)"
            )
        for k in touches.dots:
            if not 0 <= k < self.board.n_points:
                raise ArgumentError(f"{self.board.point_name} {k} is not on the board")
        zs = touches.robot_z
        with self._writing():
            self._calibration()
            self.touches = {
                int(k): tuple(touches.robot[i].tolist()) + (() if zs is None else (float(zs[i]),))
                for i, k in enumerate(touches.dots)
            }
            self._refit_registration()

    def _refit_registration(self) -> None:
        """The registration of the touches so far, as ``planarcal register`` fits it."""
        self.registered, self.registration_error = None, None
        if len(self.touches) < 3:
            self.registration_error = f"{len(self.touches)} touch points: give at least 3"
            return
        try:
            self.registered = self._registration(force=False)
        except Error as e:
            self.registration_error = str(e)

    def _registration(self, *, force: bool) -> Registered:
        path = self.workdir / TOUCHES_FILE
        atomic_write(path, self.touches_csv())
        return register_touches(
            self._calibration(),
            read_touch_csv(path),
            TOUCHES_FILE,
            force=force,
            handedness=self.handedness,
        )

    def register(self, force: bool = False) -> Path:
        """Saves the registration into the file, with ``planarcal register``'s rules: a
        named outlier, or a poor judgement without ``force``, is refused (StateError)."""
        if not isinstance(force, bool):
            raise ArgumentError(f"force must be true or false, got {force!r}")
        with self._writing():
            path = self._file()
            if self.registered is None:
                raise StateError(self.registration_error or "no registration: add touch points")
            registered = self._registration(force=force)
            if registered.refusal:
                raise StateError(f"nothing written: {registered.refusal}")
            saved = registered.calibration.save(path)
            self.calibration, self.saved, self._tracker = registered.calibration, True, None
            return saved

    def _outlier_ids(self) -> list[int]:
        registered = self.registered
        if registered is None:
            return []
        ids = list(self.touches)
        return [ids[i] for i in registered.frame.outliers if i < len(ids)]

    # -- object settings -----------------------------------------------------------------------

    def set_settings(self, changes: Any) -> None:
        if not isinstance(changes, dict):
            raise ArgumentError(f"settings must be a JSON object, got {type(changes).__name__}")
        with self._writing():
            self.settings = self.settings.with_(**changes)
            self._tracker = None

    def save_settings(self) -> Path:
        with self._writing():
            path = self._file()
            cal = self._calibration().with_object_settings(self.settings)
            saved = cal.save(path)
            self.calibration, self.saved = cal, True
            self._tracker = None
            return saved

    # -- what the page shows -------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        with self._state:
            out: dict[str, Any] = json_ready(self._state_now())
            return out

    def _state_now(self) -> dict[str, Any]:
        analysis = self._analysis
        width, height = self.pump.size
        return {
            "version": self.version,
            "mode": self.mode,
            "source": {
                "label": self.pump.label,
                "width": width,
                "height": height,
                "live": self.pump.live,
            },
            "board": {
                "description": self.board.describe(),
                "point_name": self.board.point_name,
                "points": self.board.n_points,
            },
            "file": {
                "path": None if self.path is None else str(self.path),
                "exists": self.path is not None and self.path.exists(),
                "saved": self.saved,
            },
            "stats": {
                "frames": self.pump.frames_read,
                "fps": self.display_rate.per_s,
                "latency_ms": _ms(self.display_rate.mean),
                "detect_fps": self.analysis_rate.per_s,
                "detect_latency_ms": _ms(self.analysis_rate.mean),
                "dropped": self.pump.frames_skipped,
            },
            "detection": self._detection_state(analysis),
            "focus": None if analysis is None else analysis.focus,
            "placements": [
                {
                    "index": k,
                    "name": p.name,
                    "points": len(p.detection.image_points),
                    "outline_px": p.outline_px.tolist(),
                }
                for k, p in enumerate(self.placements)
            ],
            "coverage": self._coverage_state(),
            "calibration": self._calibration_state(),
            "registration": self._registration_state(),
            "settings": self.settings.to_dict(),
            "watch": {
                "frame": self._tracker.frame if self._tracker is not None else None,
                "parts": list(analysis.parts) if analysis and analysis.mode == "watch" else [],
                "message": analysis.message if analysis and analysis.mode == "watch" else None,
                "output": None if self.output is None else self.output.state(),
            },
            "error": self.pump.error or self.error,
        }

    def _detection_state(self, analysis: Analysis | None) -> dict[str, Any]:
        if analysis is None or analysis.mode == "watch":
            return {"found": False, "points": 0, "message": "looking for the board"}
        found = analysis.detection
        if found is None:
            return {
                "found": False,
                "points": 0,
                "message": analysis.message,
                "diagnostics": self._failure is not None,
            }
        axes = overlay.board_axes_px(found)
        return {
            "found": True,
            "points": len(found.image_points),
            "partial": found.partial,
            "message": points_text(found),
            "origin_px": None if axes is None else axes[0].tolist(),
        }

    def _coverage_state(self) -> dict[str, Any] | None:
        cov = self.coverage
        if cov is None:
            return None
        region = cov.region
        return {
            "limit_mm": cov.limit_mm,
            "worst_mm": float(np.max(cov.std_mm)),
            "covered_share": cov.covered_share,
            "region": None if region is None else region.where(),
            "advice": None if region is None else region.advice(),
            "sentence": cov.sentence,
        }

    def _calibration_state(self) -> dict[str, Any] | None:
        cal = self.calibration
        if cal is None:
            return None
        stats = cal.stats
        return {
            "summary": None if self.report is None else self.report["summary"],
            "figures": [] if self.report is None else self.report["figures"],
            "saved": self.saved,
            "rms_px": stats.rms,
            "lens_model": cal.lens_model,
            "placements": max(1, len(cal.placements)),
            "registered": cal.robot_frame is not None,
        }

    def _registration_state(self) -> dict[str, Any]:
        registered = self.registered
        residuals: list[float | None] = [None] * len(self.touches)
        fit = None
        if registered is not None:
            frame = registered.frame
            residuals = [float(r) for r in frame.residuals_mm]
            fit = {
                "quality": quality(frame),
                "summary": frame.summary(),
                "outliers": self._outlier_ids(),
                "refused": registered.refusal,
            }
        analysis = self._analysis
        seen: dict[int, list[float]] = {}
        if analysis is not None and analysis.detection is not None:
            found = analysis.detection
            seen = dict(zip(found.ids.tolist(), found.image_points.tolist(), strict=True))
        touches = [
            {"id": k, "robot": list(robot), "image_px": seen.get(k), "residual_mm": residual}
            for (k, robot), residual in zip(self.touches.items(), residuals, strict=False)
        ]
        return {
            "touches": touches,
            "fit": fit,
            "message": self.registration_error,
            "handedness": self.handedness,
        }


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ArgumentError(f"{name} must be a finite number, got {value!r}")
    return float(value)


def _ms(seconds: float | None) -> float | None:
    return None if seconds is None else 1000.0 * seconds
