"""Objects on the table (bolts, nuts, washers, discs, rectangles): :class:`SceneObject` and
its outline, :class:`Silhouette`.

Objects are silhouettes (unions of convex polygons and discs, less round holes) whose *area
centroid on the plane* is ``position_mm``, exactly. With ``height_mm`` = h > 0 an object is
a right prism: the silhouette extruded from the table up to its top face at Z = -h, holes
going right through. Its truth is the centroid of its top face, the 3-D point (X, Y, -h):
a rendered scene's ``object_centroids_px`` is that point's exact projection (the image of
the silhouette's centroid for a flat object), ``object_centroids_mm`` its (X, Y) and
``object_heights_mm`` its h.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.errors import ArgumentError
from planarcal.synth.shapes import _Circle, _ConvexPolygon, _rotation_2d, _Shape, _signed_area

F64 = NDArray[np.float64]


ObjectKind = Literal["bolt", "nut", "washer", "disc", "rectangle"]
"""The shapes :class:`SceneObject` can take."""

OBJECT_KINDS: tuple[ObjectKind, ...] = ("bolt", "nut", "washer", "disc", "rectangle")


# Hexagon across flats, as a multiple of the nominal thread diameter (ISO 4032 / 4017: M8
# nuts and bolt heads are 13 mm across flats).
_HEX_ACROSS_FLATS = 1.6
# Hole diameters: a nut's (the thread's minor diameter) and a washer's, times d.
_NUT_HOLE = 0.85
_WASHER_HOLE = 1.05


def _hexagon(across_flats: float) -> F64:
    """A regular hexagon centred at 0 with flats perpendicular to x, counter-clockwise."""
    r = across_flats / math.sqrt(3.0)
    a = np.radians(np.arange(-90.0, 270.0, 60.0))
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


class Silhouette(NamedTuple):
    """An object's outline on the table in mm: ``outer`` (N, 2) counter-clockwise (positive
    shoelace area in X, Y) and ``holes``, each (M, 2), also with positive area, to subtract.
    Circles are regular polygons centred on the circle (so the area centroid is unchanged)."""

    outer: F64
    holes: tuple[F64, ...]


@dataclasses.dataclass(frozen=True)
class SceneObject:
    """An object on the table: its silhouette, placed so that its area centroid is at
    ``position_mm`` (table mm) exactly, turned by ``angle_deg`` (from +X towards +Y).

    ``size_mm`` is the object's nominal size:

    * ``"nut"``: thread diameter d; a regular hexagon 1.6 d across flats (M8: 12.8 mm) with
      a round hole of 0.85 d (the thread's minor diameter, as seen from above), flats
      perpendicular to the X axis at angle 0.
    * ``"bolt"``: thread diameter d; a hexagonal head 1.6 d across flats plus a shank d wide
      and ``length_mm`` long (default 4 d) from the middle of one flat, along +X at angle 0.
    * ``"washer"``: inner diameter d; an annulus of outer diameter 2 d, hole 1.05 d.
    * ``"disc"``: the diameter.
    * ``"rectangle"``: the width (along Y at angle 0); ``length_mm`` (along X) defaults to
      it (a square).

    ``grey`` overrides the renderer's metal grey level for this object's top (0-255).

    ``height_mm`` (default 0: a flat silhouette) makes the object a right prism: the
    silhouette extruded from the table (Z = 0) up to its top face at Z = -height_mm (table Z
    points away from the camera). Holes go right through. Its top face's area centroid is
    then the 3-D point (X, Y, -height_mm) with (X, Y) = ``position_mm``.
    """

    kind: ObjectKind
    position_mm: tuple[float, float]
    angle_deg: float = 0.0
    size_mm: float = 8.0
    length_mm: float | None = None
    grey: float | None = None
    height_mm: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in OBJECT_KINDS:
            raise ArgumentError(f"kind must be one of {', '.join(OBJECT_KINDS)}; got {self.kind!r}")
        object.__setattr__(self, "position_mm", arguments.pair("position_mm", self.position_mm))
        arguments.real("angle_deg", self.angle_deg)
        arguments.positive("size_mm", self.size_mm)
        if self.length_mm is not None:
            if self.kind not in ("bolt", "rectangle"):
                raise ArgumentError(f"length_mm applies to bolts and rectangles, not a {self.kind}")
            arguments.positive("length_mm", self.length_mm)
        if self.grey is not None:
            g = arguments.real("grey", self.grey)
            if not 0.0 <= g <= 255.0:
                raise ArgumentError(f"grey must be a grey level 0-255, got {self.grey!r}")
        height = arguments.real("height_mm", self.height_mm)
        if height < 0.0:
            raise ArgumentError(
                f"height_mm must be >= 0 (mm above the table; 0 for a flat object), got "
                f"{self.height_mm!r}"
            )

    # Local geometry: the shape before it is centred on its centroid, turned and placed.
    def _local(self) -> tuple[list[F64 | tuple[float, float, float]], list[float], F64]:
        """(parts, hole radii, centroid): parts are convex polygons (vertex arrays) or
        circles (cx, cy, r) whose union is the outline; holes are circles at the origin."""
        d = float(self.size_mm)
        if self.kind == "nut":
            return [_hexagon(_HEX_ACROSS_FLATS * d)], [_NUT_HOLE * d / 2.0], np.zeros(2)
        if self.kind == "washer":
            return [(0.0, 0.0, d)], [_WASHER_HOLE * d / 2.0], np.zeros(2)
        if self.kind == "disc":
            return [(0.0, 0.0, d / 2.0)], [], np.zeros(2)
        if self.kind == "rectangle":
            length = d if self.length_mm is None else float(self.length_mm)
            hx, hy = length / 2.0, d / 2.0
            rect = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
            return [rect], [], np.zeros(2)
        # bolt: head and shank meet along the flat at x = af / 2 (disjoint interiors).
        af = _HEX_ACROSS_FLATS * d
        length = 4.0 * d if self.length_mm is None else float(self.length_mm)
        x0 = af / 2.0
        shank = np.array([[x0, -d / 2], [x0 + length, -d / 2], [x0 + length, d / 2], [x0, d / 2]])
        a_head, a_shank = math.sqrt(3.0) / 2.0 * af * af, length * d
        cx = a_shank * (x0 + length / 2.0) / (a_head + a_shank)
        return [_hexagon(af), shank], [], np.array([cx, 0.0])

    def _place(self, local: F64, centroid: F64) -> F64:
        rot = _rotation_2d(float(self.angle_deg))
        return np.asarray((local - centroid) @ rot.T + np.array(self.position_mm), dtype=float)

    def _primitives(self) -> tuple[list[_Shape], list[_Circle]]:
        """The outline's convex parts and the holes, in table mm, for the renderer."""
        parts, holes, c = self._local()
        outer: list[_Shape] = []
        for part in parts:
            if isinstance(part, tuple):
                centre = self._place(np.array([part[:2]]), c)[0]
                outer.append(_Circle(centre, part[2]))
            else:
                outer.append(_ConvexPolygon(self._place(part, c)))
        centre = self._place(np.zeros((1, 2)), c)[0]
        return outer, [_Circle(centre, r) for r in holes]

    @property
    def hole_diameter_mm(self) -> float | None:
        """Diameter of the round hole (nuts and washers), None for the others."""
        holes = self._local()[1]
        return 2.0 * holes[0] if holes else None

    @property
    def area_mm2(self) -> float:
        """The silhouette's exact area (circles as circles)."""
        parts, holes, _ = self._local()
        area = sum(math.pi * p[2] ** 2 if isinstance(p, tuple) else _signed_area(p) for p in parts)
        return float(area - sum(math.pi * r * r for r in holes))

    def silhouette(self, arc_vertices: int = 360) -> Silhouette:
        """The outline as polygons in table mm (see :class:`Silhouette`); circles become
        regular polygons of ``arc_vertices`` vertices. The renderer draws true circles."""
        if isinstance(arc_vertices, bool) or not isinstance(arc_vertices, int | np.integer):
            raise ArgumentError(f"arc_vertices must be a whole number, got {arc_vertices!r}")
        if arc_vertices < 8:
            raise ArgumentError(f"arc_vertices must be at least 8, got {arc_vertices}")
        parts, holes, c = self._local()
        if self.kind == "bolt":
            head, shank = parts
            assert not isinstance(head, tuple) and not isinstance(shank, tuple)
            # Counter-clockwise from the head's bottom vertex; the shank is inserted on the
            # flat at x = af / 2, between head vertices 1 and 2.
            local = np.vstack([head[:2], shank, head[2:]])
        elif isinstance(parts[0], tuple):
            local = _Circle(np.array(parts[0][:2]), parts[0][2]).polygon(int(arc_vertices))
        else:
            local = parts[0]
        hole_polys = tuple(
            self._place(_Circle(np.zeros(2), r).polygon(int(arc_vertices)), c) for r in holes
        )
        return Silhouette(self._place(local, c), hole_polys)
