"""`planarcal demo --placements N`: a work area three boards wide, calibrated from N
placements, run as a user runs it; its figures checked against the cell's own truth."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planarcal.calib.calibration import Calibration
from planarcal.synth.cell import render_cell


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "planarcal", "demo", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def _mapping(out: str, who: str) -> tuple[float, float]:
    """The mean and worst error (mm) of the line for ``who`` over the whole work area."""
    m = re.search(rf"{who}:\s+mean ([0-9.]+) mm, worst ([0-9.]+) mm", out)
    assert m, out
    return float(m.group(1)), float(m.group(2))


@pytest.fixture(scope="module")
def six() -> str:
    result = _run("--placements", "6")
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_the_placements_together_beat_one_placement_over_the_whole_area(six: str) -> None:
    joint_mean, joint_worst = _mapping(six, "the 6 placements together")
    alone_mean, alone_worst = _mapping(six, "the middle one alone")
    assert joint_mean <= 0.02 and joint_worst <= 0.1  # issue 23's targets
    assert alone_mean > 20 * joint_mean and alone_worst > 20 * joint_worst
    m = re.search(r"predicted 1-sigma ([0-9.]+) mm RMS against ([0-9.]+) mm \(lens: k1", six)
    assert m and 0.5 < float(m.group(2)) / float(m.group(1)) < 2.0


def test_the_poses_printed_are_the_cells_truth(six: str) -> None:
    cell = render_cell("circles", 6, seed=0)  # the demo's cell
    rows = re.findall(
        r"^\s+(\d)\s+([a-z ]+?)\s+(-?[0-9.]+)\s+(-?[0-9.]+)\s+(-?[0-9.]+)\s+(-?[0-9.]+)"
        r"\s+(-?[0-9.]+)\s+(-?[0-9.]+)\s+([0-9.]+)\s+([0-9.]+)$",
        six,
        flags=re.MULTILINE,
    )
    assert [int(r[0]) for r in rows] == list(range(6))
    assert [r[1] for r in rows] == [p.name for p in cell.placements]
    for r in rows:
        angle, offset = cell.true_pose(int(r[0]))
        fitted = np.array([float(v) for v in r[2:5]])
        true = np.array([float(v) for v in r[5:8]])
        np.testing.assert_allclose(true, [angle, *offset], atol=0.006)
        assert abs(fitted[0] - angle) < 0.01
        assert np.hypot(*(fitted[1:] - offset)) < 0.03
        assert float(r[8]) < 0.03  # the pose's error, mm


def test_parts_are_located_over_the_whole_area(six: str) -> None:
    rows = [line.split() for line in six.splitlines() if re.match(r"\s+ID:\d+ ", line)]
    assert len(rows) == 12
    errors = [float(f[f.index("mm") - 1]) for f in rows]
    assert max(errors) < 0.1
    located = np.array([[float(f[4]), float(f[5])] for f in rows])
    # Spread over the area, not only the middle board's 160 x 120 mm.
    assert np.ptp(located[:, 0]) > 400.0 and np.ptp(located[:, 1]) > 300.0
    m = re.search(
        r"Located within ([0-9.]+) mm of the truth on average, ([0-9.]+) mm at worst .*"
        r"middle placement alone: ([0-9.]+) mm on average, ([0-9.]+) mm at worst",
        six,
    )
    assert m, six
    assert float(m.group(1)) == pytest.approx(np.mean(errors), abs=0.001)
    assert float(m.group(3)) > 20 * float(m.group(1))


def test_the_report_holds_the_placements(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    folder = tmp_path / "report"
    result = _run("--placements", "3", "--board", "chessboard", "--report", folder)
    assert result.returncode == 0, result.stderr
    assert f"Wrote to {folder}" in result.stdout
    cal = Calibration.load(folder / "calib.json")
    assert [p.name for p in cal.placements] == ["middle", "top left", "top right"]
    for name in ("placement-0.png", "placement-2.png", "objects.png", "located.png"):
        assert (folder / name).stat().st_size > 1000
    assert (folder / "coverage.png").exists() and (folder / "summary.json").exists()
    assert "--type chessboard" in result.stdout  # the next steps name the board


@pytest.mark.parametrize("count", ["1", "10", "six"])
def test_bad_counts_are_refused(count: str) -> None:
    result = _run("--placements", count)
    assert result.returncode == 2
    assert "--placements" in result.stderr and "Traceback" not in result.stderr
