"""The mapping from pixels to the output frame near each part, to second order, and what it
gives: the part's position as the centroid of its area *on the plane*, and (through its
Jacobian) its axis (planarcal.live.part_angle).

A part's centroid is measured in the image (the centroid of the area its outline encloses).
Perspective and the lens stretch one side of a part's image more than the other, so the image
of the plane's centroid is not the image's centroid: mapping the image centroid puts an
elongated part off by a tenth of a pixel or two (0.05-0.09 mm for the demo's 30 mm bolts
under a few degrees of tilt, beyond everything else in the chain). The centroid on the plane
is the area integral of the mapped point weighted by the mapping's area scale |det J|:

    X = f(c) + J M g + 1/2 H : M,

to second order in the part's size, with M the image area's central second moments, J and H
the mapping's first and second derivatives at the image centroid c, and g the gradient of
log |det J|. On the demo's parts it agrees with the centroid of the outline mapped point by
point to 0.0006 mm, and the bolts' errors fall from 0.09 to 0.01-0.03 mm; for 40-60 mm parts
under a 35 degree tilt (tests/live/test_local_map.py) from 0.3-1.3 mm to 0.03 mm at most,
within 0.012 mm of the mapped outline's centroid (the third order's share).

The derivatives come from differences of the very mapping the positions go through (one call
on 7 points per part: the centroid, a step either side along x and y, and a step either way
along the diagonal), so they hold whatever the mapping composes (a lens model, a lift to the
parts' height, a registration to a robot's frame). Their error is the step squared times the
mapping's next derivative: negligible at a pixel.

The arithmetic (the sample points, the differences, the centroid's formula) is the Rust core's
(planarcal_core::part_pose, through ``_core.part_samples``, ``_core.local_maps`` and
``_core.area_centroids``); this module calls the mapping between them. The production loop
goes through ``_core.part_poses``, which does all of it and the axis in one call.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import _core
from planarcal.errors import ArgumentError

F64 = NDArray[np.float64]

__all__ = ["SAMPLES_PER_PART", "STEP_PX", "LocalMap", "area_centroids", "local_maps"]

STEP_PX = 1.0
"""The differences' step, px: far below the scale on which the mapping bends, far above the
digits the subtraction loses (1e-16 of a position of a few hundred mm)."""

SAMPLES_PER_PART: int = _core.SAMPLES_PER_PART
"""The mapping's sample points per part (``_core.part_samples``): the centroid, +x, -x, +y,
-y, and +x+y, -x-y (for the cross derivative), in blocks of one point per part."""

Mapping = Callable[[F64], tuple[ArrayLike, ArrayLike | None]]
"""Pixels (N, 2) -> (positions in the output frame (N, 2), their 1-sigma (N,) or None)."""


class LocalMap(NamedTuple):
    """The mapping at each part's image centroid, one row per part."""

    position: F64
    """(n, 2) the centroid's image in the output frame (the image centroid mapped)."""
    std: F64 | None
    """(n,) its 1-sigma, when the mapping gives one."""
    jacobian: F64
    """(n, 2, 2) d(out)/d(px): jacobian[k, i, j] = d out_i / d px_j."""
    hessian: F64
    """(n, 2, 3) the second derivatives of each output coordinate: [d2/dx2, d2/dxdy, d2/dy2]."""


def local_maps(mapping: Mapping, centroids_px: ArrayLike, step_px: float = STEP_PX) -> LocalMap:
    """The mapping, its Jacobian and second derivatives at each centroid (one call of
    `mapping` on the 7 n sample points). NaN where a sample point has no image."""
    samples = _core.part_samples(centroids_px, step_px)
    n = len(samples) // SAMPLES_PER_PART
    if n == 0:
        return LocalMap(np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2, 2)), np.zeros((0, 2, 3)))
    mapped, std = mapping(samples)
    out = checked_mapped(mapped, len(samples))
    position, jacobian, hessian = _core.local_maps(out, step_px)
    centre_std = None if std is None else centre_block(std, n)
    return LocalMap(position, centre_std, jacobian, hessian)


def area_centroids(local: LocalMap, moments_px: ArrayLike) -> F64:
    """Each part's centroid on the plane (n, 2), from its image area's central second moments
    (n, 3: [mu20, mu11, mu02] / area, px^2) and the mapping near its image centroid: see the
    module docstring. NaN where it is not finite."""
    return _core.area_centroids(local.position, local.jacobian, local.hessian, moments_px)


def checked_mapped(mapped: ArrayLike, count: int) -> F64:
    """The mapping's positions for `count` sample points as float64 (count, 2), else an
    ArgumentError naming the shape it returned."""
    out = np.asarray(mapped, dtype=np.float64)
    if out.shape != (count, 2):
        raise ArgumentError(
            f"the mapping must return one 2-D position per pixel, (N, 2): got {out.shape} "
            f"for {count} points"
        )
    return out


def centre_block(values: ArrayLike, n: int) -> F64:
    """The sample points' values (7 n, ...) at the n centroids themselves (the first block)."""
    arr = np.asarray(values, dtype=np.float64)
    block: F64 = arr.reshape(SAMPLES_PER_PART, n, *arr.shape[1:])[0]
    return block
