"""Who gets in to planarcal's server, and who is let go: the cap on clients (``max_clients``,
``--max-clients``), idle trigger clients closed (``idle_timeout``, ``--client-idle-timeout``),
an idle client evicted for a new one at the cap, a refusal line when every client is busy,
and an over-long request line answered exactly once. Real sockets on loopback against a
ServerOutput, and against the real command (``python -m planarcal run`` in a subprocess on a
rendered video), whose stderr must report refusals and idle closes while they happen. Every
wait has a deadline: a bug fails, it does not hang."""

from __future__ import annotations

import contextlib
import json
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
import test_server as served
from test_server import WAIT_S, Client, wait_for

from planarcal.live import output_server
from planarcal.live.capture import Camera
from planarcal.live.output_server import ServerOutput

scene = served.scene  # calib.json, a 20-frame video of two discs, each frame's truth


@contextlib.contextmanager
def trigger_server(**options: object) -> Iterator[ServerOutput]:
    server = ServerOutput("127.0.0.1", 0, trigger_word="GO", **options)  # type: ignore[arg-type]
    with contextlib.closing(server):
        yield server


def test_an_overlong_request_line_gets_exactly_one_error_and_is_skipped_to_its_newline() -> None:
    with trigger_server() as server:
        robot = Client(server.port)
        robot.send("G" * (1 << 20))  # 1 MB, in many reads, and no newline yet
        assert robot.line().startswith("ERROR,a request line longer than 1024 bytes")
        robot.send("O" * 5000 + "\nGO\n")  # the rest of it, then a request
        assert wait_for(lambda: server.stats.requests == 1)
        assert server.answer(time.time(), lambda: "frame 1") == 1
        assert robot.line() == "frame 1"  # no second error line came before the answer
        assert server.stats.error_lines == 1
        robot.send("X" * 3000 + "\nGO\n")  # an overlong line and a request in one send
        assert robot.line().startswith("ERROR,a request line longer than 1024 bytes")
        assert wait_for(lambda: server.stats.requests == 2)
        assert server.answer(time.time(), lambda: "frame 2") == 1
        assert robot.line() == "frame 2"
        assert server.stats.error_lines == 2
        robot.close()


def test_an_idle_trigger_client_is_told_why_and_closed_and_a_busy_one_is_not() -> None:
    with trigger_server(idle_timeout=0.5) as server:
        idle = Client(server.port)
        busy = Client(server.port)
        busy.send("GO\n")  # waits for a frame: never idle while it does
        line = idle.line()
        assert re.fullmatch(
            r"ERROR,127\.0\.0\.1:\d+ was closed after \d+ s without a request.*", line
        )
        assert idle.read_to_end() == []
        stats = server.stats
        assert (stats.idle_closed, stats.clients) == (1, 1)
        assert server.answer(time.time(), lambda: "frame 1") == 1
        assert busy.line() == "frame 1"
        (gone,) = [c for c in stats.per_client if not c.connected]
        assert gone.closed_by == "idle" and gone.error_lines == gone.sent == 1
        for client in (idle, busy):
            client.close()


def test_at_the_cap_an_idle_client_makes_room_and_busy_ones_do_not(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setattr(output_server, "EVICT_IDLE_S", 0.3)
    with trigger_server(max_clients=2, idle_timeout=None) as server, caplog.at_level("WARNING"):
        old = Client(server.port)
        busy = Client(server.port)
        busy.send("GO\n")
        assert wait_for(lambda: server.stats.requests == 1)
        # Within the threshold nobody is idle enough: the newcomer is refused.
        early = Client(server.port)
        assert early.line().startswith("ERROR,2 controllers are connected already")
        assert early.read_to_end() == []
        time.sleep(0.4)  # the old one is now idle beyond the threshold; the busy one waits
        new = Client(server.port)
        line = old.line()
        assert re.fullmatch(
            rf"ERROR,127\.0\.0\.1:{old.port} was closed after \d+ s without a request; to "
            rf"make room for 127\.0\.0\.1:{new.port} \(2 controllers at most\)",
            line,
        ), line
        assert old.read_to_end() == []
        new.send("GO\n")
        assert wait_for(lambda: server.stats.requests == 2)
        assert server.answer(time.time(), lambda: "frame 1") == 2
        assert busy.line() == "frame 1" and new.line() == "frame 1"
        stats = server.stats
        assert (stats.refused, stats.evicted, stats.clients, stats.accepted) == (1, 1, 2, 3)
        for client in (old, busy, early, new):
            client.close()
    warnings = [r.getMessage() for r in caplog.records if r.name == "planarcal.live.outputs"]
    assert any("1 connection refused: refused 127.0.0.1" in w for w in warnings), warnings
    assert any("1 idle client evicted" in w for w in warnings), warnings


def test_in_stream_mode_a_client_beyond_the_cap_is_refused_not_an_evictor() -> None:
    with contextlib.closing(ServerOutput("127.0.0.1", 0, max_clients=1)) as server:
        reader = Client(server.port)
        assert wait_for(lambda: server.stats.clients == 1)
        time.sleep(0.1)
        other = Client(server.port)
        assert other.line().startswith("ERROR,1 controllers are connected already")
        assert server.send("a line") and reader.line() == "a line"
        assert (server.stats.refused, server.stats.evicted) == (1, 0)
        reader.close()
        other.close()


@pytest.fixture(scope="module")
def long_video(
    scene: tuple[Path, Path, np.ndarray], tmp_path_factory: pytest.TempPathFactory
) -> Path:
    """The scene's clip 450 times over (9,000 frames): a run that lasts seconds even at
    the loop's top speed (2,000 frames a second), long enough to talk to."""
    clip = Camera(scene[1], color=False)
    frames = [clip.read() for _ in range(served.CLIP)]
    clip.close()
    path = tmp_path_factory.mktemp("admission") / "long.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 30.0, (160, 120), False)
    for k in range(450 * served.CLIP):
        writer.write(frames[k % served.CLIP])
    writer.release()
    return path


def test_the_command_takes_max_clients_and_closes_idle_clients_saying_so(
    scene: tuple[Path, Path, np.ndarray], long_video: Path
) -> None:
    calib, _, _ = scene
    argv = [
        sys.executable,
        "-m",
        "planarcal",
        "run",
        "--source",
        str(long_video),
        "--calibration",
        str(calib),
        "--min-area",
        "50",
        "-o",
        "tcp-listen://127.0.0.1:0",
        "--trigger",
        "--format",
        "csv",
        "--max-clients",
        "1",
        "--client-idle-timeout",
        "1",
    ]
    proc = subprocess.Popen(argv, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        said = proc.stderr.readline()
        match = re.fullmatch(r"planarcal run: listening on 127\.0\.0\.1:(\d+); .*\n", said)
        assert match, said
        port = int(match.group(1))
        first = Client(port)
        first.send("TRIGGER\n")
        assert first.line().split(",")[3] == "2"  # a frame with the two discs
        # At the cap, and the first client was active a moment ago: refused, told why.
        second = Client(port)
        assert second.line().startswith("ERROR,1 controllers are connected already")
        assert second.read_to_end() == []
        # Idle for 1 s: the first is told why and closed, and its place is free.
        assert re.fullmatch(
            r"ERROR,127\.0\.0\.1:\d+ was closed after 1 s without a .*", first.line()
        )
        assert first.read_to_end() == []
        third = Client(port)
        third.send("TRIGGER\n")
        assert third.line().split(",")[3] == "2"
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=WAIT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert re.search(
        r"planarcal run: tcp-listen://127\.0\.0\.1:\d+: 1 connection refused: ", err
    ), err
    assert re.search(r"tcp-listen://127\.0\.0\.1:\d+: 1 idle client closed: ", err), err
    figures = json.loads(err.rsplit("planarcal run: ", 1)[1])
    output = figures["output"]
    assert (output["refused"], output["idle_closed"], output["accepted"]) == (1, 1, 2)
    for client in (first, second, third):
        client.close()
