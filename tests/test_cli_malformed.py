"""The command line a user meets when it is wrong: a malformed command line exits 2 in one
line naming the option, a job that fails on its data exits 1, and the messages name commands
and options, never Python calls."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import pytest

import planarcal
from planarcal import synth
from test_cli import _run

# Words of the Python API that must not reach a user of the command line.
API_WORDS = (
    "for_frame_size",
    "Calibration.register",
    "read()",
    "intrinsics=",
    "load_yaml",
    "calibrate_camera",
    "frame=",
    "Traceback",
)


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A board image, an objects image (and a smaller copy), a calibration made from the
    first, and a plain file."""
    d = tmp_path_factory.mktemp("files")
    scene = synth.paper_scene(seed=7)
    paths = {
        "board": d / "board.png",
        "objects": d / "objects.png",
        "small": d / "small.png",
        "cal": d / "cal.json",
        "file": d / "notes.txt",
    }
    cv2.imwrite(str(paths["board"]), scene.calibration.image)
    cv2.imwrite(str(paths["objects"]), scene.objects.image)
    cv2.imwrite(str(paths["small"]), cv2.resize(scene.objects.image, (640, 360)))
    paths["file"].write_text("not a directory\n")
    made = _run("calibrate", paths["board"], "-o", paths["cal"])
    assert made.returncode == 0, made.stderr
    return paths


def _one_line(stderr: str) -> str:
    lines = stderr.splitlines()
    assert len(lines) == 1, stderr
    return lines[0]


# (command line with {board}, {objects}, {cal}, {file}, {out} to fill in; what the line says)
MALFORMED = [
    (["board", "--pitch", "-1", "-o", "{out}.svg"], "--pitch"),
    (["board", "--pitch", "nan", "-o", "{out}.svg"], "--pitch"),
    (["board", "--cols", "0", "-o", "{out}.svg"], "cols must be between 2 and"),
    (["board", "--page", "B7", "-o", "{out}.svg"], "unknown page 'B7'"),
    (["board", "--margin", "-5", "-o", "{out}.svg"], "--margin"),
    (["board", "-o", "{out}.txt"], ".svg or .pdf"),
    (["calibrate", "{board}", "--frames", "0", "-o", "{out}"], "--frames"),
    (["calibrate", "{board}", "--check-bar", "-3", "-o", "{out}"], "--check-bar"),
    (["calibrate", "{board}", "--measured-pitch", "20,-1", "-o", "{out}"], "--measured-pitch"),
    (["calibrate", "{board}", "--rows", "1", "-o", "{out}"], "rows must be between 2 and"),
    (
        ["calibrate", "{board}", "--pitch", "5", "--diameter", "10", "-o", "{out}"],
        "diameter must be smaller",
    ),
    (["calibrate", "-o", "{out}"], "give an IMAGE"),
    (["calibrate", "{board}", "--camera", "0", "-o", "{out}"], "not both"),
    (["calibrate", "{board}", "--frames", "5", "-o", "{out}"], "--frames goes with --camera"),
    (["intrinsics", "{board}", "-o", "{out}.yaml"], "at least 3 images"),
    (["intrinsics", "{board}", "--marker-diameter", "-2", "-o", "{out}"], "--marker-diameter"),
    (
        ["register", "--calibration", "{cal}", "--points", "{file}", "-o", "{out}", "--model", "x"],
        "--model",
    ),
    (
        [
            "register",
            "--calibration",
            "{cal}",
            "--points",
            "{file}",
            "-o",
            "{out}",
            "--outlier-mm",
            "-1",
        ],
        "--outlier-mm",
    ),
    (["locate", "{objects}", "--calibration", "{cal}", "--min-area", "-4"], "--min-area"),
    (["locate", "{objects}", "--calibration", "{cal}", "--height", "inf"], "--height"),
    (["locate", "{objects}", "--calibration", "{cal}", "--frame", "world"], "--frame"),
    (["locate", "{objects}", "--calibration", "{cal}", "--annotate", "{out}.jpg"], "--annotate"),
    (["run", "--source", "{objects}", "--calibration", "{cal}", "-o", "tcp://host"], "no port"),
    (["run", "--source", "{objects}", "--calibration", "{cal}", "-o", "ftp://h:1"], "ftp"),
    (
        ["run", "--source", "{objects}", "--calibration", "{cal}", "--max-frames", "0"],
        "--max-frames",
    ),
    (
        ["run", "--source", "{objects}", "--calibration", "{cal}", "--max-reconnect", "-1"],
        "--max-reconnect",
    ),
    (["run", "--source", "{objects}", "--calibration", "{cal}", "--trigger"], "--trigger"),
    (["demo", "--report", "{file}"], "--report"),
    (["bogus"], "invalid choice: 'bogus'"),
]


@pytest.mark.parametrize(
    ("argv", "says"), MALFORMED, ids=[" ".join(a[:1] + a[-2:]) for a, _ in MALFORMED]
)
def test_a_malformed_command_line_exits_2_in_one_line(
    argv: list[str], says: str, files: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "out"
    filled = [a.format(out=out, **files) for a in argv]
    result = _run(*filled)
    assert result.returncode == 2, (filled, result.stderr)
    line = _one_line(result.stderr)
    prog = "planarcal" if argv[0] == "bogus" else f"planarcal {argv[0]}"
    assert line.startswith(f"{prog}: error: "), line
    assert says in line, line
    assert not any(word in line for word in API_WORDS), line
    assert list(tmp_path.iterdir()) == []  # nothing written
    assert result.stdout == ""


# (command line; what the line says; what it must not say)
DATA_FAILURES = [
    (["calibrate", "{objects}", "-o", "{out}"], "no 14 x 10 circle grid"),
    (["locate", "{objects}", "--calibration", "{file}"], "not valid JSON"),
    (
        ["locate", "{objects}", "--calibration", "{cal}", "--height", "5"],
        "'planarcal intrinsics'",
    ),
    (["run", "--source", "{objects}", "--calibration", "{cal}", "--height", "5"], "--intrinsics"),
    (["locate", "{objects}", "--calibration", "{cal}", "--frame", "robot"], "planarcal register"),
    (
        ["run", "--source", "{objects}", "--calibration", "{cal}", "--frame", "robot"],
        "planarcal register --calibration",
    ),
    (["locate", "{small}", "--calibration", "{cal}"], "'planarcal calibrate'"),
    (["run", "--source", "{small}", "--calibration", "{cal}"], "this frame is 640 x 360 px"),
]


@pytest.mark.parametrize(
    ("argv", "says"), DATA_FAILURES, ids=[" ".join(a[:1] + a[-2:]) for a, _ in DATA_FAILURES]
)
def test_a_job_that_fails_on_its_data_exits_1_in_the_cli_s_words(
    argv: list[str], says: str, files: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "out"
    filled = [a.format(out=out, **files) for a in argv]
    result = _run(*filled)
    assert result.returncode == 1, (filled, result.stderr)
    line = _one_line(result.stderr)
    assert line.startswith(f"planarcal {argv[0]}: error: ") and says in line, line
    assert not any(word in line for word in API_WORDS), line
    assert not out.exists()


def test_height_without_intrinsics_names_the_commands_that_give_them(
    files: dict[str, Path],
) -> None:
    result = _run("locate", files["objects"], "--calibration", files["cal"], "--height", "5")
    line = _one_line(result.stderr)
    assert "--height 5" in line
    assert "planarcal intrinsics" in line and "planarcal calibrate --intrinsics" in line


def test_the_api_keeps_its_own_words(files: dict[str, Path]) -> None:
    """The CLI rewords; a Python user still reads the calls to make."""
    cal = planarcal.Calibration.load(files["cal"])
    with pytest.raises(planarcal.IntrinsicsError, match="calibrate_camera"):
        cal.image_to_world([[600.0, 300.0]], height=5.0)
    small = cv2.imread(str(files["small"]))
    with pytest.raises(planarcal.FrameSizeError, match=r"for_frame_size\(640, 360\)"):
        planarcal.locate_objects(small, cal)
    with pytest.raises(planarcal.ArgumentError, match=r"Calibration\.register"):
        planarcal.locate_objects(cv2.imread(str(files["objects"])), cal, frame="robot")


def test_a_run_s_json_summary_still_parses(files: dict[str, Path]) -> None:
    """The checks before the loop leave a good run as it was."""
    result = _run("run", "--source", files["objects"], "--calibration", files["cal"])
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["coords"] == "board"
