"""Numbers for JSON: NaN and the infinities, which JSON cannot hold, become null."""

from __future__ import annotations

import math
from typing import Any


def json_number(v: Any) -> Any:
    """`v`, or None where it is a float JSON cannot hold (NaN, +-inf)."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v
