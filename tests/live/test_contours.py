"""The core's per-frame object measurement (planarcal._core.measure_contours, median_grey,
reading_order, Tracks) against OpenCV's own measures and plain NumPy, and its refusals."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planarcal import _core, synth

MIN_AREA, MAX_AREA = 50.0, 1e9


def scene_contours(seed: int = 3) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    image = synth.paper_scene(seed).objects.image
    u8 = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    edges = cv2.Canny(cv2.GaussianBlur(u8, (0, 0), 1.5), 30, 60, L2gradient=True)
    contours, _ = cv2.findContours(edges, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    return u8, tuple(contours)


def test_traced_measures_are_opencvs_moments_and_bounding_boxes() -> None:
    u8, contours = scene_contours()
    index, area, centroid, bbox, outlines, moments = _core.measure_contours(
        u8, contours, MIN_AREA, MAX_AREA, keep_border=True, subpixel=False
    )
    assert len(index) >= 5
    assert moments.shape == (len(index), 3) and moments.dtype == np.float64
    for k, i in enumerate(index):
        m = cv2.moments(contours[i])
        assert area[k] == pytest.approx(m["m00"], rel=1e-12)
        assert centroid[k] == pytest.approx([m["m10"] / m["m00"], m["m01"] / m["m00"]], abs=1e-9)
        # The enclosed area's central moments (Green's theorem), as OpenCV's over its area.
        central = np.array([m["mu20"], m["mu11"], m["mu02"]]) / m["m00"]
        np.testing.assert_allclose(moments[k], central, rtol=1e-9, atol=1e-9)
        assert tuple(bbox[k]) == cv2.boundingRect(contours[i])
        np.testing.assert_array_equal(outlines[k], contours[i].reshape(-1, 2))
    # Every contour OpenCV measures inside the limits is there, none twice.
    expected = {i for i, c in enumerate(contours) if MIN_AREA <= cv2.moments(c)["m00"] <= MAX_AREA}
    assert sorted(index.tolist()) == sorted(expected)


def test_subpixel_outlines_move_to_the_edge_inside_the_traced_pixels() -> None:
    u8, contours = scene_contours()
    traced = _core.measure_contours(u8, contours, MIN_AREA, MAX_AREA, subpixel=False)
    refined = _core.measure_contours(u8, contours, MIN_AREA, MAX_AREA, subpixel=True)
    np.testing.assert_array_equal(traced[0], refined[0])
    moved = [np.abs(a - b).max() for a, b in zip(traced[4], refined[4], strict=True)]
    # Moved, by less than the search's reach of 3 px.
    assert all(0 < m <= 3.0 for m in moved)
    # The centroids move by a fraction of a pixel (the outline's shifts average out).
    shift = np.hypot(*(refined[2] - traced[2]).T)
    assert (shift > 0).all() and (shift < 0.5).all()


def test_contours_touching_the_border_are_dropped_unless_kept() -> None:
    u8 = np.full((40, 50), 90, np.uint8)
    square = np.array([[0, 5], [20, 5], [20, 25], [0, 25]], np.int32).reshape(-1, 1, 2)
    inner = square + np.array([10, 5], np.int32)
    for keep, want in ((False, [1]), (True, [0, 1])):
        index = _core.measure_contours(u8, (square, inner), 1.0, 1e6, keep)[0]
        assert sorted(index.tolist()) == want


def test_bad_arguments_are_refused_by_name() -> None:
    u8, contours = scene_contours()
    with pytest.raises(ValueError, match="grey must be an 8-bit"):
        _core.measure_contours(u8.astype(np.float32), contours, 1.0, 1e6)
    with pytest.raises(ValueError, match="two-dimensional"):
        _core.measure_contours(np.zeros((4, 4, 3), np.uint8), contours, 1.0, 1e6)
    with pytest.raises(ValueError, match=r"contours\[1\] must be an int32 array"):
        _core.measure_contours(u8, [contours[0], contours[1].astype(np.float64)], 1.0, 1e6)
    with pytest.raises(ValueError, match=r"contours\[0\] must have shape"):
        _core.measure_contours(u8, [np.zeros((5, 3), np.int32)], 1.0, 1e6)
    with pytest.raises(ValueError, match="min_area"):
        _core.measure_contours(u8, contours, float("nan"), 1e6)
    # A strided view of the frame is read as the frame it shows.
    wide = np.zeros((u8.shape[0], 2 * u8.shape[1]), np.uint8)
    wide[:, ::2] = u8
    a = _core.measure_contours(u8, contours, MIN_AREA, MAX_AREA)
    b = _core.measure_contours(wide[:, ::2], contours, MIN_AREA, MAX_AREA)
    np.testing.assert_array_equal(a[2], b[2])


@settings(max_examples=40, deadline=None)
@given(
    st.integers(1, 40),
    st.integers(1, 40),
    st.integers(1, 17),
    st.integers(1, 9),
    st.integers(0, 2**32 - 1),
)
def test_median_grey_is_numpys_median_of_the_sample(
    w: int, h: int, rows: int, cols: int, seed: int
) -> None:
    image = np.random.default_rng(seed).integers(0, 256, (h, w), dtype=np.uint8)
    sample = np.sort(image[::rows, ::cols].ravel())
    assert _core.median_grey(image, rows, cols) == sample[(len(sample) - 1) // 2]


def test_median_grey_refuses_a_zero_step_and_other_images() -> None:
    with pytest.raises(ValueError, match="step"):
        _core.median_grey(np.zeros((3, 3), np.uint8), 0, 1)
    with pytest.raises(ValueError, match="8-bit"):
        _core.median_grey(np.zeros((3, 3)), 2)


def test_reading_order_is_rows_from_the_top_then_left_to_right() -> None:
    centroids = np.array([[50.0, 31.0], [10.0, 12.0], [30.0, 9.0], [5.0, 33.0], [70.0, 10.0]])
    heights = np.full(5, 10.0)
    assert _core.reading_order(centroids, heights).tolist() == [1, 2, 4, 3, 0]
    assert _core.reading_order(np.zeros((0, 2)), np.zeros(0)).tolist() == []
    with pytest.raises(ValueError, match="one value per centroid"):
        _core.reading_order(centroids, heights[:3])


def test_tracks_keep_ids_and_end_unseen_ones() -> None:
    tracks = _core.Tracks(5.0, 1)
    assert tracks.update(np.array([[0.0, 0.0], [10.0, 0.0]])).tolist() == [1, 2]
    assert tracks.update(np.array([[11.0, 1.0], [1.0, 1.0]])).tolist() == [2, 1]
    assert tracks.update(np.zeros((0, 2))).tolist() == []
    assert len(tracks) == 2
    tracks.update(np.zeros((0, 2)))
    assert len(tracks) == 0
    ids, mm = tracks.live()
    assert ids.shape == (0,) and mm.shape == (0, 2)
    assert tracks.update(np.array([[1.0, 1.0]])).tolist() == [3]
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="max_jump"):
            _core.Tracks(bad, 1)
    with pytest.raises(ValueError, match="positions"):
        tracks.update(np.zeros((3, 3)))
