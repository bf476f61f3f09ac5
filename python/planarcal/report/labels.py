"""Text on a picture that stays readable: sizes scaled to the image, and boxes placed so that
no two overlap and none covers a marked point. Every text of the drawn figures goes through
one Layout, which keeps the boxes it placed (so a test can measure them)."""

from __future__ import annotations

import dataclasses
import textwrap
from collections.abc import Iterable, Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

U8 = NDArray[np.uint8]
FONT = cv2.FONT_HERSHEY_SIMPLEX

# Text heights (px) as fractions of the image's short side, with a floor below which
# OpenCV's Hershey font stops being legible.
HEADER_FRACTION = 0.022
HEADER_MIN_PX = 11.0
SMALL_FRACTION = 0.012
SMALL_MIN_PX = 8.0


@dataclasses.dataclass(frozen=True)
class Box:
    """An axis-aligned box in pixels, [x0, x1) x [y0, y1)."""

    x0: int
    y0: int
    x1: int
    y1: int

    def overlaps(self, other: Box) -> bool:
        return (
            self.x0 < other.x1 and other.x0 < self.x1 and self.y0 < other.y1 and other.y0 < self.y1
        )

    def inside(self, width: int, height: int) -> bool:
        return self.x0 >= 0 and self.y0 >= 0 and self.x1 <= width and self.y1 <= height

    @property
    def height(self) -> int:
        return self.y1 - self.y0


def text_height(shape: tuple[int, ...], *, small: bool = False) -> float:
    """The height (px) of a header line (or, `small`, of a point's label) on an image of
    `shape` (rows, cols, ...): a fixed share of its short side, never below legibility."""
    short = float(min(shape[:2]))
    if small:
        return max(SMALL_MIN_PX, SMALL_FRACTION * short)
    return max(HEADER_MIN_PX, HEADER_FRACTION * short)


@dataclasses.dataclass(frozen=True)
class Style:
    """How a text is written: its height (px), colour (BGR) and background (None: none)."""

    height: float
    colour: tuple[int, int, int] = (20, 20, 20)
    background: tuple[int, int, int] | None = (255, 255, 255)
    bold: bool = False

    @property
    def scale(self) -> float:
        return float(cv2.getFontScaleFromHeight(FONT, max(1, round(self.height)), self.thickness))

    @property
    def thickness(self) -> int:
        return max(1, round(self.height / (9.0 if self.bold else 14.0)))

    @property
    def pad(self) -> int:
        return max(1, round(0.15 * self.height)) if self.background is not None else 0

    def size(self, text: str) -> tuple[int, int, int]:
        """(width, height above the baseline, depth below it) of `text`, px."""
        (w, h), base = cv2.getTextSize(text, FONT, self.scale, self.thickness)
        return int(w), int(h), int(base)


class Layout:
    """The texts placed on one picture: each placed where it overlaps no text placed before
    and no reserved region (a marked point), else moved or left out."""

    def __init__(self, canvas: U8) -> None:
        self.canvas = canvas
        self.height, self.width = canvas.shape[:2]
        self.boxes: list[Box] = []
        self.reserved: list[Box] = []
        self._reserved_xy = np.zeros((0, 4), dtype=np.int64)
        self._boxes_xy = np.zeros((0, 4), dtype=np.int64)
        self._texts: list[tuple[str, Style, tuple[int, int], Box]] = []
        self._leaders: list[tuple[tuple[int, int], tuple[int, int], int]] = []

    def fork(self) -> Layout:
        """A copy to try placements on: what it places is kept only if `adopt`ed."""
        other = Layout.__new__(Layout)
        other.__dict__.update(self.__dict__)
        other.boxes, other.reserved = list(self.boxes), list(self.reserved)
        other._texts, other._leaders = list(self._texts), list(self._leaders)
        return other

    def adopt(self, fork: Layout) -> None:
        """Takes over what `fork` (of this layout, nothing placed here since) placed."""
        self.__dict__.update(fork.__dict__)

    def reserve(self, boxes: Iterable[Box]) -> None:
        """Regions no text may cover (marked points, parts)."""
        self.reserved.extend(boxes)
        self._reserved_xy = np.array(
            [(b.x0, b.y0, b.x1, b.y1) for b in self.reserved], dtype=np.int64
        ).reshape(-1, 4)

    def box_at(self, text: str, style: Style, org: tuple[int, int]) -> Box:
        """The box `text` fills with its baseline starting at `org`, background included."""
        w, h, base = style.size(text)
        p = style.pad
        x, y = org
        return Box(x - p, y - h - p, x + w + p, y + base + p)

    def free(self, box: Box, *, check_reserved: bool = True) -> bool:
        if not box.inside(self.width, self.height):
            return False
        if _hits(box, self._boxes_xy):
            return False
        return not (check_reserved and _hits(box, self._reserved_xy))

    def place(
        self,
        text: str,
        style: Style,
        origins: Sequence[tuple[int, int]],
        *,
        check_reserved: bool = True,
    ) -> Box | None:
        """Writes `text` at the first of `origins` (baseline starts) where it is free; None
        (nothing drawn) when none is."""
        for org in origins:
            box = self.box_at(text, style, org)
            if self.free(box, check_reserved=check_reserved):
                self.draw(text, style, org, box)
                return box
        return None

    def draw(self, text: str, style: Style, org: tuple[int, int], box: Box) -> None:
        """Keeps `text` at `box` (drawn by `finish`, after every leader line)."""
        self._texts.append((text, style, org, box))
        self.boxes.append(box)
        row = np.array([[box.x0, box.y0, box.x1, box.y1]], dtype=np.int64)
        self._boxes_xy = np.concatenate([self._boxes_xy, row])

    def leader(self, start: tuple[int, int], end: tuple[int, int], thickness: int) -> None:
        """A line from a moved label to what it names (drawn under every text)."""
        self._leaders.append((start, end, thickness))

    def finish(self) -> list[Box]:
        """Draws the leader lines, then the texts over them; the texts' boxes."""
        for start, end, thick in self._leaders:
            cv2.line(self.canvas, start, end, (0, 0, 0), thick + 2, cv2.LINE_AA)
            cv2.line(self.canvas, start, end, (255, 255, 255), thick, cv2.LINE_AA)
        for text, style, org, box in self._texts:
            if style.background is not None:
                cv2.rectangle(
                    self.canvas, (box.x0, box.y0), (box.x1 - 1, box.y1 - 1), style.background, -1
                )
            cv2.putText(
                self.canvas,
                text,
                org,
                FONT,
                style.scale,
                style.colour,
                style.thickness,
                cv2.LINE_AA,
            )
        self._leaders, self._texts = [], []
        return list(self.boxes)

    def wrap(self, lines: Sequence[str], style: Style, width: int) -> list[str]:
        """The lines broken at spaces so that each fits `width` px (a word wider is kept)."""
        out: list[str] = []
        for line in lines:
            if style.size(line)[0] <= width:
                out.append(line)
                continue
            if "; " in line:  # a clause per line first (a residual note names two models)
                head, tail = line.split("; ", 1)
                out += self.wrap([head + ";", "  " + tail], style, width)
                continue
            chars = max(8, int(len(line) * width / max(style.size(line)[0], 1)))
            while True:
                parts = textwrap.wrap(line, chars, subsequent_indent="  ")
                if chars <= 8 or all(style.size(p)[0] <= width for p in parts):
                    break
                chars -= 1
            out += parts
        return out

    def block(
        self, lines: Sequence[str], style: Style, points: NDArray[np.float64] | None = None
    ) -> list[Box]:
        """A caption of `lines` wrapped to the image's width, in the image's top-left corner
        or, when fewer of `points` (px) fall under it there, another corner. The caption is
        placed before anything else and over what it covers."""
        margin = max(2, round(0.4 * style.height))
        wrapped = self.wrap(lines, style, self.width - 2 * margin - 2 * style.pad)
        step = round(1.5 * style.height) + 2 * style.pad
        total = step * len(wrapped)
        widest = max((style.size(t)[0] for t in wrapped), default=0) + 2 * style.pad
        corners = [
            (margin, margin),
            (margin, self.height - margin - total),
            (self.width - margin - widest, margin),
            (self.width - margin - widest, self.height - margin - total),
        ]
        corners = [(x, y) for x, y in corners if x >= 0 and y >= 0] or corners[:1]
        if points is not None and len(points):
            p = points

            def covered(corner: tuple[int, int]) -> int:
                x, y = corner
                inside = (p[:, 0] >= x) & (p[:, 0] < x + widest + margin)
                return int((inside & (p[:, 1] >= y) & (p[:, 1] < y + total + margin)).sum())

            corners.sort(key=covered)
        left, top = corners[0]
        placed = []
        for k, text in enumerate(wrapped):
            _, h, _ = style.size(text)
            org = (left + style.pad, top + k * step + style.pad + h)
            box = self.box_at(text, style, org)
            if self.free(box, check_reserved=False):
                self.draw(text, style, org, box)
                placed.append(box)
        return placed


def _hits(box: Box, others: NDArray[np.int64]) -> bool:
    """Whether `box` overlaps any of `others` (rows x0, y0, x1, y1)."""
    if not len(others):
        return False
    o = others
    return bool(
        ((box.x0 < o[:, 2]) & (o[:, 0] < box.x1) & (box.y0 < o[:, 3]) & (o[:, 1] < box.y1)).any()
    )


def point_box(x: float, y: float, r: float) -> Box:
    """The region a point marked with radius `r` at (x, y) keeps free of text."""
    k = max(1.0, 0.8 * r)
    return Box(round(x - k), round(y - k), round(x + k) + 1, round(y + k) + 1)


def around(x: float, y: float, gap: float, w: int, h: int) -> list[tuple[int, int]]:
    """Baseline origins of a `w` x `h` text next to the point (x, y), `gap` px from it:
    up-right first (where the labels always were), then the other diagonals and sides."""
    g = round(gap)
    xi, yi = round(x), round(y)
    return [
        (xi + g, yi - g),
        (xi - g - w, yi - g),
        (xi + g, yi + g + h),
        (xi - g - w, yi + g + h),
        (xi + g, yi + h // 2),
        (xi - g - w, yi + h // 2),
    ]
