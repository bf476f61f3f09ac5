"""Sub-pixel chessboard corners: a model of the corner fitted to the grey levels around it.

Near an X-corner of a chessboard (or a ChArUco board) the image is two straight edges
crossing: ``I(p) = m + g . (p - c) + a * E(d1(p)) * E(d2(p))`` where ``d1``, ``d2`` are the
signed distances of ``p`` from the two edges through the corner ``c``, ``E(d)`` a step blurred
by the lens (erf(d / (sqrt(2) * sigma))) and averaged over the pixel's width (a 1 px box
across the edge: _pixel_step), ``m`` the mean grey, ``g`` the
light's slope across the window and ``a`` half the contrast (its sign says which quadrants are
black). The nine parameters (corner x, y, the two edges' angles, sigma, m, a, g) are fitted by
weighted Levenberg-Marquardt, all corners at once.

Why this model: the image about a true corner is point-symmetric (turning it by 180 degrees
about the corner leaves it unchanged, whatever the edges' angles, the blur or the pixel
footprint), and so is the model; fitted in a window centred on the corner it has no bias,
where a gradient-based method (``cv2.cornerSubPix``) or a quadratic surface leans towards the
obtuse angle of a tilted board. Light that falls off across the window (vignetting, a lamp
to one side) is not point-symmetric and would pull the corner towards the dark side: the
slope ``g`` takes it up (on photographs it lowers the corners' scatter by up to a fifth).

The window follows the estimate. It is as large as the corner's X allows, since every pixel
along the edges adds to the fit (on photographs the wide window roughly halves the scatter of
a 12 px one): 0.65 of the distance to the nearest other corner (along either grid line or a
diagonal, so the neighbours' corners and blurred edges stay out), or 0.42 of the shorter step
on a board with marker dots (whose dots stand 0.54 of a step from the nearest corner), at
most MAX_RADIUS_PX (a window over which a lens's curvature of the edges stays small).
The fit runs in two passes: in a small window (at most START_RADIUS_PX) from the start, then
in the wide window over the pixels near the edges only (the flat rest tells nothing of where
they run), so a wide window costs little more than a small one. A corner is kept only where
the model also matches the image in the small window (a wide window fits the X about a corner
hidden under a glare spot). A lens bends the edges: given the grid lines' bends (``bends``,
from the grid of refined corners: grid_bends), the model's edges bend with them, so a wide
window keeps no lean towards their concave side (0.27 kappa r^2 for a straight-edged fit:
0.03 px in a strongly barrelled render, 0.006 with the bends; at k1 = -0.12, 0.005-0.008 px
per 400 px of radius towards the image centre, 0.0004 with them). Measured against cornerSubPix and
findChessboardCornersSB in benches/bench_detection.py.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray
from scipy.special import erf

F64 = NDArray[np.float64]

MIN_RADIUS_PX = 2.5
"""The smallest fitting window's half-width (px)."""
MAX_RADIUS_PX = 24.0
"""The largest fitting window's half-width (px): enough for any blur a corner survives, small
enough that a lens's curvature of the edges inside it stays near parabolic (see ``bends``)
and that the fit stays quick."""
START_RADIUS_PX = 10.0
"""The first pass's largest window half-width (px)."""
RADIUS_FRACTION = 0.65
"""A window's half-width in distances to the nearest other corner on a plain board."""
DOTTED_RADIUS_FRACTION = 0.42
"""A window's half-width in grid steps on a board with marker dots in its squares."""
N_PARAMS = 9
MIN_SIGMA_PX = 0.2
SHARP_SIGMA_PX = 0.7
"""Below this blur (px) an edge is modelled with the pixel's box exactly (_pixel_step)."""
MAX_SIGMA_FRACTION = 0.3
"""The largest blur, in window half-widths."""
ITERATIONS = 30
"""The most Levenberg-Marquardt steps per corner (most converge in 5-10; a converged corner
takes no more)."""
MAX_SHIFT = 0.6
"""A corner that moves farther than this fraction of its window from its start is no corner
the model recognises (a marker dot, an occluded corner): not refined."""

_SQRT2 = math.sqrt(2.0)
_SQRT_2_OVER_PI = math.sqrt(2.0 / math.pi)


@dataclasses.dataclass(frozen=True)
class RefinedCorners:
    """The refined corners and what the fit says about each."""

    points: F64
    """(N, 2) px, pixel centres at integer coordinates."""
    refined: NDArray[np.bool_]
    """Whether the fit converged to a corner (else ``points`` keeps the start)."""
    contrast: F64
    """The fitted contrast 2|a| (grey levels)."""
    sigma_px: F64
    """The fitted edge blur (px)."""
    residual: F64
    """The fit's weighted RMS residual over the contrast: about 0.02-0.1 for a clean corner."""


def corner_radius(points: F64, axes: F64, *, dotted: bool = False) -> F64:
    """A fitting window's half-width for each corner (``axes``: (N, 2, 2), the image vectors
    to the next corner along each grid line): RADIUS_FRACTION of the distance to the nearest
    other corner (along a grid line or a diagonal), or with `dotted` (marker dots in the
    squares) DOTTED_RADIUS_FRACTION of the shorter step; between MIN_RADIUS_PX and
    MAX_RADIUS_PX."""
    ax = np.asarray(axes, np.float64).reshape(-1, 2, 2)
    step = np.min(np.linalg.norm(ax, axis=2), axis=1)
    if dotted:
        radius = DOTTED_RADIUS_FRACTION * step
    else:
        diagonal = np.minimum(
            np.linalg.norm(ax[:, 0] + ax[:, 1], axis=1), np.linalg.norm(ax[:, 0] - ax[:, 1], axis=1)
        )
        radius = RADIUS_FRACTION * np.minimum(step, diagonal)
    return np.asarray(np.clip(radius, MIN_RADIUS_PX, MAX_RADIUS_PX), dtype=np.float64)


def grid_bends(points: F64) -> F64:
    """The grid lines' bends at each corner of a grid (``points`` (R, C, 2) px, NaN where a
    corner is missing): (R, C, 2, 2), along each grid line through the corner (u, then v),
    the second difference of the corners over the squared half-chord, (p+ - 2p + p-) / h^2
    (1/px; a line's ends take their neighbour's, a line of two corners none), averaged over
    the corner's 3 x 3 neighbourhood (a lens bends the lines smoothly; each corner's own
    second difference is noisy, its error over h^2). NaN where no three corners in a row
    lie near."""
    rows_g, cols_g = points.shape[:2]
    out = np.full((rows_g, cols_g, 2, 2), np.nan)
    for axis, grid in ((0, points), (1, points.transpose(1, 0, 2))):
        if grid.shape[1] < 3:
            out[:, :, axis] = 0.0  # a line of two corners: no bend to see
            continue
        second = grid[:, 2:] - 2.0 * grid[:, 1:-1] + grid[:, :-2]
        half = np.maximum(np.linalg.norm(grid[:, 2:] - grid[:, :-2], axis=2) / 2.0, 1e-9)
        b = second / half[..., None] ** 2
        b = np.concatenate([b[:, :1], b, b[:, -1:]], axis=1)
        out[:, :, axis] = b if axis == 0 else b.transpose(1, 0, 2)
    padded = np.pad(out, ((1, 1), (1, 1), (0, 0), (0, 0)), mode="edge")
    windows = [padded[i : i + rows_g, j : j + cols_g] for i in range(3) for j in range(3)]
    known = sum(np.isfinite(w).astype(np.float64) for w in windows)
    total = sum(np.where(np.isfinite(w), w, 0.0) for w in windows)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.asarray(np.where(known > 0, total / np.maximum(known, 1), np.nan), np.float64)


def refine_corners(
    grey: NDArray[np.float32] | NDArray[np.uint8],
    points: F64,
    axes: F64,
    radius: F64 | None = None,
    *,
    iterations: int = ITERATIONS,
    dotted: bool = False,
    bends: F64 | None = None,
) -> RefinedCorners:
    """Refine X-corners in `grey` (H x W) from their starting `points` (N, 2); `axes` (N, 2,
    2) are the image vectors along the two grid lines through each corner (they set the
    window, see corner_radius, unless `radius` (N,) gives it; `dotted`: the board has marker
    dots in its squares; `bends` (N, 2, 2): along each grid line the second difference of
    the corners over the squared half-chord, (p+ - 2p + p-) / h^2 (1/px), which bends the
    model's edges as a lens bends the lines). Returns the points with what the fit says
    about each (``refined`` False where it found no corner)."""
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    n = len(pts)
    ax = np.asarray(axes, np.float64).reshape(n, 2, 2)
    rad = (
        corner_radius(pts, ax, dotted=dotted) if radius is None else np.asarray(radius, np.float64)
    )
    if n == 0:
        empty = np.zeros(0)
        return RefinedCorners(pts.copy(), np.zeros(0, bool), empty, empty, empty)
    height, width = grey.shape[:2]

    # Parameters: x, y, angle of edge 1's normal, angle of edge 2's normal, sigma, m, a.
    # The light's slope (7, 8) starts flat.
    # Columns 9-12, held fixed: the grid lines' bends (see `bends`).
    theta = np.zeros((n, N_PARAMS + 4))
    theta[:, :2] = pts
    if bends is not None:
        theta[:, N_PARAMS:] = np.asarray(bends, np.float64).reshape(n, 4)
    # An edge along a grid line has its normal at 90 degrees to it.
    theta[:, 2] = np.arctan2(ax[:, 0, 1], ax[:, 0, 0]) + np.pi / 2
    theta[:, 3] = np.arctan2(ax[:, 1, 1], ax[:, 1, 0]) + np.pi / 2
    theta[:, 4] = np.clip(0.25 * rad, 0.6, 2.0)
    start = pts.copy()
    first = True
    # Two passes, the second with the windows re-read about the first's estimates (the
    # window follows the corner; within a pass it stays put, so costs compare). The first,
    # in a window of at most START_RADIUS_PX, takes the corner most of the way at a
    # quarter of the cost; the second, in the whole window, only the last hundredths.
    passes = (
        (np.minimum(rad, START_RADIUS_PX), max(1, iterations - iterations // 3)),
        (rad, max(1, iterations // 6)),
    )
    for pass_rad, steps in passes:
        ox, oy = _disc(float(pass_rad.max()))
        centre = np.rint(theta[:, :2])
        values, inside = _window(grey, centre, ox, oy, width, height)
        px = centre[:, :1] + ox[None, :]
        py = centre[:, 1:] + oy[None, :]
        # How much of the window lies in the image (before the band below narrows it).
        coverage = inside.mean(axis=1)
        if not first:
            values, px, py, inside = _near_edges(values, px, py, inside, theta)
        if first:
            # Starting levels: the mean, and the contrast by the edges' sign pattern.
            w0 = _weights(px, py, theta[:, :2], pass_rad, inside)
            s = np.sign(_dist(px, py, theta, 2)) * np.sign(_dist(px, py, theta, 3))
            sw = np.maximum(w0.sum(axis=1), 1e-12)
            theta[:, 5] = (w0 * values).sum(axis=1) / sw
            theta[:, 6] = (w0 * (values - theta[:, 5:6]) * s).sum(axis=1) / sw
            first = False
        theta = _levenberg_marquardt(theta, values, px, py, inside, pass_rad, steps)
    w = _weights(px, py, theta[:, :2], rad, inside)
    resid = _residual_jacobian(values, px, py, theta, jacobian=False)[0]
    final_cost = (w * resid**2).sum(axis=1)
    contrast = 2.0 * np.abs(theta[:, 6])
    residual = np.sqrt(final_cost / np.maximum(w.sum(axis=1), 1e-12)) / np.maximum(contrast, 1e-9)
    shift = np.hypot(*(theta[:, :2] - start).T)
    edge_angle = np.abs(np.sin(theta[:, 2] - theta[:, 3]))
    ok = (
        np.isfinite(theta).all(axis=1)
        & (shift <= MAX_SHIFT * rad)
        & (edge_angle > 0.2)  # two edges that cross, not one edge
        & (residual < 0.35)
        & (coverage >= 0.6)
        & (_inner_residual(grey, theta, rad) < 0.35)
    )
    out = np.where(ok[:, None], theta[:, :2], start)
    return RefinedCorners(out, ok, contrast, np.abs(theta[:, 4]), residual)


def _inner_residual(grey: NDArray[np.float32] | NDArray[np.uint8], theta: F64, rad: F64) -> F64:
    """The fitted model's weighted RMS residual over the contrast in the first pass's small
    window about the corner: a wide window fits the X about a corner hidden under a glare
    spot or a finger; the corner itself must be seen."""
    inner = np.minimum(rad, START_RADIUS_PX)
    ox, oy = _disc(float(inner.max()))
    centre = np.rint(theta[:, :2])
    height, width = grey.shape[:2]
    values, inside = _window(grey, centre, ox, oy, width, height)
    px = centre[:, :1] + ox[None, :]
    py = centre[:, 1:] + oy[None, :]
    w = _weights(px, py, theta[:, :2], inner, inside)
    resid = _residual_jacobian(values, px, py, theta, jacobian=False)[0]
    cost = (w * resid**2).sum(axis=1) / np.maximum(w.sum(axis=1), 1e-12)
    return np.asarray(np.sqrt(cost) / np.maximum(2.0 * np.abs(theta[:, 6]), 1e-9), np.float64)


def _near_edges(
    values: F64, px: F64, py: F64, inside: NDArray[np.bool_], theta: F64
) -> tuple[F64, F64, F64, NDArray[np.bool_]]:
    """Only the pixels within 3 blurs + 4 px of either edge: the rest, flat, says nothing
    of where the edges run (a wide window's flat part is most of its cost). The band is
    point-symmetric about the current corner, so it adds no bias. Each corner's band is
    packed to the left; the padding lies outside (``inside`` False)."""
    reach = 3.0 * np.maximum(np.abs(theta[:, 4:5]), 0.5) + 4.0
    band = (np.abs(_dist(px, py, theta, 2)) <= reach) | (np.abs(_dist(px, py, theta, 3)) <= reach)
    band &= inside
    keep = max(int(band.sum(axis=1).max()), 1)
    order = np.argsort(~band, axis=1, kind="stable")[:, :keep]
    pick = np.take_along_axis
    return (
        pick(values, order, axis=1),
        pick(px, order, axis=1),
        pick(py, order, axis=1),
        pick(band, order, axis=1),
    )


def _disc(radius: float) -> tuple[F64, F64]:
    """The pixel offsets (x, y) of a window of half-width `radius`: only its disc, since the
    weights are zero outside it."""
    r_max = math.ceil(radius + 1.0)
    offs = np.arange(-r_max, r_max + 1, dtype=np.float64)
    grid_y, grid_x = np.meshgrid(offs, offs, indexing="ij")
    disc = grid_x**2 + grid_y**2 <= (r_max - 0.5) ** 2
    return grid_x[disc], grid_y[disc]


def _levenberg_marquardt(
    theta: F64,
    values: F64,
    px: F64,
    py: F64,
    inside: NDArray[np.bool_],
    rad: F64,
    steps: int,
) -> F64:
    """`steps` damped Gauss-Newton steps on every corner at once, each step one evaluation
    of the model: a step that raises a corner's cost is undone and its damping raised."""
    theta = theta.copy()
    resid, jac = _residual_jacobian(values, px, py, theta)
    w = _weights(px, py, theta[:, :2], rad, inside)
    cost, hess, grad = _normal_equations(resid, jac, w)
    lam = np.full(len(theta), 1e-3)
    eye = np.eye(N_PARAMS)
    # Corners still moving; a converged one costs nothing more.
    active = np.arange(len(theta))
    for _ in range(steps):
        a = active
        diag = np.einsum("nii->ni", hess[a])
        damped = hess[a] + (lam[a, None, None] * (diag[:, :, None] + 1e-9)) * eye
        step = _solve(damped, -grad[a])
        trial = theta[a].copy()
        trial[:, :N_PARAMS] += step
        # A blur of more than MAX_SIGMA_FRACTION of the window leaves no corner to find in
        # it (the model flattens into a saddle that fits any smooth patch, a glare spot).
        top = np.maximum(MAX_SIGMA_FRACTION * rad[a], 2.0 * MIN_SIGMA_PX)
        trial[:, 4] = np.clip(np.abs(trial[:, 4]), MIN_SIGMA_PX, top)
        t_resid, t_jac = _residual_jacobian(values[a], px[a], py[a], trial)
        t_cost = (w[a] * t_resid**2).sum(axis=1)
        better = np.isfinite(t_cost) & (t_cost <= cost[a])
        lam[a] = np.where(better, np.maximum(lam[a] * 0.3, 1e-7), lam[a] * 10.0)
        if better.any():
            b = a[better]
            theta[b] = trial[better]
            # The window's weights move with the estimate.
            w[b] = _weights(px[b], py[b], theta[b, :2], rad[b], inside[b])
            cost[b], hess[b], grad[b] = _normal_equations(t_resid[better], t_jac[better], w[b])
        # Done: an accepted step below 5e-4 px, or damping that no step gets past.
        done = (better & (np.abs(step[:, :2]).max(axis=1) < 5e-4)) | (lam[a] > 1e6)
        active = a[~done]
        if active.size == 0:
            break
    return theta


def _normal_equations(resid: F64, jac: F64, w: F64) -> tuple[F64, F64, F64]:
    jw = jac * w[:, :, None]
    cost = (w * resid**2).sum(axis=1)
    jw_t = jw.transpose(0, 2, 1)
    hess = np.matmul(jw_t, jac)  # batched BLAS, far quicker than einsum here
    grad = np.matmul(jw_t, resid[:, :, None])[:, :, 0]
    return cost, hess, grad


def _solve(a: F64, b: F64) -> F64:
    """Each corner's 9 x 9 system; a singular one takes no step."""
    try:
        return np.asarray(np.linalg.solve(a, b[:, :, None])[:, :, 0], dtype=np.float64)
    except np.linalg.LinAlgError:
        out = np.zeros_like(b)
        for k in range(len(b)):
            try:
                out[k] = np.linalg.solve(a[k], b[k])
            except np.linalg.LinAlgError:
                out[k] = 0.0
        return out


def _window(
    grey: NDArray[np.float32] | NDArray[np.uint8],
    centre: F64,
    ox: F64,
    oy: F64,
    width: int,
    height: int,
) -> tuple[F64, NDArray[np.bool_]]:
    """The grey levels of each window (N, P) and which of its pixels lie in the image."""
    xs = centre[:, :1].astype(np.int64) + ox.astype(np.int64)[None, :]
    ys = centre[:, 1:].astype(np.int64) + oy.astype(np.int64)[None, :]
    inside = (xs >= 0) & (xs < width) & (ys >= 0) & (ys < height)
    values = grey[np.clip(ys, 0, height - 1), np.clip(xs, 0, width - 1)].astype(np.float64)
    return values, inside


def _weights(px: F64, py: F64, centre: F64, radius: F64, inside: NDArray[np.bool_]) -> F64:
    """A smooth window about the current estimate (Gaussian of the radius, cut there):
    symmetric about the corner, so the point-symmetric model keeps no bias; broad, so the
    edges' far pixels count."""
    r2 = (px - centre[:, :1]) ** 2 + (py - centre[:, 1:]) ** 2
    rr = radius[:, None] ** 2
    w = np.exp(-0.5 * r2 / rr) * (r2 <= rr)
    return np.asarray(w * inside, dtype=np.float64)


def _dist(px: F64, py: F64, theta: F64, k: int) -> F64:
    return _edge(px, py, theta, k)[0]


_Edge = tuple[F64, F64, F64, F64, F64 | None]


def _edge(px: F64, py: F64, theta: F64, k: int) -> _Edge:
    """Edge `k`'s (2 or 3) signed distance ``n . q + kappa (t . q)^2`` of each pixel (``q``
    from the corner, ``n`` the edge's normal, ``t`` its direction, ``kappa = -n . b / 2``
    from its grid line's bend ``b``), with ``t . q``, the normal's cos and sin, and kappa
    (None where no corner is given a bend: the straight model, quicker)."""
    c, s = np.cos(theta[:, k : k + 1]), np.sin(theta[:, k : k + 1])
    qx = px - theta[:, :1]
    qy = py - theta[:, 1:2]
    along = -qx * s + qy * c
    d = qx * c + qy * s
    col = N_PARAMS + 2 * (k - 2)
    bend = theta[:, col : col + 2]
    if not bend.any():
        return np.asarray(d, np.float64), along, c, s, None
    kappa = -0.5 * (c * bend[:, :1] + s * bend[:, 1:])
    return np.asarray(d + kappa * along**2, np.float64), along, c, s, kappa


def _model(
    px: F64, py: F64, theta: F64
) -> tuple[F64, tuple[F64, F64, F64], tuple[F64, F64, F64], _Edge, _Edge]:
    """The model (N, P), each edge's pixel step with its derivatives in d and sigma
    (_pixel_step) and each edge's (d, t . q, cos, sin, kappa) from _edge."""
    sig = theta[:, 4:5]
    edge1 = _edge(px, py, theta, 2)
    edge2 = _edge(px, py, theta, 3)
    step1 = _pixel_step(edge1[0], sig)
    step2 = _pixel_step(edge2[0], sig)
    light = (
        theta[:, 5:6] + theta[:, 7:8] * (px - theta[:, :1]) + theta[:, 8:9] * (py - theta[:, 1:2])
    )
    return light + theta[:, 6:7] * step1[0] * step2[0], step1, step2, edge1, edge2


def _pixel_step(d: F64, sig: F64) -> tuple[F64, F64, F64]:
    """The blurred step as a pixel sees it, and its derivatives in d and sigma: erf(d /
    (sqrt2 sigma)) averaged over the pixel's width across the edge (a box of 1 px, exact for
    an edge along the pixel grid and of the pixel's variance, 1/12, at any angle). Without
    it a sharp edge along the grid is one grey pixel that any (position, blur) pair fits:
    0.1 px off on sharp renders. Corners blurred by SHARP_SIGMA_PX or more take the erf of
    the same variance (sigma^2 + 1/12) instead, at half the cost."""
    step, by_d, by_sig = np.empty_like(d), np.empty_like(d), np.empty_like(d)
    sharp = sig[:, 0] < SHARP_SIGMA_PX
    if sharp.any():
        # F(x) = x erf(x / (sqrt2 s)) + sqrt(2/pi) s exp(-x^2 / (2 s^2)); the step is
        # F(d + 1/2) - F(d - 1/2); F' is the erf and dF/ds = sqrt(2/pi) exp(.).
        s_ = sig[sharp]
        hi, lo = d[sharp] + 0.5, d[sharp] - 0.5
        erf_hi, erf_lo = erf(hi / (_SQRT2 * s_)), erf(lo / (_SQRT2 * s_))
        exp_hi, exp_lo = np.exp(-0.5 * (hi / s_) ** 2), np.exp(-0.5 * (lo / s_) ** 2)
        step[sharp] = hi * erf_hi - lo * erf_lo + _SQRT_2_OVER_PI * s_ * (exp_hi - exp_lo)
        by_d[sharp] = erf_hi - erf_lo
        by_sig[sharp] = _SQRT_2_OVER_PI * (exp_hi - exp_lo)
    if not sharp.all():
        s_ = sig[~sharp]
        eff = np.sqrt(s_**2 + 1.0 / 12.0)
        x = d[~sharp]
        g = _SQRT_2_OVER_PI / eff * np.exp(-0.5 * (x / eff) ** 2)
        step[~sharp] = erf(x / (_SQRT2 * eff))
        by_d[~sharp] = g
        by_sig[~sharp] = -g * x / eff * (s_ / eff)
    return step, by_d, by_sig


def _residual_jacobian(
    values: F64, px: F64, py: F64, theta: F64, *, jacobian: bool = True
) -> tuple[F64, F64]:
    """The residual model - values (N, P) and its Jacobian (N, P, 9; empty unless asked)."""
    a = theta[:, 6:7]
    model, step1, step2, (d1, t1, c1, s1, kappa1), (d2, t2, c2, s2, kappa2) = _model(px, py, theta)
    if not jacobian:
        return model - values, np.zeros((0, N_PARAMS))
    e1, g1, s1_sig = step1
    e2, g2, s2_sig = step2
    de1 = a * g1 * e2  # dmodel/dd1
    de2 = a * e1 * g2  # dmodel/dd2
    jac = np.empty((*values.shape, N_PARAMS))
    # The light's slope is measured from the corner, so it moves with it.
    if kappa1 is None or kappa2 is None:
        jac[..., 0] = -de1 * c1 - de2 * c2 - theta[:, 7:8]
        jac[..., 1] = -de1 * s1 - de2 * s2 - theta[:, 8:9]
        jac[..., 2] = de1 * t1  # dd/dangle = t . q
        jac[..., 3] = de2 * t2
    else:
        k1 = 2.0 * kappa1 * t1
        k2 = 2.0 * kappa2 * t2
        jac[..., 0] = de1 * (-c1 + k1 * s1) + de2 * (-c2 + k2 * s2) - theta[:, 7:8]
        jac[..., 1] = de1 * (-s1 - k1 * c1) + de2 * (-s2 - k2 * c2) - theta[:, 8:9]
        # dd/dangle = t . q - 2 kappa (t . q)(n . q) (kappa's own turn with the edge neglected)
        jac[..., 2] = de1 * (t1 - k1 * (d1 - kappa1 * t1**2))
        jac[..., 3] = de2 * (t2 - k2 * (d2 - kappa2 * t2**2))
    jac[..., 4] = a * (s1_sig * e2 + e1 * s2_sig)
    jac[..., 5] = 1.0
    jac[..., 6] = e1 * e2
    jac[..., 7] = px - theta[:, :1]
    jac[..., 8] = py - theta[:, 1:2]
    return model - values, jac
