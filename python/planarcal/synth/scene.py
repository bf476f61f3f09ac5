"""What lies where on the table: the materials (table, paper, ink, each object, the walls of
raised objects), which one each point sees and whether a boundary may be near it
(:meth:`_Scene.classify`), and the value of a cell shaded by the exact coverage of each
layer (:meth:`_Scene.shade`). Layers are drawn in order: the paper, the dots, flat objects
(printed marks first), then raised objects, nearest to the camera in front.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board
from planarcal.errors import ArgumentError
from planarcal.synth.dots import _Dots
from planarcal.synth.objects import SceneObject
from planarcal.synth.pattern import _Pattern, _rotated_cell
from planarcal.synth.point_index import _PointIndex
from planarcal.synth.raised import _Raised
from planarcal.synth.shapes import _Circle, _coverage, _Shape

F64 = NDArray[np.float64]


# Material indices of the renderer; objects follow from _FIRST_OBJECT on.
_TABLE, _PAPER, _INK, _FIRST_OBJECT = 0, 1, 2, 3


class _Scene:
    """The geometry of a scene: which material is where on the table."""

    def __init__(
        self,
        board: Board | None,
        origin: tuple[float, float],
        angle_deg: float,
        margin: float,
        objects: Sequence[SceneObject],
        camera_centre: F64 | None = None,
        dot_diameters: F64 | None = None,
    ) -> None:
        # A circle grid is drawn by its dots' field (planarcal.synth.dots); any other board
        # from its printed ink (planarcal.synth.pattern).
        self.pattern: _Pattern | None = None
        if board is not None and not isinstance(board, CircleGridBoard):
            self.pattern = _Pattern(board.ink(), margin)
            board = None
        self.board = board
        self.ox, self.oy = origin
        a = math.radians(angle_deg)
        self.cos, self.sin = math.cos(a), math.sin(a)
        if board is not None:
            diameters = board.dot_diameters() if dot_diameters is None else dot_diameters
            self.dots = _Dots(board, diameters)
            pts = board.world_points()
            big = float(np.max(diameters)) / 2.0
            x0, x1 = float(pts[:, 0].min()) - big - margin, float(pts[:, 0].max()) + big + margin
            y0, y1 = float(pts[:, 1].min()) - big - margin, float(pts[:, 1].max()) + big + margin
            self.paper_mid = (0.5 * (x0 + x1), 0.5 * (y0 + y1))
            self.paper_half = (0.5 * (x1 - x0), 0.5 * (y1 - y0))
        # Flat objects (height 0) are layers on the table, drawn in order; raised ones
        # (_Raised) are drawn over them, nearest to the camera in front.
        self.objects: list[tuple[list[_Shape], list[_Circle]]] = []
        self.object_bbox = []
        self.flat: list[int] = []
        self.raised: list[tuple[int, _Raised]] = []
        self.side = _FIRST_OBJECT + len(objects)  # the walls' material
        for i, o in enumerate(objects):
            outer, holes = o._primitives()
            self.objects.append((outer, holes))
            if o.height_mm > 0:
                if camera_centre is None:  # pragma: no cover - render_scene passes it
                    raise ArgumentError("a raised object needs the camera's position")
                foot, distance = camera_centre[:2], -float(camera_centre[2])
                raised = _Raised(outer, holes, float(o.height_mm), foot, distance)
                self.raised.append((i, raised))
                self.object_bbox.append(raised.bbox)
                continue
            self.flat.append(i)
            boxes = np.array([p.bbox for p in outer])
            self.object_bbox.append(
                (boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max())
            )

    def _board_fields(
        self, x: F64, y: F64, pad: float
    ) -> tuple[tuple[F64, F64, F64], tuple[F64, F64, F64]]:
        """(sd, nx, ny) of the paper and of the dots, in table coordinates; the dots' field is
        exact where a dot's boundary lies within ``pad`` mm (see _Dots.field)."""
        dx, dy = x - self.ox, y - self.oy
        bx = self.cos * dx + self.sin * dy
        by = self.cos * dy - self.sin * dx
        # The paper: a rectangle in board coordinates.
        qx = np.abs(bx - self.paper_mid[0]) - self.paper_half[0]
        qy = np.abs(by - self.paper_mid[1]) - self.paper_half[1]
        along_x = qx >= qy
        sd_p = np.where(along_x, qx, qy)
        nbx = np.where(along_x, np.sign(bx - self.paper_mid[0]), 0.0)
        nby = np.where(along_x, 0.0, np.sign(by - self.paper_mid[1]))
        paper = (sd_p, self.cos * nbx - self.sin * nby, self.sin * nbx + self.cos * nby)
        sd, nbx, nby = self.dots.field(bx, by, pad)
        dots = (sd, self.cos * nbx - self.sin * nby, self.sin * nbx + self.cos * nby)
        return paper, dots

    def _other_dots(
        self, x: F64, y: F64, pad: float, nearest: F64
    ) -> Iterator[tuple[NDArray[np.intp], F64, F64, F64]]:
        """The fields, in table coordinates, of dots near points (flat) other than the
        nearest one (of signed distance ``nearest``): see _Dots.others."""
        dx, dy = x - self.ox, y - self.oy
        bx = self.cos * dx + self.sin * dy
        by = self.cos * dy - self.sin * dx
        for sel, sd, nbx, nby in self.dots.others(bx, by, pad, nearest):
            yield sel, sd, self.cos * nbx - self.sin * nby, self.sin * nbx + self.cos * nby

    def _to_board(self, x: F64, y: F64) -> tuple[F64, F64]:
        """Table points (mm) in board coordinates."""
        dx, dy = x - self.ox, y - self.oy
        return self.cos * dx + self.sin * dy, self.cos * dy - self.sin * dx

    def _shade_pattern(
        self, x: F64, y: F64, cell: tuple[F64, F64, F64, F64], lut: F64, pad: float, out: F64
    ) -> None:
        """Draw a board printed as rectangles into ``out`` (in place, over the table): each
        material by its exact share of the cell, then the circles over them."""
        assert self.pattern is not None
        bx, by = self._to_board(x, y)
        board_cell = _rotated_cell(cell, self.cos, self.sin)
        shares = self.pattern.coverage(bx, by, board_cell)
        out[:] = shares @ lut[:3]
        for sel, material, field in self.pattern.circle_fields(bx, by, pad):
            part = tuple(c[sel] for c in board_cell)
            cov = _coverage(*field, part)  # type: ignore[arg-type]
            out[sel] += (lut[material][None, :] - out[sel]) * cov[:, None]

    def _near_object(self, i: int, points: _PointIndex, pad: float) -> NDArray[np.intp]:
        return points.near(self.object_bbox[i], pad)

    def classify(self, x: F64, y: F64, radius: F64) -> tuple[NDArray[np.int16], NDArray[np.bool_]]:
        """Material index at each table point, and whether a boundary may lie within
        ``radius`` (mm) of it (conservative: it never misses one)."""
        mat = np.zeros(x.shape, dtype=np.int16)
        edge = np.zeros(x.shape, dtype=bool)
        if self.pattern is not None:
            bx, by = self._to_board(x, y)
            page, edge = self.pattern.classify(bx, by, radius)
            mat[:] = page
        if self.board is not None:
            (sd_p, _, _), (sd_d, _, _) = self._board_fields(x, y, float(radius.max()))
            mat[sd_p < 0.0] = _PAPER
            mat[sd_d < 0.0] = _INK
            edge |= (np.abs(sd_p) < radius) | (np.abs(sd_d) < radius)
        pad = float(radius.max())
        points = _PointIndex(x, y) if self.objects else None
        for i in self.flat:
            assert points is not None
            outer, holes = self.objects[i]
            sel = self._near_object(i, points, pad)
            if sel.size == 0:
                continue
            xs, ys, rs = x.ravel()[sel], y.ravel()[sel], radius.ravel()[sel]
            sd_out = outer[0].signed_distance(xs, ys)
            for p in outer[1:]:
                np.minimum(sd_out, p.signed_distance(xs, ys), out=sd_out)
            inside = sd_out < 0.0
            near = np.abs(sd_out) < rs
            for h in holes:
                sd_h = h.signed_distance(xs, ys)
                inside &= sd_h >= 0.0
                near |= np.abs(sd_h) < rs
            mat.ravel()[sel[inside]] = _FIRST_OBJECT + i
            edge.ravel()[sel[near]] = True
        # Raised objects hide what lies under them. Where two may both be hit, which is in
        # front can change within the footprint: such points are edges too.
        reached = np.zeros(x.shape, dtype=np.int32) if len(self.raised) > 1 else None
        for i, raised in self.raised:
            assert points is not None
            sel = self._near_object(i, points, pad)
            if sel.size == 0:
                continue
            xs, ys, rs = x.ravel()[sel], y.ravel()[sel], radius.ravel()[sel]
            hit, top, near, reach = raised.classify(xs, ys, rs)
            mat.ravel()[sel[hit]] = self.side
            mat.ravel()[sel[top]] = _FIRST_OBJECT + i
            edge.ravel()[sel[near]] = True
            if reached is not None:
                reached.ravel()[sel[reach]] += 1
        if reached is not None:
            edge |= reached > 1
        return mat, edge

    def shade(self, x: F64, y: F64, cell: tuple[F64, F64, F64, F64], lut: F64) -> F64:
        """The value (N, channels) of each cell centred at table point (x, y) with footprint
        ``cell`` (see _coverage): each layer's coverage of the cell, composited in order."""
        out = np.repeat(lut[_TABLE][None, :], x.size, axis=0)
        ax, ay, bx, by = cell
        # Beyond pad (mm) from its centre no boundary touches a cell: its coverage is 0 or 1.
        pad = float(np.max(np.abs(ax) + np.abs(bx) + np.abs(ay) + np.abs(by)))
        if self.pattern is not None:
            self._shade_pattern(x, y, cell, lut, pad, out)
        if self.board is not None:
            paper, dots = self._board_fields(x, y, pad)
            cov = _coverage(*paper, cell)
            out += (lut[_PAPER][None, :] - out) * cov[:, None]
            cov = _coverage(*dots, cell)
            # Where dots come close, a cell may reach two: the ink is the sum of both.
            shared = False
            for sel, *field in self._other_dots(x, y, pad, dots[0]):
                part = (ax[sel], ay[sel], bx[sel], by[sel])
                cov[sel] += _coverage(field[0], field[1], field[2], part)
                shared = True
            if shared:
                np.minimum(cov, 1.0, out=cov)
            out += (lut[_INK][None, :] - out) * cov[:, None]
        points = _PointIndex(x, y) if self.objects else None
        for i in self.flat:
            assert points is not None
            outer, holes = self.objects[i]
            sel = self._near_object(i, points, pad)
            if sel.size == 0:
                continue
            xs, ys = x[sel], y[sel]
            part = (ax[sel], ay[sel], bx[sel], by[sel])
            sd, nx, ny = outer[0].field(xs, ys)
            for p in outer[1:]:
                sd2, nx2, ny2 = p.field(xs, ys)
                closer = sd2 < sd
                sd, nx, ny = (
                    np.where(closer, a2, a1) for a1, a2 in ((sd, sd2), (nx, nx2), (ny, ny2))
                )
            cov = _coverage(sd, nx, ny, part)
            for h in holes:
                cov = cov * (1.0 - _coverage(*h.field(xs, ys), part))
            out[sel] += (lut[_FIRST_OBJECT + i][None, :] - out[sel]) * cov[:, None]
        if self.raised:
            assert points is not None
            self._shade_raised(x, y, cell, lut, pad, out, points)
        return out

    def _shade_raised(
        self,
        x: F64,
        y: F64,
        cell: tuple[F64, F64, F64, F64],
        lut: F64,
        pad: float,
        out: F64,
        points: _PointIndex,
    ) -> None:
        """Draw the raised objects over ``out`` (in place): each cell gets the wall's tone
        over the fraction of its footprint whose rays meet the object and the top's tone over
        the fraction that meets the top (a part of it). Where two raised objects both cover
        part of a cell they are drawn in the order of the heights at which the ray through
        the cell's centre meets them (the nearer to the camera in front)."""
        ax, ay, bx, by = cell
        side = lut[self.side][None, :]
        layers: list[tuple[int, NDArray[np.intp], F64, F64]] = []
        count = np.zeros(x.shape, dtype=np.int32) if len(self.raised) > 1 else None
        for k, (i, raised) in enumerate(self.raised):
            sel = self._near_object(i, points, pad)
            if sel.size == 0:
                continue
            part = (ax[sel], ay[sel], bx[sel], by[sel])
            hit, top = raised.fields(x[sel], y[sel])
            c_hit = _coverage(*hit, part)
            c_top = np.minimum(_coverage(*top, part), c_hit)
            layers.append((k, sel, c_hit, c_top))
            if count is not None:
                count[sel[c_hit > 0.0]] += 1

        def draw(o: F64, top: F64, c_hit: F64, c_top: F64) -> F64:
            """o under an object: the wall over c_hit of each cell, its top (a part of
            that) over c_top: o (1 - c_hit) + side (c_hit - c_top) + top c_top."""
            o = o + (side - o) * c_hit[:, None]
            return np.asarray(o + (top - side) * c_top[:, None], dtype=np.float64)

        def tone(k: int) -> F64:
            return np.asarray(lut[_FIRST_OBJECT + self.raised[k][0]][None, :], np.float64)

        shared = np.flatnonzero(count > 1) if count is not None else np.zeros(0, np.intp)
        if shared.size == 0:
            for k, sel, c_hit, c_top in layers:
                out[sel] = draw(out[sel], tone(k), c_hit, c_top)
            return
        # Cells that several raised objects cover in part: painter's order in each, by the
        # height at which the ray through the cell's centre meets each object.
        slot = np.full(x.shape, -1, dtype=np.intp)
        slot[shared] = np.arange(shared.size)
        depth = np.full((len(layers), shared.size), -np.inf)
        hits = np.zeros((len(layers), shared.size))
        tops = np.zeros((len(layers), shared.size))
        for m, (k, sel, c_hit, c_top) in enumerate(layers):
            at = slot[sel]
            alone = at < 0
            out[sel[alone]] = draw(out[sel[alone]], tone(k), c_hit[alone], c_top[alone])
            mine, at = sel[~alone], at[~alone]
            depth[m, at] = self.raised[k][1].entry_height(x[mine], y[mine])
            hits[m, at], tops[m, at] = c_hit[~alone], c_top[~alone]
        order = np.argsort(depth, axis=0, kind="stable")  # ties: the later object in front
        tones = np.concatenate([tone(k) for k, *_ in layers])
        cols = np.arange(shared.size)
        o = out[shared]
        for m in order:
            o = draw(o, tones[m], hits[m, cols], tops[m, cols])
        out[shared] = o
