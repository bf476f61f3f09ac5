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
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal.errors import ArgumentError

F64 = NDArray[np.float64]

__all__ = ["STEP_PX", "LocalMap", "area_centroids", "local_maps"]

STEP_PX = 1.0
"""The differences' step, px: far below the scale on which the mapping bends, far above the
digits the subtraction loses (1e-16 of a position of a few hundred mm)."""

Mapping = Callable[[F64], tuple[ArrayLike, ArrayLike | None]]
"""Pixels (N, 2) -> (positions in the output frame (N, 2), their 1-sigma (N,) or None)."""

# The points each part's mapping is sampled at, in steps: the centroid, +x, -x, +y, -y, and
# +x+y, -x-y (for the cross derivative).
_OFFSETS = np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [-1, -1]], dtype=float)


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
    c = np.asarray(centroids_px, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 2:
        raise ArgumentError(f"centroids_px must be (n, 2) px, got shape {c.shape}")
    if not (math.isfinite(step_px) and step_px > 0):
        raise ArgumentError(f"step_px must be a finite number > 0, got {step_px!r}")
    n, h = len(c), float(step_px)
    if n == 0:
        return LocalMap(np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2, 2)), np.zeros((0, 2, 3)))
    k = len(_OFFSETS)
    mapped, std = mapping((c[None, :, :] + h * _OFFSETS[:, None, :]).reshape(-1, 2))
    out = np.asarray(mapped, dtype=np.float64)
    if out.shape != (k * n, 2):
        raise ArgumentError(
            f"the mapping must return one 2-D position per pixel, (N, 2): got {out.shape} "
            f"for {k * n} points"
        )
    f0, px, mx, py, my, pp, mm = out.reshape(k, n, 2)
    jac = np.stack([(px - mx) / (2.0 * h), (py - my) / (2.0 * h)], axis=2)
    fxx = (px + mx - 2.0 * f0) / (h * h)
    fyy = (py + my - 2.0 * f0) / (h * h)
    fxy = (pp + mm - px - mx - py - my + 2.0 * f0) / (2.0 * h * h)
    centre_std = None if std is None else np.asarray(std, dtype=np.float64).reshape(k, n)[0]
    return LocalMap(f0, centre_std, jac, np.stack([fxx, fxy, fyy], axis=2))


def area_centroids(local: LocalMap, moments_px: ArrayLike) -> F64:
    """Each part's centroid on the plane (n, 2), from its image area's central second moments
    (n, 3: [mu20, mu11, mu02] / area, px^2) and the mapping near its image centroid: see the
    module docstring."""
    m = np.asarray(moments_px, dtype=np.float64)
    n = len(local.position)
    if m.shape != (n, 3):
        raise ArgumentError(f"moments_px must be (n, 3) with n = {n}, got {m.shape}")
    jac, hes = local.jacobian, local.hessian
    fx, fy = jac[:, :, 0], jac[:, :, 1]  # (n, 2) each: d out / dx, d out / dy
    fxx, fxy, fyy = hes[:, :, 0], hes[:, :, 1], hes[:, :, 2]
    det = fx[:, 0] * fy[:, 1] - fx[:, 1] * fy[:, 0]
    # d det / dx and d det / dy, over det: the gradient of log |det J|.
    ddx = _cross(fxx, fy) + _cross(fx, fxy)
    ddy = _cross(fxy, fy) + _cross(fx, fyy)
    with np.errstate(divide="ignore", invalid="ignore"):
        gx, gy = ddx / det, ddy / det
    mu20, mu11, mu02 = m[:, 0], m[:, 1], m[:, 2]
    # J M g: the area scale's lean towards one side of the part.
    mgx, mgy = mu20 * gx + mu11 * gy, mu11 * gx + mu02 * gy
    lean = fx * mgx[:, None] + fy * mgy[:, None]
    # 1/2 H : M: the mapping's bend across the part.
    bend = 0.5 * (fxx * mu20[:, None] + 2.0 * fxy * mu11[:, None] + fyy * mu02[:, None])
    return np.asarray(local.position + lean + bend, dtype=np.float64)


def _cross(a: F64, b: F64) -> F64:
    """The 2-D cross product of rows: a_x b_y - a_y b_x."""
    return np.asarray(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], dtype=np.float64)
