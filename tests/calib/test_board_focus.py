"""planarcal.calib.board_focus: focus and exposure measured on rendered boards of known blur
and exposure, detected as the live page detects them."""

from __future__ import annotations

import dataclasses
import functools
import json
import math

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal import synth
from planarcal.calib.board_focus import (
    BLURRED_MIN_PX,
    SHARP_MAX_PX,
    BoardFocus,
    board_focus,
)
from planarcal.calib.detection import BoardDetection, detect_board
from planarcal.errors import ArgumentError, ArgumentTypeError, ImageError
from planarcal.synth.cell import cell_board

KINDS = ("circles", "chessboard", "charuco")
BLURS = (0.5, 1.0, 2.0)
PIXEL_SIGMA = math.sqrt(1.0 / 12.0)
"""The render's own blur: each pixel averages its square's area (a box of variance 1/12)."""


@functools.cache
def _render(kind: str, blur: float, **options: float) -> NDArray[np.uint8]:
    scene = synth.render_scene(
        board=cell_board(kind),
        blur_sigma_px=blur,
        noise_sigma=1.0,
        seed=7,
        supersample=4 if kind == "circles" else 1,
        **options,  # type: ignore[arg-type]
    )
    return scene.image


@functools.cache
def _scene(kind: str, blur: float) -> tuple[NDArray[np.uint8], BoardDetection]:
    image = _render(kind, blur)
    return image, detect_board(image, cell_board(kind))


def _expected_width(blur: float) -> float:
    """The 10-90 % width of a step blurred by a Gaussian and the pixel's own area."""
    return 2.5631 * math.sqrt(blur**2 + PIXEL_SIGMA**2)


@pytest.mark.parametrize("kind", KINDS)
def test_edge_width_follows_the_blur(kind: str) -> None:
    found = {blur: board_focus(*_scene(kind, blur)) for blur in BLURS}
    widths = [found[blur].edge_width_px for blur in BLURS]
    assert all(math.isfinite(w) for w in widths)
    assert widths == sorted(widths) and widths[-1] > 2.0 * widths[0]
    # A ChArUco board's white margins (here 5 px between a square and its marker) bound the
    # plateau a profile can see, so its widths fall short as the blur nears that margin.
    checked = (0.5, 1.0) if kind == "charuco" else (1.0, 2.0)
    for blur in checked:
        assert found[blur].edge_width_px == pytest.approx(_expected_width(blur), rel=0.25)
    if kind != "charuco":
        for blur in (1.0, 2.0):
            assert found[blur].edge_width_px == pytest.approx(_expected_width(blur), rel=0.08)
    assert all(f.profiles >= 50 for f in found.values())
    # Sharp to blurred as the blur rises; the advice names the width.
    assert found[0.5].focus == "sharp" and found[0.5].edge_width_px <= SHARP_MAX_PX
    assert found[2.0].focus == "blurred" and found[2.0].edge_width_px >= BLURRED_MIN_PX
    assert found[0.5].exposure == "good" and found[0.5].advice is None
    advice = found[2.0].advice
    assert advice is not None and "focus" in advice
    assert f"{found[2.0].edge_width_px:.1f} px" in advice


@pytest.mark.parametrize("kind", KINDS)
def test_exposure_dark_and_saturated(kind: str) -> None:
    image, _ = _scene(kind, 1.0)
    board = cell_board(kind)
    verdicts = {}
    for gain in (0.25, 1.0, 1.6):
        frame = np.clip(np.rint(image * gain), 0, 255).astype(np.uint8)
        verdicts[gain] = board_focus(frame, detect_board(frame, board))
    normal = verdicts[1.0]
    assert normal.exposure == "good" and normal.clipped_bright == 0.0
    assert 0.6 < normal.contrast < 0.85  # paper 225, ink 35: 0.75 less blur and noise
    dark = verdicts[0.25]
    assert dark.exposure == "dark"
    assert dark.contrast == pytest.approx(0.25 * normal.contrast, abs=0.02)
    assert dark.advice is not None and "raise the exposure" in dark.advice
    # The focus is the same focus, only darker.
    assert dark.edge_width_px == pytest.approx(normal.edge_width_px, rel=0.1)
    bright = verdicts[1.6]
    assert bright.exposure in ("clipped", "bright") and bright.clipped_bright > 0.1
    assert bright.advice is not None and "lower the exposure" in bright.advice
    # Clipped paper cuts every edge's ramp short: no width is better than a false "sharp".
    assert bright.focus == "unknown" and math.isnan(bright.edge_width_px)
    assert bright.to_dict()["edge_width_px"] is None


def test_little_contrast_is_flat() -> None:
    image = _render("chessboard", 1.0, ink_grey=175.0)
    found = board_focus(image, detect_board(image, cell_board("chessboard")))
    assert found.exposure == "flat" and found.contrast < 0.25
    assert found.focus == "soft"  # the edges still measure: 2.7 px at sigma 1
    assert found.advice is not None and "contrast" in found.advice


def test_a_colour_frame_reads_as_its_grey() -> None:
    image, detection = _scene("circles", 1.0)
    grey = board_focus(image, detection)
    colour = board_focus(cv2.cvtColor(image, cv2.COLOR_GRAY2BGR), detection)
    assert colour == grey


def test_light_dots_on_a_dark_board() -> None:
    image = _render("circles", 1.0, light_on_dark=True)
    found = board_focus(image, detect_board(image, cell_board("circles")))
    dark_on_light = board_focus(*_scene("circles", 1.0))
    assert found.edge_width_px == pytest.approx(dark_on_light.edge_width_px, rel=0.05)
    assert found.contrast == pytest.approx(dark_on_light.contrast, abs=0.03)


def test_to_dict_is_json() -> None:
    found = board_focus(*_scene("chessboard", 2.0))
    data = json.loads(json.dumps(found.to_dict(), allow_nan=False))
    assert data["focus"] == "blurred" and data["exposure"] == "good"
    assert data["edge_width_px"] == pytest.approx(found.edge_width_px, abs=1e-3)
    assert set(data) >= {
        "edge_width_px",
        "contrast",
        "clipped_dark",
        "clipped_bright",
        "focus",
        "exposure",
        "advice",
    }
    assert isinstance(found, BoardFocus)


def test_bad_input_raises_clear_errors() -> None:
    image, detection = _scene("chessboard", 1.0)
    with pytest.raises(ArgumentError, match="no board detection"):
        board_focus(image, None)  # type: ignore[arg-type]
    with pytest.raises(ArgumentTypeError, match="BoardDetection"):
        board_focus(image, "chessboard")  # type: ignore[arg-type]
    with pytest.raises(ImageError, match="uint8"):
        board_focus(image.astype(np.float32), detection)
    with pytest.raises(ImageError, match="NumPy array"):
        board_focus(image.tolist(), detection)
    with pytest.raises(ImageError, match="shape"):
        board_focus(np.zeros((*image.shape, 4), np.uint8), detection)
    with pytest.raises(ImageError, match="detection was made on"):
        board_focus(image[:, :640], detection)
    outside = detection.image_points.copy()
    outside[5] += (2000.0, 0.0)
    with pytest.raises(ArgumentError, match="outside") as caught:
        board_focus(image, dataclasses.replace(detection, image_points=outside))
    assert caught.value.index == 5
    not_finite = detection.image_points.copy()
    not_finite[3, 1] = np.nan
    with pytest.raises(ArgumentError, match="point 3"):
        board_focus(image, dataclasses.replace(detection, image_points=not_finite))
    empty = dataclasses.replace(detection, image_points=np.zeros((0, 2)), ids=np.zeros(0, np.intp))
    with pytest.raises(ArgumentError, match="0 point"):
        board_focus(image, empty)
    for exc in (ArgumentError, ImageError):
        assert issubclass(exc, ValueError)
