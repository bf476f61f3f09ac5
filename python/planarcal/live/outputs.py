"""Where the production loop's lines go: stdout, a file, or a robot controller over TCP or UDP.

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
  are lost without anyone knowing how many.
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
    one datagram per line; see ``UdpOutput``.
anything else
    a file, appended to (created if absent); see ``FileOutput``.
"""

from __future__ import annotations

import abc
import collections
import contextlib
import dataclasses
import errno
import os
import re
import select
import selectors
import socket
import stat
import struct
import sys
import threading
import time
from types import TracebackType
from typing import TypeVar

from planarcal.errors import OutputError

__all__ = [
    "FileOutput",
    "Output",
    "OutputError",
    "OutputStats",
    "StreamOutput",
    "TcpOutput",
    "UdpOutput",
    "open_output",
]


_SPEC_HELP = "expected '-' (stdout), tcp://HOST:PORT, udp://HOST:PORT or a file path"


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


def open_output(spec: str | os.PathLike[str]) -> Output:
    """Opens the sink that ``spec`` names: ``-`` for stdout, ``tcp://HOST:PORT``,
    ``udp://HOST:PORT`` (IPv6 addresses in brackets: ``tcp://[::1]:5000``), anything else a
    file path to append to.

    Raises OutputError for a malformed network spec or an unknown scheme (``ftp://...``), so
    that a typo fails at start-up rather than writing a file named after it; OSError naming
    the file when a file cannot be opened, or the host when a UDP host cannot be resolved. A
    TCP controller that is not listening yet is not an error: the sink keeps trying (see
    ``TcpOutput.wait_connected``)."""
    if not isinstance(spec, str):
        return FileOutput(spec)
    if spec == "-":
        return StreamOutput(1, "stdout")
    network = _parse_network_spec(spec)
    if network is None:
        return FileOutput(spec)
    scheme, host, port = network
    if scheme == "tcp":
        return TcpOutput(host, port)
    return UdpOutput(host, port)


def _parse_network_spec(spec: str) -> tuple[str, str, int] | None:
    """(scheme, host, port) for tcp:// and udp:// specs, None for a file path."""
    if not spec.strip():
        raise OutputError(f"empty output: {_SPEC_HELP}")
    match = re.fullmatch(r"([A-Za-z][A-Za-z0-9+.-]*)://(.*)", spec, flags=re.DOTALL)
    if match is None:
        # "tcp:host:5000" is a typo for a network output far more often than a file name.
        lowered = spec.lower()
        for scheme in ("tcp", "udp"):
            if lowered.startswith(scheme + ":"):
                raise OutputError(
                    f"output {spec!r}: write {scheme}://HOST:PORT for a {scheme.upper()} peer "
                    f"(for a file of that name, write ./{spec})"
                )
        return None
    scheme, rest = match.group(1).lower(), match.group(2)
    if scheme not in ("tcp", "udp"):
        raise OutputError(f"output {spec!r}: unknown scheme {scheme!r}; {_SPEC_HELP}")
    example = f"{scheme}://192.168.0.10:5000"
    rest = rest.removesuffix("/")
    if not rest:
        raise OutputError(f"output {spec!r}: no host and port; write {scheme}://HOST:PORT")
    if any(c in rest for c in "/?#@ "):
        raise OutputError(
            f"output {spec!r}: only a host and a port may follow {scheme}://, as in {example}"
        )
    if rest.startswith("["):
        end = rest.find("]")
        if end < 0:
            raise OutputError(f"output {spec!r}: unclosed '[' around an IPv6 address")
        host, after = rest[1:end], rest[end + 1 :]
        if after and not after.startswith(":"):
            raise OutputError(f"output {spec!r}: expected ':PORT' after the ']'")
        port_text = after[1:]
    elif rest.count(":") > 1:
        raise OutputError(
            f"output {spec!r}: an IPv6 address goes in brackets, as in {scheme}://[::1]:5000"
        )
    else:
        host, _, port_text = rest.partition(":")
    if not host:
        raise OutputError(f"output {spec!r}: no host; write {scheme}://HOST:PORT")
    if not port_text:
        raise OutputError(f"output {spec!r}: no port; write {scheme}://HOST:PORT, as in {example}")
    if not re.fullmatch(r"[0-9]+", port_text):
        raise OutputError(f"output {spec!r}: the port {port_text!r} is not a number")
    port = int(port_text)
    if not 1 <= port <= 65535:
        raise OutputError(f"output {spec!r}: port {port} is out of range 1-65535")
    return scheme, host, port


def _netloc(host: str, port: int) -> str:
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def _encode_line(line: str) -> bytes:
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
        data = _encode_line(line)
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
        elif isinstance(self, TcpOutput):
            state = "connected" if s.connected else "not connected"
        else:
            state = "open"
        parts = [f"{s.sent:,} sent", f"{s.dropped:,} dropped"]
        if s.connect_attempts:
            parts.append(f"{s.reconnects:,} reconnects")
        if s.errors:
            parts.append(f"{s.errors:,} errors")
        text = f"{self.spec}: {state}, " + ", ".join(parts)
        if s.last_error:
            text += f" (last error: {s.last_error})"
        return text

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


class StreamOutput(Output):
    """Lines written to an open file descriptor (stdout, a pipe), synchronously: one
    ``write`` per line, so a line of up to PIPE_BUF bytes (4 KiB on Linux) is never
    interleaved with another writer's, and nothing sits in a user-space buffer to be lost
    on a crash (there is nothing to flush).

    A reader that has gone (EPIPE) makes the stream ``broken``: the error is counted once
    and every further line is dropped, because writing on would only fail again. When the
    stream is stdout (descriptor 1), descriptor 1 is then pointed at the null device, as
    Python's documentation advises, so that the interpreter's own flush of sys.stdout at
    exit does not print a BrokenPipeError traceback."""

    def __init__(self, fd: int, name: str, *, close_fd: bool = False) -> None:
        super().__init__(name)
        self._fd: int | None = fd
        self._close_fd = close_fd
        self._broken = False
        if fd == 1:
            # Whatever was printed to sys.stdout before must come out first.
            with contextlib.suppress(Exception):
                sys.stdout.flush()

    @property
    def broken(self) -> bool:
        return self._broken

    def _send(self, data: bytes) -> bool:
        with self._lock:
            if self._closing or self._fd is None:
                return self._drop()
            if self._broken:
                return self._drop()
            fd = self._fd
            view = memoryview(data)
            written = 0
            try:
                while written < len(data):
                    try:
                        written += os.write(fd, view[written:])
                    except BlockingIOError:
                        if written == 0:
                            # A non-blocking descriptor that is full: drop rather than wait.
                            return self._drop(f"{self.spec} is full (non-blocking); line dropped")
                        # Half a line is out: finish it, or the framing is lost.
                        select.select([], [fd], [])
            except BrokenPipeError as e:
                self._broken = True
                self._on_broken()
                return self._drop(
                    f"the reader of {self.spec} has gone ({e.strerror}); "
                    "every further line is dropped",
                    error=True,
                )
            except OSError as e:
                reason = f"cannot write to {self.spec}: {e.strerror or e}"
                if written and not self._undo_partial(fd, written):
                    self._broken = True
                    reason += "; half a line was written, so every further line is dropped"
                return self._drop(reason, error=True)
            self._n_sent += 1
            self._n_bytes += written
            return True

    def _undo_partial(self, fd: int, written: int) -> bool:
        """Removes the first `written` bytes of a line whose write failed, if the destination
        allows it (a file does, a pipe does not). True when the stream ends on a line
        boundary again."""
        return False

    def _on_broken(self) -> None:
        if self._fd == 1:
            with contextlib.suppress(OSError):
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, 1)
                os.close(devnull)

    def _close(self) -> None:
        with self._lock:
            fd, self._fd = self._fd, None
        if fd is not None and self._close_fd:
            self._sync(fd)
            with contextlib.suppress(OSError):
                os.close(fd)

    def _sync(self, fd: int) -> None:
        """Nothing for a stream: os.write leaves no user-space buffer to flush."""


class FileOutput(StreamOutput):
    """Lines appended to a file, created if absent.

    Appended, not truncated: running ``planarcal run -o positions.jsonl`` again must not
    destroy the previous hours of record; each line carries its timestamp, so runs stay
    apart. And not written through a temporary file renamed at the end (``files.atomic_write``):
    a stream is read while it grows (``tail -f``) and must hold everything up to a crash.
    Instead each line goes out in one ``write`` on a descriptor opened with O_APPEND, so a
    crash of the process leaves only complete lines (the data is in the kernel as soon as
    ``send`` returns). ``close`` also asks the disk to persist the file (fsync), once, not per
    line: hundreds of fsyncs per second would slow the loop for the sake of a power cut.

    A failed write (a full disk) is counted and the line dropped; if half of it reached the
    file, the file is cut back to the previous line end so that appending resumes on a line
    boundary. A file whose last line is unterminated when opened (a previous run's power
    cut) gets a newline first, for the same reason."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        name = os.fspath(path)
        if not name:
            raise OutputError(f"empty output: {_SPEC_HELP}")
        directory = os.path.dirname(name) or "."
        if not os.path.isdir(directory):
            raise FileNotFoundError(
                errno.ENOENT, f"cannot open output file {name!r}: no directory {directory!r}"
            )
        flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_CLOEXEC", 0)
        flags |= getattr(os, "O_BINARY", 0)
        try:
            fd = os.open(name, flags, 0o644)
        except OSError as e:
            raise type(e)(
                e.errno, f"cannot open output file {name!r} for appending: {e.strerror}"
            ) from None
        try:
            self._terminate_last_line(fd, name)
        except OSError as e:
            os.close(fd)
            raise type(e)(e.errno, f"cannot append to output file {name!r}: {e.strerror}") from None
        super().__init__(fd, name, close_fd=True)

    @staticmethod
    def _terminate_last_line(fd: int, name: str) -> None:
        info = os.fstat(fd)
        if not (info.st_size and stat.S_ISREG(info.st_mode)):
            return
        try:
            with open(name, "rb") as f:
                f.seek(-1, os.SEEK_END)
                last = f.read(1)
        except OSError:  # a write-only file: cannot look, so do not guess
            return
        if last != b"\n":
            os.write(fd, b"\n")

    def _undo_partial(self, fd: int, written: int) -> bool:
        try:
            os.ftruncate(fd, os.fstat(fd).st_size - written)
        except OSError:
            return False
        return True

    def _sync(self, fd: int) -> None:
        with contextlib.suppress(OSError):
            os.fsync(fd)


class UdpOutput(Output):
    """One datagram per line (with its newline, so a receiver that concatenates datagrams,
    such as ``nc -ul``, still sees lines), sent from a non-blocking socket.

    UDP never blocks and never retries: a datagram the local socket buffer cannot take is
    dropped and counted. A line longer than ``max_datagram`` bytes is dropped and counted
    rather than split, since half a JSON document is of no use to a controller; note that a
    datagram larger than the network's MTU (about 1,472 bytes of payload on Ethernet) is
    fragmented by IP and lost whole if any fragment is, so frames with many objects are
    better sent over TCP. When nothing listens at the peer, the network answers with ICMP
    "port unreachable", which the next send reports as "connection refused": it is counted
    as an error, never raised, and the line is retried once (the refusal concerned an
    earlier datagram)."""

    def __init__(self, host: str, port: int, *, max_datagram: int = 65_000) -> None:
        _check_port(port)
        if not 1 <= max_datagram <= 65_507:
            raise OutputError(
                f"max_datagram must be between 1 and 65,507 bytes (UDP's limit), not {max_datagram}"
            )
        super().__init__(f"udp://{_netloc(host, port)}")
        self._max_datagram = max_datagram
        try:
            infos = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
        except socket.gaierror as e:
            raise socket.gaierror(
                e.errno, f"cannot resolve the host of {self.spec}: {e.strerror}"
            ) from None
        family, kind, proto, _, address = infos[0]
        sock = socket.socket(family, kind, proto)
        try:
            sock.setblocking(False)
            sock.connect(address)  # fixes the peer, and lets ICMP errors come back to us
        except OSError as e:
            sock.close()
            raise type(e)(e.errno, f"cannot open {self.spec}: {e.strerror}") from None
        self._sock: socket.socket | None = sock

    def _send(self, data: bytes) -> bool:
        with self._lock:
            sock = self._sock
            if self._closing or sock is None:
                return self._drop()
            if len(data) > self._max_datagram:
                return self._drop(
                    f"a line of {len(data):,} bytes is longer than the {self._max_datagram:,}-byte "
                    f"datagram limit of {self.spec}; dropped, not split (use tcp:// for large "
                    "frames)"
                )
            for attempt in (1, 2):
                try:
                    sock.send(data)
                except BlockingIOError:
                    return self._drop(f"the socket buffer for {self.spec} is full; line dropped")
                except ConnectionRefusedError:
                    self._n_errors += 1
                    self._last_error = f"nothing is listening at {self.spec} (connection refused)"
                    if attempt == 2:
                        return self._drop()
                    continue
                except OSError as e:
                    return self._drop(f"cannot send to {self.spec}: {e.strerror or e}", error=True)
                break
            self._n_sent += 1
            self._n_bytes += len(data)
            return True

    def _close(self) -> None:
        with self._lock:
            sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()


def _check_port(port: int) -> None:
    if not isinstance(port, int) or isinstance(port, bool) or not 1 <= port <= 65535:
        raise OutputError(f"port {port!r} is out of range 1-65535")


# At most this much of the buffer is handed to the socket at once: what has been handed over
# is committed (a line once started must be finished on that connection), so a smaller batch
# leaves more of the buffer free to drop its oldest lines for newer ones behind a slow reader.
_BATCH_BYTES = 64 * 1024

# A connection that lasted at least this long counts as a success: the back-off starts over.
# Shorter ones (a controller that accepts and hangs up at once) keep the delay growing.
_STABLE_CONNECTION_S = 1.0


class TcpOutput(Output):
    """A TCP client that streams lines to a robot controller listening at HOST:PORT, without
    ever making the loop wait for it.

    ``send`` appends the line to a bounded buffer in memory and returns, in microseconds;
    a background (daemon) thread does all the socket work:

    * Connecting, in the background, with exponential back-off (``backoff_initial`` doubling
      to ``backoff_max``) for as long as the controller is absent. Lines sent while there is no
      connection are dropped on the spot (``send`` returns False): a robot wants the positions
      of now, not a backlog from before it was listening. ``wait_connected`` lets the loop wait
      for the controller at start-up if it wants to.
    * Writing, non-blocking, in batches of up to 64 KiB. When the controller reads more slowly
      than lines come (or stops reading, and the kernel's buffers fill), the buffer holds at
      most ``max_pending_lines`` lines and ``max_pending_bytes`` bytes; beyond that the OLDEST
      pending lines are dropped and counted, so what gets through is as fresh as it can be.
      The socket's own send buffer is capped too (``send_buffer``), because stale data
      queues there as well; what the controller's receive buffer holds is beyond our reach, so
      a controller that pauses should drain its socket and act on the last line.
    * Detecting a lost connection: the peer closing or resetting it, an error from the kernel,
      or no byte accepted for ``stall_timeout`` seconds while lines wait (a controller that
      hangs; TCP_USER_TIMEOUT is set to the same, where the system has it, for a peer that
      vanished). A stalled connection is reset rather than closed gracefully so the stale
      backlog in it is discarded rather than delivered; then the sink reconnects.
    * Freshness after a reconnect: when a connection is lost, everything still pending,
      including the rest of a line that was half written, is dropped and counted; the next
      connection starts on a line boundary with lines sent after it was established. A line is
      never split across connections.

    ``close`` writes what is pending for up to ``flush_timeout`` seconds, closes the
    connection gracefully and stops the thread; what could not be written is counted as
    dropped."""

    def __init__(
        self,
        host: str,
        port: int,
        *,
        max_pending_lines: int = 256,
        max_pending_bytes: int = 1 << 20,
        backoff_initial: float = 0.1,
        backoff_max: float = 5.0,
        connect_timeout: float = 2.0,
        stall_timeout: float | None = 5.0,
        flush_timeout: float = 1.0,
        send_buffer: int | None = 64 * 1024,
    ) -> None:
        _check_port(port)
        if not host:
            raise OutputError("a TCP output needs a host")
        for name, value in (
            ("max_pending_lines", max_pending_lines),
            ("max_pending_bytes", max_pending_bytes),
        ):
            if value < 1:
                raise OutputError(f"{name} must be at least 1, not {value}")
        for name, seconds in (
            ("backoff_initial", backoff_initial),
            ("backoff_max", backoff_max),
            ("connect_timeout", connect_timeout),
            ("stall_timeout", stall_timeout),
        ):
            if seconds is not None and not seconds > 0:
                raise OutputError(f"{name} must be a positive number of seconds, not {seconds}")
        if backoff_max < backoff_initial:
            raise OutputError(
                f"backoff_max ({backoff_max} s) is shorter than backoff_initial "
                f"({backoff_initial} s)"
            )
        if not flush_timeout >= 0:
            raise OutputError(f"flush_timeout must be >= 0 seconds, not {flush_timeout}")
        if send_buffer is not None and send_buffer < 1:
            raise OutputError(f"send_buffer must be at least 1 byte, not {send_buffer}")
        super().__init__(f"tcp://{_netloc(host, port)}")
        self.host = host
        self.port = port
        self._max_lines = max_pending_lines
        self._max_bytes = max_pending_bytes
        self._backoff_initial = backoff_initial
        self._backoff_max = backoff_max
        self._connect_timeout = connect_timeout
        self._stall_timeout = stall_timeout
        self._flush_timeout = flush_timeout
        self._send_buffer = send_buffer

        # Shared with the writer thread, under self._lock.
        self._pending: collections.deque[bytes] = collections.deque()
        self._pending_bytes = 0
        self._inflight_lines = 0  # taken by the writer, not yet fully written
        self._connected = False
        self._idle = False  # the writer waits for lines: send() must wake it
        self._stop = False
        self._stop_deadline = 0.0
        self._connects = 0
        self._attempts = 0
        self._connected_event = threading.Event()

        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._thread = threading.Thread(
            target=self._run, name=f"planarcal output {self.spec}", daemon=True
        )
        self._thread.start()

    def wait_connected(self, timeout: float | None = None) -> bool:
        """Waits until a connection is up (True) or `timeout` seconds have passed (False).
        For a loop that would rather not drop its first frames before the controller is
        there; sending never requires it."""
        return self._connected_event.wait(timeout)

    @property
    def stats(self) -> OutputStats:
        with self._lock:
            return OutputStats(
                sent=self._n_sent,
                dropped=self._n_dropped,
                bytes_sent=self._n_bytes,
                errors=self._n_errors,
                reconnects=max(self._connects - 1, 0),
                connect_attempts=self._attempts,
                connected=self._connected,
                pending=len(self._pending) + self._inflight_lines,
                broken=False,
                last_error=self._last_error,
            )

    # --- the caller's side: microseconds, never a system call unless the writer sleeps ---

    def _send(self, data: bytes) -> bool:
        size = len(data)
        with self._lock:
            if self._closing or not self._connected:
                return self._drop()
            if size > self._max_bytes:
                return self._drop(
                    f"a line of {size:,} bytes is larger than max_pending_bytes "
                    f"({self._max_bytes:,}); dropped"
                )
            pending = self._pending
            pending.append(data)
            self._pending_bytes += size
            while len(pending) > self._max_lines or self._pending_bytes > self._max_bytes:
                self._pending_bytes -= len(pending.popleft())
                self._n_dropped += 1
            wake = self._idle
            self._idle = False
        if wake:
            self._wake()
        return True

    def _wake(self) -> None:
        with contextlib.suppress(OSError):  # full (a wake-up is pending anyway) or closed
            self._wake_w.send(b"\0")

    def _close(self) -> None:
        with self._lock:
            self._stop = True
            self._stop_deadline = time.monotonic() + self._flush_timeout
        self._wake()
        if threading.current_thread() is not self._thread:
            self._thread.join(self._flush_timeout + 0.5)
        with self._lock:
            # Only if the writer is stuck (in a slow name lookup): count what it left.
            self._n_dropped += len(self._pending)
            self._pending.clear()
            self._pending_bytes = 0
        if not self._thread.is_alive():
            self._wake_r.close()
            self._wake_w.close()

    # --- the writer thread ---

    def _run(self) -> None:
        selector = selectors.DefaultSelector()
        selector.register(self._wake_r, selectors.EVENT_READ)
        delay = self._backoff_initial
        try:
            while not self._stop:
                sock = self._connect(selector)
                if sock is None:
                    self._sleep(selector, delay)
                    delay = min(delay * 2, self._backoff_max)
                    continue
                began = time.monotonic()
                reason = self._serve(selector, sock)
                self._disconnect(sock, reason)
                if self._stop:
                    break
                if time.monotonic() - began >= _STABLE_CONNECTION_S:
                    delay = self._backoff_initial  # reconnect at once: it was working
                else:
                    self._sleep(selector, delay)
                    delay = min(delay * 2, self._backoff_max)
        except Exception as e:  # a bug here must not pass silently: say it, stop accepting
            with self._lock:
                self._connected = False
                self._n_errors += 1
                self._last_error = f"the writer of {self.spec} failed: {e!r}"
            raise
        finally:
            selector.close()
            self._connected_event.clear()

    def _sleep(self, selector: selectors.BaseSelector, seconds: float) -> None:
        """Waits `seconds`, or less if close() is called."""
        deadline = time.monotonic() + seconds
        while not self._stop:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return
            if selector.select(remaining):
                self._drain_wake()

    def _drain_wake(self) -> None:
        with contextlib.suppress(OSError):
            while self._wake_r.recv(4096):
                pass

    def _connect(self, selector: selectors.BaseSelector) -> socket.socket | None:
        with self._lock:
            self._attempts += 1
        try:
            infos = socket.getaddrinfo(self.host, self.port, type=socket.SOCK_STREAM)
        except OSError as e:
            self._error(f"cannot resolve the host of {self.spec}: {e.strerror or e}")
            return None
        failure = "no address"
        for family, kind, proto, _, address in infos:
            if self._stop:
                return None
            sock = socket.socket(family, kind, proto)
            try:
                sock.setblocking(False)
                self._configure(sock)
                code = sock.connect_ex(address)
                if code in (errno.EINPROGRESS, errno.EWOULDBLOCK, errno.EALREADY, errno.EAGAIN):
                    code = self._await_connect(selector, sock)
            except OSError as e:
                code = e.errno or errno.EIO
            if code == 0:
                with self._lock:
                    self._connected = True
                    self._connects += 1
                self._connected_event.set()
                return sock
            sock.close()
            if code < 0:  # close() was called
                return None
            failure = os.strerror(code)
        self._error(f"cannot connect to {self.spec}: {failure}")
        return None

    def _await_connect(self, selector: selectors.BaseSelector, sock: socket.socket) -> int:
        """The outcome of a non-blocking connect: 0, an errno, or -1 when closing."""
        deadline = time.monotonic() + self._connect_timeout
        selector.register(sock, selectors.EVENT_WRITE)
        try:
            while True:
                if self._stop:
                    return -1
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return errno.ETIMEDOUT
                for key, _ in selector.select(remaining):
                    if key.fileobj is sock:
                        return sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
                    self._drain_wake()
        finally:
            selector.unregister(sock)

    def _configure(self, sock: socket.socket) -> None:
        """Low latency (no Nagle delay on small lines), a capped kernel buffer (stale data
        queues there too), and dead-peer detection."""
        options: list[tuple[int, int, int]] = [
            (socket.IPPROTO_TCP, socket.TCP_NODELAY, 1),
            (socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1),
        ]
        if self._send_buffer is not None:
            options.append((socket.SOL_SOCKET, socket.SO_SNDBUF, self._send_buffer))
        user_timeout = getattr(socket, "TCP_USER_TIMEOUT", None)
        if user_timeout is not None and self._stall_timeout is not None:
            options.append((socket.IPPROTO_TCP, user_timeout, int(self._stall_timeout * 1000)))
        for level, option, value in options:
            with contextlib.suppress(OSError):
                sock.setsockopt(level, option, value)

    def _error(self, message: str) -> None:
        with self._lock:
            self._n_errors += 1
            self._last_error = message

    def _serve(self, selector: selectors.BaseSelector, sock: socket.socket) -> str | None:
        """Writes lines to `sock` until it fails or close() has been called and the buffer
        is flushed. Returns why the connection is being given up, None for a clean close."""
        selector.register(sock, selectors.EVENT_READ)
        interest = selectors.EVENT_READ
        batch: memoryview | None = None
        ends: list[int] = []  # where each line of the batch ends
        done = 0  # lines of the batch fully written
        offset = 0  # bytes of the batch written
        last_progress = time.monotonic()
        try:
            while True:
                if batch is None:
                    lines: list[bytes] = []
                    with self._lock:
                        pending = self._pending
                        size = 0
                        while pending and (not lines or size + len(pending[0]) <= _BATCH_BYTES):
                            line = pending.popleft()
                            lines.append(line)
                            size += len(line)
                        self._pending_bytes -= size
                        self._inflight_lines = len(lines)
                        self._idle = not lines
                        stopping = self._stop
                    if lines:
                        batch = memoryview(b"".join(lines))
                        ends = []
                        total = 0
                        for line in lines:
                            total += len(line)
                            ends.append(total)
                        done = offset = 0
                        last_progress = time.monotonic()
                    elif stopping:
                        return None  # everything is written
                if batch is not None:
                    # Most of the time the socket takes it all at once: no need to wait.
                    try:
                        offset += sock.send(batch[offset:])
                    except BlockingIOError:
                        pass
                    except OSError as e:
                        return self._lost(e)
                    else:
                        last_progress = time.monotonic()
                        finished = done
                        while finished < len(ends) and ends[finished] <= offset:
                            finished += 1
                        if finished > done:
                            start = ends[done - 1] if done else 0
                            with self._lock:
                                self._n_sent += finished - done
                                self._n_bytes += ends[finished - 1] - start
                                self._inflight_lines -= finished - done
                            done = finished
                        if offset == len(batch):
                            batch = None
                            continue  # take the next batch straight away
                want = selectors.EVENT_READ | (selectors.EVENT_WRITE if batch is not None else 0)
                if want != interest:
                    selector.modify(sock, want)
                    interest = want
                now = time.monotonic()
                timeout: float | None = None
                if batch is not None and self._stall_timeout is not None:
                    timeout = last_progress + self._stall_timeout - now
                    if timeout <= 0:
                        return self._stalled(self._stall_timeout)
                if self._stop:
                    left = self._stop_deadline - now
                    if left <= 0:
                        return (
                            f"closing: {self.spec} did not take the last lines within "
                            f"{self._flush_timeout:g} s"
                        )
                    timeout = left if timeout is None else min(timeout, left)
                for key, mask in selector.select(timeout):
                    if key.fileobj is self._wake_r:
                        self._drain_wake()
                    elif mask & selectors.EVENT_READ:
                        # The controller may talk back; we do not listen, but must see EOF.
                        try:
                            received = sock.recv(65536)
                        except BlockingIOError:
                            continue
                        except OSError as e:
                            return self._lost(e)
                        if not received:
                            return f"{self.spec} closed the connection"
        finally:
            selector.unregister(sock)

    def _stalled(self, seconds: float) -> str:
        return (
            f"{self.spec} took no data for {seconds:g} s (the controller stopped "
            "reading, or is gone); reset the connection"
        )

    def _lost(self, e: OSError) -> str:
        if e.errno == errno.ETIMEDOUT and self._stall_timeout is not None:
            # The kernel's TCP_USER_TIMEOUT fired: the same verdict as our own stall timer.
            return self._stalled(self._stall_timeout)
        return f"lost the connection to {self.spec}: {e.strerror or e}"

    def _disconnect(self, sock: socket.socket, reason: str | None) -> None:
        with self._lock:
            self._connected = False
            lost = len(self._pending) + self._inflight_lines
            self._n_dropped += lost
            self._pending.clear()
            self._pending_bytes = 0
            self._inflight_lines = 0
            self._idle = False
            if reason is not None:
                self._n_errors += 1
                self._last_error = reason + (f"; {lost:,} unsent lines dropped" if lost else "")
        self._connected_event.clear()
        if reason is None:
            # Graceful: the controller reads every line we wrote, then end of stream.
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_WR)
        else:
            # Abortive: what is still queued towards the controller is stale, and may end in
            # half a line; a reset discards it instead of delivering it.
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        sock.close()
