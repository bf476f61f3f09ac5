"""Saves killed with SIGKILL at random moments leave the old file or the new one, complete, and
no temporary file: atomic_write hammered by processes that do nothing but save a few MB, and
`planarcal calibrate --report` run as a user runs it. Real processes, real signals, real files;
POSIX only (SIGKILL)."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

import planarcal
from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.files import atomic_write

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL is POSIX")

PACKAGE_DIR = Path(planarcal.__file__).parent
# Any temporary file atomic_write names, whatever its target.
TEMPORARY = re.compile(r"\..+\.[0-9a-f]{12}\.tmp")

# A calibration-like JSON file of a few MB: its generation, then many numbers.
PAYLOAD = '{{"format": "planarcal-calibration", "generation": {generation}, "points": {points}}}\n'

# Saves generation after generation over `target` until killed. Only planarcal.files is
# imported: the package's own imports (numpy, OpenCV, the Rust core) would take most of each
# short life. With "named" it runs as on an OS without O_TMPFILE.
SAVER = f"""
import os, sys, types
package = types.ModuleType("planarcal")
package.__path__ = [sys.argv[1]]
sys.modules["planarcal"] = package
if sys.argv[5] == "named":
    del os.O_TMPFILE
from planarcal.files import atomic_write

target, generation = sys.argv[2], int(sys.argv[4])
with open(sys.argv[3]) as f:
    points = f.read()
print("saving", flush=True)
while True:
    generation += 1
    atomic_write(target, {PAYLOAD!r}.format(generation=generation, points=points))
"""


def temporaries(directory: Path) -> list[str]:
    return [p.name for p in directory.iterdir() if TEMPORARY.fullmatch(p.name)]


def complete_generation(path: Path, points: str) -> int | None:
    """The generation of the payload in `path` if it is a complete one, else None. Compared
    byte for byte with the payload of that generation, which parses (points_file)."""
    data = path.read_bytes()
    header = re.match(rb'\{"format": "planarcal-calibration", "generation": (\d+), ', data)
    if header is None:
        return None
    generation = int(header[1])
    complete = data == PAYLOAD.format(generation=generation, points=points).encode()
    return generation if complete else None


@pytest.fixture(scope="module")
def points_file(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    rng = np.random.default_rng(15)
    points = json.dumps(rng.uniform(-1000.0, 1000.0, size=(200_000, 2)).round(6).tolist())
    path = tmp_path_factory.mktemp("payload") / "points.json"
    path.write_text(points)
    assert json.loads(PAYLOAD.format(generation=12, points=points))["generation"] == 12
    return path, points


@dataclasses.dataclass
class Kills:
    changed: int = 0  # kills after which the file held a newer generation
    complete_debris: int = 0  # temporary files left holding a complete payload
    incomplete_debris: int = 0  # and those holding less


def kill_savers(
    points_file: tuple[Path, str], directory: Path, kills: int, kind: str, seed: int
) -> Kills:
    """Starts `kills` savers over directory/calib.json in turn, each SIGKILLed at a random
    moment of its saving; after each, checks the file is complete, the old generation or a
    newer one, and counts (then removes) the temporary files left."""
    path, points = points_file
    target = directory / "calib.json"
    target.write_text(PAYLOAD.format(generation=0, points=points))
    rng = np.random.default_rng(seed)
    seen = Kills()
    generation = 0
    for _ in range(kills):
        saver = subprocess.Popen(
            [sys.executable, "-c", SAVER, *map(str, (PACKAGE_DIR, target, path, generation)), kind],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        assert saver.stdout is not None
        line = saver.stdout.readline()
        if line != b"saving\n":
            saver.kill()
            pytest.fail(f"the saver did not start: {saver.communicate()[1].decode()}")
        time.sleep(rng.uniform(0.0, 0.1))
        saver.send_signal(signal.SIGKILL)
        _, stderr = saver.communicate()
        assert saver.returncode == -signal.SIGKILL, stderr.decode()
        now = complete_generation(target, points)
        assert now is not None and now >= generation  # complete, never older than it was
        seen.changed += now > generation
        generation = now
        debris = temporaries(directory)
        assert sorted(p.name for p in directory.iterdir()) == sorted(["calib.json", *debris])
        for name in debris:
            if complete_generation(directory / name, points) is None:
                seen.incomplete_debris += 1
            else:
                seen.complete_debris += 1
            (directory / name).unlink()
    return seen


needs_anonymous_files = pytest.mark.skipif(
    not hasattr(os, "O_TMPFILE"),
    reason="no O_TMPFILE here: a killed save leaves a temporary file",
)


@needs_anonymous_files
def test_a_killed_save_leaves_a_complete_file_and_no_debris(
    points_file: tuple[Path, str], tmp_path: Path
) -> None:
    assert len(points_file[1]) > 4_000_000
    seen = kill_savers(points_file, tmp_path, 50, "anonymous", seed=1)
    assert seen.changed >= 10  # the savers were saving when killed, not only starting
    # Content is named only once complete. A kill inside the link-then-rename (the link's
    # ~35 us of a ~35 ms save here: 1 kill in 1000 measured) leaves it under the temporary
    # name; two of 50 would mean that window is much wider than it should be.
    assert seen.incomplete_debris == 0
    assert seen.complete_debris <= 1


def test_without_anonymous_files_the_next_save_removes_a_dead_savers_debris(
    points_file: tuple[Path, str], tmp_path: Path
) -> None:
    """The same kills with a named temporary file (an OS without O_TMPFILE) do leave it
    behind, which shows the kills land mid-save; the next save removes it once it is stale."""
    seen = kill_savers(points_file, tmp_path, 16, "named", seed=2)
    assert seen.changed >= 2 and seen.complete_debris + seen.incomplete_debris >= 1
    # What a dead saver leaves, a minute later: the next save removes it.
    _, points = points_file
    target = tmp_path / "calib.json"
    dead = tmp_path / ".calib.json.0123456789ab.tmp"
    dead.write_text(PAYLOAD.format(generation=7, points=points)[:1000])
    fresh = tmp_path / ".calib.json.ba9876543210.tmp"
    fresh.write_text("a live saver's")
    stale = time.time() - 61
    os.utime(dead, (stale, stale))
    atomic_write(target, PAYLOAD.format(generation=8, points=points))
    assert sorted(p.name for p in tmp_path.iterdir()) == [fresh.name, "calib.json"]


# ------------------------------------------------------------------------------------------
# planarcal calibrate --report, killed

BOARD_ARGS = ["--cols", "14", "--rows", "10", "--pitch", "20", "--diameter", "10"]
REPORT_FILES = {
    "points.csv",
    "summary.json",
    "deviations.png",
    "lens.png",
    "uncertainty.png",
    "coverage.png",
    "detection.png",
}
PNG_END = b"IEND\xaeB`\x82"  # the last chunk of every PNG


def calibrate(image: Path, output: Path, *extra: str) -> subprocess.Popen[bytes]:
    command = ["calibrate", str(image), *BOARD_ARGS, "-o", str(output), *extra]
    return subprocess.Popen(
        [sys.executable, "-m", "planarcal", *command],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )


def finished(process: subprocess.Popen[bytes]) -> None:
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 0, stderr.decode()


def calibration_content(path: Path) -> dict[str, Any]:
    """The calibration file's content, loadable, without the moment it was made."""
    Calibration.load(path)
    data: dict[str, Any] = json.loads(path.read_bytes())
    del data["created"], data["digest"]["sha256"]["created"]
    return data


def check_report(directory: Path) -> None:
    """Whatever report files are there are complete."""
    if not directory.exists():
        return
    for path in directory.iterdir():
        assert path.name in REPORT_FILES, path.name
        data = path.read_bytes()
        if path.suffix == ".png":
            assert data.startswith(b"\x89PNG") and data.endswith(PNG_END), path.name
            assert cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR) is not None
        elif path.suffix == ".csv":
            assert data.endswith(b"\n") and data.count(b"\n") == 141, path.name  # header, dots
        else:
            assert json.loads(data)


@pytest.fixture(scope="module")
def board_png(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("image") / "board.png"
    cv2.imwrite(str(path), synth.paper_scene(seed=7, objects=False).calibration.image)
    return path


@needs_anonymous_files
def test_a_killed_calibrate_leaves_the_previous_calibration(
    board_png: Path, tmp_path: Path
) -> None:
    out, report, reference = tmp_path / "out", tmp_path / "report", tmp_path / "reference"
    out.mkdir()
    reference.mkdir()
    target = out / "calib.json"
    # The previous calibration: the homography alone, to tell it from the new one.
    finished(calibrate(board_png, target, "--lens", "none"))
    previous_bytes = target.read_bytes()
    previous = calibration_content(target)
    started = time.monotonic()
    finished(calibrate(board_png, reference / "calib.json", "--report", str(reference / "r")))
    whole_run_s = time.monotonic() - started
    new = calibration_content(reference / "calib.json")
    assert new != previous
    rng = np.random.default_rng(3)
    # Spread from Python's start to the last report figure (the calibration is saved about a
    # third of the way through), in random order, each a little off the even spacing.
    moments = rng.permutation(np.linspace(0.1, 1.0, 10)) + rng.uniform(-0.03, 0.03, 10)
    outcomes = {"previous": 0, "new": 0}
    for moment in moments:
        process = calibrate(board_png, target, "--report", str(report))
        time.sleep(moment * whole_run_s)
        process.send_signal(signal.SIGKILL)
        process.communicate()
        assert sorted(p.name for p in out.iterdir()) == ["calib.json"]
        check_report(report)
        content = calibration_content(target)
        if content == previous:
            outcomes["previous"] += 1
        else:
            assert content == new
            outcomes["new"] += 1
            target.write_bytes(previous_bytes)  # for the next kill to find
    assert outcomes["previous"] and outcomes["new"], outcomes
