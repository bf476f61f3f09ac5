"""planarcal.synth.render_scene's grey levels and image effects as a TypedDict, so that a
test can keep a set of them in one place, pass it on with ``**`` and still have each one
type-checked."""

from __future__ import annotations

from typing import TypedDict, cast

from planarcal import synth


class SceneEffects(TypedDict, total=False):
    """render_scene's keywords that take a float: its grey levels and image effects."""

    table_grey: float
    paper_grey: float
    ink_grey: float
    metal_grey: float
    side_grey: float | None
    blur_sigma_px: float
    noise_sigma: float
    lighting_gradient: float
    lighting_angle_deg: float
    vignette: float
    table_texture: float
    paper_texture: float


# synth.PAPER_EFFECTS is typed Mapping[str, float], looser than what it is: some of
# render_scene's float keywords. The cast is sound once its keys are checked to be those.
assert set(synth.PAPER_EFFECTS) <= SceneEffects.__optional_keys__, set(synth.PAPER_EFFECTS)
PAPER_EFFECTS = cast(SceneEffects, synth.PAPER_EFFECTS)
