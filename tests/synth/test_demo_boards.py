"""`planarcal demo --board chessboard|charuco`: the demo renders the paper's setup with a board
of that type in the circle grid's place and runs its whole job on it (detect, calibrate,
locate, register), against the truth; the commands it suggests read its own image."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.calib.detection import detect_board
from planarcal.errors import BoardError
from planarcal.synth import demo
from planarcal.synth.demo import NEXT_STEPS


def _run(*args: str | Path, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "planarcal", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        cwd=cwd,
    )


@pytest.mark.parametrize(
    ("kind", "board_type"),
    [("chessboard", ChessboardBoard), ("charuco", CharucoBoard)],
)
def test_demo_with_another_board_runs_the_whole_job(
    kind: str, board_type: type, tmp_path: Path
) -> None:
    result = _run("demo", "--board", kind, "--report", "demo-report", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "Found all 88 corners" in out
    m = re.search(r"Corners \(88 of 88\) against the truth: ([0-9.]+) px RMS", out)
    assert m and float(m.group(1)) < 0.05
    m = re.search(r"against the truth, with the lens model: ([0-9.]+) mm mean", out)
    assert m and float(m.group(1)) < 0.02
    m = re.search(r"against the truth, a homography alone: ([0-9.]+) mm mean", out)
    assert m and float(m.group(1)) > 0.1  # the lens's distortion, as with the circles
    rows = [line for line in out.splitlines() if re.match(r"\s+ID:\d+ ", line)]
    assert len(rows) == 10
    errors = [float(f[f.index("mm") - 1]) for f in (line.split() for line in rows)]
    assert max(errors) < 0.1  # every object within 0.1 mm of where it really is
    assert "six corners touched" in out
    m = re.search(r"Parts in robot mm within [0-9.]+ mm .* ([0-9.]+) mm at worst", out)
    assert m and float(m.group(1)) < 0.2

    # What it wrote: its calibration of this board, which finds the board's corners in mm.
    folder = tmp_path / "demo-report"
    cal = Calibration.load(folder / "calib.json")
    assert isinstance(cal.board, board_type)
    assert cal.board == synth.paper.PAPER_BOARDS[kind]
    image = cv2.imread(str(folder / "board.png"), cv2.IMREAD_GRAYSCALE)
    found = detect_board(image, cal.board)
    mm = cal.image_to_world(found.image_points)
    assert np.abs(mm - cal.board.world_points()[found.ids]).max() < 0.05

    # The closing lines name this board; the calibrate command they give reads its image.
    lines = out.rstrip("\n").splitlines()
    steps = lines[-len(NEXT_STEPS) :]
    assert lines[-len(NEXT_STEPS) - 1].startswith("Wrote to demo-report: ")
    assert steps[0] == NEXT_STEPS[0] and steps[3:] == list(NEXT_STEPS[3:])
    assert f"planarcal board --type {kind} " in steps[1]
    calibrate = shlex.split(steps[2])
    assert calibrate[:3] == ["planarcal", "calibrate", "photo.png"]
    options = calibrate[3 : calibrate.index("-o")]
    again = _run("calibrate", folder / "board.png", *options, "-o", "again.json", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert Calibration.load(tmp_path / "again.json").board == cal.board


def test_demo_refuses_a_board_type_it_does_not_know() -> None:
    result = _run("demo", "--board", "hexagons")
    assert result.returncode == 2
    assert "--board" in result.stderr and "chessboard" in result.stderr


def test_paper_scene_takes_a_board_by_type_or_description() -> None:
    scene = synth.paper_scene(board="charuco", objects=False)
    assert scene.calibration.board == synth.paper.PAPER_CHARUCO
    board = ChessboardBoard(7, 5, 30.0, origin_marker=True)
    chess = synth.paper_scene(board=board)
    assert chess.calibration.board is board
    assert chess.calibration.points_in_view(margin_px=20.0).all()
    # The objects image does not depend on the board.
    np.testing.assert_array_equal(chess.objects.image, synth.paper_scene().objects.image)
    with pytest.raises(BoardError, match="board must be one of"):
        synth.paper_scene(board="hexagons")
    with pytest.raises(BoardError, match="board must be a board"):
        synth.paper_scene(board=3)  # type: ignore[arg-type]
    with pytest.raises(BoardError, match="board must be one of"):
        demo.run(board="hexagons")


@pytest.mark.parametrize("kind", ["chessboard", "charuco"])
def test_random_views_take_any_board(kind: str) -> None:
    """The accuracy statistics' random views (random_paper_scene, random_webcam_scene) put
    the board asked for in the paper board's place, aimed at its points' middle."""
    from planarcal.synth.webcam import random_webcam_scene  # noqa: PLC0415

    scene = synth.random_paper_scene(3, board=kind, max_tilt_deg=20.0)
    board = synth.paper.PAPER_BOARDS[kind]
    assert scene.board == board
    assert scene.points_in_view(margin_px=10.0).all()
    centre = 0.5 * (scene.points_px.min(axis=0) + scene.points_px.max(axis=0))
    assert np.hypot(*(centre - [640.0, 360.0])) < 60.0
    pair = random_webcam_scene(2, board=kind, parts=3)
    assert pair.calibration.board == board and pair.objects.board is None
    assert pair.calibration.points_in_view(margin_px=10.0).all()
    # The same seed gives the same view whatever the board, aimed at its middle.
    circles = synth.random_paper_scene(3, max_tilt_deg=20.0)
    for name in ("distance_mm", "tilt_deg", "tilt_axis_deg", "roll_deg"):
        assert getattr(circles.pose, name) == getattr(scene.pose, name)
    pts = board.world_points()
    shift = 0.5 * (pts.min(axis=0) + pts.max(axis=0)) - [130.0, 90.0]
    np.testing.assert_allclose(
        np.subtract(scene.pose.look_at_mm, circles.pose.look_at_mm), shift, atol=1e-9
    )
    with pytest.raises(BoardError, match="board must be one of"):
        synth.random_paper_scene(3, board="hexagons")
