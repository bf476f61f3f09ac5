"""``UdpOutput``: one datagram per line to a peer, from a non-blocking socket that never
waits and never retries.
"""

from __future__ import annotations

import socket

from planarcal.errors import OutputError
from planarcal.live.output_sink import Output
from planarcal.live.output_spec import check_port, netloc

__all__ = ["UdpOutput"]


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
        check_port(port)
        if not 1 <= max_datagram <= 65_507:
            raise OutputError(
                f"max_datagram must be between 1 and 65,507 bytes (UDP's limit), not {max_datagram}"
            )
        super().__init__(f"udp://{netloc(host, port)}")
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
                return self._drop(cause=f"a line sent after {self.spec} was closed")
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
                    return self._drop(
                        f"the socket buffer for {self.spec} is full; line dropped", full_buffer=True
                    )
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
