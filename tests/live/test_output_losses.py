"""Lines that cannot be delivered, as a user of `planarcal run` meets them: the real command
in a subprocess (``python -m planarcal run``) on a real video file of a rendered scene
(test_server's), writing to a device that is always full (``/dev/full``: a full disk), to a
file that fills mid-run (a file size limit), to a ``tcp://`` address where nothing listens,
and to a controller on loopback that reads. A loss
is warned about on stderr while it happens (the first at once, then rate-limited), the
summary says which kind of loss it was, and a run that delivered nothing it was asked to
deliver exits with status 1."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import test_server as served

from planarcal.live.output_options import undelivered
from planarcal.live.outputs import FileOutput, TcpOutput

scene = served.scene  # calib.json, a 20-frame video of two discs, each frame's truth

FRAMES = served.CLIP


def run(calib: Path, video: Path, output: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "planarcal",
            "run",
            "--source",
            str(video),
            "--calibration",
            str(calib),
            "--min-area",
            "50",
            "-o",
            output,
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def summary_of(err: str) -> dict[str, Any]:
    """The run's summary: the JSON object after the last "planarcal run: {"."""
    figures: dict[str, Any] = json.loads("{" + err.rsplit("planarcal run: {", 1)[1].split("\n")[0])
    return figures


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
    return port


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_full_disk_is_warned_about_at_once_and_the_run_fails(
    scene: tuple[Path, Path, np.ndarray],
) -> None:
    calib, video, _ = scene
    done = run(calib, video, "/dev/full")
    err = done.stderr
    assert done.returncode == 1, err
    warnings = [line for line in err.splitlines() if line.startswith("planarcal run: /dev/full:")]
    # The first loss at once, the rest at close: not one warning per frame.
    assert warnings[0].startswith(
        "planarcal run: /dev/full: 1 line lost: cannot write to /dev/full: No space left"
    ), err
    assert 2 <= len(warnings) < FRAMES, err
    output = summary_of(err)["output"]
    assert output["sent"] == 0
    assert output["dropped"] == output["dropped_write_failed"] == FRAMES
    assert output["dropped_full_buffer"] == 0
    assert f"error: no line was delivered to /dev/full: all {FRAMES} were lost" in err


@pytest.mark.skipif(sys.platform == "win32", reason="needs RLIMIT_FSIZE")
def test_a_disk_that_fills_mid_run_is_warned_about_and_what_was_written_is_whole(
    scene: tuple[Path, Path, np.ndarray], tmp_path: Path
) -> None:
    calib, video, truth = scene
    path = tmp_path / "positions.jsonl"

    def limit_file_size() -> None:  # in the child: its writes past 2,000 bytes fail (EFBIG)
        import resource  # noqa: PLC0415

        resource.setrlimit(resource.RLIMIT_FSIZE, (2000, 2000))

    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "planarcal",
            "run",
            "--source",
            str(video),
            "--calibration",
            str(calib),
            "--min-area",
            "50",
            "-o",
            str(path),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        preexec_fn=limit_file_size,
    )
    err = done.stderr
    # Some lines were delivered: the run succeeds, and says what it lost while it lost it.
    assert done.returncode == 0, err
    output = summary_of(err)["output"]
    sent, lost = output["sent"], output["dropped_write_failed"]
    assert 0 < sent < FRAMES and sent + lost == FRAMES, output
    assert f"planarcal run: {path}: 1 line lost: cannot write to {path}: File too large" in err
    lines = path.read_text().splitlines()  # only whole lines: a cut one was taken back
    assert len(lines) == sent
    served.check_positions(served.parse_json(lines), truth)


def test_a_controller_that_is_not_listening_is_warned_about_and_the_run_fails(
    scene: tuple[Path, Path, np.ndarray],
) -> None:
    calib, video, _ = scene
    port = free_port()
    done = run(calib, video, f"tcp://127.0.0.1:{port}")
    err = done.stderr
    assert done.returncode == 1, err
    where = f"tcp://127.0.0.1:{port}"
    assert (
        f"{where}: no connection after 2 s (cannot connect to {where}: Connection refused)" in err
    )
    assert f"{where}: 1 line lost: not connected to {where}" in err
    output = summary_of(err)["output"]
    assert (output["sent"], output["dropped_write_failed"]) == (0, FRAMES)
    assert f"error: no line was delivered to {where}: all {FRAMES} were lost" in err


def test_a_controller_that_listens_gets_every_frame_and_the_run_succeeds(
    scene: tuple[Path, Path, np.ndarray],
) -> None:
    calib, video, truth = scene
    with socket.create_server(("127.0.0.1", 0)) as listener:
        listener.settimeout(served.WAIT_S)
        port = listener.getsockname()[1]
        received = bytearray()

        def controller() -> None:
            conn, _ = listener.accept()
            with conn:
                while chunk := conn.recv(65536):
                    received.extend(chunk)

        reading = threading.Thread(target=controller, daemon=True)
        reading.start()
        done = run(calib, video, f"tcp://127.0.0.1:{port}")
        reading.join(served.WAIT_S)
    assert done.returncode == 0, done.stderr
    assert "line lost" not in done.stderr and "lines lost" not in done.stderr
    assert "no connection" not in done.stderr
    # The run waited for the connection: even a 20-frame video is delivered whole.
    served.check_positions(served.parse_json(received.decode().splitlines()), truth)
    output = summary_of(done.stderr)["output"]
    assert (output["sent"], output["dropped"]) == (FRAMES, 0)


def test_losses_are_rate_limited_with_their_counts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    clock = [1000.0]
    monkeypatch.setattr(time, "monotonic", lambda: clock[0])  # the warnings' clock
    out = FileOutput("/dev/full") if os.path.exists("/dev/full") else None
    if out is None:
        pytest.skip("needs /dev/full")
    with caplog.at_level("WARNING", logger="planarcal.live.outputs"):
        for _ in range(50):
            assert not out.send("{}")
        clock[0] += 9.9  # not yet: the first came less than 10 s ago
        assert not out.send("{}")
        clock[0] += 0.2
        assert not out.send("{}")  # 10.1 s after the first: the count since then
        for _ in range(7):
            assert not out.send("{}")
        out.close()  # what was not reported yet
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 3, messages
    assert messages[0].startswith("/dev/full: 1 line lost: cannot write to /dev/full")
    assert messages[0].endswith("(reported again at most every 10 s)")
    assert messages[1].startswith("/dev/full: 51 lines lost in the last 10 s: cannot write")
    assert "(52 in all: 52 not written, 0 dropped from a full buffer)" in messages[1]
    assert messages[2].startswith("/dev/full: 7 lines lost in the last 0 s")
    assert "(59 in all" in messages[2]
    assert undelivered(out) is not None


def test_undelivered_only_when_lines_were_meant_and_none_arrived(tmp_path: Path) -> None:
    with FileOutput(tmp_path / "positions.jsonl") as out:
        assert undelivered(out) is None  # nothing asked: nothing failed
        out.send("{}")
    assert undelivered(out) is None
    out.send("{}")  # after close: lost, but one line was delivered
    assert out.stats.dropped == 1 and undelivered(out) is None
    nowhere = TcpOutput("127.0.0.1", free_port())
    with nowhere:
        assert not nowhere.send("{}")
    why = undelivered(nowhere)
    assert why is not None and why.startswith(f"no line was delivered to {nowhere.spec}: all 1")
