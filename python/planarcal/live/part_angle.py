"""Each part's angle: the principal axis of the area its outline encloses, turned into the
frame its position is given in.

The axis comes from the central second moments of the enclosed area (the core's
``measure_contours``: Green's theorem over the sub-pixel outline, [mu20, mu11, mu02] / area in
px^2), not from the scatter of the outline's points (which would weigh each side by how densely
it is sampled). Pixels are not the plane: perspective and the lens stretch a part's image
differently in different directions (the mapping is not conformal), so an axis measured in
pixels can be several degrees off on the plane under a steep view. The moments are therefore
carried into the output frame through the mapping's local Jacobian J at the centroid,
C_out = J C_px J^T (first order in the part's size over the distance on which the mapping's
derivative changes: on silhouettes of 8 x 16 mm parts projected exactly from a 45 degree tilt,
the axis so turned is within 0.004 degree of the true one), and the axis is taken there.

J comes from central differences of the very mapping the positions go through
(planarcal.live.local_map, the same samples that put each part's centroid on the plane),
rather than analytically: the positions may pass through a lens model, a lift to the parts'
height and a registration to a robot's frame, and differencing the composition gives the angle
in exactly the frame of the positions, whatever is composed, with no second derivation to keep
in step. Its error is the step's (a pixel) squared times the mapping's third derivative: 1e-7
of the Jacobian against a step of 0.01 px, through the paper scene's calibration with its lens
model.

Convention: degrees in [-90, 90), measured in the output frame from its +x axis towards its +y
axis, i.e. atan2 of the axis's y over its x in that frame's coordinates. An axis has no
direction, so theta and theta + 180 are the same axis and the range is half a turn. On the
board's frame (x along a row of dots, y down a column) that is clockwise as the board is seen
when its y runs down the image; a robot's base frame seen from above is usually the mirror
image of the board's, and there the same physical axis has the opposite sign. The angle is
defined in whatever frame the positions are in, so a robot program can use it as it comes.

Too round for an axis: a part whose enclosed area's second moments are (nearly) the same in
every direction has no principal axis, and its angle is None (NaN in arrays). That is every
disc, washer and nut (a regular hexagon's moments are isotropic), and a square too: a square's
second moments are isotropic (L^4 / 12 in every direction), so the square's angle is not
given even though its sides have directions (a second-moment axis cannot tell them). The rule
(``axis_is_defined``), on the output frame's moments:

* the anisotropy (l1 - l2) / (l1 + l2) of the eigenvalues l1 >= l2 is below
  ``MIN_ANISOTROPY``; (a 1.5 : 1 rectangle or ellipse has 0.385, a 1.2 : 1 one 0.18; rendered
  discs, squares, nuts and washers under lens distortion, blur and noise were measured at up
  to 0.007 seen square-on, 0.031 under a 45 degree tilt: benches/bench_part_angle.py), or
* the angle's own 1-sigma from the outline's noise exceeds ``MAX_ANGLE_SIGMA_DEG``: each
  outline point's edge position scatters by ``EDGE_SIGMA_PX`` (measured: the angle errors of
  288 rendered rectangles and bolts were 1.23 times the model's 1-sigma at 0.1 px; 480 are
  1.05 times it at 0.12 px), which
  moves the off-diagonal moment by sigma_e sqrt(P / 2) tr(C) / A for an outline of length P
  round an area A, hence the axis by sigma_e sqrt(P / 2) / (A a) radians for anisotropy a.
  A small part needs to be more elongated than a large one for its axis to mean as much.

The arithmetic (the moments through the Jacobian, the eigen-axis, the rule, the image
direction) is the Rust core's (planarcal_core::part_pose, ``_core.part_axes``; the production
loop's ``_core.part_poses`` gives the axes with the centroids in one call), and so are the
constants below (re-exported here).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import _core
from planarcal.live.local_map import STEP_PX, local_maps

F64 = NDArray[np.float64]

__all__ = [
    "EDGE_SIGMA_PX",
    "MAX_ANGLE_SIGMA_DEG",
    "MIN_ANISOTROPY",
    "PartAxes",
    "axis_is_defined",
    "jacobians",
    "part_angles_deg",
    "part_axes",
    "wrap_deg",
]

MIN_ANISOTROPY: float = _core.MIN_ANISOTROPY
"""Below this (l1 - l2) / (l1 + l2), a part is too round for an axis (an ellipse of axes
1.08 : 1): 2.7 times the most measured on round parts; see the module docstring."""

EDGE_SIGMA_PX: float = _core.EDGE_SIGMA_PX
"""The outline's edge noise in the angle noise model, px (see the module docstring)."""

MAX_ANGLE_SIGMA_DEG: float = _core.MAX_ANGLE_SIGMA_DEG
"""An axis whose 1-sigma from the outline's noise exceeds this is not given, degrees."""


class PartAxes(NamedTuple):
    """Each part's principal axis, one row per part."""

    angles_deg: F64
    """(n,) in the output frame, degrees in [-90, 90) from its +x towards its +y; NaN where the
    part is too round for an axis."""
    axes_px: F64
    """(n, 2) the unit direction in the image (px) along which the output frame's axis lies
    (for drawing it); NaN where there is none."""
    anisotropy: F64
    """(n,) (l1 - l2) / (l1 + l2) of the output frame's moments: 0 for a disc or a square."""
    sigma_deg: F64
    """(n,) the angle's 1-sigma from the outline's noise, degrees (inf for a round part)."""


Mapping = Callable[[F64], ArrayLike]
"""Pixels (N, 2) -> positions in the output frame (N, 2)."""


def jacobians(mapping: Mapping, centroids_px: ArrayLike, step_px: float = STEP_PX) -> F64:
    """The mapping's Jacobian d(out)/d(px) at each centroid, (n, 2, 2), by central differences
    (one call of `mapping`, see planarcal.live.local_map). NaN where a sample point has no
    image (it maps to NaN)."""
    return local_maps(lambda p: (mapping(p), None), centroids_px, step_px).jacobian


def part_axes(
    moments_px: ArrayLike,
    areas_px: ArrayLike,
    jacobian: ArrayLike | None = None,
) -> PartAxes:
    """Each part's axis in the output frame from its moments (n, 3: [mu20, mu11, mu02] / area,
    px^2), its enclosed area (n,, px^2) and the mapping's Jacobian at its centroid (n, 2, 2,
    from `jacobians`; None: the output frame is the image's, angles in pixels, from +x (right)
    towards +y (down)). See the module docstring for the convention and the roundness rule.
    A part whose moments, area or Jacobian are not finite gets NaN throughout; one whose
    Jacobian is singular has no axis."""
    area = np.asarray(areas_px, dtype=np.float64).reshape(-1)
    return PartAxes(*_core.part_axes(moments_px, area, jacobian))


def part_angles_deg(moments_px: ArrayLike, areas_px: ArrayLike, jacobian: ArrayLike) -> F64:
    """Each part's angle in the frame the Jacobians (n, 2, 2, from `jacobians` or
    local_map.local_maps) take pixels to, degrees in [-90, 90), NaN where it has no axis:
    part_axes' angles without the image directions."""
    return part_axes(moments_px, areas_px, jacobian).angles_deg


def axis_is_defined(anisotropy: ArrayLike, sigma_deg: ArrayLike) -> NDArray[np.bool_]:
    """Whether each part has an axis: anisotropy at least MIN_ANISOTROPY and the angle's
    1-sigma at most MAX_ANGLE_SIGMA_DEG (the rule part_axes applies)."""
    a = np.asarray(anisotropy, dtype=np.float64)
    s = np.asarray(sigma_deg, dtype=np.float64)
    return np.asarray((a >= MIN_ANISOTROPY) & (s <= MAX_ANGLE_SIGMA_DEG), dtype=bool)


def wrap_deg(angles_deg: ArrayLike) -> F64:
    """Axis angles folded into [-90, 90) (an axis at theta is the one at theta + 180)."""
    a = np.asarray(angles_deg, dtype=np.float64)
    return np.asarray((a + 90.0) % 180.0 - 90.0, dtype=np.float64)
