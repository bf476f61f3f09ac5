"""`planarcal run -o tcp-listen://...`: loopback controllers (real sockets on 127.0.0.1, port
0) against a real run (planarcal.cli.main in-process, on a real video file of a rendered
scene, read through a real Camera that the test paces like a live camera, unplugs and
freezes: fault injection around the real capture path). Whole lines in each format, two
clients at once, one that never reads, one that closes at once, one that resets mid-line,
trigger and reply, errors during a camera fault and for unknown requests, and specs and
options refused at start-up. Every wait has a deadline: a bug fails, it does not hang."""

from __future__ import annotations

import contextlib
import json
import re
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

import planarcal.live.run as run_module
import planarcal.live.tracker as tracker_module
from planarcal import cli, synth
from planarcal.calib.calibration import Calibration
from planarcal.errors import CameraError, OutputError
from planarcal.live.capture import Camera
from planarcal.live.output_server import ServerOutput
from planarcal.live.outputs import open_output

CLIP = 20  # frames in the video; the paced camera plays it in a loop
WAIT_S = 20.0  # the longest any step may take before the test fails


def wait_for(condition: Callable[[], bool], timeout: float = WAIT_S) -> bool:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, np.ndarray]:
    """A small camera (160 x 120) over the table: its calibration file, a video of two
    discs moving, and each frame's truth (frames x 2 x 2, mm)."""
    cam = synth.CameraModel(width=160, height=120, focal_px=150.0)
    pose = synth.PlanePose(500.0, look_at_mm=(130.0, 90.0))
    world = synth.PAPER_BOARD.world_points()
    cal = Calibration(world, cam.project(world, pose), image_size=(160, 120), lens="none")
    folder = tmp_path_factory.mktemp("server")
    writer = cv2.VideoWriter(
        str(folder / "discs.avi"), cv2.VideoWriter.fourcc(*"MJPG"), 30.0, (160, 120), False
    )
    writer.set(cv2.VIDEOWRITER_PROP_QUALITY, 100)
    truth = []
    for k in range(CLIP):
        objs = [
            synth.SceneObject("disc", (60.0 + 3 * k, 60.0), size_mm=40.0),
            synth.SceneObject("disc", (200.0, 40.0 + 3 * k), size_mm=40.0),
        ]
        rendered = synth.render_scene(cam, pose, board=None, objects=objs, seed=k)
        writer.write(rendered.image)
        truth.append(rendered.object_centroids_mm)
    writer.release()
    return cal.save(folder / "calib.json"), folder / "discs.avi", np.array(truth)


class PacedCamera:
    """A live camera made of a real video file: a real Camera on the file, played in a loop
    at most `fps` frames a second. The test can unplug it (its reads fail and it closes;
    reopening fails while unplugged), freeze it (reads wait) and end it."""

    fps = 50.0
    unplugged = threading.Event()
    frozen = threading.Event()
    stuck = threading.Event()
    """Set while a read waits because the camera is frozen."""
    end = threading.Event()
    attempts = 0

    def __init__(self, source: Any, *, timeout_s: float = 5.0, color: bool = True) -> None:
        type(self).attempts += 1
        if self.unplugged.is_set():
            raise CameraError(f"{source}: no such device (injected)")
        self._args = (source, timeout_s, color)
        self.inner = self._open()
        self.resolution = self.inner.resolution
        self.source = self.label = source
        self.live = True
        self.ended = self.closed = False
        self._next = time.monotonic()

    def _open(self) -> Camera:
        source, timeout_s, color = self._args
        return Camera(source, timeout_s=timeout_s, color=color)

    def read(self) -> Any:
        if self.end.is_set():
            self.ended = True
            raise CameraError("the test ended the run (injected)")
        if self.unplugged.is_set():
            self.close()
            raise CameraError("camera stopped delivering (injected)")
        deadline = time.monotonic() + WAIT_S
        while self.frozen.is_set() and time.monotonic() < deadline and not self.end.is_set():
            self.stuck.set()
            time.sleep(0.005)
        self.stuck.clear()
        if self.end.is_set():
            self.ended = True
            raise CameraError("the test ended the run (injected)")
        self._next = max(self._next + 1.0 / self.fps, time.monotonic())
        time.sleep(max(0.0, self._next - time.monotonic()))
        try:
            return self.inner.read()
        except CameraError:
            if not self.inner.ended:
                raise
            self.inner.close()
            self.inner = self._open()  # the clip again
            return self.inner.read()

    def close(self) -> None:
        self.closed = True
        self.inner.close()


@pytest.fixture
def camera(monkeypatch: pytest.MonkeyPatch) -> Iterator[type[PacedCamera]]:
    """A fresh PacedCamera class (its own events), put in the Tracker's place of Camera."""
    cls: type[PacedCamera] = type(
        "Paced",
        (PacedCamera,),
        {name: threading.Event() for name in ("unplugged", "frozen", "stuck", "end")},
    )
    monkeypatch.setattr(tracker_module, "Camera", cls)
    yield cls
    cls.end.set()  # whatever happened, the run ends


class Run:
    """`planarcal run` in-process on its own thread; the server it opens is caught on the
    way (for its port and its live counters)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, *args: Any) -> None:
        self.outputs: list[Any] = []
        real = open_output

        def spy(spec: str, **options: Any) -> Any:
            out = real(spec, **options)
            self.outputs.append(out)
            return out

        monkeypatch.setattr(run_module, "open_output", spy)
        self.code: int | None = None
        self.error: BaseException | None = None
        self.thread = threading.Thread(
            target=self._main, args=(["run", *map(str, args)],), daemon=True
        )
        self.thread.start()

    def _main(self, argv: list[str]) -> None:
        try:
            self.code = cli.main(argv)
        except BaseException as e:  # shown by finish()
            self.error = e

    @property
    def server(self) -> ServerOutput:
        assert wait_for(lambda: bool(self.outputs) or not self.thread.is_alive()), "no server"
        assert self.outputs, f"the run ended before opening its output: {self.error!r}"
        server = self.outputs[0]
        assert isinstance(server, ServerOutput)
        return server

    def finish(self, camera: type[PacedCamera]) -> int:
        camera.end.set()
        self.thread.join(WAIT_S)
        assert not self.thread.is_alive(), "the run did not end"
        assert self.error is None, repr(self.error)
        assert self.code is not None
        return self.code


class Client:
    """A controller with a plain socket on loopback, reading lines."""

    def __init__(self, port: int, *, receive_buffer: int | None = None) -> None:
        self.sock = socket.socket()
        if receive_buffer is not None:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
        self.sock.settimeout(WAIT_S)
        self.sock.connect(("127.0.0.1", port))
        self.port: int = self.sock.getsockname()[1]
        self.buffer = b""
        self.lines: list[str] = []

    def line(self) -> str:
        """The next line (without its newline); fails after WAIT_S."""
        while b"\n" not in self.buffer:
            chunk = self.sock.recv(65536)
            assert chunk, "the server closed the connection"
            self.buffer += chunk
        line, _, self.buffer = self.buffer.partition(b"\n")
        return line.decode()

    def send(self, text: str) -> float:
        """Sends `text`; returns the time just before."""
        t = time.time()
        self.sock.sendall(text.encode())
        return t

    def read_to_end(self) -> list[str]:
        """Every line until the server closes; the stream must end on a line boundary."""
        while chunk := self.sock.recv(65536):
            self.buffer += chunk
        assert self.buffer.endswith(b"\n") or not self.buffer, self.buffer[-80:]
        lines = self.buffer.decode().splitlines()
        self.buffer = b""
        return lines

    def stats(self, server: ServerOutput) -> Any:
        peer = f"127.0.0.1:{self.port}"
        return next(c for c in server.stats.per_client if c.peer == peer)

    def close(self) -> None:
        self.sock.close()


class Reader(threading.Thread):
    """A client that reads every line on its own thread until the server closes."""

    def __init__(self, port: int) -> None:
        super().__init__(daemon=True)
        self.client = Client(port)
        self.lines: list[str] = []
        self.start()

    def run(self) -> None:
        self.lines = self.client.read_to_end()

    def all_lines(self) -> list[str]:
        self.join(WAIT_S)
        assert not self.is_alive(), "the server did not close the connection"
        return self.lines


def check_positions(frames: list[tuple[int, list[tuple[float, float]]]], truth: np.ndarray) -> None:
    """Each frame's two discs where the truth has them (the clip loops: frame k is k % CLIP);
    frame numbers strictly increasing."""
    indices = [k for k, _ in frames]
    assert indices == sorted(set(indices)) and indices
    for k, positions in frames:
        assert len(positions) == 2, (k, positions)
        for xy in positions:
            gap = np.hypot(*(truth[k % CLIP] - np.array(xy)).T)
            assert gap.min() < 2.0, (k, xy)


def parse_json(lines: list[str]) -> list[tuple[int, list[tuple[float, float]]]]:
    out = []
    for line in lines:
        d = json.loads(line)
        assert d["coords"] == "board"
        out.append((d["frame"], [tuple(o["mm"]) for o in d["objects"]]))
    return out


def parse_csv(lines: list[str], width: int = 5) -> list[tuple[int, list[tuple[float, float]]]]:
    """frame,t,coords,n then n groups of `width` fields, id,x,y first."""
    out = []
    for line in lines:
        f = line.split(",")
        n = int(f[3])
        assert f[2] == "board" and len(f) == 4 + width * n, line
        groups = [f[4 + width * k : 4 + width * (k + 1)] for k in range(n)]
        out.append((int(f[0]), [(float(g[1]), float(g[2])) for g in groups]))
    return out


TEMPLATE = "{id},{x:.2f},{y:.2f},{angle:.1f}"


@pytest.mark.parametrize(
    ("options", "parse"),
    [
        ([], parse_json),
        (["--format", "csv"], parse_csv),
        (["--template", TEMPLATE], lambda lines: parse_csv(lines, 4)),
    ],
    ids=["json", "csv", "template"],
)
def test_two_clients_get_whole_lines_in_each_format(
    scene: tuple[Path, Path, np.ndarray],
    camera: type[PacedCamera],
    monkeypatch: pytest.MonkeyPatch,
    options: list[str],
    parse: Callable[[list[str]], list[tuple[int, list[tuple[float, float]]]]],
) -> None:
    calib, video, truth = scene
    run = Run(
        monkeypatch,
        "--source",
        video,
        "--calibration",
        calib,
        "--min-area",
        50,
        "-o",
        "tcp-listen://127.0.0.1:0",
        *options,
    )
    server = run.server
    assert server.port > 0 and server.address == f"127.0.0.1:{server.port}"
    first = Client(server.port)
    head = [first.line() for _ in range(5)]  # it joined mid-stream: from a line's start
    second = Reader(server.port)
    assert wait_for(lambda: server.stats.clients == 2)
    assert wait_for(lambda: second.client.stats(server).sent >= 5)
    assert run.finish(camera) == 0
    lines = head + first.read_to_end()
    check_positions(parse(lines), truth)
    later = second.all_lines()
    check_positions(parse(later), truth)
    # Each got every line sent while it was there, none dropped.
    assert first.stats(server).sent == len(lines) and second.client.stats(server).sent == len(later)
    stats = server.stats
    assert stats.clients == 0 and stats.dropped == 0 and stats.accepted == 2
    first.close()


def test_a_client_that_never_reads_stalls_no_one(
    scene: tuple[Path, Path, np.ndarray],
    camera: type[PacedCamera],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    calib, video, truth = scene
    camera.fps = 2000.0  # as fast as the loop goes: the stuck client's buffers fill in seconds
    run = Run(
        monkeypatch,
        "--source",
        video,
        "--calibration",
        calib,
        "--min-area",
        50,
        "-o",
        "tcp-listen://127.0.0.1:0",
        # Room for the reader's thread to be descheduled on a loaded machine; the stuck
        # client's 2 KB fill at once, and then its 64 lines.
        "--client-buffer",
        64,
    )
    server = run.server
    reader = Reader(server.port)
    stuck = Client(server.port, receive_buffer=2048)  # connects, and never reads a byte
    assert wait_for(lambda: server.stats.clients == 2)
    assert wait_for(lambda: stuck.stats(server).dropped >= 50), stuck.stats(server)
    frames_at_drop = reader.client.stats(server).sent
    assert wait_for(lambda: reader.client.stats(server).sent > frames_at_drop + 50)
    assert run.finish(camera) == 0
    lines = reader.all_lines()
    check_positions(parse_json(lines), truth)
    mine, theirs = reader.client.stats(server), stuck.stats(server)
    # The reader got every line sent while it was there, in order, none dropped.
    assert mine.dropped == 0 and mine.sent == len(lines)
    assert theirs.dropped >= 50
    total = server.stats
    assert total.dropped == sum(c.dropped for c in total.per_client)
    assert total.sent == sum(c.sent for c in total.per_client)
    stuck.close()


def test_clients_that_close_at_once_or_reset_mid_line_harm_no_one(
    scene: tuple[Path, Path, np.ndarray],
    camera: type[PacedCamera],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    calib, video, truth = scene
    run = Run(
        monkeypatch,
        "--source",
        video,
        "--calibration",
        calib,
        "--min-area",
        50,
        "-o",
        "tcp-listen://127.0.0.1:0",
    )
    server = run.server
    reader = Reader(server.port)
    for _ in range(5):
        Client(server.port).close()  # connects and hangs up at once
    resetter = Client(server.port)
    assert resetter.sock.recv(20)  # half a line at most
    resetter.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    resetter.close()  # a reset, mid-line
    assert wait_for(lambda: server.stats.accepted == 7 and server.stats.clients == 1)
    sent = reader.client.stats(server).sent
    assert wait_for(lambda: reader.client.stats(server).sent > sent + 10)
    assert run.finish(camera) == 0
    lines = reader.all_lines()
    check_positions(parse_json(lines), truth)
    assert reader.client.stats(server).dropped == 0
    gone = [c for c in server.stats.per_client if c.peer != f"127.0.0.1:{reader.client.port}"]
    assert len(gone) == 6 and all(not c.connected and c.closed_by for c in gone)
    # The summary on stderr reports the server's figures, client by client.
    err = capsys.readouterr().err
    assert f"listening on 127.0.0.1:{server.port}" in err
    figures = json.loads(err.rsplit("planarcal run: ", 1)[1])
    assert figures["output"]["accepted"] == 7 and len(figures["output"]["per_client"]) == 7


def test_trigger_gets_one_answer_per_request_from_a_later_frame(
    scene: tuple[Path, Path, np.ndarray],
    camera: type[PacedCamera],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    calib, video, truth = scene
    run = Run(
        monkeypatch,
        "--source",
        video,
        "--calibration",
        calib,
        "--min-area",
        50,
        "-o",
        "tcp-listen://127.0.0.1:0",
        "--trigger",
    )
    server = run.server
    robot = Client(server.port)
    assert wait_for(lambda: server.stats.clients == 1)
    time.sleep(0.2)  # frames go by; none may be sent unasked
    robot.send("HELLO\n")
    error = json.loads(robot.line())  # the first line is the answer to HELLO: nothing before
    assert "unknown request 'HELLO'" in error["error"] and "TRIGGER" in error["error"]
    robot.send("trigger\n")  # the word is case-sensitive
    assert "unknown request 'trigger'" in json.loads(robot.line())["error"]
    seen = []
    for _ in range(3):
        asked = robot.send("TRIGGER\n")
        answer = json.loads(robot.line())
        assert answer["t"] >= asked - 1e-6  # a frame read after the request
        seen.append(answer)
    check_positions(parse_json([json.dumps(a) for a in seen]), truth)
    assert [a["frame"] for a in seen] == sorted({a["frame"] for a in seen})
    # Two requests in one packet (CRLF, as many controllers end lines): two answers; then
    # an unknown word, whose error line must come next: no third answer in between.
    robot.send("TRIGGER\r\n  TRIGGER \n\nPING\n")
    two = [json.loads(robot.line()) for _ in range(2)]
    assert all("objects" in a for a in two)
    assert "unknown request 'PING'" in json.loads(robot.line())["error"]
    # Two controllers at once: each gets its own answer.
    other = Client(server.port)
    assert wait_for(lambda: server.stats.clients == 2)
    t1, t2 = robot.send("TRIGGER\n"), other.send("TRIGGER\n")
    a1, a2 = json.loads(robot.line()), json.loads(other.line())
    assert a1["t"] >= t1 - 1e-6 and a2["t"] >= t2 - 1e-6
    # A controller that asks and closes its side still gets its answer.
    other.send("TRIGGER\n")
    other.sock.shutdown(socket.SHUT_WR)
    assert "objects" in json.loads(other.line())
    assert other.read_to_end() == []
    assert run.finish(camera) == 0
    stats = server.stats
    assert stats.requests == 8 and stats.answers == 8 and stats.error_lines == 3
    assert stats.dropped == 0
    robot.close()


def test_trigger_during_a_camera_fault_gets_an_error_line_never_silence(
    scene: tuple[Path, Path, np.ndarray],
    camera: type[PacedCamera],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    calib, video, truth = scene
    run = Run(
        monkeypatch,
        "--source",
        video,
        "--calibration",
        calib,
        "--min-area",
        50,
        "-o",
        "tcp-listen://127.0.0.1:0",
        "--trigger",
        "--trigger-word",
        "GO",
        "--trigger-timeout",
        0.5,
        "--format",
        "csv",
    )
    server = run.server
    robot = Client(server.port)

    def ask() -> str:
        robot.send("GO\n")
        return robot.line()

    check_positions(parse_csv([ask()]), truth)
    # Unplugged: the tracker is reopening it. The answer is an error line, at once.
    camera.unplugged.set()
    attempts = camera.attempts
    assert wait_for(lambda: camera.attempts >= attempts + 1)
    answer = ask()
    assert answer.startswith("ERROR,") and "not delivering" in answer, answer
    assert answer.count(",") == 1
    # Plugged in again: answers come back.
    camera.unplugged.clear()
    assert wait_for(lambda: not ask().startswith("ERROR"))
    # Frozen (open, but no frame comes): an error line once --trigger-timeout has passed.
    camera.frozen.set()
    assert camera.stuck.wait(WAIT_S)
    answer = ask()
    camera.frozen.clear()
    assert answer.startswith("ERROR,no frame within 0.5 s of the request"), answer
    assert wait_for(lambda: not ask().startswith("ERROR"))
    # A request that waits when the run ends gets an error line too (the run stopping, or
    # the timeout, whichever comes first).
    camera.frozen.set()
    assert camera.stuck.wait(WAIT_S)
    asked = server.stats.requests
    robot.send("GO\n")
    assert wait_for(lambda: server.stats.requests == asked + 1)
    assert run.finish(camera) == 0
    last = robot.read_to_end()
    assert len(last) == 1 and last[0].startswith("ERROR,"), last
    robot.close()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["-o", "tcp-listen://127.0.0.1"], "no port"),
        (["-o", "tcp-listen://127.0.0.1:70000"], "port 70000 is out of range 0-65535"),
        (["-o", "tcp-listen://:5000"], "no host to listen on"),
        (["-o", "tcp-listen://::1:5000"], "in brackets"),
        (["-o", "tcp-listen:5000"], "write tcp-listen://HOST:PORT"),
        (["--trigger"], "--trigger needs --output tcp-listen://HOST:PORT, not '-'"),
        (["-o", "tcp://127.0.0.1:5000", "--trigger"], "--trigger needs --output tcp-listen"),
        (["-o", "tcp-listen://127.0.0.1:0", "--trigger-word", "GO"], "goes with --trigger"),
        (["-o", "tcp-listen://127.0.0.1:0", "--trigger", "--trigger-word", "A B"], "spaces"),
        (["-o", "tcp-listen://127.0.0.1:0", "--trigger", "--trigger-timeout", "0"], "positive"),
        (["-o", "tcp-listen://127.0.0.1:0", "--trigger", "--trigger-timeout", "1e300"], "3600"),
        (["--client-buffer", "4"], "goes with --output tcp-listen"),
        (["-o", "tcp-listen://127.0.0.1:0", "--client-buffer", "0"], "1 to 1000000 lines"),
        (["-o", "tcp-listen://127.0.0.1:0", "--client-buffer", "10000000000"], "1 to 1000000"),
        (["--template", "{xx}"], r"unknown field \{xx\}; the fields are frame"),
        (["--format", "csv", "--template", "{id}"], "goes with the template format"),
        (["--template", "{id},{area:,.0f}"], r"field area \(\{area:,.0f\}\) can render a comma"),
        (["--max-clients", "4"], "--max-clients goes with --output tcp-listen://, not '-'"),
        (["-o", "tcp-listen://127.0.0.1:0", "--max-clients", "0"], "1 to 10,000 controllers"),
        (["-o", "tcp-listen://127.0.0.1:0", "--client-idle-timeout", "5"], "goes with --trigger"),
        (
            ["-o", "tcp-listen://127.0.0.1:0", "--trigger", "--client-idle-timeout", "-1"],
            "0 \\(never",
        ),
        (["-o", "tcp-listen://127.0.0.1:0", "--trigger", "--client-idle-timeout", "nan"], "86400"),
    ],
)
def test_bad_output_arguments_are_refused_before_the_camera_opens(
    camera: type[PacedCamera],
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    options: list[str],
    message: str,
) -> None:
    # Neither the calibration nor the source exist: the output's arguments are checked first.
    code = cli.main(
        ["run", "--source", str(tmp_path / "none.avi"), "--calibration", "none.json", *options]
    )
    err = capsys.readouterr().err
    assert code == 2 and re.search(message, err), err  # 2: a malformed command line
    assert camera.attempts == 0


def test_a_port_in_use_is_named(
    scene: tuple[Path, Path, np.ndarray],
    capsys: pytest.CaptureFixture[str],
) -> None:
    calib, video, _ = scene
    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = taken.getsockname()[1]
        code = cli.main(
            [
                "run",
                "--source",
                str(video),
                "--calibration",
                str(calib),
                "-o",
                f"tcp-listen://127.0.0.1:{port}",
            ]
        )
        err = capsys.readouterr().err
        assert code == 1 and f"port {port} is already in use" in err, err
        with pytest.raises(OutputError, match=f"127.0.0.1:{port}: port {port} is already in use"):
            open_output(f"tcp-listen://127.0.0.1:{port}")


def test_server_options_only_with_a_server_and_too_many_clients_get_an_error_line() -> None:
    with pytest.raises(OutputError, match="apply to a server"):
        open_output("-", trigger_word="GO")
    with contextlib.closing(ServerOutput("127.0.0.1", 0, max_clients=1)) as server:
        first = Client(server.port)
        assert wait_for(lambda: server.stats.clients == 1)
        second = Client(server.port)
        assert second.line().startswith("ERROR,1 controllers are connected already")
        assert second.read_to_end() == []
        assert server.stats.refused == 1
        assert server.send('{"frame": 0}') and first.line() == '{"frame": 0}'
        first.close()
        second.close()
    assert not server.send('{"frame": 1}') and server.stats.dropped == 1


@pytest.mark.skipif(not socket.has_ipv6, reason="no IPv6")
def test_ipv6_loopback_in_brackets() -> None:
    try:
        server = open_output("tcp-listen://[::1]:0")
    except OutputError as e:  # a machine without an IPv6 loopback
        pytest.skip(str(e))
    with contextlib.closing(server):
        assert isinstance(server, ServerOutput) and server.spec.startswith("tcp-listen://[::1]:")
        with socket.create_connection(("::1", server.port), timeout=WAIT_S) as conn:
            assert wait_for(lambda: server.stats.clients == 1)
            server.send("a line")
            assert conn.recv(100) == b"a line\n"


def test_the_command_says_where_it_listens_and_stops_cleanly_on_sigterm(
    scene: tuple[Path, Path, np.ndarray], tmp_path: Path
) -> None:
    calib, _, truth = scene
    long_video = tmp_path / "long.avi"
    clip = Camera(scene[1], color=False)
    frames = [clip.read() for _ in range(CLIP)]
    clip.close()
    writer = cv2.VideoWriter(
        str(long_video), cv2.VideoWriter.fourcc(*"MJPG"), 30.0, (160, 120), False
    )
    for k in range(20 * CLIP):
        writer.write(frames[k % CLIP])
    writer.release()
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
        "--template",
        TEMPLATE,
    ]
    proc = subprocess.Popen(argv, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        said = [proc.stderr.readline() for _ in range(1)]
        while "listening on" not in said[-1] and said[-1] and len(said) < 50:
            said.append(proc.stderr.readline())
        match = re.fullmatch(r"planarcal run: listening on 127\.0\.0\.1:(\d+)\n", said[-1])
        assert match, said
        client = Client(int(match.group(1)))
        lines = [client.line() for _ in range(3)]
        proc.send_signal(signal.SIGTERM)
        lines += client.read_to_end()
        _, err = proc.communicate(timeout=WAIT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    frames_seen = parse_csv(lines, 4)
    assert [k for k, _ in frames_seen] == list(range(frames_seen[0][0], frames_seen[-1][0] + 1))
    for k, positions in frames_seen:
        assert len(positions) == 2
        assert all(np.hypot(*(truth[k % CLIP] - np.array(xy)).T).min() < 2.0 for xy in positions)
    figures = json.loads(err.rsplit("planarcal run: ", 1)[1])
    assert figures["stopped_by"] == "SIGTERM"
    (me,) = figures["output"]["per_client"]
    assert me["sent"] == len(lines) and me["dropped"] == 0
    client.close()


def test_replies_keep_the_order_of_the_requests_and_overlong_lines_are_refused() -> None:
    with contextlib.closing(ServerOutput("127.0.0.1", 0, trigger_word="GO")) as server:
        robot = Client(server.port)
        robot.send("GO\nPING\n")  # the error for PING waits behind the answer owed to GO
        assert wait_for(lambda: server.stats.requests == 1 and server.stats.error_lines == 1)
        assert server.answer(time.time(), lambda: "frame 1") == 1
        assert robot.line() == "frame 1"
        assert robot.line().startswith("ERROR,unknown request 'PING'")
        # A frame read before a request does not answer it.
        before = time.time()
        robot.send("GO\n")
        assert wait_for(lambda: server.stats.requests == 2)
        assert server.answer(before, lambda: "too old") == 0
        assert server.answer(time.time(), lambda: "frame 2") == 1
        assert robot.line() == "frame 2"
        robot.send("G" * 2000)
        assert robot.line().startswith("ERROR,a request line longer than 1024 bytes")
        robot.send("O\nGO\n")  # the rest of the long line is skipped; the next one counts
        assert wait_for(lambda: server.stats.requests == 3)
        assert server.answer(time.time(), lambda: "frame 3") == 1
        assert robot.line() == "frame 3"
        robot.close()


def test_a_client_that_stalls_is_reset_and_its_drops_counted() -> None:
    server = ServerOutput("127.0.0.1", 0, stall_timeout=0.3, max_pending_lines=4)
    with contextlib.closing(server):
        stuck = Client(server.port, receive_buffer=2048)
        assert wait_for(lambda: server.stats.clients == 1)
        line = "x" * 500
        assert wait_for(lambda: not server.send(line) or server.stats.clients == 0)
        (gone,) = server.stats.per_client
        assert not gone.connected and "took no data for 0.3 s" in (gone.closed_by or "")
        assert gone.dropped > 0 and server.stats.errors == 1
        stuck.close()
