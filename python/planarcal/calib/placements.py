"""One calibration from several placements of a board: the board laid flat at K places on a
work plane larger than it, a fixed camera, one image (or one detection) per placement.

Each placement's board frame lies in the plane's at an unknown rotation and translation (its
pose); the plane's frame is the reference placement's board frame. The core
(``_core.FittedPlane.fit_placements``, planarcal_core::placements) fits the one homography and
lens jointly with every pose, so each placement's points constrain the lens where they lie,
and its covariance of H and the lens is the marginal one: a pixel far from the reference
carries how well its placement is tied to it.

This module holds what the Calibration keeps of them (``PlacementLayout``: the board points,
which placement each belongs to, the poses) and shows the user (``Placement``), how the poses
start (each placement's pixels mapped through the reference's own homography, then the rigid
fit of its board points to them), and the check that refuses a placement the plane cannot
explain: a board not flat on the plane (lifted on one side, lying on a part) or a detection
that is wrong, named instead of averaged in.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal import _core
from planarcal.calib.lens_model import LensKind
from planarcal.errors import ArgumentError, HomographyError, LensModelError, PlacementError
from planarcal.homography import estimate_homography, transform_points

F64 = NDArray[np.float64]

OUTLIER_RATIO = 4.0
"""A placement whose points, held out, land this many times farther from a flat board than
the other placements' fit predicts..."""
OUTLIER_FLOOR_PX = 0.1
"""... and by more than this (px, in the image) is refused: the plane and lens that fit the
others cannot show it where it was seen."""


@dataclasses.dataclass(frozen=True)
class PlacementLayout:
    """The placements as the fit sees them: each point's board position (mm, its board's
    frame), its placement, the reference placement and the poses (K x 3: angle rad, offset x,
    y mm: plane = R(angle) board + offset) with their covariances (K x 3 x 3)."""

    board_mm: F64
    placement: NDArray[np.intp]
    reference: int
    poses: F64
    pose_covariance: F64

    @property
    def count(self) -> int:
        return len(self.poses)

    def plane_points(self, board_mm: F64 | None = None) -> F64:
        """The board points (these, or the layout's) in the plane's frame."""
        b = self.board_mm if board_mm is None else board_mm
        pose = self.poses[self.placement]
        c, s = np.cos(pose[:, 0]), np.sin(pose[:, 0])
        return np.ascontiguousarray(
            np.stack(
                [c * b[:, 0] - s * b[:, 1] + pose[:, 1], s * b[:, 0] + c * b[:, 1] + pose[:, 2]],
                axis=1,
            )
        )

    def with_poses(self, poses: F64, covariance: F64) -> PlacementLayout:
        return dataclasses.replace(self, poses=poses, pose_covariance=covariance)

    def scaled(self, scale: F64) -> PlacementLayout:
        """The layout with board millimetres scaled by (sx, sy) (a printer's scale, see
        Calibration.rescaled); the poses are refitted by whoever uses it."""
        return dataclasses.replace(self, board_mm=np.ascontiguousarray(self.board_mm * scale))


@dataclasses.dataclass(frozen=True)
class Placement:
    """One placement of the board, as the calibration fitted it."""

    index: int
    """Its number among the placements, 0-based (the order given)."""
    name: str
    """The image it was seen in (a file name), or "placement k"."""
    image_size: tuple[int, int]
    """(width, height) of its image, px."""
    ids: NDArray[np.intp]
    """The board's ids of the points seen (indices into board.world_points())."""
    board_mm: F64
    """Those points in the board's frame, mm."""
    image_px: F64
    """Where they were seen, px."""
    plane_mm: F64
    """Where they lie in the plane's frame, mm."""
    angle_deg: float
    """The board's x axis from the plane's, degrees (counter-clockwise from x to y)."""
    offset_mm: tuple[float, float]
    """Where the board's origin lies in the plane, mm."""
    angle_std_deg: float
    """1-sigma of the angle, degrees (0 for the reference, which defines the frame)."""
    offset_std_mm: float
    """1-sigma of the offset (RMS distance), mm."""
    rms_px: float
    """RMS of its points' residuals under the joint fit, px."""
    partial: bool
    """Whether only part of the board was seen."""
    reference: bool
    """Whether its board frame is the plane's."""

    def describe(self) -> str:
        where = (
            "the reference: its board frame is the plane's"
            if self.reference
            else (
                f"at ({self.offset_mm[0]:.2f}, {self.offset_mm[1]:.2f}) mm, turned "
                f"{self.angle_deg:.3f} deg (+/- {self.offset_std_mm:.3f} mm, "
                f"{self.angle_std_deg:.4f} deg)"
            )
        )
        part = ", partial view" if self.partial else ""
        return (
            f"{placement_label(self.index, self.name)}: {len(self.ids)} points{part}, {where}; "
            f"residuals {self.rms_px:.3f} px RMS"
        )


def placement_label(k: int, name: str) -> str:
    """ "placement k (name)", or "placement k" where the name says no more."""
    own = f"placement {k}"
    return own if name == own else f"{own} ({name})"


def start_poses(
    board_mm: F64, image_px: F64, placement: NDArray[np.intp], count: int, reference: int
) -> F64:
    """Poses to start the joint fit from (K x 3): each placement's pixels mapped to the plane
    through the reference's own homography, then the rigid transform that best carries its
    board points there. The lens is ignored, so far placements start some millimetres off;
    the fit's Gauss-Newton steps on each pose take them the rest of the way."""
    ref = placement == reference
    h = estimate_homography(board_mm[ref], image_px[ref], "normalized_dlt", True)
    to_plane = np.linalg.inv(h)
    out = np.zeros((count, 3))
    for k in range(count):
        if k == reference:
            continue
        mine = placement == k
        out[k] = rigid_fit(board_mm[mine], transform_points(to_plane, image_px[mine]))
    return out


def rigid_fit(src: F64, dst: F64) -> tuple[float, float, float]:
    """The rotation and translation (angle rad, x, y) carrying src onto dst in least squares
    (Kabsch in 2-D, no reflection)."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - cs, dst - cd
    # angle = atan2(sum cross, sum dot): the 2-D Procrustes solution.
    angle = math.atan2(float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])), float(np.sum(a * b)))
    c, s = math.cos(angle), math.sin(angle)
    t = cd - np.array([c * cs[0] - s * cs[1], s * cs[0] + c * cs[1]])
    return angle, float(t[0]), float(t[1])


def fit_placements(
    layout: PlacementLayout, image_px: F64, lens: str, size: tuple[int, int]
) -> tuple[_core.FittedPlane, PlacementLayout]:
    """The core's joint fit of the plane with lens model `lens` and every pose, started at the
    layout's poses; the plane and the layout with the fitted poses."""
    return _with_poses(
        layout,
        _core.FittedPlane.fit_placements(*_core_layout(layout, image_px), *_core_model(lens, size)),
    )


def placements_at(
    h: F64,
    radial: _core.RadialLens,
    layout: PlacementLayout,
    image_px: F64,
    lens: str,
    size: tuple[int, int],
) -> tuple[_core.FittedPlane, PlacementLayout]:
    """The core's model of a placements fit at known parameters and poses (a file read back,
    a calibration rescaled to another frame size), with its covariance on these points."""
    return _with_poses(
        layout,
        _core.FittedPlane.at_placements(
            h, radial, *_core_layout(layout, image_px), *_core_model(lens, size)
        ),
    )


def _core_layout(layout: PlacementLayout, image_px: F64) -> tuple[Any, ...]:
    """The core's arguments for the points and poses: board, image, placement, reference,
    poses."""
    poses = [(float(a), float(x), float(y)) for a, x, y in layout.poses]
    return (layout.board_mm, image_px, layout.placement.tolist(), layout.reference, poses)


def _core_model(lens: str, size: tuple[int, int]) -> tuple[Any, ...]:
    return (LensKind(lens), (float(size[0]), float(size[1])))


def _with_poses(
    layout: PlacementLayout, out: tuple[_core.FittedPlane, F64, F64]
) -> tuple[_core.FittedPlane, PlacementLayout]:
    plane, poses, cov = out
    return plane, layout.with_poses(np.asarray(poses), np.asarray(cov))


def residual_rms(image_px: F64, predicted_px: F64, placement: NDArray[np.intp], count: int) -> F64:
    """Each placement's RMS residual (px, per coordinate) between its seen and predicted
    pixels."""
    d2 = np.sum((image_px - predicted_px) ** 2, axis=1)
    return np.array([math.sqrt(float(np.mean(d2[placement == k])) / 2.0) for k in range(count)])


def check_placements(
    layout: PlacementLayout,
    ideal_px: F64,
    lens: str,
    size: tuple[int, int],
    names: Sequence[str],
) -> None:
    """PlacementError naming a placement that the plane the others define cannot explain: each
    placement (of three or more) is held out, the others fitted together (lens model `lens`),
    its pixels mapped to the plane by them and its board points fitted there by a rotation and
    translation. A flat, correctly detected placement lands within the others' predicted
    error (their fit's 1-sigma at its pixels, with their residuals' noise in its pixels: a
    bad placement among them inflates both, so it is the held-out one that stands out); one
    more than OUTLIER_RATIO times off, and by more than OUTLIER_FLOOR_PX, is named with what
    its misfit looks like (``misfit``). Two placements cannot outvote each other and are not
    judged. ``ideal_px``: the pixels the plane maps (undistorted, with intrinsics)."""
    count = layout.count
    if count < 3:
        return
    worst: tuple[float, int, F64] | None = None
    for k in range(count):
        mine = layout.placement == k
        others = _without(layout, k)
        try:
            plane, _ = fit_placements(others, ideal_px[~mine], lens, size)
            seen, std = plane.image_to_world_std(ideal_px[mine], plane.sigma)
        except (HomographyError, LensModelError, ArgumentError):
            continue  # the others alone cannot map it: no verdict on it
        board = layout.board_mm[mine]
        angle, x, y = rigid_fit(board, seen)
        c, s = math.cos(angle), math.sin(angle)
        placed = board @ np.array([[c, s], [-s, c]]) + np.array([x, y])
        rms_mm = math.sqrt(float(np.mean(np.sum((seen - placed) ** 2, axis=1))))
        expected = math.sqrt(float(np.mean(std**2)))
        # The misfit in pixels: the board's spread in mm against its image's.
        px_per_mm = float(np.std(ideal_px[mine]) / max(float(np.std(board)), 1e-12))
        score = rms_mm / max(expected, 1e-12)
        if (
            score > OUTLIER_RATIO
            and rms_mm * px_per_mm > OUTLIER_FLOOR_PX
            and (worst is None or score > worst[0])
        ):
            worst = (score, k, seen)
    if worst is None:
        return
    score, k, seen = worst
    mine = layout.placement == k
    what, redo = misfit(layout.board_mm[mine], seen)
    raise PlacementError(
        f"{placement_label(k, names[k])} does not fit the plane the other placements define: "
        f"held out, its points land {score:.0f} times farther from a board laid flat than "
        f"the others' fit predicts; {what}; {redo}",
        placement=k,
    )


def _without(layout: PlacementLayout, k: int) -> PlacementLayout:
    """The layout without placement k (the others renumbered; the reference another one if k
    was it: the frame only fixes the gauge here)."""
    keep = layout.placement != k
    placement = layout.placement[keep]
    placement = placement - (placement > k)
    reference = layout.reference - (layout.reference > k) if layout.reference != k else 0
    poses = np.delete(layout.poses, k, axis=0)
    if layout.reference == k:
        # The new reference's pose becomes the identity: carry the others into its frame.
        poses = _relative_to(poses, reference)
    return PlacementLayout(
        np.ascontiguousarray(layout.board_mm[keep]),
        placement,
        int(reference),
        poses,
        np.zeros((len(poses), 3, 3)),
    )


def _relative_to(poses: F64, r: int) -> F64:
    """The poses expressed in placement r's frame (its pose then the identity)."""
    a0, x0, y0 = (float(v) for v in poses[r])
    c, s = math.cos(-a0), math.sin(-a0)
    out: F64 = poses.copy()
    dx, dy = poses[:, 1] - x0, poses[:, 2] - y0
    out[:, 0] = poses[:, 0] - a0
    out[:, 1] = c * dx - s * dy
    out[:, 2] = s * dx + c * dy
    return out


REDO_FLAT = "take that image again with the board flat on the plane, or leave it out"
REDO_DETECTION = "check the board's description (its size, layout, origin), or leave that image out"


def misfit(board_mm: F64, seen_mm: F64) -> tuple[str, str]:
    """What a placement's misfit looks like, and what to do, from the homography carrying its
    board points to where the plane puts its pixels (a correct, flat placement's is a
    rotation and a translation): a mirror or points that fit no one board (a wrong detection),
    a scale (lying on something) or a squeeze (lifted on one side)."""
    try:
        g = estimate_homography(board_mm, seen_mm, "normalized_dlt", True)
    except HomographyError:
        return "its points do not lie on one board as described: a wrong detection", REDO_DETECTION
    spread = float(np.sqrt(np.mean(np.sum((transform_points(g, board_mm) - seen_mm) ** 2, 1))))
    step = np.hypot(*np.diff(board_mm, axis=0).T)
    pitch = float(np.median(step[step > 0])) if (step > 0).any() else 1.0
    if spread > 0.05 * pitch:
        return (
            "its points do not fit one board seen through one homography either: a wrong "
            "detection (points matched to the wrong ids)",
            REDO_DETECTION,
        )
    a = g[:2, :2] / g[2, 2]
    det = float(np.linalg.det(a))
    if det < 0:
        return "it is seen mirrored: a wrong detection or board description", REDO_DETECTION
    sv = np.linalg.svd(a, compute_uv=False)
    scale = math.sqrt(det)
    squeeze = float(sv[1] / sv[0])
    if abs(scale - 1.0) > 2.0 * (1.0 - squeeze):
        side = "nearer the camera: lying on something" if scale > 1 else "farther than it"
        return (
            f"it is seen {abs(scale - 1.0):.2%} {'larger' if scale > 1 else 'smaller'} than a "
            f"board on the plane ({side}), not flat on the plane",
            REDO_FLAT,
        )
    # A board lifted on one side is seen larger towards that side: a squeeze and a slope.
    return (
        f"it is seen squeezed by {1.0 - squeeze:.2%} across one direction: lifted on one side "
        "(or bent), not flat on the plane",
        REDO_FLAT,
    )
