"""A plane calibration: the homography between the work plane (mm) and the image (px), with
everything the paper reports about it, and the honest accuracy estimate it does not.

H maps world millimetres to image pixels (the paper's Eq. 3); image -> world goes through
H^-1 (its Eq. 8). The default fit is the most accurate (the normalised DLT refined by
Levenberg-Marquardt: the maximum-likelihood estimate for pixel noise); ``solver="a33",
refine=False`` reproduces the paper's own estimator.

Beyond the paper:

* **Lens distortion from the one board image** (``lens=``): radial distortion (k1, k2, and
  optionally its centre) fitted jointly with H, so that H maps to *ideal* pixels and the
  lens maps those to the real ones. ``lens="auto"`` (the default when the image size is
  known) fits each model and keeps the one whose leave-one-out error is lowest, a richer
  model only when it earns its parameters; a board that covers too little of the image to
  determine distortion gets no lens model, and says so (``lens_note``).
* **Full intrinsics** (``intrinsics=``, a :class:`~planarcal.camera.intrinsics.CameraIntrinsics`
  from several board views or OpenCV's YAML): points are undistorted by OpenCV's model
  first. With intrinsics the camera's pose is known, so ``image_to_world(px, height=h)``
  maps the top of an object h mm tall to where it really is.
* **Uncertainty**: ``image_to_world(px, return_std=True)`` gives each point's 1-sigma error
  in mm from the fit's covariance.
* **Printer scale**: ``rescaled`` corrects the world frame by an independent measurement of
  the board's pitch (or its printed check bar), which no homography can see.
"""

from __future__ import annotations

import dataclasses
import datetime
import functools
import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import _core
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.detect import detect_board
from planarcal.camera import CameraIntrinsics, plane_pose, points_at_height
from planarcal.errors import (
    ArgumentError,
    BoardError,
    CalibrationFileError,
    FrameSizeError,
    HomographyError,
    IntrinsicsError,
    LensModelError,
)
from planarcal.files import atomic_write
from planarcal.homography import (
    SOLVERS,
    ReprojectionStats,
    Solver,
    error_stats,
    estimate_homography,
    reprojection_errors,
    transform_points,
)

F64 = NDArray[np.float64]

FILE_FORMAT = "planarcal-calibration"
FILE_VERSION = 2
READS_VERSIONS = (1, 2)

LensChoice = Literal["auto", "none", "k1", "k1k2", "k1k2c"]
LENS_MODELS = ("none", "k1", "k1k2", "k1k2c")
"""The lens models, simplest first: none (a homography alone), k1, k1 + k2, and k1 + k2 with
the distortion centre fitted too."""

# A richer lens model must lower the mean leave-one-out error by this fraction to be chosen.
LENS_MARGIN = 0.01
# The board must reach this fraction of the way from the image centre to its corners for the
# distortion to be determined at all (a small central board sees almost none of it).
MIN_LENS_COVERAGE = 0.35
# A fitted distortion centre farther than this (in half-diagonals) from the image centre is
# not a lens's: the model is fitting something else (a board that is not flat).
MAX_CENTRE_OFFSET = 0.2


@dataclasses.dataclass(frozen=True)
class LensModel:
    """The radial distortion a calibration found: an ideal pixel u is shown at
    d = c + (u - c) (1 + k1 rho^2 + k2 rho^4), rho = |u - c| / scale (OpenCV's two-term
    model with the half-diagonal as the unit instead of the focal length)."""

    model: str
    """Which parameters were fitted: "k1", "k1k2" or "k1k2c" (centre too)."""
    centre_px: tuple[float, float]
    scale_px: float
    k1: float
    k2: float
    k1_std: float
    k2_std: float
    centre_std_px: tuple[float, float]

    def displacement_px(self, ideal_px: ArrayLike) -> F64:
        """How far the lens moves each ideal pixel (N, 2), px: real minus ideal."""
        u = np.asarray(ideal_px, dtype=np.float64).reshape(-1, 2)
        q = (u - np.array(self.centre_px)) / self.scale_px
        rho2 = np.sum(q * q, axis=1, keepdims=True)
        out: F64 = q * self.scale_px * rho2 * (self.k1 + self.k2 * rho2)
        return out

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class LensCandidate:
    """One lens model tried by ``lens="auto"`` and what its leave-one-out error said."""

    model: str
    loo_mean_px: float
    """Mean leave-one-out error in the image, px (NaN if the model could not be fitted)."""
    sigma_px: float
    """Residual standard deviation per coordinate, px."""
    verdict: str
    """"chosen", "not earned" (no clear gain over a simpler model) or why it was refused."""

    def to_dict(self) -> dict[str, Any]:
        return {k: _json_number(v) for k, v in dataclasses.asdict(self).items()}


@dataclasses.dataclass(frozen=True)
class CalibrationSummary:
    """The figures a calibration is judged by (px in the image, mm on the plane)."""

    n_points: int
    solver: str
    refine: bool
    mean_px: float
    """Mean reprojection error, the paper's Eq. 7."""
    rms_px: float
    max_px: float
    min_px: float
    max_abs_dx_mm: float
    """Largest |dX| of the world coordinates after calibration (the paper's Table 4)."""
    max_abs_dy_mm: float
    loo_mean_mm: float
    """Mean leave-one-out error: how far each point lands when the fit has not seen it."""
    loo_rms_mm: float
    loo_max_mm: float
    lens: str = "none"
    """The lens model: "none", "k1", "k1k2", "k1k2c" or "intrinsics"."""
    loo_mean_px: float = float("nan")
    """Mean leave-one-out error in the image, px."""
    predicted_loo_rms_mm: float = float("nan")
    """The RMS leave-one-out error the fit's covariance predicts (compare loo_rms_mm)."""

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


class Calibration:
    """The plane's homography, its lens model, and its report.

    Build one from matched points (``Calibration(world_mm, image_px)``), from a detection
    (``Calibration.from_detection``) or straight from an image of the board
    (``Calibration.from_image``); save it with ``save`` and read it back with
    ``Calibration.load``. It pickles, so it travels to worker processes.

    ``lens`` chooses the lens-distortion model (see the module's docstring): "auto" (the
    default) picks by leave-one-out error when ``image_size`` is known and fits none without
    it; "none", "k1", "k1k2", "k1k2c" force one. The paper's estimator (``solver="a33",
    refine=False``) fits no lens. ``intrinsics`` (a CameraIntrinsics) undistorts the points
    by a full camera model instead, and makes heights above the plane mappable.
    """

    def __init__(
        self,
        world_points: ArrayLike,
        image_points: ArrayLike,
        *,
        solver: Solver = "normalized_dlt",
        refine: bool = True,
        lens: LensChoice = "auto",
        board: CircleGridBoard | None = None,
        image_size: tuple[int, int] | None = None,
        intrinsics: CameraIntrinsics | None = None,
    ) -> None:
        world = _points(world_points, "world_points")
        image = _points(image_points, "image_points")
        if len(world) != len(image):
            raise ArgumentError(
                f"world_points and image_points must match one to one, got {len(world)} "
                f"and {len(image)}"
            )
        if solver not in SOLVERS:
            raise ArgumentError(f"solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
        if lens not in ("auto", *LENS_MODELS):
            raise LensModelError(
                f"lens must be 'auto' or one of {', '.join(LENS_MODELS)}, got {lens!r}"
            )
        size = _image_size(image_size)
        if intrinsics is not None:
            if not isinstance(intrinsics, CameraIntrinsics):
                raise IntrinsicsError(
                    f"intrinsics must be a CameraIntrinsics, got {type(intrinsics).__name__}"
                )
            if size is None:
                size = intrinsics.image_size
            elif tuple(size) != tuple(intrinsics.image_size):
                raise IntrinsicsError(
                    f"the intrinsics are for {intrinsics.image_size[0]} x "
                    f"{intrinsics.image_size[1]} images, this one is {size[0]} x {size[1]}"
                )
        fit = _fit(world, image, solver, bool(refine), lens, size, intrinsics)
        self._init(world, image, fit, solver, bool(refine), board, size, intrinsics, (1.0, 1.0))

    def _init(
        self,
        world: F64,
        image: F64,
        fit: _Fit,
        solver: Solver,
        refine: bool,
        board: CircleGridBoard | None,
        image_size: tuple[int, int] | None,
        intrinsics: CameraIntrinsics | None,
        world_scale: tuple[float, float],
    ) -> None:
        self._world = world
        self._image = image
        self._fit = fit
        self._h = np.array(fit.h, dtype=np.float64)
        self._h.setflags(write=False)
        self._world.setflags(write=False)
        self._image.setflags(write=False)
        self.solver: Solver = solver
        self.refine = refine
        self.board = board
        self.image_size = None if image_size is None else (int(image_size[0]), int(image_size[1]))
        self.intrinsics = intrinsics
        self.world_scale = world_scale
        """(sx, sy): the factors ``rescaled`` applied to the board's nominal coordinates."""

    # -- construction from images ---------------------------------------------------------

    @classmethod
    def from_detection(
        cls,
        detection: Any,
        *,
        solver: Solver = "normalized_dlt",
        refine: bool = True,
        lens: LensChoice = "auto",
        intrinsics: CameraIntrinsics | None = None,
    ) -> Calibration:
        """The calibration of a BoardDetection (planarcal.detect_board's result)."""
        return cls(
            detection.world_points(),
            detection.image_points,
            solver=solver,
            refine=refine,
            lens=lens,
            board=detection.board,
            image_size=detection.image_size,
            intrinsics=intrinsics,
        )

    @classmethod
    def from_image(
        cls,
        image: Any,
        board: CircleGridBoard,
        *,
        solver: Solver = "normalized_dlt",
        refine: bool = True,
        lens: LensChoice = "auto",
        intrinsics: CameraIntrinsics | None = None,
        polarity: str = "auto",
        turned: bool = False,
    ) -> Calibration:
        """Detects `board` in `image` (array or path) and calibrates from it (``polarity``
        and ``turned`` as in detect_board)."""
        detection = detect_board(image, board, polarity=polarity, turned=turned)  # type: ignore[arg-type]
        return cls.from_detection(
            detection, solver=solver, refine=refine, lens=lens, intrinsics=intrinsics
        )

    def rescaled(
        self, measured_pitch_x_mm: float, measured_pitch_y_mm: float | None = None
    ) -> Calibration:
        """This calibration with the world frame corrected for the printer's scale.

        A homography cannot see a board printed 1 % too large: every millimetre it reports
        would be 1 % short. Measure the board independently (the distance between the first
        and last dot of a row and of a column with a steel rule, divided by the number of
        gaps; or the printed 100 mm check bar, whose measured length / 100 times the nominal
        pitch is the pitch) and pass the pitches in X (along a row) and Y (down a column);
        Y defaults to X. Needs the board the calibration was made with."""
        if self.board is None:
            raise BoardError("rescaled needs the board the calibration was made from")
        px = _positive_mm("measured_pitch_x_mm", measured_pitch_x_mm)
        py = (
            px
            if measured_pitch_y_mm is None
            else _positive_mm("measured_pitch_y_mm", measured_pitch_y_mm)
        )
        sx, sy = px / self.board.pitch, py / self.board.pitch
        for name, s in (("X", sx), ("Y", sy)):
            if not 0.8 <= s <= 1.25:
                raise BoardError(
                    f"a measured pitch in {name} of {s * self.board.pitch:.3f} mm is "
                    f"{100 * (s - 1):+.1f} % off the board's {self.board.pitch} mm: not a "
                    "printer's scale error (a different board, or a measuring slip?)"
                )
        # The fit is the same problem in scaled units: refit rather than patch H, so every
        # figure (covariance, leave-one-out) is in the new millimetres.
        scale = np.array([sx / self.world_scale[0], sy / self.world_scale[1]])
        world = np.ascontiguousarray(self._world * scale)
        lens = self._fit.lens if self._fit.lens in LENS_MODELS else "none"
        fit = _fit(
            world, self._image, self.solver, self.refine, lens, self.image_size, self.intrinsics
        )
        fit.candidates = self._fit.candidates
        fit.note = self._fit.note
        cal = Calibration.__new__(Calibration)
        cal._init(
            world,
            self._image,
            fit,
            self.solver,
            self.refine,
            self.board,
            self.image_size,
            self.intrinsics,
            (sx, sy),
        )
        return cal

    def for_frame_size(self, width: int, height: int) -> Calibration:
        """This calibration for frames of ``width`` x ``height`` px showing the same view
        uniformly scaled: a camera switched deliberately to another resolution of the same
        aspect ratio (640 x 480 -> 1280 x 960). The same pixel of the scene maps to the same
        millimetres: H, the lens model (or the intrinsics) and the points are scaled with the
        pixels (pixel centres at whole numbers: u becomes s u + (s - 1) / 2); the world frame
        is untouched. Returns self for the size it was made on.

        FrameSizeError for another aspect ratio (that is a cropped view, not a scaled one:
        calibrate again) or for a calibration that records no image size."""
        size = _given_size((width, height))
        if self.image_size is None:
            raise FrameSizeError(
                f"this calibration records no image size (an old file, or made from bare "
                f"points without image_size=): it cannot be rescaled to {size[0]} x {size[1]} "
                "px frames; calibrate at that resolution",
                size,
                None,
            )
        if size == self.image_size:
            return self
        if not _same_aspect(size, self.image_size):
            raise FrameSizeError(
                f"cannot rescale a calibration made on {_size_text(self.image_size)} frames "
                f"to {_size_text(size)}: the aspect ratio differs ({_aspect_text(size)} "
                f"against {_aspect_text(self.image_size)}), so the view is cropped, not "
                f"scaled; calibrate again at {size[0]} x {size[1]}",
                size,
                self.image_size,
            )
        return self._scaled(self.image_size, size)

    def _scaled(self, made_on: tuple[int, int], size: tuple[int, int]) -> Calibration:
        """This calibration, made on frames of `made_on`, with every pixel quantity scaled for
        frames of `size` (the same aspect ratio)."""
        s = size[0] / made_on[0]
        a = _pixel_scaling(s)
        h = a @ self._h  # world -> old pixels -> new pixels; h33 is unchanged
        image = np.ascontiguousarray(_affine(a, self._image))
        intrinsics = self.intrinsics
        if intrinsics is not None:
            intrinsics = _scaled_intrinsics(intrinsics, s, size)
        lens = self._fit.plane.lens
        centre = _affine(a, np.array([lens[:2]]))[0]
        scaled_lens = (float(centre[0]), float(centre[1]), s * lens[2], lens[3], lens[4])
        plane = _plane_at(h, self._world, image, size, self._fit.lens, scaled_lens, intrinsics)
        candidates = [
            dataclasses.replace(c, loo_mean_px=s * c.loo_mean_px, sigma_px=s * c.sigma_px)
            for c in self._fit.candidates
        ]
        note = f"{self._fit.note} (rescaled from {_size_text(made_on)} frames)"
        fit = _Fit(plane, h, self._fit.lens, candidates, note)
        cal = Calibration.__new__(Calibration)
        cal._init(
            self._world,
            image,
            fit,
            self.solver,
            self.refine,
            self.board,
            size,
            intrinsics,
            self.world_scale,
        )
        return cal

    def check_image_size(self, image_size: tuple[int, int], *, what: str = "image") -> None:
        """Raises FrameSizeError, naming both sizes, unless ``image_size`` (width, height, px)
        is the size this calibration was made on: pixels of another size map to the wrong
        millimetres. A calibration that records no size (an old file, or one made from bare
        points) cannot tell, and accepts any. ``what`` names the picture in the message
        ("image", "frame")."""
        size = _given_size(image_size)
        if self.image_size is None or size == self.image_size:
            return
        raise FrameSizeError(_size_mismatch(size, self.image_size, what), size, self.image_size)

    # -- the homography and the mapping -----------------------------------------------------

    @property
    def H(self) -> F64:
        """World (mm) -> image (px), 3 x 3, read-only. With a lens model or intrinsics, to
        the *ideal* (undistorted) pixels; the lens maps those to the real ones."""
        return self._h

    @functools.cached_property
    def H_inv(self) -> F64:
        """Ideal image (px) -> world (mm), 3 x 3, read-only: H^-1 (the paper's Eq. 8)."""
        inv = np.asarray(np.linalg.inv(self._h), dtype=np.float64)
        # Scaled like H (|h33| = 1), keeping the orientation the true inverse has.
        if abs(inv[2, 2]) > 0:
            inv /= abs(inv[2, 2])
        inv.setflags(write=False)
        return inv

    @property
    def lens(self) -> LensModel | None:
        """The radial distortion fitted with H, or None (no lens model, or intrinsics)."""
        return self._fit.lens_model()

    @property
    def lens_model(self) -> str:
        """ "none", "k1", "k1k2", "k1k2c", or "intrinsics"."""
        return self._fit.lens

    @property
    def lens_candidates(self) -> tuple[LensCandidate, ...]:
        """The models ``lens="auto"`` tried, with their leave-one-out errors and verdicts."""
        return tuple(self._fit.candidates)

    @property
    def lens_note(self) -> str:
        """Why the lens model is what it is, in a sentence."""
        return self._fit.note

    @property
    def world_points(self) -> F64:
        return self._world

    @property
    def image_points(self) -> F64:
        return self._image

    def ideal_points(self, points_px: ArrayLike) -> F64:
        """Real pixels (N, 2) -> the ideal pinhole pixels H works in (the lens removed)."""
        arr = _points(points_px, "points_px")
        if self.intrinsics is not None:
            return self.intrinsics.undistort_points(arr)
        out = self._fit.plane.undistort(arr)
        if not np.isfinite(out).all():
            k = int(np.flatnonzero(~np.isfinite(out).all(axis=1))[0])
            raise LensModelError(
                f"point {k} {tuple(arr[k])} lies beyond the lens model's valid radius"
            )
        return out

    def image_to_world(
        self,
        points_px: ArrayLike,
        *,
        height: float | ArrayLike = 0.0,
        return_std: bool = False,
        pixel_sigma: float = 0.0,
        image_size: tuple[int, int] | None = None,
    ) -> Any:
        """Pixel positions -> plane positions in mm: (N, 2) -> (N, 2), or (2,) -> (2,).

        ``image_size``: (width, height) of the image the pixels come from; FrameSizeError if
        the calibration was made on another size (see ``check_image_size``).

        ``height``: the points are ``height`` mm above the plane (an object's top face;
        scalar or one per point), not on it: located where they really are. Needs camera
        intrinsics (``intrinsics=``), which give the camera's position.

        ``return_std=True`` returns ``(mm, std_mm)``: each point's 1-sigma position error
        (sqrt of the covariance's trace: the RMS distance from the truth) from the fit's
        uncertainty, plus the pixel's own noise of ``pixel_sigma`` px per coordinate.
        """
        if image_size is not None:
            self.check_image_size(image_size)
        arr = np.asarray(points_px, dtype=np.float64)
        single = arr.ndim == 1
        if single:
            if arr.shape != (2,):
                raise ArgumentError(f"a point must have 2 coordinates, got shape {arr.shape}")
            arr = arr.reshape(1, 2)
        arr = _points(arr, "points_px")
        h = (
            np.broadcast_to(np.asarray(height, dtype=np.float64), (len(arr),))
            if np.ndim(height) == 0
            else np.asarray(height, dtype=np.float64)
        )
        if h.shape != (len(arr),) or not np.isfinite(h).all():
            raise ArgumentError(
                f"height must be a finite number or one per point ({len(arr)}), got shape "
                f"{np.shape(height)}"
            )
        ideal = self.intrinsics.undistort_points(arr) if self.intrinsics is not None else arr
        if return_std:
            world, std = self._fit.plane.image_to_world_std(ideal, float(pixel_sigma))
        else:
            world = self._fit.plane.image_to_world(ideal)
        lifted = world
        factor = np.ones(len(arr))
        if (h != 0).any():
            lifted = points_at_height(world, self.camera_pose, h)
            factor = 1.0 - h / self.camera_pose.distance_mm
        if not return_std:
            return lifted[0] if single else lifted
        std = std * np.abs(factor)
        return (lifted[0], float(std[0])) if single else (lifted, std)

    def _frame_mapper(self, height: float = 0.0) -> Callable[[F64], tuple[F64, F64]]:
        """image_to_world(px, height=height, return_std=True) for the production loop, its
        arguments checked here once: the returned function takes an (N, 2) float64 array of
        pixels straight to the core (one call) when there is nothing to undistort or lift."""
        if self.intrinsics is None and height == 0.0:
            plane = self._fit.plane
            return lambda px: plane.image_to_world_std(px, 0.0)
        if height != 0.0:
            # IntrinsicsError now, rather than on every frame with an object in it.
            _ = self.camera_pose
        return lambda px: self.image_to_world(px, height=height, return_std=True)

    def world_covariance(self, points_px: ArrayLike, *, pixel_sigma: float = 0.0) -> F64:
        """The 2 x 2 covariance (mm^2) of each point's position on the plane, (N, 2, 2)."""
        arr = _points(points_px, "points_px")
        ideal = self.intrinsics.undistort_points(arr) if self.intrinsics is not None else arr
        return self._fit.plane.world_covariance(ideal, float(pixel_sigma))

    def world_to_image(self, points_mm: ArrayLike) -> F64:
        """Plane positions in mm -> pixel positions (lens included): (N, 2) -> (N, 2), or
        (2,) -> (2,)."""
        arr = np.asarray(points_mm, dtype=np.float64)
        single = arr.ndim == 1
        if single and arr.shape != (2,):
            raise ArgumentError(f"a point must have 2 coordinates, got shape {arr.shape}")
        ideal = transform_points(self._h, arr.reshape(-1, 2))
        out = self._distort(ideal)
        return out[0] if single else out

    def _distort(self, ideal: F64) -> F64:
        if self.intrinsics is not None:
            return self.intrinsics.distort_points(ideal)
        if self._fit.lens == "none":
            return ideal
        return self._fit.plane.distort(ideal)

    @functools.cached_property
    def camera_pose(self) -> Any:
        """The camera's pose over the plane (a PlanePoseEstimate: rotation, translation,
        camera centre in world mm, distance from the plane), from H and the intrinsics."""
        if self.intrinsics is None:
            raise IntrinsicsError(
                "the camera's pose needs camera intrinsics: calibrate with intrinsics= "
                "(planarcal.calibrate_camera from several board views, or "
                "CameraIntrinsics.load_yaml)"
            )

        return plane_pose(self.intrinsics.matrix, self._h)

    # -- the paper's report -------------------------------------------------------------------

    @functools.cached_property
    def reprojected_px(self) -> F64:
        """Each world point mapped into the image, lens included (the paper's Table 3)."""
        return self._distort(transform_points(self._h, self._world))

    @functools.cached_property
    def reprojection_errors_px(self) -> F64:
        """||image_i - H world_i|| per point, in px (the paper's Eq. 6, Table 3)."""
        if self._fit.lens == "none" and self.intrinsics is None:
            return reprojection_errors(self._h, self._world, self._image)
        return np.asarray(np.hypot(*(self._image - self.reprojected_px).T), dtype=np.float64)

    @functools.cached_property
    def stats(self) -> ReprojectionStats:
        """Mean (Eq. 7), RMS, max and min of the reprojection errors, px."""
        return error_stats(self.reprojection_errors_px)

    @functools.cached_property
    def world_after_mm(self) -> F64:
        """Each image point mapped back to the plane (the paper's Table 4), mm."""
        out: F64 = self.image_to_world(self._image)
        return out

    @functools.cached_property
    def deviations_mm(self) -> F64:
        """dX, dY of the world coordinates after calibration (the paper's Table 4), mm."""
        return self.world_after_mm - self._world

    @functools.cached_property
    def _loo(self) -> tuple[F64, F64]:
        """(image px, world mm) of each point under a fit made without it."""
        n = len(self._world)
        nan = np.full((n, 2), np.nan)
        if self._fit.lens in LENS_MODELS[1:]:
            return self._fit.loo()
        if n <= 4:
            # Without one point only 3 remain: no homography can be fitted.
            return nan, nan.copy()
        ideal = (
            self.intrinsics.undistort_points(self._image)
            if self.intrinsics is not None
            else self._image
        )
        px, mm = nan.copy(), nan.copy()
        keep = np.ones(n, dtype=bool)
        for i in range(n):
            keep[i] = False
            try:
                h = estimate_homography(self._world[keep], ideal[keep], self.solver, self.refine)
                mm[i] = transform_points(h, ideal[i : i + 1], inverse=True)[0]
                px[i] = self._distort(transform_points(h, self._world[i : i + 1]))[0]
            except HomographyError:
                pass  # the rest cannot determine a homography
            keep[i] = True
        return px, mm

    @functools.cached_property
    def loo_deviations_mm(self) -> F64:
        """Leave-one-out: where each image point lands on the plane under a fit made without
        it, minus where it is (dX, dY in mm). The honest estimate of mapping accuracy at a
        point the calibration has not seen; the residuals flatter the fit."""
        return self._loo[1] - self._world

    @functools.cached_property
    def loo_errors_mm(self) -> F64:
        """Leave-one-out error per point, mm (NaN where the others cannot be fitted)."""
        return np.hypot(self.loo_deviations_mm[:, 0], self.loo_deviations_mm[:, 1])

    @functools.cached_property
    def loo_errors_px(self) -> F64:
        """Leave-one-out error per point in the image, px: how far from its dot the fit made
        without it puts the dot's centre."""
        d = self._loo[0] - self._image
        return np.hypot(d[:, 0], d[:, 1])

    @functools.cached_property
    def predicted_loo_std_mm(self) -> F64:
        """The leave-one-out error each point should have by the fit's covariance (1-sigma,
        RMS distance, mm): compare loo_errors_mm. NaN without residual degrees of freedom."""
        try:
            cov = self._fit.plane.predicted_loo_covariance()
        except LensModelError:
            return np.full(len(self._world), np.nan)
        return np.asarray(np.sqrt(np.trace(cov, axis1=1, axis2=2)), dtype=np.float64)

    def summary(self) -> CalibrationSummary:
        s = self.stats
        dev = np.abs(self.deviations_mm)
        loo = self.loo_errors_mm
        finite = loo[np.isfinite(loo)]
        loo_px = self.loo_errors_px[np.isfinite(self.loo_errors_px)]
        pred = self.predicted_loo_std_mm
        pred = pred[np.isfinite(pred)]
        nan = float("nan")
        return CalibrationSummary(
            n_points=len(self._world),
            solver=self.solver,
            refine=self.refine,
            mean_px=s.mean,
            rms_px=s.rms,
            max_px=s.max,
            min_px=s.min,
            max_abs_dx_mm=float(dev[:, 0].max()),
            max_abs_dy_mm=float(dev[:, 1].max()),
            loo_mean_mm=float(finite.mean()) if finite.size else nan,
            loo_rms_mm=float(np.sqrt(np.mean(finite**2))) if finite.size else nan,
            loo_max_mm=float(finite.max()) if finite.size else nan,
            lens=self.lens_model,
            loo_mean_px=float(loo_px.mean()) if loo_px.size else nan,
            predicted_loo_rms_mm=float(np.sqrt(np.mean(pred**2))) if pred.size else nan,
        )

    # -- persistence ------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The versioned, JSON-ready form that save() writes and from_dict() reads."""
        summary = self.summary().to_dict()
        return {
            "format": FILE_FORMAT,
            "version": FILE_VERSION,
            "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "planarcal_version": _core.__version__,
            "solver": self.solver,
            "refine": self.refine,
            "homography_world_mm_to_image_px": self._h.tolist(),
            "lens_model": self.lens_model,
            "lens": None if self.lens is None else self.lens.to_dict(),
            "lens_note": self.lens_note,
            "lens_candidates": [c.to_dict() for c in self.lens_candidates],
            "intrinsics": None if self.intrinsics is None else self.intrinsics.to_dict(),
            "world_scale": list(self.world_scale),
            "image_size_px": None if self.image_size is None else list(self.image_size),
            "board": None if self.board is None else self.board.to_dict(),
            "points": {
                "world_mm": self._world.tolist(),
                "image_px": self._image.tolist(),
            },
            "summary": {k: _json_number(v) for k, v in summary.items()},
        }

    @classmethod
    def from_dict(cls, data: Any, source: str = "calibration data") -> Calibration:
        """The calibration saved by to_dict(); CalibrationFileError if it is not one."""
        if not isinstance(data, dict):
            raise CalibrationFileError(f"{source} is not a calibration (not a JSON object)")
        if data.get("format") != FILE_FORMAT:
            raise CalibrationFileError(
                f"{source} is not a planarcal calibration (format {data.get('format')!r})"
            )
        version = data.get("version")
        if version not in READS_VERSIONS or isinstance(version, bool):
            raise CalibrationFileError(
                f"{source} is calibration file version {version!r}; this planarcal "
                f"({_core.__version__}) reads versions "
                f"{', '.join(str(v) for v in READS_VERSIONS)}"
            )
        try:
            h = np.array(data["homography_world_mm_to_image_px"], dtype=np.float64)
            world = np.array(data["points"]["world_mm"], dtype=np.float64)
            image = np.array(data["points"]["image_px"], dtype=np.float64)
            solver = data["solver"]
            refine = data["refine"]
            size = data.get("image_size_px")
            board_data = data.get("board")
        except (KeyError, TypeError, ValueError) as e:
            raise CalibrationFileError(f"{source} is missing or mangles a field: {e!r}") from None
        if h.shape != (3, 3) or not np.isfinite(h).all():
            raise CalibrationFileError(f"{source}: the homography is not a finite 3 x 3 matrix")
        if abs(np.linalg.det(h)) == 0:
            raise CalibrationFileError(f"{source}: the homography is singular")
        for name, pts in (("world_mm", world), ("image_px", image)):
            if pts.ndim != 2 or pts.shape[1:] != (2,) or not np.isfinite(pts).all():
                raise CalibrationFileError(f"{source}: points.{name} is not a list of (x, y)")
        if len(world) != len(image) or len(world) < 4:
            raise CalibrationFileError(
                f"{source}: {len(world)} world and {len(image)} image points (need 4 or more, "
                "as many of each)"
            )
        if solver not in SOLVERS or not isinstance(refine, bool):
            raise CalibrationFileError(f"{source}: unknown solver {solver!r} / refine {refine!r}")
        try:
            board = None if board_data is None else CircleGridBoard.from_dict(board_data)
        except BoardError as e:
            raise CalibrationFileError(f"{source}: {e}") from None
        if size is not None and (
            not isinstance(size, list)
            or len(size) != 2
            or not all(isinstance(v, int) for v in size)
        ):
            raise CalibrationFileError(f"{source}: image_size_px must be [width, height]")
        image_size = None if size is None else (size[0], size[1])
        fit, intrinsics, world_scale = _fit_from_dict(data, h, world, image, image_size, source)
        cal = cls.__new__(cls)
        cal._init(world, image, fit, solver, refine, board, image_size, intrinsics, world_scale)
        return cal

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Writes the calibration as human-readable JSON, atomically."""
        text = json.dumps(self.to_dict(), indent=2, allow_nan=False) + "\n"
        return atomic_write(path, text)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Calibration:
        """Reads a calibration saved by save(); CalibrationFileError if the file is not one
        (corrupt, truncated, another format or version)."""
        p = Path(path)
        try:
            text = p.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise CalibrationFileError(f"no calibration file at {str(p)!r}") from None
        except (OSError, UnicodeDecodeError) as e:
            raise CalibrationFileError(f"cannot read {str(p)!r}: {e}") from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise CalibrationFileError(
                f"{str(p)!r} is not valid JSON (corrupt or truncated?): {e}"
            ) from None
        return cls.from_dict(data, source=repr(str(p)))

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        # Pickles through the same validated, versioned form as the file.
        return (_from_dict, (self.to_dict(),))

    def __repr__(self) -> str:
        s = self.stats
        return (
            f"Calibration({len(self._world)} points, solver={self.solver!r}, "
            f"refine={self.refine}, lens={self.lens_model!r}, mean error {s.mean:.3f} px)"
        )


def _from_dict(data: dict[str, Any]) -> Calibration:
    return Calibration.from_dict(data)


def _json_number(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _points(value: ArrayLike, name: str) -> F64:
    arr = np.array(value, dtype=np.float64)
    if arr.ndim == 3 and 1 in arr.shape[:2] and arr.shape[2] == 2:
        arr = arr.reshape(-1, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ArgumentError(f"{name} must have shape (N, 2), got {arr.shape}")
    return np.ascontiguousarray(arr)


def _image_size(size: Any) -> tuple[int, int] | None:
    if size is None:
        return None
    try:
        w, h = size
    except (TypeError, ValueError):
        raise ArgumentError(f"image_size must be (width, height), got {size!r}") from None
    for v in (w, h):
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
            raise ArgumentError(f"image_size must be two positive whole numbers, got {size!r}")
    return int(w), int(h)


def _given_size(size: Any) -> tuple[int, int]:
    """A (width, height) that must be there: _image_size without None."""
    checked = _image_size(size)
    if checked is None:
        raise ArgumentError("image_size must be (width, height), got None")
    return checked


def _size_text(size: tuple[int, int]) -> str:
    return f"{size[0]} x {size[1]} px"


def _same_aspect(a: tuple[int, int], b: tuple[int, int]) -> bool:
    """Exactly the same shape (so one is the other uniformly scaled)."""
    return a[0] * b[1] == a[1] * b[0]


def _aspect_text(size: tuple[int, int]) -> str:
    """The aspect ratio in lowest terms: 1280 x 720 -> "16:9"."""
    d = math.gcd(*size)
    return f"{size[0] // d}:{size[1] // d}"


def _size_mismatch(size: tuple[int, int], made_on: tuple[int, int], what: str) -> str:
    """Why a picture of `size` cannot go through a calibration made on `made_on`, and what to
    do: rescale the calibration for a deliberate change of resolution, else calibrate again."""
    head = (
        f"this {what} is {_size_text(size)} but the calibration was made on "
        f"{_size_text(made_on)} {what}s: its pixels would map to the wrong millimetres. "
    )
    if _same_aspect(size, made_on):
        return head + (
            f"Calibrate at {size[0]} x {size[1]}, or, if the camera's resolution was changed "
            f"deliberately (the same view, scaled), use cal.for_frame_size({size[0]}, "
            f"{size[1]}) (and save it for planarcal run / locate)"
        )
    return head + (
        f"Calibrate again at {size[0]} x {size[1]}: another aspect ratio "
        f"({_aspect_text(size)} against {_aspect_text(made_on)}) is a cropped view, which "
        "cal.for_frame_size cannot rescale to"
    )


def _pixel_scaling(s: float) -> F64:
    """Old pixels -> new pixels of an image scaled by `s`, pixel centres at whole numbers: the
    image's outer edges (-0.5 and width - 0.5) go to the new ones."""
    t = (s - 1.0) / 2.0
    return np.array([[s, 0.0, t], [0.0, s, t], [0.0, 0.0, 1.0]])


def _affine(a: F64, points: F64) -> F64:
    """Points (N, 2) through an affine 3 x 3 matrix."""
    out: F64 = points @ a[:2, :2].T + a[:2, 2]
    return out


def _scaled_intrinsics(
    intrinsics: CameraIntrinsics, s: float, size: tuple[int, int]
) -> CameraIntrinsics:
    """The same camera at a resolution scaled by `s`: K scaled with the pixels; the distortion
    coefficients act on normalised coordinates and stay; the RMS errors scale."""
    per_view = intrinsics.per_view_rms_px
    return CameraIntrinsics(
        _pixel_scaling(s) @ intrinsics.matrix,
        np.array(intrinsics.dist_coeffs),
        size,
        None if intrinsics.rms_px is None else s * intrinsics.rms_px,
        intrinsics.n_views,
        None if per_view is None else tuple(s * v for v in per_view),
    )


def _positive_mm(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise BoardError(f"{name} must be a number of mm, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise BoardError(f"{name} must be a positive, finite number of mm, got {value!r}")
    return v


@dataclasses.dataclass
class _Fit:
    """What a calibration fitted: the core's model (on ideal pixels with intrinsics), its H,
    which lens model, and how it was chosen."""

    plane: _core.FittedPlane
    h: F64
    lens: str
    candidates: list[LensCandidate]
    note: str
    loo_cache: tuple[F64, F64] | None = None

    def lens_model(self) -> LensModel | None:
        if self.lens not in LENS_MODELS[1:]:
            return None
        cx, cy, scale, k1, k2 = self.plane.lens
        s1, s2, scx, scy = self.plane.lens_std
        return LensModel(self.lens, (cx, cy), scale, k1, k2, s1, s2, (scx, scy))

    def loo(self) -> tuple[F64, F64]:
        if self.loo_cache is None:
            self.loo_cache = self.plane.leave_one_out()
        return self.loo_cache


def _frame_size(image: F64, size: tuple[int, int] | None) -> tuple[float, float]:
    """The image size that centres the lens frame; without one (a plain homography, where it
    only sets the parameters' units), a box around the points."""
    if size is not None:
        return float(size[0]), float(size[1])
    reach = np.abs(image).max(axis=0) if len(image) else np.ones(2)
    return float(2.0 * reach[0] + 2.0), float(2.0 * reach[1] + 2.0)


def _plain(world: F64, image: F64, solver: Solver, refine: bool, size: Any) -> tuple[Any, F64]:
    """The homography by the chosen solver, and the core's model at it (for the covariance)."""
    h = estimate_homography(world, image, solver, refine)
    return _plain_at(h, world, image, size), h


def _plain_at(h: F64, world: F64, image: F64, size: Any) -> Any:
    """The core's model of a homography alone, at H (its covariance on these points)."""
    w, hgt = _frame_size(image, size)
    centre = ((w - 1.0) / 2.0, (hgt - 1.0) / 2.0)
    return _core.FittedPlane.at(
        h, centre, 0.5 * math.hypot(w, hgt), 0.0, 0.0, world, image, "none", (w, hgt)
    )


def _plane_at(
    h: F64,
    world: F64,
    image: F64,
    size: tuple[int, int] | None,
    lens: str,
    lens_params: tuple[float, float, float, float, float],
    intrinsics: CameraIntrinsics | None,
) -> Any:
    """The core's model of a calibration at known parameters (its covariance on these
    points): H, the lens model `lens` with its (centre x, centre y, scale, k1, k2), or the
    intrinsics."""
    if lens == "intrinsics":
        if intrinsics is None:
            raise IntrinsicsError("lens model 'intrinsics' without the intrinsics")
        return _plain_at(h, world, intrinsics.undistort_points(image), size)
    if lens == "none":
        return _plain_at(h, world, image, size)
    if size is None:
        raise LensModelError(f"lens model {lens!r} without the image size it is centred on")
    cx, cy, scale, k1, k2 = lens_params
    frame = (float(size[0]), float(size[1]))
    return _core.FittedPlane.at(h, (cx, cy), scale, k1, k2, world, image, lens, frame)


def _coverage(image: F64, size: tuple[int, int]) -> float:
    """How far the points reach from the image centre towards its corners (0 to 1)."""
    w, h = size
    centre = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    return float(np.hypot(*(image - centre).T).max() / (0.5 * math.hypot(w, h)))


def _fit(
    world: F64,
    image: F64,
    solver: Solver,
    refine: bool,
    lens: str,
    size: tuple[int, int] | None,
    intrinsics: CameraIntrinsics | None,
) -> _Fit:
    paper = solver != "normalized_dlt" or not refine
    if intrinsics is not None:
        if lens not in ("auto", "none"):
            raise LensModelError(
                f"with intrinsics the lens is the camera model's: lens must be 'auto' or "
                f"'none', got {lens!r}"
            )
        ideal = intrinsics.undistort_points(image)
        plane, h = _plain(world, ideal, solver, refine, size)
        return _Fit(plane, h, "intrinsics", [], "points undistorted by the camera's intrinsics")
    if paper and lens not in ("auto", "none"):
        raise LensModelError(
            f"a lens model is fitted jointly with H by Levenberg-Marquardt; solver={solver!r}, "
            f"refine={refine} fit a homography alone (keep the defaults to use lens={lens!r})"
        )
    if lens == "none" or paper:
        plane, h = _plain(world, image, solver, refine, size)
        why = "the paper's estimator" if paper else "asked for"
        return _Fit(plane, h, "none", [], f"no lens model ({why})")
    if size is None:
        if lens != "auto":
            raise LensModelError(
                "a lens model is centred on the image: give image_size=(width, height)"
            )
        plane, h = _plain(world, image, solver, refine, size)
        return _Fit(plane, h, "none", [], "no lens model (no image size to centre one on)")
    coverage = _coverage(image, size)
    if lens != "auto":
        plane = _core.FittedPlane.fit(world, image, lens, (float(size[0]), float(size[1])))
        note = f"lens model {lens} (asked for)"
        if coverage < MIN_LENS_COVERAGE:
            note += (
                f"; the board reaches only {coverage:.0%} of the way to the image's corners, "
                "too little to determine the distortion"
            )
        return _Fit(plane, plane.homography, lens, [], note)
    if coverage < MIN_LENS_COVERAGE:
        plane, h = _plain(world, image, solver, refine, size)
        return _Fit(
            plane,
            h,
            "none",
            [],
            f"no lens model: the board reaches only {coverage:.0%} of the way from the image "
            f"centre to its corners (at least {MIN_LENS_COVERAGE:.0%} needed), too little to "
            "determine the distortion; let the board fill more of the view",
        )
    return _select_lens(world, image, solver, refine, size)


def _select_lens(
    world: F64, image: F64, solver: Solver, refine: bool, size: tuple[int, int]
) -> _Fit:
    """Fits every lens model and keeps the simplest whose leave-one-out error no richer one
    beats by LENS_MARGIN."""
    frame = (float(size[0]), float(size[1]))
    centre = np.array([(size[0] - 1) / 2.0, (size[1] - 1) / 2.0])
    half_diagonal = 0.5 * math.hypot(*size)
    tried: dict[str, tuple[Any, float, float, str]] = {}
    caches: dict[str, tuple[F64, F64]] = {}
    for model in LENS_MODELS:
        try:
            plane = _core.FittedPlane.fit(world, image, model, frame)
        except (LensModelError, HomographyError) as e:
            if model == "none":
                raise
            tried[model] = (None, math.nan, math.nan, f"refused: {e}")
            continue
        offset = float(np.hypot(*(np.array(plane.lens[:2]) - centre)))
        if model == "k1k2c" and offset > MAX_CENTRE_OFFSET * half_diagonal:
            tried[model] = (
                None,
                math.nan,
                plane.sigma,
                f"refused: its centre ({plane.lens[0]:.0f}, {plane.lens[1]:.0f}) px is "
                f"{offset:.0f} px from the image centre, not a lens's (is the board flat?)",
            )
            continue
        px, mm = plane.leave_one_out()
        err = np.hypot(*(px - image).T)
        err = err[np.isfinite(err)]
        loo = float(err.mean()) if err.size else math.nan
        tried[model] = (plane, loo, plane.sigma, "")
        caches[model] = (px, mm)
    best = "none"
    for model in LENS_MODELS[1:]:
        plane, loo, _, why = tried[model]
        if plane is not None and loo < tried[best][1] * (1.0 - LENS_MARGIN):
            best = model
    candidates = []
    for model in LENS_MODELS:
        plane, loo, sigma, why = tried[model]
        verdict = why or ("chosen" if model == best else "not earned")
        candidates.append(LensCandidate(model, loo, sigma, verdict))
    gain = tried["none"][1]
    if best == "none":
        plane, h = _plain(world, image, solver, refine, size)
        note = (
            "no lens model: none lowered the leave-one-out error by "
            f"{LENS_MARGIN:.0%} or more ({gain:.3f} px without one)"
        )
        return _Fit(plane, h, "none", candidates, note)
    chosen = tried[best]
    note = (
        f"lens model {best}: leave-one-out error {chosen[1]:.3f} px, against {gain:.3f} px "
        "with a homography alone"
    )
    return _Fit(chosen[0], chosen[0].homography, best, candidates, note, caches[best])


def _fit_from_dict(
    data: dict[str, Any],
    h: F64,
    world: F64,
    image: F64,
    size: tuple[int, int] | None,
    source: str,
) -> tuple[_Fit, CameraIntrinsics | None, tuple[float, float]]:
    """The fit a file describes, checked against its points; CalibrationFileError if not."""
    lens = data.get("lens_model", "none")
    lens_data = data.get("lens")
    intr_data = data.get("intrinsics")
    scale = data.get("world_scale", [1.0, 1.0])
    note = data.get("lens_note", "no lens model")
    cand_data = data.get("lens_candidates", [])
    try:
        world_scale = (float(scale[0]), float(scale[1]))
        if len(scale) != 2 or not all(math.isfinite(v) and v > 0 for v in world_scale):
            raise ValueError(scale)
        candidates = [
            LensCandidate(
                str(c["model"]),
                math.nan if c["loo_mean_px"] is None else float(c["loo_mean_px"]),
                math.nan if c["sigma_px"] is None else float(c["sigma_px"]),
                str(c["verdict"]),
            )
            for c in cand_data
        ]
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise CalibrationFileError(f"{source}: bad world_scale or lens_candidates: {e!r}") from None
    intrinsics = None
    params = (0.0, 0.0, 1.0, 0.0, 0.0)  # unused without a lens model
    try:
        if lens == "intrinsics":
            intrinsics = CameraIntrinsics.from_dict(intr_data)
        elif lens in LENS_MODELS[1:]:
            if size is None or not isinstance(lens_data, dict):
                raise CalibrationFileError(
                    f"{source}: lens model {lens!r} without its parameters or the image size"
                )
            cx, cy = (float(v) for v in lens_data["centre_px"])
            params = (
                cx,
                cy,
                float(lens_data["scale_px"]),
                float(lens_data["k1"]),
                float(lens_data["k2"]),
            )
        elif lens != "none":
            raise CalibrationFileError(f"{source}: unknown lens model {lens!r}")
        plane = _plane_at(h, world, image, size, str(lens), params, intrinsics)
    except (ArgumentError, IntrinsicsError, LensModelError, HomographyError) as e:
        raise CalibrationFileError(f"{source}: {e}") from None
    except (KeyError, TypeError, ValueError) as e:
        raise CalibrationFileError(
            f"{source}: the lens is missing or mangles a field: {e!r}"
        ) from None
    return _Fit(plane, h, str(lens), candidates, str(note)), intrinsics, world_scale
