"""Things that hide part of a board: :func:`hand`, a flat hand-like shape made of
:class:`~planarcal.synth.objects.SceneObject` parts, to lay over a board as a person's hand
holding it (pass its parts in ``render_scene(objects=...)``; glare is ``render_scene``'s
``glare``). :meth:`~planarcal.synth.render.RenderedScene.points_hidden` says which board points
it covers.
"""

from __future__ import annotations

import math

import numpy as np

from planarcal import arguments
from planarcal.errors import ArgumentError
from planarcal.synth.objects import SceneObject
from planarcal.synth.shapes import _rotation_2d

# The fingers, index to little: (offset across the palm, length), in palm widths.
_FINGERS = ((-0.375, 0.8), (-0.125, 0.9), (0.125, 0.85), (0.375, 0.68))
_FINGER_WIDTH = 0.22
_PALM_LENGTH = 1.05


def hand(
    position_mm: tuple[float, float],
    angle_deg: float = 0.0,
    size_mm: float = 85.0,
    grey: float = 150.0,
) -> tuple[SceneObject, ...]:
    """A flat hand, palm down, as overlapping parts of one grey level (a palm, four fingers
    and a thumb, each rounded at its tip), to hide part of a board.

    ``position_mm``: the middle of the palm (table mm); ``angle_deg``: the direction the
    fingers point, from +X towards +Y; ``size_mm``: the palm's width (about 85 mm for an
    adult; the whole hand is then about 190 mm long); ``grey``: its grey level (skin under
    room light is a mid grey, between paper and ink). The parts overlap, so the hand is drawn
    without seams; each part is a flat SceneObject with its own truth (a hand has no
    centroid a test needs).
    """
    cx, cy = arguments.pair("position_mm", position_mm)
    angle = arguments.real("angle_deg", angle_deg)
    d = arguments.positive("size_mm", size_mm)
    g = arguments.real("grey", grey)
    if not 0.0 <= g <= 255.0:
        raise ArgumentError(f"grey must be a grey level 0-255, got {grey!r}")
    turn = _rotation_2d(angle)
    centre = np.array([cx, cy])

    def at(along: float, across: float) -> tuple[float, float]:
        p = centre + turn @ np.array([along, across])
        return (float(p[0]), float(p[1]))

    parts = [
        SceneObject("rectangle", at(0.0, 0.0), angle, d, length_mm=_PALM_LENGTH * d, grey=g),
        SceneObject("disc", at(-0.5 * _PALM_LENGTH * d, 0.0), 0.0, d, grey=g),
    ]
    w = _FINGER_WIDTH * d
    base = 0.5 * _PALM_LENGTH * d - 0.5 * w  # fingers start inside the palm
    for across, length in _FINGERS:
        reach = length * d
        parts.append(
            SceneObject("rectangle", at(base + reach / 2.0, across * d), angle, w, reach, grey=g)
        )
        parts.append(SceneObject("disc", at(base + reach, across * d), 0.0, w, grey=g))
    # The thumb: from the palm's index-finger side, 50 degrees out from the fingers.
    thumb_angle = angle - 50.0
    length = 0.75 * d
    root = np.array(at(0.05 * d, -0.4 * d))
    a = math.radians(thumb_angle)
    mid = root + 0.5 * length * np.array([math.cos(a), math.sin(a)])
    tip = root + length * np.array([math.cos(a), math.sin(a)])
    thumb_w = 1.15 * w
    parts.append(
        SceneObject(
            "rectangle", (float(mid[0]), float(mid[1])), thumb_angle, thumb_w, length, grey=g
        )
    )
    parts.append(SceneObject("disc", (float(tip[0]), float(tip[1])), 0.0, thumb_w, grey=g))
    return tuple(parts)
