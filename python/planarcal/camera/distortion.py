"""OpenCV's lens-distortion model in NumPy: the forward map, its Jacobian, its inversion and
where it can be inverted.

The model acts on normalised coordinates (x, y) = K^-1 (u, v, 1) exactly as OpenCV's does:
radial k1..k6 (rational), tangential p1, p2, thin prism s1..s4 and the tilted sensor tauX,
tauY. Everything here is vectorised over points and knows nothing of pixels or K (that is
:class:`planarcal.camera.intrinsics.CameraIntrinsics`).

OpenCV inverts the model by a fixed-point iteration that stops after 5 steps (0.8 px off at
the corners of the webcam in OpenCV's calibration tutorial); here its answer is only a start
for Newton's method on the forward model (:func:`newton`), which polishes each point until it
reproduces its target to machine precision, and :func:`unfolded` then checks that the point
lies inside the part of the model that can be inverted (before any fold-over).
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

DIST_COEFF_LENGTHS = (4, 5, 8, 12, 14)
"""The lengths OpenCV accepts for a distortion vector: (k1, k2, p1, p2[, k3[, k4, k5, k6[,
s1, s2, s3, s4[, tauX, tauY]]]])."""

# Each coefficient's name, in the order of OpenCV's distortion vector.
COEFF_NAMES: tuple[str, ...] = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
COEFF_NAMES += ("s1", "s2", "s3", "s4", "tauX", "tauY")

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
# The polar grid on which each model's fold-free disc is found once (see fold_free_radius).
_SAFE_ANGLES = 360
_SAFE_STEPS = 4000
_SAFE_MAX = 4.0


@dataclasses.dataclass(frozen=True)
class Lens:
    """The distortion vector unpacked (missing terms are 0) and the tilted sensor's
    projection matrices (None when tauX = tauY = 0)."""

    k: tuple[float, float, float, float, float, float]
    p: tuple[float, float]
    s: tuple[float, float, float, float]
    tilt: F64 | None
    untilt: F64 | None

    @classmethod
    def of(cls, d: F64) -> Lens:
        c = np.zeros(14)
        c[: d.size] = d
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4, tx, ty = (float(v) for v in c)
        tilt: F64 | None = None
        untilt: F64 | None = None
        if tx or ty:
            tilt = tilt_matrix(tx, ty)
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


def tilt_matrix(tau_x: float, tau_y: float) -> F64:
    """OpenCV's computeTiltProjectionMatrix (the tilted sensor of the 14-term model)."""
    cx, sx = math.cos(tau_x), math.sin(tau_x)
    cy, sy = math.cos(tau_y), math.sin(tau_y)
    rot_x = np.array([[1.0, 0.0, 0.0], [0.0, cx, sx], [0.0, -sx, cx]])
    rot_y = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]])
    rot = rot_y @ rot_x
    proj_z = np.array([[rot[2, 2], 0.0, -rot[0, 2]], [0.0, rot[2, 2], -rot[1, 2]], [0.0, 0.0, 1.0]])
    return np.asarray(proj_z @ rot, dtype=np.float64)


def apply_projective(m: F64, x: F64, y: F64) -> tuple[F64, F64, F64]:
    """(x, y) through the 3 x 3 projective map m, and the homogeneous w (sign matters)."""
    w = m[2, 0] * x + m[2, 1] * y + m[2, 2]
    safe = np.where(w != 0.0, w, 1.0)
    return (
        (m[0, 0] * x + m[0, 1] * y + m[0, 2]) / safe,
        (m[1, 0] * x + m[1, 1] * y + m[1, 2]) / safe,
        w,
    )


def fold_free_radius(lens: Lens) -> float:
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


def unfolded(lens: Lens, x: F64, y: F64, safe_radius: float) -> BoolArray:
    """Whether each undistorted normalised point lies in the model's valid region: along the
    segment from the optical axis to it the forward map keeps its orientation (Jacobian
    determinant > 0) and its rational denominator stays positive. Past a fold the same
    distorted position has a second preimage, so no point there can be told apart from its
    mirror inside; a model fitted by calibrateCamera is only meaningful inside the fold.
    Points within ``safe_radius`` (see fold_free_radius) pass at once; the others are
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
        _, _, w = apply_projective(lens.tilt, xd, yd)
        ok &= w > 0.0
    return ok


def opencv_guess(lens_coeffs: F64, xt: F64, yt: F64) -> tuple[F64, F64]:
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


def newton(lens: Lens, xt: F64, yt: F64, x0: F64, y0: F64) -> tuple[F64, F64, BoolArray]:
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


def continuation(lens: Lens, xt: F64, yt: F64) -> tuple[F64, F64, BoolArray]:
    """Undistort by following the solution from the optical axis outwards (solving for
    t * target, t = 0.05 .. 1): finds the preimage in the model's central, valid sheet even
    where Newton's method from a poor start reached another one."""
    x, y = 0.05 * xt, 0.05 * yt
    ok = np.ones(xt.shape, dtype=bool)
    for t in np.linspace(0.05, 1.0, 20):
        x, y, conv = newton(lens, t * xt, t * yt, x, y)
        ok &= conv
    return x, y, ok
