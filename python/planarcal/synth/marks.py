"""Marks printed on a board's paper beside its dots (numbers, arrows, text, crosses, rings):
decoration that a detector must ignore. :func:`printed_marks` makes them as flat
:class:`~planarcal.synth.objects.SceneObject` strokes in board coordinates, for
``render_scene(marks=...)``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal.calib.board import CircleGridBoard
from planarcal.errors import ArgumentError, BoardError
from planarcal.synth.dots import _board_to_table, _dot_diameters
from planarcal.synth.objects import SceneObject

F64 = NDArray[np.float64]


MarkKind = Literal["numbers", "cell_numbers", "arrows", "text", "crosses", "rings"]
"""The kinds of marks :func:`printed_marks` prints."""

MARK_KINDS: tuple[MarkKind, ...] = (
    "numbers",
    "cell_numbers",
    "arrows",
    "text",
    "crosses",
    "rings",
)

# Seven-segment digits: segments a (top), b (upper right), c (lower right), d (bottom),
# e (lower left), f (upper left), g (middle).
_DIGIT_SEGMENTS: tuple[str, ...] = ("abcdef", "bc", "abged", "abgcd", "fgbc", "afgcd")
_DIGIT_SEGMENTS += ("afgedc", "abc", "abcdefg", "abcdfg")
_DIGIT_WIDTH, _DIGIT_STROKE, _DIGIT_GAP = 0.55, 0.14, 0.25  # times the digit's height


def printed_marks(
    board: CircleGridBoard,
    kinds: MarkKind | Sequence[MarkKind] = MARK_KINDS,
    seed: int = 0,
    *,
    paper_margin_mm: float = 15.0,
    enlarged_dots: Mapping[int, float] | None = None,
) -> tuple[SceneObject, ...]:
    """Ink marks printed on a board's paper, as flat shapes in board coordinates, to pass as
    ``render_scene(marks=...)``: decoration that a detector must ignore, never part of the
    truth. Every shape is a thin rectangle (a :class:`SceneObject`); none touches a dot or
    leaves the paper (``paper_margin_mm`` and ``enlarged_dots`` must be render_scene's).

    ``kinds`` (one or several):

    * ``"numbers"``: column numbers above the first row and row numbers left of the first
      column (from 0), seven-segment digits in the outer half of the paper's margin.
    * ``"cell_numbers"``: dot numbers inside the grid, in the free space between dots (each
      beside the dot whose index it is), in about a third of those spaces (``seed`` picks).
    * ``"arrows"``: axis arrows in the inner half of the margin, along the first row (+X)
      and the first column (+Y), each about three dot spacings long.
    * ``"text"``: a line of text-like bars (letters of random widths and heights, in words)
      in the margin below the grid.
    * ``"crosses"``: small plus marks in about a quarter of the spaces between dots.
    * ``"rings"``: circles around a few dots (about one in ten, at least one), halfway to
      the nearest neighbour.

    The same arguments always give the same marks.
    """
    if not isinstance(board, CircleGridBoard):
        raise BoardError(f"board must be a CircleGridBoard, got {type(board).__name__}")
    wanted = (kinds,) if isinstance(kinds, str) else tuple(kinds)
    for kind in wanted:
        if kind not in MARK_KINDS:
            raise ArgumentError(f"kinds must be among {', '.join(MARK_KINDS)}; got {kind!r}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ArgumentError(f"seed must be a non-negative whole number, got {seed!r}")
    margin = arguments.real("paper_margin_mm", paper_margin_mm, BoardError)
    outside = {"numbers", "arrows", "text"} & set(wanted)
    if outside and margin <= 0.0:
        raise BoardError(f"{', '.join(sorted(outside))} need a paper margin, got {margin!r}")
    grid = _MarkGrid(board, _dot_diameters(board, enlarged_dots), margin, int(seed))
    makers = {
        "numbers": grid.numbers,
        "cell_numbers": grid.cell_numbers,
        "arrows": grid.arrows,
        "text": grid.text,
        "crosses": grid.crosses,
        "rings": grid.rings,
    }
    marks: list[SceneObject] = []
    for kind in MARK_KINDS:  # a fixed order: the same marks whatever order kinds come in
        if kind in wanted:
            marks.extend(makers[kind]())
    return tuple(marks)


def _bar(start: ArrayLike, end: ArrayLike, width: float) -> SceneObject:
    """A straight stroke ``width`` wide from start to end (its ends square, at the points)."""
    a, b = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    mid, d = 0.5 * (a + b), b - a
    return SceneObject(
        "rectangle",
        (float(mid[0]), float(mid[1])),
        angle_deg=math.degrees(math.atan2(d[1], d[0])),
        size_mm=width,
        length_mm=max(float(np.hypot(*d)), width),
    )


def _number_width(digits: int) -> float:
    """The width of a number of ``digits`` digits, times the digits' height."""
    return digits * _DIGIT_WIDTH + (digits - 1) * _DIGIT_GAP


def _number(value: int, centre: ArrayLike, height: float) -> list[SceneObject]:
    """``value`` in seven-segment digits ``height`` tall, centred on ``centre``."""
    text = str(value)
    w, st = _DIGIT_WIDTH * height, _DIGIT_STROKE * height
    cx, cy = np.asarray(centre, dtype=np.float64)
    left = cx - 0.5 * _number_width(len(text)) * height
    bars = []
    for k, ch in enumerate(text):
        x0 = left + k * (_DIGIT_WIDTH + _DIGIT_GAP) * height + st / 2.0
        x1 = x0 + w - st
        y0, ym, y1 = cy - (height - st) / 2.0, cy, cy + (height - st) / 2.0
        ends = {
            "a": ((x0, y0), (x1, y0)),
            "b": ((x1, y0), (x1, ym)),
            "c": ((x1, ym), (x1, y1)),
            "d": ((x0, y1), (x1, y1)),
            "e": ((x0, ym), (x0, y1)),
            "f": ((x0, y0), (x0, ym)),
            "g": ((x0, ym), (x1, ym)),
        }
        for seg in _DIGIT_SEGMENTS[int(ch)]:
            (ax, ay), (bx, by) = ends[seg]
            # Each stroke reaches half its width past its end points, so corners are filled.
            ux, uy = np.sign(bx - ax), np.sign(by - ay)
            h = st / 2.0
            bars.append(_bar((ax - ux * h, ay - uy * h), (bx + ux * h, by + uy * h), st))
    return bars


class _MarkGrid:
    """Where marks go on a board's paper (board coordinates, mm): bands of the margin
    around the dots, and the free spaces between dots, shared out so that no two kinds of
    marks meet whichever are asked for."""

    # Bands of the margin, as fractions of it out from the dots' outer edges: the arrows'
    # centre line, the numbers' and the text's.
    ARROWS, NUMBERS, TEXT = 0.3, 0.7, 0.5

    def __init__(self, board: CircleGridBoard, diameters: F64, margin: float, seed: int) -> None:
        self.board, self.margin = board, margin
        self.pts = board.world_points()
        self.radii = diameters / 2.0
        self.nominal = float(board.dots_mm())
        big = float(self.radii.max())
        lo, hi = self.pts.min(axis=0), self.pts.max(axis=0)
        self.left, self.top = float(lo[0]) - big, float(lo[1]) - big
        self.right, self.bottom = float(hi[0]) + big, float(hi[1]) + big
        self.x0, self.y0 = float(lo[0]), float(lo[1])
        self.row0 = self.pts[: board.cols]  # the first row's dots
        self.spacing = float(np.min(np.diff(self.row0[:, 0])))  # along a row
        self.holes, self.room, self.owner = self._free_spaces()
        # One draw shares everything out, the same whichever kinds are asked for: a tenth of
        # the dots get rings; of the free spaces clear of them, a third get numbers and a
        # quarter crosses.
        rng = np.random.default_rng([seed, 7])
        self.ringed = np.sort(rng.permutation(len(self.pts))[: max(1, len(self.pts) // 10)])
        self.ring_outer = self.radii + self._ring_band() * 0.45
        clear = self._clear_of_rings()
        order = rng.permutation(len(self.holes))
        order = order[clear[order]]
        n_numbers = max(1, len(order) // 3) if len(order) else 0
        n_crosses = max(1, len(order) // 4) if len(order) > 1 else 0
        self.numbered = np.sort(order[:n_numbers])
        self.crossed = np.sort(order[n_numbers : n_numbers + n_crosses])
        self.text_rng = np.random.default_rng([seed, 8])

    def _free_spaces(self) -> tuple[F64, F64, NDArray[np.intp]]:
        """The points between dots farthest from them (the centres of the squares of four
        dots; in the asymmetric layout the empty lattice points between two dots of a row),
        how far the nearest dot's edge is from each, and the dot each lies beside."""
        b, p = self.board, float(self.board.pitch)
        if b.layout == "asymmetric":
            c, r = np.meshgrid(np.arange(b.cols - 1), np.arange(b.rows))
            holes = np.column_stack([((2 * c + r % 2 + 1) * p).ravel(), (r * p).ravel()])
        else:
            c, r = np.meshgrid(np.arange(b.cols - 1), np.arange(b.rows - 1))
            holes = np.column_stack([((c + 0.5) * p).ravel(), ((r + 0.5) * p).ravel()])
        owner = (r * b.cols + c).ravel()
        gaps = np.linalg.norm(holes[:, None, :] - self.pts[None], axis=2) - self.radii[None]
        return holes, gaps.min(axis=1), owner

    def _ring_band(self) -> F64:
        """For each dot, the gap between its edge and the nearest other dot's."""
        d = np.linalg.norm(self.pts[:, None, :] - self.pts[None], axis=2) - self.radii[None]
        np.fill_diagonal(d, np.inf)
        return np.asarray(d.min(axis=1) - self.radii, dtype=np.float64)

    def _clear_of_rings(self) -> NDArray[np.bool_]:
        """Which free spaces keep their marks (at most 3/4 of their room out) off the rings."""
        c = self.pts[self.ringed]
        d = np.linalg.norm(self.holes[:, None, :] - c[None], axis=2) - self.ring_outer[self.ringed]
        return np.asarray((d > 0.8 * self.room[:, None]).all(axis=1))

    def _cell_digit_height(self) -> float:
        """One height for all numbers between dots: the longest fits in 3/4 of the smallest
        room (its half-diagonal), and none is much larger than a dot."""
        if not len(self.numbered):
            return 0.0
        digits = len(str(int(self.owner[self.numbered].max())))
        half_diagonal = 0.5 * math.hypot(_number_width(digits), 1.0)
        room = float(self.room[self.numbered].min())
        return min(0.75 * room / half_diagonal, 1.2 * self.nominal)

    def numbers(self) -> list[SceneObject]:
        m, b = self.margin, self.board
        # One height for both: column labels as tall as the band allows and narrower than
        # the gap between two of them, row labels as wide as the band and shorter than the
        # rows' spacing.
        h = min(
            0.36 * m,
            0.8 * self.spacing / _number_width(len(str(b.cols - 1))),
            0.36 * m / _number_width(len(str(b.rows - 1))),
            0.8 * float(b.pitch),
        )
        marks: list[SceneObject] = []
        for c, (x, _) in enumerate(self.row0):
            marks += _number(c, (x, self.top - self.NUMBERS * m), h)
        for r in range(b.rows):
            marks += _number(r, (self.left - self.NUMBERS * m, r * float(b.pitch)), h)
        return marks

    def cell_numbers(self) -> list[SceneObject]:
        h = self._cell_digit_height()
        marks: list[SceneObject] = []
        for k in self.numbered:
            marks += _number(int(self.owner[k]), self.holes[k], h)
        return marks

    def arrows(self) -> list[SceneObject]:
        m = self.margin
        width = 0.06 * m
        span_x = min(3.0 * self.spacing, self.right - self.x0)
        span_y = min(3.0 * float(self.board.pitch), self.bottom - self.y0)
        y, x = self.top - self.ARROWS * m, self.left - self.ARROWS * m
        return _arrow((self.x0, y), (self.x0 + span_x, y), width) + _arrow(
            (x, self.y0), (x, self.y0 + span_y), width
        )

    def text(self) -> list[SceneObject]:
        rng = self.text_rng
        m = self.margin
        h = 0.2 * m  # the x-height; ascenders are 1.5 times as tall
        base = self.bottom + self.TEXT * m + h / 2.0  # the line the letters stand on
        x, end = self.left, self.left + 0.8 * (self.right - self.left)
        marks: list[SceneObject] = []
        while True:
            for _ in range(int(rng.integers(2, 8))):
                w = h * float(rng.uniform(0.15, 0.6))
                tall = h * (1.5 if rng.uniform() < 0.3 else 1.0)
                if x + w > end:
                    return marks
                centre = (x + w / 2.0, base - tall / 2.0)
                marks.append(
                    SceneObject("rectangle", centre, angle_deg=90.0, size_mm=w, length_mm=tall)
                )
                x += w + 0.25 * h
            x += 0.8 * h

    def crosses(self) -> list[SceneObject]:
        marks: list[SceneObject] = []
        for k in self.crossed:
            (x, y), arm = self.holes[k], min(0.6 * float(self.room[k]), self.nominal)
            width = 0.2 * arm
            marks += [
                _bar((x - arm, y), (x + arm, y), width),
                _bar((x, y - arm), (x, y + arm), width),
            ]
        return marks

    def rings(self) -> list[SceneObject]:
        """Each ring: 32 chords, the stroke from 0.25 to 0.45 of the gap out from the dot."""
        gaps = self._ring_band()
        chords = 32
        marks: list[SceneObject] = []
        for k in self.ringed:
            width = 0.2 * float(gaps[k])
            rho = float(self.radii[k]) + 0.35 * float(gaps[k])  # the stroke's middle
            length = 2.0 * (rho + width / 2.0) * math.tan(math.pi / chords)
            for a in 2.0 * math.pi * np.arange(chords) / chords:
                centre = self.pts[k] + rho * np.array([math.cos(a), math.sin(a)])
                marks.append(
                    SceneObject(
                        "rectangle",
                        (float(centre[0]), float(centre[1])),
                        angle_deg=math.degrees(a) + 90.0,
                        size_mm=width,
                        length_mm=length,
                    )
                )
        return marks


def _arrow(start: ArrayLike, tip: ArrayLike, width: float) -> list[SceneObject]:
    """A shaft from start to tip and two barbs 30 degrees off it at the tip."""
    a, b = np.asarray(start, dtype=np.float64), np.asarray(tip, dtype=np.float64)
    d = (b - a) / float(np.hypot(*(b - a)))
    barb = 4.0 * width
    bars = [_bar(a, b, width)]
    for turn in (150.0, -150.0):
        t = math.radians(turn)
        back = np.array(
            [d[0] * math.cos(t) - d[1] * math.sin(t), d[0] * math.sin(t) + d[1] * math.cos(t)]
        )
        bars.append(_bar(b + back * width / 2.0, b + back * barb, width))
    return bars


def _mark_on_table(mark: SceneObject, origin: tuple[float, float], angle: float) -> SceneObject:
    """A mark given in board coordinates, placed on the table with the board."""
    at = _board_to_table(np.array([mark.position_mm]), origin, angle)[0]
    return dataclasses.replace(
        mark, position_mm=(float(at[0]), float(at[1])), angle_deg=float(mark.angle_deg) + angle
    )
