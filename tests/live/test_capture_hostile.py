"""Hostile image sources, read through Camera and `planarcal run` on real files: a folder whose
first images cannot be decoded, a frame of another size in the middle, and 16-bit and
4-channel PNGs. Each bad frame is counted and skipped, by name; good frames go on."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from test_tracker import _run as run_command
from test_tracker import render_moving

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.errors import CameraError
from planarcal.live.capture import Camera

GARBAGE = b"\x89PNG\r\n\x1a\n" + b"not an image" * 40


@pytest.fixture(scope="module")
def calibration_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The paper's camera calibrated from a rendered view of its board (1280 x 720)."""
    scene = synth.paper_scene(0).calibration
    calibration = Calibration.from_detection(detect_board(scene.image, synth.PAPER_BOARD))
    return calibration.save(tmp_path_factory.mktemp("calib") / "calib.json")


@pytest.fixture(scope="module")
def frames() -> list[np.ndarray]:
    """Four frames of three parts moving, 1280 x 720 grey."""
    return [render_moving(k).image for k in range(4)]


def write_png(path: Path, image: np.ndarray) -> None:
    assert cv2.imwrite(str(path), image), path


def summary(stderr: str) -> dict[str, Any]:
    figures: dict[str, Any] = json.loads(stderr.rsplit("planarcal run: ", 1)[1])
    return figures


def located(stdout: str) -> list[int]:
    """The frame numbers of the lines that located the three parts."""
    lines = [json.loads(line) for line in stdout.splitlines() if line.strip()]
    assert all(len(line["objects"]) == 3 for line in lines), lines
    return [line["frame"] for line in lines]


def test_run_skips_an_undecodable_first_image(
    calibration_file: Path, frames: list[np.ndarray], tmp_path: Path
) -> None:
    (tmp_path / "frame000.png").write_bytes(GARBAGE)
    for k in (1, 2, 3):
        write_png(tmp_path / f"frame{k:03d}.png", frames[k])
    result = run_command("--source", tmp_path, "--calibration", calibration_file)
    assert result.returncode == 0, result.stderr
    assert located(result.stdout) == [1, 2, 3]
    figures = summary(result.stderr)
    assert (figures["read"], figures["frames"], figures["frames_undecodable"]) == (4, 3, 1)
    assert "cannot decode" in figures["first_fault"] and "frame000.png" in figures["first_fault"]


def test_run_counts_a_frame_of_another_size_and_goes_on(
    calibration_file: Path, frames: list[np.ndarray], tmp_path: Path
) -> None:
    # The camera switched to 640 x 360 for one frame: its pixels would map to the wrong
    # millimetres, so it is skipped and counted, naming both sizes and the file.
    write_png(tmp_path / "frame000.png", frames[0])
    write_png(tmp_path / "frame001.png", frames[1])
    write_png(tmp_path / "frame002.png", cv2.resize(frames[2], (640, 360)))
    write_png(tmp_path / "frame003.png", frames[3])
    result = run_command("--source", tmp_path, "--calibration", calibration_file)
    assert result.returncode == 0, result.stderr
    assert located(result.stdout) == [0, 1, 3]
    figures = summary(result.stderr)
    assert (figures["read"], figures["frames"], figures["frames_wrong_size"]) == (4, 3, 1)
    fault = figures["first_fault"]
    assert "640x360 frame" in fault and "1280x720" in fault and "frame002.png" in fault


def test_undecodable_first_images_are_raised_in_turn_then_the_good_ones(tmp_path: Path) -> None:
    (tmp_path / "img1.png").write_bytes(b"")
    (tmp_path / "img2.jpg").write_bytes(GARBAGE)
    good = np.full((48, 64, 3), 90, np.uint8)
    write_png(tmp_path / "img3.png", good)
    write_png(tmp_path / "img4.png", good + 1)
    with Camera(tmp_path) as cam:
        assert cam.resolution == (64, 48)  # from the first image that decodes
        for name in ("img1.png", "img2.jpg"):
            with pytest.raises(CameraError, match=rf"cannot decode .*{name}.*image \d of 4"):
                cam.read()
        assert np.array_equal(cam.read(), good)
        assert np.array_equal(cam.read(), good + 1)
        assert cam.frames_read == 2
        with pytest.raises(CameraError, match="all its images were read"):
            cam.read()
    # The same through frames(): the first bad image is raised as a later one would be.
    with Camera(tmp_path) as cam, pytest.raises(CameraError, match=r"img1\.png"):
        list(cam.frames())


def test_a_folder_none_of_whose_images_decode_fails_at_open(tmp_path: Path) -> None:
    (tmp_path / "a.png").write_bytes(GARBAGE)
    (tmp_path / "b.png").write_bytes(b"")
    with pytest.raises(CameraError, match=r"none of its 2 images can be decoded.*a\.png"):
        Camera(tmp_path)


def test_16_bit_and_4_channel_pngs_are_read_as_8_bit(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    image = rng.integers(0, 256, (40, 56, 3), dtype=np.uint8)
    # 16-bit full range (65535 is white) and BGRA with a varying alpha, which is dropped.
    write_png(tmp_path / "f1.png", image.astype(np.uint16) * 257)
    alpha = rng.integers(0, 256, (40, 56, 1), dtype=np.uint8)
    write_png(tmp_path / "f2.png", np.concatenate([image, alpha], axis=2))
    write_png(tmp_path / "f3.png", image[:, :, 0].astype(np.uint16) * 257)  # 16-bit grey
    with Camera(tmp_path) as cam:
        assert np.array_equal(cam.read(), image)
        assert np.array_equal(cam.read(), image)
        assert np.array_equal(cam.read(), np.repeat(image[:, :, :1], 3, axis=2))
    with Camera(tmp_path, color=False) as cam:
        grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        # Made grey by the PNG decoder (at 16 bits for the first): within one level.
        assert np.abs(cam.read().astype(int) - grey).max() <= 1
        assert np.abs(cam.read().astype(int) - grey).max() <= 1
        assert np.array_equal(cam.read(), image[:, :, 0])


def test_a_one_pixel_image_is_a_frame_of_another_size(tmp_path: Path) -> None:
    write_png(tmp_path / "p1.png", np.full((48, 64), 7, np.uint8))
    write_png(tmp_path / "p2.png", np.full((1, 1), 7, np.uint8))
    write_png(tmp_path / "p3.png", np.full((48, 64), 9, np.uint8))
    with Camera(tmp_path, color=False) as cam:
        cam.read()
        with pytest.raises(CameraError, match=r"1x1 frame .*p2\.png.* of 64x48"):
            cam.read()
        assert int(cam.read()[0, 0]) == 9
