"""A plane calibration: the homography between the work plane (mm) and the image (px), with
everything the paper reports about it, and the honest accuracy estimate it does not.

H maps world millimetres to image pixels (the paper's Eq. 3); image -> world goes through
H^-1 (its Eq. 8). The default fit is the most accurate (the normalised DLT refined by
Levenberg-Marquardt: the maximum-likelihood estimate for pixel noise); ``solver="a33",
refine=False`` reproduces the paper's own estimator.
"""

from __future__ import annotations

import dataclasses
import datetime
import functools
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import _core
from planarcal.board import CircleGridBoard
from planarcal.errors import BoardError, CalibrationFileError, HomographyError
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
FILE_VERSION = 1


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

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


class Calibration:
    """The plane's homography and its report.

    Build one from matched points (``Calibration(world_mm, image_px)``), from a detection
    (``Calibration.from_detection``) or straight from an image of the board
    (``Calibration.from_image``); save it with ``save`` and read it back with
    ``Calibration.load``. It pickles, so it travels to worker processes.
    """

    def __init__(
        self,
        world_points: ArrayLike,
        image_points: ArrayLike,
        *,
        solver: Solver = "normalized_dlt",
        refine: bool = True,
        board: CircleGridBoard | None = None,
        image_size: tuple[int, int] | None = None,
    ) -> None:
        world = _points(world_points, "world_points")
        image = _points(image_points, "image_points")
        if len(world) != len(image):
            raise HomographyError(
                f"world_points and image_points must match one to one, got {len(world)} "
                f"and {len(image)}"
            )
        if solver not in SOLVERS:
            raise HomographyError(f"solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
        h = estimate_homography(world, image, solver, bool(refine))
        self._init(world, image, h, solver, bool(refine), board, image_size)

    def _init(
        self,
        world: F64,
        image: F64,
        h: F64,
        solver: Solver,
        refine: bool,
        board: CircleGridBoard | None,
        image_size: tuple[int, int] | None,
    ) -> None:
        self._world = world
        self._image = image
        self._h = h
        self._h.setflags(write=False)
        self._world.setflags(write=False)
        self._image.setflags(write=False)
        self.solver: Solver = solver
        self.refine = refine
        self.board = board
        self.image_size = None if image_size is None else (int(image_size[0]), int(image_size[1]))

    # -- construction from images ---------------------------------------------------------

    @classmethod
    def from_detection(
        cls, detection: Any, *, solver: Solver = "normalized_dlt", refine: bool = True
    ) -> Calibration:
        """The calibration of a BoardDetection (planarcal.detect_board's result)."""
        return cls(
            detection.world_points(),
            detection.image_points,
            solver=solver,
            refine=refine,
            board=detection.board,
            image_size=detection.image_size,
        )

    @classmethod
    def from_image(
        cls,
        image: Any,
        board: CircleGridBoard,
        *,
        solver: Solver = "normalized_dlt",
        refine: bool = True,
        polarity: str = "auto",
    ) -> Calibration:
        """Detects `board` in `image` (array or path) and calibrates from it."""
        from planarcal.detect import detect_board

        detection = detect_board(image, board, polarity=polarity)  # type: ignore[arg-type]
        return cls.from_detection(detection, solver=solver, refine=refine)

    # -- the homography and the mapping -----------------------------------------------------

    @property
    def H(self) -> F64:
        """World (mm) -> image (px), 3 x 3, read-only."""
        return self._h

    @functools.cached_property
    def H_inv(self) -> F64:
        """Image (px) -> world (mm), 3 x 3, read-only: H^-1 (the paper's Eq. 8)."""
        inv = np.asarray(np.linalg.inv(self._h), dtype=np.float64)
        # Scaled like H (|h33| = 1), keeping the orientation the true inverse has.
        if abs(inv[2, 2]) > 0:
            inv /= abs(inv[2, 2])
        inv.setflags(write=False)
        return inv

    @property
    def world_points(self) -> F64:
        return self._world

    @property
    def image_points(self) -> F64:
        return self._image

    def image_to_world(self, points_px: ArrayLike) -> F64:
        """Pixel positions -> plane positions in mm: (N, 2) -> (N, 2), or (2,) -> (2,)."""
        return _map(self._h, points_px, inverse=True)

    def world_to_image(self, points_mm: ArrayLike) -> F64:
        """Plane positions in mm -> pixel positions: (N, 2) -> (N, 2), or (2,) -> (2,)."""
        return _map(self._h, points_mm, inverse=False)

    # -- the paper's report -------------------------------------------------------------------

    @functools.cached_property
    def reprojected_px(self) -> F64:
        """Each world point mapped into the image (the paper's Table 3)."""
        return transform_points(self._h, self._world)

    @functools.cached_property
    def reprojection_errors_px(self) -> F64:
        """||image_i - H world_i|| per point, in px (the paper's Eq. 6, Table 3)."""
        return reprojection_errors(self._h, self._world, self._image)

    @functools.cached_property
    def stats(self) -> ReprojectionStats:
        """Mean (Eq. 7), RMS, max and min of the reprojection errors, px."""
        return error_stats(self.reprojection_errors_px)

    @functools.cached_property
    def world_after_mm(self) -> F64:
        """Each image point mapped back to the plane (the paper's Table 4), mm."""
        return transform_points(self._h, self._image, inverse=True)

    @functools.cached_property
    def deviations_mm(self) -> F64:
        """dX, dY of the world coordinates after calibration (the paper's Table 4), mm."""
        return self.world_after_mm - self._world

    @functools.cached_property
    def loo_deviations_mm(self) -> F64:
        """Leave-one-out: where each image point lands on the plane under a fit made without
        it, minus where it is (dX, dY in mm). The honest estimate of mapping accuracy at a
        point the calibration has not seen; the residuals flatter the fit."""
        n = len(self._world)
        if n <= 4:
            # Without one point only 3 remain: no homography can be fitted.
            return np.full((n, 2), np.nan)
        out = np.empty((n, 2))
        keep = np.ones(n, dtype=bool)
        for i in range(n):
            keep[i] = False
            try:
                h = estimate_homography(
                    self._world[keep], self._image[keep], self.solver, self.refine
                )
                out[i] = (
                    transform_points(h, self._image[i : i + 1], inverse=True)[0] - self._world[i]
                )
            except HomographyError:
                out[i] = np.nan  # the rest cannot determine a homography
            keep[i] = True
        return out

    @functools.cached_property
    def loo_errors_mm(self) -> F64:
        """Leave-one-out error per point, mm (NaN where the others cannot be fitted)."""
        return np.hypot(self.loo_deviations_mm[:, 0], self.loo_deviations_mm[:, 1])

    def summary(self) -> CalibrationSummary:
        s = self.stats
        dev = np.abs(self.deviations_mm)
        loo = self.loo_errors_mm
        finite = loo[np.isfinite(loo)]
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
        if version != FILE_VERSION:
            raise CalibrationFileError(
                f"{source} is calibration file version {version!r}; this planarcal "
                f"({_core.__version__}) reads version {FILE_VERSION}"
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
        cal = cls.__new__(cls)
        cal._init(
            world, image, h, solver, refine, board, None if size is None else (size[0], size[1])
        )
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
            f"refine={self.refine}, mean error {s.mean:.3f} px)"
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
        raise HomographyError(f"{name} must have shape (N, 2), got {arr.shape}")
    return np.ascontiguousarray(arr)


def _map(h: F64, points: ArrayLike, *, inverse: bool) -> F64:
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim == 1:
        if arr.shape != (2,):
            raise HomographyError(f"a point must have 2 coordinates, got shape {arr.shape}")
        return np.asarray(transform_points(h, arr.reshape(1, 2), inverse=inverse)[0], np.float64)
    return transform_points(h, arr, inverse=inverse)
