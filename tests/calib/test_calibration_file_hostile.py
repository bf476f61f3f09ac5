"""Calibration files that are wrong in every way a file can be: each refused at once with a
CalibrationFileError that names the problem, never loaded as a different calibration, never
a hang, a crash or another exception. Real files on disk, a real FIFO, /dev/zero."""

from __future__ import annotations

import copy
import functools
import json
import math
import os
import threading
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.calibration_file import FILE_VERSION, MAX_FILE_BYTES
from planarcal.camera import CameraIntrinsics
from planarcal.errors import CalibrationFileError
from planarcal.synth import paper_data
from synthetic import examples

WORLD = np.array(paper_data.WORLD_MM)
IMAGE = np.array(paper_data.IMAGE_PX)
K_WEBCAM = [[900.0, 0.0, 640.0], [0.0, 900.0, 360.0], [0.0, 0.0, 1.0]]
V2_FILE = Path(__file__).resolve().parents[1] / "robot" / "data" / "calibration_v2.json"

# A hang guard, not a speed figure (speed is the benches'): a file of the paper's board loads
# in milliseconds, so only a load that hangs or goes quadratic takes this long, even on a
# machine loaded by other suites (a 1 s bound failed there once).
QUICK_S = 30.0


@pytest.fixture(scope="module")
def plain() -> Calibration:
    """The paper's 28 points, a homography alone, with its board and image size."""
    return Calibration(WORLD, IMAGE, board=CircleGridBoard(), image_size=(1280, 720), lens="none")


@pytest.fixture(scope="module")
def registered(plain: Calibration) -> Calibration:
    """The same, registered to a robot turned by 30 degrees and moved (file version 3)."""
    dots = [0, 13, 126, 139, 60]
    board_mm = CircleGridBoard().world_points()[dots]
    turn = math.radians(30.0)
    rotation = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    robot_mm = board_mm @ rotation.T + [250.0, -120.0]
    return plain.register(robot_mm, dots=dots)


@pytest.fixture(scope="module")
def with_intrinsics() -> Calibration:
    """The paper's points undistorted by a full camera model (lens model "intrinsics")."""
    camera = CameraIntrinsics(
        np.array([[1000.0, 0.0, 640.0], [0.0, 1000.0, 360.0], [0.0, 0.0, 1.0]]),
        np.array([-0.05, 0.01, 0.0, 0.0, 0.0]),
        (1280, 720),
    )
    return Calibration(WORLD, IMAGE, image_size=(1280, 720), intrinsics=camera)


def _load_text(path: Path, text: str) -> Calibration:
    path.write_text(text)
    return _timed_load(path)


def _timed_load(path: Path | str) -> Calibration:
    start = time.perf_counter()
    try:
        return Calibration.load(path)
    finally:
        assert time.perf_counter() - start < QUICK_S, f"loading {path} took too long"


def _refused(path: Path, data: Any, match: str) -> None:
    with pytest.raises(CalibrationFileError, match=match):
        _load_text(path, json.dumps(data))


# -- 1. a homography and points that do not belong together --------------------------------


def test_moved_points_are_refused(plain: Calibration, tmp_path: Path) -> None:
    data = plain.to_dict()
    data["points"]["image_px"][3][0] += 500.0
    _refused(
        tmp_path / "moved.json",
        data,
        r"do not belong together: .* reprojection error of .* worst at point 3 \(500\.\d+ px\)",
    )


def test_an_edited_homography_is_refused(plain: Calibration, tmp_path: Path) -> None:
    data = plain.to_dict()
    data["homography_world_mm_to_image_px"][0][2] += 0.01  # a hundredth of a pixel
    _refused(tmp_path / "h.json", data, "do not belong together")
    data = plain.to_dict()
    identity = [[i == j for j in range(3)] for i in range(3)]
    data["homography_world_mm_to_image_px"] = identity
    _refused(tmp_path / "bools.json", data, r"not a finite 3 x 3 matrix: \[0\]\[0\] is true")


def test_an_edited_lens_is_refused(tmp_path: Path) -> None:
    # The v2 fixture has a fitted radial lens: its points are distorted pixels, and the
    # stored residuals are those of H and the lens together.
    good = json.loads(V2_FILE.read_text())
    assert good["lens_model"] == "k1k2c"
    data = copy.deepcopy(good)
    data["lens"]["k1"] *= 1.01
    _refused(tmp_path / "k1.json", data, "do not belong together")
    data = copy.deepcopy(good)
    data["lens_model"] = "none"  # the same H and points read without their lens
    _refused(tmp_path / "nolens.json", data, "do not belong together")
    data = copy.deepcopy(good)
    data["lens"]["centre_px"] = "12"  # read once as the centre (1, 2)
    _refused(tmp_path / "centre.json", data, r"lens.centre_px must be \[x, y\]: it is '12'")
    data = copy.deepcopy(good)
    data["lens"]["k2"] = "0.006"
    _refused(tmp_path / "k2.json", data, "lens.k2 must be a finite number, got '0.006'")
    data = copy.deepcopy(good)
    data["lens"]["model"] = "k1"
    _refused(tmp_path / "model.json", data, "lens.model 'k1' is not lens_model 'k1k2c'")


def test_edited_intrinsics_are_refused(with_intrinsics: Calibration, tmp_path: Path) -> None:
    back = _load_text(tmp_path / "ok.json", json.dumps(with_intrinsics.to_dict()))
    assert back.lens_model == "intrinsics" and back.intrinsics == with_intrinsics.intrinsics
    data = with_intrinsics.to_dict()
    data["intrinsics"]["dist_coeffs"][0] = -0.06
    _refused(tmp_path / "k1.json", data, "do not belong together")
    data = with_intrinsics.to_dict()
    data["intrinsics"]["image_size_px"] = [640, 360]
    _refused(tmp_path / "size.json", data, r"image_size_px \[1280, 720\] is not the intrinsics'")


@pytest.mark.parametrize(
    ("path", "value"),
    [
        (("intrinsics", "camera_matrix", 0, 0), 5e-324),
        (("intrinsics", "camera_matrix", 0, 1), 1e18),
        (("intrinsics", "camera_matrix", 1, 2), 1e308),
        (("intrinsics", "dist_coeffs", 0), -1e308),
    ],
)
def test_numbers_that_overflow_are_refused_without_numpy_warnings(
    with_intrinsics: Calibration, tmp_path: Path, path: tuple[Any, ...], value: float
) -> None:
    """An edit whose arithmetic overflows before the check that refuses it: the refusal says
    what is wrong, and NumPy's RuntimeWarnings about the intermediate values (which the
    hostile-edit properties once printed in CI) stay out of the user's console."""
    file = tmp_path / "overflow.json"
    file.write_text(json.dumps(_replaced(with_intrinsics.to_dict(), path, value)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(CalibrationFileError):
            Calibration.load(file)


def test_a_file_without_its_residuals_is_refused(plain: Calibration, tmp_path: Path) -> None:
    data = plain.to_dict()
    del data["summary"]
    _refused(tmp_path / "nosummary.json", data, "has no summary")
    data = plain.to_dict()
    data["summary"]["n_points"] = 27
    _refused(tmp_path / "count.json", data, "summary.n_points is 27 but the file holds 28")


# -- 2. wrong types and absurd sizes -------------------------------------------------------


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda d: d.update(world_scale="12"), r"world_scale must be two factors: it is '12'"),
        (lambda d: d.update(world_scale=[1, True]), r"world_scale.*\[1\] is true"),
        (lambda d: d.update(image_size_px=[10**18, 720]), r"image_size_px .* from 1 to 1000000"),
        (lambda d: d.update(image_size_px=[True, 720]), r"image_size_px .* got \[True, 720\]"),
        (lambda d: d.update(image_size_px="1280"), r"image_size_px must be \[width, height\]"),
        (lambda d: d["board"].update(cols=10**9, rows=10**9), "board.cols must be .* 2 to 1000"),
        (lambda d: d["board"].update(cols=True), "board.cols must be a whole number"),
        (lambda d: d["board"].update(pitch_mm="20"), "board.pitch_mm must be a number of mm"),
        (lambda d: d["board"].update(origin_marker="yes"), "board.origin_marker must be true"),
        (lambda d: d["board"].update(cols=3, rows=3), "the board has 9 dots .* but the file 28"),
        (lambda d: d["points"]["world_mm"][0].__setitem__(0, "0"), r"world_mm: \[0\]\[0\] is '0'"),
        (
            lambda d: d["points"]["image_px"].__setitem__(2, [1.0]),
            r"image_px: \[2\] is a list of 1",
        ),
        (lambda d: d.update(refine="true"), "refine must be true or false"),
        (lambda d: d.update(solver=["normalized_dlt"]), "unknown solver"),
        (lambda d: d.update(version=True), "version true"),
        (lambda d: d.update(version=3.0), r"version 3\.0; this planarcal .* reads versions"),
        (lambda d: d["summary"].update(rms_px="0.5"), r"summary.rms_px must be .* got '0.5'"),
        (lambda d: d.update(lens_candidates="none"), "lens_candidates must be a list"),
        (lambda d: d.update(lens_note=7), "lens_note must be a string"),
        (lambda d: d.update(lens_model=True), "lens_model true is unknown"),
    ],
)
def test_wrong_types_and_sizes_are_refused(
    plain: Calibration, tmp_path: Path, edit: Callable[[dict[str, Any]], None], match: str
) -> None:
    data = plain.to_dict()
    edit(data)
    _refused(tmp_path / "edited.json", data, match)


# -- 3. what the JSON parser itself cannot take ---------------------------------------------


def test_deep_nesting_and_huge_numbers_are_refused(plain: Calibration, tmp_path: Path) -> None:
    text = json.dumps(plain.to_dict())
    deep = '{"format": "planarcal-calibration", "a": ' + "[" * 100_000 + "]" * 100_000 + "}"
    with pytest.raises(CalibrationFileError, match="nested too deeply"):
        _load_text(tmp_path / "deep.json", deep)
    huge = text.replace(f'"version": {FILE_VERSION}', '"version": ' + "9" * 401)
    with pytest.raises(CalibrationFileError, match="an integer of 401 digits"):
        _load_text(tmp_path / "huge.json", huge)
    huge = text.replace('"world_mm": [[', '"world_mm": [[' + "1" * 401 + ", ", 1)
    with pytest.raises(CalibrationFileError, match="an integer of 401 digits"):
        _load_text(tmp_path / "huge2.json", huge)
    with pytest.raises(CalibrationFileError, match="holds NaN, which is not a JSON number"):
        _load_text(tmp_path / "nan.json", text.replace('"rms_px": ', '"rms_px": NaN, "x": ', 1))
    with pytest.raises(CalibrationFileError, match="holds -Infinity"):
        _load_text(tmp_path / "inf.json", text.replace("[[", "[[-Infinity, ", 1))
    # Deeper than any field, but not too deep for the parser: refused by the field's shape.
    data = plain.to_dict()
    nested: Any = 1.0
    for _ in range(500):
        nested = [nested]
    data["homography_world_mm_to_image_px"][1] = nested
    with pytest.raises(CalibrationFileError, match=r"not a finite 3 x 3 matrix: \[1\] is"):
        _load_text(tmp_path / "nested.json", json.dumps(data))


# -- 4. what is not a regular file ----------------------------------------------------------


def test_a_fifo_a_device_and_a_directory_are_refused_at_once(tmp_path: Path) -> None:
    fifo = tmp_path / "calib.json"
    os.mkfifo(fifo)
    # A writer that never comes: reading the FIFO would block for ever. The timer reopens it
    # for writing after 5 s so a regression fails the test instead of hanging the run.
    unblock = threading.Timer(5.0, lambda: os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)))
    unblock.start()
    try:
        with pytest.raises(
            CalibrationFileError, match=r"calib\.json' is not a regular file: .*FIFO"
        ):
            _timed_load(fifo)
    finally:
        unblock.cancel()
    with pytest.raises(CalibrationFileError, match=r"'/dev/zero' is not a regular file: .*device"):
        _timed_load("/dev/zero")
    with pytest.raises(CalibrationFileError, match="is not a regular file: it is a directory"):
        _timed_load(tmp_path)
    big = tmp_path / "big.json"
    with big.open("wb") as f:
        f.truncate(MAX_FILE_BYTES + 1)  # sparse: no disk, no time
    with pytest.raises(CalibrationFileError, match=r"big\.json' is over 16 MiB"):
        _timed_load(big)


# -- 6. files from other tools --------------------------------------------------------------


def test_intrinsics_files_are_recognised(tmp_path: Path) -> None:
    camera = CameraIntrinsics(np.array(K_WEBCAM), np.zeros(5), (1280, 720))
    for suffix, kind in ((".yaml", "OpenCV YAML"), (".xml", "OpenCV XML"), (".json", "JSON")):
        path = camera.save_yaml(tmp_path / f"camera{suffix}")
        with pytest.raises(CalibrationFileError, match=rf"looks like camera intrinsics \({kind}\)"):
            _timed_load(path)
    ros = tmp_path / "camera_info.yaml"
    ros.write_text(
        "image_width: 1280\nimage_height: 720\ncamera_name: webcam\ncamera_matrix:\n  rows: 3\n"
        "  cols: 3\n  data: [900, 0, 640, 0, 900, 360, 0, 0, 1]\ndistortion_model: plumb_bob\n"
        "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n"
    )
    with pytest.raises(CalibrationFileError, match="pass it with --intrinsics"):
        _timed_load(ros)
    fs = cv2.FileStorage(str(tmp_path / "other.yaml"), cv2.FILE_STORAGE_WRITE)
    fs.write("threshold", 3)
    fs.release()
    with pytest.raises(CalibrationFileError, match="is a YAML file, not a planarcal calibration"):
        _timed_load(tmp_path / "other.yaml")


def test_json_of_another_kind_is_named(tmp_path: Path) -> None:
    with pytest.raises(
        CalibrationFileError,
        match=r'is a JSON file but not a planarcal calibration \(no "format" field\); make one '
        "with `planarcal calibrate`",
    ):
        _load_text(tmp_path / "settings.json", '{"threshold": 3}')
    with pytest.raises(CalibrationFileError, match=r"its format is 'planarcal.robot_frame'"):
        _load_text(tmp_path / "frame.json", '{"format": "planarcal.robot_frame", "version": 1}')
    with pytest.raises(CalibrationFileError, match="not a JSON object but a list"):
        _load_text(tmp_path / "list.json", "[1, 2]")
    with pytest.raises(CalibrationFileError, match=r"not valid JSON .*: the file is empty"):
        _load_text(tmp_path / "empty.json", "")
    with pytest.raises(CalibrationFileError, match=r"not valid JSON .*: it is not UTF-8 text"):
        (tmp_path / "binary.json").write_bytes(bytes(range(256)))
        _timed_load(tmp_path / "binary.json")


# -- what still loads ----------------------------------------------------------------------


def test_every_kind_of_good_file_still_loads(
    plain: Calibration, registered: Calibration, with_intrinsics: Calibration, tmp_path: Path
) -> None:
    for name, cal in (("plain", plain), ("registered", registered), ("cam", with_intrinsics)):
        back = _timed_load(cal.save(tmp_path / f"{name}.json"))
        assert np.array_equal(back.H, cal.H) and back.summary() == cal.summary(), name
    old = _timed_load(V2_FILE)
    assert old.lens_model == "k1k2c" and old.stats.max == pytest.approx(0.0154073, rel=1e-5)


# -- the property: no edit of one value gives anything but a refusal or the same mapping ----

MAPPING_TOLERANCE = 1e-4
"""px in the image, mm on the plane or in the robot's frame."""

REPLACEMENTS = st.one_of(
    st.text(max_size=6),
    st.booleans(),
    st.none(),
    st.sampled_from([10**400, -(10**400), 10**18, 0, -1, 2**63]),
    st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -0.0, 5e-324]),
    st.recursive(st.just(1), lambda inner: st.lists(inner, min_size=1, max_size=2), max_leaves=4),
    st.just({"a": 1}),
)


def _leaves(data: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """The path of every leaf (and of every empty list or object) of a JSON document."""
    if isinstance(data, dict) and data:
        return [p for k, v in data.items() for p in _leaves(v, (*path, k))]
    if isinstance(data, list) and data:
        return [p for i, v in enumerate(data) for p in _leaves(v, (*path, i))]
    return [path]


def _replaced(data: Any, path: tuple[Any, ...], value: Any) -> Any:
    out = copy.deepcopy(data)
    target = out
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    return out


def _mutation_property(cal: Calibration, tmp_path: Path, data: st.DataObject) -> None:
    original = cal.to_dict()
    path = data.draw(st.sampled_from(_leaves(original)), label="path")
    value = data.draw(
        st.one_of(
            REPLACEMENTS,
            # A nearby number: only a value no mapping depends on may change unnoticed.
            st.floats(-1e-3, 1e-3).map(functools.partial(_nudged, original, path)),
        ),
        label="value",
    )
    file = tmp_path / "mutated.json"
    file.write_text(json.dumps(_replaced(original, path, value)))  # NaN written as NaN
    try:
        loaded = _timed_load(file)
    except CalibrationFileError:
        return
    # The same mapping. Not bit for bit: a number nudged in its last digits changes the
    # residuals by less than the check's 1e-6 px and loads; what it moves is far below any
    # measurement (MAPPING_TOLERANCE: a dot centre is known to 0.01 px at best).
    px = cal.image_points[::3]
    tol = MAPPING_TOLERANCE
    np.testing.assert_allclose(
        loaded.image_to_world(px), cal.image_to_world(px), rtol=0, atol=tol, err_msg=str(path)
    )
    world = cal.world_points
    np.testing.assert_allclose(
        loaded.world_to_image(world), cal.world_to_image(world), rtol=0, atol=tol, err_msg=str(path)
    )
    if loaded.robot_frame is not None:
        assert cal.robot_frame is not None
        np.testing.assert_allclose(
            loaded.image_to_world(px, frame="robot"),
            cal.image_to_world(px, frame="robot"),
            rtol=0,
            atol=tol,
            err_msg=str(path),
        )


def _nudged(original: Any, path: tuple[Any, ...], delta: float) -> Any:
    value = original
    for key in path:
        value = value[key]
    if isinstance(value, bool) or not isinstance(value, int | float):
        return delta
    return value * (1.0 + delta) + delta


@settings(max_examples=examples(150))
@given(data=st.data())
def test_one_edited_value_is_refused_or_changes_no_mapping(
    registered: Calibration, tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
) -> None:
    _mutation_property(registered, tmp_path_factory.mktemp("mutated"), data)


@settings(max_examples=examples(60))
@given(data=st.data())
def test_one_edited_value_of_a_camera_model_is_refused_or_changes_no_mapping(
    with_intrinsics: Calibration, tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
) -> None:
    _mutation_property(with_intrinsics, tmp_path_factory.mktemp("mutated"), data)


@settings(max_examples=examples(40))
@given(data=st.data())
def test_one_edited_value_of_a_radial_lens_is_refused_or_changes_no_mapping(
    tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
) -> None:
    _mutation_property(_v2(), tmp_path_factory.mktemp("mutated"), data)


@functools.cache
def _v2() -> Calibration:
    return Calibration.load(V2_FILE)
