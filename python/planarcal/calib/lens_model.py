"""The lens as a calibration sees it: which radial-distortion models there are, and the one a
calibration fitted (its centre, unit, k1, k2 and their standard errors)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

F64 = NDArray[np.float64]

LENS_MODELS = ("none", "k1", "k1k2", "k1k2c")
"""The lens models, simplest first: none (a homography alone), k1, k1 + k2, and k1 + k2 with
the distortion centre fitted too."""


@dataclasses.dataclass(frozen=True)
class LensModel:
    """The radial distortion a calibration found: an ideal pixel u is shown at
    d = c + (u - c) (1 + k1 rho^2 + k2 rho^4), rho = |u - c| / scale (OpenCV's two-term
    model with the half-diagonal as the unit instead of the focal length)."""

    model: str
    """Which parameters were fitted: "k1", "k1k2" or "k1k2c" (centre too)."""
    centre_px: tuple[float, float]
    scale_px: float
    k1: float
    k2: float
    k1_std: float
    k2_std: float
    centre_std_px: tuple[float, float]

    def displacement_px(self, ideal_px: ArrayLike) -> F64:
        """How far the lens moves each ideal pixel (N, 2), px: real minus ideal."""
        u = np.asarray(ideal_px, dtype=np.float64).reshape(-1, 2)
        q = (u - np.array(self.centre_px)) / self.scale_px
        rho2 = np.sum(q * q, axis=1, keepdims=True)
        out: F64 = q * self.scale_px * rho2 * (self.k1 + self.k2 * rho2)
        return out

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)
