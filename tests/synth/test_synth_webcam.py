"""Random webcam scenes (planarcal.synth.webcam): the lens's distortion centre where it is
asked to be, webcam-sized coefficients, parts apart from each other and where the truth
says, and the same scene for the same seed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planarcal.errors import ArgumentError, ImageError
from planarcal.synth.webcam import MAX_TANGENTIAL, random_webcam_scene, webcam_camera


def test_webcam_lenses_are_decentred_within_the_range_asked_for() -> None:
    rng = np.random.default_rng(0)
    offsets = []
    for _ in range(50):
        cam = webcam_camera(rng, (640, 480))
        offsets.append(math.hypot(cam.cx - 319.5, cam.cy - 239.5))
        assert -0.2 <= cam.k1 <= -0.05 and 0.0 <= cam.k2 <= 0.05
        assert max(abs(cam.p1), abs(cam.p2)) <= MAX_TANGENTIAL and cam.tangential
    assert 0.0 <= min(offsets) < 5.0 and 35.0 < max(offsets) <= 40.0
    cam = webcam_camera(rng, (1280, 720), centre_offset_px=40.0)
    assert math.hypot(cam.cx - 639.5, cam.cy - 359.5) == pytest.approx(40.0)
    with pytest.raises(ArgumentError, match="centre_offset_px"):
        webcam_camera(rng, centre_offset_px=-1.0)


def test_a_webcam_scene_shows_its_parts_where_the_truth_says() -> None:
    pair = random_webcam_scene(3, size=(640, 480), parts=8)
    again = random_webcam_scene(3, size=(640, 480), parts=8)
    np.testing.assert_array_equal(pair.objects.image, again.objects.image)
    np.testing.assert_array_equal(pair.calibration.image, again.calibration.image)
    assert pair.calibration.board is not None and pair.objects.board is None
    assert pair.calibration.camera == pair.objects.camera
    centres = pair.objects.object_centroids_mm
    assert len(centres) == 8
    gaps = np.hypot(*(centres[:, None] - centres[None]).transpose(2, 0, 1))
    assert gaps[~np.eye(8, dtype=bool)].min() > 10.0
    # Bright metal (170) on the dark table (100) at the projected centroid of every part
    # without a hole; the table through the hole of the others.
    image = pair.objects.image.astype(np.float64)
    centroids = np.rint(pair.objects.object_centroids_px).astype(int)
    for part, (x, y) in zip(pair.objects.objects, centroids, strict=True):
        holed = part.hole_diameter_mm is not None
        assert (image[y, x] < 130) if holed else (image[y, x] > 140), part
    with pytest.raises(ImageError, match="seed"):
        random_webcam_scene(-1)
