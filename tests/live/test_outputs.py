"""planarcal.live.outputs against real sockets, files and pipes: a TCP controller that reads, one
that accepts and never reads, one that goes away and comes back on the same port, one that
resets a connection half-way through a line, none at all; UDP to a listener, to a closed port
and with an oversize line; files appended to and cut short by a size limit; stdout whose
reader has gone. Loopback only, ephemeral ports; waits poll with deadlines."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import struct
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from planarcal.live.outputs import (
    FileOutput,
    Output,
    OutputError,
    StreamOutput,
    TcpOutput,
    UdpOutput,
    open_output,
)

PAD = "x" * 170  # makes a frame line about 200 bytes, like a frame with a few objects


def frame_line(i: int) -> str:
    return json.dumps({"frame": i, "t": i / 500, "pad": PAD})


def wait_for(condition: Callable[[], bool], timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.002)
    return True


def free_port() -> int:
    """A loopback port with nothing listening on it (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
    return port


class Controller:
    """A robot controller stand-in: listens on loopback, accepts connections one after the
    other and, per connection, reads everything (read=True) or never reads a byte."""

    def __init__(self, port: int = 0, *, read: bool = True) -> None:
        self.read = read
        self.listener = socket.socket()
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind(("127.0.0.1", port))
        self.listener.listen()
        self.port: int = self.listener.getsockname()[1]
        self.connections: list[socket.socket] = []
        self.received: list[bytearray] = []
        self._lock = threading.Lock()
        self._threads = [threading.Thread(target=self._accept, daemon=True)]
        self._threads[0].start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self.listener.accept()
            except OSError:
                return
            data = bytearray()
            with self._lock:
                self.connections.append(conn)
                self.received.append(data)
            if self.read:
                t = threading.Thread(target=self._read, args=(conn, data), daemon=True)
                self._threads.append(t)
                t.start()

    def _read(self, conn: socket.socket, data: bytearray) -> None:
        with contextlib.suppress(OSError):
            while chunk := conn.recv(1 << 16):
                with self._lock:
                    data.extend(chunk)

    def lines(self, index: int) -> list[bytes]:
        """The complete lines of connection `index` (an unterminated tail is left out)."""
        with self._lock:
            data = bytes(self.received[index]) if index < len(self.received) else b""
        return data.split(b"\n")[:-1]

    def reset(self, index: int) -> None:
        """Closes connection `index` abortively (RST), as a crashed controller would."""
        conn = self.connections[index]
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        conn.close()

    def close(self) -> None:
        # The listener first, so no new connection lands in a backlog that nobody accepts;
        # shut down, not only closed, so that the accept() blocked on it returns.
        with contextlib.suppress(OSError):
            self.listener.shutdown(socket.SHUT_RDWR)
        self.listener.close()
        with self._lock:
            for conn in self.connections:
                with contextlib.suppress(OSError):
                    conn.close()


@pytest.fixture
def controllers() -> Iterator[list[Controller]]:
    made: list[Controller] = []
    yield made
    for c in made:
        c.close()


@pytest.fixture
def outputs() -> Iterator[list[Output]]:
    made: list[Output] = []
    yield made
    for out in made:
        out.close()


def frames_of(lines: list[bytes]) -> list[int]:
    """Parses every line (failing the test on a broken one) and returns the frame numbers."""
    return [json.loads(line)["frame"] for line in lines]


# --- TCP ---


def test_tcp_reader_gets_every_line_in_order(
    controllers: list[Controller], outputs: list[Output]
) -> None:
    n = 5000
    server = Controller()
    controllers.append(server)
    # A buffer that holds everything: this test is about order and completeness, and a tight
    # loop on one core can outrun the writer thread for a few milliseconds at a time.
    out = TcpOutput("127.0.0.1", server.port, max_pending_lines=n, max_pending_bytes=1 << 24)
    outputs.append(out)
    assert out.wait_connected(5.0)
    assert out.stats.connected
    assert all(out.send(frame_line(i)) for i in range(n))
    out.close()
    assert wait_for(lambda: len(server.lines(0)) == n)
    assert frames_of(server.lines(0)) == list(range(n))
    s = out.stats
    assert (s.sent, s.dropped, s.errors, s.pending) == (n, 0, 0, 0)
    assert s.bytes_sent == sum(len(frame_line(i)) + 1 for i in range(n))
    assert not s.connected
    assert "5,000 sent, 0 dropped" in out.describe()
    out.close()  # idempotent
    assert not out.send(frame_line(n))  # after close: dropped and counted, not raised
    assert out.stats.dropped == 1


def test_tcp_reader_that_stops_reading_never_stalls_the_sender(
    controllers: list[Controller], outputs: list[Output]
) -> None:
    n = 100_000
    server = Controller(read=False)
    controllers.append(server)
    out = TcpOutput("127.0.0.1", server.port, flush_timeout=0.1)
    outputs.append(out)
    assert out.wait_connected(5.0)
    lines = [frame_line(i) for i in range(n)]
    durations = []
    clock = time.perf_counter
    began = clock()
    for line in lines:
        t = clock()
        out.send(line)
        durations.append(clock() - t)
    total = clock() - began
    durations.sort()
    # A send that waited on the socket would wait for the stall limit (5 s); here each send
    # is a buffer append (microseconds). The bounds are loose: a shared machine under load
    # (10 on 2 cores) preempts the test for milliseconds at a time.
    assert total < 20.0, f"{n} sends took {total:.2f} s"
    assert durations[n // 2] < 0.0005, f"median {durations[n // 2] * 1e3:.2f} ms"
    assert durations[-1] < 1.0, f"slowest send {durations[-1] * 1e3:.1f} ms"
    s = out.stats
    assert s.connected and s.errors == 0
    assert s.dropped > n // 2  # the kernel's buffers hold a few thousand lines at most
    # Connected all along: every loss was a line pushed out of the full buffer.
    assert s.dropped_full_buffer == s.dropped and s.dropped_write_failed == 0
    assert s.pending <= 256 + 64 * 1024 // 200
    assert s.sent + s.dropped + s.pending == n
    began = time.monotonic()
    out.close()
    assert time.monotonic() - began < 3.0  # flush_timeout 0.1 s, not the 5 s stall limit
    s = out.stats
    assert s.sent + s.dropped == n and s.pending == 0
    assert "did not take the last lines" in (s.last_error or "")


def test_tcp_controller_that_comes_back_gets_fresh_complete_lines(
    controllers: list[Controller], outputs: list[Output]
) -> None:
    first = Controller()
    controllers.append(first)
    port = first.port
    out = TcpOutput("127.0.0.1", port, backoff_initial=0.01, backoff_max=0.05)
    outputs.append(out)
    assert out.wait_connected(5.0)
    frame = 0

    def send_until(condition: Callable[[], bool], timeout: float = 5.0) -> None:
        nonlocal frame
        deadline = time.monotonic() + timeout
        while not condition():
            assert time.monotonic() < deadline, out.describe()
            out.send(frame_line(frame))
            frame += 1
            time.sleep(0.0005)

    send_until(lambda: len(first.lines(0)) >= 100)
    first.close()  # the controller goes away...
    send_until(lambda: not out.stats.connected)
    send_until(lambda: out.stats.connect_attempts >= 3)  # ...and is being looked for
    came_back = frame
    second = Controller(port)  # ...and comes back on the same port
    controllers.append(second)
    send_until(lambda: len(second.lines(0)) >= 100)
    out.close()

    before = frames_of(first.lines(0))
    assert before == list(range(before[0], before[0] + len(before)))
    with second._lock:
        data = bytes(second.received[0])
    assert data.endswith(b"\n")  # closed gracefully after whole lines
    after = frames_of(data.split(b"\n")[:-1])  # every line parses: nothing half-written
    assert after == sorted(after)
    assert after[0] >= came_back, "lines from before the controller came back were delivered"
    s = out.stats
    assert s.reconnects == 1
    assert s.errors >= 2  # the lost connection and at least one refused attempt
    assert s.sent + s.dropped == frame


def test_tcp_line_cut_by_a_reset_is_not_continued_on_the_next_connection(
    controllers: list[Controller], outputs: list[Output]
) -> None:
    server = Controller(read=False)
    controllers.append(server)
    out = TcpOutput("127.0.0.1", server.port, backoff_initial=0.01, backoff_max=0.05)
    outputs.append(out)
    assert out.wait_connected(5.0)
    frame = 0
    # Fill every buffer: the writer is now stuck part-way through a batch, most likely
    # part-way through a line.
    while out.stats.dropped < 2000:
        out.send(frame_line(frame))
        frame += 1
    stuck = frame
    server.read = True
    server.reset(0)
    deadline = time.monotonic() + 5.0
    while len(server.lines(1)) < 50:
        assert time.monotonic() < deadline, out.describe()
        out.send(frame_line(frame))
        frame += 1
        time.sleep(0.0005)
    with server._lock:
        data = bytes(server.received[1])
    assert data.startswith(b'{"frame": ')
    after = frames_of(data.split(b"\n")[:-1])
    assert after == sorted(after) and after[0] >= stuck
    s = out.stats
    assert s.reconnects == 1
    assert "lost the connection" in (s.last_error or "")


def test_tcp_connection_that_stalls_is_reset_and_reopened(
    controllers: list[Controller], outputs: list[Output]
) -> None:
    server = Controller(read=False)
    controllers.append(server)
    out = TcpOutput(
        "127.0.0.1", server.port, stall_timeout=0.2, backoff_initial=0.01, backoff_max=0.05
    )
    outputs.append(out)
    assert out.wait_connected(5.0)
    frame = 0
    deadline = time.monotonic() + 5.0
    while out.stats.reconnects == 0:
        assert time.monotonic() < deadline, out.describe()
        out.send(frame_line(frame))
        frame += 1
        time.sleep(0.0002)
    assert "took no data for 0.2 s" in (out.stats.last_error or "")
    assert wait_for(lambda: len(server.connections) == 2)


def test_tcp_without_a_controller_drops_quickly_and_keeps_trying(outputs: list[Output]) -> None:
    out = TcpOutput("127.0.0.1", free_port(), backoff_initial=0.01, backoff_max=0.04)
    outputs.append(out)
    n = 0
    slowest = 0.0
    deadline = time.monotonic() + 5.0
    while out.stats.connect_attempts < 4:
        assert time.monotonic() < deadline
        t = time.perf_counter()
        assert out.send(frame_line(n)) is False
        slowest = max(slowest, time.perf_counter() - t)
        n += 1
        time.sleep(0.001)
    assert slowest < 1.0  # never the connect timeout (2 s) nor a back-off
    s = out.stats
    assert not s.connected
    assert (s.sent, s.dropped, s.reconnects) == (0, n, 0)
    assert (s.dropped_write_failed, s.dropped_full_buffer) == (n, 0)  # never connected
    assert s.errors >= 3
    assert "refused" in (s.last_error or "").lower()
    assert "not connected" in out.describe()


def test_tcp_close_does_not_wait_for_the_back_off(outputs: list[Output]) -> None:
    out = TcpOutput("127.0.0.1", free_port(), backoff_initial=5.0, backoff_max=5.0)
    outputs.append(out)
    assert wait_for(lambda: out.stats.connect_attempts >= 1 and out.stats.errors >= 1)
    began = time.monotonic()
    out.close()
    assert time.monotonic() - began < 2.5  # not the 5 s back-off


def test_close_from_another_thread_while_sending(
    controllers: list[Controller], outputs: list[Output]
) -> None:
    server = Controller()
    controllers.append(server)
    out = TcpOutput("127.0.0.1", server.port)
    outputs.append(out)
    assert out.wait_connected(5.0)
    closer = threading.Timer(0.05, out.close)
    closer.start()
    n = 0
    deadline = time.monotonic() + 5.0
    while not out.closed:
        assert time.monotonic() < deadline
        out.send(frame_line(n))
        n += 1
    closer.join()
    assert not out.send(frame_line(n))
    s = out.stats
    assert s.sent + s.dropped == n + 1
    assert wait_for(lambda: len(server.lines(0)) == s.sent)
    frames = frames_of(server.lines(0))
    assert frames == sorted(frames)


@pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="needs setitimer")
@pytest.mark.parametrize("kind", ["tcp", "file"])
def test_close_from_a_signal_handler_that_interrupts_send(
    kind: str, controllers: list[Controller], outputs: list[Output], tmp_path: Path
) -> None:
    out: Output
    if kind == "tcp":
        server = Controller()
        controllers.append(server)
        tcp = TcpOutput("127.0.0.1", server.port)
        assert tcp.wait_connected(5.0)
        out = tcp
    else:
        out = FileOutput(tmp_path / "frames.jsonl")
    outputs.append(out)

    def handler(signum: int, frame: object) -> None:
        out.stats  # noqa: B018 (reading the stats in a handler must not deadlock either)
        out.close()

    previous = signal.signal(signal.SIGALRM, handler)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.03)
        n = 0
        deadline = time.monotonic() + 5.0
        while not out.closed:
            assert time.monotonic() < deadline
            out.send(frame_line(n))
            n += 1
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    s = out.stats
    assert s.sent + s.dropped == n and s.sent > 0
    if kind == "file":
        assert frames_of((tmp_path / "frames.jsonl").read_bytes().split(b"\n")[:-1]) == list(
            range(s.sent)
        )


# --- UDP ---


@pytest.fixture
def udp_receiver() -> Iterator[socket.socket]:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        s.bind(("127.0.0.1", 0))
        s.settimeout(2.0)
        yield s


def test_udp_sends_one_datagram_per_line(
    udp_receiver: socket.socket, outputs: list[Output]
) -> None:
    out = open_output(f"udp://127.0.0.1:{udp_receiver.getsockname()[1]}")
    outputs.append(out)
    assert isinstance(out, UdpOutput)
    for i in range(50):
        assert out.send(frame_line(i))
    got = [udp_receiver.recv(1 << 16) for _ in range(50)]
    assert all(d.endswith(b"\n") and d.count(b"\n") == 1 for d in got)
    assert [json.loads(d)["frame"] for d in got] == list(range(50))
    s = out.stats
    assert (s.sent, s.dropped, s.errors) == (50, 0, 0)
    assert s.bytes_sent == sum(map(len, got))


def test_udp_oversize_line_is_dropped_not_split(
    udp_receiver: socket.socket, outputs: list[Output]
) -> None:
    out = UdpOutput("127.0.0.1", udp_receiver.getsockname()[1])
    outputs.append(out)
    assert not out.send(json.dumps({"frame": 0, "pad": "x" * 70_000}))
    big = json.dumps({"frame": 1, "pad": "x" * 60_000})
    assert out.send(big)
    assert udp_receiver.recv(1 << 17) == big.encode() + b"\n"
    s = out.stats
    assert (s.sent, s.dropped, s.errors) == (1, 1, 0)
    assert "datagram limit" in (s.last_error or "")
    small = UdpOutput("127.0.0.1", udp_receiver.getsockname()[1], max_datagram=100)
    outputs.append(small)
    assert not small.send(frame_line(2))
    with pytest.raises(OutputError, match="65,507"):
        UdpOutput("127.0.0.1", 9, max_datagram=70_000)


def test_udp_to_a_closed_port_counts_errors_and_never_raises(outputs: list[Output]) -> None:
    out = UdpOutput("127.0.0.1", free_port())
    outputs.append(out)
    n = 0
    deadline = time.monotonic() + 3.0
    while out.stats.errors == 0:
        assert time.monotonic() < deadline, "no ICMP refusal seen on loopback"
        out.send(frame_line(n))
        n += 1
        time.sleep(0.005)
    s = out.stats
    assert s.sent + s.dropped == n
    assert "connection refused" in (s.last_error or "")


# --- files and stdout ---


def test_file_lines_are_whole_in_order_and_appended(tmp_path: Path) -> None:
    path = tmp_path / "positions.jsonl"
    with open_output(str(path)) as out:
        assert isinstance(out, FileOutput)
        for i in range(1000):
            assert out.send(frame_line(i))
        # Visible while the run goes on (tail -f), not only after close.
        assert path.read_bytes().count(b"\n") == 1000
    assert out.closed and out.stats.sent == 1000
    with open_output(path) as again:  # a second run appends
        again.send(frame_line(1000) + "\n")  # a trailing newline is not doubled
    assert frames_of(path.read_bytes().split(b"\n")[:-1]) == list(range(1001))
    assert path.read_bytes().endswith(b"}\n")


def test_file_whose_last_line_was_cut_gets_a_newline_before_appending(tmp_path: Path) -> None:
    path = tmp_path / "positions.jsonl"
    path.write_bytes(frame_line(0).encode() + b"\n" + b'{"frame": 1, "t"')
    with FileOutput(path) as out:
        out.send(frame_line(2))
    lines = path.read_bytes().split(b"\n")
    assert json.loads(lines[0])["frame"] == 0 and lines[1] == b'{"frame": 1, "t"'
    assert json.loads(lines[2])["frame"] == 2 and lines[3] == b""


def test_file_that_cannot_be_opened_raises_oserror_naming_it(tmp_path: Path) -> None:
    missing = tmp_path / "no such folder" / "positions.jsonl"
    with pytest.raises(FileNotFoundError, match="no such folder"):
        open_output(str(missing))
    with pytest.raises(OSError, match=str(tmp_path.name)) as info:
        open_output(str(tmp_path))  # a directory
    assert not isinstance(info.value, ValueError)
    if os.geteuid() != 0:  # root may write anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        with pytest.raises(PermissionError, match="locked"):
            open_output(str(locked / "positions.jsonl"))


_SIZE_LIMITED = textwrap.dedent(
    """
    import json, resource, sys
    from planarcal.live.outputs import FileOutput
    # Python ignores SIGXFSZ: a write past the limit is cut short, the next one fails (EFBIG).
    resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))
    out = FileOutput(sys.argv[1])
    results = [out.send(json.dumps({"frame": i, "pad": "y" * 70})) for i in range(20)]
    out.close()
    s = out.stats
    print(json.dumps([results, s.sent, s.dropped, s.errors, s.broken, s.last_error]))
    """
)


@pytest.mark.skipif(sys.platform == "win32", reason="needs RLIMIT_FSIZE")
def test_file_write_cut_short_leaves_only_whole_lines(tmp_path: Path) -> None:
    path = tmp_path / "positions.jsonl"
    run = subprocess.run(
        [sys.executable, "-c", _SIZE_LIMITED, str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert run.returncode == 0, run.stderr
    results, sent, dropped, errors, broken, last_error = json.loads(run.stdout)
    data = path.read_bytes()
    assert data.endswith(b"\n")
    assert frames_of(data.split(b"\n")[:-1]) == list(range(sent))
    assert results == [True] * sent + [False] * dropped and sent + dropped == 20
    assert 0 < sent < 20 and errors == dropped and not broken
    assert "cannot write" in last_error


def test_pipe_whose_reader_has_gone_is_broken_and_drops(outputs: list[Output]) -> None:
    read_end, write_end = os.pipe()
    os.close(read_end)
    out = StreamOutput(write_end, "pipe", close_fd=True)
    outputs.append(out)
    assert not out.send(frame_line(0))
    assert out.broken
    for i in range(1, 10):
        assert not out.send(frame_line(i))
    s = out.stats
    assert (s.sent, s.dropped, s.errors, s.broken, s.connected) == (0, 10, 1, True, False)
    assert "reader of pipe has gone" in (s.last_error or "")
    assert "broken" in out.describe()


_STDOUT_WRITER = textwrap.dedent(
    """
    import json, sys
    from planarcal.live.outputs import open_output
    out = open_output("-")
    results = [out.send(json.dumps({"frame": i})) for i in range(100_000)]
    out.close()
    s = out.stats
    summary = [s.sent, s.dropped, s.errors, s.broken, results.count(False)]
    print(json.dumps(summary), file=sys.stderr)
    """
)


def test_stdout_whose_reader_exits_counts_drops_instead_of_crashing() -> None:
    # planarcal run -o - | head -1: the reader takes one line and exits.
    child = subprocess.Popen(
        [sys.executable, "-c", _STDOUT_WRITER], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    assert child.stdout is not None and child.stderr is not None
    first = child.stdout.readline()
    child.stdout.close()
    err = child.stderr.read().decode()
    assert child.wait(timeout=60) == 0, err
    assert json.loads(first) == {"frame": 0}
    assert "Traceback" not in err and "Exception ignored" not in err, err
    # The loss is reported as it happens (Python's last-resort handler: stderr): the first
    # line lost at once, the rest at close (10 s apart at most), not a warning per line.
    *warnings, summary = err.splitlines()
    sent, dropped, errors, broken, refused = json.loads(summary)
    assert broken and errors == 1
    assert sent + dropped == 100_000 and refused == dropped > 0
    assert warnings[0].startswith("stdout: 1 line lost: the reader of stdout has gone")
    assert 2 <= len(warnings) < 10 and f"({dropped:,} in all: {dropped:,} not written" in err


# --- specs and lines ---


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("", "empty output"),
        ("tcp://", "no host and port"),
        ("tcp://192.168.0.10", "no port"),
        ("tcp://192.168.0.10:", "no port"),
        ("tcp://:5000", "no host"),
        ("tcp://host:0", "port 0 is out of range 1-65535"),
        ("tcp://host:70000", "port 70000 is out of range 1-65535"),
        ("udp://host:http", "'http' is not a number"),
        ("tcp://::1:5000", "in brackets"),
        ("tcp://[::1:5000", "unclosed"),
        ("tcp://host:5000/robot", "only a host and a port"),
        ("ftp://host/file", "unknown scheme 'ftp'"),
        ("TCP:host:5000", "write tcp://HOST:PORT"),
    ],
)
def test_bad_specs_raise_output_error_naming_the_problem(spec: str, message: str) -> None:
    with pytest.raises(OutputError, match=message) as info:
        open_output(spec)
    assert isinstance(info.value, ValueError)
    if spec:
        assert repr(spec) in str(info.value)


def test_good_specs(tmp_path: Path, outputs: list[Output]) -> None:
    stdout = open_output("-")
    outputs.append(stdout)
    assert isinstance(stdout, StreamOutput) and stdout.spec == "stdout"
    port = free_port()
    tcp = open_output(f"TCP://127.0.0.1:{port}/")
    outputs.append(tcp)
    assert isinstance(tcp, TcpOutput) and tcp.spec == f"tcp://127.0.0.1:{port}"
    udp = open_output(f"udp://[::1]:{port}") if socket.has_ipv6 else None
    if udp is not None:
        outputs.append(udp)
        assert udp.spec == f"udp://[::1]:{port}"
    path = tmp_path / "tcp:odd name"
    named = open_output(str(path))  # a file path that merely contains "tcp:"
    outputs.append(named)
    assert isinstance(named, FileOutput)


def test_lines_with_a_line_break_inside_are_refused(tmp_path: Path) -> None:
    with FileOutput(tmp_path / "x.jsonl") as out:
        with pytest.raises(OutputError, match="line break"):
            out.send(json.dumps({"frame": 0}, indent=1))
        assert out.send('{"frame": 1}\n')
    assert (tmp_path / "x.jsonl").read_bytes() == b'{"frame": 1}\n'


def test_bad_tcp_parameters_raise_output_error() -> None:
    with pytest.raises(OutputError, match="max_pending_lines"):
        TcpOutput("127.0.0.1", 9, max_pending_lines=0)
    with pytest.raises(OutputError, match="backoff_max"):
        TcpOutput("127.0.0.1", 9, backoff_initial=1.0, backoff_max=0.5)
    with pytest.raises(OutputError, match="out of range"):
        TcpOutput("127.0.0.1", 65536)
