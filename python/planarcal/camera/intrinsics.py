"""Full camera intrinsics: the pinhole matrix K and OpenCV's lens-distortion model.

A plane's homography alone maps pixels to millimetres on the plane itself; it cannot say
where a ray meets anything *above* the plane (the top of a part, a post), and it absorbs the
lens's distortion only as well as a projective map can (not at all near the image corners).
With the camera's intrinsics both become exact: pixels are first undistorted onto the ideal
pinhole image (same K), the homography of the ideal image is decomposed into the plane's pose
(:func:`plane_pose`), and a pixel's ray can then be followed to any height above the table
(:func:`points_at_height`).

Conventions (as :mod:`planarcal.synth`):

* **Pixels**: OpenCV's (the centre of pixel (row i, column j) is (x, y) = (j, i)).
* **Normalised coordinates**: (x, y) = K^-1 (u, v, 1), skew included; the distortion model
  acts on them exactly as OpenCV's (radial k1..k6, tangential p1, p2, thin prism s1..s4,
  tilted sensor tauX, tauY: distortion vectors of length 4, 5, 8, 12 or 14).
* **Table coordinates** (mm): X, Y on the plane, Z = X x Y. With a board read unmirrored
  (X along the image's x, Y along its y, as :mod:`planarcal.calib.detect` orders it) Z points away
  from the camera, into the table, and the camera centre has a negative Z.

OpenCV's own point functions ignore the skew term of K and invert the distortion by a
fixed-point iteration that stops after 5 steps (0.8 px off at the corners of the webcam in
OpenCV's calibration tutorial); here the normalisation is exact, every undistorted point is
polished by Newton's method on the forward model until it reproduces its pixel to machine
precision, and is then checked to lie inside the part of the model that can be inverted (see
:meth:`CameraIntrinsics.undistort_points`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.detect import BoardDetection, detect_board
from planarcal.errors import BoardNotFoundError, ImageError, IntrinsicsError
from planarcal.files import atomic_write

__all__ = [
    "DIST_COEFF_LENGTHS",
    "MAX_FOCAL_REL_STD",
    "CameraIntrinsics",
    "PlanePoseEstimate",
    "calibrate_camera",
    "plane_pose",
    "points_at_height",
]

F64 = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

DIST_COEFF_LENGTHS = (4, 5, 8, 12, 14)
"""The lengths OpenCV accepts for a distortion vector: (k1, k2, p1, p2[, k3[, k4, k5, k6[,
s1, s2, s3, s4[, tauX, tauY]]]])."""

MAX_FOCAL_REL_STD = 0.01
"""calibrate_camera refuses a result whose focal length is this uncertain (1 sigma, relative to
the focal length; the larger of OpenCV's covariance estimate and a profile of the fit): it
means the views do not determine it (too little tilt), and a focal length off by percents
puts every height off by about as much."""

# The forward model is checked to keep its orientation (positive Jacobian, positive rational
# denominator) at this many points along the segment from the optical axis to each point.
_FOLD_SAMPLES = 32
# Newton's method: stop at this relative residual (normalised coordinates), accept up to the
# looser one (1e-12 is about 1e-9 px for a 1000 px focal length).
_NEWTON_STOP = 1e-15
_NEWTON_ACCEPT = 1e-12
_NEWTON_ITERATIONS = 60
# Points processed at once by the vectorised fold check (bounds its memory).
_CHUNK = 65536
# The polar grid on which each model's fold-free disc is found once (see _fold_free_radius).
_SAFE_ANGLES = 360
_SAFE_STEPS = 4000
_SAFE_MAX = 4.0

_COEFF_NAMES: tuple[str, ...] = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
_COEFF_NAMES += ("s1", "s2", "s3", "s4", "tauX", "tauY")

# OpenCV's YAML/XML node names, the calibration sample's first.
_MATRIX_NODES = ("camera_matrix", "cameraMatrix", "K")
_DIST_NODES = ("distortion_coefficients", "dist_coeffs", "distCoeffs", "D")
_WIDTH_NODES = ("image_width", "imageWidth")
_HEIGHT_NODES = ("image_height", "imageHeight")
_SIZE_NODES = ("image_size", "imageSize")
_RMS_NODES = ("avg_reprojection_error", "rms", "reprojection_error")
_VIEWS_NODES = ("nr_of_frames", "nframes", "n_views")
_PER_VIEW_NODES = ("per_view_reprojection_errors",)


# ------------------------------------------------------------------------------------------
# Validation helpers


def _matrix(value: Any) -> F64:
    """A camera matrix as a read-only float64 (3, 3) array, or IntrinsicsError saying why not.

    K must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0: the skew s is allowed
    (and honoured by every mapping here), anything else in the lower rows would not be a
    pinhole camera."""
    try:
        k = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise IntrinsicsError(f"the camera matrix must be a 3 x 3 array of numbers: {e}") from None
    if k.shape != (3, 3):
        raise IntrinsicsError(f"the camera matrix must be 3 x 3, got shape {k.shape}")
    if not np.isfinite(k).all():
        raise IntrinsicsError(f"the camera matrix has NaN or infinite entries: {k.tolist()}")
    if not (k[0, 0] > 0 and k[1, 1] > 0):
        raise IntrinsicsError(
            f"the camera matrix's focal lengths must be positive, got fx={k[0, 0]!r}, "
            f"fy={k[1, 1]!r}"
        )
    if k[1, 0] != 0 or k[2, 0] != 0 or k[2, 1] != 0 or k[2, 2] != 1:
        raise IntrinsicsError(
            f"the camera matrix must be [[fx, skew, cx], [0, fy, cy], [0, 0, 1]], got {k.tolist()}"
        )
    k.setflags(write=False)
    return k


def _dist_coeffs(value: Any) -> F64:
    """A distortion vector as a read-only float64 (n,) array, n in DIST_COEFF_LENGTHS."""
    try:
        d = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise IntrinsicsError(f"the distortion coefficients must be numbers: {e}") from None
    if d.ndim == 2 and 1 in d.shape:
        d = d.reshape(-1)
    if d.ndim != 1 or d.size not in DIST_COEFF_LENGTHS:
        raise IntrinsicsError(
            "the distortion coefficients must be a vector of 4, 5, 8, 12 or 14 numbers "
            f"(OpenCV's (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1..s4[, tauX, tauY]]]])), got "
            f"shape {d.shape}"
        )
    if not np.isfinite(d).all():
        raise IntrinsicsError(f"the distortion coefficients have NaN or infinite entries: {d}")
    d.setflags(write=False)
    return d


def _whole(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise IntrinsicsError(f"{name} must be a whole number, got {value!r}")
    if value < minimum:
        raise IntrinsicsError(f"{name} must be at least {minimum}, got {value}")
    return int(value)


def _nonnegative(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise IntrinsicsError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and v >= 0):
        raise IntrinsicsError(f"{name} must be a finite number >= 0, got {value!r}")
    return v


def _image_size(value: Any) -> tuple[int, int]:
    try:
        items = list(value)
    except TypeError:
        items = []
    if len(items) != 2:
        raise IntrinsicsError(f"image_size must be (width, height) in pixels, got {value!r}")
    return (_whole("image width", items[0], 1), _whole("image height", items[1], 1))


# ------------------------------------------------------------------------------------------
# OpenCV's distortion model, in NumPy (vectorised, with its Jacobian)


@dataclasses.dataclass(frozen=True)
class _Lens:
    """The distortion vector unpacked (missing terms are 0) and the tilted sensor's
    projection matrices (None when tauX = tauY = 0)."""

    k: tuple[float, float, float, float, float, float]
    p: tuple[float, float]
    s: tuple[float, float, float, float]
    tilt: F64 | None
    untilt: F64 | None

    @classmethod
    def of(cls, d: F64) -> _Lens:
        c = np.zeros(14)
        c[: d.size] = d
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4, tx, ty = (float(v) for v in c)
        tilt: F64 | None = None
        untilt: F64 | None = None
        if tx or ty:
            tilt = _tilt_matrix(tx, ty)
            untilt = np.asarray(np.linalg.inv(tilt), dtype=np.float64)
        return cls((k1, k2, k3, k4, k5, k6), (p1, p2), (s1, s2, s3, s4), tilt, untilt)

    @property
    def identity(self) -> bool:
        return not (any(self.k) or any(self.p) or any(self.s) or self.tilt is not None)

    def distort(self, x: F64, y: F64) -> tuple[F64, F64, F64]:
        """Undistorted normalised (x, y) to distorted ones before the sensor tilt, and the
        rational model's denominator (which must stay positive)."""
        k1, k2, k3, k4, k5, k6 = self.k
        p1, p2 = self.p
        s1, s2, s3, s4 = self.s
        r2 = x * x + y * y
        num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        radial = num / den
        xy2 = 2.0 * x * y
        xd = x * radial + p1 * xy2 + p2 * (r2 + 2.0 * x * x) + r2 * (s1 + r2 * s2)
        yd = y * radial + p1 * (r2 + 2.0 * y * y) + p2 * xy2 + r2 * (s3 + r2 * s4)
        return xd, yd, den

    def jacobian(self, x: F64, y: F64) -> tuple[F64, F64, F64, F64, F64, F64, F64]:
        """distort() and its Jacobian: (xd, yd, dxd/dx, dxd/dy, dyd/dx, dyd/dy, den)."""
        k1, k2, k3, k4, k5, k6 = self.k
        p1, p2 = self.p
        s1, s2, s3, s4 = self.s
        r2 = x * x + y * y
        num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        radial = num / den
        dnum = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
        dden = k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2)
        # d radial / d r2, times 2 (d r2 / dx = 2 x).
        dr = 2.0 * (dnum * den - num * dden) / (den * den)
        xy2 = 2.0 * x * y
        xd = x * radial + p1 * xy2 + p2 * (r2 + 2.0 * x * x) + r2 * (s1 + r2 * s2)
        yd = y * radial + p1 * (r2 + 2.0 * y * y) + p2 * xy2 + r2 * (s3 + r2 * s4)
        sx = 2.0 * (s1 + 2.0 * s2 * r2)  # d(s1 r2 + s2 r2^2) / dx = sx * x
        sy = 2.0 * (s3 + 2.0 * s4 * r2)
        a = radial + x * x * dr + 2.0 * p1 * y + 6.0 * p2 * x + sx * x
        b = x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y + sx * y
        c = x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y + sy * x
        d = radial + y * y * dr + 6.0 * p1 * y + 2.0 * p2 * x + sy * y
        return xd, yd, a, b, c, d, den


def _tilt_matrix(tau_x: float, tau_y: float) -> F64:
    """OpenCV's computeTiltProjectionMatrix (the tilted sensor of the 14-term model)."""
    cx, sx = math.cos(tau_x), math.sin(tau_x)
    cy, sy = math.cos(tau_y), math.sin(tau_y)
    rot_x = np.array([[1.0, 0.0, 0.0], [0.0, cx, sx], [0.0, -sx, cx]])
    rot_y = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]])
    rot = rot_y @ rot_x
    proj_z = np.array([[rot[2, 2], 0.0, -rot[0, 2]], [0.0, rot[2, 2], -rot[1, 2]], [0.0, 0.0, 1.0]])
    return np.asarray(proj_z @ rot, dtype=np.float64)


def _apply_projective(m: F64, x: F64, y: F64) -> tuple[F64, F64, F64]:
    """(x, y) through the 3 x 3 projective map m, and the homogeneous w (sign matters)."""
    w = m[2, 0] * x + m[2, 1] * y + m[2, 2]
    safe = np.where(w != 0.0, w, 1.0)
    return (
        (m[0, 0] * x + m[0, 1] * y + m[0, 2]) / safe,
        (m[1, 0] * x + m[1, 1] * y + m[1, 2]) / safe,
        w,
    )


def _fold_free_radius(lens: _Lens) -> float:
    """A radius (normalised, undistorted) inside which the model has no fold: the forward
    map's Jacobian determinant and rational denominator are positive on a polar grid of
    _SAFE_ANGLES directions x _SAFE_STEPS radii out to _SAFE_MAX (about 76 degrees off axis),
    less one grid step. Points inside it need no check of their own (most points: the fold
    of a fitted model lies near or beyond the image's corners)."""
    if lens.identity:
        return _SAFE_MAX
    angles = np.linspace(0.0, 2.0 * np.pi, _SAFE_ANGLES, endpoint=False)
    radii = np.linspace(0.0, _SAFE_MAX, _SAFE_STEPS + 1)[1:]
    step = _SAFE_MAX / _SAFE_STEPS
    first_bad = _SAFE_MAX + step
    for chunk in np.array_split(radii, 8):
        x = chunk[:, None] * np.cos(angles)[None, :]
        y = chunk[:, None] * np.sin(angles)[None, :]
        _, _, a, b, c, d, den = lens.jacobian(x, y)
        bad = ~((a * d - b * c > 0.0) & (den > 0.0)).all(axis=1)
        if bad.any():
            first_bad = float(chunk[int(np.argmax(bad))])
            break
    return max(0.0, first_bad - step)


def _unfolded(lens: _Lens, x: F64, y: F64, safe_radius: float) -> BoolArray:
    """Whether each undistorted normalised point lies in the model's valid region: along the
    segment from the optical axis to it the forward map keeps its orientation (Jacobian
    determinant > 0) and its rational denominator stays positive. Past a fold the same
    distorted position has a second preimage, so no point there can be told apart from its
    mirror inside; a model fitted by calibrateCamera is only meaningful inside the fold.
    Points within ``safe_radius`` (see _fold_free_radius) pass at once; the others are
    checked at _FOLD_SAMPLES points along their segment."""
    ok = np.ones(x.shape, dtype=bool)
    if lens.identity:
        return ok
    far = np.flatnonzero(x * x + y * y >= safe_radius * safe_radius)
    ts = np.arange(1, _FOLD_SAMPLES + 1, dtype=np.float64) / _FOLD_SAMPLES
    step = max(1, _CHUNK // _FOLD_SAMPLES)
    for start in range(0, far.size, step):
        idx = far[start : start + step]
        xs = x[idx, None] * ts[None, :]
        ys = y[idx, None] * ts[None, :]
        _, _, a, b, c, d, den = lens.jacobian(xs, ys)
        ok[idx] = ((a * d - b * c > 0.0) & (den > 0.0)).all(axis=1)
    if lens.tilt is not None:
        xd, yd, _ = lens.distort(x, y)
        _, _, w = _apply_projective(lens.tilt, xd, yd)
        ok &= w > 0.0
    return ok


def _opencv_guess(lens_coeffs: F64, xt: F64, yt: F64) -> tuple[F64, F64]:
    """OpenCV's own iterative undistortion of untilted distorted normalised points (a
    starting point for Newton's method; NaN where it gave nothing finite)."""
    src = np.column_stack([xt, yt]).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-12)
    eye = np.eye(3)
    try:
        if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4
            out = cv2.undistortPointsIter(src, eye, lens_coeffs, None, None, criteria)
        else:  # OpenCV 5: undistortPoints takes the criteria
            out = cv2.undistortPoints(src, eye, lens_coeffs, None, None, None, criteria)
    except cv2.error:
        nan = np.full(xt.shape, np.nan)
        return nan, nan.copy()
    out = np.asarray(out, dtype=np.float64).reshape(-1, 2)
    return out[:, 0].copy(), out[:, 1].copy()


def _newton(lens: _Lens, xt: F64, yt: F64, x0: F64, y0: F64) -> tuple[F64, F64, BoolArray]:
    """Solve distort(x, y) = (xt, yt) by Newton's method with backtracking (a step is halved
    until it lowers the residual), from (x0, y0). Returns the solution and whether each point
    converged to the residual _NEWTON_ACCEPT (relative)."""
    x, y = x0.copy(), y0.copy()
    scale = 1.0 + np.hypot(xt, yt)
    xd, yd, _ = lens.distort(x, y)
    res = np.hypot(xd - xt, yd - yt)
    res = np.where(np.isfinite(res), res, np.inf)
    active = np.flatnonzero(res > _NEWTON_STOP * scale)
    for _ in range(_NEWTON_ITERATIONS):
        if active.size == 0:
            break
        xa, ya = x[active], y[active]
        fx, fy, a, b, c, d, _den = lens.jacobian(xa, ya)
        rx, ry = fx - xt[active], fy - yt[active]
        det = a * d - b * c
        with np.errstate(divide="ignore", invalid="ignore"):
            dx = (d * rx - b * ry) / det
            dy = (a * ry - c * rx) / det
        old = res[active]
        step = np.ones(active.size)
        new = np.full(active.size, np.inf)
        nx, ny = xa, ya
        for _halving in range(30):
            nx, ny = xa - step * dx, ya - step * dy
            gx, gy, _ = lens.distort(nx, ny)
            new = np.hypot(gx - xt[active], gy - yt[active])
            worse = ~(new < old)  # NaN counts as worse
            if not worse.any():
                break
            step = np.where(worse, 0.5 * step, step)
        better = new < old
        idx = active[better]
        x[idx], y[idx], res[idx] = nx[better], ny[better], new[better]
        # Points that can no longer improve are done, converged or not.
        still = better & (new > _NEWTON_STOP * scale[active])
        active = active[still]
    converged = np.isfinite(x) & np.isfinite(y) & (res <= _NEWTON_ACCEPT * scale)
    return x, y, converged


def _continuation(lens: _Lens, xt: F64, yt: F64) -> tuple[F64, F64, BoolArray]:
    """Undistort by following the solution from the optical axis outwards (solving for
    t * target, t = 0.05 .. 1): finds the preimage in the model's central, valid sheet even
    where Newton's method from a poor start reached another one."""
    x, y = 0.05 * xt, 0.05 * yt
    ok = np.ones(xt.shape, dtype=bool)
    for t in np.linspace(0.05, 1.0, 20):
        x, y, conv = _newton(lens, t * xt, t * yt, x, y)
        ok &= conv
    return x, y, ok


# ------------------------------------------------------------------------------------------
# The intrinsics


@dataclasses.dataclass(frozen=True, eq=False)
class CameraIntrinsics:
    """A camera's intrinsic matrix K and OpenCV distortion vector, for images of one size.

    ``matrix``: [[fx, skew, cx], [0, fy, cy], [0, 0, 1]] (pixels). ``dist_coeffs``: OpenCV's
    (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tauX, tauY]]]]); (1, n) and (n, 1)
    arrays are accepted and flattened. ``image_size``: (width, height) of the images the
    intrinsics belong to (K scales with the resolution, so they hold for that size only).
    ``rms_px``, ``n_views`` and ``per_view_rms_px``: the calibration's RMS reprojection
    error, how many views it used, and each view's RMS, when it was estimated here.

    Validated on construction (IntrinsicsError naming the fault); the arrays are read-only
    copies, so an instance can be shared between threads and used as a dict key.
    """

    matrix: F64
    dist_coeffs: F64
    image_size: tuple[int, int]
    rms_px: float | None = None
    n_views: int | None = None
    per_view_rms_px: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "matrix", _matrix(self.matrix))
        object.__setattr__(self, "dist_coeffs", _dist_coeffs(self.dist_coeffs))
        object.__setattr__(self, "image_size", _image_size(self.image_size))
        if self.rms_px is not None:
            object.__setattr__(self, "rms_px", _nonnegative("rms_px", self.rms_px))
        if self.n_views is not None:
            object.__setattr__(self, "n_views", _whole("n_views", self.n_views, 1))
        if self.per_view_rms_px is not None:
            try:
                items = list(self.per_view_rms_px)
            except TypeError:
                raise IntrinsicsError(
                    f"per_view_rms_px must be a sequence of numbers, got {self.per_view_rms_px!r}"
                ) from None
            values = tuple(_nonnegative(f"per_view_rms_px[{i}]", v) for i, v in enumerate(items))
            if self.n_views is not None and len(values) != self.n_views:
                raise IntrinsicsError(
                    f"per_view_rms_px has {len(values)} values for n_views={self.n_views}"
                )
            object.__setattr__(self, "per_view_rms_px", values)
        object.__setattr__(self, "_lens", _Lens.of(self.dist_coeffs))

    # -- identity --------------------------------------------------------------------------

    def _key(self) -> tuple[Any, ...]:
        return (
            self.matrix.tobytes(),
            self.dist_coeffs.tobytes(),
            self.image_size,
            self.rms_px,
            self.n_views,
            self.per_view_rms_px,
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, CameraIntrinsics):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        # Through the constructor, so a copy is validated and its arrays read-only again.
        return (
            CameraIntrinsics,
            (
                np.array(self.matrix),
                np.array(self.dist_coeffs),
                self.image_size,
                self.rms_px,
                self.n_views,
                self.per_view_rms_px,
            ),
        )

    def __repr__(self) -> str:
        rms = "" if self.rms_px is None else f", rms_px={self.rms_px:.4g}"
        views = "" if self.n_views is None else f", n_views={self.n_views}"
        skew = f", skew={self.skew:.6g}" if self.skew else ""
        return (
            f"CameraIntrinsics(fx={self.fx:.6g}, fy={self.fy:.6g}, cx={self.cx:.6g}, "
            f"cy={self.cy:.6g}{skew}, dist_coeffs={np.round(self.dist_coeffs, 6).tolist()}, "
            f"image_size={self.image_size}{rms}{views})"
        )

    # -- parts -----------------------------------------------------------------------------

    @property
    def fx(self) -> float:
        return float(self.matrix[0, 0])

    @property
    def fy(self) -> float:
        return float(self.matrix[1, 1])

    @property
    def cx(self) -> float:
        return float(self.matrix[0, 2])

    @property
    def cy(self) -> float:
        return float(self.matrix[1, 2])

    @property
    def skew(self) -> float:
        return float(self.matrix[0, 1])

    @property
    def _model(self) -> _Lens:
        lens: _Lens = self.__dict__["_lens"]
        return lens

    @functools.cached_property
    def _fold_free_radius(self) -> float:
        return _fold_free_radius(self._model)

    def _normalise(self, px: F64) -> tuple[F64, F64]:
        """Pixels to normalised coordinates, K^-1 exactly (skew included)."""
        y = (px[:, 1] - self.cy) / self.fy
        x = (px[:, 0] - self.cx - self.skew * y) / self.fx
        return x, y

    def _pixels(self, x: F64, y: F64) -> F64:
        return np.column_stack([self.fx * x + self.skew * y + self.cx, self.fy * y + self.cy])

    # -- mappings --------------------------------------------------------------------------

    def undistort_points(self, px: ArrayLike) -> F64:
        """Distorted pixel positions (..., 2) -> where the ideal pinhole camera with the same
        K would see them (..., 2): the inverse of :meth:`distort_points`.

        Each point is started from OpenCV's iterative undistortion and finished by Newton's
        method on the forward model until it reproduces its pixel to about 1e-12 of the
        normalised radius (1e-9 px), then checked to lie inside the model's valid region
        (before any fold-over, where the forward map stops being one-to-one). A point that
        cannot be inverted there raises IntrinsicsError naming it: beyond the fold a
        distorted model has either no preimage or a spurious one, and any answer would be
        wrong.
        """
        flat, shape = arguments.points("px", px, IntrinsicsError)
        ux, uy, ok = self._undistort(flat)
        if not ok.all():
            k = int(np.flatnonzero(~ok)[0])
            n_bad = int((~ok).sum())
            raise IntrinsicsError(
                f"pixel {k} {flat[k].tolist()} cannot be undistorted: it lies beyond where "
                f"the lens model {self._describe_lens()} can be inverted (its fold-over, "
                "where two directions would map to one pixel)"
                + (f"; {n_bad} points in all" if n_bad > 1 else "")
                + ". The model is only valid over the part of the image its calibration "
                "views covered."
            )
        return self._pixels(ux, uy).reshape(*shape, 2)

    def _undistort(self, flat: F64) -> tuple[F64, F64, BoolArray]:
        """Undistorted normalised coordinates of pixels (N, 2), and which are valid."""
        lens = self._model
        x, y = self._normalise(flat)
        if lens.identity or flat.shape[0] == 0:
            return x, y, np.ones(x.shape, dtype=bool)
        behind = np.zeros(x.shape, dtype=bool)
        if lens.untilt is not None:
            x, y, w = _apply_projective(lens.untilt, x, y)
            behind = ~(w > 0.0)
        coeffs = np.asarray(self.dist_coeffs[:12], dtype=np.float64)
        gx, gy = _opencv_guess(coeffs, x, y)
        bad_guess = ~(np.isfinite(gx) & np.isfinite(gy))
        gx[bad_guess], gy[bad_guess] = x[bad_guess], y[bad_guess]
        ux, uy, ok = _newton(lens, x, y, gx, gy)
        ok &= ~behind
        safe = self._fold_free_radius
        ok[ok] = _unfolded(lens, ux[ok], uy[ok], safe)
        retry = np.flatnonzero(~ok & ~behind)
        if retry.size:
            rx, ry, rok = _continuation(lens, x[retry], y[retry])
            rok[rok] = _unfolded(lens, rx[rok], ry[rok], safe)
            ux[retry[rok]], uy[retry[rok]] = rx[rok], ry[rok]
            ok[retry[rok]] = True
        return ux, uy, ok

    def distort_points(self, ideal_px: ArrayLike) -> F64:
        """Ideal pinhole pixel positions (..., 2) -> where the real, distorting camera sees
        them (..., 2): OpenCV's forward model (as cv2.projectPoints of the normalised rays
        K^-1 p, but with K's skew honoured). Points beyond the model's fold-over (see
        :meth:`undistort_points`) raise IntrinsicsError naming the first."""
        flat, shape = arguments.points("ideal_px", ideal_px, IntrinsicsError)
        lens = self._model
        x, y = self._normalise(flat)
        if lens.identity or flat.shape[0] == 0:
            return self._pixels(x, y).reshape(*shape, 2)
        ok = _unfolded(lens, x, y, self._fold_free_radius)
        if not ok.all():
            k = int(np.flatnonzero(~ok)[0])
            raise IntrinsicsError(
                f"ideal pixel {k} {flat[k].tolist()} lies beyond the fold-over of the lens "
                f"model {self._describe_lens()}: the model does not describe that direction"
            )
        xd, yd, _ = lens.distort(x, y)
        if lens.tilt is not None:
            xd, yd, _ = _apply_projective(lens.tilt, xd, yd)
        return self._pixels(xd, yd).reshape(*shape, 2)

    def check_invertible_over_image(self) -> None:
        """Raise IntrinsicsError unless every pixel of the image can be undistorted.

        The pixels of the image's border are undistorted; for a model whose valid region is
        star-shaped about the principal point (any radially dominated lens) the whole image
        is then valid, since each pixel lies on a segment from the principal point to the
        border. A model fitted to views that never reached the image's corners can fold over
        before them; this says so up front rather than at the first pixel there.
        """
        w, h = self.image_size
        xs = np.arange(w, dtype=np.float64)
        ys = np.arange(h, dtype=np.float64)
        border = np.concatenate(
            [
                np.column_stack([xs, np.zeros(w)]),
                np.column_stack([xs, np.full(w, h - 1.0)]),
                np.column_stack([np.zeros(h), ys]),
                np.column_stack([np.full(h, w - 1.0), ys]),
            ]
        )
        _, _, ok = self._undistort(border)
        if not ok.all():
            first = border[int(np.flatnonzero(~ok)[0])]
            raise IntrinsicsError(
                f"the lens model {self._describe_lens()} cannot be inverted over the whole "
                f"{w} x {h} image: it folds over before {int((~ok).sum())} of the image's "
                f"border pixels, the first at ({first[0]:g}, {first[1]:g})"
            )

    def _describe_lens(self) -> str:
        terms = [f"{n}={v:.6g}" for n, v in zip(_COEFF_NAMES, self.dist_coeffs, strict=False) if v]
        return "(" + (", ".join(terms) or "no distortion") + ")"

    # -- JSON ------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready description (plain lists and numbers; see from_dict)."""
        return {
            "camera_matrix": self.matrix.tolist(),
            "dist_coeffs": self.dist_coeffs.tolist(),
            "image_size_px": [self.image_size[0], self.image_size[1]],
            "rms_px": self.rms_px,
            "n_views": self.n_views,
            "per_view_rms_px": None if self.per_view_rms_px is None else list(self.per_view_rms_px),
        }

    @classmethod
    def from_dict(cls, data: Any) -> CameraIntrinsics:
        """The intrinsics described by to_dict(); IntrinsicsError naming the fault when
        ``data`` is not such a description."""
        if not isinstance(data, dict):
            raise IntrinsicsError(f"intrinsics must be a JSON object, got {type(data).__name__}")
        missing = [k for k in ("camera_matrix", "dist_coeffs", "image_size_px") if k not in data]
        if missing:
            raise IntrinsicsError(f"intrinsics lack {', '.join(missing)}: got {sorted(data)}")
        for key in ("camera_matrix", "dist_coeffs"):
            if not _nested_numbers(data[key]):
                raise IntrinsicsError(f"intrinsics {key} must be (lists of) numbers: {data[key]!r}")
        size = data["image_size_px"]
        if not isinstance(size, list | tuple):
            raise IntrinsicsError(f"image_size_px must be [width, height], got {size!r}")
        per_view = data.get("per_view_rms_px")
        if per_view is not None and not isinstance(per_view, list | tuple):
            raise IntrinsicsError(f"per_view_rms_px must be a list of numbers, got {per_view!r}")
        return cls(
            matrix=np.array(data["camera_matrix"], dtype=np.float64),
            dist_coeffs=np.array(data["dist_coeffs"], dtype=np.float64),
            image_size=_image_size(size),
            rms_px=data.get("rms_px"),
            n_views=data.get("n_views"),
            per_view_rms_px=None if per_view is None else tuple(per_view),
        )

    # -- OpenCV files ----------------------------------------------------------------------

    def save_yaml(self, path: str | os.PathLike[str]) -> Path:
        """Write the intrinsics as OpenCV's calibration sample does (``camera_matrix``,
        ``distortion_coefficients``, ``image_width``, ``image_height``, and
        ``avg_reprojection_error``, ``nr_of_frames``, ``per_view_reprojection_errors`` when
        known), atomically. The format follows the suffix: ``.xml`` XML, ``.json`` JSON,
        anything else YAML. Numbers are written with 17 significant digits, so a loaded file
        gives back exactly these intrinsics.

        The required nodes come last and the distortion vector at the very end: a file cut
        short anywhere then lacks a required node or ends inside one, and load_yaml refuses
        it instead of reading a shortened number.
        """
        target = Path(path)
        suffix = target.suffix.lower()
        fmt = suffix if suffix in (".xml", ".json") else ".yaml"
        fs = cv2.FileStorage("intrinsics" + fmt, cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
        if self.n_views is not None:
            fs.write("nr_of_frames", int(self.n_views))
        if self.rms_px is not None:
            fs.write("avg_reprojection_error", float(self.rms_px))
        if self.per_view_rms_px is not None and self.per_view_rms_px:
            fs.write(
                "per_view_reprojection_errors",
                np.array(self.per_view_rms_px, dtype=np.float64).reshape(-1, 1),
            )
        fs.write("image_width", int(self.image_size[0]))
        fs.write("image_height", int(self.image_size[1]))
        fs.write("camera_matrix", np.array(self.matrix))
        fs.write("distortion_coefficients", np.array(self.dist_coeffs).reshape(-1, 1))
        text = fs.releaseAndGetString()
        return atomic_write(target, text)

    @classmethod
    def load_yaml(cls, path: str | os.PathLike[str]) -> CameraIntrinsics:
        """Read intrinsics from an OpenCV calibration file (YAML, XML or JSON as written by
        cv2.FileStorage): OpenCV's calibration sample's nodes ``camera_matrix``,
        ``distortion_coefficients``, ``image_width``, ``image_height`` (and
        ``avg_reprojection_error``, ``nr_of_frames``, ``per_view_reprojection_errors`` if
        present), or the common variants ``cameraMatrix`` / ``K``, ``dist_coeffs`` /
        ``distCoeffs`` / ``D``, ``image_size`` / ``imageSize`` as [width, height]. Matrices
        may be ``!!opencv-matrix`` nodes, ROS-style maps with ``rows``, ``cols``, ``data``, or
        plain (nested) lists.

        IntrinsicsError says which: no such file, a file that is not OpenCV's format
        (corrupt or truncated), or the nodes that are missing or malformed.
        """
        p = Path(path)
        try:
            raw = p.read_bytes()
        except FileNotFoundError:
            raise IntrinsicsError(f"no intrinsics file at {str(p)!r}") from None
        except OSError as e:
            raise IntrinsicsError(f"cannot read {str(p)!r}: {e.strerror or e}") from None
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise IntrinsicsError(
                f"{str(p)!r} is not an OpenCV YAML/XML file: it is not text (corrupt?)"
            ) from None
        if not text.strip():
            raise IntrinsicsError(f"{str(p)!r} is empty")
        if "\x00" in text:
            raise IntrinsicsError(f"{str(p)!r} is not an OpenCV YAML/XML file: it has NUL bytes")
        try:
            fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
            opened = fs.isOpened()
            root = fs.root() if opened else None
        except (cv2.error, SystemError) as e:
            # OpenCV's parser errors surface as SystemError with the cv2.error as its cause.
            raise IntrinsicsError(
                f"{str(p)!r} is not a valid OpenCV YAML/XML/JSON file (corrupt or "
                f"truncated?): {_last_line(e)}"
            ) from None
        if root is None or not root.isMap():
            raise IntrinsicsError(
                f"{str(p)!r} holds no OpenCV calibration nodes (expected camera_matrix, "
                "distortion_coefficients, image_width, image_height)"
            )
        return _from_file_storage(root, repr(str(p)))


def _nested_numbers(value: Any) -> bool:
    """Whether value is a number or a (nested) list of numbers (no bools, no strings)."""
    if isinstance(value, bool):
        return False
    if isinstance(value, int | float):
        return True
    if isinstance(value, list | tuple):
        return all(_nested_numbers(v) for v in value)
    return False


# ------------------------------------------------------------------------------------------
# Reading cv2.FileStorage nodes


def _find(root: Any, names: Sequence[str]) -> tuple[str, Any] | None:
    for name in names:
        node = root.getNode(name)
        if not node.empty() and not node.isNone():
            return name, node
    return None


def _node_number(node: Any, what: str) -> float:
    if not (node.isInt() or node.isReal()):
        raise IntrinsicsError(f"{what} is not a number")
    return float(node.real())


def _node_matrix(node: Any, what: str) -> F64:
    """A matrix node as float64: an ``!!opencv-matrix``, a map with rows, cols and data
    (ROS's camera_info YAML), or a (nested) sequence of numbers."""
    if node.isMap():
        keys = set(node.keys())
        if "data" not in keys:
            raise IntrinsicsError(f"{what} is a map without 'data': {sorted(keys)}")
        if "dt" in keys:
            try:
                m = node.mat()
            except (cv2.error, SystemError) as e:
                raise IntrinsicsError(
                    f"{what} is a malformed opencv-matrix: {_last_line(e)}"
                ) from None
            if m is None:
                raise IntrinsicsError(f"{what} is a malformed opencv-matrix")
            return np.asarray(m, dtype=np.float64)
        data = _node_matrix(node.getNode("data"), what + ".data").reshape(-1)
        if "rows" in keys and "cols" in keys:
            rows = _node_number(node.getNode("rows"), what + ".rows")
            cols = _node_number(node.getNode("cols"), what + ".cols")
            if rows * cols != data.size:
                raise IntrinsicsError(
                    f"{what} says {rows:g} x {cols:g} but has {data.size} numbers"
                )
            return data.reshape(int(rows), int(cols))
        return data
    if node.isSeq():
        items = [node.at(i) for i in range(node.size())]
        if items and all(item.isSeq() for item in items):
            rows_ = [_node_matrix(item, what).reshape(-1) for item in items]
            if len({r.size for r in rows_}) != 1:
                raise IntrinsicsError(f"{what} has rows of different lengths")
            return np.vstack(rows_)
        return np.array([_node_number(item, what) for item in items], dtype=np.float64)
    raise IntrinsicsError(f"{what} is not a matrix")


def _from_file_storage(root: Any, source: str) -> CameraIntrinsics:
    k_node = _find(root, _MATRIX_NODES)
    d_node = _find(root, _DIST_NODES)
    w_node = _find(root, _WIDTH_NODES)
    h_node = _find(root, _HEIGHT_NODES)
    s_node = _find(root, _SIZE_NODES)
    missing = []
    if k_node is None:
        missing.append(" / ".join(_MATRIX_NODES))
    if d_node is None:
        missing.append(" / ".join(_DIST_NODES))
    if s_node is None and (w_node is None or h_node is None):
        if w_node is None:
            missing.append("image_width")
        if h_node is None:
            missing.append("image_height")
    if missing:
        present = sorted(root.keys())
        raise IntrinsicsError(
            f"{source} lacks the node(s) {'; '.join(missing)} (it has: "
            f"{', '.join(present) or 'nothing'}); corrupt or truncated, or not a camera "
            "calibration"
        )
    assert k_node is not None and d_node is not None
    try:
        matrix = _node_matrix(k_node[1], f"{source}: {k_node[0]}")
        dist = _node_matrix(d_node[1], f"{source}: {d_node[0]}")
        if w_node is not None and h_node is not None:
            width = _node_number(w_node[1], f"{source}: {w_node[0]}")
            height = _node_number(h_node[1], f"{source}: {h_node[0]}")
        else:
            assert s_node is not None
            size = _node_matrix(s_node[1], f"{source}: {s_node[0]}").reshape(-1)
            if size.size != 2:
                raise IntrinsicsError(f"{source}: {s_node[0]} must be [width, height]")
            width, height = float(size[0]), float(size[1])
        if not (width.is_integer() and height.is_integer()):
            raise IntrinsicsError(f"{source}: the image size {width:g} x {height:g} is not whole")
        rms = n_views = per_view = None
        if (found := _find(root, _RMS_NODES)) is not None:
            rms = _node_number(found[1], f"{source}: {found[0]}")
        if (found := _find(root, _VIEWS_NODES)) is not None:
            views = _node_number(found[1], f"{source}: {found[0]}")
            if not (views.is_integer() and views >= 1):
                raise IntrinsicsError(f"{found[0]} must be a whole number >= 1, got {views:g}")
            n_views = int(views)
        if (found := _find(root, _PER_VIEW_NODES)) is not None:
            per_view = tuple(_node_matrix(found[1], f"{source}: {found[0]}").reshape(-1).tolist())
            if n_views is not None and len(per_view) != n_views:
                per_view = None  # other tools write these differently; not worth refusing
        return CameraIntrinsics(
            matrix=matrix,
            dist_coeffs=dist,
            image_size=(int(width), int(height)),
            rms_px=rms,
            n_views=n_views,
            per_view_rms_px=per_view,
        )
    except IntrinsicsError as e:
        message = str(e)
        if not message.startswith(source):
            message = f"{source}: {message}"
        raise IntrinsicsError(message) from None


# ------------------------------------------------------------------------------------------
# Calibration from board views


def _view_name(view: Any, index: int) -> str:
    if isinstance(view, str | os.PathLike):
        return f"view {index} ({str(Path(view))!r})"
    return f"view {index}"


def calibrate_camera(
    views: Sequence[Any],
    board: CircleGridBoard,
    *,
    fix_aspect_ratio: bool = False,
    zero_tangent: bool = False,
    rational: bool = False,
) -> CameraIntrinsics:
    """Estimate a camera's intrinsics from several views of a flat board (Zhang's method, as
    cv2.calibrateCamera).

    ``views``: images (arrays or paths) or BoardDetection objects (of ``board``), all of one
    image size; each image is searched with detect_board. ``fix_aspect_ratio`` fixes fx = fy
    (square pixels), ``zero_tangent`` fixes p1 = p2 = 0, ``rational`` fits OpenCV's rational
    model (8 coefficients instead of 5).

    The focal length is determined by perspective: by how the board's image converges when
    the board is tilted. At least 3 views are needed, tilted by 20-40 degrees about different
    axes, and spread over the image (the distortion is only known where the board has been).
    Raises IntrinsicsError for fewer than 3 views, views of different sizes, views that leave
    the focal length undetermined (all nearly facing the camera: its 1-sigma uncertainty
    exceeds MAX_FOCAL_REL_STD), or a fitted distortion that folds over inside the image;
    BoardNotFoundError (ImageError) naming the view whose board was not found (which could
    not be read).

    The result carries the overall RMS reprojection error (``rms_px``), each view's
    (``per_view_rms_px``) and ``n_views``.
    """
    if isinstance(views, str | os.PathLike | np.ndarray | BoardDetection):
        raise IntrinsicsError(
            "views must be a list of images, paths or board detections (one per view), got a "
            f"single {type(views).__name__}"
        )
    if not isinstance(board, CircleGridBoard):
        raise IntrinsicsError(f"board must be a CircleGridBoard, got {type(board).__name__}")
    views = list(views)
    if len(views) < 3:
        raise IntrinsicsError(
            f"camera calibration needs at least 3 views of the board, got {len(views)}: "
            "take 6-10, tilted 20-40 degrees about different axes and spread over the image"
        )
    detections: list[BoardDetection] = []
    for i, view in enumerate(views):
        if isinstance(view, BoardDetection):
            if view.board != board:
                raise IntrinsicsError(
                    f"{_view_name(view, i)} is a detection of another board ({view.board}), "
                    f"not {board}"
                )
            det = view
        else:
            try:
                # Each view has its own pose: a board turned in one of them is no mistake.
                det = detect_board(view, board, turned=True)
            except BoardNotFoundError as e:
                raise BoardNotFoundError(f"{_view_name(view, i)}: {e}", e.diagnostics) from None
            except ImageError as e:
                raise ImageError(f"{_view_name(view, i)}: {e}") from None
        if detections and det.image_size != detections[0].image_size:
            w0, h0 = detections[0].image_size
            w, h = det.image_size
            raise IntrinsicsError(
                f"{_view_name(view, i)} is {w} x {h} px but view 0 is {w0} x {h0} px: all views "
                "must come from the same camera at the same resolution"
            )
        detections.append(det)

    # calibrateCamera takes float32 points only (Point3f / Point2f): 6e-5 px of rounding at
    # 1280 px, far below any detection's noise.
    world = board.world_points()
    object_points = [
        np.column_stack([world, np.zeros(len(world))]).reshape(-1, 1, 3).astype(np.float32)
        for _ in detections
    ]
    image_points = [d.image_points.reshape(-1, 1, 2).astype(np.float32) for d in detections]
    size = detections[0].image_size
    flags = 0
    if fix_aspect_ratio:
        flags |= cv2.CALIB_FIX_ASPECT_RATIO
    if zero_tangent:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    if rational:
        flags |= cv2.CALIB_RATIONAL_MODEL
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    try:
        result = cv2.calibrateCameraExtended(
            object_points,
            image_points,
            size,
            np.eye(3),  # only its aspect ratio (1) is used, with CALIB_FIX_ASPECT_RATIO
            np.zeros(8 if rational else 5),
            flags=flags,
            criteria=criteria,
        )
    except cv2.error as e:
        raise IntrinsicsError(
            f"cv2.calibrateCamera failed on the {len(detections)} views ({_last_line(e)}): the "
            "views are probably degenerate; tilt the board 20-40 degrees about different axes"
        ) from None
    rms, k, dist, _rvecs, _tvecs, std_intrinsics, _std_extrinsics, per_view = result
    k_est: F64 = np.asarray(k, dtype=np.float64)
    dist_est: F64 = np.asarray(dist, dtype=np.float64).reshape(-1)
    std = np.asarray(std_intrinsics, dtype=np.float64).reshape(-1)
    if not (np.isfinite(k_est).all() and np.isfinite(dist_est).all() and math.isfinite(rms)):
        raise IntrinsicsError(
            "cv2.calibrateCamera gave no finite result: the views are degenerate; tilt the "
            "board 20-40 degrees about different axes"
        )
    # How well the views pin the focal length down, two ways: OpenCV's covariance (per axis)
    # and a profile of the fit (see _focal_profile_rel_std), which exact degeneracies
    # cannot hide from: OpenCV pseudo-inverts a singular normal matrix, so views that face the
    # camera squarely give an arbitrary focal length with a tiny "standard deviation".
    n_params = 4 + (8 if rational else 5) + 6 * len(detections)
    rel_std = [
        float(std[0] / k_est[0, 0]) if k_est[0, 0] > 0 else math.inf,
        float(std[1] / k_est[1, 1]) if k_est[1, 1] > 0 else math.inf,
        _focal_profile_rel_std(
            object_points, image_points, size, k_est, dist_est, flags, float(rms), n_params
        ),
    ]
    worst = max(v if math.isfinite(v) else math.inf for v in rel_std)
    if not worst <= MAX_FOCAL_REL_STD:
        shown = "unbounded" if not math.isfinite(worst) else f"+- {100 * worst:.2g} %"
        rational_note = (
            " The rational model's extra terms can also stand in for a focal length (with k1 "
            "and k4 both large its radial factor is nearly a constant scale): unless the views "
            "cover the whole image, calibrate without rational=True."
            if rational
            else ""
        )
        raise IntrinsicsError(
            f"the views do not determine the focal length (fx = {k_est[0, 0]:.1f} px, "
            f"{shown}; at most {100 * MAX_FOCAL_REL_STD:g} % is accepted): the views need more "
            "tilt. Only perspective (a board whose image converges) measures the focal "
            "length: tilt the board 20-40 degrees, about different axes, in several views."
            + rational_note
        )
    # OpenCV returns the coefficients it estimated (5, or 8 with the rational model; 14 if it
    # ever widens them): trim to the length it was asked for.
    n = 8 if rational else 5
    if dist_est.size < n:
        dist_est = np.pad(dist_est, (0, n - dist_est.size))
    intrinsics = CameraIntrinsics(
        matrix=_clean_matrix(k_est),
        dist_coeffs=dist_est[:n],
        image_size=size,
        rms_px=float(rms),
        n_views=len(detections),
        per_view_rms_px=tuple(float(v) for v in np.asarray(per_view).reshape(-1)),
    )
    try:
        intrinsics.check_invertible_over_image()
    except IntrinsicsError as e:
        raise IntrinsicsError(
            f"{e}. The fitted distortion folds over inside the image: add views with the "
            "board near the image's corners and edges, or fit fewer terms (zero_tangent=True, "
            "no rational model)"
        ) from None
    return intrinsics


def _focal_profile_rel_std(
    object_points: list[Any],
    image_points: list[Any],
    size: tuple[int, int],
    k: F64,
    dist: F64,
    flags: int,
    rms: float,
    n_params: int,
) -> float:
    """The focal length's relative 1-sigma uncertainty from the fit's profile: the
    calibration is redone with the focal length held 5 % too short and 5 % too long (all else
    refitted) and the rise of the sum of squared residuals, in units of the residual variance,
    is Delta chi^2 = (0.05 / sigma_rel)^2 for a well-determined focal length. Views that
    cannot tell focal lengths apart refit as well at either (Delta chi^2 ~ 0: infinite). The
    refits start from the distortion rescaled along the exact degeneracy of a fronto-parallel
    board (k_i by s^2i, p_i by s), so they find it where it exists."""
    n_obs = 2 * sum(len(p) for p in image_points)
    sse = rms * rms * n_obs
    sigma2 = sse / max(n_obs - n_params, 1)
    if not sigma2 > 0:
        return 0.0  # a perfect fit: nothing to measure the uncertainty by (synthetic data)
    delta = 0.05
    rises = []
    for s in (1.0 - delta, 1.0 + delta):
        k0 = np.array(k, dtype=np.float64)
        k0[0, 0] *= s
        k0[1, 1] *= s
        d0 = np.array(dist, dtype=np.float64)
        powers = np.array([2, 4, 1, 1, 6, 2, 4, 6][: d0.size], dtype=np.float64)
        d0[: powers.size] *= s**powers
        try:
            refit = cv2.calibrateCamera(
                object_points,
                image_points,
                size,
                k0,
                d0,
                flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_FOCAL_LENGTH,
                criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-15),
            )
        except cv2.error:
            return math.inf
        rms_fixed = float(refit[0])
        if not math.isfinite(rms_fixed):
            return math.inf
        rises.append((rms_fixed * rms_fixed * n_obs - sse) / sigma2)
    rise = min(rises)
    return delta / math.sqrt(rise) if rise > 0 else math.inf


def _clean_matrix(k: F64) -> F64:
    """calibrateCamera's K with its structural zeros and one exactly so (they are, up to the
    last bit of its arithmetic)."""
    out = np.array(k, dtype=np.float64)
    out[1, 0] = out[2, 0] = out[2, 1] = 0.0
    out[2, 2] = 1.0
    return out


def _last_line(e: BaseException) -> str:
    """The gist of an OpenCV error: its last line (OpenCV's "(-215:...) ..." part). Errors
    raised inside OpenCV's Python bindings can surface as a SystemError whose cause is the
    cv2.error."""
    cause = e.__cause__ if isinstance(e, SystemError) and e.__cause__ is not None else e
    text = str(cause).strip()
    return text.splitlines()[-1].strip() if text else type(cause).__name__


# ------------------------------------------------------------------------------------------
# The plane's pose from its homography


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
        else _matrix(intrinsics_matrix)
    )
    try:
        h = np.array(H, dtype=np.float64)
    except (TypeError, ValueError):
        raise IntrinsicsError("H must be a 3 x 3 array of numbers") from None
    if h.shape != (3, 3) or not np.isfinite(h).all():
        raise IntrinsicsError(f"H must be a finite 3 x 3 matrix, got {h.tolist()}")
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
