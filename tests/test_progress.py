"""Long work shows its progress on a terminal (issue 26): `calibrate` from several placements
draws a bar on stderr when stderr is a terminal (a pseudo-terminal here, the real CLI in a
child process), and nothing at all where the output is not a terminal (pipes, TERM=dumb):
stdout keeps its one JSON object and stderr stays empty."""

from __future__ import annotations

import fcntl
import json
import os
import pty
import struct
import subprocess
import sys
import termios
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

import cv2
import numpy as np
import pytest

from planarcal.commands.calibrate import still_average
from planarcal.live.capture import Camera
from planarcal.progress import counter, note, progress
from planarcal.synth.cell import render_cell

BOARD = ["--cols", "9", "--rows", "7", "--pitch", "20"]  # render_cell's circle grid


@pytest.fixture(scope="module")
def placements(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Three placements of the board on a work area, one image each."""
    d = tmp_path_factory.mktemp("progress")
    cell = render_cell("circles", 3)
    paths = []
    for k, image in enumerate(cell.images):
        path = d / f"{'ABC'[k]}.png"
        cv2.imwrite(str(path), image)
        paths.append(path)
    return paths


def _calibrate(images: list[Path]) -> list[str]:
    return [sys.executable, "-m", "planarcal", "calibrate", *map(str, images), *BOARD]


def _on_a_terminal(argv: list[str], env: dict[str, str]) -> tuple[int, bytes, str]:
    """Runs argv with stderr on a pseudo-terminal of 100 x 30 and stdout on a pipe: its status,
    what the terminal received and stdout."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    child = subprocess.Popen(
        argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=slave, env=env
    )
    os.close(slave)
    seen: list[bytes] = []

    def read() -> None:  # while the child runs: a pty's buffer is small
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:  # EIO: the child closed its end
                return
            if not chunk:
                return
            seen.append(chunk)

    reader = threading.Thread(target=read)
    reader.start()
    assert child.stdout is not None
    stdout = child.stdout.read().decode()
    status = child.wait(timeout=300)
    reader.join(timeout=30)
    os.close(master)
    return status, b"".join(seen), stdout


def _env(**change: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("TERM", "NO_COLOR")}
    return {**env, "TERM": "xterm-256color", **change}


def test_placements_show_progress_on_a_terminal(placements: list[Path], tmp_path: Path) -> None:
    out = tmp_path / "cal.json"
    argv = [*_calibrate(placements), "-o", str(out), "--json"]
    status, terminal, stdout = _on_a_terminal(argv, _env())
    assert status == 0, terminal.decode(errors="replace")
    text = terminal.decode()
    # tqdm redraws at most every 0.1 s, so how far the bar is seen to get before it is
    # erased depends on the machine's speed; its start is always drawn.
    assert "Finding the board:" in text and "0/3" in text, text
    # Erased when done: the last thing on the terminal is the bar's line cleared.
    assert text.endswith("\r"), repr(text[-120:])
    summary = json.loads(stdout)  # stdout is the JSON alone
    assert [p["name"] for p in summary["placements"]] == ["A.png", "B.png", "C.png"]


def test_pipes_carry_no_progress(placements: list[Path], tmp_path: Path) -> None:
    out = tmp_path / "cal.json"
    argv = [*_calibrate(placements), "-o", str(out), "--json"]
    run = subprocess.run(argv, capture_output=True, text=True, timeout=300, env=_env())
    assert run.returncode == 0, run.stderr
    assert run.stderr == ""
    summary = json.loads(run.stdout)
    assert len(summary["placements"]) == 3
    text = subprocess.run(
        [*_calibrate(placements), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        env=_env(),
    )
    assert text.returncode == 0 and text.stderr == ""
    assert "Finding" not in text.stdout and "\r" not in text.stdout
    assert text.stdout.splitlines()[-1] == f"Saved the calibration to {out}"


@pytest.fixture
def terminal() -> Iterator[tuple[TextIO, int]]:
    """A pseudo-terminal that reports no size (as a bare one does): a text stream on its
    terminal side, and the other side to read what was drawn."""
    master, slave = pty.openpty()
    os.set_blocking(master, False)
    stream = os.fdopen(slave, "w", encoding="utf-8")
    yield stream, master
    stream.close()
    os.close(master)


def _drawn(master: int) -> str:
    try:
        return os.read(master, 65536).decode()
    except BlockingIOError:
        return ""


def test_a_terminal_without_a_size_still_gets_a_bar(
    terminal: tuple[TextIO, int], monkeypatch: pytest.MonkeyPatch
) -> None:
    stream, master = terminal
    monkeypatch.setenv("TERM", "xterm")
    assert list(progress(range(4), desc="Counting", stream=stream)) == [0, 1, 2, 3]
    stream.flush()
    assert "Counting:   0%" in _drawn(master)


def test_a_dumb_terminal_gets_no_bar(
    terminal: tuple[TextIO, int], monkeypatch: pytest.MonkeyPatch
) -> None:
    stream, master = terminal
    monkeypatch.setenv("TERM", "dumb")  # an editor's shell: every redraw would be a new line
    assert list(progress(range(4), desc="Counting", stream=stream)) == [0, 1, 2, 3]
    with counter(desc="Units", total=2, stream=stream) as bar:
        bar.update(2)
    note("a row", stream=stream)
    stream.flush()
    assert _drawn(master) == "a row\r\n"


def test_a_hand_advanced_bar_and_notes_above_it(
    terminal: tuple[TextIO, int], monkeypatch: pytest.MonkeyPatch
) -> None:
    stream, master = terminal
    monkeypatch.setenv("TERM", "xterm")
    with counter(desc="Units", total=4, unit="unit", leave=True, stream=stream) as bar:
        bar.update(1)
        note("a row", stream=stream)
        bar.update(3)
    stream.flush()
    drawn = _drawn(master)
    assert "a row\r\n" in drawn
    # The bar was redrawn below the note, and kept (leave) at 4/4 with a new line.
    assert drawn.index("Units:") < drawn.index("a row") < drawn.rindex("4/4 ")
    assert drawn.endswith("\r\n")


def test_frames_averaged_show_progress(
    tmp_path: Path, terminal: tuple[TextIO, int], monkeypatch: pytest.MonkeyPatch
) -> None:
    """`calibrate --camera` counts the frames it averages (a folder of one still view here),
    on sys.stderr as it is when the work runs."""
    stream, master = terminal
    image = np.full((48, 64), 128, np.uint8)
    for k in range(3):
        cv2.imwrite(str(tmp_path / f"frame{k}.png"), image)
    monkeypatch.setenv("TERM", "xterm")
    monkeypatch.setattr(sys, "stderr", stream)
    with Camera(str(tmp_path)) as camera:
        mean = still_average(camera, 3)
    assert float(mean.mean()) == 128.0
    stream.flush()
    drawn = _drawn(master)
    assert "Averaging frames:" in drawn and "/3" in drawn, drawn


def test_not_a_terminal_is_left_alone(capsys: pytest.CaptureFixture[str]) -> None:
    """In-process (captured, as the CLI's tests run it): items pass through, nothing drawn."""
    assert list(progress(iter("abc"), desc="Letters")) == ["a", "b", "c"]
    with counter(desc="Units", total=3) as bar:
        bar.update(3)
    note("a row")
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == "a row\n"
