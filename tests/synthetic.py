"""Synthetic homography problems with known truth, shared by the test modules."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from hypothesis import strategies as st
from numpy.typing import NDArray

F64 = NDArray[np.float64]

# PLANARCAL_EXAMPLES_SCALE=20 runs every property test with 20 times its examples.
EXAMPLES_SCALE = float(os.environ.get("PLANARCAL_EXAMPLES_SCALE", "1"))


def examples(n: int) -> int:
    """Hypothesis examples for a property test, scaled by PLANARCAL_EXAMPLES_SCALE."""
    return max(1, round(n * EXAMPLES_SCALE))


def project(h: F64, points: F64) -> F64:
    """Points through H, plain NumPy, no checks."""
    v = np.c_[points, np.ones(len(points))] @ h.T
    return np.asarray(v[:, :2] / v[:, 2:], dtype=np.float64)


def unit_homography(rng: np.random.Generator) -> F64:
    """Rotation, anisotropic scale, shear and perspective acting on the unit square, with w
    kept within [0.4, 1.6] over it: a well-conditioned view."""
    a = rng.uniform(-np.pi, np.pi)
    sx, sy = rng.uniform(0.5, 2.0, 2)
    rot = np.array(
        [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1.0]], dtype=np.float64
    )
    h = rot @ np.array([[sx, rng.uniform(-0.3, 0.3), 0], [0, sy, 0], [0, 0, 1.0]], dtype=np.float64)
    h[0, 2], h[1, 2] = rng.uniform(-0.5, 0.5, 2)
    h[2, 0], h[2, 1] = rng.uniform(-0.3, 0.3, 2)
    return h


def frame(spread: float, offset: float) -> F64:
    """Maps the unit square onto [offset, offset + spread]^2."""
    return np.array([[spread, 0, offset], [0, spread, offset], [0, 0, 1.0]])


def general_position(u: F64, min_twice_area: float = 0.02) -> bool:
    """No three of the first (up to) six points nearly collinear."""
    k = min(len(u), 6)
    for i in range(k):
        for j in range(i + 1, k):
            for m in range(j + 1, k):
                d1, d2 = u[j] - u[i], u[m] - u[i]
                if abs(d1[0] * d2[1] - d1[1] * d2[0]) <= min_twice_area:
                    return False
    return True


def unit_points(rng: np.random.Generator, n: int) -> F64:
    while True:
        u = rng.uniform(0.0, 1.0, (n, 2))
        if general_position(u):
            return u


class Problem:
    """src in one frame, dst in another, related exactly by `truth`."""

    def __init__(
        self,
        rng: np.random.Generator,
        n: int,
        src_frame: F64,
        dst_frame: F64,
    ) -> None:
        self.u = unit_points(rng, n)
        self.h0 = unit_homography(rng)
        self.src_frame, self.dst_frame = src_frame, dst_frame
        self.src = project(src_frame, self.u)
        self.dst = project(dst_frame, project(self.h0, self.u))
        self.truth = dst_frame @ self.h0 @ np.linalg.inv(src_frame)

    @property
    def dst_scale(self) -> float:
        """Size of destination coordinates (offset plus spread), for absolute tolerances."""
        return float(np.abs(self.dst).max())


def relative_h_error(a: F64, b: F64) -> float:
    """|| a/|a| - b/|b| ||_F with the signs aligned (kornia's convention)."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    return float(min(np.linalg.norm(a - b), np.linalg.norm(a + b)))


def identical(a: Any, b: Any) -> bool:
    """Same answer: equal arrays of the same dtype and shape (NaN equal to NaN), recursively."""
    if a is None or b is None:
        return a is None and b is None
    if isinstance(a, tuple):
        return isinstance(b, tuple) and len(a) == len(b) and all(map(identical, a, b))
    if isinstance(a, np.ndarray):
        return (
            isinstance(b, np.ndarray)
            and a.dtype == b.dtype
            and a.shape == b.shape
            and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
        )
    return bool(a == b)


# OpenCV's robust findHomography flags, by name (the reference list, independent of planarcal).
OPENCV_ROBUST_METHODS = (
    "LMEDS",
    "RANSAC",
    "RHO",
    "USAC_DEFAULT",
    "USAC_PARALLEL",
    "USAC_FM_8PTS",
    "USAC_FAST",
    "USAC_ACCURATE",
    "USAC_PROSAC",
    "USAC_MAGSAC",
)


point_counts = st.one_of(
    st.integers(4, 20), st.integers(21, 500), st.sampled_from([1_000, 5_000, 10_000])
)
log_spreads = st.floats(-3.0, 5.0)
offset_ratios = st.floats(-100.0, 100.0)
seeds = st.integers(0, 2**32 - 1)


@st.composite
def exact_problems(draw: st.DrawFn) -> Problem:
    """Noise-free problems: 4 to 10,000 points, spreads 1e-3 to 1e5, offsets up to 100 times
    the spread, independently in each image."""
    rng = np.random.default_rng(draw(seeds))
    n = draw(point_counts)
    s, d = 10 ** draw(log_spreads), 10 ** draw(log_spreads)
    src_frame = frame(s, draw(offset_ratios) * s)
    dst_frame = frame(d, draw(offset_ratios) * d)
    return Problem(rng, n, src_frame, dst_frame)
