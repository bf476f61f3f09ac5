"""Frame sizes: checking that a picture is the size a calibration was made on, saying why
not and what to do, and the same calibration for frames of another resolution of the same
aspect ratio (every pixel quantity scaled, the world frame untouched)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal._core import RadialLens
from planarcal.calib.plane_fit import PlaneFit, plane_at
from planarcal.camera import CameraIntrinsics
from planarcal.errors import ArgumentError

F64 = NDArray[np.float64]


def checked_image_size(size: Any) -> tuple[int, int] | None:
    """``image_size=`` checked: None, or (width, height) in whole pixels."""
    if size is None:
        return None
    try:
        w, h = size
    except (TypeError, ValueError):
        raise ArgumentError(f"image_size must be (width, height), got {size!r}") from None
    for v in (w, h):
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
            raise ArgumentError(f"image_size must be two positive whole numbers, got {size!r}")
    return int(w), int(h)


def given_size(size: Any) -> tuple[int, int]:
    """A (width, height) that must be there: checked_image_size without None."""
    checked = checked_image_size(size)
    if checked is None:
        raise ArgumentError("image_size must be (width, height), got None")
    return checked


def size_text(size: tuple[int, int]) -> str:
    return f"{size[0]} x {size[1]} px"


def same_aspect(a: tuple[int, int], b: tuple[int, int]) -> bool:
    """Exactly the same shape (so one is the other uniformly scaled)."""
    return a[0] * b[1] == a[1] * b[0]


def aspect_text(size: tuple[int, int]) -> str:
    """The aspect ratio in lowest terms: 1280 x 720 -> "16:9"."""
    d = math.gcd(*size)
    return f"{size[0] // d}:{size[1] // d}"


def size_mismatch(size: tuple[int, int], made_on: tuple[int, int], what: str) -> str:
    """Why a picture of `size` cannot go through a calibration made on `made_on`, and what to
    do: rescale the calibration for a deliberate change of resolution, else calibrate again."""
    head = (
        f"this {what} is {size_text(size)} but the calibration was made on "
        f"{size_text(made_on)} {what}s: its pixels would map to the wrong millimetres. "
    )
    if same_aspect(size, made_on):
        return head + (
            f"Calibrate at {size[0]} x {size[1]}, or, if the camera's resolution was changed "
            f"deliberately (the same view, scaled), use cal.for_frame_size({size[0]}, "
            f"{size[1]}) (and save it for planarcal run / locate)"
        )
    return head + (
        f"Calibrate again at {size[0]} x {size[1]}: another aspect ratio "
        f"({aspect_text(size)} against {aspect_text(made_on)}) is a cropped view, which "
        "cal.for_frame_size cannot rescale to"
    )


def pixel_scaling(s: float) -> F64:
    """Old pixels -> new pixels of an image scaled by `s`, pixel centres at whole numbers: the
    image's outer edges (-0.5 and width - 0.5) go to the new ones."""
    t = (s - 1.0) / 2.0
    return np.array([[s, 0.0, t], [0.0, s, t], [0.0, 0.0, 1.0]])


def affine(a: F64, points: F64) -> F64:
    """Points (N, 2) through an affine 3 x 3 matrix."""
    out: F64 = points @ a[:2, :2].T + a[:2, 2]
    return out


def scaled_intrinsics(
    intrinsics: CameraIntrinsics, s: float, size: tuple[int, int]
) -> CameraIntrinsics:
    """The same camera at a resolution scaled by `s`: K scaled with the pixels; the distortion
    coefficients act on normalised coordinates and stay; the RMS errors scale."""
    per_view = intrinsics.per_view_rms_px
    return CameraIntrinsics(
        pixel_scaling(s) @ intrinsics.matrix,
        np.array(intrinsics.dist_coeffs),
        size,
        None if intrinsics.rms_px is None else s * intrinsics.rms_px,
        intrinsics.n_views,
        None if per_view is None else tuple(s * v for v in per_view),
    )


def scaled_fit(
    fit: PlaneFit,
    h: F64,
    world: F64,
    image: F64,
    made_on: tuple[int, int],
    size: tuple[int, int],
    intrinsics: CameraIntrinsics | None,
) -> PlaneFit:
    """`fit`, made on frames of `made_on`, for frames of `size`: `h`, `image` and `intrinsics`
    are already scaled; the lens's centre and unit and the candidates' pixel errors follow."""
    s = size[0] / made_on[0]
    lens = fit.plane.lens
    centre = affine(pixel_scaling(s), np.array([lens.centre_px]))[0]
    scaled_lens = RadialLens(
        (float(centre[0]), float(centre[1])), s * lens.scale_px, lens.k1, lens.k2
    )
    layout = fit.placements
    plane, layout = plane_at(h, world, image, size, fit.lens, scaled_lens, intrinsics, layout)
    candidates = [
        dataclasses.replace(c, loo_mean_px=s * c.loo_mean_px, sigma_px=s * c.sigma_px)
        for c in fit.candidates
    ]
    note = f"{fit.note} (rescaled from {size_text(made_on)} frames)"
    return PlaneFit(plane, h, fit.lens, candidates, note, placements=layout)
