"""A rendered work cell: one fixed camera over a work area several boards wide, and the board
photographed at several places on it (one image per placement), with exact truth.

It is the ground truth of calibration from several placements (issue 23): the board is laid
flat at K places on the work plane, each placement is photographed by the same camera, and a
calibration fits one plane-to-image mapping with each placement's unknown in-plane pose.

Frames
------
* **Table** (mm): the work plane, as everywhere in :mod:`planarcal.synth`. The work area is
  the rectangle [0, width] x [0, height]; the camera looks at its centre.
* **Plane** (mm): the frame a calibration from several placements reports in, the reference
  placement's board frame. :meth:`Cell.truth_plane_mm` takes a table point there exactly;
  :meth:`Cell.pixel_of` gives the pixel any table point is seen at (lens included), so a bench
  samples the whole work area (:meth:`Cell.area_points`), maps each true pixel through a
  calibration and compares it with :meth:`Cell.truth_plane_mm`.
* **Placement poses**: placement k's board lies on the table at ``angle_deg`` with its centre
  (the middle of its printed field) at ``centre_mm``; in the plane frame its pose is
  :meth:`Cell.true_pose` (plane = R(angle) board + offset, as a calibration reports it).

Placements not flat on the plane
--------------------------------
A placement may be ``raised_mm`` (the board lying flat on a part that high) or
``lifted_mm`` (one edge, the board's +x side, lifted that high, the opposite edge on the
table). Its image is rendered exactly with the board on that plane: the camera and the board's
position are unchanged, only the plane the renderer traces rays to is the board's. That plane is
a rigid motion (Q, s) of the table (X_table = Q (x, y, 0) + s), so its pose as the camera sees
it is R' = R Q, t' = R s + t, which :func:`_plane_pose` writes as an ordinary
:class:`PlanePose` (roll, tilt about an in-plane axis, distance, aim point) and checks to
machine precision. The table around the board is rendered on the same plane, which no one can
see: it is uniform. The placement's ``scene.points_px`` are its board points' true pixels, on
the board's real plane; the table truth (:meth:`Cell.truth_plane_mm`, :meth:`Cell.pixel_of`)
is the flat table's, unchanged.

A wrong detection is a corruption of the detection, not of the image:
:func:`mirrored_detection` gives a detection's points the ids of the board mirrored about its
middle column (every point seen where its mirror image lies): no rotation and translation in
the plane maps a board onto its mirror image, so a calibration must refuse that placement. (A
shift of every id by a whole pitch is a rigid motion of the board in its own plane: the
placement's pose absorbs it exactly and nothing can detect it, nor does it harm the mapping
unless the placement is the reference.)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board, is_board
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.calib.detection import BoardDetection
from planarcal.errors import ArgumentError
from planarcal.synth.camera import CameraModel, PlanePose
from planarcal.synth.dots import _board_to_table
from planarcal.synth.paper import PAPER_EFFECTS
from planarcal.synth.render import RenderedScene, render_scene
from planarcal.synth.shapes import _rotation_2d

F64 = NDArray[np.float64]

CELL_BOARDS: Mapping[str, Board] = {
    "circles": CircleGridBoard(cols=9, rows=7, pitch=20.0, diameter=10.0),
    "chessboard": ChessboardBoard(cols=9, rows=6, square=20.0),
    "charuco": CharucoBoard(squares_x=9, squares_y=7, square=20.0, marker=15.0),
}
"""The cell's board by type: each about 200 x 160 mm of paper (a circle grid of 9 x 7 dots,
20 mm apart; a chessboard of 9 x 6 inner corners of 20 mm; a ChArUco board of 9 x 7 squares of
20 mm)."""

CELL_CAMERA = CameraModel(width=1280, height=960, focal_px=1000.0, k1=-0.12, k2=0.02)
"""The cell's camera: 1280 x 960, f = 1000 px (65 degrees across), webcam-like barrel
distortion (k1 = -0.12, k2 = 0.02: 7 px at the image's corners)."""

PAPER_MARGIN_MM = 15.0
"""The paper beyond the board's printed field (render_scene's default)."""

# The placements' places, in thirds of the work area (column, row), in the order they are
# used: the middle (the reference), the four corners, then the middles of the four sides.
_SLOTS = ((1, 1), (0, 0), (2, 0), (2, 2), (0, 2), (1, 0), (2, 1), (1, 2), (0, 1))
# Their names, as the camera sees them (the table's x to the right of the image, y down it).
_SLOT_NAMES = (
    "middle",
    "top left",
    "top right",
    "bottom right",
    "bottom left",
    "top",
    "right",
    "bottom",
    "left",
)
# The boards' angles (degrees), in the same order: varied, and within 35 degrees, where every
# board type's detector reads the board's ids the way they are printed.
_ANGLES = (3.0, 12.0, -18.0, 25.0, -10.0, 30.0, -24.0, 16.0, -32.0)
# How far the seed moves each placement from its slot (a fraction of the board) and turns it.
_JITTER_BOARDS, _JITTER_DEG = 0.05, 3.0
# The work area's margin in the image, each side, as a fraction of the image's size.
_IMAGE_MARGIN = 0.03


@dataclasses.dataclass(frozen=True, eq=False)
class CellPlacement:
    """One placement of the board and its photograph.

    ``name``: where it is in the work area ("middle", "top left", ...: the image's top is
    the table's -y side) or, for a place given, "placement k";
    ``centre_mm``: where the middle of the board's printed field lies on the table;
    ``origin_mm``: where its world origin (board point 0's frame origin) lies;
    ``angle_deg``: the board's x axis from the table's (towards its y); ``raised_mm``: how
    high the part it lies on is (0: on the table); ``lifted_mm``: how high its +x edge is
    lifted (0: flat); ``pose``: the plane the board lay on, as the camera saw it (the table's
    own pose when the board is flat); ``scene``: the rendered image and its truth (its
    ``points_px``: each board point's true pixel, on the plane the board really lay on).
    """

    index: int
    name: str
    centre_mm: tuple[float, float]
    origin_mm: tuple[float, float]
    angle_deg: float
    raised_mm: float
    lifted_mm: float
    pose: PlanePose
    scene: RenderedScene

    @property
    def image(self) -> NDArray[np.uint8]:
        return self.scene.image

    @property
    def flat(self) -> bool:
        """Whether the board lay flat on the table."""
        return self.raised_mm == 0.0 and self.lifted_mm == 0.0


@dataclasses.dataclass(frozen=True, eq=False)
class Cell:
    """A rendered work cell (see the module): the camera, the table's pose, the work area, the
    board and its placements (each with its image and truth), and the reference placement,
    whose board frame is the plane frame a calibration reports in."""

    board: Board
    camera: CameraModel
    pose: PlanePose
    area_mm: tuple[float, float]
    placements: tuple[CellPlacement, ...]
    reference: int

    @property
    def images(self) -> tuple[NDArray[np.uint8], ...]:
        """The placements' images, in placement order."""
        return tuple(p.image for p in self.placements)

    @property
    def board_size_mm(self) -> tuple[float, float]:
        """The board's paper (its printed field and the margin around it), width and height."""
        x0, y0, x1, y1 = self.board.ink().field
        return (x1 - x0 + 2.0 * PAPER_MARGIN_MM, y1 - y0 + 2.0 * PAPER_MARGIN_MM)

    def truth_plane_mm(self, table_mm: ArrayLike) -> F64:
        """Table points (..., 2) in the plane frame (the reference placement's board frame),
        exactly."""
        p, shape = arguments.points("table_mm", table_mm)
        ref = self.placements[self.reference]
        out = (p - np.array(ref.origin_mm)) @ _rotation_2d(ref.angle_deg)
        return np.asarray(out.reshape(*shape, 2), np.float64)

    def table_mm(self, plane_mm: ArrayLike) -> F64:
        """Plane-frame points (..., 2) on the table (the inverse of :meth:`truth_plane_mm`)."""
        p, shape = arguments.points("plane_mm", plane_mm)
        ref = self.placements[self.reference]
        out = _board_to_table(p, ref.origin_mm, ref.angle_deg)
        return np.asarray(out.reshape(*shape, 2), np.float64)

    def pixel_of(self, table_mm: ArrayLike) -> F64:
        """The exact pixel (..., 2) each table point is seen at, lens distortion included."""
        return self.camera.project(table_mm, self.pose)

    def true_pose(self, index: int) -> tuple[float, tuple[float, float]]:
        """Placement ``index``'s board in the plane frame, as a calibration reports it:
        (angle_deg, (x, y) offset mm) with plane = R(angle) board + offset (for a board not
        flat: where it would lie had it been laid flat there)."""
        if isinstance(index, bool) or not isinstance(index, int | np.integer):
            raise ArgumentError(f"index must be a placement's index, got {index!r}")
        if not 0 <= index < len(self.placements):
            raise ArgumentError(
                f"placement {index} does not exist (the cell has {len(self.placements)})"
            )
        p, ref = self.placements[int(index)], self.placements[self.reference]
        angle = (p.angle_deg - ref.angle_deg + 180.0) % 360.0 - 180.0
        offset = self.truth_plane_mm(np.array(p.origin_mm))
        return angle, (float(offset[0]), float(offset[1]))

    def area_points(self, step_mm: float = 10.0) -> F64:
        """A grid of table points (n, 2) over the whole work area, ``step_mm`` apart, its edges
        included."""
        step = arguments.positive("step_mm", step_mm)
        w, h = self.area_mm
        xs = np.linspace(0.0, w, max(2, math.ceil(w / step) + 1))
        ys = np.linspace(0.0, h, max(2, math.ceil(h / step) + 1))
        gx, gy = np.meshgrid(xs, ys)
        return np.column_stack([gx.ravel(), gy.ravel()])

    def distance_to_boards_mm(self, table_mm: ArrayLike, count: int | None = None) -> F64:
        """Each table point's (...) distance to the nearest flat placement's board points (the
        rectangle they span; 0 inside it): 0 on a placement, large far from every one.
        ``count``: only the first ``count`` placements (a calibration from those)."""
        p, shape = arguments.points("table_mm", table_mm)
        n = len(self.placements) if count is None else count
        if isinstance(n, bool) or not isinstance(n, int | np.integer):
            raise ArgumentError(f"count must be a number of placements, got {count!r}")
        if not 1 <= n <= len(self.placements):
            raise ArgumentError(f"count must be 1 to {len(self.placements)}, got {count!r}")
        pts = self.board.world_points()
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        best = np.full(len(p), np.inf)
        for placement in self.placements[:n]:
            if not placement.flat:
                continue
            b = (p - np.array(placement.origin_mm)) @ _rotation_2d(placement.angle_deg)
            gap = np.maximum(np.maximum(lo - b, b - hi), 0.0)
            best = np.minimum(best, np.hypot(gap[:, 0], gap[:, 1]))
        return np.asarray(best.reshape(shape), np.float64)


def cell_board(board: Board | str) -> Board:
    """A board for a cell: a board as it is, or a board type's name (:data:`CELL_BOARDS`)."""
    if isinstance(board, str):
        if board not in CELL_BOARDS:
            raise ArgumentError(
                f"board must be a board or one of {', '.join(CELL_BOARDS)}, got {board!r}"
            )
        return CELL_BOARDS[board]
    if not is_board(board):
        raise ArgumentError(
            f"board must be a board or a board type's name, got {type(board).__name__}"
        )
    return board


def render_cell(
    board: Board | str = "circles",
    placements: int | Sequence[tuple[float, float, float]] = 6,
    *,
    area_boards: float = 3.0,
    camera: CameraModel = CELL_CAMERA,
    tilt_deg: float = 8.0,
    tilt_axis_deg: float = 30.0,
    raised_mm: Mapping[int, float] | None = None,
    lifted_mm: Mapping[int, float] | None = None,
    reference: int = 0,
    seed: int = 0,
    effects: Mapping[str, float] = PAPER_EFFECTS,
    supersample: int = 4,
) -> Cell:
    """Render a work cell: ``camera`` (default :data:`CELL_CAMERA`) fixed above a work area
    ``area_boards`` board papers wide and high (at least 3), tilted ``tilt_deg`` about an
    in-plane axis at ``tilt_axis_deg``, from the distance at which the whole area fills the
    image less a 3 % margin; the board (a board or a type's name, :data:`CELL_BOARDS`) at each
    placement, each photographed on its own with ``effects`` (render_scene's tones and image
    effects; default the paper's: blur, noise, uneven light) and noise seeded per image.

    ``placements``: how many (1 to 9: the middle of the area first, then its four corners,
    then the middles of its sides; each moved up to 5 % of a board and turned up to 3 degrees
    by ``seed`` from a set of angles within 35 degrees, and kept inside the area), or each
    one's (x, y, angle_deg): its field's centre on the table (mm) and its angle.

    ``raised_mm`` (placement index -> mm): that placement's board lies flat on a part that
    high. ``lifted_mm`` (index -> mm): its +x edge is lifted that high, the -x edge on the
    table. ``reference``: the placement whose board frame is the plane frame.

    Raises ArgumentError for bad arguments (a count, an area, a height, a reference out of
    range, a placement outside the image).
    """
    shown = cell_board(board)
    if not isinstance(camera, CameraModel):
        raise ArgumentError(f"camera must be a CameraModel, got {type(camera).__name__}")
    area_factor = arguments.real("area_boards", area_boards)
    if not 3.0 <= area_factor <= 10.0:
        raise ArgumentError(
            f"area_boards must be 3 to 10 (board sizes across the work area), got {area_boards!r}"
        )
    tilt = arguments.real("tilt_deg", tilt_deg)
    if not 0.0 <= tilt <= 30.0:
        raise ArgumentError(f"tilt_deg must be 0 to 30, got {tilt_deg!r}")
    axis = arguments.real("tilt_axis_deg", tilt_axis_deg)
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ArgumentError(f"seed must be a non-negative whole number, got {seed!r}")
    x0, y0, x1, y1 = shown.ink().field
    paper = np.array([x1 - x0, y1 - y0]) + 2.0 * PAPER_MARGIN_MM
    field_centre = np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0])
    area = paper * area_factor
    rng = np.random.default_rng(int(seed))
    places = _places(placements, area, paper, rng)
    count = len(places)
    raised = _heights("raised_mm", raised_mm, count)
    lifted = _heights("lifted_mm", lifted_mm, count)
    if isinstance(reference, bool) or not isinstance(reference, int | np.integer):
        raise ArgumentError(f"reference must be a placement's index, got {reference!r}")
    if not 0 <= reference < count:
        raise ArgumentError(f"reference {reference} is not a placement (there are {count})")
    if raised[reference] or lifted[reference]:
        raise ArgumentError(f"the reference placement {reference} must lie flat on the table")
    for k, h in enumerate(lifted):
        if h >= paper[0]:
            raise ArgumentError(
                f"lifted_mm[{k}] = {h:g} is more than the board's paper is wide ({paper[0]:g} mm)"
            )
    table_pose = _framing_pose(camera, area, tilt, axis)
    rendered = []
    for k, (x, y, angle) in enumerate(places):
        origin = np.array([x, y]) - _rotation_2d(angle) @ field_centre
        pose = _placement_plane(
            table_pose, shown, (float(origin[0]), float(origin[1])), angle, raised[k], lifted[k]
        )
        scene = render_scene(
            camera,
            pose,
            board=shown,
            board_origin_mm=(float(origin[0]), float(origin[1])),
            board_angle_deg=angle,
            paper_margin_mm=PAPER_MARGIN_MM,
            seed=int(rng.integers(0, 2**31)),
            supersample=supersample,
            **effects,  # type: ignore[arg-type]
        )
        if not scene.points_in_view(2.0).all():
            raise ArgumentError(
                f"placement {k} at ({x:g}, {y:g}) mm reaches outside the image: place it "
                "inside the work area"
            )
        rendered.append(
            CellPlacement(
                index=k,
                name=_SLOT_NAMES[k]
                if isinstance(placements, int | np.integer)
                else f"placement {k}",
                centre_mm=(x, y),
                origin_mm=(float(origin[0]), float(origin[1])),
                angle_deg=angle,
                raised_mm=raised[k],
                lifted_mm=lifted[k],
                pose=pose,
                scene=scene,
            )
        )
    return Cell(
        board=shown,
        camera=camera,
        pose=table_pose,
        area_mm=(float(area[0]), float(area[1])),
        placements=tuple(rendered),
        reference=int(reference),
    )


def mirrored_detection(detection: BoardDetection) -> BoardDetection:
    """A wrong detection: ``detection`` with each point given the id of its mirror image about
    the board's middle column (the image points unchanged, ids ascending as a detection's
    are). Every point then claims to lie where its mirror image does, which no rotation and
    translation of the board in the plane explains."""
    if not isinstance(detection, BoardDetection):
        raise ArgumentError(f"detection must be a BoardDetection, got {type(detection).__name__}")
    pts = detection.board.world_points()
    xs = pts[:, 0].min() + pts[:, 0].max() - pts[:, 0]
    gap = np.hypot(xs[:, None] - pts[None, :, 0], pts[:, 1, None] - pts[None, :, 1])
    mirror = gap.argmin(axis=1)
    if not np.allclose(gap[np.arange(len(pts)), mirror], 0.0, atol=1e-9):
        raise ArgumentError("this board's points are not symmetric about its middle column")
    ids = mirror[np.asarray(detection.ids, np.intp)]
    order = np.argsort(ids, kind="stable")
    n = len(ids)
    changes: dict[str, object] = {"ids": ids[order].astype(np.intp)}
    for name in ("image_points", "refined", "enlarged", "dot_diameters_px"):
        values = getattr(detection, name)
        if len(values) == n:
            changes[name] = np.ascontiguousarray(values[order])
    return dataclasses.replace(detection, **changes)  # type: ignore[arg-type]


def _places(
    placements: int | Sequence[tuple[float, float, float]],
    area: F64,
    paper: F64,
    rng: np.random.Generator,
) -> list[tuple[float, float, float]]:
    """Each placement's (x, y, angle_deg): the field's centre on the table and its angle."""
    if isinstance(placements, bool):
        raise ArgumentError(f"placements must be a count or a list of places, got {placements!r}")
    if isinstance(placements, int | np.integer):
        if not 1 <= placements <= len(_SLOTS):
            raise ArgumentError(f"placements must be 1 to {len(_SLOTS)}, got {placements}")
        out = []
        for (i, j), angle in zip(_SLOTS[:placements], _ANGLES, strict=False):
            a = angle + float(rng.uniform(-_JITTER_DEG, _JITTER_DEG))
            centre = (np.array([i, j]) + 0.5) * area / 3.0
            centre = centre + rng.uniform(-1.0, 1.0, 2) * _JITTER_BOARDS * paper
            # Inside the area: the turned paper's half-extents from its edges.
            c, s = abs(math.cos(math.radians(a))), abs(math.sin(math.radians(a)))
            half = 0.5 * np.array([c * paper[0] + s * paper[1], s * paper[0] + c * paper[1]])
            centre = np.clip(centre, half, np.maximum(half, area - half))
            out.append((float(centre[0]), float(centre[1]), a))
        return out
    try:
        items = list(placements)
    except TypeError:
        raise ArgumentError(
            f"placements must be a count or a list of (x, y, angle_deg), got {placements!r}"
        ) from None
    if not 1 <= len(items) <= 64:
        raise ArgumentError(f"placements must list 1 to 64 places, got {len(items)}")
    out = []
    for k, item in enumerate(items):
        try:
            x, y, a = item
        except (TypeError, ValueError):
            raise ArgumentError(
                f"placements[{k}] must be (x_mm, y_mm, angle_deg), got {item!r}"
            ) from None
        out.append(
            (
                arguments.real(f"placements[{k}] x", x),
                arguments.real(f"placements[{k}] y", y),
                arguments.real(f"placements[{k}] angle", a),
            )
        )
    return out


def _heights(name: str, values: Mapping[int, float] | None, count: int) -> list[float]:
    """Each placement's height (mm) from an index -> height mapping (0 where not given)."""
    out = [0.0] * count
    if values is None:
        return out
    if not isinstance(values, Mapping):
        raise ArgumentError(f"{name} must map placement indices to heights in mm, got {values!r}")
    for index, value in values.items():
        if isinstance(index, bool) or not isinstance(index, int | np.integer):
            raise ArgumentError(f"{name}: {index!r} is not a placement's index")
        if not 0 <= index < count:
            raise ArgumentError(f"{name}: placement {index} does not exist (there are {count})")
        h = arguments.real(f"{name}[{index}]", value)
        if not 0.0 <= h <= 100.0:
            raise ArgumentError(f"{name}[{index}] must be 0 to 100 mm, got {value!r}")
        out[int(index)] = h
    return out


def _framing_pose(camera: CameraModel, area: F64, tilt: float, axis: float) -> PlanePose:
    """The camera's pose over the area: aimed at its centre, tilted, from the nearest distance
    (in 1 % steps) at which its corners lie inside the image less the margin."""
    corners = np.array([[0.0, 0.0], [area[0], 0.0], [area[0], area[1]], [0.0, area[1]]])
    edges = np.linspace(0.0, 1.0, 9)[:, None]
    outline = np.vstack(
        [a + edges * (b - a) for a, b in zip(corners, np.roll(corners, -1, 0), strict=True)]
    )
    size = np.array([camera.width, camera.height], dtype=np.float64)
    lo, hi = _IMAGE_MARGIN * size - 0.5, (1.0 - _IMAGE_MARGIN) * size - 0.5
    distance = float(camera.focal_px * np.max(area / ((1.0 - 2.0 * _IMAGE_MARGIN) * size)))
    centre = (float(area[0] / 2.0), float(area[1] / 2.0))
    for _ in range(200):
        pose = PlanePose(distance, tilt_deg=tilt, tilt_axis_deg=axis, look_at_mm=centre)
        px = camera.project(outline, pose)
        if (px >= lo).all() and (px <= hi).all():
            return pose
        distance *= 1.01
    raise ArgumentError(f"the camera cannot frame the work area at a tilt of {tilt:g} degrees")


def _placement_plane(
    table: PlanePose,
    board: Board,
    origin: tuple[float, float],
    angle: float,
    raised: float,
    lifted: float,
) -> PlanePose:
    """The plane a placement's board lies on, as a PlanePose with the table's 2-D frame on it:
    the table's own pose for a flat board; raised by ``raised`` mm; turned about the paper's
    -x edge so that its +x edge is ``lifted`` mm higher."""
    if not raised and not lifted:
        return table
    q = np.eye(3)
    # Table Z points away from the camera: up is -Z.
    shift = np.array([0.0, 0.0, -raised])
    if lifted:
        x0, _, x1, _ = board.ink().field
        width = x1 - x0 + 2.0 * PAPER_MARGIN_MM
        rot = _rotation_2d(angle)
        hinge_point = np.append(
            _board_to_table(np.array([[x0 - PAPER_MARGIN_MM, 0.0]]), origin, angle)[0], 0.0
        )
        hinge = np.append(rot[:, 1], 0.0)  # the board's y axis on the table
        # Turning about the board's y axis by +beta takes its +x side to -Z (towards the camera).
        turn, _ = cv2.Rodrigues(hinge * math.asin(lifted / width))
        q = np.asarray(turn, np.float64)
        shift = shift + hinge_point - q @ hinge_point
    r, t = table.rotation(), table.translation()
    return _plane_pose(r @ q, r @ shift + t)


def _plane_pose(rotation: F64, translation: F64) -> PlanePose:
    """The PlanePose whose rotation and translation are these (X_cam = R X_plane + t): the
    roll about the optical axis, then the tilt about an in-plane axis, the distance and the
    aim point, each solved exactly and the result checked."""
    r = np.asarray(rotation, np.float64)
    # R = Rz(roll) T with T a turn about an in-plane axis: T's skew part has no z component.
    roll = math.atan2(r[1, 0] - r[0, 1], r[0, 0] + r[1, 1])
    c, s = math.cos(roll), math.sin(roll)
    tilt_part = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ r
    rvec, _ = cv2.Rodrigues(tilt_part)
    v = rvec.ravel()
    tilt, axis = float(np.hypot(v[0], v[1])), math.atan2(v[1], v[0])
    normal = r[2, :]  # the optical axis in plane coordinates
    u = r.T @ np.asarray(translation, np.float64)
    distance = float(u[2] / normal[2])
    look = distance * normal[:2] - u[:2]
    pose = PlanePose(
        distance,
        tilt_deg=math.degrees(tilt),
        tilt_axis_deg=math.degrees(axis),
        roll_deg=math.degrees(roll),
        look_at_mm=(float(look[0]), float(look[1])),
    )
    scale = 1e-9 * (1.0 + float(np.abs(translation).max()))
    if not (
        np.allclose(pose.rotation(), r, atol=1e-12)
        and np.allclose(pose.translation(), translation, atol=scale)
    ):
        raise ArgumentError("the board's plane cannot be written as a camera pose")
    return pose
