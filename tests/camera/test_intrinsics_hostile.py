"""Intrinsics files that OpenCV's parser would read as something else, or that are no file:
each refused at once with an IntrinsicsError naming the problem. Real files written here (a
ROS camera_info YAML, OpenCV FileStorage YAML and JSON), a real FIFO, /dev/zero."""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.camera import CameraIntrinsics
from planarcal.camera.file_storage import MAX_FILE_BYTES
from planarcal.errors import IntrinsicsError
from planarcal.synth import paper_data

K = [[900.0, 0.0, 640.0], [0.0, 900.0, 360.0], [0.0, 0.0, 1.0]]
QUICK_S = 1.0


def _load(path: Path | str) -> CameraIntrinsics:
    start = time.perf_counter()
    try:
        return CameraIntrinsics.load_yaml(path)
    finally:
        assert time.perf_counter() - start < QUICK_S, f"loading {path} took too long"


def _camera_info(
    path: Path, model: str, coeffs: list[float], width: str = "1280", k: str = ""
) -> Path:
    """A ROS camera_info calibration file, as camera_calibration_parsers writes it."""
    data = k or str([v for row in K for v in row])
    path.write_text(
        f"image_width: {width}\nimage_height: 720\ncamera_name: webcam\ncamera_matrix:\n"
        f"  rows: 3\n  cols: 3\n  data: {data}\ndistortion_model: {model}\n"
        f"distortion_coefficients:\n  rows: 1\n  cols: {len(coeffs)}\n  data: {coeffs}\n"
        "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
        "projection_matrix:\n  rows: 3\n  cols: 4\n"
        "  data: [900, 0, 640, 0, 0, 900, 360, 0, 0, 0, 1, 0]\n"
    )
    return path


# -- 5. lens models other than OpenCV's standard one ----------------------------------------


def test_a_ros_fisheye_camera_info_is_refused(tmp_path: Path) -> None:
    path = _camera_info(tmp_path / "fisheye.yaml", "equidistant", [0.1, 0.01, -0.002, 0.0005])
    with pytest.raises(
        IntrinsicsError,
        match=r"fisheye\.yaml': distortion_model 'equidistant' \(the fisheye model\) is not "
        "supported: .* plumb_bob or rational_polynomial",
    ):
        _load(path)
    path = _camera_info(tmp_path / "other.yaml", "kannala_brandt", [0.1, 0.01, 0.0, 0.0])
    with pytest.raises(IntrinsicsError, match="distortion_model 'kannala_brandt' is not supported"):
        _load(path)


def test_ros_camera_info_of_opencvs_models_loads(tmp_path: Path) -> None:
    coeffs = [-0.1, 0.02, 0.001, -0.001, 0.003]
    got = _load(_camera_info(tmp_path / "plumb_bob.yaml", "plumb_bob", coeffs))
    assert np.array_equal(got.matrix, K) and got.dist_coeffs.tolist() == coeffs
    assert got.image_size == (1280, 720)
    rational = [-0.1, 0.02, 0.001, -0.001, 0.003, 0.01, 0.002, 0.0001]
    got = _load(_camera_info(tmp_path / "rational.yaml", "rational_polynomial", rational))
    assert got.dist_coeffs.tolist() == rational
    # A model whose name and coefficients disagree is not guessed at.
    with pytest.raises(IntrinsicsError, match="'plumb_bob' has 4 or 5 distortion coefficients"):
        _load(_camera_info(tmp_path / "eight.yaml", "plumb_bob", rational))


def test_an_opencv_fisheye_calibration_is_refused(tmp_path: Path) -> None:
    # OpenCV's calibration sample writes fisheye_model: 1 for cv2.fisheye's 4 coefficients.
    path = tmp_path / "out_camera_data.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("nr_of_frames", 12)
    fs.write("image_width", 1280)
    fs.write("image_height", 720)
    fs.write("fisheye_model", 1)
    fs.write("camera_matrix", np.array(K))
    fs.write("distortion_coefficients", np.array([[0.1], [0.01], [-0.002], [0.0005]]))
    fs.release()
    with pytest.raises(IntrinsicsError, match=r"fisheye_model is 1: the fisheye lens model"):
        _load(path)
    # The same file of the standard model loads.
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 1280)
    fs.write("image_height", 720)
    fs.write("fisheye_model", 0)
    fs.write("camera_matrix", np.array(K))
    fs.write("distortion_coefficients", np.zeros((5, 1)))
    fs.release()
    assert _load(path).image_size == (1280, 720)


# -- 2. and 3. numbers that are not numbers, sizes beyond any camera, nesting ---------------


@pytest.mark.parametrize(
    ("width", "match"),
    [
        ("1e18", r"image_size 1000000000000000000 x 720 px is beyond any camera"),
        # OpenCV 5 reads it as a clamped integer, OpenCV 4 fails an assertion on it.
        ("9" * 401, "image_width is an integer too large to read|OpenCV cannot read its nodes"),
        ('"1280"', r"image_width is not a number \(it is the text '1280'\)"),
        ("true", "line 1: image_width holds true or false where a number belongs"),
        (".nan", "image_width is nan, not a finite number"),
    ],
)
def test_sizes_that_are_not_sizes_are_refused(tmp_path: Path, width: str, match: str) -> None:
    path = _camera_info(tmp_path / "camera.yaml", "plumb_bob", [0.0] * 5, width=width)
    with pytest.raises(IntrinsicsError, match=match):
        _load(path)


def test_booleans_and_nesting_in_matrices_are_refused(tmp_path: Path) -> None:
    path = _camera_info(
        tmp_path / "bool.yaml", "plumb_bob", [0.0] * 5, k="[true, 0, 640, 0, 900, 360, 0, 0, 1]"
    )
    with pytest.raises(IntrinsicsError, match="line 7: data holds true or false"):
        _load(path)
    deep = "[" * 5000 + "]" * 5000
    path = _camera_info(tmp_path / "deep.yaml", "plumb_bob", [0.0] * 5, k=deep)
    # OpenCV 4 parses it and planarcal refuses the node; OpenCV 5 refuses the nesting itself.
    nested = r"camera_matrix\.data is nested too deeply|Too many nested collections"
    with pytest.raises(IntrinsicsError, match=nested):
        _load(path)
    doc = {
        "image_width": 1280,
        "image_height": True,
        "camera_matrix": K,
        "distortion_coefficients": [0.0] * 5,
    }
    path = tmp_path / "bool.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(IntrinsicsError, match="image_height holds true or false"):
        _load(path)
    path.write_text('{"camera_matrix": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(IntrinsicsError, match="nested too deeply"):
        _load(path)


def test_intrinsics_json_fields_are_checked_strictly() -> None:
    good = CameraIntrinsics(np.array(K), np.zeros(5), (1280, 720)).to_dict()
    for key, value, match in (
        ("camera_matrix", [[10**400, 0, 640], [0, 900, 360], [0, 0, 1]], "beyond a float"),
        ("camera_matrix", [[[900.0]] * 3] * 3, "must be .*numbers"),
        ("dist_coeffs", [0, 0, 0, "0"], "dist_coeffs must be"),
        ("image_size_px", [10**18, 720], "beyond any camera"),
        ("image_size_px", [True, 720], "image width must be a whole number"),
    ):
        with pytest.raises(IntrinsicsError, match=match):
            CameraIntrinsics.from_dict({**good, key: value})


# -- 4. what is not a regular file ----------------------------------------------------------


def test_a_fifo_a_device_a_directory_and_a_huge_file_are_refused(tmp_path: Path) -> None:
    fifo = tmp_path / "camera.yaml"
    os.mkfifo(fifo)
    # If reading ever blocked, a writer opening the FIFO after 5 s ends it: a failure, no hang.
    unblock = threading.Timer(5.0, lambda: os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)))
    unblock.start()
    try:
        with pytest.raises(IntrinsicsError, match=r"camera\.yaml' is not a regular file: .*FIFO"):
            _load(fifo)
    finally:
        unblock.cancel()
    with pytest.raises(IntrinsicsError, match=r"'/dev/zero' is not a regular file: .*device"):
        _load("/dev/zero")
    with pytest.raises(IntrinsicsError, match="is not a regular file: it is a directory"):
        _load(tmp_path)
    big = tmp_path / "big.yaml"
    with big.open("wb") as f:
        f.truncate(MAX_FILE_BYTES + 1)
    with pytest.raises(IntrinsicsError, match=r"big\.yaml' is over 4 MiB"):
        _load(big)


# -- 6. a calibration given for intrinsics --------------------------------------------------


def test_a_planarcal_calibration_is_named(tmp_path: Path) -> None:
    cal = Calibration(
        np.array(paper_data.WORLD_MM),
        np.array(paper_data.IMAGE_PX),
        board=CircleGridBoard(),
        image_size=(1280, 720),
        lens="none",
    )
    path = cal.save(tmp_path / "calib.json")
    with pytest.raises(
        IntrinsicsError,
        match=r"calib\.json' is a planarcal calibration .* pass it with --calibration",
    ):
        _load(path)
    with pytest.raises(IntrinsicsError, match="is a planarcal calibration, not camera intrinsics"):
        CameraIntrinsics.from_dict(cal.to_dict())
