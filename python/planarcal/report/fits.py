"""The calibration as the report compares it: the fit before the lens model (a homography
alone on the same points) and which of the lens model's parameters were fitted."""

from __future__ import annotations

from planarcal.calib.calibration import Calibration, LensModel


def homography_alone(cal: Calibration) -> Calibration:
    """The "before" fit: a homography alone on the same points (no lens, no intrinsics), in
    the same millimetres (Calibration.homography_alone)."""
    return cal.homography_alone()


def fitted_parameters(lens: LensModel) -> list[str]:
    """Which of the lens's parameters were fitted (the others are fixed: k2 = 0, the centre
    at the image's)."""
    return {"k1": ["k1"], "k1k2": ["k1", "k2"]}.get(lens.model, ["k1", "k2", "centre"])
