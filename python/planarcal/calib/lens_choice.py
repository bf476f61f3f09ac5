"""Which lens model a calibration fits: the policy behind ``lens=`` ("auto" fits each model
and keeps the simplest whose leave-one-out error no richer one clearly beats; a board that
covers too little of the image gets none), the candidates it tried and its verdicts, and the
cases where no lens model is fitted at all (intrinsics, the paper's estimator, no image size)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal import _core
from planarcal.calib.lens_candidate import LensCandidate
from planarcal.calib.lens_model import LENS_MODELS, LensKind
from planarcal.calib.placements import PlacementLayout, fit_placements
from planarcal.calib.plane_fit import PlaneFit, fit_homography_alone
from planarcal.camera import CameraIntrinsics
from planarcal.errors import HomographyError, LensModelError
from planarcal.homography import Solver

F64 = NDArray[np.float64]

LensChoice = Literal["auto", "none", "k1", "k1k2", "k1k2c"]

# A richer lens model must lower the mean leave-one-out error by this fraction to be chosen.
LENS_MARGIN = 0.01
# The points must span this fraction of the half-diagonal in distance from the image centre
# for the distortion to be determined at all: a small central board sees almost none of it,
# and a patch in one corner sees it only over its own span of radii (a distortion the same
# over all its points is a scale, which the homography takes).
MIN_LENS_COVERAGE = 0.35
# A fitted distortion centre farther than this (in half-diagonals) from the image centre is
# not a lens's: the model is fitting something else (a board that is not flat).
MAX_CENTRE_OFFSET = 0.2


def _coverage(image: F64, size: tuple[int, int]) -> float:
    """The span of distances from the image centre that the points cover, as a share of the
    half-diagonal (0 to 1): from the nearest point of their convex hull (0 when the hull
    holds the centre, as a whole board in view does) to the farthest point. A partial view
    in a corner reaches the corner but spans only the radii of its patch."""
    w, h = size
    centre = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    reach = float(np.hypot(*(image - centre).T).max())
    return (reach - hull_distance(image, centre)) / (0.5 * math.hypot(w, h))


def hull_distance(points: F64, at: F64) -> float:
    """The distance from `at` to the convex hull of `points` (px), 0 inside it."""
    pts = np.asarray(points, np.float64)
    if len(pts) == 0:
        return math.inf
    if len(pts) < 3:
        return float(np.hypot(*(pts - at).T).min())
    hull = cv2.convexHull(pts.astype(np.float32)).reshape(-1, 2).astype(np.float64)
    if len(hull) < 3:
        return float(np.hypot(*(pts - at).T).min())
    # Inside: every edge turns the same way round `at` (the hull is convex).
    a, b = hull, np.roll(hull, -1, axis=0)
    cross = (b[:, 0] - a[:, 0]) * (at[1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (at[0] - a[:, 0])
    if (cross >= 0).all() or (cross <= 0).all():
        return 0.0
    ab = b - a
    t = np.clip(np.sum((at - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), 1e-300), 0, 1)
    nearest = a + t[:, None] * ab
    return float(np.hypot(*(nearest - at).T).min())


def fit_with_lens(
    world: F64,
    image: F64,
    solver: Solver,
    refine: bool,
    lens: str,
    size: tuple[int, int] | None,
    intrinsics: CameraIntrinsics | None,
    layout: PlacementLayout | None = None,
) -> PlaneFit:
    """The fit ``lens=`` asks for: the intrinsics' undistortion, no lens model (asked for,
    the paper's estimator, or nothing to centre one on), a forced model, or the choice. With
    the placements' `layout` (its poses the start), each is the joint fit of every
    placement's pose with the plane (`world` is then unused)."""
    paper = solver != "normalized_dlt" or not refine
    fit = _fitter(world, image, size, layout, intrinsics)
    if intrinsics is not None:
        if lens not in ("auto", "none"):
            raise LensModelError(
                f"with intrinsics the lens is the camera model's: lens must be 'auto' or "
                f"'none', got {lens!r}"
            )
        ideal = intrinsics.undistort_points(image)
        if layout is not None:
            plane, placed = fit("none")
            return PlaneFit(
                plane,
                plane.homography,
                "intrinsics",
                [],
                "points undistorted by the camera's intrinsics",
                placements=placed,
            )
        plane, h = fit_homography_alone(world, ideal, solver, refine, size)
        return PlaneFit(plane, h, "intrinsics", [], "points undistorted by the camera's intrinsics")
    if paper and lens not in ("auto", "none"):
        raise LensModelError(
            f"a lens model is fitted jointly with H by Levenberg-Marquardt; solver={solver!r}, "
            f"refine={refine} fit a homography alone (keep the defaults to use lens={lens!r})"
        )
    if lens == "none" or paper:
        why = "the paper's estimator" if paper else "asked for"
        return _alone(world, image, solver, refine, size, fit, layout, f"no lens model ({why})")
    if size is None:
        if lens != "auto":
            raise LensModelError(
                "a lens model is centred on the image: give image_size=(width, height)"
            )
        return _alone(
            world, image, solver, refine, size, fit, layout,
            "no lens model (no image size to centre one on)",
        )  # fmt: skip
    coverage = _coverage(image, size)
    if lens != "auto":
        plane, placed = fit(lens)
        note = f"lens model {lens} (asked for)"
        if coverage < MIN_LENS_COVERAGE:
            note += (
                f"; the {_reach_words(layout)} only {coverage:.0%} of the way from the "
                "image centre to its corners (from its nearest point to its farthest), too "
                "little to determine the distortion"
            )
        return PlaneFit(plane, plane.homography, lens, [], note, placements=placed)
    if coverage < MIN_LENS_COVERAGE:
        return _alone(
            world,
            image,
            solver,
            refine,
            size,
            fit,
            layout,
            f"no lens model: the {_reach_words(layout)} only {coverage:.0%} of the way "
            f"from the image centre to its corners (from its nearest point to its farthest; "
            f"at least {MIN_LENS_COVERAGE:.0%} needed), too little to determine the "
            "distortion; let the board fill more of the view",
        )
    return _select_lens(world, image, solver, refine, size, fit, layout)


Fitter = Callable[[str], tuple[Any, PlacementLayout | None]]


def _fitter(
    world: F64,
    image: F64,
    size: tuple[int, int] | None,
    layout: PlacementLayout | None,
    intrinsics: CameraIntrinsics | None,
) -> Fitter:
    """The fit of one lens model: the plane's alone, or jointly with the placements' poses
    (started from a fit with no lens model, whose poses are the closer start)."""
    if layout is None:

        def one(model: str) -> tuple[Any, PlacementLayout | None]:
            assert size is not None
            frame = (float(size[0]), float(size[1]))
            return _core.FittedPlane.fit(world, image, LensKind(model), frame), None

        return one
    if size is None:
        raise LensModelError("a calibration from placements needs the images' size")
    ideal = image if intrinsics is None else intrinsics.undistort_points(image)
    start: list[PlacementLayout] = []

    def joint(model: str) -> tuple[Any, PlacementLayout | None]:
        if not start:
            start.append(fit_placements(layout, ideal, "none", size)[1])
        return fit_placements(start[0], ideal, model, size)

    return joint


def _reach_words(layout: PlacementLayout | None) -> str:
    return "board reaches" if layout is None else "placements reach"


def _alone(
    world: F64,
    image: F64,
    solver: Solver,
    refine: bool,
    size: tuple[int, int] | None,
    fit: Fitter,
    layout: PlacementLayout | None,
    note: str,
    candidates: list[LensCandidate] | None = None,
) -> PlaneFit:
    """No lens model: the chosen solver's homography (one board view) or the joint fit with
    no lens parameters (placements)."""
    if layout is not None:
        plane, placed = fit("none")
        return PlaneFit(plane, plane.homography, "none", candidates or [], note, placements=placed)
    plane, h = fit_homography_alone(world, image, solver, refine, size)
    return PlaneFit(plane, h, "none", candidates or [], note)


def _select_lens(
    world: F64,
    image: F64,
    solver: Solver,
    refine: bool,
    size: tuple[int, int],
    fit: Fitter,
    layout: PlacementLayout | None,
) -> PlaneFit:
    """Fits every lens model and keeps the simplest whose leave-one-out error no richer one
    beats by LENS_MARGIN."""
    centre = np.array([(size[0] - 1) / 2.0, (size[1] - 1) / 2.0])
    half_diagonal = 0.5 * math.hypot(*size)
    tried: dict[str, tuple[Any, float, float, str]] = {}
    caches: dict[str, tuple[F64, F64]] = {}
    placed: dict[str, PlacementLayout | None] = {}
    for model in LENS_MODELS:
        try:
            plane, placed[model] = fit(model)
        except (LensModelError, HomographyError) as e:
            if model == "none":
                raise
            tried[model] = (None, math.nan, math.nan, f"refused: {e}")
            continue
        offset = float(np.hypot(*(np.array(plane.lens.centre_px) - centre)))
        if model == "k1k2c" and offset > MAX_CENTRE_OFFSET * half_diagonal:
            tried[model] = (
                None,
                math.nan,
                plane.sigma,
                f"refused: its centre ({plane.lens.centre_px[0]:.0f}, "
                f"{plane.lens.centre_px[1]:.0f}) px is "
                f"{offset:.0f} px from the image centre, not a lens's (is the board flat?)",
            )
            continue
        px, mm = plane.leave_one_out()
        err = np.hypot(*(px - image).T)
        err = err[np.isfinite(err)]
        loo = float(err.mean()) if err.size else math.nan
        tried[model] = (plane, loo, plane.sigma, "")
        caches[model] = (px, mm)
    best = "none"
    for model in LENS_MODELS[1:]:
        plane, loo, _, why = tried[model]
        if plane is not None and loo < tried[best][1] * (1.0 - LENS_MARGIN):
            best = model
    candidates = []
    for model in LENS_MODELS:
        plane, loo, sigma, why = tried[model]
        verdict = why or ("chosen" if model == best else "not earned")
        candidates.append(LensCandidate(model, loo, sigma, verdict))
    gain = tried["none"][1]
    if best == "none":
        note = (
            "no lens model: none lowered the leave-one-out error by "
            f"{LENS_MARGIN:.0%} or more ({gain:.3f} px without one)"
        )
        return _alone(world, image, solver, refine, size, fit, layout, note, candidates)
    chosen = tried[best]
    note = (
        f"lens model {best}: leave-one-out error {chosen[1]:.3f} px, against {gain:.3f} px "
        "with a homography alone"
    )
    return PlaneFit(
        chosen[0], chosen[0].homography, best, candidates, note, caches[best], placed[best]
    )
