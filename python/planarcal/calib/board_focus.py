"""Focus and exposure measured on the calibration board itself, cheap enough for every live
frame (issue 24): how wide the edges of the board's marks are, and how its paper and ink sit
in the 8-bit range, each with a verdict and one sentence of what to do.

Edges: the detection says where the marks are, so no edge has to be searched for. On a circle
grid a profile crosses each sampled dot's rim along the rim's normal (the dot's outline from
its stated diameter, or its measured one, through the homography of the detected points: an
ellipse under tilt); on a chessboard or a ChArUco board it crosses the square edge between two
neighbouring corners at its midpoint, perpendicular to the line joining them. Each profile is
sampled every 0.25 px (bilinear), its dark and light levels read beside the edge, and the
distance between its 10 % and 90 % crossings is its rise width; the board's is the median.
At most ``MAX_PROFILES`` profiles, spread evenly over the board and over edge directions.

Exposure: the grey levels inside the board's region (the convex hull of the detected points
grown by half a pitch): its dark and light levels (robust percentiles), the share of pixels
clipped at either end.

Measured (tests/calib/test_board_focus.py; 1280 x 720 renders of the cell's boards, noise 1):
against the step's true width 2.56 sqrt(s^2 + 1/12) for a blur of sigma s (the 1/12 is the
pixel's own area), circle grids and chessboards read within 2 % for s = 1-3 px, within 7 %
at 0.5 and 4 (a sharp render, whose 1-px box edge is 0.8 px wide, reads 0.95 px); with noise
3 they read up to 5 % wide. A ChArUco board's white margin between a square and its
marker (here 5 px) is the only light plateau beside its edges, so its widths fall short as the
blur nears it: 4 % at s = 1, 19 % at s = 2 (still "blurred"); a little more blur and its
markers no longer decode. Saturated paper cuts every ramp short (an edge 2.8 px wide read 1.9
px at a gain of 1.6), so profiles with a clipped level are not measured: the focus is then
"unknown" rather than falsely "sharp". A call at 1280 x 720 takes 1-1.5 ms of CPU on a chessboard or
ChArUco board, 3-4 ms on a circle grid (200 longer profiles and a homography), measured on a
2-core machine loaded by other jobs.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.detection import BoardDetection
from planarcal.errors import ArgumentError, ArgumentTypeError, ImageError

F64 = NDArray[np.float64]

# Focus. A Gaussian blur of sigma s gives an edge 2.56 s wide (10-90 %); a pixel's own area
# adds about 0.3 px of sigma. A well-focused 720p webcam shows edges 1.5-2.5 px wide (its
# lens and demosaicing), so 2.5 px is the top of "as sharp as such a camera gets". At 4 px
# (sigma about 1.5 px) the focus is clearly off: a dot 20 px across loses the flat core that
# its centre's fit leans on, and a turn of the focus ring reliably gains it back.
SHARP_MAX_PX = 2.5
"""Edges at most this wide (10-90 %, px) are sharp."""
BLURRED_MIN_PX = 4.0
"""Edges at least this wide are blurred; between the two, soft."""

# Exposure, on the board's light level (its paper, or its dots on a light-on-dark board) and
# its contrast. Webcams' auto-exposure puts white paper at about 170-230; under 100 the ink
# and the paper are less than 100 levels apart, where sensor noise (2-4 levels, more with the
# gain a dark scene gets) and 8-bit steps start to cost edge precision. Above 245 the paper
# has no headroom: a little more light and it clips. A clipped white (or black) area flattens
# the profile of every edge it reaches and shifts the marks' centres, so 1 % of the board
# clipped already counts (noise alone clips far fewer). Contrast under 0.25 of full scale
# (64 levels) with the paper well exposed means washed-out ink, glare or haze.
DARK_LEVEL = 100.0
"""A board whose light level (grey, 0-255) is under this is dark."""
BRIGHT_LEVEL = 245.0
"""A board whose light level is over this (without clipping) is bright."""
CLIPPED_SHARE = 0.01
"""A share of the board's pixels at 253+ (or 2-) over this is clipped."""
FLAT_CONTRAST = 0.25
"""Contrast (light - dark) / 255 under this is flat."""
CLIP_DARK, CLIP_BRIGHT = 2, 253
"""Grey levels counted as clipped black (<=) and clipped white (>=)."""
LEVEL_PERCENTILES = (5.0, 95.0)
"""The percentiles of the board region's grey levels read as its ink and paper levels:
robust to noise, specks and a few clipped pixels, inside the ink even on a circle grid, whose
dots cover about a sixth of its region."""

GAUSS_10_90 = 2.0 * 1.2815516
"""The 10-90 % width of a Gaussian-blurred step, in sigmas (2 z(0.9))."""

MAX_PROFILES = 200
"""The most edge profiles sampled per call: enough for a stable median (its spread over
200 profiles is a few hundredths of a px), few enough for about a millisecond."""
STEP_PX = 0.25
"""Sampling step along a profile (px): a sharp edge (0.8 px) still gets three samples."""
MAX_REACH_PX = 16.0
"""How far a profile reaches each side of its edge at most (px): the plateaus of edges up to
about 12 px wide (sigma 5 px), far beyond "blurred"."""
MIN_REACH_PX = 1.5
"""A profile with less room than this on either side (marks too small in the image) is not
sampled."""
MIN_PROFILES = 5
"""Fewer measured profiles than this give no edge width (nan)."""
MIN_EDGE_STEP = 8.0
"""A profile whose dark and light levels are less than this many grey levels apart (or
under a third of the region's contrast) is not measured: noise, not an edge."""


@dataclasses.dataclass(frozen=True)
class BoardFocus:
    """Focus and exposure of the board in one frame (see the module).

    ``edge_width_px``: the 10-90 % rise width across the edges of the board's marks (px),
    median over the sampled profiles; nan when no edge could be measured. ``contrast``:
    (light level - dark level) / 255 in the board's region (its paper and ink, robust
    percentiles). ``clipped_dark`` / ``clipped_bright``: the share of the region's pixels at
    <= 2 / >= 253. ``focus``: "sharp", "soft", "blurred" or "unknown" (no edge measured);
    ``exposure``: "good", "dark", "bright", "clipped" or "flat" (too little contrast);
    ``advice``: one sentence of what to do, None when both are good.
    """

    edge_width_px: float
    contrast: float
    clipped_dark: float
    clipped_bright: float
    focus: str
    exposure: str
    advice: str | None
    light_level: float = math.nan
    """The board's light level (grey 0-255: its paper on dark-on-light boards)."""
    dark_level: float = math.nan
    """The board's dark level (its ink on dark-on-light boards)."""
    profiles: int = 0
    """How many edge profiles were measured."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: numbers rounded for display, nan as None."""

        def num(value: float, digits: int) -> float | None:
            return round(value, digits) if math.isfinite(value) else None

        return {
            "edge_width_px": num(self.edge_width_px, 3),
            "contrast": num(self.contrast, 4),
            "clipped_dark": num(self.clipped_dark, 5),
            "clipped_bright": num(self.clipped_bright, 5),
            "focus": self.focus,
            "exposure": self.exposure,
            "advice": self.advice,
            "light_level": num(self.light_level, 2),
            "dark_level": num(self.dark_level, 2),
            "profiles": self.profiles,
        }


def board_focus(image: Any, detection: BoardDetection) -> BoardFocus:
    """The focus and exposure of the board `detection` found in `image` (the uint8 grey or
    BGR frame it was found in). ArgumentError for no detection or one whose points are not
    in the image, ImageError for an image that is not a uint8 frame of the detection's size.
    """
    frame, points = _checked(image, detection)
    h, w = frame.shape[:2]
    pitch = detection.pitch_px
    if not math.isfinite(pitch) or pitch <= 0.0:
        raise ArgumentError("the detection's points are all in one place: no board to measure")
    region = _region(points, pitch)
    centres, normals, reach = _profiles(detection, points)
    # Profiles that would leave the image are dropped; the rest fix the window read.
    ends = np.concatenate(
        [centres - normals * reach[:, :1], centres + normals * reach[:, 1:2]], axis=0
    )
    inside = np.all((ends >= 0.0) & (ends <= (w - 1.0, h - 1.0)), axis=1)
    keep = inside[: len(centres)] & inside[len(centres) :]
    centres, normals, reach = centres[keep], normals[keep], reach[keep]
    corners = np.concatenate([region.astype(np.float64), ends[np.concatenate([keep, keep])]])
    x0, y0 = np.clip(np.floor(corners.min(axis=0)).astype(int), 0, (w - 1, h - 1))
    x1, y1 = np.clip(np.ceil(corners.max(axis=0)).astype(int) + 2, 1, (w, h))
    window = frame[y0:y1, x0:x1]
    if window.ndim == 3:  # only the board's window is turned grey
        grey = np.asarray(cv2.cvtColor(window, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    else:
        grey = np.ascontiguousarray(window)

    dark, light, clip_dark, clip_bright = _levels(grey, region - (x0, y0))
    contrast = (light - dark) / 255.0
    widths = _widths(grey, centres - (x0, y0), normals, reach, light - dark)
    width = _without_sampler(float(np.median(widths))) if len(widths) >= MIN_PROFILES else math.nan
    focus = _focus(width)
    exposure = _exposure(light, contrast, clip_dark, clip_bright)
    return BoardFocus(
        edge_width_px=width,
        contrast=contrast,
        clipped_dark=clip_dark,
        clipped_bright=clip_bright,
        focus=focus,
        exposure=exposure,
        advice=_advice(focus, exposure, width, light, contrast, clip_dark, clip_bright),
        light_level=light,
        dark_level=dark,
        profiles=len(widths),
    )


def _checked(image: Any, detection: Any) -> tuple[NDArray[np.uint8], F64]:
    """The image (uint8, grey or BGR, the detection's size) and the detected points."""
    if detection is None:
        raise ArgumentError("no board detection: find the board (detect_board) first")
    if not isinstance(detection, BoardDetection):
        raise ArgumentTypeError(
            f"detection must be a BoardDetection, got {type(detection).__name__}"
        )
    if not isinstance(image, np.ndarray):
        raise ImageError(f"image must be a NumPy array, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise ImageError(f"image must be 8-bit (uint8), got dtype {image.dtype}")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)):
        raise ImageError(f"image must be grey (h, w) or BGR (h, w, 3), got shape {image.shape}")
    h, w = image.shape[:2]
    if (w, h) != tuple(detection.image_size):
        raise ImageError(
            f"the image is {w} x {h} px but the detection was made on "
            f"{detection.image_size[0]} x {detection.image_size[1]}"
        )
    points = np.asarray(detection.image_points, dtype=np.float64).reshape(-1, 2)
    if len(points) < 2:
        raise ArgumentError(f"the detection holds {len(points)} point(s): no board to measure")
    bad = ~np.all(np.isfinite(points) & (points >= -0.5) & (points <= (w - 0.5, h - 0.5)), axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        raise ArgumentError(
            f"detected point {k} at {points[k].tolist()} is outside the {w} x {h} image: "
            "the detection is not of this image",
            index=k,
        )
    return image, points


def _region(points: F64, pitch: float) -> NDArray[np.int32]:
    """The board's region: the convex hull of the points grown by half a pitch (a 16-gon
    about each hull vertex), as an int32 polygon."""
    hull = cv2.convexHull(points.astype(np.float32)).reshape(-1, 2)
    a = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    ring = 0.5 * pitch * np.column_stack([np.cos(a), np.sin(a)])
    grown = (hull[:, None, :] + ring[None, :, :]).reshape(-1, 2).astype(np.float32)
    return np.asarray(np.rint(cv2.convexHull(grown).reshape(-1, 2)), dtype=np.int32)


def _levels(
    grey: NDArray[np.uint8], polygon: NDArray[np.int32]
) -> tuple[float, float, float, float]:
    """Dark level, light level, share clipped dark, share clipped bright in the polygon."""
    mask = np.zeros(grey.shape, np.uint8)
    cv2.fillConvexPoly(mask, polygon.astype(np.int32), 255)
    hist = cv2.calcHist([grey], [0], mask, [256], [0, 256]).ravel()
    total = float(hist.sum())
    if total <= 0.0:  # a region clipped away entirely (cannot happen with points inside)
        return math.nan, math.nan, math.nan, math.nan
    cum = np.cumsum(hist) / total
    lo, hi = (float(np.searchsorted(cum, p / 100.0)) for p in LEVEL_PERCENTILES)
    return (
        lo,
        hi,
        float(hist[: CLIP_DARK + 1].sum()) / total,
        float(hist[CLIP_BRIGHT:].sum()) / total,
    )


def _profiles(detection: BoardDetection, points: F64) -> tuple[F64, F64, F64]:
    """Where edges cross: each profile's centre (px), unit normal, and reach (px) on its
    negative side, its positive side and on whichever side is light (the third column: a
    ChArUco board's white margin before its marker; inf where no such limit)."""
    board = detection.board
    if isinstance(board, CircleGridBoard):
        return _rim_profiles(detection, points)
    ids = np.asarray(detection.ids, dtype=np.intp)
    if len(ids) != len(points):
        ids = np.arange(len(points), dtype=np.intp)
    cols = int(board.cols)
    where = {int(k): i for i, k in enumerate(ids)}
    pairs = [
        (i, where[k + step])
        for i, k in enumerate(ids.tolist())
        for step in (1, cols)
        if (step == cols or (k + 1) % cols != 0) and (k + step) in where
    ]
    if not pairs:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 3))
    pick = np.asarray(pairs, dtype=np.intp)
    if len(pick) > MAX_PROFILES:
        pick = pick[np.linspace(0, len(pick) - 1, MAX_PROFILES).round().astype(np.intp)]
    a, b = points[pick[:, 0]], points[pick[:, 1]]
    along = b - a
    length = np.hypot(along[:, 0], along[:, 1])
    normals = np.column_stack([-along[:, 1], along[:, 0]]) / length[:, None]
    # Towards the square's middle, short of a chessboard's marker dots (0.33 of a square
    # from the edge).
    side = np.minimum(0.3 * length, MAX_REACH_PX)
    light = np.full(len(length), np.inf)
    if isinstance(board, CharucoBoard):
        margin = 0.5 * (float(board.square) - float(board.marker)) / float(board.square)
        light = 0.85 * margin * length
    return 0.5 * (a + b), normals, np.column_stack([side, side, light])


def _rim_profiles(detection: BoardDetection, points: F64) -> tuple[F64, F64, F64]:
    """Profiles across the rims of regular dots (see _profiles), along the rim's normal."""
    board = detection.board
    assert isinstance(board, CircleGridBoard)
    empty = np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 3))
    ids = np.asarray(detection.ids, dtype=np.intp)
    if len(ids) != len(points) or len(points) < 4:
        return empty
    world: F64 = np.asarray(board.world_points()[ids], dtype=np.float64)
    found, _ = cv2.findHomography(world, points, 0)
    if found is None or not np.all(np.isfinite(found)):
        return empty
    hom: F64 = np.asarray(found, dtype=np.float64)
    regular = board.dot_kinds()[ids] == 0
    measured = np.asarray(detection.dot_diameters_px, dtype=np.float64)
    if board.diameter is not None:
        radius = 0.5 * board.dot_diameters()[ids]
    elif len(measured) == len(points) and np.all(np.isfinite(measured)):
        # The print's diameter unstated: the measured one, through the local scale.
        scale = np.sqrt(np.abs(np.linalg.det(_jacobian(hom, world))))
        radius = 0.5 * measured / scale
    else:
        radius = 0.5 * board.dot_diameters()[ids]
    gap = float(board.neighbour_distance) - radius - float(radius.max())
    usable = np.flatnonzero(regular & (gap > 0.0) & (radius > 0.0))
    if len(usable) == 0:
        return empty
    per_dot = int(np.clip(MAX_PROFILES // len(usable), 4, 8))
    n_dots = min(len(usable), MAX_PROFILES // per_dot)
    dots = usable[np.linspace(0, len(usable) - 1, n_dots).round().astype(np.intp)]
    # Each dot's angles turned by the golden angle from the last: every edge direction (and
    # so every phase against the pixel grid) is sampled.
    turn = np.arange(len(dots))[:, None] * 2.39996 + np.arange(per_dot)[None, :] * (
        2.0 * np.pi / per_dot
    )
    u = np.stack([np.cos(turn), np.sin(turn)], axis=-1).reshape(-1, 2)
    which = np.repeat(dots, per_dot)
    r = radius[which]
    rim_world: F64 = world[which] + r[:, None] * u
    # The rim as the homography draws it, about the detected centre (which the lens may have
    # moved from the homography's).
    centre_px = _apply(hom, world[which])
    rim = points[which] + _apply(hom, rim_world) - centre_px
    jac = _jacobian(hom, rim_world)
    tangent = np.einsum("nij,nj->ni", jac, np.column_stack([-u[:, 1], u[:, 0]]))
    normals = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    outward = np.einsum("nij,nj->ni", jac, u)
    normals *= np.sign(np.sum(normals * outward, axis=1))[:, None]
    normals /= np.hypot(normals[:, 0], normals[:, 1])[:, None]
    # The least px per mm at the rim: its reach in px is short, never too long.
    least = np.linalg.svd(jac, compute_uv=False)[:, -1]
    inner = np.minimum(0.8 * r * least, MAX_REACH_PX)
    outer = np.minimum(0.8 * gap[which] * least, MAX_REACH_PX)
    return rim, normals, np.column_stack([inner, outer, np.full(len(r), np.inf)])


def _apply(hom: F64, world: F64) -> F64:
    p = world @ hom[:, :2].T + hom[:, 2]
    return np.asarray(p[:, :2] / p[:, 2:3], dtype=np.float64)


def _jacobian(hom: F64, world: F64) -> F64:
    """d(image)/d(world) of the homography at each world point, (n, 2, 2)."""
    p = world @ hom[:, :2].T + hom[:, 2]
    img = p[:, :2] / p[:, 2:3]
    top = hom[None, :2, :2] - img[:, :, None] * hom[None, 2:3, :2]
    return np.asarray(top / p[:, 2, None, None], dtype=np.float64)


def _widths(
    grey: NDArray[np.uint8], centres: F64, normals: F64, reach: F64, region_step: float
) -> F64:
    """The 10-90 % rise width (px) of each profile that crosses a clear edge."""
    ok = (reach[:, 0] >= MIN_REACH_PX) & (reach[:, 1] >= MIN_REACH_PX)
    centres, normals, reach = centres[ok], normals[ok], reach[ok]
    if len(centres) == 0:
        return np.zeros(0)
    half = math.ceil(float(reach[:, :2].max()) / STEP_PX)
    t = np.arange(-half, half + 1) * STEP_PX
    xy = centres[:, None, :] + t[None, :, None] * normals[:, None, :]
    values = _bilinear(grey, xy)
    valid = (t[None, :] >= -reach[:, :1]) & (t[None, :] <= reach[:, 1:2])
    # Which side is dark: the means over the same distance each side (within a ChArUco
    # board's white margin, whichever side it is on).
    near = reach.min(axis=1)[:, None]
    neg = valid & (t[None, :] < 0) & (t[None, :] >= -near)
    pos = valid & (t[None, :] > 0) & (t[None, :] <= near)
    dark_neg = np.sum(values * neg, axis=1) / np.maximum(neg.sum(axis=1), 1) < np.sum(
        values * pos, axis=1
    ) / np.maximum(pos.sum(axis=1), 1)
    # Orient every profile dark -> light along increasing index.
    values = np.where(dark_neg[:, None], values, values[:, ::-1])
    valid = np.where(dark_neg[:, None], valid, valid[:, ::-1])
    # The light side may be shorter than the geometry allows (a ChArUco board's margin).
    valid &= t[None, :] <= reach[:, 2:3]
    dark_side = valid & (t[None, :] < 0)
    light_side = valid & (t[None, :] > 0)
    # Levels: the darkest quarter of the dark side, the lightest quarter of the light side
    # (the plateaus, or a narrow strip's crest).
    dark = _extreme_mean(np.where(dark_side, values, np.inf), dark_side.sum(axis=1))
    light = -_extreme_mean(np.where(light_side, -values, np.inf), light_side.sum(axis=1))
    step = light - dark
    q = (values - dark[:, None]) / np.where(step > 0, step, 1.0)[:, None]
    q = np.where(valid, q, np.nan)

    n, m = q.shape
    idx = np.arange(m)
    centre = half
    with np.errstate(invalid="ignore"):
        rise = (q[:, :-1] < 0.5) & (q[:, 1:] >= 0.5)
        low = q <= 0.1
        high = q >= 0.9
    # The 50 % crossing nearest the expected edge; then the 10 % and 90 % crossings next to it.
    dist = np.where(rise, np.abs(idx[:-1] - centre), m)
    i50 = np.argmin(dist, axis=1)
    has50 = dist[np.arange(n), i50] < m
    lows = np.where(low & (idx[None, :] <= i50[:, None]), idx[None, :], -1)
    i10 = lows.max(axis=1)
    highs = np.where(high & (idx[None, :] > i50[:, None]), idx[None, :], m)
    i90 = highs.min(axis=1)
    good = (
        has50
        & (i10 >= 0)
        & (i90 < m)
        & (step >= max(MIN_EDGE_STEP, region_step / 3.0))
        # A clipped plateau cuts the ramp short and the edge looks sharper than it is.
        & (light < CLIP_BRIGHT - 0.5)
        & (dark > CLIP_DARK + 0.5)
        & (np.abs(i50 - centre) * STEP_PX <= 0.6 * np.minimum(reach[:, 0], reach[:, 1]) + 1.0)
    )
    rows = np.flatnonzero(good)
    if len(rows) == 0:
        return np.zeros(0)
    a, b = i10[rows], i90[rows]
    qa0, qa1 = q[rows, a], q[rows, a + 1]
    qb0, qb1 = q[rows, b - 1], q[rows, b]
    t10 = a + (0.1 - qa0) / (qa1 - qa0)
    t90 = b - 1 + (0.9 - qb0) / (qb1 - qb0)
    return np.asarray((t90 - t10) * STEP_PX, dtype=np.float64)


def _without_sampler(width: float) -> float:
    """The image's edge width from a profile's: bilinear sampling convolves the profile with
    a tent of variance 1/6 px^2 whatever the edge's direction (1/6 along each axis, so along
    any unit normal), which widens a Gaussian edge in quadrature; removed likewise. Measured
    on rendered edges of known blur, this takes the profile's width from 9 % over the image's
    to within 2 % (sigma 0.5-2 px)."""
    sampler = GAUSS_10_90 * GAUSS_10_90 / 6.0
    return math.sqrt(max(width * width - sampler, 0.0))


def _extreme_mean(sorted_from: F64, count: NDArray[np.intp]) -> F64:
    """Mean of the smallest quarter (at least one) of each row's finite values, the others
    being +inf."""
    s = np.sort(sorted_from, axis=1)
    k = np.maximum(count // 4, 1)
    s = np.where(np.isfinite(s), s, 0.0)
    cum = np.cumsum(s, axis=1)
    return np.asarray(cum[np.arange(len(s)), k - 1] / k, dtype=np.float64)


def _bilinear(grey: NDArray[np.uint8], xy: F64) -> F64:
    """Bilinear samples of grey at (x, y) positions inside it, shape xy.shape[:-1]."""
    h, w = grey.shape
    x = np.clip(xy[..., 0], 0.0, w - 1.0)
    y = np.clip(xy[..., 1], 0.0, h - 1.0)
    x0 = np.minimum(x.astype(np.intp), w - 2)
    y0 = np.minimum(y.astype(np.intp), h - 2)
    fx, fy = x - x0, y - y0
    flat = grey.ravel()
    i = y0 * w + x0
    v00, v01 = flat[i].astype(np.float64), flat[i + 1]
    v10, v11 = flat[i + w], flat[i + w + 1]
    top = v00 + fx * (v01 - v00)
    bottom = v10 + fx * (v11 - v10.astype(np.float64))
    return np.asarray(top + fy * (bottom - top), dtype=np.float64)


def _focus(width: float) -> str:
    if not math.isfinite(width):
        return "unknown"
    if width <= SHARP_MAX_PX:
        return "sharp"
    return "soft" if width < BLURRED_MIN_PX else "blurred"


def _exposure(light: float, contrast: float, clip_dark: float, clip_bright: float) -> str:
    # Clipped white first (nothing else can be judged under it); then a dark board, whose
    # fix (more light) also lifts its contrast and its crushed ink; then crushed ink alone.
    if clip_bright > CLIPPED_SHARE:
        return "clipped"
    if light < DARK_LEVEL:
        return "dark"
    if clip_dark > CLIPPED_SHARE:
        return "clipped"
    if light > BRIGHT_LEVEL:
        return "bright"
    return "flat" if contrast < FLAT_CONTRAST else "good"


def _advice(
    focus: str,
    exposure: str,
    width: float,
    light: float,
    contrast: float,
    clip_dark: float,
    clip_bright: float,
) -> str | None:
    parts = []
    if exposure == "clipped" and clip_bright > CLIPPED_SHARE:
        parts.append(
            f"lower the exposure or the light: {100 * clip_bright:.0f} % of the board is "
            "saturated white"
        )
    elif exposure == "dark":
        parts.append(
            f"raise the exposure or add light: the board's paper is at grey {light:.0f}, "
            f"good is {DARK_LEVEL:.0f} to {BRIGHT_LEVEL:.0f}"
        )
    elif exposure == "clipped":
        parts.append(
            f"lower the exposure's gain or the contrast: {100 * clip_dark:.0f} % of the board "
            "is crushed to black"
        )
    elif exposure == "bright":
        parts.append(
            f"lower the exposure a little: the board's paper is at grey {light:.0f}, close to "
            f"saturation (good is {DARK_LEVEL:.0f} to {BRIGHT_LEVEL:.0f})"
        )
    elif exposure == "flat":
        parts.append(
            f"light the board evenly and keep glare off it: its contrast is {contrast:.2f}, "
            f"good is {FLAT_CONTRAST:.2f} or more"
        )
    if focus in ("soft", "blurred"):
        how = "a little" if focus == "soft" else ""
        parts.append(
            f"turn the focus ring{' ' + how if how else ''}: edges are {width:.1f} px wide, "
            f"sharp is under {SHARP_MAX_PX:g} px"
        )
    elif focus == "unknown" and parts:
        parts.append("the focus can be measured")
    elif focus == "unknown":
        parts.append("bring the board closer or into focus: no edge of its marks could be measured")
    return "; then ".join(parts) if parts else None
