"""The lens as a calibration sees it: which radial-distortion models there are (LensKind), and
the one a calibration fitted (its centre, unit, k1, k2 and their standard errors). The lens
itself, its distortion and inverse, is the core's RadialLens."""

from __future__ import annotations

import dataclasses
import enum
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal._core import RadialLens

F64 = NDArray[np.float64]


class LensKind(str, enum.Enum):
    """A lens model by name: which of the radial lens's parameters are fitted. It is a str,
    so the core takes it by its name, the name files store."""

    NONE = "none"
    K1 = "k1"
    K1K2 = "k1k2"
    K1K2C = "k1k2c"


# Plain strings (not the members), so that messages and files show "k1", not LensKind.K1.
LENS_MODELS = tuple(kind.value for kind in LensKind)
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
        return self.radial.distort(u) - u

    @property
    def radial(self) -> RadialLens:
        """The lens itself (the core's): distort, undistort, fold and valid radius."""
        return RadialLens(self.centre_px, self.scale_px, self.k1, self.k2)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)
