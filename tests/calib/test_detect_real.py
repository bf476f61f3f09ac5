"""Board detection on the real photographs in ../shared/data/real (BoofCV-Data, CC BY 4.0,
Peter Abeles): a 10 x 8 grid of 15 mm dots, 25 mm apart, tilted, on a clipboard, lit unevenly.
OpenCV's findCirclesGrid finds 4 of the 6 with its default flags."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

import planarcal
from conftest import SHARED, RecordProperty
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.detect import detect_board
from planarcal.errors import BoardNotFoundError, ImageError

REAL = SHARED / "data" / "real" / "boofcv-circle-regular"
BOARD = CircleGridBoard(cols=10, rows=8, pitch=25.0, diameter=15.0)
IMAGES = [f"image0000{i}.jpg" for i in range(6)]


def _photo(name: str) -> Path:
    path = REAL / name
    if not path.exists():
        pytest.skip(f"the real photographs are not here ({REAL}): ../shared is absent")
    return path


def _read(path: Path, flags: int = cv2.IMREAD_COLOR) -> NDArray[np.uint8]:
    image = cv2.imread(str(path), flags)
    assert image is not None, f"cannot read {path}"
    return np.asarray(image, dtype=np.uint8)


def _symmetries(grid: np.ndarray) -> list[np.ndarray]:
    return [grid, grid[::-1], grid[:, ::-1], grid[::-1, ::-1]]


@pytest.mark.parametrize("name", IMAGES)
def test_every_real_photograph_is_detected_in_the_boards_order(
    name: str, record_property: RecordProperty
) -> None:
    path = _photo(name)
    det = detect_board(path, BOARD)
    pts = det.image_points
    assert pts.shape == (80, 2) and pts.dtype == np.float64
    assert det.image_size == (640, 480)
    grid = pts.reshape(8, 10, 2)
    # Unmirrored: X along a row and Y down a column turn the same way as in the image.
    x_step, y_step = grid[4, 5] - grid[4, 4], grid[5, 4] - grid[4, 4]
    assert x_step[0] * y_step[1] - x_step[1] * y_step[0] > 0
    # The stated rule: point 0 is the unmirrored reading's corner nearest the image's top-left.
    corners = [grid[0, 0], grid[-1, -1]]  # the two unmirrored readings' origins
    assert np.hypot(*corners[0]) <= np.hypot(*corners[1])
    # The same dots OpenCV's clustering finder sees, up to a re-reading of the grid.
    grey = _read(path, cv2.IMREAD_GRAYSCALE)
    flags = cv2.CALIB_CB_SYMMETRIC_GRID | cv2.CALIB_CB_CLUSTERING
    found, cv_pts = cv2.findCirclesGrid(grey, (10, 8), flags=flags)
    assert found
    cv_grid = cv_pts.reshape(8, 10, 2).astype(np.float64)
    gaps = [np.abs(g - grid).max() for g in _symmetries(cv_grid)]
    assert min(gaps) < 1.5, "a different grid from OpenCV's"
    assert (
        np.median(np.linalg.norm(_symmetries(cv_grid)[int(np.argmin(gaps))] - grid, axis=-1)) < 0.2
    )
    # Residuals of a homography through the centres: the paper is not flat and the lens
    # distorts, so they are not zero; OpenCV's centres give 0.23-0.51 px mean.
    world = BOARD.world_points()
    h = planarcal.estimate_homography(world, pts, refine=True)
    errors = planarcal.reprojection_errors(h, world, pts)
    record_property("residual_mean_px", float(errors.mean()))
    print(
        f"{name}: {det.method} finder, residual mean {errors.mean():.3f} px, "
        f"RMS {det.residual_rms_px:.3f} px"
    )
    assert errors.mean() < 0.6
    assert det.residual_rms_px == pytest.approx(np.sqrt(np.mean(errors**2)), rel=1e-6)


def test_dot_sizes_are_measured() -> None:
    det = detect_board(_photo("image00003.jpg"), BOARD)
    d = det.dot_diameters_px
    assert d.shape == (80,)
    # 15 mm dots 25 mm apart: diameters about 0.6 of the local pitch.
    assert 0.45 < np.median(d) / det.pitch_px < 0.75


def test_the_wrong_board_size_is_refused_with_what_was_seen() -> None:
    path = _photo("image00003.jpg")
    with pytest.raises(BoardNotFoundError) as err:
        detect_board(path, CircleGridBoard(14, 10, 20, 10))
    message = str(err.value)
    assert "14 x 10" in message and "140 dots" in message
    assert "80 dark dots" in message
    assert "fewer dots than the board has" in message
    with pytest.raises(BoardNotFoundError, match="80 dark dots"):
        detect_board(path, CircleGridBoard(8, 8, 25, 15))


def test_a_board_partly_out_of_view_is_refused() -> None:
    image = _read(_photo("image00003.jpg"))
    cropped = image[:, : image.shape[1] // 2]
    with pytest.raises(BoardNotFoundError, match="fewer dots than the board has"):
        detect_board(cropped, BOARD)


def test_light_dots_on_a_dark_board_are_found() -> None:
    image = _read(_photo("image00001.jpg"))
    dark = detect_board(image, BOARD)
    light = detect_board(255 - image, BOARD)
    assert light.polarity == "light" and dark.polarity == "dark"
    assert np.abs(light.image_points - dark.image_points).max() < 0.05
    with pytest.raises(BoardNotFoundError, match="polarity 'light'"):
        detect_board(255 - image, BOARD, polarity="dark")


def test_no_board_in_view() -> None:
    rng = np.random.default_rng(0)
    texture = cv2.GaussianBlur(rng.uniform(0, 255, (480, 640)).astype(np.uint8), (0, 0), 3)
    with pytest.raises(BoardNotFoundError, match="no 10 x 8 circle grid"):
        detect_board(texture, BOARD)
    with pytest.raises(BoardNotFoundError):
        detect_board(np.full((480, 640), 200, np.uint8), BOARD)


@pytest.mark.parametrize(
    ("image", "match"),
    [
        (np.zeros((0, 0), np.uint8), "empty"),
        (np.zeros((480, 640, 2), np.uint8), "shape"),
        (np.full((480, 640), np.nan, np.float32), "NaN"),
        (np.zeros((4, 4), np.uint8), "too small"),
        ("no/such/file.png", "no image file"),
        (np.array([["a"]]), "numbers"),
        (42, "array or a path"),
    ],
)
def test_unusable_images_are_refused(image: object, match: str) -> None:
    with pytest.raises(ImageError, match=match):
        detect_board(image, BOARD)


def test_unreadable_image_files(tmp_path: Path) -> None:
    empty = tmp_path / "empty.png"
    empty.write_bytes(b"")
    with pytest.raises(ImageError, match="empty"):
        detect_board(empty, BOARD)
    junk = tmp_path / "junk.jpg"
    junk.write_bytes(b"\xff\xd8\xff not really a jpeg")
    with pytest.raises(ImageError, match="not an image OpenCV can decode"):
        detect_board(junk, BOARD)
    # Truncated: a real JPEG cut in half decodes partly or not at all, never silently wrong.
    real = _photo("image00003.jpg").read_bytes()
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(real[: len(real) // 3])
    try:
        det = detect_board(cut, BOARD)
    except (ImageError, BoardNotFoundError):
        return
    assert det.residual_rms_px < 1.0  # if it decodes enough to find the board, it is right
