# Stubs of the compiled module planarcal._core (checked by python -m mypy.stubtest).
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "DegenerateError",
    "HomographyError",
    "PointAtInfinityError",
    "__version__",
    "_after_fork_in_child",
    "error_stats",
    "estimate_homography",
    "estimate_homography_robust",
    "estimate_homography_robust_batch",
    "find_homography",
    "find_homography_robust",
    "perspective_transform",
    "reprojection_errors",
    "transform_points",
]
__version__: str

class HomographyError(ValueError): ...
class DegenerateError(HomographyError): ...
class PointAtInfinityError(HomographyError): ...

def estimate_homography(
    src: ArrayLike, dst: ArrayLike, solver: str = "normalized_dlt", refine: bool = False
) -> NDArray[np.float64]: ...
def find_homography(
    src: ArrayLike, dst: ArrayLike
) -> tuple[NDArray[np.float64] | None, NDArray[np.uint8]]: ...

_RobustTuple = tuple[
    NDArray[np.float64] | None, NDArray[np.bool_], int, int, str, float, float, int
]

def estimate_homography_robust(
    src: ArrayLike,
    dst: ArrayLike,
    threshold: float = 3.0,
    confidence: float = 0.999,
    max_iters: int = 10000,
    seed: int = 0,
    scores: ArrayLike | None = None,
    method: str = "msac",
) -> _RobustTuple: ...
def estimate_homography_robust_batch(
    problems: Any,
    threshold: float = 3.0,
    confidence: float = 0.999,
    max_iters: int = 10000,
    seed: int = 0,
    method: str = "msac",
) -> list[_RobustTuple]: ...
def find_homography_robust(
    src: ArrayLike,
    dst: ArrayLike,
    method: str,
    threshold: float,
    max_iters: int,
    confidence: float,
    ordered: bool,
) -> tuple[NDArray[np.float64] | None, NDArray[np.uint8]]: ...
def transform_points(
    h: ArrayLike, points: ArrayLike, inverse: bool = False, invalid: str = "raise"
) -> NDArray[np.float64]: ...
def perspective_transform(src: ArrayLike, m: ArrayLike) -> NDArray[Any] | None: ...
def reprojection_errors(
    h: ArrayLike, src: ArrayLike, dst: ArrayLike, invalid: str = "raise"
) -> NDArray[np.float64]: ...
def error_stats(errors: ArrayLike) -> tuple[int, float, float, float, float, int, int]: ...
def _after_fork_in_child() -> None: ...
