"""Calibration: the paper's report, leave-one-out, mapping, files and pickling."""

from __future__ import annotations

import json
import multiprocessing
import pickle
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import planarcal
from conftest import SHARED
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import FILE_VERSION, Calibration
from planarcal.errors import ArgumentError, CalibrationFileError
from planarcal.synth import paper_data

WORLD = np.array(paper_data.WORLD_MM)
IMAGE = np.array(paper_data.IMAGE_PX)


@pytest.fixture(scope="module")
def cal() -> Calibration:
    # The paper's own estimator family, a homography alone (test_lens.py covers lens models).
    return Calibration(WORLD, IMAGE, board=CircleGridBoard(), image_size=(1280, 720), lens="none")


def test_default_is_the_gold_standard_and_a33_is_the_papers_estimator(cal: Calibration) -> None:
    assert (cal.solver, cal.refine) == ("normalized_dlt", True)
    assert np.array_equal(cal.H, planarcal.estimate_homography(WORLD, IMAGE, refine=True))
    paper = Calibration(WORLD, IMAGE, solver="a33", refine=False)
    assert np.array_equal(paper.H, planarcal.estimate_homography(WORLD, IMAGE, "a33"))
    assert paper.H[2, 2] == 1.0
    # The gold standard has the smallest RMS reprojection error of all fits.
    assert cal.stats.rms <= paper.stats.rms


def test_report_matches_the_definitions(cal: Calibration) -> None:
    assert np.allclose(cal.reprojected_px, planarcal.transform_points(cal.H, WORLD))
    errors = np.linalg.norm(IMAGE - cal.reprojected_px, axis=1)  # Eq. 6
    assert np.allclose(cal.reprojection_errors_px, errors)
    s = cal.summary()
    assert s.mean_px == pytest.approx(errors.mean())  # Eq. 7
    assert s.rms_px == pytest.approx(np.sqrt(np.mean(errors**2)))
    assert s.max_px == pytest.approx(errors.max())
    assert s.min_px == pytest.approx(errors.min())
    # Table 4: image points back through H^-1, and their deviations.
    back = planarcal.transform_points(cal.H, IMAGE, inverse=True)
    assert np.allclose(cal.world_after_mm, back)
    assert np.allclose(cal.deviations_mm, back - WORLD)
    assert s.max_abs_dx_mm == pytest.approx(np.abs(back - WORLD)[:, 0].max())
    assert s.n_points == 28


def test_leave_one_out_refits_without_each_point(cal: Calibration) -> None:
    for i in (0, 13, 27):
        keep = np.arange(28) != i
        h = planarcal.estimate_homography(WORLD[keep], IMAGE[keep], refine=True)
        predicted = planarcal.transform_points(h, IMAGE[i : i + 1], inverse=True)[0]
        assert np.allclose(cal.loo_deviations_mm[i], predicted - WORLD[i], atol=1e-9)
    # Held-out points land further off than fitted ones: the residuals flatter the fit.
    in_sample = np.linalg.norm(cal.deviations_mm, axis=1)
    assert cal.loo_errors_mm.mean() > in_sample.mean()
    assert cal.summary().loo_mean_mm == pytest.approx(cal.loo_errors_mm.mean())


def test_four_points_have_no_leave_one_out() -> None:
    c = Calibration(WORLD[[0, 13, 14, 27]], IMAGE[[0, 13, 14, 27]])
    assert np.isnan(c.loo_errors_mm).all()
    assert np.isnan(c.summary().loo_mean_mm)
    json.dumps(c.to_dict(), allow_nan=False)  # NaN is written as null


def test_mapping_both_ways(cal: Calibration) -> None:
    mm = cal.image_to_world(IMAGE)
    assert mm.shape == (28, 2)
    assert np.allclose(cal.world_to_image(mm), IMAGE, atol=1e-9)
    single = cal.image_to_world([400.0, 300.0])
    assert single.shape == (2,)
    assert np.allclose(single, cal.image_to_world([[400.0, 300.0]])[0])
    assert np.allclose(cal.H_inv @ cal.H / (cal.H_inv @ cal.H)[2, 2], np.eye(3), atol=1e-12)
    with pytest.raises(ArgumentError, match="2 coordinates"):
        cal.image_to_world([1.0, 2.0, 3.0])


def test_bad_points_are_refused() -> None:
    with pytest.raises(ArgumentError, match="one to one"):
        Calibration(WORLD, IMAGE[:-1])
    with pytest.raises(ArgumentError, match="shape"):
        Calibration(WORLD[:, :1], IMAGE)
    with pytest.raises(ArgumentError, match="solver"):
        Calibration(WORLD, IMAGE, solver="ransac")  # type: ignore[arg-type]
    with pytest.raises(planarcal.DegenerateError):
        Calibration(WORLD[:14], IMAGE[:14])  # one row of the board: collinear


def test_save_and_load_round_trip(cal: Calibration, tmp_path: Path) -> None:
    path = cal.save(tmp_path / "calib.json")
    data = json.loads(path.read_text())
    assert data["format"] == "planarcal-calibration" and data["version"] == FILE_VERSION
    assert data["summary"]["n_points"] == 28  # human-readable: the figures are in the file
    back = Calibration.load(path)
    assert np.array_equal(back.H, cal.H)
    assert np.array_equal(back.world_points, WORLD) and np.array_equal(back.image_points, IMAGE)
    assert back.board == cal.board and back.image_size == (1280, 720)
    assert back.summary() == cal.summary()
    # Saving again replaces the file whole.
    cal.save(path)
    assert Calibration.load(path).summary() == cal.summary()


@pytest.mark.parametrize(
    ("mangle", "match"),
    [
        (lambda t: t[: len(t) // 2], "not valid JSON"),
        (lambda t: "", "not valid JSON"),
        (lambda t: "\x00\x01garbage", "not valid JSON"),
        (lambda t: "[1, 2, 3]", "not a calibration"),
        (lambda t: t.replace('"planarcal-calibration"', '"something-else"'), "not a planarcal"),
        (
            lambda t: t.replace(f'"version": {FILE_VERSION}', f'"version": {FILE_VERSION + 1}'),
            f"version {FILE_VERSION + 1}",
        ),
        (lambda t: t.replace('"homography_world_mm_to_image_px"', '"h"'), "missing"),
        (lambda t: t.replace('"solver": "normalized_dlt"', '"solver": "magic"'), "solver"),
    ],
)
def test_corrupt_files_are_refused(
    cal: Calibration, tmp_path: Path, mangle: Callable[[str], str], match: str
) -> None:
    path = cal.save(tmp_path / "calib.json")
    path.write_text(mangle(path.read_text()))
    with pytest.raises(CalibrationFileError, match=match):
        Calibration.load(path)


def test_tampered_numbers_are_refused(cal: Calibration, tmp_path: Path) -> None:
    data = cal.to_dict()
    data["homography_world_mm_to_image_px"][0][0] = float("nan")
    with pytest.raises(CalibrationFileError, match="finite 3 x 3"):
        Calibration.from_dict(json.loads(json.dumps(data)))
    data = cal.to_dict()
    data["points"]["image_px"] = data["points"]["image_px"][:3]
    with pytest.raises(CalibrationFileError, match="3 image points"):
        Calibration.from_dict(data)
    data = cal.to_dict()
    data["board"] = {"cols": 1}
    with pytest.raises(CalibrationFileError, match="board"):
        Calibration.from_dict(data)


def test_missing_and_unwritable_paths(cal: Calibration, tmp_path: Path) -> None:
    with pytest.raises(CalibrationFileError, match="no calibration file"):
        Calibration.load(tmp_path / "absent.json")
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    with pytest.raises(OSError, match=r"a-file"):
        cal.save(blocker / "calib.json")  # a path under a regular file
    target = tmp_path / "calib.json"
    cal.save(target)
    before = target.read_bytes()
    (tmp_path / "dir.json").mkdir()
    with pytest.raises(OSError, match=r"dir\.json"):
        cal.save(tmp_path / "dir.json")  # a directory is in the way
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file", "calib.json", "dir.json"]


def _remote_map(c: Calibration) -> np.ndarray:
    return np.asarray(c.image_to_world(IMAGE), dtype=np.float64)


def test_pickles_and_travels_to_a_worker_process(cal: Calibration) -> None:
    back = pickle.loads(pickle.dumps(cal))
    assert np.array_equal(back.H, cal.H) and back.summary() == cal.summary()
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        remote = pool.apply(_remote_map, (cal,))
    assert np.array_equal(remote, cal.image_to_world(IMAGE))


def test_from_image_on_the_papers_kind_of_board(tmp_path: Path) -> None:
    path = SHARED / "data" / "real" / "boofcv-circle-regular" / "image00003.jpg"
    if not path.exists():
        pytest.skip("../shared is absent")
    c = Calibration.from_image(path, CircleGridBoard(10, 8, 25, 15))
    assert c.image_size == (640, 480) and c.board is not None
    s = c.summary()
    assert s.n_points == 80 and s.mean_px < 0.5
    # The board's own dots map back to where they are to well under a millimetre.
    assert s.loo_max_mm < 1.0
