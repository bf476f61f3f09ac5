"""A part's centroid on the plane from the mapping near its image centroid, to second order
(planarcal.live.local_map): against the centroid of its outline mapped point by point, and
against the truth, on a rendered perspective view."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal import synth
from planarcal.errors import ArgumentError
from planarcal.live.local_map import area_centroids, local_maps
from planarcal.live.objects import _detect

F64 = NDArray[np.float64]


def polygon_centroid(p: F64) -> F64:
    x, y = p[:, 0], p[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = cross.sum() / 2.0
    out: F64 = np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * a)
    return out


@pytest.fixture(scope="module")
def steep() -> synth.RenderedScene:
    """Long parts under a 35 degree tilt through a distorting lens: the image centroid's image
    is far (tenths of a mm) from the part's centroid on the plane."""
    camera = synth.CameraModel(k1=-0.1, k2=0.02)
    pose = synth.PlanePose(distance_mm=450.0, tilt_deg=35.0, tilt_axis_deg=20.0)
    parts = [
        synth.SceneObject("bolt", (-60.0, -30.0), angle_deg=15.0, size_mm=8.0, length_mm=50.0),
        synth.SceneObject("rectangle", (50.0, 20.0), angle_deg=-40.0, size_mm=10.0, length_mm=60.0),
        synth.SceneObject("bolt", (0.0, 60.0), angle_deg=100.0, size_mm=8.0, length_mm=40.0),
    ]
    return synth.render_scene(camera, pose, board=None, objects=parts, blur_sigma_px=0.8)


def test_the_centroid_on_the_plane_is_the_mapped_outline_centroid(
    steep: synth.RenderedScene,
) -> None:
    view = steep
    found = _detect(view.image)
    assert len(found.areas) == 3

    def to_plane(px: F64) -> tuple[F64, None]:
        return np.asarray(view.camera.image_to_plane(px, view.pose), dtype=np.float64), None

    local = local_maps(to_plane, found.centroids)
    plane = area_centroids(local, found.moments)
    exact = np.array([polygon_centroid(to_plane(o)[0]) for o in found.outlines])
    truth = view.object_centroids_mm
    nearest = np.linalg.norm(plane[:, None] - truth[None], axis=2).argmin(axis=1)
    naive_err = np.linalg.norm(local.position - truth[nearest], axis=1)
    err = np.linalg.norm(plane - truth[nearest], axis=1)
    # Second order is the mapped outline's centroid to a hundredth of a mm at this tilt (the
    # third order's share, for parts 60 mm long), and the truth's within 0.05 mm; the image
    # centroid's image is more than a millimetre off.
    np.testing.assert_allclose(plane, exact, atol=0.015)
    assert err.max() < 0.05, err
    assert naive_err.max() > 1.0, naive_err


def test_an_affine_mapping_has_no_correction() -> None:
    a = np.array([[0.5, 0.1], [-0.2, 0.4]])
    c = np.array([[10.0, 20.0], [300.0, 40.0]])
    local = local_maps(lambda p: (p @ a.T + [3.0, -7.0], np.ones(len(p))), c)
    np.testing.assert_allclose(local.jacobian, np.broadcast_to(a, (2, 2, 2)), atol=1e-12)
    np.testing.assert_allclose(local.hessian, 0.0, atol=1e-9)
    np.testing.assert_allclose(area_centroids(local, [[40.0, 5.0, 9.0]] * 2), c @ a.T + [3, -7])
    assert local.std is not None and local.std.shape == (2,)


def test_bad_input_is_refused_by_name() -> None:
    with pytest.raises(ArgumentError, match="centroids_px"):
        local_maps(lambda p: (p, None), np.zeros((3, 3)))
    with pytest.raises(ArgumentError, match="step_px"):
        local_maps(lambda p: (p, None), np.zeros((3, 2)), step_px=-1.0)
    with pytest.raises(ArgumentError, match="one 2-D position per pixel"):
        local_maps(lambda p: (p[:, 0], None), np.zeros((3, 2)))
    local = local_maps(lambda p: (p, None), np.zeros((2, 2)))
    with pytest.raises(ArgumentError, match="moments_px"):
        area_centroids(local, np.zeros((3, 3)))
    empty = local_maps(lambda p: (p, None), np.zeros((0, 2)))
    assert area_centroids(empty, np.zeros((0, 3))).shape == (0, 2)
