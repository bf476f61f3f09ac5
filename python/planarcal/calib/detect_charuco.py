"""Find a ChArUco board (planarcal.calib.charuco.CharucoBoard) in an image: its inner
chessboard corners, with OpenCV's ids, from any part of the board in view.

1. The markers: ``cv2.aruco.ArucoDetector`` on the image (on a copy downscaled to at most
   ``DETECT_MAX_SIDE`` px for large images; the corners are measured at full resolution).
2. Which markers to believe, and which printed layout: every marker's four corners give a
   homography board mm -> pixels; two markers near each other in the image agree when each
   one's homography puts the other where it is seen. The largest group of agreeing markers
   is the board; a marker outside it (a wrong decode, a stray id) is dropped. For a board
   whose two layouts differ (an even number of rows) both are tried and the one whose group
   is larger is kept (``layout``).
3. OpenCV's ``refineDetectedMarkers`` looks for the markers missed in the candidates it
   rejected, then the corners: each one next to a marker is predicted by its markers'
   homographies (as ``CharucoDetector`` does), then from the corners found so far the next
   ones are predicted by the local homography of their neighbours, so the chessboard is
   followed where markers could not be read (blur, glare, small markers). Every corner is
   refined with ``cv2.cornerSubPix`` in a window that keeps clear of the markers, then to
   the centre of point symmetry of the ink around it (the black squares, the white gaps and
   the markers' black borders look the same turned by 180 degrees about the corner, however
   blurred; on renders with exact truth 5 times closer than CharucoDetector's corners), and
   checked against the board's ink around it mapped into the image: a corner whose
   neighbourhood does not look like the board's is dropped, so no corner carries a wrong id.
   A corner two markers vouch for is kept even so, at their prediction (``refined`` False).
4. A board described wrongly says so: markers of another dictionary, ids beyond the board's
   markers, markers that fit another board size, layout or marker size raise
   BoardMismatchError naming what was seen ("markers of DICT_5X5_50 ids 0-17: a 6 x 6
   board?").
"""

from __future__ import annotations

import math
import time
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from planarcal.calib.charuco import CharucoBoard, dictionary_id
from planarcal.calib.corner_refine import grid_bends
from planarcal.calib.detection import BoardDetection
from planarcal.errors import ArgumentError, BoardMismatchError, BoardNotFoundError
from planarcal.images import grey_levels

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

DETECT_MAX_SIDE = 2048
"""Markers are looked for on a copy of the image at most this many pixels a side (the
corners are refined at full resolution)."""

SEARCH_MAX_SIDE = 1024
"""Other dictionaries are tried on a copy at most this many pixels a side."""

SEARCH_DEADLINE_S = 1.2
"""Other dictionaries are tried until this long after the detection started (the issue's
bound for any 720p image is 2 s)."""

MIN_CORNERS = 4

INK_MATCH = 0.5
"""The least correlation between the grey levels about a refined corner and the board's ink
there for the corner to be kept where it was refined."""

MAX_ASYMMETRY = 1.0
"""The most a refined corner's disc may differ from itself turned by 180 degrees (RMS over
the grey levels' spread): real corners, blurred, tilted, in JPEG, stay below 0.65; one half
hidden by an object reaches 1.4."""

WINDOW_FRACTION = 0.75
"""cornerSubPix's half window, as a fraction of the distance from the corner to the nearest
marker corner in the image (the window's corners, at sqrt(2) times the half window, stay
clear of the marker's edges)."""

MAX_HALF_WINDOW = 30

SYMMETRY_MIN_RADIUS = 8.0
"""The smallest disc (px) the centre of symmetry is found in, however near the markers: on
renders blurred by 1.5 px, a smaller one loses corners and accuracy."""

SYMMETRY_SECOND_MOMENT = 0.25 * (
    1.0 - 4.0 * math.exp(-2.0) / math.sqrt(2.0 * math.pi) / math.erf(math.sqrt(2.0))
)
"""The mean squared distance along an edge, in squared disc radii, of the centre of
symmetry's weights (a Gaussian of half the radius, cut at the radius): a lens bends the
edges (y = a x^2 along each), which turned by 180 degrees bend the other way, so the centre
of symmetry leans a * this * radius^2 towards their concave side (0.001-0.002 px per 400 px
of radius, inwards, at k1 = -0.12): _without_bend_lean takes it off."""


SMOOTHING_SIGMA = 1.0
"""Gaussian smoothing (px) of the image the corners are measured on (cornerSubPix, the
centre of symmetry, the ink check): it averages the sensor noise and the pixel grid's steps
along the edges, and leaves a corner where it is (a point of symmetry). On renders with
exact truth it halves cornerSubPix's error on sharp images."""


ORIENTATION_RULE = (
    "the ArUco markers' ids fix every corner's id (OpenCV's ChArUco numbering: corner "
    "k = r * (squares_x - 1) + c from the top-left inner corner)"
)

# The dictionaries tried when the stated one finds no board, the most used first: one of
# each family (the smaller ones are its first codes; 250 codes, as decoding time grows
# with the dictionary's size).
_FAMILIES = (
    "DICT_4X4_250",
    "DICT_5X5_250",
    "DICT_6X6_250",
    "DICT_APRILTAG_36h11",
    "DICT_ARUCO_ORIGINAL",
    "DICT_APRILTAG_16h5",
    "DICT_7X7_250",
    "DICT_APRILTAG_25h9",
    "DICT_ARUCO_MIP_36h12",
    "DICT_APRILTAG_36h10",
)


# ----------------------------------------------------------------------------------------
# Board geometry in squares (cells x across, y down; corner (c, r) at (c + 1, r + 1)).


def marker_cells(squares_x: int, squares_y: int, legacy: bool) -> I64:
    """The cell (x, y) of each marker id of a squares_x x squares_y board, OpenCV's order:
    the white squares row by row; black at the top left, except in the legacy layout of a
    board with an even number of rows."""
    marker_parity = 0 if (legacy and squares_y % 2 == 0) else 1
    y, x = np.divmod(np.arange(squares_x * squares_y), squares_x)
    keep = (x + y) % 2 == marker_parity
    return np.column_stack([x[keep], y[keep]]).astype(np.int64)


def _marker_square_corners(cells: I64, inset: float) -> F64:
    """Marker corners in squares (TL, TR, BR, BL), (n, 4, 2), for markers inset by `inset`
    squares from their cell's edges."""
    tl = cells.astype(np.float64) + inset
    size = 1.0 - 2.0 * inset
    offsets = np.array([[0.0, 0.0], [size, 0.0], [size, size], [0.0, size]])
    return np.asarray(tl[:, None, :] + offsets[None, :, :], np.float64)


def _apply(h: F64, pts: F64) -> F64:
    """A homography (or a stack of them, (n, 3, 3) with pts (n, m, 2)) applied to points."""
    pts = np.asarray(pts, np.float64)
    x, y = pts[..., 0], pts[..., 1]
    if h.ndim == 2:
        h = h[None]
        x, y = x[None], y[None]
    else:
        x, y = (
            np.broadcast_to(x, (len(h), *x.shape[1:])),
            np.broadcast_to(y, (len(h), *y.shape[1:])),
        )
    e = h.reshape(len(h), 9, *([1] * (x.ndim - 1)))
    u = e[:, 0] * x + e[:, 1] * y + e[:, 2]
    v = e[:, 3] * x + e[:, 4] * y + e[:, 5]
    w = e[:, 6] * x + e[:, 7] * y + e[:, 8]
    w = np.where(np.abs(w) < 1e-12, 1e-12, w)
    out = np.stack([u / w, v / w], axis=-1)
    return np.asarray(out[0] if pts.ndim == out.ndim - 1 else out, np.float64)


def _marker_homographies(obj: F64, img: F64) -> F64:
    """Each marker's homography from its corners in squares to its corners in pixels."""
    hs = np.empty((len(obj), 3, 3))
    for i in range(len(obj)):
        hs[i] = cv2.getPerspectiveTransform(obj[i].astype(np.float32), img[i].astype(np.float32))
    return hs


def _quad_side_px(img: F64) -> F64:
    """Each quad's side in pixels (the square root of its area)."""
    x, y = img[..., 0], img[..., 1]
    area = 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1))
    return np.asarray(np.sqrt(np.maximum(area, 1e-9)), np.float64)


class _MarkerPairs:
    """Markers near each other in the image, and whether they agree about where they sit on
    a board: each marker's homography (its cell's squares -> pixels) must put its
    neighbour's centre where that is seen, both ways, within a quarter of a square plus a
    tenth per square between them (lens distortion, corner noise)."""

    def __init__(self, img: F64, inset: float) -> None:
        self.n = len(img)
        self.i = self.j = np.zeros(0, np.int64)
        if self.n < 2:
            return
        unit = _marker_square_corners(np.zeros((self.n, 2), np.int64), inset)
        self.hs = _marker_homographies(unit, img)
        self.centres = img.mean(axis=1)
        square_px = _quad_side_px(img) / (1.0 - 2.0 * inset)  # a square near each marker
        dist, nbr = cKDTree(self.centres).query(self.centres, k=min(self.n, 9))
        i = np.repeat(np.arange(self.n), dist.shape[1] - 1)
        j = nbr[:, 1:].ravel()
        d = dist[:, 1:].ravel()
        scale = np.minimum(square_px[i], square_px[j])
        keep = (i < j) & (d / scale <= 8.0)
        self.i, self.j = i[keep], j[keep]
        self.tol = scale[keep] * (0.25 + 0.1 * d[keep] / scale[keep])

    def agreement(self, cells: I64) -> _Agreement:
        """Which pairs agree when the markers sit in `cells` (x, y squares)."""
        i, j = self.i, self.j
        if len(i) == 0:
            return _Agreement(self.n, i, j, 0)
        delta = (cells[j] - cells[i]).astype(np.float64) + 0.5
        e_ij = np.linalg.norm(_apply(self.hs[i], delta[:, None, :])[:, 0] - self.centres[j], axis=1)
        e_ji = np.linalg.norm(
            _apply(self.hs[j], 1.0 - delta[:, None, :])[:, 0] - self.centres[i], axis=1
        )
        ok = (e_ij < self.tol) & (e_ji < self.tol)
        agreement = _Agreement(self.n, i[ok], j[ok], int(np.count_nonzero(~ok)))
        agreement.error = float(np.mean((e_ij + e_ji) / self.tol)) if len(i) else 0.0
        return agreement


class _Agreement:
    """The pairs of markers that agree (and how many pairs disagree)."""

    def __init__(self, n: int, agree_i: I64, agree_j: I64, disagree: int) -> None:
        self.n, self.agree_i, self.agree_j, self.disagree = n, agree_i, agree_j, disagree
        self.error = 0.0
        """The pairs' mean distance between where each puts the other and where it is seen,
        in tolerances."""

    @property
    def n_agree(self) -> int:
        return len(self.agree_i)

    def largest_group(self) -> NDArray[np.bool_]:
        """The markers of the largest group joined by agreements (none when no two agree)."""
        keep = np.zeros(self.n, bool)
        if len(self.agree_i) == 0:
            return keep
        graph = coo_matrix(
            (np.ones(len(self.agree_i)), (self.agree_i, self.agree_j)), shape=(self.n, self.n)
        )
        _, labels = connected_components(graph, directed=False)
        keep[labels == np.argmax(np.bincount(labels))] = True
        return keep


# ----------------------------------------------------------------------------------------
# Markers.


def _uint8(grey: NDArray[Any]) -> NDArray[np.uint8]:
    if grey.dtype == np.uint8:
        return np.ascontiguousarray(grey, dtype=np.uint8)
    return np.asarray(np.clip(np.rint(grey), 0, 255), dtype=np.uint8)


def _downscaled(grey: NDArray[np.uint8], max_side: int) -> tuple[NDArray[np.uint8], float]:
    """A copy at most max_side px a side (area averaged) and its scale (copy px / image px)."""
    h, w = grey.shape
    scale = min(1.0, max_side / max(h, w))
    if scale >= 1.0:
        return grey, 1.0
    small = np.asarray(
        cv2.resize(
            grey,
            (max(1, round(w * scale)), max(1, round(h * scale))),
            interpolation=cv2.INTER_AREA,
        ),
        np.uint8,
    )
    return small, float(small.shape[1] / w)


def _detection_dictionary(board: CharucoBoard) -> Any:
    """The board's dictionary cut to its first codes: the board's markers and as many again
    (up to 32 more: ids beyond the board's say it was described too small), as decoding time
    grows with the dictionary's size."""
    full = board.opencv_dictionary()
    n = min(len(full.bytesList), board.n_markers + min(board.n_markers, 32))
    if n == len(full.bytesList):
        return full
    return cv2.aruco.Dictionary(
        full.bytesList[:n], int(full.markerSize), int(full.maxCorrectionBits)
    )


def _marker_detector(dictionary: Any) -> Any:
    params = cv2.aruco.DetectorParameters()
    return cv2.aruco.ArucoDetector(dictionary, params)


def _find_markers(
    small: NDArray[np.uint8], dictionary: Any
) -> tuple[F64, I64, tuple[Any, ...], Any]:
    """Markers on the detection copy: corners (n, 4, 2) in its pixels, ids, and the rejected
    candidates (for refineDetectedMarkers)."""
    detector = _marker_detector(dictionary)
    corners, ids, rejected = detector.detectMarkers(small)
    if ids is None or len(ids) == 0:
        return np.zeros((0, 4, 2)), np.zeros(0, np.int64), rejected, detector
    quad = np.asarray(corners, np.float64).reshape(-1, 4, 2)
    return quad, np.asarray(ids, np.int64).ravel(), rejected, detector


def _to_full(points: F64, scale: float) -> F64:
    """Pixel-centre coordinates on the downscaled copy -> on the full image."""
    if scale == 1.0:
        return points
    return (points + 0.5) / scale - 0.5


def _id_ranges(ids: I64) -> str:
    """'0-17' or '3, 5, 9-12' for a list of ids."""
    values = sorted({int(i) for i in ids})
    parts: list[str] = []
    start = prev = values[0]
    for v in [*values[1:], None]:
        if v is not None and v == prev + 1:
            prev = v
            continue
        parts.append(f"{start}" if start == prev else f"{start}-{prev}")
        if v is not None:
            start = prev = v
    return ", ".join(parts)


# ----------------------------------------------------------------------------------------
# What board the markers fit.


def _fit_board_size(img: F64, ids: I64, inset: float) -> tuple[int, int, int] | None:
    """The squares_x (and the fewest squares_y holding the ids) of the board whose layout
    the markers fit best, with the number of markers that agree; None when fewer than three
    markers agree under any width."""
    if len(ids) < 3:
        return None
    max_id = int(ids.max())
    pairs = _MarkerPairs(img, inset)
    best: tuple[int, int, int] | None = None
    for sx in range(2, min(200, 2 * max_id + 3)):
        sy = max(2, math.ceil(2 * (max_id + 1) / sx))
        while (sx * sy) // 2 <= max_id:
            sy += 1
        for legacy in (False, True) if sy % 2 == 0 else (False,):
            cells = marker_cells(sx, sy, legacy)
            n = int(pairs.agreement(cells[ids]).largest_group().sum())
            if n >= 3 and (best is None or n > best[2]):
                best = (sx, sy, n)
    return best


def _board_guess(img: F64, ids: I64, inset: float) -> str:
    """'a 6 x 6 board?': the board the markers seen suggest (the fewest rows that hold
    their ids, 'or taller' when the ids seen may not reach the last row)."""
    fit = _fit_board_size(img, ids, inset)
    n = int(ids.max()) + 1
    if fit is None:
        return f"a board of at least {n} markers?"
    sx, sy, _ = fit
    last_row_seen = n > (sx * (sy - 1)) // 2 + max(1, sx // 2 - 1)
    return f"a {sx} x {sy} board?" if last_row_seen else f"a {sx} x {sy} board, or taller?"


def _smallest_dictionary(family: str, max_id: int) -> str:
    """The smallest predefined dictionary of `family` (e.g. DICT_5X5_250) holding max_id."""
    if not family.endswith("_250"):
        return family
    stem = family[: -len("250")]
    for size in (50, 100, 250, 1000):
        if max_id < size:
            return f"{stem}{size}"
    return family


def _search_dictionaries(
    grey: NDArray[np.uint8], board: CharucoBoard, deadline: float
) -> tuple[str, F64, I64] | None:
    """The dictionary (other than the board's own) under which most markers decode and
    agree, with those markers; None when none shows at least three."""
    small, scale = _downscaled(grey, SEARCH_MAX_SIDE)
    inset = 0.5 * (1.0 - board.marker / board.square)
    best: tuple[str, F64, I64] | None = None
    seconds_per_code = 0.0
    for family in _FAMILIES:
        if family == board.dictionary or (
            family.endswith("_250")
            and board.dictionary.startswith(family[:-3])
            and len(board.opencv_dictionary().bytesList) >= 250
        ):
            continue
        dictionary = cv2.aruco.getPredefinedDictionary(dictionary_id(family))
        # Decoding time grows with the dictionary's size: skip one that would not finish.
        codes = len(dictionary.bytesList)
        if time.perf_counter() + seconds_per_code * codes > deadline:
            continue
        started = time.perf_counter()
        quad, ids, _, _ = _find_markers(small, dictionary)
        seconds_per_code = max(seconds_per_code, (time.perf_counter() - started) / codes)
        if len(ids) < 3:
            continue
        # Codes alone can decode by chance in noise: the markers must sit as a board's do.
        fit = _fit_board_size(quad, ids, inset)
        if fit is None:
            continue
        if best is None or len(ids) > len(best[2]):
            best = (family, _to_full(quad, scale), ids)
        if fit[2] >= 6:
            break  # a board's worth of markers: this is the dictionary
    return best


# ----------------------------------------------------------------------------------------
# Corners.


class _CornerTemplate:
    """The board's ink around an inner corner, as sample points in squares (relative to the
    corner) and the darkness expected there (1 ink, 0 paper): the two black squares, the
    white gap of the two marker squares and the markers' black border cells."""

    def __init__(self, board: CharucoBoard) -> None:
        gap = 0.5 * (1.0 - board.marker / board.square)
        bits = int(board.opencv_dictionary().markerSize) + 2
        border = (board.marker / board.square) / bits
        half = min(0.5, gap + border)
        n = 13
        u = (np.arange(n) + 0.5) / n * 2.0 * half - half
        xs, ys = np.meshgrid(u, u)
        pts = np.column_stack([xs.ravel(), ys.ravel()])
        ax, ay = np.abs(pts[:, 0]), np.abs(pts[:, 1])
        # Quadrants: (+,+) and (-,-) hold the squares of the corner's own cell and the one
        # diagonally before it; which of the two diagonals is black depends on the corner.
        same_sign = np.sign(pts[:, 0]) == np.sign(pts[:, 1])
        in_marker_border = (ax > gap) & (ay > gap)
        self.points = pts
        self.same_sign = same_sign
        self.in_marker_border = in_marker_border
        # Leave out samples within a hair of an edge (blur makes them grey either way).
        margin = 0.12 * half
        near_edge = (ax < margin) | (ay < margin)
        near_edge |= (np.abs(ax - gap) < margin) & (ay > gap - margin)
        near_edge |= (np.abs(ay - gap) < margin) & (ax > gap - margin)
        self.use = ~near_edge
        self.half = half
        self.gap = gap

    def expected(self, black_on_same_sign: NDArray[np.bool_]) -> F64:
        """Expected darkness per corner (rows) and sample (columns)."""
        black_diag = self.same_sign[None, :] == black_on_same_sign[:, None]
        ink = black_diag | (~black_diag & self.in_marker_border[None, :])
        return np.asarray(ink, np.float64)


def _local_homography(obj: F64, img: F64) -> F64 | None:
    if len(obj) < 4:
        return None
    centred = obj - obj.mean(axis=0)
    if np.linalg.svd(centred, compute_uv=False)[-1] < 0.3 * math.sqrt(len(obj)) * 0.3:
        return None  # (nearly) on one line
    h, _ = cv2.findHomography(obj.astype(np.float64), img.astype(np.float64), 0)
    if h is None or not np.all(np.isfinite(h)):
        return None
    return np.asarray(h, np.float64)


class _CornerFinder:
    """Predicts, refines and checks the inner corners of one board in one image."""

    def __init__(
        self,
        grey: NDArray[np.uint8],
        board: CharucoBoard,
        legacy: bool,
        marker_img: F64,
        marker_ids: I64,
    ) -> None:
        self.grey = grey
        self.board = board
        self.cols, self.rows = board.cols, board.rows
        self.inset = 0.5 * (1.0 - board.marker / board.square)
        self.template = _CornerTemplate(board)
        cells = marker_cells(board.squares_x, board.squares_y, legacy)
        self.marker_parity = int((cells[0, 0] + cells[0, 1]) % 2)
        obj = _marker_square_corners(cells[marker_ids], self.inset)
        self.marker_h = {
            int(m): h
            for m, h in zip(marker_ids, _marker_homographies(obj, marker_img), strict=True)
        }
        self.cell_marker = {(int(x), int(y)): i for i, (x, y) in enumerate(cells)}
        # Support for local homographies: the markers' corners, then the corners found.
        self.support_obj = [obj.reshape(-1, 2)]
        self.support_img = [marker_img.reshape(-1, 2)]
        self.found: dict[int, F64] = {}
        self.unrefined: set[int] = set()
        # The disc (px) each corner's centre of symmetry was found in (not there: none).
        self.symmetry_radius: dict[int, float] = {}
        self.blurred = np.asarray(
            cv2.GaussianBlur(grey.astype(np.float32), (0, 0), SMOOTHING_SIGMA), np.float32
        )
        self.asymmetry = np.zeros(0)
        self._gradients: (
            tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]] | None
        ) = None

    def corner_obj(self, k: int) -> F64:
        r, c = divmod(k, self.cols)
        return np.array([c + 1.0, r + 1.0])

    def adjacent_markers(self, k: int) -> list[int]:
        r, c = divmod(k, self.cols)
        out = []
        for cell in ((c, r), (c + 1, r), (c, r + 1), (c + 1, r + 1)):
            m = self.cell_marker.get(cell)
            if m is not None and m in self.marker_h:
                out.append(m)
        return out

    def black_on_same_sign(self, ks: I64) -> NDArray[np.bool_]:
        """Whether the corner's (+,+) and (-,-) quadrants are the black squares."""
        r, c = np.divmod(ks, self.cols)
        # The (+,+) quadrant is cell (c + 1, r + 1); a marker (white) cell has the parity.
        return np.asarray(((c + 1 + r + 1) % 2) != self.marker_parity, bool)

    def predict_from_markers(self, ks: list[int]) -> F64:
        out = np.empty((len(ks), 2))
        for n, k in enumerate(ks):
            markers = self.adjacent_markers(k)
            p = np.broadcast_to(self.corner_obj(k), (len(markers), 1, 2))
            out[n] = _apply(np.stack([self.marker_h[m] for m in markers]), p)[:, 0].mean(axis=0)
        return out

    def local_fit(self, k: int) -> F64 | None:
        """The homography (squares -> px) of the support points near corner k."""
        if len(self.support_obj) > 1:
            self.support_obj = [np.vstack(self.support_obj)]
            self.support_img = [np.vstack(self.support_img)]
        obj, img = self.support_obj[0], self.support_img[0]
        centre = self.corner_obj(k)
        d = np.max(np.abs(obj - centre), axis=1)
        for radius in (1.6, 2.6, 3.6):
            near = d <= radius
            if near.sum() >= 6:
                h = _local_homography(obj[near], img[near])
                if h is not None:
                    return h
        return None

    def refine(self, ks: list[int], predicted: F64, hs: list[F64]) -> tuple[F64, F64]:
        """cornerSubPix in a window clear of the markers, then the centre of symmetry of the
        ink around the corner; each corner's refined position and its ink correlation
        (-1..1) with the board around it."""
        g = self.inset
        hstack = np.stack(hs)
        centres = np.array([self.corner_obj(k) for k in ks])
        # The nearest marker corners: diagonally in the two marker squares.
        diag = np.array([[g, g], [-g, -g], [g, -g], [-g, g], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
        mapped = _apply(hstack, centres[:, None, :] + diag[None, :, :])
        d = np.linalg.norm(mapped[:, :4] - mapped[:, 4:5], axis=2).min(axis=1)
        square_px = np.linalg.norm(mapped[:, 5:] - mapped[:, 4:5], axis=2).min(axis=1)
        halves = np.clip((WINDOW_FRACTION * d).astype(np.int64), 2, MAX_HALF_WINDOW)
        refined = predicted.copy()
        h_img, w_img = self.grey.shape
        inside = (
            (predicted[:, 0] >= halves + 1)
            & (predicted[:, 1] >= halves + 1)
            & (predicted[:, 0] <= w_img - halves - 2)
            & (predicted[:, 1] <= h_img - halves - 2)
        )
        criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.001)
        for half in np.unique(halves[inside]):
            sel = inside & (halves == half)
            pts = predicted[sel].astype(np.float32).reshape(-1, 1, 2)
            out = cv2.cornerSubPix(self.blurred, pts, (int(half), int(half)), (-1, -1), criteria)
            refined[sel] = out.reshape(-1, 2)
        # Then the centre of symmetry, in a disc that holds no marker bit (the ink there is
        # the same turned by 180 degrees): on renders 5 times closer to the truth than
        # cornerSubPix alone, and it holds under blur that leaves cornerSubPix lost.
        t = self.template.half
        axes = np.array([[t, 0.0], [-t, 0.0], [0.0, t], [0.0, -t]])
        reach = _apply(hstack, centres[:, None, :] + axes[None, :, :])
        radius = 0.9 * np.linalg.norm(reach - mapped[:, 4:5], axis=2).min(axis=1)
        # Only the X itself (two lines through the corner) is symmetric under perspective and
        # a lens; the markers' borders farther out are so only to first order and pulled the
        # fit by up to 0.8 px on an oblique close-up. So the disc stops short of the nearest
        # marker corner, but keeps SYMMETRY_MIN_RADIUS px for blurred small squares.
        radius = np.minimum(radius, np.maximum(0.9 * d, SYMMETRY_MIN_RADIUS))
        symmetric = self.symmetry_refine(refined, radius)
        # Where the disc leaves the image the border's replicated pixels are no symmetry.
        disc_inside = (
            (symmetric[:, 0] >= radius + 1)
            & (symmetric[:, 1] >= radius + 1)
            & (symmetric[:, 0] <= w_img - radius - 2)
            & (symmetric[:, 1] <= h_img - radius - 2)
        )
        use = inside & disc_inside
        refined[use] = symmetric[use]
        for i in np.flatnonzero(use):
            self.symmetry_radius[ks[i]] = max(float(radius[i]), 2.0)  # symmetry_refine's
        moved = np.linalg.norm(refined - predicted, axis=1)
        corr = self.ink_correlation(ks, refined, hstack, centres, mapped[:, 4])
        # A third of a square away it would be another corner (whose ink, the other
        # diagonal black, the check refuses anyway).
        limit = np.maximum(np.maximum(0.8 * halves + 0.5, 0.6 * d), 0.3 * square_px)
        # Not symmetric about the point found: part of the corner hidden (an occluder's
        # edge pulls the fit), not a corner to keep where it was refined.
        lopsided = use & (self.asymmetry > MAX_ASYMMETRY)
        corr[~inside | (moved > limit) | lopsided] = -1.0
        return refined, corr

    def symmetry_refine(self, start: F64, radius: F64, iterations: int = 25) -> F64:
        """The centre of point symmetry of the grey levels within `radius` px of each
        corner (Gauss-Newton from `start`): the board's ink around an inner corner, the two
        black squares, the white gaps and the markers' black borders, is the same turned by
        180 degrees about the corner, however blurred."""
        if self._gradients is None:
            img = self.blurred
            gx = np.asarray(cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3) / 8.0, np.float32)
            gy = np.asarray(cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3) / 8.0, np.float32)
            self._gradients = (img, gx, gy)
        img, gx, gy = self._gradients
        q = start.copy()
        r_max = int(np.clip(np.ceil(radius.max()), 2, 200))
        stride = max(1, r_max // 12)  # at most 25 x 25 samples however large the squares
        u = np.arange(-r_max, r_max + 1, stride, dtype=np.float64)
        vx, vy = np.meshgrid(u, u)
        v = np.column_stack([vx.ravel(), vy.ravel()])
        v = v[(v[:, 1] > 0) | ((v[:, 1] == 0) & (v[:, 0] > 0))]  # one of each pair +-v
        dist = np.linalg.norm(v, axis=1)
        rad = np.maximum(radius, 2.0)[:, None]
        weight = np.where(
            dist[None, :] <= rad, np.exp(-0.5 * (dist[None, :] / (0.5 * rad)) ** 2), 0.0
        )

        def sample(image: NDArray[np.float32], pts: F64) -> F64:
            p32 = pts.astype(np.float32)
            out = cv2.remap(
                image, p32[..., 0], p32[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
            )
            return np.asarray(out, np.float64)

        active = np.arange(len(q))
        for _ in range(iterations):
            qa, w = q[active], weight[active]
            a = qa[:, None, :] + v[None, :, :]
            b = qa[:, None, :] - v[None, :, :]
            r = sample(img, a) - sample(img, b)
            jx = sample(gx, a) - sample(gx, b)
            jy = sample(gy, a) - sample(gy, b)
            sxx = (w * jx * jx).sum(1)
            sxy = (w * jx * jy).sum(1)
            syy = (w * jy * jy).sum(1)
            bx = -(w * jx * r).sum(1)
            by = -(w * jy * r).sum(1)
            det = sxx * syy - sxy * sxy
            ok = det > 1e-9 * np.maximum(sxx * syy, 1e-12)
            safe = np.where(ok, det, 1.0)
            step = np.column_stack(
                [
                    np.where(ok, (syy * bx - sxy * by) / safe, 0.0),
                    np.where(ok, (sxx * by - sxy * bx) / safe, 0.0),
                ]
            )
            norm = np.linalg.norm(step, axis=1)
            step *= np.minimum(1.0, 1.0 / np.maximum(norm, 1e-12))[:, None]  # 1 px a step at most
            q[active] = qa + step
            active = active[norm >= 0.005]
            if len(active) == 0:
                break
        # How far from symmetric the disc is at the end: the turned difference's RMS over
        # the grey levels' spread (a corner half hidden by something else is not symmetric).
        a = q[:, None, :] + v[None, :, :]
        b = q[:, None, :] - v[None, :, :]
        ia, ib = sample(img, a), sample(img, b)
        wsum = np.maximum(weight.sum(1), 1e-9)
        mean = (weight * (ia + ib)).sum(1) / (2 * wsum)
        spread = np.sqrt(
            (weight * ((ia - mean[:, None]) ** 2 + (ib - mean[:, None]) ** 2)).sum(1) / (2 * wsum)
        )
        self.asymmetry = np.sqrt((weight * (ia - ib) ** 2).sum(1) / wsum) / np.maximum(spread, 1.0)
        return np.asarray(q, np.float64)

    def ink_correlation(
        self, ks: list[int], at: F64, hstack: F64, centres: F64, predicted: F64
    ) -> F64:
        """Correlation of the grey levels around each corner with the board's ink there."""
        t = self.template
        pts = t.points[t.use]
        mapped = _apply(hstack, centres[:, None, :] + pts[None, :, :])
        mapped += (at - predicted)[:, None, :]
        m32 = mapped.astype(np.float32)
        samples = cv2.remap(
            self.blurred,
            np.ascontiguousarray(m32[:, :, 0]),
            np.ascontiguousarray(m32[:, :, 1]),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )
        expected = t.expected(self.black_on_same_sign(np.asarray(ks, np.int64)))[:, t.use]
        darkness = 255.0 - samples.astype(np.float64)
        a = darkness - darkness.mean(axis=1, keepdims=True)
        b = expected - expected.mean(axis=1, keepdims=True)
        denom = np.sqrt((a * a).sum(axis=1) * (b * b).sum(axis=1))
        corr = (a * b).sum(axis=1) / np.maximum(denom, 1e-9)
        # A flat patch (no contrast) is no corner.
        corr[darkness.std(axis=1) < 4.0] = -1.0
        return np.asarray(corr, np.float64)

    def accept(self, ks: list[int], points: F64, *, refined: bool = True) -> None:
        """Keep corners; refined ones also support the local fits of their neighbours."""
        for k, p in zip(ks, points, strict=True):
            self.found[k] = p
        if not refined:
            self.unrefined.update(ks)
            return
        self.support_obj.append(np.array([self.corner_obj(k) for k in ks]).reshape(-1, 2))
        self.support_img.append(points.reshape(-1, 2))

    def run(self, deadline: float) -> dict[int, F64]:
        """Every corner that can be found, by id (``unrefined`` then holds those that keep
        their markers' prediction: two markers vouch for them, but the image showed no
        corner there to refine, as on a glare or a fold)."""
        n = self.cols * self.rows
        tried: set[int] = set()
        by_markers: dict[int, int] = {}
        for k in range(n):
            count = len(self.adjacent_markers(k))
            if count:
                by_markers[k] = count
        ks = sorted(by_markers)
        two = {k for k in ks if by_markers[k] >= 2}
        if ks:
            predicted = self.predict_from_markers(ks)
            hs = [self.marker_h[self.adjacent_markers(k)[0]] for k in ks]
            refined, corr = self.refine(ks, predicted, hs)
            tried.update(ks)
            # Two markers vouch for a corner's id; the ink check only keeps its refinement
            # honest. One marker alone must show the board's ink around the corner.
            ok = [i for i in range(len(ks)) if corr[i] >= INK_MATCH]
            # Two markers vouch for a corner whose refinement the ink does not confirm
            # (an occluder's edge, glare): kept at their prediction, not refined.
            fallback = [
                i
                for i, k in enumerate(ks)
                if k in two and corr[i] < INK_MATCH and self._inside(predicted[i])
            ]
            self.accept([ks[i] for i in ok], refined[ok])
            self.accept([ks[i] for i in fallback], predicted[fallback], refined=False)
        # Follow the chessboard from the corners found.
        for _ in range(self.cols + self.rows):
            if time.thread_time() > deadline:
                break
            frontier: set[int] = set()
            for k in self.found:
                r, c = divmod(k, self.cols)
                for dr, dc in ((0, 1), (0, -1), (1, 0), (-1, 0)):
                    rr, cc = r + dr, c + dc
                    if 0 <= rr < self.rows and 0 <= cc < self.cols:
                        kk = rr * self.cols + cc
                        if kk not in self.found and kk not in tried:
                            frontier.add(kk)
            if not frontier:
                break
            cand: list[int] = []
            hs_c: list[F64] = []
            for k in sorted(frontier):
                h = self.local_fit(k)
                tried.add(k)
                if h is not None:
                    cand.append(k)
                    hs_c.append(h)
            if not cand:
                break
            predicted = np.array(
                [_apply(h, self.corner_obj(k)[None])[0] for k, h in zip(cand, hs_c, strict=True)]
            )
            refined, corr = self.refine(cand, predicted, hs_c)
            keep = [i for i in range(len(cand)) if corr[i] >= INK_MATCH]
            if keep:
                self.accept([cand[i] for i in keep], refined[keep])
        return self.found

    def _inside(self, p: F64) -> bool:
        h, w = self.grey.shape
        return bool(0 <= p[0] <= w - 1 and 0 <= p[1] <= h - 1)


# ----------------------------------------------------------------------------------------
# The detector.


def _time_budget(image_px: int) -> float:
    """Seconds allowed for following the chessboard (the issue's bounds: 2 s for a 720p
    image, 8 s for a 16 MP photo, with room for the rest)."""
    return 1.2 if image_px <= 1_500_000 else 4.0


def _not_collinear(ids: I64, cols: int) -> bool:
    r, c = np.divmod(ids, cols)
    pts = np.column_stack([c, r]).astype(np.float64)
    if len(pts) < 3:
        return False
    return bool(np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)[-1] > 1e-6)


def _layout_name(legacy: bool) -> str:
    return "legacy" if legacy else "current"


def _layout_words(legacy: bool) -> str:
    return (
        "OpenCV's legacy layout (before 4.6, legacy=True)"
        if legacy
        else "OpenCV's current layout (4.6 and later, legacy=False)"
    )


class _Markers:
    """The markers decoded in one image: corners on the detection copy (n, 4, 2), ids, and
    what refineDetectedMarkers needs."""

    def __init__(self, grey: NDArray[np.uint8], board: CharucoBoard) -> None:
        dictionary = _detection_dictionary(board)
        small, scale = _downscaled(grey, DETECT_MAX_SIDE)
        # (OpenCV's smallest marker is a fraction of the image's size, 15 px on the copy:
        # the full image would need 40 px, so it would find no more.)
        quad, ids, rejected, detector = _find_markers(small, dictionary)
        self.small, self.scale = small, scale
        self.quad, self.ids = quad, ids
        self.rejected, self.detector = rejected, detector
        on_board = ids < board.n_markers
        self.stray_ids = ids[~on_board]
        self.quad_on, self.ids_on = quad[on_board], ids[on_board]


def _choose_layout(
    board: CharucoBoard, markers: _Markers, inset: float
) -> tuple[bool, NDArray[np.bool_]]:
    """The printed layout the markers fit and the markers that agree in it; BoardNotFoundError
    when the markers cannot tell the layouts apart, BoardMismatchError when they fit the
    other layout than the one described."""
    if board.layouts_differ:
        layouts = [False, True] if board.legacy is None else [board.legacy, not board.legacy]
    else:
        layouts = [bool(board.legacy)]
    groups: dict[bool, NDArray[np.bool_]] = {}
    scores: dict[bool, tuple[int, int]] = {}
    pairs = _MarkerPairs(markers.quad_on, inset)
    for legacy in layouts:
        cells = marker_cells(board.squares_x, board.squares_y, legacy)
        agreement = pairs.agreement(cells[markers.ids_on])
        groups[legacy] = agreement.largest_group()
        scores[legacy] = (int(groups[legacy].sum()), agreement.n_agree - agreement.disagree)
    ids = markers.ids_on
    if board.legacy is None and board.layouts_differ:
        if scores[False] == scores[True] and scores[False][0] >= 2:
            by_edge = _layout_from_board_edge(board, markers, inset, groups[False])
            if by_edge is not None:
                return by_edge, groups[by_edge]
            raise BoardNotFoundError(
                f"the {len(ids)} markers seen (ids {_id_ranges(ids)}) fit both printed layouts "
                "of this board (it has an even number of rows, and the markers seen do not "
                "show which): give the layout (legacy=True for boards printed by OpenCV "
                "before 4.6, legacy=False after), or show more rows of markers"
            )
        legacy = scores[True] > scores[False]
        return legacy, groups[legacy]
    legacy = layouts[0]
    if board.layouts_differ:
        mine, other = scores[legacy][0], scores[not legacy][0]
        if other >= 2 and other >= mine + 2:
            raise BoardMismatchError(
                f"the markers seen (ids {_id_ranges(ids)}) are laid out as in "
                f"{_layout_words(not legacy)}, not in {_layout_words(legacy)} as described "
                f"({other} markers agree with that layout, {mine} with this one): describe "
                f"the board with legacy={not legacy} (or None to read either)"
            )
    return legacy, groups[legacy]


def _layout_from_board_edge(
    board: CharucoBoard, markers: _Markers, inset: float, keep: NDArray[np.bool_]
) -> bool | None:
    """The layout (legacy or not) that the board's edge in view shows, when the markers'
    places fit both (the two layouts then differ by a shift of one square: the markers at
    the ends of the rows, which would tell, are out of view). Next to a marker, a square
    that one layout has black the other has beyond the board: light paper. None when no such
    square is in view or its grey levels do not say."""
    quad, ids = markers.quad_on[keep], markers.ids_on[keep]
    hs = _MarkerPairs(quad, inset).hs
    if len(ids) < 2:
        return None
    offsets = np.array([(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dx or dy])
    expected = []
    for legacy in (False, True):
        cells = marker_cells(board.squares_x, board.squares_y, legacy)
        marker_parity = int(cells[0].sum() % 2)
        near = cells[ids][:, None, :] + offsets[None, :, :]
        x, y = near[..., 0], near[..., 1]
        on_board = (x >= 0) & (y >= 0) & (x < board.squares_x) & (y < board.squares_y)
        is_marker = on_board & ((x + y) % 2 == marker_parity)
        # 1: a black square, 0: beyond the board, -1: a marker square (not compared).
        expected.append(np.where(is_marker, -1, np.where(on_board, 1, 0)))
    differ = (expected[0] != expected[1]) & (expected[0] >= 0) & (expected[1] >= 0)
    if not differ.any():
        return None
    # Each square's middle half, sampled through its marker's homography.
    u = np.array([0.3, 0.5, 0.7])
    patch = np.stack(np.meshgrid(u, u), axis=-1).reshape(-1, 2)
    marker_idx, offset_idx = np.nonzero(differ)
    pts = offsets[offset_idx][:, None, :] + patch[None, :, :]
    px = _apply(hs[marker_idx], pts.astype(np.float64)).astype(np.float32)
    h, w = markers.small.shape
    inside = np.all((px[..., 0] >= 0) & (px[..., 0] <= w - 1), axis=1) & np.all(
        (px[..., 1] >= 0) & (px[..., 1] <= h - 1), axis=1
    )
    if not inside.any():
        return None
    values = cv2.remap(
        markers.small.astype(np.float32), px[..., 0], px[..., 1], cv2.INTER_LINEAR
    ).mean(axis=1)[inside]
    black_if_current = expected[0][marker_idx, offset_idx][inside] == 1
    # The black squares both layouts have next to the markers: the ink's grey.
    mi, oi = np.nonzero((expected[0] == 1) & (expected[1] == 1))
    if len(mi) == 0:
        return None
    ref = _apply(hs[mi], (offsets[oi][:, None, :] + patch[None, :, :]).astype(np.float64))
    ref32 = ref.astype(np.float32)
    black = float(
        np.median(
            cv2.remap(
                markers.small.astype(np.float32), ref32[..., 0], ref32[..., 1], cv2.INTER_LINEAR
            )
        )
    )
    # Only light paper decides: a dark square there may be a black square or a dark table
    # beyond a board printed to its edge. The layout that has the board end where the
    # image is light (and, where it has black squares, dark) is the one printed.
    lighter = values - black >= LIGHT_PAPER
    for legacy, its_black in ((False, black_if_current), (True, ~black_if_current)):
        beyond = ~its_black
        if (
            beyond.sum() >= 2
            and lighter[beyond].all()
            and not lighter[its_black].any()
            and (lighter[beyond].sum() > 0)
        ):
            return legacy
    return None


LIGHT_PAPER = 50.0
"""Grey levels above the black squares' that a square must show to be read as the paper
beyond the board's edge."""


def _refuse(
    grey: NDArray[np.uint8], board: CharucoBoard, markers: _Markers, n_group: int, start: float
) -> None:
    """Raise the error that says what was seen when the markers do not make the board: ids
    beyond its markers, another dictionary, another size, or nothing."""
    inset = 0.5 * (1.0 - board.marker / board.square)
    stray, ids = markers.stray_ids, markers.ids
    name = board.dictionary
    if len(stray) >= 2 and len(stray) >= n_group:
        # Every id of the dictionary, for the board's size (only a few beyond the board's
        # were decoded).
        quad, ids, _, _ = _find_markers(markers.small, board.opencv_dictionary())
        raise BoardMismatchError(
            f"markers of {name} ids {_id_ranges(ids)}: the described board "
            f"({board.describe()}) has ids 0-{board.n_markers - 1}; "
            f"{_board_guess(quad, ids, inset)}"
        )
    n_inconsistent = len(markers.ids_on) - n_group
    if n_group >= 2 and n_inconsistent >= max(4, n_group):
        raise BoardMismatchError(
            f"markers of {name} ids {_id_ranges(markers.ids_on)}: only {n_group} of them sit "
            f"where the described board ({board.describe()}) has them; "
            f"{_board_guess(markers.quad_on, markers.ids_on, inset)}"
        )
    if n_group >= 2:
        return
    ratio = _fit_marker_ratio(board, markers)
    if ratio is not None:
        raise BoardMismatchError(
            f"the markers of {name} seen (ids {_id_ranges(markers.ids_on)}) fit this board "
            f"with markers {ratio * board.square:.3g} mm wide for its {board.square:g} mm "
            f"squares ({ratio:.2f} of the square), not the {board.marker:g} mm described: "
            "measure the printed marker (its black border, outside to outside) and the square"
        )
    found = _search_dictionaries(grey, board, start + SEARCH_DEADLINE_S)
    if found is not None:
        family, quad_x, ids_x = found
        seen_own = "not seen" if len(ids) == 0 else f"seen only {len(ids)}"
        raise BoardMismatchError(
            f"markers of {_smallest_dictionary(family, int(ids_x.max()))} ids "
            f"{_id_ranges(ids_x)}: {_board_guess(quad_x, ids_x, inset)} (the board was "
            f"described as {board.describe()}, whose {name} markers were {seen_own})"
        )
    if len(ids):
        seen = f"{len(ids)} markers of {name} decoded (ids {_id_ranges(ids)})"
        if len(ids) >= 2:
            seen += ", no two of them where the board would put them"
    else:
        seen = f"no marker of {name} decoded"
    raise BoardNotFoundError(
        f"no {board.describe()} found: {seen}, nor markers of another predefined dictionary. "
        "Try a sharper, evenly lit view in which the markers are at least 20 px wide, and "
        "check the board's dictionary"
    )


def _fit_marker_ratio(board: CharucoBoard, markers: _Markers) -> float | None:
    """The marker-to-square ratio under which at least three of the markers seen agree (the
    one under which most do), when the stated one lets no two agree; None when none does."""
    if len(markers.ids_on) < 3:
        return None
    best: tuple[int, float, float] | None = None
    layouts = (False, True) if board.layouts_differ else (bool(board.legacy),)
    cells = {legacy: marker_cells(board.squares_x, board.squares_y, legacy) for legacy in layouts}
    for ratio in np.arange(0.30, 0.96, 0.01):
        pairs = _MarkerPairs(markers.quad_on, 0.5 * (1.0 - ratio))
        for legacy in layouts:
            agreement = pairs.agreement(cells[legacy][markers.ids_on])
            n = int(agreement.largest_group().sum())
            # The most markers agreeing, then the closest agreement.
            if n >= 3 and (best is None or (n, -agreement.error) > (best[0], -best[2])):
                best = (n, float(ratio), agreement.error)
    return None if best is None else best[1]


def _recover_markers(
    board: CharucoBoard, markers: _Markers, legacy: bool, keep: NDArray[np.bool_]
) -> tuple[F64, I64]:
    """The agreeing markers, with those OpenCV's refineDetectedMarkers recovers from the
    candidates it rejected (kept when they agree with the others too)."""
    quad, ids = markers.quad_on[keep], markers.ids_on[keep]
    inset = 0.5 * (1.0 - board.marker / board.square)
    try:
        r_corners, r_ids, _, _ = markers.detector.refineDetectedMarkers(
            markers.small,
            board.opencv_board(legacy),
            [q.reshape(1, 4, 2).astype(np.float32) for q in quad],
            ids.reshape(-1, 1).astype(np.int32),
            markers.rejected,
        )
    except cv2.error:
        return quad, ids  # the markers detected stand
    if r_ids is None or len(r_ids) <= len(ids):
        return quad, ids
    q2 = np.asarray(r_corners, np.float64).reshape(-1, 4, 2)
    i2 = np.asarray(r_ids, np.int64).ravel()
    on = i2 < board.n_markers
    cells = marker_cells(board.squares_x, board.squares_y, legacy)
    group = _MarkerPairs(q2[on], inset).agreement(cells[i2[on]]).largest_group()
    if group.sum() > len(ids):
        return q2[on][group], i2[on][group]
    return quad, ids


def detect_charuco(image: Any, board: CharucoBoard, **options: Any) -> BoardDetection:
    """Find the ChArUco `board` in `image` (an array, grey or BGR, any real dtype, or a path):
    the inner corners seen, with OpenCV's ids, refined to sub-pixel (see the module).

    Any part of the board in view is a detection (``partial``) as long as it shows at least
    four corners not on one line. ``layout`` says which printed layout was read ("legacy" or
    "current"; for a board with an odd number of rows the two are the same board and
    ``board.legacy``, else "current", is reported). Raises BoardNotFoundError saying what was
    seen, and BoardMismatchError when the markers say the board is not the one described
    (another dictionary, more markers, another size or layout)."""
    if options:
        raise ArgumentError(f"detect_charuco takes no options, got {', '.join(sorted(options))}")
    if not isinstance(board, CharucoBoard):
        raise ArgumentError(f"board must be a CharucoBoard, got {type(board).__name__}")
    start = time.perf_counter()
    grey = _uint8(grey_levels(image))
    height, width = grey.shape
    inset = 0.5 * (1.0 - board.marker / board.square)

    markers = _Markers(grey, board)
    legacy, keep = _choose_layout(board, markers, inset)
    n_group = int(keep.sum())
    if (
        n_group < 2
        or len(markers.stray_ids) >= max(3, n_group)
        or (len(markers.ids_on) - n_group >= max(4, n_group))
    ):
        _refuse(grey, board, markers, n_group, start)

    marker_quad, marker_ids = _recover_markers(board, markers, legacy, keep)
    warnings: list[str] = []
    dropped = np.setdiff1d(markers.ids_on, marker_ids)
    if len(dropped):
        warnings.append(
            f"marker ids {_id_ranges(dropped)} do not sit where the board has them (a "
            "misread code or another board in view): left out"
        )
    if len(markers.stray_ids):
        warnings.append(
            f"marker ids {_id_ranges(markers.stray_ids)} are not on this board (ids 0-"
            f"{board.n_markers - 1}): left out"
        )

    finder = _CornerFinder(grey, board, legacy, _to_full(marker_quad, markers.scale), marker_ids)
    # CPU time of this thread (not wall-clock time, which other work on the machine
    # stretches): the same image gives the same corners however busy the machine is.
    found = finder.run(time.thread_time() + _time_budget(height * width))
    corner_ids = np.array(sorted(found), np.intp)
    if len(corner_ids) < MIN_CORNERS or not _not_collinear(corner_ids, board.cols):
        n = len(corner_ids)
        raise BoardNotFoundError(
            f"{board.describe()}: {len(marker_ids)} of its markers seen (ids "
            f"{_id_ranges(marker_ids)}), which show {n} inner corner{'s' if n != 1 else ''}"
            + (" all on one line" if n >= MIN_CORNERS else "")
            + f"; at least {MIN_CORNERS} corners not on one line are needed. Show more of the "
            "board"
        )
    points = np.array([found[int(k)] for k in corner_ids], np.float64)
    points = _without_bend_lean(points, corner_ids, board, finder)
    return BoardDetection(
        board=board,
        image_points=points,
        image_size=(width, height),
        method="charuco",
        residual_rms_px=_homography_rms(board.world_points()[corner_ids], points),
        ids=corner_ids,
        polarity="dark",
        refined=~np.isin(corner_ids, list(finder.unrefined)),
        orientation="marker",
        orientation_rule=ORIENTATION_RULE,
        warnings=tuple(warnings),
        layout=_layout_name(legacy),
    )


def _without_bend_lean(
    points: F64, ids: NDArray[np.intp], board: CharucoBoard, finder: _CornerFinder
) -> F64:
    """The corners less the lean a lens's bend of the edges gives their centre of symmetry
    (SYMMETRY_SECOND_MOMENT): each edge bends as its grid line through the refined corners
    (corner_refine.grid_bends), so the correction adds no free parameter. A smooth radial
    field otherwise, which a calibration absorbs unseen (issue 23). Corners without a bend
    (fewer than three in a row near) or a centre of symmetry are left as they are."""
    radius = np.array([finder.symmetry_radius.get(int(k), np.nan) for k in ids])
    refined = ~np.isin(ids, list(finder.unrefined))
    if len(ids) < 4 or not np.isfinite(radius).any():
        return points
    rows, cols = np.divmod(ids, board.cols)
    grid = np.full((board.rows, board.cols, 2), np.nan)
    grid[rows[refined], cols[refined]] = points[refined]
    bends = grid_bends(grid)[rows, cols]  # (N, 2, 2): along u (the board's x), along v
    # The edges' directions: the board's axes through the corners' homography.
    world = board.world_points()[ids]
    found_h, _ = cv2.findHomography(world, points, 0)
    if found_h is None:
        return points
    h = np.asarray(found_h, np.float64)
    step = 0.5 * board.square
    axes = np.stack(
        [_apply(h, world + e) - _apply(h, world - e) for e in ((step, 0.0), (0.0, step))], axis=1
    )
    tangents = axes / np.maximum(np.linalg.norm(axes, axis=2, keepdims=True), 1e-12)
    normals = np.stack([-tangents[..., 1], tangents[..., 0]], axis=2)  # (N, 2 edges, 2)
    # Each edge y = a x^2 (a = n . b / 2) leans the centre by a <x^2> along its normal.
    lean_n = 0.5 * np.sum(normals * bends, axis=2) * (SYMMETRY_SECOND_MOMENT * radius**2)[:, None]
    det = normals[:, 0, 0] * normals[:, 1, 1] - normals[:, 0, 1] * normals[:, 1, 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        lean = np.column_stack(
            [
                (normals[:, 1, 1] * lean_n[:, 0] - normals[:, 0, 1] * lean_n[:, 1]) / det,
                (normals[:, 0, 0] * lean_n[:, 1] - normals[:, 1, 0] * lean_n[:, 0]) / det,
            ]
        )
    ok = np.isfinite(lean).all(axis=1) & (np.abs(det) > 0.2)
    out = np.array(points, np.float64)
    out[ok] -= lean[ok]
    return out


def _homography_rms(world: F64, points: F64) -> float:
    """RMS distance of the points from the best homography through them (px)."""
    h, _ = cv2.findHomography(world, points, 0)
    if h is None:
        return float("nan")
    return float(
        np.sqrt(np.mean(np.sum((_apply(np.asarray(h, np.float64), world) - points) ** 2, axis=1)))
    )
