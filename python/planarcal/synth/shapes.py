"""Flat shapes on the table plane as signed-distance fields: how the renderer finds the pixels
a boundary crosses and shades them by exact area.

A field is (signed distance, outward normal x, y) at each point, negative inside. Discs,
convex polygons and the convex hull of two discs have exact (or, outside a polygon,
conservative) ones; union, intersection and complement combine them. :func:`_coverage` is
the fraction of a cell (a parallelogram) on the inner side of a boundary, treated as
straight across the cell.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import cast

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def _rotation_2d(angle_deg: float) -> F64:
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


class _Circle:
    """A disc (centre, radius) in table mm."""

    def __init__(self, centre: F64, radius: float) -> None:
        self.cx, self.cy, self.radius = float(centre[0]), float(centre[1]), float(radius)
        self.bbox = (
            self.cx - radius,
            self.cx + radius,
            self.cy - radius,
            self.cy + radius,
        )

    def signed_distance(self, x: F64, y: F64) -> F64:
        return np.asarray(np.hypot(x - self.cx, y - self.cy) - self.radius, dtype=np.float64)

    def field(self, x: F64, y: F64) -> tuple[F64, F64, F64]:
        """Signed distance (exact) and the unit outward normal of the nearest boundary."""
        dx, dy = x - self.cx, y - self.cy
        d = np.hypot(dx, dy)
        safe = np.where(d > 0.0, d, 1.0)
        return d - self.radius, np.where(d > 0.0, dx / safe, 1.0), dy / safe

    def polygon(self, n: int) -> F64:
        a = 2.0 * np.pi * np.arange(n) / n
        return np.column_stack(
            [self.cx + self.radius * np.cos(a), self.cy + self.radius * np.sin(a)]
        )

    def lifted(self, centre: F64, grow: float) -> _Circle:
        """This disc scaled by 1 + grow about ``centre`` (see _Raised)."""
        c = np.array([self.cx, self.cy])
        return _Circle(c + grow * (c - centre), (1.0 + grow) * self.radius)


class _ConvexPolygon:
    """A convex polygon in table mm; its signed distance is exact inside and a lower bound
    outside (the largest distance beyond an edge's line), which keeps edge finding
    conservative."""

    def __init__(self, vertices: F64) -> None:
        v = np.asarray(vertices, dtype=np.float64)
        if _signed_area(v) < 0:
            v = v[::-1]
        self.vertices = v
        e = np.roll(v, -1, axis=0) - v
        n = np.column_stack([e[:, 1], -e[:, 0]]) / np.hypot(e[:, 0], e[:, 1])[:, None]
        self.normals = n
        self.offsets = np.sum(n * v, axis=1)
        self.bbox = (
            float(v[:, 0].min()),
            float(v[:, 0].max()),
            float(v[:, 1].min()),
            float(v[:, 1].max()),
        )

    def signed_distance(self, x: F64, y: F64) -> F64:
        n, c = self.normals, self.offsets
        out = n[0, 0] * x + n[0, 1] * y - c[0]
        for i in range(1, len(c)):
            np.maximum(out, n[i, 0] * x + n[i, 1] * y - c[i], out=out)
        return np.asarray(out, dtype=np.float64)

    def field(self, x: F64, y: F64) -> tuple[F64, F64, F64]:
        """Signed distance (as signed_distance) and the outward normal of the edge that gives
        it: exact near the edges, away from the corners."""
        n, c = self.normals, self.offsets
        d = n[:, 0, None] * x.ravel()[None, :] + n[:, 1, None] * y.ravel()[None, :] - c[:, None]
        k = np.argmax(d, axis=0)
        sd = np.take_along_axis(d, k[None, :], axis=0)[0]
        return sd.reshape(x.shape), n[k, 0].reshape(x.shape), n[k, 1].reshape(x.shape)

    def lifted(self, centre: F64, grow: float) -> _ConvexPolygon:
        """This polygon scaled by 1 + grow about ``centre`` (see _Raised)."""
        return _ConvexPolygon(self.vertices + grow * (self.vertices - centre))


class _DiscHull:
    """The convex hull of two discs ``a`` and ``b``: the tangent lines' band between them
    capped by their arcs (a disc alone when one holds the other). Its signed distance is
    exact (the distance to the nearest of the two arcs or the two tangent segments)."""

    def __init__(self, a: _Circle, b: _Circle) -> None:
        self.bbox = (
            min(a.bbox[0], b.bbox[0]),
            max(a.bbox[1], b.bbox[1]),
            min(a.bbox[2], b.bbox[2]),
            max(a.bbox[3], b.bbox[3]),
        )
        self.a, self.b = a, b
        dx, dy = b.cx - a.cx, b.cy - a.cy
        self.length = math.hypot(dx, dy)
        self.single: _Circle | None = None
        if self.length <= abs(b.radius - a.radius) * (1.0 + 1e-12):
            self.single = a if a.radius >= b.radius else b
            return
        self.ux, self.uy = dx / self.length, dy / self.length
        # The upper tangent's outward normal is (sin, cos) in the frame (u, w), w = u turned
        # +90 degrees; it touches a at angle asin(sin) beyond the perpendicular.
        self.sin = (a.radius - b.radius) / self.length
        self.cos = math.sqrt(max(0.0, 1.0 - self.sin * self.sin))

    def signed_distance(self, x: F64, y: F64) -> F64:
        return self.field(x, y)[0]

    def field(self, x: F64, y: F64) -> tuple[F64, F64, F64]:
        """Signed distance (exact) and the unit outward normal of the nearest boundary."""
        if self.single is not None:
            return self.single.field(x, y)
        sd_a, nx_a, ny_a = self.a.field(x, y)
        sd_b, nx_b, ny_b = self.b.field(x, y)
        px, py = x - self.a.cx, y - self.a.cy
        along = px * self.ux + py * self.uy
        across = py * self.ux - px * self.uy
        side = np.where(across >= 0.0, 1.0, -1.0)
        # Position along the tangent segment (direction (cos, -sin) in (u, |w|)): before its
        # point on a (k < 0) the arc of a is nearest, past its point on b the arc of b.
        k = self.cos * along - self.sin * np.abs(across)
        sd_t = self.sin * along + self.cos * np.abs(across) - self.a.radius
        nx_t = self.sin * self.ux - side * self.cos * self.uy
        ny_t = self.sin * self.uy + side * self.cos * self.ux
        on_a, on_b = k < 0.0, k > self.cos * self.length
        sd = np.where(on_a, sd_a, np.where(on_b, sd_b, sd_t))
        nx = np.where(on_a, nx_a, np.where(on_b, nx_b, nx_t))
        ny = np.where(on_a, ny_a, np.where(on_b, ny_b, ny_t))
        return np.asarray(sd, np.float64), np.asarray(nx, np.float64), np.asarray(ny, np.float64)


def _convex_hull(points: F64) -> F64:
    """Convex hull, counter-clockwise (positive area), without collinear or coincident
    vertices (Andrew's monotone chain); vertices closer than 1e-9 of the extent merge."""
    pts = np.unique(np.asarray(points, dtype=np.float64), axis=0)
    tol = 1e-9 * (1.0 + float(np.ptp(pts, axis=0).max()))

    def chain(seq: Iterable[F64]) -> list[F64]:
        out: list[F64] = []
        for q in seq:
            while len(out) >= 2:
                a, b = out[-2], out[-1]
                cross = (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])
                if cross > tol * math.hypot(q[0] - a[0], q[1] - a[1]):
                    break
                out.pop()
            if not out or math.hypot(q[0] - out[-1][0], q[1] - out[-1][1]) > tol:
                out.append(q)
        return out

    lower, upper = chain(pts), chain(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


_Shape = _Circle | _ConvexPolygon
_Primitive = _Circle | _ConvexPolygon | _DiscHull
_Field = tuple[F64, F64, F64]


def _union(a: _Field, b: _Field) -> _Field:
    """The field (signed distance, outward normal) of the union: the nearer boundary inside
    either, exact in sign and 1-Lipschitz (so edge finding stays conservative)."""
    closer = b[0] < a[0]
    return (
        np.where(closer, b[0], a[0]),
        np.where(closer, b[1], a[1]),
        np.where(closer, b[2], a[2]),
    )


def _intersection(a: _Field, b: _Field) -> _Field:
    """The field of the intersection (the larger signed distance; see _union)."""
    return cast("_Field", tuple(-v for v in _union(_complement(a), _complement(b))))


def _complement(a: _Field) -> _Field:
    return (-a[0], -a[1], -a[2])


def _line_interval(shape: _Shape, x: F64, y: F64, vx: F64, vy: F64) -> tuple[F64, F64]:
    """The interval [lo, hi] of s for which (x, y) + s (vx, vy) lies in the convex shape
    (lo > hi: none; a zero direction gives (-inf, inf) inside, nothing outside)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        if isinstance(shape, _Circle):
            dx, dy = x - shape.cx, y - shape.cy
            a = vx * vx + vy * vy
            b = dx * vx + dy * vy
            c = dx * dx + dy * dy - shape.radius**2
            disc = b * b - a * c
            root = np.sqrt(np.maximum(disc, 0.0))
            moving = a > 0.0
            safe = np.where(moving, a, 1.0)
            lo = np.where(moving, (-b - root) / safe, np.where(c <= 0.0, -np.inf, np.inf))
            hi = np.where(moving, (-b + root) / safe, np.where(c <= 0.0, np.inf, -np.inf))
            empty = moving & (disc < 0.0)
            return np.where(empty, np.inf, lo), np.where(empty, -np.inf, hi)
        lo = np.full(x.shape, -np.inf)
        hi = np.full(x.shape, np.inf)
        for (nx, ny), off in zip(shape.normals, shape.offsets, strict=True):
            num = off - (nx * x + ny * y)
            den = nx * vx + ny * vy
            t = num / np.where(den != 0.0, den, 1.0)
            hi = np.where(den > 0.0, np.minimum(hi, t), hi)
            lo = np.where(den < 0.0, np.maximum(lo, t), lo)
            out = (den == 0.0) & (num < 0.0)
            lo, hi = np.where(out, np.inf, lo), np.where(out, -np.inf, hi)
        return lo, hi


def _signed_area(poly: F64) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _coverage(sd: F64, nx: F64, ny: F64, cell: tuple[F64, F64, F64, F64]) -> F64:
    """Fraction of each cell on the inner side (sd < 0) of a straight boundary.

    The cell is the parallelogram spanned by (ax, ay) and (bx, by) (its footprint on the
    plane) around the point where the signed distance is ``sd`` and the boundary's unit
    normal (nx, ny). Across the boundary, a point uniformly distributed over the cell has a
    distance that is the sum of two uniform variables (the two sides projected on the
    normal): the coverage is their distribution function, which is exact for a straight
    boundary whatever its direction."""
    ax, ay, bx, by = cell
    pa = 0.5 * np.abs(nx * ax + ny * ay)
    pb = 0.5 * np.abs(nx * bx + ny * by)
    hi, lo = np.maximum(pa, pb), np.minimum(pa, pb)
    lo = np.maximum(lo, 1e-12 * hi + 1e-300)
    x = -sd
    cov = 0.5 + x / (2.0 * hi)
    tail = hi + lo - np.abs(x)
    q = tail * tail / (8.0 * hi * lo)
    cov = np.where(x < lo - hi, q, cov)
    cov = np.where(x > hi - lo, 1.0 - q, cov)
    return np.asarray(np.clip(np.where(tail <= 0.0, x > 0.0, cov), 0.0, 1.0), np.float64)
