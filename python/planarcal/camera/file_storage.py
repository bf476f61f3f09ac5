"""Camera intrinsics in OpenCV's calibration files (cv2.FileStorage: YAML, XML or JSON).

Written as OpenCV's calibration sample writes them; read from that layout and the common
variants (other node names, ROS-style matrices, plain lists). The intrinsics themselves are
:class:`planarcal.camera.intrinsics.CameraIntrinsics`, whose ``save_yaml`` and ``load_yaml``
call :func:`write_intrinsics` and :func:`read_intrinsics`.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.camera.opencv_errors import last_line
from planarcal.errors import IntrinsicsError
from planarcal.files import atomic_write

if TYPE_CHECKING:
    from planarcal.camera.intrinsics import CameraIntrinsics

F64 = NDArray[np.float64]
T = TypeVar("T")

# OpenCV's YAML/XML node names, the calibration sample's first.
_MATRIX_NODES = ("camera_matrix", "cameraMatrix", "K")
_DIST_NODES = ("distortion_coefficients", "dist_coeffs", "distCoeffs", "D")
_WIDTH_NODES = ("image_width", "imageWidth")
_HEIGHT_NODES = ("image_height", "imageHeight")
_SIZE_NODES = ("image_size", "imageSize")
_RMS_NODES = ("avg_reprojection_error", "rms", "reprojection_error")
_VIEWS_NODES = ("nr_of_frames", "nframes", "n_views")
_PER_VIEW_NODES = ("per_view_reprojection_errors",)

# A node found, with the name it was found under (for messages).
_Found = tuple[str, Any]


# ------------------------------------------------------------------------------------------
# Writing


def write_intrinsics(intrinsics: CameraIntrinsics, path: str | os.PathLike[str]) -> Path:
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
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise IntrinsicsError(f"no intrinsics file at {str(p)!r}") from None
    except OSError as e:
        raise IntrinsicsError(f"cannot read {str(p)!r}: {e.strerror or e}") from None
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
    return _from_file_storage(root, repr(str(p)), make)


def _from_file_storage(root: Any, source: str, make: Callable[..., T]) -> T:
    nodes = _required_nodes(root, source)
    try:
        matrix = _node_matrix(nodes.matrix[1], _what(source, nodes.matrix))
        dist = _node_matrix(nodes.dist[1], _what(source, nodes.dist))
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
        raise IntrinsicsError(f"{what} is not a number")
    return float(node.real())


def _node_matrix(node: Any, what: str) -> F64:
    """A matrix node as float64: an ``!!opencv-matrix``, a map with rows, cols and data
    (ROS's camera_info YAML), or a (nested) sequence of numbers."""
    if node.isMap():
        return _map_matrix(node, what)
    if node.isSeq():
        return _sequence_matrix(node, what)
    raise IntrinsicsError(f"{what} is not a matrix")


def _map_matrix(node: Any, what: str) -> F64:
    """An ``!!opencv-matrix`` (it has ``dt``) or a map with ``data`` and perhaps ``rows`` and
    ``cols``."""
    keys = set(node.keys())
    if "data" not in keys:
        raise IntrinsicsError(f"{what} is a map without 'data': {sorted(keys)}")
    if "dt" in keys:
        try:
            m = node.mat()
        except (cv2.error, SystemError) as e:
            raise IntrinsicsError(f"{what} is a malformed opencv-matrix: {last_line(e)}") from None
        if m is None:
            raise IntrinsicsError(f"{what} is a malformed opencv-matrix")
        return np.asarray(m, dtype=np.float64)
    data = _node_matrix(node.getNode("data"), what + ".data").reshape(-1)
    if "rows" in keys and "cols" in keys:
        rows = _node_number(node.getNode("rows"), what + ".rows")
        cols = _node_number(node.getNode("cols"), what + ".cols")
        if rows * cols != data.size:
            raise IntrinsicsError(f"{what} says {rows:g} x {cols:g} but has {data.size} numbers")
        return data.reshape(int(rows), int(cols))
    return data


def _sequence_matrix(node: Any, what: str) -> F64:
    """A sequence of numbers (a vector) or of sequences (the rows of a matrix)."""
    items = [node.at(i) for i in range(node.size())]
    if items and all(item.isSeq() for item in items):
        rows = [_node_matrix(item, what).reshape(-1) for item in items]
        if len({r.size for r in rows}) != 1:
            raise IntrinsicsError(f"{what} has rows of different lengths")
        return np.vstack(rows)
    return np.array([_node_number(item, what) for item in items], dtype=np.float64)
