"""Robust estimation: a homography from correspondences of which many may be wrong.

The search (in the Rust core) is USAC-style MSAC: minimal 4-point samples (PROSAC order when
quality scores are given, or when outliers dominate and neighbourhood consistency can rank
the matches), cheap sample checks, SPRT early rejection, local optimisation of every new best
model and termination adapted to the confidence. The best model is refitted to its inliers
(normalised DLT, then Levenberg-Marquardt; then with a Cauchy kernel where their residuals
have a heavier tail than Gaussian noise, as real matches do) and the inlier mask recomputed
from the final H, so the two always agree. ``method="lmeds"`` is least median of squares instead: no
threshold, at most 50% outliers.

Deterministic: the same inputs and ``seed`` give bit-identical results on every run and any
number of threads.

These functions only document and type the compiled module's: it converts the options (an
``ArgumentError`` naming a bad one), the core checks their ranges, and ``RobustResult`` is
its frozen result class.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Literal

from numpy.typing import ArrayLike

from planarcal import _core
from planarcal._core import RobustResult

__all__ = [
    "RobustMethod",
    "RobustResult",
    "StopReason",
    "estimate_homography_robust",
    "estimate_homography_robust_batch",
]

RobustMethod = Literal["msac", "lmeds"]
"""``"msac"``: thresholded (truncated-quadratic) scoring; ``"lmeds"``: least median."""

StopReason = Literal["converged", "max_iterations", "no_consensus"]
"""Why the search stopped: the confidence was reached; ``max_iters`` iterations were run
first (the result may still be right, but is not certified); no model had more support than
chance gives (``H`` is None)."""


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
    median squared residual and ignores ``threshold``; the result's ``threshold`` is the one it
    derives from its inliers' scale.

    A problem in which no model has more support than chance returns a result with
    ``H=None`` and ``stop_reason="no_consensus"``. Bad input raises ``ArgumentError`` (a
    ``ValueError``) naming it: shapes, NaN (``index`` and ``point_set`` name the point),
    threshold <= 0, confidence outside (0, 1), max_iters outside [1, 10**7]; fewer than 4
    points raise ``HomographyError``, and a set no sample can fit (fewer than 4 distinct
    points, all on one line, or all but one) ``DegenerateError``, at once. The search runs
    with the GIL released and stops on Ctrl-C (``KeyboardInterrupt``).
    """
    return _core.estimate_homography_robust(
        src, dst, threshold, confidence, max_iters, seed, scores, method
    )


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
    return _core.estimate_homography_robust_batch(
        problems, threshold, confidence, max_iters, seed, method
    )
