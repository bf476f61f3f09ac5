"""What a printed page is drawn with: circles, black areas (rectangles filled as one path),
stroked lines, filled polygons and text, in page mm (from the top-left corner, y down), each
with the box it covers; and coordinates as the SVG and PDF writers write them.

Text widths are budgeted at 0.66 em per character (Courier's 0.6 plus 10 % for an SVG
viewer that substitutes another monospace font), heights at 0.8 em above and 0.25 em below
the baseline, so the text stays inside the margins whatever font is substituted."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Literal

# Text metrics, in font sizes (em). Courier's advance is exactly 0.6 em; the budget adds 10 %
# for a substituted monospace font in SVG viewers.
COURIER_ADVANCE = 0.6
ADVANCE_BUDGET = 0.66
ASCENT, DESCENT = 0.8, 0.25
_EPS = 1e-9  # tolerance of the fit tests, mm


Box = tuple[float, float, float, float]
"""(x0, y0, x1, y1) in page mm, y down."""


@dataclasses.dataclass(frozen=True)
class Circle:
    """A filled circle: a dot, black unless ``white`` (a chessboard's marker dot on a black
    square)."""

    cx: float
    cy: float
    r: float
    group: str
    id: str
    cls: str
    white: bool = False

    def box(self) -> Box:
        return (self.cx - self.r, self.cy - self.r, self.cx + self.r, self.cy + self.r)


@dataclasses.dataclass(frozen=True)
class Area:
    """Black rectangles (x0, y0, x1, y1) filled as one path: a chessboard's squares, an ArUco
    marker's cells. They may share edges but never overlap, so the path's fill is exactly
    their union, and a rasteriser's anti-aliasing leaves no pale seam where two of them meet
    (as it would drawing them one by one)."""

    rects: tuple[Box, ...]
    group: str
    id: str
    cls: str

    def box(self) -> Box:
        return union(self.rects)


@dataclasses.dataclass(frozen=True)
class Line:
    """A straight line stroked `width` mm wide, butt caps."""

    x1: float
    y1: float
    x2: float
    y2: float
    width: float
    group: str
    id: str
    cls: str

    def box(self) -> Box:
        # Butt caps: the stroke reaches w/2 to either side; w/2 along is a safe bound too.
        h = self.width / 2
        return (
            min(self.x1, self.x2) - h,
            min(self.y1, self.y2) - h,
            max(self.x1, self.x2) + h,
            max(self.y1, self.y2) + h,
        )


@dataclasses.dataclass(frozen=True)
class Polygon:
    """A filled polygon: an arrow head."""

    points: tuple[tuple[float, float], ...]
    group: str
    id: str
    cls: str

    def box(self) -> Box:
        xs = [p[0] for p in self.points]
        ys = [p[1] for p in self.points]
        return (min(xs), min(ys), max(xs), max(ys))


@dataclasses.dataclass(frozen=True)
class Text:
    """A line of text, its baseline at y, anchored at x by its start, middle or end."""

    x: float
    y: float  # baseline
    text: str
    size: float
    anchor: Literal["start", "middle", "end"]
    bold: bool
    group: str
    id: str
    cls: str

    def _left(self, width: float) -> float:
        if self.anchor == "middle":
            return self.x - width / 2
        if self.anchor == "end":
            return self.x - width
        return self.x

    def pdf_x(self) -> float:
        """Where the text starts with Courier's exact advance."""
        return self._left(COURIER_ADVANCE * self.size * len(self.text))

    def box(self) -> Box:
        width = ADVANCE_BUDGET * self.size * len(self.text)
        left = self._left(width)
        return (left, self.y - ASCENT * self.size, left + width, self.y + DESCENT * self.size)


Shape = Circle | Area | Line | Polygon | Text
"""Anything drawn; each carries its SVG group, element id and class."""


def union(boxes: Iterable[Box]) -> Box:
    """The box covering all of `boxes`."""
    x0s, y0s, x1s, y1s = zip(*boxes, strict=True)
    return (min(x0s), min(y0s), max(x1s), max(y1s))


def shift(shape: Shape, dx: float, dy: float) -> Shape:
    """`shape` moved by (dx, dy) mm."""
    if isinstance(shape, Circle):
        return dataclasses.replace(shape, cx=shape.cx + dx, cy=shape.cy + dy)
    if isinstance(shape, Line):
        return dataclasses.replace(
            shape, x1=shape.x1 + dx, y1=shape.y1 + dy, x2=shape.x2 + dx, y2=shape.y2 + dy
        )
    if isinstance(shape, Polygon):
        return dataclasses.replace(shape, points=tuple((x + dx, y + dy) for x, y in shape.points))
    if isinstance(shape, Area):
        moved = tuple((x0 + dx, y0 + dy, x1 + dx, y1 + dy) for x0, y0, x1, y1 in shape.rects)
        return dataclasses.replace(shape, rects=moved)
    return dataclasses.replace(shape, x=shape.x + dx, y=shape.y + dy)


def inside(box: Box, frame: Box) -> bool:
    """Whether `box` lies within `frame` (to 1e-9 mm)."""
    return (
        box[0] >= frame[0] - _EPS
        and box[1] >= frame[1] - _EPS
        and box[2] <= frame[2] + _EPS
        and box[3] <= frame[3] + _EPS
    )


def fmt(value: float) -> str:
    """A coordinate for SVG or PDF: fixed point, 9 decimals, no exponent, no trailing zeros."""
    text = f"{float(value):.9f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text
