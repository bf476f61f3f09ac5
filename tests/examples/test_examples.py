"""The examples in examples/, each run as a user runs it (``python examples/x.py``, a real
subprocess) with small sizes, and what it prints or writes checked against the truth of the
scenes it renders: the parts' mm within tolerance, the controller's parts received over a
real socket, the batch CSV row for row, the drop-in's homography. The Dask example runs on a
real local cluster of 2 worker processes, and once more against a scheduler the test starts,
as it would against a real one."""

from __future__ import annotations

import csv
import importlib.util
import re
import subprocess
import sys
from collections import defaultdict
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from distributed import LocalCluster

from planarcal import synth
from planarcal.calib.calibration import Calibration

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
TIMEOUT_S = 300  # a deadline for a hung example; each takes seconds


def run_example(name: str, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(EXAMPLES / name), *args],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        cwd=cwd,
        check=False,
    )


def load_example(name: str) -> ModuleType:
    """An example's module, for its constants (its main does not run)."""
    spec = importlib.util.spec_from_file_location(name.removesuffix(".py"), EXAMPLES / name)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def nearest_mm(point: tuple[float, float], truth: np.ndarray) -> float:
    return float(np.hypot(*(truth - np.asarray(point)).T).min())


# A located part's row: "  3 bolt     37.269    71.987   0.0172   20.0   0.0332 mm".
PART_ROW = re.compile(
    r"^\s*(\d+) (nut|bolt)\s+([-\d.]+)\s+([-\d.]+)\s+([\d.]+)\s+(\S+)\s+([\d.]+) mm$"
)


def test_calibrate_and_locate_finds_every_part_within_tolerance(tmp_path: Path) -> None:
    saved = tmp_path / "calib.json"
    done = run_example("calibrate_and_locate.py", "--save", str(saved))
    assert done.returncode == 0, done.stdout + done.stderr
    rows = [PART_ROW.match(line) for line in done.stdout.splitlines()]
    parts = [m for m in rows if m is not None]
    truth = np.array([o.position_mm for o in synth.PAPER_OBJECTS])
    assert len(parts) == len(truth)
    for m in parts:
        x, y, sigma = float(m[3]), float(m[4]), float(m[5])
        # The printed position against the scene's truth, not against the example's check.
        assert nearest_mm((x, y), truth) < 0.1
        assert 0.005 < sigma < 0.05
    assert sum(m[2] == "bolt" for m in parts) == 3
    assert done.stdout.rstrip().endswith("PASS")
    loaded = Calibration.load(saved)
    assert len(loaded.world_points) == synth.PAPER_BOARD.n_points


def test_calibrate_and_locate_fails_when_the_parts_are_off(tmp_path: Path) -> None:
    # Tighter than any real error: the example's check must then say so and exit 1.
    done = run_example("calibrate_and_locate.py", "--tolerance-mm", "0.0001")
    assert done.returncode == 1
    assert "FAIL: a part lies" in done.stdout


def test_opencv_dropin_gives_a_homography_close_to_the_truth() -> None:
    done = run_example("opencv_dropin.py")
    assert done.returncode == 0, done.stdout + done.stderr
    errors = dict(re.findall(r"^(cv2|planarcal)\s+\d+\s+([\d.]+) px$", done.stdout, re.M))
    assert set(errors) == {"cv2", "planarcal"}
    assert float(errors["planarcal"]) < 1.0
    assert "not a drop-in" not in done.stdout
    assert "With 3 matches, planarcal: caught planarcal.errors" in done.stdout


# A part the controller received: "frame  12  part  3  at (  27.287,   71.987) mm +- ...".
RECEIVED = re.compile(r"^frame\s+(\d+)\s+part\s+(\d+)\s+at \(\s*([-\d.]+),\s*([-\d.]+)\) mm")


@pytest.mark.parametrize("mode", [[], ["--trigger"]], ids=["stream", "trigger"])
def test_robot_client_reads_parts_over_tcp(mode: list[str]) -> None:
    done = run_example("robot_tcp_client.py", "--parts", "25", *mode)
    assert done.returncode == 0, done.stdout + done.stderr
    received = [m for m in map(RECEIVED.match, done.stdout.splitlines()) if m is not None]
    assert len(received) >= 25
    # Where each part was on that frame: the example's video holds each position of the
    # paper's parts for HOLD_FRAMES frames, moving them STEP_MM along x between positions.
    example = load_example("robot_tcp_client.py")
    paper = np.array([o.position_mm for o in synth.PAPER_OBJECTS])
    frames = defaultdict(list)
    for m in received:
        frame = int(m[1])
        shift = example.STEP_MM * (frame // example.HOLD_FRAMES - example.RENDERS / 2)
        assert nearest_mm((float(m[3]), float(m[4])), paper + np.array([shift, 0.0])) < 0.15
        frames[frame].append(int(m[2]))
    # Whole lines: every frame read has all ten parts, each id once.
    assert all(sorted(ids) == list(range(1, 11)) for ids in frames.values())


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as rows:
        return list(csv.DictReader(rows))


def check_batch_csv(parts_csv: Path, truth_csv: Path) -> None:
    """The batch CSV: every rendered image, with one row per part placed, each at its place."""
    truth: dict[str, list[tuple[float, float]]] = defaultdict(list)
    for row in read_csv(truth_csv):
        truth[Path(row["image"]).name].append((float(row["x_mm"]), float(row["y_mm"])))
    found: dict[str, list[dict[str, str]]] = defaultdict(list)
    for row in read_csv(parts_csv):
        found[Path(row["image"]).name].append(row)
    assert set(found) == set(truth)
    for image, rows in found.items():
        assert len(rows) == len(truth[image])
        assert sorted(int(row["part"]) for row in rows) == list(range(1, len(rows) + 1))
        for row in rows:
            point = (float(row["x_mm"]), float(row["y_mm"]))
            assert nearest_mm(point, np.array(truth[image])) < 0.15
            assert 0.0 < float(row["std_mm"]) < 0.1


def test_batch_dask_on_a_local_cluster_then_on_a_scheduler(tmp_path: Path) -> None:
    work = tmp_path / "work"
    done = run_example(
        "batch_dask.py",
        *("--count", "6", "--workers", "2", "--workdir", str(work)),
        *("--csv", str(tmp_path / "parts.csv")),
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "on a local cluster of 2 workers" in done.stdout
    check_batch_csv(tmp_path / "parts.csv", work / "truth.csv")

    # The same code against a scheduler's address, on the user's images and calibration file.
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None)  # type: ignore[no-untyped-call]
    with cluster:
        address = cluster.scheduler_address
        again = run_example(
            "batch_dask.py",
            *("--images", str(work / "parts-*.png"), "--calibration", str(work / "calib.json")),
            *("--scheduler", address, "--csv", str(tmp_path / "again.csv")),
        )
    assert again.returncode == 0, again.stdout + again.stderr
    assert f"on {address}" in again.stdout
    assert read_csv(tmp_path / "again.csv") == read_csv(tmp_path / "parts.csv")


def test_batch_dask_scaling_prints_the_table_and_draws_the_figure(tmp_path: Path) -> None:
    figure = tmp_path / "scaling.png"
    done = run_example(
        "batch_dask.py",
        *("--count", "4", "--repeats", "1", "--scaling", "1,2", "--figure", str(figure)),
    )
    assert done.returncode == 0, done.stdout + done.stderr
    rows = re.findall(r"^\| (\d) \| ([\d.]+) \|", done.stdout, re.M)
    assert [workers for workers, _ in rows] == ["1", "2"]
    assert all(float(rate) > 0 for _, rate in rows)
    assert figure.read_bytes().startswith(b"\x89PNG")
