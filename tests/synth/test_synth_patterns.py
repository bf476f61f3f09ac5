"""Chessboards and ChArUco boards in the renderer (planarcal.synth.pattern): pixels against a
brute-force reference, X-junctions without bias, no seam where rectangles share an edge,
OpenCV's own detectors reading the renders with the truth's ids, partial views (pose,
hand, glare) and the time a render takes."""

from __future__ import annotations

import time

import cv2
import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.board_ink import BoardInk
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.errors import BoardError, ImageError
from planarcal.synth import CameraModel, PlanePose, render_scene
from planarcal.synth.pattern import _Pattern
from planarcal.synth.render import _radiance
from planarcal.synth.scene import _Scene

PAPER, INK, TABLE = 225.0, 35.0, 100.0
LUT = np.array([[TABLE], [PAPER], [INK], [0.0]])


def middle(board: ChessboardBoard | CharucoBoard) -> tuple[float, float]:
    pts = board.world_points()
    m = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    return (float(m[0]), float(m[1]))


def radiance(
    board: ChessboardBoard | CharucoBoard,
    camera: CameraModel,
    pose: PlanePose,
    angle: float = 0.0,
) -> tuple[np.ndarray, _Scene]:
    """The renderer's float image (before rounding) of the board alone, and its scene."""
    scene = _Scene(board, (0.0, 0.0), angle, 15.0, (), pose.camera_centre_mm())
    image, _, _ = _radiance(camera, pose, scene, LUT, 8)
    return image[:, :, 0].astype(np.float64), scene


def brute_force(
    scene: _Scene, camera: CameraModel, pose: PlanePose, ys: np.ndarray, xs: np.ndarray
) -> np.ndarray:
    """Each pixel's mean over 32 x 32 point samples, each traced to the plane on its own."""
    m = 32
    o = (np.arange(m) + 0.5) / m - 0.5
    out = np.zeros((len(ys), len(xs)))
    f = camera.focal_px
    for row, y in enumerate(ys):
        u = (xs[:, None, None] + o[None, None, :] - camera.cx) / f
        v = (y + o[None, :, None] - camera.cy) / f
        u, v = (np.ascontiguousarray(a) for a in np.broadcast_arrays(u, v))
        px, py, ok = camera._rays_to_plane(u, v, pose)
        assert ok.all()
        material, _ = scene.classify(px.ravel(), py.ravel(), np.zeros(px.size))
        out[row] = LUT[material, 0].reshape(len(xs), -1).mean(axis=1)
    return out


@pytest.mark.parametrize(
    ("board", "window"),
    [
        # A chessboard's X-junctions and its origin marker's white and black dots.
        (ChessboardBoard(9, 6, 25.0, origin_marker=True), (290, 330, 560, 620)),
        # A ChArUco board's markers: cells sharing edges, corners inside the marker.
        (CharucoBoard(7, 5, 30.0, 22.0, "DICT_4X4_50"), (300, 340, 500, 560)),
    ],
    ids=["chessboard-marker", "charuco"],
)
def test_pixels_match_a_brute_force_reference(
    board: ChessboardBoard | CharucoBoard, window: tuple[int, int, int, int]
) -> None:
    camera = CameraModel(1280, 720, 1070.0, k1=-0.2, k2=0.05)
    pose = PlanePose(
        450.0, tilt_deg=25.0, tilt_axis_deg=40.0, roll_deg=7.0, look_at_mm=middle(board)
    )
    image, scene = radiance(board, camera, pose, angle=13.0)
    y0, y1, x0, x1 = window
    reference = brute_force(scene, camera, pose, np.arange(y0, y1), np.arange(x0, x1))
    error = np.abs(image[y0:y1, x0:x1] - reference) / (PAPER - INK)
    crossed = (reference > INK + 1) & (reference < PAPER - 1)
    assert crossed.sum() > 100  # the window holds edges
    # The reference's own sampling (1/32 of a pixel across an edge) bounds the agreement.
    assert error.max() < 0.003
    assert error.mean() < 2e-4


def edge_points(image: np.ndarray, corner: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Sub-pixel points of the straight edge through ``corner`` along ``direction``, 6 to 21
    px from it on both sides: in each pixel row (column) across the edge, the light area of
    the row's pixels is the distance from the edge, where the edge crosses the row's middle,
    to the row's light end (exact for a straight edge and exact pixel areas)."""
    d = direction / np.linalg.norm(direction)
    steep = abs(d[1]) > abs(d[0])
    light = (image - INK) / (PAPER - INK)
    out = []
    for sign in (-1.0, 1.0):
        for t in range(6, 22):
            q = corner + sign * t * d
            if steep:
                y = round(q[1])
                centre = corner[0] + (y - corner[1]) * d[0] / d[1]
                lo = round(centre) - 6
                values = light[y, lo : lo + 13]
                area = values.sum()
                x = lo + 12.5 - area if values[-1] > values[0] else lo - 0.5 + area
                out.append((x, y))
            else:
                x = round(q[0])
                centre = corner[1] + (x - corner[0]) * d[1] / d[0]
                lo = round(centre) - 6
                values = light[lo : lo + 13, x]
                area = values.sum()
                y = lo + 12.5 - area if values[-1] > values[0] else lo - 0.5 + area
                out.append((x, y))
    return np.array(out, dtype=np.float64)


def corner_by_lines(image: np.ndarray, truth: np.ndarray, cols: int, k: int) -> np.ndarray:
    """Corner k where the straight lines fitted to its two edges cross."""
    normals, offsets = [], []
    for neighbour in (k + 1, k + cols):
        pts = edge_points(image, truth[k], truth[neighbour] - truth[k])
        centre = pts.mean(axis=0)
        normal = np.linalg.svd(pts - centre)[2][1]
        normals.append(normal)
        offsets.append(normal @ centre)
    return np.asarray(np.linalg.solve(np.array(normals), np.array(offsets)), np.float64)


@pytest.mark.parametrize(
    "pose",
    [
        PlanePose(380.0, look_at_mm=(100.0, 62.5)),
        PlanePose(380.0, tilt_deg=30.0, tilt_axis_deg=40.0, roll_deg=7.0, look_at_mm=(100.0, 62.5)),
        PlanePose(
            380.0, tilt_deg=45.0, tilt_axis_deg=120.0, roll_deg=-5.0, look_at_mm=(100.0, 62.5)
        ),
    ],
    ids=["square-on", "tilt-30", "tilt-45"],
)
def test_x_junctions_render_without_bias(pose: PlanePose) -> None:
    board = ChessboardBoard(9, 6, 25.0)
    scene = render_scene(CameraModel(), pose, board=board)  # sharp, noise-free, 8 bits
    truth = scene.points_px
    image = scene.image.astype(np.float64)
    errors = [
        np.linalg.norm(corner_by_lines(image, truth, board.cols, k) - truth[k])
        for k in (10, 12, 14, 20, 22, 28, 30, 32, 38, 40, 42)
    ]
    # uint8 rounding alone: the corner's position is unbiased to 0.005 px.
    assert max(errors) < 0.005, errors


def test_rectangles_sharing_an_edge_leave_no_seam() -> None:
    # One black square, and the same square as five rectangles sharing edges (a marker's
    # cells): every cell, however it lies across the shared edges, is covered alike.
    whole = BoardInk(np.array([[0.0, 0.0, 10.0, 10.0]]), np.zeros((0, 4)), (0.0, 0.0, 10.0, 10.0))
    pieces = BoardInk(
        np.array(
            [
                [0.0, 0.0, 3.0, 4.0],
                [3.0, 0.0, 10.0, 4.0],
                [0.0, 4.0, 10.0, 7.5],
                [0.0, 7.5, 6.0, 10.0],
                [6.0, 7.5, 10.0, 10.0],
            ]
        ),
        np.zeros((0, 4)),
        (0.0, 0.0, 10.0, 10.0),
    )
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-1.0, 11.0, (2, 20000))
    x[:5000] = rng.choice([3.0, 6.0], 5000) + rng.uniform(-0.05, 0.05, 5000)
    y[5000:10000] = rng.choice([4.0, 7.5], 5000) + rng.uniform(-0.05, 0.05, 5000)
    cell = tuple(rng.uniform(-0.12, 0.12, (4, 20000)))
    a = _Pattern(whole, 2.0).coverage(x, y, cell)
    b = _Pattern(pieces, 2.0).coverage(x, y, cell)
    np.testing.assert_allclose(b, a, atol=1e-12)
    np.testing.assert_allclose(a.sum(axis=1), 1.0, atol=1e-12)
    inside = (np.abs(x - 5.0) < 4.5) & (np.abs(y - 5.0) < 4.5)
    np.testing.assert_allclose(b[inside, 2], 1.0, atol=1e-12)  # all ink, no seam
    # Two rectangles meeting where rounding puts one's end a hair past the other's start
    # (0.1 + 0.2 mm and 0.3 mm) are one line: no sliver of paper or double ink.
    rounded = BoardInk(
        np.array([[0.0, 0.0, 0.1 + 0.2, 1.0], [0.3, 0.0, 1.0, 1.0]]),
        np.zeros((0, 4)),
        (0.0, 0.0, 1.0, 1.0),
    )
    unit = BoardInk(np.array([[0.0, 0.0, 1.0, 1.0]]), np.zeros((0, 4)), (0.0, 0.0, 1.0, 1.0))
    u, v = rng.uniform(-0.2, 1.2, (2, 5000))
    small = tuple(0.05 * c[:5000] for c in cell)
    np.testing.assert_allclose(
        _Pattern(rounded, 0.5).coverage(u, v, small),
        _Pattern(unit, 0.5).coverage(u, v, small),
        atol=1e-12,
    )
    assert len(_Pattern(rounded, 0.5).xs) == 5  # the paper, the ink and the line between


def test_a_marker_border_is_solid_ink() -> None:
    # A ChArUco marker's black border is made of one run per row of cells: seen square on
    # with its cells 6.7 px wide, the pixels wholly inside the border are exactly the ink.
    board = CharucoBoard(3, 3, 40.0, 30.0, "DICT_4X4_50")
    camera = CameraModel(640, 480, 500.0)
    scene = render_scene(camera, PlanePose(375.0, look_at_mm=(60.0, 60.0)), board=board)
    corners = board.marker_corners()[0]
    px = scene.project(corners.reshape(-1, 2))
    x0, y0 = px.min(axis=0)
    cell = (px[:, 0].max() - x0) / 6.0  # 4 x 4 bits and the border
    left = scene.image[int(np.ceil(y0)) + 1 : int(y0 + 6 * cell) - 1, int(np.ceil(x0)) + 1]
    assert cell > 6.0
    assert left.size > 30 and (left == INK).all()


def test_charuco_renders_read_by_opencv_with_the_truths_ids() -> None:
    for board in (
        CharucoBoard(5, 6, 30.0, 22.0, "DICT_5X5_100", legacy=False),
        CharucoBoard(5, 6, 30.0, 22.0, "DICT_5X5_100", legacy=True),
        CharucoBoard(9, 7, 20.0, 15.0, "DICT_6X6_250"),
    ):
        pose = PlanePose(
            400.0, tilt_deg=20.0, tilt_axis_deg=70.0, roll_deg=4.0, look_at_mm=middle(board)
        )
        scene = render_scene(CameraModel(k1=-0.05), pose, board=board, blur_sigma_px=0.6)
        detector = cv2.aruco.CharucoDetector(board.opencv_board(board.legacy))
        corners, ids, _, _ = detector.detectBoard(scene.image)
        assert ids is not None and len(ids) == board.n_points, board.describe()
        ids = ids.ravel()
        error = np.linalg.norm(corners.reshape(-1, 2) - scene.points_px[ids], axis=1)
        assert error.max() < 0.2, board.describe()


def test_chessboard_renders_read_by_opencv_in_the_truths_order() -> None:
    board = ChessboardBoard(9, 6, 25.0, origin_marker=True)
    pose = PlanePose(
        400.0, tilt_deg=25.0, tilt_axis_deg=200.0, roll_deg=-6.0, look_at_mm=middle(board)
    )
    scene = render_scene(
        CameraModel(k1=-0.08), pose, board=board, blur_sigma_px=0.8, noise_sigma=1.0
    )
    found, corners = cv2.findChessboardCornersSB(scene.image, (9, 6), flags=cv2.CALIB_CB_ACCURACY)
    assert found
    corners = corners.reshape(-1, 2)
    truth = scene.points_px
    if np.linalg.norm(corners[0] - truth[0]) > np.linalg.norm(corners[0] - truth[-1]):
        corners = corners[::-1]  # a plain chessboard reads either way round
    assert np.linalg.norm(corners - truth, axis=1).max() < 0.15


def test_a_chessboard_is_centred_and_light_on_dark_inverts_it() -> None:
    board = ChessboardBoard(7, 5, 20.0)
    dark = render_scene(board=board, light_on_dark=True)
    light = render_scene(board=board)
    centre = light.points_px.mean(axis=0)
    np.testing.assert_allclose(centre, [639.5, 359.5], atol=1.0)  # the default pose
    # Square (0, 0), the top-left one, is black; its middle inverted on dark paper.
    x, y = np.rint(light.project([[-10.0, -10.0]])[0]).astype(int)
    assert light.image[y, x] == INK and dark.image[y, x] == PAPER


def test_partial_view_by_pose() -> None:
    board = CharucoBoard(7, 5, 30.0, 22.0, "DICT_5X5_100")
    # Aimed near the board's left edge from close by: its right part is outside the image.
    pose = PlanePose(250.0, tilt_deg=10.0, tilt_axis_deg=90.0, look_at_mm=(10.0, 75.0))
    scene = render_scene(board=board, pose=pose)
    inside = scene.points_in_view()
    px = scene.points_px
    assert 0 < inside.sum() < board.n_points
    expected = (px[:, 0] >= -0.5) & (px[:, 0] <= 1279.5) & (px[:, 1] >= -0.5) & (px[:, 1] <= 719.5)
    np.testing.assert_array_equal(inside, expected)
    np.testing.assert_array_equal(scene.dots_in_view(), inside)
    assert scene.points_in_view(margin_px=200.0).sum() < inside.sum()


def test_a_hand_hides_the_points_under_it() -> None:
    board = ChessboardBoard(9, 6, 25.0)
    hand = synth.hand((170.0, 100.0), angle_deg=-60.0, size_mm=80.0, grey=150.0)
    scene = render_scene(board=board, objects=hand)
    hidden = scene.points_hidden()
    assert 3 < hidden.sum() < board.n_points - 10
    px = np.rint(scene.points_px).astype(int)
    values = scene.image[px[:, 1], px[:, 0]]
    # A hidden point's pixel shows the hand or is next to it; a visible one shows the board.
    assert (values[hidden] == 150).mean() > 0.6
    assert not (values[~hidden] == 150).any()
    assert scene.points_visible().sum() == board.n_points - hidden.sum()
    # A larger clearance hides more.
    assert scene.points_hidden(clearance_mm=20.0).sum() > hidden.sum()


def test_glare_saturates_and_hides_points() -> None:
    board = CharucoBoard(7, 5, 30.0, 22.0, "DICT_5X5_100")
    plain = render_scene(board=board)
    k = 9
    x, y = plain.points_px[k]
    scene = render_scene(board=board, glare=[(x, y, 20.0)], noise_sigma=2.0)
    near = np.hypot(*np.mgrid[-40:41, -40:41][::-1] * 1.0) < 19.0
    patch = scene.image[round(y) - 40 : round(y) + 41, round(x) - 40 : round(x) + 41]
    assert (patch[near] == 255).all()  # the ink too
    hidden = scene.points_hidden()
    assert hidden[k] and hidden.sum() == 1
    assert not plain.points_hidden().any()


def test_bad_arguments_name_the_problem() -> None:
    board = ChessboardBoard(9, 6, 25.0)
    with pytest.raises(BoardError, match="enlarged_dots applies to circle grids"):
        render_scene(board=board, enlarged_dots={3: 10.0})
    with pytest.raises(BoardError, match="board must be"):
        render_scene(board="chessboard")  # type: ignore[arg-type]
    with pytest.raises(ImageError, match="glare"):
        render_scene(board=board, glare=[(1.0, 2.0)])  # type: ignore[list-item]
    with pytest.raises(ImageError, match="radius must be > 0"):
        render_scene(board=board, glare=[(1.0, 2.0, 0.0)])
    with pytest.raises(ImageError, match="glare"):
        render_scene(board=board, glare=3)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="size_mm"):
        synth.hand((0.0, 0.0), size_mm=-1.0)


@pytest.mark.parametrize(
    "board",
    [ChessboardBoard(9, 6, 25.0), CharucoBoard(7, 5, 30.0, 22.0, "DICT_5X5_100")],
    ids=["chessboard-9x6", "charuco-7x5"],
)
def test_a_720p_render_takes_a_few_seconds(board: ChessboardBoard | CharucoBoard) -> None:
    # The board filling most of a webcam's view through its lens, blurred and noisy.
    pose = PlanePose(
        420.0, tilt_deg=20.0, tilt_axis_deg=30.0, roll_deg=5.0, look_at_mm=middle(board)
    )
    start = time.process_time()  # this process's CPU time: the machine is shared
    render_scene(synth.PAPER_CAMERA, pose, board=board, blur_sigma_px=0.8, noise_sigma=2.0)
    assert time.process_time() - start < 4.0


# ----------------------------------------------------------------------------- the corpus

SMALL_VARIANTS = [
    name
    for kind in ("chessboard", "charuco")
    for name in synth.VARIANTS_BY_KIND[kind]
    if "4k" not in name  # the 4K renders take a few seconds each: one test below
]


@pytest.mark.parametrize("name", SMALL_VARIANTS)
def test_chessboard_and_charuco_variants_hold_their_truth(name: str) -> None:
    """Each variant's truth is its scene's, its visible points are inside the image and
    unhidden, and at every visible corner the image is a saddle: of the four squares about
    it, those across from each other are alike and those beside each other differ."""
    v = synth.board_variant(name)
    assert v.board.kind in ("chessboard", "charuco")
    np.testing.assert_array_equal(v.truth_px, v.scene.points_px)
    assert v.enlarged.shape == v.visible.shape == (v.board.n_points,)
    assert not v.enlarged.any()
    assert v.visible.sum() >= 8
    partial = "hand" in name or "cut_off" in name or "glare" in name
    assert v.visible.all() != partial, name
    grey = (v.image if v.image.ndim == 2 else v.image.mean(axis=2)).astype(np.float64)
    pts = v.board.world_points()
    step = 0.25 * float(v.board.pitch)
    if isinstance(v.board, CharucoBoard):  # within the white margin about the markers
        step = 0.25 * (float(v.board.square) - float(v.board.marker))
    clear = v.visible.copy()
    for x, y, r in v.scene.glare:  # visible near glare, but brightened unevenly
        clear &= np.hypot(*(v.truth_px - [x, y]).T) > 2.5 * r
    for k in np.flatnonzero(clear):
        quads = pts[k] + step * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
        at = np.rint(v.scene.project(_to_table(v, quads))).astype(int)
        a, b, c, d = (grey[y, x] for x, y in at)
        contrast = abs(a + c - b - d) / 2.0
        assert contrast > 40.0, (name, k)
        assert abs(a - c) < 0.5 * contrast and abs(b - d) < 0.5 * contrast, (name, k)


def _to_table(v: synth.BoardVariant, board_mm: np.ndarray) -> np.ndarray:
    a = np.radians(v.scene.board_angle_deg)
    turn = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return np.asarray(board_mm @ turn.T + np.array(v.scene.board_origin_mm), np.float64)


def test_partial_circle_grids_say_which_dots_remain() -> None:
    cut = synth.board_variant("fiducial_plate_row_cut")
    rows = cut.visible.reshape(14, 16)
    assert rows[:13].all() and not rows[13].any()  # the last row is cut off
    assert cut.enlarged.sum() == 4 and cut.visible[cut.enlarged].all()
    glare = synth.board_variant("fiducial_plate_glare")
    assert np.flatnonzero(~glare.visible).tolist() == [7 * 16 + 8]
    x, y = np.rint(glare.truth_px[7 * 16 + 8]).astype(int)
    assert glare.image[y, x] == 255  # the dot is lost in the glare
    hand = synth.board_variant("origin_marker_hand")
    hidden = np.flatnonzero(~hand.visible)
    assert 5 < len(hidden) < 30
    rows, cols = np.divmod(hidden, 10)
    assert rows.min() >= 3 and cols.min() >= 5  # the far corner, never the origin
    for v in (cut, glare, hand):  # every visible dot shows dark ink at its centre
        px = np.rint(v.truth_px[v.visible]).astype(int)
        assert (v.image[px[:, 1], px[:, 0]] < 120).all(), v.name


def test_the_corpus_covers_the_board_types() -> None:
    assert set(synth.VARIANTS_BY_KIND) == {"circles", "circles_partial", "chessboard", "charuco"}
    assert synth.VARIANTS_BY_KIND["circles"] is synth.BOARD_VARIANTS
    names = [n for kind in synth.VARIANTS_BY_KIND.values() for n in kind]
    assert len(names) == len(set(names))
    big = synth.board_variant("charuco_4k_small_markers")
    assert big.image.shape == (2160, 3840) and big.visible.all()
    circles = synth.board_variants(names=["rotated_90"])[0]
    assert circles.visible.all()
    with pytest.raises(ValueError, match="kind must be one of"):
        synth.board_variants(kind="squares")
