"""`planarcal run`: the production loop as a command.

Frames from ``--source`` (a camera index, video file, image folder or stream URL) go through a
``Tracker`` with ``--calibration``; each frame becomes one line (``--format json``, ``csv`` or
a ``--template``: see ``line_format``) on ``--output``: stdout, a file, a TCP/UDP peer such as
a robot controller, or ``tcp-listen://HOST:PORT``, where planarcal is the server that
controllers connect to, each reading every frame or, with ``--trigger``, asking for one frame
at a time (see ``output_server``). A live progress line (frames, fps, objects, drops) is drawn
on stderr when it is a terminal. Ctrl-C or SIGTERM end the loop after the frame in hand: what
was written is flushed, and a summary goes to stderr.

Exit status 1 (after the summary) when no frame was delivered: every frame read failed (with
the count and the first and last fault on stderr), or the source gave none (a camera that
never came, a run stopped before its first frame); at once, before any frame, when the
source's frames are not of the size the calibration was made on (``FrameSizeError``). Also
exit status 1, after the summary, when lines were meant for the output and none got there (a
full disk, no controller at a tcp:// address: ``output_options.undelivered``); losses are
warned about on stderr while they happen.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import functools
import json
import logging
import math
import signal
import sys
import time
from collections.abc import Iterator
from typing import Any, TextIO

from planarcal.calib.calibration import Calibration
from planarcal.errors import OutputError
from planarcal.live.line_format import FIELDS, FORMATS, LineFormat, line_format
from planarcal.live.output_options import (
    add_server_arguments,
    server_options,
    undelivered,
    wait_for_peer,
)
from planarcal.live.output_server import ServerOutput, check_trigger_word
from planarcal.live.output_spec import parse_network_spec
from planarcal.live.outputs import open_output
from planarcal.live.tracker import LoopStats, Tracker

# Redraw the progress line at most this often, s.
PROGRESS_PERIOD_S = 0.25


# Beyond these a setting is a typo: a controller waits seconds for its answer, not days (and
# a timer that far off overflows the selector), and a client's queue is also capped in bytes.
MAX_TRIGGER_TIMEOUT_S = 3600.0
MAX_CLIENT_BUFFER_LINES = 1_000_000


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
        faults = stats.frames_undecodable + stats.frames_wrong_size + stats.failed
        line = (
            f"{stats.frames} frames  {stats.fps:6.1f} fps  {stats.objects} objects  "
            f"dropped {stats.frames_dropped} frames / {_dropped(output)} messages  "
            f"faults {faults}  camera reconnects {stats.camera_reconnects}"
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


def nothing_delivered(tracker: Tracker) -> str | None:
    """Why the run delivered no frame, when it delivered none though frames were asked for
    (every frame read failed, the source gave none, or the run was stopped first); None if
    any frame was processed."""
    s = tracker.stats
    if s.frames or tracker.max_frames == 0:
        return None
    faults = s.frames_undecodable + s.frames_wrong_size + s.failed
    if not faults:
        down = f"; the camera was down {s.camera_down_s:.1f} s" if s.camera_down_s else ""
        return f"no frame was delivered: {s.read} frames read{down}"
    why = (
        f"every frame failed: {faults} of the {s.read} frames read ({s.frames_undecodable} "
        f"undecodable, {s.frames_wrong_size} of the wrong size, {s.failed} failed in detection"
    )
    why += f", {s.frames_dropped} dropped)" if s.frames_dropped else ")"
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


def add_output_arguments(p: argparse.ArgumentParser) -> None:
    """The run command's output arguments: where the lines go, their format, trigger mode."""
    g = p.add_argument_group("output (where the lines go, and what they look like)")
    g.add_argument(
        "-o",
        "--output",
        default="-",
        help="- (stdout, the default), a file (appended to), tcp://HOST:PORT or udp://HOST:PORT "
        "(a controller listening there), or tcp-listen://HOST:PORT (planarcal listens; up to "
        "--max-clients controllers connect; port 0: any free port, printed on stderr)",
    )
    g.add_argument(
        "--format",
        choices=FORMATS,
        default=None,
        help="json (the default), csv (frame,t,coords,n then id,x,y,angle,std per object, one "
        "line per frame), or template (with --template)",
    )
    g.add_argument(
        "--template",
        default=None,
        metavar="TEMPLATE",
        help="each object as this Python format string, after frame,t,coords,n on the frame's "
        "line, e.g. '{id},{x:.2f},{y:.2f},{angle:.1f}'; fields: " + ", ".join(FIELDS),
    )
    g.add_argument(
        "--trigger",
        action="store_true",
        help="with tcp-listen: send nothing unrequested; answer each request line from a "
        "client with the next frame read after it (or an error line)",
    )
    g.add_argument(
        "--trigger-word",
        default=None,
        metavar="WORD",
        help="the request line (case-sensitive; default TRIGGER); any other line gets an "
        "error line",
    )
    g.add_argument(
        "--trigger-timeout",
        type=float,
        default=None,
        metavar="S",
        help="answer a request with an error line when no frame comes within S seconds (default 3)",
    )
    g.add_argument(
        "--client-buffer",
        type=int,
        default=None,
        metavar="LINES",
        help="with tcp-listen: lines queued for each client at most (default 256); beyond, a "
        "slow client's oldest lines are dropped and counted",
    )
    add_server_arguments(g)


@dataclasses.dataclass(frozen=True)
class OutputPlan:
    """The output arguments, checked: what to open and how to write each frame."""

    spec: str
    format: LineFormat
    server: dict[str, Any]
    """ServerOutput's options (tcp-listen only; empty otherwise)."""
    trigger: bool


def output_plan(args: argparse.Namespace) -> OutputPlan:
    """Checks the output arguments before anything is opened: OutputError (naming the
    argument) for a malformed spec or template, --trigger without tcp-listen, or an option
    that goes with another one that is absent."""
    spec = str(args.output)
    network = parse_network_spec(spec)
    listening = network is not None and network[0] == "tcp-listen"
    fmt = line_format(args.format, args.template)
    # A server's error lines (a request it cannot answer, a client too many) in the format.
    server: dict[str, Any] = {"error_line": fmt.error} if listening else {}
    if args.trigger:
        if not listening:
            raise OutputError(
                f"--trigger needs --output tcp-listen://HOST:PORT, not {spec!r}: controllers "
                "send their requests to planarcal as the server"
            )
        word = "TRIGGER" if args.trigger_word is None else args.trigger_word
        check_trigger_word(word)
        timeout = 3.0 if args.trigger_timeout is None else args.trigger_timeout
        if not (math.isfinite(timeout) and 0 < timeout <= MAX_TRIGGER_TIMEOUT_S):
            raise OutputError(
                f"--trigger-timeout must be a positive number of seconds up to "
                f"{MAX_TRIGGER_TIMEOUT_S:g}, not {timeout}"
            )
        server.update(trigger_word=word, trigger_timeout=timeout)
    else:
        for name, value in (
            ("--trigger-word", args.trigger_word),
            ("--trigger-timeout", args.trigger_timeout),
        ):
            if value is not None:
                raise OutputError(f"{name} goes with --trigger")
    if args.client_buffer is not None:
        if not listening:
            raise OutputError(f"--client-buffer goes with --output tcp-listen://, not {spec!r}")
        if not 1 <= args.client_buffer <= MAX_CLIENT_BUFFER_LINES:
            raise OutputError(
                f"--client-buffer must be 1 to {MAX_CLIENT_BUFFER_LINES} lines, not "
                f"{args.client_buffer}"
            )
        server["max_pending_lines"] = args.client_buffer
    server.update(server_options(args, spec, listening))
    return OutputPlan(spec, fmt, server, bool(args.trigger))


def _source_fault(tracker: Tracker) -> str | None:
    """Why a trigger cannot be answered now, or None: the camera is down (being reopened)."""
    down = tracker.source_down
    return None if down is None else f"{down}; planarcal is reopening it"


def main(args: argparse.Namespace, detect_options: dict[str, Any] | None = None) -> int:
    """The loop `planarcal run` runs; ``detect_options`` override the calibration's object
    settings (see Tracker)."""
    # The tracker's fault log (a source lost and reopened, frames skipped) goes to stderr, like
    # the summary, unless the application set up logging itself.
    log = logging.getLogger("planarcal")
    if not log.handlers and not logging.getLogger().handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("planarcal run: %(message)s"))
        log.addHandler(handler)
        log.setLevel(logging.INFO)
    # The output's arguments first: a typo in a spec or a template fails before the camera
    # is opened.
    plan = output_plan(args)
    calibration = Calibration.load(args.calibration)
    source: int | str = int(args.source) if args.source.isdigit() else args.source
    detect = dict(detect_options or {})
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
        if plan.server:
            plan.server["fault"] = functools.partial(_source_fault, tracker)
        output = open_output(plan.spec, **plan.server)
    except BaseException:
        tracker.close()
        raise
    if isinstance(output, ServerOutput):
        mode = f"; trigger mode: send {output.trigger_word}" if plan.trigger else ""
        print(f"planarcal run: listening on {output.address}{mode}", file=sys.stderr, flush=True)
    wait_for_peer(output)  # a tcp:// controller that is listening gets the first frames too
    fmt = plan.format
    progress = Progress(sys.stderr)
    serialise_s = 0.0
    with stop_on_signals(tracker) as received:
        try:
            for result in tracker:
                t0 = time.perf_counter()
                if plan.trigger and isinstance(output, ServerOutput):
                    # Only a frame that a request waits for is formatted.
                    output.answer(result.timestamp, functools.partial(fmt.frame, result))
                else:
                    output.send(fmt.frame(result))
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
    failure = nothing_delivered(tracker)
    if failure is not None:
        print(f"planarcal run: error: {failure}", file=sys.stderr)
        return 1
    lost = undelivered(output)  # lines were meant for a destination and none got there
    if lost is not None:
        print(f"planarcal run: error: {lost}", file=sys.stderr)
        return 1
    if received and received[0] == "SIGINT":
        # The run ended cleanly, but a shell or a supervisor reads 130 as "stopped by Ctrl-C",
        # as for every other command.
        return 130
    return 0
