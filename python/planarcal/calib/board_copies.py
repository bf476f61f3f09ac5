"""Several copies of one board in one image, each a placement (issue 23).

Copies of a board laid out at once on the work plane (the same description; for a ChArUco
board the same marker ids in each copy) are placements seen together:
:func:`detect_board_copies` finds every copy, each as the :class:`BoardDetection` that
``detect_board`` gives for an image of that copy alone, ready for
``Calibration.from_detections``.

How:

* Circle grids and chessboards: their detectors find one board at a time. Each copy found is
  blanked (the board's printed field, grown by ``BLANK_MARGIN`` of a pitch and mapped into
  the image by the homography through its points, filled with the median grey of the paper
  just around it) and the image searched again, until no board is found.
* ChArUco boards: every copy shows the same marker ids, which the ChArUco detector would take
  for misread codes. The markers are grouped into copies first, as the detector groups them
  into one board: two markers near each other belong together when each one's homography
  puts the other where it is seen, at their places on the board; each connected group is a
  copy (it holds every id at most once). Each copy is then read by the ChArUco detector on
  the image with the other copies blanked.

Then, for every kind, each copy is read once more on the image with every *other* copy
blanked, so it is found exactly as it would be alone (the blanking lies beyond its paper's
printed field): the same points as ``detect_board`` on an image of that copy alone (measured
on renders: identical for circle grids and ChArUco boards, within 0.0012 px for
chessboards).

A copy cut by the image's edge counts as long as its detector reads partial views (a ChArUco
board any four corners; a circle grid or chessboard a part that identifies itself: see their
detectors). Copies are returned in reading order of their centres in the image: rows of
copies from the top (a copy starts a new row when its centre lies more than half a copy's
height below the first of the current row), left to right in each row.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planarcal.calib.boards import BOARD_TYPES, Board, is_board
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.detect_charuco import (
    _marker_square_corners,
    _MarkerPairs,
    _Markers,
    _to_full,
    marker_cells,
)
from planarcal.calib.detection import BoardDetection, detect_board
from planarcal.errors import ArgumentError, BoardNotFoundError, BoardTurnedError
from planarcal.images import grey_levels

F64 = NDArray[np.float64]
Grey = NDArray[np.uint8] | NDArray[np.float32]

BLANK_MARGIN = 0.4
"""How far beyond its printed field a found copy is blanked, in pitches (a printed board's
paper reaches further: the cell's reaches 15 mm beyond, 0.75 of a 20 mm pitch)."""

BLANK_MARGIN_PX = 3.0
"""And this many pixels more (the lens bends the field's edges off the points' homography)."""

MAX_COPIES = 64
"""The most copies looked for when ``max_copies`` is not given."""


def detect_board_copies(
    image: Any, board: Board, *, max_copies: int | None = None, **detector_options: Any
) -> list[BoardDetection]:
    """Every copy of ``board`` in ``image`` (an array, grey or BGR, or a path), each a
    BoardDetection with its ids and points, in reading order of the copies' centres (rows
    from the top, left to right; see the module). ``max_copies``: at most that many (default:
    all, up to 64; when there are more, which ones is the search's choice).
    ``detector_options``: the board kind's detector's (a circle grid's ``polarity`` and
    ``turned``), for every copy.

    Each copy's points are those ``detect_board`` finds on an image of that copy alone.
    Raises BoardNotFoundError (what the detector saw) when no copy is found, and what the
    detector raises for a board described wrongly."""
    if not is_board(board):
        raise ArgumentError(
            f"board must be one of planarcal's boards ({', '.join(BOARD_TYPES)}), got "
            f"{type(board).__name__}"
        )
    limit = MAX_COPIES if max_copies is None else max_copies
    if isinstance(limit, bool) or not isinstance(limit, int | np.integer) or limit < 1:
        raise ArgumentError(f"max_copies must be a whole number >= 1, got {max_copies!r}")
    grey = grey_levels(image)
    if isinstance(board, CharucoBoard):
        if detector_options:
            raise ArgumentError(
                f"a ChArUco board's detector takes no options, got {', '.join(detector_options)}"
            )
        regions = _charuco_regions(grey, board)
    else:
        regions = _regions_one_by_one(grey, board, int(limit), detector_options)
    found: list[BoardDetection] = []
    for k, region in enumerate(regions):
        alone = _blanked(grey, [r for j, r in enumerate(regions) if j != k])
        try:
            det: BoardDetection | None = detect_board(alone, board, **detector_options)
        except BoardNotFoundError:
            det = None  # a few stray ChArUco markers, not a board
        if det is None or not _inside(region.polygon, det.image_points).all():
            det = region.detection  # pragma: no cover - the copy as first found, if any
        if det is not None:
            found.append(det)
    if not found:  # no group of markers makes a copy: the detector says what it sees
        return [detect_board(grey, board)]
    return _reading_order(found)[: int(limit)]


@dataclasses.dataclass(frozen=True)
class _Region:
    """Where a copy lies in the image: a polygon (n, 2) px to blank; and the copy's
    detection as first found (with other copies in view), where it was found one by one."""

    polygon: F64
    detection: BoardDetection | None = None


def _regions_one_by_one(
    grey: Grey, board: Board, limit: int, options: dict[str, Any]
) -> list[_Region]:
    """The copies of a circle grid or chessboard, found one at a time, each blanked before
    the next search: their regions."""
    regions: list[_Region] = []
    work = grey
    turned: list[BoardTurnedError] = []
    while len(regions) < limit:
        try:
            det = detect_board(work, board, **options)
        except BoardTurnedError as e:
            if "turned" in options:
                raise
            # A copy that can be read only turned by 90 degrees: blank it too (read turned)
            # and say so at the end, rather than leave it out or stop the search at it.
            turned.append(e)
            det = detect_board(work, board, **options, turned=True)
        except BoardNotFoundError:
            if regions:
                break
            raise
        if any(_inside(r.polygon, det.image_points).any() for r in regions):
            break  # pragma: no cover - a blanked copy cannot be found again
        region = dataclasses.replace(_detection_region(det), detection=det)
        regions.append(region)
        work = _blanked(work, [region])
    if turned:
        raise BoardTurnedError(
            f"{len(turned)} of the {len(regions)} copies found can be read only turned by 90 "
            f"degrees ({turned[0]}): copies may lie at any angle, so pass turned=True (--turned) "
            "to accept each copy's frame as it lies",
            turned[0].diagnostics,
        )
    return regions


def _pitch_mm(board: Board) -> float:
    """The distance between neighbouring board points (mm)."""
    pts = board.world_points()
    d = np.hypot(*(pts[1:] - pts[:-1]).T)
    return float(np.min(d[d > 0]))


def _field_outline(box: tuple[float, float, float, float], step: float) -> F64:
    """A rectangle's outline (x0, y0, x1, y1), sampled about every ``step``."""
    x0, y0, x1, y1 = box
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], np.float64)
    out = []
    for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
        n = max(2, int(np.ceil(np.hypot(*(b - a)) / step)))
        out.append(a + np.linspace(0.0, 1.0, n, endpoint=False)[:, None] * (b - a))
    return np.vstack(out)


def _grown_polygon(h: F64, outline: F64) -> F64:
    """An outline mapped through homography ``h``, grown by BLANK_MARGIN_PX."""
    p = cv2.perspectiveTransform(outline.reshape(-1, 1, 2), h).reshape(-1, 2)
    hull = cv2.convexHull(p.astype(np.float32)).reshape(-1, 2).astype(np.float64)
    centre = hull.mean(axis=0)
    away = hull - centre
    norm = np.maximum(np.hypot(away[:, 0], away[:, 1]), 1e-9)
    return np.asarray(hull + away / norm[:, None] * BLANK_MARGIN_PX, np.float64)


def _detection_region(det: BoardDetection) -> _Region:
    """A found copy's printed field, grown by BLANK_MARGIN pitches, in the image."""
    board = det.board
    h, _ = cv2.findHomography(det.world_points(), det.image_points, 0)
    if h is None:  # pragma: no cover - a detection has four points not on one line
        raise BoardNotFoundError("a copy's points give no homography")
    grow = BLANK_MARGIN * _pitch_mm(board)
    x0, y0, x1, y1 = (float(v) for v in board.ink().field)
    box = (x0 - grow, y0 - grow, x1 + grow, y1 + grow)
    return _Region(_grown_polygon(np.asarray(h, np.float64), _field_outline(box, grow)))


def _charuco_regions(grey: Grey, board: CharucoBoard) -> list[_Region]:
    """A ChArUco board's copies from its markers: the groups of markers that agree about
    where they sit on the board (in the printed layout under which most pairs agree), each
    group's board with BLANK_MARGIN squares around it, in the image."""
    u8 = np.asarray(np.clip(np.rint(grey), 0, 255), np.uint8) if grey.dtype != np.uint8 else grey
    markers = _Markers(np.asarray(u8, np.uint8), board)
    quad = markers.quad_on
    ids = markers.ids_on
    if len(ids) < 2:
        return []
    inset = 0.5 * (1.0 - board.marker / board.square)
    pairs = _MarkerPairs(quad, inset)
    layouts = [False, True] if board.legacy is None else [bool(board.legacy)]
    best = None
    for legacy in layouts:
        cells = marker_cells(board.squares_x, board.squares_y, legacy)
        agreement = pairs.agreement(cells[ids])
        score = (agreement.n_agree, -agreement.disagree)
        if best is None or score > best[0]:
            best = (score, legacy, agreement, cells)
    assert best is not None
    _, legacy, agreement, cells = best
    if agreement.n_agree == 0:
        return []
    graph = coo_matrix(
        (np.ones(agreement.n_agree), (agreement.agree_i, agreement.agree_j)),
        shape=(len(ids), len(ids)),
    )
    _, labels = connected_components(graph, directed=False)
    regions = []
    for label in np.unique(labels):
        members = np.flatnonzero(labels == label)
        if len(members) < 2:
            continue  # a lone marker: a stray decode, or too little of a copy to read
        obj = _marker_square_corners(cells[ids[members]], inset).reshape(-1, 2)
        img = _to_full(quad[members], markers.scale).reshape(-1, 2)
        h, _ = cv2.findHomography(obj, img, 0)
        if h is None:  # pragma: no cover - two markers give eight points
            continue
        g = BLANK_MARGIN
        box = (-g, -g, board.squares_x + g, board.squares_y + g)
        regions.append(_Region(_grown_polygon(np.asarray(h, np.float64), _field_outline(box, 0.5))))
    return regions


def _inside(polygon: F64, points: F64) -> NDArray[np.bool_]:
    """Whether each point lies inside a convex polygon."""
    contour = polygon.astype(np.float32).reshape(-1, 1, 2)
    return np.array(
        [cv2.pointPolygonTest(contour, (float(x), float(y)), False) >= 0 for x, y in points],
        dtype=bool,
    )


def _blanked(grey: Grey, regions: Sequence[_Region]) -> Grey:
    """A copy of the image with each region filled with the median grey of a ring just
    outside it (the paper the copy lies on)."""
    if not regions:
        return grey
    out: Grey = grey.copy()
    height, width = grey.shape
    for region in regions:
        inner = np.zeros((height, width), np.uint8)
        pts = np.rint(region.polygon * 16).astype(np.int32).reshape(-1, 1, 2)
        cv2.fillPoly(inner, [pts], 1, lineType=cv2.LINE_8, shift=4)
        inside = inner.astype(bool)
        ring = np.asarray(cv2.dilate(inner, np.ones((7, 7), np.uint8)), bool) & ~inside
        values = grey[ring]
        fill = float(np.median(values)) if values.size else float(np.median(grey))
        out[inside] = fill
    return out


def _reading_order(found: list[BoardDetection]) -> list[BoardDetection]:
    """The copies in reading order of their centres (see the module)."""
    if len(found) < 2:
        return found
    centres = np.array([d.image_points.mean(axis=0) for d in found])
    heights = np.array([np.ptp(d.image_points[:, 1]) for d in found])
    half = 0.5 * float(np.median(heights))
    order = np.argsort(centres[:, 1], kind="stable")
    rows: list[list[int]] = []
    for k in order:
        if rows and centres[k, 1] - centres[rows[-1][0], 1] <= half:
            rows[-1].append(int(k))
        else:
            rows.append([int(k)])
    ordered = [k for row in rows for k in sorted(row, key=lambda j: centres[j, 0])]
    return [found[k] for k in ordered]
