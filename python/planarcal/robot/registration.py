"""RobotFrame: the registration of the calibrated plane (board mm) to a robot's base frame
(robot mm), fitted from touch points, with everything a user needs to trust it or redo it:
per-point residuals, leave-one-out errors, the touches named as outliers, the handedness, with
z the plane's height and tilt in the robot frame, and the transform's own 1-sigma error at any
board point (``std_mm``), to carry a position's uncertainty into the robot frame."""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal.errors import ArgumentError, CalibrationFileError, RegistrationError
from planarcal.robot.handedness import (
    MIN_HAND_Z,
    Handedness,
    check_hand_determined,
    hand_margin,
    mirrored_of,
)
from planarcal.robot.outliers import MAX_OUTLIERS, OutlierSearch, find_outliers, leave_one_out
from planarcal.robot.plane_height import PlaneHeight, fit_plane_height, tilt_warnings
from planarcal.robot.prediction_error import (
    noise_sigma_mm,
    parameter_covariance,
    prediction_std_mm,
)
from planarcal.robot.summary import registration_summary
from planarcal.robot.touch_pairs import DEFAULT_POINT_NAME, PointIds, checked_point_name
from planarcal.robot.transform_fit import (
    F64,
    MODELS,
    Model,
    apply,
    check_geometry,
    fit,
    fit_hand,
)

# What to_dict writes and from_dict reads.
FORMAT = "planarcal.robot_frame"
VERSION = 1
# How far a stored transform may differ from the refit of its stored pairs (relative).
STORED_TRANSFORM_TOLERANCE = 1e-6
# The smallest ratio of the fitted linear part's singular values: below it the map has no
# usable inverse (robot_to_plane).
MIN_SINGULAR_RATIO = 1e-6
# The largest coordinate (mm) a pair may have: 1 km is beyond any robot cell, and it keeps the
# fit's sums of squares far from overflow.
MAX_COORDINATE_MM = 1e6


def _frozen(a: ArrayLike) -> F64:
    out = np.array(a, dtype=np.float64)
    out.setflags(write=False)
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class RobotFrame:
    """A fitted map board mm -> robot mm (use ``RobotFrame.fit``).

    ``plane_to_robot`` and ``robot_to_plane`` are 3 x 3 affine matrices (last row 0 0 1);
    ``reflected`` says the map mirrors (the board's frame and the robot's are of opposite
    handedness); ``rotation_deg`` (the angle of the rotation after any mirroring of the board's
    y axis) and ``scale`` are None for an affine model. Per point (in the order given):
    ``residuals_mm`` under the fit, ``leave_one_out_mm`` under the fit of the other points
    used (for a dropped outlier, its error under the fit). ``rms_mm``, ``max_mm`` and
    ``leave_one_out_rms_mm`` are over the points used. ``outliers`` names the points whose
    leave-one-out error exceeded ``outlier_threshold_mm``; ``dropped_outliers`` says whether
    the fit left them out. ``plane`` is the plane's height and tilt when z was given.
    ``plane_std_mm`` is each board point's own 1-sigma error (RMS distance, mm) where the
    board points were measured rather than known (N-point pairs mapped from pixels), else
    None. ``handedness`` is the hand given to the fit ("right", "left"; None: the touches'),
    ``dots`` the board point id of each pair when the pairs were given as ids (the table and
    the messages name the pairs by them; the field keeps its name, and the file's, for every
    board), ``point_name`` what the board calls its points ("dot" on a circle grid, "corner"
    on a chessboard or ChArUco board: "corner 12"), ``work_area_mm`` the corners ((x0, y0), (x1,
    y1)) of the board area the map serves (the board's extent; None: the touched points'),
    where the judgement looks at the map's own error. ``outlier_search_capped``: the outlier
    search stopped after MAX_OUTLIERS removals with a touch still above the threshold."""

    model: Model
    reflected: bool
    plane_to_robot: F64
    robot_to_plane: F64
    rotation_deg: float | None
    scale: float | None
    plane_mm: F64
    robot_mm: F64
    robot_z_mm: F64 | None
    residuals_mm: F64
    leave_one_out_mm: F64
    rms_mm: float
    max_mm: float
    leave_one_out_rms_mm: float
    outliers: tuple[int, ...]
    dropped_outliers: bool
    outlier_mm: float | None
    outlier_threshold_mm: float
    plane: PlaneHeight | None
    warnings: tuple[str, ...]
    plane_std_mm: F64 | None = None
    handedness: Handedness | None = None
    dots: tuple[int, ...] | None = None
    work_area_mm: F64 | None = None
    outlier_search_capped: bool = False
    point_name: str = DEFAULT_POINT_NAME

    @classmethod
    def fit(
        cls,
        plane_mm: ArrayLike,
        robot_mm: ArrayLike,
        *,
        model: Model = "rigid",
        robot_z: ArrayLike | None = None,
        outlier_mm: float | None = None,
        drop_outliers: bool = False,
        plane_std_mm: ArrayLike | None = None,
        handedness: Handedness | None = None,
        dots: ArrayLike | None = None,
        work_area_mm: ArrayLike | None = None,
        point_name: str | None = None,
    ) -> RobotFrame:
        """The registration fitted to pairs of board points (N, 2) and robot points (N, 2),
        or (N, 3) with z (or z as ``robot_z``), all in mm. ``outlier_mm`` is the leave-one-out
        error above which a point is named an outlier (default max(1 mm, 5 x the median
        leave-one-out error of the other points without it); ``drop_outliers`` refits without
        them. ``plane_std_mm`` (N,): the board points' own 1-sigma errors (mm) where they were
        measured (N-point pairs: image px mapped through the calibration); they set a floor
        under the touch noise that ``std_mm`` assumes. ``handedness``: the robot frame's hand
        with z up from the table, "right" (a mirrored map: the usual) or "left" (not
        mirrored), for rigid and similarity; None takes it from the touches, which must then
        lie off one line by well over their noise (RegistrationError otherwise, naming the
        touches at the line's ends). ``dots`` (N,): the board point id of each pair, for
        the table and the messages. ``point_name``: what the board calls its points
        (``board.point_name``: "dot", "corner"), the word the table and the messages use;
        None: the name ``dots`` carries (touch_pairs.PointIds, as Calibration.register gives
        them), else "dot". ``work_area_mm``: points (K, 2) whose bounding box is the
        area the map serves (the board's extent), where the judgement (``quality``) looks at
        the map's own error. ArgumentError for malformed arguments, RegistrationError for
        pairs that cannot fix the model."""
        if model not in MODELS:
            raise ArgumentError(f"model must be one of {', '.join(MODELS)}, got {model!r}")
        if not isinstance(drop_outliers, bool):
            raise ArgumentError(f"drop_outliers must be True or False, got {drop_outliers!r}")
        mirrored = mirrored_of(handedness)
        threshold_given = (
            None if outlier_mm is None else arguments.positive("outlier_mm", outlier_mm)
        )
        plane, robot, z = _pairs(plane_mm, robot_mm, robot_z)
        plane_std = _plane_std(plane_std_mm, len(plane))
        name = _point_name(point_name, dots)
        dot_index = _dots(dots, len(plane), name)
        area = _work_area(work_area_mm)
        check_geometry(plane, robot, model)
        try:
            fitted = _Fitted.of(plane, robot, model, mirrored, threshold_given, drop_outliers)
            fitted.check_hand(plane, plane_std, mirrored, _namer(dot_index, name), name)
        except (np.linalg.LinAlgError, FloatingPointError, OverflowError) as e:
            # A safeguard: _pairs bounds the coordinates, so this is not a path.
            raise RegistrationError(f"the point pairs cannot be fitted ({e})") from None
        matrix, used = fitted.matrix, fitted.used
        rotation_deg, scale = _rotation_and_scale(matrix, model, fitted.reflected)
        height = None if z is None else fit_plane_height(robot[used], z[used])
        warnings = (
            *tilt_warnings(height, z is not None),
            *fitted.hand_warnings(plane, robot, mirrored),
            *_capped_warning(fitted.search),
        )
        return cls(
            model=model,
            reflected=fitted.reflected,
            plane_to_robot=_frozen(matrix),
            robot_to_plane=_frozen(np.linalg.inv(matrix)),
            rotation_deg=rotation_deg,
            scale=scale,
            plane_mm=_frozen(plane),
            robot_mm=_frozen(robot),
            robot_z_mm=None if z is None else _frozen(z),
            residuals_mm=_frozen(fitted.residuals),
            leave_one_out_mm=_frozen(fitted.loo),
            rms_mm=float(np.sqrt(np.mean(fitted.residuals[used] ** 2))),
            max_mm=float(fitted.residuals[used].max()),
            leave_one_out_rms_mm=float(np.sqrt(np.mean(fitted.loo[used] ** 2))),
            outliers=fitted.search.outliers,
            dropped_outliers=drop_outliers,
            outlier_mm=threshold_given,
            outlier_threshold_mm=fitted.search.threshold_mm,
            plane=height,
            warnings=warnings,
            plane_std_mm=None if plane_std is None else _frozen(plane_std),
            handedness=handedness,
            dots=dot_index,
            work_area_mm=None if area is None else _frozen(area),
            outlier_search_capped=fitted.search.capped,
            point_name=name,
        )

    def pair_name(self, index: int) -> str:
        """How the table and the messages name pair ``index``: "dot k" or "corner k" (its
        board point, by ``point_name``) when the pairs were given as ids, else "touch i" (its
        row, from 0)."""
        return _namer(self.dots, self.point_name)(index)

    def with_point_name(self, point_name: str) -> RobotFrame:
        """This registration with the board's points called ``point_name`` ("dot",
        "corner") in its table and messages; the fit is unchanged."""
        return dataclasses.replace(self, point_name=checked_point_name(point_name))

    @property
    def used(self) -> NDArray[np.bool_]:
        """A boolean mask (N,) of the points the fit used."""
        mask = np.ones(len(self.plane_mm), dtype=np.bool_)
        if self.dropped_outliers:
            mask[list(self.outliers)] = False
        return mask

    def to_robot(self, points_mm: ArrayLike) -> F64:
        """Board points (..., 2) in mm as robot points (..., 2) in mm."""
        flat, lead = arguments.points("points_mm", points_mm)
        return apply(self.plane_to_robot, flat).reshape(*lead, 2)

    def to_plane(self, robot_mm: ArrayLike) -> F64:
        """Robot points (..., 2) in mm as board points (..., 2) in mm."""
        flat, lead = arguments.points("robot_mm", robot_mm)
        return apply(self.robot_to_plane, flat).reshape(*lead, 2)

    @functools.cached_property
    def _covariance(self) -> tuple[F64, F64, float]:
        used = self.used
        return parameter_covariance(
            self.plane_to_robot,
            self.plane_mm[used],
            self.robot_mm[used],
            self.model,
            self.reflected,
            None if self.plane_std_mm is None else self.plane_std_mm[used],
        )

    @property
    def noise_mm(self) -> float:
        """The touch noise (mm per coordinate) the fit assumes: from its residuals, and at
        least the floor of a robot's repeatability plus the board points' own error."""
        return self._covariance[2]

    @property
    def distance_gain(self) -> float:
        """The most a distance on the board grows in the robot frame: 1 for rigid, the scale
        for similarity, the largest singular value of the linear part for affine."""
        if self.model == "rigid":
            return 1.0
        return float(np.linalg.svd(self.plane_to_robot[:2, :2], compute_uv=False)[0])

    def std_mm(self, points_mm: ArrayLike) -> F64:
        """The transform's own 1-sigma error (RMS distance, mm) at board points (..., 2) in
        mm: from the fit's parameter covariance and the touch noise (``noise_mm``). Smallest
        near the touched points' centroid, growing away from it."""
        flat, lead = arguments.points("points_mm", points_mm)
        centre, cov, _ = self._covariance
        std = prediction_std_mm(self.plane_to_robot, centre, cov, flat, self.model, self.reflected)
        return std.reshape(lead)

    @property
    def corners_mm(self) -> F64:
        """The four corners (4, 2) of the area the judgement covers: ``work_area_mm``, or the
        bounding box of the touched points used."""
        box = self.work_area_mm
        if box is None:
            used = self.plane_mm[self.used]
            box = np.array([used.min(axis=0), used.max(axis=0)])
        (x0, y0), (x1, y1) = box
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])

    @functools.cached_property
    def corner_std_mm(self) -> float:
        """The map's own 1-sigma (mm) at the worst corner of the area it serves
        (``corners_mm``): how well the touches' layout fixes it where parts will be."""
        return float(self.std_mm(self.corners_mm).max())

    def robot_std_mm(self, points_mm: ArrayLike, board_std_mm: ArrayLike) -> F64:
        """The 1-sigma error (RMS distance, mm) in the robot frame of board points (..., 2)
        known to ``board_std_mm`` (...): the board error carried through the map (unchanged
        by a rigid one, which keeps distances; scaled by ``distance_gain`` otherwise, an upper
        bound for affine) and the transform's own error (``std_mm``), in quadrature."""
        own = self.std_mm(points_mm)
        try:
            board = np.broadcast_to(np.asarray(board_std_mm, dtype=np.float64), own.shape)
        except (TypeError, ValueError):
            raise ArgumentError(
                f"board_std_mm must be one number per point, shape {own.shape}, got "
                f"{np.shape(board_std_mm)}"
            ) from None
        out: F64 = np.sqrt((self.distance_gain * board) ** 2 + own**2)
        return out

    def summary(self, lines: Sequence[int] | None = None) -> str:
        """The transform, the residual table and the fit's quality in words, with what to do
        if it is poor; ``lines`` (N,): each pair's line in the file it came from, a column of
        the table."""
        return registration_summary(self, lines)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict: the pairs and the options (what from_dict refits: the model, the
        outlier options, the hand given, the dots and the work area), the transform and the
        fit's measures (what from_dict checks and a reader can see)."""

        def number(x: float) -> float | None:
            return x if math.isfinite(x) else None

        return {
            "format": FORMAT,
            "version": VERSION,
            "model": self.model,
            "outlier_mm": self.outlier_mm,
            "drop_outliers": self.dropped_outliers,
            "plane_mm": self.plane_mm.tolist(),
            "robot_mm": self.robot_mm.tolist(),
            "robot_z_mm": None if self.robot_z_mm is None else self.robot_z_mm.tolist(),
            "reflected": self.reflected,
            "plane_to_robot": self.plane_to_robot.tolist(),
            "rotation_deg": self.rotation_deg,
            "scale": self.scale,
            "residuals_mm": self.residuals_mm.tolist(),
            "leave_one_out_mm": [number(x) for x in self.leave_one_out_mm.tolist()],
            "rms_mm": self.rms_mm,
            "max_mm": self.max_mm,
            "leave_one_out_rms_mm": number(self.leave_one_out_rms_mm),
            "outliers": list(self.outliers),
            "outlier_threshold_mm": self.outlier_threshold_mm,
            "plane": None if self.plane is None else self.plane.to_dict(),
            "warnings": list(self.warnings),
            "plane_std_mm": None if self.plane_std_mm is None else self.plane_std_mm.tolist(),
            "handedness": self.handedness,
            "dots": None if self.dots is None else list(self.dots),
            "work_area_mm": None if self.work_area_mm is None else self.work_area_mm.tolist(),
            "outlier_search_capped": self.outlier_search_capped,
            "corner_std_mm": number(self.corner_std_mm),
        }

    @classmethod
    def from_dict(
        cls, data: Any, source: str = "the registration", *, point_name: str | None = None
    ) -> RobotFrame:
        """The registration a dict from to_dict describes: refitted from its pairs and checked
        against its stored transform; CalibrationFileError if it is malformed, of another
        version, or does not hold together. ``point_name``: what the calibration's board
        calls its points (the file does not store it: its fields are those of every board),
        "dot" if None."""
        if not isinstance(data, dict):
            raise CalibrationFileError(f"{source} is not a registration (not a JSON object)")
        if data.get("format") != FORMAT or data.get("version") != VERSION:
            raise CalibrationFileError(
                f"{source} is not a {FORMAT} version {VERSION} (format "
                f"{data.get('format')!r}, version {data.get('version')!r})"
            )
        try:
            frame = cls.fit(
                data["plane_mm"],
                data["robot_mm"],
                model=data["model"],
                robot_z=data["robot_z_mm"],
                outlier_mm=data["outlier_mm"],
                drop_outliers=data["drop_outliers"],
                plane_std_mm=data.get("plane_std_mm"),
                # Absent from files written before they existed (which refit as before).
                handedness=data.get("handedness"),
                dots=data.get("dots"),
                work_area_mm=data.get("work_area_mm"),
                point_name=point_name,
            )
            stored = np.asarray(data["plane_to_robot"], dtype=np.float64)
            reflected, outliers = data["reflected"], data["outliers"]
        except KeyError as e:
            raise CalibrationFileError(f"{source} is missing the field {e}") from None
        except (ArgumentError, RegistrationError, TypeError, ValueError) as e:
            raise CalibrationFileError(f"{source}: {e}") from None
        tolerance = STORED_TRANSFORM_TOLERANCE * max(1.0, float(np.abs(frame.plane_to_robot).max()))
        if (
            stored.shape != (3, 3)
            or not np.all(np.abs(stored - frame.plane_to_robot) <= tolerance)
            or reflected != frame.reflected
            or outliers != list(frame.outliers)
        ):
            raise CalibrationFileError(
                f"{source}: the stored transform, handedness or outliers are not those of its "
                "point pairs (edited or corrupt)"
            )
        return frame


def _pairs(
    plane_mm: ArrayLike, robot_mm: ArrayLike, robot_z: ArrayLike | None
) -> tuple[F64, F64, F64 | None]:
    """The board points (N, 2), robot points (N, 2) and z (N,) or None, checked."""
    plane, lead = arguments.points("plane_mm", plane_mm)
    if len(lead) != 1:
        raise ArgumentError(f"plane_mm must have shape (N, 2), got {np.shape(plane_mm)}")
    robot_all = arguments.real_array(
        "robot_mm", robot_mm, what="an array of (x, y) or (x, y, z) points"
    )
    if robot_all.ndim != 2 or robot_all.shape[1] not in (2, 3):
        raise ArgumentError(f"robot_mm must have shape (N, 2) or (N, 3), got {robot_all.shape}")
    robot, _ = arguments.points("robot_mm", robot_all[:, :2])
    z = robot_all[:, 2] if robot_all.shape[1] == 3 else None
    if robot_z is not None:
        if z is not None:
            raise ArgumentError("z given twice: as robot_mm's third column and as robot_z")
        z = arguments.real_array("robot_z", robot_z, what="an array of N heights")
        if z.shape != (len(robot),):
            raise ArgumentError(f"robot_z must have shape ({len(robot)},), got {z.shape}")
    if z is not None and not np.isfinite(z).all():
        k = int(np.flatnonzero(~np.isfinite(z))[0])
        raise ArgumentError(f"robot z of point {k} is not finite: {z[k]!r}", k)
    if len(plane) != len(robot):
        raise ArgumentError(
            f"plane_mm and robot_mm must pair up: {len(plane)} board points, "
            f"{len(robot)} robot points"
        )
    for name, values in (("plane_mm", plane), ("robot_mm", robot), ("robot z", z)):
        _check_bounded(name, values)
    return plane, robot, z


def _check_bounded(name: str, values: F64 | None) -> None:
    """ArgumentError for a coordinate beyond MAX_COORDINATE_MM, naming its point."""
    if values is None or not values.size:
        return
    size = np.abs(values).reshape(len(values), -1).max(axis=1)
    if size.max() > MAX_COORDINATE_MM:
        k = int(np.argmax(size > MAX_COORDINATE_MM))
        raise ArgumentError(
            f"{name}: point {k} is {float(size[k]):.3g} mm from the origin, beyond any robot "
            f"cell ({MAX_COORDINATE_MM:g} mm at most): check the units and the columns",
            k,
        )


def _plane_std(value: ArrayLike | None, n: int) -> F64 | None:
    """The board points' own 1-sigma errors (N,), checked: finite and >= 0."""
    if value is None:
        return None
    std = arguments.real_array("plane_std_mm", value, what="an array of N errors in mm")
    if std.shape != (n,):
        raise ArgumentError(f"plane_std_mm must have shape ({n},), got {std.shape}")
    bad = np.flatnonzero(~(np.isfinite(std) & (std >= 0)))
    if bad.size:
        k = int(bad[0])
        raise ArgumentError(f"plane_std_mm of point {k} must be finite and >= 0: {std[k]!r}", k)
    return std


def _rotation_and_scale(
    matrix: F64, model: Model, reflected: bool
) -> tuple[float | None, float | None]:
    # The linear part is scale x R(theta) x diag(1, -1 if reflected): undo the mirror, read
    # the angle of the rotation left.
    if model == "affine":
        return None, None
    linear = matrix[:2, :2] @ np.diag([1.0, -1.0 if reflected else 1.0])
    angle = math.degrees(math.atan2(linear[1, 0], linear[0, 0]))
    scale = float(math.hypot(linear[0, 0], linear[1, 0]))
    return angle, (1.0 if model == "rigid" else scale)


def _point_name(given: str | None, dots: ArrayLike | None) -> str:
    """The word for the board's points: the one given, else the one the ids carry."""
    if given is not None:
        return checked_point_name(given)
    return dots.point_name if isinstance(dots, PointIds) else DEFAULT_POINT_NAME


def _dots(value: ArrayLike | None, n: int, point_name: str) -> tuple[int, ...] | None:
    """The board point id of each pair (N,), checked: whole numbers >= 0 (not bools)."""
    if value is None:
        return None
    try:
        items = np.asarray(value, dtype=object)
    except (TypeError, ValueError):
        raise ArgumentError(f"dots must be a list of N {point_name} indices") from None
    if items.shape != (n,):
        raise ArgumentError(f"dots must have shape ({n},), got {items.shape}")
    out = []
    for i, v in enumerate(items.tolist()):
        whole = isinstance(v, int | np.integer) and not isinstance(v, bool | np.bool_)
        if not whole or v < 0:
            raise ArgumentError(
                f"dots: {v!r} (pair {i}) is not a {point_name} index (a whole number)", i
            )
        out.append(int(v))
    return tuple(out)


def _work_area(value: ArrayLike | None) -> F64 | None:
    """The bounding box ((x0, y0), (x1, y1)) of the points (K, 2) given, or None."""
    if value is None:
        return None
    flat, _ = arguments.points("work_area_mm", value)
    if not len(flat):
        raise ArgumentError("work_area_mm must hold at least one point")
    _check_bounded("work_area_mm", flat)
    return np.array([flat.min(axis=0), flat.max(axis=0)])


def _namer(dots: tuple[int, ...] | None, point_name: str) -> Callable[[int], str]:
    """How messages name pair i: by its board point ("dot 7", "corner 7"), else by its row."""
    if dots is None:
        return lambda i: f"touch {i}"
    return lambda i: f"{point_name} {dots[i]}"


def _capped_warning(search: OutlierSearch) -> tuple[str, ...]:
    if not search.capped:
        return ()
    return (
        f"the outlier search stopped after naming {MAX_OUTLIERS} touches with more still "
        "above the threshold: not every wrong touch is named, and so many look like pairs "
        "mispaired as a whole (the order of the points, the board's origin, the units)",
    )


@dataclasses.dataclass(frozen=True)
class _Fitted:
    """The fit's steps: the outlier search, the fit of the points used, and each point's
    residual (``residual_xy`` (N, 2), ``residuals`` (N,)) and leave-one-out error."""

    model: Model
    search: OutlierSearch
    used: NDArray[np.bool_]
    matrix: F64
    reflected: bool
    residual_xy: F64
    residuals: F64
    loo: F64

    @classmethod
    def of(
        cls,
        plane: F64,
        robot: F64,
        model: Model,
        mirrored: bool | None,
        outlier_mm: float | None,
        drop_outliers: bool,
    ) -> _Fitted:
        search = find_outliers(plane, robot, model, outlier_mm, mirrored)
        used = np.ones(len(plane), dtype=bool)
        if drop_outliers:
            used[list(search.outliers)] = False
        matrix, reflected = fit_hand(plane[used], robot[used], model, mirrored)
        _check_invertible(matrix)
        residual_xy = apply(matrix, plane) - robot
        residuals = np.hypot(*residual_xy.T)
        loo = residuals.copy()  # a dropped point's fit is already the fit without it
        loo[used] = leave_one_out(plane[used], robot[used], model, reflected)
        return cls(model, search, used, matrix, reflected, residual_xy, residuals, loo)

    @property
    def trusted(self) -> NDArray[np.bool_]:
        """The points not named outliers (dropped or not)."""
        mask = np.ones(len(self.residuals), dtype=bool)
        mask[list(self.search.outliers)] = False
        return mask

    def check_hand(
        self,
        plane: F64,
        plane_std: F64 | None,
        mirrored: bool | None,
        name: Callable[[int], str],
        point_name: str,
    ) -> None:
        """RegistrationError unless the touches not named outliers fix the hand (or it was
        given), or when an affine fit's hand is not the one given; the board's points called
        ``point_name``."""
        trusted = self.trusted
        sigma = noise_sigma_mm(
            self.residual_xy[trusted], self.model, None if plane_std is None else plane_std[trusted]
        )
        index = np.flatnonzero(trusted)
        check_hand_determined(
            apply(self.matrix, plane[trusted]),
            sigma,
            self.model,
            mirrored is not None,
            lambda k: name(int(index[k])),
            point_name,
        )
        if self.model == "affine" and mirrored is not None and self.reflected != mirrored:
            raise RegistrationError(
                f"the touches give an affine map that {_mirrors(self.reflected)}, but the hand "
                f"given says it {_mirrors(mirrored)}: check the pairs and the hand"
            )

    def hand_warnings(self, plane: F64, robot: F64, mirrored: bool | None) -> tuple[str, ...]:
        """A warning when the touches fix the other hand than the one given."""
        if mirrored is None or self.model == "affine":  # affine's hand is checked
            return ()
        p, q = plane[self.used], robot[self.used]
        other = fit(p, q, self.model, not mirrored)
        other_xy = apply(other, p) - q
        other_rms = float(np.sqrt(np.mean(np.sum(other_xy**2, axis=1))))
        given_rms = float(np.sqrt(np.mean(self.residuals[self.used] ** 2)))
        sigma = noise_sigma_mm(other_xy, self.model)
        if other_rms >= given_rms or hand_margin(apply(other, p), sigma) < MIN_HAND_Z:
            return ()
        return (
            f"the touches show the other hand: a map that {_mirrors(not mirrored)} fits them "
            f"with an RMS of {other_rms:.3g} mm, the hand given ({_mirrors(mirrored)}) with "
            f"{given_rms:.3g} mm; check the hand given",
        )


def _check_invertible(matrix: F64) -> None:
    """RegistrationError for a map that flattens the board (robot points on a line under
    board points that are not, or pairs that do not correspond): it has no inverse."""
    s = np.linalg.svd(matrix[:2, :2], compute_uv=False)
    if not s[1] > MIN_SINGULAR_RATIO * s[0]:
        raise RegistrationError(
            f"the fitted map flattens the board (its linear part's singular values "
            f"{s[0]:.3g} and {s[1]:.3g}): the robot points do not follow the board points "
            "(robot points on a line, or pairs that do not correspond); check the pairing"
        )


def _mirrors(mirrored: bool) -> str:
    return "mirrors" if mirrored else "does not mirror"
