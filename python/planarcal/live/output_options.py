"""The server's options of ``planarcal run`` (``--max-clients``, ``--client-idle-timeout``),
checked before anything is opened, and what the run checks of its output at its start and
end: a peer that is not there (``wait_for_peer``) and a run that delivered nothing
(``undelivered``).
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from planarcal.errors import OutputError
from planarcal.live.output_server import IDLE_TIMEOUT_S
from planarcal.live.output_sink import LOG, Output

__all__ = [
    "MAX_CLIENTS",
    "MAX_IDLE_TIMEOUT_S",
    "PEER_WAIT_S",
    "add_server_arguments",
    "server_options",
    "undelivered",
    "wait_for_peer",
]

MAX_CLIENTS = 10_000
"""The most ``--max-clients`` may be: each client holds a descriptor and up to its queue of
lines in memory."""

MAX_IDLE_TIMEOUT_S = 86_400.0
"""The longest ``--client-idle-timeout`` (a day); 0 means never."""

PEER_WAIT_S = 2.0
"""How long ``planarcal run`` waits for a TCP controller before its first frame, so that a
controller that is listening gets the first frames too (a short video would otherwise be
over before the connection is up)."""


def add_server_arguments(group: argparse._ArgumentGroup) -> None:
    """Adds ``--max-clients`` and ``--client-idle-timeout`` to the run command's output
    arguments."""
    group.add_argument(
        "--max-clients",
        type=int,
        default=None,
        metavar="N",
        help="with tcp-listen: controllers connected at once, at most (default 32); one more "
        "gets an error line and is closed, except that with --trigger it takes the place of "
        "the client idle longest (idle at least 10 s)",
    )
    group.add_argument(
        "--client-idle-timeout",
        type=float,
        default=None,
        metavar="S",
        help="with --trigger: close a client that sends no request for S seconds (default "
        f"{IDLE_TIMEOUT_S:g}; 0: never), after an error line saying why",
    )


def server_options(args: argparse.Namespace, spec: str, listening: bool) -> dict[str, Any]:
    """``ServerOutput``'s options from ``--max-clients`` and ``--client-idle-timeout``.
    Raises OutputError (naming the option) for a value out of range, or an option without
    the mode it goes with."""
    options: dict[str, Any] = {}
    if args.max_clients is not None:
        if not listening:
            raise OutputError(f"--max-clients goes with --output tcp-listen://, not {spec!r}")
        if not 1 <= args.max_clients <= MAX_CLIENTS:
            raise OutputError(
                f"--max-clients must be 1 to {MAX_CLIENTS:,} controllers, not {args.max_clients}"
            )
        options["max_clients"] = args.max_clients
    idle = args.client_idle_timeout
    if idle is not None:
        if not args.trigger:
            raise OutputError(
                "--client-idle-timeout goes with --trigger (in stream mode a client that "
                "stops reading is reset after 5 s instead)"
            )
        if not (math.isfinite(idle) and 0 <= idle <= MAX_IDLE_TIMEOUT_S):
            raise OutputError(
                f"--client-idle-timeout must be 0 (never) to {MAX_IDLE_TIMEOUT_S:g} seconds, "
                f"not {idle}"
            )
        options["idle_timeout"] = idle if idle > 0 else None
    return options


def wait_for_peer(output: Output, timeout: float = PEER_WAIT_S) -> bool:
    """Waits up to `timeout` seconds for a sink that connects out (``tcp://``) to connect;
    warns (on the outputs' logger) when it does not: its lines are dropped until it does.
    True at once for the other sinks."""
    wait = getattr(output, "wait_connected", None)
    if wait is None or wait(timeout):
        return True
    last = output.stats.last_error
    LOG.warning(
        "%s: no connection after %g s%s; lines are dropped (and counted) until the "
        "controller accepts one, and planarcal keeps trying",
        output.spec,
        timeout,
        f" ({last})" if last else "",
    )
    return False


def undelivered(output: Output) -> str | None:
    """Why the run failed to deliver anything, when lines were meant for a destination and
    none was delivered (``sent`` 0, ``dropped`` not): a full disk, no controller at a
    ``tcp://`` address, a client of the server that never took a line. None otherwise: some
    lines were delivered, or none was meant for anyone (a server no client connected to, a
    trigger server never asked)."""
    s = output.stats
    if s.sent or not s.dropped:
        return None
    why = (
        f"no line was delivered to {output.spec}: all {s.dropped:,} were lost "
        f"({s.dropped_write_failed:,} could not be written, {s.dropped_full_buffer:,} "
        "dropped from a full buffer)"
    )
    if s.last_error:
        why += f"; last error: {s.last_error}"
    return why
