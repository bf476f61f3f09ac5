# Stubs of the compiled module planarcal._core (checked by python -m mypy.stubtest).
from collections.abc import Iterable, Sequence
from typing import Any, final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal.calib.lens_model import LensKind
from planarcal.homography.robust import RobustMethod, StopReason

__all__ = [
    "EDGE_SIGMA_PX",
    "MAX_ANGLE_SIGMA_DEG",
    "MIN_ANISOTROPY",
    "SAMPLES_PER_PART",
    "FittedPlane",
    "LensStd",
    "RadialLens",
    "RobustResult",
    "Tracks",
    "__version__",
    "_after_fork_in_child",
    "area_centroids",
    "error_stats",
    "estimate_homography",
    "estimate_homography_robust",
    "estimate_homography_robust_batch",
    "find_homography",
    "find_homography_robust",
    "frame_json",
    "local_maps",
    "measure_contours",
    "median_grey",
    "part_axes",
    "part_poses",
    "part_samples",
    "perspective_transform",
    "reading_order",
    "refine_dot_centres",
    "reprojection_errors",
    "transform_points",
]
__version__: str
SAMPLES_PER_PART: int
MIN_ANISOTROPY: float
EDGE_SIGMA_PX: float
MAX_ANGLE_SIGMA_DEG: float

# The exceptions the bindings raise are planarcal.errors' classes (pyo3::import_exception!),
# and MemoryError when a buffer that grows with the input cannot be allocated.

@final
class RadialLens:
    def __new__(
        cls, centre_px: tuple[float, float], scale_px: float, k1: float = 0.0, k2: float = 0.0
    ) -> RadialLens: ...
    @classmethod
    def identity(cls, width: float, height: float) -> RadialLens: ...
    @property
    def centre_px(self) -> tuple[float, float]: ...
    @property
    def scale_px(self) -> float: ...
    @property
    def k1(self) -> float: ...
    @property
    def k2(self) -> float: ...
    @property
    def fold_radius(self) -> float: ...
    @property
    def valid_radius(self) -> float: ...
    def distort(self, ideal_px: ArrayLike) -> NDArray[np.float64]: ...
    def undistort(self, px: ArrayLike, invalid: str = "raise") -> NDArray[np.float64]: ...
    def __eq__(self, value: object, /) -> bool: ...
    def __reduce__(self) -> tuple[type[RadialLens], tuple[Any, ...]]: ...

@final
class LensStd:
    def __new__(cls, k1: float, k2: float, centre_px: tuple[float, float]) -> LensStd: ...
    @property
    def k1(self) -> float: ...
    @property
    def k2(self) -> float: ...
    @property
    def centre_px(self) -> tuple[float, float]: ...
    def __eq__(self, value: object, /) -> bool: ...
    def __reduce__(self) -> tuple[type[LensStd], tuple[Any, ...]]: ...

@final
class FittedPlane:
    @staticmethod
    def fit(
        world: ArrayLike, image: ArrayLike, lens: LensKind, image_size: tuple[float, float]
    ) -> FittedPlane: ...
    @staticmethod
    def at(
        h: ArrayLike,
        lens: RadialLens,
        world: ArrayLike,
        image: ArrayLike,
        free: LensKind,
        image_size: tuple[float, float],
    ) -> FittedPlane: ...
    @staticmethod
    def fit_placements(
        board: ArrayLike,
        image: ArrayLike,
        placement: Sequence[int],
        reference: int,
        start: Sequence[tuple[float, float, float]],
        lens: LensKind,
        image_size: tuple[float, float],
    ) -> tuple[FittedPlane, NDArray[np.float64], NDArray[np.float64]]: ...
    @staticmethod
    def at_placements(
        h: ArrayLike,
        lens: RadialLens,
        board: ArrayLike,
        image: ArrayLike,
        placement: Sequence[int],
        reference: int,
        poses: Sequence[tuple[float, float, float]],
        free: LensKind,
        image_size: tuple[float, float],
    ) -> tuple[FittedPlane, NDArray[np.float64], NDArray[np.float64]]: ...
    @property
    def homography(self) -> NDArray[np.float64]: ...
    @property
    def lens(self) -> RadialLens: ...
    @property
    def lens_params(self) -> str: ...
    @property
    def lens_inverse(self) -> str: ...
    @property
    def lens_std(self) -> LensStd: ...
    @property
    def cost(self) -> float: ...
    @property
    def dof(self) -> int: ...
    @property
    def sigma(self) -> float: ...
    @property
    def iterations(self) -> int: ...
    def with_model_sigma(self, sigma_px: float) -> FittedPlane: ...
    @property
    def model_sigma_px(self) -> float: ...
    def image_to_world(self, px: ArrayLike, invalid: str = "raise") -> NDArray[np.float64]: ...
    def world_to_image(self, mm: ArrayLike) -> NDArray[np.float64]: ...
    def world_covariance(self, px: ArrayLike, pixel_sigma: float = 0.0) -> NDArray[np.float64]: ...
    def image_to_world_std(
        self, px: ArrayLike, pixel_sigma: float = 0.0
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...
    def leave_one_out(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...
    def predicted_loo_covariance(self) -> NDArray[np.float64]: ...

def estimate_homography(
    src: ArrayLike, dst: ArrayLike, solver: str, refine: bool
) -> NDArray[np.float64]: ...
def find_homography(
    src: ArrayLike, dst: ArrayLike
) -> tuple[NDArray[np.float64] | None, NDArray[np.uint8]]: ...

# Defined here, re-exported as planarcal.RobustResult (its __module__ says so).
@final
class RobustResult:
    def __new__(
        cls,
        H: NDArray[np.float64] | None,
        inliers: NDArray[np.bool_],
        n_inliers: int,
        iterations: int,
        stop_reason: StopReason,
        rms_inlier_error: float,
        threshold: float,
        local_optimizations: int,
        poorly_constrained: bool = False,
    ) -> RobustResult: ...
    @property
    def H(self) -> NDArray[np.float64] | None: ...
    @property
    def inliers(self) -> NDArray[np.bool_]: ...
    @property
    def n_inliers(self) -> int: ...
    @property
    def iterations(self) -> int: ...
    @property
    def stop_reason(self) -> StopReason: ...
    @property
    def rms_inlier_error(self) -> float: ...
    @property
    def threshold(self) -> float: ...
    @property
    def local_optimizations(self) -> int: ...
    @property
    def poorly_constrained(self) -> bool: ...
    @property
    def success(self) -> bool: ...
    @property
    def inlier_ratio(self) -> float: ...
    def __reduce__(self) -> tuple[type[RobustResult], tuple[Any, ...]]: ...

def estimate_homography_robust(
    src: ArrayLike,
    dst: ArrayLike,
    threshold: float,
    confidence: float,
    max_iters: int,
    seed: int,
    scores: ArrayLike | None,
    method: RobustMethod,
) -> RobustResult: ...
def estimate_homography_robust_batch(
    problems: Iterable[tuple[ArrayLike, ArrayLike]],
    threshold: float,
    confidence: float,
    max_iters: int,
    seed: int,
    method: RobustMethod,
) -> list[RobustResult]: ...
def find_homography_robust(
    src: ArrayLike,
    dst: ArrayLike,
    method: RobustMethod,
    threshold: float,
    max_iters: int,
    confidence: float,
    ordered: bool,
) -> tuple[NDArray[np.float64] | None, NDArray[np.uint8]]: ...
def transform_points(
    h: ArrayLike, points: ArrayLike, inverse: bool, invalid: str
) -> NDArray[np.float64]: ...
def perspective_transform(src: ArrayLike, m: ArrayLike) -> NDArray[Any] | None: ...
def reprojection_errors(
    h: ArrayLike, src: ArrayLike, dst: ArrayLike, invalid: str
) -> NDArray[np.float64]: ...
def error_stats(errors: ArrayLike) -> tuple[int, float, float, float, float, int, int]: ...
def _after_fork_in_child() -> None: ...
def measure_contours(
    grey: ArrayLike,
    contours: Sequence[Any],
    min_area: float,
    max_area: float,
    keep_border: bool = False,
    subpixel: bool = True,
    outlines: bool = True,
) -> tuple[
    NDArray[np.int64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.int64],
    list[NDArray[np.float64]],
    NDArray[np.float64],
]: ...
def frame_json(
    index: int,
    timestamp: float,
    ids: NDArray[np.int64],
    centroids_px: ArrayLike,
    world_mm: ArrayLike,
    std_mm: ArrayLike,
    angles_deg: ArrayLike,
    coords: str,
) -> str: ...
def median_grey(grey: ArrayLike, row_step: int = 16, col_step: int = 2) -> int: ...
def reading_order(centroids: ArrayLike, heights: ArrayLike) -> NDArray[np.int64]: ...
def part_samples(centroids_px: ArrayLike, step_px: float) -> NDArray[np.float64]: ...
def part_poses(
    samples_mm: ArrayLike, moments_px: ArrayLike, areas_px: ArrayLike, step_px: float
) -> tuple[
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
]: ...
def local_maps(
    samples_mm: ArrayLike, step_px: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]: ...
def area_centroids(
    positions: ArrayLike, jacobians: ArrayLike, hessians: ArrayLike, moments_px: ArrayLike
) -> NDArray[np.float64]: ...
def part_axes(
    moments_px: ArrayLike, areas_px: ArrayLike, jacobians: ArrayLike | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]: ...
def refine_dot_centres(
    ink_dark: ArrayLike, points: ArrayLike, diameters: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.uint8]]: ...

@final
class Tracks:
    def __new__(cls, max_jump: float, max_missing: int) -> Tracks: ...
    def update(self, positions: ArrayLike) -> NDArray[np.int64]: ...
    def live(self) -> tuple[NDArray[np.int64], NDArray[np.float64]]: ...
    def __len__(self) -> int: ...
