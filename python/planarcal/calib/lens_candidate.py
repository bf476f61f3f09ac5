"""One lens model a calibration's ``lens="auto"`` tried, and what its leave-one-out error
said: what the fit (plane_fit) records and the choice (lens_choice) makes, in a module of its
own so that neither imports the other for it."""

from __future__ import annotations

import dataclasses
from typing import Any

from planarcal.calib.json_number import json_number


@dataclasses.dataclass(frozen=True)
class LensCandidate:
    """One lens model tried by ``lens="auto"`` and what its leave-one-out error said."""

    model: str
    loo_mean_px: float
    """Mean leave-one-out error in the image, px (NaN if the model could not be fitted)."""
    sigma_px: float
    """Residual standard deviation per coordinate, px."""
    verdict: str
    """"chosen", "not earned" (no clear gain over a simpler model) or why it was refused."""

    def to_dict(self) -> dict[str, Any]:
        return {k: json_number(v) for k, v in dataclasses.asdict(self).items()}
