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
  in mm from the fit's covariance, the model's bias and the pixel's own noise (a located
  part's, by default): ``error_budget`` (calib.error_budget) says what each term is.
* **Printer scale**: ``rescaled`` corrects the world frame by an independent measurement of
  the board's pitch (or its printed check bar), which no homography can see.
* **The robot's frame**: ``register`` (or ``with_robot_frame``) attaches a registration of the
  board to a robot's base frame (a :class:`~planarcal.robot.RobotFrame`, from touch points or
  N-point pairs); ``image_to_world(px, frame="robot")`` then maps pixels straight to robot
  mm, the registration's own error carried into the 1-sigma. It is saved with the file.
* **How objects are detected here**: ``object_settings`` (calib.object_settings: area limits,
  a region of interest, the blur), set by ``with_object_settings`` and saved with the file;
  ``locate_objects``, the ``Tracker`` and the commands use them unless told otherwise.

This module is the Calibration class; its parts live beside it: ``lens_model`` (the lens it
fitted), ``lens_choice`` (which lens model, and the candidates tried), ``plane_fit`` (the
core's model of the fit), ``leave_one_out``, ``frame_size`` (size checks and rescaling) and
``calibration_file`` (the JSON format).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal.calib import calibration_file, frame_size
from planarcal.calib.board_points import match_board_points
from planarcal.calib.boards import BOARD_TYPES, Board, is_board
from planarcal.calib.calibration_file import FILE_FORMAT, FILE_VERSION, READS_VERSIONS
from planarcal.calib.detection import detect_board
from planarcal.calib.detector_options import check_detector_options
from planarcal.calib.error_budget import OUTLINE_CENTROID_SIGMA_PX, ErrorBudget, with_budget
from planarcal.calib.extrapolation import Extrapolation, extrapolation
from planarcal.calib.leave_one_out import homography_leave_one_out
from planarcal.calib.lens_candidate import LensCandidate
from planarcal.calib.lens_choice import (
    LENS_MARGIN,
    MAX_CENTRE_OFFSET,
    MIN_LENS_COVERAGE,
    LensChoice,
    fit_with_lens,
)
from planarcal.calib.lens_model import LENS_MODELS, LensModel
from planarcal.calib.object_settings import ObjectSettings
from planarcal.calib.placement_set import (
    calibration_placements,
    checked_reference,
    detect_copies,
    detect_placement,
    placement_layout,
    placement_names,
    same_camera_and_board,
)
from planarcal.calib.placements import Placement, PlacementLayout, check_placements
from planarcal.calib.plane_fit import PlaneFit, plane_at
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
from planarcal.homography import (
    SOLVERS,
    ReprojectionStats,
    Solver,
    error_stats,
    reprojection_errors,
    transform_points,
)
from planarcal.robot.handedness import Handedness
from planarcal.robot.output_frame import Coords, board_to_robot, checked_frame, default_frame
from planarcal.robot.registration import RobotFrame
from planarcal.robot.touch_pairs import board_extent, plane_points
from planarcal.robot.transform_fit import Model

# Other modules and old code import these from here; they live in the modules named above.
__all__ = [
    "FILE_FORMAT",
    "FILE_VERSION",
    "LENS_MARGIN",
    "LENS_MODELS",
    "MAX_CENTRE_OFFSET",
    "MIN_LENS_COVERAGE",
    "READS_VERSIONS",
    "Calibration",
    "CalibrationSummary",
    "LensCandidate",
    "LensChoice",
    "LensModel",
]

F64 = NDArray[np.float64]


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
    loo_rms_px: float = float("nan")
    """RMS leave-one-out error in the image, px: unlike the mm figures, which scale with the
    board's stated pitch (a pitch stated ten times too small reports errors ten times too
    small), no wrong description of the board can flatter it."""
    loo_max_px: float = float("nan")
    """Largest leave-one-out error in the image, px."""
    covered_share: float = float("nan")
    """The share of the image inside the outline (convex hull) of the calibration's points:
    the rest is extrapolated (``Calibration.extrapolation``)."""
    covered_std_mm: float = float("nan")
    """The largest 1-sigma mapping error the calibration predicts at its own points, mm."""
    image_std_mm: float = float("nan")
    """The largest 1-sigma mapping error it predicts anywhere in the image, mm (where the
    image is farthest from its points); NaN without an image size."""

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def __str__(self) -> str:
        """The figures in a few lines (the full report `planarcal calibrate` prints is the
        report layer's: ``planarcal.report.summary_text(cal)``); a summary made by hand, of
        no calibration, is its fields."""
        cal = self.__dict__.get("_calibration")
        if cal is None:
            return repr(self)
        return "\n".join(cal.describe_lines(self))


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
        board: Board | None = None,
        image_size: tuple[int, int] | None = None,
        intrinsics: CameraIntrinsics | None = None,
    ) -> None:
        world = _points(world_points, "world_points")
        if board is not None and not is_board(board):
            raise BoardError(
                f"board must be one of planarcal's boards ({', '.join(BOARD_TYPES)}) or None, "
                f"got {type(board).__name__}"
            )
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
        size = frame_size.checked_image_size(image_size)
        ids = None if board is None else _point_ids(board, world, (1.0, 1.0))
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
        fit = fit_with_lens(world, image, solver, bool(refine), lens, size, intrinsics)
        fit = calibration_file.fit_as_loaded(fit, world, image, size, intrinsics)
        self._init(
            world, image, fit, solver, bool(refine), board, size, intrinsics, (1.0, 1.0), ids=ids
        )

    def _init(
        self,
        world: F64,
        image: F64,
        fit: PlaneFit,
        solver: Solver,
        refine: bool,
        board: Board | None,
        image_size: tuple[int, int] | None,
        intrinsics: CameraIntrinsics | None,
        world_scale: tuple[float, float],
        robot_frame: RobotFrame | None = None,
        created: str | None = None,
        *,
        ids: NDArray[np.intp] | None = None,
        placement_names: tuple[str, ...] = (),
        placement_partial: tuple[bool, ...] = (),
        object_settings: ObjectSettings | None = None,
    ) -> None:
        self._world = world
        self._image = image
        if board is not None and ids is None:
            ids = _point_ids(board, world, world_scale)
        self.point_ids: NDArray[np.intp] | None = ids
        """The board's ids of the calibration's points (indices into
        ``board.world_points()``, matching world_points and image_points), or None without a
        board. A whole board has every id; a partial view those seen."""
        if ids is not None:
            ids.setflags(write=False)
        # The error bars' terms beyond the fit's covariance, recomputed from the points (files
        # do not store them); the plane then includes the model's bias in every uncertainty.
        self._fit, budget = with_budget(fit, world, image, board, intrinsics, ids)
        self.error_budget: ErrorBudget = budget
        """What std_mm covers beyond the fit's covariance (see calib.error_budget)."""
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
        self.robot_frame = robot_frame
        """The registration of the board to the robot's base frame, or None (see register)."""
        self._placement_names = placement_names
        self._placement_partial = placement_partial
        self.object_settings = ObjectSettings() if object_settings is None else object_settings
        """How objects are detected in this camera's images (area limits, roi, blur; each
        None: detect_objects' default): see with_object_settings."""
        self.created = calibration_file.now_stamp() if created is None else created
        """When this calibration was made (ISO 8601, UTC): kept by save and load, so that a
        re-save of an unchanged calibration is the same file."""

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
        """The calibration of a BoardDetection (planarcal.detect_board's result) of any
        board, whole or partial: its points are the ones found (``point_ids`` their ids)."""
        board = getattr(detection, "board", None)
        if not is_board(board) or not hasattr(detection, "world_points"):
            raise ArgumentError(
                f"detection must be a BoardDetection (planarcal.detect_board's result), got "
                f"{type(detection).__name__}"
            )
        return cls(
            detection.world_points(),
            detection.image_points,
            solver=solver,
            refine=refine,
            lens=lens,
            board=board,
            image_size=detection.image_size,
            intrinsics=intrinsics,
        )

    @classmethod
    def from_image(
        cls,
        image: Any,
        board: Board,
        *,
        solver: Solver = "normalized_dlt",
        refine: bool = True,
        lens: LensChoice = "auto",
        intrinsics: CameraIntrinsics | None = None,
        **detector_options: Any,
    ) -> Calibration:
        """Detects `board` (any type) in `image` (array or path) and calibrates from what is
        found; ``detector_options`` go to the detector of the board's kind (a circle grid's
        ``polarity`` and ``turned``, see detect_board)."""
        if not is_board(board):
            raise BoardError(
                f"board must be one of planarcal's boards ({', '.join(BOARD_TYPES)}), got "
                f"{type(board).__name__}"
            )
        check_detector_options(board.kind, detector_options)
        detection = detect_board(image, board, **detector_options)
        return cls.from_detection(
            detection, solver=solver, refine=refine, lens=lens, intrinsics=intrinsics
        )

    @classmethod
    def from_detections(
        cls,
        detections: Sequence[Any],
        *,
        reference: int = 0,
        lens: LensChoice = "auto",
        intrinsics: CameraIntrinsics | None = None,
        names: Sequence[str] | None = None,
    ) -> Calibration:
        """One calibration from several placements of one board: its detections (each
        planarcal.detect_board's result, whole or partial) in images from the one fixed
        camera, the board laid flat at another place on the plane in each. Every
        placement's in-plane pose is fitted jointly with the one homography and lens, so the
        lens is fitted wherever a placement lay and the error bars hold over the whole work
        area (``placements`` gives each pose). The plane's frame is placement `reference`'s
        board frame. ``names`` label the placements in messages and the report (default
        "placement k").

        One detection is ``from_detection``'s calibration. PlacementError names a placement
        the others' plane cannot explain (a board not flat on the plane, a wrong
        detection); FrameSizeError images of different sizes; BoardError detections of
        different boards."""
        dets = list(detections) if isinstance(detections, Sequence) else None
        if not dets:
            raise ArgumentError(
                "detections must be a non-empty sequence of BoardDetections (planarcal."
                f"detect_board's results), got {type(detections).__name__}"
            )
        labels = placement_names(names, len(dets))
        reference = checked_reference(reference, len(dets))
        if len(dets) == 1:
            cal = cls.from_detection(dets[0], lens=lens, intrinsics=intrinsics)
            cal._placement_names = labels
            cal._placement_partial = (bool(dets[0].partial),)
            return cal
        board, size = same_camera_and_board(dets, labels)
        layout = placement_layout(dets, reference)
        image = np.ascontiguousarray(np.concatenate([d.image_points for d in dets]))
        ids = np.concatenate([d.ids for d in dets]).astype(np.intp)
        if lens not in ("auto", *LENS_MODELS):
            raise LensModelError(
                f"lens must be 'auto' or one of {', '.join(LENS_MODELS)}, got {lens!r}"
            )
        if intrinsics is not None and not isinstance(intrinsics, CameraIntrinsics):
            raise IntrinsicsError(
                f"intrinsics must be a CameraIntrinsics, got {type(intrinsics).__name__}"
            )
        return cls._from_layout(
            layout,
            image,
            board,
            size,
            ids,
            lens=lens,
            intrinsics=intrinsics,
            names=labels,
            partial=tuple(bool(d.partial) for d in dets),
        )

    @classmethod
    def _from_layout(
        cls,
        layout: PlacementLayout,
        image: F64,
        board: Board,
        size: tuple[int, int],
        ids: NDArray[np.intp],
        *,
        lens: LensChoice,
        intrinsics: CameraIntrinsics | None,
        names: tuple[str, ...],
        partial: tuple[bool, ...],
        world_scale: tuple[float, float] = (1.0, 1.0),
        check: bool = True,
    ) -> Calibration:
        """The placements fit of `layout` (its poses the start) and `image`; ``check``
        refuses a placement the others' plane cannot explain (PlacementError)."""
        try:
            fit = fit_with_lens(
                layout.board_mm, image, "normalized_dlt", True, lens, size, intrinsics, layout
            )
        except (LensModelError, HomographyError) as e:
            raise type(e)(f"the placements cannot be fitted together: {e}") from None
        assert fit.placements is not None
        world = fit.placements.plane_points()
        fit = calibration_file.fit_as_loaded(fit, world, image, size, intrinsics)
        assert fit.placements is not None
        if check:
            ideal = image if intrinsics is None else intrinsics.undistort_points(image)
            lens_fitted = fit.lens if fit.lens in LENS_MODELS else "none"
            check_placements(fit.placements, ideal, lens_fitted, size, names)
        cal = cls.__new__(cls)
        cal._init(
            world,
            image,
            fit,
            "normalized_dlt",
            True,
            board,
            size,
            intrinsics,
            world_scale,
            ids=ids,
            placement_names=names,
            placement_partial=partial,
        )
        return cal

    def homography_alone(self) -> Calibration:
        """The same points fitted by a homography alone (no lens model, no intrinsics), in the
        same millimetres: the "before" of the report's comparison. A calibration from
        several placements is refitted with its placements."""
        layout = self._fit.placements
        if layout is None or self.board is None or self.image_size is None:
            sx, sy = (float(v) for v in self.world_scale)
            scaled = (sx, sy) != (1.0, 1.0) and self.board is not None
            # A calibration corrected for the printer's scale is fitted on the board's own
            # points, then corrected as it was.
            alone = Calibration(
                self._world / np.array([sx, sy]) if scaled else self._world,
                self._image,
                solver=self.solver,
                refine=self.refine,
                lens="none",
                board=self.board,
                image_size=self.image_size,
            )
            if scaled and self.board is not None:
                return alone.rescaled(self.board.pitch * sx, self.board.pitch * sy)
            return alone
        assert self.point_ids is not None
        return Calibration._from_layout(
            layout,
            self._image,
            self.board,
            self.image_size,
            self.point_ids,
            lens="none",
            intrinsics=None,
            names=self._placement_names,
            partial=self._placement_partial,
            world_scale=self.world_scale,
            check=False,
        )

    @classmethod
    def from_images(
        cls,
        images: Sequence[Any],
        board: Board,
        *,
        reference: int = 0,
        lens: LensChoice = "auto",
        intrinsics: CameraIntrinsics | None = None,
        names: Sequence[str] | None = None,
        copies: bool = False,
        **detector_options: Any,
    ) -> Calibration:
        """``from_detections`` of `board` detected in each of `images` (arrays or paths; a
        path's file name is its placement's name unless ``names`` are given, one per image).
        ``copies=True``: each image may show several copies of the board laid out at once
        (planarcal.detect_board_copies), each copy a placement ("A.png copy 1", ... in
        reading order), `reference` counting the copies."""
        if not is_board(board):
            raise BoardError(
                f"board must be one of planarcal's boards ({', '.join(BOARD_TYPES)}), got "
                f"{type(board).__name__}"
            )
        if isinstance(images, (str, os.PathLike)) or not isinstance(images, Sequence) or not images:
            raise ArgumentError(
                "images must be a non-empty sequence of images or paths, got "
                f"{type(images).__name__}"
            )
        check_detector_options(board.kind, detector_options)
        if names is None:
            names = [
                Path(im).name if isinstance(im, (str, os.PathLike)) else f"placement {k}"
                for k, im in enumerate(images)
            ]
        labels = placement_names(names, len(images))
        if copies:
            detections, found = [], []
            for k, im in enumerate(images):
                seen, called = detect_copies(im, board, k, labels[k], detector_options)
                detections += seen
                found += called
            labels = tuple(found)
            reference = checked_reference(reference, len(detections))
        else:
            reference = checked_reference(reference, len(images))
            detections = [
                detect_placement(im, board, k, reference, labels[k], detector_options)
                for k, im in enumerate(images)
            ]
        return cls.from_detections(
            detections, reference=reference, lens=lens, intrinsics=intrinsics, names=labels
        )

    @property
    def placements(self) -> tuple[Placement, ...]:
        """The board's placements this calibration was made from, each with its pose in the
        plane (``from_detections``): one for a calibration from one board view (the
        reference), none for one made from bare points."""
        return calibration_placements(self)

    def rescaled(
        self, measured_pitch_x_mm: float, measured_pitch_y_mm: float | None = None
    ) -> Calibration:
        """This calibration with the world frame corrected for the printer's scale.

        A homography cannot see a board printed 1 % too large: every millimetre it reports
        would be 1 % short. Measure the board independently (the distance between the first
        and last dot or corner of a row and of a column with a steel rule, divided by the
        number of gaps; or the printed 100 mm check bar, whose measured length / 100 times the
        nominal pitch is the pitch) and pass the pitches in X (along a row) and Y (down a
        column); Y defaults to X. The pitch is ``board.pitch``: a circle grid's, a
        chessboard's or ChArUco board's square. Needs the board the calibration was made
        with. A registration to the
        robot is not carried over: it was fitted in the old millimetres (register again)."""
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
        layout = self._fit.placements
        world = np.ascontiguousarray(self._world * scale)
        if layout is not None:
            # Each board is scaled in its own frame: the poses are refitted with it.
            layout = layout.scaled(scale)
        lens = self._fit.lens if self._fit.lens in LENS_MODELS else "none"
        fit = fit_with_lens(
            world,
            self._image,
            self.solver,
            self.refine,
            lens,
            self.image_size,
            self.intrinsics,
            layout,
        )
        if fit.placements is not None:
            world = fit.placements.plane_points()
        fit.candidates = self._fit.candidates
        fit.note = self._fit.note
        fit = calibration_file.fit_as_loaded(
            fit, world, self._image, self.image_size, self.intrinsics
        )
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
            ids=self.point_ids,
            placement_names=self._placement_names,
            placement_partial=self._placement_partial,
            object_settings=self.object_settings,  # in pixels, which a scale leaves as they are
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
        size = frame_size.given_size((width, height))
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
        if not frame_size.same_aspect(size, self.image_size):
            raise FrameSizeError(
                f"cannot rescale a calibration made on {frame_size.size_text(self.image_size)} "
                f"frames to {frame_size.size_text(size)}: the aspect ratio differs "
                f"({frame_size.aspect_text(size)} against "
                f"{frame_size.aspect_text(self.image_size)}), so the view is cropped, not "
                f"scaled; calibrate again at {size[0]} x {size[1]}",
                size,
                self.image_size,
            )
        return self._scaled(self.image_size, size)

    def _scaled(self, made_on: tuple[int, int], size: tuple[int, int]) -> Calibration:
        """This calibration, made on frames of `made_on`, with every pixel quantity scaled for
        frames of `size` (the same aspect ratio)."""
        s = size[0] / made_on[0]
        a = frame_size.pixel_scaling(s)
        h = a @ self._h  # world -> old pixels -> new pixels; h33 is unchanged
        image = np.ascontiguousarray(frame_size.affine(a, self._image))
        intrinsics = self.intrinsics
        if intrinsics is not None:
            intrinsics = frame_size.scaled_intrinsics(intrinsics, s, size)
        fit = frame_size.scaled_fit(self._fit, h, self._world, image, made_on, size, intrinsics)
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
            self.robot_frame,
            ids=self.point_ids,
            placement_names=self._placement_names,
            placement_partial=self._placement_partial,
            object_settings=self.object_settings.scaled(s, size),
        )
        return cal

    def check_image_size(self, image_size: tuple[int, int], *, what: str = "image") -> None:
        """Raises FrameSizeError, naming both sizes, unless ``image_size`` (width, height, px)
        is the size this calibration was made on: pixels of another size map to the wrong
        millimetres. A calibration that records no size (an old file, or one made from bare
        points) cannot tell, and accepts any. ``what`` names the picture in the message
        ("image", "frame")."""
        size = frame_size.given_size(image_size)
        if self.image_size is None or size == self.image_size:
            return
        raise FrameSizeError(
            frame_size.size_mismatch(size, self.image_size, what), size, self.image_size
        )

    # -- the robot's frame ------------------------------------------------------------------

    def with_robot_frame(self, robot_frame: RobotFrame | None) -> Calibration:
        """This calibration with ``robot_frame`` as its registration to the robot (None: with
        none); a new Calibration, this one unchanged. The registration's board points must be
        in this calibration's board mm (``register`` makes sure of that)."""
        if robot_frame is not None and not isinstance(robot_frame, RobotFrame):
            raise ArgumentError(
                f"robot_frame must be a RobotFrame or None, got {type(robot_frame).__name__}"
            )
        # A copy of everything else as it is (the fit and what was computed from it): only
        # the registration differs, and nothing in the board frame depends on it.
        cal = Calibration.__new__(Calibration)
        cal.__dict__.update(self.__dict__)
        cal.robot_frame = robot_frame
        cal.created = calibration_file.now_stamp()  # another calibration than this one
        return cal

    # -- how objects are detected -----------------------------------------------------------

    def with_object_settings(self, settings: ObjectSettings) -> Calibration:
        """This calibration with ``settings`` as its object-detection settings (area limits,
        region of interest, blur: calib.object_settings), which ``save`` records and
        ``locate_objects``, the ``Tracker`` and the commands use by default; a new
        Calibration, this one unchanged. ``created`` is kept: the mapping is this one's.
        ArgumentError for settings that are not an ObjectSettings, or that this
        calibration's images cannot take (an roi beyond them, a blur wider than them)."""
        if not isinstance(settings, ObjectSettings):
            raise ArgumentError(
                f"settings must be an ObjectSettings, got {type(settings).__name__}"
            )
        settings.check_image_size(self.image_size)
        cal = Calibration.__new__(Calibration)
        cal.__dict__.update(self.__dict__)
        cal.object_settings = settings
        return cal

    def register(
        self,
        robot_mm: ArrayLike,
        *,
        dots: ArrayLike | None = None,
        board_mm: ArrayLike | None = None,
        image_px: ArrayLike | None = None,
        robot_z: ArrayLike | None = None,
        model: Model = "rigid",
        outlier_mm: float | None = None,
        drop_outliers: bool = False,
        handedness: Handedness | None = None,
    ) -> Calibration:
        """This calibration registered to a robot's base frame (a new Calibration with
        ``robot_frame`` set) from point pairs: robot points (N, 2) or (N, 3) with z, in mm,
        each paired with one of

        * ``dots``: the id of the board point (a dot, a corner) the robot's tool touched
          (N,), 0-based as ``board.world_points()`` numbers them (k = row x cols + col from
          the origin point), whether or not the camera saw it (a calibration from several
          placements: the board lying where the reference placement had it, whose frame is
          the plane's);
        * ``board_mm``: the touched points' board positions (N, 2), mm (in the plane's
          frame);
        * ``image_px``: N-point, where the camera saw the part the robot placed (N, 2), px;
          mapped through this calibration, their 1-sigma goes into the fit's noise floor.

        ``model``, ``robot_z``, ``outlier_mm``, ``drop_outliers`` and ``handedness`` as in
        RobotFrame.fit; the board's extent is the area its quality is judged over.
        ArgumentError (an index off the board, malformed points), BoardError (dots, but no
        board recorded), RegistrationError (pairs that cannot fix the model, or touches on one
        line with no hand given)."""
        plane, plane_std, dot_index = plane_points(
            self, dots=dots, board_mm=board_mm, image_px=image_px
        )
        frame = RobotFrame.fit(
            plane,
            robot_mm,
            model=model,
            robot_z=robot_z,
            outlier_mm=outlier_mm,
            drop_outliers=drop_outliers,
            plane_std_mm=plane_std,
            handedness=handedness,
            dots=dot_index,
            work_area_mm=board_extent(self),
        )
        return self.with_robot_frame(frame)

    @property
    def default_frame(self) -> Coords:
        """The frame positions are given in unless a call says otherwise: "robot" once a
        registration is attached, else "board"."""
        return default_frame(self.robot_frame)

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
        out = self._fit.plane.lens.undistort(arr, invalid="nan")
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
        pixel_sigma: float = OUTLINE_CENTROID_SIGMA_PX,
        image_size: tuple[int, int] | None = None,
        frame: Coords = "board",
    ) -> Any:
        """Pixel positions -> plane positions in mm: (N, 2) -> (N, 2), or (2,) -> (2,).

        ``frame``: "board" (the default: the board's mm) or "robot" (the robot's base frame
        through the registration, ``robot_frame.to_robot`` of the board position; an
        ArgumentError if the calibration has none).

        ``image_size``: (width, height) of the image the pixels come from; FrameSizeError if
        the calibration was made on another size (see ``check_image_size``).

        ``height``: the points are ``height`` mm above the plane (an object's top face;
        scalar or one per point), not on it: located where they really are. Needs camera
        intrinsics (``intrinsics=``), which give the camera's position.

        ``return_std=True`` returns ``(mm, std_mm)``: each point's 1-sigma position error
        (sqrt of the covariance's trace: the RMS distance from the truth) from the fit's
        uncertainty and the model's bias (``error_budget``), plus the pixel's own noise of
        ``pixel_sigma`` px per coordinate (default: a part centroid's from the outline
        detector, ``OUTLINE_CENTROID_SIGMA_PX``; 0 for an exact pixel). In the
        robot frame the registration's own error at the point is added in quadrature
        (``RobotFrame.robot_std_mm``).
        """
        registration = (
            self.robot_frame if checked_frame(frame, self.robot_frame) == "robot" else None
        )
        if image_size is not None:
            self.check_image_size(image_size)
        arr = arguments.real_array("points_px", points_px)
        single = arr.ndim == 1
        if single:
            if arr.shape != (2,):
                raise ArgumentError(f"a point must have 2 coordinates, got shape {arr.shape}")
            arr = arr.reshape(1, 2)
        arr = _points(arr, "points_px")
        h = (
            np.broadcast_to(arguments.real_array("height", height), (len(arr),))
            if np.ndim(height) == 0
            else arguments.real_array("height", height)
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
            if registration is not None:
                lifted, _ = board_to_robot(registration, lifted)
            return lifted[0] if single else lifted
        std = std * np.abs(factor)
        if registration is not None:
            lifted, robot_std = board_to_robot(registration, lifted, std)
            assert robot_std is not None
            std = robot_std
        return (lifted[0], float(std[0])) if single else (lifted, std)

    def _frame_mapper(
        self, height: float = 0.0, frame: Coords = "board"
    ) -> Callable[[F64, int], tuple[F64, F64]]:
        """image_to_world(px, height=height, return_std=True, frame=frame) for the production
        loop, its arguments checked here once. The returned function takes an (N, 2) float64
        array of pixels and how many of its first rows need their 1-sigma (a frame's part
        centroids: the points round them are mapped only for the mapping's derivatives, and
        the covariance is most of a point's cost); it goes straight to the core when there is
        nothing to undistort or lift, then through the registration for the robot frame."""
        registration = (
            self.robot_frame if checked_frame(frame, self.robot_frame) == "robot" else None
        )
        if height != 0.0:
            # IntrinsicsError now, rather than on every frame with an object in it.
            _ = self.camera_pose
        plane = self._fit.plane
        direct = self.intrinsics is None and height == 0.0

        def board(px: F64, with_std: int) -> tuple[F64, F64]:
            if direct:
                _, std = plane.image_to_world_std(px[:with_std], OUTLINE_CENTROID_SIGMA_PX)
                return plane.image_to_world(px), std
            _, std = self.image_to_world(px[:with_std], height=height, return_std=True)
            return self.image_to_world(px, height=height), std

        if registration is None:
            return board

        def robot(px: F64, with_std: int) -> tuple[F64, F64]:
            mm, std = board(px, with_std)
            _, robot_std = board_to_robot(registration, mm[:with_std], std)
            assert robot_std is not None
            return registration.to_robot(mm), robot_std

        return robot

    def world_covariance(
        self, points_px: ArrayLike, *, pixel_sigma: float = OUTLINE_CENTROID_SIGMA_PX
    ) -> F64:
        """The 2 x 2 covariance (mm^2) of each point's position on the plane, (N, 2, 2)."""
        arr = _points(points_px, "points_px")
        ideal = self.intrinsics.undistort_points(arr) if self.intrinsics is not None else arr
        return self._fit.plane.world_covariance(ideal, float(pixel_sigma))

    def world_to_image(self, points_mm: ArrayLike) -> F64:
        """Plane positions in mm -> pixel positions (lens included): (N, 2) -> (N, 2), or
        (2,) -> (2,)."""
        arr = arguments.real_array("points_mm", points_mm)
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
        return self._fit.plane.lens.distort(ideal)

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
        if self._fit.lens in LENS_MODELS[1:]:
            return self._fit.loo()
        ideal = (
            self.intrinsics.undistort_points(self._image)
            if self.intrinsics is not None
            else self._image
        )
        return homography_leave_one_out(self._world, ideal, self.solver, self.refine, self._distort)

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
        plane = self._fit.plane
        scale = 1.0
        if self._fit.placements is not None:
            # The leave-one-out refits hold the poses (a point moves its placement's pose by
            # little), so its error is predicted with them held too: the plane's model of the
            # same parameters on the points where the poses put them, at the joint fit's noise.
            held, _ = plane_at(
                self._h,
                self._world,
                self._image,
                self.image_size,
                self._fit.lens,
                plane.lens,
                self.intrinsics,
            )
            scale = held.dof / max(plane.dof, 1)
            plane = held
        try:
            cov = plane.predicted_loo_covariance() * scale
        except LensModelError:
            return np.full(len(self._world), np.nan)
        return np.asarray(np.sqrt(np.trace(cov, axis1=1, axis2=2)), dtype=np.float64)

    @functools.cached_property
    def extrapolation(self) -> Extrapolation | None:
        """Where the calibration's points are in the image and what it predicts beyond them:
        the share of the image their outline covers, and the largest 1-sigma mapping error
        (mm, from the error bars of ``image_to_world(..., return_std=True)``, the pixel
        itself exact) at the points and over the whole image, with where it is largest and a
        grid of the image's 1-sigma for drawing. ``warning`` says when the rest of the image
        is extrapolated well beyond the points' accuracy (a board in one corner of the
        view). None without an image size."""
        if self.image_size is None:
            return None
        return extrapolation(self.mapping_std_mm, self._image, self.image_size)

    def mapping_std_mm(self, points_px: ArrayLike) -> F64:
        """The calibration's own predicted 1-sigma mapping error (mm, RMS distance) at pixels
        (N, 2), the pixel itself exact: what ``image_to_world(..., return_std=True,
        pixel_sigma=0)`` gives, but inf where a pixel has no place on the plane (beyond the
        plane's horizon, as the points see it, or beyond the lens model's reach) instead of
        an error: the map the coverage view (calib.coverage) and ``extrapolation`` draw."""
        px = _points(points_px, "points_px")
        out = np.full(len(px), np.inf)
        if self.intrinsics is not None:
            ideal = self.intrinsics.undistort_points(px, invalid="nan")
            feed = ideal
        else:
            ideal = self._fit.plane.lens.undistort(px, invalid="nan")
            feed = px
        # The points' side of the horizon: H^-1's third coordinate keeps their sign there.
        points_ideal = (
            self.intrinsics.undistort_points(self._image)
            if self.intrinsics is not None
            else self._fit.plane.lens.undistort(self._image, invalid="nan")
        )
        inv = self.H_inv
        w = ideal @ inv[2, :2] + inv[2, 2]
        w_points = points_ideal @ inv[2, :2] + inv[2, 2]
        side = float(np.sign(np.nanmedian(w_points)))
        ok = np.flatnonzero(np.isfinite(ideal).all(axis=1) & (w * side > 0))
        self._std_into(np.ascontiguousarray(feed), ok, out)
        out[~np.isfinite(out)] = np.inf
        return out

    def _std_into(self, feed: F64, rows: NDArray[np.intp], out: F64) -> None:
        """The plane's 1-sigma of `feed[rows]` into `out[rows]`; where the core refuses the
        batch (a pixel beyond the lens model's reach), each half on its own, so that one such
        pixel leaves only itself without a place."""
        if not len(rows):
            return
        try:
            _, std = self._fit.plane.image_to_world_std(feed[rows], 0.0)
            out[rows] = std
        except (HomographyError, LensModelError, ArgumentError):
            if len(rows) > 1:
                half = len(rows) // 2
                self._std_into(feed, rows[:half], out)
                self._std_into(feed, rows[half:], out)

    def describe_lines(self, summary: CalibrationSummary | None = None) -> list[str]:
        """The calibration in a few lines: its board and points, its errors, its lens and,
        for points that cover only part of the image, what the rest is predicted at (what
        ``str(cal.summary())`` prints; the full report is planarcal.report.summary_text)."""
        s = self.summary() if summary is None else summary
        placements = self._fit.placements
        if self.board is None:
            points = f"{s.n_points} points (no board recorded)"
        elif placements is not None:
            points = (
                f"{placements.count} placements of {self.board.describe()}: {s.n_points} "
                f"{self.board.point_name}s (the plane's frame is placement "
                f"{placements.reference}'s board frame)"
            )
        else:
            seen = len(self._world)
            total = self.board.n_points
            name = self.board.point_name
            points = f"{self.board.describe()}: {seen} of its {total} {name}s"
        lines = [
            f"Calibration from {points}",
            f"Reprojection error (px): mean {s.mean_px:.4f}, RMS {s.rms_px:.4f}, "
            f"max {s.max_px:.4f}",
            f"Leave-one-out error (mm): mean {s.loo_mean_mm:.4f}, RMS {s.loo_rms_mm:.4f}, "
            f"max {s.loo_max_mm:.4f} ({s.loo_rms_px:.4f} px RMS)",
            f"Lens: {self.lens_note}",
        ]
        ex = self.extrapolation
        if ex is not None and ex.warning is not None:
            lines.append(f"Warning: {ex.warning}")
        return lines

    def summary(self) -> CalibrationSummary:
        s = self.stats
        dev = np.abs(self.deviations_mm)
        loo = self.loo_errors_mm
        finite = loo[np.isfinite(loo)]
        loo_px = self.loo_errors_px[np.isfinite(self.loo_errors_px)]
        pred = self.predicted_loo_std_mm
        pred = pred[np.isfinite(pred)]
        nan = float("nan")
        ex = self.extrapolation
        summary = CalibrationSummary(
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
            loo_rms_px=float(np.sqrt(np.mean(loo_px**2))) if loo_px.size else nan,
            loo_max_px=float(loo_px.max()) if loo_px.size else nan,
            covered_share=nan if ex is None else ex.covered_share,
            covered_std_mm=nan if ex is None else ex.covered_std_mm,
            image_std_mm=nan if ex is None else ex.image_std_mm,
        )
        # What str(summary) describes; not a field, so no part of to_dict, == or repr.
        object.__setattr__(summary, "_calibration", self)
        return summary

    # -- persistence ------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The versioned, JSON-ready form that save() writes and from_dict() reads."""
        return calibration_file.calibration_to_dict(self)

    @classmethod
    def from_dict(
        cls, data: Any, source: str = "calibration data", *, trust_edits: bool = False
    ) -> Calibration:
        """The calibration saved by to_dict(); CalibrationFileError, naming the field, if it
        is not one: if its homography, lens and points do not reproduce the residuals it
        records, if a value its other values determine does not agree with them, or (a
        version 4 file) if a field is not what it was saved with (its digest).
        ``trust_edits=True`` accepts a file edited on purpose: every check but the digest
        (see ``load``)."""
        # An edited number can overflow on its way to the check that refuses it: the refusal
        # names the problem, and NumPy's warnings about the intermediate values are noise.
        with np.errstate(all="ignore"):
            try:
                c = calibration_file.contents_from_dict(data, source)
                cal = cls.__new__(cls)
                cal._init(
                    c.world,
                    c.image,
                    c.fit,
                    c.solver,
                    c.refine,
                    c.board,
                    c.image_size,
                    c.intrinsics,
                    c.world_scale,
                    c.robot_frame,
                    c.created,
                    ids=c.point_ids,
                    placement_names=c.placement_names,
                    placement_partial=c.placement_partial,
                    object_settings=c.object_settings,
                )
                errors_px = cal.reprojection_errors_px
                calibration_file.check_residuals(errors_px, c.residuals, source)
                calibration_file.check_consistent(cal, data, source)
            except CalibrationFileError:
                raise
            except (ArgumentError, HomographyError, IntrinsicsError, LensModelError) as e:
                # Numbers that pass every check of their own but cannot be used together.
                raise CalibrationFileError(f"{source}: {e}") from None
            except (OverflowError, RecursionError) as e:
                # A dict built in Python, not read from a file (read_file refuses these).
                raise CalibrationFileError(
                    f"{source}: a number too large or a value nested too deeply ({e})"
                ) from None
        if c.version >= calibration_file.DIGEST_SINCE and not trust_edits:
            calibration_file.check_digest(data, source)
        return cal

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Writes the calibration as human-readable JSON, atomically, with the digest of its
        fields. A calibration saved again unchanged (loaded, or the same object) writes the
        same bytes."""
        return calibration_file.write_file(path, self.to_dict())

    @classmethod
    def load(cls, path: str | os.PathLike[str], *, trust_edits: bool = False) -> Calibration:
        """Reads a calibration saved by save(); CalibrationFileError, naming the problem, if
        the file is not one (corrupt, truncated, another format or version), is inconsistent
        (a value its other values determine does not agree) or was edited (its digest).

        ``trust_edits=True`` is for a file changed on purpose (a note, the image size, a
        registration removed): every check is made but the digest's, and ``save`` then
        writes the file with a digest of its own. An edit its other values contradict (a
        point, the board's pitch, a registration's pair) is refused even so: calibrate or
        register again."""
        return cls.from_dict(
            calibration_file.read_file(path),
            source=repr(str(Path(path))),
            trust_edits=trust_edits,
        )

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        # Pickles through the same validated, versioned form as the file.
        return (_from_dict, (self.to_dict(),))

    def __repr__(self) -> str:
        s = self.stats
        registered = "" if self.robot_frame is None else f", registered ({self.robot_frame.model})"
        return (
            f"Calibration({len(self._world)} points, solver={self.solver!r}, "
            f"refine={self.refine}, lens={self.lens_model!r}, mean error {s.mean:.3f} px"
            f"{registered})"
        )


def _from_dict(data: dict[str, Any]) -> Calibration:
    return Calibration.from_dict(data)


def _points(value: ArrayLike, name: str) -> F64:
    arr = np.array(value, dtype=np.float64)
    if arr.ndim == 3 and 1 in arr.shape[:2] and arr.shape[2] == 2:
        arr = arr.reshape(-1, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ArgumentError(f"{name} must have shape (N, 2), got {arr.shape}")
    return np.ascontiguousarray(arr)


def _positive_mm(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise BoardError(f"{name} must be a number of mm, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise BoardError(f"{name} must be a positive, finite number of mm, got {value!r}")
    return v


def _point_ids(board: Board, world: F64, world_scale: tuple[float, float]) -> NDArray[np.intp]:
    """The board's ids of the world points; BoardError naming a point that is no point of the
    board (another board's description, or points of another board)."""
    ids, problem = match_board_points(board, world, world_scale)
    if problem is not None or ids is None:
        raise BoardError(f"the points do not belong to the board: {problem}")
    return ids
