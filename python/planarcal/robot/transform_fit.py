"""The closed-form least-squares fits of a 2-D transform from point pairs (board mm -> robot
mm): rigid and similarity by Umeyama's method with the handedness chosen by the caller, affine
by linear least squares; and the checks that refuse pairs too few or too clustered to fix one.

A board's frame (x along a row, y down a column) and a robot's base frame seen from above are
usually mirror images, so rigid and similarity are fitted both ways (a proper rotation, and a
reflection followed by a rotation) and the smaller residual wins. Affine has 6 degrees of
freedom and includes reflections: its handedness is the sign of its determinant."""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

from planarcal.errors import RegistrationError

F64 = NDArray[np.float64]

Model = Literal["rigid", "similarity", "affine"]
MODELS: tuple[Model, ...] = ("rigid", "similarity", "affine")

# Points that fix each model exactly; a fit needs one more pair to show a residual.
MINIMAL_POINTS: dict[Model, int] = {"rigid": 2, "similarity": 2, "affine": 3}

# The RMS distance of the points from their centroid below which they are too clustered to
# fix a rotation (mm): a touch's error of 0.05 mm would turn it by more than a degree.
MIN_SPREAD_MM = 2.0

# Affine only: the points' width across their main line relative to their length (the ratio
# of the singular values of the centred points) below which they are too nearly collinear to
# fix the transform across that line.
MIN_WIDTH_RATIO = 0.02


def apply(matrix: F64, points: F64) -> F64:
    """points (N, 2) mapped through the 3 x 3 affine matrix (its last row 0 0 1)."""
    out: F64 = points @ matrix[:2, :2].T + matrix[:2, 2]
    return out


def check_geometry(plane_mm: F64, robot_mm: F64, model: Model) -> None:
    """RegistrationError unless the pairs are enough, and spread enough, to fix the model."""
    n = len(plane_mm)
    needed = MINIMAL_POINTS[model] + 1
    if n < needed:
        raise RegistrationError(
            f"a {model} registration needs at least {needed} point pairs "
            f"({needed - 1} fix the transform, 1 more measures its residual), got {n}"
        )
    for name, pts in (("board", plane_mm), ("robot", robot_mm)):
        spread = spread_mm(pts)
        if spread < MIN_SPREAD_MM:
            raise RegistrationError(
                f"the {name} points are too clustered to fix the transform: their RMS distance "
                f"from their centroid is {spread:.3g} mm (at least {MIN_SPREAD_MM:g} mm); "
                "touch points spread across the board"
            )
    if model == "affine":
        ratio = width_ratio(plane_mm)
        if ratio < MIN_WIDTH_RATIO:
            raise RegistrationError(
                "the board points are (nearly) collinear, which leaves an affine transform "
                f"free across their line (width/length {ratio:.3g}, at least "
                f"{MIN_WIDTH_RATIO:g}); add touch points off the line or use model='rigid'"
            )


def spread_mm(points: F64) -> float:
    """The RMS distance (mm) of the points from their centroid."""
    return float(np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1))))


def width_ratio(points: F64) -> float:
    """The smaller singular value of the centred points over the larger (0 on a line)."""
    s = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return float(s[1] / s[0]) if s[0] > 0 else 0.0


def fit(plane_mm: F64, robot_mm: F64, model: Model, reflected: bool) -> F64:
    """The 3 x 3 matrix of the least-squares transform plane -> robot; for rigid and
    similarity with determinant of the sign ``reflected`` asks (ignored for affine)."""
    if model == "affine":
        return fit_affine(plane_mm, robot_mm)
    return _fit_umeyama(plane_mm, robot_mm, model == "similarity", reflected)


def fit_either_hand(plane_mm: F64, robot_mm: F64, model: Model) -> tuple[F64, bool]:
    """The least-squares transform and whether it reflects: for rigid and similarity both
    handednesses are fitted and the smaller sum of squared residuals kept (the proper one on a
    tie, so the choice is deterministic)."""
    if model == "affine":
        m = fit_affine(plane_mm, robot_mm)
        return m, bool(np.linalg.det(m[:2, :2]) < 0)
    proper = fit(plane_mm, robot_mm, model, False)
    mirror = fit(plane_mm, robot_mm, model, True)
    cost_proper = float(np.sum((apply(proper, plane_mm) - robot_mm) ** 2))
    cost_mirror = float(np.sum((apply(mirror, plane_mm) - robot_mm) ** 2))
    return (mirror, True) if cost_mirror < cost_proper else (proper, False)


def fit_hand(plane_mm: F64, robot_mm: F64, model: Model, mirrored: bool | None) -> tuple[F64, bool]:
    """The least-squares transform and whether it reflects: of the hand ``mirrored`` asks for
    (rigid and similarity), or the better of the two (None; affine, whose hand is its own)."""
    if mirrored is None or model == "affine":
        return fit_either_hand(plane_mm, robot_mm, model)
    return fit(plane_mm, robot_mm, model, mirrored), mirrored


def _fit_umeyama(plane_mm: F64, robot_mm: F64, with_scale: bool, reflected: bool) -> F64:
    # Umeyama (1991): the rotation from the SVD of the cross-covariance, its smallest
    # singular direction flipped where needed to give the determinant asked for.
    mu_p = plane_mm.mean(axis=0)
    mu_q = robot_mm.mean(axis=0)
    p = plane_mm - mu_p
    q = robot_mm - mu_q
    u, s, vt = np.linalg.svd(q.T @ p / len(p))
    sign = (-1.0 if reflected else 1.0) * float(np.linalg.det(u) * np.linalg.det(vt))
    d = np.array([1.0, sign])
    rotation = u @ np.diag(d) @ vt
    scale = float(s @ d) / float(np.mean(np.sum(p**2, axis=1))) if with_scale else 1.0
    m = np.eye(3)
    m[:2, :2] = scale * rotation
    m[:2, 2] = mu_q - scale * rotation @ mu_p
    return m


def fit_affine(plane_mm: F64, robot_mm: F64) -> F64:
    """The 3 x 3 matrix of the least-squares affine transform plane -> robot."""
    # Centred for conditioning: the board's coordinates may sit hundreds of mm from 0.
    mu_p = plane_mm.mean(axis=0)
    mu_q = robot_mm.mean(axis=0)
    a, *_ = np.linalg.lstsq(plane_mm - mu_p, robot_mm - mu_q, rcond=None)
    m = np.eye(3)
    m[:2, :2] = a.T
    m[:2, 2] = mu_q - a.T @ mu_p
    return m
