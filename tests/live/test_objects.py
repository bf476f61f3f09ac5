"""Object location: the paper's chain on rendered scenes whose truth is known."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.errors import ImageError
from planarcal.live.objects import board_region_px, detect_objects, locate_objects


@pytest.fixture(scope="module")
def scene() -> synth.PaperScene:
    return synth.paper_scene(seed=3)


@pytest.fixture(scope="module")
def cal(scene: synth.PaperScene) -> Calibration:
    return Calibration.from_image(scene.calibration.image, synth.PAPER_BOARD)


def test_every_object_is_found_at_its_true_place(scene: synth.PaperScene) -> None:
    objects = detect_objects(scene.objects.image)
    truth = scene.objects.object_centroids_px
    assert len(objects) == len(truth) == 10
    for o in objects:
        gap = np.linalg.norm(truth - np.array(o.centroid_px), axis=1).min()
        assert gap < 0.5, o.id  # px, from edges traced through blur and noise
        assert o.contour_px.ndim == 2 and o.contour_px.shape[1] == 2
        assert o.area_px > 100 and o.world_mm is None


def test_located_in_millimetres(scene: synth.PaperScene, cal: Calibration) -> None:
    located = locate_objects(scene.objects.image, cal)
    truth = scene.objects.object_centroids_mm
    gaps = []
    for o in located:
        assert o.world_mm is not None
        gaps.append(np.linalg.norm(truth - np.array(o.world_mm), axis=1).min())
    # The homography cannot follow the lens's barrel distortion: a few tenths of a mm.
    assert len(gaps) == 10 and max(gaps) < 0.6 and np.mean(gaps) < 0.4


def test_ids_follow_reading_order(scene: synth.PaperScene) -> None:
    objects = detect_objects(scene.objects.image)
    assert [o.id for o in objects] == list(range(1, 11))
    ys = [o.centroid_px[1] for o in objects]
    # Rows from the top: an object never starts a row above the previous row's first.
    typical = np.median([o.bbox_px[3] for o in objects])
    for a, b in itertools.pairwise(objects):
        if abs(a.centroid_px[1] - b.centroid_px[1]) <= 0.5 * typical:
            assert a.centroid_px[0] < b.centroid_px[0]  # same row: left to right
    assert ys[0] <= min(ys) + 0.5 * typical
    # The same scene with other noise gives the same IDs to the same objects.
    again = detect_objects(synth.paper_scene(seed=4).objects.image)
    assert [round(o.centroid_px[0] / 20) for o in again] == [
        round(o.centroid_px[0] / 20) for o in objects
    ]


def test_filters(scene: synth.PaperScene) -> None:
    image = scene.objects.image
    all_objects = detect_objects(image)
    # Area limits: the bolts' outlines are about 1150 px^2 here, the nuts' about 640.
    areas = np.array([o.area_px for o in all_objects])
    assert ((areas > 900) == (areas > 1000)).all()  # two clear groups
    bolts = detect_objects(image, min_area_px=900)
    nuts = detect_objects(image, max_area_px=900)
    assert len(bolts) == (areas > 900).sum() == 3 and len(nuts) == 7
    assert all(o.area_px > 900 for o in bolts) and all(o.area_px <= 900 for o in nuts)
    # A mask keeps the objects whose centre it covers.
    mask = np.zeros(image.shape[:2], np.uint8)
    mask[:, : image.shape[1] // 2] = 1
    left = detect_objects(image, mask=mask)
    assert 0 < len(left) < 10 and all(o.centroid_px[0] < image.shape[1] / 2 for o in left)
    # Excluded polygons drop what lies inside them.
    first = all_objects[0]
    x, y, w, h = first.bbox_px
    box = [(x - 2, y - 2), (x + w + 2, y - 2), (x + w + 2, y + h + 2), (x - 2, y + h + 2)]
    rest = detect_objects(image, exclude_polygons=[box])
    assert len(rest) == 9 and all(o.centroid_px != first.centroid_px for o in rest)


def test_objects_cut_by_the_border_are_not_reported(scene: synth.PaperScene) -> None:
    """Half an object would report half an object's centroid: it is not an object."""
    image = scene.objects.image
    whole = detect_objects(image)
    first = whole[0]
    x, _, w, _ = first.bbox_px
    left = x + w // 2
    cut = np.ascontiguousarray(image[:, left:])  # slices through the first object
    for keep in (False, True):
        kept = detect_objects(cut, keep_border=keep)
        inside = [o for o in whole if o.bbox_px[0] > left]
        assert len(kept) == len(inside)
        for o in kept:  # each reported object is a whole one, where it was
            gaps = [
                np.hypot(
                    o.centroid_px[0] + left - i.centroid_px[0], o.centroid_px[1] - i.centroid_px[1]
                )
                for i in inside
            ]
            assert min(gaps) < 1e-6


def test_the_board_region_can_be_ignored() -> None:
    """Objects beside a board in one picture: the board's dots are not objects. (The table
    is as light as the paper, so no paper outline encloses the dots.)"""
    objects = (synth.SceneObject("nut", (300.0, 60.0)), synth.SceneObject("bolt", (310.0, 140.0)))
    pose = synth.PlanePose(distance_mm=560, look_at_mm=(170, 95))
    view = synth.render_scene(
        synth.CameraModel(),
        pose,
        board=synth.PAPER_BOARD,
        objects=objects,
        table_grey=225,
        paper_grey=225,
        metal_grey=60,
        blur_sigma_px=0.8,
        noise_sigma=1.0,
        seed=1,
    )
    detection = detect_board(view.image, synth.PAPER_BOARD)
    region = board_region_px(detection)
    found = detect_objects(view.image, exclude_polygons=[region])
    assert len(found) == 2
    truth = view.object_centroids_px
    for o in found:
        assert np.linalg.norm(truth - np.array(o.centroid_px), axis=1).min() < 0.5
    assert len(detect_objects(view.image)) == 2 + 140  # without it, every dot is an object


def test_bad_input() -> None:
    with pytest.raises(ImageError, match="empty"):
        detect_objects(np.zeros((0, 0), np.uint8))
    with pytest.raises(ImageError, match="mask"):
        detect_objects(np.zeros((50, 60), np.uint8), mask=np.ones((10, 10)))
    with pytest.raises(ImageError, match="blur_sigma"):
        detect_objects(np.zeros((50, 60), np.uint8), blur_sigma=-1)
    assert detect_objects(np.full((50, 60), 128, np.uint8)) == []
