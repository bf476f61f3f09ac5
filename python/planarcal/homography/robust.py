"""Robust estimation: a homography from correspondences of which many may be wrong.

The search (in the Rust core) is USAC-style MSAC: minimal 4-point samples (PROSAC order when
quality scores are given, or when outliers dominate and neighbourhood consistency can rank
the matches), cheap sample checks, SPRT early rejection, local optimisation of every new best
model and termination adapted to the confidence. The best model is refitted to its inliers
(normalised DLT, then Levenberg-Marquardt) and the inlier mask recomputed from the final H,
so the two always agree. ``method="lmeds"`` is least median of squares instead: no
threshold, at most 50% outliers.

Deterministic: the same inputs and ``seed`` give bit-identical results on every run and any
number of threads.
"""

from __future__ import annotations

import operator
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Literal, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import _core
from planarcal.errors import ArgumentError

RobustMethod = Literal["msac", "lmeds"]
"""``"msac"``: thresholded (truncated-quadratic) scoring; ``"lmeds"``: least median."""

StopReason = Literal["converged", "max_iterations", "no_consensus"]
"""Why the search stopped: the confidence was reached; ``max_iters`` iterations were run
first (the result may still be right, but is not certified); no model had more support than
chance gives (``H`` is None)."""


@dataclass(frozen=True, eq=False)
class RobustResult:
    """The outcome of a robust fit.

    ``H`` is None when no homography was found (``stop_reason == "no_consensus"``), for
    example when every correspondence is an outlier; check ``success`` (or ``H is None``)
    before using it.
    """

    H: NDArray[np.float64] | None
    """dst ~ H src (3 x 3, oriented, H[2, 2] = 1 as estimate_homography returns it)."""
    inliers: NDArray[np.bool_]
    """(N,) bool: within ``threshold`` of the final H (all False without one)."""
    n_inliers: int
    iterations: int
    """Iterations: minimal samples that passed the sample checks (OpenCV's count)."""
    stop_reason: StopReason
    rms_inlier_error: float
    """RMS transfer error of the inliers under H, in destination units (NaN without H)."""
    threshold: float
    """The inlier threshold of the mask (LMedS derives it from the median residual)."""
    local_optimizations: int
    """New best models that were locally optimised."""

    @property
    def success(self) -> bool:
        """Whether a homography was found."""
        return self.H is not None

    @property
    def inlier_ratio(self) -> float:
        return self.n_inliers / len(self.inliers) if len(self.inliers) else 0.0

    def __repr__(self) -> str:
        return (
            f"RobustResult(success={self.success}, n_inliers={self.n_inliers} of "
            f"{len(self.inliers)}, iterations={self.iterations}, "
            f"stop_reason={self.stop_reason!r}, rms_inlier_error={self.rms_inlier_error:.4g}, "
            f"threshold={self.threshold:.4g})"
        )


def _result(raw: tuple[Any, ...]) -> RobustResult:
    H, inliers, n_inliers, iterations, stop, rms, threshold, lo_runs = raw
    return RobustResult(
        H=H,
        inliers=inliers,
        n_inliers=n_inliers,
        iterations=iterations,
        stop_reason=cast(StopReason, stop),
        rms_inlier_error=rms,
        threshold=threshold,
        local_optimizations=lo_runs,
    )


def _integer(value: object, name: str) -> int:
    """An integer argument (Python or NumPy), else an ArgumentError naming it."""
    if isinstance(value, bool):
        raise ArgumentError(f"{name} must be an integer, got {value!r}")
    try:
        return operator.index(value)  # type: ignore[arg-type]
    except TypeError:
        raise ArgumentError(f"{name} must be an integer, got {value!r}") from None


def _real(value: object, name: str) -> float:
    """A real-number argument, else an ArgumentError naming it."""
    if isinstance(value, (bool, str, bytes)):
        raise ArgumentError(f"{name} must be a number, got {value!r}")
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ArgumentError(f"{name} must be a number, got {value!r}") from None


def check_robust_options(
    threshold: object, confidence: object, max_iters: object, seed: object, method: object
) -> tuple[float, float, int, int, str]:
    """The options as the core takes them, or an ArgumentError naming the bad one."""
    if method not in ("msac", "lmeds"):
        raise ArgumentError(f'method must be "msac" or "lmeds", got {method!r}')
    t = _real(threshold, "threshold")
    if method == "msac" and not (np.isfinite(t) and t > 0):
        raise ArgumentError(
            f"threshold must be a positive, finite distance (destination units), got {t!r}"
        )
    c = _real(confidence, "confidence")
    if not 0 < c < 1:
        raise ArgumentError(f"confidence must be strictly between 0 and 1, got {c!r}")
    k = _integer(max_iters, "max_iters")
    if k <= 0:
        raise ArgumentError(f"max_iters must be at least 1, got {k}")
    s = _integer(seed, "seed")
    if not 0 <= s < 2**64:
        raise ArgumentError(f"seed must be an integer in [0, 2**64), got {s}")
    return t, c, min(k, 2**62), s, str(method)


def estimate_homography_robust(
    src: ArrayLike,
    dst: ArrayLike,
    threshold: float = 3.0,
    confidence: float = 0.999,
    max_iters: int = 10_000,
    seed: int = 0,
    scores: ArrayLike | None = None,
    method: RobustMethod = "msac",
) -> RobustResult:
    """Fit H with dst ~ H src despite outliers; returns a ``RobustResult``.

    ``threshold`` is the largest transfer error of an inlier in destination units (pixels
    for an image); ``confidence`` the probability, when the search stops, that it has drawn
    an all-inlier sample; ``max_iters`` caps the iterations (minimal samples that pass the
    sample checks, as OpenCV counts them). ``scores`` (one number per
    correspondence, higher is better, e.g. a descriptor match's ratio-test margin) make the
    search sample the best correspondences first (PROSAC). ``method="lmeds"`` minimises the
    median squared residual and ignores ``threshold``.

    A problem in which no model has more support than chance returns a result with
    ``H=None`` and ``stop_reason="no_consensus"``. Bad input raises ``ArgumentError`` (a
    ``ValueError``) naming it: shapes, NaN (``index`` and ``point_set`` name the point),
    threshold <= 0, confidence outside (0, 1), max_iters < 1; fewer than 4 points raise
    ``HomographyError``.
    """
    t, c, k, s, m = check_robust_options(threshold, confidence, max_iters, seed, method)
    return _result(_core.estimate_homography_robust(src, dst, t, c, k, s, scores, m))


def estimate_homography_robust_batch(
    problems: Iterable[tuple[ArrayLike, ArrayLike]],
    threshold: float = 3.0,
    confidence: float = 0.999,
    max_iters: int = 10_000,
    seed: int = 0,
    method: RobustMethod = "msac",
) -> list[RobustResult]:
    """Robust fits of many independent problems, ``[(src, dst), ...]``, in one call.

    The problems run in parallel on all cores with the GIL released, each with the given
    options and ``seed``; result ``i`` is identical to ``estimate_homography_robust`` on
    problem ``i``. A problem that fails raises what ``estimate_homography_robust`` would, its
    message naming the problem's index.
    """
    t, c, k, s, m = check_robust_options(threshold, confidence, max_iters, seed, method)
    pairs: Sequence[tuple[ArrayLike, ArrayLike]] = list(problems)
    return [_result(r) for r in _core.estimate_homography_robust_batch(pairs, t, c, k, s, m)]
