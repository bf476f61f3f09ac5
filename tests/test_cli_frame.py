"""`planarcal locate` says which frame its millimetres are in: the table's header, the JSON's
"coords" and the annotated image's title, for the board's frame and the robot's."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

import planarcal
from planarcal import synth
from test_cli import _run

# The title's box (white, like every label) in the annotated image's top-left corner.
TITLE_BAND = (slice(0, 40), slice(0, 600))


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The objects image, its calibration, and the same registered to a robot."""
    d = tmp_path_factory.mktemp("frame")
    scene = synth.paper_scene(seed=7)
    paths = {"objects": d / "objects.png", "board": d / "board.json", "robot": d / "robot.json"}
    cv2.imwrite(str(paths["objects"]), scene.objects.image)
    cal = planarcal.Calibration.from_image(scene.calibration.image, synth.PAPER_BOARD)
    cal.save(paths["board"])
    # Dots 0, 13, 126 and 139 (the corners) touched by a robot whose frame is the board's
    # moved by (100, 50) mm.
    corners = np.array([[0.0, 0.0], [260.0, 0.0], [0.0, 180.0], [260.0, 180.0]])
    cal.register(corners + np.array([100.0, 50.0]), dots=[0, 13, 126, 139]).save(paths["robot"])
    return paths


def _white(picture: NDArray[Any]) -> int:
    return int(np.count_nonzero((picture[TITLE_BAND] == 255).all(axis=2)))


@pytest.mark.parametrize(("calibration", "frame"), [("board", "board"), ("robot", "robot")])
def test_locate_says_which_frame(
    setup: dict[str, Path], tmp_path: Path, calibration: str, frame: str
) -> None:
    args = ("locate", setup["objects"], "--calibration", setup[calibration])
    table = _run(*args)
    assert table.returncode == 0, table.stderr
    assert table.stdout.splitlines()[0].startswith(f"Positions in the {frame} frame (mm ")
    found = _run(*args, "--json")
    assert json.loads(found.stdout)["coords"] == frame
    annotated = tmp_path / f"{frame}.png"
    assert _run(*args, "--annotate", annotated).returncode == 0
    picture = cv2.imread(str(annotated))
    assert picture is not None
    assert _white(picture) > 1000  # the title's box


def test_the_titles_differ_with_the_frame(setup: dict[str, Path], tmp_path: Path) -> None:
    pictures: dict[str, NDArray[Any]] = {}
    for frame in ("board", "robot"):
        out = tmp_path / f"{frame}.png"
        args = ("--calibration", setup["robot"], "--frame", frame, "--annotate", out)
        result = _run("locate", setup["objects"], *args)
        assert result.returncode == 0, result.stderr
        assert f"Positions in the {frame} frame" in result.stdout
        picture = cv2.imread(str(out))
        assert picture is not None
        pictures[frame] = picture
    board, robot = pictures["board"], pictures["robot"]
    assert not np.array_equal(board[TITLE_BAND], robot[TITLE_BAND])
    # Below the title the two differ only in the labels' numbers, not the picture.
    assert np.array_equal(board[300:, :100], robot[300:, :100])
