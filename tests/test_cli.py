"""Every `planarcal` command, run as a user runs it, its output and its files checked."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

import planarcal
from planarcal import synth
from planarcal.cli import _out_of_memory, build_parser

BOARD_ARGS = ["--cols", "14", "--rows", "10", "--pitch", "20", "--diameter", "10"]


def _run(*args: str | Path, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "planarcal", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=cwd,
    )


@pytest.fixture(scope="module")
def scene() -> synth.PaperScene:
    return synth.paper_scene(seed=7)


@pytest.fixture(scope="module")
def images(scene: synth.PaperScene, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("images")
    paths = {"board": d / "board.png", "objects": d / "objects.png"}
    cv2.imwrite(str(paths["board"]), scene.calibration.image)
    cv2.imwrite(str(paths["objects"]), scene.objects.image)
    return paths


# ------------------------------------------------------------------------------------------
# demo


@pytest.mark.parametrize("console_script", [True, False], ids=["console-script", "python-m"])
def test_demo_runs_the_whole_pipeline_on_a_rendered_scene(console_script: bool) -> None:
    if console_script:
        exe = shutil.which("planarcal")
        if exe is None:
            pytest.fail("the planarcal console script is not installed on PATH")
        result = subprocess.run([exe, "demo"], capture_output=True, text=True, timeout=120)
    else:
        result = _run("demo")
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "Found all 140 dots" in out
    m = re.search(r"Dot centres against the truth: ([0-9.]+) px RMS", out)
    assert m and float(m.group(1)) < 0.05
    m = re.search(r"mean ([0-9.]+), RMS [0-9.]+, max ([0-9.]+)", out)
    assert m and float(m.group(1)) < 0.05  # the lens model removes the distortion
    m = re.search(r"A homography alone \(the paper's model\): mean ([0-9.]+) px", out)
    assert m and 0.2 < float(m.group(1)) < 1.0  # the lens's distortion, like the paper's
    m = re.search(r"against the truth, with the lens model: ([0-9.]+) mm mean", out)
    assert m and float(m.group(1)) < 0.02
    m = re.search(r"against the truth, a homography alone: ([0-9.]+) mm mean", out)
    assert m and float(m.group(1)) > 0.1
    rows = [line for line in out.splitlines() if re.match(r"\s+ID:\d+ ", line)]
    assert len(rows) == 10
    # ... error "mm", 1-sigma, angle, true angle
    fields = [line.split() for line in rows]
    errors = [float(f[f.index("mm") - 1]) for f in fields]
    assert max(errors) < 0.1  # every object within 0.1 mm of where it really is
    sigmas = [float(f[f.index("mm") + 1]) for f in fields]
    assert 0.5 < np.sqrt(np.mean(np.square(errors))) / np.sqrt(np.mean(np.square(sigmas))) < 2
    for f in fields:
        if f[1] == "bolt":  # an axis, within half a degree of the truth
            assert abs(float(f[-2]) - float(f[-1])) < 0.5, f
        else:  # nuts are too round for one
            assert f[-2:] == ["-", "-"], f
    assert "Located within" in out
    m = re.search(r"Parts in robot mm within [0-9.]+ mm .* ([0-9.]+) mm at worst", out)
    assert m and float(m.group(1)) < 0.2
    m = re.search(r"the bolts' angles within ([0-9.]+) degree", out)
    assert m and float(m.group(1)) < 0.5


def test_no_command_prints_usage_and_fails() -> None:
    result = _run()
    assert result.returncode == 2
    assert "usage: planarcal" in result.stderr


def test_version() -> None:
    result = _run("--version")
    assert result.returncode == 0
    assert result.stdout.strip() == f"planarcal {planarcal.__version__}"


# ------------------------------------------------------------------------------------------
# board


@pytest.mark.parametrize("suffix", ["svg", "pdf"])
def test_board_writes_a_printable_file(tmp_path: Path, suffix: str) -> None:
    out = tmp_path / f"board.{suffix}"
    result = _run("board", *BOARD_ARGS, "-o", out)
    assert result.returncode == 0, result.stderr
    assert "A3 landscape" in result.stdout  # the paper's board needs A3 (auto page)
    assert "100 mm" in result.stdout
    data = out.read_bytes()
    if suffix == "svg":
        assert b'width="420mm"' in data and b'height="297mm"' in data
        assert data.count(b"<circle") == 140
    else:
        assert data.startswith(b"%PDF")
        assert re.search(rb"/MediaBox \[0 0 1190\.55\d* 841\.889\d*\]", data)


def test_board_refuses_a_page_it_does_not_fit(tmp_path: Path) -> None:
    out = tmp_path / "board.pdf"
    result = _run("board", *BOARD_ARGS, "--page", "A4", "-o", out)
    assert result.returncode == 1
    assert "does not fit on A4" in result.stderr and "A3" in result.stderr
    assert "Traceback" not in result.stderr
    assert not out.exists()


def test_board_bad_output_paths(tmp_path: Path) -> None:
    result = _run("board", "-o", tmp_path / "board.txt")
    assert result.returncode == 2 and ".svg or .pdf" in result.stderr  # a malformed -o
    blocker = tmp_path / "file"
    blocker.write_text("")
    result = _run("board", "-o", blocker / "board.svg")
    assert result.returncode == 1 and "board.svg" in result.stderr
    assert "Traceback" not in result.stderr


# ------------------------------------------------------------------------------------------
# calibrate


def test_calibrate_json_and_report(images: dict[str, Path], tmp_path: Path) -> None:
    cal_path, report = tmp_path / "calib.json", tmp_path / "report"
    result = _run(
        "calibrate", images["board"], *BOARD_ARGS, "-o", cal_path, "--report", report, "--json"
    )
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)  # one JSON object, nothing else on stdout
    assert summary["n_points"] == 140 and summary["solver"] == "normalized_dlt"
    for key in (
        "mean_error_px",
        "max_error_px",
        "min_error_px",
        "rms_error_px",
        "loo_mean_error_mm",
        "max_abs_dx_mm",
        "max_abs_dy_mm",
    ):
        assert isinstance(summary[key], float)
    assert summary["min_error_px"] <= summary["mean_error_px"] <= summary["max_error_px"]
    assert summary["calibration_file"] == str(cal_path)
    # The calibration file loads and agrees with the summary.
    cal = planarcal.Calibration.load(cal_path)
    assert cal.summary().mean_px == pytest.approx(summary["mean_error_px"])
    # The report: the per-point table, the summary, and the two figures.
    rows = (report / "points.csv").read_text().splitlines()
    assert len(rows) == 141 and rows[0].startswith("dot,row,col,world_x_mm")
    first = rows[1].split(",")
    assert first[:5] == ["0", "0", "0", "0.000000", "0.000000"]  # dot 0, the origin
    assert json.loads((report / "summary.json").read_text())["n_points"] == 140
    for name in ("detection.png", "deviations.png"):
        picture = cv2.imread(str(report / name))
        assert picture is not None and picture.shape[0] > 200, name
    assert sorted(summary["report_files"]) == sorted(str(p) for p in report.iterdir())


def test_calibrate_prints_a_readable_summary(images: dict[str, Path], tmp_path: Path) -> None:
    result = _run(
        "calibrate", images["board"], "-o", tmp_path / "c.json", "--solver", "a33", "--no-refine"
    )
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "Found all 140 dots" in out and "Homography: a33, from 140 points" in out
    assert "Leave-one-out error (mm)" in out and "Saved the calibration to" in out


def test_calibrate_from_a_video_file_and_an_image_folder(
    scene: synth.PaperScene, tmp_path: Path
) -> None:
    video = tmp_path / "board.avi"
    frame = cv2.cvtColor(scene.calibration.image, cv2.COLOR_GRAY2BGR)
    writer = cv2.VideoWriter(
        str(video), cv2.VideoWriter.fourcc(*"MJPG"), 10, (frame.shape[1], frame.shape[0])
    )
    assert writer.isOpened()
    for _ in range(5):
        writer.write(frame)
    writer.release()
    result = _run(
        "calibrate", "--camera", video, "--frames", "4", "-o", tmp_path / "v.json", "--json"
    )
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["n_points"] == 140
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(3):
        cv2.imwrite(str(folder / f"f{i}.png"), frame)
    result = _run("calibrate", "--camera", folder, "--frames", "3", "-o", tmp_path / "f.json")
    assert result.returncode == 0, result.stderr
    # Asking for more frames than the folder holds fails, naming the source.
    result = _run("calibrate", "--camera", folder, "--frames", "5", "-o", tmp_path / "g.json")
    assert result.returncode == 1 and "frames" in result.stderr
    assert not (tmp_path / "g.json").exists()


def test_calibrate_failures_say_what_is_wrong(images: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "c.json"
    cases = [
        (("calibrate", tmp_path / "missing.png", "-o", out), "no image file"),
        (
            ("calibrate", images["board"], "--cols", "10", "--rows", "8", "-o", out),
            "no 10 x 8 circle grid",
        ),
        (("calibrate", images["objects"], "-o", out), "no 14 x 10 circle grid"),
        # The paper's 10 mm dots, 20 mm apart, described as 15 mm ones (issue 21).
        (
            ("calibrate", images["board"], "--diameter", "15", "-o", out),
            "the board says 15 mm (0.75): the diameter or the pitch is wrong",
        ),
    ]
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"not a png at all")
    cases.append((("calibrate", junk, "-o", out), "not an image OpenCV can decode"))
    for args, message in cases:
        result = _run(*args)
        assert result.returncode == 1, (args, result.stderr)
        assert message in result.stderr, (args, result.stderr)
        assert "Traceback" not in result.stderr
    # A command line that cannot be right, whatever the image: malformed, status 2.
    malformed = [
        (
            ("calibrate", images["board"], "--pitch", "5", "--diameter", "10", "-o", out),
            "diameter must be smaller",
        ),
        (("calibrate", "-o", out), "give an IMAGE"),
    ]
    for args, message in malformed:
        result = _run(*args)
        assert result.returncode == 2, (args, result.stderr)
        assert message in result.stderr, (args, result.stderr)
    assert not out.exists()
    blocker = tmp_path / "file"
    blocker.write_text("")
    result = _run("calibrate", images["board"], "-o", blocker / "c.json")
    assert result.returncode == 1 and "c.json" in result.stderr


# Runs `planarcal calibrate IMAGE` in a process whose address space is capped at what its
# imports took plus HEADROOM MB: an image too large for the memory left, on any machine.
OUT_OF_MEMORY_RUN = """
import resource, sys
import planarcal.commands.calibrate
from planarcal.cli import main
size = next(int(l.split()[1]) * 1024 for l in open("/proc/self/status") if l.startswith("VmSize:"))
limit = size + int(sys.argv[1]) * 2**20
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
sys.exit(main(["calibrate", sys.argv[2], "-o", sys.argv[3]]))
"""


@pytest.mark.skipif(sys.platform != "linux", reason="caps memory with RLIMIT_AS, reads /proc")
def test_an_image_too_large_for_the_memory_is_one_line(tmp_path: Path) -> None:
    # 16000 x 16000 px: 256 MB decoded, about 1 GB to search for dots. With 100 MB to spare
    # OpenCV's decoder runs out, with 800 MB the dot search (a MemoryError) or OpenCV's.
    huge = np.full((16000, 16000), 200, np.uint8)
    huge[::50, ::50] = 0
    image = tmp_path / "huge.png"
    cv2.imwrite(str(image), huge)
    del huge
    out = tmp_path / "c.json"
    for headroom_mb in (100, 800):
        result = subprocess.run(
            [sys.executable, "-c", OUT_OF_MEMORY_RUN, str(headroom_mb), str(image), str(out)],
            capture_output=True,
            text=True,
            timeout=300,
            check=False,
        )
        assert result.returncode == 1, (headroom_mb, result.stderr)
        assert "Traceback" not in result.stderr, result.stderr
        assert len(result.stderr.strip().splitlines()) == 1, result.stderr
        assert re.fullmatch(
            r"planarcal calibrate: error: (out of|not enough) memory.*: free memory \(close "
            r"other programs\), or give a smaller image \(scaled down, or cropped to the work "
            r"area\)\n",
            result.stderr,
        ), result.stderr
    assert not out.exists()
    # Commands that can look at part of an image say so.
    locating = build_parser().parse_args(["locate", "big.png", "--calibration", "c.json"])
    assert _out_of_memory("", locating).endswith("or look at part of it with --roi")
    assert "--roi" not in _out_of_memory(
        "", build_parser().parse_args(["calibrate", "big.png", "-o", "c.json"])
    )


# ------------------------------------------------------------------------------------------
# locate


def test_locate_gives_objects_in_millimetres(
    images: dict[str, Path], scene: synth.PaperScene, tmp_path: Path
) -> None:
    cal_path = tmp_path / "calib.json"
    assert _run("calibrate", images["board"], "-o", cal_path).returncode == 0
    annotated = tmp_path / "objects.png"
    result = _run(
        "locate", images["objects"], "--calibration", cal_path, "--json", "--annotate", annotated
    )
    assert result.returncode == 0, result.stderr
    found = json.loads(result.stdout)["objects"]
    truth = scene.objects.object_centroids_mm
    assert len(found) == len(truth) == 10
    assert [o["id"] for o in found] == list(range(1, 11))
    for o in found:
        gap = np.linalg.norm(truth - np.array(o["world_mm"]), axis=1).min()
        assert gap < 0.6, o
        # Each bolt's axis on the board, as it was placed (folded into [-90, 90)); the nuts
        # are too round for one (null).
        placed = scene.objects.objects[
            int(np.argmin(np.linalg.norm(truth - o["world_mm"], axis=1)))
        ]
        if placed.kind == "bolt":
            turn = (o["angle_deg"] - placed.angle_deg + 90.0) % 180.0 - 90.0
            assert -90.0 <= o["angle_deg"] < 90.0 and abs(turn) < 0.5, o
        else:
            assert o["angle_deg"] is None, o
    picture = cv2.imread(str(annotated))
    assert picture is not None and picture.shape[:2] == scene.objects.image.shape[:2]
    # The readable table: one row per object.
    table = _run("locate", images["objects"], "--calibration", cal_path).stdout
    rows = [line for line in table.splitlines() if line.startswith("ID:")]
    assert len(rows) == 10 and "angle (deg)" in table
    # The angle is the last column: three bolts have one, the seven nuts "-".
    assert sorted(row.split()[-1] == "-" for row in rows) == [False] * 3 + [True] * 7


def test_locate_refuses_a_corrupt_calibration(images: dict[str, Path], tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "planarcal-calibration", "version": 1, "homogr')
    result = _run("locate", images["objects"], "--calibration", bad)
    assert result.returncode == 1 and "not valid JSON" in result.stderr
    result = _run("locate", images["objects"], "--calibration", tmp_path / "none.json")
    assert result.returncode == 1 and "no calibration file" in result.stderr


# ------------------------------------------------------------------------------------------
# lens models, printer scale, intrinsics and heights


def test_calibrate_lens_choice_and_printer_scale(images: dict[str, Path], tmp_path: Path) -> None:
    auto, plain, scaled = tmp_path / "auto.json", tmp_path / "plain.json", tmp_path / "s.json"
    out = _run("calibrate", images["board"], *BOARD_ARGS, "-o", auto, "--json")
    assert out.returncode == 0, out.stderr
    assert planarcal.Calibration.load(auto).lens_model in ("k1", "k1k2", "k1k2c")
    out = _run("calibrate", images["board"], *BOARD_ARGS, "-o", plain, "--lens", "none", "--json")
    assert out.returncode == 0, out.stderr
    a, p = planarcal.Calibration.load(auto), planarcal.Calibration.load(plain)
    assert p.lens_model == "none" and a.summary().loo_mean_mm < p.summary().loo_mean_mm / 5
    # The check bar measured 101 mm: every distance grows by 1 %.
    out = _run("calibrate", images["board"], *BOARD_ARGS, "-o", scaled, "--check-bar", "101")
    assert out.returncode == 0, out.stderr
    s = planarcal.Calibration.load(scaled)
    assert s.world_scale == pytest.approx((1.01, 1.01))
    px = a.world_to_image(np.array([[0.0, 0.0], [260.0, 180.0]]))
    d_a, d_s = (np.linalg.norm(np.diff(c.image_to_world(px), axis=0)) for c in (a, s))
    assert d_s == pytest.approx(1.01 * d_a, rel=1e-6)
    bad = _run("calibrate", images["board"], "-o", scaled, "--measured-pitch", "30")
    assert bad.returncode == 1 and "printer's scale" in bad.stderr  # the data refute it
    bad = _run("calibrate", images["board"], "-o", scaled, "--measured-pitch", "x,y")
    assert bad.returncode == 2 and "X,Y" in bad.stderr


def test_intrinsics_then_objects_of_known_height(tmp_path: Path) -> None:
    board = synth.PAPER_BOARD
    views = []
    for k, (tilt, axis) in enumerate(((25, 0), (25, 90), (30, 45), (30, 200), (20, 300))):
        pose = synth.PlanePose(600.0, tilt_deg=tilt, tilt_axis_deg=axis, look_at_mm=(130, 90))
        scene = synth.render_scene(synth.PAPER_CAMERA, pose, blur_sigma_px=0.8, noise_sigma=2)
        path = tmp_path / f"view{k}.png"
        cv2.imwrite(str(path), scene.image)
        views.append(path)
    yaml = tmp_path / "camera.yaml"
    out = _run("intrinsics", *views, *BOARD_ARGS, "-o", yaml)
    assert out.returncode == 0, out.stderr
    assert "focal length" in out.stdout and yaml.exists()
    cam = planarcal.CameraIntrinsics.load_yaml(yaml)
    assert cam.fx == pytest.approx(synth.PAPER_CAMERA.focal_px, rel=0.005)
    # The working view, and a calibration made with the intrinsics.
    scene = synth.random_paper_scene(3)
    work = tmp_path / "work.png"
    cv2.imwrite(str(work), scene.image)
    cal_path = tmp_path / "calib.json"
    out = _run("calibrate", work, *BOARD_ARGS, "-o", cal_path, "--intrinsics", yaml)
    assert out.returncode == 0, out.stderr
    cal = planarcal.Calibration.load(cal_path)
    assert cal.lens_model == "intrinsics" and cal.intrinsics == cam
    # Tops of 20 mm posts: located where they are with the height, millimetres off without.
    tops = np.array([[20.0, 15.0], [250.0, 20.0], [130.0, 90.0], [240.0, 170.0]])
    rvec, tvec = scene.pose.rvec_tvec()
    xyz = np.column_stack([tops, np.full(len(tops), -20.0)])
    px = cv2.projectPoints(xyz, rvec, tvec, scene.camera.matrix(), scene.camera.dist_coeffs())[0]
    px = px.reshape(-1, 2)
    with_height = cal.image_to_world(px, height=20.0)
    without = cal.image_to_world(px)
    assert np.abs(with_height - tops).max() < 0.1
    assert np.hypot(*(without - tops).T).max() > 5.0
    # Without intrinsics, a height cannot be honoured: it says so.
    auto = planarcal.Calibration.from_image(work, board)
    with pytest.raises(planarcal.IntrinsicsError, match="intrinsics"):
        auto.image_to_world(px, height=20.0)
    bad = _run("intrinsics", views[0], *BOARD_ARGS, "-o", tmp_path / "x.yaml")
    assert bad.returncode == 2 and "at least 3" in bad.stderr


def test_board_arguments_default_per_command() -> None:
    parser = build_parser()
    # Printing: an origin marker unless told otherwise; the diameter is chosen by the command.
    printing = parser.parse_args(["board", "-o", "b.svg"])
    assert printing.origin_marker is True and printing.diameter is None
    assert printing.layout == "symmetric"
    assert parser.parse_args(["board", "--no-origin-marker", "-o", "b.svg"]).origin_marker is False
    # Finding: no marker unless told; an absent diameter stays unknown (measured from the image).
    for command in (["calibrate", "photo.png"], ["intrinsics", "a.png", "b.png", "c.png"]):
        finding = parser.parse_args([*command, "-o", "out"])
        assert finding.origin_marker is False and finding.diameter is None
        assert finding.layout == "symmetric"
        told = parser.parse_args([*command, "--origin-marker", "--layout", "asymmetric", "-o", "x"])
        assert told.origin_marker is True and told.layout == "asymmetric"
        assert parser.parse_args([*command, "--no-origin-marker", "-o", "x"]).origin_marker is False
