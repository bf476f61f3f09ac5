"""What every output sink is: ``Output``, the base class that keeps the promises listed in
``planarcal.live.outputs`` (a line is sent whole or dropped and counted, ``send`` never raises
for the destination, ``close`` is idempotent and safe from a signal handler), and
``OutputStats``, the snapshot of its counters. The sinks themselves (stdout and files, UDP,
TCP) subclass ``Output`` in their own modules. A loss is reported while it happens, on the
``planarcal.live.outputs`` logger (``RateLimitedWarnings``: the first at once, then at most
every ``WARNING_PERIOD_S`` with the counts).
"""

from __future__ import annotations

import abc
import dataclasses
import logging
import math
import threading
import time
from collections.abc import Callable
from types import TracebackType
from typing import TypeVar

from planarcal.errors import OutputError

__all__ = [
    "LOG",
    "WARNING_PERIOD_S",
    "LossKind",
    "Output",
    "OutputStats",
    "RateLimitedWarnings",
    "encode_line",
]

LOG = logging.getLogger("planarcal.live.outputs")
"""Where the sinks report losses (lines, clients) while they happen; ``planarcal run`` shows
it on stderr (without a handler, Python's last-resort handler prints warnings there too)."""

WARNING_PERIOD_S = 10.0
"""A kind of loss is reported at once the first time, then at most once per this many
seconds, with the count since the last report: a line lost per frame must not become a
warning per frame."""


@dataclasses.dataclass(frozen=True, slots=True)
class OutputStats:
    """A snapshot of a sink's counters, for the loop's progress line and its exit summary."""

    sent: int
    """Lines handed to the operating system whole (written to the file or pipe, sent as a
    datagram, or written completely into a TCP connection)."""
    dropped: int
    """Lines not delivered, for any reason: ``dropped_full_buffer + dropped_write_failed``."""
    dropped_full_buffer: int
    """Of those, lines pushed out of a full buffer behind a reader slower than the loop (the
    reader is there and reading; it gets the newest lines)."""
    dropped_write_failed: int
    """Of those, lines that could not be written at all: no connection or no reader (a TCP
    controller not listening, a pipe whose reader has gone), a write that failed (a full
    disk), a connection lost or reset with the line still queued, a line too large for the
    sink, a send after close."""
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


class LossKind:
    """One kind of loss a ``RateLimitedWarnings`` reports, and its state."""

    __slots__ = ("count", "details", "due", "last", "message", "plural", "singular")

    def __init__(
        self, singular: str, plural: str, details: Callable[[], str] | None = None
    ) -> None:
        self.singular = singular
        self.plural = plural
        self.details = details
        """Adds the running totals to a report, made only when one is made."""
        self.count = 0
        """Losses since the last report."""
        self.last: float | None = None
        """When the last report was made (time.monotonic()); None: never."""
        self.due = -math.inf
        """When the next loss is reported at once."""
        self.message = ""
        """The latest cause."""


class RateLimitedWarnings:
    """Warnings about losses (lines, clients) on ``LOG``, while they happen and without a
    flood: each kind is reported the first time at once, then at most once every `period`
    seconds with how many happened since the last report; ``flush`` reports what is left
    (at close). Not thread-safe: the owner holds its lock."""

    __slots__ = ("_kinds", "period", "where")

    def __init__(self, where: str, period: float = WARNING_PERIOD_S) -> None:
        self.where = where
        self.period = period
        self._kinds: dict[str, LossKind] = {}

    def kind(
        self, singular: str, plural: str, details: Callable[[], str] | None = None
    ) -> LossKind:
        """The kind of loss named by its singular and plural ("line lost", "lines lost"),
        made on first use; `details` adds the running totals to each of its reports."""
        kind = self._kinds.get(singular)
        if kind is None:
            kind = self._kinds[singular] = LossKind(singular, plural, details)
        return kind

    def note(self, kind: LossKind, n: int, message: str) -> None:
        """`n` more losses of `kind`; `message` says the latest cause."""
        kind.count += n
        kind.message = message
        now = time.monotonic()
        if now >= kind.due and n > 0:
            self._report(kind, now)

    def flush(self) -> None:
        """Reports every kind with losses not reported yet."""
        now = time.monotonic()
        for kind in self._kinds.values():
            if kind.count:
                self._report(kind, now)

    def _report(self, kind: LossKind, now: float) -> None:
        what = f"{kind.count:,} {kind.singular if kind.count == 1 else kind.plural}"
        message = kind.message
        if kind.details is not None:
            message += f" ({kind.details()})"
        if kind.last is None:
            text = (
                f"{self.where}: {what}: {message} (reported again at most every {self.period:g} s)"
            )
        else:
            text = f"{self.where}: {what} in the last {now - kind.last:.0f} s: {message}"
        LOG.warning(text)
        kind.count = 0
        kind.last = now
        kind.due = now + self.period


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
        self._n_full = 0  # lines dropped from a full buffer
        self._n_failed = 0  # lines that could not be written
        self._n_bytes = 0
        self._n_errors = 0
        self._last_error: str | None = None
        self._warnings = RateLimitedWarnings(spec)
        self._lines_lost = self._warnings.kind("line lost", "lines lost", self._loss_totals)

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
            with self._lock:
                self._warnings.flush()

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
                dropped=self._n_full + self._n_failed,
                dropped_full_buffer=self._n_full,
                dropped_write_failed=self._n_failed,
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
        if s.dropped:
            parts[-1] += (
                f" ({s.dropped_write_failed:,} not written, {s.dropped_full_buffer:,} from a "
                "full buffer)"
            )
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

    @property
    def _n_dropped(self) -> int:
        return self._n_full + self._n_failed

    def _drop(
        self,
        reason: str | None = None,
        *,
        error: bool = False,
        full_buffer: bool = False,
        cause: str | None = None,
    ) -> bool:
        """Counts one line lost (see ``_lose``); returns False for send() to return. The
        caller holds self._lock."""
        self._lose(1, reason, error=error, full_buffer=full_buffer, cause=cause)
        return False

    def _lose(
        self,
        n: int,
        reason: str | None = None,
        *,
        full_buffer: bool = False,
        error: bool = False,
        cause: str | None = None,
    ) -> None:
        """Counts `n` lines lost: pushed out of a full buffer (`full_buffer`), or not
        written. `reason` becomes the last error, `error` counts one; `cause` says why in
        the warning when there is no `reason` (the last error otherwise). Reported on
        ``LOG``, rate-limited. The caller holds self._lock."""
        if n <= 0:
            return
        if full_buffer:
            self._n_full += n
        else:
            self._n_failed += n
        if error:
            self._n_errors += 1
        if reason is not None:
            self._last_error = reason
        if reason is not None:
            cause = reason
        elif cause is None and full_buffer:
            cause = "the reader is slower than the loop: its oldest lines are dropped"
        elif cause is None:
            cause = self._last_error or "the line could not be written"
        self._warnings.note(self._lines_lost, n, cause)

    def _loss_totals(self) -> str:
        """The lines lost so far, for a warning (the caller holds self._lock)."""
        return (
            f"{self._n_full + self._n_failed:,} in all: {self._n_failed:,} not written, "
            f"{self._n_full:,} dropped from a full buffer"
        )

    @abc.abstractmethod
    def _send(self, data: bytes) -> bool:
        """Delivers one encoded line (ending in a newline); must count it as sent or dropped
        and check ``self._closing`` under ``self._lock``."""

    @abc.abstractmethod
    def _close(self) -> None:
        """Flushes and releases the destination; called once, after ``_closing`` is set."""
