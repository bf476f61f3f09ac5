"""Limits found by trying hostile input, each where no other test file owns it: a board too
large to compute, and the mode of the production loop's appended output file."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import planarcal
from planarcal.live.outputs import open_output


@pytest.mark.parametrize(("cols", "rows"), [(10**9, 10**9), (1001, 10), (10, 1001)])
def test_a_board_too_large_to_compute_is_refused_when_made(cols: int, rows: int) -> None:
    # It used to be accepted, and detection then asked NumPy for exabytes (MemoryError).
    with pytest.raises(planarcal.BoardError, match="between 2 and 1000 dots"):
        planarcal.CircleGridBoard(cols=cols, rows=rows)
    assert planarcal.CircleGridBoard(cols=1000, rows=2).world_points().shape == (2000, 2)


@pytest.mark.parametrize("umask", [0o002, 0o022, 0o077])
def test_the_loops_output_file_gets_the_umasks_mode(tmp_path: Path, umask: int) -> None:
    path = tmp_path / "parts.jsonl"
    old = os.umask(umask)
    try:
        output = open_output(str(path))
        output.close()
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask
