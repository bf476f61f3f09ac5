"""`planarcal live`: the live setup page (planarcal.web) served from a source's frames.

The URL is the first line printed (with the token when one is needed), once the port is
bound. Ctrl-C or SIGTERM stop the server, said in one line (exit status 130 for Ctrl-C, as
every command, 0 for SIGTERM): a change being made (a save) finishes first, and every file
is written atomically, so no half-written file is left."""

from __future__ import annotations

import argparse
import contextlib
import ipaddress
import secrets
import signal
import socket
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from planarcal.cli import INTERRUPTED
from planarcal.commands import BOARD_GIVEN, board_arguments, board_from, command_line, positive
from planarcal.commands.calibrate import add_detector_arguments, detector_options_of
from planarcal.commands.locate import add_detection_arguments, detection_overrides
from planarcal.errors import ArgumentError, MissingDependencyError, OutputError
from planarcal.live import run

DESCRIPTION = (
    "Serve the live setup page: the live image with the board's detection, focus and "
    "exposure, placements captured by a click and the predicted error map, calibration, "
    "registration to the robot by clicking points, and the parts located live. Open the "
    "printed URL in a browser. Needs the extra planarcal[live]."
)
DEFAULT_PORT = 8000


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = DESCRIPTION
    p.add_argument(
        "--source",
        required=True,
        help="camera index (0), video file (played in a loop), image folder or stream URL",
    )
    p.add_argument(
        "--calibration",
        type=Path,
        default=None,
        help="the calibration file: loaded when it exists, and the only file written "
        "(without it a calibration can be downloaded from the page, not saved)",
    )
    p.add_argument(
        "--recalibrate",
        action="store_true",
        help="start in the set-up view even though the calibration file exists",
    )
    p.add_argument(
        "--max-error-mm",
        type=positive,
        default=None,
        metavar="MM",
        help="the error map outlines where the predicted error is above this (default: twice "
        "the error at the placements' points)",
    )
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="the address to listen on (default 127.0.0.1, this computer only); any other "
        "needs the token",
    )
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"(default {DEFAULT_PORT})")
    p.add_argument(
        "--token",
        default=None,
        help="the token every request must carry (default: generated when --host is not loopback)",
    )
    board_arguments(p)
    # The file's board unless a board option is typed.
    p.set_defaults(type=None)
    add_detector_arguments(p)
    add_detection_arguments(p)
    # The watch view's frames to controllers, as `planarcal run` sends them: none unless -o.
    run.add_output_arguments(p)
    p.set_defaults(output=None)
    for action in p._actions:
        if action.dest == "output":
            action.help = (
                "the watch view's frames as lines, as planarcal run writes them (default: none): "
                "a file, tcp://HOST:PORT, udp://HOST:PORT or tcp-listen://HOST:PORT (controllers "
                "connect; the page lists them)"
            )


def _loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _bound_socket(host: str, port: int) -> socket.socket:
    """A listening socket at host:port (port 0: any free one); ArgumentError when it cannot
    be had (in use, not this computer's address)."""
    if not 0 <= port <= 65535:
        raise argparse.ArgumentError(None, f"--port {port} is not a port (0 to 65535)")
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as e:
        raise ArgumentError(f"--host {host}: not an address of this computer ({e})") from None
    family, kind, proto, _, address = infos[0]
    sock = socket.socket(family, kind, proto)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(address)
        sock.listen(64)
    except OSError as e:
        sock.close()
        raise ArgumentError(f"cannot listen on {host}:{port}: {e.strerror or e}") from None
    return sock


class _TerminatedError(Exception):
    """SIGTERM, raised: its default action would end the process at once (uvicorn sends it
    again once stopped), leaving the session open and its temporary folder behind."""


@contextlib.contextmanager
def _sigterm_raised() -> Iterator[None]:
    """SIGTERM raises _TerminatedError here (in the main thread; elsewhere it stays as it is)."""

    def handler(signum: int, frame: Any) -> None:
        raise _TerminatedError

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _url(host: str, sock: socket.socket, token: str | None) -> str:
    port = sock.getsockname()[1]
    shown = socket.gethostname() if host in ("0.0.0.0", "::") else host
    if ":" in shown:
        shown = f"[{shown}]"
    return f"http://{shown}:{port}/" + (f"?token={token}" if token else "")


def main(args: argparse.Namespace) -> int:
    try:
        import uvicorn  # noqa: PLC0415 - the extra planarcal[live]; the other commands run without it

        from planarcal.web.app import create_app  # noqa: PLC0415 - needs starlette (the extra)
    except ImportError as e:
        raise MissingDependencyError(
            f"planarcal live needs the extra planarcal[live] ({e.name} is not installed): "
            "pip install 'planarcal[live]'",
            name=e.name,
        ) from None
    from planarcal.live.output_server import ServerOutput  # noqa: PLC0415
    from planarcal.live.outputs import open_output  # noqa: PLC0415
    from planarcal.web.frames import FramePump  # noqa: PLC0415 - OpenCV, after the check
    from planarcal.web.session import Feed, LiveSession  # noqa: PLC0415

    typed = args.type is not None or bool(getattr(args, BOARD_GIVEN, None))
    if args.type is None:
        args.type = "circles"
    has_file = args.calibration is not None and args.calibration.exists()
    board = board_from(args) if typed or not has_file else None  # else the file's
    token = args.token
    if token is None and not _loopback(args.host):
        token = secrets.token_urlsafe(16)
    plan = None
    if args.output is not None:
        with command_line(OutputError):
            plan = run.output_plan(args)
    sock = _bound_socket(args.host, args.port)
    source: int | str = int(args.source) if args.source.isdigit() else args.source
    with tempfile.TemporaryDirectory(prefix="planarcal-live-") as workdir:
        pump = FramePump(source)
        feed = None
        try:
            if plan is not None:
                feed = Feed(open_output(plan.spec, **plan.server), plan.format, plan.trigger)
                if isinstance(feed.output, ServerOutput):
                    print(
                        f"planarcal live: controllers connect to {feed.output.address}",
                        file=sys.stderr,
                    )
            session = LiveSession(
                pump,
                board=board,
                calibration_path=args.calibration,
                workdir=Path(workdir),
                recalibrate=args.recalibrate,
                max_error_mm=args.max_error_mm,
                detector_options=None,
                settings=detection_overrides(args),
                output=feed,
            )
        except BaseException:
            pump.close()
            if feed is not None:
                feed.close()
            raise
        interrupted = False
        try:
            # --polarity / --turned, checked against the board now known (maybe the file's);
            # the session's detector reads this dict.
            session.options.update(detector_options_of(args, session.board))
            config = uvicorn.Config(
                create_app(session, token=token),
                log_level="warning",
                timeout_graceful_shutdown=2,
            )
            try:
                with _sigterm_raised():
                    print(_url(args.host, sock, token), flush=True)
                    uvicorn.Server(config).run(sockets=[sock])
            except KeyboardInterrupt:
                # uvicorn stops gracefully on Ctrl-C, then raises it again: the server has
                # stopped, which the one line below says (not the CLI's "interrupted" too).
                interrupted = True
            except _TerminatedError:
                pass  # stopped as asked, the same way
        finally:
            session.close()
            sock.close()
            print("planarcal live: stopped", file=sys.stderr)
    return INTERRUPTED if interrupted else 0
