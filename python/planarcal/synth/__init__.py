"""Synthetic photographs of a work plane with known truth: a board, objects, a camera.

Use it to test a setup before a camera is mounted, and as the ground truth of planarcal's
demo and tests. A scene is a flat *table* (the work plane) seen by a pinhole camera with
radial lens distortion. On the table lie, optionally, a printed circle-grid board
(:class:`~planarcal.calib.board.CircleGridBoard` on a sheet of paper: either layout, an origin
marker up to as wide as the dots' spacing, enlarged fiducial dots anywhere in the grid,
printed marks beside the dots) and objects (bolts, nuts, washers, discs, rectangles:
:class:`SceneObject`), flat or standing up off the table. :func:`render_scene` photographs
it and returns the 8-bit image with the exact truth: where every dot centre and every object
centroid lies on the table (mm) and in the image (px), and each dot's printed diameter.

Any board of :mod:`planarcal.calib.boards` renders: circle grids, chessboards and ChArUco
boards (drawn from the board's printed ink by exact area), whole or in part (a pose that
cuts it off, a :func:`hand` over it, glare), with each point's truth by id.

For board detection, :func:`board_variants` renders a corpus of boards with their truth
(circle grids: dot sizes from 0.15 to 0.85 of the pitch, both layouts, markers and
fiducials, printed marks (:func:`printed_marks`), 320 x 240 to 4K, webcam JPEG
(:func:`jpeg`), distortion, tilt, uneven light, light dots on dark paper, textured tables;
chessboards and ChArUco boards likewise, and partial views: ``kind="chessboard"``,
``"charuco"``).

The modules, from the bottom up:

* ``camera``: :class:`PlanePose`, :class:`CameraModel`, :class:`View`; the conventions
  (table coordinates, pixels, the lens) that everything here follows.
* ``shapes``, ``point_index``: flat shapes as signed-distance fields, and finding points
  near one.
* ``objects``: :class:`SceneObject` (bolts, nuts, ...) and its :class:`Silhouette`;
  ``occluders``: :func:`hand`.
* ``raised``: objects with height, as regions of the table plane.
* ``dots``: a board's dots on the table and their field; ``pattern``: a board printed as
  rectangles (chessboards, ChArUco) as exact regions.
* ``scene``: which material each table point sees, and a cell shaded by exact coverage.
* ``effects``: textures, uneven lighting, blur, noise, :func:`jpeg`.
* ``marks``: :func:`printed_marks` beside the dots.
* ``render``: :func:`render_scene` and :class:`RenderedScene`: how it renders, and how
  accurately.
* ``paper``: the paper's setup (``PAPER_*``), :func:`paper_scene`, :func:`render_paper_look`,
  :func:`random_paper_scene`.
* ``corpus``: :data:`BOARD_VARIANTS`, :func:`board_variant`, :func:`board_variants`.
* ``cell``: :func:`render_cell`, a work cell several boards wide with the board photographed
  at several placements (:class:`Cell`), and :func:`mirrored_detection`.
* ``copies``: :func:`render_copies`, several copies of a board in one image, each with
  its truth (:class:`RenderedCopies`).
* ``demo`` and ``paper_data``: the built-in demo and the paper's published numbers.
"""

from __future__ import annotations

from planarcal.synth.camera import CameraModel, PlanePose, View
from planarcal.synth.cell import Cell, CellPlacement, mirrored_detection, render_cell
from planarcal.synth.copies import BoardCopy, RenderedCopies, relative_pose, render_copies
from planarcal.synth.corpus import (
    BOARD_VARIANTS,
    CHARUCO_VARIANTS,
    CHESSBOARD_VARIANTS,
    CIRCLE_PARTIAL_VARIANTS,
    VARIANTS_BY_KIND,
    BoardVariant,
    board_variant,
    board_variants,
)
from planarcal.synth.effects import jpeg
from planarcal.synth.live_video import LiveVideo, write_live_video
from planarcal.synth.marks import MARK_KINDS, MarkKind, printed_marks
from planarcal.synth.objects import OBJECT_KINDS, ObjectKind, SceneObject, Silhouette
from planarcal.synth.occluders import hand
from planarcal.synth.paper import (
    PAPER_BOARD,
    PAPER_CAMERA,
    PAPER_EFFECTS,
    PAPER_OBJECTS,
    PAPER_POSE,
    PaperScene,
    paper_scene,
    random_paper_scene,
    render_paper_look,
)
from planarcal.synth.render import RenderedScene, render_scene

__all__ = [
    "BOARD_VARIANTS",
    "CHARUCO_VARIANTS",
    "CHESSBOARD_VARIANTS",
    "CIRCLE_PARTIAL_VARIANTS",
    "MARK_KINDS",
    "OBJECT_KINDS",
    "PAPER_BOARD",
    "PAPER_CAMERA",
    "PAPER_EFFECTS",
    "PAPER_OBJECTS",
    "PAPER_POSE",
    "VARIANTS_BY_KIND",
    "BoardCopy",
    "BoardVariant",
    "CameraModel",
    "Cell",
    "CellPlacement",
    "LiveVideo",
    "MarkKind",
    "ObjectKind",
    "PaperScene",
    "PlanePose",
    "RenderedCopies",
    "RenderedScene",
    "SceneObject",
    "Silhouette",
    "View",
    "board_variant",
    "board_variants",
    "hand",
    "jpeg",
    "mirrored_detection",
    "paper_scene",
    "printed_marks",
    "random_paper_scene",
    "relative_pose",
    "render_cell",
    "render_copies",
    "render_paper_look",
    "render_scene",
    "write_live_video",
]
