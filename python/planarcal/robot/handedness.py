"""Whether touch points fix a registration's hand: if the map from the board to the robot
mirrors or not, and the hand a user can state instead.

Touches on one line cannot tell. Mirrored in that line, each touch lands where it was, so both
hands fit them equally well, and a part off the line lands at its mirror image, twice its
distance from the line away: hundreds of mm off under a residual of a few hundredths. Near a
line the data choose the hand by the sign of sum d_i (+-d_i + e_i) (d_i each touch's distance
from the touches' main line, e_i its touch noise across it, sigma per coordinate), so they pick
the right one with z = sqrt(sum d_i^2) / sigma standard deviations to spare. The hand is taken
from the data only at z >= MIN_HAND_Z; below that a registration is refused unless the hand is
given.

The hand given is the robot frame's, with its z axis up from the table (towards the camera):
"right" (the usual robot base frame) or "left". The board's frame seen from the front has its
y axis clockwise from its x axis (x along a row, y down a column), so a right-handed robot
frame is its mirror image: "right" is a mirrored map, "left" one that does not mirror."""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import numpy as np

from planarcal.errors import ArgumentError, RegistrationError
from planarcal.robot.summary import USABLE_MM
from planarcal.robot.transform_fit import F64, Model

Handedness = Literal["right", "left"]
HANDEDNESS: tuple[Handedness, ...] = ("right", "left")

# sqrt(sum d_i^2) / sigma at which the data fix the hand: the wrong hand then needs a 10-sigma
# noise draw (a wrong hand puts parts hundreds of mm off, so the margin is wide).
MIN_HAND_Z = 10.0

# Touches this far from their main line (root-sum-square) fix the hand under a touch noise
# of a usable registration's 1 mm: when they do not, the pairs' disagreement hides the hand,
# not their layout.
SPREAD_FOR_HAND_MM = MIN_HAND_Z * USABLE_MM


def mirrored_of(handedness: object) -> bool | None:
    """Whether the hand given makes the map mirror (None: not given); ArgumentError for a value
    that is not "right", "left" or None."""
    if handedness is None:
        return None
    if handedness not in HANDEDNESS:
        raise ArgumentError(
            f"handedness must be 'right', 'left' or None (from the touches), got {handedness!r}"
        )
    return handedness == "right"


def handedness_of(mirrored: bool) -> Handedness:
    """The robot frame's hand (z up) of a map that mirrors or not."""
    return "right" if mirrored else "left"


def across_line_mm(points_mm: F64) -> float:
    """sqrt(sum d_i^2) (mm): the root-sum-square distance of the points from their main line
    (the smaller singular value of the centred points); 0 on a line."""
    if len(points_mm) < 2:
        return 0.0
    s = np.linalg.svd(points_mm - points_mm.mean(axis=0), compute_uv=False)
    return float(s[-1])


def line_ends(points_mm: F64) -> tuple[int, int]:
    """The indices of the two points farthest apart along the points' main line."""
    centred = points_mm - points_mm.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    along = centred @ vt[0]
    first, last = int(np.argmin(along)), int(np.argmax(along))
    return (first, last) if first < last else (last, first)


def hand_margin(mapped_mm: F64, sigma_mm: float) -> float:
    """z = sqrt(sum d_i^2) / sigma: how many standard deviations of the touch noise keep the
    data's choice of hand from flipping (``mapped_mm``: the touches' board points mapped by the
    fit, in the noise's robot mm)."""
    return across_line_mm(mapped_mm) / sigma_mm if sigma_mm > 0 else float("inf")


def check_hand_determined(
    mapped_mm: F64,
    sigma_mm: float,
    model: Model,
    hand_given: bool,
    name: Callable[[int], str],
    point_name: str = "dot",
) -> None:
    """RegistrationError when the touches leave the hand free under the touch noise
    ``sigma_mm`` (per coordinate) and it was not given (or the model is affine, whose hand is
    its points'): for touches near a line, naming the two at its ends (``name`` of an index)
    and the board's points by ``point_name`` ("dot", "corner"); for touches spread well, whose
    noise only a wrong pair explains, saying so.
    ``mapped_mm``: their board points mapped by the fit, in the robot's mm like the noise (a
    similarity's scale or an affine's stretch changes their distances from the line)."""
    if hand_given and model != "affine":
        return
    rss = across_line_mm(mapped_mm)
    if rss >= MIN_HAND_Z * sigma_mm:
        return
    if rss >= SPREAD_FOR_HAND_MM:
        raise RegistrationError(
            f"the touches disagree too much to show whether the robot frame is the board's "
            f"mirror image: they fit with a touch noise of {sigma_mm:.3g} mm per coordinate, "
            f"and their {rss:.3g} mm from their main line (root-sum-square) is under "
            f"{MIN_HAND_Z:g} x that; they are spread well, so a pair is wrong (a {point_name} "
            f"touched for another, a mistyped coordinate, pairs out of order): check the pairs "
            f"and touch again"
        )
    first, last = line_ends(mapped_mm)
    fix = (
        "or give the hand (handedness='right' for a right-handed robot frame with z up, "
        "'left' otherwise; --handedness right|left or --no-mirror)"
        if model != "affine"
        else "or fit model='rigid' or 'similarity' with the hand given (handedness=, --handedness)"
    )
    raise RegistrationError(
        f"the touch points lie too near one line for their noise to show whether the robot "
        f"frame is the board's mirror image: their distances from it come to {rss:.3g} mm "
        f"(root-sum-square), under {MIN_HAND_Z:g} x the touch noise of {sigma_mm:.3g} mm, and "
        f"a part off the line could be placed at its mirror image; touch at least one "
        f"{point_name} off the line through {name(first)} and {name(last)}, {fix}"
    )
