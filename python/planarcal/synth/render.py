"""Photographing a scene: :func:`render_scene` renders a table with, optionally, a board, its
printed marks and objects on it, and returns the 8-bit image with its exact truth
(:class:`RenderedScene`). The conventions are in :mod:`planarcal.synth.camera` and
:mod:`planarcal.synth.objects`.

How it renders
--------------
Every pixel is traced back to the table exactly: its position is undistorted (Newton's
method on the radial polynomial, to machine precision), the ray through it is intersected
with the plane, and the material there (table, paper, ink, an object) gives the grey level.
Pixels whose footprint on the plane crosses no boundary (found conservatively from signed
distances to every boundary) take the material at their centre. Each of the others, the
edge pixels, is split into n x n cells (``supersample``, default 8); every cell centre is
traced through the lens to the plane on its own, and the cell is shaded by the exact
fraction of its footprint (the parallelogram the cell maps to) on each side of the nearest
boundary, treated as straight across the cell. The pixel's value is the mean of its cells:
anti-aliasing by area, correct through distortion and perspective; only boundary curvature
within a cell (about 1e-5 of a dot's area at n = 8) and polygon corners are approximated.
Then, in this order: the textures of the table and the paper (added where each material
covers a pixel, its exact share of the pixel counted), uneven lighting (a multiplicative gain
in the image), a Gaussian blur, additive Gaussian noise (seeded), rounding to uint8.

The dots' boundary and where dots touch: :mod:`planarcal.synth.dots`; objects with height
(walls, tops, occlusion): :mod:`planarcal.synth.raised`. A chessboard or a ChArUco board is
drawn from its printed ink (``board.ink()``) by :mod:`planarcal.synth.pattern`: the page's
rectangles cut it into atoms of one material each, and a cell is shaded by the exact area
of each atom it meets (a polygon clip where an atom's corner lies in the cell), so squares
meeting at a corner (X-junctions) and rectangles sharing an edge (a marker's cells) are
exact, with no seam; only the circles of a chessboard's origin marker use the straight
boundary above.

Measured accuracy (tests/synth/test_synth.py, tests/synth/test_synth_boards.py): pixel
values agree with a brute-force reference (1024 point samples per pixel) to 0.002 of the
contrast; so they do where an asymmetric grid's enlarged dots or an origin marker touch
their neighbours (0.009 at worst, the reference's own sampling, 0.0002 on average). In an
asymmetric grid (dots 23 px), each dot's darkness centroid lies within 0.0015 px of its
projected centre, and an enlarged dot's darkness sums to its area within 0.002 %. With
raised objects (walls, a nut's through-hole, a 30 mm tall disc hiding a 12 mm block that
hides a flat disc, through strong distortion and a 25 degree tilt) they agree with rays
followed one by one through the prisms (32 x 32 jittered rays per pixel) to 0.01 of the
contrast, that reference's own sampling noise (0.0003 on average); where two raised objects
meet in the image, to 0.02 (0.04 at n = 4). In a sharp, noise-free, untilted, undistorted
render of the paper's board (dots 21 px across), the intensity-weighted centroid of every
dot lies within 0.002 px of its projected centre (measured: 0.0018 px at worst, 0.0006 px on
average, uint8 rounding and the centroid's own sampling bias included). The same holds for
the top of a raised disc (20 mm across and 20 mm tall, 117 mm from the nadir of a camera 500
mm up: its wall is 11 px wide): the centroid of its top's coverage in the image lies within
0.001 px of the projection of (X, Y, -h). A full 1280 x 720 render of the paper's
calibration image takes about 0.4 s on a 2-core machine (0.6 s in colour);
:func:`~planarcal.synth.paper.paper_scene` renders its two images in about 0.6 s. Height
costs little: with the paper's ten objects on its board, 6 to 6.5 mm tall rather than flat,
the render takes about 10 % longer. At 1280 x 720 an asymmetric grid costs as much as a
symmetric one; four enlarged dots add about 15 %, both textures 45 %, 220 printed strokes
(numbers, arrows, text) 55 %. The whole corpus of
:func:`~planarcal.synth.corpus.board_variants` renders in about 10 s (4 s of it the 4K
image).

Chessboards and ChArUco boards (tests/synth/test_synth_patterns.py): pixel values agree with
the brute-force reference (32 x 32 point samples per pixel, each traced through the lens) to
0.0016 of the contrast (0.00005 on average) through strong barrel distortion (k1 = -0.2), a
25 degree tilt and a board turned 13 degrees, around X-junctions, an origin marker's white
and black dots and ArUco markers' cells. X-junctions are unbiased: in a sharp, noise-free
1280 x 720 render of a 9 x 6 chessboard (squares about 70 px) square on, tilted 30 and 45
degrees, each corner where straight lines fitted to its two edges cross lies within 5e-6 px
of its projected truth before rounding, within 0.0026 px (0.0016 px RMS, 33 corners) in
the 8-bit image. OpenCV's ``CharucoDetector`` reads renders of both ChArUco layouts with
every corner's id and within 0.2 px of the truth, ``findChessboardCornersSB`` a blurred,
noisy render within 0.15 px. Time, in this process's CPU seconds at 1280 x 720 through the
paper's webcam lens with blur and noise (measured on a 2-core machine shared by other jobs,
whose wall-clock times were three to four times these): a 9 x 6 chessboard 0.8-1.0 s, a
7 x 5 ChArUco board 1.2-1.7 s, a 12 x 9 ChArUco board 1.8-2.6 s; a 3840 x 2160 chessboard
or ChArUco board 4-5 s.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board, is_board
from planarcal.errors import ArgumentError, BoardError, ImageError
from planarcal.synth.camera import CameraModel, PlanePose, View
from planarcal.synth.dots import _board_to_table, _dot_diameters
from planarcal.synth.effects import (
    _apply_image_effects,
    _checked_glare,
    _checked_image_effects,
    _ImageEffects,
    _plane_texture,
)
from planarcal.synth.marks import _mark_on_table
from planarcal.synth.objects import SceneObject
from planarcal.synth.scene import _FIRST_OBJECT, _PAPER, _TABLE, _Scene

F64 = NDArray[np.float64]


# BGR tints of the materials with color=True (multiplying the grey level).
_TINT_TABLE = (0.90, 1.0, 1.08)
_TINT_PAPER = (0.98, 1.0, 1.01)
_TINT_INK = (1.06, 1.0, 0.96)
_TINT_METAL = (1.03, 1.0, 0.96)

# The default wall tone of raised objects, times the table's: vertical metal faces under
# overhead light, lit at grazing angles, look darker than the bench they stand on.
_SIDE_SHADE = 0.6


@dataclasses.dataclass(frozen=True, eq=False)
class RenderedScene:
    """A rendered scene and its truth.

    ``image``: uint8, (height, width) grey or (height, width, 3) BGR.
    ``dot_centres_px``: (n_points, 2) float64, the exact projection (lens distortion
    included) of each board point (a dot's centre, a chessboard's or a ChArUco board's inner
    corner) in id order (``board.world_points()``; for a grid, point k = r * cols + c); (0, 2)
    without a board. ``points_px`` is the same array under the name every board shares.
    ``object_centroids_px``: (len(objects), 2), the projection of each
    object's centroid: of its top face, the 3-D point (X, Y, -h) with (X, Y) its
    ``position_mm`` and h its ``height_mm`` (0 for a flat object). Note that the image of a
    circle's or object's centre is not the centroid of its image under perspective or
    distortion: these are the truth a detector's answer should be compared with, its bias
    included.
    ``world_to_image``: the table (mm) -> image (px) homography, scaled so H[2, 2] = 1. It is
    exact when the camera has no distortion; otherwise it is the undistorted part (the ideal
    pinhole image; the pixels differ from it by the lens distortion). ``board_to_image``:
    the same from board coordinates (mm, origin at dot 0), None without a board.
    ``effects``: the image effects and grey levels the scene was rendered with.
    ``dot_diameters_mm``: (rows * cols,), the diameter each dot was printed with, in board
    order (the board's ``dot_diameters()`` with ``enlarged_dots`` applied); (0,) without a
    circle grid. ``marks``: the printed marks, in board coordinates (decoration: no truth).
    ``glare``: the glare spots (x_px, y_px, radius_px) the image was rendered with.

    Which points a detector can see: :meth:`points_in_view` (inside the image),
    :meth:`points_hidden` (under an object or lost in glare), :meth:`points_visible` (both).
    """

    image: NDArray[np.uint8]
    dot_centres_px: F64
    object_centroids_px: F64
    objects: tuple[SceneObject, ...]
    board: Board | None
    board_origin_mm: tuple[float, float]
    board_angle_deg: float
    camera: CameraModel
    pose: PlanePose
    world_to_image: F64
    board_to_image: F64 | None
    effects: Mapping[str, float | int | bool]
    dot_diameters_mm: F64 = dataclasses.field(default_factory=lambda: np.zeros(0))
    marks: tuple[SceneObject, ...] = ()
    glare: tuple[tuple[float, float, float], ...] = ()

    @property
    def points_px(self) -> F64:
        """The board points' exact projections, (n_points, 2), in id order (0-based: row k
        is the point ``board.world_points()[k]``); (0, 2) without a board."""
        return self.dot_centres_px

    @property
    def points_mm(self) -> F64:
        """The board points in table coordinates (mm), (n_points, 2), in id order."""
        if self.board is None:
            return np.zeros((0, 2))
        return _board_to_table(
            self.board.world_points(), self.board_origin_mm, self.board_angle_deg
        )

    @property
    def dot_centres_mm(self) -> F64:
        """Board dot centres in table coordinates (mm), (rows * cols, 2), in board order
        (the same as ``points_mm``, for any board)."""
        return self.points_mm

    @property
    def object_centroids_mm(self) -> F64:
        """Object centroids (their ``position_mm``) in table coordinates, (len(objects), 2):
        X and Y of the top face's centroid (of the silhouette's, for a flat object), which
        lies ``object_heights_mm`` above the table."""
        return np.array([o.position_mm for o in self.objects], dtype=np.float64).reshape(-1, 2)

    @property
    def object_heights_mm(self) -> F64:
        """Each object's height above the table (mm), (len(objects),); 0 for flat ones."""
        return np.array([float(o.height_mm) for o in self.objects], dtype=np.float64)

    def truth(self) -> dict[str, F64]:
        """The ground truth as arrays: ``dot_centres_mm``, ``dot_centres_px``,
        ``object_centroids_mm``, ``object_heights_mm``, ``object_centroids_px`` (table mm,
        image px)."""
        return {
            "dot_centres_mm": self.dot_centres_mm,
            "dot_centres_px": self.dot_centres_px.copy(),
            "object_centroids_mm": self.object_centroids_mm,
            "object_heights_mm": self.object_heights_mm,
            "object_centroids_px": self.object_centroids_px.copy(),
        }

    @property
    def view(self) -> View:
        """This scene's camera and pose."""
        return View(self.camera, self.pose)

    def project(self, world_xy: ArrayLike, height_mm: ArrayLike = 0.0) -> F64:
        """Table points (mm), ``height_mm`` above the table (a scalar or one per point), to
        pixels through this scene's camera and pose (exact; see CameraModel.project)."""
        return self.camera.project(world_xy, self.pose, height_mm)

    def points_in_view(self, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """Whether each board point (id order) lies inside the image, ``margin_px`` from its
        border: a circle grid's whole dot, a corner's point itself (give a margin of a few
        pixels for the squares about it to show)."""
        if self.board is None:
            return np.zeros(0, dtype=bool)
        m = arguments.real("margin_px", margin_px)
        if not isinstance(self.board, CircleGridBoard):
            return _inside(self.points_px, self.camera, m)
        return self.dots_in_view(m)

    def points_hidden(
        self, clearance_mm: float | None = None, glare_radii: float = 1.5
    ) -> NDArray[np.bool_]:
        """Whether each board point (id order) is hidden: an object (flat or raised, as the
        camera sees it) covers some of the board within ``clearance_mm`` of it (default: a
        dot's radius; a quarter of the square about a corner), or it lies within
        ``glare_radii`` radii of a glare spot's centre in the image (1.5: where the spot
        adds 107 grey levels or more). Printed marks hide nothing."""
        board = self.board
        if board is None:
            return np.zeros(0, dtype=bool)
        hidden = np.zeros(board.n_points, dtype=bool)
        reach = arguments.real("glare_radii", glare_radii)
        for x, y, r in self.glare:
            hidden |= np.hypot(self.points_px[:, 0] - x, self.points_px[:, 1] - y) < reach * r
        if not self.objects:
            return hidden
        if clearance_mm is None:
            if isinstance(board, CircleGridBoard):
                radius: F64 = self.dot_diameters_mm / 2.0
            else:
                radius = np.full(board.n_points, 0.25 * float(board.pitch))
        else:
            radius = np.full(board.n_points, arguments.real("clearance_mm", clearance_mm))
        # Samples on the point and on rings about it, as the camera sees the table there.
        a = 2.0 * np.pi * np.arange(24) / 24
        ring = np.column_stack([np.cos(a), np.sin(a)])
        offsets = np.vstack([[0.0, 0.0], 0.5 * ring, ring])
        pts = self.points_mm
        samples = pts[:, None, :] + radius[:, None, None] * offsets[None]
        centre = self.pose.camera_centre_mm()
        margin = float(self.effects.get("paper_margin_mm", 15.0))
        scene = _Scene(
            board, self.board_origin_mm, self.board_angle_deg, margin, self.objects, centre
        )
        x, y = samples[..., 0].reshape(-1), samples[..., 1].reshape(-1)
        material, _ = scene.classify(x, y, np.zeros_like(x))
        covered = (material >= _FIRST_OBJECT).reshape(len(pts), -1).any(axis=1)
        return hidden | covered

    def points_visible(
        self, margin_px: float = 0.0, clearance_mm: float | None = None
    ) -> NDArray[np.bool_]:
        """Whether each board point is in view (:meth:`points_in_view`) and not hidden
        (:meth:`points_hidden`): the ids a detector of a partial view should find."""
        return self.points_in_view(margin_px) & ~self.points_hidden(clearance_mm)

    def dots_in_view(self, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """Whether each dot lies wholly inside the image, ``margin_px`` from its border (for
        a chessboard or a ChArUco board: :meth:`points_in_view`)."""
        if self.board is None:
            return np.zeros(0, dtype=bool)
        if not isinstance(self.board, CircleGridBoard):
            return self.points_in_view(margin_px)
        m = arguments.real("margin_px", margin_px)
        a = 2.0 * np.pi * np.arange(64) / 64
        ring = np.column_stack([np.cos(a), np.sin(a)])
        pts = self.board.world_points()
        rad = self.dot_diameters_mm / 2.0
        if len(rad) != len(pts):
            rad = self.board.dot_diameters() / 2.0
        outline = (pts[:, None, :] + rad[:, None, None] * ring[None]).reshape(-1, 2)
        px = self.project(_board_to_table(outline, self.board_origin_mm, self.board_angle_deg))
        w, h = self.camera.width, self.camera.height
        inside = (
            (px[:, 0] >= m - 0.5)
            & (px[:, 0] <= w - 0.5 - m)
            & (px[:, 1] >= m - 0.5)
            & (px[:, 1] <= h - 0.5 - m)
        )
        return np.asarray(inside.reshape(len(pts), -1).all(axis=1))


def render_scene(
    camera: CameraModel | None = None,
    pose: PlanePose | None = None,
    *,
    board: Board | None = CircleGridBoard(),  # noqa: B008 (frozen, immutable)
    board_origin_mm: tuple[float, float] = (0.0, 0.0),
    board_angle_deg: float = 0.0,
    paper_margin_mm: float = 15.0,
    light_on_dark: bool = False,
    enlarged_dots: Mapping[int, float] | None = None,
    marks: Sequence[SceneObject] = (),
    objects: Sequence[SceneObject] = (),
    table_grey: float = 100.0,
    paper_grey: float = 225.0,
    ink_grey: float = 35.0,
    metal_grey: float = 170.0,
    side_grey: float | None = None,
    blur_sigma_px: float = 0.0,
    noise_sigma: float = 0.0,
    lighting_gradient: float = 0.0,
    lighting_angle_deg: float = 0.0,
    vignette: float = 0.0,
    table_texture: float = 0.0,
    paper_texture: float = 0.0,
    glare: Sequence[tuple[float, float, float]] = (),
    color: bool = False,
    seed: int = 0,
    supersample: int = 8,
) -> RenderedScene:
    """Photograph a table with, optionally, a board and objects on it; see
    :mod:`planarcal.synth.camera` for the conventions and this module's docstring for the
    method.

    Geometry: ``camera`` (default :class:`CameraModel()`: 1280 x 720, f = 1070 px, no
    distortion) looks at the table from ``pose`` (default: 500 mm straight above the middle
    of the board's points, or the table origin without a board). ``board`` (any board of
    :mod:`planarcal.calib.boards`; default the paper's 14 x 10 circle grid; None for none)
    lies with the origin of its world coordinates (a grid's point 0, a ChArUco board's
    outer top-left corner) at ``board_origin_mm`` on the table, turned by
    ``board_angle_deg`` (from +X towards +Y), printed on paper reaching ``paper_margin_mm``
    beyond the outer edges of its ink (``board.ink().field``): dark ink on light paper, or
    light on dark with ``light_on_dark=True`` (paper and ink grey levels swapped). A
    chessboard or a ChArUco board is drawn from its ``ink()`` (black rectangles, then
    circles black or white) by exact area (:mod:`planarcal.synth.pattern`). A circle grid,
    either layout
    (``board.layout``); each dot is as large as ``board.dot_diameters()`` says (the origin
    marker's up to the distance between neighbours: it may then touch them), except the dots
    in ``enlarged_dots`` (dot index -> diameter in mm, at least the board's dots and at most
    ``board.neighbour_distance``): fiducials anywhere in the grid (circle grids only). The
    board's diameter must be known. ``marks`` are decoration printed on the paper: flat shapes (as
    :class:`SceneObject`, ``height_mm`` 0) in *board* coordinates, so they move with the
    board; those without their own ``grey`` are printed in the board's ink (light on dark
    too). They are drawn over the paper and the dots, under the objects, and are no part of
    the objects' truth (see :func:`printed_marks`). ``objects`` lie on top: flat
    ones (``height_mm`` 0) later over earlier, raised ones over everything flat and, among
    themselves, nearer to the camera in front (see :mod:`planarcal.synth.raised`). An
    object must be lower than the camera.

    Tones (grey levels 0-255, before lighting): ``table_grey``, ``paper_grey``,
    ``ink_grey``, ``metal_grey`` (objects' tops without their own ``grey``), ``side_grey``
    (the walls of raised objects; None: 0.6 x ``table_grey``, dark upright faces under
    overhead light). ``color=True`` returns BGR, each material's grey level slightly tinted
    (a warm table, white paper, near-black ink, cool metal).

    Textures (standard deviation in grey levels; 0: a uniform material): ``table_texture``
    adds a wood- or carpet-like random pattern (grain, mottling and streaks at a few scales)
    to the table, ``paper_texture`` a finer fibre-and-mottle one to the paper (not to the
    ink or the marks). Both are drawn on the plane, so perspective foreshortens them; their
    finest detail is about two pixels at the image's median scale (fine enough to look
    like grain, coarse enough not to alias), so they depend on the camera and the pose as
    well as on ``seed`` (from which they draw their own streams, not the image noise's).
    They are lit like the material they are on.

    Effects, applied in this order: ``lighting_gradient`` G (gain falling linearly from
    1 + G/2 to 1 - G/2 across the image, the bright side towards ``lighting_angle_deg``,
    measured in the image from +x towards +y) and ``vignette`` V (gain 1 - V (r / r_corner)^2
    around the principal point); Gaussian blur of ``blur_sigma_px`` px; additive Gaussian
    noise of ``noise_sigma`` grey levels drawn from ``numpy.random.default_rng(seed)``;
    rounding and clipping to uint8. The same arguments always give the same image.

    ``glare``: bright spots (x_px, y_px, radius_px) in the image, a lamp's reflection: each
    adds light after the lighting's gain and before the blur (2^-(d/r)^2 times twice full
    scale at distance d from its centre), so the image saturates out to its radius and the
    points there are lost (see :meth:`RenderedScene.points_hidden`).

    Partial views: choose a pose that leaves part of the board outside the image (the truth
    holds every point's projection, :meth:`RenderedScene.points_in_view` says which are
    inside), lay objects over it (:func:`planarcal.synth.hand`'s parts, or any flat
    SceneObject with a ``grey``), or add ``glare``; :meth:`RenderedScene.points_visible`
    gives the ids left.

    ``supersample``: n for the n x n cells of each edge pixel (1-32; see the module's
    docstring). Cells are shaded by exact coverage, so 4 is already within 0.002 of the
    contrast for 10-pixel dots; more only refines curvature and corners. A chessboard's or a
    ChArUco board's rectangles are exact in any cell: 1 renders them as accurately as 8
    (against a 32 x 32-sample reference, 0.0015 of the contrast either way) in 40 % of the
    time; its marker dots and the objects still take the straight-boundary rule.

    Errors: ValueError for a pose whose plane does not fill the view (its horizon is in the
    image) or for bad objects (one as high as the camera), BoardError for the board's
    placement, ImageError for the image parameters (tones, effects, supersample).
    """
    camera = CameraModel() if camera is None else camera
    if not isinstance(camera, CameraModel):
        raise ArgumentError(f"camera must be a CameraModel, got {type(camera).__name__}")
    origin, angle, margin = _checked_board(board, board_origin_mm, board_angle_deg, paper_margin_mm)
    diameters = None
    if isinstance(board, CircleGridBoard):
        diameters = _dot_diameters(board, enlarged_dots)
    elif enlarged_dots:
        raise BoardError("enlarged_dots applies to circle grids, not to a " + board_kind(board))
    spots = _checked_glare(glare)
    pose = _default_pose(board, origin, angle) if pose is None else pose
    if not isinstance(pose, PlanePose):
        raise ArgumentError(f"pose must be a PlanePose, got {type(pose).__name__}")
    objs, printed = _checked_layers(objects, marks)
    tones = _checked_tones(table_grey, paper_grey, ink_grey, metal_grey, side_grey)
    effects = _checked_image_effects(
        blur_sigma_px,
        noise_sigma,
        lighting_gradient,
        lighting_angle_deg,
        vignette,
        table_texture,
        paper_texture,
    )
    _check_whole_numbers(supersample, seed)
    camera_centre = pose.camera_centre_mm()
    _check_below_camera(objs, camera_centre)

    # Marks are the first flat layers (over the board, under the objects).
    layers = tuple(_mark_on_table(m, origin, angle) for m in printed) + objs
    scene = _Scene(board, origin, angle, margin, layers, camera_centre, diameters)
    lut = _tones(tones, layers, len(printed), light_on_dark=bool(light_on_dark), color=bool(color))
    radiance = _evenly_lit(
        camera, pose, scene, lut, effects, int(supersample), int(seed), color=bool(color)
    )
    image = _apply_image_effects(radiance, camera, effects, int(seed), spots)
    assert image.shape[:2] == (camera.height, camera.width)

    h_world = camera.homography(pose)
    dots_px, h_board = _board_truth(camera, pose, board, origin, angle, h_world)
    record: dict[str, float | int | bool] = {
        **tones,
        **effects.record(),
        "light_on_dark": bool(light_on_dark),
        "color": bool(color),
        "seed": int(seed),
        "supersample": int(supersample),
        "paper_margin_mm": margin,
        **effects.textures,
    }
    return RenderedScene(
        image=image,
        dot_centres_px=dots_px,
        object_centroids_px=_object_centroids_px(camera, pose, objs),
        objects=objs,
        board=board,
        board_origin_mm=origin,
        board_angle_deg=angle,
        camera=camera,
        pose=pose,
        world_to_image=h_world,
        board_to_image=h_board,
        effects=record,
        dot_diameters_mm=np.zeros(0) if diameters is None else diameters,
        marks=printed,
        glare=spots,
    )


def board_kind(board: Board | None) -> str:
    """What a board is, in words: 'circle grid', 'chessboard', 'ChArUco board'."""
    kind = getattr(board, "kind", None)
    names = {"circles": "circle grid", "chessboard": "chessboard", "charuco": "ChArUco board"}
    return names.get(str(kind), type(board).__name__)


def _inside(px: F64, camera: CameraModel, margin: float) -> NDArray[np.bool_]:
    """Whether each pixel position lies in the image, ``margin`` px from its border."""
    w, h = camera.width, camera.height
    return np.asarray(
        (px[:, 0] >= margin - 0.5)
        & (px[:, 0] <= w - 0.5 - margin)
        & (px[:, 1] >= margin - 0.5)
        & (px[:, 1] <= h - 0.5 - margin)
    )


def _checked_board(
    board: Board | None,
    origin_mm: tuple[float, float],
    angle_deg: float,
    paper_margin_mm: float,
) -> tuple[tuple[float, float], float, float]:
    """The board's placement, checked: (origin, angle, paper margin); BoardError if bad."""
    if board is not None and not is_board(board):
        raise BoardError(
            "board must be a CircleGridBoard, ChessboardBoard, CharucoBoard or None, got "
            f"{type(board).__name__}"
        )
    origin = arguments.pair("board_origin_mm", origin_mm, BoardError)
    angle = arguments.real("board_angle_deg", angle_deg, BoardError)
    margin = arguments.real("paper_margin_mm", paper_margin_mm, BoardError)
    if margin < 0:
        raise BoardError(f"paper_margin_mm must be >= 0, got {paper_margin_mm!r}")
    return origin, angle, margin


def _default_pose(board: Board | None, origin: tuple[float, float], angle: float) -> PlanePose:
    """500 mm straight above the middle of the board's points (the table origin without
    one)."""
    centre = np.zeros(2)
    if board is not None:
        pts = board.world_points()
        middle = 0.5 * (pts.min(axis=0) + pts.max(axis=0))[None, :]
        if isinstance(board, CircleGridBoard) and board.layout != "asymmetric":
            middle = np.array([[board.cols - 1, board.rows - 1]]) * (board.pitch / 2.0)
        centre = _board_to_table(middle, origin, angle)[0]
    return PlanePose(500.0, look_at_mm=(float(centre[0]), float(centre[1])))


def _checked_layers(
    objects: Sequence[SceneObject], marks: Sequence[SceneObject]
) -> tuple[tuple[SceneObject, ...], tuple[SceneObject, ...]]:
    """The objects and the printed marks as tuples, checked (marks must be flat)."""
    objs = tuple(objects)
    for i, o in enumerate(objs):
        if not isinstance(o, SceneObject):
            raise ArgumentError(f"objects[{i}] must be a SceneObject, got {type(o).__name__}")
    printed = tuple(marks)
    for i, o in enumerate(printed):
        if not isinstance(o, SceneObject):
            raise ArgumentError(f"marks[{i}] must be a SceneObject, got {type(o).__name__}")
        if o.height_mm != 0.0:
            raise ArgumentError(f"marks[{i}] must be flat (height_mm 0): marks are printed")
    return objs, printed


def _checked_tones(
    table_grey: float,
    paper_grey: float,
    ink_grey: float,
    metal_grey: float,
    side_grey: float | None,
) -> dict[str, float]:
    """The materials' grey levels by argument name, side_grey's default filled in; ImageError
    for one outside 0-255."""
    tones = {
        name: arguments.real(name, value, ImageError)
        for name, value in (
            ("table_grey", table_grey),
            ("paper_grey", paper_grey),
            ("ink_grey", ink_grey),
            ("metal_grey", metal_grey),
        )
    }
    tones["side_grey"] = (
        _SIDE_SHADE * tones["table_grey"]
        if side_grey is None
        else arguments.real("side_grey", side_grey, ImageError)
    )
    for name, value in tones.items():
        if not 0.0 <= value <= 255.0:
            raise ImageError(f"{name} must be a grey level 0-255, got {value!r}")
    return tones


def _check_whole_numbers(supersample: int, seed: int) -> None:
    """ImageError unless supersample is 1 to 32 and seed a non-negative whole number."""
    if isinstance(supersample, bool) or not isinstance(supersample, int | np.integer):
        raise ImageError(f"supersample must be a whole number, got {supersample!r}")
    if not 1 <= supersample <= 32:
        raise ImageError(f"supersample must be 1 to 32, got {supersample}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ImageError(f"seed must be a non-negative whole number, got {seed!r}")


def _check_below_camera(objects: Sequence[SceneObject], camera_centre: F64) -> None:
    """ValueError for an object as high as the camera (or higher)."""
    for i, o in enumerate(objects):
        if o.height_mm >= -camera_centre[2]:
            raise ArgumentError(
                f"objects[{i}].height_mm ({o.height_mm!r}) reaches the camera, which is "
                f"{-camera_centre[2]:.6g} mm above the table"
            )


def _evenly_lit(
    camera: CameraModel,
    pose: PlanePose,
    scene: _Scene,
    lut: F64,
    effects: _ImageEffects,
    n: int,
    seed: int,
    *,
    color: bool,
) -> NDArray[np.float32]:
    """The image before lighting, blur and noise, float32: (height, width) grey or
    (height, width, 3) BGR, with the table's and the paper's textures where they show."""
    amplitudes = (
        (_TABLE, effects.textures["table_texture"]),
        (_PAPER, effects.textures["paper_texture"]),
    )
    textured = [(material, v) for material, v in amplitudes if v > 0.0]
    if textured:
        radiance = _textured_radiance(camera, pose, scene, lut, textured, n, seed, color=color)
    else:
        radiance, _, _ = _radiance(camera, pose, scene, lut, n)
    if not color:
        radiance = np.ascontiguousarray(radiance[:, :, 0])
    return radiance


def _textured_radiance(
    camera: CameraModel,
    pose: PlanePose,
    scene: _Scene,
    lut: F64,
    textured: Sequence[tuple[int, float]],
    n: int,
    seed: int,
    *,
    color: bool,
) -> NDArray[np.float32]:
    """_radiance with each (material, amplitude) of ``textured`` given its texture, added in
    proportion to the share of each pixel that the material covers (tinted like it)."""
    # One more channel per textured material: the fraction of each pixel it covers.
    shares = np.zeros((len(lut), len(textured)))
    for j, (material, _) in enumerate(textured):
        shares[material, j] = 1.0
    radiance, plane_x, plane_y = _radiance(camera, pose, scene, np.hstack([lut, shares]), n)
    channels = lut.shape[1]
    for j, (material, amplitude) in enumerate(textured):
        pattern = _plane_texture(plane_x, plane_y, material, seed) * amplitude
        covered = pattern * radiance[:, :, channels + j]
        tint = _TINT_TABLE if material == _TABLE else _TINT_PAPER
        for ch in range(channels):
            radiance[:, :, ch] += covered * (tint[ch] if color else 1.0)
    return radiance[:, :, :channels]


def _board_truth(
    camera: CameraModel,
    pose: PlanePose,
    board: Board | None,
    origin: tuple[float, float],
    angle: float,
    h_world: F64,
) -> tuple[F64, F64 | None]:
    """The board's points in the image (exact, lens included) and the board -> image
    homography (H[2, 2] = 1); (0, 2) and None without a board."""
    if board is None:
        return np.zeros((0, 2)), None
    dots_mm = _board_to_table(board.world_points(), origin, angle)
    dots_px = camera.project(dots_mm, pose)
    b2t = np.array(
        [
            [math.cos(math.radians(angle)), -math.sin(math.radians(angle)), origin[0]],
            [math.sin(math.radians(angle)), math.cos(math.radians(angle)), origin[1]],
            [0.0, 0.0, 1.0],
        ]
    )
    h_board = h_world @ b2t
    return dots_px, h_board / h_board[2, 2]


def _object_centroids_px(
    camera: CameraModel, pose: PlanePose, objects: Sequence[SceneObject]
) -> F64:
    """Each object's truth in the image: the projection of its top face's centroid."""
    centroids = np.array([o.position_mm for o in objects], dtype=np.float64).reshape(-1, 2)
    heights = np.array([float(o.height_mm) for o in objects], dtype=np.float64)
    return camera.project(centroids, pose, heights) if len(objects) else np.zeros((0, 2))


def _tones(
    tones: Mapping[str, float],
    objects: Sequence[SceneObject],
    n_marks: int = 0,
    *,
    light_on_dark: bool,
    color: bool,
) -> F64:
    """The material -> value table, (n_materials, 1) grey or (n_materials, 3) BGR. The
    first ``n_marks`` objects are printed marks: the board's ink unless they have a grey."""
    paper, ink = tones["paper_grey"], tones["ink_grey"]
    if light_on_dark:
        paper, ink = ink, paper
    rows: list[tuple[float, tuple[float, float, float]]] = [
        (tones["table_grey"], _TINT_TABLE),
        (paper, _TINT_PAPER),
        (ink, _TINT_INK),
    ]
    for i, o in enumerate(objects):
        if i < n_marks:
            rows.append((ink if o.grey is None else float(o.grey), _TINT_INK))
            continue
        rows.append((tones["metal_grey"] if o.grey is None else float(o.grey), _TINT_METAL))
    rows.append((tones["side_grey"], _TINT_METAL))  # the walls of raised objects
    if not color:
        return np.array([[g] for g, _ in rows], dtype=np.float64)
    return np.asarray(
        np.clip(np.array([[g * t for t in tint] for g, tint in rows]), 0, 255), np.float64
    )


def _radiance(
    camera: CameraModel,
    pose: PlanePose,
    scene: _Scene,
    lut: F64,
    n: int,
) -> tuple[NDArray[np.float32], F64, F64]:
    """The noise-free, evenly lit image in float32, (height, width, channels): pure pixels
    take their material's value, edge pixels the mean over n x n cells, each traced through
    the lens to the plane and shaded by the exact coverage of its footprint; and the table
    points (X, Y) of the pixels' centres."""
    w, h = camera.width, camera.height
    f = float(camera.focal_px)
    # The plane points of the pixel corners.
    xd = ((np.arange(w + 1, dtype=np.float64) - 0.5 - camera.cx) / f)[None, :]
    yd = ((np.arange(h + 1, dtype=np.float64) - 0.5 - camera.cy) / f)[:, None]
    cx, cy, ok = camera._rays_to_plane(xd, yd, pose)
    if not ok.all():
        raise ArgumentError(
            "the plane does not fill the view: part of the image sees above its horizon "
            f"(tilt {pose.tilt_deg} degrees is too steep for this camera and distance)"
        )
    # Pixel centres (mean of the corners: exact to second order, and only used where the
    # whole footprint, with a margin, lies in one material) and footprint radii.
    px = 0.25 * (cx[:-1, :-1] + cx[1:, :-1] + cx[:-1, 1:] + cx[1:, 1:])
    py = 0.25 * (cy[:-1, :-1] + cy[1:, :-1] + cy[:-1, 1:] + cy[1:, 1:])
    rad = np.hypot(cx[:-1, :-1] - px, cy[:-1, :-1] - py)
    for rows, cols in ((slice(1, None), slice(None, -1)), (slice(None, -1), slice(1, None))):
        np.maximum(rad, np.hypot(cx[rows, cols] - px, cy[rows, cols] - py), out=rad)
    np.maximum(rad, np.hypot(cx[1:, 1:] - px, cy[1:, 1:] - py), out=rad)
    rad = rad * 1.05 + 1e-9
    mat, edge = scene.classify(px, py, rad)
    out = lut[mat].astype(np.float32)
    ey, ex = np.nonzero(edge)
    if ey.size:
        o = (np.arange(n) + 0.5) / n - 0.5
        ou = np.tile(o, n)
        ov = np.repeat(o, n)
        chunk = max(1, 1_000_000 // (n * n))
        for start in range(0, ey.size, chunk):
            iy, ix = ey[start : start + chunk], ex[start : start + chunk]
            su = ((ix[:, None] + ou[None, :]) - camera.cx) / f
            sv = ((iy[:, None] + ov[None, :]) - camera.cy) / f
            sx, sy, sok = camera._rays_to_plane(su, sv, pose)
            assert sok.all()
            # The pixel's Jacobian (plane mm per pixel along u and v) from its corners,
            # scaled to one cell.
            ju_x = 0.5 * (cx[iy, ix + 1] - cx[iy, ix] + cx[iy + 1, ix + 1] - cx[iy + 1, ix]) / n
            ju_y = 0.5 * (cy[iy, ix + 1] - cy[iy, ix] + cy[iy + 1, ix + 1] - cy[iy + 1, ix]) / n
            jv_x = 0.5 * (cx[iy + 1, ix] - cx[iy, ix] + cx[iy + 1, ix + 1] - cx[iy, ix + 1]) / n
            jv_y = 0.5 * (cy[iy + 1, ix] - cy[iy, ix] + cy[iy + 1, ix + 1] - cy[iy, ix + 1]) / n
            cell = tuple(np.repeat(j, n * n) for j in (ju_x, ju_y, jv_x, jv_y))
            values = scene.shade(sx.ravel(), sy.ravel(), cell, lut)  # type: ignore[arg-type]
            out[iy, ix] = values.reshape(len(iy), n * n, -1).mean(axis=1)
    return np.ascontiguousarray(out, dtype=np.float32), px, py
