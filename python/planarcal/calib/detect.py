"""Finding the board in an image: every dot's centre, sub-pixel, in the board's order.

The search (dark dots on light paper, then light dots on a dark board, unless one is asked
for):

1. Blobs: filled ellipses seen over several grey levels (planarcal.calib.blobs), of any size from
   about 4 px across to the largest a board in view can have; the board's nominal dot size
   is not needed.
2. Grids: lattices grown from the blobs and the board's dot pattern placed on them
   (planarcal.calib.grid_search), which is indifferent to dots of other sizes on the grid (an
   origin marker as wide as the pitch, fiducials) and to marks off it (printed numbers,
   arrows, the board's edge, texture). Where that finds nothing, OpenCV's findCirclesGrid
   with its own defaults, as long as the blobs in view keep it quick (it can run for
   minutes on thousands of them).
3. Every candidate is refined and checked (planarcal.calib.dot_centres): each centre from the dot's
   grey levels over a plane fitted to the paper around it, then corrected for perspective
   (the conic offset, with each dot's diameter measured in the image). A dot that cannot be
   measured keeps its blob centre and is flagged (``refined``), instead of sinking the board;
   so is one that strays far from where the dots around it put it (a mark over it), which
   takes their prediction. A grid with more such dots than a board may miss, or whose dots
   continue past an edge (a larger board), is not the board's and is refused.
4. Partial views, where no whole board is found (planarcal.calib.partial_view): a lattice
   that fits inside the board in one way only (up to the turns that map the board's print
   onto itself) is read as the part of the board it is: its enlarged dots (the board's
   ``fiducials``, its origin marker) on the board's, its regular dots on regular ones, or a
   lattice as large as the board with dots lost to glare. The board's other dots in view
   join it (across an object, the rest of the lattice), and the detection has the ids of the
   dots found (``ids``; dots that cannot be measured or checked against their neighbours
   are left out, not filled in). A part that fits the board in several ways (a plain grid
   cut off) is refused, saying that the view is partial and ambiguous and what would fix it.

The board's reading. The world frame (X along a row, Y down a column, as printed and seen
from the front) maps onto the image without a mirror. An origin marker (the board's, or
any corner dot clearly larger than its neighbours: recognised without being declared) is
dot 0; a board's fiducials must be where it has them, and fix the reading where they break
the grid's symmetry. A grid whose pattern has one unmirrored reading (an asymmetric grid
with an odd number of rows) fixes it by itself. Otherwise the orientation is ambiguous,
and dot 0 is the corner nearest the image's top-left (pixel (0, 0)); the detection says so
(``orientation``, ``orientation_rule``). A
non-square board that can only be read turned by 90 degrees (its rows running down the
image) is refused with the command line that reads it as given (``--cols`` and ``--rows``
swapped), unless ``turned=True`` or a marker settles it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Any, Literal, cast

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planarcal.calib.blobs import Blobs, find_blobs
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.detection import AMBIGUOUS_RULE, Orientation
from planarcal.calib.detection import BoardDetection as BoardDetection  # its old home
from planarcal.calib.detection import detect_board as detect_board  # the public name, here too
from planarcal.calib.dot_centres import not_refined_reasons, refine_centres
from planarcal.calib.dot_sizes import (
    check_description,
    measured_sizes,
)
from planarcal.calib.grid_search import (
    LATTICE_SYMMETRIES,
    Lattice,
    board_pattern,
    fill_holes,
    grow_lattices,
    lattice_extent,
    lattice_to_world,
    max_holes,
    outer_ring,
    place_board,
)
from planarcal.calib.partial_view import join_blobs, place_partial
from planarcal.errors import ArgumentError, BoardNotFoundError, BoardTurnedError, DegenerateError
from planarcal.homography import estimate_homography, reprojection_errors, transform_points
from planarcal.images import ROWS_PER_CHUNK, grey_levels

F64 = NDArray[np.float64]
Polarity = Literal["auto", "dark", "light"]

# A dot whose ink area exceeds its neighbours' by this factor is enlarged (a marker, a fiducial).
MARKER_AREA_RATIO = 1.35
# Smallest dot looked for (px across).
MIN_DOT_PX = 3.5
# OpenCV's finder runs only below this many blobs in view: beyond it it can take minutes (its
# clustering variant, which the lattice search makes unnecessary, is never run).
OPENCV_MAX_BLOBS = 600

# A partial view needs this many dots, on at least three lattice lines each way.
MIN_PARTIAL_DOTS = 8
# Of a partial view's dots, up to one in this many may stray from their neighbours (partly
# hidden) and be left out.
PARTIAL_STRAY_SHARE = 8
# Lattices tried as partial views per polarity, largest first.
MAX_PARTIAL_LATTICES = 3

FIDUCIAL_RULE = "the board's fiducial dots, which fix its reading, are where the board has them"
PARTIAL_RULE = (
    "a partial view: the dots in view, with the board's enlarged dots seen among them (and "
    "not seen where they are regular), fit the board in one way only"
)
NO_MARKER = "no origin marker"
"""How the refusal of a whole grid without the origin marker described begins."""
PATTERN_RULE = (
    "the grid's own pattern has one reading that is not mirrored (an asymmetric grid with an "
    "odd number of rows): dot 0 is its origin"
)


@dataclasses.dataclass(frozen=True)
class SeenBlobs:
    """The blobs one polarity's search saw: centres (N, 2) px and diameters (N,) px."""

    polarity: Literal["dark", "light"]
    centres_px: F64
    diameters_px: F64
    grid: tuple[int, int, int] | None = None
    """The largest grid of these blobs: (dots across the image, dots down, dots in it)."""


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
    partial_views: tuple[PartialView, ...] = ()
    """The partial views of the board seen that could not be read (ambiguous)."""


@dataclasses.dataclass(frozen=True)
class PartialView:
    """Part of the board seen, which fits the board in several ways."""

    polarity: Literal["dark", "light"]
    dots: int
    """Dots seen in it."""
    grid: tuple[int, int]
    """(dots across the image, dots down) of its lattice."""
    ways: int
    """Distinct readings it fits the board in (-1: more than were counted)."""
    enlarged: int
    """Enlarged dots seen in it (fiducials or a marker the board's description lacks?)."""


def detect_circle_grid(
    image: Any, board: CircleGridBoard, *, polarity: Polarity = "auto", turned: bool = False
) -> BoardDetection:
    """Find the circle grid `board` in `image` (an array, grey or BGR, any real dtype, or a
    path); planarcal.calib.detection.detect_board's detector for circle grids.

    Returns the centre of every dot in the board's order, or of the dots in view (``ids``)
    of a partial view that identifies itself (see the module's docstring); raises
    BoardNotFoundError, saying what was seen and what to try, when the image shows neither
    (with ``.diagnostics``: the blobs, the candidate grids refused and the ambiguous partial
    views). ``turned=True`` accepts a
    non-square board without an origin marker that lies turned by 90 degrees in the image
    (otherwise refused as BoardTurnedError: usually ``--cols`` and ``--rows`` swapped).
    BoardMismatchError when the board found contradicts the description: its dots, measured
    on the board, are not the stated diameter for the stated pitch, or its origin marker is
    not the stated size (see planarcal.calib.dot_sizes).
    """
    if polarity not in ("auto", "dark", "light"):
        raise ArgumentError(f"polarity must be 'auto', 'dark' or 'light', got {polarity!r}")
    if not isinstance(board, CircleGridBoard):
        raise ArgumentError(f"board must be a CircleGridBoard, got {type(board).__name__}")
    grey = grey_levels(image)
    polarities: tuple[Literal["dark", "light"], ...] = (
        ("dark", "light") if polarity == "auto" else (polarity,)
    )
    refused: list[RefusedCandidate] = []
    seen: list[SeenBlobs] = []
    turned_error: BoardTurnedError | None = None
    views: list[PartialView] = []
    for pol in polarities:
        # Memory: an 8-bit image is searched as it is (the light dots' search thresholds it
        # the other way), a float one through one 8-bit copy per polarity; the float copy
        # the refinement reads is made only once there is a grid to refine.
        u8, dark = _search_image(grey, pol)
        blobs = find_blobs(u8, MIN_DOT_PX, _largest_dot_px(u8.shape, board), dark=dark)
        ink = _InkDark(grey, pol)
        grids: list[tuple[int, int, int]] = []
        # Lattices that may be part of the board, read as such once no whole board is found.
        partial: list[Lattice] = []
        every: list[Lattice] = []
        candidates = _candidates(u8, blobs, board, pol, refused, grids, partial, every)
        for method, points, sizes, filled in candidates:
            try:
                return _finish(ink.get(), points, sizes, filled, board, method, pol, blobs, turned)
            except BoardTurnedError as e:
                turned_error = turned_error or e
                refused.append(RefusedCandidate(method, pol, points, str(e)))
            except _RefusedError as why:
                refused.append(RefusedCandidate(method, pol, points, str(why)))
        largest = max(grids, key=lambda g: g[2], default=None)
        seen.append(SeenBlobs(pol, blobs.centres, blobs.diameters, largest))
        del u8, candidates  # free this polarity's search image before the next one's
        # No whole board: part of it, where the part in view says which part it is.
        for lattice in partial[:MAX_PARTIAL_LATTICES]:
            points = blobs.centres[lattice.blob]
            others = [other for other in every if other is not lattice]
            try:
                return _finish_partial(ink.get(), lattice, board, pol, blobs, others, turned)
            except _AmbiguousViewError as e:
                views.append(e.view)
            except BoardTurnedError as e:
                turned_error = turned_error or e
                refused.append(RefusedCandidate("partial", pol, points, str(e)))
            except _RefusedError as why:
                refused.append(RefusedCandidate("partial", pol, points, str(why)))
        del ink
    h, w = grey.shape
    diagnostics = DetectionDiagnostics(board, (w, h), tuple(seen), tuple(refused), tuple(views))
    if turned_error is not None:
        raise BoardTurnedError(str(turned_error), diagnostics)
    raise BoardNotFoundError(_explain(grey, board, seen, polarities, refused, views), diagnostics)


class _RefusedError(Exception):
    """A candidate grid that failed a check (the reason is the message)."""


class _AmbiguousViewError(Exception):
    """Part of the board seen that fits it in several ways."""

    def __init__(self, view: PartialView) -> None:
        super().__init__(f"a partial view that fits the board in {view.ways} ways")
        self.view = view


def _search_image(
    grey: NDArray[np.uint8] | NDArray[np.float32], polarity: Literal["dark", "light"]
) -> tuple[NDArray[np.uint8], bool]:
    """The 8-bit image the blob search reads for `polarity`, and whether it shows the dots
    dark (else light: an 8-bit grey image as it is, for light dots)."""
    if grey.dtype == np.uint8:
        return cast(NDArray[np.uint8], grey), polarity == "dark"
    return _ink_u8(cast(NDArray[np.float32], grey), polarity), True


def _ink_u8(grey: NDArray[np.float32], polarity: Literal["dark", "light"]) -> NDArray[np.uint8]:
    """The ink (grey, or 255 - grey for light dots) rounded to 8 bits, a block of rows at a
    time."""
    out = np.empty(grey.shape, dtype=np.uint8)
    for top in range(0, grey.shape[0], ROWS_PER_CHUNK):
        rows = slice(top, top + ROWS_PER_CHUNK)
        ink = grey[rows] if polarity == "dark" else np.float32(255.0) - grey[rows]
        out[rows] = np.clip(np.rint(ink), 0, 255)
    return out


class _InkDark:
    """The float32 ink (grey, or 255 - grey for light dots) that the refinement reads, made
    on first use: a search that finds no grid never holds it."""

    def __init__(
        self, grey: NDArray[np.uint8] | NDArray[np.float32], polarity: Literal["dark", "light"]
    ) -> None:
        self._grey = grey
        self._polarity = polarity
        self._ink: NDArray[np.float32] | None = None

    def get(self) -> NDArray[np.float32]:
        if self._ink is None:
            grey = self._grey.astype(np.float32, copy=False)
            self._ink = grey if self._polarity == "dark" else np.float32(255.0) - grey
        return self._ink


# ------------------------------------------------------------------------------------------
# Candidate grids


def _largest_dot_px(shape: tuple[int, ...], board: CircleGridBoard) -> float:
    """The largest dot (an origin marker as wide as the neighbour distance) that a board
    wholly in view can show, px, with slack for perspective (near dots look larger)."""
    h, w = shape[:2]
    span = board.world_points().max(axis=0) / board.neighbour_distance
    longest, shortest = max(float(max(span)), 1.0), max(float(min(span)), 1.0)
    step_max = min(max(w, h) / longest, min(w, h) / shortest)
    return float(max(8.0, 2.0 * step_max))


def _candidates(
    u8: NDArray[np.uint8],
    blobs: Blobs,
    board: CircleGridBoard,
    polarity: Literal["dark", "light"],
    refused: list[RefusedCandidate],
    grids: list[tuple[int, int, int]],
    partial: list[Lattice],
    every: list[Lattice],
) -> Iterator[tuple[str, F64, F64, NDArray[np.bool_]]]:
    """(method, points (n, 2) in a reading of the board's order, blob diameters (n,) px,
    which dots are filled in where no blob was). Lattices that fit inside the board (or are
    it, with holes) and may be part of it are added to `partial`, every lattice to `every`."""
    n = board.n_points
    # A lattice three times the board's size is no board of this size: it stops growing.
    for lattice in grow_lattices(blobs, min_nodes=min(n, 4), max_nodes=max(3 * n, n + 200)):
        placements = place_board(lattice, board)
        pts = blobs.centres[lattice.blob]
        cols, rows = lattice_extent(lattice, blobs.centres)
        grids.append((cols, rows, len(lattice.blob)))
        every.append(lattice)
        if len(placements) <= 1 and _may_be_partial(lattice):
            partial.append(lattice)
        if len(placements) == 1:
            p = placements[0]
            points = fill_holes(p, blobs.centres)
            sizes = np.where(p.blob >= 0, blobs.diameters[p.blob], np.nan)
            sizes[p.blob < 0] = float(np.nanmedian(sizes))
            if np.isfinite(points).all():
                yield "lattice", points, sizes, p.blob < 0
        elif len(placements) > 1:
            refused.append(
                RefusedCandidate(
                    "lattice",
                    polarity,
                    pts,
                    f"a grid of about {cols} x {rows} dots, larger than the board's "
                    f"{board.cols} x {board.rows}: the board fits in it {len(placements)} ways",
                )
            )
        elif len(lattice.blob) >= max(4, n // 2):
            refused.append(
                RefusedCandidate(
                    "lattice",
                    polarity,
                    pts,
                    f"a grid of about {cols} x {rows} dots ({len(lattice.blob)} dots), which "
                    f"the board's {board.cols} x {board.rows} does not fill",
                )
            )
    # OpenCV needs the board's dots among the blobs its detector keeps (25 to 5000 px^2:
    # 5.6 to 80 px across), and runs away on thousands of them.
    in_its_range = int(((blobs.diameters >= 5.6) & (blobs.diameters <= 80.0)).sum())
    if polarity == "dark" and 0.5 * n <= in_its_range and len(blobs) <= OPENCV_MAX_BLOBS:
        for points in _opencv_grid(u8, board):
            yield "opencv", points, _sizes_at(points, blobs), np.zeros(len(points), bool)


def _opencv_grid(u8: NDArray[np.uint8], board: CircleGridBoard) -> Iterator[F64]:
    """OpenCV's findCirclesGrid with its default blob detector, as a user would call it:
    the floor planarcal never falls below."""
    asymmetric = board.layout == "asymmetric"
    flags = cv2.CALIB_CB_ASYMMETRIC_GRID if asymmetric else cv2.CALIB_CB_SYMMETRIC_GRID
    try:
        found, centres = cv2.findCirclesGrid(u8, (board.cols, board.rows), flags=flags)
    except cv2.error:
        return
    if not found or centres is None or len(centres) != board.n_points:
        return
    yield np.asarray(centres, dtype=np.float64).reshape(-1, 2)


def _sizes_at(points: F64, blobs: Blobs) -> F64:
    """The diameter of the blob at each point (half the spacing where no blob is)."""
    spacing = _nearest_distance(points)
    sizes = 0.5 * spacing
    if len(blobs):
        d, nearest = cKDTree(blobs.centres).query(points)
        close = d < 0.3 * spacing
        sizes[close] = blobs.diameters[nearest[close]]
    return sizes


# ------------------------------------------------------------------------------------------
# Refinement, reading, checks


def _finish(
    ink_dark: NDArray[np.float32],
    points: F64,
    sizes: F64,
    filled: NDArray[np.bool_],
    board: CircleGridBoard,
    method: str,
    polarity: Literal["dark", "light"],
    blobs: Blobs,
    turned: bool,
) -> BoardDetection:
    spacing = _nearest_distance(points)
    pitch = float(np.median(spacing))
    if not np.isfinite(pitch) or pitch < 4.0:
        raise _RefusedError(f"dots too close together ({pitch:.1f} px apart)")
    # A blob is never larger than its spacing: a clipped size keeps the windows sane.
    sizes = np.minimum(sizes, spacing)
    measured = refine_centres(ink_dark, points, sizes)
    unseen = np.flatnonzero(filled & ~measured.refined)
    if unseen.size:
        raise _RefusedError(
            f"no dot where the grid has one (near pixel {points[unseen[0]].round(1).tolist()})"
        )
    enlarged = _enlarged(points, measured.areas, pitch)
    centres, refined, doubts = _checked_by_neighbours(
        measured.centres, measured.areas, measured.refined, enlarged, board, pitch
    )
    reading, orientation, rule, warnings = _reading(centres, enlarged, board, turned)
    centres = centres[reading]
    areas = measured.areas[reading]
    refined = refined[reading]
    enlarged = enlarged[reading]
    warnings = (*warnings, *doubts)
    world = board.world_points()
    try:
        corrected, h, diameters_mm = _unbias(centres, world, areas, enlarged)
        residuals = reprojection_errors(h, world, corrected)
    except (DegenerateError, ValueError) as e:
        raise _RefusedError(f"the points do not form a grid: {e}") from None
    diameters = 2.0 * np.sqrt(areas / np.pi)
    beyond = _continues_beyond(corrected, board, blobs, float(np.median(diameters)), pitch)
    if beyond is not None:
        raise _RefusedError(
            f"the dots continue past the grid's {beyond} edge: the board in view is larger than "
            f"{board.cols} x {board.rows} (check --cols and --rows)"
        )
    # Named by their index in the board's reading, as everywhere.
    why_not = not_refined_reasons(measured.status[reading])
    if why_not:
        warnings = (
            *warnings,
            f"{len(why_not)} of {len(refined)} dots could not be measured and keep "
            f"a coarser centre ({'; '.join(why_not[:3])})",
        )
    dot_sizes = measured_sizes(
        board,
        diameters_mm,
        enlarged,
        diameters,
        orientation == "marker",
        ink_dark,
        corrected,
    )
    check_description(board, dot_sizes)
    height, width = ink_dark.shape[:2]
    return BoardDetection(
        board=board,
        image_points=np.ascontiguousarray(corrected),
        image_size=(width, height),
        method=method,
        polarity=polarity,
        dot_diameters_px=diameters,
        residual_rms_px=float(np.sqrt(np.mean(residuals**2))),
        refined=refined,
        enlarged=enlarged,
        orientation=orientation,
        orientation_rule=rule,
        warnings=warnings,
        sizes=dot_sizes,
    )


def _may_be_partial(lattice: Lattice) -> bool:
    """Whether a lattice is large enough to be read as part of a board: MIN_PARTIAL_DOTS
    dots on at least three lines each way (a homography, and a shape to place)."""
    if len(lattice.blob) < MIN_PARTIAL_DOTS:
        return False
    return all(len(np.unique(lattice.nodes[:, axis])) >= 3 for axis in (0, 1))


def _finish_partial(
    ink_dark: NDArray[np.float32],
    lattice: Lattice,
    board: CircleGridBoard,
    polarity: Literal["dark", "light"],
    blobs: Blobs,
    others: list[Lattice],
    turned: bool,
) -> BoardDetection:
    """Part of the board, read from a lattice that fits inside it in one way only (its
    enlarged dots, or its extent, say where it lies on the board), with the other blobs that
    are board dots joined to it. Dots that cannot be measured, or stray from where their
    neighbours put them, are left out: a partial view names the dots it found."""
    points = blobs.centres[lattice.blob]
    spacing = _nearest_distance(points)
    pitch = float(np.median(spacing))
    if not np.isfinite(pitch) or pitch < 4.0:
        raise _RefusedError(f"dots too close together ({pitch:.1f} px apart)")
    if not board.dot_kinds().any():
        # A plain board's placements need no sizes: an ambiguous view costs no refinement.
        every = np.ones(len(points), dtype=bool)
        fit = place_partial(lattice.nodes, points, every, ~every, board)
        if fit.ways != 1:
            across, down = lattice_extent(lattice, blobs.centres)
            # Enlarged dots, by their blobs' sizes: fiducials the description may lack.
            big = _enlarged(points, blobs.diameters[lattice.blob] ** 2, pitch)
            raise _AmbiguousViewError(
                PartialView(polarity, len(points), (across, down), fit.ways, int(big.sum()))
            )
    measured = refine_centres(ink_dark, points, np.minimum(blobs.diameters[lattice.blob], spacing))
    enlarged = _enlarged(measured.centres, measured.areas, pitch)
    usable = measured.refined
    fit = place_partial(lattice.nodes, measured.centres, usable, enlarged, board)
    if fit.ways == 0:
        marks = (
            "" if not board.dot_kinds().any() else ", with its enlarged dots where the board's are,"
        )
        raise _RefusedError(
            f"a grid of {len(lattice.blob)} dots that does not fit inside the board{marks} "
            "without a mirror"
        )
    if fit.ways != 1:
        across, down = lattice_extent(lattice, blobs.centres)
        raise _AmbiguousViewError(
            PartialView(
                polarity, int(usable.sum()), (across, down), fit.ways, int(enlarged[usable].sum())
            )
        )
    world = board.world_points()
    readings = [r[usable] for r in fit.readings]
    centres = measured.centres[usable]
    reading, orientation, rule = _partial_reading(readings, centres, board)
    ids = reading
    areas = measured.areas[usable]
    # The board's other dots in view: blobs off the lattice (across an object, glare).
    taken = np.zeros(len(blobs), dtype=bool)
    taken[lattice.blob] = True
    found_px = blobs.diameters[lattice.blob][usable]
    joined = join_blobs(
        ids, centres, found_px, blobs.centres, blobs.diameters, taken, board, others
    )
    if joined.ids.size:
        extra = refine_centres(
            ink_dark, blobs.centres[joined.blob], np.minimum(blobs.diameters[joined.blob], pitch)
        )
        keep = extra.refined
        ids = np.concatenate([ids, joined.ids[keep]])
        centres = np.concatenate([centres, extra.centres[keep]])
        areas = np.concatenate([areas, extra.areas[keep]])
    order = np.argsort(ids)
    ids, centres, areas = ids[order], centres[order], areas[order]
    enlarged = _enlarged(centres, areas, pitch)
    kinds = board.dot_kinds() > 0
    if kinds.any():
        # Joined dots of the wrong kind (a blob swollen by glare) are not the board's.
        agree = enlarged == kinds[ids]
        ids, centres, areas, enlarged = ids[agree], centres[agree], areas[agree], enlarged[agree]
    if len(ids) < MIN_PARTIAL_DOTS:
        raise _RefusedError(f"only {len(ids)} dots of the partial view could be measured")
    # A partial view's edge dots are often partly hidden (by the object that hides the
    # rest): up to one in PARTIAL_STRAY_SHARE may stray, and is left out.
    checked, ok, doubts = _checked_by_neighbours(
        centres,
        areas,
        np.ones(len(ids), bool),
        enlarged,
        board,
        pitch,
        world=world[ids],
        allowed=max(2, max_holes(board), len(ids) // PARTIAL_STRAY_SHARE),
    )
    del checked, doubts
    ok &= _checked_when_alone(world[ids], centres, ok, board, pitch)
    warnings: tuple[str, ...] = ()
    if not ok.all():
        warnings = (
            f"{int((~ok).sum())} dot(s) left out, far from where their neighbours put them or "
            f"with too few neighbours to tell (partly hidden?): "
            f"{', '.join(str(k) for k in ids[~ok][:8])}",
        )
        ids, centres, areas, enlarged = ids[ok], centres[ok], areas[ok], enlarged[ok]
    if len(ids) < MIN_PARTIAL_DOTS:
        raise _RefusedError(f"only {len(ids)} dots of the partial view agree with each other")
    if orientation == "ambiguous" and not kinds.any():
        warnings = (*warnings, *_turned_check(centres, world[ids], board, turned))
    try:
        corrected, h, diameters_mm = _unbias(centres, world[ids], areas, enlarged)
        residuals = reprojection_errors(h, world[ids], corrected)
    except (DegenerateError, ValueError) as e:
        raise _RefusedError(f"the points do not form a grid: {e}") from None
    diameters = 2.0 * np.sqrt(areas / np.pi)
    beyond = _continues_beyond(corrected, board, blobs, float(np.median(diameters)), pitch, ids=ids)
    if beyond is not None:
        raise _RefusedError(
            f"the dots continue past the grid's {beyond} edge: the board in view is larger than "
            f"{board.cols} x {board.rows} (check --cols and --rows)"
        )
    dot_sizes = measured_sizes(
        board,
        diameters_mm,
        enlarged,
        diameters,
        board.origin_marker and orientation == "marker",
        ink_dark,
        corrected,
        ids,
    )
    check_description(board, dot_sizes)
    height, width = ink_dark.shape[:2]
    return BoardDetection(
        board=board,
        image_points=np.ascontiguousarray(corrected),
        image_size=(width, height),
        method="lattice",
        residual_rms_px=float(np.sqrt(np.mean(residuals**2))),
        ids=ids.astype(np.intp),
        polarity=polarity,
        dot_diameters_px=diameters,
        refined=np.ones(len(ids), dtype=bool),
        enlarged=enlarged,
        orientation=orientation,
        orientation_rule=rule,
        warnings=warnings,
        sizes=dot_sizes,
    )


def _checked_when_alone(
    world: F64, centres: F64, ok: NDArray[np.bool_], board: CircleGridBoard, pitch: float
) -> NDArray[np.bool_]:
    """Which dots of a partial view pass the neighbours' check: a dot with too few checked
    neighbours within two steps (between the fingers of a hand, beside dots left out) is
    checked against those within three, as strictly as the rest against theirs (twice the
    limit: a wider fit bends less with the lens); one that cannot be checked is left out (a
    partly hidden dot looks like a dot)."""
    ok = ok.copy()
    near = _predict_from_neighbours(world, centres, world, board, known=ok)
    gap = np.hypot(*(centres - near).T)
    checked = ok & np.isfinite(gap)
    typical = float(np.median(gap[checked])) if checked.any() else 0.0
    limit = 2.0 * float(
        np.clip(10.0 * typical, MIN_DISAGREEMENT_PX, NEIGHBOUR_DISAGREEMENT_PITCH * pitch)
    )
    for _ in range(len(world)):
        lone = np.flatnonzero(ok & ~checked)
        if not lone.size:
            break
        wide = _predict_from_neighbours(
            world, centres, world[lone], board, known=checked, steps=3.0
        )
        wide_gap = np.hypot(*(centres[lone] - wide).T)
        good = np.isfinite(wide_gap) & (wide_gap < limit)
        checked[lone[good]] = True
        if good.all():
            break
        if not good.any():
            ok[lone] = False
            break
    kept: NDArray[np.bool_] = ok & checked
    return kept


def _partial_reading(
    readings: list[NDArray[np.intp]], centres: F64, board: CircleGridBoard
) -> tuple[NDArray[np.intp], Orientation, str]:
    """Of a partial view's readings (the ids of its dots, one reading per turn of the board
    onto itself), the one chosen as a whole board's would be: the only one, else the one
    whose dot 0 lies nearest the image's top-left (where the homography of the dots seen puts
    it)."""
    if len(readings) == 1:
        if board.layout == "asymmetric" and board.rows % 2 == 1:
            return readings[0], "pattern", PATTERN_RULE
        return readings[0], "marker", PARTIAL_RULE
    world = board.world_points()

    def origin_distance(ids: NDArray[np.intp]) -> float:
        try:
            h = estimate_homography(world[ids], centres)
        except (DegenerateError, ValueError):
            return float("inf")
        return float(np.hypot(*transform_points(h, world[:1])[0]))

    best = min(readings, key=origin_distance)
    return best, "ambiguous", AMBIGUOUS_RULE


def _turned_check(
    centres: F64, world: F64, board: CircleGridBoard, turned: bool
) -> tuple[str, ...]:
    """A non-square plain board read with its rows running down the image: refused as a
    whole board's would be (usually --cols and --rows swapped), unless `turned`."""
    if board.cols == board.rows or board.layout != "symmetric":
        return ()
    design = np.column_stack([world, np.ones(len(world))])
    coef = np.linalg.lstsq(design, centres, rcond=None)[0]
    x_axis = coef[0]
    if abs(x_axis[1]) <= abs(x_axis[0]):
        return ()
    if not turned:
        raise BoardTurnedError(
            f"the {board.cols} x {board.rows} grid lies turned by 90 degrees in the image "
            f"(its rows run down the image).{_swap_hint(board)} If the board really lies "
            "turned, accept its frame as it is with --turned (turned=True)."
        )
    return ("the board lies turned by 90 degrees in the image (accepted: turned)",)


# A dot this far from where its neighbours put it (in pitches) is not measured right (a mark or
# glare over it, a dot split in two) and takes their prediction instead; nearer dots are
# judged against how well the board's dots agree on the whole (_checked_by_neighbours).
NEIGHBOUR_DISAGREEMENT_PITCH = 0.15
# ... and never within this many px: below it a dot may sit where a lens or the paper puts it.
MIN_DISAGREEMENT_PX = 0.25
# A dot with less ink than this fraction of its neighbours' is partly hidden.
MIN_AREA_OF_NEIGHBOURS = 0.5


def _checked_by_neighbours(
    centres: F64,
    areas: F64,
    refined: NDArray[np.bool_],
    enlarged: NDArray[np.bool_],
    board: CircleGridBoard,
    pitch: float,
    *,
    world: F64 | None = None,
    allowed: int | None = None,
) -> tuple[F64, NDArray[np.bool_], tuple[str, ...]]:
    """Each centre against the homography through the dots around it (two steps on the
    board; the board's bend by the lens is smooth over that, however strong the lens): a dot
    that strays from it far more than the dots do on the whole, or that shows much less ink
    than its neighbours, keeps their prediction instead, flagged as not refined. The worst
    goes first and no longer predicts its neighbours, so one bad dot does not condemn the
    dots around it. More such dots than a board may miss is no board: refused. `world`: the
    dots' board positions (mm), every dot of the board in order when None; `allowed`: how
    many dots may stray (a whole board's max_holes, at least 2, when None)."""
    world = board.world_points() if world is None else world
    neighbourhoods = _around(world, 2.01 * board.neighbour_distance)
    trusted = np.ones(len(world), dtype=bool)
    why: dict[int, str] = {}
    for k, near in enumerate(neighbourhoods):
        regular = [j for j in near if not enlarged[j]]
        if (
            not enlarged[k]
            and len(regular) >= 3
            and areas[k] < MIN_AREA_OF_NEIGHBOURS * float(np.median(areas[regular]))
        ):
            trusted[k] = False
            why[k] = "much less ink than its neighbours"
    predicted = _predict_from_neighbours(world, centres, world, board, known=trusted)
    gap = np.hypot(*(centres - predicted).T)
    # Far beyond how well the dots agree with their neighbours on the whole (ten times the
    # median gap: real photographs' good dots stay within six, through a strong lens and at
    # the board's edges), at most NEIGHBOUR_DISAGREEMENT_PITCH, never within
    # MIN_DISAGREEMENT_PX.
    typical = float(np.nanmedian(gap)) if np.isfinite(gap).any() else 0.0
    floor = MIN_DISAGREEMENT_PX
    limit = float(np.clip(10.0 * typical, floor, max(floor, NEIGHBOUR_DISAGREEMENT_PITCH * pitch)))
    allowed = max(2, max_holes(board)) if allowed is None else allowed
    while len(why) <= allowed:
        excess = np.where(trusted & np.isfinite(gap), gap / limit, 0.0)
        k = int(np.argmax(excess))
        if excess[k] <= 1.0:
            break
        trusted[k] = False
        why[k] = f"{gap[k]:.1f} px from where its neighbours put it"
        # Only the dots around it change their prediction.
        around = np.array([k, *neighbourhoods[k]], dtype=np.intp)
        predicted[around] = _predict_from_neighbours(
            world, centres, world[around], board, known=trusted
        )
        gap[around] = np.hypot(*(centres[around] - predicted[around]).T)
    if len(why) > allowed:
        raise _RefusedError(
            f"not the board's grid: {len(why)} or more dots stray from where their neighbours "
            f"put them"
        )
    out = centres.copy()
    ok = refined.copy()
    doubts = []
    for k, reason in sorted(why.items()):
        if np.isfinite(predicted[k]).all():
            out[k] = predicted[k]
            ok[k] = False
            doubts.append(f"dot at pixel {centres[k].round(1).tolist()}: {reason}")
    if doubts:
        doubts = [
            f"{len(doubts)} dot(s) replaced by where their neighbours put them (partly hidden?), "
            f"flagged as not refined: {'; '.join(doubts[:3])}"
        ]
    return out, ok, tuple(doubts)


def _predict_from_neighbours(
    world: F64,
    image: F64,
    queries: F64,
    board: CircleGridBoard,
    *,
    known: NDArray[np.bool_] | None = None,
    steps: float = 2.0,
) -> F64:
    """Where each world point in `queries` lies in the image, by a homography through the
    board's dots (world, image) within `steps` steps of it, other than itself and those not
    `known`; NaN where fewer than five are."""
    reach = (steps + 0.01) * board.neighbour_distance
    near = cKDTree(world).query_ball_point(queries, r=reach)
    out = np.full((len(queries), 2), np.nan)
    for k, js in enumerate(near):
        use = [
            j
            for j in js
            if (known is None or known[j]) and not np.array_equal(world[j], queries[k])
        ]
        if len(use) < 5:
            continue
        try:
            h = estimate_homography(world[use], image[use])
            out[k] = transform_points(h, queries[[k]])[0]
        except ValueError:
            continue
    return out


def _nearest_distance(points: F64) -> F64:
    """Each point's distance to its nearest other point."""
    dist, _ = cKDTree(points).query(points, k=2)
    nearest: F64 = np.asarray(dist[:, 1], dtype=np.float64)
    return nearest


def _around(points: F64, radius: float) -> list[list[int]]:
    """For each point, the other points within `radius`."""
    near = cKDTree(points).query_ball_point(points, r=radius)
    return [[j for j in js if j != k] for k, js in enumerate(near)]


def _enlarged(points: F64, areas: F64, pitch: float) -> NDArray[np.bool_]:
    """Dots whose ink area exceeds the median of the dots around them (within two pitches)
    by MARKER_AREA_RATIO."""
    out = np.zeros(len(points), dtype=bool)
    for k, around in enumerate(_around(points, 2.2 * pitch)):
        if len(around) >= 2:
            out[k] = areas[k] > MARKER_AREA_RATIO * float(np.median(areas[around]))
    return out


def _readings(board: CircleGridBoard) -> list[NDArray[np.intp]]:
    """The re-indexings of the board's dots that map its pattern onto itself (its
    symmetries: the identity, a turn by 180 degrees, and the turns and mirrors a square grid
    adds), as permutations: reading[k] is the found dot that is dot k."""
    pattern = board_pattern(board)
    pattern -= pattern.min(axis=0)
    index = {tuple(p): k for k, p in enumerate(pattern.tolist())}
    out = []
    for m in LATTICE_SYMMETRIES:
        turned = pattern @ m.T
        turned -= turned.min(axis=0)
        perm = [index.get(tuple(p)) for p in turned.tolist()]
        if None not in perm:
            out.append(np.array(perm, dtype=np.intp))
    return out


def _unmirrored(points: F64, world: F64) -> bool:
    """Whether the world frame maps onto these image points without a mirror: the affine
    fit's determinant is positive (image y runs down, like the board's Y)."""
    design = np.column_stack([world, np.ones(len(world))])
    coef = np.linalg.lstsq(design, points, rcond=None)[0]
    return bool(np.linalg.det(coef[:2, :2].T) > 0)


def _reading(
    centres: F64, enlarged: NDArray[np.bool_], board: CircleGridBoard, turned: bool
) -> tuple[NDArray[np.intp], Orientation, str, tuple[str, ...]]:
    """The one re-indexing of the found dots that is the board's, how it was chosen, and
    warnings."""
    world = board.world_points()
    readings = [r for r in _readings(board) if _unmirrored(centres[r], world)]
    swap = _swap_hint(board)
    if not readings:
        raise _RefusedError(
            "the grid has no unmirrored reading: is the board seen from behind, or in a "
            f"mirror?{swap}"
        )
    if board.fiducials:
        return _fiducial_reading(centres, enlarged, board, readings)
    corners = _corner_dots(board)
    marker_at = [k for k in corners if enlarged[k]] if len(corners) else []
    if len(marker_at) == 1:
        marker = marker_at[0]
        for r in readings:
            if r[0] == marker:
                return r, "marker", "dot 0 is the origin marker (the enlarged corner dot)", ()
        raise _RefusedError(
            "the board appears mirrored (its origin marker can only be read with X and Y "
            f"swapped): is it seen from behind, or in a mirror?{swap}"
        )
    if board.origin_marker:
        found = "several enlarged corner dots" if marker_at else "no enlarged corner dot"
        raise _RefusedError(
            f"{NO_MARKER}: the board has one, but {found} was seen (is the board's "
            "marker setting right?)"
        )
    if len(readings) == 1:
        return readings[0], "pattern", PATTERN_RULE, ()
    best = min(readings, key=lambda r: float(np.hypot(*centres[r[0]])))
    warnings: tuple[str, ...] = ()
    if board.cols != board.rows and board.layout == "symmetric":
        x_axis = centres[best[1]] - centres[best[0]]
        if abs(x_axis[1]) > abs(x_axis[0]):
            message = (
                f"the {board.cols} x {board.rows} grid lies turned by 90 degrees in the image "
                f"(its rows run down the image).{swap} If the board really lies turned, accept "
                "its frame as it is with --turned (turned=True)."
            )
            if not turned:
                raise BoardTurnedError(message)
            warnings = ("the board lies turned by 90 degrees in the image (accepted: turned)",)
    return best, "ambiguous", AMBIGUOUS_RULE, warnings


def _fiducial_reading(
    centres: F64,
    enlarged: NDArray[np.bool_],
    board: CircleGridBoard,
    readings: list[NDArray[np.intp]],
) -> tuple[NDArray[np.intp], Orientation, str, tuple[str, ...]]:
    """Of a board with fiducials, the unmirrored readings that put the enlarged dots seen
    exactly on the board's enlarged dots: one where they fix the orientation, else the one
    whose dot 0 is nearest the image's top-left, as for any symmetric board (the fiducials
    agreeing with the description, the board's size is not doubted: no turned check)."""
    kinds = board.dot_kinds() > 0
    agree = [r for r in readings if np.array_equal(enlarged[r], kinds)]
    if not agree:
        seen = int(enlarged.sum())
        ids = ", ".join(str(k) for k in np.flatnonzero(kinds)[:8])
        raise _RefusedError(
            f"{seen} enlarged dot(s) seen, not where the board's enlarged dots are (ids {ids}): "
            "check the board's fiducials (and origin marker)"
        )
    if len(agree) == 1:
        rule = (
            "dot 0 is the origin marker (the enlarged corner dot)"
            if board.origin_marker
            else FIDUCIAL_RULE
        )
        return agree[0], "marker", rule, ()
    best = min(agree, key=lambda r: float(np.hypot(*centres[r[0]])))
    return best, "ambiguous", AMBIGUOUS_RULE, ()


def _swap_hint(board: CircleGridBoard) -> str:
    if board.cols == board.rows or board.layout != "symmetric":
        return ""
    return f" Did you mean --cols {board.rows} --rows {board.cols}?"


def _corner_dots(board: CircleGridBoard) -> list[int]:
    """The indices of the board's corner dots (where an origin marker can be)."""
    world = board.world_points()
    out = {
        int(np.argmin(sx * world[:, 0] + sy * world[:, 1]))
        for sx, sy in ((1, 1), (-1, 1), (1, -1), (-1, -1))
    }
    return sorted(out)


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


def _diameters_mm(
    h: F64, world: F64, areas_px: F64, enlarged: NDArray[np.bool_], *, shared: bool = True
) -> F64:
    """Each dot's diameter on the board, mm, from its ink area in the image through the
    homography's local scale: with `shared`, the regular dots share their median (less noisy
    than each one's), enlarged dots keep their own."""
    hinv = np.linalg.inv(h)
    eps = 1e-3
    p = transform_points(h, world)
    px = transform_points(hinv, p + np.array([eps, 0.0]))
    py = transform_points(hinv, p + np.array([0.0, eps]))
    # mm^2 per px^2 at each dot: the Jacobian of the image-to-board map.
    jx, jy = (px - world) / eps, (py - world) / eps
    scale = np.abs(jx[:, 0] * jy[:, 1] - jx[:, 1] * jy[:, 0])
    d = 2.0 * np.sqrt(areas_px * scale / np.pi)
    regular = ~enlarged
    if shared and regular.any():
        d = np.where(regular, float(np.median(d[regular])), d)
    out: F64 = d
    return out


def _unbias(
    points: F64, world: F64, areas_px: F64, enlarged: NDArray[np.bool_]
) -> tuple[F64, F64, F64]:
    """The measured centres (centroids of the dots' images) moved to the images of the dots'
    centres, by the conic offset under the homography they imply, with the dots' diameters
    measured from the image; recomputed once from the corrected points' homography (it
    changes by well under 1e-4 px after). Returns the centres, the homography and each
    dot's own diameter on the board (mm at the board's pitch) under it."""
    h = estimate_homography(world, points, refine=True)
    diameters = _diameters_mm(h, world, areas_px, enlarged)
    corrected = points
    for _ in range(2):
        corrected = points - conic_centre_offset(h, world, diameters)
        h = estimate_homography(world, corrected, refine=True)
    return corrected, h, _diameters_mm(h, world, areas_px, enlarged, shared=False)


def _continues_beyond(
    points: F64,
    board: CircleGridBoard,
    blobs: Blobs,
    dot_px: float,
    pitch_px: float,
    *,
    ids: NDArray[np.intp] | None = None,
) -> str | None:
    """The edge past which the grid visibly goes on (dots of the same size where one more row
    or column would be), or None. A grid found inside a larger board is not that board: its
    origin would be the wrong dot. `points` are the board's dots `ids` (every dot when None:
    of a partial view, the places next to its dots are looked at)."""
    if not len(blobs):
        return None
    ring = lattice_to_world(board, outer_ring(board))
    span = board.world_points().max(axis=0)
    tol = 1e-6 * float(board.pitch)
    x, y = ring[:, 0], ring[:, 1]
    edges = {
        "top": y < -tol,
        "bottom": y > span[1] + tol,
        "left": x < -tol,
        "right": x > span[0] + tol,
    }
    xy = blobs.centres
    similar = (blobs.diameters > 0.5 * dot_px) & (blobs.diameters < 2.0 * dot_px)
    # A step outside the board: its nearest dots all lie to one side, three steps reach enough.
    world = board.world_points() if ids is None else board.world_points()[ids]
    predicted = _predict_from_neighbours(world, points, ring, board, steps=3.0)
    if ids is not None:
        # Of a partial view, only the places next to the dots found.
        for name in edges:
            edges[name] &= np.isfinite(predicted).all(axis=1)
    near = np.zeros(len(ring), dtype=bool)
    for k, q in enumerate(predicted):
        if np.isfinite(q).all():
            d = np.hypot(xy[:, 0] - q[0], xy[:, 1] - q[1])
            near[k] = bool((similar & (d < 0.25 * pitch_px)).any())
    for name, on_edge in edges.items():
        if near[on_edge].sum() >= max(2, int(on_edge.sum()) // 2):
            return name
    return None


# ------------------------------------------------------------------------------------------
# Explaining a failure


def _explain(
    grey: NDArray[np.uint8] | NDArray[np.float32],
    board: CircleGridBoard,
    seen: list[SeenBlobs],
    polarities: tuple[Literal["dark", "light"], ...],
    refused: list[RefusedCandidate],
    views: list[PartialView] | None = None,
) -> str:
    n = board.n_points
    grid_named = f"{board.cols} x {board.rows} circle grid ({n} dots)"
    image_named = f"{grey.shape[1]} x {grey.shape[0]} image"
    # The whole grid found, refused only for the marker described: the marker is the doubt.
    marker_missed = board.origin_marker and any(
        r.reason.startswith(NO_MARKER) and len(r.points_px) == n for r in refused
    )
    if marker_missed:
        lines = [
            f"the {grid_named} was found in the {image_named}, but not its origin marker (an "
            "enlarged corner dot)."
        ]
    else:
        lines = [f"no {grid_named} found in the {image_named}."]
    counts = []
    grid_hint = ""
    for seen_blobs in seen:
        group = _dominant_size_group(seen_blobs.diameters_px)
        pol = seen_blobs.polarity
        if seen_blobs.grid is not None and seen_blobs.grid[2] >= 4:
            across, down, count = seen_blobs.grid
            lines.append(f"Seen: {count} {pol} dots in a grid of about {across} x {down}.")
            counts.append(count)
            if across * down == count and {across, down} != {board.cols, board.rows}:
                grid_hint = f"or is the board {across} x {down} (--cols {across} --rows {down})?"
        elif group.size:
            size = float(np.median(seen_blobs.diameters_px[group]))
            lines.append(f"Seen: {group.size} {pol} dots of about {size:.0f} px across.")
            counts.append(int(group.size))
        else:
            lines.append(f"Seen: no {pol} dots of a plausible size.")
            counts.append(0)
    best = max(counts) if counts else 0
    hints = []
    view = max(views or [], key=lambda v: v.dots, default=None)
    if view is not None:
        ways = "more ways than were counted" if view.ways < 0 else f"{view.ways} ways"
        lines.append(
            f"The view is partial and ambiguous: {view.dots} of the board's {n} dots seen "
            f"({view.polarity}, in a grid of about {view.grid[0]} x {view.grid[1]}), which fit "
            f"inside the board in {ways}: nothing in view says which of its dots they are."
        )
        if view.enlarged and not board.dot_kinds().any():
            lines.append(
                f"{view.enlarged} enlarged dot(s) seen among them: if the board has fiducial "
                "dots or an origin marker, describe them (--fiducials K,K,... or --origin-marker; "
                "fiducials=(ids...) or origin_marker=True in Python) "
                "and the view is read from them."
            )
        marks = (
            "or let its enlarged dots be seen"
            if board.dot_kinds().any()
            else "or use a board that identifies its dots (an origin marker, --origin-marker, "
            "or fiducial dots, --fiducials K,K,...)"
        )
        hints.append(
            f"fewer dots than the board has: put the whole board in view (not cut off or "
            f"covered), {marks}; and is the board {board.cols} x {board.rows}?"
        )
        best = -1  # the hint is given
    if best < 0:
        pass
    elif marker_missed:
        hints.append(
            "if the board has no origin marker, use --no-origin-marker (origin_marker=False "
            "in Python); if it has one, keep it in view and uncovered"
        )
    elif best and best < n:
        hints.append(
            f"fewer dots than the board has: is the whole board in view (not cut off or "
            f"covered), and is it {board.cols} x {board.rows}?"
        )
    elif best > n:
        hints.append(
            f"more dots than the board has: is it really {board.cols} x {board.rows}? "
            "Other round things in view count too; crop or mask them"
        )
    else:
        hints.append("check the board's size (--cols, --rows) and that it is in view")
    if grid_hint:
        hints.append(grid_hint)
    if len(polarities) == 1:
        other = "light" if polarities[0] == "dark" else "dark"
        hints.append(f"if the dots are {other}er than the board, use polarity '{other}'")
    hints.append("improve focus and lighting; avoid glare on the board")
    lines.append("Try: " + "; ".join(hints) + ".")
    if refused:
        lines.append(
            "Candidates refused: "
            + " | ".join(f"{r.method} ({r.polarity} dots): {r.reason}" for r in refused[:4])
        )
    return " ".join(lines)


def _dominant_size_group(diameters: F64) -> NDArray[np.intp]:
    """The blobs whose size is within a factor of 2 of the most common size."""
    if not diameters.size:
        return np.zeros(0, dtype=np.intp)
    sizes = np.log(diameters)
    ordered = np.sort(sizes)
    counts = np.searchsorted(ordered, sizes + 0.35, "right") - np.searchsorted(
        ordered, sizes - 0.35, "left"
    )
    mode = sizes[int(np.argmax(counts))]
    group: NDArray[np.intp] = np.flatnonzero(np.abs(sizes - mode) <= np.log(2.0))
    return group
