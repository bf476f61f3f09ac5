"""A board printed as rectangles (a chessboard's squares, a ChArUco board's squares and marker
cells) on its paper, as exact regions of the table: :class:`_Pattern`.

The page is cut into *atoms*: the cells of the grid whose lines are every x and every y at
which a rectangle or the paper has an edge. Each atom is wholly table, paper or ink, so the
page is a small table of materials (a few thousand atoms for a large ChArUco board) and:

* the material at a point is one binary search per axis;
* whether a boundary may lie within r of a point is whether the atoms of the box of half-side
  r about it are all of one material (summed-area tables: exact, conservative for a disc);
* a renderer's cell (a parallelogram, see :func:`planarcal.synth.shapes._coverage`) is
  covered by each material by the sum of the exact areas of its intersections with the
  atoms it meets: each atom's share is four values of the area of the cell below and left
  of an atom corner (a quadrant), a trapezoid formula where the corner lies outside the
  cell's bounding box and an exact polygon clip where it lies inside.

So squares that touch at a corner (a chessboard's X-junctions) and rectangles that share an
edge (a marker's cells) are shaded by exact areas, with no seam and no bias at the corner.
The board's circles (a chessboard's origin-marker dots, black or white) are drawn over the
rectangles with the dots' straight-boundary coverage (:mod:`planarcal.synth.dots`).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.board_ink import BoardInk
from planarcal.synth.shapes import _Circle, _coverage

F64 = NDArray[np.float64]
I64 = NDArray[np.intp]

# Materials of the page (the renderer's indices, see planarcal.synth.scene).
_TABLE, _PAPER, _INK = 0, 1, 2


class _Pattern:
    """A board's page in board coordinates (mm): the paper reaching ``margin`` beyond the
    ink's field, the black rectangles on it, then the circles (black: ink, white: paper)."""

    def __init__(self, ink: BoardInk, margin: float) -> None:
        fx0, fy0, fx1, fy1 = (float(v) for v in ink.field)
        self.paper = (fx0 - margin, fy0 - margin, fx1 + margin, fy1 + margin)
        rects = np.asarray(ink.rects, np.float64).reshape(-1, 4)
        px0, py0, px1, py1 = self.paper
        # Edges closer than rounding (a rectangle's end computed apart from its neighbour's
        # start) are one line: no atom a hair wide between rectangles that meet.
        tol = 1e-9 * (1.0 + max(abs(v) for v in self.paper))
        self.xs = _merged(np.concatenate([rects[:, 0], rects[:, 2], [px0, px1]]), tol)
        self.ys = _merged(np.concatenate([rects[:, 1], rects[:, 3], [py0, py1]]), tol)
        # Atom (j, i) spans xs[i - 1]..xs[i] by ys[j - 1]..ys[j]; index 0 and the last are
        # the table beyond the page on each side (an index is searchsorted(..., "right")).
        grid = np.full((len(self.ys) + 1, len(self.xs) + 1), _TABLE, dtype=np.int8)

        def line(edges: F64, values: F64 | list[float]) -> I64:
            """The atom index just past each edge value (its merged line's)."""
            return np.searchsorted(edges, np.asarray(values) - tol).astype(np.intp) + 1

        i0, i1 = line(self.xs, [px0, px1])
        j0, j1 = line(self.ys, [py0, py1])
        grid[j0:j1, i0:i1] = _PAPER
        ri0, ri1 = line(self.xs, rects[:, 0]), line(self.xs, rects[:, 2])
        rj0, rj1 = line(self.ys, rects[:, 1]), line(self.ys, rects[:, 3])
        for a, b, c, d in zip(rj0, rj1, ri0, ri1, strict=True):
            grid[a:b, c:d] = _INK
        self.grid = grid
        # Summed-area tables of each material's atoms: table[m][j, i] counts atoms of
        # material m in rows < j and columns < i.
        self.counts = [
            np.pad((grid == m).astype(np.int32).cumsum(0).cumsum(1), ((1, 0), (1, 0)))
            for m in (_TABLE, _PAPER, _INK)
        ]
        # Atom edges with the table's half-planes beyond the page.
        self.x_edges = np.concatenate([[-np.inf], self.xs, [np.inf]])
        self.y_edges = np.concatenate([[-np.inf], self.ys, [np.inf]])
        circles = np.asarray(ink.circles, np.float64).reshape(-1, 4)
        self.circles = [
            (_Circle(c[:2], float(c[2])), _INK if c[3] >= 0.5 else _PAPER) for c in circles
        ]

    def _atoms(self, x: F64, y: F64) -> tuple[I64, I64]:
        return np.searchsorted(self.xs, x, side="right"), np.searchsorted(self.ys, y, side="right")

    def classify(self, x: F64, y: F64, radius: F64) -> tuple[NDArray[np.int8], NDArray[np.bool_]]:
        """The material at each board point (table, paper or ink; circles included) and
        whether a boundary may lie within ``radius`` of it (conservative)."""
        shape = x.shape
        x, y, radius = (np.asarray(v, np.float64).reshape(-1) for v in (x, y, radius))
        i_lo, j_lo = self._atoms(x - radius, y - radius)
        i_hi, j_hi = self._atoms(x + radius, y + radius)
        mat = self.grid[j_lo, i_lo]
        edge = np.zeros(x.shape, dtype=bool)
        # Points whose box meets several atoms: the material at the point itself, and an
        # edge unless every atom of the box is of that material.
        k = np.flatnonzero((i_lo != i_hi) | (j_lo != j_hi))
        if k.size:
            i_lo, i_hi, j_lo, j_hi = i_lo[k], i_hi[k], j_lo[k], j_hi[k]
            i, j = self._atoms(x[k], y[k])
            here = self.grid[j, i]
            table = self.counts
            same = np.zeros(k.size, dtype=np.int64)
            for m in (_TABLE, _PAPER, _INK):
                t = table[m]
                n = t[j_hi + 1, i_hi + 1] - t[j_lo, i_hi + 1] - t[j_hi + 1, i_lo] + t[j_lo, i_lo]
                same = np.where(here == m, n, same)
            mat[k] = here
            edge[k] = same < (i_hi - i_lo + 1) * (j_hi - j_lo + 1)
        for circle, material in self.circles:
            sd = circle.signed_distance(x, y)
            mat[sd < 0.0] = material
            edge |= np.abs(sd) < radius
        return mat.reshape(shape), edge.reshape(shape)

    def coverage(self, x: F64, y: F64, cell: tuple[F64, F64, F64, F64]) -> F64:
        """(N, 3): the exact fraction of each cell (centre (x, y), footprint spanned by the
        cell's vectors, all in board mm) that the table, the paper and the ink cover, before
        the circles."""
        ax, ay, bx, by = cell
        hx = 0.5 * (np.abs(ax) + np.abs(bx))
        hy = 0.5 * (np.abs(ay) + np.abs(by))
        i_lo, j_lo = self._atoms(x - hx, y - hy)
        i_hi, j_hi = self._atoms(x + hx, y + hy)
        out = np.zeros((x.size, 3))
        alone = (i_lo == i_hi) & (j_lo == j_hi)
        out[alone, self.grid[j_lo[alone], i_lo[alone]]] = 1.0
        mixed = np.flatnonzero(~alone)
        if mixed.size == 0:
            return out
        i_lo, i_hi, j_lo, j_hi = i_lo[mixed], i_hi[mixed], j_lo[mixed], j_hi[mixed]
        xm, ym = x[mixed], y[mixed]
        cm = tuple(v[mixed] for v in cell)
        for di in range(int((i_hi - i_lo).max()) + 1):
            for dj in range(int((j_hi - j_lo).max()) + 1):
                sel = np.flatnonzero((i_lo + di <= i_hi) & (j_lo + dj <= j_hi))
                i, j = i_lo[sel] + di, j_lo[sel] + dj
                quadrant = _Quadrants(xm[sel], ym[sel], tuple(v[sel] for v in cm))  # type: ignore[arg-type]
                x0, x1 = self.x_edges[i], self.x_edges[i + 1]
                y0, y1 = self.y_edges[j], self.y_edges[j + 1]
                share = (
                    quadrant.area(x1, y1)
                    - quadrant.area(x0, y1)
                    - quadrant.area(x1, y0)
                    + quadrant.area(x0, y0)
                )
                np.add.at(out, (mixed[sel], self.grid[j, i]), share)
        return out

    def circle_fields(
        self, x: F64, y: F64, pad: float
    ) -> Iterator[tuple[I64, int, tuple[F64, F64, F64]]]:
        """(indices, material, (sd, nx, ny)) of each circle, in board coordinates, at the
        points within ``pad`` of its bounding box (in drawing order)."""
        for circle, material in self.circles:
            x0, x1, y0, y1 = circle.bbox
            near_x = (x >= x0 - pad) & (x <= x1 + pad)
            sel = np.flatnonzero(near_x & (y >= y0 - pad) & (y <= y1 + pad))
            if sel.size:
                yield sel, material, circle.field(x[sel], y[sel])


def _merged(values: F64, tol: float) -> F64:
    """The distinct values, sorted, those within ``tol`` of the previous one dropped."""
    v = np.unique(values)
    keep = np.concatenate([[True], np.diff(v) > tol])
    return np.asarray(v[keep], np.float64)


class _Quadrants:
    """The exact fraction of each cell (a parallelogram) lying in a quadrant x < a, y < b."""

    def __init__(self, x: F64, y: F64, cell: tuple[F64, F64, F64, F64]) -> None:
        self.x, self.y, self.cell = x, y, cell
        ax, ay, bx, by = cell
        self.hx = 0.5 * (np.abs(ax) + np.abs(bx))
        self.hy = 0.5 * (np.abs(ay) + np.abs(by))

    def area(self, a: F64, b: F64) -> F64:
        """Fraction of each cell with x < a and y < b (a, b may be infinite)."""
        hx, hy, cell = self.hx, self.hy, self.cell
        with np.errstate(invalid="ignore"):
            u, v = a - self.x, b - self.y  # the corner relative to the cell's centre
        out = np.zeros(u.size)
        left, below = u >= hx, v >= hy
        inside_x, inside_y = (u > -hx) & ~left, (v > -hy) & ~below
        out[left & below] = 1.0
        zeros, ones = np.zeros(u.size), np.ones(u.size)
        # The corner beyond the cell along x (or y): a straight boundary across it.
        k = np.flatnonzero(left & inside_y)
        if k.size:
            part = tuple(c[k] for c in cell)
            out[k] = _coverage(-v[k], zeros[k], ones[k], part)  # type: ignore[arg-type]
        k = np.flatnonzero(below & inside_x)
        if k.size:
            part = tuple(c[k] for c in cell)
            out[k] = _coverage(-u[k], ones[k], zeros[k], part)  # type: ignore[arg-type]
        k = np.flatnonzero(inside_x & inside_y)
        if k.size:
            out[k] = _quadrant_clip(u[k], v[k], tuple(c[k] for c in cell))  # type: ignore[arg-type]
        return out


def _quadrant_clip(u: F64, v: F64, cell: tuple[F64, F64, F64, F64]) -> F64:
    """Fraction of the parallelogram centred at 0 and spanned by the cell's vectors that
    lies in x < u, y < v: the parallelogram clipped by each half-plane in turn, its area by
    the shoelace formula. A clip keeps a fixed number of vertices: each vertex beyond the
    line is moved onto it (which only adds segments along the line, of no area) and each
    edge that crosses the line gains the crossing point."""
    ax, ay, bx, by = cell
    px = 0.5 * np.column_stack([-ax - bx, ax - bx, ax + bx, bx - ax])
    py = 0.5 * np.column_stack([-ay - by, ay - by, ay + by, by - ay])
    px, py = _clip(px, py, u)
    py, px = _clip(py, px, v)
    area = 0.5 * np.sum(px * np.roll(py, -1, axis=1) - np.roll(px, -1, axis=1) * py, axis=1)
    det = ax * by - ay * bx
    return np.asarray(np.clip(area / det, 0.0, 1.0), np.float64)


def _clip(p: F64, q: F64, limit: F64) -> tuple[F64, F64]:
    """Polygons (rows of vertices, coordinates p along the clip's axis and q across) clipped
    to p <= limit, with twice the vertices (see _quadrant_clip)."""
    lim = limit[:, None]
    pn, qn = np.roll(p, -1, axis=1), np.roll(q, -1, axis=1)
    crossing = (p - lim) * (pn - lim) < 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(crossing, (lim - p) / np.where(crossing, pn - p, 1.0), 0.0)
    kept = np.minimum(p, lim)
    cross_p = np.where(crossing, np.broadcast_to(lim, p.shape), kept)
    cross_q = np.where(crossing, q + t * (qn - q), q)
    out_p = np.stack([kept, cross_p], axis=2).reshape(p.shape[0], -1)
    out_q = np.stack([q, cross_q], axis=2).reshape(p.shape[0], -1)
    return out_p, out_q


def _rotated_cell(
    cell: tuple[F64, F64, F64, F64], cos: float, sin: float
) -> tuple[F64, F64, F64, F64]:
    """A cell's vectors turned from table into board coordinates."""
    ax, ay, bx, by = cell
    return (cos * ax + sin * ay, cos * ay - sin * ax, cos * bx + sin * by, cos * by - sin * bx)
