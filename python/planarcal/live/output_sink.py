"""What every output sink is: ``Output``, the base class that keeps the promises listed in
``planarcal.live.outputs`` (a line is sent whole or dropped and counted, ``send`` never raises
for the destination, ``close`` is idempotent and safe from a signal handler), and
``OutputStats``, the snapshot of its counters. The sinks themselves (stdout and files, UDP,
TCP) subclass ``Output`` in their own modules.
"""

from __future__ import annotations

import abc
import dataclasses
import threading
from types import TracebackType
from typing import TypeVar

from planarcal.errors import OutputError

__all__ = ["Output", "OutputStats", "encode_line"]


@dataclasses.dataclass(frozen=True, slots=True)
class OutputStats:
    """A snapshot of a sink's counters, for the loop's progress line and its exit summary."""

    sent: int
    """Lines handed to the operating system whole (written to the file or pipe, sent as a
    datagram, or written completely into a TCP connection)."""
    dropped: int
    """Lines not delivered: buffer overflow behind a slow reader, no connection, a failed
    write, an oversize datagram, a broken pipe, a send after close."""
    bytes_sent: int
    """Bytes of the lines counted in ``sent``, newlines included."""
    errors: int
    """I/O failures: failed connection attempts, lost or stalled connections, write errors,
    errors reported by the network for earlier datagrams."""
    reconnects: int
    """TCP: connections established after the first one. 0 for the other sinks."""
    connect_attempts: int
    """TCP: connection attempts made, successful or not. 0 for the other sinks."""
    connected: bool
    """TCP: a connection is up. The other sinks: open and not broken."""
    pending: int
    """TCP: lines accepted by ``send`` and not yet written. 0 for the other sinks."""
    broken: bool
    """stdout or a pipe whose reader has gone: every further line is dropped."""
    last_error: str | None
    """The most recent failure, in words, or None."""


def encode_line(line: str) -> bytes:
    """The line as UTF-8 ending in exactly one newline. A line break inside would split one
    document into two unparseable lines at the reader, so it is refused."""
    at = line.find("\n")
    if at == -1:
        return (line + "\n").encode("utf-8")
    if at == len(line) - 1:
        return line.encode("utf-8")
    raise OutputError(
        f"a line to send contains a line break at character {at}: send one JSON document "
        "per line (json.dumps without indent)"
    )


_O = TypeVar("_O", bound="Output")


class Output(abc.ABC):
    """A destination for newline-delimited JSON: ``send`` a line, read ``stats``, ``close``.

    ``send`` is meant to be called from one thread (the loop). ``close`` and ``stats`` may be
    called from any thread, and ``close`` from a signal handler that interrupted ``send``:
    the close then waits until that ``send`` has finished (a lock would deadlock there)."""

    def __init__(self, spec: str) -> None:
        self.spec = spec
        """The destination, normalised: ``stdout``, ``tcp://host:port``, a file path."""
        # Guards the counters and the sink's own state; re-entrant so that a signal handler
        # that reads stats while the interrupted thread holds it does not deadlock.
        self._lock = threading.RLock()
        self._close_lock = threading.RLock()
        self._closing = False
        self._sender: int | None = None
        self._close_deferred = False
        self._n_sent = 0
        self._n_dropped = 0
        self._n_bytes = 0
        self._n_errors = 0
        self._last_error: str | None = None

    def send(self, line: str) -> bool:
        """Sends one JSON line (a trailing newline is added if absent). True when the line
        was written or, on TCP, queued for writing; False when it was dropped (and counted).
        Never raises for an I/O failure; raises OutputError for a line with a line break
        inside, which would corrupt the framing."""
        data = encode_line(line)
        self._sender = threading.get_ident()
        try:
            return self._send(data)
        finally:
            self._sender = None
            if self._close_deferred:
                self._close_deferred = False
                self.close()

    def close(self) -> None:
        """Flushes and closes. Idempotent; safe from another thread and from a signal
        handler (when the handler interrupted ``send``, the sink closes as that ``send``
        returns). Lines sent afterwards are dropped and counted, not raised on, because a
        signal handler may close the sink while the loop is still sending."""
        if self._sender == threading.get_ident():
            # A signal handler interrupted send() on this thread: send() closes when done.
            self._close_deferred = True
            return
        with self._close_lock:
            if self._closing:
                # Closed already, or a signal handler interrupted close() on this thread.
                return
            with self._lock:
                self._closing = True
            self._close()

    @property
    def closed(self) -> bool:
        """True once ``close`` has been called."""
        return self._closing

    @property
    def broken(self) -> bool:
        """True when the destination is gone for good (a pipe whose reader has exited):
        every further line is dropped. A TCP sink is never broken: it reconnects."""
        return False

    @property
    def stats(self) -> OutputStats:
        """A consistent snapshot of the counters."""
        with self._lock:
            return OutputStats(
                sent=self._n_sent,
                dropped=self._n_dropped,
                bytes_sent=self._n_bytes,
                errors=self._n_errors,
                reconnects=0,
                connect_attempts=0,
                connected=not self._closing and not self.broken,
                pending=0,
                broken=self.broken,
                last_error=self._last_error,
            )

    def describe(self) -> str:
        """One line for a log or the exit summary: where, the state, the counts, the last
        error."""
        s = self.stats
        if self.broken:
            state = "broken (reader gone)"
        elif self.closed:
            state = "closed"
        else:
            state = self._open_state(s)
        parts = [f"{s.sent:,} sent", f"{s.dropped:,} dropped"]
        if s.connect_attempts:
            parts.append(f"{s.reconnects:,} reconnects")
        if s.errors:
            parts.append(f"{s.errors:,} errors")
        text = f"{self.spec}: {state}, " + ", ".join(parts)
        if s.last_error:
            text += f" (last error: {s.last_error})"
        return text

    def _open_state(self, stats: OutputStats) -> str:
        """The state ``describe`` shows while the sink is neither broken nor closed."""
        return "open"

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.describe()}>"

    def __enter__(self: _O) -> _O:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _drop(self, reason: str | None = None, *, error: bool = False) -> bool:
        """Counts one dropped line (and an error); returns False for send() to return.
        The caller holds self._lock."""
        self._n_dropped += 1
        if error:
            self._n_errors += 1
        if reason is not None:
            self._last_error = reason
        return False

    @abc.abstractmethod
    def _send(self, data: bytes) -> bool:
        """Delivers one encoded line (ending in a newline); must count it as sent or dropped
        and check ``self._closing`` under ``self._lock``."""

    @abc.abstractmethod
    def _close(self) -> None:
        """Flushes and releases the destination; called once, after ``_closing`` is set."""
