"""Camera intrinsics in OpenCV's calibration files (cv2.FileStorage: YAML, XML or JSON).

Written as OpenCV's calibration sample writes them; read from that layout and the common
variants (other node names, ROS-style matrices, plain lists). The intrinsics themselves are
:class:`planarcal.camera.intrinsics.CameraIntrinsics`, whose ``save_yaml`` and ``load_yaml``
call :func:`write_intrinsics` and :func:`read_intrinsics`: this module writes any object
with the intrinsics' fields (``IntrinsicsFields``) and reads into whatever constructor it is
given, so it imports no model (the model imports it, without a loop).
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol, TypeVar

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.bounded_read import read_regular_file
from planarcal.camera.opencv_errors import last_line
from planarcal.errors import IntrinsicsError
from planarcal.file_formats import CALIBRATION_FORMAT
from planarcal.files import atomic_write

F64 = NDArray[np.float64]
T = TypeVar("T")


class IntrinsicsFields(Protocol):
    """What a file is written from (planarcal.camera.CameraIntrinsics has it)."""

    @property
    def matrix(self) -> F64: ...

    @property
    def dist_coeffs(self) -> F64: ...

    @property
    def image_size(self) -> tuple[int, int]: ...

    @property
    def rms_px(self) -> float | None: ...

    @property
    def n_views(self) -> int | None: ...

    @property
    def per_view_rms_px(self) -> tuple[float, ...] | None: ...


# OpenCV's YAML/XML node names, the calibration sample's first.
_MATRIX_NODES = ("camera_matrix", "cameraMatrix", "K")
_DIST_NODES = ("distortion_coefficients", "dist_coeffs", "distCoeffs", "D")
_WIDTH_NODES = ("image_width", "imageWidth")
_HEIGHT_NODES = ("image_height", "imageHeight")
_SIZE_NODES = ("image_size", "imageSize")
_RMS_NODES = ("avg_reprojection_error", "rms", "reprojection_error")
_VIEWS_NODES = ("nr_of_frames", "nframes", "n_views")
_PER_VIEW_NODES = ("per_view_reprojection_errors",)
_READ_NODES = frozenset(
    (
        *_MATRIX_NODES,
        *_DIST_NODES,
        *_WIDTH_NODES,
        *_HEIGHT_NODES,
        *_SIZE_NODES,
        *_RMS_NODES,
        *_VIEWS_NODES,
        *_PER_VIEW_NODES,
    )
)
# The keys of a matrix written as a map (OpenCV's !!opencv-matrix, ROS's rows/cols/data).
_MATRIX_FIELDS = frozenset(("rows", "cols", "data", "dt"))

# The lens models a file may name: OpenCV's own (k1, k2, p1, p2[, k3[, k4, k5, k6]]) under
# ROS's names for it (camera_info's distortion_model), with the coefficient counts each has.
SUPPORTED_MODELS = {"plumb_bob": (4, 5), "rational_polynomial": (8,)}
_MODEL_NODES = ("distortion_model", "distortionModel")
# OpenCV's calibration sample writes fisheye_model: 1 for cv2.fisheye's model.
_FISHEYE_NODES = ("fisheye_model", "use_fisheye_model")

MAX_FILE_BYTES = 4 * 2**20
"""The largest intrinsics file read: OpenCV's calibration sample writes some 100 kB even
with every view's board points; beyond this it is not a calibration."""

# OpenCV saturates an integer too long for 64 bits to 2**63 - 1 (which reads back as 2**63).
_INT64_LIMIT = 2.0**63

_YAML_LINE = re.compile(r"^\s*(?:-\s+)?(?P<key>[A-Za-z_][\w-]*)\s*:(?P<value>.*)$")
_YAML_BOOLEANS = frozenset(("true", "false", "True", "False", "TRUE", "FALSE"))

# A node found, with the name it was found under (for messages).
_Found = tuple[str, Any]


# ------------------------------------------------------------------------------------------
# Writing


def write_intrinsics(intrinsics: IntrinsicsFields, path: str | os.PathLike[str]) -> Path:
    """Write the intrinsics as OpenCV's calibration sample does, atomically (see
    CameraIntrinsics.save_yaml); the path written."""
    target = Path(path)
    suffix = target.suffix.lower()
    fmt = suffix if suffix in (".xml", ".json") else ".yaml"
    fs = cv2.FileStorage("intrinsics" + fmt, cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    if intrinsics.n_views is not None:
        fs.write("nr_of_frames", int(intrinsics.n_views))
    if intrinsics.rms_px is not None:
        fs.write("avg_reprojection_error", float(intrinsics.rms_px))
    if intrinsics.per_view_rms_px is not None and intrinsics.per_view_rms_px:
        fs.write(
            "per_view_reprojection_errors",
            np.array(intrinsics.per_view_rms_px, dtype=np.float64).reshape(-1, 1),
        )
    # The required nodes last and the distortion vector at the very end: a file cut short
    # anywhere then lacks a required node or ends inside one.
    fs.write("image_width", int(intrinsics.image_size[0]))
    fs.write("image_height", int(intrinsics.image_size[1]))
    fs.write("camera_matrix", np.array(intrinsics.matrix))
    fs.write("distortion_coefficients", np.array(intrinsics.dist_coeffs).reshape(-1, 1))
    text = fs.releaseAndGetString()
    return atomic_write(target, text)


# ------------------------------------------------------------------------------------------
# Reading


def read_intrinsics(path: str | os.PathLike[str], make: Callable[..., T]) -> T:
    """The intrinsics in an OpenCV calibration file (see CameraIntrinsics.load_yaml), built
    by ``make`` from the keyword arguments matrix, dist_coeffs, image_size, rms_px, n_views
    and per_view_rms_px. IntrinsicsError naming the file and the fault, including those
    ``make`` raises."""
    p = Path(path)
    raw = read_regular_file(p, "intrinsics file", MAX_FILE_BYTES, IntrinsicsError)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise IntrinsicsError(
            f"{str(p)!r} is not an OpenCV YAML/XML file: it is not text (corrupt?)"
        ) from None
    if not text.strip():
        raise IntrinsicsError(f"{str(p)!r} is empty")
    if "\x00" in text:
        raise IntrinsicsError(f"{str(p)!r} is not an OpenCV YAML/XML file: it has NUL bytes")
    _check_text(text, repr(str(p)))
    if not text.lstrip().startswith(("%YAML", "<", "{")):
        # Plain YAML without OpenCV's header (a ROS camera_info): OpenCV 4 tells the format
        # from the header alone and refuses it ("Unsupported file storage format").
        text = "%YAML:1.0\n" + text
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
        opened = fs.isOpened()
        root = fs.root() if opened else None
    except (cv2.error, SystemError) as e:
        # OpenCV's parser errors surface as SystemError with the cv2.error as its cause.
        raise IntrinsicsError(
            f"{str(p)!r} is not a valid OpenCV YAML/XML/JSON file (corrupt or "
            f"truncated?): {last_line(e)}"
        ) from None
    if root is None or not root.isMap():
        raise IntrinsicsError(
            f"{str(p)!r} holds no OpenCV calibration nodes (expected camera_matrix, "
            "distortion_coefficients, image_width, image_height)"
        )
    try:
        return _from_file_storage(root, repr(str(p)), make)
    except (cv2.error, SystemError) as e:
        # OpenCV 4 asserts while reading some malformed nodes (a 401-digit integer).
        raise IntrinsicsError(
            f"{str(p)!r} is not a valid OpenCV YAML/XML/JSON file (OpenCV cannot read its "
            f"nodes): {last_line(e)}"
        ) from None


def _check_text(text: str, source: str) -> None:
    """IntrinsicsError for what OpenCV's parser would misread rather than refuse: a
    planarcal calibration (JSON) given for intrinsics, and booleans where numbers belong
    (OpenCV reads YAML's and JSON's true as the number 1)."""
    if text.lstrip("\ufeff \t\r\n").startswith(("{", "[")):
        try:
            data = json.loads(text)
        except RecursionError:
            raise IntrinsicsError(f"{source} is nested too deeply to be intrinsics") from None
        except ValueError:
            return  # not JSON as Python reads it; OpenCV's parser says what it makes of it
        if isinstance(data, dict) and data.get("format") == CALIBRATION_FORMAT:
            raise IntrinsicsError(
                f"{source} is a planarcal calibration (from `planarcal calibrate`), not camera "
                "intrinsics: pass it with --calibration (Calibration.load)"
            )
        if isinstance(data, dict):
            for node in _READ_NODES:
                if _holds_bool(data.get(node)):
                    raise IntrinsicsError(
                        f"{source}: {node} holds true or false where numbers belong"
                    )
        return
    if text.lstrip().startswith("<"):
        return  # OpenCV's XML reads true as text, which the node checks refuse
    for number, line in enumerate(text.splitlines(), start=1):
        match = _YAML_LINE.match(line)
        key: str | None = match["key"] if match else None
        value: str = match["value"] if match else line
        if key is not None and key not in _READ_NODES and key not in _MATRIX_FIELDS:
            continue  # a node not read (a camera's name, a flag): its value is its own
        pieces = (piece.strip() for piece in re.split(r"[\[\],]|^\s*-\s", value.split("#")[0]))
        if any(piece in _YAML_BOOLEANS for piece in pieces):
            raise IntrinsicsError(
                f"{source} line {number}: {key or 'a list'} holds true or false where a "
                "number belongs (OpenCV would read it as 1 or 0)"
            )


def _holds_bool(value: Any, depth: int = 0) -> bool:
    """Whether a JSON value holds a bool within the depth of a matrix map's data."""
    if isinstance(value, bool):
        return True
    if depth > 3:
        return False
    if isinstance(value, list):
        return any(_holds_bool(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return any(_holds_bool(v, depth + 1) for v in value.values())
    return False


def _from_file_storage(root: Any, source: str, make: Callable[..., T]) -> T:
    nodes = _required_nodes(root, source)
    try:
        matrix = _node_matrix(nodes.matrix[1], _what(source, nodes.matrix))
        dist = _node_matrix(nodes.dist[1], _what(source, nodes.dist))
        _check_lens_model(root, dist.size, source)
        size = _image_size(nodes, source)
        rms, n_views, per_view = _calibration_record(root, source)
        return make(
            matrix=matrix,
            dist_coeffs=dist,
            image_size=size,
            rms_px=rms,
            n_views=n_views,
            per_view_rms_px=per_view,
        )
    except IntrinsicsError as e:
        message = str(e)
        if not message.startswith(source):
            message = f"{source}: {message}"
        raise IntrinsicsError(message) from None


@dataclasses.dataclass(frozen=True)
class _RequiredNodes:
    """The nodes a calibration file must have: K, the distortion vector, and the image size
    as width and height or as one [width, height] node."""

    matrix: _Found
    dist: _Found
    width: _Found | None
    height: _Found | None
    size: _Found | None


def _required_nodes(root: Any, source: str) -> _RequiredNodes:
    """The required nodes, or IntrinsicsError listing every one that is missing."""
    k_node = _find(root, _MATRIX_NODES)
    d_node = _find(root, _DIST_NODES)
    w_node = _find(root, _WIDTH_NODES)
    h_node = _find(root, _HEIGHT_NODES)
    s_node = _find(root, _SIZE_NODES)
    missing = []
    if k_node is None:
        missing.append(" / ".join(_MATRIX_NODES))
    if d_node is None:
        missing.append(" / ".join(_DIST_NODES))
    if s_node is None and (w_node is None or h_node is None):
        if w_node is None:
            missing.append("image_width")
        if h_node is None:
            missing.append("image_height")
    if missing:
        present = sorted(root.keys())
        raise IntrinsicsError(
            f"{source} lacks the node(s) {'; '.join(missing)} (it has: "
            f"{', '.join(present) or 'nothing'}); corrupt or truncated, or not a camera "
            "calibration"
        )
    assert k_node is not None and d_node is not None
    return _RequiredNodes(k_node, d_node, w_node, h_node, s_node)


def _image_size(nodes: _RequiredNodes, source: str) -> tuple[int, int]:
    """(width, height) from image_width and image_height, else from image_size."""
    if nodes.width is not None and nodes.height is not None:
        width = _node_number(nodes.width[1], _what(source, nodes.width))
        height = _node_number(nodes.height[1], _what(source, nodes.height))
    else:
        assert nodes.size is not None  # _required_nodes saw to it
        size = _node_matrix(nodes.size[1], _what(source, nodes.size)).reshape(-1)
        if size.size != 2:
            raise IntrinsicsError(f"{source}: {nodes.size[0]} must be [width, height]")
        width, height = float(size[0]), float(size[1])
    if not (width.is_integer() and height.is_integer()):
        raise IntrinsicsError(f"{source}: the image size {width:g} x {height:g} is not whole")
    return int(width), int(height)


def _check_lens_model(root: Any, n_coeffs: int, source: str) -> None:
    """IntrinsicsError if the file names a lens model other than OpenCV's standard one (a
    ROS camera_info's equidistant, OpenCV's fisheye_model: 1): its coefficients mean
    something else, and read as OpenCV's they would map every pixel wrongly."""
    supported = " or ".join(SUPPORTED_MODELS)
    if (found := _find(root, _FISHEYE_NODES)) is not None:
        flag = _node_number(found[1], _what(source, found))
        if flag != 0:
            raise IntrinsicsError(
                f"{source}: {found[0]} is {flag:g}: the fisheye lens model (cv2.fisheye) is not "
                f"supported; planarcal uses OpenCV's standard model ({supported}): calibrate "
                "the camera with `planarcal intrinsics`"
            )
    if (found := _find(root, _MODEL_NODES)) is None:
        return
    node = found[1]
    model: str | None = node.string() if node.isString() else None
    if model not in SUPPORTED_MODELS:
        what = repr(model) if model is not None else "not a name"
        fisheye = " (the fisheye model)" if model in ("equidistant", "fisheye") else ""
        raise IntrinsicsError(
            f"{source}: {found[0]} {what}{fisheye} is not supported: planarcal uses OpenCV's "
            f"standard lens model, {supported}; calibrate the camera with `planarcal "
            "intrinsics`"
        )
    if n_coeffs not in SUPPORTED_MODELS[model]:
        raise IntrinsicsError(
            f"{source}: {found[0]} {model!r} has "
            f"{' or '.join(map(str, SUPPORTED_MODELS[model]))} distortion coefficients, the "
            f"file {n_coeffs}"
        )


def _calibration_record(
    root: Any, source: str
) -> tuple[float | None, int | None, tuple[float, ...] | None]:
    """The optional nodes: the RMS reprojection error, the number of views and each view's
    RMS (None where absent; per-view errors that do not match the views are dropped)."""
    rms = n_views = per_view = None
    if (found := _find(root, _RMS_NODES)) is not None:
        rms = _node_number(found[1], _what(source, found))
    if (found := _find(root, _VIEWS_NODES)) is not None:
        views = _node_number(found[1], _what(source, found))
        if not (views.is_integer() and views >= 1):
            raise IntrinsicsError(f"{found[0]} must be a whole number >= 1, got {views:g}")
        n_views = int(views)
    if (found := _find(root, _PER_VIEW_NODES)) is not None:
        per_view = tuple(_node_matrix(found[1], _what(source, found)).reshape(-1).tolist())
        if n_views is not None and len(per_view) != n_views:
            per_view = None  # other tools write these differently; not worth refusing
    return rms, n_views, per_view


# ------------------------------------------------------------------------------------------
# cv2.FileStorage nodes


def _what(source: str, found: _Found) -> str:
    """How messages name a node: the file, then the node's name."""
    return f"{source}: {found[0]}"


def _find(root: Any, names: Sequence[str]) -> _Found | None:
    """The first of ``names`` that root has, with its node; None if it has none."""
    for name in names:
        node = root.getNode(name)
        if not node.empty() and not node.isNone():
            return name, node
    return None


def _node_number(node: Any, what: str) -> float:
    if not (node.isInt() or node.isReal()):
        text = f" (it is the text {node.string()[:40]!r})" if node.isString() else ""
        raise IntrinsicsError(f"{what} is not a number{text}")
    value = float(node.real())
    if node.isInt() and abs(value) >= _INT64_LIMIT:
        raise IntrinsicsError(f"{what} is an integer too large to read (beyond 64 bits)")
    if not np.isfinite(value):
        raise IntrinsicsError(f"{what} is {value}, not a finite number")
    return value


def _node_matrix(node: Any, what: str, depth: int = 0) -> F64:
    """A matrix node as float64: an ``!!opencv-matrix``, a map with rows, cols and data
    (ROS's camera_info YAML), or a (nested) sequence of numbers. At most a map of rows of
    numbers deep: anything nested deeper is no matrix (and could exhaust the stack)."""
    if depth > 2:
        raise IntrinsicsError(f"{what} is nested too deeply for a matrix")
    if node.isMap():
        return _map_matrix(node, what, depth + 1)
    if node.isSeq():
        return _sequence_matrix(node, what, depth + 1)
    raise IntrinsicsError(f"{what} is not a matrix")


# OpenCV's type codes of one-channel matrices (uchar, schar, ushort, short, int, float,
# double; half in OpenCV 5).
_ONE_CHANNEL_TYPES = frozenset({"u", "c", "w", "s", "i", "f", "d", "h"})


def _map_matrix(node: Any, what: str, depth: int) -> F64:
    """An ``!!opencv-matrix`` (it has ``dt``) or a map with ``data`` and perhaps ``rows`` and
    ``cols``."""
    keys = set(node.keys())
    if "data" not in keys:
        raise IntrinsicsError(f"{what} is a map without 'data': {sorted(keys)}")
    if "dt" in keys:
        # Read as its rows, cols and data, never by OpenCV's FileNode.mat(): on a malformed
        # node (rows without cols) it writes out of bounds and the process aborts later.
        dt = node.getNode("dt")
        if not (dt.isString() and dt.string() in _ONE_CHANNEL_TYPES):
            shown = repr(dt.string()) if dt.isString() else "not a type name"
            raise IntrinsicsError(
                f"{what} is an opencv-matrix of type {shown}; expected one channel of numbers "
                f"(dt: {', '.join(sorted(_ONE_CHANNEL_TYPES))})"
            )
        if not ({"rows", "cols"} <= keys or "sizes" in keys):
            raise IntrinsicsError(f"{what} is an opencv-matrix without rows and cols")
    data = _node_matrix(node.getNode("data"), what + ".data", depth).reshape(-1)
    if "sizes" in keys and not {"rows", "cols"} <= keys:
        # An !!opencv-nd-matrix (OpenCV 5 writes a vector as one): its sizes, one or two.
        sizes_node = node.getNode("sizes")
        if sizes_node.isSeq():
            sizes = _node_matrix(sizes_node, what + ".sizes", depth).reshape(-1)
        else:  # XML writes a vector's one size as a number
            sizes = np.array([_node_number(sizes_node, what + ".sizes")])
        if not (1 <= sizes.size <= 2 and all(n.is_integer() and n >= 1 for n in sizes.tolist())):
            raise IntrinsicsError(f"{what}: sizes must be one or two whole numbers >= 1")
        if int(np.prod(sizes)) != data.size:
            shape = " x ".join(f"{n:g}" for n in sizes)
            raise IntrinsicsError(f"{what} says {shape} but has {data.size} numbers")
        return data.reshape([int(n) for n in sizes])
    if "rows" in keys and "cols" in keys:
        rows = _node_number(node.getNode("rows"), what + ".rows")
        cols = _node_number(node.getNode("cols"), what + ".cols")
        if not (rows.is_integer() and cols.is_integer() and rows >= 1 and cols >= 1):
            raise IntrinsicsError(f"{what}: rows and cols must be whole numbers >= 1")
        if rows * cols != data.size:
            raise IntrinsicsError(f"{what} says {rows:g} x {cols:g} but has {data.size} numbers")
        return data.reshape(int(rows), int(cols))
    return data


def _sequence_matrix(node: Any, what: str, depth: int) -> F64:
    """A sequence of numbers (a vector) or of sequences (the rows of a matrix)."""
    items = [node.at(i) for i in range(node.size())]
    if items and all(item.isSeq() for item in items):
        rows = [_node_matrix(item, what, depth).reshape(-1) for item in items]
        if len({r.size for r in rows}) != 1:
            raise IntrinsicsError(f"{what} has rows of different lengths")
        return np.vstack(rows)
    return np.array([_node_number(item, what) for item in items], dtype=np.float64)
