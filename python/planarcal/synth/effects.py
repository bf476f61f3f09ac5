"""What a photograph adds to the geometry: the textures of the table and the paper, uneven
lighting (a gradient and vignetting), blur, sensor noise and rounding to 8 bits, and a
webcam's JPEG (:func:`jpeg`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.errors import ImageError
from planarcal.synth.camera import CameraModel
from planarcal.synth.scene import _TABLE

F64 = NDArray[np.float64]


class _ImageEffects(NamedTuple):
    """render_scene's image effects, checked (see there)."""

    blur: float  # px
    noise: float  # grey levels
    gradient: float
    light_angle: float  # degrees
    vignette: float
    textures: dict[str, float]  # table_texture, paper_texture: grey levels

    def record(self) -> dict[str, float]:
        """The effects by render_scene's argument names (the textures apart)."""
        return {
            "blur_sigma_px": self.blur,
            "noise_sigma": self.noise,
            "lighting_gradient": self.gradient,
            "lighting_angle_deg": self.light_angle,
            "vignette": self.vignette,
        }


def _checked_image_effects(
    blur_sigma_px: float,
    noise_sigma: float,
    lighting_gradient: float,
    lighting_angle_deg: float,
    vignette: float,
    table_texture: float,
    paper_texture: float,
) -> _ImageEffects:
    """render_scene's effects arguments, checked; ImageError for one out of range."""
    blur = arguments.real("blur_sigma_px", blur_sigma_px, ImageError)
    noise = arguments.real("noise_sigma", noise_sigma, ImageError)
    gradient = arguments.real("lighting_gradient", lighting_gradient, ImageError)
    light_angle = arguments.real("lighting_angle_deg", lighting_angle_deg, ImageError)
    vig = arguments.real("vignette", vignette, ImageError)
    textures = {
        name: arguments.real(name, value, ImageError)
        for name, value in (("table_texture", table_texture), ("paper_texture", paper_texture))
    }
    for name, value in textures.items():
        if not 0.0 <= value <= 255.0:
            raise ImageError(f"{name} must be 0 to 255 grey levels, got {value!r}")
    if not 0.0 <= blur <= 50.0:
        raise ImageError(f"blur_sigma_px must be 0 to 50 px, got {blur_sigma_px!r}")
    if noise < 0.0:
        raise ImageError(f"noise_sigma must be >= 0 grey levels, got {noise_sigma!r}")
    if not 0.0 <= gradient < 2.0:
        raise ImageError(f"lighting_gradient must be in [0, 2), got {lighting_gradient!r}")
    if not 0.0 <= vig < 1.0:
        raise ImageError(f"vignette must be in [0, 1), got {vignette!r}")
    return _ImageEffects(blur, noise, gradient, light_angle, vig, textures)


def _apply_image_effects(
    radiance: NDArray[np.float32],
    camera: CameraModel,
    effects: _ImageEffects,
    seed: int,
    glare: tuple[tuple[float, float, float], ...] = (),
) -> NDArray[np.uint8]:
    """The evenly lit, sharp image (float32, grey or BGR; changed in place) photographed:
    the lighting's gain, the glare spots, the blur, the noise (from ``default_rng(seed)``),
    rounded to uint8."""
    if effects.gradient or effects.vignette:
        gain = _lighting(camera, effects.gradient, effects.light_angle, effects.vignette)
        radiance *= gain if radiance.ndim == 2 else gain[:, :, None]
    if glare:
        light = _glare(camera, glare)
        radiance += light if radiance.ndim == 2 else light[:, :, None]
    if effects.blur > 0.0:
        blur = effects.blur
        radiance = np.asarray(
            cv2.GaussianBlur(
                radiance, (0, 0), sigmaX=blur, sigmaY=blur, borderType=cv2.BORDER_REFLECT
            ),
            dtype=np.float32,
        )
    if effects.noise > 0.0:
        rng = np.random.default_rng(seed)
        radiance += rng.normal(0.0, effects.noise, radiance.shape).astype(np.float32)
    return np.clip(np.rint(radiance), 0, 255).astype(np.uint8)


GLARE_PEAK = 510.0
"""The light a glare spot adds at its centre, in grey levels: twice full scale, so that the
spot saturates out to its radius whatever lies under it (see :func:`_glare`)."""


def _checked_glare(glare: object) -> tuple[tuple[float, float, float], ...]:
    """render_scene's glare spots as (x_px, y_px, radius_px) tuples; ImageError if bad."""
    try:
        spots = [tuple(spot) for spot in glare]  # type: ignore[attr-defined]
    except TypeError:
        raise ImageError(
            f"glare must be a sequence of (x_px, y_px, radius_px) spots, got {glare!r}"
        ) from None
    out = []
    for k, spot in enumerate(spots):
        if len(spot) != 3:
            raise ImageError(f"glare[{k}] must be (x_px, y_px, radius_px), got {spot!r}")
        x, y, r = (arguments.real(f"glare[{k}]", v, ImageError) for v in spot)
        if r <= 0.0:
            raise ImageError(f"glare[{k}]: the radius must be > 0 px, got {r!r}")
        out.append((x, y, r))
    return tuple(out)


def _glare(camera: CameraModel, spots: tuple[tuple[float, float, float], ...]) -> F64:
    """The light of glare spots, (height, width) grey levels: each adds GLARE_PEAK
    2^-(d/r)^2 at distance d from its centre, so a spot saturates any surface out to its
    radius r (where it adds 255) and fades beyond (32 grey levels at 2 r)."""
    x = np.arange(camera.width, dtype=np.float64)[None, :]
    y = np.arange(camera.height, dtype=np.float64)[:, None]
    light = np.zeros((camera.height, camera.width))
    for cx, cy, r in spots:
        light += GLARE_PEAK * np.exp2(-((x - cx) ** 2 + (y - cy) ** 2) / (r * r))
    return np.asarray(light, dtype=np.float32)


def _lighting(camera: CameraModel, gradient: float, angle_deg: float, vig: float) -> F64:
    """The multiplicative gain of the uneven lighting, (height, width)."""
    w, h = camera.width, camera.height
    x = np.arange(w, dtype=np.float64)[None, :]
    y = np.arange(h, dtype=np.float64)[:, None]
    gain = np.ones((h, w))
    if gradient:
        a = math.radians(angle_deg)
        proj = (x - (w - 1) / 2.0) * math.cos(a) + (y - (h - 1) / 2.0) * math.sin(a)
        extent = 0.5 * ((w - 1) * abs(math.cos(a)) + (h - 1) * abs(math.sin(a)))
        gain = gain * (1.0 + 0.5 * gradient * proj / extent)
    if vig:
        r2 = (x - camera.cx) ** 2 + (y - camera.cy) ** 2
        corner = max(
            (cxx - camera.cx) ** 2 + (cyy - camera.cy) ** 2
            for cxx in (0.0, w - 1.0)
            for cyy in (0.0, h - 1.0)
        )
        gain = gain * (1.0 - vig * r2 / corner)
    return np.asarray(gain, dtype=np.float32)


# The textures' layers: (cells along u, cells along v, weight), u along the grain.
_TABLE_LAYERS = ((2, 2, 0.35), (4, 4, 0.45), (12, 12, 0.5), (48, 2, 0.7))
_PAPER_LAYERS = ((2, 2, 0.7), (6, 6, 0.4))


def _plane_texture(x: F64, y: F64, material: int, seed: int) -> NDArray[np.float32]:
    """A random texture of unit standard deviation on the table plane, sampled at the table
    points (x, y) (mm, one per pixel): a sum of value-noise layers (white noise on grids of
    2 texels and coarser, cubic-interpolated), each of them normalised, on a grid whose
    texel is the pixels' median footprint, turned by a random angle (the grain's
    direction)."""
    rng = np.random.default_rng([seed, material])  # not the image noise's stream
    turn = rng.uniform(0.0, math.pi)
    c, s = math.cos(turn), math.sin(turn)
    u, v = c * x + s * y, c * y - s * x
    step = np.hypot(np.diff(u[::8], axis=1), np.diff(v[::8], axis=1))
    texel = float(np.median(step))
    u0, v0 = float(u.min()) - 2.0 * texel, float(v.min()) - 2.0 * texel
    nu = math.ceil((float(u.max()) - u0) / texel) + 3
    nv = math.ceil((float(v.max()) - v0) / texel) + 3
    growth = math.sqrt(nu * nv / (4.0 * x.size))  # steep views see far: cap the grid
    if growth > 1.0:
        texel *= growth
        nu, nv = int(nu / growth) + 3, int(nv / growth) + 3
    layers = _TABLE_LAYERS if material == _TABLE else _PAPER_LAYERS
    grid = np.zeros((nv, nu), dtype=np.float32)
    for su, sv, weight in layers:
        coarse = rng.standard_normal((nv // sv + 4, nu // su + 4)).astype(np.float32)
        fine = cv2.resize(
            coarse, (coarse.shape[1] * su, coarse.shape[0] * sv), interpolation=cv2.INTER_CUBIC
        )[:nv, :nu]
        grid += weight * fine / max(float(fine.std()), 1e-6)
    grid /= max(float(grid.std()), 1e-6)
    map_u = ((u - u0) / texel).astype(np.float32)
    map_v = ((v - v0) / texel).astype(np.float32)
    out = cv2.remap(grid, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return np.asarray(out, dtype=np.float32)


def jpeg(image: NDArray[np.uint8], quality: int = 75) -> NDArray[np.uint8]:
    """``image`` (uint8, grey or BGR) compressed as JPEG at ``quality`` (0-100) and decoded
    again, as a webcam's stream would deliver it: 8 x 8 blocking and ringing at edges, and in
    colour the chroma subsampling. Same shape and dtype."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
        raise ImageError("jpeg needs a uint8 image")
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)):
        raise ImageError(f"jpeg needs a grey or BGR image, got shape {image.shape}")
    if isinstance(quality, bool) or not isinstance(quality, int | np.integer):
        raise ImageError(f"quality must be a whole number 0-100, got {quality!r}")
    if not 0 <= quality <= 100:
        raise ImageError(f"quality must be 0-100, got {quality}")
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 grey or BGR image
        raise ImageError("JPEG encoding failed")
    flag = cv2.IMREAD_GRAYSCALE if image.ndim == 2 else cv2.IMREAD_COLOR
    return np.asarray(cv2.imdecode(data, flag), dtype=np.uint8)
