"""The paper's setup as a scene: its board, camera, pose, objects and effects (``PAPER_*``),
the demo's pair of images (:func:`paper_scene`) and random views of it for accuracy
statistics (:func:`random_paper_scene`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numpy as np

from planarcal import arguments
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board, is_board
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.errors import ArgumentError, BoardError, ImageError
from planarcal.synth.camera import CameraModel, PlanePose
from planarcal.synth.objects import SceneObject
from planarcal.synth.render import RenderedScene, render_scene

PAPER_BOARD = CircleGridBoard(cols=14, rows=10, pitch=20.0, diameter=10.0)
"""The paper's board: 14 x 10 dots of 10 mm, 20 mm apart, no origin marker."""

PAPER_CHESSBOARD = ChessboardBoard(cols=11, rows=8, square=24.0)
"""A chessboard in the paper board's place: 11 x 8 inner corners of 24 mm (240 x 168 mm,
the paper's 260 x 180 mm dot field), corner 0 at the table origin, so its points span the
paper's objects."""

PAPER_CHARUCO = CharucoBoard(
    squares_x=12, squares_y=9, square=24.0, marker=18.0, dictionary="DICT_5X5_100"
)
"""A ChArUco board in the paper board's place: 12 x 9 squares of 24 mm with 18 mm DICT_5X5_100
markers (its 11 x 8 inner corners where :data:`PAPER_CHESSBOARD`'s are, 24 mm further on:
its world origin, the outer corner, at the table origin)."""

PAPER_BOARDS: Mapping[str, Board] = {
    "circles": PAPER_BOARD,
    "chessboard": PAPER_CHESSBOARD,
    "charuco": PAPER_CHARUCO,
}
"""The board of :func:`paper_scene` by type (``board="circles"`` and so on)."""

PAPER_CAMERA = CameraModel(
    width=1280, height=720, focal_px=1070.0, principal=(644.0, 355.0), k1=-0.12, k2=0.03
)
"""A Logitech C525-like webcam at 1280 x 720: about 69 degrees diagonal field of view
(f = 1070 px), principal point a few pixels off centre, the mild barrel distortion of a
plastic lens (k1 = -0.12, k2 = 0.03: about 40 px inwards at the image corners, up to 3.6 px
at the board's; a homography fitted to the board's exact dot centres is off by 0.5 px on
average, 1.8 px at worst, close to the paper's 0.677 / 1.911 px with its detection noise and
whole-pixel rounding)."""

PAPER_POSE = PlanePose(
    distance_mm=500.0, tilt_deg=3.0, tilt_axis_deg=35.0, roll_deg=0.8, look_at_mm=(135.0, 92.0)
)
"""500 mm above the board's middle, tilted 3 degrees, rolled 0.8 degrees: about 2.1 px/mm,
dots about 21 px across, the board's paper about 640 x 460 px of the 1280 x 720 image."""

PAPER_OBJECTS: tuple[SceneObject, ...] = (
    SceneObject("nut", (98.9, 155.9), angle_deg=12.0, size_mm=8.0),
    SceneObject("nut", (144.3, 138.2), angle_deg=41.0, size_mm=8.0),
    SceneObject("bolt", (33.1, 145.2), angle_deg=-75.0, size_mm=6.0, length_mm=30.0),
    SceneObject("nut", (85.4, 120.1), angle_deg=5.0, size_mm=8.0),
    SceneObject("bolt", (238.4, 128.7), angle_deg=100.0, size_mm=6.0, length_mm=30.0),
    SceneObject("nut", (189.2, 106.3), angle_deg=27.0, size_mm=8.0),
    SceneObject("nut", (132.8, 78.5), angle_deg=50.0, size_mm=8.0),
    SceneObject("bolt", (37.3, 72.0), angle_deg=20.0, size_mm=6.0, length_mm=30.0),
    SceneObject("nut", (109.8, 45.0), angle_deg=18.0, size_mm=8.0),
    SceneObject("nut", (165.7, 37.3), angle_deg=33.0, size_mm=8.0),
)
"""Three M6 x 30 bolts and seven M8 nuts at the paper's Table 5 positions (rounded to
0.1 mm), in board coordinates, inside the calibrated area and at least 5 mm apart."""

PAPER_EFFECTS: Mapping[str, float] = {
    "table_grey": 100.0,
    "paper_grey": 225.0,
    "ink_grey": 35.0,
    "metal_grey": 170.0,
    "blur_sigma_px": 0.8,
    "noise_sigma": 2.5,
    "lighting_gradient": 0.2,
    "lighting_angle_deg": 200.0,
    "vignette": 0.25,
}
"""Grey levels and image effects of the paper scene: a dark-grey bench, white paper, black
ink, bright steel; a lamp on the left (20 % gain gradient), a webcam's vignetting (25 % at
the corners), slight defocus (blur 0.8 px) and sensor noise (2.5 grey levels)."""


class PaperScene(NamedTuple):
    """The demo's pair of images: ``calibration`` (the board alone) and ``objects`` (the
    board removed, the objects in its place), same camera and pose."""

    calibration: RenderedScene
    objects: RenderedScene


def paper_scene(
    seed: int = 0,
    *,
    distortion: bool = True,
    objects: bool = True,
    color: bool = False,
    board: Board | str = "circles",
) -> PaperScene:
    """The demo's scene, modelled on the paper's setup; returns (calibration, objects).

    The paper's board (:data:`PAPER_BOARD`, dot 0 at the table origin, so board and table
    coordinates agree) seen by :data:`PAPER_CAMERA` (without its distortion if
    ``distortion=False``) from :data:`PAPER_POSE`, with :data:`PAPER_EFFECTS`. The objects
    image has the same camera, pose and effects, the board removed and
    :data:`PAPER_OBJECTS` on the table (none if ``objects=False``). The noise of the two
    images comes from two streams spawned from ``seed``.

    ``board``: another board in the paper board's place, by type (:data:`PAPER_BOARDS`:
    "circles", "chessboard", "charuco") or any board, its world origin at the table origin
    (board and table coordinates agree); the objects image is the same whatever the board.
    """
    board = paper_board(board)
    camera = PAPER_CAMERA
    if not distortion:
        camera = dataclasses.replace(camera, k1=0.0, k2=0.0)
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ImageError(f"seed must be a non-negative whole number, got {seed!r}")
    seeds = [int(s.generate_state(1)[0]) for s in np.random.SeedSequence(int(seed)).spawn(2)]

    def render(board: Board | None, things: Sequence[SceneObject], seed: int) -> RenderedScene:
        return render_paper_look(camera, PAPER_POSE, board, things, seed, color=color)

    calibration = render(board, (), seeds[0])
    scene = render(None, PAPER_OBJECTS if objects else (), seeds[1])
    return PaperScene(calibration, scene)


def paper_board(board: Board | str) -> Board:
    """A board given by type (:data:`PAPER_BOARDS`) or as itself; BoardError otherwise."""
    if isinstance(board, str):
        if board not in PAPER_BOARDS:
            raise BoardError(
                f"board must be one of {', '.join(PAPER_BOARDS)} or a board, got {board!r}"
            )
        return PAPER_BOARDS[board]
    if not is_board(board):
        raise BoardError(f"board must be a board or a board type, got {type(board).__name__}")
    return board


def random_paper_scene(
    seed: int,
    *,
    px_per_mm: float = 1.9,
    max_tilt_deg: float = 5.0,
    objects: Sequence[SceneObject] = (),
    board: Board | str = "circles",
) -> RenderedScene:
    """A random view of the paper's setup, for measuring accuracy over many scenes: the
    paper's board and camera (:data:`PAPER_CAMERA`, its lens distortion included) at the
    distance that gives ``px_per_mm`` at the board's centre, tilted up to ``max_tilt_deg``
    about a random axis, rolled up to 3 degrees, aimed within 10 mm of the board's centre,
    with :data:`PAPER_EFFECTS` (blur, noise, uneven lighting) and seeded noise. The same
    seed always gives the same scene. ``board``: another board in the paper board's place
    (as :func:`paper_scene`'s), the view aimed at its points' middle."""
    shown = paper_board(board)
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ImageError(f"seed must be a non-negative whole number, got {seed!r}")
    rng = np.random.default_rng(int(seed))
    scale = arguments.positive("px_per_mm", px_per_mm)
    tilt = arguments.real("max_tilt_deg", max_tilt_deg)
    if not 0.0 <= tilt <= 60.0:
        raise ArgumentError(f"max_tilt_deg must be 0 to 60, got {max_tilt_deg!r}")
    pose = random_board_pose(rng, PAPER_CAMERA.focal_px / scale, tilt, shown)
    return render_paper_look(PAPER_CAMERA, pose, shown, objects, int(rng.integers(0, 2**31)))


def random_board_pose(
    rng: np.random.Generator,
    distance_mm: float,
    max_tilt_deg: float,
    board: Board = PAPER_BOARD,
) -> PlanePose:
    """A random view of a board (the paper's unless told) from ``distance_mm``: tilted up to
    ``max_tilt_deg`` about a random axis, rolled up to 3 degrees, aimed within 10 mm of the
    middle of its points (the draws in that order, so a seed always gives the same view)."""
    pts = board.world_points()
    middle = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    if isinstance(board, CircleGridBoard) and board.layout != "asymmetric":
        middle = np.array([board.cols - 1, board.rows - 1]) * board.pitch / 2.0
    return PlanePose(
        distance_mm=float(distance_mm),
        tilt_deg=float(rng.uniform(0.0, max_tilt_deg)),
        tilt_axis_deg=float(rng.uniform(0.0, 360.0)),
        roll_deg=float(rng.uniform(-3.0, 3.0)),
        look_at_mm=(
            float(middle[0] + rng.uniform(-10.0, 10.0)),
            float(middle[1] + rng.uniform(-10.0, 10.0)),
        ),
    )


def render_paper_look(
    camera: CameraModel,
    pose: PlanePose,
    board: Board | None,
    objects: Sequence[SceneObject],
    seed: int,
    *,
    color: bool = False,
) -> RenderedScene:
    """render_scene with the paper scene's tones and effects (PAPER_EFFECTS): ``board=None``
    and parts for an image of the parts alone, as a production camera sees them."""
    e = PAPER_EFFECTS
    return render_scene(
        camera,
        pose,
        board=board,
        objects=objects,
        color=color,
        seed=seed,
        table_grey=e["table_grey"],
        paper_grey=e["paper_grey"],
        ink_grey=e["ink_grey"],
        metal_grey=e["metal_grey"],
        blur_sigma_px=e["blur_sigma_px"],
        noise_sigma=e["noise_sigma"],
        lighting_gradient=e["lighting_gradient"],
        lighting_angle_deg=e["lighting_angle_deg"],
        vignette=e["vignette"],
    )
