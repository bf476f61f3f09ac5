"""Where the production loop's lines go: stdout, a file, a robot controller over TCP or UDP,
or the controllers that connect to planarcal as a server.

``planarcal run`` emits one line of JSON per camera frame, hundreds per second for hours.
``open_output(spec)`` turns the ``-o`` argument into a sink; every sink keeps the same
promises, chosen for a live stream that a robot acts on:

* ``send(line)`` never raises because of the destination. A line that cannot be delivered is
  dropped and counted, and ``send`` returns False; the loop carries on. The network sinks
  never wait on the network either: capture must not stall because a controller is slow,
  absent or restarting.
* Lines stay whole. A file, pipe or datagram gets each line in one write; on TCP a
  connection that fails part-way through a line is abandoned, never continued, so every byte
  stream a reader sees is parseable newline-delimited JSON (at worst with an unterminated
  last line before a disconnect, which a line reader discards).
* Everything is accounted for: once ``close()`` has returned, ``stats.sent + stats.dropped``
  is the number of ``send`` calls. ``sent`` means handed to the operating system: TCP has no
  application-level acknowledgement, so lines in the kernel's buffers when a connection dies
  are lost without anyone knowing how many. ``dropped`` is the sum of two kinds of loss:
  ``dropped_full_buffer`` (a reader slower than the loop: its oldest lines pushed out of a
  full buffer, the newest kept) and ``dropped_write_failed`` (no connection or reader, a
  failed write such as a full disk, a connection lost with the line queued, a line too large,
  a send after close).
* A loss is reported while it happens: a warning on the ``planarcal.live.outputs`` logger
  (stderr under ``planarcal run``; Python's last-resort handler prints it there too when the
  application configured no logging), the first at once and then at most one every 10 s
  with the counts since, and what is left at close. ``output_options.undelivered`` says
  when a sink was given lines and delivered none (``planarcal run`` then exits 1).
* ``close()`` flushes what it can (within ``flush_timeout`` on TCP), is idempotent, and may
  be called from another thread or from a signal handler while ``send`` is running.

The sinks:

``-``
    stdout, written synchronously (one ``write`` per line). A reader that goes away
    (``planarcal run | head``) is reported once (``broken``) and every further line is
    dropped; the loop decides whether that means stop. A reader that is merely slow blocks
    the loop, as a pipe should: use ``tcp://`` for a consumer that may lag.
``tcp://HOST:PORT``
    a client of a controller listening there; see ``TcpOutput`` (bounded buffer, newest lines
    kept, reconnection with back-off, fresh data after a reconnect).
``udp://HOST:PORT``
    one datagram per line; see ``UdpOutput``. UDP has no acknowledgement: a datagram the
    network loses, or that no one listens for, may still count as sent.
``tcp-listen://HOST:PORT``
    planarcal listens; up to ``max_clients`` controllers connect, each with its own bounded
    queue (a slow one drops its own oldest lines, counted, and holds back no one); in
    trigger mode each request line gets one answer, and idle clients are closed after
    ``idle_timeout`` or make room for a new one at the cap. See ``ServerOutput``. Its counts
    are per client.
anything else
    a file, appended to (created if absent); see ``FileOutput``.

The modules: ``output_spec`` (reading the spec), ``output_sink`` (``Output``, the base every
sink derives from, and ``OutputStats``), ``output_stream`` (stdout, pipes, files),
``output_udp``, ``output_tcp``, ``output_server``, ``output_socket`` (what the TCP sinks
share) and ``output_options`` (the server's command-line options, and the checks ``planarcal
run`` makes of its output). Everything is importable from here.
"""

from __future__ import annotations

import os
from typing import Any

from planarcal.errors import OutputError
from planarcal.live.output_options import undelivered
from planarcal.live.output_server import ServerOutput
from planarcal.live.output_server_stats import ClientStats, ServerStats
from planarcal.live.output_sink import Output, OutputStats
from planarcal.live.output_spec import parse_network_spec
from planarcal.live.output_stream import FileOutput, StreamOutput
from planarcal.live.output_tcp import TcpOutput
from planarcal.live.output_udp import UdpOutput

__all__ = [
    "ClientStats",
    "FileOutput",
    "Output",
    "OutputError",
    "OutputStats",
    "ServerOutput",
    "ServerStats",
    "StreamOutput",
    "TcpOutput",
    "UdpOutput",
    "open_output",
    "undelivered",
]


def open_output(spec: str | os.PathLike[str], **server_options: Any) -> Output:
    """Opens the sink that ``spec`` names: ``-`` for stdout, ``tcp://HOST:PORT``,
    ``udp://HOST:PORT``, ``tcp-listen://HOST:PORT`` (IPv6 addresses in brackets:
    ``tcp://[::1]:5000``), anything else a file path to append to. `server_options` go to
    ``ServerOutput`` (trigger_word, max_pending_lines, ...) and only with tcp-listen.

    Raises OutputError for a malformed network spec or an unknown scheme (``ftp://...``), so
    that a typo fails at start-up rather than writing a file named after it; OSError naming
    the file when a file cannot be opened, or the host when a UDP host cannot be resolved. A
    TCP controller that is not listening yet is not an error: the sink keeps trying (see
    ``TcpOutput.wait_connected``). A server that cannot listen (the port in use, an address
    not of this machine) raises OutputError naming it."""
    network = parse_network_spec(spec) if isinstance(spec, str) and spec != "-" else None
    if server_options and (network is None or network[0] != "tcp-listen"):
        raise OutputError(
            f"output {str(spec)!r}: {', '.join(sorted(server_options))} apply to a server "
            "(tcp-listen://HOST:PORT) only"
        )
    if not isinstance(spec, str):
        return FileOutput(spec)
    if spec == "-":
        return StreamOutput(1, "stdout")
    if network is None:
        return FileOutput(spec)
    scheme, host, port = network
    if scheme == "tcp-listen":
        return ServerOutput(host, port, **server_options)
    if scheme == "tcp":
        return TcpOutput(host, port)
    return UdpOutput(host, port)
