"""Finding the board in an image: every dot's centre, sub-pixel, in the board's order.

The search tries OpenCV's symmetric circle-grid finder, then its clustering finder, each with
a blob detector sized from the image (OpenCV's default caps dots at 5000 px^2), each with the
grid read both ways; then, as a last resort, it assembles the grid itself from the blobs. Dark
dots on light paper and light dots on a dark board are both tried unless one is asked for.

Every result is then refined and checked before it is returned:

* Centres are refined to sub-pixel precision by the grey-level centroid of each dot over a
  plane fitted to its local background (so uneven lighting does not pull them), which weighs
  partly covered edge pixels by how much ink they see; no thresholding, no rounding.
* The order is made canonical. The board's world frame (X along a row, Y down a column, as
  printed and seen from the front) must map onto the image without a mirror; among the
  orders that keep that handedness, point 0 is the origin marker when the board has one, and
  otherwise the corner dot nearest the image's top-left corner (pixel (0, 0)). A board with a
  marker that can only be read mirrored (seen from behind, or in a mirror) is refused.
* A homography is fitted from the board to the found centres; a result whose points stray
  from it by more than a third of the dot pitch is not the board's grid and is refused.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from planarcal.board import CircleGridBoard
from planarcal.errors import BoardNotFoundError, DegenerateError
from planarcal.homography import estimate_homography, reprojection_errors
from planarcal.images import as_grey

F64 = NDArray[np.float64]
Polarity = Literal["auto", "dark", "light"]

# A found grid whose points stray this far (in dot pitches) from a homography is not the board.
MAX_GRID_RESIDUAL_PITCH = 1.0 / 3.0
# The origin marker's area must exceed its neighbours' by this factor to count as found.
MARKER_AREA_RATIO = 1.35


@dataclasses.dataclass(frozen=True)
class BoardDetection:
    """The board found in an image.

    ``image_points[k]`` is the centre of dot k, in pixels (float64; pixel centres at integer
    coordinates, as OpenCV), in the order of ``board.world_points()``.
    """

    board: CircleGridBoard
    image_points: F64
    image_size: tuple[int, int]
    """(width, height) of the image in pixels."""
    method: str
    """Which finder succeeded: "symmetric", "clustering" or "blobs"."""
    polarity: Literal["dark", "light"]
    """Dark dots on a light board, or light dots on a dark one."""
    dot_diameters_px: F64
    """Each dot's equivalent diameter in pixels (from its ink area)."""
    residual_rms_px: float
    """RMS distance of the centres from the best homography through them (px)."""

    def world_points(self) -> F64:
        """The dots' world positions in mm, matching image_points."""
        return self.board.world_points()

    @property
    def pitch_px(self) -> float:
        """Median distance between neighbouring dots in the image (px)."""
        return _median_pitch(self.image_points.reshape(self.board.rows, self.board.cols, 2))


def detect_board(
    image: Any, board: CircleGridBoard, *, polarity: Polarity = "auto"
) -> BoardDetection:
    """Find `board` in `image` (an array, grey or BGR, any real dtype, or a path).

    Returns the centre of every dot in the board's order; raises BoardNotFoundError, saying
    what was seen and what to try, when the image does not show the whole board.
    """
    if polarity not in ("auto", "dark", "light"):
        raise ValueError(f"polarity must be 'auto', 'dark' or 'light', got {polarity!r}")
    grey = as_grey(image)
    polarities: tuple[Literal["dark", "light"], ...] = (
        ("dark", "light") if polarity == "auto" else (polarity,)
    )
    refusals: list[str] = []
    for pol in polarities:
        ink_dark = grey if pol == "dark" else 255.0 - grey
        u8 = np.clip(np.rint(ink_dark), 0, 255).astype(np.uint8)
        detector = _blob_detector(u8.shape, board)
        blobs = _blobs(u8, detector)
        for method, grid in _grid_candidates(u8, detector, blobs, board):
            try:
                return _finish(ink_dark, grid, board, method, pol, blobs)
            except _RefusedError as why:
                refusals.append(f"{method} ({pol} dots): {why}")
    raise BoardNotFoundError(_explain(grey, board, polarities, refusals))


@dataclasses.dataclass(frozen=True)
class SeenBlobs:
    """The blobs one polarity's search saw: centres (N, 2) px and diameters (N,) px."""

    polarity: Literal["dark", "light"]
    centres_px: F64
    diameters_px: F64


@dataclasses.dataclass(frozen=True)
class RefusedCandidate:
    """A grid a finder put forward and the check that refused it."""

    method: str
    polarity: Literal["dark", "light"]
    points_px: F64
    """The candidate's dots (K, 2), px: as many as were found (possibly fewer than the board's)."""
    reason: str


@dataclasses.dataclass(frozen=True)
class DetectionDiagnostics:
    """What a failed search saw (``BoardNotFoundError.diagnostics``)."""

    board: CircleGridBoard
    image_size: tuple[int, int]
    """(width, height) px."""
    blobs: tuple[SeenBlobs, ...]
    candidates: tuple[RefusedCandidate, ...]


class _RefusedError(Exception):
    """A candidate grid that failed a check (the reason is the message)."""


# ------------------------------------------------------------------------------------------
# Candidate grids


def _grid_candidates(
    u8: NDArray[np.uint8], detector: Any, blobs: list[_Blob], board: CircleGridBoard
) -> Iterator[tuple[str, F64]]:
    """(method, grid of shape (rows, cols, 2)) for each way of finding the dots, in order."""
    import cv2

    patterns = [(board.cols, board.rows)]
    if board.rows != board.cols:
        patterns.append((board.rows, board.cols))
    for method, flags in (
        ("symmetric", cv2.CALIB_CB_SYMMETRIC_GRID),
        ("clustering", cv2.CALIB_CB_SYMMETRIC_GRID | cv2.CALIB_CB_CLUSTERING),
    ):
        for pattern in patterns:
            try:
                found, centres = cv2.findCirclesGrid(
                    u8, pattern, flags=flags, blobDetector=detector
                )
            except cv2.error:
                continue
            if found and centres is not None and len(centres) == board.n_points:
                yield (
                    method,
                    _pattern_to_grid(
                        np.asarray(centres, dtype=np.float64).reshape(-1, 2), pattern, board
                    ),
                )
    grid = _assemble_grid(blobs, board)
    if grid is not None:
        yield "blobs", grid


def _pattern_to_grid(points: F64, pattern: tuple[int, int], board: CircleGridBoard) -> F64:
    """OpenCV's row-major list for pattern (w, h) as a (rows, cols, 2) grid of the board's
    shape (transposed when the board was read the other way round)."""
    w, h = pattern
    grid = points.astype(np.float64).reshape(h, w, 2)
    if (h, w) != (board.rows, board.cols):
        grid = grid.transpose(1, 0, 2)
    return np.ascontiguousarray(grid)


def _expected_dot_diameter_range(
    shape: tuple[int, ...], board: CircleGridBoard
) -> tuple[float, float]:
    """Smallest and largest plausible dot diameter in pixels for a board fully in view."""
    h, w = shape[:2]
    longest = max(board.cols, board.rows) - 1
    shortest = min(board.cols, board.rows) - 1
    # The whole grid is in view: its pitch is at most what fits along the image, with slack
    # for perspective (the near side of a tilted board looks larger).
    pitch_max = 2.0 * min(max(w, h) / max(longest, 1), min(w, h) / max(shortest, 1))
    ratio = board.origin_marker_diameter / board.pitch
    return 3.0, max(6.0, pitch_max * ratio)


def _blob_detector(shape: tuple[int, ...], board: CircleGridBoard) -> Any:
    import cv2

    d_min, d_max = _expected_dot_diameter_range(shape, board)
    p = cv2.SimpleBlobDetector.Params()
    p.filterByColor = True
    p.blobColor = 0
    p.filterByArea = True
    p.minArea = float(np.pi / 4 * d_min**2)
    p.maxArea = float(np.pi / 4 * d_max**2)
    # Tilted dots are ellipses: keep circularity and inertia loose.
    p.filterByCircularity = True
    p.minCircularity = 0.5
    p.filterByInertia = True
    p.minInertiaRatio = 0.2
    p.filterByConvexity = True
    p.minConvexity = 0.8
    p.minThreshold = 10
    p.maxThreshold = 240
    p.thresholdStep = 10
    p.minDistBetweenBlobs = max(2.0, 0.5 * d_min)
    return cv2.SimpleBlobDetector.create(p)


@dataclasses.dataclass(frozen=True)
class _Blob:
    x: float
    y: float
    size: float


def _blobs(u8: NDArray[np.uint8], detector: Any) -> list[_Blob]:
    return [_Blob(k.pt[0], k.pt[1], k.size) for k in detector.detect(u8)]


def _dominant_size_group(blobs: list[_Blob]) -> list[_Blob]:
    """The blobs whose size is within a factor of 2 of the most common size."""
    if not blobs:
        return []
    sizes = np.log(np.array([b.size for b in blobs]))
    # The size with the most blobs within a factor of sqrt(2) around it.
    counts = [(np.abs(sizes - s) <= 0.35).sum() for s in sizes]
    mode = sizes[int(np.argmax(counts))]
    return [b for b, s in zip(blobs, sizes, strict=True) if abs(s - mode) <= np.log(2.0)]


def _assemble_grid(blobs: list[_Blob], board: CircleGridBoard) -> F64 | None:
    """The grid put together from blob centres alone: the hull's four corners give a first
    homography from grid indices to pixels, every blob is assigned to its nearest grid
    position, and the homography is refitted from all of them until the assignment settles."""
    import cv2

    group = _dominant_size_group(blobs)
    if len(group) != board.n_points:
        return None
    pts = np.array([[b.x, b.y] for b in group], dtype=np.float64)
    hull = cv2.convexHull(pts.astype(np.float32)).reshape(-1, 2)
    perimeter = cv2.arcLength(hull, True)
    corners = None
    for eps in perimeter * np.geomspace(0.005, 0.2, 24):
        approx = cv2.approxPolyDP(hull, float(eps), True).reshape(-1, 2)
        if len(approx) == 4:
            corners = approx.astype(np.float64)
            break
        if len(approx) < 4:
            break
    if corners is None:
        return None
    for cols, rows in {(board.cols, board.rows), (board.rows, board.cols)}:
        unit = np.array([[0, 0], [cols - 1, 0], [cols - 1, rows - 1], [0, rows - 1]], float)
        for shift in range(4):
            quad = np.roll(corners, shift, axis=0)
            grid = _assign(pts, unit, quad, cols, rows)
            if grid is not None:
                if (rows, cols) != (board.rows, board.cols):
                    grid = grid.transpose(1, 0, 2)
                return np.ascontiguousarray(grid)
    return None


def _assign(pts: F64, unit: F64, quad: F64, cols: int, rows: int) -> F64 | None:
    import cv2

    h = cv2.getPerspectiveTransform(unit.astype(np.float32), quad.astype(np.float32))
    for _ in range(4):
        try:
            inv = np.linalg.inv(h)
        except np.linalg.LinAlgError:
            return None
        g = cv2.perspectiveTransform(pts.reshape(-1, 1, 2), inv).reshape(-1, 2)
        idx = np.rint(g).astype(int)
        if (np.abs(g - idx) > 0.35).any():
            return None
        if (idx[:, 0] < 0).any() or (idx[:, 0] >= cols).any():
            return None
        if (idx[:, 1] < 0).any() or (idx[:, 1] >= rows).any():
            return None
        flat = idx[:, 1] * cols + idx[:, 0]
        if len(np.unique(flat)) != len(flat):
            return None
        grid = np.empty((rows, cols, 2))
        grid[idx[:, 1], idx[:, 0]] = pts
        h, _ = cv2.findHomography(idx.astype(np.float64), pts, 0)
        if h is None:
            return None
    return grid


# ------------------------------------------------------------------------------------------
# Refinement, ordering, checks


def _finish(
    ink_dark: NDArray[np.float32],
    grid: F64,
    board: CircleGridBoard,
    method: str,
    polarity: Literal["dark", "light"],
    blobs: list[_Blob],
) -> BoardDetection:
    rows, cols = board.rows, board.cols
    pitch = _median_pitch(grid)
    if not np.isfinite(pitch) or pitch < 4.0:
        raise _RefusedError(f"dots too close together ({pitch:.1f} px apart)")
    centres, areas = refine_centres(ink_dark, grid.reshape(-1, 2), _local_pitch(grid).ravel())
    grid = centres.reshape(rows, cols, 2)
    area_grid = areas.reshape(rows, cols)
    grid, area_grid = _canonical_order(grid, area_grid, board)
    points = grid.reshape(-1, 2)
    world = board.world_points()
    try:
        points, h = _unbias(points, world, board.dot_diameters())
        residuals = reprojection_errors(h, world, points)
    except (DegenerateError, ValueError) as e:
        raise _RefusedError(f"the points do not form a grid: {e}") from None
    worst = float(residuals.max())
    if worst > MAX_GRID_RESIDUAL_PITCH * pitch:
        k = int(residuals.argmax())
        raise _RefusedError(
            f"not the board's grid: dot {k} is {worst:.1f} px from where a homography puts "
            f"it (pitch {pitch:.1f} px)"
        )
    diameters = 2.0 * np.sqrt(area_grid.reshape(-1) / np.pi)
    beyond = _continues_beyond(h, board, blobs, float(np.median(diameters)), pitch)
    if beyond is not None:
        raise _RefusedError(
            f"the dots continue past the grid's {beyond} edge: the board in view is larger than "
            f"{cols} x {rows} (check --cols and --rows)"
        )
    height, width = ink_dark.shape[:2]
    return BoardDetection(
        board=board,
        image_points=np.ascontiguousarray(points),
        image_size=(width, height),
        method=method,
        polarity=polarity,
        dot_diameters_px=diameters,
        residual_rms_px=float(np.sqrt(np.mean(residuals**2))),
    )


def conic_centre_offset(h: F64, centres_mm: F64, diameters_mm: F64) -> F64:
    """How far the centre of each circle's image (an ellipse) lies from the image of its
    centre, px: the perspective bias of any centroid-based centre. The circle of radius r
    about c is the conic Q = [[1, 0, -cx], [0, 1, -cy], [-cx, -cy, cx^2 + cy^2 - r^2]]; its
    image is H^-T Q H^-1, whose centre solves the conic's 2 x 2 linear part."""
    hinv = np.linalg.inv(h)
    out = np.empty((len(centres_mm), 2))
    for k, ((cx, cy), d) in enumerate(zip(centres_mm, diameters_mm, strict=True)):
        r = 0.5 * d
        q = np.array([[1.0, 0.0, -cx], [0.0, 1.0, -cy], [-cx, -cy, cx * cx + cy * cy - r * r]])
        c = hinv.T @ q @ hinv
        centre = np.linalg.solve(c[:2, :2], -c[:2, 2])
        image = h @ np.array([cx, cy, 1.0])
        out[k] = centre - image[:2] / image[2]
    return out


def _unbias(points: F64, world: F64, diameters: F64) -> tuple[F64, F64]:
    """The measured centres (centroids of the dots' images) moved to the images of the dots'
    centres, by the conic offset under the homography they imply; the offset is recomputed
    once from the corrected points' homography (it changes by well under 1e-4 px after)."""
    h = estimate_homography(world, points, refine=True)
    for _ in range(2):
        corrected = points - conic_centre_offset(h, world, diameters)
        h = estimate_homography(world, corrected, refine=True)
    return corrected, h


def _continues_beyond(
    h: F64, board: CircleGridBoard, blobs: list[_Blob], dot_px: float, pitch_px: float
) -> str | None:
    """The edge past which the grid visibly goes on (dots of the same size where one more row
    or column would be), or None. A grid found inside a larger board is not that board: its
    origin would be the wrong dot."""
    if not blobs:
        return None
    from planarcal.homography import transform_points

    p = board.pitch
    cols, rows = board.cols, board.rows
    edges = {
        "top": [(c * p, -p) for c in range(cols)],
        "bottom": [(c * p, rows * p) for c in range(cols)],
        "left": [(-p, r * p) for r in range(rows)],
        "right": [(cols * p, r * p) for r in range(rows)],
    }
    xy = np.array([[b.x, b.y] for b in blobs])
    size = np.array([b.size for b in blobs])
    similar = (size > 0.5 * dot_px) & (size < 2.0 * dot_px)
    for name, positions in edges.items():
        predicted = transform_points(h, np.array(positions), invalid="nan")
        seen = 0
        for q in predicted:
            if not np.isfinite(q).all():
                continue
            d = np.hypot(xy[:, 0] - q[0], xy[:, 1] - q[1])
            if (similar & (d < 0.25 * pitch_px)).any():
                seen += 1
        if seen >= max(2, len(positions) // 2):
            return name
    return None


def _local_pitch(grid: F64) -> F64:
    """Each dot's distance to its nearest grid neighbour (perspective makes near dots
    larger and further apart than far ones), shape (rows, cols)."""
    along = np.linalg.norm(np.diff(grid, axis=1), axis=2)
    down = np.linalg.norm(np.diff(grid, axis=0), axis=2)
    near = np.full(grid.shape[:2], np.inf)
    near[:, :-1] = np.minimum(near[:, :-1], along)
    near[:, 1:] = np.minimum(near[:, 1:], along)
    near[:-1, :] = np.minimum(near[:-1, :], down)
    near[1:, :] = np.minimum(near[1:, :], down)
    return near


def _median_pitch(grid: F64) -> float:
    along = np.linalg.norm(np.diff(grid, axis=1), axis=2).ravel()
    down = np.linalg.norm(np.diff(grid, axis=0), axis=2).ravel()
    return float(np.median(np.concatenate([along, down])))


def _symmetries(rows: int, cols: int) -> Iterator[tuple[str, Any]]:
    """The re-indexings of a rows x cols grid onto itself (as functions on (r, c, ...) arrays)."""
    yield "identity", lambda a: a
    yield "flip rows", lambda a: a[::-1]
    yield "flip columns", lambda a: a[:, ::-1]
    yield "rotate 180", lambda a: a[::-1, ::-1]
    if rows == cols:
        yield "transpose", lambda a: a.transpose(1, 0, *range(2, a.ndim))
        yield "rotate 90", lambda a: a.transpose(1, 0, *range(2, a.ndim))[::-1]
        yield "rotate 270", lambda a: a.transpose(1, 0, *range(2, a.ndim))[:, ::-1]
        yield "anti-transpose", lambda a: a.transpose(1, 0, *range(2, a.ndim))[::-1, ::-1]


def _handedness(grid: F64) -> float:
    """Twice the signed area of the grid's corner quadrilateral, in image coordinates (y down):
    positive when the board's X and Y axes appear as printed, negative when mirrored."""
    q = np.array([grid[0, 0], grid[0, -1], grid[-1, -1], grid[-1, 0]])
    x, y = q[:, 0], q[:, 1]
    return float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _canonical_order(grid: F64, areas: F64, board: CircleGridBoard) -> tuple[F64, F64]:
    """The one re-indexing of the found grid that is the board's: unmirrored, with point 0 at
    the origin marker (if any) or at the corner nearest the image's top-left."""
    rows, cols = board.rows, board.cols
    candidates = []
    for _name, f in _symmetries(rows, cols):
        g, a = f(grid), f(areas)
        if g.shape[:2] == (rows, cols) and _handedness(g) > 0:
            candidates.append((np.ascontiguousarray(g), np.ascontiguousarray(a)))
    if not candidates:
        raise _RefusedError("the grid has no unmirrored reading")
    if not board.origin_marker:
        return min(candidates, key=lambda ga: float(np.hypot(*ga[0][0, 0])))
    # The marker: the corner dot whose ink area most exceeds its neighbours'.
    corner_ratio = {}
    for r, c in ((0, 0), (0, cols - 1), (rows - 1, 0), (rows - 1, cols - 1)):
        nr, nc = (1 if r == 0 else rows - 2), (1 if c == 0 else cols - 2)
        neighbours = [areas[r, nc], areas[nr, c], areas[nr, nc]]
        corner_ratio[(r, c)] = areas[r, c] / float(np.median(neighbours))
    ranked = sorted(corner_ratio.items(), key=lambda kv: -kv[1])
    (best, ratio), (_, second) = ranked[0], ranked[1]
    if ratio < MARKER_AREA_RATIO or ratio < 1.15 * second:
        raise _RefusedError(
            f"no origin marker: no corner dot is clearly larger than its neighbours "
            f"(largest ratio {ratio:.2f})"
        )
    marker_xy = grid[best]
    for g, a in candidates:
        if np.allclose(g[0, 0], marker_xy):
            return g, a
    raise _RefusedError(
        "the board appears mirrored (its origin marker can only be read with X and Y "
        "swapped): is it seen from behind, or in a mirror?"
    )


def refine_centres(ink_dark: NDArray[np.float32], points: F64, pitches: F64) -> tuple[F64, F64]:
    """Sub-pixel centres and ink areas (px^2) of the dark dots near `points`, each of which is
    `pitches[k]` pixels from its nearest neighbour.

    Each dot's centre is the centroid of its darkness: (background - pixel) / (background -
    ink), clipped to [0, 1], over a disc around the dot, where the background is a plane
    fitted (robustly) to a ring of paper around it and the ink level is the dot's darkest
    decile. Edge pixels count by how much ink they see, so the estimate is sub-pixel without
    thresholds. Three passes: each sizes the dot and re-centres the disc on it.
    """
    h, w = ink_dark.shape[:2]
    out = np.array(points, dtype=np.float64, copy=True)
    areas = np.zeros(len(out))
    for k in range(len(out)):
        cx, cy = out[k]
        half = 0.5 * float(pitches[k])
        radius = 0.45 * half  # a first guess; replaced by the measured size
        for _ in range(3):
            ring_in = min(radius + max(2.0, 0.3 * radius), 0.95 * half)
            ring_out = min(ring_in + max(2.0, 0.25 * radius), half)
            # The disc must be in the image; the ring may be cut by the border.
            if cx - ring_in < 0 or cy - ring_in < 0 or cx + ring_in > w - 1 or cy + ring_in > h - 1:
                raise _RefusedError(f"dot {k} is cut by the image border")
            x0, x1 = max(0, int(np.floor(cx - ring_out))), min(w, int(np.ceil(cx + ring_out)) + 1)
            y0, y1 = max(0, int(np.floor(cy - ring_out))), min(h, int(np.ceil(cy + ring_out)) + 1)
            patch = ink_dark[y0:y1, x0:x1].astype(np.float64)
            yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
            r = np.hypot(xx - cx, yy - cy)
            ring = (r >= ring_in) & (r <= ring_out)
            inside = r < ring_in
            if ring.sum() < 6 or inside.sum() < 4:
                raise _RefusedError(f"dot {k} is too small to measure")
            background = _ring_plane(patch, xx - cx, yy - cy, ring)
            weight = _ink_weights(patch, background, inside)
            if weight is None:
                raise _RefusedError(f"dot {k} has no contrast with its background")
            total = float(weight.sum())
            if total <= 0:
                raise _RefusedError(f"dot {k} has no ink")
            cx = float((weight * xx).sum() / total)
            cy = float((weight * yy).sum() / total)
            radius = float(np.sqrt(total / np.pi))
        out[k] = (cx, cy)
        areas[k] = total
    return out, areas


def _ink_weights(patch: F64, background: F64, inside: NDArray[np.bool_]) -> F64 | None:
    """How much of each pixel the dot's ink covers, in [0, 1]; None without contrast.

    Light is multiplicative, so coverage is read from the ratio of a pixel to the local
    background, which uneven lighting does not change. Only the edge band carries sub-pixel
    information; the interior counts as exactly 1 and the outside as exactly 0, so sensor noise
    there adds nothing. The three regions are told apart on a smoothed copy of the coverage,
    where noise cannot flip them; the band (smoothed coverage 0.2 to 0.8, widened by a pixel)
    keeps each pixel's measured, linear coverage, which is what makes a sampled centroid exact
    (a steeper transform of it was measured to quantise). The thresholds balance noise against
    bias: on rendered dots they beat findCirclesGrid's centres under every combination of
    blur (0.7, 1.5 px), noise (0, 3 grey levels) and lighting gradient tried.
    """
    import cv2

    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(background > 0, patch / background, 1.0)
    darkness = 1.0 - ratio
    core = float(
        np.median(darkness[inside][darkness[inside] >= np.percentile(darkness[inside], 75)])
    )
    if not core > 0:
        return None
    cover = np.clip(darkness / core, 0.0, 1.0)
    smooth = cv2.GaussianBlur(cover.astype(np.float32), (0, 0), 1.0).astype(np.float64)
    solid = smooth > 0.8
    clear = smooth < 0.2
    # Widen the edge band by a pixel either way: its pixels keep their measured coverage.
    band = ~(solid | clear)
    band = cv2.dilate(band.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    weight = np.where(band, cover, np.where(solid, 1.0, 0.0))
    weight_in: F64 = weight * inside
    return weight_in


def _ring_plane(patch: F64, dx: F64, dy: F64, ring: NDArray[np.bool_]) -> F64:
    """A plane a + b dx + c dy fitted to the ring's pixels, ignoring dark intruders (a
    neighbouring dot, the board's edge): pixels far below the first fit are dropped and the
    plane refitted."""
    values = patch[ring]
    design = np.column_stack([np.ones(values.size), dx[ring], dy[ring]])
    keep = np.ones(values.size, dtype=bool)
    coef: F64 = np.zeros(3)
    for _ in range(3):
        coef = np.asarray(np.linalg.lstsq(design[keep], values[keep], rcond=None)[0], np.float64)
        resid = values - design @ coef
        spread = 1.4826 * float(np.median(np.abs(resid[keep]))) + 1e-6
        new_keep = resid > -3.0 * spread
        if new_keep.sum() < 6 or (new_keep == keep).all():
            break
        keep = new_keep
    plane: F64 = coef[0] + coef[1] * dx + coef[2] * dy
    return plane


# ------------------------------------------------------------------------------------------
# Explaining a failure


def _explain(
    grey: NDArray[np.float32],
    board: CircleGridBoard,
    polarities: tuple[Literal["dark", "light"], ...],
    refusals: list[str],
) -> str:
    u8 = np.clip(np.rint(grey), 0, 255).astype(np.uint8)
    detector = _blob_detector(u8.shape, board)
    seen = []
    for pol in polarities:
        work = u8 if pol == "dark" else 255 - u8
        group = _dominant_size_group(_blobs(work, detector))
        if group:
            size = float(np.median([b.size for b in group]))
            seen.append((len(group), pol, size))
        else:
            seen.append((0, pol, 0.0))
    n = board.n_points
    lines = [
        f"no {board.cols} x {board.rows} circle grid ({n} dots) found in the "
        f"{grey.shape[1]} x {grey.shape[0]} image."
    ]
    for count, pol, size in seen:
        if count:
            lines.append(f"Seen: {count} {pol} dots of about {size:.0f} px across.")
        else:
            lines.append(f"Seen: no {pol} dots of a plausible size.")
    best = max(seen)
    hints = []
    if best[0] and best[0] < n:
        hints.append(
            f"fewer dots than the board has: is the whole board in view (not cut off or "
            f"covered), and is it {board.cols} x {board.rows}?"
        )
    elif best[0] > n:
        hints.append(
            f"more dots than the board has: is it really {board.cols} x {board.rows}? "
            "Other round things in view count too; crop or mask them."
        )
    else:
        hints.append("check the board's size (--cols, --rows) and that it is in view")
    if len(polarities) == 1:
        other = "light" if polarities[0] == "dark" else "dark"
        hints.append(f"if the dots are {other}er than the board, use polarity '{other}'")
    hints.append("improve focus and lighting; avoid glare on the board")
    lines.append("Try: " + "; ".join(hints) + ".")
    if refusals:
        lines.append("Candidates refused: " + " | ".join(refusals[:4]))
    return " ".join(lines)
