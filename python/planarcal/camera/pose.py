"""The table plane's pose from the camera's intrinsics and the plane's homography, and where
the rays of table points are at a height above it.

Table coordinates (mm) are those of :mod:`planarcal.camera.intrinsics`: X, Y on the plane,
Z = X x Y (into the table for a board read unmirrored), so the camera centre has a negative Z.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal.camera import validation
from planarcal.camera.intrinsics import CameraIntrinsics
from planarcal.errors import IntrinsicsError

__all__ = ["PlanePoseEstimate", "plane_pose", "points_at_height"]

F64 = NDArray[np.float64]


@dataclasses.dataclass(frozen=True, eq=False)
class PlanePoseEstimate:
    """Where the camera is relative to the table plane, from K and the plane's homography.

    ``rotation`` R (3 x 3) and ``translation`` t (3,): table coordinates to camera
    coordinates, X_cam = R X_table + t (OpenCV's rvec/tvec convention). ``camera_centre_mm``
    (3,): the optical centre in table coordinates, C = -R^T t. ``distance_mm``: the camera's
    distance from the plane (> 0). ``up`` (3,): the plane's unit normal pointing towards
    the camera, in table coordinates ((0, 0, -1) when Z points into the table).
    """

    rotation: F64
    translation: F64
    camera_centre_mm: F64
    distance_mm: float
    up: F64

    def __post_init__(self) -> None:
        for name, shape in (
            ("rotation", (3, 3)),
            ("translation", (3,)),
            ("camera_centre_mm", (3,)),
            ("up", (3,)),
        ):
            try:
                a = np.array(getattr(self, name), dtype=np.float64)
            except (TypeError, ValueError):
                raise IntrinsicsError(f"{name} must be an array of numbers") from None
            if a.shape != shape or not np.isfinite(a).all():
                raise IntrinsicsError(f"{name} must be finite, of shape {shape}, got {a.shape}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        d = self.distance_mm
        if isinstance(d, bool) or not isinstance(d, int | float | np.integer | np.floating):
            raise IntrinsicsError(f"distance_mm must be a number, got {d!r}")
        if not (math.isfinite(d) and d > 0):
            raise IntrinsicsError(f"distance_mm must be a finite distance > 0, got {d!r}")
        object.__setattr__(self, "distance_mm", float(d))

    @property
    def foot_mm(self) -> F64:
        """The point of the plane straight below the camera (table X, Y in mm)."""
        return np.asarray(self.camera_centre_mm[:2], dtype=np.float64)

    def rvec_tvec(self) -> tuple[F64, F64]:
        """OpenCV's (rvec, tvec), each (3, 1), for cv2.projectPoints and the like."""
        rvec, _ = cv2.Rodrigues(np.array(self.rotation))
        return np.asarray(rvec, np.float64).reshape(3, 1), np.array(self.translation).reshape(3, 1)

    def __repr__(self) -> str:
        c = ", ".join(f"{v:.6g}" for v in self.camera_centre_mm)
        return f"PlanePoseEstimate(camera_centre_mm=[{c}], distance_mm={self.distance_mm:.6g})"


def plane_pose(intrinsics_matrix: ArrayLike | CameraIntrinsics, H: ArrayLike) -> PlanePoseEstimate:
    """The plane's pose from the camera matrix K and the homography H that maps the plane
    (mm, Z = 0) to *ideal* pixels (undistorted with the same K: fit H to undistort_points of
    the detected dots, not to the raw ones, or the pose absorbs the lens's distortion).

    K^-1 H = lambda [r1 r2 t]; lambda's size is the mean length of the first two columns and
    its sign puts the plane's origin in front of the camera (t_z > 0: true whenever the origin
    was in view, as a board's dot 0 is). [r1 r2 r1 x r2] is then replaced by the nearest
    rotation (SVD), which spreads the noise of H over both axes instead of trusting r1.

    Raises IntrinsicsError for a malformed K or H, a singular H, or an origin in the camera's
    focal plane (t_z = 0: the plane cannot have been seen there).
    """
    k = (
        intrinsics_matrix.matrix
        if isinstance(intrinsics_matrix, CameraIntrinsics)
        else validation.camera_matrix(intrinsics_matrix)
    )
    try:
        h = np.array(H, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):  # Overflow: an integer like 10**400
        raise IntrinsicsError("H must be a 3 x 3 array of numbers") from None
    if h.shape != (3, 3) or not np.isfinite(h).all():
        raise IntrinsicsError(f"H must be a finite 3 x 3 matrix, got {h.tolist()}")
    # Overflow and NaN are looked for below, not warned of on the way.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        m = np.linalg.solve(k, h)
        n1, n2, n3 = (float(np.linalg.norm(m[:, i])) for i in range(3))
        scale = 0.5 * (n1 + n2)
        # det(K^-1 H) = lambda^3 (r3 . t), lambda^3 times the camera's distance from the plane.
        if not (n1 > 0 and n2 > 0 and n3 > 0) or abs(np.linalg.det(m)) <= 1e-12 * n1 * n2 * n3:
            raise IntrinsicsError(
                f"H is singular: it does not map a plane onto the image ({h.tolist()})"
            )
        if abs(m[2, 2]) <= 1e-12 * n3:
            raise IntrinsicsError(
                "the plane's origin lies in the camera's focal plane (t_z = 0): H cannot be the "
                "homography of a plane seen by this camera"
            )
        lam = scale if m[2, 2] > 0 else -scale
        r1, r2, t = m[:, 0] / lam, m[:, 1] / lam, m[:, 2] / lam
        approx = np.column_stack([r1, r2, np.cross(r1, r2)])
        # K^-1 H or its rotation part beyond double precision (K and H of wildly different
        # scales, 1e308 and 1e-308): NumPy's SVD would fail with "SVD did not converge".
        finite = np.isfinite(m).all() and np.isfinite(approx).all() and np.isfinite(t).all()
        if not (finite and math.isfinite(scale)):
            raise IntrinsicsError(
                "K^-1 H overflows double precision: the camera matrix and H cannot be of one "
                f"camera and plane (K = {k.tolist()}, H = {h.tolist()})"
            )
    u, _s, vt = np.linalg.svd(approx)
    rotation = u @ vt
    if np.linalg.det(rotation) < 0:  # cannot happen with r3 = r1 x r2; kept as a guard
        u[:, -1] *= -1.0
        rotation = u @ vt
    centre = -rotation.T @ t
    # Table coordinates: the plane is Z = 0 and its normal is the Z axis; the side the
    # camera is on is the sign of its Z.
    distance = abs(float(centre[2]))
    up = np.array([0.0, 0.0, math.copysign(1.0, float(centre[2]))])
    return PlanePoseEstimate(
        rotation=np.asarray(rotation, dtype=np.float64),
        translation=np.asarray(t, dtype=np.float64),
        camera_centre_mm=centre,
        distance_mm=distance,
        up=up,
    )


def points_at_height(
    world_xy: ArrayLike, pose_estimate: PlanePoseEstimate, height_mm: ArrayLike
) -> F64:
    """Where the rays that meet the table at ``world_xy`` (..., 2) are at ``height_mm`` above
    the table (towards the camera), in table X, Y (mm).

    A pixel's table point (from the calibration's homography) is where its ray meets the
    plane; an object's top at height h is seen by the same pixel but lies nearer to the
    point below the camera: at world_xy + (h / D) (C_xy - world_xy), with C_xy the camera's
    foot on the plane and D its distance (similar triangles). ``height_mm`` is a scalar or one
    value per point (negative: below the table's surface). IntrinsicsError if a height is not
    finite or reaches the camera (h >= D).
    """
    if not isinstance(pose_estimate, PlanePoseEstimate):
        raise IntrinsicsError(
            f"pose_estimate must be a PlanePoseEstimate, got {type(pose_estimate).__name__}"
        )
    flat, shape = arguments.points("world_xy", world_xy, IntrinsicsError)
    try:
        h = np.asarray(height_mm, dtype=np.float64)
    except (TypeError, ValueError):
        raise IntrinsicsError("height_mm must be a number or an array of numbers") from None
    if h.ndim == 0:
        h = np.full(flat.shape[0], float(h))
    elif h.shape == shape:
        h = h.reshape(-1)
    else:
        raise IntrinsicsError(
            f"height_mm must be a number or one per point (shape {shape}), got shape {h.shape}"
        )
    if not np.isfinite(h).all():
        k = int(np.flatnonzero(~np.isfinite(h))[0])
        raise IntrinsicsError(f"height_mm[{k}] is not finite: {float(h[k])}")
    d = float(pose_estimate.distance_mm)
    if h.size and not float(h.max()) < d:
        k = int(np.argmax(h))
        raise IntrinsicsError(
            f"height {h[k]:g} mm (point {k}) reaches the camera, which is {d:.6g} mm above the "
            "table: heights must be below the camera"
        )
    foot = np.asarray(pose_estimate.camera_centre_mm[:2], dtype=np.float64)
    out = flat + (h / d)[:, None] * (foot[None, :] - flat)
    return np.asarray(out.reshape(*shape, 2), dtype=np.float64)
