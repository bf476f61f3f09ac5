"""The coverage figure: the image, dimmed, under the calibration's predicted 1-sigma mapping
error (mm) as a colour map with its scale, each placement's outline numbered, the largest
region above the limit outlined with where to put the board next, and a title saying so.
Drawn with OpenCV at the image's own size (text scaled to it), so a live page can draw it
per frame; PNG bytes out for the report."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.calib.calibration import Calibration
from planarcal.calib.coverage import Coverage, calibration_coverage
from planarcal.images import as_grey
from planarcal.report.drawing import png_bytes
from planarcal.report.labels import Box

U8 = NDArray[np.uint8]
F64 = NDArray[np.float64]

REGION_BGR = (0, 0, 255)
"""The outline of the largest region above the limit, and the cross where the board goes
next: pure red, which the colour map (viridis) never is."""
PLACEMENT_BGR = (255, 255, 255)
HALO_BGR = (0, 0, 0)
MAP_ALPHA = 0.6
"""How much of the colour map covers the dimmed image."""
SHORT_NAME = 16
"""A placement's name is written beside its number when at most this long."""
FONT = cv2.FONT_HERSHEY_SIMPLEX


def coverage_figure(
    cal: Calibration, image: Any = None, *, max_error_mm: float | None = None
) -> bytes:
    """The coverage figure of a calibration (``calibration_coverage``) over `image` (one of
    its images, dimmed; a plain grey background when None or of another size), as PNG bytes
    of the image's size."""
    cov = calibration_coverage(cal, max_error_mm)
    return png_bytes(draw_coverage(image, cov, placement_labels(cal)))


def placements_under(images: Sequence[Any]) -> Any:
    """What the coverage is drawn over for several placements' images: their brightest
    pixels, each board where it lay (the paper over the table); one image as it is."""
    if len(images) > 1:
        return np.max(np.stack([as_grey(im) for im in images]), axis=0)
    return images[0] if images else None


def placement_labels(cal: Any) -> list[str]:
    """Each placement's label: its index (0-based) and, when short, its name."""
    placements = tuple(getattr(cal, "placements", None) or ())
    if not placements:
        return ["0"]
    out = []
    for k, p in enumerate(placements):
        index = getattr(p, "index", k)
        name = str(getattr(p, "name", "") or "")
        named = name and name != f"placement {index}" and len(name) <= SHORT_NAME
        out.append(f"{index} {name}" if named else str(index))
    return out


def draw_coverage(
    image: Any,
    cov: Coverage,
    labels: Sequence[str] | None = None,
    *,
    text_boxes: list[Box] | None = None,
) -> U8:
    """The coverage drawn over `image` (grey or BGR, dimmed; a plain grey background when
    None or not of the coverage's image size): BGR, the image's size. `labels`: one per
    placement (default: their indices). `text_boxes`, when given, receives the text panels'
    boxes (none overlaps another)."""
    w, h = cov.image_size
    s = max(0.9, max(w, h) / 1280.0)  # text and lines relative to a 1280-pixel-wide image
    canvas = _background(image, (w, h))
    norm = _Scale(cov)
    # Drawn from the grid, interpolated at the image's size by OpenCV (a 4K image in tens
    # of ms): colours between nodes, the no-place mask where a node with weight has none.
    finite_grid = np.isfinite(cov.std_mm)
    finite = _upsampled(cov, finite_grid.astype(np.uint8) * 255, cv2.INTER_LINEAR) == 255
    if finite.any():
        levels = cv2.applyColorMap(norm.level(cov.std_mm), cv2.COLORMAP_VIRIDIS)
        colour = _upsampled(cov, levels, cv2.INTER_LINEAR)
        mixed = cv2.addWeighted(canvas, 1.0 - MAP_ALPHA, colour, MAP_ALPHA, 0.0)
        cv2.copyTo(mixed, finite.astype(np.uint8), canvas)
    names = list(labels) if labels is not None else [str(k) for k in range(len(cov.outlines_px))]
    centres = [_placement(canvas, hull, s) for hull in cov.outlines_px]
    region = cov.region
    if region is not None:
        thick = max(2, round(2 * s))
        for run in _region_outline(cov):
            pts = [run.reshape(-1, 1, 2)]
            cv2.polylines(canvas, pts, False, (255, 255, 255), thick + 2, cv2.LINE_AA)
            cv2.polylines(canvas, pts, False, REGION_BGR, thick, cv2.LINE_8)
        tx, ty = (round(v) for v in region.target_px)
        cv2.drawMarker(canvas, (tx, ty), REGION_BGR, cv2.MARKER_CROSS, int(24 * s), thick)
    # The panels, the title and scale first: a placement's label or "next" goes where it
    # covers neither them nor another label (moved down, up, right or left when it would).
    panels = [_title(canvas, cov, s)]
    panels.append(_scale_bar(canvas, norm, cov, s, has_no_place=not finite.all(), avoid=panels))
    for k, centre in enumerate(centres):
        if centre is not None:
            label = names[k] if k < len(names) else str(k)
            (tw, th), _ = cv2.getTextSize(label, FONT, 0.65 * s, max(1, round(2 * s)))
            org = (round(centre[0] - tw / 2), round(centre[1] + th / 2))
            panels.append(_free_text(canvas, [label], org, s, panels, big=True))
    if region is not None:
        tx, ty = (round(v) for v in region.target_px)
        org = (tx + int(8 * s), ty - int(8 * s))
        panels.append(_free_text(canvas, ["next"], org, s, panels))
    if text_boxes is not None:
        text_boxes.extend(panels)
    return canvas


def _upsampled(cov: Coverage, grid: NDArray[Any], interpolation: int) -> NDArray[Any]:
    """A (ny, nx[, 3]) array on the coverage's grid at the image's size, node (i, j) on
    pixel (grid_x[j], grid_y[i]) exactly, the edges' values carried beyond."""
    w, h = cov.image_size
    ny, nx = grid.shape[:2]
    to_grid = np.array([[(nx - 1) / max(w - 1, 1), 0.0, 0.0], [0.0, (ny - 1) / max(h - 1, 1), 0.0]])
    flags = interpolation | cv2.WARP_INVERSE_MAP
    return np.asarray(
        cv2.warpAffine(grid, to_grid, (w, h), flags=flags, borderMode=cv2.BORDER_REPLICATE)
    )


NO_PLACE = 1e30
"""Stands for inf (no place on the plane) in the float32 map the outline is traced on."""


def _region_outline(cov: Coverage) -> list[NDArray[np.int32]]:
    """The largest region's outline at the image's resolution, (M, 2) int px runs: the
    pixels above the limit (by the interpolated map) near the region's grid nodes, traced,
    the stretches along the image's border left out (the region runs on beyond it)."""
    region = cov.region
    assert region is not None
    w, h = cov.image_size
    # The region's nodes grown by one, so that it reaches its edge between nodes.
    grown = cv2.dilate(region.mask.astype(np.uint8), np.ones((3, 3), np.uint8))
    near = _upsampled(cov, grown, cv2.INTER_NEAREST)
    field = np.minimum(cov.std_mm, NO_PLACE).astype(np.float32)
    above = _upsampled(cov, field, cv2.INTER_LINEAR) > cov.limit_mm
    mask = (near.astype(bool) & above).astype(np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    runs = []
    for c in contours:
        pts = np.asarray(c.reshape(-1, 2), np.int32)
        border = (pts[:, 0] <= 0) | (pts[:, 0] >= w - 1) | (pts[:, 1] <= 0) | (pts[:, 1] >= h - 1)
        runs += _inner_runs(pts, border)
    return runs


def _inner_runs(pts: NDArray[np.int32], border: NDArray[np.bool_]) -> list[NDArray[np.int32]]:
    """The closed polyline `pts` cut into the runs whose segments do not lie along the
    image's border (both ends on it)."""
    keep = ~(border & np.roll(border, -1))  # segment k: pts[k] -> pts[k + 1]
    if keep.all():
        return [np.vstack([pts, pts[:1]])]
    start = int(np.flatnonzero(~keep)[0]) + 1  # begin just after a dropped segment
    pts, keep = np.roll(pts, -start, axis=0), np.roll(keep, -start)
    closed = np.vstack([pts, pts[:1]])
    edges = np.flatnonzero(np.diff(np.concatenate([[0], keep.astype(np.int8), [0]])))
    return [closed[a : b + 1] for a, b in zip(edges[::2], edges[1::2], strict=True)]


class _Scale:
    """The colour scale: logarithmic when the map spans more than a factor of 8, else
    linear, from the map's smallest finite value to its largest."""

    def __init__(self, cov: Coverage) -> None:
        values = cov.std_mm[np.isfinite(cov.std_mm)]
        self.lo = float(values.min()) if values.size else 0.0
        self.hi = float(values.max()) if values.size else 1.0
        if not self.hi > self.lo:
            self.hi = self.lo + max(abs(self.lo), 1e-6)
        self.log = self.lo > 0 and self.hi > 8 * self.lo

    def fraction(self, v: F64) -> F64:
        """Where values fall on the scale, 0 (lo) to 1 (hi), clipped."""
        with np.errstate(divide="ignore", invalid="ignore"):
            if self.log:
                t = np.log(v / self.lo) / math.log(self.hi / self.lo)
            else:
                t = (v - self.lo) / (self.hi - self.lo)
        return np.clip(np.nan_to_num(t, nan=1.0, posinf=1.0), 0.0, 1.0)

    def level(self, v: F64) -> U8:
        """The colour map's 8-bit level of each value."""
        return np.rint(255.0 * self.fraction(v)).astype(np.uint8)

    def ticks(self) -> list[float]:
        """Round values (1, 2, 5 x 10^k; evenly spaced on a linear scale) on the scale."""
        if self.log:
            out = [
                m * 10.0**e
                for e in range(math.floor(math.log10(self.lo)), math.ceil(math.log10(self.hi)) + 1)
                for m in (1.0, 2.0, 5.0)
            ]
            return [v for v in out if self.lo <= v <= self.hi]
        step = _nice((self.hi - self.lo) / 4.0)
        first = math.ceil(self.lo / step) * step
        return [first + k * step for k in range(6) if first + k * step <= self.hi * (1 + 1e-9)]


def _nice(x: float) -> float:
    """The smallest of 1, 2, 5 x 10^k at or above x (x > 0)."""
    e = 10.0 ** math.floor(math.log10(x))
    return next(m * e for m in (1.0, 2.0, 5.0, 10.0) if m * e >= x * (1 - 1e-9))


def _background(image: Any, size: tuple[int, int]) -> U8:
    """The image as dimmed grey BGR, or plain grey when there is none of that size."""
    w, h = size
    grey: NDArray[np.float32] | None = None
    if image is not None:
        grey = as_grey(image)
        if grey.shape != (h, w):
            grey = None
    if grey is None:
        grey = np.full((h, w), 128.0, np.float32)
    dim = cv2.convertScaleAbs(grey, alpha=0.5, beta=30.0)  # 30 + grey / 2, saturated
    return np.asarray(cv2.cvtColor(dim, cv2.COLOR_GRAY2BGR), np.uint8)


def _placement(canvas: U8, hull: F64, s: float) -> tuple[float, float] | None:
    """A placement's outline (white on a dark halo); its middle, where its label goes."""
    if not len(hull):
        return None
    pts = [np.rint(hull * 16).astype(np.int32).reshape(-1, 1, 2)]
    thick = max(1, round(1.5 * s))
    cv2.polylines(canvas, pts, True, HALO_BGR, thick + 2, cv2.LINE_AA, 4)
    cv2.polylines(canvas, pts, True, PLACEMENT_BGR, thick, cv2.LINE_AA, 4)
    m = cv2.moments(hull.astype(np.float32))
    cx, cy = (m["m10"] / m["m00"], m["m01"] / m["m00"]) if m["m00"] else hull.mean(axis=0)
    return float(cx), float(cy)


def _free_text(
    canvas: U8,
    lines: Sequence[str],
    org: tuple[int, int],
    s: float,
    taken: Sequence[Box],
    *,
    big: bool = False,
) -> Box:
    """`_text_lines` at `org`, or moved by whole panels down, up, right or left (up to nine)
    to the first place where its panel overlaps none of `taken`; at `org` when none is."""
    box = _text_lines(canvas, lines, org, s, big=big, dry=True)
    dx, dy = box.x1 - box.x0 + 2, box.y1 - box.y0 + 2
    for k in range(10):
        for mx, my in ((0, 0),) if k == 0 else ((0, k), (0, -k), (k, 0), (-k, 0)):
            at = (org[0] + mx * dx, org[1] + my * dy)
            trial = _text_lines(canvas, lines, at, s, big=big, dry=True)
            if not any(trial.overlaps(t) for t in taken):
                return _text_lines(canvas, lines, at, s, big=big)
    return _text_lines(canvas, lines, org, s, big=big)


def _text_lines(
    canvas: U8,
    lines: Sequence[str],
    org: tuple[int, int],
    s: float,
    *,
    big: bool = False,
    dry: bool = False,
) -> Box:
    """Lines of dark text on a white panel, the first baseline at `org` (kept inside the
    image); the panel's box (`dry`: only that, nothing drawn)."""
    scale, thick = (0.65 * s, max(1, round(2 * s))) if big else (0.5 * s, max(1, round(s)))
    sizes = [cv2.getTextSize(t, FONT, scale, thick) for t in lines]
    line_h = max(th + base for (_, th), base in sizes) + int(4 * s)
    width = max(tw for (tw, _), _ in sizes)
    h, w = canvas.shape[:2]
    x = min(max(int(4 * s), org[0]), max(0, w - width - int(4 * s)))
    y = min(max(line_h, org[1]), max(line_h, h - line_h * len(lines)))
    top = y - line_h + int(4 * s)
    pad = int(3 * s)
    box = Box(
        max(0, x - pad),
        max(0, top - pad),
        min(w, x + width + pad + 1),
        min(h, top + line_h * len(lines) + 1),
    )
    if dry:
        return box
    cv2.rectangle(
        canvas, (x - pad, top - pad), (x + width + pad, top + line_h * len(lines)), (255,) * 3, -1
    )
    for k, text in enumerate(lines):
        cv2.putText(
            canvas, text, (x, y + k * line_h), FONT, scale, (20, 20, 20), thick, cv2.LINE_AA
        )
    return box


def _wrapped(text: str, width: int, s: float) -> list[str]:
    """The text broken between words into lines no wider than `width` px."""
    lines: list[str] = []
    for word in text.split(" "):
        trial = f"{lines[-1]} {word}" if lines else word
        if lines and cv2.getTextSize(trial, FONT, 0.5 * s, max(1, round(s)))[0][0] <= width:
            lines[-1] = trial
        else:
            lines.append(word)
    return lines


def _title(canvas: U8, cov: Coverage, s: float) -> Box:
    """The title: what the map is, the placements' coverage, and the sentence."""
    n = len(cov.outlines_px)
    head = (
        f"Predicted 1-sigma mapping error (mm, pixel exact); {n} placement"
        f"{' covers' if n == 1 else 's cover'} {100 * cov.covered_share:.0f} % of the image"
    )
    width = canvas.shape[1] - int(16 * s)
    sentence = cov.sentence
    lines = _wrapped(head, width, s) + _wrapped(sentence[0].upper() + sentence[1:], width, s)
    return _text_lines(canvas, lines, (int(8 * s), int(20 * s)), s)


def _scale_bar(
    canvas: U8,
    norm: _Scale,
    cov: Coverage,
    s: float,
    *,
    has_no_place: bool,
    avoid: Sequence[Box] = (),
) -> Box:
    """The colour scale, labelled in mm, with the limit marked, at the bottom-right."""
    h, w = canvas.shape[:2]
    bar_w, bar_h = int(16 * s), int(0.4 * h)
    ticks = norm.ticks()
    texts = [_tick(v) for v in ticks]
    label_w = max(
        [cv2.getTextSize(t, FONT, 0.45 * s, max(1, round(s)))[0][0] for t in texts] or [0]
    )
    title = "mm"
    notes = [f"red: limit {_tick(cov.limit_mm)}"] + (
        ["no colour: no place"] if has_no_place else []
    )
    note_w = max(cv2.getTextSize(t, FONT, 0.45 * s, max(1, round(s)))[0][0] for t in notes)
    pad = int(6 * s)
    panel_w = max(bar_w + label_w + 3 * pad, note_w + 2 * pad)
    panel_h = bar_h + int(22 * s) * (1 + len(notes)) + 2 * pad
    x0, y0 = _free_corner(cov, (w, h), (panel_w, panel_h), pad, avoid)
    cv2.rectangle(canvas, (x0, y0), (x0 + panel_w, y0 + panel_h), (255,) * 3, -1)
    thick = max(1, round(s))
    cv2.putText(canvas, title, (x0 + pad, y0 + int(18 * s)), FONT, 0.5 * s, (20,) * 3, thick)
    bx, by = x0 + pad, y0 + int(26 * s)
    levels = np.linspace(255, 0, bar_h).astype(np.uint8).reshape(-1, 1)
    strip = cv2.applyColorMap(np.repeat(levels, bar_w, axis=1), cv2.COLORMAP_VIRIDIS)
    canvas[by : by + bar_h, bx : bx + bar_w] = strip

    def y_of(v: float) -> int:
        return by + round((1.0 - float(norm.fraction(np.array([v]))[0])) * (bar_h - 1))

    for v, text in zip(ticks, texts, strict=True):
        y = y_of(v)
        cv2.line(canvas, (bx + bar_w, y), (bx + bar_w + int(4 * s), y), (20,) * 3, thick)
        cv2.putText(
            canvas, text, (bx + bar_w + pad, y + int(5 * s)), FONT, 0.45 * s, (20,) * 3, thick
        )
    if norm.lo <= cov.limit_mm <= norm.hi:
        y = y_of(cov.limit_mm)
        cv2.line(canvas, (bx - int(3 * s), y), (bx + bar_w + int(3 * s), y), REGION_BGR, 2 * thick)
    for k, note in enumerate(notes):
        y = by + bar_h + int(22 * s) * (k + 1)
        cv2.putText(canvas, note, (x0 + pad, y), FONT, 0.45 * s, (20,) * 3, thick, cv2.LINE_AA)
    return Box(x0, y0, x0 + panel_w + 1, y0 + panel_h + 1)


def _free_corner(
    cov: Coverage,
    size: tuple[int, int],
    panel: tuple[int, int],
    pad: int,
    avoid: Sequence[Box] = (),
) -> tuple[int, int]:
    """The top-left of a `panel` (width, height) in the image's bottom-right corner, else its
    bottom-left or right or left middle: the first that hides neither where the board goes
    next nor a placement (else the one hiding least of them), and never one over a panel of
    `avoid` (the title) where another is free of them."""
    (w, h), (pw, ph) = size, panel
    corners = [
        (w - pw - pad, h - ph - pad),
        (pad, h - ph - pad),
        (w - pw - pad, (h - ph) // 2),
        (pad, (h - ph) // 2),
    ]
    boxes = [
        (float(o[:, 0].min()), float(o[:, 1].min()), float(o[:, 0].max()), float(o[:, 1].max()))
        for o in cov.outlines_px
        if len(o)
    ]
    target = cov.region.target_px if cov.region is not None else None

    def hidden(x: int, y: int) -> float:
        area = sum(
            max(0.0, min(x + pw, bx1) - max(x, bx0)) * max(0.0, min(y + ph, by1) - max(y, by0))
            for bx0, by0, bx1, by1 in boxes
        )
        near = 3 * pad  # the target's cross and its label
        if target is not None and x - near <= target[0] <= x + pw + near:
            area += float(w * h) if y - near <= target[1] <= y + ph + near else 0.0
        clash = Box(x, y, x + pw + 1, y + ph + 1)
        return area + (4.0 * w * h if any(clash.overlaps(b) for b in avoid) else 0.0)

    return min(corners, key=lambda c: hidden(*c))  # the first of the least hidden


def _tick(v: float) -> str:
    """A tick's label: up to three significant figures, no exponent down to 0.0001 mm."""
    return f"{float(f'{v:.3g}'):g}" if v >= 1e-4 else f"{v:.0e}"
