"""The calibration file: the versioned JSON form of a Calibration (what ``to_dict`` writes and
``from_dict`` reads), which versions this planarcal reads, and the checks that turn a corrupt,
truncated or foreign file into a CalibrationFileError rather than a wrong calibration.

Version 3 adds ``robot_frame``: the registration to the robot (RobotFrame.to_dict: the model,
the point pairs, the residuals), or null; refitted from its pairs on load and refused if the
stored transform is not theirs. Versions 1 and 2 have none and load without one.

Version 4 adds ``digest``: the SHA-256 of each other field's canonical JSON, so that a file
edited by hand is refused, naming the field, even where the edit leaves it consistent (an
image size, a dot diameter, a note). Files of every version are also checked for consistency:
each value the others determine (a lens's standard errors, the registration's residuals, the
world points as the board's dots) is re-derived and must agree, so that a file whose digest
was recomputed still cannot carry a value its other fields contradict. Versions 1 to 3
predate the digest and load on those checks alone.

Version 5 reads every board type: ``board`` is the board's ``to_dict()`` with its ``type``
("circles", "chessboard" or "charuco"; planarcal.calib.boards.board_from_dict reads it), and
``points.ids`` the board's ids of the points (0-based indices into the board's points: all of
them for a whole board, those seen for a partial view; null without a board), re-derived
from the world points on load. Its summary adds the points' coverage of the image and the
predicted error beyond them (calib.extrapolation). A version 4 file's board is a circle grid
(no ``type``); it loads as before.

Version 6 adds ``placements``: for a calibration from several placements of the board
(Calibration.from_detections), the reference placement, each placement's name, image size,
number of points, whether it is a partial view and its fitted in-plane pose, and
``point_placement``, the placement of each point (null for a calibration from one view). Its
world points are in the plane's frame: each must be its board point (``points.ids``) carried
by its placement's pose, and the homography, lens and poses must reproduce the residuals the
file records; the covariance (the error bars) is rebuilt with the poses free, as fitted.

Version 7 adds ``object_settings``: how objects are detected in this camera's images
(ObjectSettings.to_dict: ``min_area_px``, ``max_area_px``, ``roi`` as [x, y, width, height]
and ``blur_sigma``, each null for detect_objects' default), covered by the digest like every
field, checked for its types and ranges and against the image size on load. Files of
versions 1 to 6 load with the defaults (every setting null)."""

from __future__ import annotations

import dataclasses
import datetime
import functools
import hashlib
import json
import math
import os
import re
import reprlib
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from planarcal import _core
from planarcal._core import RadialLens
from planarcal.bounded_read import read_regular_file
from planarcal.calib.board import MAX_BOARD_DOTS_PER_SIDE
from planarcal.calib.board_points import POINT_TOLERANCE_REL, match_board_points
from planarcal.calib.boards import BOARD_TYPES, Board, board_from_dict
from planarcal.calib.json_number import is_json_int, is_json_real, json_number
from planarcal.calib.lens_candidate import LensCandidate
from planarcal.calib.lens_model import LENS_MODELS
from planarcal.calib.object_settings import ObjectSettings
from planarcal.calib.placement_file import placements_from_dict, placements_to_dict
from planarcal.calib.placements import PlacementLayout
from planarcal.calib.plane_fit import PlaneFit, plane_at
from planarcal.camera import CameraIntrinsics
from planarcal.camera.intrinsics import MAX_IMAGE_SIDE_PX
from planarcal.errors import (
    ArgumentError,
    BoardError,
    CalibrationFileError,
    HomographyError,
    IntrinsicsError,
    LensModelError,
)
from planarcal.file_formats import CALIBRATION_FORMAT
from planarcal.files import atomic_write
from planarcal.homography import SOLVERS, Solver, error_stats
from planarcal.robot.registration import RobotFrame
from planarcal.robot.transform_fit import apply

if TYPE_CHECKING:
    # Only a type here: calibration imports this module to read and write itself.
    from planarcal.calib.calibration import Calibration

F64 = NDArray[np.float64]

FILE_FORMAT = CALIBRATION_FORMAT
FILE_VERSION = 7
READS_VERSIONS = (1, 2, 3, 4, 5, 6, 7)
ROBOT_FRAME_SINCE = 3
DIGEST_SINCE = 4
BOARD_TYPES_SINCE = 5
"""The first version whose board has a type (and points their ids)."""
PLACEMENTS_SINCE = 6
"""The first version that records placements."""
OBJECT_SETTINGS_SINCE = 7
"""The first version that records the object-detection settings."""

SUMMARY_SINCE_5 = ("covered_share", "covered_std_mm", "image_std_mm")
"""The summary's fields a version 5 file adds (the points' coverage of the image)."""

BOARD_FIELD_TYPES: dict[str, dict[str, str]] = {
    "circles": {
        "cols": "count",
        "rows": "count",
        "pitch_mm": "mm",
        "diameter_mm": "mm or null",
        "origin_marker": "bool",
        "marker_diameter_mm": "mm or null",
        "layout": "str",
    },
    "chessboard": {"cols": "count", "rows": "count", "square_mm": "mm", "origin_marker": "bool"},
    "charuco": {
        "squares_x": "count",
        "squares_y": "count",
        "square_mm": "mm",
        "marker_mm": "mm",
        "dictionary": "str",
        "legacy": "bool or null",
    },
}
"""Each board type's fields in a file and their JSON types (the board checks their values)."""

FIELDS = (
    "format",
    "version",
    "created",
    "planarcal_version",
    "solver",
    "refine",
    "homography_world_mm_to_image_px",
    "lens_model",
    "lens",
    "lens_note",
    "lens_candidates",
    "intrinsics",
    "world_scale",
    "image_size_px",
    "board",
    "points",
    "summary",
    "robot_frame",
    "placements",
    "object_settings",
    "digest",
)
"""Every field of a version 7 file, in the order written; older versions wrote some of
them."""
ALWAYS = ("solver", "refine", "homography_world_mm_to_image_px", "points")
"""The fields every version has."""

EDIT_HINT = (
    "a calibration is changed by planarcal (calibrate or register again); to keep an edit "
    "made on purpose: planarcal check {path} --accept-edits "
    "(docs/guides/calibrating.md, Calibration files)"
)
"""What a refusal by the digest adds: how to change a file (``{path}``: the file's)."""

MAX_FILE_BYTES = 16 * 2**20
"""The largest calibration file read: one of the paper's board is 30 kB, one of a 100 x 100
dot board with its registration about 1 MB; beyond that it is not a calibration."""

MAX_INT_DIGITS = 309
"""Integers longer than this are beyond a float's range (1.8e308): no field holds one."""

RESIDUAL_TOLERANCE_PX = 1e-6
RESIDUAL_TOLERANCE_REL = 1e-6
"""How closely a loaded calibration must reproduce the residuals its file records (see
check_residuals)."""

ROBOT_TOLERANCE_MM = 1e-6
"""How closely a registration's stored transform must agree with its refit (see
_robot_frame): rounding is some 1e-13 mm."""

DERIVED_TOLERANCE_REL = 1e-6
DERIVED_TOLERANCE_ABS = 1e-9
"""How closely a value a file stores must agree with its re-derivation from the file's other
values (see check_consistent): the same arithmetic on the same numbers agrees to some 1e-12
relative; the margin is for another platform's rounding or iterations, and is far below
anything an edit that matters changes."""

MAX_ROBOT_MM = 1e9
"""The largest number of mm a registration holds (a robot reaches metres; 10^9 mm is a
thousand km): beyond it a refit or its error bars overflow, and the file could not be saved
again."""

IMAGE_MARGIN = 0.1
"""How far beyond the image (a share of its side) an image point may lie: dots detected lie
inside it; an image size swapped or cut puts a board's points far outside."""

__all__ = ["POINT_TOLERANCE_REL"]  # where it was; it lives with the matching, board_points
# A dict or file with these is camera intrinsics (OpenCV's, ROS's, or CameraIntrinsics'
# to_dict), not a calibration: the message says where it belongs.
INTRINSICS_KEYS = ("camera_matrix", "cameraMatrix", "K")
INTRINSICS_HINT = (
    "looks like camera intrinsics ({kind}), not a planarcal calibration: pass it with "
    "--intrinsics; a calibration is the JSON file `planarcal "
    "calibrate` writes"
)
_INTRINSICS_NODE = re.compile(
    r"^\s*(?:camera_matrix|cameraMatrix|K)\s*:|<(?:camera_matrix|cameraMatrix|K)[\s>]", re.M
)
_YAML_KEY = re.compile(r"^[A-Za-z_][\w-]*\s*:(?:\s|$)", re.M)


@dataclasses.dataclass(frozen=True)
class FileContents:
    """A calibration file's contents, checked: what Calibration is built from."""

    world: F64
    image: F64
    fit: PlaneFit
    solver: Solver
    refine: bool
    board: Board | None
    image_size: tuple[int, int] | None
    intrinsics: CameraIntrinsics | None
    world_scale: tuple[float, float]
    residuals: StoredResiduals
    robot_frame: RobotFrame | None = None
    created: str | None = None
    version: int = FILE_VERSION
    point_ids: NDArray[np.intp] | None = None
    placement_names: tuple[str, ...] = ()
    placement_partial: tuple[bool, ...] = ()
    object_settings: ObjectSettings = dataclasses.field(default_factory=ObjectSettings)


@dataclasses.dataclass(frozen=True)
class StoredResiduals:
    """The reprojection errors a file says its homography leaves at its points (its
    summary's mean, RMS, max and min, px): what check_residuals holds the loaded
    calibration to."""

    mean_px: float
    rms_px: float
    max_px: float
    min_px: float


def calibration_to_dict(
    cal: Calibration, *, summary: bool = True, version: int = FILE_VERSION
) -> dict[str, Any]:
    """The versioned, JSON-ready form of `cal` (Calibration.to_dict), with its digest.
    ``summary=False`` leaves out the summary (its leave-one-out errors are the costly part)
    and the digest: what check_consistent compares a file with, in the form of the file's
    ``version`` (a version 4 file's board has no type, its points no ids).
    CalibrationFileError if a value cannot be written (not a finite number), naming it."""
    typed = version >= BOARD_TYPES_SINCE
    points: dict[str, Any] = {}
    if typed:
        points["ids"] = None if cal.point_ids is None else [int(i) for i in cal.point_ids]
    points["world_mm"] = cal.world_points.tolist()
    points["image_px"] = cal.image_points.tolist()
    content: dict[str, Any] = {
        "format": FILE_FORMAT,
        "version": version,
        "created": cal.created,
        "planarcal_version": _core.__version__,
        "solver": cal.solver,
        "refine": cal.refine,
        "homography_world_mm_to_image_px": cal.H.tolist(),
        "lens_model": cal.lens_model,
        "lens": None if cal.lens is None else cal.lens.to_dict(),
        "lens_note": cal.lens_note,
        "lens_candidates": [c.to_dict() for c in cal.lens_candidates],
        "intrinsics": None if cal.intrinsics is None else cal.intrinsics.to_dict(),
        "world_scale": list(cal.world_scale),
        "image_size_px": None if cal.image_size is None else list(cal.image_size),
        "board": None if cal.board is None else board_to_dict(cal.board, typed),
        "points": points,
    }
    if summary:
        figures = cal.summary().to_dict()
        if not typed:
            figures = {k: v for k, v in figures.items() if k not in SUMMARY_SINCE_5}
        content["summary"] = {k: json_number(v) for k, v in figures.items()}
    content["robot_frame"] = None if cal.robot_frame is None else cal.robot_frame.to_dict()
    if version >= PLACEMENTS_SINCE:
        content["placements"] = placements_to_dict(cal)
    if version >= OBJECT_SETTINGS_SINCE:
        content["object_settings"] = cal.object_settings.to_dict()
    # A board that does not describe the points, or points beyond the image (the API takes
    # both: Calibration(world, image, board=..., image_size=...)), would be refused on load
    # as edited.
    problem = image_points_problem(cal.image_points, cal.image_size)
    if problem is None and cal.board is not None and cal._fit.placements is None:
        problem = board_points_problem(cal.board, cal.world_points, cal.world_scale)
    if problem is not None:
        raise CalibrationFileError(f"the calibration cannot be saved: {problem}")
    bad = _first_non_finite(content)
    if bad is not None:
        raise CalibrationFileError(
            f"the calibration cannot be saved: {bad} is not a finite number (a value beyond "
            "a float's range went into it)"
        )
    # What a reader parses: tuples become lists, NumPy's floats Python's.
    content = json.loads(json.dumps(content))
    if summary:
        content["digest"] = {"sha256": field_digests(content)}
    return content


def board_to_dict(board: Board, typed: bool = True) -> dict[str, Any]:
    """The board as a file holds it: its ``to_dict()`` with its ``type`` first (a circle
    grid's to_dict has none); without it (`typed` False) as a version 4 file, whose board is
    always a circle grid."""
    data = {k: v for k, v in board.to_dict().items() if k != "type"}
    return {"type": board.kind, **data} if typed else data


def now_stamp() -> str:
    """The time now as a file's ``created`` writes it (ISO 8601, UTC, whole seconds); the
    time SOURCE_DATE_EPOCH gives (seconds since 1970, the reproducible-builds convention)
    when it is set, so that two runs on the same images write the same file to the bit."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    if epoch.isdigit() and len(epoch) <= 12:
        at = datetime.datetime.fromtimestamp(int(epoch), datetime.timezone.utc)
    else:
        at = datetime.datetime.now(datetime.timezone.utc)
    return at.isoformat(timespec="seconds")


def field_digests(data: dict[str, Any]) -> dict[str, str]:
    """The SHA-256 (hex) of each field of `data` but the digest, of its canonical JSON
    ({"key": value} with sorted keys, no spaces, UTF-8): what a version 4 file's ``digest``
    holds. A field per digest, so that a refusal names the field edited."""
    out = {}
    for key, value in data.items():
        if key == "digest":
            continue
        text = json.dumps(
            {key: value},
            sort_keys=True,
            separators=(",", ":"),
            ensure_ascii=False,
            allow_nan=False,
        )
        out[key] = hashlib.sha256(text.encode("utf-8")).hexdigest()
    return out


def contents_from_dict(data: Any, source: str) -> FileContents:
    """The calibration a file's parsed JSON holds; CalibrationFileError if it is not one
    (`source` names it in the messages). Every field is checked for its JSON type (a number
    is an int or a float, never a bool or a string), its shape and its range before use, and
    the fields of its version must all be there, with none of another's."""
    if not isinstance(data, dict):
        raise CalibrationFileError(
            f"{source} is not a calibration (not a JSON object but {_json_type(data)})"
        )
    version = _check_format(data, source)
    _check_fields(data, version, source)
    h_data = _field(data, "homography_world_mm_to_image_px", source)
    h = _reals(h_data, (3, 3), source, "the homography is not a finite 3 x 3 matrix")
    points = _field(data, "points", source)
    if not isinstance(points, dict):
        raise CalibrationFileError(f"{source}: points must be a JSON object, got {_show(points)}")
    world, image = (
        _reals(_field(points, key, source, "points."), (None, 2), source, f"points.{key}")
        for key in ("world_mm", "image_px")
    )
    if len(world) != len(image) or len(world) < 4:
        raise CalibrationFileError(
            f"{source}: {len(world)} world and {len(image)} image points (need 4 or more, "
            "as many of each)"
        )
    with np.errstate(all="ignore"):  # a determinant of huge entries is inf: not singular
        singular = abs(np.linalg.det(h)) == 0
    if singular:
        raise CalibrationFileError(f"{source}: the homography is singular")
    solver = _field(data, "solver", source)
    if not isinstance(solver, str) or solver not in SOLVERS:
        raise CalibrationFileError(
            f"{source}: unknown solver {_show(solver)} (one of {', '.join(SOLVERS)})"
        )
    refine = _field(data, "refine", source)
    if not isinstance(refine, bool):
        raise CalibrationFileError(f"{source}: refine must be true or false, got {_show(refine)}")
    image_size = _image_size(data.get("image_size_px"), source)
    _check_in_image(image, image_size, source)
    # Each placement is one view of the board; their points together may outnumber it.
    one_view = len(world) if data.get("placements") is None else 0
    board = _board(data.get("board"), one_view, version, source)
    placed = placements_from_dict(
        data.get("placements"), board, points.get("ids"), len(world), image_size, source
    )
    if placed is None:
        fit, intrinsics, world_scale = _fit_from_dict(data, h, world, image, image_size, source)
        point_ids = _check_on_board(board, world, world_scale, source)
        _check_ids(points.get("ids"), point_ids, board, version, source)
    else:
        assert board is not None
        point_ids = placed.ids
        world_scale = _world_scale(data, source)
        layout = placed.layout(board, world_scale)
        _check_placed_points(layout, world, source)
        fit, intrinsics, world_scale = _fit_from_dict(
            data, h, world, image, image_size, source, layout
        )
    robot_frame = _robot_frame(
        data.get("robot_frame"), source, None if board is None else board.point_name
    )
    settings = _object_settings(data.get("object_settings"), image_size, source)
    return FileContents(
        world,
        image,
        fit,
        solver,
        refine,
        board,
        image_size,
        intrinsics,
        world_scale,
        _stored_residuals(data, len(world), source),
        robot_frame,
        _created(data, version, source),
        version,
        point_ids,
        () if placed is None else placed.names,
        () if placed is None else placed.partial,
        settings,
    )


def check_consistent(cal: Calibration, data: dict[str, Any], source: str) -> None:
    """CalibrationFileError unless every value the file stores that the calibration it
    describes re-derives (a lens's standard errors, the board as to_dict writes it, the whole
    registration but its pairs, the summary's counts, names and deviations) agrees with it,
    of the same JSON type and to DERIVED_TOLERANCE_REL: a value edited, or one that overflows
    when re-derived (a file that could not be saved again), is named. Files of version 4 must
    also have every field to_dict writes, and no other, at every level."""
    version = data.get("version")
    strict = is_json_int(version) and version >= DIGEST_SINCE
    derived = calibration_to_dict(
        cal, summary=False, version=version if is_json_int(version) else FILE_VERSION
    )
    for key, value in derived.items():
        if key in ("format", "version", "created", "planarcal_version") or key not in data:
            continue
        _agree(data[key], value, key, strict, source)
    _check_summary(
        cal, data["summary"], strict, version if is_json_int(version) else FILE_VERSION, source
    )


def check_digest(data: dict[str, Any], source: str) -> None:
    """CalibrationFileError unless a version 4 file's digest is that of its fields: each
    field is named that is not what the file was saved with (edited by hand?)."""
    digest = data.get("digest")
    stored = digest.get("sha256") if isinstance(digest, dict) else None
    if not (isinstance(digest, dict) and isinstance(stored, dict) and len(digest) == 1):
        raise CalibrationFileError(
            f'{source}: its digest is not a digest ({{"sha256": {{field: hex}}}}) but '
            f"{_show(digest)}: edited by hand? {_edit_hint(source)}"
        )
    try:
        actual = field_digests(data)
    except (TypeError, ValueError) as e:
        raise CalibrationFileError(f"{source}: holds a value JSON cannot ({e})") from None
    edited = [k for k in actual if stored.get(k) != actual[k]]
    edited += [k for k in stored if k not in actual]
    if edited:
        names = ", ".join(edited)
        raise CalibrationFileError(
            f"{source}: {names} {'is' if len(edited) == 1 else 'are'} not what the file was "
            f"saved with (its digest does not match): edited by hand? {_edit_hint(source)}"
        )


def _edit_hint(source: str) -> str:
    # `source` is the file's name as repr writes it ('calib.json'), or a description of a
    # dict (from_dict's "calibration data"), for which the command names a file.
    path = source if source[:1] in "'\"" else "'calib.json'"
    return EDIT_HINT.format(path=path)


def fit_as_loaded(
    fit: PlaneFit,
    world: F64,
    image: F64,
    size: tuple[int, int] | None,
    intrinsics: CameraIntrinsics | None,
) -> PlaneFit:
    """`fit` as loading its file gives it: a radial lens's model rebuilt at its parameters
    (the fit's own carries its iterations' last digits, which a file does not keep), so that
    a calibration maps, reports and saves the same before and after a save: a re-save of an
    unchanged calibration is the same file, byte for byte. A homography alone, or with
    intrinsics, is built the same way either way."""
    if fit.lens not in LENS_MODELS[1:] and fit.placements is None:
        return fit
    plane, layout = plane_at(
        fit.h, world, image, size, fit.lens, fit.plane.lens, intrinsics, fit.placements
    )
    return PlaneFit(plane, fit.h, fit.lens, fit.candidates, fit.note, placements=layout)


def board_points_problem(board: Board, world: F64, world_scale: tuple[float, float]) -> str | None:
    """What is wrong with world points `world` as points of `board` (scaled by
    `world_scale`, see Calibration.rescaled), or None: each must lie on its own point of the
    board (calib.board_points). A board described otherwise than the points (another pitch,
    layout or size) is another calibration."""
    return match_board_points(board, world, world_scale)[1]


def image_points_problem(image: F64, size: tuple[int, int] | None) -> str | None:
    """What is wrong with image points `image` as pixels of images of `size` (width,
    height), or None: each must lie within the image (pixel centres at whole numbers, so
    from -0.5 to width - 0.5), give or take IMAGE_MARGIN of its side (points made by a
    model rather than detected may stray a little)."""
    if size is None:
        return None
    side = np.array([size[0], size[1]], dtype=np.float64)
    low, high = -0.5 - IMAGE_MARGIN * side, side - 0.5 + IMAGE_MARGIN * side
    outside = np.flatnonzero(~np.all((image >= low) & (image <= high), axis=1))
    if not outside.size:
        return None
    k = int(outside[0])
    return (
        f"image point {k} ({image[k][0]:g}, {image[k][1]:g}) px lies outside the "
        f"{size[0]} x {size[1]} px image"
    )


def write_file(path: str | os.PathLike[str], data: dict[str, Any]) -> Path:
    """Writes `data` (calibration_to_dict's) as human-readable JSON, atomically."""
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    return atomic_write(path, text)


def read_file(path: str | os.PathLike[str]) -> Any:
    """The parsed JSON of the file at `path`; CalibrationFileError if it cannot be read, is
    not JSON (saying what it looks like instead: camera intrinsics, another YAML or XML
    file), or holds what no calibration can (NaN, numbers beyond a float, nesting too deep)."""
    name = str(Path(path))
    raw = read_regular_file(path, "calibration file", MAX_FILE_BYTES, CalibrationFileError)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise CalibrationFileError(
            f"{name!r} is not valid JSON (corrupt, or not a calibration?): it is not UTF-8 text"
        ) from None
    foreign = _foreign_text(text)
    if foreign is not None:
        raise CalibrationFileError(f"{name!r} {foreign}")
    try:
        return json.loads(
            text,
            parse_constant=functools.partial(_refuse_constant, name),
            parse_int=functools.partial(_bounded_int, name),
        )
    except CalibrationFileError:
        raise
    except json.JSONDecodeError as e:
        what = "the file is empty" if not text.strip() else str(e)
        raise CalibrationFileError(
            f"{name!r} is not valid JSON (corrupt or truncated?): {what}"
        ) from None
    except RecursionError:
        raise CalibrationFileError(
            f"{name!r} is not a calibration: its JSON is nested too deeply to read"
        ) from None


def check_residuals(errors_px: F64, stored: StoredResiduals, source: str) -> None:
    """CalibrationFileError unless the loaded calibration's reprojection errors (each point's,
    px, lens included) are those its file states: a homography, lens and points that do not
    belong together (points moved, a matrix edited) would otherwise load as a valid
    calibration and map wrongly.

    The file's figures were computed from these very numbers, which JSON keeps exactly
    (17 significant digits), by the same arithmetic: a faithful file reproduces them to
    rounding, about 1e-12 px. RESIDUAL_TOLERANCE_PX plus RESIDUAL_TOLERANCE_REL of the stored
    figure leaves a margin for another platform's summation order or the lens model's
    iterations, and is still far below any edit that changes a mapping (a thousandth of a
    pixel)."""
    stats = error_stats(errors_px)
    for name, got, want in (
        ("mean", stats.mean, stored.mean_px),
        ("RMS", stats.rms, stored.rms_px),
        ("max", stats.max, stored.max_px),
        ("min", stats.min, stored.min_px),
    ):
        if not abs(got - want) <= RESIDUAL_TOLERANCE_PX + RESIDUAL_TOLERANCE_REL * want:
            worst = int(np.argmax(errors_px))
            raise CalibrationFileError(
                f"{source}: its homography, lens (or intrinsics) and points do not belong "
                "together: they "
                f"leave a {name} reprojection error of {got:.6g} px where its summary records "
                f"{want:.6g} px (summary.{name.lower()}_px), the worst at point {worst} "
                f"({errors_px[worst]:.6g} px); the file was edited or is corrupt"
            )


# -- what a file holds, checked field by field ---------------------------------------------


def _check_format(data: dict[str, Any], source: str) -> int:
    """The file's version; CalibrationFileError unless `data` says it is a calibration of a
    version read here; a dict of camera intrinsics, or of no known format, is named as such."""
    if "format" not in data:
        if any(k in data for k in INTRINSICS_KEYS):
            raise CalibrationFileError(f"{source} {INTRINSICS_HINT.format(kind='JSON')}")
        raise CalibrationFileError(
            f'{source} is a JSON file but not a planarcal calibration (no "format" field); '
            "make one with `planarcal calibrate`"
        )
    file_format = data["format"]
    if file_format != FILE_FORMAT:
        raise CalibrationFileError(
            f"{source} is a JSON file but not a planarcal calibration (its format is "
            f"{_show(file_format)}, not {FILE_FORMAT!r}); make one with `planarcal calibrate`"
        )
    version = data.get("version")
    if not is_json_int(version) or version not in READS_VERSIONS:
        raise CalibrationFileError(
            f"{source} is calibration file version {_show(version)}; this planarcal "
            f"({_core.__version__}) reads versions "
            f"{', '.join(str(v) for v in READS_VERSIONS)}"
        )
    return int(version)


def _check_fields(data: dict[str, Any], version: int, source: str) -> None:
    """CalibrationFileError for a field no version writes, a field of a later version than
    the file's (a digest or a registration in an older file: its version was edited), or a
    missing one of those its version always writes (a version 3 file's robot_frame, every
    field of a version 4 file)."""
    since = {
        "robot_frame": ROBOT_FRAME_SINCE,
        "digest": DIGEST_SINCE,
        "placements": PLACEMENTS_SINCE,
        "object_settings": OBJECT_SETTINGS_SINCE,
    }
    for key in FIELDS if version >= DIGEST_SINCE else ALWAYS:
        if key != "summary" and version >= since.get(key, 0):  # summary: _stored_residuals
            _field(data, key, source)
    for key, first in since.items():
        # A null registration (or placements) is none, as in the versions before it.
        null_is_none = key in ("robot_frame", "placements") and data.get(key) is None
        if key in data and version < first and not null_is_none:
            raise CalibrationFileError(
                f"{source}: a version {version} file has no {key} (files have one from "
                f"version {first}): its version was edited?"
            )
        if key not in data and version >= first:
            raise CalibrationFileError(
                f"{source} is missing the field {key} (a version {version} file always has "
                "it: null where there is none)"
            )
    for key in data:
        if key not in FIELDS:
            raise CalibrationFileError(
                f"{source}: unknown field {_show(key)} (not one a calibration file has: "
                "edited by hand?)"
            )


def _created(data: dict[str, Any], version: int, source: str) -> str | None:
    """When the calibration was made (ISO 8601), kept through a re-save; None for a file
    without one."""
    created = data.get("created")
    if created is None and version < DIGEST_SINCE:
        return None
    try:
        if not isinstance(created, str) or len(created) > 64:
            raise ValueError
        datetime.datetime.fromisoformat(created)
    except ValueError:
        raise CalibrationFileError(
            f"{source}: created must be the time it was made (ISO 8601, as "
            f"{now_stamp()!r}), got {_show(created)}"
        ) from None
    version_text = data.get("planarcal_version")
    if not (isinstance(version_text, str) or (version_text is None and version < DIGEST_SINCE)):
        raise CalibrationFileError(
            f"{source}: planarcal_version must be a string, got {_show(version_text)}"
        )
    return created


def _check_in_image(image: F64, size: tuple[int, int] | None, source: str) -> None:
    problem = image_points_problem(image, size)
    if problem is not None:
        raise CalibrationFileError(
            f"{source}: points.image_px: {problem} (image_size_px): the image size or the "
            "points were edited"
        )


def _check_on_board(
    board: Board | None, world: F64, world_scale: tuple[float, float], source: str
) -> NDArray[np.intp] | None:
    """The board's ids of the world points (the board's points scaled by world_scale), or
    None without a board; CalibrationFileError unless each is a point of the board, and
    unless world_scale is 1 without a board (only rescaled sets it)."""
    if board is None:
        if world_scale != (1.0, 1.0):
            raise CalibrationFileError(
                f"{source}: world_scale {list(world_scale)} without a board (a scale corrects "
                "a board's pitch: it is [1.0, 1.0] without one)"
            )
        return None
    ids, problem = match_board_points(board, world, world_scale)
    if problem is not None or ids is None:
        raise CalibrationFileError(
            f"{source}: points.world_mm: {problem}: board (its size, pitch or layout), "
            "world_scale or the points were edited"
        )
    return ids


def _check_ids(
    stored: Any,
    ids: NDArray[np.intp] | None,
    board: Board | None,
    version: int,
    source: str,
) -> None:
    """CalibrationFileError unless a version 5 file's points.ids are the ids of the board
    points its world points lie on (null without a board); check_consistent names any other
    difference (a missing or extra field)."""
    if version < BOARD_TYPES_SINCE:
        return
    if ids is None or board is None:
        if stored is not None:
            raise CalibrationFileError(
                f"{source}: points.ids {_show(stored)} without a board (board is null): the "
                "board or the points were edited"
            )
        return
    if not (isinstance(stored, list) and len(stored) == len(ids) and all(map(is_json_int, stored))):
        raise CalibrationFileError(
            f"{source}: points.ids must be a list of {len(ids)} point ids (whole numbers), "
            f"got {_show(stored)}"
        )
    differ = np.flatnonzero(np.asarray(stored, dtype=object) != ids)
    if differ.size:
        k = int(differ[0])
        raise CalibrationFileError(
            f"{source}: points.ids[{k}] is {_show(stored[k])} but world point {k} lies on "
            f"{board.point_name} {int(ids[k])} of the board ({board.describe()}): board, "
            "world_scale or the points were edited"
        )


def _field(data: dict[str, Any], key: str, source: str, prefix: str = "") -> Any:
    if key not in data:
        raise CalibrationFileError(f"{source} is missing the field {prefix}{key}")
    return data[key]


def _image_size(size: Any, source: str) -> tuple[int, int] | None:
    """image_size_px: null, or [width, height] in whole pixels up to MAX_IMAGE_SIDE_PX."""
    if size is None:
        return None
    if (
        not isinstance(size, list | tuple)
        or len(size) != 2
        or not all(is_json_int(v) and 1 <= v <= MAX_IMAGE_SIDE_PX for v in size)
    ):
        raise CalibrationFileError(
            f"{source}: image_size_px must be [width, height], two whole numbers of pixels "
            f"from 1 to {MAX_IMAGE_SIDE_PX}, got {_show(size)}"
        )
    return int(size[0]), int(size[1])


def _board(board_data: Any, n_points: int, version: int, source: str) -> Board | None:
    """The board, or None: its type (a version 4 file's is a circle grid, and says none), its
    fields' JSON types checked (the board checks their values, MAX_BOARD_DOTS_PER_SIDE a side
    at most), and at least the file's points."""
    if board_data is None:
        return None
    if not isinstance(board_data, dict):
        raise CalibrationFileError(f"{source}: board must be a JSON object or null")
    kind = board_data.get("type", "circles")
    if version < BOARD_TYPES_SINCE and kind != "circles":
        # (A version 4 file's check_consistent names a "type" even of "circles".)
        raise CalibrationFileError(
            f"{source}: a version {version} file's board is a circle grid, not "
            f"{_show(kind)} (board types come with version {BOARD_TYPES_SINCE}): its version "
            "was edited?"
        )
    if not (isinstance(kind, str) and kind in BOARD_FIELD_TYPES):
        raise CalibrationFileError(
            f"{source}: board.type must be one of {', '.join(BOARD_TYPES)}, got {_show(kind)}"
        )
    for key, want in BOARD_FIELD_TYPES[kind].items():
        value = board_data.get(key)
        if value is None and key not in board_data and key in ("origin_marker", "layout"):
            continue  # written since version 2 (their defaults before)
        if not _json_type_is(value, want):
            raise CalibrationFileError(
                f"{source}: board.{key} must be {_TYPE_WORDS[want]}, got {_show(value)}"
            )
    try:
        board = board_from_dict(board_data)
    except BoardError as e:
        raise CalibrationFileError(f"{source}: board: {e}") from None
    if board.n_points < n_points:
        raise CalibrationFileError(
            f"{source}: the board has {board.n_points} {board.point_name}s "
            f"({board.describe()}) but the file {n_points} points"
        )
    return board


_TYPE_WORDS = {
    "count": f"a whole number from 2 to {MAX_BOARD_DOTS_PER_SIDE}",
    "mm": "a number of mm",
    "mm or null": "a number of mm or null",
    "bool": "true or false",
    "bool or null": "true, false or null",
    "str": "a string",
}


def _json_type_is(value: Any, want: str) -> bool:
    """Whether a board field's JSON value is of the kind `want` (a key of _TYPE_WORDS)."""
    if want == "count":
        return is_json_int(value) and 2 <= value <= MAX_BOARD_DOTS_PER_SIDE
    if want == "mm":
        return is_json_real(value)
    if want == "mm or null":
        return value is None or is_json_real(value)
    if want == "bool":
        return isinstance(value, bool)
    if want == "bool or null":
        return value is None or isinstance(value, bool)
    return isinstance(value, str)


def _object_settings(
    settings_data: Any, size: tuple[int, int] | None, source: str
) -> ObjectSettings:
    """The object-detection settings (the defaults for a file before version 7, which
    _check_fields makes sure has none): of their JSON types and ranges, and usable on images
    of the file's size (an roi within them)."""
    if settings_data is None:
        return ObjectSettings()
    try:
        settings = ObjectSettings.from_dict(settings_data)
        settings.check_image_size(size)
    except ArgumentError as e:
        raise CalibrationFileError(f"{source}: object_settings: {e} (edited or corrupt)") from None
    return settings


def _robot_frame(robot_data: Any, source: str, point_name: str | None) -> RobotFrame | None:
    """The registration to the robot, or None: refitted from its pairs by RobotFrame.from_dict,
    whose check of the stored transform lets each entry differ by 1e-6 of the largest (with a
    250 mm translation, 2.5e-4 in the rotation's entries: 0.075 mm 300 mm from the origin).
    Here the stored transform must put the pairs' board points where the refitted one does to
    ROBOT_TOLERANCE_MM: a pair edited by a fraction of a millimetre would otherwise move every
    robot position silently. ``point_name``: what the board calls its points ("dot",
    "corner"), for the registration's table and messages (the file does not store it)."""
    if robot_data is None:
        return None
    _check_robot_values(robot_data, source)
    where = f"{source}: robot_frame (its registration to the robot)"
    frame = RobotFrame.from_dict(robot_data, where, point_name=point_name)
    stored = np.asarray(robot_data["plane_to_robot"], dtype=np.float64)  # checked 3 x 3
    drift = float(np.abs(apply(stored, frame.plane_mm) - frame.to_robot(frame.plane_mm)).max())
    if not drift <= ROBOT_TOLERANCE_MM:
        raise CalibrationFileError(
            f"{where}: its stored transform puts its board points up to {drift:.3g} mm from "
            "where its point pairs put them (edited or corrupt)"
        )
    return frame


def _check_robot_values(robot_data: Any, source: str) -> None:
    """CalibrationFileError unless the registration's pairs and options are of their JSON
    types and shapes (RobotFrame.from_dict would take the string "1" or true as 1.0) and
    within MAX_ROBOT_MM (beyond it a refit overflows, and the file could not be saved)."""
    if not isinstance(robot_data, dict):
        raise CalibrationFileError(
            f"{source}: robot_frame must be a JSON object or null, got {_show(robot_data)}"
        )
    plane = _robot_reals(robot_data, "plane_mm", (None, 2), source)
    n = len(plane)
    rows = robot_data.get("robot_mm")
    width = len(rows[0]) if isinstance(rows, list) and rows and isinstance(rows[0], list) else 2
    _robot_reals(robot_data, "robot_mm", (n, 3 if width == 3 else 2), source)
    for key in ("robot_z_mm", "plane_std_mm"):
        if robot_data.get(key) is not None:
            _robot_reals(robot_data, key, (n,), source)
    _reals(
        _field(robot_data, "plane_to_robot", source, "robot_frame."),
        (3, 3),
        source,
        "robot_frame.plane_to_robot",
    )
    outlier = robot_data.get("outlier_mm")
    if outlier is not None and not (is_json_real(outlier) and 0 < outlier <= MAX_ROBOT_MM):
        raise CalibrationFileError(
            f"{source}: robot_frame.outlier_mm must be null or a number of mm from 0 to "
            f"{MAX_ROBOT_MM:g}, got {_show(outlier)}"
        )
    for key in ("drop_outliers", "reflected"):
        if not isinstance(robot_data.get(key), bool):
            raise CalibrationFileError(
                f"{source}: robot_frame.{key} must be true or false, got "
                f"{_show(robot_data.get(key))}"
            )
    if not isinstance(robot_data.get("model"), str):
        raise CalibrationFileError(
            f"{source}: robot_frame.model must be a string, got {_show(robot_data.get('model'))}"
        )
    outliers = robot_data.get("outliers")
    if not (isinstance(outliers, list) and all(is_json_int(i) for i in outliers)):
        raise CalibrationFileError(
            f"{source}: robot_frame.outliers must be a list of point indices, got {_show(outliers)}"
        )


def _robot_reals(
    robot_data: dict[str, Any], key: str, shape: tuple[int | None, ...], source: str
) -> F64:
    """robot_frame[key]: finite numbers of `shape`, each within MAX_ROBOT_MM (and >= 0 for
    the board points' errors)."""
    what = f"robot_frame.{key}"
    values = _reals(_field(robot_data, key, source, "robot_frame."), shape, source, what)
    low = 0.0 if key == "plane_std_mm" else -MAX_ROBOT_MM
    bad = np.flatnonzero(~((values >= low) & (values <= MAX_ROBOT_MM)))
    if bad.size:
        at = "".join(f"[{i}]" for i in np.unravel_index(int(bad[0]), values.shape))
        raise CalibrationFileError(
            f"{source}: {what}{at} is {float(values.flat[bad[0]])!r}: beyond a registration's "
            f"range ({low:g} to {MAX_ROBOT_MM:g} mm)"
        )
    return values


def _agree(stored: Any, derived: Any, path: str, strict: bool, source: str) -> None:
    """CalibrationFileError, naming the entry at `path`, unless the file's value `stored`
    is `derived` (a calibration's own re-derivation of it): the same JSON type, the same
    strings, booleans and nulls, numbers to DERIVED_TOLERANCE_REL (and _ABS); objects with
    the same fields (`strict`; otherwise those stored are compared, and texts only for
    their type, for older versions)."""
    if isinstance(derived, dict):
        if not isinstance(stored, dict):
            raise CalibrationFileError(
                f"{source}: {path} must be a JSON object, got {_show(stored)}"
            )
        for key, value in derived.items():
            if key in stored:
                _agree(stored[key], value, f"{path}.{key}", strict, source)
            elif strict:
                raise CalibrationFileError(f"{source} is missing the field {path}.{key}")
        extra = [k for k in stored if k not in derived]
        if strict and extra:
            raise CalibrationFileError(
                f"{source}: unknown field {path}.{extra[0]} (edited by hand?)"
            )
    elif isinstance(derived, list | tuple):
        if not isinstance(stored, list) or len(stored) != len(derived):
            raise CalibrationFileError(
                f"{source}: {path} must be a list of {len(derived)}, got {_show(stored)}"
            )
        for i, (s, d) in enumerate(zip(stored, derived, strict=True)):
            _agree(s, d, f"{path}[{i}]", strict, source)
    elif isinstance(derived, str) and not strict:
        # A text a file of an older version stores (a warning) may be worded otherwise now.
        if not isinstance(stored, str):
            raise CalibrationFileError(f"{source}: {path} must be a string, got {_show(stored)}")
    elif isinstance(derived, bool | str) or derived is None:
        if type(stored) is not type(derived) or stored != derived:
            raise CalibrationFileError(
                f"{source}: {path} is {_show(stored)} where the file's other fields give "
                f"{_show(derived)} (edited or corrupt)"
            )
    elif is_json_int(derived) and not is_json_int(stored):
        # A count or an id: a whole number, as written (3.0 is not point 3).
        raise CalibrationFileError(
            f"{source}: {path} must be a whole number, got {_show(stored)} (edited or corrupt)"
        )
    else:
        _agree_number(stored, float(derived), path, source)


def _agree_number(stored: Any, derived: float, path: str, source: str) -> None:
    if not math.isfinite(derived):
        raise CalibrationFileError(
            f"{source}: {path} overflows when re-derived from the file's other values "
            "(numbers beyond any calibration's: edited or corrupt)"
        )
    if not is_json_real(stored):
        raise CalibrationFileError(
            f"{source}: {path} must be a number, got {_show(stored)} (edited or corrupt)"
        )
    if not abs(float(stored) - derived) <= (
        DERIVED_TOLERANCE_ABS + DERIVED_TOLERANCE_REL * abs(derived)
    ):
        raise CalibrationFileError(
            f"{source}: {path} is {float(stored)!r} where the file's other fields give "
            f"{derived!r} (edited or corrupt)"
        )


def _check_summary(
    cal: Calibration, summary: dict[str, Any], strict: bool, version: int, source: str
) -> None:
    """The summary's fields a loaded calibration re-derives cheaply (its counts, names and
    largest deviations) must agree; the rest (leave-one-out errors, recomputed whenever a
    summary is asked for) must be numbers >= 0 or null. The reprojection errors are
    check_residuals'."""
    # Only here: calibration imports this module.
    from planarcal.calib.calibration import CalibrationSummary  # noqa: PLC0415

    names = [f.name for f in dataclasses.fields(CalibrationSummary)]
    if strict and version < BOARD_TYPES_SINCE:
        names = [n for n in names if n not in SUMMARY_SINCE_5]
    dev = np.abs(cal.deviations_mm)
    derived: dict[str, Any] = {
        "n_points": len(cal.world_points),
        "solver": cal.solver,
        "refine": cal.refine,
        "lens": cal.lens_model,
        "max_abs_dx_mm": float(dev[:, 0].max()),
        "max_abs_dy_mm": float(dev[:, 1].max()),
    }
    for key in names if strict else summary:
        if key not in names:
            raise CalibrationFileError(f"{source}: unknown field summary.{key} (edited by hand?)")
        value = _field(summary, key, source, "summary.")
        if key in derived:
            _agree(value, derived[key], f"summary.{key}", strict, source)
        elif not (value is None or (is_json_real(value) and value >= 0)):
            raise CalibrationFileError(
                f"{source}: summary.{key} must be a number >= 0 or null, got {_show(value)}"
            )


def _first_non_finite(value: Any, path: str = "") -> str | None:
    """The path ("robot_frame.plane.rms_mm") of the first float in `value` that JSON cannot
    hold (NaN, +-inf), or None."""
    if isinstance(value, dict):
        items: Any = ((f"{path}.{k}" if path else str(k), v) for k, v in value.items())
    elif isinstance(value, list | tuple):
        items = ((f"{path}[{i}]", v) for i, v in enumerate(value))
    else:
        return path if isinstance(value, float) and not math.isfinite(value) else None
    for sub_path, sub in items:
        found = _first_non_finite(sub, sub_path)
        if found is not None:
            return found
    return None


def _stored_residuals(data: dict[str, Any], n_points: int, source: str) -> StoredResiduals:
    """The summary's reprojection errors, which check_residuals compares with the loaded
    calibration's own."""
    summary = data.get("summary")
    if not isinstance(summary, dict):
        raise CalibrationFileError(
            f"{source} has no summary (its reprojection errors, which a loaded calibration "
            "is checked against)"
        )
    if summary.get("n_points") != n_points or not is_json_int(summary.get("n_points")):
        raise CalibrationFileError(
            f"{source}: summary.n_points is {_show(summary.get('n_points'))} but the file "
            f"holds {n_points} points"
        )
    values = []
    for key in ("mean_px", "rms_px", "max_px", "min_px"):
        value = summary.get(key)
        if not (is_json_real(value) and value >= 0):
            raise CalibrationFileError(
                f"{source}: summary.{key} must be a reprojection error in px (a number >= 0), "
                f"got {_show(value)}"
            )
        values.append(float(value))
    return StoredResiduals(*values)


def _reals(value: Any, shape: tuple[int | None, ...], where: str, what: str) -> F64:
    """Nested JSON lists of finite numbers of `shape` (None: any length) as a float64 array;
    otherwise CalibrationFileError "`where`: `what`: " and the entry at fault. Only the
    expected depth is walked, so no nesting can make it recurse further."""
    rows = len(value) if isinstance(value, list | tuple) else 0
    out = np.empty([rows if n is None else n for n in shape])

    def fill(item: Any, level: int, index: tuple[int, ...]) -> None:
        at = "".join(f"[{i}]" for i in index) or "it"
        if level == len(shape):
            if not is_json_real(item):
                raise CalibrationFileError(
                    f"{where}: {what}: {at} is {_show(item)}, not a finite number"
                )
            out[index] = float(item)
            return
        if not isinstance(item, list | tuple) or len(item) != out.shape[level]:
            length = "" if not isinstance(item, list | tuple) else f" of {len(item)}"
            raise CalibrationFileError(
                f"{where}: {what}: {at} is {_show(item) if not length else 'a list' + length}, "
                f"not a list of {out.shape[level]}"
            )
        for i, sub in enumerate(item):
            fill(sub, level + 1, (*index, i))

    fill(value, 0, ())
    return out


def _json_type(value: Any) -> str:
    return {list: "a list", str: "a string", bool: "a boolean", type(None): "null"}.get(
        type(value), "a number"
    )


_SHOW = reprlib.Repr()
_SHOW.maxstring = _SHOW.maxother = 40
_SHOW.maxlong = 24


def _show(value: Any) -> str:
    """`value` for a message as JSON writes it where that differs (true, null), cut short
    (a field may hold a whole file's worth, or be nested deep)."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    return _SHOW.repr(value)


def _refuse_constant(name: str, constant: str) -> Any:
    raise CalibrationFileError(
        f"{name!r} holds {constant}, which is not a JSON number: a calibration file has only "
        "finite numbers (edited, or written by another tool?)"
    )


def _bounded_int(name: str, digits: str) -> int:
    # Beyond a float's range no field can use it; refusing here keeps int() and float() from
    # failing later (Python refuses ints of over 4300 digits, floats overflow at 1e308).
    if len(digits.lstrip("-")) > MAX_INT_DIGITS:
        raise CalibrationFileError(
            f"{name!r} holds an integer of {len(digits.lstrip('-'))} digits: beyond any "
            "number a calibration file holds (corrupt or edited?)"
        )
    return int(digits)


def _foreign_text(text: str) -> str | None:
    """What a file that is not JSON looks like, said to the user (None if it may be JSON):
    an OpenCV or ROS intrinsics file (YAML or XML), or some other YAML or XML."""
    head = text.lstrip("\ufeff \t\r\n")[:4096]
    if head.startswith(("{", "[")) or not head:
        return None
    if head.startswith("<"):
        kind = "XML"
    elif head.startswith(("%YAML", "---")) or _YAML_KEY.search(head):
        kind = "YAML"
    else:
        return None
    if _INTRINSICS_NODE.search(text[:65536]):
        return INTRINSICS_HINT.format(kind=f"OpenCV {kind}")
    return (
        f"is a {kind} file, not a planarcal calibration (a JSON file made by `planarcal calibrate`)"
    )


def _fit_from_dict(
    data: dict[str, Any],
    h: F64,
    world: F64,
    image: F64,
    size: tuple[int, int] | None,
    source: str,
    layout: PlacementLayout | None = None,
) -> tuple[PlaneFit, CameraIntrinsics | None, tuple[float, float]]:
    """The fit a file describes, checked against its points; CalibrationFileError if not.
    Version 1 files have none of these fields: no lens, the nominal world scale."""
    lens = data.get("lens_model", "none")
    note = data.get("lens_note", "no lens model")
    if not isinstance(lens, str) or lens not in (*LENS_MODELS, "intrinsics"):
        raise CalibrationFileError(
            f"{source}: lens_model {_show(lens)} is unknown (one of "
            f"{', '.join(LENS_MODELS)}, intrinsics)"
        )
    if not isinstance(note, str):
        raise CalibrationFileError(f"{source}: lens_note must be a string, got {_show(note)}")
    world_scale = _world_scale(data, source)
    candidates = _lens_candidates(data.get("lens_candidates", []), source)
    intrinsics = None
    radial = None  # a lens model's own
    if lens == "intrinsics":
        try:
            intrinsics = CameraIntrinsics.from_dict(data.get("intrinsics"))
        except IntrinsicsError as e:
            raise CalibrationFileError(f"{source}: intrinsics: {e}") from None
        if size is not None and size != intrinsics.image_size:
            raise CalibrationFileError(
                f"{source}: image_size_px {list(size)} is not the intrinsics' "
                f"{list(intrinsics.image_size)}"
            )
    elif lens != "none":
        radial = _radial_lens(data.get("lens"), lens, size, source)
    try:
        plane, layout = plane_at(h, world, image, size, lens, radial, intrinsics, layout)
    except (ArgumentError, IntrinsicsError, LensModelError, HomographyError) as e:
        raise CalibrationFileError(
            f"{source}: its homography, lens (or intrinsics) and points cannot be used "
            f"together: {e}"
        ) from None
    return PlaneFit(plane, h, lens, candidates, note, placements=layout), intrinsics, world_scale


def _world_scale(data: dict[str, Any], source: str) -> tuple[float, float]:
    scale = data.get("world_scale", [1.0, 1.0])
    world_scale_array = _reals(scale, (2,), source, "world_scale must be two factors")
    if not (world_scale_array > 0).all():
        raise CalibrationFileError(
            f"{source}: world_scale must be two factors > 0, got {_show(scale)}"
        )
    return (float(world_scale_array[0]), float(world_scale_array[1]))


def _check_placed_points(layout: PlacementLayout, world: F64, source: str) -> None:
    """CalibrationFileError unless each world point is its board point carried by its
    placement's pose (to POINT_TOLERANCE_REL of the board's extent)."""
    placed = layout.plane_points()
    reach = float(np.abs(layout.board_mm).max()) + 1.0
    off = np.hypot(*(placed - world).T)
    bad = np.flatnonzero(~(off <= POINT_TOLERANCE_REL * reach))
    if bad.size:
        k = int(bad[0])
        raise CalibrationFileError(
            f"{source}: points.world_mm[{k}] is not its board point carried by its "
            f"placement's pose ({off[k]:.3g} mm off): the points, ids or placements were edited"
        )


def _radial_lens(lens_data: Any, lens: str, size: tuple[int, int] | None, source: str) -> Any:
    """The RadialLens of lens model `lens` from the file's ``lens`` object."""
    if size is None or not isinstance(lens_data, dict):
        raise CalibrationFileError(
            f"{source}: lens model {lens!r} without its parameters (lens) or the image size "
            "(image_size_px)"
        )
    if lens_data.get("model", lens) != lens:
        raise CalibrationFileError(
            f"{source}: lens.model {_show(lens_data.get('model'))} is not lens_model {lens!r}"
        )
    centre_data = _field(lens_data, "centre_px", source, "lens.")
    centre = _reals(centre_data, (2,), source, "lens.centre_px must be [x, y]")
    values = {}
    for key in ("scale_px", "k1", "k2"):
        value = _field(lens_data, key, source, "lens.")
        if not is_json_real(value):
            raise CalibrationFileError(
                f"{source}: lens.{key} must be a finite number, got {_show(value)}"
            )
        values[key] = float(value)
    if not values["scale_px"] > 0:
        raise CalibrationFileError(f"{source}: lens.scale_px must be > 0, got {values['scale_px']}")
    # The lens frame is the image's: its unit the half-diagonal, its centre the image's
    # unless the model fits it (k1k2c).
    w, h = size
    frame = [0.5 * math.hypot(w, h)]
    stored = [values["scale_px"]]
    if lens != "k1k2c":
        frame += [(w - 1.0) / 2.0, (h - 1.0) / 2.0]
        stored += [float(centre[0]), float(centre[1])]
    for got, want in zip(stored, frame, strict=True):
        if not abs(got - want) <= DERIVED_TOLERANCE_REL * want:
            raise CalibrationFileError(
                f"{source}: lens.scale_px {stored[0]!r} and lens.centre_px {centre.tolist()} are "
                f"not the frame of image_size_px {[w, h]} (its half-diagonal {frame[0]!r}"
                + ("" if len(frame) == 1 else f", its centre {frame[1:]}")
                + "): the image size or the lens was edited"
            )
    try:
        return RadialLens(
            (float(centre[0]), float(centre[1])), values["scale_px"], values["k1"], values["k2"]
        )
    except (ArgumentError, LensModelError) as e:
        raise CalibrationFileError(f"{source}: lens: {e}") from None


def _lens_candidates(cand_data: Any, source: str) -> list[LensCandidate]:
    """The lens models tried (for the report): model, errors (null where not fitted)."""
    if not isinstance(cand_data, list):
        raise CalibrationFileError(f"{source}: lens_candidates must be a list")
    candidates = []
    for i, c in enumerate(cand_data):
        where = f"{source}: lens_candidates[{i}]"
        if not isinstance(c, dict):
            raise CalibrationFileError(f"{where} must be a JSON object, got {_show(c)}")
        model, verdict = c.get("model"), c.get("verdict")
        if not (isinstance(model, str) and isinstance(verdict, str)):
            raise CalibrationFileError(f"{where}: model and verdict must be strings")
        errors = []
        for key in ("loo_mean_px", "sigma_px"):
            value = c.get(key)
            if not (value is None or is_json_real(value)):
                raise CalibrationFileError(
                    f"{where}.{key} must be a number or null, got {_show(value)}"
                )
            errors.append(math.nan if value is None else float(value))
        candidates.append(LensCandidate(model, errors[0], errors[1], verdict))
    return candidates
