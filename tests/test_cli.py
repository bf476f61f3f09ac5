"""The `planarcal` command line, run as users run it."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys

import numpy as np
import pytest


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, capture_output=True, text=True, timeout=120, check=False)


@pytest.mark.parametrize(
    "command",
    [["planarcal", "demo"], [sys.executable, "-m", "planarcal", "demo"]],
    ids=["console-script", "python-m"],
)
def test_demo_runs_the_papers_calibration(command: list[str]) -> None:
    if command[0] == "planarcal" and shutil.which("planarcal") is None:
        pytest.fail("the planarcal console script is not installed on PATH")
    result = _run(*command)
    assert result.returncode == 0, result.stderr
    out = result.stdout
    # Table 3 reproduced from the paper's matrix, to a hundredth of a pixel.
    m = re.search(r"reprojected coordinates within ([0-9.]+) px", out)
    assert m and float(m.group(1)) < 0.01
    # One row per solver, with a plausible mean error in pixels.
    for label in ("a33 = 1 least squares", "plain DLT by SVD", "normalised DLT + Levenberg"):
        row = next(line for line in out.splitlines() if label in line)
        mean = float(row.split()[-6])
        assert 0.5 < mean < 0.8, row
    # All ten objects mapped to millimetres, close to the paper's Table 5.
    rows = [line.split() for line in out.splitlines() if re.match(r"\s+ID:\d+ ", line)]
    assert len(rows) == 10
    for row in rows:
        ours, paper = np.array(row[3:5], float), np.array(row[5:7], float)
        assert np.abs(ours - paper).max() < 1.0, row


def test_no_command_prints_usage_and_fails() -> None:
    result = _run(sys.executable, "-m", "planarcal")
    assert result.returncode == 2
    assert "usage: planarcal" in result.stderr


def test_version() -> None:
    import planarcal

    result = _run(sys.executable, "-m", "planarcal", "--version")
    assert result.returncode == 0
    assert result.stdout.strip() == f"planarcal {planarcal.__version__}"
