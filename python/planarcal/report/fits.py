"""The calibration as the report compares it: the fit before the lens model (a homography
alone on the same points) and which of the lens model's parameters were fitted."""

from __future__ import annotations

import numpy as np

from planarcal.calib.calibration import Calibration, LensModel


def homography_alone(cal: Calibration) -> Calibration:
    """The "before" fit: a homography alone on the same points (no lens, no intrinsics), in
    the same millimetres (a calibration corrected for the printer's scale is fitted on the
    board's own points, then corrected as it was)."""
    sx, sy = (float(v) for v in cal.world_scale)
    scaled = (sx, sy) != (1.0, 1.0) and cal.board is not None
    alone = Calibration(
        cal.world_points / np.array([sx, sy]) if scaled else cal.world_points,
        cal.image_points,
        solver=cal.solver,
        refine=cal.refine,
        lens="none",
        board=cal.board,
        image_size=cal.image_size,
    )
    if scaled and cal.board is not None:
        return alone.rescaled(cal.board.pitch * sx, cal.board.pitch * sy)
    return alone


def fitted_parameters(lens: LensModel) -> list[str]:
    """Which of the lens's parameters were fitted (the others are fixed: k2 = 0, the centre
    at the image's)."""
    return {"k1": ["k1"], "k1k2": ["k1", "k2"]}.get(lens.model, ["k1", "k2", "centre"])
