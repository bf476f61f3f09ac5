"""Hostile inputs for every public entry point, and the judge of what each call did.

Shared by the fuzzing campaign (benches/bench_fuzz.py, millions of inputs in watched worker
processes) and its short version in the suite (tests/test_fuzz_short.py). Generation is numpy,
seeded and cheap: case ``i`` of an entry point is rebuilt from ``(seed, i)`` alone
(``case_at``), so a crash or a hang in a worker is reproduced from its index.

Every call ends in one of these outcomes:

* ``result``: it returned, and the result passed the entry point's checks (a finite H scaled as
  documented, finite points unless a NaN fill was asked for, a consistent robust result...);
* ``error``: it raised a ``planarcal.Error`` with a message (the target for bad input);
* ``unclean``: it raised anything else (a raw ``TypeError`` from numpy, a ``ZeroDivisionError``,
  an empty message): a finding, counted by exception type;
* ``panic``: a Rust panic crossed into Python (``pyo3_runtime.PanicException``);
* ``bad_result``: it returned something its documentation rules out;
* ``degenerate_h``: an H for points that determine none (fewer than 4 distinct points,
  collinear, or all but one collinear, judged here by numpy on the input as the call saw it);
* ``corrupt_accepted``: a mutated file that loaded without mapping exactly like the original.
"""

from __future__ import annotations

import atexit
import contextlib
import dataclasses
import inspect
import json
import logging
import math
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
import warnings
import zlib
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

import planarcal as pc
from planarcal import _core

F64 = NDArray[np.float64]

# Cases of one entry point are generated in blocks of this many from one seeded generator:
# case i is rebuilt by replaying its block (a generator per case would cost more than most
# calls).
BLOCK = 64

SPECIALS = np.array(
    [0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, -5e-324, 2.2250738585072014e-308, 1e-300,
     1e300, -1e300, np.finfo(np.float64).max, np.finfo(np.float64).min, 1.0, -1.0]
)  # fmt: skip
COLLINEAR_TOL = 1e-11
"""Relative deviation from a line below which a set counts as collinear here: a margin under
the core's own 1e-10, so that rounding differences between the two tests never flag a set."""

ROBUST_FLAGS = (
    pc.RANSAC,
    pc.LMEDS,
    pc.RHO,
    pc.USAC_DEFAULT,
    pc.USAC_PARALLEL,
    pc.USAC_FM_8PTS,
    pc.USAC_FAST,
    pc.USAC_ACCURATE,
    pc.USAC_PROSAC,
    pc.USAC_MAGSAC,
)
GOOD_THRESHOLDS = (3.0, 1.0, 0.5, 10.0)
GOOD_CONFIDENCES = (0.995, 0.999, 0.5, 1 - 1e-12)
THRESHOLDS: tuple[Any, ...] = (
    3.0, 3.0, 1.0, 0.5, 10.0, 0.0, -1.0, math.nan, math.inf, -math.inf, 1e-300, 1e300, 5e-324,
    "3", True, False, None, np.float32(3.0), np.int64(3), 2**70, [3.0],
)  # fmt: skip
SMALL_BUDGETS: tuple[Any, ...] = (1, 2, 5, 10, 20, 50, 0, -1, 1.5, np.int32(7), np.uint8(3))
HOSTILE_BUDGETS: tuple[Any, ...] = (
    10**7 + 1, 2**31, 2**63, 2**64, 2**200, -(2**63), "10", None, True, math.nan, math.inf,
    1e7, np.uint64(2**64 - 1), np.int64(-1),
)  # fmt: skip
CONFIDENCES: tuple[Any, ...] = (
    0.995, 0.999, 0.5, 0.0, 1.0, math.nan, 1 - 1e-16, 1 - 1e-12, 1e-300, -0.1, 1.5, math.inf,
    "0.9", None, True, np.float32(0.99),
)  # fmt: skip
SEEDS: tuple[Any, ...] = (
    0, 1, 12345, -1, 2**64 - 1, 2**64, 2**200, 1.5, "0", None, True, np.uint64(7), np.int8(-3),
)  # fmt: skip
BAD_SOLVERS: tuple[Any, ...] = ("", "NORMALIZED_DLT", "junk", None, 3, b"svd", "svd\x00")
BAD_FLAGS: tuple[Any, ...] = (None, 1, 0.0, 1.0, "yes", "", [], np.bool_(True), 2**70)
BAD_METHODS: tuple[Any, ...] = ("MSAC", "", None, 1, "ransac")


def block_rng(entry: str, seed: int, block: int) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(entry.encode()), block])


def pick(rng: np.random.Generator, options: tuple[Any, ...] | list[Any]) -> Any:
    return options[int(rng.integers(len(options)))]


def pick_mostly(
    rng: np.random.Generator, good: tuple[Any, ...], bad: tuple[Any, ...], p_bad: float = 0.1
) -> Any:
    """A valid option value most of the time (so the points reach the numerics), a hostile one
    with probability p_bad."""
    return pick(rng, bad if rng.random() < p_bad else good)


# -- numbers and point sets ----------------------------------------------------------------


def numbers(rng: np.random.Generator, n: int) -> F64:
    """n coordinates from one of several mixtures: ordinary, extreme magnitudes, subnormal,
    small integers, ordinary with specials (0, -0.0, inf, NaN, huge, tiny) sprinkled in."""
    kind = int(rng.integers(12))
    if kind <= 2 or kind >= 9:
        out = rng.uniform(0.0, 2000.0, n)
    elif kind == 3:
        out = rng.choice([-1.0, 1.0], n) * 10.0 ** rng.uniform(-300, 300, n)
    elif kind == 4:
        out = (rng.choice([-1.0, 1.0], n) * rng.integers(1, 1000, n) * 5e-324).astype(np.float64)
    elif kind == 5:
        out = rng.integers(-10, 11, n).astype(np.float64)
    elif kind == 6:
        out = rng.uniform(0.0, 2000.0, n)
        hit = rng.random(n) < 0.2
        out[hit] = rng.choice(SPECIALS, int(hit.sum()))
    elif kind == 7:
        out = rng.uniform(-1.0, 1.0, n) * 10.0 ** float(rng.choice([-300, -150, 150, 300]))
    else:
        out = rng.uniform(0.0, 2000.0, n)
        if n:
            out[int(rng.integers(n))] = rng.choice(SPECIALS)
    return out


def count_points(rng: np.random.Generator) -> int:
    """N: 0-3 (too few), exactly 4 (most often: the minimal case), small, larger, rarely
    huge."""
    u = rng.random()
    if u < 0.12:
        return int(rng.integers(0, 4))
    if u < 0.45:
        return 4
    if u < 0.9:
        return int(rng.integers(5, 13))
    if u < 0.9995:
        return int(rng.integers(13, 300))
    return int(rng.choice([10_000, 100_000]))


def random_homography(rng: np.random.Generator) -> F64:
    h = np.eye(3) + rng.normal(0.0, 0.3, (3, 3))
    h[2, :2] *= 1e-3
    h[:2, 2] = rng.uniform(-500, 500, 2)
    return h


def project(h: F64, points: F64) -> F64:
    with np.errstate(all="ignore"):
        v = np.c_[points, np.ones(len(points))] @ h.T
        return np.asarray(v[:, :2] / v[:, 2:], dtype=np.float64)


# The shapes a source set is built in, with whether the set is degenerate by construction
# (the judge tests the input actually passed, whatever it was built as).
STRUCTURES: tuple[str, ...] = ("random", "random", "image", "image", "collinear")
STRUCTURES += ("all_but_one", "few_distinct", "duplicates", "nearly_collinear")


def structured_pair(rng: np.random.Generator, n: int) -> tuple[F64, F64, str]:
    """(src, dst, structure): random sets, exact images under a random H, or the degenerate
    shapes a homography must refuse."""
    structure = pick(rng, STRUCTURES)
    src = np.stack([numbers(rng, n), numbers(rng, n)], axis=1)
    if structure == "collinear" and n:
        a, d = rng.uniform(0, 2000, 2), rng.normal(0, 1, 2)
        src = a + rng.uniform(-1000, 1000, (n, 1)) * d
    elif structure == "all_but_one" and n:
        a, d = rng.uniform(0, 2000, 2), rng.normal(0, 1, 2)
        src = a + rng.uniform(-1000, 1000, (n, 1)) * d
        src[int(rng.integers(n))] += rng.normal(0, 300, 2)
    elif structure == "few_distinct" and n:
        distinct = rng.uniform(0, 2000, (int(rng.integers(1, 4)), 2))
        src = distinct[rng.integers(len(distinct), size=n)]
    elif structure == "duplicates" and n > 1:
        src[rng.integers(n, size=n // 2)] = src[int(rng.integers(n))]
    elif structure == "nearly_collinear" and n:
        a, d = rng.uniform(0, 2000, 2), rng.normal(0, 1, 2)
        src = a + rng.uniform(-1000, 1000, (n, 1)) * d
        src += rng.normal(0, 1, (n, 2)) * 10.0 ** rng.uniform(-12, -3)
    if structure == "image" or rng.random() < 0.3:
        dst = project(random_homography(rng), src)
    else:
        dst = np.stack([numbers(rng, n), numbers(rng, n)], axis=1)
    if rng.random() < 0.5:  # the degenerate set on the other side
        src, dst = dst, src
    return src, dst, structure


# -- how the arrays are passed ---------------------------------------------------------------

DTYPES = (
    np.float16, np.float32, np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16,
    np.uint32, np.uint64, np.bool_, np.complex128, np.object_, np.str_, np.longdouble,
)  # fmt: skip


def _convert(rng: np.random.Generator, a: F64) -> Any:
    dtype = pick(rng, DTYPES)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        return a.astype(dtype)


def _view(rng: np.random.Generator, a: F64) -> Any:
    kind = int(rng.integers(4))
    if kind == 0:  # every other row of a larger array
        big = np.empty((2 * len(a), *a.shape[1:]), dtype=a.dtype)
        big[::2] = a
        big[1::2] = np.nan
        return big[::2]
    if kind == 1:  # Fortran order
        return np.asfortranarray(a)
    if kind == 2:  # a column slice of a wider array
        wide = np.zeros((*a.shape[:-1], a.shape[-1] + 3), dtype=a.dtype)
        wide[..., 1 : 1 + a.shape[-1]] = a
        return wide[..., 1 : 1 + a.shape[-1]]
    reverse = a[::-1]
    return reverse[::-1]


def _reshape(rng: np.random.Generator, a: F64) -> Any:
    n = a.shape[0]
    return pick(
        rng,
        [
            a.reshape(n, 1, 2) if a.ndim == 2 and a.shape[1] == 2 else a,
            a.reshape(1, n, 2) if a.ndim == 2 and a.shape[1] == 2 else a,
            np.c_[a, np.ones(n)] if a.ndim == 2 else a,  # (N, 3): homogeneous
            a.reshape(-1),
            a.T,
            a[..., :1],
            a.reshape(1, 1, -1),
            np.float64(1.0),
            np.zeros(()),
            np.stack([a, a]),
        ],
    )


def hostile_container(rng: np.random.Generator, a: F64) -> Any:
    """`a` as a caller might pass it: as is (half the time), another dtype, a strided view, a
    read-only array, nested lists or tuples, another shape, or not an array at all."""
    u = rng.random()
    if u < 0.5:
        return a
    if u < 0.65:
        return _convert(rng, a)
    if u < 0.73:
        return _view(rng, a)
    if u < 0.8:
        frozen = a.copy()
        frozen.flags.writeable = False
        return frozen
    if u < 0.86:
        return a.tolist()
    if u < 0.89:
        return tuple(tuple(row) for row in a.tolist()) if a.ndim == 2 else a.tolist()
    if u < 0.97:
        return _reshape(rng, a)
    return pick(
        rng,
        [None, "points", 3.0, [], [[]], [[1.0, 2.0], [3.0]], {"x": 1}, b"\x00" * 16, object()],
    )


def real_points(obj: Any) -> F64 | None:
    """The (N, 2) float64 points `obj` stands for, as a caller's numpy would read them; None
    when it is not plainly that (the call should then refuse it anyway)."""
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            a = np.asarray(obj)
            if a.dtype.kind not in "fiub" and not (
                a.dtype.kind == "O" and all(isinstance(v, float | int) for v in a.flat)
            ):
                return None
            a = a.astype(np.float64)
    except (TypeError, ValueError, OverflowError):
        return None
    if a.ndim == 3 and 1 in a.shape[:2] and a.shape[2] == 2:
        a = a.reshape(-1, 2)
    if a.ndim != 2 or a.shape[1] != 2:
        return None
    return a


def _collinear(points: F64) -> bool:
    """All points within COLLINEAR_TOL (relative to their RMS radius) of one line."""
    if len(points) < 3:
        return True
    scale = np.abs(points).max()
    if not scale > 0:
        return True
    q = points / scale
    q = q - q.mean(axis=0)
    rms = math.sqrt(float((q**2).sum(axis=1).mean()))
    if not rms > 0:
        return True
    normal = np.linalg.svd(q, full_matrices=False)[2][-1]
    return float(np.abs(q @ normal).max()) <= COLLINEAR_TOL * rms


def degenerate_reason(points: F64) -> str | None:
    """Why no homography can map from or to `points`, or None: numpy's own test, independent
    of the core's."""
    if not np.isfinite(points).all():
        return None  # refused as bad input, not a geometry question
    distinct = np.unique(points, axis=0)
    if len(distinct) < 4:
        return f"{len(distinct)} distinct points"
    if _collinear(distinct):
        return "collinear"
    if len(distinct) <= 64:
        for i in range(len(distinct)):
            if _collinear(np.delete(distinct, i, axis=0)):
                return f"collinear but for one point, {distinct[i].tolist()}"
    return None


def degenerate_pair_reason(src: Any, dst: Any) -> str | None:
    for name, points in (("src", real_points(src)), ("dst", real_points(dst))):
        if points is not None:
            reason = degenerate_reason(points)
            if reason:
                return f"{name}: {reason}"
    return None


# -- checks of results -------------------------------------------------------------------------


def h_problem(h: Any, convention: str = "native") -> str | None:
    """What is wrong with a returned homography: not float64 3 x 3, not finite, not scaled as
    documented (|h33| = 1, or unit norm when h33 is negligible; OpenCV's h33 = 1)."""
    if not isinstance(h, np.ndarray) or h.shape != (3, 3) or h.dtype != np.float64:
        return f"H is not a float64 3x3 array: {type(h).__name__} {getattr(h, 'shape', '')}"
    if not np.isfinite(h).all():
        return f"H has non-finite entries: {h.tolist()}"
    unit_norm = abs(float(np.linalg.norm(h)) - 1.0) < 1e-9
    if convention == "opencv" and not (h[2, 2] == 1.0 or unit_norm):
        return f"findHomography's H[2,2] = {h[2, 2]!r}, not 1"
    if not (abs(h[2, 2]) == 1.0 or unit_norm):
        return f"H scaled neither |h33| = 1 nor unit norm: {h.tolist()}"
    return None


def robust_result_problem(r: Any, n: int | None) -> str | None:
    if not isinstance(r, pc.RobustResult):
        return f"not a RobustResult: {type(r).__name__}"
    inliers = np.asarray(r.inliers)
    if inliers.dtype != np.bool_ or (n is not None and inliers.shape != (n,)):
        return f"inliers {inliers.dtype} {inliers.shape} for {n} points"
    if int(inliers.sum()) != r.n_inliers:
        return f"n_inliers {r.n_inliers} but {int(inliers.sum())} in the mask"
    if r.H is None:
        return None if r.stop_reason == "no_consensus" else f"H None, stop {r.stop_reason}"
    if not math.isfinite(r.rms_inlier_error):
        return f"rms_inlier_error {r.rms_inlier_error} with an H"
    return h_problem(r.H)


def mask_problem(mask: Any, n: int | None) -> str | None:
    if not isinstance(mask, np.ndarray) or mask.dtype != np.uint8:
        return f"mask is not uint8: {type(mask).__name__}"
    if n is not None and mask.size != n:
        return f"mask of {mask.size} for {n} points"
    if not np.isin(mask, (0, 1)).all():
        return "mask values other than 0 and 1"
    return None


def finite_points_problem(out: Any, n: int | None, nan_rows: bool = False) -> str | None:
    if not isinstance(out, np.ndarray) or out.dtype.kind != "f":
        return f"not a float array: {type(out).__name__}"
    flat = out.reshape(-1, 2) if out.size % 2 == 0 else out
    if n is not None and len(flat) != n:
        return f"{len(flat)} points out for {n} in"
    if np.isinf(out).any():
        return "infinite output coordinates"
    if nan_rows:
        partial = np.isnan(flat).any(axis=1) & ~np.isnan(flat).all(axis=1)
        return "rows half NaN" if partial.any() else None
    return None if not np.isnan(out).any() else "NaN output coordinates"


# -- cases -------------------------------------------------------------------------------------


@dataclasses.dataclass
class Case:
    """One call: the function, its arguments, and the check of its result (None when it is
    fine, else what is wrong; a message starting "degenerate" is a degenerate input given an
    H)."""

    fn: Callable[..., Any]
    args: tuple[Any, ...]
    kwargs: dict[str, Any]
    check: Callable[[Any], str | None]
    note: str = ""
    also: tuple[type[BaseException], ...] = (Exception,)
    """What a clean error must also be, beside a planarcal.Error (ValueError where every
    fault is the input's, CalibrationFileError for a file)."""

    def describe(self, limit: int = 4000) -> str:
        def short(v: Any) -> str:
            text = repr(v)
            if isinstance(v, np.ndarray):
                flags = "" if v.flags.writeable else ", read-only"
                flags += "" if v.flags.c_contiguous else ", non-contiguous"
                text = f"np.array({v.tolist()!r}, dtype={v.dtype.name}){flags} shape {v.shape}"
            return text if len(text) < limit else text[:limit] + "..."

        parts = [short(a) for a in self.args] + [f"{k}={short(v)}" for k, v in self.kwargs.items()]
        return f"{getattr(self.fn, '__qualname__', self.fn)}({', '.join(parts)})  # {self.note}"


def n_of(points: Any) -> int | None:
    p = real_points(points)
    return None if p is None else len(p)


def h_checker(src: Any, dst: Any, convention: str = "native") -> Callable[[Any], str | None]:
    def check(h: Any) -> str | None:
        return h_problem(h, convention) or _degenerate_message(src, dst)

    return check


def _degenerate_message(src: Any, dst: Any) -> str | None:
    reason = degenerate_pair_reason(src, dst)
    return None if reason is None else f"degenerate input given an H ({reason})"


def pair_args(rng: np.random.Generator) -> tuple[Any, Any, str]:
    src, dst, structure = structured_pair(rng, count_points(rng))
    if rng.random() < 0.03:  # sets of different lengths
        dst = dst[: max(0, len(dst) - 1)]
    if rng.random() < 0.3:  # plain arrays: the geometry, not the container, is the test
        return src, dst, structure
    return hostile_container(rng, src), hostile_container(rng, dst), structure


def case_estimate(rng: np.random.Generator) -> Case:
    src, dst, structure = pair_args(rng)
    solver = pick_mostly(rng, pc.SOLVERS, BAD_SOLVERS)
    refine = pick_mostly(rng, (False, True), BAD_FLAGS)
    return Case(
        pc.estimate_homography, (src, dst, solver, refine), {}, h_checker(src, dst), structure
    )


def case_find(rng: np.random.Generator) -> Case:
    src, dst, structure = pair_args(rng)
    method = pick_mostly(rng, (0, 0, *ROBUST_FLAGS), (-1, 1, 3, 99, 2**70, 8.0, "8", None))
    kwargs: dict[str, Any] = {"method": method}
    if rng.random() < 0.7:
        kwargs["ransacReprojThreshold"] = pick_mostly(rng, GOOD_THRESHOLDS, THRESHOLDS, 0.3)
    kwargs["maxIters"] = pick(rng, SMALL_BUDGETS if rng.random() < 0.9 else HOSTILE_BUDGETS)
    if rng.random() < 0.7:
        kwargs["confidence"] = pick_mostly(rng, GOOD_CONFIDENCES, CONFIDENCES, 0.3)
    if rng.random() < 0.1:
        n = n_of(src) or 0
        kwargs["mask"] = pick(rng, (np.zeros((n, 1), np.uint8), np.zeros(n, np.float64), "mask"))

    def check(out: Any) -> str | None:
        if not (isinstance(out, tuple) and len(out) == 2):
            return f"not (H, mask): {type(out).__name__}"
        h, mask = out
        problem = mask_problem(mask, n_of(src))
        if problem or h is None:
            return problem
        return h_problem(h, "opencv") or _degenerate_message(src, dst)

    return Case(pc.findHomography, (src, dst), kwargs, check, structure)


def hostile_matrix(rng: np.random.Generator, shape: tuple[int, int] = (3, 3)) -> Any:
    kind = int(rng.integers(6))
    if kind <= 1 and shape == (3, 3):
        m = random_homography(rng)
    elif kind == 2:
        m = np.outer(rng.normal(size=shape[0]), rng.normal(size=shape[1]))  # rank 1
    elif kind == 3:
        m = rng.normal(size=shape)
        m.flat[int(rng.integers(m.size))] = rng.choice(SPECIALS)
    else:
        m = numbers(rng, shape[0] * shape[1]).reshape(shape)
    return hostile_container(rng, m)


def points_arg(rng: np.random.Generator) -> tuple[Any, F64]:
    n = count_points(rng)
    points = np.stack([numbers(rng, n), numbers(rng, n)], axis=1)
    return hostile_container(rng, points), points


def case_transform(rng: np.random.Generator) -> Case:
    h = hostile_matrix(rng)
    points, _ = points_arg(rng)
    inverse = pick_mostly(rng, (False, True), BAD_FLAGS)
    invalid = pick_mostly(rng, ("raise", "nan"), ("inf", "", None, 1, "NAN"))
    n = n_of(points)
    kwargs = {"inverse": inverse, "invalid": invalid}
    return Case(
        pc.transform_points,
        (h, points),
        kwargs,
        lambda out: finite_points_problem(out, n, nan_rows=invalid == "nan"),
    )


def case_perspective(rng: np.random.Generator) -> Case:
    shape = pick(rng, ((3, 3), (3, 3), (3, 3), (4, 4), (3, 4), (4, 3), (2, 2), (3, 2)))
    m = hostile_matrix(rng, shape)
    n = count_points(rng)
    dim = 3 if shape[1] == 4 else 2
    pts = np.stack([numbers(rng, n) for _ in range(dim)], axis=-1).reshape(n, 1, dim)
    src = hostile_container(rng, pts) if rng.random() < 0.5 else pts.astype(np.float32)

    def check(out: Any) -> str | None:
        if out is None:
            return None if np.asarray(src).size == 0 else "None for a non-empty input"
        return finite_points_problem(out, None)

    return Case(pc.perspectiveTransform, (src, m), {}, check)


def case_reprojection(rng: np.random.Generator) -> Case:
    h = hostile_matrix(rng)
    src, dst, structure = pair_args(rng)
    invalid = pick_mostly(rng, ("raise", "inf"), ("nan", "", None, 1))
    n = n_of(src)

    def check(out: Any) -> str | None:
        if not isinstance(out, np.ndarray) or out.dtype != np.float64 or out.ndim != 1:
            return f"not a 1-D float64 array: {type(out).__name__}"
        if n is not None and len(out) != n:
            return f"{len(out)} errors for {n} points"
        if np.isnan(out).any() or (out < 0).any():
            return "NaN or negative errors"
        if invalid == "raise" and np.isinf(out).any():
            return "infinite errors with invalid='raise'"
        return None

    return Case(pc.reprojection_errors, (h, src, dst), {"invalid": invalid}, check, structure)


def case_stats(rng: np.random.Generator) -> Case:
    h = hostile_matrix(rng)
    src, dst, structure = pair_args(rng)

    def check(out: Any) -> str | None:
        if not isinstance(out, pc.ReprojectionStats):
            return f"not ReprojectionStats: {type(out).__name__}"
        values = (out.mean, out.rms, out.max, out.min)
        return None if all(math.isfinite(v) and v >= 0 for v in values) else f"stats {out}"

    return Case(pc.reprojection_stats, (h, src, dst), {}, check, structure)


def robust_options(rng: np.random.Generator, n: int) -> dict[str, Any]:
    options: dict[str, Any] = {}
    if rng.random() < 0.7:
        options["threshold"] = pick_mostly(rng, GOOD_THRESHOLDS, THRESHOLDS, 0.3)
    if rng.random() < 0.7:
        options["confidence"] = pick_mostly(rng, GOOD_CONFIDENCES, CONFIDENCES, 0.3)
    options["max_iters"] = pick(rng, SMALL_BUDGETS if rng.random() < 0.9 else HOSTILE_BUDGETS)
    if rng.random() < 0.5:
        options["seed"] = pick_mostly(rng, (0, 1, 12345, 2**64 - 1), SEEDS, 0.3)
    if rng.random() < 0.3:
        options["method"] = pick_mostly(rng, ("msac", "lmeds"), BAD_METHODS)
    return options


def big_budget_case(rng: np.random.Generator) -> tuple[F64, F64, dict[str, Any]]:
    """The largest accepted budget, on exact correspondences (the search converges at once) or
    on a degenerate set (refused at once): a budget is the caller's to spend, not a hang."""
    n = int(rng.integers(4, 13))
    src = rng.uniform(0, 2000, (n, 2))
    if rng.random() < 0.5:
        src[:, 1] = 2.0 * src[:, 0] + 1.0
    return src, project(random_homography(rng), src), {"max_iters": 10**7}


def case_robust(rng: np.random.Generator) -> Case:
    if rng.random() < 0.01:
        src, dst, options = big_budget_case(rng)
        structure = "big budget"
    else:
        src, dst, structure = pair_args(rng)
        options = robust_options(rng, n_of(src) or 0)
    n = n_of(src)
    if rng.random() < 0.2:
        count = n or 0
        scores = numbers(rng, count + int(rng.choice([0, 0, 0, 1, -1]) if count else 0))
        options["scores"] = hostile_container(rng, scores)

    def check(r: Any) -> str | None:
        return robust_result_problem(r, n) or (
            _degenerate_message(src, dst) if r.H is not None else None
        )

    return Case(pc.estimate_homography_robust, (src, dst), options, check, structure)


def case_robust_batch(rng: np.random.Generator) -> Case:
    count = int(rng.choice([0, 1, 2, 3, 5]))
    pairs = [pair_args(rng)[:2] for _ in range(count)]
    problems: Any = pairs
    if rng.random() < 0.05:  # an iterator (a valid argument, consumed by the call), or junk
        problems = pick(rng, (None, 3, [(1, 2)], [([[0.0, 0.0]] * 4,)], iter(pairs), "ab"))
    options = robust_options(rng, 0)

    def check(results: Any) -> str | None:
        if not isinstance(results, list) or len(results) != count:
            return f"{type(results).__name__} for {count} problems"
        for (src, dst), r in zip(pairs, results, strict=True):
            problem = robust_result_problem(r, n_of(src))
            if problem or r.H is None:
                return problem
            degenerate = _degenerate_message(src, dst)
            if degenerate:
                return degenerate
        return None

    return Case(pc.estimate_homography_robust_batch, (problems,), options, check)


def case_tracks(rng: np.random.Generator) -> Case:
    # The options as Tracker passes them (it checks them first); the positions are hostile.
    max_jump = pick(rng, (25.0, 25.0, 1e-300, 1e300, 5e-324))
    max_missing = pick(rng, (5, 5, 0, 1, 2**31))
    frames = [points_arg(rng)[0] for _ in range(int(rng.integers(1, 4)))]

    def run(*frames: Any) -> list[Any]:
        tracks = _core.Tracks(max_jump, max_missing)
        ids: list[Any] = [tracks.update(f) for f in frames]
        ids.append(tracks.live())
        return ids

    def check(out: Any) -> str | None:
        ids, (live_ids, live_positions) = out[:-1], out[-1]
        for frame_ids in [*ids, live_ids]:
            if not isinstance(frame_ids, np.ndarray) or frame_ids.dtype != np.int64:
                return "ids are not int64"
            if (frame_ids < 1).any():
                return f"track id below 1: {frame_ids.tolist()}"
        # Non-finite positions are kept, each on a track of its own (planarcal_core::Tracks).
        return None if len(live_ids) == len(live_positions) else "live ids and positions differ"

    return Case(run, tuple(frames), {}, check)


NUMERIC_ENTRIES: dict[str, Callable[[np.random.Generator], Case]] = {
    "estimate_homography": case_estimate,
    "findHomography": case_find,
    "perspectiveTransform": case_perspective,
    "transform_points": case_transform,
    "reprojection_errors": case_reprojection,
    "reprojection_stats": case_stats,
    "estimate_homography_robust": case_robust,
    "estimate_homography_robust_batch": case_robust_batch,
    "Tracks.update": case_tracks,
}


# -- images, files, the loop -----------------------------------------------------------------

IMAGE_DTYPES: tuple[Any, ...] = (np.uint8, np.uint8, np.uint16, np.int16, np.float32)
IMAGE_DTYPES += (np.float64, np.bool_, np.int64, np.complex64, np.object_)


def hostile_image(rng: np.random.Generator, size: tuple[int, int] = (1280, 720)) -> Any:
    """An image a caller might pass: blank, noise, shapes, NaN, another size or dtype, 1-D,
    4-channel, a view, read-only, or not an image at all."""
    w, h = (
        size if rng.random() < 0.6 else pick(rng, ((1, 1), (3, 2), (64, 48), (0, 5), (2000, 1500)))
    )
    kind = int(rng.integers(5))
    if kind == 0:
        img = np.full((h, w), rng.integers(256), np.uint8)
    elif kind == 1:
        small = rng.integers(0, 256, (max(1, h // 16), max(1, w // 16)), dtype=np.uint8)
        img = cv2.resize(small, (w, h), interpolation=cv2.INTER_NEAREST) if w and h else small
    else:
        img = np.full((h, w), 200, np.uint8)
        for _ in range(int(rng.integers(0, 12))):
            centre = (int(rng.integers(0, max(w, 1))), int(rng.integers(0, max(h, 1))))
            radius = int(rng.integers(1, 80))
            cv2.circle(img, centre, radius, int(rng.integers(0, 120)), -1)
    u = rng.random()
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        if u < 0.15:
            return img.astype(pick(rng, IMAGE_DTYPES))
        if u < 0.2:
            f = img.astype(np.float64)
            if f.size:
                f.flat[rng.integers(f.size, size=3)] = rng.choice(SPECIALS, 3)
            return f
        if u < 0.27:
            return np.dstack([img] * int(rng.choice([2, 3, 4])))
        if u < 0.3:
            return img[::2, ::2]
        if u < 0.33:
            img.flags.writeable = False
            return img
        if u < 0.36:
            return pick(rng, (None, img.reshape(-1), img[None, None], "no_such.png", 3, []))
    return img


@dataclasses.dataclass
class Fixtures:
    """What the non-numeric entry points need: a real calibration, its file, an intrinsics
    file, a folder to run the tracker on; made once per process under a temporary folder."""

    folder: Path
    calibration: pc.Calibration
    calibration_json: str
    probe_px: F64
    probe_mm: F64
    intrinsics: pc.CameraIntrinsics
    intrinsics_texts: dict[str, str]
    tracker: pc.Tracker
    board_image: NDArray[np.uint8]
    board: pc.CircleGridBoard


_FIXTURES: Fixtures | None = None


def fixtures() -> Fixtures:
    global _FIXTURES
    if _FIXTURES is None:
        # Only the file and image cases need these.
        from planarcal.synth import paper_data  # noqa: PLC0415
        from planarcal.synth.corpus import board_variant  # noqa: PLC0415

        folder = Path(tempfile.mkdtemp(prefix="planarcal_fuzz_"))
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        world, image = np.array(paper_data.WORLD_MM), np.array(paper_data.IMAGE_PX)
        cal = pc.Calibration(
            world, image, board=pc.CircleGridBoard(), image_size=(1280, 720), lens="none"
        )
        cal.save(folder / "calib.json")
        probe = np.array([[640.0, 360.0], [100.0, 80.0], [1200.0, 700.0]])
        intrinsics = pc.CameraIntrinsics(
            np.array([[900.0, 0.0, 640.0], [0.0, 910.0, 360.0], [0.0, 0.0, 1.0]]),
            np.array([-0.1, 0.02, 0.001, -0.001, 0.0]),
            (1280, 720),
        )
        texts = {}
        for suffix in (".yml", ".xml", ".json"):
            path = intrinsics.save_yaml(folder / f"camera{suffix}")
            texts[suffix] = path.read_text()
        (folder / "frames").mkdir()
        cv2.imwrite(str(folder / "frames" / "0.png"), np.full((720, 1280), 200, np.uint8))
        tracker = pc.Tracker(cal, str(folder / "frames"))
        atexit.register(tracker.close)
        variant = board_variant("webcam_320x240_jpeg")
        _FIXTURES = Fixtures(
            folder,
            cal,
            (folder / "calib.json").read_text(),
            probe,
            cal.image_to_world(probe),
            intrinsics,
            texts,
            tracker,
            np.asarray(variant.image, dtype=np.uint8),
            _circle_grid(variant.board),
        )
    return _FIXTURES


def _circle_grid(board: object) -> pc.CircleGridBoard:
    """The corpus variant's board: a circle grid (the fixtures' calibration is of one)."""
    assert isinstance(board, pc.CircleGridBoard)
    return board


def damaged_board(rng: np.random.Generator, image: NDArray[np.uint8]) -> Any:
    """A real board's picture, damaged: noise, a dtype or range change, NaN or inf pixels,
    a crop, a flip, a blur of contrast."""
    out: Any = image.astype(np.float64)
    kind = int(rng.integers(6))
    if kind == 0:
        out = out + rng.normal(0, float(rng.choice([1, 10, 60])), out.shape)
    elif kind == 1:
        out = out * float(rng.choice([1e-300, 1e-3, 1 / 255, 256, 1e300]))
    elif kind == 2:
        out.flat[rng.integers(out.size, size=int(rng.integers(1, 50)))] = rng.choice(SPECIALS)
    elif kind == 3:
        h, w = out.shape
        out = out[int(rng.integers(h // 2)) :, : w - int(rng.integers(w // 2))]
    elif kind == 4:
        out = out[::-1] if rng.random() < 0.5 else out.T
    else:
        out = 128 + (out - 128) * float(rng.choice([0.01, 0.1, 0.5]))
    dtype = pick(rng, (np.uint8, np.uint16, np.float32, np.float64, np.int32))
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        if np.dtype(dtype).kind in "iu":
            out = np.clip(np.nan_to_num(out), 0, np.iinfo(dtype).max)
        return out.astype(dtype)


def case_detect(rng: np.random.Generator) -> Case:
    fx = fixtures()
    board = pick(rng, (fx.board, fx.board, pc.CircleGridBoard(), None, "7x5"))
    if rng.random() < 0.5:
        image = damaged_board(rng, fx.board_image)
    else:
        image = hostile_image(rng, (int(rng.integers(8, 400)), int(rng.integers(8, 300))))
    polarity = pick(rng, ("auto", "dark", "light", "auto", "x", None))
    turned = pick(rng, (False, True))

    def check(d: Any) -> str | None:
        pts = np.asarray(d.image_points)
        return None if np.isfinite(pts).all() else "non-finite dot centres"

    return Case(pc.detect_board, (image, board), {"polarity": polarity, "turned": turned}, check)


DEEP = "<nested absurdly deep>"


def _mutate_json(rng: np.random.Generator, data: Any) -> Any:
    """`data` with one leaf (or container) replaced, removed or nested absurdly deep."""
    paths: list[tuple[Any, ...]] = []

    def walk(node: Any, path: tuple[Any, ...]) -> None:
        paths.append(path)
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, (*path, k))
        elif isinstance(node, list):
            for i, v in enumerate(node):
                walk(v, (*path, i))

    walk(data, ())
    path = pick(rng, paths[1:])
    value = pick(
        rng,
        [
            "x", "", True, False, None, 2**80, -(2**80), -1, 0, 1.5, math.nan, math.inf, -math.inf,
            1e308, 5e-324, [], {}, [1.0] * 3, {"a": 1}, DEEP, "9" * 5000,
        ],
    )  # fmt: skip
    parent = data
    for key in path[:-1]:
        parent = parent[key]
    if rng.random() < 0.15:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value
    return data


def _mutate_bytes(rng: np.random.Generator, text: bytes) -> bytes:
    kind = int(rng.integers(5))
    if kind == 0:  # truncated
        return text[: int(rng.integers(0, max(len(text), 1)))]
    if kind == 1:  # bytes flipped
        b = bytearray(text)
        for i in rng.integers(0, max(len(b), 1), size=int(rng.integers(1, 6))):
            if b:
                b[int(i)] = int(rng.integers(256))
        return bytes(b)
    if kind == 2:
        return rng.bytes(int(rng.integers(0, 2000)))
    if kind == 3:  # a number swapped for another token
        token: bytes = pick(
            rng, [b"nan", b"NaN", b"inf", b"-inf", b"1e999", b"null", b"true", b'"x"']
        )
        digits = [i for i, c in enumerate(text) if chr(c).isdigit()]
        if not digits:
            return text
        i = int(pick(rng, digits))
        return text[:i] + token + text[i + 1 :]
    tail: bytes = pick(rng, [b"\x00", b"{}", b"garbage", b"\n" * 3])
    return text + tail


def case_calibration_load(rng: np.random.Generator) -> Case:
    fx = fixtures()
    path = fx.folder / f"mutated_{os.getpid()}.json"
    if rng.random() < 0.6:
        mutated = _mutate_json(rng, json.loads(fx.calibration_json))
        depth = int(rng.choice([10, 1000, 100_000]))
        text = json.dumps(mutated, allow_nan=True)
        body = text.replace(f'"{DEEP}"', "[" * depth + "0" + "]" * depth).encode()
    else:
        body = _mutate_bytes(rng, fx.calibration_json.encode())

    def load(p: Path, body: bytes) -> pc.Calibration:
        p.write_bytes(body)
        return pc.Calibration.load(p)

    def check(cal: Any) -> str | None:
        try:
            mm = cal.image_to_world(fx.probe_px)
            same = np.array_equal(mm, fx.probe_mm)
        except Exception as e:  # a loaded file that then fails to map is corrupt too
            return f"corrupt file accepted: mapping then raised {type(e).__name__}: {e}"
        return None if same else "corrupt file accepted: it maps points differently"

    return Case(load, (path, body), {}, check, "calibration file")


def case_intrinsics_load(rng: np.random.Generator) -> Case:
    fx = fixtures()
    suffix = pick(rng, (".yml", ".xml", ".json"))
    path = fx.folder / f"mutated_{os.getpid()}{suffix}"
    body = _mutate_bytes(rng, fx.intrinsics_texts[suffix].encode())

    def load(p: Path, body: bytes) -> pc.CameraIntrinsics:
        p.write_bytes(body)
        return pc.CameraIntrinsics.load_yaml(p)

    def check(k: Any) -> str | None:
        if k == fx.intrinsics:
            return None
        m, d = np.asarray(k.matrix), np.asarray(k.dist_coeffs)
        sane = (
            np.isfinite(m).all()
            and np.isfinite(d).all()
            and m[2].tolist() == [0.0, 0.0, 1.0]
            and m[0, 0] > 0
            and m[1, 1] > 0
            and min(k.image_size) > 0
        )
        return None if sane else f"corrupt file accepted: {k}"

    return Case(load, (path, body), {}, check, "intrinsics file")


def case_locate(rng: np.random.Generator) -> Case:
    fx = fixtures()
    image = hostile_image(rng)
    kwargs: dict[str, Any] = {}
    if rng.random() < 0.3:
        kwargs["height_mm"] = pick(rng, (0.0, 5.0, -1.0, math.nan, 1e300, "1"))
    if rng.random() < 0.2:
        kwargs["frame"] = pick(rng, ("board", "robot", "x"))
    if rng.random() < 0.2:
        kwargs["min_area_px"] = pick(rng, (0.0, -1.0, math.nan, 1e300, 5.0))

    def check(found: Any) -> str | None:
        for o in found:
            if not (np.isfinite(o.world_mm).all() and np.isfinite(o.world_std_mm).all()):
                return f"non-finite object {o}"
        return None

    return Case(pc.locate_objects, (image, fx.calibration), kwargs, check)


def case_tracker(rng: np.random.Generator) -> Case:
    tracker = fixtures().tracker
    frame = hostile_image(rng)

    def check(r: Any) -> str | None:
        for o in r.objects:
            if not np.isfinite(o.world_mm).all():
                return f"non-finite tracked object {o}"
        return None

    return Case(tracker.process, (frame,), {}, check)


# -- registration to a robot (issue 21) --------------------------------------------------------

# How far a fit may be from the truth before it is a confident wrong answer: this many times
# its own reported 1-sigma (std_mm) plus the touch noise the truth was given.
WRONG_ANSWER_SIGMAS = 5.0
REGISTRATION_NOISE_MM = (0.0, 0.0, 0.005, 0.02, 0.05, 0.2)
BAD_MODELS: tuple[Any, ...] = ("", "Rigid", None, 3, "projective", True)
BAD_OUTLIER_MM: tuple[Any, ...] = (0.0, -1.0, math.nan, math.inf, "1", True, 1e-300, [1.0])


# Whether the fit takes the robot frame's hand ("right", "left"), as from issue 21 on.
HANDEDNESS_OPTION = "handedness" in inspect.signature(pc.RobotFrame.fit).parameters


@dataclasses.dataclass
class RobotTruth:
    """The board -> robot map the touches were made with: its 3 x 3 matrix, whether it
    mirrors, the model it belongs to, and the touch noise (mm per coordinate)."""

    matrix: F64
    reflected: bool
    model: str
    noise_mm: float

    def apply(self, plane: F64) -> F64:
        return np.asarray(plane @ self.matrix[:2, :2].T + self.matrix[:2, 2], dtype=np.float64)


def robot_truth(rng: np.random.Generator) -> RobotTruth:
    """A random rigid, similarity or affine map, mirrored half the time (a board's frame and
    a robot's base frame seen from above are usually of opposite hands)."""
    model = pick(rng, ("rigid", "rigid", "similarity", "affine"))
    angle = rng.uniform(-math.pi, math.pi)
    reflected = bool(rng.random() < 0.5)
    rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    linear = rotation @ np.diag([1.0, -1.0 if reflected else 1.0])
    if model == "similarity":
        linear *= rng.uniform(0.5, 2.0)
    elif model == "affine":
        linear = linear @ np.array([[rng.uniform(0.7, 1.4), rng.uniform(-0.3, 0.3)], [0.0, 1.0]])
    m = np.eye(3)
    m[:2, :2] = linear
    m[:2, 2] = rng.uniform(-1000.0, 1000.0, 2)
    return RobotTruth(m, reflected, model, float(pick(rng, REGISTRATION_NOISE_MM)))


def registration_count(rng: np.random.Generator) -> int:
    """Pairs: too few (0-3), a few, many, rarely thousands (a fit's cost is a hang risk)."""
    u = rng.random()
    if u < 0.1:
        return int(rng.integers(0, 4))
    if u < 0.7:
        return int(rng.integers(4, 9))
    if u < 0.998:
        return int(rng.integers(9, 60))
    return int(rng.choice([2000, 20_000]))


# Board-side shapes; "collinear" and "near_line" (within 0.05 mm of one line) leave the
# handedness of the map undetermined for every model.
REGISTRATION_SHAPES: tuple[str, ...] = ("spread", "spread", "spread", "collinear", "near_line")
REGISTRATION_SHAPES += ("duplicates",)
REGISTRATION_SHAPES += ("clustered", "two_places")


def board_shape(rng: np.random.Generator, n: int, shape: str, span: F64) -> F64:
    """n board points (mm) of one shape across a board of `span` (width, height) mm."""
    pts = rng.uniform(0.0, 1.0, (n, 2)) * span
    if shape in ("collinear", "near_line") and n:
        a, b = rng.uniform(0.0, 1.0, (2, 2)) * span
        pts = a + rng.uniform(0.0, 1.0, (n, 1)) * (b - a)
        if shape == "near_line":
            normal = np.array([a[1] - b[1], b[0] - a[0]]) / max(float(np.hypot(*(b - a))), 1e-9)
            pts += rng.uniform(-0.05, 0.05, (n, 1)) * normal
    elif shape == "duplicates" and n > 1:
        pts[rng.integers(n, size=n // 2 + 1)] = pts[int(rng.integers(n))]
    elif shape == "clustered" and n:
        pts = pts[:1] + rng.uniform(-1.0, 1.0, (n, 2))
    elif shape == "two_places" and n:
        pts = pts[rng.integers(2, size=n) % max(n, 1)] if n > 1 else pts
    return pts


def _board_side(
    rng: np.random.Generator, cal: pc.Calibration, n: int, shape: str
) -> tuple[str, Any, F64]:
    """How the board side is given (dots, board_mm or image_px), the value given, and the
    board points (mm) it stands for."""
    board = cal.board
    assert board is not None
    span = np.array([(board.cols - 1) * board.pitch, (board.rows - 1) * board.pitch])
    how = pick(rng, ("board_mm", "board_mm", "dots", "image_px", "fit"))
    if how == "dots":
        if shape in ("collinear", "near_line"):
            row = int(rng.integers(board.rows))
            index = row * board.cols + rng.integers(board.cols, size=n)
        else:
            index = rng.integers(board.n_points, size=n)
        plane = board.world_points()[index] * np.asarray(cal.world_scale)
        return how, index.tolist() if rng.random() < 0.5 else index, plane
    plane = board_shape(rng, n, shape, span)
    if how == "image_px":
        px = cal.world_to_image(plane) if n else np.zeros((0, 2))
        return how, px, np.asarray(cal.image_to_world(px), dtype=np.float64).reshape(-1, 2)
    return how, plane, plane


def hostile_robot(rng: np.random.Generator, robot: F64) -> tuple[Any, bool]:
    """The robot points as a caller might pass them, and whether they still mean `robot`
    (strings of the same numbers do; NaN, 1e308, complex, bools and the rest do not)."""
    u = rng.random()
    if u < 0.55 or not robot.size:
        return robot, True
    if u < 0.62:
        return robot.astype(str), True
    if u < 0.66:
        return robot.tolist(), True
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        if u < 0.7:
            return robot.astype(np.complex128) * pick(rng, (1.0, 1j, 1 + 1e-3j)), False
        if u < 0.74:
            bent: list[Any] = robot.tolist()
            bent[int(rng.integers(len(bent)))][int(rng.integers(2))] = pick(rng, (True, False))
            return bent, False
        if u < 0.78:
            return robot > robot.mean(), False
        if u < 0.86:
            out = robot.copy()
            out.flat[int(rng.integers(out.size))] = rng.choice(SPECIALS)
            return out, False
        if u < 0.9:
            return robot * float(pick(rng, (1e300, 1e306, 1e-300, 5e-324))), False
        if u < 0.94:
            return np.c_[robot, rng.choice([0.0, 1e308, np.nan], len(robot))], False
    return pick(rng, (None, "robot", [[1.0, 2.0]], robot[:, :1], robot.T, {"x": 1})), False


@dataclasses.dataclass
class RegistrationCase:
    """What a registration case knows beside its call: the truth and whether the call's
    inputs still stand for it."""

    truth: RobotTruth
    plane: F64
    meaningful: bool
    span: F64 = dataclasses.field(default_factory=lambda: np.array([260.0, 180.0]))
    """The board's extent (mm) from its origin dot: where parts are placed."""


def case_registration(rng: np.random.Generator) -> Case:
    """RobotFrame.fit or Calibration.register of touches made through a known map, with
    board sides of every shape (collinear and within 0.05 mm of a line among them) and robot
    points of every hostile kind."""
    cal = fixtures().calibration
    truth = robot_truth(rng)
    n, shape = registration_count(rng), pick(rng, REGISTRATION_SHAPES)
    how, given, plane = _board_side(rng, cal, n, shape)
    robot = truth.apply(plane) + rng.normal(0.0, truth.noise_mm, (n, 2)) if n else plane
    robot_arg, meaningful = hostile_robot(rng, robot)
    kwargs: dict[str, Any] = {"model": truth.model if rng.random() < 0.85 else "affine"}
    if rng.random() < 0.05:
        kwargs["model"] = pick(rng, BAD_MODELS)
        meaningful = False
    if rng.random() < 0.1:
        kwargs["outlier_mm"] = pick(rng, BAD_OUTLIER_MM)
    if rng.random() < 0.1:
        kwargs["drop_outliers"] = pick(rng, (True, False, None, 1, "yes"))
    if HANDEDNESS_OPTION and rng.random() < 0.25:
        # The hand stated (a right-handed robot frame is the board's mirror image): the true
        # one fixes a map the touches on one line cannot; a wrong or malformed one is the
        # caller's fault, judged only for a clean answer.
        right, wrong = ("right", "left") if truth.reflected else ("left", "right")
        kwargs["handedness"] = pick_mostly(rng, (right,), (wrong, "RIGHT", "", True, 1), 0.3)
        meaningful &= kwargs["handedness"] == right
    known = RegistrationCase(truth, plane, meaningful)
    check = registration_checker(known)
    note = f"{how}, {shape}, {n} pairs, {truth.model}{' mirrored' if truth.reflected else ''}"
    if how == "fit":
        return Case(pc.RobotFrame.fit, (plane, robot_arg), kwargs, check, note, (ValueError,))
    kwargs[how] = given

    def register(cal: pc.Calibration, robot_mm: Any, **kw: Any) -> Any:
        return cal.register(robot_mm, **kw).robot_frame

    return Case(register, (cal, robot_arg), kwargs, check, note, (ValueError,))


def registration_checker(known: RegistrationCase) -> Callable[[Any], str | None]:
    def check(frame: Any) -> str | None:
        if not isinstance(frame, pc.RobotFrame):
            return f"not a RobotFrame: {type(frame).__name__}"
        if not np.isfinite(frame.plane_to_robot).all():
            return f"a non-finite transform: {frame.plane_to_robot.tolist()}"
        if not known.meaningful:
            return None
        return registration_error(frame, known)

    return check


def registration_error(frame: Any, known: RegistrationCase) -> str | None:
    """ "wrong answer: ..." when the fit's handedness is not the truth's, or it maps a touched
    point (or their centroid) farther from the truth than WRONG_ANSWER_SIGMAS x (its own
    std_mm + the touch noise)."""
    truth = known.truth
    if bool(frame.reflected) != truth.reflected:
        return (
            f"wrong answer: reflected={frame.reflected} for a map that "
            f"{'mirrors' if truth.reflected else 'does not mirror'} (rms {frame.rms_mm:.3g} mm)"
        )
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]) * known.span
    probe = np.vstack([np.unique(known.plane, axis=0), known.plane.mean(axis=0), corners])
    off = np.hypot(*(frame.to_robot(probe) - truth.apply(probe)).T)
    std = frame.std_mm(probe)
    bound = WRONG_ANSWER_SIGMAS * (std + truth.noise_mm) + 1e-9 * (1.0 + np.abs(probe).max())
    worst = int(np.argmax(off - bound))
    if off[worst] > bound[worst]:
        return (
            f"wrong answer: {off[worst]:.3g} mm from the truth at {probe[worst].tolist()} "
            f"where its std_mm is {std[worst]:.3g} (noise {truth.noise_mm} mm)"
        )
    return None


# -- the calibration-file editor (issue 21) ----------------------------------------------------

# What the editor does to one node of a saved calibration's JSON, by the node's type; every
# node also gets "delete" (its key, or its place in its list, removed).
EDITS_NUMBER: tuple[str, ...] = (
    "string",
    "true",
    "false",
    "null",
    "huge",
    "-huge",
    "2**80",
    "nan",
    "inf",
)
EDITS_NUMBER += ("-inf", "negate", "zero", "nudge", "list", "object", "swap", "delete")
EDITS_STRING = ("empty", "other", "number", "null", "true", "list", "delete")
EDITS_BOOL = ("not", "zero", "one", "string", "null", "delete")
EDITS_NULL = ("zero", "string", "list", "object", "false", "delete")
EDITS_LIST = ("shorten", "lengthen", "empty", "reverse", "wrap", "object", "null", "delete")
EDITS_OBJECT = ("add_key", "empty", "list", "null", "string", "delete")


def _edits_of(value: Any) -> tuple[str, ...]:
    if isinstance(value, bool):
        return EDITS_BOOL
    if isinstance(value, int | float):
        return EDITS_NUMBER
    if isinstance(value, str):
        return EDITS_STRING
    if value is None:
        return EDITS_NULL
    return EDITS_LIST if isinstance(value, list) else EDITS_OBJECT


def json_paths(data: Any) -> list[tuple[Any, ...]]:
    """The path (keys and indices) of every node of `data` but the root, depth first."""
    paths: list[tuple[Any, ...]] = []

    def walk(node: Any, path: tuple[Any, ...]) -> None:
        if path:
            paths.append(path)
        if isinstance(node, dict | list):
            for k, v in node.items() if isinstance(node, dict) else enumerate(node):
                walk(v, (*path, k))

    walk(data, ())
    return paths


def file_edits(data: Any) -> list[tuple[tuple[Any, ...], str]]:
    """Every (path, edit) the editor makes to `data`: each node changed in each way its type
    allows (case i of the editor is edit i modulo their number)."""
    edits: list[tuple[tuple[Any, ...], str]] = []
    for path in json_paths(data):
        node = data
        for key in path:
            node = node[key]
        edits.extend((path, edit) for edit in _edits_of(node))
    return edits


def _edited_value(value: Any, edit: str, sibling: Any) -> Any:
    """`value` changed by `edit` (not "delete", "swap" gets `sibling`)."""
    number = value if isinstance(value, int | float) and not isinstance(value, bool) else 1.0
    table: dict[str, Any] = {
        "string": str(value), "true": True, "false": False, "null": None, "huge": 1e308,
        "-huge": -1e308, "2**80": 2**80, "nan": math.nan, "inf": math.inf, "-inf": -math.inf,
        "negate": -number, "zero": 0, "one": 1, "nudge": number * 1.01 + 0.01, "list": [value],
        "object": {"value": value}, "swap": sibling, "empty": "" if isinstance(value, str) else
        type(value)() if isinstance(value, list | dict) else value, "other": f"{value}x",
        "number": 1.0, "not": not value, "wrap": [value],
    }  # fmt: skip
    if edit in table:
        return table[edit]
    if edit == "shorten":
        return value[:-1]
    if edit == "lengthen":
        return [*value, value[-1] if value else 0.0]
    if edit == "reverse":
        return value[::-1]
    assert edit == "add_key", edit
    return {**value, "extra": 1}


def edit_json(data: Any, path: tuple[Any, ...], edit: str) -> Any:
    """`data` (changed in place) with the node at `path` edited."""
    parent = data
    for key in path[:-1]:
        parent = parent[key]
    key = path[-1]
    if edit == "delete":
        del parent[key]
        return data
    sibling = parent[key]
    if isinstance(parent, list) and len(parent) > 1:
        sibling = parent[(key + 1) % len(parent)]
    elif isinstance(parent, dict) and len(parent) > 1:
        keys = list(parent)
        sibling = parent[keys[(keys.index(key) + 1) % len(keys)]]
    parent[key] = _edited_value(parent[key], edit, sibling)
    return data


@dataclasses.dataclass
class RegisteredFixture:
    """A saved calibration with a registration to a robot, and what it maps a fixed set of
    pixels to (board mm, robot mm)."""

    text: str
    data: Any
    edits: list[tuple[tuple[Any, ...], str]]
    probe_px: F64
    board_mm: F64
    robot_mm: F64


_REGISTERED: RegisteredFixture | None = None


def registered_fixture() -> RegisteredFixture:
    global _REGISTERED
    if _REGISTERED is None:
        fx = fixtures()
        dots = [0, 5, 13, 70, 126, 139, 64]
        plane = fx.calibration.board.world_points()[dots]  # type: ignore[union-attr]
        truth = np.array([[0.0, 1.0], [1.0, 0.0]])  # a mirror: the usual board-to-robot case
        robot = plane @ truth.T + [250.0, -120.0] + np.linspace(-0.02, 0.02, 14).reshape(7, 2)
        cal = fx.calibration.register(robot, dots=dots)
        path = cal.save(fx.folder / "registered.json")
        text = path.read_text()
        data = json.loads(text)
        probe = np.array([[640.0, 360.0], [100.0, 80.0], [1200.0, 700.0], [300.0, 500.0]])
        _REGISTERED = RegisteredFixture(
            text,
            data,
            file_edits(data),
            probe,
            cal.image_to_world(probe),
            cal.image_to_world(probe, frame="robot"),
        )
    return _REGISTERED


def case_calibration_edit(rng: np.random.Generator, index: int = 0) -> Case:
    """Edit `index` (modulo their number) of a real saved calibration with a registration:
    every node changed in type and value, lists shortened and lengthened, keys removed and
    added."""
    fx = registered_fixture()
    path, edit = fx.edits[index % len(fx.edits)]
    body = json.dumps(edit_json(json.loads(fx.text), path, edit), allow_nan=True).encode()
    where = fixtures().folder / f"edited_{os.getpid()}.json"

    def load(p: Path, body: bytes) -> pc.Calibration:
        p.write_bytes(body)
        return pc.Calibration.load(p)

    def check(cal: Any) -> str | None:
        # A file whose registration is removed (or null) is a valid file of a calibration
        # not registered: it says so (frame="robot" is refused), so its robot side is not
        # compared.
        frame = "robot" if cal.robot_frame is not None else "board"
        try:
            board = cal.image_to_world(fx.probe_px)
            robot = (
                fx.robot_mm if frame == "board" else cal.image_to_world(fx.probe_px, frame=frame)
            )
        except Exception as e:  # a file that loads and then cannot map means something else
            return f"wrong answer: loaded, then mapping raised {type(e).__name__}: {e}"
        if not (np.array_equal(board, fx.board_mm) and np.array_equal(robot, fx.robot_mm)):
            moved = max(np.abs(board - fx.board_mm).max(), np.abs(robot - fx.robot_mm).max())
            return f"wrong answer: loaded with another meaning (moved up to {moved:.3g} mm)"
        try:
            cal.save(where.with_suffix(".resaved.json"))
        except Exception as e:
            return f"saving the loaded file raised {type(e).__name__}: {e}"
        return None

    note = f"{edit} {'/'.join(map(str, path))}: calibration file"
    return Case(load, (where, body), {}, check, note, (pc.CalibrationFileError,))


# -- the trigger server (issue 21) -------------------------------------------------------------

TRIGGER = b"TRIGGER"
MAX_REQUEST_BYTES = 1024  # output_server's: a longer line is not a request
# Beyond its trigger timeout (and an idle client's eviction), how long a well-behaved
# controller may wait for its answer, s: longer is a request lost.
ANSWER_GRACE_S = 3.0
# Idle clients are evicted after this long when the server takes the option (issue 21).
SERVER_IDLE_S = 1.0
FRAME_PERIODS_S = (0.01, 0.03, 0.1)


def _connect(port: int, timeout: float) -> Any:
    sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
    sock.settimeout(timeout)
    return sock


def _read_lines(sock: Any, until: float, want: int | None = None) -> tuple[list[bytes], str]:
    """Lines read until EOF (or `want` lines, or the deadline): the lines, and how it ended
    ("eof", "enough", "timeout", "reset")."""
    buf = b""
    lines: list[bytes] = []
    while want is None or len(lines) < want:
        left = until - time.monotonic()
        if left <= 0:
            return lines, "timeout"
        sock.settimeout(left)
        try:
            data = sock.recv(65536)
        except TimeoutError:
            return lines, "timeout"
        except OSError:
            return lines, "reset"
        if not data:
            return lines, "eof"
        buf += data
        *whole, buf = buf.split(b"\n")
        lines.extend(whole)
    return lines, "enough"


@dataclasses.dataclass
class Peer:
    """One hostile client's plan: what it sends, whether it then closes its side, and how
    many replies it must get (None: at most one per line sent, as many as the server could
    give before letting it go)."""

    kind: str
    send: bytes
    shut_write: bool = False
    expect: int | None = None
    read: bool = True
    reset: bool = False


def hostile_peer(rng: np.random.Generator) -> Peer:
    kind = pick(rng, ("huge", "binary", "half_closed", "flood", "reset", "deaf", "words"))
    if kind == "huge":
        size = int(pick(rng, (1025, 4096, 100_000, 2_000_000)))
        end = b"\n" if rng.random() < 0.7 else b""
        # An overlong line gets one error line; the TRIGGER after it is a request of its own.
        return Peer(kind, b"A" * size + end + TRIGGER + b"\n", True, 2 if end else 1)
    if kind == "binary":
        return Peer(kind, rng.bytes(int(rng.integers(1, 5000))), bool(rng.random() < 0.5))
    if kind == "half_closed":
        n = int(rng.integers(1, 17))
        return Peer(kind, (TRIGGER + b"\n") * n, True, n)
    if kind == "flood":
        n = int(pick(rng, (20, 64, 65, 300, 5000)))
        return Peer(kind, (TRIGGER + b"\r\n") * n, bool(rng.random() < 0.5), n if n <= 64 else None)
    if kind == "reset":
        return Peer(kind, TRIGGER + b"\n", reset=True, read=False)
    if kind == "deaf":  # asks and never reads
        return Peer(kind, (TRIGGER + b"\n") * int(rng.integers(1, 60)), read=False)
    lines = [b"trigger", b" TRIGGER ", b"TRIGGER TRIGGER", b"", b"\r", b"\xff\xfe", b"TRIG"]
    chosen = [pick(rng, lines) for _ in range(int(rng.integers(1, 10)))]
    replies = sum(1 for line in chosen if line.strip())
    return Peer(kind, b"\n".join(chosen) + b"\n", True, replies)


def _run_peer(port: int, peer: Peer, until: float, out: dict[str, Any]) -> None:
    try:
        sock = _connect(port, 2.0)
    except OSError as e:
        out["connect"] = str(e)
        return
    try:
        if peer.reset:
            sock.sendall(peer.send)
            sock.setsockopt(
                socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00"
            )
            return
        with contextlib.suppress(OSError):
            sock.sendall(peer.send)
            if peer.shut_write:
                sock.shutdown(socket.SHUT_WR)
        if peer.read:
            out["lines"], out["end"] = _read_lines(sock, until)
        else:
            time.sleep(max(0.0, min(0.5, until - time.monotonic())))
    finally:
        sock.close()


def _controller(port: int, until: float, out: dict[str, Any]) -> None:
    """A well-behaved controller: connects, asks once, reads one line; if it is turned away
    (an error line and a close, as a server at its cap does) it connects again, until
    `until`."""
    errors: list[str] = []
    while time.monotonic() < until:
        try:
            sock = _connect(port, 1.0)
        except OSError as e:
            errors.append(f"connect: {e}")
            time.sleep(0.1)
            continue
        with sock:
            try:
                sock.sendall(TRIGGER + b"\n")
            except OSError as e:
                errors.append(f"send: {e}")
                continue
            lines, end = _read_lines(sock, until, want=1)
        if lines and lines[0].startswith(b'{"frame"'):
            out["answer"] = lines[0]
            return
        errors.append(f"{lines[:1]!r} then {end}")
        time.sleep(0.1)
    out["errors"] = errors


def _frames(server: Any, period: float, stop: Any) -> None:
    k = 0
    while not stop.wait(period):
        k += 1
        server.answer(time.time(), lambda k=k: f'{{"frame": {k}}}')


def trigger_session(
    peers: list[Peer], idle_peers: int, cap: int, trigger_timeout: float, period: float
) -> dict[str, Any]:
    """A trigger server on loopback fed a frame every `period` s, the hostile `peers` and
    `idle_peers` idle connections thrown at it, then a well-behaved controller; what each
    got, and how long close() took."""
    from planarcal.live.output_server import ServerOutput  # noqa: PLC0415

    options: dict[str, Any] = {"trigger_word": "TRIGGER", "trigger_timeout": trigger_timeout}
    options["max_clients"] = cap
    if "idle_timeout" in inspect.signature(ServerOutput).parameters:
        options["idle_timeout"] = SERVER_IDLE_S
    until = time.monotonic() + trigger_timeout + SERVER_IDLE_S + ANSWER_GRACE_S
    # The server's reports of refusals, resets and idle closes are its business, not the
    # judge's: kept off the campaign's output.
    log = logging.getLogger("planarcal")
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        return _session(ServerOutput("127.0.0.1", 0, **options), peers, idle_peers, period, until)
    finally:
        log.setLevel(level)


def _session(
    server: Any, peers: list[Peer], idle_peers: int, period: float, until: float
) -> dict[str, Any]:
    stop = threading.Event()
    feeder = threading.Thread(target=_frames, args=(server, period, stop), daemon=True)
    feeder.start()
    idle = []
    outs: list[dict[str, Any]] = [{} for _ in peers]
    threads = [
        threading.Thread(target=_run_peer, args=(server.port, p, until, o), daemon=True)
        for p, o in zip(peers, outs, strict=True)
    ]
    try:
        for _ in range(idle_peers):
            with contextlib.suppress(OSError):
                idle.append(_connect(server.port, 2.0))
        for t in threads:
            t.start()
        controller: dict[str, Any] = {}
        _controller(server.port, until, controller)
        for t in threads:
            t.join(max(0.0, until - time.monotonic()) + 1.0)
    finally:
        stop.set()
        started = time.monotonic()
        server.close()
        closed_s = time.monotonic() - started
        for sock in idle:
            sock.close()
    return {"controller": controller, "peers": outs, "close_s": closed_s, "alive": threads}


def session_problem(session: dict[str, Any], peers: list[Peer], full: bool) -> str | None:
    """What went wrong in a trigger session: the controller's request lost, a request given
    more or fewer replies than one, a hang. A client may get one line more, last, before the
    server closes it (an error line saying why: idle, evicted); a server at its cap (`full`)
    may turn a client away with one error line."""
    if session["close_s"] > 5.0:
        return f"hang: close() took {session['close_s']:.1f} s"
    if any(t.is_alive() for t in session["alive"]):
        return "hang: a client's connection neither answered nor closed"
    controller = session["controller"]
    if "answer" not in controller:
        return (
            f"silent loss: the well-behaved controller got no answer: {controller['errors'][-3:]}"
        )
    for peer, out in zip(peers, session["peers"], strict=True):
        lines, end = out.get("lines"), out.get("end")
        if lines is None:
            continue
        goodbye = end == "eof" and bool(lines) and not lines[-1].startswith(b'{"frame"')
        if full and goodbye and len(lines) == 1:
            continue  # turned away at the cap, with the reason
        replies = len(lines) - goodbye
        # An unfinished line is answered once it is too long to be a request.
        sent = peer.send.count(b"\n") + (len(peer.send.rsplit(b"\n", 1)[-1]) > MAX_REQUEST_BYTES)
        if replies > max(sent, 1):
            return f"bad result: {peer.kind} client sent {sent} lines, got {len(lines)} replies"
        if peer.expect is not None and len(lines) == peer.expect:
            continue
        if peer.expect is not None and replies != peer.expect and end != "reset":
            return (
                f"silent loss: {peer.kind} client owed {peer.expect} replies, got {replies} ({end})"
            )
    return None


def case_trigger_server(rng: np.random.Generator) -> Case:
    """A trigger server's session: hostile clients (overlong lines, binary, floods, half-
    closed, resets, clients that never read, idle ones beyond the cap), then a well-behaved
    controller, which must get its answer."""
    cap = int(pick(rng, (2, 4, 8, 32)))
    peers = [hostile_peer(rng) for _ in range(int(rng.integers(0, min(cap, 5) + 1)))]
    idle_peers = int(pick(rng, (0, 0, 0, cap - len(peers), cap + 3)))
    trigger_timeout = float(pick(rng, (0.3, 1.0)))
    period = float(pick(rng, FRAME_PERIODS_S))
    note = f"cap {cap}, {idle_peers} idle, " + " ".join(p.kind for p in peers)
    return Case(
        trigger_session,
        (peers, max(0, idle_peers), cap, trigger_timeout, period),
        {},
        lambda session: session_problem(session, peers, len(peers) + idle_peers >= cap),
        note,
    )


# -- planarcal run over hostile sources (issue 21) ---------------------------------------------

RUN_FRAMES = 12
# A run over a source this small that takes longer than this has hung.
RUN_TIMEOUT_S = 30.0
# Words of a report of a loss: on stderr (beside the summary) or as a summary's key.
LOSS_WORDS: tuple[str, ...] = (
    "lost",
    "skip",
    "truncat",
    "corrupt",
    "cannot",
    "fail",
    "missing",
    "undecodable",
)
LOSS_WORDS += ("damaged", "error", "warning", "fewer", "dropped", "vanish", "wrong_size")


def _frame_image(k: int) -> NDArray[np.uint8]:
    img = np.full((720, 1280), 200, np.uint8)
    for j in range(3):
        cv2.circle(img, (200 + 300 * j + 10 * k, 200 + 100 * j), 30, 40, -1)
    return img


@dataclasses.dataclass
class RunSources:
    """A real video (MJPG, RUN_FRAMES frames of the calibration's size), and the frames as
    PNG bytes, to damage."""

    video: bytes
    pngs: list[bytes]
    calibration: Path


_RUN_SOURCES: RunSources | None = None


def run_sources() -> RunSources:
    global _RUN_SOURCES
    if _RUN_SOURCES is None:
        fx = fixtures()
        path = fx.folder / "good.avi"
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 10.0, (1280, 720))
        frames = [_frame_image(k) for k in range(RUN_FRAMES)]
        for f in frames:
            writer.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))
        writer.release()
        pngs = [cv2.imencode(".png", f)[1].tobytes() for f in frames]
        _RUN_SOURCES = RunSources(path.read_bytes(), pngs, fx.folder / "calib.json")
    return _RUN_SOURCES


@dataclasses.dataclass
class SourcePlan:
    """A hostile source to write: its kind, the files (name -> bytes, None for a folder of
    that name; a name ending in ' -> TARGET' a symbolic link), the good frames in it, the
    files made unreadable, and the file that vanishes mid-run."""

    kind: str
    files: dict[str, bytes | None]
    good: int
    locked: tuple[str, ...] = ()
    vanish: str | None = None


VIDEO_DAMAGE = ("truncated", "truncated", "bytes_flipped", "zeroed", "empty", "garbage")
FOLDER_KINDS = ("mixed", "mixed", "vanishing", "only_bad", "empty")


def _damaged_video(rng: np.random.Generator, video: bytes, kind: str) -> bytes:
    if kind == "truncated":
        return video[: int(len(video) * rng.uniform(0.02, 0.98))]
    if kind == "bytes_flipped":
        b = bytearray(video)
        for i in rng.integers(0, len(b), int(rng.integers(1, 50))):
            b[int(i)] = int(rng.integers(256))
        return bytes(b)
    if kind == "zeroed":
        a, n = int(rng.integers(len(video))), int(rng.integers(1, 100_000))
        return video[:a] + bytes(min(len(video) - a, n)) + video[a + n :]
    return b"" if kind == "empty" else rng.bytes(int(rng.integers(1, 200_000)))


BAD_IMAGE_FILES: dict[str, Callable[[bytes], bytes | None]] = {
    "notes.txt": lambda png: b"not an image\n",
    "junk.png": lambda png: b"this is text, not a PNG\n" * 10,
    "empty.png": lambda png: b"",
    "truncated.png": lambda png: png[: len(png) // 3],
    "flipped.png": lambda png: png[:100] + bytes(200) + png[300:],
    "small.png": lambda png: cv2.imencode(".png", np.zeros((48, 64), np.uint8))[1].tobytes(),
    "folder.png": lambda png: None,
    "dangling.png -> /nonexistent/x.png": lambda png: b"",
    "locked.png": lambda png: png,
    # Unreadable even for root: reading /proc/self/mem at offset 0 is an I/O error.
    "unreadable.png -> /proc/self/mem": lambda png: b"",
    "fifo.png": lambda png: b"",
}
# Made a FIFO (a reader would wait for a writer for ever).
FIFO_SUFFIX = "fifo.png"


def source_plan(rng: np.random.Generator, kind: str | None = None) -> SourcePlan:
    """A hostile source of `kind` ("video truncated", "folder mixed", ...; None: drawn)."""
    src = run_sources()
    if kind is None:
        video = rng.random() < 0.4
        kind = f"video {pick(rng, VIDEO_DAMAGE)}" if video else f"folder {pick(rng, FOLDER_KINDS)}"
    what, how = kind.split()
    if what == "video":
        body = _damaged_video(rng, src.video, how)
        return SourcePlan(kind, {"video.avi": body}, 0 if how == "empty" else -1)
    fewest = 2 if how == "vanishing" else 1
    good = 0 if how in ("only_bad", "empty") else int(rng.integers(fewest, RUN_FRAMES + 1))
    files: dict[str, bytes | None] = {f"{k:03d}.png": src.pngs[k] for k in range(good)}
    locked: list[str] = []
    if how in ("mixed", "only_bad"):
        for name in rng.choice(list(BAD_IMAGE_FILES), int(rng.integers(1, 5)), replace=False):
            stem = str(name)
            target = f"{int(rng.integers(RUN_FRAMES)):03d}_{stem}"
            files[target] = BAD_IMAGE_FILES[stem](src.pngs[0])
            if stem == "locked.png":
                locked.append(target)
    vanish = f"{good - 1:03d}.png" if how == "vanishing" and good > 1 else None
    return SourcePlan(kind, files, good, tuple(locked), vanish)


def write_source(plan: SourcePlan, where: Path) -> Path:
    """The source on disk: a video file, or a folder of the plan's files."""
    if where.exists():
        for path in where.rglob("*"):  # unreadable files and folders too
            path.chmod(0o700) if path.is_dir() and not path.is_symlink() else None
        shutil.rmtree(where)
    where.mkdir(parents=True)
    if plan.kind.startswith("video"):
        path = where / "video.avi"
        path.write_bytes(plan.files["video.avi"] or b"")
        return path
    for name, body in plan.files.items():
        if " -> " in name:
            link, target = name.split(" -> ")
            os.symlink(target, where / link)
        elif body is None:
            (where / name).mkdir()
        elif name.endswith(FIFO_SUFFIX):
            os.mkfifo(where / name)
        else:
            (where / name).write_bytes(body)
    for name in plan.locked:
        os.chmod(where / name, 0)
    return where


def _vanish_when_started(child: Any, out: Path, victim: Path) -> None:
    """Removes `victim` once the run has written its first line (the folder listed, the
    last image not read yet, unless the run is faster than this poll)."""
    deadline = time.monotonic() + RUN_TIMEOUT_S
    while child.poll() is None and time.monotonic() < deadline:
        if out.exists() and out.stat().st_size:
            break
        time.sleep(0.005)
    victim.unlink(missing_ok=True)


def run_on_source(plan: SourcePlan, where: Path) -> dict[str, Any]:
    """`planarcal run` over the plan's source, to a file, in a child: its exit status, the
    lines it wrote, its stderr; "timeout" if it did not end within RUN_TIMEOUT_S."""
    source = write_source(plan, where)
    out = where.parent / f"{where.name}.out"
    out.unlink(missing_ok=True)
    command = [sys.executable, "-m", "planarcal", "run", "--calibration"]
    command += [str(run_sources().calibration), "--source", str(source), "-o", str(out)]
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    if plan.vanish:
        _vanish_when_started(child, out, source / plan.vanish)
    try:
        _, err = child.communicate(timeout=RUN_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        child.kill()
        _, err = child.communicate()
        return {"timeout": True, "stderr": err.decode(errors="replace")}
    lines = out.read_bytes().count(b"\n") if out.exists() else 0
    done = {"status": child.returncode, "lines": lines, "stderr": err.decode(errors="replace")}
    done["readable"] = _readable_extras(plan, source)
    return done


def _readable_extras(plan: SourcePlan, source: Path) -> int:
    """The plan's damaged images that OpenCV reads all the same (a damaged PNG may still
    decode; a file made unreadable is read by root): frames a run may deliver beyond the
    good ones."""
    if not source.is_dir():
        return 0
    extras = 0
    for name in plan.files:
        path = source / name.split(" -> ")[0]
        if not name[:3].isdigit() or name.endswith("_small.png") or len(name) == 7:
            continue  # not an image of the folder's, of the wrong size, or a good one
        if path.is_file() and os.access(path, os.R_OK) and cv2.imread(str(path)) is not None:
            extras += 1
    return extras


def _reported_loss(stderr: str) -> bool:
    """Whether the run said it lost something: a line on stderr beside the summary, or a
    nonzero count of faults in the summary."""
    for line in stderr.splitlines():
        body = line.removeprefix("planarcal run: ")
        if body.startswith("{"):
            with contextlib.suppress(ValueError):
                summary = json.loads(body)
                if _loss_counts(summary):
                    return True
            continue
        if any(word in line.lower() for word in LOSS_WORDS):
            return True
    return False


def _loss_counts(node: Any, key: str = "") -> int:
    if isinstance(node, dict):
        return sum(_loss_counts(v, k) for k, v in node.items() if k != "stage_s")
    lossy = any(word in key.lower() for word in LOSS_WORDS)
    return int(node) if lossy and isinstance(node, int) and not isinstance(node, bool) else 0


def run_problem(done: dict[str, Any], plan: SourcePlan) -> str | None:
    """A hang, a traceback, exit 0 having delivered nothing, or exit 0 with frames lost and
    no report of it (a damaged video's frames count as lost against the RUN_FRAMES it
    held)."""
    err = done["stderr"]
    if done.get("timeout"):
        return f"hang: planarcal run over a {plan.kind} did not end in {RUN_TIMEOUT_S:g} s"
    if "Traceback" in err:
        return f"unclean: a traceback: {err.strip().splitlines()[-1][:200]}"
    if done["status"] != 0:
        return None if err.strip() else f"silent loss: exit {done['status']} and nothing said"
    expected = RUN_FRAMES if plan.good < 0 else plan.good
    if done["lines"] == 0:
        return f"silent loss: exit 0 having delivered nothing ({plan.kind})"
    if done["lines"] > expected + done["readable"]:
        return f"bad result: {done['lines']} lines from {expected} frames"
    if done["lines"] < expected and not _reported_loss(err):
        return f"silent loss: exit 0, {done['lines']} of {expected} frames, no report of a loss"
    return None


def case_run_source(rng: np.random.Generator) -> Case:
    """`planarcal run` over a hostile source: a truncated or byte-damaged video, an empty or
    random file, a folder with non-images, empty, truncated, unreadable or wrong-sized
    images, a folder of nothing but those, or one whose image vanishes mid-run."""
    plan = source_plan(rng)
    where = fixtures().folder / f"source_{os.getpid()}"

    def check(done: Any) -> str | None:
        return run_problem(done, plan)

    return Case(run_on_source, (plan, where), {}, check, plan.kind)


FILE_ENTRIES: dict[str, Callable[..., Case]] = {
    "detect_board": case_detect,
    "Calibration.load": case_calibration_load,
    "CameraIntrinsics.load_yaml": case_intrinsics_load,
    "locate_objects": case_locate,
    "Tracker.process": case_tracker,
    "registration": case_registration,
    "calibration_editor": case_calibration_edit,
    "trigger_server": case_trigger_server,
    "planarcal_run": case_run_source,
}
ENTRIES = {**NUMERIC_ENTRIES, **FILE_ENTRIES}
# Entry points whose cases are sessions of seconds (sockets, a child process), not calls.
SESSION_ENTRIES = frozenset({"trigger_server", "planarcal_run"})
# Entry points whose case i is the i-th of a list (every edit of a file), not a draw.
INDEXED = frozenset({"calibration_editor"})


def cases(entry: str, seed: int, start: int, stop: int) -> Iterator[tuple[int, Case]]:
    """Cases start..stop-1 of `entry`, each rebuilt identically whatever range asks for it."""
    make: Callable[..., Case] = ENTRIES[entry]
    block = start // BLOCK
    while block * BLOCK < stop:
        rng = block_rng(entry, seed, block)
        for index in range(block * BLOCK, (block + 1) * BLOCK):
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                case = make(rng, index) if entry in INDEXED else make(rng)
            if start <= index < stop:
                yield index, case
        block += 1


def case_at(entry: str, seed: int, index: int) -> Case:
    return next(cases(entry, seed, index, index + 1))[1]


# -- the judge ---------------------------------------------------------------------------------

OUTCOMES: tuple[str, ...] = ("result", "error", "unclean", "panic", "bad_result", "degenerate_h")
OUTCOMES += ("corrupt_accepted",)
OUTCOMES += ("wrong_answer", "silent_loss", "hang")


def judge(case: Case) -> tuple[str, str]:
    """(outcome, detail) of one call; see the module's docstring."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = case.fn(*case.args, **case.kwargs)
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as e:
        name = type(e).__name__
        if name == "PanicException":
            return "panic", f"{name}: {e}"[:300]
        if isinstance(e, pc.Error) and str(e).strip():
            if case.note.endswith("file") and not isinstance(
                e, pc.CalibrationFileError | pc.IntrinsicsError
            ):
                return "unclean", f"{name} (not the file error): {e}"[:300]
            if not isinstance(e, case.also):
                wanted = " or ".join(t.__name__ for t in case.also)
                return "unclean", f"{name} (not a {wanted}): {e}"[:300]
            return "error", name
        return "unclean", f"{type(e).__module__}.{name}: {e}"[:300]
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        problem = case.check(out)
    if problem is None:
        return "result", ""
    if problem.startswith("degenerate"):
        return "degenerate_h", problem
    if problem.startswith("corrupt"):
        return "corrupt_accepted", problem
    for outcome in ("wrong_answer", "silent_loss", "hang", "unclean"):
        if problem.startswith(outcome.replace("_", " ")):
            return outcome, problem
    return "bad_result", problem


@dataclasses.dataclass
class Tally:
    """Counts of one entry point's outcomes, with the first few findings' indices."""

    inputs: int = 0
    outcomes: Counter[str] = dataclasses.field(default_factory=Counter)
    error_types: Counter[str] = dataclasses.field(default_factory=Counter)
    unclean_types: Counter[str] = dataclasses.field(default_factory=Counter)
    findings: list[tuple[int, str, str]] = dataclasses.field(default_factory=list)

    def add(self, index: int, outcome: str, detail: str, keep: int = 20) -> None:
        self.inputs += 1
        self.outcomes[outcome] += 1
        if outcome == "error":
            self.error_types[detail] += 1
        elif outcome != "result":
            kind = detail.split(":", 1)[0] if outcome == "unclean" else outcome
            self.unclean_types[kind] += outcome == "unclean"
            if len(self.findings) < keep:
                self.findings.append((index, outcome, detail))

    def merge(self, other: Tally, keep: int = 20) -> None:
        self.inputs += other.inputs
        self.outcomes.update(other.outcomes)
        self.error_types.update(other.error_types)
        self.unclean_types.update(+other.unclean_types)
        self.findings.extend(other.findings[: max(0, keep - len(self.findings))])


def run(entry: str, seed: int, start: int, stop: int) -> Tally:
    tally = Tally()
    for index, case in cases(entry, seed, start, stop):
        tally.add(index, *judge(case))
    return tally
