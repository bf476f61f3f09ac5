"""Putting a board's grid together from blob centres: lattices grown from seeds, then the
board's dot pattern placed on them.

A board's dots sit on a lattice: every dot's neighbours are one step away along two
directions, and a step changes slowly across the image (perspective and lens distortion bend
the lattice, they do not break it). So the grid is grown, not guessed: from a seed blob whose
neighbours form a lattice cell, each known node predicts its four neighbours by continuing the
step that reached it, and the blob nearest each prediction joins if it is close (within a
third of a step) and of a dot's size. Blobs of another size or off the lattice (printed
numbers, arrows, the board's edge, texture) never join; enlarged dots (an origin marker, the
fiducials of a metal plate) do, since only their centre has to fit. Each blob joins at most
one lattice, so the search is linear in the number of blobs, whatever the clutter.

The board is then found as a placement of its own dot pattern (in lattice steps: a
rectangle for the symmetric layout, a checkerboard half for the asymmetric one, whose nearest
neighbours are diagonal) on the lattice's nodes under one of the eight turns and mirrors of a
square lattice. Which reading of the board is the right one is decided later (detect.py).
"""

from __future__ import annotations

import dataclasses
from collections import deque

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planarcal.calib.blobs import Blobs
from planarcal.calib.board import CircleGridBoard

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

# A predicted node takes the nearest blob within this fraction of the local step.
ACCEPT_STEP_FRACTION = 1.0 / 3.0
# A blob joins a lattice when its diameter is at least this fraction of the lattice's median
# (printed marks are smaller than dots) and at most this fraction of the step (a dot is never
# wider than the distance to its neighbours: an enlarged dot can be six times a small one).
MIN_SIZE_OF_MEDIAN = 0.5
MAX_SIZE_OF_STEP = 1.15
# Neighbours considered per blob (a lattice cell's 8 and room for clutter between them).
K_NEIGHBOURS = 16
# At most this many seeds are grown per image: the search stays bounded on any clutter.
MAX_SEEDS = 400


@dataclasses.dataclass(frozen=True)
class Lattice:
    """Blobs on a lattice: node (i, j) of ``nodes[k]`` is blob ``blob[k]``."""

    nodes: I64
    """(M, 2) integer lattice coordinates."""
    blob: NDArray[np.intp]
    """(M,) indices into the Blobs the lattice was grown on."""


@dataclasses.dataclass(frozen=True)
class Placement:
    """The board's dots found on a lattice: dot k of the board is blob ``blob[k]``."""

    blob: NDArray[np.intp]
    """(n,) blob index of each board dot; -1 where the dot is missing."""
    nodes: I64
    """(n, 2) lattice node of each board dot."""


def board_pattern(board: CircleGridBoard) -> I64:
    """The board's dots in lattice steps, (rows * cols, 2), in board order: (c, r) for the
    symmetric layout; for the asymmetric one, whose lattice runs along the diagonals, the
    diagonal coordinates ((x + y) / 2, (x - y) / 2) of dot (x, y) = (2 c + r % 2, r)."""
    r, c = np.divmod(np.arange(board.n_points, dtype=np.int64), board.cols)
    if board.layout == "asymmetric":
        x = 2 * c + r % 2
        return np.column_stack([(x + r) // 2, (x - r) // 2])
    return np.column_stack([c, r])


def lattice_to_world(board: CircleGridBoard, nodes: I64) -> F64:
    """World positions (mm) of lattice nodes in the coordinates of board_pattern."""
    a, b = nodes[:, 0].astype(np.float64), nodes[:, 1].astype(np.float64)
    if board.layout == "asymmetric":
        a, b = a + b, a - b
    return np.column_stack([a, b]) * float(board.pitch)


def outer_ring(board: CircleGridBoard) -> I64:
    """The lattice nodes one step outside the board's pattern (where a larger board's next
    dots would be), in the coordinates of board_pattern."""
    pattern = board_pattern(board)
    inside = {tuple(p) for p in pattern.tolist()}
    ring = {
        (p[0] + di, p[1] + dj)
        for p in pattern.tolist()
        for di, dj in _STEPS
        if (p[0] + di, p[1] + dj) not in inside
    }
    return np.array(sorted(ring), dtype=np.int64)


def neighbours(centres: F64, k: int = K_NEIGHBOURS) -> tuple[NDArray[np.intp], F64]:
    """The k nearest other blobs of each blob, nearest first: indices (N, k') and distances
    (N, k'), k' = min(k, N - 1)."""
    k = min(k, len(centres) - 1)
    dist, index = cKDTree(centres).query(centres, k=k + 1)
    # The nearest of each is itself (or a blob at the very same place: drop column 0 all the
    # same, one of the two is then the other's neighbour).
    return np.asarray(index[:, 1:], dtype=np.intp), np.asarray(dist[:, 1:], dtype=np.float64)


def grow_lattices(blobs: Blobs, min_nodes: int, max_nodes: int) -> list[Lattice]:
    """Lattices of at least `min_nodes` blobs, largest first, each blob in at most one; a
    lattice stops growing at `max_nodes` (it is then larger than any board looked for)."""
    n = len(blobs)
    if n < max(min_nodes, 4):
        return []
    xy, size = blobs.centres, blobs.diameters
    near, _ = neighbours(xy)
    used = np.zeros(n, dtype=bool)
    found: list[Lattice] = []
    for seed, u, v in _seeds(xy, size, near)[:MAX_SEEDS]:
        if used[seed]:
            continue
        lattice = _grow(seed, u, v, xy, size, near, used, max_nodes)
        if lattice is None:
            continue
        used[lattice.blob] = True
        if len(lattice.blob) >= min_nodes:
            found.append(lattice)
    found.sort(key=lambda lat: -len(lat.blob))
    return found


def _seeds(xy: F64, size: F64, near: NDArray[np.intp]) -> list[tuple[int, F64, F64]]:
    """(blob, step u, step v) for every blob whose neighbours form a lattice cell around it,
    best first: most of the eight cell neighbours found, then the most uniform in size.
    u is the nearest neighbour of about the same size, v the next one at 60 to 120 degrees to
    it and of about the same length."""
    n, k = near.shape
    k8 = min(8, k)
    ring = near[:, :k8]
    ratio = size[ring] / size[:, None]
    similar = (ratio > 0.6) & (ratio < 1.6)
    vec = xy[ring] - xy[:, None, :]  # (n, k8, 2)
    length = np.hypot(vec[..., 0], vec[..., 1])
    first = np.argmax(similar, axis=1)
    has_u = similar.any(axis=1)
    rows = np.arange(n)
    u = vec[rows, first]
    lu = length[rows, first]
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = (vec @ u[:, :, None])[..., 0] / (length * lu[:, None])
        rel = length / lu[:, None]
    ok_v = similar & (np.abs(cos) < 0.5) & (rel > 0.5) & (rel < 2.0)
    second = np.argmax(ok_v, axis=1)
    has = has_u & ok_v.any(axis=1)
    v = vec[rows, second]
    lv = length[rows, second]
    # How many of the eight cell neighbours (+-u, +-v, +-u+-v) are blobs.
    tol = ACCEPT_STEP_FRACTION * np.minimum(lu, lv)
    offsets = np.array([(a, b) for a in (-1, 0, 1) for b in (-1, 0, 1) if (a, b) != (0, 0)])
    cell = offsets[None, :, 0, None] * u[:, None, :] + offsets[None, :, 1, None] * v[:, None, :]
    around = xy[near] - xy[:, None, :]  # (n, k, 2)
    gap = np.hypot(*(cell[:, :, None, :] - around[:, None, :, :]).transpose(3, 0, 1, 2))
    hits = (gap.min(axis=2) < tol[:, None]).sum(axis=1)
    spread = np.std(np.log(ratio), axis=1)
    score = np.where(has & (hits >= 3), hits - spread, -np.inf)
    order = np.argsort(-score, kind="stable")
    order = order[np.isfinite(score[order])]
    return [(int(i), u[i], v[i]) for i in order]


_STEPS = ((1, 0), (-1, 0), (0, 1), (0, -1))


def _grow(
    seed: int,
    u: F64,
    v: F64,
    xy: F64,
    size: F64,
    near: NDArray[np.intp],
    used: NDArray[np.bool_],
    max_nodes: int,
) -> Lattice | None:
    """The lattice grown from `seed` with first steps u (along i) and v (along j)."""
    at: dict[tuple[int, int], int] = {(0, 0): seed}
    taken = {seed}
    # The step that reached each node, per axis: continued to predict the next node.
    step: dict[tuple[int, int], tuple[F64, F64]] = {(0, 0): (u, v)}
    # The dots' size: the seed cell's (printed marks are smaller, enlarged dots larger).
    cell = near[seed, :8]
    smallest = MIN_SIZE_OF_MEDIAN * float(np.median(np.append(size[cell], size[seed])))
    queue: deque[tuple[int, int]] = deque([(0, 0)])
    while queue and len(at) < max_nodes:
        node = queue.popleft()
        here = at[node]
        su, sv = step[node]
        cand = near[here]
        for di, dj in _STEPS:
            nxt = (node[0] + di, node[1] + dj)
            if nxt in at:
                continue
            back = (node[0] - di, node[1] - dj)
            # Continue the step that reached this node, or the cell's first steps.
            delta = xy[here] - xy[at[back]] if back in at else di * su + dj * sv
            predicted = xy[here] + delta
            stride = float(np.hypot(delta[0], delta[1]))
            reach = ACCEPT_STEP_FRACTION * stride
            d = np.hypot(*(xy[cand] - predicted).T)
            for j in np.argsort(d):
                if d[j] >= reach:
                    break
                b = int(cand[j])
                if b in taken or used[b]:
                    continue
                if not smallest <= size[b] <= MAX_SIZE_OF_STEP * stride:
                    continue
                at[nxt] = b
                taken.add(b)
                new_step = xy[b] - xy[here]
                if di:
                    step[nxt] = (di * new_step, sv)
                else:
                    step[nxt] = (su, dj * new_step)
                queue.append(nxt)
                break
    if len(at) < 4:
        return None
    nodes = np.array(list(at.keys()), dtype=np.int64)
    blob = np.array(list(at.values()), dtype=np.intp)
    return Lattice(nodes - nodes.min(axis=0), blob)


# The eight turns and mirrors of a square lattice, as integer 2 x 2 matrices.
LATTICE_SYMMETRIES = tuple(
    np.array(m, dtype=np.int64)
    for m in (
        [[1, 0], [0, 1]],
        [[0, -1], [1, 0]],
        [[-1, 0], [0, -1]],
        [[0, 1], [-1, 0]],
        [[-1, 0], [0, 1]],
        [[1, 0], [0, -1]],
        [[0, 1], [1, 0]],
        [[0, -1], [-1, 0]],
    )
)


def place_board(lattice: Lattice, board: CircleGridBoard) -> list[Placement]:
    """The placements of the board's dot pattern on the lattice's nodes with the fewest
    missing dots (at most max_holes(board): a dot hidden by a mark or glare is filled in by
    its neighbours and must then be measured), one per distinct set of nodes (the board's
    own symmetries give the same set several times; detect.py chooses the reading). Two
    are enough to know the board is not this lattice: the search stops there."""
    pattern = board_pattern(board)
    width, height = (lattice.nodes.max(axis=0) + 1).tolist()
    occupied = np.full((width, height), -1, dtype=np.intp)
    occupied[lattice.nodes[:, 0], lattice.nodes[:, 1]] = np.arange(len(lattice.nodes))
    allowed = max_holes(board)
    seen: set[bytes] = set()
    out: list[tuple[int, Placement]] = []
    for m in LATTICE_SYMMETRIES:
        turned = pattern @ m.T
        turned -= turned.min(axis=0)
        span = turned.max(axis=0)
        if span[0] >= width or span[1] >= height:
            continue
        for ox in range(width - int(span[0])):
            for oy in range(height - int(span[1])):
                nodes = turned + np.array([ox, oy])
                at = occupied[nodes[:, 0], nodes[:, 1]]
                holes = int((at < 0).sum())
                if holes > allowed:
                    continue
                if sum(1 for h, _ in out if h == 0) >= 2 and holes:
                    continue
                key = np.sort(nodes[:, 0] * height + nodes[:, 1]).tobytes()
                if key in seen:
                    continue
                seen.add(key)
                blob = np.where(at >= 0, lattice.blob[np.maximum(at, 0)], -1)
                out.append(
                    (
                        holes,
                        Placement(
                            blob=blob,
                            nodes=nodes,
                        ),
                    )
                )
                if sum(1 for h, _ in out if h == 0) >= 2:
                    return [p for h, p in out if h == 0]
    if not out:
        return []
    fewest = min(h for h, _ in out)
    return [p for h, p in out if h == fewest]


def max_holes(board: CircleGridBoard) -> int:
    """Missing dots a placement may have: one in fifty (one on small boards)."""
    return max(1, board.n_points // 50) if board.n_points >= 12 else 0


def fill_holes(placement: Placement, centres: F64) -> F64:
    """The placement's dot positions (n, 2) px: its blobs' centres, and for each missing dot
    the position a homography through the nearest found dots (in lattice steps) predicts."""
    blob = placement.blob
    found = blob >= 0
    points = np.zeros((len(blob), 2))
    points[found] = centres[blob[found]]
    known = placement.nodes[found].astype(np.float64)
    for k in np.flatnonzero(~found):
        d = np.abs(known - placement.nodes[k]).max(axis=1)
        near = np.argsort(d, kind="stable")[:12]
        h, _ = cv2.findHomography(known[near], points[found][near], 0)
        if h is None:
            points[k] = np.nan
            continue
        q = h @ np.array([*placement.nodes[k].astype(np.float64), 1.0])
        points[k] = q[:2] / q[2]
    return points


def lattice_extent(lattice: Lattice, centres: F64) -> tuple[int, int]:
    """(across, down): the lattice's size in dots along the image's rows and columns, counting
    the lines of nodes that are at least 80 % full (what a user's board looks like when its
    size was given wrongly)."""
    width, height = (lattice.nodes.max(axis=0) + 1).tolist()
    occupied = np.zeros((width, height), dtype=bool)
    occupied[lattice.nodes[:, 0], lattice.nodes[:, 1]] = True
    per_i = occupied.sum(axis=1)
    per_j = occupied.sum(axis=0)
    along_i = int((per_i >= 0.8 * per_i.max()).sum())
    along_j = int((per_j >= 0.8 * per_j.max()).sum())
    # Which lattice axis runs across the image: the mean step between nodes one apart in i.
    index = {tuple(n): k for k, n in enumerate(lattice.nodes.tolist())}
    steps = [
        centres[lattice.blob[index[(i + 1, j)]]] - centres[lattice.blob[k]]
        for k, (i, j) in enumerate(lattice.nodes.tolist())
        if (i + 1, j) in index
    ]
    if steps:
        dx, dy = np.abs(np.array(steps)).mean(axis=0)
        if dy > dx:
            return along_j, along_i
    return along_i, along_j
