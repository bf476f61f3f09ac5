"""The coverage view: where the board has been laid, and where to lay it next.

A calibration from several placements of one board (a fixed camera, one image per placement)
maps the image well near its placements and by extrapolation beyond them. This module
measures that as a function of the placements alone (their pixels and the calibration's
predicted 1-sigma error at any pixel), so that the report, the command-line summary and a live
page that recomputes it after each placement share one answer: the predicted error over the
whole image on a fine grid, each placement's outline, the share of the image they cover, and
the largest connected region whose predicted error is above a limit, with a sentence saying
where it is. Pixels with no place on the plane (beyond its horizon, or the lens model's reach)
count as above any limit.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.arguments import F64
from planarcal.calib import frame_size
from planarcal.calib.extrapolation import convex_hull
from planarcal.errors import ArgumentError, ArgumentTypeError

MAP_NODES = 321
"""Grid nodes along the image's longer side (the shorter in proportion, the same step), the
image's corners and edges among them: the predicted error is smooth, so a step of 4 px at
1280 x 720 (12 px at 4K) interpolates it to well under 1 % while costing some 58 000
evaluations (about 10 ms with a lens model on one core)."""

MIN_STEP_PX = 4.0
"""The finest grid step, px: a small image gains nothing from a finer one."""

DEFAULT_LIMIT_FACTOR = 2.0
"""Without a limit given, the limit is this many times the largest predicted error at the
placements' points: the image is covered where it is mapped about as well as where the board
was laid, and what lies beyond twice that is worth a placement."""

MOST_OF_THE_IMAGE = 0.5
"""A region covering at least this share of the image is described as most of it, around
the part where a board would best go."""

NAMING_SHARE = 0.5
"""A region is named by the thirds of the image (its 3 x 3 cells) that hold at least this
share of what the cell holding most of it holds: a strip down the left side holds its three
left cells alike (the left edge), a patch in a corner mostly its corner's."""


@dataclasses.dataclass(frozen=True)
class Region:
    """A connected region of the image whose predicted error is above the limit."""

    share: float
    """The share of the image it covers (0 to 1)."""
    bbox_px: tuple[int, int, int, int]
    """(x0, y0, x1, y1): its bounding box, the pixels image[y0:y1, x0:x1] (columns x0 to
    x1 - 1, rows y0 to y1 - 1; within 0..width, 0..height)."""
    centroid_px: tuple[float, float]
    """Its centroid in px (of an L-shaped region, possibly outside it)."""
    target_px: tuple[float, float]
    """Where to centre the board next, px (always inside the region): its node of the worst
    predicted error among those a placement's reach (``board_reach_px``) from its edges and
    the image's, or, when none is that far in, its node farthest in."""
    worst_std_mm: float
    """The largest predicted 1-sigma error in it, mm (inf where part has no place)."""
    worst_at_px: tuple[float, float]
    """Where that largest error is, px."""
    part: str
    """The part of the image to put the board in next ("bottom-right corner", "top edge",
    "centre"): the third of the image, across and down, holding `target_px`."""
    outline_px: tuple[F64, ...]
    """Its outline in the image: closed polylines (M, 2) in px, through the grid's nodes."""
    mask: NDArray[np.bool_]
    """(ny, nx): its nodes on the coverage's grid."""

    @property
    def spread(self) -> bool:
        """Whether it is no one part of the image: it covers most of it (MOST_OF_THE_IMAGE),
        or reaches across it both ways (around the placements)."""
        ny, nx = self.mask.shape
        columns, rows = self.mask.any(axis=0).sum(), self.mask.any(axis=1).sum()
        return self.share >= MOST_OF_THE_IMAGE or bool(columns > 0.9 * nx and rows > 0.9 * ny)

    @property
    def name(self) -> str:
        """The part of the image the region lies in (see NAMING_SHARE): a corner
        ("bottom-left corner"), a side ("left edge": a strip along it, or a patch on it), the
        centre; one along several sides, "bottom and left edges"; else "middle"."""
        ny, nx = self.mask.shape
        rows, cols = np.nonzero(self.mask)
        cells = np.zeros((3, 3))
        np.add.at(cells, (_thirds(rows, ny), _thirds(cols, nx)), 1.0)
        return _named(cells >= NAMING_SHARE * cells.max())

    def where(self) -> str:
        """The region named in words with its extent: "the bottom-right corner of the image
        (x 900-1280 px, y 540-720 px, 14 % of the image)", "the left edge of the image (x
        0-230 px, y 0-720 px, 18 % ...)"; one spread over the image, "most of the image
        (...)" or "the image around the placements (...)"."""
        x0, y0, x1, y1 = self.bbox_px
        extent = f"x {x0}-{x1} px, y {y0}-{y1} px, {_percent(self.share)}"
        if self.share >= MOST_OF_THE_IMAGE:
            return f"most of the image ({extent})"
        if self.spread:
            return f"the image around the placements ({extent})"
        return f"the {self.name} of the image ({extent})"

    def advice(self) -> str:
        """Where to put the board next: "put the board there next, centred near (1183,
        623) px"; where the region is more than that part (spread over the image, a strip
        along a side), which part of it."""
        where = "there"
        if self.spread or self.name != self.part:
            where = f"{'at' if self.part.endswith('edge') else 'in'} its {self.part}"
        tx, ty = self.target_px
        return f"put the board {where} next, centred near ({tx:.0f}, {ty:.0f}) px"


@dataclasses.dataclass(frozen=True)
class Coverage:
    """The predicted 1-sigma mapping error over a whole image, the placements' outlines and
    the largest region above a limit (see ``coverage``)."""

    image_size: tuple[int, int]
    """(width, height) of the image, px."""
    grid_x: F64
    """(nx,) the grid's columns, px (0 and width - 1 among them)."""
    grid_y: F64
    """(ny,) the grid's rows, px (0 and height - 1 among them)."""
    std_mm: F64
    """(ny, nx) the predicted 1-sigma error at each node, mm (inf where it has no place)."""
    outlines_px: tuple[F64, ...]
    """Each placement's outline in the image (the convex hull of its points), (M, 2) px."""
    covered_share: float
    """The share of the image inside at least one placement's outline (0 to 1)."""
    points_std_mm: float
    """The largest predicted 1-sigma error at the placements' points, mm; inf when the
    calibration predicts none there (no error bars: then no region is found)."""
    limit_mm: float
    """The limit, mm: the one given, or DEFAULT_LIMIT_FACTOR x points_std_mm."""
    limit_given: bool
    """Whether the limit was given (else it is the default)."""
    region: Region | None
    """The largest connected region whose predicted error is above the limit, None when the
    whole image is within it."""

    @property
    def image_std_mm(self) -> float:
        """The largest predicted 1-sigma error over the image, mm (inf where part of it has
        no place on the plane)."""
        return float(self.std_mm.max())

    @property
    def sentence(self) -> str:
        """Where the board is needed next, in one sentence: the largest region above the
        limit (where it is, how large, its worst predicted error, the limit), or that the
        whole image is within the limit."""
        limit = f"the {_mm(self.limit_mm)} limit" + (
            "" if self.limit_given else f" ({DEFAULT_LIMIT_FACTOR:g} x the error at the points)"
        )
        region = self.region
        if not math.isfinite(self.points_std_mm):
            return (
                "no predicted error: the calibration has no error bars at its placements' "
                "points (too few points to estimate them, or none with a place on the plane)"
            )
        if region is None:
            return (
                f"the predicted error is within {limit} over the whole image (up to "
                f"{_mm(self.image_std_mm)}, {_mm(self.points_std_mm)} at the placements' "
                "points)"
            )
        if math.isfinite(region.worst_std_mm):
            worst = f"predicted error up to {_mm(region.worst_std_mm)}, above {limit}"
        else:
            worst = (
                "part of it has no place on the plane (beyond its horizon or the lens "
                f"model's reach), the rest is above {limit}"
            )
        return f"{region.where()}: {worst}; {region.advice()}"

    def std_at(self, points_px: Any) -> F64:
        """The map's predicted 1-sigma (mm) at pixels (N, 2), interpolated bilinearly
        between the grid's nodes (inf next to a node with no place); pixels beyond the
        image take its edge's."""
        px, _ = arguments.points("points_px", points_px)
        x0, x1, fx = _cells(px[:, 0], self.grid_x)
        y0, y1, fy = _cells(px[:, 1], self.grid_y)
        m = self.std_mm
        return _lerp(_lerp(m[y0, x0], m[y0, x1], fx), _lerp(m[y1, x0], m[y1, x1], fx), fy)

    def std_image(self) -> F64:
        """The map at every pixel of the image, (height, width), interpolated bilinearly."""
        w, h = self.image_size
        x0, x1, fx = _cells(np.arange(w, dtype=np.float64), self.grid_x)
        y0, y1, fy = _cells(np.arange(h, dtype=np.float64), self.grid_y)
        m = self.std_mm
        rows = _lerp(m[:, x0], m[:, x1], fx[None, :])  # (ny, w)
        return _lerp(rows[y0], rows[y1], fy[:, None])

    def to_dict(self) -> dict[str, Any]:
        """The figures (not the map), JSON-ready (inf as None)."""
        out: dict[str, Any] = {
            "covered_share": self.covered_share,
            "placements": len(self.outlines_px),
            "points_std_mm": _num(self.points_std_mm),
            "image_std_mm": _num(self.image_std_mm),
            "limit_mm": _num(self.limit_mm),
            "limit_given": self.limit_given,
            "region": None,
            "sentence": self.sentence,
        }
        r = self.region
        if r is not None:
            out["region"] = {
                "share": r.share,
                "bbox_px": list(r.bbox_px),
                "centroid_px": list(r.centroid_px),
                "target_px": list(r.target_px),
                "worst_std_mm": _num(r.worst_std_mm),
                "worst_at_px": list(r.worst_at_px),
                "part": r.part,
            }
        return out


def map_grid(size: tuple[int, int]) -> tuple[F64, F64]:
    """The coverage grid of a `size` (width, height) image: (columns, rows) in px, the
    image's first and last pixels among them, the same step along both (MAP_NODES along the
    longer side, no finer than MIN_STEP_PX)."""
    w, h = size
    step = max(MIN_STEP_PX, (max(w, h) - 1.0) / (MAP_NODES - 1))

    def axis(n_px: int) -> F64:
        nodes = 1 if n_px == 1 else math.ceil((n_px - 1) / step) + 1
        return np.linspace(0.0, n_px - 1.0, nodes)

    return axis(w), axis(h)


def coverage(
    std_mm_at: Callable[[F64], F64],
    image_size: tuple[int, int],
    placements_px: Sequence[Any],
    max_error_mm: float | None = None,
) -> Coverage:
    """The coverage of a `image_size` (width, height) image by placements whose points are
    `placements_px` (one (N, 2) array of px per placement), given ``std_mm_at(px)``: the
    calibration's predicted 1-sigma error in mm at pixels (K, 2), pixel exact, inf (or NaN)
    where a pixel has no place on the plane. `max_error_mm`: the limit (mm, > 0); None takes
    DEFAULT_LIMIT_FACTOR times the largest predicted error at the placements' points.
    Raises ArgumentError on a bad argument, naming it."""
    if not callable(std_mm_at):
        raise ArgumentTypeError(
            f"std_mm_at must be a function of pixels (K, 2), got {type(std_mm_at).__name__}"
        )
    size = frame_size.given_size(image_size)
    placements = _placements(placements_px)
    limit = None if max_error_mm is None else arguments.positive("max_error_mm", max_error_mm)
    xs, ys = map_grid(size)
    gx, gy = np.meshgrid(xs, ys)
    nodes = np.column_stack([gx.ravel(), gy.ravel()])
    all_points = np.concatenate(placements)
    std = _evaluated(std_mm_at, np.concatenate([nodes, all_points]))
    grid_std = std[: len(nodes)].reshape(len(ys), len(xs))
    point_std = std[len(nodes) :]
    finite = point_std[np.isfinite(point_std)]
    points_std = float(finite.max()) if finite.size else math.inf
    if limit is None:
        limit = DEFAULT_LIMIT_FACTOR * points_std
    outlines = tuple(convex_hull(p) for p in placements)
    above = ~(grid_std <= limit)  # inf is above any limit
    if not math.isfinite(points_std):
        above[:] = False  # no error bars at all: nothing to compare (see Coverage.sentence)
    return Coverage(
        size,
        xs,
        ys,
        grid_std,
        outlines,
        _covered_share(outlines, size),
        points_std,
        limit,
        max_error_mm is not None,
        _largest_region(above, grid_std, xs, ys, size, board_reach_px(outlines)),
    )


def calibration_coverage(cal: Any, max_error_mm: float | None = None) -> Coverage:
    """The coverage of a Calibration's image by its placements (``cal.placements``; a
    calibration from one detection has one: its points), its predicted 1-sigma error that of
    ``image_to_world(..., return_std=True, pixel_sigma=0)`` (inf where a pixel has no place
    on the plane). See ``coverage``; ArgumentError without an image size."""
    size = getattr(cal, "image_size", None)
    if size is None:
        raise ArgumentError(
            "the calibration has no image size (it was made from points without "
            "image_size=): there is no image to cover"
        )
    placements = tuple(getattr(cal, "placements", None) or ())
    points = [p.image_px for p in placements] if placements else [cal.image_points]
    return coverage(cal.mapping_std_mm, size, points, max_error_mm)


def _placements(placements_px: Sequence[Any]) -> list[F64]:
    """The placements' points checked: a non-empty sequence of non-empty (N, 2) arrays."""
    if isinstance(placements_px, str | bytes | np.ndarray) or not isinstance(
        placements_px, Sequence
    ):
        raise ArgumentTypeError(
            "placements_px must be a sequence of (N, 2) arrays, one per placement, got "
            f"{type(placements_px).__name__}"
        )
    if not placements_px:
        raise ArgumentError("placements_px is empty: a coverage needs at least one placement")
    out = []
    for k, p in enumerate(placements_px):
        pts, _ = arguments.points(f"placements_px[{k}]", p)
        if not len(pts):
            raise ArgumentError(f"placements_px[{k}] has no points")
        out.append(pts)
    return out


def _evaluated(std_mm_at: Callable[[F64], F64], px: F64) -> F64:
    """std_mm_at(px) checked: (K,) non-negative, NaN taken as no place (inf)."""
    std = np.asarray(std_mm_at(np.ascontiguousarray(px)), dtype=np.float64)
    if std.shape != (len(px),):
        raise ArgumentError(
            f"std_mm_at must return one value per pixel, shape ({len(px)},), got {std.shape}"
        )
    std = np.where(np.isnan(std), np.inf, std)
    if (std < 0).any():
        raise ArgumentError(f"std_mm_at returned a negative error: {float(std.min())!r} mm")
    return std


def _covered_share(outlines: Sequence[F64], size: tuple[int, int]) -> float:
    """The share of the image inside at least one of the convex `outlines` (drawn at the
    image's resolution, 1/16 px vertices)."""
    w, h = size
    mask = np.zeros((h, w), np.uint8)
    for hull in outlines:
        if len(hull) >= 3:
            pts = np.rint(hull * 16.0).astype(np.int32)
            cv2.fillConvexPoly(mask, pts, 1, cv2.LINE_8, 4)
    return float(cv2.countNonZero(mask)) / float(w * h)


def _cell_edges(nodes: F64, n_px: int) -> F64:
    """The edges of the pixels each node stands for: midway between nodes, the image's own
    edges (-0.5, n_px - 0.5) outside."""
    return np.concatenate([[-0.5], 0.5 * (nodes[1:] + nodes[:-1]), [n_px - 0.5]])


def board_reach_px(outlines: Sequence[F64]) -> float:
    """How far a placement reaches from its centre in the image, px: half the side of the
    square of its outline's area (the median over the placements; 0 for outlines of fewer
    than three points)."""
    areas = [abs(float(cv2.contourArea(o.astype(np.float32)))) for o in outlines if len(o) >= 3]
    return 0.5 * math.sqrt(float(np.median(areas))) if areas else 0.0


def _largest_region(
    above: NDArray[np.bool_],
    std: F64,
    xs: F64,
    ys: F64,
    size: tuple[int, int],
    reach_px: float,
) -> Region | None:
    """The largest (by area) 8-connected region of the grid's nodes `above` the limit;
    `reach_px`: how far a board reaches from its centre (for the region's target)."""
    if not above.any():
        return None
    w, h = size
    ex, ey = _cell_edges(xs, w), _cell_edges(ys, h)
    area = np.outer(np.diff(ey), np.diff(ex))
    count, labels = cv2.connectedComponents(above.astype(np.uint8), connectivity=8)
    areas = np.bincount(labels.ravel(), weights=area.ravel(), minlength=count)
    areas[0] = -1.0  # the nodes within the limit
    mask = labels == int(np.argmax(areas))
    rows, cols = np.nonzero(mask)
    # Pixel k spans k - 0.5 to k + 0.5: the box's edges as slice bounds.
    bbox = (
        round(float(ex[cols.min()]) + 0.5),
        round(float(ey[rows.min()]) + 0.5),
        round(float(ex[cols.max() + 1]) + 0.5),
        round(float(ey[rows.max() + 1]) + 0.5),
    )
    weights = area[rows, cols]
    centroid = (
        float(np.average(xs[cols], weights=weights)),
        float(np.average(ys[rows], weights=weights)),
    )
    worst = int(np.argmax(np.where(mask, std, -1.0)))
    wy, wx = np.unravel_index(worst, mask.shape)
    target = _target(mask, std, xs, ys, reach_px)
    return Region(
        float(areas.max()) / float(w * h),
        bbox,
        centroid,
        target,
        float(std[wy, wx]),
        (float(xs[wx]), float(ys[wy])),
        _part(target, size),
        _outline(mask, xs, ys),
        mask,
    )


def _target(
    mask: NDArray[np.bool_], std: F64, xs: F64, ys: F64, reach_px: float
) -> tuple[float, float]:
    """Where in the region to centre the board next (see ``Region.target_px``)."""
    # Each node's distance to the region's edge or the image's (a border of nodes outside).
    padded = np.pad(mask.astype(np.uint8), 1)
    depth = cv2.distanceTransform(padded, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)[1:-1, 1:-1]
    step = float(np.mean([np.diff(a).mean() for a in (xs, ys) if len(a) > 1] or [1.0]))
    depth_px = np.where(mask, depth * step, -1.0)
    room = depth_px >= reach_px
    if not room.any():
        room = depth_px == depth_px.max()
    # The worst error there; among equals (several with no place) the deepest, then the
    # nearest the region's middle.
    key = np.where(room, std, -1.0).ravel()
    best = np.flatnonzero(key == key.max())
    rows, cols = np.unravel_index(best, mask.shape)
    rr, cc = np.nonzero(mask)
    off_middle = np.hypot(xs[cols] - xs[cc].mean(), ys[rows] - ys[rr].mean())
    k = int(np.lexsort((off_middle, -depth_px.ravel()[best]))[0])
    return float(xs[cols[k]]), float(ys[rows[k]])


def _part(px: tuple[float, float], size: tuple[int, int]) -> str:
    """The part of the image (by its thirds) holding `px`: a corner, an edge or the centre."""
    w, h = size
    col = min(2, int(3.0 * (px[0] + 0.5) / w))
    row = min(2, int(3.0 * (px[1] + 0.5) / h))
    return _part_name(("top", None, "bottom")[row], ("left", None, "right")[col])


def _thirds(index: NDArray[np.intp], n: int) -> NDArray[np.intp]:
    """The third (0, 1, 2) of an axis of `n` evenly spaced nodes holding each node `index`."""
    return np.minimum(2, (3.0 * (index + 0.5) / n).astype(np.intp))


def _named(held: NDArray[np.bool_]) -> str:
    """The name of the part of the image made of the `held` thirds (3 x 3, rows down)."""
    rows, cols = np.flatnonzero(held.any(axis=1)), np.flatnonzero(held.any(axis=0))
    vertical = ("top", None, "bottom")
    horizontal = ("left", None, "right")
    if len(rows) == 1 and len(cols) == 1:
        return _part_name(vertical[rows[0]], horizontal[cols[0]])
    # Along one side: a strip, or a patch on it reaching over two of its thirds.
    if len(cols) == 1 and horizontal[cols[0]]:
        return f"{horizontal[cols[0]]} edge"
    if len(rows) == 1 and vertical[rows[0]]:
        return f"{vertical[rows[0]]} edge"
    # Along several sides (an L, a U): those with two of their three thirds held.
    along = (("top", held[0]), ("bottom", held[2]), ("left", held[:, 0]), ("right", held[:, 2]))
    sides = [side for side, cells in along if cells.sum() >= 2]
    if len(sides) == 1:
        return f"{sides[0]} edge"
    if sides:
        return f"{', '.join(sides[:-1])} and {sides[-1]} edges"
    return "centre" if held[1, 1] else "middle"


def _part_name(vertical: str | None, horizontal: str | None) -> str:
    """One third across and one down: a corner, an edge or the centre."""
    if vertical and horizontal:
        return f"{vertical}-{horizontal} corner"
    if vertical or horizontal:
        return f"{vertical or horizontal} edge"
    return "centre"


def _outline(mask: NDArray[np.bool_], xs: F64, ys: F64) -> tuple[F64, ...]:
    """The region's outer outline(s) and those of its holes, through its edge nodes, px."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
    out = []
    for c in contours:
        ij = c.reshape(-1, 2)
        out.append(np.column_stack([xs[ij[:, 0]], ys[ij[:, 1]]]))
    return tuple(out)


def _cells(v: F64, nodes: F64) -> tuple[NDArray[np.intp], NDArray[np.intp], F64]:
    """For positions `v` (px) along an axis of evenly spaced grid `nodes`: the nodes on
    either side of each (clipped to the grid) and the fraction of the way from one to the
    other."""
    if len(nodes) == 1:
        zero = np.zeros(len(v), np.intp)
        return zero, zero, np.zeros(len(v))
    step = (nodes[-1] - nodes[0]) / (len(nodes) - 1)
    pos = np.clip((v - nodes[0]) / step, 0.0, len(nodes) - 1.0)
    i = np.minimum(pos.astype(np.intp), len(nodes) - 2)
    return i, i + 1, pos - i


def _lerp(a: F64, b: F64, t: F64) -> F64:
    """(1 - t) a + t b, inf when either end with a weight is inf (no inf - inf)."""
    with np.errstate(invalid="ignore"):
        mixed = (1.0 - t) * a + t * b
        return np.asarray(np.where(t == 0.0, a, np.where(t == 1.0, b, mixed)), np.float64)


def _mm(v: float) -> str:
    """A length in mm to two significant figures, without an exponent."""
    if not math.isfinite(v):
        return "no place (inf)"
    if v >= 100:
        return f"{v:.0f} mm"
    return f"{float(f'{v:.2g}'):g} mm"


def _percent(share: float) -> str:
    return "under 1 % of the image" if share < 0.005 else f"{100.0 * share:.0f} % of the image"


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None
