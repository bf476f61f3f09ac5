"""The camera of a synthetic scene: where the table plane is (:class:`PlanePose`), a pinhole
camera with OpenCV's radial lens (:class:`CameraModel`), and the two together (:class:`View`).

Conventions (those of all of :mod:`planarcal.synth`)
-----------------------------------------------------
* **Table coordinates** (mm): X and Y on the plane, Z = X x Y pointing *away* from the
  camera (into the table), so a point h mm above the table is (X, Y, -h). A board placed
  with ``board_origin_mm=(0, 0)`` and ``board_angle_deg=0`` has board coordinates equal to
  table coordinates.
* **Pixels**: OpenCV's convention. The centre of pixel (row i, column j) is at (x, y) =
  (j, i); the pixel covers [j - 0.5, j + 0.5] x [i - 0.5, i + 0.5]. The default principal
  point is the image centre, ((width - 1) / 2, (height - 1) / 2).
* **Camera**: OpenCV's frame (x right, y down, z along the optical axis) and its
  distortion model on normalised coordinates: radial, x_d = x_u (1 + k1 r^2 + k2 r^4) with
  r^2 = x_u^2 + y_u^2, plus the tangential (decentring) terms p1, p2,
  x_d += 2 p1 x_u y_u + p2 (r^2 + 2 x_u^2), y_d += p1 (r^2 + 2 y_u^2) + 2 p2 x_u y_u;
  then pixel = focal_px * x_d + principal. ``cv2.projectPoints`` with
  ``rvec, tvec = pose.rvec_tvec()``, ``camera.matrix()`` and ``camera.dist_coeffs()``
  gives the same pixels as :meth:`CameraModel.project` (which takes points above the table
  too: ``height_mm``).

The radial part is the package's one radial lens, :class:`planarcal._core.RadialLens`,
centred on the principal point with the focal length as its radius unit (which makes its k1,
k2 OpenCV's). Going the other way, from a pixel to the table point it sees, is exact too: the
lens undistorts the position (Newton's method on the radial polynomial, to machine
precision; with tangential terms, Newton's method on the whole two-dimensional model started
from the radial inverse), and the ray through it is intersected with the plane. The
renderer traces every pixel so. A camera without tangential terms (p1 = p2 = 0, the default)
takes the radial lens alone, bit for bit as before they existed.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal._core import RadialLens
from planarcal.errors import ArgumentError, ImageError

F64 = NDArray[np.float64]

# Newton steps for the tangential model's inverse: from the radial inverse it converges in 3-4
# within the image (quadratically); the rest are for points far out.
_NEWTON_STEPS = 30


def _heights(value: ArrayLike, shape: tuple[int, ...]) -> F64 | None:
    """Heights above the table (mm) for points of leading shape ``shape``, flat (N,); None
    when they are all zero (the plane itself, computed as before heights existed)."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ArgumentError("height_mm must be a number or an array of numbers") from None
    try:
        flat = np.broadcast_to(a, shape).reshape(-1)
    except ValueError:
        raise ArgumentError(
            f"height_mm must be a scalar or one height per point (shape {shape}), got shape "
            f"{a.shape}"
        ) from None
    bad = np.flatnonzero(~np.isfinite(flat))
    if bad.size:
        raise ArgumentError(
            f"height_mm: height {int(bad[0])} is not finite: {float(flat[bad[0]])!r}"
        )
    return None if not flat.any() else np.ascontiguousarray(flat)


@dataclasses.dataclass(frozen=True)
class PlanePose:
    """Where the table plane is, seen from the camera.

    The camera looks at the table point ``look_at_mm`` (X, Y in mm), which lies on its
    optical axis ``distance_mm`` in front of it (so it appears at the principal point).
    With no tilt and no roll the camera looks straight down the plane's normal, the table's
    X axis runs to the right of the image and Y down it. ``tilt_deg`` then rotates the plane
    about the in-plane axis through ``look_at_mm`` at ``tilt_axis_deg`` from X (towards Y),
    by the right-hand rule in table coordinates (Z into the table); ``roll_deg`` finally
    rotates the scene about the optical axis (positive turns the image clockwise on screen).
    |tilt| must be below 90 degrees (the camera must face the plane).
    """

    distance_mm: float
    tilt_deg: float = 0.0
    tilt_axis_deg: float = 0.0
    roll_deg: float = 0.0
    look_at_mm: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        d = arguments.real("distance_mm", self.distance_mm)
        if d <= 0:
            raise ArgumentError(
                f"distance_mm must be positive, got {self.distance_mm!r}: a plane at a "
                "distance <= 0 is at or behind the camera"
            )
        tilt = arguments.real("tilt_deg", self.tilt_deg)
        if not abs(tilt) < 90.0:
            raise ArgumentError(
                f"tilt_deg must be between -90 and 90 (exclusive), got {self.tilt_deg!r}: "
                "at 90 degrees or more the camera sees the plane edge-on or from behind"
            )
        arguments.real("tilt_axis_deg", self.tilt_axis_deg)
        arguments.real("roll_deg", self.roll_deg)
        object.__setattr__(self, "look_at_mm", arguments.pair("look_at_mm", self.look_at_mm))

    def rotation(self) -> F64:
        """R (3 x 3): table coordinates to camera coordinates, X_cam = R X_table + t."""
        a = math.radians(self.tilt_axis_deg)
        axis = np.array([math.cos(a), math.sin(a), 0.0])
        tilt, _ = cv2.Rodrigues(axis * math.radians(self.tilt_deg))
        r = math.radians(self.roll_deg)
        c, s = math.cos(r), math.sin(r)
        roll = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return np.asarray(roll @ tilt, dtype=np.float64)

    def translation(self) -> F64:
        """t (3,): the table origin in camera coordinates (mm)."""
        look = np.array([*self.look_at_mm, 0.0])
        t = np.array([0.0, 0.0, float(self.distance_mm)]) - self.rotation() @ look
        return np.asarray(t, dtype=np.float64)

    def rvec_tvec(self) -> tuple[F64, F64]:
        """OpenCV's (rvec, tvec), each (3, 1) float64, for cv2.projectPoints and the like."""
        rvec, _ = cv2.Rodrigues(self.rotation())
        tvec = np.asarray(self.translation(), dtype=np.float64).reshape(3, 1)
        return np.asarray(rvec, dtype=np.float64).reshape(3, 1), tvec

    def camera_centre_mm(self) -> F64:
        """The camera's optical centre in table coordinates, (3,) (its Z is negative)."""
        return np.asarray(-self.rotation().T @ self.translation(), dtype=np.float64)


@dataclasses.dataclass(frozen=True)
class CameraModel:
    """A pinhole camera with square pixels and OpenCV's distortion: two radial terms and
    the two tangential ones.

    ``focal_px`` is the focal length in pixels; ``principal`` the principal point in pixels
    (None: the image centre, ((width - 1) / 2, (height - 1) / 2)), which is also the
    distortion's centre; ``k1``, ``k2`` the radial coefficients on normalised coordinates
    (k1 < 0: barrel, as in most webcams); ``p1``, ``p2`` OpenCV's tangential (decentring)
    coefficients (a lens element slightly off the axis: |p| up to about 1e-3 on webcams). The
    distortion must be invertible over the image (no fold-over between the centre and the
    corners). The default focal length, 1070 px, is a Logitech C525's at 1280 x 720 (about
    69 degrees diagonal field of view).
    """

    width: int = 1280
    height: int = 720
    focal_px: float = 1070.0
    principal: tuple[float, float] | None = None
    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise ImageError(f"{name} must be a whole number of pixels, got {value!r}")
            if not 2 <= value <= 65536:
                raise ImageError(f"{name} must be 2 to 65536 pixels, got {value}")
            object.__setattr__(self, name, int(value))
        arguments.positive("focal_px", self.focal_px)
        if self.principal is not None:
            object.__setattr__(self, "principal", arguments.pair("principal", self.principal))
        k1, k2 = arguments.real("k1", self.k1), arguments.real("k2", self.k2)
        p1, p2 = arguments.real("p1", self.p1), arguments.real("p2", self.p2)
        # The lens must invert over the image: its fold, seen in the image, beyond the corners.
        if (k1 or k2) and not self.lens.valid_radius > self._corner_radius() * self.focal_px:
            raise ArgumentError(
                f"distortion k1={k1}, k2={k2} folds over inside the image: the radial "
                "mapping stops increasing before the image corners, so pixels near them "
                "would see two places at once; use milder coefficients"
            )
        if self.tangential and not self._tangential_invertible():
            raise ArgumentError(
                f"distortion k1={k1}, k2={k2}, p1={p1}, p2={p2} folds over inside the "
                "image: the mapping is not one to one between the image centre and its "
                "border, so some pixels would see two places at once; use milder coefficients"
            )

    @property
    def lens(self) -> RadialLens:
        """The lens's radial part in pixels: centred on the principal point, the focal length
        its unit (the tangential terms are not in it)."""
        return RadialLens((self.cx, self.cy), float(self.focal_px), float(self.k1), float(self.k2))

    @property
    def cx(self) -> float:
        return (self.width - 1) / 2.0 if self.principal is None else self.principal[0]

    @property
    def cy(self) -> float:
        return (self.height - 1) / 2.0 if self.principal is None else self.principal[1]

    def _corner_radius(self) -> float:
        """Largest normalised (distorted) radius of the image's outer pixel corners."""
        xs = (np.array([-0.5, self.width - 0.5]) - self.cx) / self.focal_px
        ys = (np.array([-0.5, self.height - 0.5]) - self.cy) / self.focal_px
        return float(np.sqrt(np.max(xs**2) + np.max(ys**2)))

    def matrix(self) -> F64:
        """The intrinsic matrix K (3 x 3)."""
        f = float(self.focal_px)
        return np.array([[f, 0.0, self.cx], [0.0, f, self.cy], [0.0, 0.0, 1.0]])

    def dist_coeffs(self) -> F64:
        """OpenCV's distortion vector (k1, k2, p1, p2, k3) = (k1, k2, p1, p2, 0)."""
        return np.array([self.k1, self.k2, self.p1, self.p2, 0.0], dtype=np.float64)

    @property
    def distorted(self) -> bool:
        return bool(self.k1 or self.k2 or self.p1 or self.p2)

    @property
    def tangential(self) -> bool:
        """Whether the lens has tangential terms (then the radial lens alone is not it)."""
        return bool(self.p1 or self.p2)

    def _distort_normalized(self, x: F64, y: F64) -> tuple[F64, F64]:
        """OpenCV's model on undistorted normalised coordinates (any matching shapes)."""
        k1, k2, p1, p2 = float(self.k1), float(self.k2), float(self.p1), float(self.p2)
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + k2 * r2)
        xy = x * y
        return (
            x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy,
        )

    def _distortion_jacobian(self, x: F64, y: F64) -> tuple[F64, F64, F64, F64]:
        """d(x_d, y_d) / d(x_u, y_u) of the full model: (a, b, c, d) = [[a, b], [c, d]]."""
        k1, k2, p1, p2 = float(self.k1), float(self.k2), float(self.p1), float(self.p2)
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + k2 * r2)
        dradial = 2.0 * (k1 + 2.0 * k2 * r2)  # d radial / d(x or y), per unit of x or y
        return (
            radial + x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x,
            x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
            x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
            radial + y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x,
        )

    def _undistort_normalized(self, xd: F64, yd: F64) -> tuple[F64, F64, NDArray[np.bool_]]:
        """The full model's inverse by Newton's method (vectorised), started from the radial
        lens's exact inverse (the tangential terms are small beside the radial ones), and
        whether each point converged to machine precision."""
        xd, yd = np.broadcast_arrays(np.asarray(xd, np.float64), np.asarray(yd, np.float64))
        shape = xd.shape
        xd, yd = xd.reshape(-1), yd.reshape(-1)
        if self.k1 or self.k2:
            f = float(self.focal_px)
            px = np.column_stack([xd * f + self.cx, yd * f + self.cy])
            start = self.lens.undistort(px, invalid="nan")
            x, y = (start[:, 0] - self.cx) / f, (start[:, 1] - self.cy) / f
            # Beyond the radial lens's reach, start from the distorted position itself.
            lost = ~(np.isfinite(x) & np.isfinite(y))
            x, y = np.where(lost, xd, x), np.where(lost, yd, y)
        else:
            x, y = xd.copy(), yd.copy()
        tol = 16.0 * np.finfo(np.float64).eps * (1.0 + np.abs(xd) + np.abs(yd))
        done = np.zeros(xd.shape, dtype=bool)
        # Only the points still moving are worked on (most converge in 3 steps); while all
        # are, without gathering them.
        active: NDArray[np.intp] | slice = slice(None)
        for _ in range(_NEWTON_STEPS):
            xa, ya = x[active], y[active]
            gx, gy = self._distort_normalized(xa, ya)
            ex, ey = gx - xd[active], gy - yd[active]
            moving = (np.abs(ex) > tol[active]) | (np.abs(ey) > tol[active])
            if not moving.all():
                index = np.arange(xd.size)[active]
                done[index[~moving]] = True
                if moving.sum() == 0:
                    break
                active = index[moving]
                xa, ya, ex, ey = xa[moving], ya[moving], ex[moving], ey[moving]
            a, b, c, d = self._distortion_jacobian(xa, ya)
            det = a * d - b * c
            # A fold (det <= 0) stops the point where it is: it stays not done.
            det = np.where(det > 0.0, det, np.inf)
            x[active] = xa - (d * ex - b * ey) / det
            y[active] = ya - (a * ey - c * ex) / det
        return x.reshape(shape), y.reshape(shape), done.reshape(shape)

    def _tangential_invertible(self) -> bool:
        """Whether the full model is one to one over the image: every border pixel
        undistorts (Newton converges) and the Jacobian's determinant stays positive on the
        straight lines from the centre to the undistorted border (no fold on the way)."""
        w, h = self.width, self.height
        n = 64
        top, right = np.linspace(-0.5, w - 0.5, n), np.linspace(-0.5, h - 0.5, n)
        xs = np.concatenate([top, np.full(n, w - 0.5), top[::-1], np.full(n, -0.5)])
        ys = np.concatenate([np.full(n, -0.5), right, np.full(n, h - 0.5), right[::-1]])
        f = float(self.focal_px)
        x, y, ok = self._undistort_normalized((xs - self.cx) / f, (ys - self.cy) / f)
        if not ok.all():
            return False
        t = np.linspace(0.0, 1.05, 128)[:, None]
        a, b, c, d = self._distortion_jacobian(t * x[None], t * y[None])
        return bool(((a * d - b * c) > 0.0).all())

    def _to_px(self, normalized: F64) -> F64:
        return np.asarray(normalized * float(self.focal_px) + [self.cx, self.cy], np.float64)

    def _to_normalized(self, px: F64) -> F64:
        return np.asarray((px - [self.cx, self.cy]) / float(self.focal_px), np.float64)

    def distort(self, normalized: ArrayLike) -> F64:
        """Undistorted normalised coordinates (..., 2) to distorted ones."""
        p, shape = arguments.points("normalized", normalized)
        if not self.distorted:
            return p.reshape(*shape, 2)
        if self.tangential:
            return np.stack(self._distort_normalized(p[:, 0], p[:, 1]), axis=-1).reshape(*shape, 2)
        out = self._to_normalized(self.lens.distort(self._to_px(p)))
        return out.reshape(*shape, 2)

    def undistort(self, normalized: ArrayLike) -> F64:
        """Distorted normalised coordinates (..., 2) to undistorted ones (exact inverse of
        :meth:`distort` within the image's radius)."""
        p, shape = arguments.points("normalized", normalized)
        if not self.distorted:
            return p.reshape(*shape, 2)
        if self.tangential:
            x, y, ok = self._undistort_normalized(p[:, 0], p[:, 1])
            if not ok.all():
                i = int(np.flatnonzero(~ok)[0])
                raise ArgumentError(
                    f"normalized point {i} {p[i].tolist()} is beyond the lens's reach: "
                    "its distortion cannot be inverted there"
                )
            return np.column_stack([x, y]).reshape(*shape, 2)
        out = self._to_normalized(self.lens.undistort(self._to_px(p)))
        return out.reshape(*shape, 2)

    def homography(self, pose: PlanePose) -> F64:
        """The table (mm) -> image (px) homography K [r1 r2 t], scaled so H[2, 2] = 1 (-1 if
        the table origin is behind the camera: points in front keep w > 0).

        It is the exact projection without distortion; with distortion it is the undistorted
        part (the projection onto the ideal pinhole image, before the lens bends it).
        """
        r = pose.rotation()
        m = np.column_stack([r[:, 0], r[:, 1], pose.translation()])
        h = self.matrix() @ m
        scale = h[2, 2] if abs(h[2, 2]) > 1e-12 * np.abs(h).max() else np.linalg.norm(h)
        return np.asarray(h / abs(scale), dtype=np.float64)

    def project(self, world_xy: ArrayLike, pose: PlanePose, height_mm: ArrayLike = 0.0) -> F64:
        """Table points (..., 2) in mm to pixels (..., 2), exactly, lens distortion included.

        ``height_mm``: how far above the table the points are (mm; a scalar or one height per
        point, shaped like the points' leading dimensions; negative: below it). A point
        (X, Y) at height h is the 3-D table point (X, Y, -h) (table Z points away from the
        camera), as for ``cv2.projectPoints``. Raises ValueError for a point at or behind the
        camera's plane (it has no image).
        """
        p, shape = arguments.points("world_xy", world_xy)
        heights = _heights(height_mm, shape)
        r, t = pose.rotation(), pose.translation()
        cam = p @ r[:, :2].T + t
        if heights is not None:
            cam = cam - heights[:, None] * r[:, 2]
        behind = np.flatnonzero(cam[:, 2] <= 1e-9 * float(pose.distance_mm))
        if behind.size:
            i = int(behind[0])
            where = "" if heights is None else f" at height {float(heights[i])!r} mm"
            raise ArgumentError(
                f"world point {i} {p[i].tolist()}{where} is behind the camera: it has no image"
            )
        if self.tangential:
            x, y = cam[:, 0] / cam[:, 2], cam[:, 1] / cam[:, 2]
            px = self._to_px(np.column_stack(self._distort_normalized(x, y)))
        else:
            px = self._to_px(cam[:, :2] / cam[:, 2:])
            if self.distorted:
                px = self.lens.distort(px)
        return np.asarray(px.reshape(*shape, 2), dtype=np.float64)

    def image_to_plane(self, pixels: ArrayLike, pose: PlanePose) -> F64:
        """Pixels (..., 2) to the table points (mm) they see: undistort, back-project the
        ray, intersect it with the plane (exact). ValueError if a ray misses the plane."""
        p, shape = arguments.points("pixels", pixels)
        x, y, ok = self._rays_to_plane(
            (p[:, 0] - self.cx) / self.focal_px, (p[:, 1] - self.cy) / self.focal_px, pose
        )
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            raise ArgumentError(f"pixel {i} {p[i].tolist()} sees above the plane's horizon")
        return np.column_stack([x, y]).reshape(*shape, 2)

    def _rays_to_plane(
        self, xd: F64, yd: F64, pose: PlanePose
    ) -> tuple[F64, F64, NDArray[np.bool_]]:
        """Distorted normalised coordinates (any matching shapes) to table X, Y, and whether
        the ray hits the plane in front of the camera."""
        xu, yu = xd, yd
        ok_lens: NDArray[np.bool_] | bool = True
        if self.tangential:
            xu, yu, ok_lens = self._undistort_normalized(xd, yd)
        elif self.distorted:
            f = float(self.focal_px)
            xd, yd = np.broadcast_arrays(xd, yd)
            px = np.stack([xd * f + self.cx, yd * f + self.cy], axis=-1)
            ideal = self.lens.undistort(px.reshape(-1, 2)).reshape(px.shape)
            xu, yu = (ideal[..., 0] - self.cx) / f, (ideal[..., 1] - self.cy) / f
        r = pose.rotation()
        minv = np.linalg.inv(np.column_stack([r[:, 0], r[:, 1], pose.translation()]))
        w = minv[2, 0] * xu + minv[2, 1] * yu + minv[2, 2]
        ok = (w > 1e-12) & ok_lens
        w = np.where(ok, w, 1.0)
        x = (minv[0, 0] * xu + minv[0, 1] * yu + minv[0, 2]) / w
        y = (minv[1, 0] * xu + minv[1, 1] * yu + minv[1, 2]) / w
        return x, y, ok


@dataclasses.dataclass(frozen=True)
class View:
    """A camera at a pose: the mapping between the table (mm) and the image (px)."""

    camera: CameraModel
    pose: PlanePose

    def project(self, world_xy: ArrayLike, height_mm: ArrayLike = 0.0) -> F64:
        """Table points (..., 2) in mm, ``height_mm`` above the table, to pixels, exactly
        (see CameraModel.project)."""
        return self.camera.project(world_xy, self.pose, height_mm)

    def homography(self) -> F64:
        """The table -> image homography (see CameraModel.homography): exact without
        distortion, else the undistorted part."""
        return self.camera.homography(self.pose)

    def image_to_plane(self, pixels: ArrayLike) -> F64:
        """Pixels to the table points they see (see CameraModel.image_to_plane)."""
        return self.camera.image_to_plane(pixels, self.pose)
