"""Checks of a user's arguments, shared by the Python layer: each returns the value as the
code needs it or raises the caller's exception type (``ArgumentError`` unless told), naming
the argument and, for points, the first point at fault."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal.errors import ArgumentError

F64 = NDArray[np.float64]


def real(name: str, value: object, exc: type[ValueError] = ArgumentError) -> float:
    """value as a finite float (a Python or NumPy number, not a bool)."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise exc(f"{name} must be a number, got {value!r}")
    try:
        v = float(value)
    except OverflowError:  # an integer beyond double precision (10**400)
        v = math.inf
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


def real_array(
    name: str,
    value: ArrayLike,
    exc: type[ValueError] = ArgumentError,
    what: str = "an array of real numbers",
) -> F64:
    """value as a float64 array of any shape whose elements are real numbers: a string,
    bytes, a bool or a complex number (which ``np.asarray(..., float64)`` would take "12.5" as
    12.5, True as 1, or drop the imaginary part of) is refused, naming it, and so is what
    cannot be converted (``what`` says what was expected). Finiteness is the caller's to check
    (it knows which point to name)."""
    try:
        natural = value if isinstance(value, np.ndarray) else np.asarray(value)
        bad = _first_not_real(value, natural)
    except (TypeError, ValueError, OverflowError):  # a ragged nesting
        raise exc(f"{name} must be {what}") from None
    if bad is not None:
        raise exc(f"{name} must hold real numbers, got {bad!r} (a {type(bad).__name__})")
    try:
        # Numbers already read as numbers are not read again from the Python objects.
        source = natural if natural.dtype.kind in "fiu" else value
        out: F64 = np.asarray(source, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise exc(f"{name} must be {what}") from None
    return out


# Elements (and array dtype kinds) that are not real numbers, though NumPy converts them.
_NOT_REAL = (str, bytes, bool, np.bool_, complex, np.complexfloating)
_NOT_REAL_KINDS = "USbcVmM"


def _first_not_real(value: ArrayLike, natural: NDArray[Any]) -> object | None:
    """The first element of value (``natural``: as NumPy reads it) that is not a real
    number, or None."""
    if natural.dtype.kind in "fiu":
        if natural is value or not _holds_bools(value, natural.ndim):
            return None
    elif natural.dtype.kind != "O" and natural is value:
        return natural.flat[0] if natural.dtype.kind in _NOT_REAL_KINDS and value.size else None
    # The slow way, element by element as objects: a float dtype would have turned a list's
    # True into 1.0, and a str dtype every number into a string.
    elements = value if isinstance(value, np.ndarray) else np.asarray(value, dtype=object)
    return next((x for x in elements.flat if isinstance(x, _NOT_REAL)), None)


def _holds_bools(value: ArrayLike, ndim: int) -> bool:
    """Whether the nested sequence value (ndim deep) has a bool among its leaves, which
    NumPy converts to 1.0 among floats: one pass over the leaves' types."""
    if ndim == 0:
        return isinstance(value, bool | np.bool_)
    leaves: Iterable[object] = cast("Iterable[object]", value)
    for _ in range(ndim - 1):
        leaves = itertools.chain.from_iterable(cast("Iterable[Iterable[object]]", leaves))
    return any(issubclass(t, bool | np.bool_) for t in set(map(type, leaves)))


def points(
    name: str, value: ArrayLike, exc: type[ValueError] = ArgumentError
) -> tuple[F64, tuple[int, ...]]:
    """value as finite (N, 2) float64 points (real numbers: see ``real_array``), plus the
    leading shape of the (..., 2) array given, to give results back in."""
    a = real_array(name, value, exc, "an array of (x, y) points")
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
