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
import dataclasses
import json
import math
import os
import shutil
import tempfile
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
            variant.board,
        )
    return _FIXTURES


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


FILE_ENTRIES: dict[str, Callable[[np.random.Generator], Case]] = {
    "detect_board": case_detect,
    "Calibration.load": case_calibration_load,
    "CameraIntrinsics.load_yaml": case_intrinsics_load,
    "locate_objects": case_locate,
    "Tracker.process": case_tracker,
}
ENTRIES = {**NUMERIC_ENTRIES, **FILE_ENTRIES}


def cases(entry: str, seed: int, start: int, stop: int) -> Iterator[tuple[int, Case]]:
    """Cases start..stop-1 of `entry`, each rebuilt identically whatever range asks for it."""
    make = ENTRIES[entry]
    block = start // BLOCK
    while block * BLOCK < stop:
        rng = block_rng(entry, seed, block)
        for index in range(block * BLOCK, (block + 1) * BLOCK):
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                case = make(rng)
            if start <= index < stop:
                yield index, case
        block += 1


def case_at(entry: str, seed: int, index: int) -> Case:
    return next(cases(entry, seed, index, index + 1))[1]


# -- the judge ---------------------------------------------------------------------------------

OUTCOMES = ("result", "error", "unclean", "panic", "bad_result", "degenerate_h", "corrupt_accepted")


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
