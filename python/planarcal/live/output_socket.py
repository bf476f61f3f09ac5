"""The pieces the TCP sinks share (``TcpOutput``, a client; ``ServerOutput``, a server): a
bounded queue of lines that keeps the newest, the batch of lines committed to a connection
(never half a line), the socket options, a graceful or abortive close, and the wake-up
pipe of a selector thread.
"""

from __future__ import annotations

import collections
import contextlib
import itertools
import socket
import struct

__all__ = [
    "BATCH_BYTES",
    "LineBatch",
    "LineQueue",
    "Waker",
    "close_socket",
    "configure_socket",
]

# At most this much of a queue is handed to a socket at once: what has been handed over is
# committed (a line once started must be finished on that connection), so a smaller batch
# leaves more of the queue free to drop its oldest lines for newer ones behind a slow reader.
BATCH_BYTES = 64 * 1024


class LineBatch:
    """Lines joined for one connection. What has been handed to the socket is committed: a
    line once started must be finished on that connection, or the reader sees half of it."""

    __slots__ = ("data", "done", "ends", "offset")

    def __init__(self, lines: list[bytes]) -> None:
        self.data = memoryview(b"".join(lines))
        self.ends = list(itertools.accumulate(len(line) for line in lines))
        """Where each line ends in ``data``."""
        self.done = 0
        """Lines fully written."""
        self.offset = 0
        """Bytes written."""

    @property
    def lines(self) -> int:
        """How many lines the batch holds."""
        return len(self.ends)

    @property
    def written(self) -> bool:
        """True once every byte is written."""
        return self.offset == len(self.data)

    def rest(self) -> memoryview:
        """The bytes not written yet."""
        return self.data[self.offset :]

    def advance(self, written: int) -> tuple[int, int]:
        """Records `written` more bytes as written; returns how many lines that completed,
        and their size in bytes."""
        self.offset += written
        finished = self.done
        while finished < len(self.ends) and self.ends[finished] <= self.offset:
            finished += 1
        if finished == self.done:
            return 0, 0
        start = self.ends[self.done - 1] if self.done else 0
        lines, size = finished - self.done, self.ends[finished - 1] - start
        self.done = finished
        return lines, size

    def write_to(self, sock: socket.socket) -> tuple[bool, int, int]:
        """Hands the socket as much of the batch as it takes without waiting: whether it
        took anything (False: its buffer is full), and the lines (and bytes) that completed.
        An OSError means the connection failed."""
        try:
            written = sock.send(self.rest())
        except BlockingIOError:
            return False, 0, 0
        lines, size = self.advance(written)
        return True, lines, size


class LineQueue:
    """Encoded lines waiting for a connection, at most ``max_lines`` lines and ``max_bytes``
    bytes: beyond that the OLDEST are dropped, so what gets through is as fresh as it can
    be. Not thread-safe: the owner holds its lock."""

    __slots__ = ("_lines", "max_bytes", "max_lines", "size")

    def __init__(self, max_lines: int, max_bytes: int) -> None:
        self._lines: collections.deque[bytes] = collections.deque()
        self.max_lines = max_lines
        self.max_bytes = max_bytes
        self.size = 0
        """Bytes queued."""

    def __len__(self) -> int:
        return len(self._lines)

    def push(self, data: bytes) -> int:
        """Queues a line (no larger than max_bytes); returns how many old lines it pushed
        out."""
        lines = self._lines
        lines.append(data)
        self.size += len(data)
        dropped = 0
        while len(lines) > self.max_lines or self.size > self.max_bytes:
            self.size -= len(lines.popleft())
            dropped += 1
        return dropped

    def take_batch(self) -> LineBatch | None:
        """The oldest lines, up to BATCH_BYTES (at least one line), as a batch; None when
        the queue is empty."""
        lines = self._lines
        taken: list[bytes] = []
        size = 0
        while lines and (not taken or size + len(lines[0]) <= BATCH_BYTES):
            line = lines.popleft()
            taken.append(line)
            size += len(line)
        self.size -= size
        return LineBatch(taken) if taken else None

    def clear(self) -> int:
        """Empties the queue; returns how many lines it held."""
        n = len(self._lines)
        self._lines.clear()
        self.size = 0
        return n


def configure_socket(
    sock: socket.socket, *, send_buffer: int | None, stall_timeout: float | None
) -> None:
    """Low latency (no Nagle delay on small lines), a capped kernel buffer (stale data
    queues there too), and dead-peer detection (keep-alive; TCP_USER_TIMEOUT of
    `stall_timeout` where the system has it). Options the system refuses are skipped."""
    options: list[tuple[int, int, int]] = [
        (socket.IPPROTO_TCP, socket.TCP_NODELAY, 1),
        (socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1),
    ]
    if send_buffer is not None:
        options.append((socket.SOL_SOCKET, socket.SO_SNDBUF, send_buffer))
    user_timeout = getattr(socket, "TCP_USER_TIMEOUT", None)
    if user_timeout is not None and stall_timeout is not None:
        options.append((socket.IPPROTO_TCP, user_timeout, int(stall_timeout * 1000)))
    for level, option, value in options:
        with contextlib.suppress(OSError):
            sock.setsockopt(level, option, value)


def close_socket(sock: socket.socket, *, abort: bool) -> None:
    """Closes a connection. Gracefully (``abort=False``): the peer reads every byte written,
    then end of stream. Abortively: a reset, which discards what is still queued towards
    the peer (stale, and possibly ending in half a line) instead of delivering it."""
    with contextlib.suppress(OSError):
        if abort:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        else:
            sock.shutdown(socket.SHUT_WR)
    sock.close()


class Waker:
    """A socket pair that wakes a selector thread: register ``reader`` for EVENT_READ,
    ``wake()`` from any thread, ``drain()`` on the selector thread when it fires."""

    def __init__(self) -> None:
        self.reader, self._writer = socket.socketpair()
        self.reader.setblocking(False)
        self._writer.setblocking(False)

    def wake(self) -> None:
        with contextlib.suppress(OSError):  # full (a wake-up is pending anyway) or closed
            self._writer.send(b"\0")

    def drain(self) -> None:
        with contextlib.suppress(OSError):
            while self.reader.recv(4096):
                pass

    def close(self) -> None:
        self.reader.close()
        self._writer.close()
