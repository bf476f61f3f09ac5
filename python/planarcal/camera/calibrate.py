"""Camera intrinsics from several views of a flat board (Zhang's method, as
cv2.calibrateCamera), refused when the views leave the focal length undetermined or the fitted
distortion folds over inside the image.

The steps: detect the board in each view, fit with OpenCV, check how well the views pin the
focal length down (OpenCV's covariance and a profile of the fit), and check that the fitted
model can be inverted over the whole image.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.calib.boards import BOARD_TYPES, Board, is_board
from planarcal.calib.detection import BoardDetection, detect_board
from planarcal.calib.detector_options import detector_options
from planarcal.camera.intrinsics import CameraIntrinsics
from planarcal.camera.opencv_errors import last_line
from planarcal.errors import BoardNotFoundError, ImageError, IntrinsicsError
from planarcal.progress import progress

__all__ = ["MAX_FOCAL_REL_STD", "calibrate_camera"]

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]

MIN_VIEW_POINTS = 6
"""The fewest board points a view may give: 4 fix its homography, and a view's pose and its
share of the intrinsics need more (a partial view of fewer adds no information, only
risk)."""

MAX_FOCAL_REL_STD = 0.01
"""calibrate_camera refuses a result whose focal length is this uncertain (1 sigma, relative to
the focal length; the larger of OpenCV's covariance estimate and a profile of the fit): it
means the views do not determine it (too little tilt), and a focal length off by percents
puts every height off by about as much."""


def calibrate_camera(
    views: Sequence[Any],
    board: Board,
    *,
    fix_aspect_ratio: bool = False,
    zero_tangent: bool = False,
    rational: bool = False,
) -> CameraIntrinsics:
    """Estimate a camera's intrinsics from several views of a flat board (Zhang's method, as
    cv2.calibrateCamera).

    ``views``: images (arrays or paths) or BoardDetection objects (of ``board``: a circle
    grid, chessboard or ChArUco board), all of one image size; each image is searched with
    detect_board. A view may show part of the board (a detection's ``ids``: each view's
    points are those it found, MIN_VIEW_POINTS at least), which also lets views reach the
    image's corners, where the distortion is otherwise unknown. ``fix_aspect_ratio`` fixes fx = fy
    (square pixels), ``zero_tangent`` fixes p1 = p2 = 0, ``rational`` fits OpenCV's rational
    model (8 coefficients instead of 5).

    The focal length is determined by perspective: by how the board's image converges when
    the board is tilted. At least 3 views are needed, tilted by 20-40 degrees about different
    axes, and spread over the image (the distortion is only known where the board has been).
    Raises IntrinsicsError for fewer than 3 views, views of different sizes, views that leave
    the focal length undetermined (all nearly facing the camera: its 1-sigma uncertainty
    exceeds MAX_FOCAL_REL_STD), or a fitted distortion that folds over inside the image;
    BoardNotFoundError (ImageError) naming the view whose board was not found (which could
    not be read).

    The result carries the overall RMS reprojection error (``rms_px``), each view's
    (``per_view_rms_px``) and ``n_views``.
    """
    detections = _detect_views(_checked_views(views, board), board)
    points = _ViewPoints.of(board, detections)
    flags = _calibration_flags(fix_aspect_ratio, zero_tangent, rational)
    fit = _fit(points, flags, rational)
    _check_focal_length_determined(fit, points, flags, rational)
    return _intrinsics(fit, points, rational)


# ------------------------------------------------------------------------------------------
# The views


def _checked_views(views: Sequence[Any], board: Board) -> list[Any]:
    """The views as a list, or IntrinsicsError for a single view, another kind of board, or
    too few views."""
    if isinstance(views, str | os.PathLike | np.ndarray | BoardDetection):
        raise IntrinsicsError(
            "views must be a list of images, paths or board detections (one per view), got a "
            f"single {type(views).__name__}"
        )
    if not is_board(board):
        raise IntrinsicsError(
            f"board must be one of planarcal's boards ({', '.join(BOARD_TYPES)}), got "
            f"{type(board).__name__}"
        )
    views = list(views)
    if len(views) < 3:
        raise IntrinsicsError(
            f"camera calibration needs at least 3 views of the board, got {len(views)}: "
            "take 6-10, tilted 20-40 degrees about different axes and spread over the image"
        )
    return views


def _detect_views(views: list[Any], board: Board) -> list[BoardDetection]:
    """The board's detection in each view, all of one image size."""
    detections: list[BoardDetection] = []
    for i, view in enumerate(progress(views, desc="Finding the board", unit="view")):
        det = _detection(view, i, board)
        if detections and det.image_size != detections[0].image_size:
            w0, h0 = detections[0].image_size
            w, h = det.image_size
            raise IntrinsicsError(
                f"{_view_name(view, i)} is {w} x {h} px but view 0 is {w0} x {h0} px: all views "
                "must come from the same camera at the same resolution"
            )
        if len(det.ids) < MIN_VIEW_POINTS:
            raise IntrinsicsError(
                f"{_view_name(view, i)} shows {len(det.ids)} {board.point_name}s of the board: "
                f"a view needs at least {MIN_VIEW_POINTS}; leave it out or take it again with "
                "more of the board in view"
            )
        detections.append(det)
    return detections


def _detection(view: Any, index: int, board: Board) -> BoardDetection:
    """The view itself if it is a detection of ``board``, else detect_board's in it; errors
    name the view."""
    if isinstance(view, BoardDetection):
        if view.board != board:
            raise IntrinsicsError(
                f"{_view_name(view, index)} is a detection of another board ({view.board}), "
                f"not {board}"
            )
        return view
    try:
        # Each view has its own pose: a board turned in one of them is no mistake (where the
        # board's detector would otherwise refuse it).
        turned = {"turned": True} if "turned" in detector_options(board.kind) else {}
        return detect_board(view, board, **turned)
    except BoardNotFoundError as e:
        raise BoardNotFoundError(f"{_view_name(view, index)}: {e}", e.diagnostics) from None
    except ImageError as e:
        raise ImageError(f"{_view_name(view, index)}: {e}") from None


def _view_name(view: Any, index: int) -> str:
    if isinstance(view, str | os.PathLike):
        return f"view {index} ({str(Path(view))!r})"
    return f"view {index}"


@dataclasses.dataclass(frozen=True)
class _ViewPoints:
    """What cv2.calibrateCamera takes: each view's board points (mm, Z = 0) and image points
    (px), and the image size (width, height)."""

    object_points: list[F32]
    image_points: list[F32]
    size: tuple[int, int]

    @classmethod
    def of(cls, board: Board, detections: list[BoardDetection]) -> _ViewPoints:
        # calibrateCamera takes float32 points only (Point3f / Point2f): 6e-5 px of rounding
        # at 1280 px, far below any detection's noise. Each view's own points: those it found.
        object_points = []
        for d in detections:
            world = board.world_points()[d.ids]
            object_points.append(
                np.column_stack([world, np.zeros(len(world))]).reshape(-1, 1, 3).astype(np.float32)
            )
        image_points = [d.image_points.reshape(-1, 1, 2).astype(np.float32) for d in detections]
        return cls(object_points, image_points, detections[0].image_size)

    @property
    def n_views(self) -> int:
        return len(self.image_points)


# ------------------------------------------------------------------------------------------
# The fit


def _calibration_flags(fix_aspect_ratio: bool, zero_tangent: bool, rational: bool) -> int:
    """cv2.calibrateCamera's flags for calibrate_camera's options."""
    flags = 0
    if fix_aspect_ratio:
        flags |= cv2.CALIB_FIX_ASPECT_RATIO
    if zero_tangent:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    if rational:
        flags |= cv2.CALIB_RATIONAL_MODEL
    return flags


@dataclasses.dataclass(frozen=True)
class _Fit:
    """cv2.calibrateCameraExtended's result: the RMS reprojection error (px), K, the
    distortion vector, the intrinsics' standard deviations (fx, fy, cx, cy, then the
    distortion's) and each view's RMS."""

    rms: float
    matrix: F64
    dist: F64
    std: F64
    per_view_rms: F64


def _fit(points: _ViewPoints, flags: int, rational: bool) -> _Fit:
    """cv2.calibrateCameraExtended on the views; IntrinsicsError if it fails or gives
    anything not finite (degenerate views)."""
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    try:
        result = cv2.calibrateCameraExtended(
            points.object_points,
            points.image_points,
            points.size,
            np.eye(3),  # only its aspect ratio (1) is used, with CALIB_FIX_ASPECT_RATIO
            np.zeros(8 if rational else 5),
            flags=flags,
            criteria=criteria,
        )
    except cv2.error as e:
        raise IntrinsicsError(
            f"cv2.calibrateCamera failed on the {points.n_views} views ({last_line(e)}): the "
            "views are probably degenerate; tilt the board 20-40 degrees about different axes"
        ) from None
    rms, k, dist, _rvecs, _tvecs, std_intrinsics, _std_extrinsics, per_view = result
    fit = _Fit(
        rms=float(rms),
        matrix=np.asarray(k, dtype=np.float64),
        dist=np.asarray(dist, dtype=np.float64).reshape(-1),
        std=np.asarray(std_intrinsics, dtype=np.float64).reshape(-1),
        per_view_rms=np.asarray(per_view, dtype=np.float64).reshape(-1),
    )
    if not (
        np.isfinite(fit.matrix).all() and np.isfinite(fit.dist).all() and math.isfinite(fit.rms)
    ):
        raise IntrinsicsError(
            "cv2.calibrateCamera gave no finite result: the views are degenerate; tilt the "
            "board 20-40 degrees about different axes"
        )
    return fit


# ------------------------------------------------------------------------------------------
# The checks of the result


def _check_focal_length_determined(
    fit: _Fit, points: _ViewPoints, flags: int, rational: bool
) -> None:
    """IntrinsicsError unless the views pin the focal length down to MAX_FOCAL_REL_STD.

    Measured two ways: OpenCV's covariance (per axis) and a profile of the fit (see
    _focal_profile_rel_std), which exact degeneracies cannot hide from: OpenCV pseudo-inverts
    a singular normal matrix, so views that face the camera squarely give an arbitrary focal
    length with a tiny "standard deviation"."""
    k_est, std = fit.matrix, fit.std
    n_params = 4 + (8 if rational else 5) + 6 * points.n_views
    rel_std = [
        float(std[0] / k_est[0, 0]) if k_est[0, 0] > 0 else math.inf,
        float(std[1] / k_est[1, 1]) if k_est[1, 1] > 0 else math.inf,
        _focal_profile_rel_std(
            points.object_points,
            points.image_points,
            points.size,
            k_est,
            fit.dist,
            flags,
            fit.rms,
            n_params,
        ),
    ]
    worst = max(v if math.isfinite(v) else math.inf for v in rel_std)
    if worst <= MAX_FOCAL_REL_STD:
        return
    shown = "unbounded" if not math.isfinite(worst) else f"+- {100 * worst:.2g} %"
    rational_note = (
        " The rational model's extra terms can also stand in for a focal length (with k1 "
        "and k4 both large its radial factor is nearly a constant scale): unless the views "
        "cover the whole image, calibrate without rational=True."
        if rational
        else ""
    )
    raise IntrinsicsError(
        f"the views do not determine the focal length (fx = {k_est[0, 0]:.1f} px, "
        f"{shown}; at most {100 * MAX_FOCAL_REL_STD:g} % is accepted): the views need more "
        "tilt. Only perspective (a board whose image converges) measures the focal "
        "length: tilt the board 20-40 degrees, about different axes, in several views."
        + rational_note
    )


def _intrinsics(fit: _Fit, points: _ViewPoints, rational: bool) -> CameraIntrinsics:
    """The fit as CameraIntrinsics, or IntrinsicsError if its distortion folds over inside
    the image."""
    # OpenCV returns the coefficients it estimated (5, or 8 with the rational model; 14 if it
    # ever widens them): trim to the length it was asked for.
    n = 8 if rational else 5
    dist_est = fit.dist
    if dist_est.size < n:
        dist_est = np.pad(dist_est, (0, n - dist_est.size))
    intrinsics = CameraIntrinsics(
        matrix=_clean_matrix(fit.matrix),
        dist_coeffs=dist_est[:n],
        image_size=points.size,
        rms_px=fit.rms,
        n_views=points.n_views,
        per_view_rms_px=tuple(float(v) for v in fit.per_view_rms),
    )
    try:
        intrinsics.check_invertible_over_image()
    except IntrinsicsError as e:
        raise IntrinsicsError(
            f"{e}. The fitted distortion folds over inside the image: add views with the "
            "board near the image's corners and edges, or fit fewer terms (zero_tangent=True, "
            "no rational model)"
        ) from None
    return intrinsics


def _focal_profile_rel_std(
    object_points: list[Any],
    image_points: list[Any],
    size: tuple[int, int],
    k: F64,
    dist: F64,
    flags: int,
    rms: float,
    n_params: int,
) -> float:
    """The focal length's relative 1-sigma uncertainty from the fit's profile: the
    calibration is redone with the focal length held 5 % too short and 5 % too long (all else
    refitted) and the rise of the sum of squared residuals, in units of the residual variance,
    is Delta chi^2 = (0.05 / sigma_rel)^2 for a well-determined focal length. Views that
    cannot tell focal lengths apart refit as well at either (Delta chi^2 ~ 0: infinite). The
    refits start from the distortion rescaled along the exact degeneracy of a fronto-parallel
    board (k_i by s^2i, p_i by s), so they find it where it exists."""
    n_obs = 2 * sum(len(p) for p in image_points)
    sse = rms * rms * n_obs
    sigma2 = sse / max(n_obs - n_params, 1)
    if not sigma2 > 0:
        return 0.0  # a perfect fit: nothing to measure the uncertainty by (synthetic data)
    delta = 0.05
    rises = []
    for s in (1.0 - delta, 1.0 + delta):
        k0 = np.array(k, dtype=np.float64)
        k0[0, 0] *= s
        k0[1, 1] *= s
        d0 = np.array(dist, dtype=np.float64)
        powers = np.array([2, 4, 1, 1, 6, 2, 4, 6][: d0.size], dtype=np.float64)
        d0[: powers.size] *= s**powers
        try:
            refit = cv2.calibrateCamera(
                object_points,
                image_points,
                size,
                k0,
                d0,
                flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_FOCAL_LENGTH,
                criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-15),
            )
        except cv2.error:
            return math.inf
        rms_fixed = float(refit[0])
        if not math.isfinite(rms_fixed):
            return math.inf
        rises.append((rms_fixed * rms_fixed * n_obs - sse) / sigma2)
    rise = min(rises)
    return delta / math.sqrt(rise) if rise > 0 else math.inf


def _clean_matrix(k: F64) -> F64:
    """calibrateCamera's K with its structural zeros and one exactly so (they are, up to the
    last bit of its arithmetic)."""
    out = np.array(k, dtype=np.float64)
    out[1, 0] = out[2, 0] = out[2, 1] = 0.0
    out[2, 2] = 1.0
    return out
