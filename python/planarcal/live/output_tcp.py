"""``TcpOutput``: a TCP client that streams lines to a robot controller from a background
writer thread, so that the loop never waits on the network: a bounded buffer that keeps the
newest lines, reconnection with back-off, and fresh data (never half a line) after a
reconnect.
"""

from __future__ import annotations

import errno
import os
import selectors
import socket
import threading
import time

from planarcal.errors import OutputError
from planarcal.live.output_sink import Output, OutputStats
from planarcal.live.output_socket import LineBatch, LineQueue, Waker, close_socket, configure_socket
from planarcal.live.output_spec import check_port, netloc

__all__ = ["TcpOutput"]


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
        check_port(port)
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
        super().__init__(f"tcp://{netloc(host, port)}")
        self.host = host
        self.port = port
        self._max_bytes = max_pending_bytes
        self._backoff_initial = backoff_initial
        self._backoff_max = backoff_max
        self._connect_timeout = connect_timeout
        self._stall_timeout = stall_timeout
        self._flush_timeout = flush_timeout
        self._send_buffer = send_buffer

        # Shared with the writer thread, under self._lock.
        self._pending = LineQueue(max_pending_lines, max_pending_bytes)
        self._inflight_lines = 0  # taken by the writer, not yet fully written
        self._connected = False
        self._idle = False  # the writer waits for lines: send() must wake it
        self._stop = False
        self._stop_deadline = 0.0
        self._connects = 0
        self._attempts = 0
        self._connected_event = threading.Event()

        self._waker = Waker()
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
                dropped=self._n_full + self._n_failed,
                dropped_full_buffer=self._n_full,
                dropped_write_failed=self._n_failed,
                bytes_sent=self._n_bytes,
                errors=self._n_errors,
                reconnects=max(self._connects - 1, 0),
                connect_attempts=self._attempts,
                connected=self._connected,
                pending=len(self._pending) + self._inflight_lines,
                broken=False,
                last_error=self._last_error,
            )

    def _open_state(self, stats: OutputStats) -> str:
        return "connected" if stats.connected else "not connected"

    # --- the caller's side: microseconds, never a system call unless the writer sleeps ---

    def _send(self, data: bytes) -> bool:
        size = len(data)
        with self._lock:
            if self._closing:
                return self._drop(cause=f"a line sent after {self.spec} was closed")
            if not self._connected:
                return self._drop(cause=self._not_connected())
            if size > self._max_bytes:
                return self._drop(
                    f"a line of {size:,} bytes is larger than max_pending_bytes "
                    f"({self._max_bytes:,}); dropped"
                )
            pushed_out = self._pending.push(data)
            if pushed_out:
                self._lose(pushed_out, full_buffer=True)
            wake = self._idle
            self._idle = False
        if wake:
            self._wake()
        return True

    def _not_connected(self) -> str:
        """Why a line cannot be sent now (the caller holds the lock)."""
        why = f"not connected to {self.spec}"
        if self._last_error is not None:
            why += f" (last error: {self._last_error})"
        return why + "; lines are dropped until the controller accepts a connection"

    def _wake(self) -> None:
        self._waker.wake()

    def _close(self) -> None:
        with self._lock:
            self._stop = True
            self._stop_deadline = time.monotonic() + self._flush_timeout
        self._wake()
        if threading.current_thread() is not self._thread:
            self._thread.join(self._flush_timeout + 0.5)
        with self._lock:
            # Only if the writer is stuck (in a slow name lookup): count what it left.
            self._lose(self._pending.clear(), cause=f"{self.spec} was closed with lines queued")
        if not self._thread.is_alive():
            self._waker.close()

    # --- the writer thread ---

    def _run(self) -> None:
        selector = selectors.DefaultSelector()
        selector.register(self._waker.reader, selectors.EVENT_READ)
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
        self._waker.drain()

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
                configure_socket(
                    sock, send_buffer=self._send_buffer, stall_timeout=self._stall_timeout
                )
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

    def _error(self, message: str) -> None:
        with self._lock:
            self._n_errors += 1
            self._last_error = message

    def _serve(self, selector: selectors.BaseSelector, sock: socket.socket) -> str | None:
        """Writes lines to `sock` until it fails or close() has been called and the buffer
        is flushed. Returns why the connection is being given up, None for a clean close."""
        selector.register(sock, selectors.EVENT_READ)
        interest = selectors.EVENT_READ
        batch: LineBatch | None = None
        last_progress = time.monotonic()
        try:
            while True:
                if batch is None:
                    batch, stopping = self._take_batch()
                    if batch is not None:
                        last_progress = time.monotonic()
                    elif stopping:
                        return None  # everything is written
                if batch is not None:
                    # Most of the time the socket takes it all at once: no need to wait.
                    try:
                        progressed = self._write(sock, batch)
                    except OSError as e:
                        return self._lost(e)
                    if progressed:
                        last_progress = time.monotonic()
                        if batch.written:
                            batch = None
                            continue  # take the next batch straight away
                want = selectors.EVENT_READ | (selectors.EVENT_WRITE if batch is not None else 0)
                if want != interest:
                    selector.modify(sock, want)
                    interest = want
                timeout, reason = self._wait_limit(batch is not None, last_progress)
                if reason is None:
                    reason = self._handle_events(selector, sock, timeout)
                if reason is not None:
                    return reason
        finally:
            selector.unregister(sock)

    def _take_batch(self) -> tuple[LineBatch | None, bool]:
        """The oldest pending lines as the next batch (None when nothing is pending), and
        whether close() has been called."""
        with self._lock:
            batch = self._pending.take_batch()
            self._inflight_lines = batch.lines if batch is not None else 0
            self._idle = batch is None
            stopping = self._stop
        return batch, stopping

    def _write(self, sock: socket.socket, batch: LineBatch) -> bool:
        """Hands the socket as much of the batch as it takes without waiting and counts the
        lines that are then complete. False when it took nothing (its buffer is full); an
        OSError means the connection failed."""
        progressed, lines, size = batch.write_to(sock)
        if lines:
            with self._lock:
                self._n_sent += lines
                self._n_bytes += size
                self._inflight_lines -= lines
        return progressed

    def _wait_limit(self, writing: bool, last_progress: float) -> tuple[float | None, str | None]:
        """How long the writer may wait for the socket (None: no limit), or why it gives the
        connection up instead: no byte taken for stall_timeout while a batch waits, or the
        flush_timeout of close() has run out."""
        now = time.monotonic()
        timeout: float | None = None
        if writing and self._stall_timeout is not None:
            timeout = last_progress + self._stall_timeout - now
            if timeout <= 0:
                return None, self._stalled(self._stall_timeout)
        if self._stop:
            left = self._stop_deadline - now
            if left <= 0:
                return None, (
                    f"closing: {self.spec} did not take the last lines within "
                    f"{self._flush_timeout:g} s"
                )
            timeout = left if timeout is None else min(timeout, left)
        return timeout, None

    def _handle_events(
        self, selector: selectors.BaseSelector, sock: socket.socket, timeout: float | None
    ) -> str | None:
        """Waits up to `timeout` for the socket or a wake-up and handles what came; returns
        why the connection is lost, if it is."""
        for key, mask in selector.select(timeout):
            if key.fileobj is self._waker.reader:
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
        return None

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
            lost = self._pending.clear() + self._inflight_lines
            self._inflight_lines = 0
            self._idle = False
            if reason is not None:
                self._n_errors += 1
                self._last_error = reason + (f"; {lost:,} unsent lines dropped" if lost else "")
            self._lose(lost, cause=reason or f"{self.spec} closed with lines unsent")
        self._connected_event.clear()
        # Graceful after a clean close: the controller reads every line we wrote. Abortive
        # after a failure: what is still queued towards it is stale, maybe half a line.
        close_socket(sock, abort=reason is not None)
