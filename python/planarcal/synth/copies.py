"""Several copies of one board in one photograph, with exact truth per copy (issue 23).

Several copies of a board laid out at once on the work plane (the same description; for a
ChArUco board the same marker ids in each copy) are several placements seen in one image:
:func:`render_copies` renders them, each at its own place and angle on the table, and
returns the image with each copy's true pixels by id (:class:`BoardCopy`) and its pose
relative to a reference copy as a calibration from placements reports it
(:meth:`RenderedCopies.true_pose`).

How it renders: exactly as :func:`~planarcal.synth.render.render_scene` renders one board,
with one scene per copy composed on the table. The copies' papers must not overlap (they are
kept ``min_gap_mm`` apart, checked), so every table point lies on at most one copy's paper and
a pixel's footprint, which is far smaller than the gap, meets at most one copy: each point
takes its material from the copy whose paper it lies on (the table elsewhere), and each cell
of an edge pixel is shaded by the copy whose paper is nearest to it, by that copy's own exact
coverage. The composed image is then lit, blurred and noised once, as one photograph. With a
single copy the image is render_scene's, pixel for pixel (tests/calib/test_board_copies.py).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board
from planarcal.errors import ArgumentError
from planarcal.synth.camera import CameraModel, PlanePose
from planarcal.synth.cell import CELL_CAMERA, PAPER_MARGIN_MM, _framing_pose, cell_board
from planarcal.synth.dots import _board_to_table, _dot_diameters
from planarcal.synth.effects import _apply_image_effects, _checked_image_effects
from planarcal.synth.render import (
    _check_whole_numbers,
    _checked_board,
    _checked_tones,
    _evenly_lit,
    _tones,
)
from planarcal.synth.scene import _Scene
from planarcal.synth.shapes import _rotation_2d

F64 = NDArray[np.float64]

MIN_GAP_MM = 2.0
"""The least distance between two copies' papers (mm): far more than a pixel's footprint,
so no pixel sees two copies."""

_IMAGE_EFFECTS = (
    "blur_sigma_px",
    "noise_sigma",
    "lighting_gradient",
    "lighting_angle_deg",
    "vignette",
    "table_texture",
    "paper_texture",
)
_TONES = ("table_grey", "paper_grey", "ink_grey", "metal_grey")  # metal: no objects here


@dataclasses.dataclass(frozen=True, eq=False)
class BoardCopy:
    """One copy of the board in the image: ``centre_mm`` (where the middle of its printed
    field lies on the table), ``origin_mm`` (where its world origin lies), ``angle_deg`` (its
    x axis from the table's, towards +y), ``points_mm`` and ``points_px`` (each board point
    on the table and its exact pixel, lens included, in id order: row k is
    ``board.world_points()[k]``) and ``paper_px`` (the corners of its paper in the image)."""

    index: int
    centre_mm: tuple[float, float]
    origin_mm: tuple[float, float]
    angle_deg: float
    points_mm: F64
    points_px: F64
    paper_px: F64

    def in_view(self, width: int, height: int, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """Whether each point (id order) lies in a ``width`` x ``height`` image, ``margin_px``
        from its border."""
        p = self.points_px
        return np.asarray(
            (p[:, 0] >= margin_px - 0.5)
            & (p[:, 0] <= width - 0.5 - margin_px)
            & (p[:, 1] >= margin_px - 0.5)
            & (p[:, 1] <= height - 0.5 - margin_px)
        )


@dataclasses.dataclass(frozen=True, eq=False)
class RenderedCopies:
    """An image of several copies of ``board`` on the table and each copy's truth."""

    image: NDArray[np.uint8]
    board: Board
    camera: CameraModel
    pose: PlanePose
    copies: tuple[BoardCopy, ...]
    effects: Mapping[str, float | int | bool]

    def true_pose(self, index: int, reference: int = 0) -> tuple[float, tuple[float, float]]:
        """Copy ``index``'s board in the frame of copy ``reference``'s board, as a calibration
        from placements reports it: (angle_deg, (x, y) mm) with plane = R(angle) board +
        offset."""
        return relative_pose(self._copy("index", index), self._copy("reference", reference))

    def _copy(self, name: str, k: int) -> BoardCopy:
        """Copy ``k``; ArgumentError, naming the argument, for no such copy."""
        if isinstance(k, bool) or not isinstance(k, int | np.integer):
            raise ArgumentError(f"{name} must be a copy's index, got {k!r}")
        if not 0 <= k < len(self.copies):
            raise ArgumentError(f"copy {k} does not exist (there are {len(self.copies)})")
        return self.copies[int(k)]

    def truth_plane_mm(self, table_mm: F64, reference: int = 0) -> F64:
        """Table points (n, 2) in copy ``reference``'s board frame, exactly."""
        p, shape = arguments.points("table_mm", table_mm)
        ref = self._copy("reference", reference)
        out = (p - np.array(ref.origin_mm)) @ _rotation_2d(ref.angle_deg)
        return np.asarray(out.reshape(*shape, 2), np.float64)

    def pixel_of(self, table_mm: F64) -> F64:
        """The exact pixel each table point is seen at, lens distortion included."""
        return self.camera.project(table_mm, self.pose)


def relative_pose(copy: BoardCopy, reference: BoardCopy) -> tuple[float, tuple[float, float]]:
    """``copy``'s board in ``reference``'s board frame (both on the same table, in one image
    or in several from the same camera): (angle_deg, (x, y) mm), plane = R(angle) board +
    offset, as a calibration from placements reports a placement's pose."""
    angle = (copy.angle_deg - reference.angle_deg + 180.0) % 360.0 - 180.0
    offset = (np.array(copy.origin_mm) - np.array(reference.origin_mm)) @ _rotation_2d(
        reference.angle_deg
    )
    return angle, (float(offset[0]), float(offset[1]))


class _Copies(_Scene):
    """Several board scenes on one table, their papers apart: each table point's material is
    that of the copy whose paper it lies on, each cell is shaded by the nearest paper's copy."""

    def __init__(self, scenes: Sequence[_Scene], papers: Sequence[tuple[float, ...]]) -> None:
        super().__init__(None, (0.0, 0.0), 0.0, 0.0, ())
        self.scenes = list(scenes)
        self.papers = list(papers)

    def _paper_distance(self, x: F64, y: F64) -> F64:
        """(n_copies, n) signed distance (mm) of each point from each copy's paper."""
        out = np.empty((len(self.scenes), x.size))
        for k, (scene, (x0, y0, x1, y1)) in enumerate(zip(self.scenes, self.papers, strict=True)):
            bx, by = scene._to_board(x.ravel(), y.ravel())
            out[k] = _box_distance(bx, by, (x0, y0, x1, y1))
        return out

    def classify(self, x: F64, y: F64, radius: F64) -> tuple[NDArray[np.int16], NDArray[np.bool_]]:
        mat = np.zeros(x.shape, dtype=np.int16)
        edge = np.zeros(x.shape, dtype=bool)
        for scene in self.scenes:
            m, e = scene.classify(x, y, radius)
            on = m != 0
            mat[on] = m[on]
            edge |= e
        return mat, edge

    def shade(self, x: F64, y: F64, cell: tuple[F64, F64, F64, F64], lut: F64) -> F64:
        nearest = np.argmin(self._paper_distance(x, y), axis=0)
        out = np.empty((x.size, lut.shape[1]))
        for k, scene in enumerate(self.scenes):
            sel = np.flatnonzero(nearest == k)
            if sel.size:
                part = (cell[0][sel], cell[1][sel], cell[2][sel], cell[3][sel])
                out[sel] = scene.shade(x[sel], y[sel], part, lut)
        return out


def _box_distance(bx: F64, by: F64, box: tuple[float, ...]) -> F64:
    """Signed distance (negative inside) of points from an axis-aligned box (x0, y0, x1, y1)."""
    x0, y0, x1, y1 = box
    qx = np.abs(bx - 0.5 * (x0 + x1)) - 0.5 * (x1 - x0)
    qy = np.abs(by - 0.5 * (y0 + y1)) - 0.5 * (y1 - y0)
    outside = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0))
    return np.asarray(outside + np.minimum(np.maximum(qx, qy), 0.0), np.float64)


def _paper_box(scene: _Scene) -> tuple[float, float, float, float]:
    """A copy's paper in its board coordinates (x0, y0, x1, y1), as its scene draws it."""
    if scene.pattern is not None:
        x0, y0, x1, y1 = scene.pattern.paper
        return (x0, y0, x1, y1)
    (mx, my), (hx, hy) = scene.paper_mid, scene.paper_half
    return (mx - hx, my - hy, mx + hx, my + hy)


def _box_corners(box: tuple[float, ...]) -> F64:
    x0, y0, x1, y1 = box
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], np.float64)


def _check_apart(
    scenes: Sequence[_Scene],
    papers: Sequence[tuple[float, ...]],
    angles: Sequence[float],
    gap: float,
) -> None:
    """ArgumentError when two copies' papers come closer than ``gap`` mm (or overlap): the
    outline of each, sampled every 0.5 mm, must keep that far from the other's paper."""
    outlines = []
    for scene, box, angle in zip(scenes, papers, angles, strict=True):
        corners = _box_corners(box)
        pts = []
        for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
            n = max(2, math.ceil(float(np.hypot(*(b - a))) / 0.5) + 1)
            pts.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
        board_pts = np.vstack(pts)
        outlines.append(_board_to_table(board_pts, (scene.ox, scene.oy), angle))
    for i in range(len(scenes)):
        for j in range(len(scenes)):
            if i == j:
                continue
            bx, by = scenes[j]._to_board(outlines[i][:, 0], outlines[i][:, 1])
            closest = float(_box_distance(bx, by, papers[j]).min())
            if closest < gap:
                raise ArgumentError(
                    f"copies {min(i, j)} and {max(i, j)} overlap or lie closer than {gap:g} mm "
                    f"(their papers {closest:.3g} mm apart): place them apart"
                )


def render_copies(
    board: Board | str,
    places: Sequence[tuple[float, float, float]],
    *,
    camera: CameraModel = CELL_CAMERA,
    pose: PlanePose | None = None,
    paper_margin_mm: float = PAPER_MARGIN_MM,
    min_gap_mm: float = MIN_GAP_MM,
    seed: int = 0,
    supersample: int = 4,
    effects: Mapping[str, float] | None = None,
) -> RenderedCopies:
    """Render one image of several copies of ``board`` (a board, or a type's name of
    :data:`planarcal.synth.cell.CELL_BOARDS`) lying on the table.

    ``places``: each copy's (x, y, angle_deg): where the middle of its printed field lies on
    the table (mm) and its angle (its x axis from the table's, towards +y), 1 to 16 copies;
    their papers (``paper_margin_mm`` beyond the ink) must lie ``min_gap_mm`` apart.
    ``camera`` (default the cell's, 1280 x 960 with barrel distortion) looks from ``pose``
    (default: 8 degrees of tilt, aimed at the middle of the box from the table origin to the
    papers' far corners, from the distance that frames that box with a 3 % margin; the places
    must then lie at positive x and y). ``effects``: render_scene's tones (``table_grey``,
    ``paper_grey``, ``ink_grey``; ``metal_grey`` is taken and unused, so that
    :data:`~planarcal.synth.paper.PAPER_EFFECTS` can be given as it is) and image effects
    (``blur_sigma_px``, ``noise_sigma``, ``lighting_gradient``, ``lighting_angle_deg``,
    ``vignette``, ``table_texture``, ``paper_texture``) by name, as render_scene takes them;
    default none (a sharp, noise-free image). The noise is drawn from ``seed``.

    A copy may reach outside the image (a partial view): its truth holds every point,
    :meth:`BoardCopy.in_view` says which lie inside. Raises ArgumentError for bad arguments
    (copies overlapping, an unknown effect).
    """
    shown = cell_board(board)
    if not isinstance(camera, CameraModel):
        raise ArgumentError(f"camera must be a CameraModel, got {type(camera).__name__}")
    effects = {} if effects is None else effects
    if not isinstance(effects, Mapping):
        raise ArgumentError(f"effects must map effect names to values, got {effects!r}")
    unknown = sorted(set(effects) - set(_IMAGE_EFFECTS) - set(_TONES))
    if unknown:
        raise ArgumentError(f"unknown effects {', '.join(unknown)}")
    try:
        items = [tuple(p) for p in places]
    except TypeError:
        raise ArgumentError(f"places must be a list of (x, y, angle_deg), got {places!r}") from None
    if not 1 <= len(items) <= 16:
        raise ArgumentError(f"places must list 1 to 16 copies, got {len(items)}")
    gap = arguments.real("min_gap_mm", min_gap_mm)
    if gap < 0.0:
        raise ArgumentError(f"min_gap_mm must be >= 0, got {min_gap_mm!r}")
    _check_whole_numbers(supersample, seed)
    x0, y0, x1, y1 = shown.ink().field
    field_centre = np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0])
    diameters = _dot_diameters(shown, None) if isinstance(shown, CircleGridBoard) else None

    scenes: list[_Scene] = []
    placed: list[tuple[tuple[float, float], float, tuple[float, float]]] = []
    for k, item in enumerate(items):
        if len(item) != 3:
            raise ArgumentError(f"places[{k}] must be (x_mm, y_mm, angle_deg), got {item!r}")
        cx = arguments.real(f"places[{k}] x", item[0])
        cy = arguments.real(f"places[{k}] y", item[1])
        angle = arguments.real(f"places[{k}] angle", item[2])
        o = np.array([cx, cy]) - _rotation_2d(angle) @ field_centre
        origin, angle, margin = _checked_board(
            shown, (float(o[0]), float(o[1])), angle, paper_margin_mm
        )
        scenes.append(_Scene(shown, origin, angle, margin, (), None, diameters))
        placed.append((origin, angle, (cx, cy)))
    papers = [_paper_box(s) for s in scenes]
    _check_apart(scenes, papers, [angle for _, angle, _ in placed], gap)

    if pose is None:
        corners = np.vstack(
            [
                _board_to_table(_box_corners(box), origin, angle)
                for box, (origin, angle, _) in zip(papers, placed, strict=True)
            ]
        )
        if (corners < 0.0).any():
            raise ArgumentError(
                "with the default pose every copy's paper must lie at positive x and y on the "
                "table (or give a pose)"
            )
        pose = _framing_pose(camera, corners.max(axis=0), 8.0, 30.0)
    if not isinstance(pose, PlanePose):
        raise ArgumentError(f"pose must be a PlanePose, got {type(pose).__name__}")

    tones = _checked_tones(
        float(effects.get("table_grey", 100.0)),
        float(effects.get("paper_grey", 225.0)),
        float(effects.get("ink_grey", 35.0)),
        float(effects.get("metal_grey", 170.0)),
        None,
    )
    image_effects = _checked_image_effects(
        *(float(effects.get(name, 0.0)) for name in _IMAGE_EFFECTS)
    )
    scene = _Copies(scenes, papers)
    lut = _tones(tones, (), 0, light_on_dark=False, color=False)
    radiance = _evenly_lit(
        camera, pose, scene, lut, image_effects, int(supersample), int(seed), color=False
    )
    image = _apply_image_effects(radiance, camera, image_effects, int(seed))

    copies = []
    for k, ((origin, angle, centre), box) in enumerate(zip(placed, papers, strict=True)):
        points_mm = _board_to_table(shown.world_points(), origin, angle)
        copies.append(
            BoardCopy(
                index=k,
                centre_mm=centre,
                origin_mm=origin,
                angle_deg=angle,
                points_mm=points_mm,
                points_px=camera.project(points_mm, pose),
                paper_px=camera.project(_board_to_table(_box_corners(box), origin, angle), pose),
            )
        )
    record: dict[str, float | int | bool] = {
        **tones,
        **image_effects.record(),
        **image_effects.textures,
        "seed": int(seed),
        "supersample": int(supersample),
        "paper_margin_mm": float(paper_margin_mm),
    }
    return RenderedCopies(
        image=image,
        board=shown,
        camera=camera,
        pose=pose,
        copies=tuple(copies),
        effects=record,
    )
