"""``ServerOutput``: planarcal as the server (``-o tcp-listen://HOST:PORT``). Controllers
connect to it (up to ``max_clients`` at once), whenever they like, and read whole lines: the
stream of every frame, or (trigger mode) one answer per request.

One background thread owns every socket (a selector over the listener, the clients and a
wake-up pipe; all non-blocking), like ``TcpOutput``'s writer, so the loop only appends lines
to per-client queues in memory and returns: no client, however slow, stalled or gone, makes
it wait, nor holds back the other clients.
"""

from __future__ import annotations

import collections
import contextlib
import errno
import selectors
import socket
import threading
import time
from collections.abc import Callable

from planarcal.errors import OutputError
from planarcal.live.output_server_stats import ClientStats, ServerStats
from planarcal.live.output_sink import Output, OutputStats, encode_line
from planarcal.live.output_socket import (
    LineBatch,
    LineQueue,
    Waker,
    close_socket,
    configure_socket,
)
from planarcal.live.output_spec import check_port, netloc

__all__ = ["ServerOutput"]

# A request line longer than this is not a request: answered with an error and skipped.
MAX_REQUEST_BYTES = 1024

# Requests one client may have waiting for a frame at once; more are answered with an error.
MAX_WAITING_REQUESTS = 16

# Replies one client may be owed (error lines held back behind a request that waits for its
# frame included); a client that sends more lines than that is let go.
MAX_OWED_REPLIES = 64

# Clients that have left and are still listed in the stats (the totals count them all).
_GONE_KEPT = 16

IDLE_TIMEOUT_S = 600.0
"""Trigger mode: a client that sends no request for this long is closed (``idle_timeout``).
Longer than a controller's pauses between parts (seconds) or batches (minutes); short
enough that a controller that vanished without closing (a power cut, a reboot) frees its
place in minutes, not at TCP keep-alive's two hours."""

EVICT_IDLE_S = 10.0
"""Trigger mode, at ``max_clients``: a new connection takes the place of the client idle
longest, if it has been idle at least this long (or ``idle_timeout``, if shorter)."""

# How often the fault check runs while requests wait for a frame, s.
_FAULT_POLL_S = 0.1


class _Reply:
    """A request's place in its client's line of replies: when it came (time.time()), by
    when it must be answered (monotonic), and its reply once known (None: waiting for a
    frame)."""

    __slots__ = ("data", "deadline", "received")

    def __init__(self, received: float, deadline: float, data: bytes | None = None) -> None:
        self.received = received
        self.deadline = deadline
        self.data = data


class _Client:
    """One connection's state. Its counters and queue are shared with the loop's thread
    (under the server's lock); its socket is the selector thread's alone."""

    __slots__ = (
        "active",
        "answers",
        "batch",
        "bytes",
        "closed_by",
        "discarding",
        "eof",
        "error_lines",
        "failed",
        "full",
        "idle",
        "inbuf",
        "interest",
        "last_progress",
        "n_requests",
        "peer",
        "queue",
        "requests",
        "sent",
        "sock",
    )

    def __init__(self, sock: socket.socket, peer: str, queue: LineQueue) -> None:
        self.sock = sock
        self.peer = peer
        self.queue = queue
        self.batch: LineBatch | None = None
        self.idle = True
        """Nothing queued nor in flight: a new line must wake the selector thread."""
        self.last_progress = time.monotonic()
        self.inbuf = bytearray()
        self.discarding = False
        """Skipping the rest of an overlong request line."""
        self.requests: collections.deque[_Reply] = collections.deque()
        """Replies owed, in the order of the requests: a reply goes out once it and every
        one before it are known, so a controller may pair answers with requests in order."""
        self.eof = False
        """The client closed its side: no more requests; it leaves once its lines are out."""
        self.interest = 0
        self.active = time.monotonic()
        """When the client last did something (connected, sent a line): for the idle
        timeout and for choosing whom to evict."""
        self.sent = self.full = self.failed = self.bytes = 0
        self.n_requests = self.answers = self.error_lines = 0
        self.closed_by: str | None = None

    @property
    def owes(self) -> bool:
        """Something is owed to it or on its way: a reply, a queued or half-written line."""
        return bool(self.requests) or self.batch is not None or bool(len(self.queue))

    def stats(self) -> ClientStats:
        return ClientStats(
            self.peer,
            self.closed_by is None,
            self.sent,
            self.full + self.failed,
            self.full,
            self.failed,
            self.n_requests,
            self.answers,
            self.error_lines,
            self.closed_by,
        )


def _peer_name(address: object) -> str:
    if isinstance(address, tuple) and len(address) >= 2:
        return netloc(str(address[0]), int(address[1]))
    return str(address)


class ServerOutput(Output):
    """Listens at HOST:PORT (port 0: any free port, then in ``port``) for controllers; see
    the module docstring.

    Stream mode (``trigger_word=None``): every line ``send`` gets goes to every connected
    client. A client that connects mid-stream starts with the next line sent after it was
    accepted: it never sees half a line. Each client has its own bounded queue
    (``max_pending_lines`` lines and ``max_pending_bytes`` bytes; with the kernel's send
    buffer of ``send_buffer`` bytes, what a client that stops reading can hold up); when it
    is full the client's OLDEST lines are dropped and counted for it. A client that takes no
    byte for ``stall_timeout`` seconds while lines wait is reset (its stale backlog
    discarded); one that resets, or closes, is let go. Anything a client sends is ignored.

    Trigger mode (``trigger_word`` given): nothing is sent unrequested. A client sends a
    request line (the word, case-sensitive; surrounding spaces and a CR are ignored, blank
    lines skipped); ``answer(timestamp, make_line)``, which the loop calls for each frame,
    answers every request received before ``timestamp`` (the time the frame was read) with
    that frame's line: the answer is always of a frame read after the request. A request
    gets an error line instead (``error_line(message)``) when ``fault()`` says the source
    is down (at once, and while it waits), when no frame comes within ``trigger_timeout``
    seconds, when the server closes, or when more than 16 of the client's requests are
    waiting. Any other line gets an error line naming the word. Every line a client sends
    (blank lines aside) gets exactly one line back, in the order sent (an error for a later
    line waits behind an answer still owed), so a controller may pipeline requests and pair
    the replies in order; one that sends more than 64 lines ahead of their replies is let
    go. A client that closes its side gets the replies it is owed, then is let go. The
    frame lines of the answers are made (``make_line``) only when a request waits: between
    triggers the loop formats nothing.

    ``max_clients`` connections at most. In trigger mode a client is idle while it owes
    nothing and has sent no line: one idle for ``idle_timeout`` seconds (None: never) gets
    an error line and is closed, and at ``max_clients`` a new connection takes the place of
    the client idle longest (it too gets an error line saying why), provided that one has
    been idle for ``EVICT_IDLE_S`` (or ``idle_timeout``, if shorter): a controller that
    restarts gets in even while its old connection, dead without a goodbye, still holds a
    place. Otherwise (and always in stream mode, where a client that stops reading is reset
    by ``stall_timeout``) the new connection gets an error line and is closed. Refusals,
    evictions, idle closes, resets and lost lines are reported on the
    ``planarcal.live.outputs`` logger while they happen (rate-limited).

    ``close`` answers waiting requests with an error, writes what is queued for up to
    ``flush_timeout`` seconds, closes every connection and the listener."""

    def __init__(
        self,
        host: str,
        port: int,
        *,
        trigger_word: str | None = None,
        trigger_timeout: float = 3.0,
        error_line: Callable[[str], str] | None = None,
        fault: Callable[[], str | None] | None = None,
        max_clients: int = 32,
        idle_timeout: float | None = IDLE_TIMEOUT_S,
        max_pending_lines: int = 256,
        max_pending_bytes: int = 1 << 20,
        stall_timeout: float | None = 5.0,
        flush_timeout: float = 1.0,
        send_buffer: int | None = 32 * 1024,
        backlog: int = 16,
    ) -> None:
        check_port(port, lowest=0)
        if not host:
            raise OutputError("a TCP server needs a host to listen on (0.0.0.0: every interface)")
        for name, value in (
            ("max_clients", max_clients),
            ("max_pending_lines", max_pending_lines),
            ("max_pending_bytes", max_pending_bytes),
            ("backlog", backlog),
        ):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise OutputError(f"{name} must be a whole number of at least 1, not {value!r}")
        for name, seconds in (
            ("trigger_timeout", trigger_timeout),
            ("stall_timeout", stall_timeout),
            ("idle_timeout", idle_timeout),
        ):
            if seconds is not None and not (isinstance(seconds, int | float) and seconds > 0):
                raise OutputError(f"{name} must be a positive number of seconds, not {seconds}")
        if not flush_timeout >= 0:
            raise OutputError(f"flush_timeout must be >= 0 seconds, not {flush_timeout}")
        if send_buffer is not None and send_buffer < 1:
            raise OutputError(f"send_buffer must be at least 1 byte, not {send_buffer}")
        if trigger_word is not None:
            check_trigger_word(trigger_word)
        super().__init__(f"tcp-listen://{netloc(host, port)}")
        self.host = host
        self.trigger_word = trigger_word
        self._word = trigger_word.encode("utf-8") if trigger_word is not None else b""
        self._trigger_timeout = float(trigger_timeout)
        self._error_line = error_line or _plain_error_line
        self._fault = fault
        self._max_clients = max_clients
        self._idle_timeout = idle_timeout
        self._evict_idle = EVICT_IDLE_S if idle_timeout is None else min(EVICT_IDLE_S, idle_timeout)
        self._max_lines = max_pending_lines
        self._max_bytes = max_pending_bytes
        self._stall_timeout = stall_timeout
        self._flush_timeout = flush_timeout
        self._send_buffer = send_buffer

        self._listener = self._listen(host, port, backlog)
        self.port: int = self._listener.getsockname()[1]
        """The port listened on (the one the system chose, for port 0)."""
        self.spec = f"tcp-listen://{netloc(host, self.port)}"

        # Shared with the selector thread, under self._lock.
        self._clients: list[_Client] = []
        self._gone: collections.deque[ClientStats] = collections.deque(maxlen=_GONE_KEPT)
        self._waiting = 0  # requests of all clients waiting for a frame
        self._stop = False
        self._stop_deadline = 0.0
        self._accepted = self._refused = self._evicted = self._idle_closed = 0
        self._lines = self._unheard = 0
        self._requests = self._answers = self._error_lines = 0

        self._waker = Waker()
        self._thread = threading.Thread(
            target=self._run, name=f"planarcal output {self.spec}", daemon=True
        )
        self._thread.start()

    def _listen(self, host: str, port: int, backlog: int) -> socket.socket:
        where = f"tcp-listen://{netloc(host, port)}"
        try:
            infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
        except socket.gaierror as e:
            raise OutputError(f"cannot listen on {where}: unknown host ({e.strerror})") from None
        family, kind, proto, _, address = infos[0]
        sock = socket.socket(family, kind, proto)
        try:
            # A restart may bind at once over the last run's closing connections; two live
            # servers still cannot share the port.
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind(address)
            sock.listen(backlog)
            sock.setblocking(False)
        except OSError as e:
            sock.close()
            if e.errno == errno.EADDRINUSE:
                raise OutputError(
                    f"cannot listen on {where}: port {port} is already in use (another "
                    "planarcal run, or another server; choose another port)"
                ) from None
            raise OutputError(f"cannot listen on {where}: {e.strerror or e}") from None
        return sock

    @property
    def address(self) -> str:
        """Where the server listens, ``host:port``."""
        return netloc(self.host, self.port)

    def wait_clients(self, n: int = 1, timeout: float | None = None) -> bool:
        """Waits until at least `n` clients are connected (True) or `timeout` s have passed."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            with self._lock:
                if len(self._clients) >= n:
                    return True
            if deadline is not None and time.monotonic() >= deadline:
                return False
            time.sleep(0.005)

    @property
    def stats(self) -> ServerStats:
        with self._lock:
            clients = self._clients
            return ServerStats(
                sent=self._n_sent,
                dropped=self._n_full + self._n_failed,
                dropped_full_buffer=self._n_full,
                dropped_write_failed=self._n_failed,
                bytes_sent=self._n_bytes,
                errors=self._n_errors,
                reconnects=0,
                connect_attempts=0,
                connected=not self._closing,
                pending=sum(len(c.queue) + _inflight(c) for c in clients),
                broken=False,
                last_error=self._last_error,
                address=self.address,
                clients=len(clients),
                accepted=self._accepted,
                refused=self._refused,
                evicted=self._evicted,
                idle_closed=self._idle_closed,
                lines=self._lines,
                unheard=self._unheard,
                requests=self._requests,
                answers=self._answers,
                error_lines=self._error_lines,
                per_client=(*self._gone, *(c.stats() for c in clients)),
            )

    def _open_state(self, stats: OutputStats) -> str:
        n = stats.clients if isinstance(stats, ServerStats) else 0
        return f"listening, {n} client{'s' if n != 1 else ''}"

    # --- the loop's side: microseconds, never a system call unless the selector sleeps ---

    def _send(self, data: bytes) -> bool:
        with self._lock:
            if self._closing:
                return self._drop(cause=f"a line sent after {self.spec} was closed")
            self._lines += 1
            listeners = [c for c in self._clients if not c.eof]
            if not listeners:
                self._unheard += 1
                return False
            wake = False
            for client in listeners:
                wake |= self._queue(client, data)
        if wake:
            self._waker.wake()
        return True

    def answer(self, timestamp: float, make_line: Callable[[], str]) -> int:
        """Trigger mode: answers every request received before `timestamp` (when the frame
        was read, time.time()) with the line `make_line()` makes (called only if a request
        waits: formatting costs nothing between triggers). Returns how many requests it
        answered."""
        if not self._waiting:  # an int read: the common case takes no lock
            return 0
        with self._lock:
            due = any(_first_waiting(c, timestamp) is not None for c in self._clients)
        if not due:
            return 0
        data = encode_line(make_line())
        answered = 0
        wake = False
        # Filled and released under one hold of the lock: the selector thread never sees a
        # request gone and its answer not yet queued (it would let a client that has closed
        # its side go without it).
        with self._lock:
            for client in self._clients:
                n = 0
                for reply in client.requests:  # in the order received: stop at a later one
                    if reply.data is not None:
                        continue
                    if reply.received > timestamp:
                        break
                    reply.data = data
                    n += 1
                if not n:
                    continue
                self._waiting -= n
                client.answers += n
                answered += n
                wake |= self._release(client)
            self._answers += answered
        if wake:
            self._waker.wake()
        return answered

    def _release(self, client: _Client) -> bool:
        """Queues the replies at the head of the client's line that are known (under the
        lock); True if the selector thread must be woken for them."""
        wake = False
        requests = client.requests
        while requests and (data := requests[0].data) is not None:
            requests.popleft()
            wake |= self._queue(client, data)
        return wake

    def _queue(self, client: _Client, data: bytes) -> bool:
        """Queues a line for a client (under the lock); True if the selector thread must be
        woken for it."""
        if len(data) > self._max_bytes:
            client.failed += 1
            self._drop(
                f"a line of {len(data):,} bytes is larger than max_pending_bytes "
                f"({self._max_bytes:,}); dropped"
            )
            return False
        pushed_out = client.queue.push(data)
        if pushed_out:
            client.full += pushed_out
            self._lose(
                pushed_out,
                full_buffer=True,
                cause=f"{client.peer} reads more slowly than lines come: its oldest are dropped",
            )
        wake, client.idle = client.idle, False
        return wake

    def _close(self) -> None:
        with self._lock:
            self._stop = True
            self._stop_deadline = time.monotonic() + self._flush_timeout
        self._waker.wake()
        if threading.current_thread() is not self._thread:
            self._thread.join(self._flush_timeout + 1.0)
        if not self._thread.is_alive():
            self._waker.close()

    # --- the selector thread ---

    def _run(self) -> None:
        selector = selectors.DefaultSelector()
        selector.register(self._listener, selectors.EVENT_READ)
        selector.register(self._waker.reader, selectors.EVENT_READ)
        stopping = False
        try:
            while True:
                if self._stop and not stopping:
                    stopping = True
                    selector.unregister(self._listener)
                    self._listener.close()  # no new clients; the port is free at once
                    self._fail_requests("planarcal is stopping")
                self._pump(selector)
                if stopping and self._flushed():
                    break
                for key, mask in selector.select(self._next_timeout(stopping)):
                    if key.fileobj is self._listener:
                        self._accept(selector)
                    elif key.fileobj is self._waker.reader:
                        self._waker.drain()
                    elif mask & selectors.EVENT_READ:
                        self._read(selector, key.data)
                self._check_timers(selector)
        except Exception as e:  # a bug here must not pass silently: say it, then stop
            with self._lock:
                self._n_errors += 1
                self._last_error = f"the server {self.spec} failed: {e!r}"
            raise
        finally:
            with self._lock:
                clients = list(self._clients)
            for client in clients:
                in_flight = client.batch is not None and not client.batch.written
                self._remove(
                    selector,
                    client,
                    "closing: lines still in flight" if in_flight else None,
                    closed_by="the server closed",
                )
            if not stopping:
                self._listener.close()
            selector.close()

    def _idle_until(self, client: _Client) -> float | None:
        """Trigger mode: when the client's idle timeout runs out (monotonic), if it is idle
        (it owes nothing, and has not closed its side); None otherwise."""
        if self.trigger_word is None or self._idle_timeout is None:
            return None
        if client.owes or client.eof or client.closed_by is not None:
            return None
        return client.active + self._idle_timeout

    def _flushed(self) -> bool:
        """True when every queued line is written, or close()'s flush time has run out."""
        if time.monotonic() >= self._stop_deadline:
            return True
        with self._lock:
            return all(c.batch is None and not len(c.queue) for c in self._clients)

    def _next_timeout(self, stopping: bool) -> float | None:
        """How long the selector may sleep: until the next stall limit, request deadline,
        fault poll or the end of close()'s flush time."""
        now = time.monotonic()
        limits: list[float] = []
        with self._lock:
            for client in self._clients:
                if client.batch is not None and self._stall_timeout is not None:
                    limits.append(client.last_progress + self._stall_timeout)
                limits.extend(r.deadline for r in client.requests if r.data is None)
                idle_until = self._idle_until(client)
                if idle_until is not None:
                    limits.append(idle_until)
            if self._waiting and self._fault is not None:
                limits.append(now + _FAULT_POLL_S)
        if stopping:
            limits.append(self._stop_deadline)
        if not limits:
            return None
        return max(0.0, min(limits) - now)

    def _accept(self, selector: selectors.BaseSelector) -> None:
        while True:
            try:
                sock, address = self._listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as e:  # out of descriptors, a connection aborted before accept
                self._error(f"{self.spec}: accept failed: {e.strerror or e}")
                return
            peer = _peer_name(address)
            sock.setblocking(False)
            if not self._make_room(selector, peer):
                self._refuse(sock, peer)
                continue
            configure_socket(sock, send_buffer=self._send_buffer, stall_timeout=self._stall_timeout)
            client = _Client(sock, peer, LineQueue(self._max_lines, self._max_bytes))
            with self._lock:
                self._clients.append(client)
                self._accepted += 1
            self._set_interest(selector, client, selectors.EVENT_READ)

    def _make_room(self, selector: selectors.BaseSelector, newcomer: str) -> bool:
        """True when a new client may come in: below max_clients, or (trigger mode) after
        the client idle longest, for at least the eviction threshold, has been let go."""
        now = time.monotonic()
        with self._lock:
            if len(self._clients) < self._max_clients:
                return True
            if self.trigger_word is None:
                return False
            idle = [c for c in self._clients if not c.owes and not c.eof]
            oldest = min(idle, key=lambda c: c.active, default=None)
            if oldest is None or now - oldest.active < self._evict_idle:
                return False
            self._evicted += 1
            message = (
                f"{oldest.peer} was closed after {now - oldest.active:.0f} s without a request, "
                f"to make room for {newcomer} ({self._max_clients} controllers at most)"
            )
            self._report("idle client evicted", "idle clients evicted", message)
        self._let_go(selector, oldest, message, closed_by="evicted for a new client (idle)")
        return True

    def _refuse(self, sock: socket.socket, peer: str) -> None:
        """Tells a connection beyond max_clients why, and closes it."""
        message = (
            f"{self._max_clients} controllers are connected already, the most this server "
            "takes (--max-clients); try again later"
        )
        with self._lock:
            self._refused += 1
            self._error_lines += 1
            self._report(
                "connection refused",
                "connections refused",
                f"refused {peer}: {message}",
            )
        with contextlib.suppress(OSError):
            sock.send(encode_line(self._error_line(message)))
        close_socket(sock, abort=False)

    def _let_go(
        self, selector: selectors.BaseSelector, client: _Client, message: str, closed_by: str
    ) -> None:
        """Closes an idle client gracefully after an error line saying why. It owes nothing,
        so its stream is on a line boundary and the line goes out whole or not at all."""
        data = encode_line(self._error_line(message))
        try:
            written = client.sock.send(data)
        except OSError:
            written = 0
        with self._lock:
            client.error_lines += 1
            self._error_lines += 1
            if written == len(data):
                client.sent += 1
                client.bytes += written
                self._n_sent += 1
                self._n_bytes += written
        self._remove(selector, client, None, closed_by=closed_by)

    def _set_interest(self, selector: selectors.BaseSelector, client: _Client, want: int) -> None:
        if want == client.interest:
            return
        if not client.interest:
            selector.register(client.sock, want, client)
        elif not want:
            selector.unregister(client.sock)
        else:
            selector.modify(client.sock, want, client)
        client.interest = want

    def _read(self, selector: selectors.BaseSelector, client: _Client) -> None:
        try:
            data = client.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as e:
            self._remove(selector, client, self._lost(client, e))
            return
        if not data:
            # The client closed its side: it sends nothing more, and may still read.
            client.eof = True
            with self._lock:
                if self.trigger_word is None:
                    lost = client.queue.clear()
                    client.failed += lost
                    self._lose(lost, cause=f"{client.peer} closed its side with lines queued")
            self._set_interest(selector, client, client.interest & ~selectors.EVENT_READ)
            return
        if self.trigger_word is not None:
            client.active = time.monotonic()
            self._requests_in(selector, client, data)
        # In stream mode what a client sends means nothing: it is read and let go.

    def _requests_in(self, selector: selectors.BaseSelector, client: _Client, data: bytes) -> None:
        """Splits what a client sent into request lines and handles each. A line longer than
        MAX_REQUEST_BYTES gets one error line, however it arrives (whole, or in pieces that
        are each skipped up to its newline), so every line sent gets exactly one reply."""
        buf = client.inbuf
        if client.discarding:
            # The rest of an overlong line, already answered: skipped up to its newline.
            end = data.find(b"\n")
            if end < 0:
                return
            client.discarding = False
            data = data[end + 1 :]
        buf += data
        while (end := buf.find(b"\n")) >= 0:
            line = bytes(buf[: min(end, MAX_REQUEST_BYTES + 1)])
            del buf[: end + 1]
            if len(client.requests) >= MAX_OWED_REPLIES:
                self._remove(
                    selector,
                    client,
                    f"{client.peer} sent more than {MAX_OWED_REPLIES} requests ahead of their "
                    "answers; reset the connection",
                )
                return
            if len(line) > MAX_REQUEST_BYTES:
                self._reply_overlong(client)
            else:
                self._request(client, line)
        if len(buf) > MAX_REQUEST_BYTES:
            buf.clear()
            client.discarding = True
            self._reply_overlong(client)

    def _reply_overlong(self, client: _Client) -> None:
        self._reply_error(
            client,
            f"a request line longer than {MAX_REQUEST_BYTES} bytes; send "
            f"{self.trigger_word} and a newline",
        )

    def _request(self, client: _Client, raw: bytes) -> None:
        text = raw.strip()
        if not text:
            return  # a blank line (a keep-alive): not a request
        if text != self._word:
            shown = text[:40].decode("utf-8", "replace")
            self._reply_error(
                client,
                f"unknown request {shown!r}: send {self.trigger_word} and a newline "
                "(case-sensitive)",
            )
            return
        with self._lock:
            client.n_requests += 1
            self._requests += 1
            waiting = len(client.requests)
        fault = self._source_fault()
        if fault is not None:
            self._reply_error(client, f"no frame to answer with: {fault}")
        elif waiting >= MAX_WAITING_REQUESTS:
            self._reply_error(client, f"{waiting} requests of this client wait already")
        else:
            with self._lock:
                received = time.time()
                client.requests.append(_Reply(received, time.monotonic() + self._trigger_timeout))
                self._waiting += 1

    def _reply_error(self, client: _Client, message: str) -> None:
        """An error line as the client's next reply (after those it is owed already)."""
        data = encode_line(self._error_line(message))
        with self._lock:
            if client.closed_by is not None:
                return
            client.error_lines += 1
            self._error_lines += 1
            client.requests.append(_Reply(0.0, 0.0, data))
            wake = self._release(client)
        if wake:
            self._waker.wake()

    def _fail_requests(self, message: str, late_only: bool = False) -> None:
        """Answers waiting requests (of every client; only those past their deadline with
        `late_only`) with an error line saying `message`."""
        now = time.monotonic()
        data: bytes | None = None
        wake = False
        with self._lock:
            for client in self._clients:
                n = 0
                for reply in client.requests:
                    if reply.data is None and (not late_only or reply.deadline <= now):
                        if data is None:  # made only when a request fails
                            data = encode_line(self._error_line(message))
                        reply.data = data
                        n += 1
                if n:
                    self._waiting -= n
                    client.error_lines += n
                    self._error_lines += n
                    wake |= self._release(client)
        if wake:
            self._waker.wake()

    def _check_timers(self, selector: selectors.BaseSelector) -> None:
        """Resets stalled clients; closes idle ones; answers requests past their deadline,
        or while the source is down, with an error line."""
        now = time.monotonic()
        with self._lock:
            clients = list(self._clients)
            waiting = self._waiting
        for client in clients:
            deadline = self._idle_until(client)
            if deadline is not None and deadline <= now:
                idle = now - client.active
                message = f"{client.peer} was closed after {idle:.0f} s without a request"
                with self._lock:
                    self._idle_closed += 1
                    self._report("idle client closed", "idle clients closed", message)
                self._let_go(
                    selector, client, message + " (--client-idle-timeout)", closed_by="idle"
                )
                continue
            if (
                client.batch is not None
                and self._stall_timeout is not None
                and now - client.last_progress >= self._stall_timeout
            ):
                self._remove(selector, client, self._stalled(client))
        if waiting:
            fault = self._source_fault()
            if fault is not None:
                self._fail_requests(f"no frame to answer with: {fault}")
            else:
                self._fail_requests(
                    f"no frame within {self._trigger_timeout:g} s of the request", late_only=True
                )

    def _pump(self, selector: selectors.BaseSelector) -> None:
        """Writes to every client what its socket takes without waiting; watches for
        writability where a batch is stuck; lets go of clients that are done."""
        with self._lock:
            clients = list(self._clients)
        for client in clients:
            while True:
                if client.batch is None:
                    with self._lock:
                        client.batch = client.queue.take_batch()
                        client.idle = client.batch is None
                    if client.batch is None:
                        break
                    client.last_progress = time.monotonic()
                try:
                    progressed, lines, size = client.batch.write_to(client.sock)
                except OSError as e:
                    self._remove(selector, client, self._lost(client, e))
                    break
                if lines:
                    with self._lock:
                        client.sent += lines
                        client.bytes += size
                        self._n_sent += lines
                        self._n_bytes += size
                if not progressed:
                    break
                # A reply on its way counts as activity: idle time starts once it is out.
                client.last_progress = client.active = time.monotonic()
                if client.batch.written:
                    client.batch = None
            if client.closed_by is not None:
                continue
            if client.eof and client.batch is None and not client.requests and client.idle:
                self._remove(selector, client, None, closed_by="closed by the client")
                continue
            want = 0 if client.eof else selectors.EVENT_READ
            if client.batch is not None:
                want |= selectors.EVENT_WRITE
            self._set_interest(selector, client, want)

    def _remove(
        self,
        selector: selectors.BaseSelector,
        client: _Client,
        reason: str | None,
        *,
        closed_by: str | None = None,
    ) -> None:
        """Lets a client go: gracefully (`reason` None: all it was given is written), or by
        a reset (`reason` says why, and counts as an error). What it still had queued, and
        its waiting requests, are dropped and counted."""
        with self._lock:
            if client.closed_by is not None:
                return
            lost = client.queue.clear() + _inflight(client)
            client.failed += lost
            self._waiting -= sum(r.data is None for r in client.requests)
            client.requests.clear()
            client.closed_by = closed_by or reason or "closed"
            if reason is not None:
                self._n_errors += 1
                self._last_error = reason + (f"; {lost:,} unsent lines dropped" if lost else "")
                self._report("client reset", "clients reset", reason)
            self._lose(lost, cause=f"{client.peer} left with lines unsent ({client.closed_by})")
            self._clients.remove(client)
            self._gone.append(client.stats())
        self._set_interest(selector, client, 0)
        close_socket(client.sock, abort=reason is not None)

    def _stalled(self, client: _Client) -> str:
        return (
            f"{client.peer} took no data for {self._stall_timeout:g} s (stopped reading, or "
            "gone); reset the connection"
        )

    def _lost(self, client: _Client, e: OSError) -> str:
        if e.errno == errno.ETIMEDOUT and self._stall_timeout is not None:
            # The kernel's TCP_USER_TIMEOUT fired: the same verdict as our own stall timer.
            return self._stalled(client)
        return f"lost {client.peer}: {e.strerror or e}"

    def _source_fault(self) -> str | None:
        """Why the source cannot give a frame now (from ``fault``), or None. A ``fault``
        that raises is a fault too: the selector thread must outlive it."""
        if self._fault is None:
            return None
        try:
            return self._fault()
        except Exception as e:
            return f"the state of the source is unknown ({e!r})"

    def _report(self, singular: str, plural: str, message: str) -> None:
        """Reports a client refused, evicted, closed or reset on ``LOG`` (rate-limited, per
        kind: "client reset", "clients reset"). The caller holds self._lock."""
        self._warnings.note(self._warnings.kind(singular, plural), 1, message)

    def _error(self, message: str) -> None:
        with self._lock:
            self._n_errors += 1
            self._last_error = message


def _first_waiting(client: _Client, timestamp: float) -> _Reply | None:
    """The client's first request waiting for a frame, if it came before `timestamp`."""
    for reply in client.requests:
        if reply.data is None:
            return reply if reply.received <= timestamp else None
    return None


def _inflight(client: _Client) -> int:
    """Lines of the client's batch not yet fully written."""
    batch = client.batch
    return batch.lines - batch.done if batch is not None else 0


def _plain_error_line(message: str) -> str:
    return "ERROR," + " ".join(message.split()).replace(",", ";")


def check_trigger_word(word: str) -> None:
    """Raises OutputError unless `word` can be a request line: non-empty, printable, no
    spaces (a controller sends it followed by a newline)."""
    if not isinstance(word, str) or not word:
        raise OutputError("the trigger word must be a non-empty string")
    if not word.isprintable() or any(c.isspace() for c in word) or len(word) > 64:
        raise OutputError(
            f"the trigger word {word!r} must be printable, without spaces, at most 64 characters"
        )
