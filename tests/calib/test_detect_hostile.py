"""detect_board on hostile images: every dtype a grey image comes in (the same dots from
each), values and shapes it cannot use (an ImageError naming what it expects), and images
too large or too noisy for a careless search, run in subprocesses under an address-space
limit and a timeout."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.detect import BoardDetection, detect_board
from planarcal.errors import ImageError
from planarcal.images import as_grey, grey_levels

BOARD = synth.PAPER_BOARD


@pytest.fixture(scope="module")
def board_image() -> np.ndarray:
    """The paper's board, rendered 1280 x 720 grey uint8."""
    image: np.ndarray = synth.paper_scene(0).calibration.image
    assert image.dtype == np.uint8 and image.ndim == 2
    return image


@pytest.fixture(scope="module")
def reference(board_image: np.ndarray) -> BoardDetection:
    return detect_board(board_image, BOARD)


@pytest.mark.parametrize(
    "convert",
    [
        pytest.param(lambda u8: u8.astype(np.float32) / 255.0, id="float32 0..1"),
        pytest.param(lambda u8: u8 / 255.0, id="float64 0..1"),
        pytest.param(lambda u8: u8.astype(np.float16) / np.float16(255), id="float16 0..1"),
        pytest.param(lambda u8: u8.astype(np.float32), id="float32 0..255"),
        pytest.param(lambda u8: u8.astype(np.uint16) * 257, id="uint16 full range"),
        pytest.param(lambda u8: u8.astype(np.int16), id="int16 0..255"),
        pytest.param(lambda u8: u8.astype(np.int64), id="int64 0..255"),
        pytest.param(lambda u8: u8[:, :, None], id="H x W x 1"),
        pytest.param(lambda u8: cv2.cvtColor(u8, cv2.COLOR_GRAY2BGR), id="BGR"),
        pytest.param(lambda u8: cv2.cvtColor(u8, cv2.COLOR_GRAY2BGRA), id="BGRA"),
        pytest.param(lambda u8: np.asfortranarray(u8), id="Fortran order"),
    ],
)
def test_every_dtype_gives_the_same_dots(
    board_image: np.ndarray, reference: BoardDetection, convert: object
) -> None:
    assert callable(convert)
    image = convert(board_image)
    found = detect_board(image, BOARD)
    # float16 holds 0..1 to 11 bits: a few thousandths of a grey level off.
    tol = 2e-2 if image.dtype == np.float16 else 1e-3
    assert np.abs(found.image_points - reference.image_points).max() <= tol
    assert found.image_size == reference.image_size


def test_16_bit_and_4_channel_png_files(
    board_image: np.ndarray, reference: BoardDetection, tmp_path: Path
) -> None:
    sixteen = tmp_path / "board16.png"
    assert cv2.imwrite(str(sixteen), board_image.astype(np.uint16) * 257)
    stored = cv2.imread(str(sixteen), cv2.IMREAD_UNCHANGED)
    assert stored is not None and stored.dtype == np.uint16
    bgra = tmp_path / "board_bgra.png"
    alpha = np.random.default_rng(1).integers(0, 256, board_image.shape, dtype=np.uint8)
    assert cv2.imwrite(str(bgra), np.dstack([board_image] * 3 + [alpha]))
    for path in (sixteen, bgra):
        found = detect_board(path, BOARD)
        assert np.abs(found.image_points - reference.image_points).max() <= 1e-3, path


def test_grey_levels_scale_each_dtype_to_0_255() -> None:
    levels = np.array([[0, 51, 102], [153, 204, 255]] * 4, dtype=np.uint8)
    expected = levels.astype(np.float32)
    for image in (
        levels,
        levels / 255.0,
        levels.astype(np.uint16) * 257,
        levels.astype(np.int32),
        levels.astype(np.float32),
    ):
        assert np.allclose(as_grey(np.tile(image, (1, 3))), np.tile(expected, (1, 3)), atol=1e-4)
    on = np.zeros((8, 9), dtype=bool)
    on[2:5, 3:7] = True
    assert np.array_equal(grey_levels(on), np.where(on, 255, 0))
    # An 8-bit grey image is read as it is, not copied.
    u8 = np.zeros((10, 12), np.uint8)
    assert grey_levels(u8) is u8


@pytest.mark.parametrize(
    ("image", "message"),
    [
        (np.full((20, 20), np.nan, np.float32), r"NaN or infinite.*0\.\.1 or 0\.\.255"),
        (np.full((20, 20), np.inf), r"NaN or infinite"),
        (np.full((20, 20), -0.5), r"from -0\.5 to -0\.5; a float image .*0\.\.1 .*0\.\.255"),
        (np.linspace(0, 1000, 400).reshape(20, 20), r"from 0 to 1000; a float image"),
        (np.full((20, 20), -3, np.int16), r"\(int16\) holds values from -3.*uint16 \(full range\)"),
        (np.full((20, 20), 4096, np.int32), r"\(int32\) holds values from 4096"),
        (np.zeros((20, 20), np.complex64), r"must hold numbers, got dtype complex64"),
        (np.zeros((20, 20), object), r"must hold numbers, got dtype object"),
        (np.zeros((0, 640), np.uint8), r"empty \(shape \(0, 640\)\)"),
        (np.zeros((480, 0, 3), np.uint8), r"empty"),
        (np.zeros((1, 1), np.uint8), r"too small to show a board \(1 x 1\)"),
        (np.zeros((5, 400), np.uint8), r"too small"),
        (np.zeros((20, 20, 2), np.uint8), r"H x W x 4 \(BGRA\), got shape \(20, 20, 2\)"),
        (np.zeros((20, 20, 3, 1), np.uint8), r"got shape \(20, 20, 3, 1\)"),
        (np.zeros(400, np.uint8), r"got shape \(400,\)"),
        ([[0, 1], [1, 0]], r"NumPy array or a path, got list"),
    ],
)
def test_images_it_cannot_use_are_named(image: object, message: str) -> None:
    with pytest.raises(ImageError, match=message):
        detect_board(image, BOARD)


def test_nan_in_the_colour_of_a_bgra_image_is_refused_but_not_in_its_alpha() -> None:
    image = np.full((20, 20, 4), 0.5, np.float32)
    image[:, :, 3] = np.nan  # alpha is not used
    assert np.allclose(grey_levels(image), 127.5)
    image[3, 4, 1] = np.nan
    with pytest.raises(ImageError, match="NaN"):
        grey_levels(image)


def _run_python(code: str, timeout_s: float) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        check=False,
    )


def test_a_large_image_is_searched_within_a_few_times_its_size() -> None:
    """A 6000 x 6000 frame (36 MB), white with dark bars, under an address-space limit of
    400 MB beyond what the process holds: the search used to need over 800 MB of address
    space beyond the image (float copies of the whole frame, two levels' 32-bit labels at
    once, OpenCV's per-thread statistics); it needs about 250 (threads' stacks included)."""
    result = _run_python(
        """
        import resource, time
        import numpy as np
        from planarcal import synth
        from planarcal.calib.detect import detect_board
        from planarcal.errors import BoardNotFoundError

        image = np.full((6000, 6000), 255, np.uint8)
        image[:, ::100] = 100
        image[:, 1::100] = 100
        status = open("/proc/self/status").read().split("VmSize:")[1]
        in_use = int(status.split()[0]) * 1024
        resource.setrlimit(resource.RLIMIT_AS, (in_use + 400 * 2**20, resource.RLIM_INFINITY))
        try:
            detect_board(image, synth.PAPER_BOARD)
        except BoardNotFoundError as e:
            print("not found:", str(e)[:60])
        """,
        timeout_s=120,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.startswith("not found: no 14 x 10 circle grid"), result.stdout


def test_a_large_noise_image_is_searched_in_bounded_time() -> None:
    """4000 x 4000 uniform noise: a million components at each grey level. About 7 s of
    CPU here; the bound leaves room for a loaded machine, not for a search that grows with
    the shapes in view."""
    result = _run_python(
        """
        import numpy as np
        from planarcal import synth
        from planarcal.calib.detect import detect_board
        from planarcal.errors import BoardNotFoundError

        noise = np.random.default_rng(0).integers(0, 256, (4000, 4000), dtype=np.uint8)
        try:
            detect_board(noise, synth.PAPER_BOARD)
        except BoardNotFoundError as e:
            print("not found:", str(e)[:60])
        """,
        timeout_s=240,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.startswith("not found: no 14 x 10 circle grid"), result.stdout
