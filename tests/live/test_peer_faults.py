"""Peers that misbehave against the production loop's TCP outputs, with the loop timed.

`planarcal run` runs in-process (planarcal.cli.main on a real video file, read through
test_server's PacedCamera at a fixed rate, as a live camera delivers) with ``-o
tcp-listen://`` (planarcal the server) and ``-o tcp://`` (planarcal connects out). Real
sockets on loopback then misbehave: peers that never read while many MB of lines come (each
line about 8 KB), peers that close at once, peers that reset (RST) half-way through a line,
controllers that send TRIGGER and reset, and one that floods requests and never reads.

test_server.py has these faults one at a time, with small lines and small buffers. This file
adds what it does not measure: every call the loop makes to its output is timed (none may
wait on a peer), the loop must keep the source's rate (the frames a live source drops
because the loop was late are counted), every line is accounted for (sent or counted as
dropped, per peer, exactly), and the peers that behave get every line, whole.
"""

from __future__ import annotations

import json
import socket
import statistics
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import test_server as served
from test_server import (
    WAIT_S,
    Client,
    PacedCamera,
    Reader,
    Run,
    check_positions,
    parse_csv,
    wait_for,
)

from planarcal.live.output_server import ServerOutput
from planarcal.live.output_socket import close_socket
from planarcal.live.output_tcp import TcpOutput

# test_server's fixtures, here too: the rendered scene (its calibration file, a 20-frame
# video of two discs, each frame's truth) and PacedCamera in the Tracker's place of Camera.
scene = served.scene
camera = served.camera

FPS = 250.0
"""The paced camera's rate. The loop alone runs at over 2,000 frames a second on these
160 x 120 frames, so at this rate it is idle most of the time unless a peer holds it up."""

TEMPLATE = "{id},{x:.4f},{y:.4f}," + "z" * 4000
"""A template that makes a line of about 8 KB from two parts: 2 MB a second at FPS, so the
buffers of a peer that never reads are full within a second and MB are dropped after."""
WIDTH = 4
"""Fields per part on a TEMPLATE line."""

MAX_CALL_S = 0.5
"""The longest any call from the loop to its output may take. A call that waited for a peer
would take until the stall timeout (5 s) or for ever; a busy shared machine may preempt a
call for a few tens of milliseconds."""
MEDIAN_CALL_S = 0.002
"""The median call: a line appended to in-memory queues takes microseconds."""
LATE_SHARE = 0.05
"""Of the frames read, the most the loop may have been too late for (a live source drops
them): a stall of a second would drop 250."""


class OutputCalls:
    """Times every call the loop makes to `method` of the output class `cls` (patched for the
    test; only the loop's thread calls it)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, cls: type, method: str) -> None:
        self.durations: list[float] = []
        original = getattr(cls, method)

        def timed(output: Any, *args: Any, **kwargs: Any) -> Any:
            began = time.perf_counter()
            try:
                return original(output, *args, **kwargs)
            finally:
                self.durations.append(time.perf_counter() - began)

        monkeypatch.setattr(cls, method, timed)

    def check_none_waited(self) -> None:
        assert self.durations, "the loop never called its output"
        slowest = max(self.durations)
        median = statistics.median(self.durations)
        assert slowest < MAX_CALL_S, f"a call took {slowest * 1e3:.1f} ms: the loop waited"
        assert median < MEDIAN_CALL_S, f"the median call took {median * 1e3:.2f} ms"


def peer(client: Client) -> str:
    """How the server names `client` in its stats."""
    return f"127.0.0.1:{client.port}"


def loop_figures(err: str) -> dict[str, Any]:
    """The run's summary (the JSON object on stderr's last line)."""
    figures: dict[str, Any] = json.loads(err.rsplit("planarcal run: ", 1)[1])
    return figures


def check_kept_its_rate(figures: dict[str, Any], calls: OutputCalls) -> None:
    """Every frame processed made one call to the output, and the loop was late for few of
    the frames the source delivered."""
    assert figures["frames"] == len(calls.durations)
    assert figures["frames_undecodable"] == 0 and figures["failed"] == 0
    late = figures["frames_dropped"]
    assert late <= LATE_SHARE * figures["read"], f"the loop was late for {late} frames"
    calls.check_none_waited()


def check_lines(lines: list[str]) -> list[int]:
    """Every line a whole TEMPLATE line of two parts; returns their frame numbers."""
    frames = parse_csv(lines, WIDTH)
    assert all(line.endswith("z" * 4000) for line in lines)
    return [k for k, _ in frames]


def run_args(video: Path, calib: Path, output: str, *extra: Any) -> list[Any]:
    return [
        "--source",
        video,
        "--calibration",
        calib,
        "--min-area",
        50,
        "-o",
        output,
        "--template",
        TEMPLATE,
        *extra,
    ]


def test_stream_peers_that_never_read_close_or_reset_never_slow_the_loop(
    scene: tuple[Path, Path, np.ndarray],
    camera: type[PacedCamera],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    calib, video, truth = scene
    camera.fps = FPS
    camera.frozen.set()  # no frame until the peers are there: each then gets every line
    calls = OutputCalls(monkeypatch, ServerOutput, "send")
    run = Run(monkeypatch, *run_args(video, calib, "tcp-listen://127.0.0.1:0"))
    server = run.server
    reader = Reader(server.port)
    stuck = Client(server.port)  # never reads: its default buffers fill, then MB are dropped
    resetter = Client(server.port, receive_buffer=4096)  # never reads, then resets mid-line
    assert wait_for(lambda: server.stats.clients == 3)
    camera.frozen.clear()

    # Its lines are dropped once its connection is full and a batch is stuck in flight.
    assert wait_for(lambda: resetter.stats(server).dropped > 0)
    head = resetter.sock.recv(1000)
    assert head and b"\n" not in head  # the first part of its first line, no more
    close_socket(resetter.sock, abort=True)  # RST, half-way through a line
    for _ in range(5):
        Client(server.port).close()  # connects and hangs up at once
    assert wait_for(lambda: server.stats.accepted == 8 and server.stats.clients == 2)
    assert wait_for(lambda: server.stats.lines >= 600)  # 600 lines of 8 KB to each peer
    assert run.finish(camera) == 0

    lines = reader.all_lines()
    frames = check_lines(lines)
    check_positions(parse_csv(lines, WIDTH), truth)
    stats = server.stats
    # The reader got every line the loop sent, whole and in order.
    assert len(lines) == stats.lines == len(calls.durations)
    assert frames == sorted(set(frames))
    mine = reader.client.stats(server)
    assert (mine.sent, mine.dropped) == (len(lines), 0)
    # The peer that never read: a few of the MB sent reached it, the rest are counted. It is
    # there to the end, or (when a loaded machine slows the run past its 5 s stall limit)
    # reset, and then the lines after it left were never meant for it.
    theirs = stuck.stats(server)
    assert stats.lines * len(lines[0]) > 4e6 and theirs.sent * len(lines[0]) < 2e6
    assert not theirs.connected
    if theirs.closed_by == "the server closed":
        assert theirs.sent + theirs.dropped == stats.lines
    else:
        assert "took no data for 5 s" in (theirs.closed_by or ""), theirs
        assert theirs.sent + theirs.dropped < stats.lines
    assert theirs.dropped_full_buffer > 0  # pushed out behind a reader that never read
    assert "closing: lines still in flight" in (stats.last_error or "") or (
        "took no data for 5 s" in (theirs.closed_by or "")
    )
    reset = resetter.stats(server)
    assert not reset.connected and (reset.closed_by or "").startswith("lost 127.0.0.1")
    assert reset.dropped > 0 and reset.sent + reset.dropped <= stats.lines
    gone = [c for c in stats.per_client if c.peer not in (peer(reader.client), peer(stuck))]
    assert len(gone) == 6 and all(not c.connected and c.closed_by for c in gone)
    assert stats.dropped == sum(c.dropped for c in stats.per_client)
    assert stats.sent == sum(c.sent for c in stats.per_client)
    check_kept_its_rate(loop_figures(capsys.readouterr().err), calls)
    stuck.close()


def flood(sock: socket.socket, data: bytes, outcome: list[BaseException]) -> None:
    """Sends `data` (blocking) until it is sent or the connection fails; keeps the error."""
    try:
        sock.sendall(data)
    except OSError as e:
        outcome.append(e)


DEAF_REQUESTS = 400
"""Requests of the trigger client that never reads: 3 MB of answers."""


def ask_deafly(client: Client, times: int) -> None:
    """Sends TRIGGER every 2 ms and never reads an answer."""
    for _ in range(times):
        client.send("TRIGGER\n")
        time.sleep(0.002)


def test_trigger_peers_that_never_read_reset_or_flood_never_slow_the_loop(
    scene: tuple[Path, Path, np.ndarray],
    camera: type[PacedCamera],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    calib, video, truth = scene
    camera.fps = FPS
    calls = OutputCalls(monkeypatch, ServerOutput, "answer")
    run = Run(monkeypatch, *run_args(video, calib, "tcp-listen://127.0.0.1:0", "--trigger"))
    server = run.server
    robot = Client(server.port)
    answers: list[str] = []

    def ask(times: int) -> None:
        for _ in range(times):
            asked = robot.send("TRIGGER\n")
            answer = robot.line()
            assert float(answer.split(",")[1]) >= asked - 1e-6  # a frame read after it
            answers.append(answer)

    # One that asks every 2 ms and never reads: its answers (MB) fill its buffers, then drop.
    deaf = Client(server.port)
    asking = threading.Thread(target=ask_deafly, args=(deaf, DEAF_REQUESTS), daemon=True)
    asking.start()
    ask(5)
    # Controllers that send TRIGGER and reset before their answer can come.
    quitters = [Client(server.port) for _ in range(3)]
    for quitter in quitters:
        quitter.send("TRIGGER\n")
        close_socket(quitter.sock, abort=True)
    ask(5)
    # One that resets half-way through its answer.
    halfway = Client(server.port)
    halfway.send("TRIGGER\n")
    head = halfway.sock.recv(1000)
    assert head and b"\n" not in head
    close_socket(halfway.sock, abort=True)
    # One that never reads and sends 8 MB of requests: let go, and nobody waits for it.
    flooder = Client(server.port)
    failed: list[BaseException] = []
    sender = threading.Thread(
        target=flood, args=(flooder.sock, b"TRIGGER\n" * (1 << 20), failed), daemon=True
    )
    sender.start()
    ask(20)
    sender.join(WAIT_S)
    assert not sender.is_alive() and failed, "the flooder was not let go"
    asking.join(WAIT_S)
    assert not asking.is_alive()
    assert wait_for(lambda: deaf.stats(server).requests == DEAF_REQUESTS)
    assert wait_for(lambda: server.stats.clients == 2 and server.stats.accepted == 7)
    assert run.finish(camera) == 0

    check_lines(answers)
    check_positions(parse_csv(answers, WIDTH), truth)
    stats = server.stats
    me = robot.stats(server)
    assert (me.requests, me.answers, me.sent, me.error_lines, me.dropped) == (30, 30, 30, 0, 0)
    by_peer = {c.peer: c for c in stats.per_client}
    for quitter in [*quitters, halfway]:
        gone = by_peer[peer(quitter)]
        assert gone.requests == 1 and not gone.connected and gone.closed_by
    assert by_peer[peer(halfway)].sent == 1  # its answer went out whole; it left mid-line
    flooded = by_peer[peer(flooder)]
    assert "sent more than 64 requests ahead of their answers" in (flooded.closed_by or "")
    # Every request of the deaf one got one reply line, written whole or counted as dropped.
    theirs = by_peer[peer(deaf)]
    assert theirs.answers + theirs.error_lines == DEAF_REQUESTS
    assert theirs.sent + theirs.dropped == DEAF_REQUESTS and theirs.dropped > 0
    assert stats.requests == sum(c.requests for c in stats.per_client)
    assert stats.answers == sum(c.answers for c in stats.per_client)
    check_kept_its_rate(loop_figures(capsys.readouterr().err), calls)
    for client in (robot, deaf, flooder):
        client.close()


def read_all(conn: socket.socket, into: bytearray) -> None:
    """Reads until the peer closes (or the connection fails)."""
    try:
        while chunk := conn.recv(1 << 16):
            into.extend(chunk)
    except OSError:
        pass


def test_controller_that_closes_never_reads_or_resets_never_slows_the_loop(
    scene: tuple[Path, Path, np.ndarray],
    camera: type[PacedCamera],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    calib, video, truth = scene
    camera.fps = FPS
    calls = OutputCalls(monkeypatch, TcpOutput, "send")
    with socket.create_server(("127.0.0.1", 0)) as controller:
        controller.settimeout(WAIT_S)
        port = controller.getsockname()[1]
        run = Run(monkeypatch, *run_args(video, calib, f"tcp://127.0.0.1:{port}"))
        assert wait_for(lambda: bool(run.outputs)), "the run opened no output"
        output = run.outputs[0]
        assert isinstance(output, TcpOutput)

        first, _ = controller.accept()
        first.close()  # hangs up at once

        # Never reads (its buffers fill, then lines drop), and talks back: 8 MB that the
        # writer must read and discard without falling behind.
        second, _ = controller.accept()
        second.settimeout(WAIT_S)
        failed: list[BaseException] = []
        talking = threading.Thread(
            target=flood, args=(second, b"STATUS OK\n" * 800_000, failed), daemon=True
        )
        talking.start()
        dropped = output.stats.dropped
        assert wait_for(lambda: output.stats.dropped >= dropped + 250), output.describe()
        head = second.recv(1000)
        assert head and b"\n" not in head  # the connection began on a line's first byte
        talking.join(WAIT_S)
        assert not talking.is_alive() and not failed, "the writer did not read what came"
        close_socket(second, abort=True)  # RST, half-way through a line

        third, _ = controller.accept()  # reads everything
        received = bytearray()
        reading = threading.Thread(target=read_all, args=(third, received), daemon=True)
        reading.start()
        assert wait_for(lambda: received.count(b"\n") >= 100)
        assert run.finish(camera) == 0
        reading.join(WAIT_S)
        assert not reading.is_alive()
        third.close()

    # The third connection began on a line boundary, with lines sent after it was made, and
    # ended gracefully after a whole line.
    assert received.endswith(b"\n")
    lines = received.decode().splitlines()
    frames = check_lines(lines)
    check_positions(parse_csv(lines, WIDTH), truth)
    assert frames == sorted(set(frames))
    stats = output.stats
    assert stats.reconnects == 2 and stats.pending == 0 and stats.errors >= 2
    assert "lost the connection" in (stats.last_error or "")
    # Every line the loop sent was written whole to a connection or counted as dropped.
    assert stats.sent + stats.dropped == len(calls.durations)
    assert stats.dropped >= 250 and stats.sent >= len(lines)
    check_kept_its_rate(loop_figures(capsys.readouterr().err), calls)
