"""A folder where an image belongs is named as one, with what reads a folder; `calibrate
--camera DIR` averages only frames of one still view and names the frames that differ."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from planarcal import synth
from test_cli import _run


@pytest.fixture(scope="module")
def views(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """Two folders: three noisy pictures of one view, and those followed by three of another."""
    d = tmp_path_factory.mktemp("views")
    still, moved = d / "still", d / "moved"
    still.mkdir()
    moved.mkdir()
    rng = np.random.default_rng(3)
    first, second = synth.random_paper_scene(1).image, synth.random_paper_scene(2).image
    for k in range(6):
        view = first if k < 3 else second
        # A camera's noise (3 grey levels) is no change of view.
        noisy = np.clip(np.rint(view + rng.normal(0.0, 3.0, view.shape)), 0, 255)
        image = noisy.astype(np.uint8)
        if k < 3:
            cv2.imwrite(str(still / f"view{k + 1}.png"), image)
        cv2.imwrite(str(moved / f"view{k + 1}.png"), image)
    return still, moved


def test_a_folder_given_as_an_image_says_so(views: tuple[Path, Path], tmp_path: Path) -> None:
    still, _ = views
    out = tmp_path / "c.json"
    result = _run("calibrate", still, "-o", out)
    assert result.returncode == 1, result.stderr
    assert f"{str(still)!r} is a directory" in result.stderr
    assert f"--camera {still}" in result.stderr
    assert len(result.stderr.splitlines()) == 1 and not out.exists()
    result = _run("locate", still, "--calibration", out)
    assert result.returncode == 1, result.stderr
    assert "is a directory" in result.stderr and f"--source {still}" in result.stderr


def test_calibrate_averages_a_still_view(views: tuple[Path, Path], tmp_path: Path) -> None:
    still, _ = views
    out = tmp_path / "c.json"
    result = _run("calibrate", "--camera", still, "--frames", "3", "-o", out, "--json")
    assert result.returncode == 0, result.stderr
    assert out.exists()


def test_calibrate_refuses_frames_of_different_views(
    views: tuple[Path, Path], tmp_path: Path
) -> None:
    _, moved = views
    out = tmp_path / "c.json"
    result = _run("calibrate", "--camera", moved, "--frames", "6", "-o", out)
    assert result.returncode == 1, result.stderr
    [line] = result.stderr.splitlines()
    assert "do not show one still view" in line
    for k in (4, 5, 6):  # the frames of the second view, each named with its file
        assert f"frame {k} (view{k}.png)" in line
    for k in (2, 3):
        assert f"frame {k} " not in line
    assert "frame 1 (view1.png)" in line
    assert not out.exists()
