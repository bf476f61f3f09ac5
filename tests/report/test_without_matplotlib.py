"""matplotlib is the optional extra `planarcal[report]`: without it every command runs except
the figures, which are refused up front with one line naming the extra; with it, drawing a
report never changes the host's matplotlib backend. Each case runs in a real subprocess, where
matplotlib is made unimportable by a package of its name, first on the path, that fails to
import exactly as an absent one does."""

from __future__ import annotations

import json
import os
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
from planarcal.report.figure import MATPLOTLIB_MISSING

BOARD_ARGS = ["--cols", "14", "--rows", "10", "--pitch", "20", "--diameter", "10"]
# The working tree's planarcal, whichever one the test process imported.
PACKAGE_ROOT = Path(planarcal.__file__).resolve().parents[1]
IMPORTS = "planarcal, planarcal.cli, planarcal.live, planarcal.calib, planarcal.synth"


def _blocker(root: Path, missing: str) -> Path:
    """A directory holding a `matplotlib` package that raises what Python raises when the
    module `missing` is absent (matplotlib itself, or one of its own dependencies)."""
    package = root / f"without_{missing}" / "matplotlib"
    package.mkdir(parents=True, exist_ok=True)
    (package / "__init__.py").write_text(
        f"raise ModuleNotFoundError({f'No module named {missing!r}'!r}, name={missing!r})\n"
    )
    return package.parent


@pytest.fixture(scope="module")
def no_matplotlib(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _blocker(tmp_path_factory.mktemp("blockers"), "matplotlib")


def _python(
    *args: str | Path,
    blocked: Path | None,
    cwd: Path | None = None,
    env: dict[str, str] | None = None,
) -> subprocess.CompletedProcess[str]:
    """`python ARGS` on the working tree's planarcal; with `blocked` (a blocker directory)
    first on the path, matplotlib cannot be imported."""
    path = [str(PACKAGE_ROOT), os.environ.get("PYTHONPATH", "")]
    if blocked is not None:
        path.insert(0, str(blocked))
    full_env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in path if p), **(env or {})}
    return subprocess.run(
        [sys.executable, *map(str, args)],
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
        cwd=cwd,
        env=full_env,
    )


def _planarcal(
    *args: str | Path, blocked: Path | None, cwd: Path | None = None
) -> subprocess.CompletedProcess[str]:
    return _python("-m", "planarcal", *args, blocked=blocked, cwd=cwd)


def _script_result(result: subprocess.CompletedProcess[str]) -> Any:
    """The JSON a `python -c` script printed last."""
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def images(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    scene = synth.paper_scene(seed=7)
    d = tmp_path_factory.mktemp("images")
    paths = {"board": d / "board.png", "objects": d / "objects.png", "blank": d / "blank.png"}
    cv2.imwrite(str(paths["board"]), scene.calibration.image)
    cv2.imwrite(str(paths["objects"]), scene.objects.image)
    cv2.imwrite(str(paths["blank"]), np.full((480, 640), 200, np.uint8))
    return paths


@pytest.fixture(scope="module")
def calibrated(
    images: dict[str, Path], no_matplotlib: Path, tmp_path_factory: pytest.TempPathFactory
) -> tuple[subprocess.CompletedProcess[str], Path]:
    """`planarcal calibrate` without matplotlib, and the calibration file it was asked for."""
    calib = tmp_path_factory.mktemp("calibrated") / "calib.json"
    result = _planarcal(
        "calibrate", images["board"], *BOARD_ARGS, "-o", calib, blocked=no_matplotlib
    )
    return result, calib


# ------------------------------------------------------------------------------------------
# importing


def test_importing_planarcal_loads_no_matplotlib() -> None:
    # matplotlib is installed here: nothing may load it before a figure is drawn.
    script = f"import json, sys, {IMPORTS}; print(json.dumps(sorted(sys.modules)))"
    loaded = _script_result(_python("-c", script, blocked=None))
    assert "planarcal.cli" in loaded and "planarcal.live" in loaded
    assert [m for m in loaded if m.split(".")[0] == "matplotlib"] == []


def test_planarcal_imports_without_matplotlib(no_matplotlib: Path) -> None:
    script = (
        f"import json, {IMPORTS}, planarcal.report\n"
        "try:\n    import matplotlib\nexcept ImportError as e:\n    blocked = str(e)\n"
        "else:\n    blocked = None\n"
        "error = planarcal.MissingDependencyError.__name__\n"
        "print(json.dumps({'blocked': blocked, 'error': error}))"
    )
    seen = _script_result(_python("-c", script, blocked=no_matplotlib))
    assert seen == {"blocked": "No module named 'matplotlib'", "error": "MissingDependencyError"}


# ------------------------------------------------------------------------------------------
# the commands without matplotlib


def test_demo_runs_without_matplotlib(no_matplotlib: Path, tmp_path: Path) -> None:
    result = _planarcal("demo", blocked=no_matplotlib, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "Found all 140 dots" in result.stdout
    assert "Traceback" not in result.stderr
    # Its hint to see the figures says what they need.
    assert "demo --report demo-report (after: pip install 'planarcal[report]')" in result.stdout


@pytest.mark.parametrize("suffix", [".pdf", ".svg"])
def test_board_prints_without_matplotlib(no_matplotlib: Path, tmp_path: Path, suffix: str) -> None:
    out = tmp_path / f"board{suffix}"
    result = _planarcal("board", "-o", out, blocked=no_matplotlib)
    assert result.returncode == 0, result.stderr
    assert out.read_bytes().startswith(b"%PDF" if suffix == ".pdf" else b"<?xml")


def test_demo_report_is_refused_up_front_naming_the_extra(
    no_matplotlib: Path, tmp_path: Path
) -> None:
    report = tmp_path / "demo-report"
    start = time.perf_counter()
    result = _planarcal("demo", "--report", report, blocked=no_matplotlib, cwd=tmp_path)
    took = time.perf_counter() - start
    assert result.returncode == 2
    assert result.stderr == f"planarcal demo: error: {MATPLOTLIB_MISSING}\n"
    assert "pip install 'planarcal[report]'" in result.stderr
    assert result.stdout == ""  # no scene rendered, nothing calibrated
    assert not report.exists()
    assert took < 60


def test_calibrate_report_is_refused_before_the_image_is_read(
    no_matplotlib: Path, tmp_path: Path
) -> None:
    # The image does not exist: without the up-front check this fails with status 1 on it.
    report = tmp_path / "report"
    result = _planarcal(
        "calibrate",
        tmp_path / "no-such-photo.png",
        "-o",
        tmp_path / "calib.json",
        "--report",
        report,
        blocked=no_matplotlib,
    )
    assert result.returncode == 2
    assert result.stderr == f"planarcal calibrate: error: {MATPLOTLIB_MISSING}\n"
    assert not report.exists() and not (tmp_path / "calib.json").exists()


def test_calibrate_without_report_works_without_matplotlib(
    calibrated: tuple[subprocess.CompletedProcess[str], Path],
) -> None:
    result, calib = calibrated
    assert result.returncode == 0, result.stderr
    assert f"Saved the calibration to {calib}" in result.stdout
    cal = planarcal.Calibration.load(calib)
    assert len(cal.world_points) == 140 and cal.stats.mean < 0.1


def test_calibrate_json_works_without_matplotlib(
    images: dict[str, Path], no_matplotlib: Path, tmp_path: Path
) -> None:
    calib = tmp_path / "calib.json"
    result = _planarcal(
        "calibrate", images["board"], *BOARD_ARGS, "-o", calib, "--json", blocked=no_matplotlib
    )
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout)
    assert out["calibration_file"] == str(calib) and "report_files" not in out


def test_board_not_found_fails_in_one_line_without_matplotlib(
    images: dict[str, Path], no_matplotlib: Path, tmp_path: Path
) -> None:
    result = _planarcal(
        "calibrate",
        images["blank"],
        *BOARD_ARGS,
        "-o",
        tmp_path / "calib.json",
        blocked=no_matplotlib,
    )
    assert result.returncode == 1
    assert result.stderr.startswith("planarcal calibrate: error: ")
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert not (tmp_path / "calib.json").exists()


def test_locate_and_run_work_without_matplotlib(
    calibrated: tuple[subprocess.CompletedProcess[str], Path],
    images: dict[str, Path],
    no_matplotlib: Path,
    tmp_path: Path,
) -> None:
    _, calib = calibrated
    annotated = tmp_path / "located.png"
    result = _planarcal(
        "locate",
        images["objects"],
        "--calibration",
        calib,
        "--annotate",
        annotated,
        "--json",
        blocked=no_matplotlib,
    )
    assert result.returncode == 0, result.stderr
    assert len(json.loads(result.stdout)["objects"]) == 10
    assert cv2.imread(str(annotated)) is not None  # drawn with OpenCV, not matplotlib

    folder = tmp_path / "frames"
    folder.mkdir()
    (folder / "0001.png").write_bytes(images["objects"].read_bytes())
    result = _planarcal(
        "run",
        "--source",
        folder,
        "--calibration",
        calib,
        "--max-frames",
        "1",
        blocked=no_matplotlib,
    )
    assert result.returncode == 0, result.stderr
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    assert len(lines) == 1 and len(lines[0]["objects"]) == 10


def test_a_broken_matplotlib_is_named_as_such(
    tmp_path: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    # Installed, but one of its own dependencies is missing: not "not installed".
    broken = _blocker(tmp_path_factory.mktemp("broken"), "pyparsing")
    result = _planarcal(
        "calibrate",
        tmp_path / "photo.png",
        "-o",
        tmp_path / "calib.json",
        "--report",
        tmp_path / "report",
        blocked=broken,
    )
    assert result.returncode == 2
    assert result.stderr == (
        "planarcal calibrate: error: the report's figures need matplotlib, which is installed "
        "but cannot be imported (No module named 'pyparsing'): pip install --force-reinstall "
        "matplotlib\n"
    )


# ------------------------------------------------------------------------------------------
# the Python API without matplotlib

_FIGURES_WITHOUT_MATPLOTLIB = """
import json, sys
from pathlib import Path
import cv2
import planarcal
from planarcal import report

cal = planarcal.Calibration.load(sys.argv[1])
image = cv2.imread(sys.argv[2])
out = Path(sys.argv[3])
seen = {}
calls = {
    "write_report": lambda: report.write_report(cal, out / "report", image=image),
    "write_detection_failure": lambda: report.write_detection_failure(
        out / "failed", image, None, "no board"
    ),
    "deviation_figure": lambda: report.deviation_figure(cal),
    "lens_figure": lambda: report.lens_figure(cal),
    "uncertainty_figure": lambda: report.uncertainty_figure(cal),
    "detection_failure_figure": lambda: report.detection_failure_figure(image, None, "x"),
}
for name, call in calls.items():
    try:
        call()
    except planarcal.MissingDependencyError as e:
        seen[name] = {
            "message": str(e),
            "name": e.name,
            "import_error": isinstance(e, ImportError),
            "planarcal_error": isinstance(e, planarcal.Error),
        }
    else:
        seen[name] = "drawn"
# The tables need no matplotlib.
seen["csv_rows"] = len(report.points_csv(cal).splitlines())
seen["written"] = sorted(p.name for p in out.iterdir())
print(json.dumps(seen))
"""


def test_the_report_writers_raise_missing_dependency_error(
    calibrated: tuple[subprocess.CompletedProcess[str], Path],
    images: dict[str, Path],
    no_matplotlib: Path,
    tmp_path: Path,
) -> None:
    _, calib = calibrated
    script = _FIGURES_WITHOUT_MATPLOTLIB
    seen = _script_result(
        _python("-c", script, calib, images["board"], tmp_path, blocked=no_matplotlib)
    )
    refusal = {
        "message": MATPLOTLIB_MISSING,
        "name": "matplotlib",
        "import_error": True,
        "planarcal_error": True,
    }
    for name in (
        "write_report",
        "write_detection_failure",
        "deviation_figure",
        "lens_figure",
        "uncertainty_figure",
        "detection_failure_figure",
    ):
        assert seen[name] == refusal, name
    assert seen["csv_rows"] == 141  # the header and 140 points
    assert seen["written"] == []  # refused before anything was written: no half report


# ------------------------------------------------------------------------------------------
# with matplotlib: the host's backend is left alone

_DRAW_UNDER_A_BACKEND = """
import json, sys
from pathlib import Path
import cv2
import matplotlib
import planarcal
from planarcal import report

before = matplotlib.get_backend()
cal = planarcal.Calibration.load(sys.argv[1])
image = cv2.imread(sys.argv[2])
out = Path(sys.argv[3])
written = report.write_report(cal, out, image=image)
written.append(report.write_detection_failure(out, image, None, "no board"))
print(json.dumps({
    "before": before,
    "after": matplotlib.get_backend(),
    "rc_backend": matplotlib.rcParams["backend"],
    "pyplot": "matplotlib.pyplot" in sys.modules,
    "written": sorted(Path(p).name for p in written),
    "png": all(Path(p).read_bytes().startswith(bytes([0x89]) + b"PNG")
               for p in written if str(p).endswith(".png")),
}))
"""


@pytest.mark.parametrize("backend", ["svg", "pdf"])
def test_drawing_the_report_leaves_the_hosts_backend_alone(
    calibrated: tuple[subprocess.CompletedProcess[str], Path],
    images: dict[str, Path],
    tmp_path: Path,
    backend: str,
) -> None:
    _, calib = calibrated
    result = _python(
        "-c",
        _DRAW_UNDER_A_BACKEND,
        calib,
        images["board"],
        tmp_path,
        blocked=None,
        env={"MPLBACKEND": backend},
    )
    seen = _script_result(result)
    assert seen["before"] == seen["after"] == seen["rc_backend"] == backend
    assert seen["pyplot"] is False  # the OO API alone: pyplot's state is never touched
    assert seen["written"] == [
        "coverage.png",
        "detection_failed.png",
        "deviations.png",
        "lens.png",
        "points.csv",
        "summary.json",
        "uncertainty.png",
    ]
    assert seen["png"] is True
