"""When the board is not found: the figure of what the search saw (the blobs, each candidate
grid and why it was refused, the error), and `calibrate --report` writing it before failing."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

import planarcal.commands.calibrate
from conftest import decode_png
from planarcal import report, synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.detect import DetectionDiagnostics, RefusedCandidate, SeenBlobs, detect_board
from planarcal.cli import main
from planarcal.errors import BoardNotFoundError

SMALL_BOARD = ["--cols", "10", "--rows", "8", "--pitch", "20", "--diameter", "10"]
MESSAGE = "no 10 x 8 circle grid (80 dots) found in the 1280 x 720 image."
REASONS = (
    "the dots continue past the grid's right edge: the board in view is larger than 10 x 8",
    "not the board's grid: dot 4 is 30.0 px from where a homography puts it",
)
GREEN_BGR = (44, 160, 44)  # matplotlib's tab:green, the second candidate's colour


@pytest.fixture(scope="module")
def scene() -> Any:
    """A rendered 14 x 10 board."""
    return synth.paper_scene(seed=0, objects=False).calibration


@pytest.fixture(scope="module")
def image_file(scene: Any, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("images") / "board.png"
    cv2.imwrite(str(path), scene.image)
    return path


@pytest.fixture(scope="module")
def diagnostics(scene: Any) -> DetectionDiagnostics:
    """What a search for a 10 x 8 board in the 14 x 10 one could see: every dot as a dark
    blob, a few light ones, and two candidate grids refused."""
    found = detect_board(scene.image, scene.board).image_points
    h, w = scene.image.shape[:2]
    return DetectionDiagnostics(
        board=CircleGridBoard(cols=10, rows=8, pitch=20.0, diameter=10.0),
        image_size=(w, h),
        blobs=(
            SeenBlobs("dark", found, np.full(len(found), 21.0)),
            SeenBlobs("light", found[:5] + np.array([0.0, 30.0]), np.full(5, 12.0)),
        ),
        candidates=(
            RefusedCandidate("symmetric", "dark", found[:80], REASONS[0]),
            RefusedCandidate("blobs", "dark", found[60:], REASONS[1]),
        ),
    )


def _plausible(picture: np.ndarray[Any, Any]) -> None:
    h, w = picture.shape[:2]
    assert 500 <= h <= 1300 and w == 1600, picture.shape
    assert picture.std() > 10  # something is drawn, not a blank page


def _pixels_of(picture: np.ndarray[Any, Any], bgr: tuple[int, int, int]) -> int:
    near = np.abs(picture.astype(int) - np.array(bgr)).max(axis=2) <= 12
    return int(near.sum())


# ------------------------------------------------------------------------------------------
# the figure


def test_the_figure_draws_blobs_and_candidates(scene: Any, diagnostics: Any) -> None:
    drawn = decode_png(report.detection_failure_figure(scene.image, diagnostics, MESSAGE))
    bare = decode_png(report.detection_failure_figure(scene.image, None, MESSAGE))
    _plausible(drawn)
    _plausible(bare)
    # The second candidate's line is drawn in its colour; the image alone has none of it.
    assert _pixels_of(drawn, GREEN_BGR) > 200
    assert _pixels_of(bare, GREEN_BGR) == 0


def test_the_text_gives_the_error_the_blobs_and_each_reason(diagnostics: Any) -> None:
    text = report.detection_failure_text(diagnostics, MESSAGE, width=1000)
    assert f"Error: {MESSAGE}" in text
    assert "Blobs seen: 140 dark, about 21 px across" in text
    assert "Blobs seen: 5 light, about 12 px across" in text
    assert f"1. symmetric (dark dots): {REASONS[0]}" in text
    assert f"2. blobs (dark dots): {REASONS[1]}" in text


def test_without_a_record_the_text_is_the_error(diagnostics: Any) -> None:
    text = report.detection_failure_text(None, MESSAGE, width=1000)
    assert text.startswith(f"Error: {MESSAGE}") and "Candidate" not in text


def test_a_long_list_of_candidates_is_cut_short(diagnostics: Any) -> None:
    many = DetectionDiagnostics(
        board=diagnostics.board,
        image_size=diagnostics.image_size,
        blobs=(),
        candidates=diagnostics.candidates * 7,
    )
    text = report.detection_failure_text(many, MESSAGE, width=1000)
    assert "10. blobs" in text and "11. " not in text and "... and 4 more" in text


def test_a_grey_image_with_nothing_seen(diagnostics: Any) -> None:
    blank = np.full((480, 640), 128, dtype=np.uint8)
    nothing = DetectionDiagnostics(
        board=diagnostics.board, image_size=(640, 480), blobs=(), candidates=()
    )
    picture = decode_png(report.detection_failure_figure(blank, nothing, MESSAGE))
    assert picture.shape[1] == 1600 and picture.std() > 10
    assert "No candidate grid" in report.detection_failure_text(nothing, MESSAGE)


# ------------------------------------------------------------------------------------------
# calibrate --report


def _calibrate(image: Path, tmp_path: Path, *extra: str) -> int:
    return main(["calibrate", str(image), *SMALL_BOARD, "-o", str(tmp_path / "c.json"), *extra])


def _failure_lines(stderr: str) -> tuple[str, str]:
    """The line saying where the figure is, and the error line."""
    lines = stderr.strip().split("\n")
    assert len(lines) == 2, stderr
    return lines[0], lines[1]


def test_calibrate_draws_what_was_seen_and_still_fails(
    image_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A real failure: the 14 x 10 board looked for as 10 x 8."""
    report_dir = tmp_path / "report"
    assert _calibrate(image_file, tmp_path, "--report", str(report_dir)) == 1
    figure = report_dir / report.DETECTION_FAILED_PNG
    where, error = _failure_lines(capsys.readouterr().err)
    assert where == f"planarcal calibrate: drew what the search saw in {figure}"
    assert error.startswith("planarcal calibrate: error: no 10 x 8 circle grid")
    assert sorted(p.name for p in report_dir.iterdir()) == [figure.name]  # no debris
    picture = cv2.imread(str(figure))
    assert picture is not None
    _plausible(picture)
    assert not (tmp_path / "c.json").exists()


def test_calibrate_draws_the_searchs_record(
    image_file: Path,
    diagnostics: Any,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The record the error carries is what is drawn."""

    def refuse(*args: Any, **kwargs: Any) -> Any:
        raise BoardNotFoundError(MESSAGE, diagnostics)

    monkeypatch.setattr(planarcal.commands.calibrate, "detect_board", refuse)
    report_dir = tmp_path / "report"
    assert _calibrate(image_file, tmp_path, "--report", str(report_dir)) == 1
    _, error = _failure_lines(capsys.readouterr().err)
    assert error == f"planarcal calibrate: error: {MESSAGE}"
    picture = cv2.imread(str(report_dir / report.DETECTION_FAILED_PNG))
    assert picture is not None
    assert _pixels_of(picture, GREEN_BGR) > 200


def test_calibrate_on_a_blank_image(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 200, dtype=np.uint8))
    assert _calibrate(blank, tmp_path, "--report", str(tmp_path / "r")) == 1
    where, error = _failure_lines(capsys.readouterr().err)
    assert report.DETECTION_FAILED_PNG in where and "error: no 10 x 8 circle grid" in error
    picture = cv2.imread(str(tmp_path / "r" / report.DETECTION_FAILED_PNG))
    assert picture is not None and picture.shape[1] == 1600 and picture.std() > 10


def test_without_report_nothing_is_drawn(
    image_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _calibrate(image_file, tmp_path) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error: no 10 x 8 circle grid" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_an_unwritable_report_directory_keeps_the_real_error(
    image_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert _calibrate(image_file, tmp_path, "--report", str(blocker / "report")) == 1
    note, error = _failure_lines(capsys.readouterr().err)
    assert note.startswith("planarcal calibrate: could not draw what was seen: ")
    assert error.startswith("planarcal calibrate: error: no 10 x 8 circle grid")
