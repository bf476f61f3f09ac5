"""A new user's first hour: a board their printer takes, a demo that shows its figures, and a
calibration summary that prints as the report.

Every command runs as a user runs it (``python -m planarcal`` in a subprocess); the commands
it suggests are run too, and what they write is parsed back.
"""

from __future__ import annotations

import json
import pickle
import re
import shlex
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import cv2
import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration, CalibrationSummary
from planarcal.calib.detect import detect_board
from planarcal.cli import build_parser
from planarcal.report import summary_text
from planarcal.report.printable import PAGE_SIZES, page_refusal, smaller_board
from planarcal.synth.demo import NEXT_STEPS
from test_cli import _run

SVG = "{http://www.w3.org/2000/svg}"
MARGIN = 10.0  # mm, the board command's default


def _run_suggested(command: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """A `planarcal ...` command line as printed, run word for word."""
    words = shlex.split(command)
    assert words[:2] == ["planarcal", "board"], command
    return _run(*words[1:], cwd=cwd)


def _commands(text: str) -> list[str]:
    """The command lines quoted (`...`) in a message."""
    return re.findall(r"`(planarcal [^`]*)`", text)


def _option(command: str, name: str) -> str:
    words = shlex.split(command)
    return words[words.index(name) + 1]


def _check_page(svg: Path, page: str, margin: float = MARGIN) -> int:
    """Asserts the SVG is one `page` (either orientation) with every dot inside the margins;
    returns how many dots it has."""
    root = ET.parse(svg).getroot()
    width = float(root.get("width", "nan").removesuffix("mm"))
    height = float(root.get("height", "nan").removesuffix("mm"))
    assert sorted((width, height)) == sorted(PAGE_SIZES[page]), (width, height)
    circles = root.findall(f".//{SVG}g[@id='dots']/{SVG}circle")
    for c in circles:
        cx, cy, r = (float(c.get(k, "nan")) for k in ("cx", "cy", "r"))
        assert margin <= cx - r and cx + r <= width - margin
        assert margin <= cy - r and cy + r <= height - margin
    return len(circles)


# --------------------------------------------------------------------------- the board


def test_board_and_calibrate_share_their_defaults() -> None:
    parser = build_parser()
    default = CircleGridBoard()
    for command in (["board", "-o", "b.svg"], ["calibrate", "photo.png", "-o", "c.json"]):
        args = parser.parse_args(command)
        assert (args.cols, args.rows, args.pitch) == (default.cols, default.rows, default.pitch)


def test_default_board_says_which_board_fits_a4_and_letter(tmp_path: Path) -> None:
    result = _run("board", "-o", "board.svg", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "on A3 landscape" in result.stdout  # the paper's board: 275 x 195 mm of dots
    assert "It needs A3 paper." in result.stdout
    for page in ("A4", "letter"):
        line = next(x for x in result.stdout.splitlines() if x.startswith(f"On {page}: "))
        (command,) = _commands(line)
        assert "calibrate with the same --cols, --rows and --pitch" in line
        assert _option(command, "--pitch") == "20"  # the dots stay as large in the image
        made = _run_suggested(command, tmp_path)
        assert made.returncode == 0, made.stderr
        assert f"on {page} " in made.stdout and "It needs" not in made.stdout
        cols, rows = int(_option(command, "--cols")), int(_option(command, "--rows"))
        assert _check_page(tmp_path / "board.svg", page) == cols * rows


@pytest.mark.parametrize("page", ["A4", "letter"])
def test_a_page_too_small_names_a_command_that_fits_it(tmp_path: Path, page: str) -> None:
    result = _run("board", "--page", page, "-o", "board.svg", cwd=tmp_path)
    assert result.returncode == 1
    assert "Traceback" not in result.stderr and len(result.stderr.splitlines()) == 1
    assert f"does not fit on {page}" in result.stderr
    assert not (tmp_path / "board.svg").exists()
    (command,) = _commands(result.stderr)
    assert _option(command, "--page") == page and _option(command, "-o") == "board.svg"
    made = _run_suggested(command, tmp_path)
    assert made.returncode == 0, made.stderr
    cols, rows = int(_option(command, "--cols")), int(_option(command, "--rows"))
    assert _check_page(tmp_path / "board.svg", page) == cols * rows
    # The board printed is found by calibrate with the same three numbers.
    board = CircleGridBoard(
        cols=cols, rows=rows, pitch=float(_option(command, "--pitch")), diameter=10.0
    )
    assert page_refusal(board, page) is None


def test_a3_holds_the_default_board(tmp_path: Path) -> None:
    result = _run("board", "--page", "A3", "-o", "board.svg", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "It needs" not in result.stdout and "On A4" not in result.stdout
    assert _check_page(tmp_path / "board.svg", "A3") == 140


def test_the_suggested_command_keeps_the_options_given(tmp_path: Path) -> None:
    options = ["--diameter", "8", "--marker-diameter", "14", "--margin", "12"]
    result = _run("board", "--page", "A4", *options, "-o", "b.svg", cwd=tmp_path)
    assert result.returncode == 1
    (command,) = _commands(result.stderr)
    for name, value in zip(options[::2], options[1::2], strict=True):
        assert _option(command, name) == value, command
    made = _run_suggested(command, tmp_path)
    assert made.returncode == 0, made.stderr
    _check_page(tmp_path / "b.svg", "A4", margin=12.0)


def test_a_board_offered_at_a_finer_pitch_prints(tmp_path: Path) -> None:
    # No 2 x 3 of these fits A4 at 141.3 mm: every dot is offered closer together, the dots
    # and the marker (as wide as the spacing allows) scaled with them.
    options = ["--cols", "3", "--rows", "3", "--pitch", "141.3", "--layout", "asymmetric"]
    options += ["--diameter", "98.91", "--marker-diameter", "199.82"]
    result = _run("board", "--page", "A4", *options, "-o", "b.svg", cwd=tmp_path)
    assert result.returncode == 1
    (command,) = _commands(result.stderr)
    assert (_option(command, "--cols"), _option(command, "--rows")) == ("3", "3")
    pitch = float(_option(command, "--pitch"))
    assert pitch < 141.3 and pitch % 0.5 == 0
    assert float(_option(command, "--diameter")) == pytest.approx(98.91 * pitch / 141.3, abs=0.01)
    made = _run_suggested(command, tmp_path)
    assert made.returncode == 0, made.stderr
    assert _check_page(tmp_path / "b.svg", "A4") == 9


def test_smaller_board_has_the_most_dots_at_the_pitch() -> None:
    paper = CircleGridBoard(origin_marker=True)
    for page in ("A4", "letter"):
        best = smaller_board(paper, PAGE_SIZES[page], "auto", MARGIN)
        assert best is not None and best.pitch == paper.pitch and best.diameter == paper.diameter
        assert page_refusal(best, page) is None
        # No board of more dots, within the asked 14 x 10 at the same pitch, fits.
        for cols in range(2, paper.cols + 1):
            for rows in range(2, paper.rows + 1):
                if cols * rows > best.cols * best.rows:
                    bigger = CircleGridBoard(cols, rows, 20.0, 10.0, origin_marker=True)
                    assert page_refusal(bigger, page) is not None, (cols, rows)
    assert smaller_board(paper, PAGE_SIZES["A3"], "auto", MARGIN) is None  # it fits A3


def test_smaller_board_shrinks_the_pitch_only_when_no_dots_fit_at_it() -> None:
    huge = CircleGridBoard(cols=3, rows=3, pitch=200.0, diameter=100.0, origin_marker=True)
    assert page_refusal(CircleGridBoard(2, 2, 200.0, 100.0, origin_marker=True), "A4")
    best = smaller_board(huge, PAGE_SIZES["A4"], "auto", MARGIN)
    assert best is not None and (best.cols, best.rows) == (3, 3)
    assert best.pitch < 200.0 and best.pitch % 0.5 == 0
    assert best.diameter == pytest.approx(best.pitch / 2)  # the dots scaled with it
    assert page_refusal(best, "A4") is None
    coarser = CircleGridBoard(3, 3, best.pitch + 0.5, (best.pitch + 0.5) / 2, origin_marker=True)
    assert page_refusal(coarser, "A4") is not None  # the largest such pitch
    # A page too small for the check bar holds no board at all: no offer, a larger page.
    message = page_refusal(huge, "40x40")
    assert message is not None and "smaller board" not in message and "larger page" in message


# --------------------------------------------------------------------------- the demo


def test_demo_ends_with_where_the_figures_are_and_what_to_run_next() -> None:
    result = _run("demo")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.rstrip("\n").splitlines()
    assert lines[-len(NEXT_STEPS) :] == list(NEXT_STEPS)
    assert lines[-len(NEXT_STEPS) - 1] == (
        "To see the figures and the images: planarcal demo --report demo-report"
    )
    steps = "\n".join(NEXT_STEPS)
    for command in ("planarcal board", "planarcal calibrate", "planarcal locate", "planarcal run"):
        assert command in steps


def test_demo_report_writes_the_figures_images_and_calibration(tmp_path: Path) -> None:
    result = _run("demo", "--report", "demo-report", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    folder = tmp_path / "demo-report"
    lines = result.stdout.rstrip("\n").splitlines()
    assert lines[-len(NEXT_STEPS) :] == list(NEXT_STEPS)
    wrote = lines[-len(NEXT_STEPS) - 1]
    assert wrote.startswith("Wrote to demo-report: ")
    names = wrote.removeprefix("Wrote to demo-report: ").split(", ")
    assert sorted(names) == sorted(p.name for p in folder.iterdir())
    pictures = {
        "board.png": (720, 1280),
        "objects.png": (720, 1280),
        "located.png": (720, 1280),
        "detection.png": None,
        "deviations.png": None,
        "lens.png": None,
        "uncertainty.png": None,
    }
    for name, shape in pictures.items():
        image = cv2.imread(str(folder / name))
        assert image is not None, name
        if shape is not None:
            assert image.shape[:2] == shape, name
    # The objects drawn: the located image differs from the rendered one.
    assert np.any(
        cv2.imread(str(folder / "located.png")) != cv2.imread(str(folder / "objects.png"))
    )
    # The calibration saved is the one the demo made: it finds the board's dots in mm.
    cal = Calibration.load(folder / "calib.json")
    board = cv2.imread(str(folder / "board.png"), cv2.IMREAD_GRAYSCALE)
    assert cal.board is not None
    found = detect_board(board, cal.board)
    mm = cal.image_to_world(found.image_points)
    assert np.abs(mm - cal.board.world_points()).max() < 0.05
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["n_points"] == 140
    assert (folder / "points.csv").read_text().count("\n") == 141  # a header, a row a dot


def test_demo_report_into_a_file_fails_in_one_line(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    result = _run("demo", "--report", blocker / "report")
    assert result.returncode == 1
    assert "Traceback" not in result.stderr and len(result.stderr.splitlines()) == 1
    assert blocker.read_text() == ""


# --------------------------------------------------------------------------- the summary


@pytest.fixture(scope="module")
def calibration() -> Calibration:
    scene = synth.paper_scene(seed=3, objects=False)
    board = scene.calibration.board
    assert board is not None
    return Calibration.from_detection(detect_board(scene.calibration.image, board))


def test_printing_the_summary_prints_its_figures(calibration: Calibration) -> None:
    summary = calibration.summary()
    text = str(summary)
    # A few lines made by the calibration itself (the model layer imports no report); the
    # calibrate command's full text is the report layer's summary_text.
    assert f"RMS {summary.rms_px:.4f}" in text and f"{summary.n_points} of its" in text
    assert text != summary_text(calibration) and f"RMS {summary.rms_px:.3f}" in summary_text(
        calibration
    )
    # The figures stay the dataclass's: fields, dict, equality and repr.
    assert "_calibration" not in summary.to_dict()
    assert summary.to_dict()["rms_px"] == summary.rms_px
    assert summary == calibration.summary()
    assert repr(summary).startswith("CalibrationSummary(n_points=140, ")
    again = pickle.loads(pickle.dumps(summary))
    assert again == summary and str(again) == text


def test_a_summary_made_by_hand_prints_its_fields() -> None:
    nan = float("nan")
    summary = CalibrationSummary(
        n_points=4,
        solver="normalized_dlt",
        refine=True,
        mean_px=0.5,
        rms_px=0.5,
        max_px=0.5,
        min_px=0.5,
        max_abs_dx_mm=0.1,
        max_abs_dy_mm=0.1,
        loo_mean_mm=nan,
        loo_rms_mm=nan,
        loo_max_mm=nan,
    )
    assert str(summary) == repr(summary)
