"""What a calibration's error bars must cover beyond the fit's covariance, and how big each
term is: the error budget behind ``std_mm``.

The fit's covariance (sigma^2 (J^T J)^-1, carried to the plane) says how far the estimated
model is from the best model of its kind, if the residuals were independent noise. On
rendered scenes (benches/bench_accuracy.py) the mapping is 2-5x further from the truth than
that says, and parts 10-70x, for three reasons the covariance cannot see:

* **The dots' lens bias** (``dot_bias_px``). A dot's measured centre is the centroid of its
  image; the detector moves it back to the image of the dot's centre for perspective (the
  conic's offset) but not for the lens: the lens bends the dot's image unevenly (it
  magnifies one side more than the other), which moves its centroid by 0.002-0.01 px, away
  from the distortion centre in proportion to the distance from it. That field is smooth, so
  the fit absorbs it (into H's scale and the lens's coefficients) and the residuals stay
  white: the calibration then maps every pixel with that field's error. It is computed here
  from the fitted model and the board's dots: each dot's disc carried through H and the lens
  (a fixed quadrature), its centroid in the image against the lens's image of its ideal
  centroid. A chessboard's or ChArUco board's corners are points, which the lens moves
  with their image: they have none, as long as the detector's model of a corner follows the
  lens's bend of its edges (corner_refine, and ChArUco's centre of symmetry: measured on
  renders within 0.0004 and 0.001 px per 400 px of radius, tests/calib/test_corner_bias.py).
  Not counted: a vignette's fall-off of the light leans a chessboard's corners towards the
  brighter centre (0.002 px per 400 px under 25 % at the image's corners) and ChArUco's
  away from it (0.0013); the fitted model does not know the light.
* **The lens model's bias** (``lens_bias_px``). Where the lens model cannot follow the real
  lens (a centre assumed where it is not, tangential terms), the residuals are a smooth
  field that neighbouring dots share, and a pixel between them has it too; the detector's
  own noise is not shared. The shared part is the residuals' covariance between neighbouring
  dots (one pitch apart), per coordinate, taken as zero where it is negative.
* **The part detector's centroid error** (``OUTLINE_CENTROID_SIGMA_PX``): a located part's
  centroid comes from its sub-pixel outline, which blur, noise and the edges' sampling move;
  measured against the truth on rendered parts (nuts, washers, discs, bolts), once carried
  to the plane to second order, it is about 0.025 px per coordinate. It is a property of
  the pixel, not of the calibration: it enters as ``pixel_sigma``, the pixel's own noise.

The first two are the model's bias, ``model_sigma_px`` = hypot(dot, lens): the core's
``FittedPlane.with_model_sigma`` adds it to every pixel's noise in quadrature (mapped to the
plane through the local Jacobian, as a pixel's noise is), so ``image_to_world_std`` and every
path through it (the production loop's) include it. It is recomputed from the stored points
whenever a calibration is built or loaded: files do not change.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planarcal.calib.boards import Board
from planarcal.calib.plane_fit import PlaneFit
from planarcal.camera import CameraIntrinsics
from planarcal.errors import BoardError
from planarcal.homography import transform_points

F64 = NDArray[np.float64]

OUTLINE_CENTROID_SIGMA_PX = 0.025
"""The part detector's centroid error, px per coordinate (1-sigma): the RMS error of the
sub-pixel outline's centroid, carried to the plane to second order (planarcal.live.local_map),
against the truth on rendered parts with blur (0.8 px), noise (2.5 grey levels) and uneven
lighting: 0.013-0.021 px for discs, nuts and washers, 0.028-0.037 px for bolts, 0.021-0.025
px over a mix (webcam, paper and demo scenes of bench_accuracy.py's error-bar section)."""

# Neighbouring dots: those within this factor of the nearest spacing.
_NEIGHBOUR_SLACK = 1.05


@dataclasses.dataclass(frozen=True)
class ErrorBudget:
    """The terms of a calibration's error bars beyond the fit's covariance, px per coordinate
    (1-sigma)."""

    dot_bias_px: float
    """The dots' lens bias the fit absorbed (the RMS over the dots of their centroid shift)."""
    lens_bias_px: float
    """The lens model's bias: the residual field neighbouring dots share."""
    detector_px: float = OUTLINE_CENTROID_SIGMA_PX
    """A located part's centroid error (the pixel's own noise, not the calibration's)."""

    @property
    def model_sigma_px(self) -> float:
        """The model's bias, px per coordinate: what every mapped pixel carries."""
        return math.hypot(self.dot_bias_px, self.lens_bias_px)

    def describe(self) -> str:
        """The budget in a sentence."""
        return (
            f"model bias {self.model_sigma_px:.4f} px per coordinate (the dots' lens bias "
            f"{self.dot_bias_px:.4f} px, the lens model's {self.lens_bias_px:.4f} px), part "
            f"centroids {self.detector_px:.3f} px"
        )

    def to_dict(self) -> dict[str, Any]:
        return {**dataclasses.asdict(self), "model_sigma_px": self.model_sigma_px}


def _disc_quadrature(rings: int = 6, spokes: int = 16) -> F64:
    """Points of equal area over the unit disc (midpoints in r^2 and in angle), (K, 2): the
    centroid of any smooth weighting over the disc to well under 1e-3 of its shift here."""
    r = np.sqrt((np.arange(rings) + 0.5) / rings)
    t = (np.arange(spokes) + 0.5) * (2.0 * math.pi / spokes)
    rr, tt = np.meshgrid(r, t)
    return np.column_stack([(rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel()])


def _area_scale(f: Callable[[F64], F64], p: F64, step: float) -> F64:
    """|det J| of the map f at points p (N, 2), by central differences of `step`."""
    ex, ey = np.array([step, 0.0]), np.array([0.0, step])
    dx = f(p + ex) - f(p - ex)
    dy = f(p + ey) - f(p - ey)
    return np.asarray(np.abs(dx[:, 0] * dy[:, 1] - dx[:, 1] * dy[:, 0]) / (4.0 * step * step))


def dot_centroid_shift_px(
    h: F64, distort: Callable[[F64], F64], world: F64, diameters_mm: F64
) -> F64:
    """How far the lens moves each dot's measured centre from the image of its centre, px,
    (N, 2): the centroid of the dot's image (its disc through H to ideal pixels, then through
    ``distort`` to real ones, weighted by area) minus the lens's image of its ideal
    centroid. The detector corrects the ideal part (perspective) and not this one."""
    q = _disc_quadrature()
    n, k = len(world), len(q)
    pts = (world[:, None, :] + 0.5 * diameters_mm[:, None, None] * q[None]).reshape(-1, 2)

    def to_ideal(p: F64) -> F64:
        return transform_points(h, p)

    ideal = to_ideal(pts)
    real = distort(ideal)
    # Area elements: the board's disc is sampled evenly, so each sample's image area is its
    # Jacobian's determinant (through H, then through the lens).
    w_ideal = _area_scale(to_ideal, pts, 1e-3 * float(np.median(diameters_mm)))
    w_real = w_ideal * _area_scale(distort, ideal, 1e-2)
    ideal, real = ideal.reshape(n, k, 2), real.reshape(n, k, 2)
    w_ideal, w_real = w_ideal.reshape(n, k, 1), w_real.reshape(n, k, 1)
    centroid_ideal = (ideal * w_ideal).sum(axis=1) / w_ideal.sum(axis=1)
    centroid_real = (real * w_real).sum(axis=1) / w_real.sum(axis=1)
    return np.asarray(centroid_real - distort(centroid_ideal), dtype=np.float64)


def shared_residual_sigma_px(world: F64, residuals_px: F64) -> float:
    """The part of the residuals that neighbouring points share, px per coordinate: the
    square root of the mean product of neighbours' residuals (per coordinate), 0 where that
    is negative (independent noise, or fewer than two neighbour pairs)."""
    if len(world) < 3:
        return 0.0
    tree = cKDTree(world)
    nearest = _median_spacing(tree, world)
    if not nearest > 0.0:
        return 0.0
    pairs = tree.query_pairs(_NEIGHBOUR_SLACK * nearest, output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    ok = np.isfinite(residuals_px[i]).all(axis=1) & np.isfinite(residuals_px[j]).all(axis=1)
    i, j = i[ok], j[ok]
    if len(i) < 2:
        return 0.0
    shared = float(np.mean(np.sum(residuals_px[i] * residuals_px[j], axis=1))) / 2.0
    return math.sqrt(shared) if shared > 0.0 else 0.0


def _dot_diameters(board: Board | None, ids: NDArray[np.intp] | None, world: F64) -> F64:
    """Each point's dot diameter, mm: a circle grid's dots (its origin marker's included, for
    the ids seen), 0 for a board whose points are corners (a corner is a point: the lens
    moves it with its image, no area's centroid to bias), or half the points' spacing when
    the board or its dot size is unknown (a typical circle grid)."""
    if board is not None and ids is not None and len(ids) == len(world):
        dot_diameters = getattr(board, "dot_diameters", None)
        if dot_diameters is None:
            return np.zeros(len(world))
        try:
            return np.asarray(dot_diameters(), dtype=np.float64)[ids]
        except BoardError:
            pass  # the dot size is unknown: estimate it below
    if len(world) < 2:
        return np.zeros(len(world))
    return np.full(len(world), 0.5 * _median_spacing(cKDTree(world), world))


def _median_spacing(tree: Any, world: F64) -> float:
    """The median distance from each point to its nearest other point, mm."""
    d, _ = tree.query(world, k=2)
    return float(np.median(d[:, 1]))


def error_budget(
    fit: PlaneFit,
    world: F64,
    image: F64,
    board: Board | None,
    intrinsics: CameraIntrinsics | None,
    ids: NDArray[np.intp] | None = None,
) -> ErrorBudget:
    """The budget of a calibration fitted as ``fit`` to ``world`` (mm) and ``image`` (the
    measured pixels) on ``board``, whose points ``ids`` they are (None: bare points, whose
    dots' size is guessed from their spacing), with ``intrinsics`` when the lens is the
    camera's."""
    plane = fit.plane
    if intrinsics is not None:
        distort: Callable[[F64], F64] = intrinsics.distort_points
        measured = intrinsics.undistort_points(image)
        # Residuals in the ideal image, where the plane was fitted.
        residuals = measured - transform_points(fit.h, world)
    elif fit.lens == "none":
        distort = _identity
        residuals = image - transform_points(fit.h, world)
    else:
        lens = plane.lens
        distort = lens.distort
        residuals = image - plane.world_to_image(world)
    diameters = _dot_diameters(board, ids, world)
    shift = np.zeros((len(world), 2))
    dots = diameters > 0
    if dots.any():
        shift[dots] = dot_centroid_shift_px(fit.h, distort, world[dots], diameters[dots])
    finite = np.isfinite(shift).all(axis=1)
    dot = float(np.sqrt(np.mean(np.sum(shift[finite] ** 2, axis=1)) / 2.0)) if finite.any() else 0.0
    return ErrorBudget(dot, shared_residual_sigma_px(world, residuals))


def _identity(p: F64) -> F64:
    return p


def with_budget(
    fit: PlaneFit,
    world: F64,
    image: F64,
    board: Board | None,
    intrinsics: CameraIntrinsics | None,
    ids: NDArray[np.intp] | None = None,
) -> tuple[PlaneFit, ErrorBudget]:
    """``fit`` with its plane carrying the budget's model bias (every uncertainty it gives
    includes it), and the budget."""
    budget = error_budget(fit, world, image, board, intrinsics, ids)
    plane = fit.plane.with_model_sigma(budget.model_sigma_px)
    return dataclasses.replace(fit, plane=plane), budget
