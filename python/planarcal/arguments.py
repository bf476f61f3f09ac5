"""Checks of a user's arguments, shared by the Python layer: each returns the value as the
code needs it or raises the caller's exception type (``ArgumentError`` unless told), naming
the argument and, for points, the first point at fault."""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal.errors import ArgumentError

F64 = NDArray[np.float64]


def real(name: str, value: object, exc: type[ValueError] = ArgumentError) -> float:
    """value as a finite float (a Python or NumPy number, not a bool)."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise exc(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise exc(f"{name} must be finite, got {value!r}")
    return v


def positive(name: str, value: object, exc: type[ValueError] = ArgumentError) -> float:
    """value as a finite float > 0."""
    v = real(name, value, exc)
    if v <= 0:
        raise exc(f"{name} must be positive, got {value!r}")
    return v


def pair(name: str, value: object, exc: type[ValueError] = ArgumentError) -> tuple[float, float]:
    """value as a pair of finite floats (x, y)."""
    try:
        items = list(cast("Iterable[object]", value))
    except TypeError:
        items = []
    if len(items) != 2:
        raise exc(f"{name} must be a pair (x, y), got {value!r}")
    return (real(f"{name}[0]", items[0], exc), real(f"{name}[1]", items[1], exc))


def points(
    name: str, value: ArrayLike, exc: type[ValueError] = ArgumentError
) -> tuple[F64, tuple[int, ...]]:
    """value as finite (N, 2) float64 points, plus the leading shape of the (..., 2) array
    given, to give results back in."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise exc(f"{name} must be an array of (x, y) points") from None
    if a.ndim == 0 or a.shape[-1] != 2:
        raise exc(f"{name} must have shape (..., 2), got {a.shape}")
    flat = a.reshape(-1, 2)
    bad = np.flatnonzero(~np.isfinite(flat).all(axis=1))
    if bad.size:
        k = int(bad[0])
        message = f"{name}: point {k} is not finite: {flat[k].tolist()}"
        if issubclass(exc, ArgumentError):
            raise exc(message, k)
        raise exc(message)
    return flat, a.shape[:-1]
