"""The calibration report: the lens model and the uncertainty in the summaries, the per-point
table and the figures, on a rendered scene detected and calibrated for real."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import types
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from conftest import decode_png
from planarcal import report, synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.camera.intrinsics import CameraIntrinsics
from planarcal.errors import IntrinsicsError, LensModelError, PointAtInfinityError
from planarcal.report import drawing
from planarcal.synth import paper_data

# The per-point table's columns before the lens and uncertainty columns were added: scripts
# read them by position, so they keep their order. The first is the dot's index (0 the origin
# dot, as in the touch CSV and the API; it was a 1-based "point" before issue 21).
OLD_COLUMNS = [
    "dot",
    "row",
    "col",
    "world_x_mm",
    "world_y_mm",
    "image_x_px",
    "image_y_px",
    "reprojected_x_px",
    "reprojected_y_px",
    "error_px",
    "world_after_x_mm",
    "world_after_y_mm",
    "dx_mm",
    "dy_mm",
    "loo_dx_mm",
    "loo_dy_mm",
    "loo_error_mm",
]
REPORT_FILES = {
    "points.csv",
    "summary.json",
    "deviations.png",
    "lens.png",
    "uncertainty.png",
    "coverage.png",
    "detection.png",
}


@pytest.fixture(scope="module")
def scene() -> Any:
    return synth.paper_scene(seed=0, objects=False).calibration


@pytest.fixture(scope="module")
def detection(scene: Any) -> Any:
    return detect_board(scene.image, scene.board)


@pytest.fixture(scope="module")
def cal(detection: Any) -> Calibration:
    return Calibration.from_detection(detection)


@pytest.fixture(scope="module")
def before(cal: Calibration) -> Calibration:
    """The homography alone on the same points."""
    return Calibration(
        cal.world_points,
        cal.image_points,
        lens="none",
        board=cal.board,
        image_size=cal.image_size,
    )


@pytest.fixture(scope="module")
def paper_cal() -> Calibration:
    """The paper's 28 points: no board, no image size (so no lens model)."""
    return Calibration(paper_data.WORLD_MM, paper_data.IMAGE_PX)


def _plausible(picture: np.ndarray[Any, Any]) -> None:
    h, w = picture.shape[:2]
    assert 400 <= h <= 3000 and 600 <= w <= 3000, picture.shape
    assert picture.std() > 10  # something is drawn, not a blank page


# ------------------------------------------------------------------------------------------
# the summaries


def test_the_scene_needs_a_lens_model(cal: Calibration, before: Calibration) -> None:
    """The premise of the before / after figures: the rendered lens distorts, and the
    calibration found a model for it."""
    assert cal.lens_model != "none" and cal.lens is not None
    assert cal.stats.mean < before.stats.mean


def test_summary_json_carries_the_lens_and_its_candidates(
    cal: Calibration, before: Calibration, detection: Any
) -> None:
    out = report.summary_json(cal, detection)
    again = json.loads(json.dumps(out, allow_nan=False))
    assert again == out  # plain JSON through and through
    assert out["lens_model"] == cal.lens_model and out["lens_note"] == cal.lens_note
    lens = out["lens"]
    assert cal.lens is not None
    assert lens["model"] == cal.lens_model
    assert lens["k1"] == pytest.approx(cal.lens.k1) and lens["k2"] == pytest.approx(cal.lens.k2)
    assert lens["k1_std"] == pytest.approx(cal.lens.k1_std)
    assert lens["centre_px"] == pytest.approx(list(cal.lens.centre_px))
    assert "k1" in lens["fitted"]
    assert math.isfinite(out["lens_max_displacement_px"]) and out["lens_max_displacement_px"] > 0
    models = [c["model"] for c in out["lens_candidates"]]
    assert models == [c.model for c in cal.lens_candidates] and models
    chosen = [c["model"] for c in out["lens_candidates"] if c["verdict"] == "chosen"]
    assert chosen == [cal.lens_model]
    for c, mine in zip(out["lens_candidates"], cal.lens_candidates, strict=True):
        assert c["loo_mean_px"] == pytest.approx(mine.loo_mean_px)
    # Predicted against measured leave-one-out error.
    s = cal.summary()
    assert out["predicted_loo_rms_error_mm"] == pytest.approx(s.predicted_loo_rms_mm)
    assert out["loo_rms_measured_over_predicted"] == pytest.approx(
        s.loo_rms_mm / s.predicted_loo_rms_mm
    )
    # Before (a homography alone) and after (the chosen model).
    b, a = out["before_after"]["before"], out["before_after"]["after"]
    assert b["lens_model"] == "none" and a["lens_model"] == cal.lens_model
    assert b["mean_error_px"] == pytest.approx(before.summary().mean_px)
    assert b["max_error_px"] == pytest.approx(before.summary().max_px)
    assert b["loo_mean_error_mm"] == pytest.approx(before.summary().loo_mean_mm)
    assert a["mean_error_px"] == pytest.approx(s.mean_px)
    assert a["loo_rms_error_mm"] == pytest.approx(s.loo_rms_mm)
    # The keys that were there before stay.
    assert out["n_points"] == len(cal.world_points) and out["mean_error_px"] == s.mean_px
    assert out["detection"]["method"] == detection.method
    assert "world_scale" not in out  # (1, 1): nothing to say


def test_summary_text_shows_the_model_and_before_after(
    cal: Calibration, before: Calibration, detection: Any
) -> None:
    text = report.summary_text(cal, detection)
    assert cal.lens is not None
    assert f"Lens model {cal.lens_model}:" in text
    assert f"k1 = {cal.lens.k1:.5f} +/- {cal.lens.k1_std:.5f}" in text
    for c in cal.lens_candidates:
        assert any(line.split()[:1] == [c.model] and c.verdict in line for line in text.split("\n"))
    table = text[text.index("Before / after") :]
    b, a = before.summary(), cal.summary()
    for value in (f"{b.mean_px:.3f}", f"{a.mean_px:.3f}", f"{b.max_px:.3f}", f"{a.max_px:.3f}"):
        assert value in table
    assert f"{b.loo_mean_mm:.4f}" in table and f"{a.loo_mean_mm:.4f}" in table
    ratio = a.loo_rms_mm / a.predicted_loo_rms_mm
    assert f"(ratio {ratio:.2f})" in text
    # The lines that were there before stay.
    assert f"Found all {a.n_points} dots" in text and "Leave-one-out error (mm)" in text
    assert f"Lens: {cal.lens_note}" in text


def test_the_world_scale_is_reported_when_corrected(cal: Calibration) -> None:
    assert cal.board is not None
    scaled = cal.rescaled(cal.board.pitch * 1.004, cal.board.pitch * 0.997)
    out = report.summary_json(scaled)
    assert out["world_scale"] == pytest.approx([1.004, 0.997])
    text = report.summary_text(scaled)
    assert "World scale" in text and "+0.40 %" in text and "-0.30 %" in text


def test_without_a_lens_model_there_is_no_before_after(before: Calibration) -> None:
    out = report.summary_json(before)
    json.dumps(out, allow_nan=False)
    assert out["lens_model"] == "none" and out["lens"] is None
    assert out["lens_max_displacement_px"] is None and "before_after" not in out
    text = report.summary_text(before)
    assert "Before / after" not in text and "Lens model " not in text


# ------------------------------------------------------------------------------------------
# the per-point table


def test_points_csv_has_the_leave_one_out_columns(cal: Calibration) -> None:
    rows = list(csv.reader(io.StringIO(report.points_csv(cal))))
    header, body = rows[0], rows[1:]
    assert header == [*OLD_COLUMNS, "loo_error_px", "predicted_loo_std_mm", "refined", "enlarged"]
    assert len(body) == len(cal.world_points)
    loo_px = np.array([float(r[header.index("loo_error_px")]) for r in body])
    predicted = np.array([float(r[header.index("predicted_loo_std_mm")]) for r in body])
    assert np.isfinite(loo_px).all() and np.isfinite(predicted).all()
    assert loo_px == pytest.approx(cal.loo_errors_px, abs=1e-6)
    assert predicted == pytest.approx(cal.predicted_loo_std_mm, abs=1e-6)
    assert (predicted > 0).all()


def test_points_csv_numbers_the_dots_as_the_api_does(cal: Calibration) -> None:
    rows = list(csv.DictReader(io.StringIO(report.points_csv(cal))))
    cols = cal.board.cols if cal.board is not None else 0
    assert [r["dot"] for r in rows] == [str(k) for k in range(len(cal.world_points))]
    for k in (0, 1, cols, len(rows) - 1):
        # Dot k is row k // cols, column k % cols, at world_points[k] (the origin for 0).
        r = rows[k]
        assert (int(r["row"]), int(r["col"])) == divmod(k, cols)
        world = (float(r["world_x_mm"]), float(r["world_y_mm"]))
        assert world == pytest.approx(tuple(cal.world_points[k]), abs=1e-6)
    assert (float(rows[0]["world_x_mm"]), float(rows[0]["world_y_mm"])) == (0.0, 0.0)


# ------------------------------------------------------------------------------------------
# the figures


@pytest.fixture(scope="module")
def lens_png(cal: Calibration, scene: Any) -> bytes:
    return report.lens_figure(cal, image=scene.image)


def test_lens_figure_decodes(lens_png: bytes) -> None:
    picture = decode_png(lens_png)
    _plausible(picture)
    h, w = picture.shape[:2]
    assert w > h  # two panels side by side in each row


def test_lens_figure_without_the_image(cal: Calibration) -> None:
    _plausible(decode_png(report.lens_figure(cal)))


def test_uncertainty_figure_decodes(cal: Calibration) -> None:
    _plausible(decode_png(report.uncertainty_figure(cal)))


@pytest.mark.parametrize("which", ["lens_none", "paper_points"])
def test_every_figure_without_a_lens_model(
    which: str, before: Calibration, paper_cal: Calibration, tmp_path: Path
) -> None:
    """A homography alone (asked for), and the paper's 28 points without an image size:
    every figure, the summaries and the report directory."""
    c = before if which == "lens_none" else paper_cal
    assert c.lens_model == "none"
    json.dumps(report.summary_json(c), allow_nan=False)
    assert "Reprojection error (px)" in report.summary_text(c)
    written = report.write_report(c, tmp_path / "report")
    # No image size (the paper's points), no map over the image.
    no_image = {"detection.png"} | ({"coverage.png"} if c.image_size is None else set())
    assert {p.name for p in written} == REPORT_FILES - no_image
    assert sorted(p.name for p in (tmp_path / "report").iterdir()) == sorted(
        p.name for p in written
    )
    for p in written:
        if p.suffix == ".png":
            _plausible(decode_png(p.read_bytes()))


def test_four_points_leave_no_room_for_uncertainty(tmp_path: Path) -> None:
    """Four points fit a homography exactly: no residuals, no leave-one-out, no covariance.
    The report says so instead of failing."""
    world = np.array(paper_data.WORLD_MM)
    image = np.array(paper_data.IMAGE_PX)
    corners = [int(np.argmin(world.sum(axis=1))), int(np.argmax(world.sum(axis=1)))]
    corners += [
        int(np.argmin(world[:, 0] - world[:, 1])),
        int(np.argmax(world[:, 0] - world[:, 1])),
    ]
    exact = Calibration(world[corners], image[corners])
    out = report.summary_json(exact)
    json.dumps(out, allow_nan=False)
    assert out["predicted_loo_rms_error_mm"] is None
    assert out["loo_rms_measured_over_predicted"] is None
    assert "Uncertainty:" not in report.summary_text(exact)
    written = report.write_report(exact, tmp_path)
    for p in written:
        if p.suffix == ".png":
            _plausible(decode_png(p.read_bytes()))


def test_unmappable_pixels_are_masked_not_fatal(cal: Calibration) -> None:
    """Camera intrinsics whose distortion folds over inside the image: the corners of the
    working area have no place on the plane, and the figures leave them blank."""
    assert cal.image_size is not None
    w, h = cal.image_size
    f = 0.7 * w
    intrinsics = CameraIntrinsics(
        np.array([[f, 0.0, (w - 1) / 2], [0.0, f, (h - 1) / 2], [0.0, 0.0, 1.0]]),
        np.array([-0.5, 0.0, 0.0, 0.0, 0.0]),
        (w, h),
    )
    folded = Calibration(
        cal.world_points,
        intrinsics.distort_points(cal.image_points),
        intrinsics=intrinsics,
        board=cal.board,
    )
    corner = np.array([[0.0, 0.0]])
    with pytest.raises((IntrinsicsError, LensModelError, PointAtInfinityError)):
        folded.image_to_world(corner, return_std=True)
    _plausible(decode_png(report.uncertainty_figure(folded)))
    _plausible(decode_png(report.lens_figure(folded)))
    out = report.summary_json(folded)
    json.dumps(out, allow_nan=False)
    assert out["lens_model"] == "intrinsics" and "before_after" in out


# ------------------------------------------------------------------------------------------
# the report directory


def test_write_report_writes_six_files_and_no_debris(
    cal: Calibration, scene: Any, detection: Any, tmp_path: Path
) -> None:
    out = tmp_path / "fresh"
    written = report.write_report(cal, out, image=scene.image, detection=detection)
    assert {p.name for p in written} == REPORT_FILES and len(written) == len(REPORT_FILES)
    assert all(p.parent == out for p in written)
    # No temporary files left behind: exactly the files written.
    assert sorted(p.name for p in out.iterdir()) == sorted(REPORT_FILES)
    for p in written:
        if p.suffix == ".png":
            picture = cv2.imread(str(p))
            assert picture is not None, p.name
            _plausible(picture)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["lens_model"] == cal.lens_model
    assert (out / "points.csv").read_text() == report.points_csv(cal, detection)


# ------------------------------------------------------------------------------------------
# which model the detection figure's residual comes from


def test_the_detection_figure_names_the_model_of_each_residual(
    cal: Calibration, before: Calibration, detection: Any
) -> None:
    """The figure quotes the homography alone's residual and the chosen lens model's, each
    named, and the summary text gives the same figures in the same words."""
    label = "\n".join(drawing.detection_label(detection, report.residual_note(cal)))
    alone, chosen = f"{before.stats.rms:.3f}", f"{cal.stats.rms:.3f}"
    assert (
        f"residual of the homography alone through the centres: {alone} px RMS; "
        f"with the lens model {cal.lens_model}: {chosen} px RMS"
    ) in label
    text = report.summary_text(cal, detection)
    assert f"Reprojection error (px), with the lens model {cal.lens_model}: " in text
    assert f"RMS {chosen}," in text
    rms_row = next(line for line in text.split("\n") if "reprojection error, RMS (px)" in line)
    assert rms_row.split()[-2:] == [alone, chosen]


def test_without_a_lens_model_the_residual_is_the_homography_alone(before: Calibration) -> None:
    note = report.residual_note(before)
    assert note.startswith("residual of the homography alone") and "(no lens model)" in note
    assert f"{before.stats.rms:.3f} px RMS" in note
    assert "Reprojection error (px), of the homography alone: " in report.summary_text(before)


def test_the_detection_alone_quotes_its_own_residual(detection: Any) -> None:
    """Without a calibration the figure still says what its residual is."""
    label = drawing.detection_label(detection)
    assert label[1] == (
        "residual of the homography alone through the centres: "
        f"{detection.residual_rms_px:.3f} px RMS"
    )


# ------------------------------------------------------------------------------------------
# the detection's own findings: dots not refined, enlarged dots, orientation, warnings

ORIGINAL_FIELDS = (
    "board",
    "image_points",
    "image_size",
    "method",
    "polarity",
    "dot_diameters_px",
    "residual_rms_px",
)
NOT_REFINED = (4, 50)  # the dots' indices, as every file and text names them
ENLARGED = (0,)
RULE = "dot 0 is the corner dot nearest the image's top-left corner"


def _plain(detection: Any) -> Any:
    """The detection as it was before it carried per-dot flags (whatever detect.py adds)."""
    fields = {name: getattr(detection, name) for name in ORIGINAL_FIELDS}
    return types.SimpleNamespace(**fields, pitch_px=detection.pitch_px)


def _flagged(detection: Any, **extra: Any) -> Any:
    """The detection with two dots not refined, one enlarged, an ambiguous orientation and a
    warning (or what `extra` says instead)."""
    n = len(detection.image_points)
    refined = np.ones(n, dtype=bool)
    refined[list(NOT_REFINED)] = False
    enlarged = np.zeros(n, dtype=bool)
    enlarged[list(ENLARGED)] = True
    fields = {
        "refined": refined,
        "enlarged": enlarged,
        "orientation": "ambiguous",
        "orientation_rule": RULE,
        "warnings": ("the board fills little of the image",),
        **extra,
    }
    is_instance = dataclasses.is_dataclass(detection) and not isinstance(detection, type)
    if is_instance and all(f in {x.name for x in dataclasses.fields(detection)} for f in fields):
        return dataclasses.replace(detection, **fields)  # once detect.py carries them
    return types.SimpleNamespace(**vars(_plain(detection)), **fields)


def test_summaries_carry_the_detections_findings(cal: Calibration, detection: Any) -> None:
    flagged = _flagged(detection)
    out = report.summary_json(cal, flagged)["detection"]
    assert out["n_not_refined"] == 2 and out["not_refined_dots"] == [4, 50]
    assert out["enlarged_dots"] == [0]
    assert out["orientation"] == f"ambiguous: {RULE}" and out["orientation_rule"] == RULE
    assert out["warnings"] == ["the board fills little of the image"]
    json.dumps(out, allow_nan=False)
    text = report.summary_text(cal, flagged)
    assert f"Orientation (which dot is the origin): ambiguous: {RULE}" in text
    assert "Centres refined: 138 of 140 dots; not refined (a coarser centre kept): dots 4, 50" in (
        text
    )
    assert "Enlarged dots: dot 0" in text
    assert "Warning: the board fills little of the image" in text


def test_an_origin_marker_is_named_as_such(cal: Calibration, detection: Any) -> None:
    marked = _flagged(detection, orientation="marker", warnings=())
    assert report.summary_json(cal, marked)["detection"]["orientation"] == "origin marker"
    text = report.summary_text(cal, marked)
    assert "Orientation (which dot is the origin): origin marker" in text
    assert "Warning:" not in text


def test_summaries_without_the_findings_say_nothing_of_them(
    cal: Calibration, detection: Any
) -> None:
    out = report.summary_json(cal, _plain(detection))["detection"]
    assert set(out) == {"method", "polarity", "pitch_px", "residual_rms_px"}
    text = report.summary_text(cal, _plain(detection))
    assert "Orientation" not in text and "Centres refined" not in text


def test_points_csv_flags_each_dot(cal: Calibration, detection: Any) -> None:
    rows = list(csv.DictReader(io.StringIO(report.points_csv(cal, _flagged(detection)))))
    refined = [r["dot"] for r in rows if r["refined"] == "0"]
    enlarged = [r["dot"] for r in rows if r["enlarged"] == "1"]
    assert refined == ["4", "50"] and enlarged == ["0"]
    assert {r["refined"] for r in rows} == {"0", "1"}
    # Unknown: empty cells, the same header.
    plain = list(csv.DictReader(io.StringIO(report.points_csv(cal, _plain(detection)))))
    assert {r["refined"] for r in plain} == {""} and {r["enlarged"] for r in plain} == {""}


def test_the_detection_figure_marks_the_flagged_dots(scene: Any, detection: Any) -> None:
    flagged = _flagged(detection)
    label = drawing.detection_label(flagged)
    assert any("red cross: 2 dot(s) not refined" in line for line in label)
    assert any("magenta ring: 1 enlarged dot(s)" in line for line in label)
    marked = drawing.draw_detection(scene.image, flagged)
    plain = drawing.draw_detection(scene.image, _plain(detection))
    r = int(0.6 * detection.pitch_px)  # the ring's radius is half a pitch

    def changed(k: int) -> bool:
        x, y = np.rint(detection.image_points[k]).astype(int)
        window = (slice(y - r, y + r + 1), slice(x - r, x + r + 1))
        return bool((marked[window] != plain[window]).any())

    assert all(changed(k) for k in (*NOT_REFINED, *ENLARGED))
    middle = len(detection.image_points) // 2 + detection.board.cols // 2
    assert not changed(middle)


def test_the_detection_figure_labels_each_dot_with_its_index(scene: Any, detection: Any) -> None:
    """Dot 9 (the last of the first row's first ten) is labelled "9", one digit wide, as the
    CSV files and the API number it; it was "10"."""
    drawn = drawing.draw_detection(scene.image, detection)
    # The labels' green (0, 200, 0), antialiased over the grey image: nothing else near dot 9
    # is green.
    bgr = drawn.astype(np.int32)
    label_green = bgr[:, :, 1] - np.maximum(bgr[:, :, 0], bgr[:, :, 2]) > 60
    x, y = detection.image_points[9]
    pitch = detection.pitch_px
    box = label_green[int(y - 0.6 * pitch) : int(y), int(x) : int(x + 0.9 * pitch)]
    columns = np.flatnonzero(box.any(axis=0))
    assert columns.size, "no label beside dot 9"
    width = int(columns[-1] - columns[0] + 1)
    scale = 0.35 * max(0.5, max(drawn.shape[:2]) / 1280.0)
    (one, _), _ = cv2.getTextSize("9", cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    (two, _), _ = cv2.getTextSize("10", cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    assert abs(width - one) < abs(width - two), (width, one, two)


def test_write_report_carries_the_findings(
    cal: Calibration, scene: Any, detection: Any, tmp_path: Path
) -> None:
    report.write_report(cal, tmp_path, image=scene.image, detection=_flagged(detection))
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["detection"]["not_refined_dots"] == [4, 50]
    rows = list(csv.DictReader(io.StringIO((tmp_path / "points.csv").read_text())))
    assert [r["dot"] for r in rows if r["refined"] == "0"] == ["4", "50"]
