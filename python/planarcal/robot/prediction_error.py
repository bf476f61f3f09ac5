"""How well a registration predicts a point it was not fitted to: the 1-sigma error (mm, RMS
distance) of the fitted board-to-robot transform at any board point, from the fit's
parameter covariance.

The transform is linearised about the touched points' centroid c, q = L (p - c) + t, in the
model's own parameters (rigid: the angle and t; similarity: L = [[a, -b], [b, a]] x mirror
and t; affine: L's four entries and t), so the covariance is well conditioned wherever the
board sits. The touch noise sigma (per coordinate) is estimated from the residuals,
sigma^2 = RSS / (2N - dof), and never taken below the floor: a robot's repeatability plus the
board points' own error (N-point pairs, mapped from pixels), so three touches that happen to
agree exactly do not claim an exact transform."""

from __future__ import annotations

import math

import numpy as np

from planarcal.robot.transform_fit import F64, Model, apply

# The touch noise (mm per coordinate) no registration is taken to be better than: a good
# industrial robot's repeatability.
TOUCH_NOISE_FLOOR_MM = 0.02

# Degrees of freedom of each model's parameters.
DOF: dict[Model, int] = {"rigid": 3, "similarity": 4, "affine": 6}


def noise_sigma_mm(residuals_xy: F64, model: Model, plane_std_mm: F64 | None = None) -> float:
    """The touch noise per coordinate (mm) the residuals (N, 2) of the points used show,
    floored at TOUCH_NOISE_FLOOR_MM and the board points' own error (their RMS-distance
    1-sigma ``plane_std_mm``, N, over sqrt 2 per coordinate) added in quadrature."""
    redundancy = 2 * len(residuals_xy) - DOF[model]
    from_residuals = float(np.sum(residuals_xy**2)) / redundancy if redundancy > 0 else 0.0
    floor = TOUCH_NOISE_FLOOR_MM**2
    if plane_std_mm is not None and len(plane_std_mm):
        floor += float(np.mean(plane_std_mm**2)) / 2.0
    return math.sqrt(max(from_residuals, floor))


def jacobian(matrix: F64, centre: F64, points: F64, model: Model, reflected: bool) -> F64:
    """d(robot point)/d(parameters) at each board point: (N, 2, dof)."""
    n = len(points)
    d = points - centre
    jac = np.zeros((n, 2, DOF[model]))
    jac[:, 0, -2] = 1.0  # the translation is the last two parameters
    jac[:, 1, -1] = 1.0
    if model == "rigid":
        # d/dtheta of R(theta) M d is the 90-degree turn of L d.
        ld = d @ matrix[:2, :2].T
        jac[:, 0, 0] = -ld[:, 1]
        jac[:, 1, 0] = ld[:, 0]
    elif model == "similarity":
        u = d * np.array([1.0, -1.0 if reflected else 1.0])
        jac[:, 0, 0], jac[:, 1, 0] = u[:, 0], u[:, 1]  # d/da
        jac[:, 0, 1], jac[:, 1, 1] = -u[:, 1], u[:, 0]  # d/db
    else:
        jac[:, 0, 0], jac[:, 0, 1] = d[:, 0], d[:, 1]  # row x of L
        jac[:, 1, 2], jac[:, 1, 3] = d[:, 0], d[:, 1]  # row y of L
    return jac


def parameter_covariance(
    matrix: F64,
    plane_used: F64,
    robot_used: F64,
    model: Model,
    reflected: bool,
    plane_std_mm: F64 | None = None,
) -> tuple[F64, F64, float]:
    """(the centroid c the parameters are taken about, their covariance (dof, dof), the touch
    noise sigma per coordinate) of the fit ``matrix`` to the pairs used."""
    centre = plane_used.mean(axis=0)
    jac = jacobian(matrix, centre, plane_used, model, reflected).reshape(-1, DOF[model])
    sigma = noise_sigma_mm(apply(matrix, plane_used) - robot_used, model, plane_std_mm)
    # pinv: a degenerate layout is refused before a fit, so this is a safeguard, not a path.
    cov = sigma**2 * np.linalg.pinv(jac.T @ jac)
    return centre, cov, sigma


def prediction_std_mm(
    matrix: F64, centre: F64, covariance: F64, points: F64, model: Model, reflected: bool
) -> F64:
    """The transform's own 1-sigma error (RMS distance, mm) at each board point (N, 2)."""
    jac = jacobian(matrix, centre, points, model, reflected)
    cov = jac @ covariance @ jac.transpose(0, 2, 1)
    return np.asarray(np.sqrt(np.maximum(np.trace(cov, axis1=1, axis2=2), 0.0)), dtype=np.float64)
