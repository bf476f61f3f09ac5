"""Rendered views of any board with exact-enough truth, for the chessboard tests and
benches/bench_detection.py (until planarcal.synth renders every board type itself).

The board's ink (``board.ink()``) is drawn once in board millimetres at high resolution
(axis-aligned rectangles with exact area coverage, discs anti-aliased), then every output
pixel is the mean of ``supersample``^2 point samples of it, each traced back through the lens
and the homography: the area average a sensor takes. Pixel centres are at integer
coordinates (OpenCV's convention), as in the truth.

The lens is a one-term radial model written from the image side, ``ideal = centre + (p -
centre) * (1 + k * r^2)`` with ``r = |p - centre| / focal``, so rendering needs no inverse;
the truth solves it for each corner by Newton's method.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]


@dataclasses.dataclass(frozen=True)
class RenderedBoard:
    """A rendered image (uint8 grey) and the true pixel of every board point (NaN where the
    point lies outside the image)."""

    image: U8
    truth: F64
    homography: F64


def look_at_homography(
    board_size_mm: tuple[float, float],
    image_size: tuple[int, int],
    *,
    fill: float = 0.6,
    tilt_deg: float = 0.0,
    tilt_axis_deg: float = 0.0,
    roll_deg: float = 0.0,
    shift_px: tuple[float, float] = (0.0, 0.0),
    focal_px: float | None = None,
    centre_mm: tuple[float, float] | None = None,
) -> F64:
    """A homography board mm -> image px of a pinhole camera looking at the board's centre
    (or ``centre_mm``) from a distance where the board spans `fill` of the image, the board
    tilted by `tilt_deg` about an in-plane axis at `tilt_axis_deg`, rolled by `roll_deg`."""
    w, h = image_size
    f = focal_px if focal_px is not None else 1.1 * max(w, h)
    bw, bh = board_size_mm
    cx_mm, cy_mm = centre_mm if centre_mm is not None else (bw / 2.0, bh / 2.0)
    a = math.radians(tilt_axis_deg)
    axis = np.array([math.cos(a), math.sin(a), 0.0])
    t = math.radians(tilt_deg)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    tilt = np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * (k @ k)
    r = math.radians(roll_deg)
    roll = np.array([[math.cos(r), -math.sin(r), 0], [math.sin(r), math.cos(r), 0], [0, 0, 1]])
    rot = tilt @ roll
    distance = f * max(bw / (fill * w), bh / (fill * h))
    # Board point (x, y, 0) in camera coordinates: rot @ (x - cx, y - cy, 0) + (0, 0, d).
    pose = np.column_stack([rot[:, 0], rot[:, 1], [0.0, 0.0, distance]])
    pose[:, 2] -= rot[:, 0] * cx_mm + rot[:, 1] * cy_mm
    k_mat = np.array([[f, 0, w / 2.0 - 0.5 + shift_px[0]], [0, f, h / 2.0 - 0.5 + shift_px[1]]])
    k_mat = np.vstack([k_mat, [0, 0, 1]])
    hom = k_mat @ pose
    return np.asarray(hom / hom[2, 2], dtype=np.float64)


def _apply(h: F64, pts: F64) -> F64:
    v = np.c_[pts, np.ones(len(pts))] @ h.T
    return np.asarray(v[:, :2] / v[:, 2:], dtype=np.float64)


def _ink_canvas(ink: object, px_per_mm: float) -> tuple[NDArray[np.float32], F64]:
    """The board's ink as reflectance (1 white paper, 0 ink) on a canvas, and the affine map
    board mm -> canvas px (pixel centres at integers), with a white margin around."""
    x0, y0, x1, y1 = ink.field  # type: ignore[attr-defined]
    margin = 0.25 * max(x1 - x0, y1 - y0)
    ox, oy = x0 - margin, y0 - margin
    cw = math.ceil((x1 - x0 + 2 * margin) * px_per_mm)
    ch = math.ceil((y1 - y0 + 2 * margin) * px_per_mm)
    canvas = np.ones((ch, cw), np.float32)
    # Exact area coverage of each axis-aligned rectangle: separable fractional coverage.
    edges_x = np.arange(cw + 1, dtype=np.float64)
    edges_y = np.arange(ch + 1, dtype=np.float64)
    for rx0, ry0, rx1, ry1 in ink.rects:  # type: ignore[attr-defined]
        ax0, ax1 = (rx0 - ox) * px_per_mm, (rx1 - ox) * px_per_mm
        ay0, ay1 = (ry0 - oy) * px_per_mm, (ry1 - oy) * px_per_mm
        i0, i1 = max(int(ax0) - 1, 0), min(int(ax1) + 2, cw)
        j0, j1 = max(int(ay0) - 1, 0), min(int(ay1) + 2, ch)
        cx = np.clip(
            np.minimum(edges_x[i0 + 1 : i1 + 1], ax1) - np.maximum(edges_x[i0:i1], ax0), 0, 1
        )
        cy = np.clip(
            np.minimum(edges_y[j0 + 1 : j1 + 1], ay1) - np.maximum(edges_y[j0:j1], ay0), 0, 1
        )
        canvas[j0:j1, i0:i1] -= np.outer(cy, cx).astype(np.float32)
    shift = 4
    for cxm, cym, rad, black in ink.circles:  # type: ignore[attr-defined]
        centre = (
            round(((cxm - ox) * px_per_mm - 0.5) * (1 << shift)),
            round(((cym - oy) * px_per_mm - 0.5) * (1 << shift)),
        )
        cv2.circle(
            canvas,
            centre,
            round(rad * px_per_mm * (1 << shift)),
            float(1.0 - black),
            -1,
            cv2.LINE_AA,
            shift,
        )
    to_canvas = np.array(
        [[px_per_mm, 0, -ox * px_per_mm - 0.5], [0, px_per_mm, -oy * px_per_mm - 0.5], [0, 0, 1]]
    )
    return np.clip(canvas, 0, 1), to_canvas


def undistort_px(p: F64, k: float, centre: tuple[float, float], focal: float) -> F64:
    """The lens's image-side model: the ideal pixel of a distorted pixel."""
    c = np.asarray(centre)
    d = (p - c) / focal
    r2 = (d**2).sum(axis=1, keepdims=True)
    return np.asarray(c + (p - c) * (1 + k * r2), dtype=np.float64)


def distort_px(q: F64, k: float, centre: tuple[float, float], focal: float) -> F64:
    """The distorted pixel of an ideal pixel (Newton on the image-side model)."""
    c = np.asarray(centre)
    u = (q - c) / focal  # ideal, normalised
    s = np.sqrt((u**2).sum(axis=1))
    rho = s.copy()  # distorted radius: rho * (1 + k rho^2) = s
    for _ in range(50):
        f = rho * (1 + k * rho**2) - s
        rho -= f / (1 + 3 * k * rho**2)
    scale = np.where(s > 0, rho / np.where(s > 0, s, 1), 1.0)
    return np.asarray(c + (q - c) * scale[:, None], dtype=np.float64)


def render_board(
    board: object,
    homography: F64,
    image_size: tuple[int, int],
    *,
    supersample: int = 8,
    blur_px: float = 0.0,
    noise: float = 0.0,
    k: float = 0.0,
    black: float = 30.0,
    white: float = 220.0,
    gradient: float = 0.0,
    seed: int = 0,
) -> RenderedBoard:
    """Render `board` (any planarcal board: its ``ink()``) seen through `homography` (board
    mm -> ideal image px) and the radial lens `k`, area-averaged over supersample^2 samples per
    pixel, then blurred (Gaussian, `blur_px` sigma), lit with a left-to-right `gradient`
    (fraction) and given Gaussian `noise` (grey levels sigma)."""
    w, h = image_size
    focal = float(max(w, h))
    centre = ((w - 1) / 2.0, (h - 1) / 2.0)
    # Canvas resolution: 1.5 canvas px per sample at the board's largest scale (its pixels
    # are exact area coverage; the bilinear samples of it blur the edges symmetrically, which
    # moves no corner), at most 8000 px across.
    world = np.asarray(board.world_points(), np.float64)  # type: ignore[attr-defined]
    ink = board.ink()  # type: ignore[attr-defined]
    x0, y0, x1, y1 = ink.field
    outline = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], np.float64)
    img_outline = _apply(homography, outline)
    mm_per_px = max(x1 - x0, y1 - y0) / max(
        1.0, float(np.max(np.hypot(*(np.roll(img_outline, 1, 0) - img_outline).T)))
    )
    px_per_mm = min(1.5 * supersample / mm_per_px, 8000.0 / max(x1 - x0, y1 - y0) / 1.5)
    canvas, to_canvas = _ink_canvas(ink, px_per_mm)
    h_inv = to_canvas @ np.linalg.inv(homography)
    reflect = np.ones((h, w), np.float32)
    # Only the board's bounding box (its outline through the lens, with a margin) is traced.
    corners_px = img_outline if not k else distort_px(img_outline, k, centre, focal)
    pad = 0.3 * float(np.max(np.ptp(corners_px, axis=0))) + 4
    bx0 = int(np.clip(np.floor(corners_px[:, 0].min() - pad), 0, w))
    bx1 = int(np.clip(np.ceil(corners_px[:, 0].max() + pad), 0, w))
    by0 = int(np.clip(np.floor(corners_px[:, 1].min() - pad), 0, h))
    by1 = int(np.clip(np.ceil(corners_px[:, 1].max() + pad), 0, h))
    s = supersample
    bw = bx1 - bx0
    if bw > 0 and by1 > by0:
        offsets = ((np.arange(s) + 0.5) / s - 0.5).astype(np.float32)
        sx = (np.arange(bx0, bx1, dtype=np.float32)[:, None] + offsets[None, :]).ravel()
        rows_per = max(1, 4_000_000 // (bw * s * s))
        for top in range(by0, by1, rows_per):
            n = min(by1, top + rows_per) - top
            sy = (np.arange(top, top + n, dtype=np.float32)[:, None] + offsets[None, :]).ravel()
            gx = np.broadcast_to(sx[None, :], (len(sy), len(sx)))
            gy = np.broadcast_to(sy[:, None], (len(sy), len(sx)))
            if k:
                dx = (gx - np.float32(centre[0])) / np.float32(focal)
                dy = (gy - np.float32(centre[1])) / np.float32(focal)
                g = np.float32(1.0) + np.float32(k) * (dx * dx + dy * dy)
                px = np.float32(centre[0]) + (gx - np.float32(centre[0])) * g
                py = np.float32(centre[1]) + (gy - np.float32(centre[1])) * g
            else:
                px, py = gx, gy
            m = h_inv.astype(np.float32)
            qz = m[2, 0] * px + m[2, 1] * py + m[2, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                mx = (m[0, 0] * px + m[0, 1] * py + m[0, 2]) / qz
                my = (m[1, 0] * px + m[1, 1] * py + m[1, 2]) / qz
            bad = ~(np.isfinite(mx) & np.isfinite(my)) | (qz <= 0)
            mx[bad] = -10
            my[bad] = -10
            samples = cv2.remap(
                canvas, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=1.0
            )
            reflect[top : top + n, bx0:bx1] = samples.reshape(n, s, bw, s).mean(axis=(1, 3))
    level = black + (white - black) * reflect.astype(np.float64)
    if gradient:
        level *= 1.0 - gradient * (np.arange(w) / w)[None, :]
    if blur_px > 0:
        level = np.asarray(cv2.GaussianBlur(level, (0, 0), blur_px), np.float64)
    if noise > 0:
        level = level + np.random.default_rng(seed).normal(0, noise, level.shape)
    image = np.clip(np.rint(level), 0, 255).astype(np.uint8)
    truth = _apply(homography, world)
    if k:
        truth = distort_px(truth, k, centre, focal)
    outside = (truth[:, 0] < 0) | (truth[:, 1] < 0) | (truth[:, 0] > w - 1) | (truth[:, 1] > h - 1)
    truth[outside] = np.nan
    return RenderedBoard(image, truth, homography)
