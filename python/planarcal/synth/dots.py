"""A board's printed dots on the table: each dot's diameter (enlarged dots applied), board
coordinates placed on the table, and the dots' signed-distance field (:class:`_Dots`).

The dots' boundary is that of the dot whose signed distance is the smallest (exact in
either layout, whatever each dot's size). Dots never overlap but may touch (an origin
marker or an enlarged dot as wide as the distance between neighbours): where two dots come
within a cell of each other the cell's ink is the sum of its coverage by each.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.calib.board import CircleGridBoard
from planarcal.errors import BoardError
from planarcal.synth.point_index import _PointIndex
from planarcal.synth.shapes import _rotation_2d

F64 = NDArray[np.float64]


def _dot_diameters(board: CircleGridBoard, enlarged: Mapping[int, float] | None) -> F64:
    """Each dot's diameter (mm), board order: the board's, with ``enlarged`` applied."""
    diameters = board.dot_diameters()  # BoardError when the board's diameter is unknown
    if enlarged is None:
        return diameters
    if not isinstance(enlarged, Mapping):
        raise BoardError(f"enlarged_dots must map dot indices to diameters, got {enlarged!r}")
    nominal, limit = float(board.dots_mm()), board.neighbour_distance
    for index, value in enlarged.items():
        if isinstance(index, bool) or not isinstance(index, int | np.integer):
            raise BoardError(f"enlarged_dots: {index!r} is not a dot index")
        if not 0 <= index < board.n_points:
            raise BoardError(
                f"enlarged_dots: dot {index} does not exist (the board has {board.n_points})"
            )
        d = arguments.real(f"enlarged_dots[{index}]", value, BoardError)
        if not nominal <= d <= limit:
            raise BoardError(
                f"enlarged_dots[{index}] = {value!r} mm: an enlarged dot must be at least the "
                f"board's dots ({nominal:g} mm) and at most the distance between neighbours "
                f"({limit:g} mm)"
            )
        diameters[int(index)] = d
    return diameters


def _board_to_table(points: F64, origin: tuple[float, float], angle_deg: float) -> F64:
    return np.asarray(points @ _rotation_2d(angle_deg).T + np.array(origin), dtype=np.float64)


class _Dots:
    """A board's dots in board coordinates (mm) and their field: the signed distance to the
    dot whose signed distance is the smallest (not the one with the nearest centre: near a
    larger dot, a smaller neighbour's centre may be nearer), with that dot's outward normal.

    All dots are at least the board's nominal size. The nearest node of the dot lattice, found
    by rounding (exact for equal dots), gives every dot's field at the nominal radius; each
    larger dot (the origin marker, enlarged dots) is then evaluated on its own wherever its
    boundary may lie within ``pad`` of a point, and wins where its signed distance is
    smaller. Farther from it both values exceed ``pad``, so neither the material, the edge
    finding nor any cell's coverage (0) depends on which is kept.

    Dots are disjoint (they may touch), so a cell's ink is the sum of its coverage by each
    dot. Only dots less than 2 ``pad`` apart can both reach a cell within ``pad`` of its
    centre: :meth:`others` gives those dots' fields where they are not the nearest.
    """

    def __init__(self, board: CircleGridBoard, diameters: F64) -> None:
        self.pitch = float(board.pitch)
        self.cols, self.rows = board.cols, board.rows
        self.asymmetric = board.layout == "asymmetric"
        self.radius = float(board.dots_mm()) / 2.0
        pts = board.world_points()
        radii = np.asarray(diameters, dtype=np.float64) / 2.0
        self.larger = [
            (float(pts[k, 0]), float(pts[k, 1]), float(radii[k]))
            for k in np.flatnonzero(radii > self.radius)
        ]
        self.centres, self.radii = pts, radii
        self.gaps = _smallest_gaps(pts, radii)

    def _offset_to_nearest_centre(self, bx: F64, by: F64) -> tuple[F64, F64]:
        """(bx, by) less the nearest dot centre."""
        p = self.pitch
        if not self.asymmetric:
            c = np.clip(np.rint(bx / p), 0, self.cols - 1)
            r = np.clip(np.rint(by / p), 0, self.rows - 1)
            return bx - c * p, by - r * p
        # Dot (c, r) at ((2 c + r % 2) p, r p): the rows alternate between two sets of x.
        # The nearest dot is the nearest in the nearest row or in the nearest row of the
        # other parity (the rows of one parity have the same x: the nearer row wins).
        t = by / p
        r0 = np.clip(np.rint(t), 0, self.rows - 1)
        step = np.where(t >= r0, 1.0, -1.0)
        r1 = r0 + step
        r1 = np.where((r1 < 0) | (r1 > self.rows - 1), r0 - step, r1)
        best: tuple[F64, F64] | None = None
        for r in (r0, r1):
            shift = np.mod(r, 2.0)
            x = (2.0 * np.clip(np.rint((bx / p - shift) / 2.0), 0, self.cols - 1) + shift) * p
            vx, vy = bx - x, by - r * p
            if best is None:
                best = (vx, vy)
            else:
                nearer = np.hypot(vx, vy) < np.hypot(*best)
                best = (np.where(nearer, vx, best[0]), np.where(nearer, vy, best[1]))
        assert best is not None
        return best

    def field(self, bx: F64, by: F64, pad: float) -> tuple[F64, F64, F64]:
        """(sd, nx, ny) in board coordinates (see the class)."""
        vx, vy = self._offset_to_nearest_centre(bx, by)
        rad: F64 | float = self.radius
        if self.larger:
            shape = vx.shape
            vx, vy, bxf, byf = (np.array(a, dtype=np.float64).reshape(-1) for a in (vx, vy, bx, by))
            rad_f = np.full(vx.shape, self.radius)
            points = _PointIndex(bxf, byf)
            for cx, cy, r in self.larger:
                sel = points.near((cx - r, cx + r, cy - r, cy + r), pad)
                if sel.size == 0:
                    continue
                ux, uy = bxf[sel] - cx, byf[sel] - cy
                nearer = np.hypot(ux, uy) - r < np.hypot(vx[sel], vy[sel]) - rad_f[sel]
                sel = sel[nearer]
                vx[sel], vy[sel], rad_f[sel] = ux[nearer], uy[nearer], r
            vx, vy, rad = vx.reshape(shape), vy.reshape(shape), rad_f.reshape(shape)
        d = np.hypot(vx, vy)
        safe = np.where(d > 0.0, d, 1.0)
        return d - rad, np.where(d > 0.0, vx / safe, 1.0), vy / safe

    def others(
        self, bx: F64, by: F64, pad: float, nearest: F64
    ) -> Iterator[tuple[NDArray[np.intp], F64, F64, F64]]:
        """(indices, sd, nx, ny) of each dot that lies within ``pad`` of points (flat) where
        another dot, of signed distance ``nearest``, is the nearest: only dots closer than
        2 pad to a neighbour can."""
        close = np.flatnonzero(self.gaps < 2.0 * pad)
        if close.size == 0:
            return
        points = _PointIndex(bx, by)
        for k in close:
            (cx, cy), r = self.centres[k], float(self.radii[k])
            sel = points.near((cx - r, cx + r, cy - r, cy + r), pad)
            ux, uy = bx[sel] - cx, by[sel] - cy
            d = np.hypot(ux, uy)
            sd = d - r
            keep = (sd < pad) & (sd > nearest[sel])
            d, ux, uy = d[keep], ux[keep], uy[keep]
            safe = np.where(d > 0.0, d, 1.0)
            yield sel[keep], sd[keep], np.where(d > 0.0, ux / safe, 1.0), uy / safe


def _smallest_gaps(centres: F64, radii: F64) -> F64:
    """For each disc, the distance from its edge to the nearest other disc's edge."""
    out = np.empty(len(centres))
    for start in range(0, len(centres), 256):
        part = slice(start, start + 256)
        d = np.linalg.norm(centres[part, None, :] - centres[None], axis=2) - radii[None]
        d[np.arange(d.shape[0]), np.arange(start, start + d.shape[0])] = np.inf
        out[part] = d.min(axis=1) - radii[part]
    return out
