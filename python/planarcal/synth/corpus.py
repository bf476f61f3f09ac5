"""The board-detection corpus: :data:`BOARD_VARIANTS` names its circle-grid variants,
:data:`CHESSBOARD_VARIANTS` and :data:`CHARUCO_VARIANTS` those of the other board types
(:data:`VARIANTS_BY_KIND` all three), each a recipe (a shot: board, camera, tilt, effects,
what covers the board) that :func:`board_variant` frames, renders and returns with its exact
truth; :func:`board_variants` renders one kind's (or every kind's) variants.
"""

from __future__ import annotations

import dataclasses
import zlib
from collections.abc import Callable, Iterable, Mapping
from typing import NamedTuple, cast

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.errors import ArgumentError
from planarcal.synth.camera import CameraModel, PlanePose
from planarcal.synth.dots import _board_to_table
from planarcal.synth.effects import jpeg
from planarcal.synth.marks import _bar, _number, printed_marks
from planarcal.synth.objects import ObjectKind, SceneObject
from planarcal.synth.occluders import hand
from planarcal.synth.paper import PAPER_BOARD
from planarcal.synth.render import RenderedScene, render_scene
from planarcal.synth.shapes import _rotation_2d

F64 = NDArray[np.float64]


@dataclasses.dataclass(frozen=True, eq=False)
class BoardVariant:
    """One image of :func:`board_variants`' corpus and its truth.

    ``image``: uint8, grey or BGR, JPEG-compressed where ``jpeg_quality`` is set.
    ``truth_px``: (n_points, 2), each board point's exact projection (a dot's centre, an
    inner corner), in id order (``scene.points_px``). ``enlarged``: (n_points,) bool, the
    dots printed larger than the board's dots (an origin marker, fiducials; none on other
    boards). ``visible``: (n_points,) bool, the points a detector should find: in the image
    (a whole dot; a corner at least 3 px inside) and not hidden by an object or glare
    (``scene.points_visible``); all of them in every circle-grid variant. ``scene``:
    everything else (camera, pose, diameters, marks, objects, glare, effects); its
    ``image`` is before JPEG.
    """

    name: str
    description: str
    board: Board
    image: NDArray[np.uint8]
    truth_px: F64
    enlarged: NDArray[np.bool_]
    scene: RenderedScene
    jpeg_quality: int | None = None
    visible: NDArray[np.bool_] = dataclasses.field(default_factory=lambda: np.zeros(0, dtype=bool))


class _Shot(NamedTuple):
    """A corpus variant's recipe: the render_scene arguments less the pose, which
    _board_shot frames (see there), and the JPEG quality."""

    board: Board
    camera: CameraModel
    fill: float = 0.8
    tilt_deg: float = 0.0
    board_angle_deg: float = 0.0
    jpeg_quality: int | None = None
    options: Mapping[str, object] = {}
    aim: tuple[float, float] = (0.0, 0.0)  # the aim's offset from the middle, in sizes


def _board_shot(shot: _Shot, rng: np.random.Generator) -> tuple[RenderedScene, int | None]:
    """Render a corpus shot: the camera aimed at the board's middle (within 2 % of its
    size) from the distance at which the board's paper spans ``fill`` of the image
    (before tilt and lens), tilted about a random in-plane axis, rolled up to 4 degrees;
    noise seeded from rng."""
    board, camera = shot.board, shot.camera
    margin = float(cast("float", shot.options.get("paper_margin_mm", 15.0)))
    pts = board.world_points()
    if isinstance(board, CircleGridBoard):
        big = float(np.max(board.dot_diameters())) / 2.0 + margin
        lo, hi = pts.min(axis=0) - big, pts.max(axis=0) + big
    else:
        x0, y0, x1, y1 = board.ink().field
        lo, hi = np.array([x0, y0]) - margin, np.array([x1, y1]) + margin
    roll = float(rng.uniform(-4.0, 4.0))
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    seen = corners @ _rotation_2d(shot.board_angle_deg + roll).T
    span = np.ptp(seen, axis=0)
    distance = float(camera.focal_px) * max(
        span[0] / (shot.fill * camera.width), span[1] / (shot.fill * camera.height)
    )
    middle = 0.5 * (pts.min(axis=0) + pts.max(axis=0)) + rng.uniform(-0.02, 0.02, 2) * (hi - lo)
    if shot.aim != (0.0, 0.0):
        middle = middle + np.array(shot.aim) * (hi - lo)
    look = _board_to_table(middle[None, :], (0.0, 0.0), shot.board_angle_deg)[0]
    pose = PlanePose(
        distance_mm=distance,
        tilt_deg=shot.tilt_deg,
        tilt_axis_deg=float(rng.uniform(0.0, 360.0)),
        roll_deg=roll,
        look_at_mm=(float(look[0]), float(look[1])),
    )
    options = dict(shot.options)
    options.setdefault("supersample", 4)
    glare_at = options.pop("glare_at", None)
    if glare_at is not None:  # (point ids, radius px): glare centred on those points
        ids, radius = cast("tuple[tuple[int, ...], float]", glare_at)
        on = camera.project(_board_to_table(pts[list(ids)], (0.0, 0.0), shot.board_angle_deg), pose)
        options["glare"] = tuple((float(x), float(y), float(radius)) for x, y in on)
    scene = render_scene(
        camera,
        pose,
        board=board,
        board_angle_deg=shot.board_angle_deg,
        seed=int(rng.integers(0, 2**31)),
        **options,  # type: ignore[arg-type]
    )
    return scene, shot.jpeg_quality


def _ratio_shot(ratio: float) -> Callable[[np.random.Generator], _Shot]:
    """A dot diameter / pitch sweep's shot: boards, cameras and lighting vary with it."""
    setups = {
        0.15: (11, 8, 20.0, CameraModel(1280, 720, 1100.0, k1=-0.08, k2=0.01), 5.0),
        0.3: (9, 6, 25.0, CameraModel(1600, 1200, 1500.0, k1=-0.05), 12.0),
        0.5: (7, 5, 30.0, CameraModel(1280, 960, 1000.0, principal=(650.0, 470.0)), 0.0),
        0.66: (8, 11, 12.0, CameraModel(1024, 768, 900.0, k1=-0.1, k2=0.02), 15.0),
        0.85: (10, 7, 10.0, CameraModel(1920, 1080, 1600.0, k1=-0.06), 3.0),
    }
    cols, rows, pitch, camera, tilt = setups[ratio]

    def shot(rng: np.random.Generator) -> _Shot:
        board = CircleGridBoard(cols, rows, pitch, round(ratio * pitch, 6))
        effects = {"blur_sigma_px": 0.6 + ratio, "noise_sigma": 2.0 + 1.5 * ratio}
        return _Shot(board, camera, 0.8, tilt, options={**effects, "vignette": 0.2})

    return shot


def _shot_origin_as_wide_as_pitch(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(10, 10, 20.0, 10.0, origin_marker=True, marker_diameter=20.0)
    effects = {"blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(
        board, CameraModel(1280, 720, 1070.0, k1=-0.1, k2=0.02), 0.85, 6.0, 0.0, None, effects
    )


def _shot_fiducials_barrel(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(16, 14, 10.0, 2.0)
    fiducials = {r * 16 + c: 6.0 for r, c in ((3, 3), (3, 12), (10, 3), (10, 11))}
    camera = CameraModel(640, 480, 420.0, k1=-0.3, k2=0.08)
    effects = {
        "enlarged_dots": fiducials,
        "paper_margin_mm": 6.0,
        "vignette": 0.45,
        "blur_sigma_px": 0.6,
        "noise_sigma": 2.0,
        "supersample": 8,
    }
    return _Shot(board, camera, 0.92, 4.0, options=effects)


def _shot_printed_marks(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(6, 6, 20.0, 13.2)
    marks = printed_marks(board, ("numbers", "cell_numbers", "arrows"), int(rng.integers(0, 1000)))
    effects = {"marks": marks, "blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.1), 0.85, 8.0, options=effects)


def _shot_marks_rings_crosses_text(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(9, 7, 18.0, 7.2)
    marks = printed_marks(board, ("rings", "crosses", "text"), int(rng.integers(0, 1000)))
    effects = {"marks": marks, "blur_sigma_px": 0.7, "noise_sigma": 2.0, "lighting_gradient": 0.2}
    return _Shot(board, CameraModel(1280, 960, 1150.0, k1=-0.08), 0.8, 10.0, options=effects)


def _shot_webcam_320x240(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(7, 5, 25.0, 10.0)
    camera = CameraModel(320, 240, 280.0, k1=-0.18, k2=0.03)
    effects = {"blur_sigma_px": 0.9, "noise_sigma": 3.0, "vignette": 0.3, "supersample": 8}
    return _Shot(board, camera, 0.8, 5.0, jpeg_quality=75, options=effects)


def _shot_webcam_640x480(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(9, 6, 20.0, 10.0)
    camera = CameraModel(640, 480, 560.0, principal=(322.0, 236.0), k1=-0.12, k2=0.02)
    effects = {
        "color": True,
        "blur_sigma_px": 0.8,
        "noise_sigma": 2.5,
        "lighting_gradient": 0.25,
        "lighting_angle_deg": 200.0,
        "vignette": 0.3,
    }
    return _Shot(board, camera, 0.8, 7.0, jpeg_quality=75, options=effects)


def _shot_uhd(rng: np.random.Generator) -> _Shot:
    camera = CameraModel(3840, 2160, 3200.0)
    effects = {"blur_sigma_px": 1.5, "noise_sigma": 1.5}
    return _Shot(PAPER_BOARD, camera, 0.8, 3.0, options=effects)


def _shot_light_on_dark(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(12, 9, 15.0, 7.5)
    effects = {"light_on_dark": True, "table_grey": 140.0, "blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.1), 0.85, 5.0, options=effects)


def _shot_uneven_light(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(11, 8, 20.0, 10.0)
    effects = {
        "lighting_gradient": 1.2,
        "lighting_angle_deg": 30.0,
        "vignette": 0.5,
        "blur_sigma_px": 0.8,
        "noise_sigma": 2.0,
    }
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.05), 0.85, 5.0, options=effects)


def _shot_textured_table(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(8, 6, 20.0, 10.0)
    effects = {
        "table_texture": 25.0,
        "paper_texture": 4.0,
        "table_grey": 120.0,
        "blur_sigma_px": 0.7,
        "noise_sigma": 2.0,
    }
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.08), 0.45, 10.0, options=effects)


def _shot_tilt_35(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(11, 8, 20.0, 10.0)
    effects = {"blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(
        board, CameraModel(1280, 720, 1070.0, k1=-0.1, k2=0.02), 0.6, 35.0, options=effects
    )


def _shot_asymmetric_4x11(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(4, 11, 20.0, 15.0, layout="asymmetric")
    effects = {"blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.1), 0.85, 10.0, options=effects)


def _shot_asymmetric_large(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(9, 17, 8.0, 6.5, layout="asymmetric")
    camera = CameraModel(1920, 1080, 1500.0, k1=-0.08, k2=0.01)
    effects = {"blur_sigma_px": 0.9, "noise_sigma": 2.0, "vignette": 0.2}
    return _Shot(board, camera, 0.85, 8.0, board_angle_deg=90.0, options=effects)


def _shot_rotated_90(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(12, 7, 15.0, 7.0)
    effects = {"blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.1), 0.85, 5.0, 90.0, options=effects)


_VARIANTS: dict[str, tuple[Callable[[np.random.Generator], _Shot], str]] = {
    "ratio_0.15": (
        _ratio_shot(0.15),
        "11 x 8 dots, diameter 0.15 x pitch (3 mm, 20 mm apart), 1280 x 720, mild barrel, "
        "5 degrees tilt",
    ),
    "ratio_0.30": (
        _ratio_shot(0.3),
        "9 x 6 dots, diameter 0.3 x pitch, 1600 x 1200, 12 degrees tilt",
    ),
    "ratio_0.50": (
        _ratio_shot(0.5),
        "7 x 5 dots, diameter 0.5 x pitch (15 mm, 30 mm apart), 1280 x 960, off-centre "
        "principal point, no distortion",
    ),
    "ratio_0.66": (
        _ratio_shot(0.66),
        "8 x 11 dots (portrait), diameter 0.66 x pitch, 1024 x 768, 15 degrees tilt",
    ),
    "ratio_0.85": (
        _ratio_shot(0.85),
        "10 x 7 dots, diameter 0.85 x pitch (8.5 mm, 10 mm apart: 1.5 mm gaps), 1920 x 1080",
    ),
    "origin_as_wide_as_pitch": (
        _shot_origin_as_wide_as_pitch,
        "10 x 10 dots of 0.5 x pitch with an origin dot as wide as the pitch (it reaches "
        "halfway to its neighbours' edges)",
    ),
    "fiducials_barrel": (
        _shot_fiducials_barrel,
        "16 x 14 small dots (2 mm, about 4-6 px) with 4 enlarged fiducials (6 mm) inside the "
        "grid, 640 x 480 wide-angle lens with strong barrel distortion (k1 = -0.3), strong "
        "vignetting",
    ),
    "printed_marks": (
        _shot_printed_marks,
        "6 x 6 dots of 0.66 x pitch with printed row and column numbers, dot numbers "
        "between dots and axis arrows",
    ),
    "marks_rings_crosses_text": (
        _shot_marks_rings_crosses_text,
        "9 x 7 dots of 0.4 x pitch with rings around some dots, crosses between dots and a "
        "line of text below the grid",
    ),
    "webcam_320x240_jpeg": (
        _shot_webcam_320x240,
        "7 x 5 dots at 320 x 240 (dots about 10 px), webcam lens, blur, noise, JPEG q75",
    ),
    "webcam_640x480_jpeg": (
        _shot_webcam_640x480,
        "9 x 6 dots at 640 x 480 in colour (BGR), webcam lens, uneven light, JPEG q75",
    ),
    "uhd_3840x2160": (
        _shot_uhd,
        "the paper's 14 x 10 board at 3840 x 2160 (dots about 60 px), no distortion",
    ),
    "light_on_dark": (
        _shot_light_on_dark,
        "12 x 9 light dots on dark paper, on a mid-grey table",
    ),
    "uneven_light": (
        _shot_uneven_light,
        "11 x 8 dots under a strong lighting gradient (gain 1.6 to 0.4) and 50 % vignetting",
    ),
    "textured_table": (
        _shot_textured_table,
        "8 x 6 dots filling under half the image, on a wood-like textured table (25 grey "
        "levels), textured paper",
    ),
    "tilt_35": (
        _shot_tilt_35,
        "11 x 8 dots tilted 35 degrees about a random axis, webcam lens",
    ),
    "asymmetric_4x11": (
        _shot_asymmetric_4x11,
        "OpenCV's classic asymmetric grid: 4 x 11 dots, rows offset by half a spacing",
    ),
    "asymmetric_large": (
        _shot_asymmetric_large,
        "a 9 x 17 asymmetric grid of small dots turned 90 degrees, 1920 x 1080",
    ),
    "rotated_90": (
        _shot_rotated_90,
        "a 12 x 7 board turned 90 degrees on the table: its rows run down the image",
    ),
}

_MakeShot = Callable[[np.random.Generator], _Shot]


def _caption(board: Board, rng: np.random.Generator) -> tuple[SceneObject, ...]:
    """Printed marks for a chessboard's or a ChArUco board's page, in board mm: numbers along
    the margin above the pattern and a line of 'text' (bars of random lengths) below it."""
    x0, y0, x1, y1 = board.ink().field
    height = 0.4 * float(board.pitch)
    marks: list[SceneObject] = []
    for k, x in enumerate(np.linspace(x0 + height, x1 - height, 6)):
        marks += _number(int(rng.integers(0, 100)) + k, (float(x), y0 - 0.9 * height), height)
    x = x0
    while x < x1 - 2 * height:
        length = float(rng.uniform(0.4, 2.5)) * height
        y = y1 + 0.9 * height
        marks.append(_bar((x, y), (min(x + length, x1), y), 0.5 * height))
        x += length + 0.6 * height
    return tuple(marks)


def _clutter(
    rng: np.random.Generator, around: tuple[float, float, float, float]
) -> list[SceneObject]:
    """Parts lying on the table about a board (table mm, the board's box ``around``): bolts,
    nuts and washers off its paper."""
    x0, y0, x1, y1 = around
    out = []
    for k in range(8):
        side = k % 4
        t = float(rng.uniform(0.1, 0.9))
        gap = float(rng.uniform(12.0, 30.0))
        x = (x0 + t * (x1 - x0), x1 + gap, x0 + t * (x1 - x0), x0 - gap)[side]
        y = (y0 - gap, y0 + t * (y1 - y0), y1 + gap, y0 + t * (y1 - y0))[side]
        kinds: tuple[ObjectKind, ...] = ("bolt", "nut", "washer")
        kind = kinds[k % 3]
        grey = float(rng.uniform(120.0, 200.0))
        out.append(
            SceneObject(
                kind, (x, y), float(rng.uniform(0, 360)), float(rng.choice([5.0, 8.0])), grey=grey
            )
        )
    return out


def _page_box(board: Board, margin: float = 15.0) -> tuple[float, float, float, float]:
    x0, y0, x1, y1 = board.ink().field
    return (x0 - margin, y0 - margin, x1 + margin, y1 + margin)


def _chess_shot(
    board: Board,
    camera: CameraModel,
    fill: float,
    tilt: float,
    angle: float = 0.0,
    quality: int | None = None,
    aim: tuple[float, float] = (0.0, 0.0),
    **options: object,
) -> _Shot:
    effects: dict[str, object] = {"blur_sigma_px": 0.8, "noise_sigma": 2.0}
    effects.update(options)
    return _Shot(board, camera, fill, tilt, angle, quality, effects, aim)


_CHESSBOARD_SHOTS: dict[str, tuple[_MakeShot, str]] = {
    "chessboard_9x6_webcam": (
        lambda rng: _chess_shot(
            ChessboardBoard(9, 6, 25.0),
            CameraModel(1280, 720, 1070.0, k1=-0.12, k2=0.03),
            0.8,
            8.0,
            vignette=0.25,
            lighting_gradient=0.2,
        ),
        "OpenCV's tutorial chessboard, 9 x 6 inner corners of 25 mm, 1280 x 720 webcam lens",
    ),
    "chessboard_7x7_vga_jpeg": (
        lambda rng: _chess_shot(
            ChessboardBoard(7, 7, 20.0),
            CameraModel(640, 480, 560.0, k1=-0.15, k2=0.03),
            0.8,
            12.0,
            quality=75,
            color=True,
            blur_sigma_px=0.9,
            noise_sigma=2.5,
        ),
        "a square 7 x 7 chessboard at 640 x 480 in colour, webcam JPEG q75",
    ),
    "chessboard_marker_tilt_45": (
        lambda rng: _chess_shot(
            ChessboardBoard(11, 8, 15.0, origin_marker=True),
            CameraModel(1600, 1200, 1500.0, k1=-0.05),
            0.6,
            45.0,
        ),
        "an 11 x 8 chessboard with an origin marker, tilted 45 degrees, 1600 x 1200",
    ),
    "chessboard_small_squares_4k": (
        lambda rng: _chess_shot(
            ChessboardBoard(16, 11, 10.0),
            CameraModel(3840, 2160, 3200.0),
            0.8,
            5.0,
            blur_sigma_px=1.5,
            noise_sigma=1.5,
        ),
        "a 16 x 11 chessboard of 10 mm squares at 3840 x 2160",
    ),
    "chessboard_uneven_light_textured": (
        lambda rng: _chess_shot(
            ChessboardBoard(8, 5, 30.0),
            CameraModel(1280, 720, 1070.0, k1=-0.08),
            0.55,
            10.0,
            lighting_gradient=1.0,
            lighting_angle_deg=30.0,
            vignette=0.4,
            table_texture=20.0,
            paper_texture=4.0,
            table_grey=120.0,
        ),
        "an 8 x 5 chessboard under half the image, strong lighting gradient and vignetting, "
        "textured table and paper",
    ),
    "chessboard_portrait_rotated_barrel": (
        lambda rng: _chess_shot(
            ChessboardBoard(5, 8, 22.0),
            CameraModel(1280, 960, 700.0, k1=-0.3, k2=0.08),
            0.85,
            6.0,
            angle=90.0,
        ),
        "a 5 x 8 (portrait) chessboard turned 90 degrees, wide-angle lens with strong barrel",
    ),
    "chessboard_marks_clutter": (
        lambda rng: _chess_shot(
            ChessboardBoard(10, 7, 18.0),
            CameraModel(1920, 1080, 1600.0, k1=-0.06),
            0.6,
            15.0,
            marks=_caption(ChessboardBoard(10, 7, 18.0), rng),
            objects=_clutter(rng, _page_box(ChessboardBoard(10, 7, 18.0))),
        ),
        "a 10 x 7 chessboard with printed numbers and text in its margin and bolts, nuts and "
        "washers about it, 1920 x 1080",
    ),
    "chessboard_marker_hand": (
        lambda rng: _chess_shot(
            ChessboardBoard(9, 6, 25.0, origin_marker=True),
            CameraModel(1280, 720, 1070.0, k1=-0.1),
            0.8,
            10.0,
            objects=hand((190.0, 130.0), -60.0, 80.0, 150.0),
        ),
        "a 9 x 6 chessboard with an origin marker, a hand over its right part (partial view)",
    ),
}

_CHARUCO_SHOTS: dict[str, tuple[_MakeShot, str]] = {
    "charuco_7x5_webcam": (
        lambda rng: _chess_shot(
            CharucoBoard(7, 5, 30.0, 22.0, "DICT_5X5_100"),
            CameraModel(1280, 720, 1070.0, k1=-0.12, k2=0.03),
            0.8,
            8.0,
            vignette=0.25,
        ),
        "a 7 x 5 ChArUco board (30 mm squares, 22 mm DICT_5X5_100 markers), 1280 x 720 webcam",
    ),
    "charuco_legacy_6x6": (
        lambda rng: _chess_shot(
            CharucoBoard(6, 6, 25.0, 18.0, "DICT_4X4_50", legacy=True),
            CameraModel(1280, 960, 1000.0, k1=-0.05),
            0.8,
            15.0,
        ),
        "a 6 x 6 ChArUco board in OpenCV's layout before 4.6 (an even number of rows)",
    ),
    "charuco_12x9_1080p_tilt": (
        lambda rng: _chess_shot(
            CharucoBoard(12, 9, 20.0, 15.0, "DICT_6X6_250"),
            CameraModel(1920, 1080, 1500.0, k1=-0.06, k2=0.01),
            0.8,
            30.0,
        ),
        "a 12 x 9 ChArUco board of DICT_6X6_250 markers, tilted 30 degrees, 1920 x 1080",
    ),
    "charuco_apriltag_vga_jpeg": (
        lambda rng: _chess_shot(
            CharucoBoard(5, 7, 35.0, 26.0, "DICT_APRILTAG_36h11"),
            CameraModel(640, 480, 560.0, k1=-0.15, k2=0.03),
            0.85,
            8.0,
            quality=80,
            blur_sigma_px=0.9,
            noise_sigma=2.5,
        ),
        "a 5 x 7 ChArUco board of AprilTag 36h11 markers at 640 x 480, JPEG q80",
    ),
    "charuco_4k_small_markers": (
        lambda rng: _chess_shot(
            CharucoBoard(14, 10, 15.0, 11.0, "DICT_4X4_100"),
            CameraModel(3840, 2160, 3000.0),
            0.75,
            10.0,
            blur_sigma_px=1.4,
            noise_sigma=1.5,
        ),
        "a 14 x 10 ChArUco board of 15 mm squares at 3840 x 2160",
    ),
    "charuco_marks_clutter_light": (
        lambda rng: _chess_shot(
            CharucoBoard(8, 6, 25.0, 18.75, "DICT_5X5_100"),
            CameraModel(1280, 960, 1100.0, k1=-0.1),
            0.6,
            12.0,
            marks=_caption(CharucoBoard(8, 6, 25.0, 18.75, "DICT_5X5_100"), rng),
            objects=_clutter(rng, _page_box(CharucoBoard(8, 6, 25.0, 18.75, "DICT_5X5_100"))),
            lighting_gradient=0.8,
            lighting_angle_deg=200.0,
            table_texture=15.0,
        ),
        "an 8 x 6 ChArUco board with printed numbers and text, parts about it, uneven light, "
        "textured table",
    ),
    "charuco_cut_off": (
        lambda rng: _chess_shot(
            CharucoBoard(9, 6, 25.0, 18.0, "DICT_5X5_100"),
            CameraModel(1280, 720, 1070.0, k1=-0.1),
            1.3,
            10.0,
            aim=(0.3, 0.2),
        ),
        "a 9 x 6 ChArUco board seen close up, its left and top parts outside the image",
    ),
    "charuco_hand_glare": (
        lambda rng: _chess_shot(
            CharucoBoard(7, 5, 30.0, 22.0, "DICT_5X5_100"),
            CameraModel(1280, 720, 1070.0, k1=-0.1),
            0.8,
            8.0,
            objects=hand((60.0, 150.0), -80.0, 85.0, 140.0),
            glare=((830.0, 250.0, 35.0),),
        ),
        "a 7 x 5 ChArUco board, a hand over its lower left part and glare on its right",
    ),
}


def _ucl_plate() -> CircleGridBoard:
    """A plate like the shared UCL one: 16 x 14 dots of 2 mm, 5 mm apart."""
    return CircleGridBoard(16, 14, 5.0, 2.0)


_UCL_FIDUCIALS = {r * 16 + c: 3.5 for r, c in ((3, 3), (3, 12), (10, 3), (10, 11))}

_CIRCLE_PARTIAL_SHOTS: dict[str, tuple[_MakeShot, str]] = {
    "fiducial_plate_row_cut": (
        lambda rng: _Shot(
            _ucl_plate(),
            CameraModel(1920, 1080, 1300.0, k1=-0.25, k2=0.06),
            1.15,
            6.0,
            options={
                "enlarged_dots": _UCL_FIDUCIALS,
                "paper_margin_mm": 4.0,
                "vignette": 0.4,
                "blur_sigma_px": 0.8,
                "noise_sigma": 2.0,
                "supersample": 8,
            },
            aim=(0.0, -0.12),
        ),
        "a 16 x 14 plate of 2 mm dots 5 mm apart with 4 enlarged fiducials (like the shared "
        "UCL plate), strong barrel, its last row cut off by the image's edge",
    ),
    "fiducial_plate_glare": (
        lambda rng: _Shot(
            _ucl_plate(),
            CameraModel(1920, 1080, 1300.0, k1=-0.25, k2=0.06),
            0.9,
            8.0,
            options={
                "enlarged_dots": _UCL_FIDUCIALS,
                "paper_margin_mm": 4.0,
                "blur_sigma_px": 0.8,
                "noise_sigma": 2.0,
                "supersample": 8,
                "glare_at": ((7 * 16 + 8,), 14.0),
            },
        ),
        "the fiducial plate whole, a glare spot over one dot inside the grid",
    ),
    "origin_marker_hand": (
        lambda rng: _Shot(
            CircleGridBoard(10, 8, 20.0, 10.0, origin_marker=True),
            CameraModel(1280, 720, 1070.0, k1=-0.1),
            0.85,
            8.0,
            options={
                "objects": hand((170.0, 150.0), -50.0, 80.0, 150.0),
                "blur_sigma_px": 0.8,
                "noise_sigma": 2.0,
            },
        ),
        "a 10 x 8 grid with an origin marker, a hand over its far corner",
    ),
}

BOARD_VARIANTS: Mapping[str, str] = {name: text for name, (_, text) in _VARIANTS.items()}
"""The corpus' circle-grid variants, by name, and what each shows (see
:func:`board_variants`)."""

CIRCLE_PARTIAL_VARIANTS: Mapping[str, str] = {n: t for n, (_, t) in _CIRCLE_PARTIAL_SHOTS.items()}
"""The corpus' partial views of circle grids (part of the board outside the image, under a
hand or in glare), apart from :data:`BOARD_VARIANTS`, whose every dot is in view."""

CHESSBOARD_VARIANTS: Mapping[str, str] = {n: t for n, (_, t) in _CHESSBOARD_SHOTS.items()}
"""The corpus' chessboard variants, by name, and what each shows."""

CHARUCO_VARIANTS: Mapping[str, str] = {n: t for n, (_, t) in _CHARUCO_SHOTS.items()}
"""The corpus' ChArUco variants, by name, and what each shows."""

VARIANTS_BY_KIND: Mapping[str, Mapping[str, str]] = {
    "circles": BOARD_VARIANTS,
    "circles_partial": CIRCLE_PARTIAL_VARIANTS,
    "chessboard": CHESSBOARD_VARIANTS,
    "charuco": CHARUCO_VARIANTS,
}
"""The variants by kind (a board's ``kind``, and "circles_partial") -> name -> description."""

_ALL_SHOTS: dict[str, tuple[_MakeShot, str]] = {
    **_VARIANTS,
    **_CIRCLE_PARTIAL_SHOTS,
    **_CHESSBOARD_SHOTS,
    **_CHARUCO_SHOTS,
}


def board_variant(name: str, seed: int = 0) -> BoardVariant:
    """One variant of :func:`board_variants`' corpus (of any board type), by name."""
    if name not in _ALL_SHOTS:
        raise ArgumentError(f"no board variant {name!r}; the variants: {', '.join(_ALL_SHOTS)}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ArgumentError(f"seed must be a non-negative whole number, got {seed!r}")
    # Each variant draws from its own stream, so a subset renders as in the whole corpus.
    rng = np.random.default_rng([int(seed), zlib.crc32(name.encode())])
    make, description = _ALL_SHOTS[name]
    shot = make(rng)
    scene, quality = _board_shot(shot, rng)
    image = scene.image if quality is None else jpeg(scene.image, quality)
    board = shot.board
    if isinstance(board, CircleGridBoard):
        enlarged = np.asarray(scene.dot_diameters_mm > board.dots_mm())
        visible = scene.points_visible()
    else:
        enlarged = np.zeros(board.n_points, dtype=bool)
        visible = scene.points_visible(margin_px=3.0)
    return BoardVariant(
        name=name,
        description=description,
        board=board,
        image=image,
        truth_px=scene.dot_centres_px.copy(),
        enlarged=enlarged,
        scene=scene,
        jpeg_quality=quality,
        visible=visible,
    )


def board_variants(
    seed: int = 0, names: Iterable[str] | None = None, kind: str = "circles"
) -> list[BoardVariant]:
    """A corpus of boards to test and benchmark board detection on: every variant of
    ``kind`` (:data:`VARIANTS_BY_KIND`: "circles", the default, for :data:`BOARD_VARIANTS`,
    "circles_partial", "chessboard", "charuco", or "all") or those in ``names`` (of any
    kind, in that order), each rendered with its exact truth. The same seed always gives
    the same corpus.

    Circle grids sweep the dot diameter / pitch ratio (0.15 to 0.85), both layouts, origin
    markers and fiducials, printed marks, resolutions from 320 x 240 to 3840 x 2160, webcam
    JPEG, lens distortion, tilt, lighting, light-on-dark boards and textured tables; every
    dot lies wholly inside its image (about 10 s on two cores for all of them, 4 s of that
    the 4K image); "circles_partial" are circle grids in part (a fiducial plate like the
    shared UCL one with a row cut off or a dot in glare, a hand over a marker board).
    Chessboards and ChArUco boards sweep proportions (5 x 8 to 16 x 11 inner
    corners, 5 x 7 to 14 x 10 squares), square sizes (10 to 35 mm), dictionaries (4x4 to
    6x6, AprilTag, both ChArUco layouts), 640 x 480 to 3840 x 2160, lenses from none to
    strong barrel, tilts to 45 degrees, uneven light, textures, printed marks and parts on
    the table; some are partial views (a hand, glare, part of the board outside the image:
    ``visible`` says which points remain).
    """
    if names is not None:
        chosen = [names] if isinstance(names, str) else list(names)
    elif kind == "all":
        chosen = list(_ALL_SHOTS)
    elif kind in VARIANTS_BY_KIND:
        chosen = list(VARIANTS_BY_KIND[kind])
    else:
        raise ArgumentError(
            f"kind must be one of {', '.join([*VARIANTS_BY_KIND, 'all'])}, got {kind!r}"
        )
    return [board_variant(name, seed) for name in chosen]
