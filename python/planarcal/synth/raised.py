"""Objects with height (right prisms on the table), as regions of the table plane.

Objects with height are rendered just as exactly as flat ones, in the same table-plane
terms. With the camera centre D mm above the table, over the table point F (its foot), the
ray that meets the table at P crosses the plane of a top at height h at P + (h / D) (F - P).
So the rays that meet the top inside the silhouette S are those whose table point lies in S
scaled by 1 / (1 - h / D) about F; and those that meet the object at all (its top or a wall)
are those whose segment between the two planes meets S: for each convex part, the convex
hull of the part and its scaled copy (a polygon, or the hull of two discs), less the rays
that go through a hole at both heights (the through-hole's two discs). Both regions have
exact signed distances, so edge pixels are found and their cells shaded as for flat
objects: the object's top grey (``grey`` or ``metal_grey``) over the top's region, the
walls' tone ``side_grey`` over the rest of the object's (default 0.6 x ``table_grey``:
upright metal faces, lit at grazing angles under overhead light, look darker than the
bench). The walls that show are those facing the camera: in the image they lie between the
outline of the object's base and that of its top, on the side towards the camera's nadir
(the image of F); on the far side the top overhangs the base and hides the table, the paper
and the dots there. Inside a nut's or washer's hole the far inner wall shows, and the table
beyond it. A raised object hides everything flat (the board, flat objects). Where raised
objects overlap in the image, the one that the ray meets first (nearest to the camera) is
in front; a cell crossed by the boundary between two of them takes, for the whole cell, the
order that holds at its centre: that occlusion boundary alone is point-sampled at n x n
rather than area-weighted, the one approximation heights add (corners where two outlines
meet are approximated as for polygons). Walls have one tone whatever their direction (no
shading, no shadows, no reflections).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planarcal.errors import ArgumentError
from planarcal.synth.shapes import (
    _Circle,
    _complement,
    _convex_hull,
    _ConvexPolygon,
    _DiscHull,
    _Field,
    _intersection,
    _line_interval,
    _Primitive,
    _Shape,
    _union,
)

F64 = NDArray[np.float64]


class _Raised:
    """An object of height h > 0 seen from a camera whose centre is ``distance`` (D) above
    the table at ``foot`` (table X, Y), as regions of the table plane: a ray that meets the
    table at P crosses the top's plane Z = -h at P + (h / D) (foot - P), so

    * it meets the top inside the silhouette S when P lies in S scaled by 1 / (1 - h / D)
      about ``foot`` (``top``: each part and hole so scaled);
    * it meets the solid at all (top or wall) when its segment between the two planes meets
      S: for a convex part K that is the convex hull of K and its scaled copy (``hull``),
      less, for a hole H (inside K, a through-hole), the rays that pass through the hole at
      both planes (H and its scaled copy, both convex, so the whole segment is in the hole).

    Every region is a union, intersection or difference of discs, convex polygons and hulls
    of two discs, all with exact (or conservative) signed distances, so the renderer's
    edge finding and coverage work on them as on flat objects.
    """

    def __init__(
        self,
        parts: list[_Shape],
        holes: list[_Circle],
        height: float,
        foot: F64,
        distance: float,
    ) -> None:
        if holes and len(parts) != 1:  # pragma: no cover - holes only in nuts and washers
            raise ArgumentError("a raised object with holes must be one convex part")
        self.height, self.distance = float(height), float(distance)
        self.lam = self.height / self.distance
        self.foot = np.asarray(foot, dtype=np.float64)
        grow = self.lam / (1.0 - self.lam)  # the scale factor 1 / (1 - h / D), less 1
        self.parts, self.holes = parts, holes
        self.top: list[_Shape] = [p.lifted(self.foot, grow) for p in parts]
        self.holes_top = [h.lifted(self.foot, grow) for h in holes]
        self.hull: list[_Primitive] = []
        for base, top in zip(parts, self.top, strict=True):
            if isinstance(base, _Circle):
                assert isinstance(top, _Circle)
                self.hull.append(_DiscHull(base, top))
            else:
                assert isinstance(top, _ConvexPolygon)
                hull = _convex_hull(np.vstack([base.vertices, top.vertices]))
                self.hull.append(_ConvexPolygon(hull))
        boxes = np.array([p.bbox for p in self.hull])
        self.bbox = (boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max())

    def fields(self, x: F64, y: F64) -> tuple[_Field, _Field]:
        """The fields of the region whose rays meet the object (hit) and of its top."""
        hit = self.hull[0].field(x, y)
        top = self.top[0].field(x, y)
        for p in self.hull[1:]:
            hit = _union(hit, p.field(x, y))
        for p in self.top[1:]:
            top = _union(top, p.field(x, y))
        for h, ht in zip(self.holes, self.holes_top, strict=True):
            f_ht = ht.field(x, y)
            hit = _intersection(hit, _complement(_intersection(h.field(x, y), f_ht)))
            top = _intersection(top, _complement(f_ht))
        return hit, top

    def classify(
        self, x: F64, y: F64, radius: F64
    ) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
        """At each table point: whether its ray meets the object, meets its top, whether a
        boundary of either region may lie within ``radius`` (conservative), and whether the
        hit region may reach within ``radius``."""
        sd_hit = self.hull[0].signed_distance(x, y)
        for p in self.hull[1:]:
            np.minimum(sd_hit, p.signed_distance(x, y), out=sd_hit)
        sd_top = self.top[0].signed_distance(x, y)
        for p in self.top[1:]:
            np.minimum(sd_top, p.signed_distance(x, y), out=sd_top)
        hit, top = sd_hit < 0.0, sd_top < 0.0
        near = (np.abs(sd_hit) < radius) | (np.abs(sd_top) < radius)
        reach = sd_hit < radius
        for h, ht in zip(self.holes, self.holes_top, strict=True):
            sd_h, sd_ht = h.signed_distance(x, y), ht.signed_distance(x, y)
            hit &= (sd_h >= 0.0) | (sd_ht >= 0.0)
            top &= sd_ht >= 0.0
            near |= (np.abs(sd_h) < radius) | (np.abs(sd_ht) < radius)
        return hit, top & hit, near, reach

    def entry_height(self, x: F64, y: F64) -> F64:
        """How high (mm) the ray that meets the table at (x, y) first meets the object (its
        height for the top, less for a wall), -inf where it misses: for the painter's order
        where two raised objects overlap in the image."""
        vx, vy = self.foot[0] - x, self.foot[1] - y  # the ray rises along P + s v
        best = np.full(x.shape, -np.inf)
        for part in self.parts:
            lo, hi = _line_interval(part, x, y, vx, vy)
            s = np.minimum(hi, self.lam)
            for h in self.holes:
                h_lo, h_hi = _line_interval(h, x, y, vx, vy)
                s = np.where((h_lo < s) & (s < h_hi), h_lo, s)
            ok = (lo <= hi) & (s >= np.maximum(lo, 0.0))
            np.maximum(best, np.where(ok, s * self.distance, -np.inf), out=best)
        return best
