"""What a calibration fitted: the core's model of the plane (``_core.FittedPlane``: H, the lens,
their covariance) with the lens model's name and how it was chosen, and the ways to build the
core's model, by fitting a homography alone or at parameters already known."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal import _core
from planarcal._core import RadialLens
from planarcal.calib.lens_candidate import LensCandidate
from planarcal.calib.lens_model import LENS_MODELS, LensKind, LensModel
from planarcal.calib.placements import PlacementLayout, placements_at
from planarcal.camera import CameraIntrinsics
from planarcal.errors import IntrinsicsError, LensModelError
from planarcal.homography import Solver, estimate_homography

F64 = NDArray[np.float64]


@dataclasses.dataclass
class PlaneFit:
    """What a calibration fitted: the core's model (on ideal pixels with intrinsics), its H,
    which lens model, and how it was chosen."""

    plane: _core.FittedPlane
    h: F64
    lens: str
    candidates: list[LensCandidate]
    note: str
    loo_cache: tuple[F64, F64] | None = None
    placements: PlacementLayout | None = None
    """The placements fitted with the plane, with their poses (None: one board view)."""

    def lens_model(self) -> LensModel | None:
        if self.lens not in LENS_MODELS[1:]:
            return None
        lens, std = self.plane.lens, self.plane.lens_std
        return LensModel(
            self.lens,
            lens.centre_px,
            lens.scale_px,
            lens.k1,
            lens.k2,
            std.k1,
            std.k2,
            std.centre_px,
        )

    def loo(self) -> tuple[F64, F64]:
        if self.loo_cache is None:
            self.loo_cache = self.plane.leave_one_out()
        return self.loo_cache


def _frame_size(image: F64, size: tuple[int, int] | None) -> tuple[float, float]:
    """The image size that centres the lens frame; without one (a plain homography, where it
    only sets the parameters' units), a box around the points."""
    if size is not None:
        return float(size[0]), float(size[1])
    reach = np.abs(image).max(axis=0) if len(image) else np.ones(2)
    return float(2.0 * reach[0] + 2.0), float(2.0 * reach[1] + 2.0)


def fit_homography_alone(
    world: F64, image: F64, solver: Solver, refine: bool, size: Any
) -> tuple[Any, F64]:
    """The homography by the chosen solver, and the core's model at it (for the covariance)."""
    h = estimate_homography(world, image, solver, refine)
    return homography_alone_at(h, world, image, size), h


def homography_alone_at(h: F64, world: F64, image: F64, size: Any) -> Any:
    """The core's model of a homography alone, at H (its covariance on these points)."""
    w, hgt = _frame_size(image, size)
    return _core.FittedPlane.at(h, _ideal_lens(w, hgt), world, image, LensKind.NONE, (w, hgt))


def _ideal_lens(w: float, hgt: float) -> RadialLens:
    """No distortion, centred on a w x hgt image (its unit the half-diagonal)."""
    return RadialLens(((w - 1.0) / 2.0, (hgt - 1.0) / 2.0), 0.5 * math.hypot(w, hgt))


def plane_at(
    h: F64,
    world: F64,
    image: F64,
    size: tuple[int, int] | None,
    lens: str,
    radial: RadialLens | None,
    intrinsics: CameraIntrinsics | None,
    layout: PlacementLayout | None = None,
) -> tuple[Any, PlacementLayout | None]:
    """The core's model of a calibration at known parameters (its covariance on these
    points): H, the lens model `lens` with its radial lens, or the intrinsics; with the
    placements' `layout`, the placements fit's at its poses (and the layout it gives)."""
    if layout is not None:
        if size is None:
            raise LensModelError("a calibration from placements records its image size")
        ideal = image if intrinsics is None else intrinsics.undistort_points(image)
        free = lens if lens in LENS_MODELS else "none"
        if radial is None or free == "none":
            radial = _ideal_lens(float(size[0]), float(size[1]))
        return placements_at(h, radial, layout, ideal, free, size)
    return _plane_at(h, world, image, size, lens, radial, intrinsics), None


def _plane_at(
    h: F64,
    world: F64,
    image: F64,
    size: tuple[int, int] | None,
    lens: str,
    radial: RadialLens | None,
    intrinsics: CameraIntrinsics | None,
) -> Any:
    if lens == "intrinsics":
        if intrinsics is None:
            raise IntrinsicsError("lens model 'intrinsics' without the intrinsics")
        return homography_alone_at(h, world, intrinsics.undistort_points(image), size)
    if lens == "none":
        return homography_alone_at(h, world, image, size)
    if size is None or radial is None:
        raise LensModelError(f"lens model {lens!r} without the image size it is centred on")
    frame = (float(size[0]), float(size[1]))
    return _core.FittedPlane.at(h, radial, world, image, LensKind(lens), frame)
