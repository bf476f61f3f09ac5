"""Reading part of a circle grid: which of the board's dots a lattice of blobs is, when the
part in view says so, and the board's other dots in view added to it.

A lattice grown from the blobs (planarcal.calib.grid_search) knows its dots' neighbours, not
their ids. Placed on the board (one of the eight turns and mirrors of the lattice, and an
offset), every node must land on a board dot, the enlarged dots seen on the board's enlarged
dots (its fiducials, its origin marker) and the regular dots seen on regular ones, and the
board's X and Y must map onto the image without a mirror. Placements that differ by a turn
that maps the board's print onto itself (a plain rectangle turned by 180 degrees, the UCL
plate's four fiducials too) are one reading, told apart by the same rule as a whole board's;
any other pair leaves the view ambiguous. So a plain grid cut off is ambiguous (it fits the
board at several offsets), while a view that shows a fiducial, or the origin marker with
enough of the lattice around it, or a lattice as large as the board, fits one way only.

The placement is anchored on an enlarged dot seen (each of the board's enlarged dots in
turn), so its cost is the number of the board's enlarged dots, not of its offsets; without
one every offset is tried, up to MAX_OFFSET_TESTS, and on a plain symmetric board the
placements are counted without trying them (every offset that keeps the lattice inside the
rectangle is one).

Then the view grows (join_blobs): blobs off the lattice join where the found dots around them
put a board dot not yet found, a ring at a time and across small gaps, and other lattices
(the far side of an object laid across the board) join whole where the homography of the
found dots puts most of their dots, and then their own steps all of them, on dots not yet
found, of the right kind.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.grid_search import (
    LATTICE_SYMMETRIES,
    Lattice,
    board_pattern,
    lattice_to_world,
)

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

# Offsets x nodes tested at most when no enlarged dot anchors the placement: beyond it the
# view fits the board in more ways than are worth counting (it is ambiguous).
MAX_OFFSET_TESTS = 4_000_000
# A blob joins a partial view when it lies within this fraction of a step of a board dot's
# place (predicted by the found dots around it).
JOIN_STEP_FRACTION = 0.2
# Found dots a blob's place is predicted from (an affine map through them), and how far it
# may lie from the nearest of them (local steps): first one ring at a time, then across a
# gap (an object over the board, glare).
PREDICT_FROM = 8
NEAR_REACH_STEPS = 1.6
FAR_REACH_STEPS = 3.5


@dataclasses.dataclass(frozen=True)
class PartialFit:
    """The placements of a lattice on the board: ``readings`` are the valid ones (node k is
    dot ``reading[k]``) of the one distinct reading there is, when ``ways == 1``."""

    readings: list[NDArray[np.intp]]
    ways: int
    """Distinct readings (placements up to the board's turns onto itself): 0 none fits, 1 the
    view identifies itself, more ambiguous; -1 more than could be counted."""


def pattern_grid(board: CircleGridBoard) -> tuple[NDArray[np.intp], I64]:
    """The board's dots on their lattice: an array (lattice x, lattice y) -> dot id (-1 where
    the lattice has no dot of the board) and the shift from board_pattern's coordinates to
    its indices."""
    pattern = board_pattern(board)
    shift = -pattern.min(axis=0)
    cells = pattern + shift
    grid = np.full(tuple((cells.max(axis=0) + 1).tolist()), -1, dtype=np.intp)
    grid[cells[:, 0], cells[:, 1]] = np.arange(board.n_points)
    return grid, shift


def world_to_lattice(board: CircleGridBoard, world: F64) -> F64:
    """Board mm to board_pattern's lattice coordinates (fractional), lattice_to_world's
    inverse."""
    a, b = world[:, 0] / float(board.pitch), world[:, 1] / float(board.pitch)
    if board.layout == "asymmetric":
        a, b = 0.5 * (a + b), 0.5 * (a - b)
    return np.column_stack([a, b])


def unmirrored(points: F64, world: F64) -> bool:
    """Whether world points map onto these image points without a mirror (the affine fit's
    determinant is positive: image y runs down, like the board's Y)."""
    design = np.column_stack([world, np.ones(len(world))])
    coef = np.linalg.lstsq(design, points, rcond=None)[0]
    return bool(np.linalg.det(coef[:2, :2].T) > 0)


def place_partial(
    nodes: I64,
    centres: F64,
    usable: NDArray[np.bool_],
    enlarged: NDArray[np.bool_],
    board: CircleGridBoard,
) -> PartialFit:
    """The placements of lattice `nodes` (M, 2) whose image points are `centres` (M, 2) on
    `board`; `usable` says which nodes' sizes were measured, `enlarged` which of them are
    enlarged (ignored on a board without enlarged dots, where they tell nothing)."""
    grid, shift = pattern_grid(board)
    kinds = board.dot_kinds() > 0
    has_marks = bool(kinds.any())
    size = np.array(grid.shape, dtype=np.int64)
    anchor = np.flatnonzero(usable & enlarged) if has_marks else np.zeros(0, np.intp)
    marks_at = board_pattern(board)[kinds] + shift
    if not has_marks and board.layout == "symmetric":
        ways = _plain_ways(nodes, centres, board)
        if ways != 1:
            return PartialFit([], ways)
    found: list[NDArray[np.intp]] = []
    for m in LATTICE_SYMMETRIES:
        turned = nodes @ m.T
        if not unmirrored(centres, lattice_to_world(board, turned)):
            continue
        low, high = turned.min(axis=0), turned.max(axis=0)
        if anchor.size:
            offsets = marks_at - turned[anchor[0]]
        else:
            xs = np.arange(-low[0], size[0] - high[0])
            ys = np.arange(-low[1], size[1] - high[1])
            if xs.size * ys.size * len(nodes) > MAX_OFFSET_TESTS:
                return PartialFit([], -1)
            offsets = np.array(np.meshgrid(xs, ys, indexing="ij")).reshape(2, -1).T
        # Each offset's cells, a block of offsets at a time (bounded memory).
        block = max(1, MAX_OFFSET_TESTS // (4 * len(nodes)))
        for first in range(0, len(offsets), block):
            cells = turned[None, :, :] + offsets[first : first + block, None, :]
            inside = ((cells >= 0) & (cells < size)).all(axis=(1, 2))
            cells = cells[inside]
            ids = grid[cells[..., 0], cells[..., 1]]
            valid = (ids >= 0).all(axis=1)
            if has_marks:
                valid &= (kinds[ids[:, usable]] == enlarged[usable]).all(axis=1)
            found.extend(row.astype(np.intp) for row in ids[valid])
    if not found:
        return PartialFit([], 0)
    turns = board.reading_symmetries()
    classes: dict[bytes, list[NDArray[np.intp]]] = {}
    for ids in found:
        key = min(turn[ids].tobytes() for turn in turns)
        classes.setdefault(key, []).append(ids)
    if len(classes) != 1:
        return PartialFit([], len(classes))
    (readings,) = classes.values()
    return PartialFit(readings, 1)


def _plain_ways(nodes: I64, centres: F64, board: CircleGridBoard) -> int:
    """The readings of a lattice on a plain symmetric board, counted without trying them:
    every offset that keeps the lattice's box inside the board's rectangle is a placement,
    and each reading is as many placements as the board has turns onto itself."""
    placements = 0
    for m in LATTICE_SYMMETRIES:
        turned = nodes @ m.T
        span = turned.max(axis=0) - turned.min(axis=0)
        fits = (board.cols - span[0]) * (board.rows - span[1])
        inside = span[0] < board.cols and span[1] < board.rows and fits > 0
        if inside and unmirrored(centres, lattice_to_world(board, turned)):
            placements += int(fits)
    return placements // len(board.reading_symmetries())


@dataclasses.dataclass(frozen=True)
class Joined:
    """Blobs that join a partial view: blob indices and the board dot each is."""

    blob: NDArray[np.intp]
    ids: NDArray[np.intp]


class _View:
    """The dots a partial view has found so far (board ids and image points), growing."""

    def __init__(
        self, ids: NDArray[np.intp], centres: F64, diameters: F64, board: CircleGridBoard
    ) -> None:
        self.board = board
        self.grid, self.shift = pattern_grid(board)
        self.kinds = board.dot_kinds() > 0
        self.world_all = board.world_points()
        self.have = np.zeros(board.n_points, dtype=bool)
        self.have[ids] = True
        self.ids: list[int] = list(ids.tolist())
        self.xy: list[F64] = list(centres)
        self.size: list[float] = list(diameters.tolist())
        self.joined_blob: list[int] = []
        self.joined_id: list[int] = []

    def dot_at(self, cell: I64) -> int:
        """The board dot at a lattice cell (board_pattern's coordinates), or -1."""
        cx, cy = cell + self.shift
        if not (0 <= cx < self.grid.shape[0] and 0 <= cy < self.grid.shape[1]):
            return -1
        return int(self.grid[cx, cy])

    def add(self, blob: int, dot: int, xy: F64, size: float) -> None:
        self.have[dot] = True
        self.ids.append(dot)
        self.xy.append(xy)
        self.size.append(size)
        self.joined_blob.append(blob)
        self.joined_id.append(dot)


def join_blobs(
    ids: NDArray[np.intp],
    centres: F64,
    diameters: F64,
    blob_centres: F64,
    blob_diameters: F64,
    taken: NDArray[np.bool_],
    board: CircleGridBoard,
    others: list[Lattice] | None = None,
) -> Joined:
    """The blobs not `taken` that are board dots the view's found dots (`ids` at `centres`,
    blobs `diameters` px across) have not got, each of that dot's kind (enlarged or not, by
    its size against the regular dots around it). A blob's place on the board comes from an
    affine map through the PREDICT_FROM found dots nearest it, and must lie within
    JOIN_STEP_FRACTION of a dot not yet found: the view grows a ring at a time, then across
    gaps of up to FAR_REACH_STEPS. Beyond that (an object across the board), the `others`
    lattices join whole where the homography of the found dots puts them on board dots not
    yet found."""
    view = _View(ids, centres, diameters, board)
    regular = ~view.kinds[ids]
    smallest = 0.5 * float(np.min(diameters[regular])) if regular.any() else 0.0
    free = ~taken & (blob_diameters > smallest)
    for _ in range(board.n_points):
        _grow(view, free, blob_centres, blob_diameters)
        if not _join_lattice(view, free, others or [], blob_centres, blob_diameters):
            break
    return Joined(np.array(view.joined_blob, dtype=np.intp), np.array(view.joined_id, np.intp))


# A blob this much wider than the regular dots around it can be an enlarged dot (the area
# ratio that tells a marker, MARKER_AREA_RATIO in detect.py, as a ratio of diameters), and up
# to REGULAR_AT_MOST a regular one: a blob's size is coarse (its thresholds'); the detector
# sizes the dots from their ink once measured.
ENLARGED_AT_LEAST = 1.35**0.5
REGULAR_AT_MOST = 1.3


def _right_kind(view: _View, dot: int, ratio: float) -> bool:
    """Whether a blob `ratio` times as wide as the regular dots around it can be board dot
    `dot`: an enlarged one, or a regular one (not much smaller)."""
    if view.kinds[dot]:
        return ratio > ENLARGED_AT_LEAST
    return 0.6 < ratio < REGULAR_AT_MOST


def _local_sizes(view: _View, near: NDArray[np.intp]) -> F64:
    """The median diameter of the regular found dots among each row of `near` (indices of
    found dots), px."""
    size = np.asarray(view.size)
    regular = ~view.kinds[np.asarray(view.ids)]
    values = np.where(regular[near], size[near], np.nan)
    out: F64 = np.nanmedian(values, axis=1) if regular.any() else np.nanmedian(size[near], 1)
    return out


def _grow(view: _View, free: NDArray[np.bool_], blob_centres: F64, blob_diameters: F64) -> None:
    """Joins the free blobs near the view's dots, a ring at a time, then across small gaps."""
    reach = NEAR_REACH_STEPS
    for _ in range(view.board.n_points):
        candidates = np.flatnonzero(free)
        if not candidates.size or len(view.ids) < 4:
            return
        xy = np.asarray(view.xy)
        tree = cKDTree(xy)
        step = tree.query(xy, k=2)[0][:, 1]
        k = min(PREDICT_FROM, len(xy))
        dist, near = tree.query(blob_centres[candidates], k=k)
        dist, near = np.atleast_2d(dist), np.atleast_2d(near)
        close = dist[:, 0] <= reach * step[near[:, 0]]
        candidates, near = candidates[close], near[close]
        world = view.world_all[np.asarray(view.ids)]
        with np.errstate(all="ignore"):
            ratio = dict(
                zip(
                    candidates.tolist(),
                    blob_diameters[candidates] / _local_sizes(view, near),
                    strict=True,
                )
            )
        best: dict[int, tuple[float, int]] = {}
        for blob, cell, gap in _placed(candidates, near, xy, world, blob_centres, view.board):
            dot = view.dot_at(cell)
            if dot < 0 or view.have[dot]:
                continue
            if not _right_kind(view, dot, float(ratio[blob])):
                continue
            if dot not in best or gap < best[dot][0]:
                best[dot] = (gap, blob)
        if not best:
            if reach == FAR_REACH_STEPS:
                return
            reach = FAR_REACH_STEPS
            continue
        reach = NEAR_REACH_STEPS
        for dot, (_, blob) in best.items():
            free[blob] = False
            view.add(blob, dot, blob_centres[blob], float(blob_diameters[blob]))


def _join_lattice(
    view: _View,
    free: NDArray[np.bool_],
    others: list[Lattice],
    blob_centres: F64,
    blob_diameters: F64,
) -> bool:
    """Joins the first of the `others` lattices that lies on board dots not yet found, each
    of the right kind; whether one did. The homography of the found dots, extrapolated
    across the gap (a lens bends it), only has to put most of the lattice's dots within half
    a step of their places: the lattice's own steps then say which dot each is (the turn and
    offset most of its dots vote for)."""
    if len(view.ids) < 4:
        return False
    world = view.world_all[np.asarray(view.ids)]
    h, _ = cv2.findHomography(np.asarray(view.xy), world, 0)
    if h is None:
        return False
    for other in others:
        mine = free[other.blob]
        blobs, nodes = other.blob[mine], other.nodes[mine]
        if len(blobs) < 4:
            continue
        mapped = cv2.perspectiveTransform(blob_centres[blobs].reshape(-1, 1, 2), h)
        lattice = world_to_lattice(view.board, np.asarray(mapped, np.float64).reshape(-1, 2))
        if not np.isfinite(lattice).all():
            continue
        cells = np.rint(lattice).astype(np.int64)
        votes: dict[tuple[int, ...], int] = {}
        for k, m in enumerate(LATTICE_SYMMETRIES):
            for o in (cells - nodes @ m.T).tolist():
                key = (k, *o)
                votes[key] = votes.get(key, 0) + 1
        (k, *offset), count = max(votes.items(), key=lambda kv: kv[1])
        if count < 0.6 * len(blobs):
            continue
        placed = nodes @ LATTICE_SYMMETRIES[k].T + np.array(offset)
        dots = [view.dot_at(c) for c in placed]
        if min(dots) < 0 or view.have[dots].any():
            continue
        ratio = blob_diameters[blobs] / _lattice_sizes(nodes, blob_diameters[blobs])
        if not all(_right_kind(view, d, r) for d, r in zip(dots, ratio.tolist(), strict=True)):
            continue
        for dot, blob in zip(dots, blobs.tolist(), strict=True):
            free[blob] = False
            view.add(blob, dot, blob_centres[blob], float(blob_diameters[blob]))
        return True
    return False


def _lattice_sizes(nodes: I64, diameters: F64) -> F64:
    """Each lattice node's reference size: the median diameter of the nodes within two steps
    of it (its own included; an enlarged dot among them does not move a median of many)."""
    out = np.empty(len(nodes))
    for k, node in enumerate(nodes):
        near = np.abs(nodes - node).max(axis=1) <= 2
        out[k] = float(np.median(diameters[near]))
    return out


def _placed(
    candidates: NDArray[np.intp],
    near: NDArray[np.intp],
    xy: F64,
    world: F64,
    blob_centres: F64,
    board: CircleGridBoard,
) -> list[tuple[int, I64, float]]:
    """(blob, lattice cell, distance from it in steps) for each candidate blob that lies
    within JOIN_STEP_FRACTION of a lattice cell, by an affine map through its `near` found
    dots (image `xy`, board `world`)."""
    if not candidates.size:
        return []
    design = np.concatenate([xy[near], np.ones((*near.shape, 1))], axis=2)  # (C, k, 3)
    coef = np.linalg.pinv(design) @ world[near]  # (C, 3, 2)
    at = np.concatenate([blob_centres[candidates], np.ones((len(candidates), 1))], axis=1)
    mm = np.einsum("ci,cij->cj", at, coef)
    lattice = world_to_lattice(board, mm)
    cells = np.rint(lattice).astype(np.int64)
    # The gap in steps between neighbouring dots (the asymmetric lattice's steps are its
    # diagonals, one neighbour distance long).
    gap = np.hypot(*(lattice - cells).T)
    ok = np.flatnonzero(np.isfinite(gap) & (gap < JOIN_STEP_FRACTION))
    return [(int(candidates[i]), cells[i], float(gap[i])) for i in ok]
