"""Numbers for JSON: NaN and the infinities, which JSON cannot hold, become null; and what a
parsed JSON value must be to be a whole number or a finite real (never a bool)."""

from __future__ import annotations

import math
from typing import Any, TypeGuard

import numpy as np


def json_number(v: Any) -> Any:
    """`v`, or None where it is a float JSON cannot hold (NaN, +-inf)."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def json_ready(value: Any) -> Any:
    """`value` with every float JSON cannot hold (nested in dicts, lists and tuples) as None,
    tuples as lists and numpy numbers as Python ones."""
    if isinstance(value, dict):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    return json_number(value)


def is_json_int(value: Any) -> TypeGuard[int]:
    """A JSON whole number (never a bool, which Python counts as an int)."""
    return isinstance(value, int) and not isinstance(value, bool)


def is_json_real(value: Any) -> TypeGuard[int | float]:
    """A JSON number (int or float, never a bool) that is a finite float."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False
