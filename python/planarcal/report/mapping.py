"""Where the image's pixels land on the plane, and how far the lens moves them: which pixels
have a place on the plane at all (inside the lens model's fold, on the plane's side of the
horizon), a mapping applied with NaN where it has no answer, and the lens's displacement of
each pixel. The summaries and the lens and uncertainty figures share these."""

from __future__ import annotations

import collections
import functools
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from planarcal.arguments import F64
from planarcal.calib.calibration import Calibration, LensModel
from planarcal.errors import HomographyError, IntrinsicsError, LensModelError
from planarcal.report.figure import require_matplotlib

if TYPE_CHECKING:
    from planarcal.camera.intrinsics import CameraIntrinsics


MAP_ERRORS = (HomographyError, LensModelError, IntrinsicsError)
"""What mapping a pixel raises where it has no answer (beyond a lens model's valid radius, on
or past the plane's horizon)."""


def masked(f: Callable[[F64], F64], points: F64, width: int, budget: int = 32) -> F64:
    """f applied to the points (N, 2) -> (N, width), NaN where f cannot map a point.

    f maps all or raises: a batch that raises is halved, breadth first, until the points
    that fail are found. The callers rule out beforehand what they can (``mappable``), so
    this is a safety net; as a failure can cost a model tens of ms, after `budget` of them
    the batches still failing are left NaN whole rather than searched point by point."""
    out = np.full((len(points), width), np.nan)
    todo = collections.deque([(0, len(points))])
    failures = 0
    while todo:
        a, b = todo.popleft()
        if a == b:
            continue
        try:
            out[a:b] = np.asarray(f(points[a:b]), dtype=np.float64).reshape(b - a, width)
        except MAP_ERRORS:
            failures += 1
            if b - a > 1 and failures < budget:
                m = (a + b) // 2
                todo += [(a, m), (m, b)]
    out[~np.isfinite(out).all(axis=1)] = np.nan
    return out


@functools.lru_cache(maxsize=16)
def _intrinsics_fold(intrinsics: CameraIntrinsics) -> float:
    """The largest radius (normalised: tan of the angle off the optical axis) out to which
    the camera's lens model maps every direction without folding over (bisected with its
    own check), or infinity when it does not fold within 76 degrees."""

    def maps(r: float) -> bool:
        try:
            intrinsics.distort_points(_normalised_circle(intrinsics, r))
        except IntrinsicsError:
            return False
        return True

    lo, hi = 0.0, 4.0
    if maps(hi):
        return math.inf
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if maps(mid) else (lo, mid)
    return lo


def _normalised_circle(intrinsics: CameraIntrinsics, r: float, n: int = 720) -> F64:
    """The ideal pixels at normalised radius r about the optical axis (n, 2)."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    rays = np.column_stack([r * np.cos(t), r * np.sin(t), np.ones(n)])
    px = rays @ intrinsics.matrix.T
    return np.asarray(px[:, :2] / px[:, 2:], dtype=np.float64)


def _normalised_radius(intrinsics: CameraIntrinsics, ideal_px: F64) -> F64:
    rays = np.column_stack([ideal_px, np.ones(len(ideal_px))]) @ np.linalg.inv(intrinsics.matrix).T
    return np.asarray(np.hypot(rays[:, 0], rays[:, 1]) / rays[:, 2], dtype=np.float64)


def _before_fold(lens: LensModel, ideal_px: F64) -> NDArray[np.bool_]:
    """Which ideal pixels lie inside the lens model's fold (where it is one to one)."""
    rho = np.hypot(*((ideal_px - np.array(lens.centre_px)) / lens.scale_px).T)
    return np.asarray(rho < (1.0 - 1e-6) * lens.radial.fold_radius, dtype=np.bool_)


def mappable(cal: Calibration, px: F64) -> NDArray[np.bool_]:
    """Which pixels have a place on the plane: inside the lens model's valid radius (its fold
    seen in the image), and on the plane's side of the horizon."""
    ok = np.asarray(np.isfinite(px).all(axis=1), dtype=np.bool_)
    lens = cal.lens
    if lens is not None:
        valid = lens.radial.valid_radius
        if math.isfinite(valid):
            ok &= np.hypot(*(px - np.array(lens.centre_px)).T) < (1.0 - 1e-6) * valid
    elif cal.intrinsics is not None:
        fold = _intrinsics_fold(cal.intrinsics)
        if math.isfinite(fold):
            require_matplotlib()
            from matplotlib.path import Path as Outline  # noqa: PLC0415 (matplotlib is loaded when a figure is drawn)

            # The pixels the lens shows the unfolded directions at: inside the fold's image
            # (less a margin: at the fold itself the mapping's slope goes to zero).
            edge = cal.intrinsics.distort_points(_normalised_circle(cal.intrinsics, 0.97 * fold))
            ok[ok] = Outline(edge).contains_points(px[ok])
    ideal = np.full_like(px, np.nan)
    ideal[ok] = masked(cal.ideal_points, px[ok], 2)
    # H^-1 is oriented: the third homogeneous coordinate is positive in front of the camera.
    row = cal.H_inv[2]
    v = ideal @ row[:2] + row[2]
    scale = np.abs(row).sum() * (1.0 + np.abs(ideal).sum(axis=1))
    return np.asarray(np.isfinite(v) & (v > 1e-9 * scale), dtype=np.bool_)


def displacement(cal: Calibration, ideal_px: F64) -> F64:
    """How far the lens moves each ideal pixel (N, 2), px (real minus ideal); NaN beyond the
    model's fold, or without a lens model."""
    out = np.full_like(ideal_px, np.nan)
    if cal.lens is not None:
        ok = _before_fold(cal.lens, ideal_px)
        out[ok] = cal.lens.displacement_px(ideal_px[ok])
    elif cal.intrinsics is not None:
        intr = cal.intrinsics
        ok = np.asarray(np.isfinite(ideal_px).all(axis=1), dtype=np.bool_)
        ok[ok] = _normalised_radius(intr, ideal_px[ok]) < _intrinsics_fold(intr)
        out[ok] = masked(lambda u: intr.distort_points(u) - u, ideal_px[ok], 2)
    return out


def max_displacement_px(cal: Calibration) -> float:
    """The most the lens moves a pixel of the image (at its border, for a radial model), px;
    NaN without an image size or a lens model."""
    if cal.lens_model == "none" or cal.image_size is None:
        return math.nan
    w, h = cal.image_size
    t = np.linspace(0.0, 1.0, 201)
    x, y = t * w - 0.5, t * h - 0.5  # the image's outer edge, pixel centres at integers
    border = np.concatenate(
        [
            np.column_stack([x, np.full_like(t, -0.5)]),
            np.column_stack([x, np.full_like(t, h - 0.5)]),
            np.column_stack([np.full_like(t, -0.5), y]),
            np.column_stack([np.full_like(t, w - 0.5), y]),
        ]
    )
    moved = np.hypot(*displacement(cal, border).T)
    moved = moved[np.isfinite(moved)]
    return float(moved.max()) if moved.size else math.nan
