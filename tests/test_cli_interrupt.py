"""Ctrl-C: a real SIGINT to a `planarcal` process at work ends it with one line on stderr and
status 130, never a traceback, and leaves every file it wrote whole (or not there)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import pytest

from planarcal import synth

# The status of a command Ctrl-C ended, as a shell gives for a process that SIGINT killed.
INTERRUPTED = 130

# How long a process may take to get going, or to end once interrupted (a bound against a
# hang, not a measurement: the 2 cores are shared).
PATIENCE_S = 120.0


def _start(*args: str | Path, cwd: Path | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "planarcal", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
    )


def _wait_for(condition: Callable[[], bool], proc: subprocess.Popen[str]) -> None:
    """Polls `condition` until it holds; fails if the process ends first."""
    deadline = time.monotonic() + PATIENCE_S
    while not condition():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the command never got going"
        time.sleep(0.02)


def _interrupt(proc: subprocess.Popen[str]) -> tuple[int, str, str]:
    assert proc.poll() is None, "the command ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=PATIENCE_S)
    return proc.returncode, out, err


def _assert_whole(folder: Path) -> None:
    """Every file in `folder` complete: PNGs decode, JSON parses; no temporary left."""
    for path in folder.iterdir():
        assert not path.name.startswith("."), f"a temporary file was left: {path.name}"
        if path.suffix == ".png":
            assert cv2.imread(str(path)) is not None, f"{path.name} is not a whole PNG"
        elif path.suffix == ".json":
            json.loads(path.read_text())
        elif path.suffix == ".csv":
            assert path.read_text().endswith("\n"), f"{path.name} is cut short"


@pytest.mark.parametrize("delay_s", [0.0, 1.0, 3.0])
def test_ctrl_c_ends_the_demo_in_one_line(tmp_path: Path, delay_s: float) -> None:
    report = tmp_path / "report"
    proc = _start("demo", "--report", report)
    _wait_for(report.is_dir, proc)  # made before the work starts
    time.sleep(delay_s)
    if proc.poll() is not None:  # done before the later interrupts: nothing to test
        pytest.skip("the demo finished before the interrupt")
    code, out, err = _interrupt(proc)
    if code == 0:  # it finished as the interrupt arrived: a clean end all the same
        assert "Traceback" not in err and "Exception ignored" not in err, err
        _assert_whole(report)
        pytest.skip("the demo finished as the interrupt arrived")
    assert code == INTERRUPTED, err
    assert err.splitlines() == ["planarcal demo: interrupted"], err
    assert out == ""
    _assert_whole(report)


def test_ctrl_c_ends_calibrate_on_a_large_folder(tmp_path: Path) -> None:
    folder = tmp_path / "frames"
    folder.mkdir()
    image = synth.paper_scene(seed=7).calibration.image
    cv2.imwrite(str(folder / "f000.png"), image)
    for k in range(1, 400):  # links to the one file: 400 frames, no room taken
        (folder / f"f{k:03d}.png").hardlink_to(folder / "f000.png")
    out = tmp_path / "calib.json"
    proc = _start("calibrate", "--camera", folder, "--frames", "400", "-o", out, "--json")
    time.sleep(1.0)  # while loading or averaging: either is ended in one line
    code, stdout, err = _interrupt(proc)
    assert code == INTERRUPTED, err
    assert err.splitlines() == ["planarcal calibrate: interrupted"], err
    assert stdout == ""
    assert not out.exists()
    _assert_whole(tmp_path)


def test_ctrl_c_stops_a_run_cleanly(tmp_path: Path) -> None:
    scene = synth.paper_scene(seed=7)
    cv2.imwrite(str(tmp_path / "board.png"), scene.calibration.image)
    cal = tmp_path / "calib.json"
    made = subprocess.run(
        [sys.executable, "-m", "planarcal", "calibrate", tmp_path / "board.png", "-o", cal],
        capture_output=True,
        timeout=PATIENCE_S,
        check=False,
    )
    assert made.returncode == 0, made.stderr
    # A long source: 3000 frames, each a link to the one image file.
    frames = tmp_path / "frames"
    frames.mkdir()
    cv2.imwrite(str(frames / "f0000.png"), scene.objects.image)
    for k in range(1, 3000):
        (frames / f"f{k:04d}.png").hardlink_to(frames / "f0000.png")
    lines = tmp_path / "lines.jsonl"
    proc = _start("run", "--source", frames, "--calibration", cal, "-o", lines)
    _wait_for(lambda: lines.exists() and lines.read_text().count("\n") >= 5, proc)
    code, _, err = _interrupt(proc)
    assert "Traceback" not in err
    # The run's own summary is its one line, and its status says Ctrl-C stopped it.
    summary = [line for line in err.splitlines() if line.startswith("planarcal run: {")]
    assert len(summary) == 1, err
    assert json.loads(summary[0].removeprefix("planarcal run: "))["stopped_by"] == "SIGINT"
    assert code == INTERRUPTED
    written = lines.read_text()
    assert written.endswith("\n")
    for line in written.splitlines():
        json.loads(line)  # every line whole
