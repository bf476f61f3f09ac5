"""The production loop's one core call per frame (_core.part_samples, _core.part_poses): the
same centroids and axes as planarcal.live.local_map and part_angle give step by step, and bad
input refused by name."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal import _core, synth
from planarcal.errors import ArgumentError
from planarcal.live.local_map import STEP_PX, area_centroids, centre_block, local_maps
from planarcal.live.objects import _detect
from planarcal.live.part_angle import part_axes

F64 = NDArray[np.float64]


def test_one_call_gives_what_the_steps_give_on_a_steep_view() -> None:
    camera = synth.CameraModel(k1=-0.1, k2=0.02)
    pose = synth.PlanePose(distance_mm=450.0, tilt_deg=35.0, tilt_axis_deg=20.0)
    parts = [
        synth.SceneObject("bolt", (-60.0, -30.0), angle_deg=15.0, size_mm=8.0, length_mm=50.0),
        synth.SceneObject("rectangle", (50.0, 20.0), angle_deg=-40.0, size_mm=10.0, length_mm=60.0),
        synth.SceneObject("disc", (0.0, 60.0), size_mm=20.0),
    ]
    view = synth.render_scene(camera, pose, board=None, objects=parts, blur_sigma_px=0.8)
    found = _detect(view.image, outlines=False)
    assert len(found.areas) == 3

    def to_plane(px: F64) -> F64:
        return np.asarray(view.camera.image_to_plane(px, view.pose), dtype=np.float64)

    samples = _core.part_samples(found.centroids, STEP_PX)
    assert samples.shape == (21, 2)
    np.testing.assert_array_equal(centre_block(samples, 3), found.centroids)
    mm, jac, angles, axes, anisotropy, sigma = _core.part_poses(
        to_plane(samples), found.moments, found.areas, STEP_PX
    )
    local = local_maps(lambda p: (to_plane(p), None), found.centroids)
    steps = part_axes(found.moments, found.areas, local.jacobian)
    np.testing.assert_array_equal(mm, area_centroids(local, found.moments))
    np.testing.assert_array_equal(jac, local.jacobian)
    np.testing.assert_array_equal(angles, steps.angles_deg)
    np.testing.assert_allclose(axes, steps.axes_px, atol=1e-15)
    np.testing.assert_array_equal(anisotropy, steps.anisotropy)
    np.testing.assert_array_equal(sigma, steps.sigma_deg)
    # The two elongated parts have an axis, the disc none; the centroids are near the truth.
    assert np.isfinite(angles).sum() == 2
    truth = view.object_centroids_mm
    assert np.linalg.norm(mm[:, None] - truth[None], axis=2).min(axis=1).max() < 0.05


def test_a_sample_without_an_image_leaves_only_its_part_without_a_pose() -> None:
    moments = np.array([[140.0, 20.0, 10.0]] * 2)
    samples = _core.part_samples([[10.0, 10.0], [50.0, 10.0]], 1.0) * 0.5
    samples[4] = np.nan  # the first part's -x sample
    mm, jac, angles, axes, anisotropy, sigma = _core.part_poses(samples, moments, [400.0] * 2, 1.0)
    assert np.isnan(mm[0]).all() and np.isnan(angles[0]) and np.isnan(axes[0]).all()
    assert math.isnan(anisotropy[0]) and math.isnan(sigma[0])
    np.testing.assert_allclose(mm[1], [25.0, 5.0])
    np.testing.assert_allclose(jac[1], 0.5 * np.eye(2))
    assert math.isfinite(angles[1])


def test_bad_input_is_refused_by_name() -> None:
    ok_samples, ok_moments, ok_areas = np.zeros((14, 2)), np.ones((2, 3)), np.ones(2)
    with pytest.raises(ArgumentError, match="centroids_px"):
        _core.part_samples(np.zeros((3, 3)), 1.0)
    for step in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ArgumentError, match="step_px"):
            _core.part_samples(np.zeros((3, 2)), step)
        with pytest.raises(ArgumentError, match="step_px"):
            _core.part_poses(ok_samples, ok_moments, ok_areas, step)
    with pytest.raises(ArgumentError, match=r"samples_mm.*7 per part, 2 parts"):
        _core.part_poses(np.zeros((13, 2)), ok_moments, ok_areas, 1.0)
    with pytest.raises(ArgumentError, match="moments_px"):
        _core.part_poses(ok_samples, np.ones((2, 2)), ok_areas, 1.0)
    with pytest.raises(ArgumentError, match="areas_px"):
        _core.part_poses(ok_samples, ok_moments, np.ones(3), 1.0)
    with pytest.raises(ArgumentError, match="samples_mm"):
        _core.part_poses(np.array([["a", "b"]] * 14), ok_moments, ok_areas, 1.0)
    with pytest.raises(ArgumentError, match="7 mapped points per part"):
        _core.local_maps(np.zeros((8, 2)), 1.0)
    with pytest.raises(ArgumentError, match="hessians"):
        _core.area_centroids(np.zeros((2, 2)), np.zeros((2, 2, 2)), np.zeros((2, 3)), ok_moments)
    # No parts: empty arrays of the right shapes.
    out = _core.part_poses(np.zeros((0, 2)), np.zeros((0, 3)), np.zeros(0), 1.0)
    assert [a.shape for a in out] == [(0, 2), (0, 2, 2), (0,), (0, 2), (0,), (0,)]
