"""Finding a chessboard in an image: its inner corners, sub-pixel, with their ids.

1. **Finding**, with OpenCV's finders on the image downscaled to 800 px (then 1280, 2048,
   3200 and the image itself, while the time budget allows: each finder's time per pixel is
   learnt on the smaller copies, so noise and clutter, which slow them, end the search
   sooner): a board with an origin marker first by OpenCV's marker reading
   (``findChessboardCornersSB`` with ``CALIB_CB_MARKER | CALIB_CB_LARGER``, a 3 x 3 pattern:
   any part of the board that holds the marker); then ``findChessboardCorners`` (adaptive
   threshold, normalised; its quick check first), ``findChessboardCornersSB`` with
   ``CALIB_CB_LARGER`` (the largest grid of corners in view: the whole board, a part with a
   marker, or what the message names), and on the larger copies ``findChessboardCornersSB``
   exhaustive (without ``CALIB_CB_ACCURACY``, which only upsamples for OpenCV's own
   sub-pixel step, at twice the time) and ``findChessboardCorners`` in full.
2. **Refinement** at full resolution (planarcal.calib.corner_refine): a model of each corner
   (two blurred edges crossing) fitted to the grey levels; its figures against OpenCV's are in
   benches/bench_detection.py.
3. **Reading**: which board corner each grid corner is.
   - An origin marker (three dots in an L about the middle, chessboard.py) is read from the
     squares' centres: corner 0 is fixed by it, and so is every corner of a partial view,
     which is then grown to every corner in view (each predicted from its neighbours'
     homography and kept where a corner is found there). ``orientation="marker"``.
   - Without one, the squares' colours fix the reading where the board's two ends differ (a
     non-square board with cols + rows odd, as OpenCV's 9 x 6 ``pattern.png``: its top-left
     square is black, its bottom-right white): ``orientation="pattern"``.
   - Otherwise (cols + rows even, or a square board) the board looks the same turned by 180
     degrees (and a square one with an even side by 90): corner 0 is the board corner
     nearest the image's top-left of the readings that are not mirrored,
     ``orientation="ambiguous"`` with that rule. A non-square board that can only be read
     turned by 90 degrees (its rows running down the image) is refused with BoardTurnedError
     (``--cols`` and ``--rows`` swapped?) unless ``turned=True``.
   OpenCV's corner order may be mirrored and starts at either end; planarcal's is always
   row-major from corner 0 (see ChessboardBoard) with X to the right of Y as printed.

A plain chessboard partly out of view (or covered) is refused: which of its corners are in
view cannot be told. The message says so and names the boards that identify themselves.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Iterator
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.calib.chessboard import ChessboardBoard
from planarcal.calib.corner_refine import (
    RefinedCorners,
    corner_radius,
    grid_bends,
    refine_corners,
)
from planarcal.calib.detection import BoardDetection, Orientation
from planarcal.errors import (
    ArgumentError,
    ArgumentTypeError,
    BoardMismatchError,
    BoardNotFoundError,
    BoardTurnedError,
    DegenerateError,
    HomographyError,
)
from planarcal.homography import estimate_homography, reprojection_errors, transform_points
from planarcal.images import grey_levels

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]
I64 = NDArray[np.int64]

FIND_LONG_SIDES = (800, 1280, 2048, 3200)
"""The finders' images: the image downscaled to these many px along its longer side (each
one that is smaller than the image, then the image itself if it is not much larger)."""
TIME_BUDGET_S = 1.2
"""Seconds the finders may take for an image of up to a megapixel..."""
TIME_BUDGET_PER_MEGAPIXEL_S = 0.33
"""... plus this per further megapixel (a 16-megapixel photograph: about 6 s in all). A
finder is started only where its expected time (below) still fits."""
CLASSIC_S_PER_PIXEL = 1.0e-6
SB_S_PER_PIXEL = 0.4e-6
SB_EXHAUSTIVE_S_PER_PIXEL = 0.8e-6
"""findChessboardCorners', findChessboardCornersSB's and its exhaustive search's least time
per pixel where they find no board (on two cores); each finder's rate on the image at hand,
once measured on a smaller copy, replaces it where it is higher (noise and clutter slow them
several times)."""
BEND_LEAN_PX = 0.001
"""The corners are refined again with bent edges (_bent_edges) where a straight-edged fit
would lean by more than this somewhere. The lean grows with the distance from the lens's
centre, a smooth radial field that the calibration's homography and lens absorb unseen
(the residuals stay white, the error bars miss it): 0.01 px left 0.005-0.008 px per 400 px
of radius inwards at k1 = -0.12 (tests/calib/test_corner_bias.py)."""

AMBIGUOUS_CHESS_RULE = (
    "no origin marker, and the board looks the same turned: corner 0 is the board corner "
    "nearest the image's top-left corner, of the readings that are not mirrored"
)
PATTERN_CHESS_RULE = (
    "no origin marker: the squares' colours fix the reading (the board's top-left square is "
    "black, its bottom-right one white): corner 0 is the inner corner of the black one"
)
MARKER_CHESS_RULE = (
    "corner 0 is fixed by the origin marker (the black square with a white dot, and the "
    "white squares with black dots along the board's X and Y from it)"
)
PARTIAL_ADVICE = (
    "A plain chessboard partly out of view (or partly covered) is ambiguous: which of its "
    "corners are in view cannot be told. Bring the whole board into view, or use a board "
    "that identifies itself: a chessboard with an origin marker (ChessboardBoard(..., "
    "origin_marker=True), --marker) or a ChArUco board (--type charuco)."
)

# The eight signed permutations of the grid's axes: (u, v) -> M (u, v).
_SYMMETRIES = tuple(
    np.array(m, dtype=np.int64)
    for m in (
        [[1, 0], [0, 1]],
        [[-1, 0], [0, -1]],
        [[0, -1], [1, 0]],
        [[0, 1], [-1, 0]],
        [[-1, 0], [0, 1]],
        [[1, 0], [0, -1]],
        [[0, 1], [1, 0]],
        [[0, -1], [-1, 0]],
    )
)


@dataclasses.dataclass(frozen=True)
class ChessboardDiagnostics:
    """What a failed chessboard search saw (``BoardNotFoundError.diagnostics``)."""

    board: ChessboardBoard
    image_size: tuple[int, int]
    """(width, height) px."""
    attempts: tuple[str, ...]
    """Each finder tried, at which scale, and its outcome."""
    grid_shape: tuple[int, int] | None
    """The largest grid of chessboard corners seen (corners across, down), if any."""
    grid_points_px: F64
    """Its corners (K, 2) px."""


@dataclasses.dataclass
class _Grid:
    """Corners on a grid as a finder returned them: points[v, u] (rows v, columns u), px."""

    points: F64
    method: str


@dataclasses.dataclass(frozen=True)
class _Reading:
    """Grid corner (u, v) is board corner M (u, v) + t = (c, r)."""

    m: I64
    t: I64
    orientation: Orientation
    rule: str
    warnings: tuple[str, ...] = ()


class _RefusedError(Exception):
    """A grid that is not the board (the reason is the message)."""


def detect_chessboard(
    image: Any, board: ChessboardBoard, *, turned: bool = False
) -> BoardDetection:
    """Find the chessboard `board` in `image` (an array, grey or BGR, any real dtype, or a
    path); planarcal.calib.detection.detect_board's detector for chessboards.

    Returns the inner corners found with their ids (``ids``: 0-based, row-major from corner
    0, see ChessboardBoard): every corner of a whole board; with an origin marker, the
    corners in view of a board partly out of view or covered. ``turned=True`` accepts a
    non-square board whose reading is ambiguous and that lies turned by 90 degrees in the
    image (otherwise BoardTurnedError: usually ``--cols`` and ``--rows`` swapped). Raises
    BoardNotFoundError saying what was seen and what to try (``.diagnostics``: a
    ChessboardDiagnostics), BoardMismatchError when the board in view is larger than
    described.
    """
    if not isinstance(board, ChessboardBoard):
        raise ArgumentError(f"board must be a ChessboardBoard, got {type(board).__name__}")
    if not isinstance(turned, bool):
        raise ArgumentTypeError(f"turned must be True or False, got {turned!r}")
    grey = grey_levels(image)
    u8 = _as_u8(grey)
    finder = _Finder(u8, board)
    refusals: list[str] = []
    turned_error: BoardTurnedError | None = None
    for grid in finder.grids():
        try:
            return _finish(grey, grid, board, turned)
        except BoardTurnedError as e:
            # Every finder finds the same grid, read the same way: no use going on.
            turned_error = e
            break
        except _RefusedError as e:
            refusals.append(f"{grid.method}: {e}")
    if turned_error is not None:
        raise BoardTurnedError(str(turned_error), finder.diagnostics())
    message = _explain(board, finder, refusals)  # probes for the largest grid in view
    raise BoardNotFoundError(message, finder.diagnostics())


def _as_u8(grey: NDArray[np.uint8] | NDArray[np.float32]) -> U8:
    if grey.dtype == np.uint8:
        return cast(U8, grey)
    return np.clip(np.rint(grey), 0, 255).astype(np.uint8)


# ------------------------------------------------------------------------------------------
# Finding


class _Finder:
    """OpenCV's finders over a downscaled copy and a larger one, within a time budget; each
    grid found is handed out as it comes, so the first that reads as the board ends the
    search."""

    def __init__(self, u8: U8, board: ChessboardBoard) -> None:
        self.u8 = u8
        self.board = board
        h, w = u8.shape
        # Processor time, not wall-clock: what the search finds does not depend on what
        # else the machine is doing.
        self.start = time.process_time()
        megapixels = w * h / 1e6
        self.budget = TIME_BUDGET_S + TIME_BUDGET_PER_MEGAPIXEL_S * max(0.0, megapixels - 1.0)
        self.attempts: list[str] = []
        self.largest: _Grid | None = None
        self.probed = False
        self.rates = {
            "classic": CLASSIC_S_PER_PIXEL,
            "sb": SB_S_PER_PIXEL,
            "sb-exhaustive": SB_EXHAUSTIVE_S_PER_PIXEL,
        }
        self._scaled: dict[int, tuple[U8, float]] = {}

    def _image(self, long_side: int) -> tuple[U8, float]:
        h, w = self.u8.shape
        scale = min(1.0, long_side / max(h, w))
        key = round(scale * 1e6)
        if key not in self._scaled:
            if scale >= 1.0:
                self._scaled[key] = (self.u8, 1.0)
            else:
                size = (max(8, round(w * scale)), max(8, round(h * scale)))
                small: U8 = np.asarray(
                    cv2.resize(self.u8, size, interpolation=cv2.INTER_AREA), dtype=np.uint8
                )
                self._scaled[key] = (small, size[0] / w)
        return self._scaled[key]

    def _fits(self, side: int, finder: str) -> bool:
        img, _ = self._image(side)
        expected = self.rates[finder] * img.size
        return bool(time.process_time() - self.start + expected <= self.budget)

    def _timed(self, finder: str, pixels: int, seconds: float) -> None:
        """Learn the finder's time per pixel on this image (clutter and noise slow it)."""
        self.rates[finder] = max(self.rates[finder], seconds / max(pixels, 1))

    def _sides(self) -> list[int]:
        long_side = max(self.u8.shape)
        sides = [s for s in FIND_LONG_SIDES if s * 1.25 < long_side]
        if long_side <= FIND_LONG_SIDES[-1] * 1.25:
            sides.append(long_side)
        return sides

    def grids(self) -> Iterator[_Grid]:
        board = self.board
        whole = (board.cols, board.rows)
        n = cv2.CALIB_CB_NORMALIZE_IMAGE
        first, *rest = self._sides()
        marker = n | cv2.CALIB_CB_MARKER | cv2.CALIB_CB_LARGER
        # The smallest image first: OpenCV's marker reading (a marker board), the classic
        # finder's quick check, then the largest grid of corners in view, whatever its size
        # (the whole board, a part with a marker, or what the message names), then the
        # classic finder in full.
        if board.origin_marker:
            yield from self._sb(first, (3, 3), marker, "opencv-sb-marker")
        yield from self._classic(first, whole, cv2.CALIB_CB_FAST_CHECK)
        yield from self._sb(first, (3, 3), n | cv2.CALIB_CB_LARGER, "opencv-sb-larger")
        self.probed = True
        yield from self._classic(first, whole, 0)
        # Then larger images, while time allows.
        for side in rest:
            if board.origin_marker:
                yield from self._sb(side, (3, 3), marker, "opencv-sb-marker")
            # Exhaustive, without CALIB_CB_ACCURACY: that flag upsamples the image for
            # OpenCV's own sub-pixel corners (planarcal refines its own) at twice the time.
            exhaustive = n | cv2.CALIB_CB_EXHAUSTIVE
            yield from self._sb(side, whole, exhaustive, "opencv-sb", rate="sb-exhaustive")
            yield from self._classic(side, whole, 0)
            if board.origin_marker:
                yield from self._sb(side, (3, 3), n | cv2.CALIB_CB_LARGER, "opencv-sb-larger")

    def _classic(self, side: int, size: tuple[int, int], extra: int) -> Iterator[_Grid]:
        if not self._fits(side, "classic") and not extra:
            return
        img, scale = self._image(side)
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | extra
        start = time.process_time()
        try:
            found, corners = cv2.findChessboardCorners(img, size, flags=flags)
        except cv2.error:
            found, corners = False, None
        if not extra:
            self._timed("classic", img.size, time.process_time() - start)
        quick = " (quick check)" if extra else ""
        label = f"findChessboardCorners{quick} at {img.shape[1]} x {img.shape[0]}"
        self.attempts.append(f"{label}: {'found' if found else 'not found'}")
        if found and corners is not None:
            pts = corners.reshape(size[1], size[0], 2).astype(np.float64)
            grid = _Grid(_to_full(pts, scale), "opencv-classic")
            self._keep_largest(grid)
            yield grid

    def _sb(
        self,
        side: int,
        size: tuple[int, int],
        flags: int,
        method: str,
        *,
        always: bool = False,
        rate: str = "sb",
    ) -> Iterator[_Grid]:
        if not always and not self._fits(side, rate):
            return
        img, scale = self._image(side)
        start = time.process_time()
        try:
            found, corners, meta = cv2.findChessboardCornersSBWithMeta(img, size, flags)
        except cv2.error:
            found, corners, meta = False, None, None
        self._timed(rate, img.size, time.process_time() - start)
        label = f"findChessboardCornersSB ({method}) at {img.shape[1]} x {img.shape[0]}"
        self.attempts.append(f"{label}: {'found' if found else 'not found'}")
        if not found or corners is None:
            return
        rows, cols = (meta.shape[:2]) if meta is not None and meta.size else (size[1], size[0])
        if rows * cols != len(corners):
            return
        grid = _Grid(_to_full(corners.reshape(rows, cols, 2).astype(np.float64), scale), method)
        self._keep_largest(grid)
        yield grid

    def _keep_largest(self, grid: _Grid) -> None:
        if self.largest is None or grid.points[..., 0].size > self.largest.points[..., 0].size:
            self.largest = grid

    def probe(self) -> _Grid | None:
        """The largest grid of chessboard corners in view, whatever its size (for the
        message when the board is not found)."""
        if self.largest is None and not self.probed:
            side = self._sides()[0]
            for grid in self._sb(side, (3, 3), cv2.CALIB_CB_LARGER, "probe", always=True):
                self.largest = grid
        return self.largest

    def diagnostics(self) -> ChessboardDiagnostics:
        grid = self.largest
        h, w = self.u8.shape
        shape = None if grid is None else (grid.points.shape[1], grid.points.shape[0])
        points = np.zeros((0, 2)) if grid is None else grid.points.reshape(-1, 2)
        return ChessboardDiagnostics(self.board, (w, h), tuple(self.attempts), shape, points)


def _to_full(points: F64, scale: float) -> F64:
    """Points found on an image scaled by `scale` in the full image's pixels (pixel centres
    at integers in both)."""
    if scale == 1.0:
        return points
    return (points + 0.5) / scale - 0.5


# ------------------------------------------------------------------------------------------
# Refinement, reading, growth


def _grid_axes(points: F64) -> F64:
    """(R, C, 2, 2): at each grid corner the image vectors to the next corner along u and
    along v (central differences inside, one-sided at the edges)."""
    eu = np.gradient(points, axis=1) if points.shape[1] > 1 else np.zeros_like(points)
    ev = np.gradient(points, axis=0) if points.shape[0] > 1 else np.zeros_like(points)
    return np.stack([eu, ev], axis=2)


def _finish(
    grey: NDArray[np.uint8] | NDArray[np.float32],
    grid: _Grid,
    board: ChessboardBoard,
    turned: bool,
) -> BoardDetection:
    rows_g, cols_g = grid.points.shape[:2]
    if rows_g < 2 or cols_g < 2:
        raise _RefusedError("too few corners")
    axes = _grid_axes(grid.points)
    flat = grid.points.reshape(-1, 2)
    refined = refine_corners(grey, flat, axes.reshape(-1, 2, 2), dotted=board.origin_marker)
    points = refined.points.reshape(rows_g, cols_g, 2)
    refined, points = _bent_edges(grey, flat, axes, refined, points, board.origin_marker)
    levels = _cell_levels(grey, points)
    reading = _marker_reading(points, levels, board)
    if reading is None:
        if board.origin_marker:
            if rows_g * cols_g == board.n_points:
                raise _RefusedError(
                    "no origin marker was seen on the board's grid (is the board's marker "
                    "setting right? origin_marker=True says it has one)"
                )
            raise _RefusedError("no origin marker in the grid of corners found")
        if {rows_g, cols_g} != {board.rows, board.cols}:
            raise _RefusedError(f"a grid of {cols_g} x {rows_g} corners")
        reading = _plain_reading(points, levels, board, turned)
    elif not board.origin_marker:
        # Marker dots on a board described without them: refined again with windows that
        # keep clear of the dots (a wide window over a dot moves its corner by 0.1 px).
        refined = refine_corners(grey, flat, axes.reshape(-1, 2, 2), dotted=True)
        points = refined.points.reshape(rows_g, cols_g, 2)
    return _detection(grey, grid, points, refined, reading, board)


def _bent_edges(
    grey: NDArray[np.uint8] | NDArray[np.float32],
    flat: F64,
    axes: F64,
    refined: RefinedCorners,
    points: F64,
    dotted: bool,
) -> tuple[RefinedCorners, F64]:
    """Refined again with the model's edges bent as the grid lines through the refined
    corners bend (a lens's distortion), where the bend inside a corner's window would lean
    a straight-edged fit by more than BEND_LEAN_PX somewhere (0.27 kappa r^2 towards the
    concave side); the bends come from the grid, so the fit gains no free parameter."""
    bends = grid_bends(points).reshape(-1, 2, 2)
    if not np.isfinite(bends).all():
        return refined, points
    radius = corner_radius(flat, axes.reshape(-1, 2, 2), dotted=dotted)
    # Only the bend across a line (perspective alone changes the spacing along it).
    ax = axes.reshape(-1, 2, 2)
    direction = ax / np.maximum(np.linalg.norm(ax, axis=2, keepdims=True), 1e-12)
    across = np.abs(direction[..., 0] * bends[..., 1] - direction[..., 1] * bends[..., 0])
    kappa = 0.5 * np.max(across, axis=1)
    if not (0.27 * kappa * radius**2 > BEND_LEAN_PX).any():
        return refined, points
    again = refine_corners(grey, flat, axes.reshape(-1, 2, 2), dotted=dotted, bends=bends)
    return again, again.points.reshape(points.shape)


def _cell_levels(grey: NDArray[np.uint8] | NDArray[np.float32], points: F64) -> F64:
    """For each grid cell (R - 1, C - 1): the grey level of its middle (within a tenth of the
    square) and of a ring about it (0.3 to 0.36 of the square), by bilinear sampling in the
    cell's corners' bilinear frame. Shape (R - 1, C - 1, 2)."""
    p00 = points[:-1, :-1]
    p10 = points[:-1, 1:]
    p01 = points[1:, :-1]
    p11 = points[1:, 1:]
    angles = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    offsets = [(0.0, 0.0)] + [(0.08 * math.cos(a), 0.08 * math.sin(a)) for a in angles[::2]]
    ring = [(r * math.cos(a), r * math.sin(a)) for r in (0.3, 0.36) for a in angles]
    out = np.zeros((*p00.shape[:2], 2))
    for k, group in enumerate((offsets, ring)):
        s = np.array([o[0] for o in group]) + 0.5
        t = np.array([o[1] for o in group]) + 0.5
        pos = (
            p00[..., None, :] * ((1 - s) * (1 - t))[:, None]
            + p10[..., None, :] * (s * (1 - t))[:, None]
            + p01[..., None, :] * ((1 - s) * t)[:, None]
            + p11[..., None, :] * (s * t)[:, None]
        )
        mx = pos[..., 0].astype(np.float32).reshape(-1, len(group))
        my = pos[..., 1].astype(np.float32).reshape(-1, len(group))
        src = grey if grey.dtype == np.float32 else grey.astype(np.float32)
        vals = cv2.remap(src, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        out[..., k] = vals.mean(axis=1).reshape(p00.shape[:2])
    return out


def _cell_colours(levels: F64) -> tuple[NDArray[np.int64], NDArray[np.int64], float]:
    """Each cell's colour (1 black, 0 white) by its ring's level, each cell's dot (1 a
    white dot on black, -1 a black dot on white, 0 none), and the board's contrast."""
    ring = levels[..., 1]
    mid = float(np.median(ring))
    dark = ring < mid
    black_level = float(np.median(ring[dark])) if dark.any() else mid
    white_level = float(np.median(ring[~dark])) if (~dark).any() else mid
    contrast = white_level - black_level
    black = (ring < 0.5 * (black_level + white_level)).astype(np.int64)
    diff = levels[..., 0] - ring
    dot = np.zeros_like(black)
    if contrast > 0:
        dot[(black == 1) & (diff > 0.35 * contrast)] = 1
        dot[(black == 0) & (diff < -0.35 * contrast)] = -1
    return black, dot, contrast


def _marker_reading(points: F64, levels: F64, board: ChessboardBoard) -> _Reading | None:
    """The reading fixed by an origin marker on this grid, if one is read: the black cell
    with a white dot whose two neighbours along perpendicular grid lines are white cells
    with black dots (every marker cell chessboard.py draws)."""
    _, dot, contrast = _cell_colours(levels)
    if contrast <= 0:
        return None
    found: list[tuple[int, int, I64, I64]] = []
    for v, u in zip(*np.nonzero(dot == 1), strict=True):
        legs = []
        for du, dv in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            uu, vv = u + du, v + dv
            if 0 <= vv < dot.shape[0] and 0 <= uu < dot.shape[1] and dot[vv, uu] == -1:
                legs.append(np.array([du, dv], dtype=np.int64))
        if len(legs) == 2 and int(legs[0] @ legs[1]) == 0:
            found.append((int(u), int(v), legs[0], legs[1]))
    if len(found) != 1:
        return None
    u0, v0, leg1, leg2 = found[0]
    # Where the marker is on this board's layout (also when it was not declared).
    origin = dataclasses.replace(board, origin_marker=True).marker_cells()[0]
    # The L is symmetric: which leg is X is what keeps the board unmirrored.
    for a, b in ((leg1, leg2), (leg2, leg1)):
        # M a = (1, 0) and M b = (0, 1): M is the inverse of the matrix with columns a, b.
        m = np.rint(np.linalg.inv(np.column_stack([a, b]).astype(np.float64))).astype(np.int64)
        # Cell (u0, v0) has its centre at corner coordinates (u0 + 0.5, v0 + 0.5); board
        # square (i, j) at (i - 0.5, j - 0.5).
        centre_board = np.array([origin[0] - 0.5, origin[1] - 0.5])
        t = np.rint(centre_board - m @ np.array([u0 + 0.5, v0 + 0.5])).astype(np.int64)
        reading = _Reading(m, t, "marker", MARKER_CHESS_RULE)
        if _unmirrored(points, reading):
            return reading
    raise _RefusedError("the origin marker's reading is mirrored")


def _corner_coords(shape: tuple[int, int], reading: _Reading) -> I64:
    """(R, C, 2) board coordinates (c, r) of each grid corner under `reading`."""
    v, u = np.mgrid[: shape[0], : shape[1]]
    uv = np.stack([u, v], axis=-1).astype(np.int64)
    return np.asarray(uv @ reading.m.T + reading.t, dtype=np.int64)


def _unmirrored(points: F64, reading: _Reading) -> bool:
    """Whether the board's frame maps onto the image without a mirror (image y runs down,
    like the board's Y): the affine fit's determinant is positive."""
    cr = _corner_coords(points.shape[:2], reading).reshape(-1, 2).astype(np.float64)
    design = np.column_stack([cr, np.ones(len(cr))])
    coef = np.linalg.lstsq(design, points.reshape(-1, 2), rcond=None)[0]
    return bool(np.linalg.det(coef[:2, :2].T) > 0)


def _plain_reading(points: F64, levels: F64, board: ChessboardBoard, turned: bool) -> _Reading:
    """The reading of a whole board without a marker (see the module)."""
    rows_g, cols_g = points.shape[:2]
    black, _, contrast = _cell_colours(levels)
    readings = []
    for m in _SYMMETRIES:
        corners = np.array([[0, 0], [cols_g - 1, 0], [0, rows_g - 1], [cols_g - 1, rows_g - 1]])
        mapped = corners @ m.T
        t = -mapped.min(axis=0)
        span = mapped.max(axis=0) - mapped.min(axis=0)
        if (int(span[0]), int(span[1])) != (board.cols - 1, board.rows - 1):
            continue
        reading = _Reading(m, t, "ambiguous", AMBIGUOUS_CHESS_RULE)
        if _unmirrored(points, reading):
            readings.append(reading)
    if not readings:
        raise _RefusedError("the grid has no unmirrored reading: is the board seen from behind?")
    # The squares' colours: each reading's agreement with the board's (inner cells only).
    agree = []
    for reading in readings:
        cr = _corner_coords(points.shape[:2], reading)
        # Cell (u, v) is board square (i, j) with (i - 0.5, j - 0.5) its centre's coordinates.
        centre = (cr[:-1, :-1] + cr[1:, 1:]) / 2.0
        i = np.rint(centre[..., 0] + 0.5).astype(np.int64)
        j = np.rint(centre[..., 1] + 0.5).astype(np.int64)
        expected = ((i + j) % 2 == 0).astype(np.int64)
        agree.append(float(np.mean(expected == black)) if contrast > 0 else 0.5)
    best_agree = max(agree)
    clear = [r for r, a in zip(readings, agree, strict=True) if a >= 0.9]
    if best_agree >= 0.9 and len(clear) == 1 and min(agree) <= 0.1:
        only = clear[0]
        best = _Reading(only.m, only.t, "pattern", PATTERN_CHESS_RULE)
    else:
        if best_agree >= 0.9:
            readings = clear

        # Corner 0 nearest the image's top-left.
        def first_corner(r: _Reading) -> float:
            cr = _corner_coords(points.shape[:2], r)
            at = np.argwhere((cr[..., 0] == 0) & (cr[..., 1] == 0))[0]
            return float(np.hypot(*points[at[0], at[1]]))

        best = min(readings, key=first_corner)
    if board.cols == board.rows:
        return best
    # A non-square board whose only reading runs its rows down the image: --cols and --rows
    # swapped, most often.
    cr = _corner_coords(points.shape[:2], best)
    p0 = points[(cr[..., 0] == 0) & (cr[..., 1] == 0)][0]
    p1 = points[(cr[..., 0] == 1) & (cr[..., 1] == 0)][0]
    x_axis = p1 - p0
    if abs(x_axis[1]) <= abs(x_axis[0]):
        return best
    if not turned:
        raise BoardTurnedError(
            f"found {board.rows} x {board.cols} inner corners (across x down the image), "
            f"described {board.cols} x {board.rows}: the board lies turned by 90 degrees "
            f"in the image, or --cols and --rows are swapped (--cols {board.rows} --rows "
            f"{board.cols}?). If it really lies turned, accept its frame as it is with "
            "--turned (turned=True)."
        )
    warning = "the board lies turned by 90 degrees in the image (accepted: turned)"
    return dataclasses.replace(best, warnings=(warning,))


def _detection(
    grey: NDArray[np.uint8] | NDArray[np.float32],
    grid: _Grid,
    points: F64,
    refined: RefinedCorners,
    reading: _Reading,
    board: ChessboardBoard,
) -> BoardDetection:
    shape = points.shape[:2]
    cr = _corner_coords(shape, reading).reshape(-1, 2)
    pts = points.reshape(-1, 2)
    ok = refined.refined.copy()
    contrast = refined.contrast
    warnings: list[str] = list(reading.warnings)
    inside = (cr[:, 0] >= 0) & (cr[:, 0] < board.cols) & (cr[:, 1] >= 0) & (cr[:, 1] < board.rows)
    if reading.orientation == "marker":
        _check_not_larger(cr, inside, ok, board)
    reference = float(np.median(contrast[ok])) if ok.any() else 0.0
    # A finder's corner is the board's only where the image shows an X-corner there.
    axes = _grid_axes(points).reshape(-1, 2, 2)
    ok &= _x_shaped(grey, pts, axes, reference)
    known: dict[tuple[int, int], tuple[F64, bool]] = {
        (int(c), int(r)): (pts[k], bool(ok[k])) for k, (c, r) in enumerate(cr) if inside[k]
    }
    _flag_strays(known)
    if reading.orientation == "marker":
        # A marker fixes every corner: unrefined ones are dropped, the rest of the board in
        # view is grown.
        known = {key: val for key, val in known.items() if val[1]}
        _grow(grey, known, board, reference)
    else:
        _check_no_continuation(grey, points, refined, board)
        # A corner that could not be refined (at the image's edge, under glare) takes where
        # its refined neighbours put it, flagged; the finder's own guess is coarser.
        good = {key: val for key, val in known.items() if val[1]}
        bad = [key for key, val in known.items() if not val[1]]
        if bad and len(good) >= 5:
            predicted, _ = _local_prediction(good, bad)
            for key, p in zip(bad, predicted, strict=True):
                if np.isfinite(p).all():
                    known[key] = (p, False)
    ids = np.array(sorted(r * board.cols + c for c, r in known), dtype=np.intp)
    if len(ids) < 4:
        raise _RefusedError("fewer than 4 corners of the board found")
    image_points = np.array([known[(int(i % board.cols), int(i // board.cols))][0] for i in ids])
    refined_flags = np.array(
        [known[(int(i % board.cols), int(i // board.cols))][1] for i in ids], dtype=bool
    )
    if not refined_flags.all():
        warnings.append(
            f"{int((~refined_flags).sum())} of {len(ids)} corners could not be refined (at "
            "the image's edge, under glare?): placed where their neighbours put them, flagged "
            "as not refined"
        )
    world = board.world_points()[ids]
    try:
        h = estimate_homography(world, image_points)
        residuals = reprojection_errors(h, world, image_points)
    except (DegenerateError, HomographyError, ValueError) as e:
        raise _RefusedError(f"the corners do not form a board: {e}") from None
    height, width = grey.shape[:2]
    return BoardDetection(
        board=board,
        image_points=np.ascontiguousarray(image_points, dtype=np.float64),
        image_size=(width, height),
        method=grid.method,
        residual_rms_px=float(np.sqrt(np.mean(residuals**2))),
        ids=ids,
        polarity="dark",
        refined=refined_flags,
        enlarged=np.zeros(len(ids), dtype=bool),
        orientation=reading.orientation,
        orientation_rule=reading.rule,
        warnings=tuple(warnings),
    )


def _check_not_larger(
    cr: I64, inside: NDArray[np.bool_], ok: NDArray[np.bool_], board: ChessboardBoard
) -> None:
    """A grid whose corners run a whole line past the board's edge is a larger board."""
    beyond = (~inside) & ok
    if beyond.sum() >= min(board.cols, board.rows):
        raise BoardMismatchError(
            f"the chessboard in view is larger than described ({board.cols} x {board.rows} "
            f"inner corners): {int(beyond.sum())} corners lie past its edges. Check --cols "
            "and --rows."
        )


def _local_prediction(
    known: dict[tuple[int, int], tuple[F64, bool]], queries: list[tuple[int, int]]
) -> tuple[F64, F64]:
    """Each query corner's image position and grid axes, by the homography through the known
    corners within two steps of it (NaN where fewer than 5 are)."""
    keys = np.array(list(known.keys()), dtype=np.float64).reshape(-1, 2)
    vals = np.array([v[0] for v in known.values()]).reshape(-1, 2)
    out = np.full((len(queries), 2), np.nan)
    axes = np.full((len(queries), 2, 2), np.nan)
    for k, (c, r) in enumerate(queries):
        near = np.max(np.abs(keys - (c, r)), axis=1) <= 2
        if near.sum() < 5:
            continue
        try:
            h = estimate_homography(keys[near], vals[near])
            p = transform_points(h, np.array([[c, r], [c + 1, r], [c, r + 1]], np.float64))
        except (DegenerateError, HomographyError, ValueError):
            continue
        out[k] = p[0]
        axes[k, 0] = p[1] - p[0]
        axes[k, 1] = p[2] - p[0]
    return out, axes


def _flag_strays(known: dict[tuple[int, int], tuple[F64, bool]]) -> None:
    """Flag (as not refined) each corner far from where its neighbours' homography puts it
    (a finder's corner on an occluder's edge), the worst first, so that one bad corner does
    not condemn its neighbours. In place."""
    keys = list(known.keys())
    for _ in range(len(keys)):
        good = {k: v for k, v in known.items() if v[1]}
        if len(good) < 6:
            return
        worst, worst_excess = None, 1.0
        for key in good:
            others = {k: v for k, v in good.items() if k != key}
            predicted, axes = _local_prediction(others, [key])
            if not np.isfinite(predicted).all():
                continue
            step = float(np.min(np.linalg.norm(axes[0], axis=1)))
            gap = float(np.hypot(*(good[key][0] - predicted[0])))
            excess = gap / max(0.15 * step, 1.0)
            if excess > worst_excess:
                worst, worst_excess = key, excess
        if worst is None:
            return
        known[worst] = (known[worst][0], False)


def _x_corners(
    grey: NDArray[np.uint8] | NDArray[np.float32],
    predicted: F64,
    axes: F64,
    reference: float,
    dotted: bool,
) -> tuple[F64, NDArray[np.bool_]]:
    """Refine at predicted positions; True where an X-corner of the board's contrast is there
    (within a quarter step of the prediction)."""
    h, w = grey.shape[:2]
    good = np.isfinite(predicted).all(axis=1)
    margin = 2.0
    good &= (predicted[:, 0] > margin) & (predicted[:, 0] < w - 1 - margin)
    good &= (predicted[:, 1] > margin) & (predicted[:, 1] < h - 1 - margin)
    found = np.zeros(len(predicted), dtype=bool)
    points = predicted.copy()
    # The quick look first (the four squares about the prediction), the fit only where it
    # sees an X-corner: a fit where there is none runs to its last step.
    idx = np.flatnonzero(good)
    if idx.size:
        idx = idx[_x_shaped(grey, predicted[idx], axes[idx], reference)]
    if idx.size == 0:
        return points, found
    res = refine_corners(grey, predicted[idx], axes[idx], dotted=dotted)
    step = np.min(np.linalg.norm(axes[idx], axis=2), axis=1)
    moved = np.hypot(*(res.points - predicted[idx]).T)
    ok = res.refined & (moved < 0.25 * step) & (res.contrast > 0.4 * reference)
    ok &= _x_shaped(grey, res.points, axes[idx], reference)
    found[idx] = ok
    points[idx] = res.points
    return points, found


def _x_shaped(
    grey: NDArray[np.uint8] | NDArray[np.float32], points: F64, axes: F64, reference: float
) -> NDArray[np.bool_]:
    """Whether the four squares about each point are an X-corner's: opposite ones alike,
    neighbouring ones of the board's contrast (where a board's edge meets the paper, a
    T-junction, two neighbouring squares are paper)."""
    quads = []
    for su, sv in ((1, 1), (-1, -1), (1, -1), (-1, 1)):
        samples = []
        for f in (0.16, 0.21, 0.26):  # clear of a marker dot (radius 0.2 of a square)
            pos = points + f * (su * axes[:, 0] + sv * axes[:, 1])
            samples.append(pos)
        pos_all = np.stack(samples, axis=1)  # (N, 3, 2)
        mx = pos_all[..., 0].astype(np.float32)
        my = pos_all[..., 1].astype(np.float32)
        src = grey if grey.dtype == np.float32 else grey.astype(np.float32)
        vals = cv2.remap(src, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        quads.append(vals.mean(axis=1))
    pp, mm, pm, mp = quads
    contrast_a = np.abs(pp - pm)
    contrast_b = np.abs(mm - mp)
    alike = np.maximum(np.abs(pp - mm), np.abs(pm - mp))
    same_sign = np.sign(pp - pm) == np.sign(mm - mp)
    strong = np.minimum(contrast_a, contrast_b) > 0.4 * reference
    return np.asarray(same_sign & strong & (alike < 0.3 * np.minimum(contrast_a, contrast_b)))


def _grow(
    grey: NDArray[np.uint8] | NDArray[np.float32],
    known: dict[tuple[int, int], tuple[F64, bool]],
    board: ChessboardBoard,
    reference: float,
) -> None:
    """Add every board corner in view: predicted from its known neighbours, kept where the
    refinement finds an X-corner there. In place."""
    tried: set[tuple[int, int]] = set()
    for _ in range(board.cols + board.rows):
        frontier = [
            (c, r)
            for r in range(board.rows)
            for c in range(board.cols)
            if (c, r) not in known
            and (c, r) not in tried
            and any((c + dc, r + dr) in known for dc in (-1, 0, 1) for dr in (-1, 0, 1))
        ]
        if not frontier:
            return
        predicted, axes = _local_prediction(known, frontier)
        # Growth follows a marker read: its dots stand in the squares.
        points, found = _x_corners(grey, predicted, axes, reference, True)
        added = False
        for k, key in enumerate(frontier):
            if np.isfinite(predicted[k]).all():
                tried.add(key)
            if found[k]:
                known[key] = (points[k], True)
                added = True
        if not added:
            return


def _check_no_continuation(
    grey: NDArray[np.uint8] | NDArray[np.float32],
    points: F64,
    refined: RefinedCorners,
    board: ChessboardBoard,
) -> None:
    """A whole grid whose lines run on past an edge with X-corners (where the board's outer
    squares meet the paper there are none) is part of a larger board: refused."""
    rows_g, cols_g = points.shape[:2]
    reference = float(np.median(refined.contrast[refined.refined])) if refined.refined.any() else 0
    edges = {
        "top": (points[0] - (points[1] - points[0]), points[0] - points[1]),
        "bottom": (points[-1] + (points[-1] - points[-2]), points[-1] - points[-2]),
        "left": (points[:, 0] - (points[:, 1] - points[:, 0]), points[:, 0] - points[:, 1]),
        "right": (points[:, -1] + (points[:, -1] - points[:, -2]), points[:, -1] - points[:, -2]),
    }
    # Every edge's predictions refined at once.
    predicted = np.concatenate([p for p, _ in edges.values()])
    axes = np.concatenate(
        [np.stack([np.gradient(p, axis=0), step], axis=1) for p, step in edges.values()]
    )
    _, found = _x_corners(grey, predicted, axes, reference, board.origin_marker)
    start = 0
    for name, (edge, _) in edges.items():
        hits = int(found[start : start + len(edge)].sum())
        start += len(edge)
        if hits >= max(2, (len(edge) + 1) // 2):
            raise BoardMismatchError(
                f"the chessboard's corners continue past the {name} edge of the "
                f"{cols_g} x {rows_g} grid found: the board in view is larger than "
                f"{board.cols} x {board.rows} inner corners (check --cols and --rows)"
            )


# ------------------------------------------------------------------------------------------
# Explaining a failure


def _explain(board: ChessboardBoard, finder: _Finder, refusals: list[str]) -> str:
    h, w = finder.u8.shape
    lines = [
        f"no chessboard of {board.cols} x {board.rows} inner corners found in the {w} x {h} image."
    ]
    grid = finder.probe()
    if grid is None:
        lines.append("Seen: no grid of chessboard corners.")
        lines.append(
            "Try: is the whole board in view, in focus and evenly lit (no glare)? Is it "
            f"{board.cols} x {board.rows} inner corners (the squares less one each way)?"
        )
    else:
        rows_g, cols_g = grid.points.shape[:2]
        along_u = grid.points[0, -1] - grid.points[0, 0]
        if abs(along_u[1]) > abs(along_u[0]):  # name it as it lies: across x down the image
            rows_g, cols_g = cols_g, rows_g
        lines.append(f"Seen: a grid of {cols_g} x {rows_g} chessboard corners.")
        n_seen = rows_g * cols_g
        larger = (rows_g >= board.rows and cols_g >= board.cols) or (
            rows_g >= board.cols and cols_g >= board.rows
        )
        # Within a square of the image's edge: cut off by it, most likely.
        step = float(np.median(np.linalg.norm(np.diff(grid.points, axis=1), axis=2)))
        pts = grid.points.reshape(-1, 2)
        at_edge = bool(
            pts.min() < step or (pts[:, 0].max() > w - 1 - step) or (pts[:, 1].max() > h - 1 - step)
        )
        other_size = (
            f"is the board {cols_g} x {rows_g} inner corners (--cols {cols_g} --rows {rows_g})?"
        )
        if n_seen > board.n_points and larger:
            lines.append(
                f"found {cols_g} x {rows_g} inner corners, described {board.cols} x "
                f"{board.rows}: --cols {cols_g} --rows {rows_g}?"
            )
        elif board.origin_marker:
            lines.append(
                "No origin marker was read on it: if the board has none, use --no-origin-marker "
                "(origin_marker=False in Python); if it has one (three dots about the board's "
                "middle), keep it in view and uncovered."
            )
            if n_seen != board.n_points and not at_edge:
                lines.append("Or " + other_size)
        elif at_edge:
            lines.append(PARTIAL_ADVICE)
            lines.append("Or " + other_size)
        else:
            lines.append(
                f"found {cols_g} x {rows_g} inner corners, described {board.cols} x {board.rows}: "
                f"{other_size} (If the board is partly covered: {PARTIAL_ADVICE})"
            )
    if refusals:
        lines.append("Refused: " + " | ".join(refusals[:3]))
    return " ".join(lines)


__all__ = ["ChessboardDiagnostics", "corner_radius", "detect_chessboard"]
