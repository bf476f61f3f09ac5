"""Where a calibration's points are in the image, and what it predicts beyond them.

A homography (and a lens model) fitted to points in one part of the image is an
interpolation there and an extrapolation everywhere else: its error bars, which the fit's
covariance carries to any pixel (``Calibration.image_to_world(..., return_std=True)``), grow
with the distance from the points. A board seen whole in the middle of the view covers most of
what a camera is used for; a partial view, or a board in one corner, leaves the rest of the
image mapped by extrapolation, whose predicted error this module measures over a grid of the
whole image, so that the summary can warn and the report draw it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

GRID_STEPS = 24
"""Grid cells along the image's longer side (the shorter in proportion): some 24 x 14 points
for 16:9, every one of the image's corners and edges among them."""

WARN_SHARE = 0.15
"""The summary warns when the points' outline covers less than this share of the image, or
leaves out the image's centre (a partial view, or a board in one corner): most of the view
is then mapped by extrapolation. A board in the middle of the view (the paper's covers 23 %
of its image) is not warned about, though its far corners are predicted worse than its
points: the figures say by how much (``image_std_mm``)."""


@dataclasses.dataclass(frozen=True)
class Extrapolation:
    """A calibration's coverage of its image and its predicted error beyond its points."""

    covered_share: float
    """The share of the image inside the convex hull of the calibration's points (0 to 1)."""
    covered_std_mm: float
    """The largest predicted 1-sigma mapping error at the calibration's points, mm."""
    image_std_mm: float
    """The largest predicted 1-sigma mapping error over the whole image, mm (inf where part
    of the image has no place on the plane: beyond its horizon, or the lens model's reach)."""
    image_std_at_px: tuple[float, float]
    """Where in the image that largest error is (px)."""
    grid_px: F64
    """(K, 2) pixels over the whole image, corners and edges included, for drawing."""
    grid_std_mm: F64
    """(K,) the predicted 1-sigma at each grid pixel, mm (inf where it has no place)."""
    grid_covered: NDArray[np.bool_]
    """(K,) whether each grid pixel lies inside the points' hull."""
    hull_px: F64
    """(M, 2) the points' convex hull in the image, px."""
    covers_centre: bool = True
    """Whether the points' hull holds the image's centre."""

    @property
    def ratio(self) -> float:
        """image_std_mm / covered_std_mm: how much worse the worst of the image is."""
        if not self.covered_std_mm > 0:
            return math.inf if self.image_std_mm > 0 else 1.0
        return self.image_std_mm / self.covered_std_mm

    @property
    def warning(self) -> str | None:
        """A sentence for the summary when the rest of the image is extrapolated (the points
        cover under WARN_SHARE of it, or not its centre), else None."""
        if self.covered_share >= WARN_SHARE and self.covers_centre:
            return None
        x, y = self.image_std_at_px
        if math.isfinite(self.image_std_mm):
            worst = (
                f"the predicted 1-sigma error grows from {self.covered_std_mm:.3g} mm at the "
                f"points to {self.image_std_mm:.3g} mm at ({x:.0f}, {y:.0f}) px"
            )
        else:
            worst = (
                f"the predicted 1-sigma error is {self.covered_std_mm:.3g} mm at the points, "
                f"and part of the image (at ({x:.0f}, {y:.0f}) px) has no place on the plane"
            )
        return (
            f"the calibration's points cover {self.covered_share:.0%} of the image"
            + ("" if self.covers_centre else ", not its centre")
            + "; the leave-one-out errors hold within their outline, the rest is "
            + f"extrapolated: {worst}. Use positions there with care, or "
            "calibrate with the board where the parts will be"
        )

    def to_dict(self) -> dict[str, Any]:
        """The figures (not the grid), JSON-ready (inf as None)."""

        def num(v: float) -> float | None:
            return float(v) if math.isfinite(v) else None

        return {
            "covered_share": num(self.covered_share),
            "covered_std_mm": num(self.covered_std_mm),
            "image_std_mm": num(self.image_std_mm),
            "image_std_at_px": [float(v) for v in self.image_std_at_px],
            "covers_centre": self.covers_centre,
            "warning": self.warning,
        }


def image_grid(size: tuple[int, int], steps: int = GRID_STEPS) -> F64:
    """Pixels over a `size` (width, height) image, its corner pixels and edges included:
    (K, 2), x varying fastest."""
    w, h = size
    nx = max(2, round(steps * w / max(w, h)) + 1)
    ny = max(2, round(steps * h / max(w, h)) + 1)
    xs = np.linspace(0.0, w - 1.0, nx)
    ys = np.linspace(0.0, h - 1.0, ny)
    gx, gy = np.meshgrid(xs, ys)
    return np.column_stack([gx.ravel(), gy.ravel()])


def convex_hull(points: F64) -> F64:
    """The convex hull of (N, 2) points, (M, 2) (the points themselves for fewer than 3)."""
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    if len(pts) < 3:
        return np.array(pts, np.float64)
    hull = cv2.convexHull(pts.astype(np.float32)).reshape(-1, 2)
    return np.asarray(hull, np.float64)


def covered_share(hull: F64, size: tuple[int, int]) -> float:
    """The share of a `size` image inside the convex polygon `hull` (clipped to the image)."""
    w, h = size
    if len(hull) < 3:
        return 0.0
    frame = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
    area, _ = cv2.intersectConvexConvex(hull.astype(np.float32), frame.astype(np.float32))
    return float(min(1.0, max(0.0, area / (w * h))))


def inside_hull(hull: F64, points: F64) -> NDArray[np.bool_]:
    """Whether each of `points` (K, 2) lies inside the convex polygon `hull` (edges in)."""
    if len(hull) < 3:
        return np.zeros(len(points), bool)
    a, b = hull, np.roll(hull, -1, axis=0)
    cross = (b[None, :, 0] - a[None, :, 0]) * (points[:, None, 1] - a[None, :, 1]) - (
        b[None, :, 1] - a[None, :, 1]
    ) * (points[:, None, 0] - a[None, :, 0])
    tol = 1e-9 * float(np.abs(hull).max() + 1.0) ** 2
    return np.asarray((cross >= -tol).all(axis=1) | (cross <= tol).all(axis=1))


def extrapolation(
    std_at: Callable[[F64], F64], image_points: F64, size: tuple[int, int]
) -> Extrapolation:
    """The coverage and predicted errors of a calibration whose points are `image_points`
    (px) in `size` images; ``std_at(px)`` is its 1-sigma in mm at pixels (N, 2) (inf where a
    pixel has no place on the plane)."""
    grid = image_grid(size)
    grid_std = np.asarray(std_at(grid), np.float64)
    point_std = np.asarray(std_at(image_points), np.float64)
    hull = convex_hull(image_points)
    finite = point_std[np.isfinite(point_std)]
    covered = float(finite.max()) if finite.size else math.inf
    worst = int(np.argmax(grid_std))
    image_std = float(grid_std[worst])
    at = (float(grid[worst, 0]), float(grid[worst, 1]))
    if not image_std >= covered:  # the points' worst is the image's (NaN-safe)
        image_std = covered
    return Extrapolation(
        covered_share(hull, size),
        covered,
        image_std,
        at,
        grid,
        grid_std,
        inside_hull(hull, grid),
        hull,
        bool(inside_hull(hull, np.array([[(size[0] - 1) / 2.0, (size[1] - 1) / 2.0]]))[0]),
    )
