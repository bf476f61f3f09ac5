"""What a ``ServerOutput`` (planarcal as the controllers' server) reports: its own figures and
each client's, for the run summary and for programs that watch a running loop."""

from __future__ import annotations

import dataclasses

from planarcal.live.output_sink import OutputStats

__all__ = ["ClientStats", "ServerStats"]


@dataclasses.dataclass(frozen=True, slots=True)
class ClientStats:
    """One controller's connection."""

    peer: str
    """Its address, ``host:port``."""
    connected: bool
    sent: int
    """Lines (frames, answers, error lines) written to it whole."""
    dropped: int
    """Lines meant for it and not written: ``dropped_full_buffer + dropped_write_failed``."""
    dropped_full_buffer: int
    """Of those, its oldest lines pushed out of its full queue while it read more slowly
    than lines came."""
    dropped_write_failed: int
    """Of those, lines it never got: it left, was reset or closed its side with them still
    queued, or a line was larger than its queue."""
    requests: int
    """Trigger requests received from it."""
    answers: int
    """Frame lines queued in answer to its requests."""
    error_lines: int
    """Error lines queued for it (a request that could not be answered, an unknown one)."""
    closed_by: str | None
    """Why the connection ended (None while it is up)."""


@dataclasses.dataclass(frozen=True, slots=True)
class ServerStats(OutputStats):
    """``OutputStats`` of a server: ``sent``, ``dropped`` and ``bytes_sent`` count lines per
    client (a line that reaches three clients is sent three times), ``pending`` the lines
    queued for all clients, ``connected`` that the server is listening. Then the server's
    own figures."""

    address: str
    """Where it listens, ``host:port`` (the port the system chose for port 0)."""
    clients: int
    """Controllers connected now."""
    accepted: int
    """Connections accepted in all."""
    refused: int
    """Connections refused because ``max_clients`` were connected, none of them idle."""
    evicted: int
    """Idle clients closed to make room for a new connection at ``max_clients``."""
    idle_closed: int
    """Clients closed after ``idle_timeout`` seconds without a request (trigger mode)."""
    lines: int
    """Lines the loop sent (stream mode; each one goes to every client)."""
    unheard: int
    """Of those, lines sent while no client was connected (not counted as dropped)."""
    requests: int
    """Trigger requests received (the trigger word)."""
    answers: int
    """Frame lines queued in answer to a request."""
    error_lines: int
    """Error lines queued: requests that could not be answered, unknown requests."""
    per_client: tuple[ClientStats, ...]
    """The connected clients and the last few that left, oldest first."""
