"""`planarcal run`: the production loop as a command.

Frames from ``--source`` (a camera index, video file, image folder or stream URL) go through a
``Tracker`` with ``--calibration``; each frame becomes one JSON line on ``--output`` (stdout,
a file, or a TCP/UDP peer such as a robot controller). A live progress line (frames, fps,
objects, drops) is drawn on stderr when it is a terminal. Ctrl-C or SIGTERM end the loop after
the frame in hand: what was written is flushed, and a summary goes to stderr.

Exit status 1 (after the summary) when every frame read failed, with the count and the first
and last fault on stderr; at once, before any frame, when the source's frames are not of the
size the calibration was made on (``FrameSizeError``).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import logging
import signal
import sys
import time
from collections.abc import Iterator
from typing import Any, TextIO

from planarcal.calib.calibration import Calibration
from planarcal.live.outputs import open_output
from planarcal.live.tracker import LoopStats, Tracker

# Redraw the progress line at most this often, s.
PROGRESS_PERIOD_S = 0.25


class Progress:
    """A one-line status on a terminal, rewritten in place; silent when not a terminal."""

    def __init__(self, stream: TextIO, enabled: bool | None = None) -> None:
        self.stream = stream
        isatty = getattr(stream, "isatty", None)
        self.enabled = bool(isatty and isatty()) if enabled is None else enabled
        self._last = 0.0
        self._width = 0

    def update(self, stats: LoopStats, output: Any, *, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self._last < PROGRESS_PERIOD_S:
            return
        self._last = now
        line = (
            f"{stats.frames} frames  {stats.fps:6.1f} fps  {stats.objects} objects  "
            f"dropped {stats.dropped} frames / {_dropped(output)} messages  "
            f"faults {stats.corrupt + stats.failed}  reconnects {stats.reconnects}"
        )
        pad = max(0, self._width - len(line))
        self._width = len(line)
        self.stream.write("\r" + line + " " * pad)
        self.stream.flush()

    def end(self) -> None:
        if self.enabled and self._width:
            self.stream.write("\n")
            self.stream.flush()


def _dropped(output: Any) -> int:
    stats = getattr(output, "stats", None)
    return int(getattr(stats, "dropped", 0)) if stats is not None else 0


@contextlib.contextmanager
def stop_on_signals(tracker: Tracker) -> Iterator[list[str]]:
    """SIGINT and SIGTERM stop the tracker after the frame in hand (instead of killing the
    process mid-write); the previous handlers come back afterwards. Yields the names of the
    signals received."""
    received: list[str] = []

    def handler(signum: int, _frame: Any) -> None:
        received.append(signal.Signals(signum).name)
        tracker.stop()

    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        # Outside the main thread signals cannot be caught: they stay as they are.
        with contextlib.suppress(ValueError):
            previous[sig] = signal.signal(sig, handler)
    try:
        yield received
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def summary(tracker: Tracker, output: Any, received: list[str]) -> dict[str, Any]:
    """The run's figures as one JSON-ready object."""
    out = tracker.stats.to_dict()
    ostats = getattr(output, "stats", None)
    if dataclasses.is_dataclass(ostats) and not isinstance(ostats, type):
        out["output"] = {"spec": getattr(output, "spec", None), **dataclasses.asdict(ostats)}
    out["stopped_by"] = received[0] if received else None
    if tracker.first_error is not None:
        out["first_fault"] = str(tracker.first_error)
    if tracker.last_error is not None:
        out["last_fault"] = str(tracker.last_error)
    return out


def all_frames_failed(tracker: Tracker) -> str | None:
    """Why the run located nothing when every frame it read failed; None if any frame was
    processed, or none failed."""
    s = tracker.stats
    faults = s.corrupt + s.failed
    if s.frames or not faults:
        return None
    why = (
        f"every frame failed: {faults} of the {s.read} frames read ({s.corrupt} undecodable "
        f"or of the wrong size, {s.failed} failed in detection"
    )
    why += f", {s.dropped} dropped)" if s.dropped else ")"
    first, last = tracker.first_error, tracker.last_error
    why += f"; first fault: {first}"
    if last is not None and last is not first:
        why += f"; last fault: {last}"
    return why


def stage_report(stats: LoopStats, serialise_s: float) -> str:
    """Time per frame in each stage (ms) and the share of the loop's wall time."""
    stages = dict(stats.stage_s)
    stages["serialise+send"] = serialise_s
    wall = max(stats.elapsed_s, 1e-9)
    n = max(stats.frames, 1)
    lines = [f"{stats.frames} frames in {wall:.2f} s: {stats.fps:.1f} fps"]
    for name, seconds in stages.items():
        lines.append(
            f"  {name:<15}{1e3 * seconds / n:8.3f} ms/frame  {100 * seconds / wall:5.1f} % of wall"
        )
    return "\n".join(lines)


def main(args: argparse.Namespace) -> int:
    # The tracker's fault log (a source lost and reopened, frames skipped) goes to stderr, like
    # the summary, unless the application set up logging itself.
    log = logging.getLogger("planarcal")
    if not log.handlers and not logging.getLogger().handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("planarcal run: %(message)s"))
        log.addHandler(handler)
        log.setLevel(logging.INFO)
    calibration = Calibration.load(args.calibration)
    source: int | str = int(args.source) if args.source.isdigit() else args.source
    detect: dict[str, Any] = {}
    if args.min_area is not None:
        detect["min_area_px"] = args.min_area
    # The tracker first: a source that does not match the calibration is refused before the
    # output is opened (no empty file, no connection to the controller).
    tracker = Tracker(
        calibration,
        source,
        height_mm=args.height,
        max_frames=args.max_frames,
        max_reconnect_s=args.max_reconnect,
        detect_options=detect,
        frame=args.frame,
    )
    try:
        output = open_output(args.output)
    except BaseException:
        tracker.close()
        raise
    progress = Progress(sys.stderr)
    serialise_s = 0.0
    with stop_on_signals(tracker) as received:
        try:
            for result in tracker:
                t0 = time.perf_counter()
                output.send(result.to_json())
                serialise_s += time.perf_counter() - t0
                if getattr(output, "broken", False):
                    tracker.stop()  # the reader of stdout went away: nothing left to do
                progress.update(tracker.stats, output)
        finally:
            progress.update(tracker.stats, output, force=True)
            progress.end()
            output.close()
            tracker.close()
    report = summary(tracker, output, received)
    if args.fps_report:
        print(stage_report(tracker.stats, serialise_s), file=sys.stderr)
    print(f"planarcal run: {json.dumps(report, allow_nan=False)}", file=sys.stderr)
    failure = all_frames_failed(tracker)
    if failure is not None:
        print(f"planarcal run: error: {failure}", file=sys.stderr)
        return 1
    return 0
