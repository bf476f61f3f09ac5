"""Board variants in the renderer (planarcal.synth): both layouts, per-dot sizes and enlarged
dots (touching their neighbours at the limit), printed marks, textures, JPEG and the corpus
of board variants, each checked against geometry computed independently of the renderer."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.errors import BoardError, ImageError
from planarcal.synth import CameraModel, PlanePose, SceneObject, render_scene
from planarcal.synth.dots import _board_to_table

PAPER, INK, TABLE = 225.0, 35.0, 100.0


def supersampled_plane_points(camera: CameraModel, pose: PlanePose, m: int) -> np.ndarray:
    """The table points of m x m point samples in every pixel, (height, width, m * m, 2)."""
    o = (np.arange(m) + 0.5) / m - 0.5
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    su = (u[..., None, None] + o[None, None, None, :]).repeat(m, axis=2)
    sv = (v[..., None, None] + o[None, None, :, None]).repeat(m, axis=3)
    plane = camera.image_to_plane(np.stack([su, sv], axis=-1).reshape(-1, 2), pose)
    return plane.reshape(camera.height, camera.width, m * m, 2)


def weighted_centroid(weights: np.ndarray, x0: int, y0: int) -> np.ndarray:
    ys, xs = np.mgrid[y0 : y0 + weights.shape[0], x0 : x0 + weights.shape[1]]
    centroid = np.array([(weights * xs).sum(), (weights * ys).sum()]) / weights.sum()
    return np.asarray(centroid, dtype=np.float64)


# ----------------------------------------------------------------------------- the dots


@pytest.mark.parametrize(
    ("board", "enlarged"),
    [
        # Two diagonal neighbours of an asymmetric grid, both as wide as the neighbour
        # distance: they touch.
        (
            CircleGridBoard(5, 6, 10.0, 5.0, layout="asymmetric"),
            {7: 10.0 * math.sqrt(2.0), 12: 10.0 * math.sqrt(2.0)},
        ),
        # An origin marker as wide as the pitch, touching an enlarged neighbour as wide.
        (
            CircleGridBoard(5, 6, 10.0, 4.0, origin_marker=True, marker_diameter=10.0),
            {1: 10.0, 6: 8.0},
        ),
    ],
    ids=["asymmetric-touching", "marker-touching"],
)
def test_pixels_match_a_brute_force_reference(
    board: CircleGridBoard, enlarged: dict[int, float]
) -> None:
    """Through distortion and tilt, where dots of different sizes touch, every pixel is the
    fraction of its area inside some dot, as 32 x 32 point samples per pixel measure it."""
    pts = board.world_points()
    centre = 0.5 * (pts[min(enlarged)] + pts[max(enlarged)])  # between the two large dots
    camera = CameraModel(width=48, height=40, focal_px=600.0, k1=-0.2, k2=0.05)
    pose = PlanePose(
        300.0, tilt_deg=25.0, tilt_axis_deg=70.0, roll_deg=10.0, look_at_mm=tuple(centre)
    )
    scene = render_scene(
        camera,
        pose,
        board=board,
        enlarged_dots=enlarged,
        paper_grey=250.0,
        ink_grey=0.0,
        supersample=4,
    )
    diameters = board.dot_diameters()
    for k, d in enlarged.items():
        diameters[k] = d
    np.testing.assert_array_equal(scene.dot_diameters_mm, diameters)
    plane = supersampled_plane_points(camera, pose, 32)
    ink = np.zeros(plane.shape[:-1], dtype=bool)
    for p, d in zip(pts, diameters, strict=True):
        ink |= np.hypot(plane[..., 0] - p[0], plane[..., 1] - p[1]) < d / 2.0
    reference = 250.0 * (1.0 - ink.mean(axis=2))
    assert 0.3 < (reference < 125).mean() < 0.9  # mostly the large dots, some paper
    error = np.abs(scene.image - reference)
    assert error.max() < 0.02 * 250, error.max()
    assert error.mean() < 0.001 * 250, error.mean()


@pytest.mark.parametrize("roll", [0.0, 7.3])
def test_asymmetric_dots_render_where_the_truth_says(roll: float) -> None:
    """OpenCV's asymmetric grid, untilted and undistorted: the centroid of each dot's
    darkness lies within 0.01 px (measured: 0.0015 px at worst) of its projected centre, and the
    centres are the board's world points ((2 c + r % 2) pitch, r pitch) projected."""
    board = CircleGridBoard(4, 11, 10.0, 7.0, layout="asymmetric")
    camera = CameraModel(width=640, height=480, focal_px=1000.0)
    pose = PlanePose(310.0, roll_deg=roll, look_at_mm=(35.3, 49.6))
    scene = render_scene(camera, pose, board=board, paper_grey=PAPER, ink_grey=INK)
    assert scene.dots_in_view(margin_px=5).all()
    np.testing.assert_allclose(scene.dot_centres_px, camera.project(board.world_points(), pose))
    world = board.world_points()
    np.testing.assert_array_equal(world[4], [10.0, 10.0])  # row 1 shifted by one pitch
    image = scene.image.astype(np.float64)
    half = round(3.5 * 1000.0 / 310.0) + 3  # the dot's radius in px and a margin
    errors = []
    for c in scene.dot_centres_px:
        x0, y0 = round(c[0]) - half, round(c[1]) - half
        box = PAPER - image[y0 : y0 + 2 * half + 1, x0 : x0 + 2 * half + 1]
        errors.append(np.linalg.norm(weighted_centroid(box, x0, y0) - c))
    assert max(errors) < 0.01, max(errors)


def test_enlarged_dots_have_the_area_of_their_diameter() -> None:
    """An enlarged dot and an origin marker as wide as the pitch cover pi d^2 / 4 mm^2 of the
    image (at the exact scale of an untilted, undistorted view), to 0.02 % (measured:
    0.002 %)."""
    board = CircleGridBoard(10, 10, 20.0, 10.0, origin_marker=True, marker_diameter=20.0)
    camera = CameraModel(width=800, height=800, focal_px=1200.0)
    distance = 500.0
    pose = PlanePose(distance, roll_deg=3.0, look_at_mm=(90.0, 90.0))
    enlarged = {44: 17.5, 45: 14.0}
    scene = render_scene(camera, pose, board=board, enlarged_dots=enlarged)
    assert scene.dots_in_view(margin_px=2).all()
    scale = camera.focal_px / distance  # px per mm
    darkness = (PAPER - scene.image.astype(np.float64)) / (PAPER - INK)
    for k, d in [(0, 20.0), *enlarged.items(), (99, 10.0)]:
        assert scene.dot_diameters_mm[k] == d
        c = scene.dot_centres_px[k]
        half = round(d / 2.0 * scale) + 3
        x0, y0 = round(c[0]) - half, round(c[1]) - half
        area = darkness[y0 : y0 + 2 * half + 1, x0 : x0 + 2 * half + 1].sum()
        assert area == pytest.approx(math.pi * d * d / 4.0 * scale * scale, rel=2e-4), k


def test_dots_in_view_counts_the_enlarged_dots() -> None:
    """A dot is in view when its printed (enlarged) disc is, not its nominal one."""
    board = CircleGridBoard(4, 3, 20.0, 5.0)
    camera = CameraModel(width=200, height=150, focal_px=500.0)
    pose = PlanePose(500.0, look_at_mm=(30.0, 20.0))  # 1 px per mm: dot 0 at (69.5, 54.5)
    plain = render_scene(camera, pose, board=board)
    scene = render_scene(camera, pose, board=board, enlarged_dots={0: 19.0})
    assert plain.dots_in_view(margin_px=50).all()  # dot 0 reaches y = 52
    inside = scene.dots_in_view(margin_px=50)  # enlarged, y = 45
    assert not inside[0] and inside[1:].all()


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda: render_scene(enlarged_dots={140: 12.0}), "dot 140 does not exist"),
        (lambda: render_scene(enlarged_dots={3: 20.5}), "at most the distance"),
        (lambda: render_scene(enlarged_dots={3: 8.0}), "at least the board's dots"),
        (lambda: render_scene(enlarged_dots={"3": 12.0}), "not a dot index"),  # type: ignore[dict-item]
        (lambda: render_scene(enlarged_dots=[12.0]), "must map"),  # type: ignore[arg-type]
    ],
)
def test_bad_boards_raise_board_errors(make: Callable[[], object], words: str) -> None:
    with pytest.raises(BoardError, match=words):
        make()


def test_default_pose_looks_at_an_asymmetric_board_s_middle() -> None:
    board = CircleGridBoard(4, 11, 20.0, 15.0, layout="asymmetric")
    scene = render_scene(board=board)
    middle = 0.5 * (board.world_points().min(axis=0) + board.world_points().max(axis=0))
    assert scene.pose.look_at_mm == pytest.approx(tuple(middle))


# ----------------------------------------------------------------------------- marks


def mark_outlines(marks: tuple[SceneObject, ...]) -> np.ndarray:
    """The marks' rectangles as (n, 4, 2) vertices."""
    assert all(m.kind == "rectangle" for m in marks)
    return np.array([m.silhouette().outer for m in marks])


def distance_to_outlines(quads: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(n_quads, n_points): each point's distance to each convex quad (0 inside)."""
    a, b = quads, np.roll(quads, -1, axis=1)
    e = b - a  # (n, 4, 2)
    rel = points[None, None, :, :] - a[:, :, None, :]  # (n, 4, p, 2)
    t = np.clip(np.einsum("nepk,nek->nep", rel, e) / np.sum(e * e, axis=2)[..., None], 0, 1)
    closest = a[:, :, None, :] + t[..., None] * e[:, :, None, :]
    edge = np.linalg.norm(points[None, None] - closest, axis=3).min(axis=1)
    cross = e[:, :, None, 0] * rel[..., 1] - e[:, :, None, 1] * rel[..., 0]
    inside = (cross >= 0).all(axis=1) | (cross <= 0).all(axis=1)
    return np.where(inside, 0.0, edge)


BOARDS = [
    CircleGridBoard(6, 6, 20.0, 13.2),
    CircleGridBoard(9, 7, 20.0, 8.0, layout="asymmetric"),
    CircleGridBoard(12, 9, 15.0, 6.0, origin_marker=True),
]


@pytest.mark.parametrize("board", BOARDS, ids=["6x6-0.66", "asymmetric", "marker"])
@pytest.mark.parametrize("kind", synth.MARK_KINDS)
def test_marks_stay_off_the_dots_and_on_the_paper(
    board: CircleGridBoard, kind: synth.MarkKind
) -> None:
    """No mark touches a dot (nor comes within a tenth of the gap between dots) or leaves
    the paper; the kinds asked for together never overlap each other."""
    margin = 12.0
    marks = synth.printed_marks(board, kind, seed=3, paper_margin_mm=margin)
    assert marks, kind
    quads = mark_outlines(marks)
    pts, radii = board.world_points(), board.dot_diameters() / 2.0
    gap = board.neighbour_distance - 2.0 * radii.max()
    clearance = distance_to_outlines(quads, pts) - radii[None, :]
    assert clearance.min() > 0.1 * gap, clearance.min()
    big = radii.max() + margin
    lo, hi = pts.min(axis=0) - big, pts.max(axis=0) + big
    assert (quads >= lo).all() and (quads <= hi).all()


def test_kinds_of_marks_do_not_overlap() -> None:
    """Marks of different kinds asked for together keep apart (their outlines' vertices lie
    outside every other kind's marks)."""
    board = CircleGridBoard(12, 9, 15.0, 6.0)
    by_kind = {k: mark_outlines(synth.printed_marks(board, k, seed=5)) for k in synth.MARK_KINDS}
    for a, qa in by_kind.items():
        for b, qb in by_kind.items():
            if a != b:
                d = distance_to_outlines(qb, qa.reshape(-1, 2))
                assert d.min() > 0.0, (a, b)
    together = synth.printed_marks(board, synth.MARK_KINDS, seed=5)
    assert len(together) == sum(len(q) for q in by_kind.values())
    assert synth.printed_marks(board, ("text", "rings"), 5) == synth.printed_marks(
        board, ("rings", "text"), 5
    )


def test_marks_land_where_asked() -> None:
    """Rings centre on dots, column numbers above the columns, row numbers beside the rows,
    arrows along the first row and column, numbers between dots at the spaces' centres."""
    board = CircleGridBoard(6, 5, 20.0, 10.0)
    pts = board.world_points()

    def centre(marks: tuple[SceneObject, ...]) -> np.ndarray:
        quads = mark_outlines(marks).reshape(-1, 2)
        return np.asarray(0.5 * (quads.min(axis=0) + quads.max(axis=0)))

    rings = synth.printed_marks(board, "rings", seed=1)
    assert len(rings) % 32 == 0
    for k in range(len(rings) // 32):
        ring_centre = centre(rings[32 * k : 32 * (k + 1)])
        assert np.linalg.norm(pts - ring_centre, axis=1).min() < 1e-9
    numbers = synth.printed_marks(board, "numbers", seed=1)
    tops = [m for m in numbers if m.position_mm[1] < -5.0 - 0.3 * 15.0]
    lefts = [m for m in numbers if m.position_mm[0] < -5.0 - 0.3 * 15.0]
    assert tops and lefts and len(tops) + len(lefts) == len(numbers)
    # Each column's number over its column, each row's beside its row (within half a
    # digit's width: a seven-segment 1 is all on the right), drawn with that digit's
    # segments (0 has 6 strokes, 1 has 2, 2 has 5, ...).
    strokes = [6, 2, 5, 5, 4, 5]
    height = tops[0].size_mm / 0.14  # a digit's strokes are 0.14 of its height wide
    for c, x in enumerate(pts[: board.cols, 0]):
        near = [m for m in tops if abs(m.position_mm[0] - x) < 0.4 * board.pitch]
        assert len(near) == strokes[c]
        assert abs(centre(tuple(near))[0] - x) <= 0.3 * height
    for r, y in enumerate(pts[:: board.cols, 1]):
        near = [m for m in lefts if abs(m.position_mm[1] - y) < 0.4 * board.pitch]
        assert len(near) == strokes[r]
        assert abs(centre(tuple(near))[1] - y) < 1e-9
    arrows = synth.printed_marks(board, "arrows", seed=1)
    assert len(arrows) == 6  # two shafts, four barbs
    shaft_x, shaft_y = arrows[0], arrows[3]
    assert shaft_x.angle_deg == pytest.approx(0.0) and shaft_x.position_mm[1] < -5.0
    assert shaft_y.angle_deg == pytest.approx(90.0) and shaft_y.position_mm[0] < -5.0
    # Numbers between dots: each label centred on the centre of a square of four dots (its
    # height exactly, its width within half a digit, as above).
    cells = synth.printed_marks(board, "cell_numbers", seed=1)
    height = cells[0].size_mm / 0.14
    holes = (np.mgrid[0:5, 0:4].reshape(2, -1).T + 0.5) * board.pitch
    owner = np.linalg.norm(
        np.array([m.position_mm for m in cells])[:, None] - holes[None], axis=2
    ).argmin(axis=1)
    for k in np.unique(owner):
        label = tuple(m for m, o in zip(cells, owner, strict=True) if o == k)
        assert abs(centre(label)[1] - holes[k][1]) < 1e-9
        assert abs(centre(label)[0] - holes[k][0]) <= 0.3 * height


def test_marks_render_in_the_ink_and_are_no_truth() -> None:
    """Rendered, marks are ink where they lie (moving with the board), the dots and the
    paper away from them are untouched, and they are no objects: the truth ignores them.
    Light on dark they are printed in the (light) ink too."""
    board = CircleGridBoard(6, 6, 20.0, 13.2)
    camera = CameraModel(width=640, height=480, focal_px=900.0)
    look = _board_to_table(np.array([[50.0, 50.0]]), (30.0, -20.0), 25.0)[0]
    pose = PlanePose(330.0, look_at_mm=(float(look[0]), float(look[1])))
    marks = synth.printed_marks(board, ("numbers", "cell_numbers", "arrows", "text"), seed=2)
    for light_on_dark, ink in ((False, INK), (True, PAPER)):
        render = functools.partial(
            render_scene,
            camera,
            pose,
            board=board,
            light_on_dark=light_on_dark,
            board_origin_mm=(30.0, -20.0),
            board_angle_deg=25.0,
        )
        plain = render()
        scene = render(marks=marks)
        assert scene.marks == marks and scene.objects == ()
        assert scene.object_centroids_px.shape == (0, 2)
        np.testing.assert_array_equal(scene.dot_centres_px, plain.dot_centres_px)
        changed = scene.image != plain.image
        assert changed.sum() > 500
        # Every stroke's middle is ink (those at least 2 px wide: thinner ones are grey).
        on_table = _board_to_table(np.array([m.position_mm for m in marks]), (30.0, -20.0), 25.0)
        px = np.rint(camera.project(on_table, pose)).astype(int)
        wide = np.array([m.size_mm * 900.0 / 330.0 >= 2.0 for m in marks])
        assert wide.sum() > 20
        values = scene.image[px[wide, 1], px[wide, 0]].astype(float)
        assert np.abs(values - ink).max() < 0.35 * (PAPER - INK)
        # Nothing changes inside the dots.
        v, u = np.mgrid[0 : camera.height, 0 : camera.width]
        radius_px = 6.6 * 900.0 / 330.0
        for c in scene.dot_centres_px:
            assert not changed[np.hypot(u - c[0], v - c[1]) < radius_px - 1.0].any()


def test_marks_must_be_flat_scene_objects() -> None:
    with pytest.raises(ValueError, match=r"marks\[0\] must be flat"):
        render_scene(marks=[SceneObject("disc", (0, 0), height_mm=1.0)])
    with pytest.raises(ValueError, match=r"marks\[0\] must be a SceneObject"):
        render_scene(marks=["a digit"])  # type: ignore[list-item]
    with pytest.raises(ValueError, match="kinds must be among"):
        synth.printed_marks(CircleGridBoard(), "logo")  # type: ignore[arg-type]
    with pytest.raises(BoardError, match="need a paper margin"):
        synth.printed_marks(CircleGridBoard(), "arrows", paper_margin_mm=0.0)


# ----------------------------------------------------------------------------- textures


def pure(image: np.ndarray, value: float) -> np.ndarray:
    """Pixels of exactly ``value`` whose 8 neighbours are too (wholly in one material)."""
    eq = image == value
    out = eq.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            out &= np.roll(np.roll(eq, dy, axis=0), dx, axis=1)
    out[[0, -1], :] = False
    out[:, [0, -1]] = False
    return np.asarray(out, dtype=np.bool_)


@pytest.mark.parametrize("light_on_dark", [False, True])
def test_textures_only_on_their_material(light_on_dark: bool) -> None:
    """The table's texture changes the table only, the paper's the paper only (not the dots
    nor the table), each with about the standard deviation asked for; both are seeded."""
    board = CircleGridBoard(6, 4, 20.0, 10.0)
    camera = CameraModel(width=400, height=300, focal_px=700.0, k1=-0.1)
    pose = PlanePose(600.0, tilt_deg=20.0, tilt_axis_deg=30.0, look_at_mm=(50.0, 30.0))
    render = functools.partial(
        render_scene, camera, pose, board=board, light_on_dark=light_on_dark, table_grey=TABLE
    )
    plain = render().image
    table = render(table_texture=12.0).image
    paper = render(paper_texture=6.0).image
    paper_tone, ink_tone = (INK, PAPER) if light_on_dark else (PAPER, INK)
    on_table, on_paper, on_ink = pure(plain, TABLE), pure(plain, paper_tone), pure(plain, ink_tone)
    assert min(on_table.sum(), on_paper.sum(), on_ink.sum()) > 1000
    d_table = table.astype(float) - plain
    d_paper = paper.astype(float) - plain
    assert not d_table[on_paper | on_ink].any()
    assert not d_paper[on_table | on_ink].any()
    assert 0.6 * 12.0 < d_table[on_table].std() < 1.4 * 12.0
    assert 0.6 * 6.0 < d_paper[on_paper].std() < 1.4 * 6.0
    assert (d_table[on_table] != 0).mean() > 0.8
    again = render(table_texture=12.0).image
    np.testing.assert_array_equal(again, table)
    other = render(table_texture=12.0, seed=1).image
    assert (other != table)[on_table].mean() > 0.5


def test_texture_is_bounded_and_validated() -> None:
    with pytest.raises(ImageError, match="table_texture"):
        render_scene(table_texture=-1.0)
    with pytest.raises(ImageError, match="paper_texture"):
        render_scene(paper_texture=math.nan)


# ----------------------------------------------------------------------------- JPEG


@pytest.mark.parametrize("color", [False, True])
def test_jpeg_changes_the_image_but_not_its_form(color: bool) -> None:
    scene = render_scene(CameraModel(320, 240, 400.0), color=color, noise_sigma=2.0)
    out = synth.jpeg(scene.image, 75)
    assert out.shape == scene.image.shape and out.dtype == np.uint8
    assert (out != scene.image).mean() > 0.1
    err75 = np.abs(out.astype(float) - scene.image).mean()
    err95 = np.abs(synth.jpeg(scene.image, 95).astype(float) - scene.image).mean()
    err10 = np.abs(synth.jpeg(scene.image, 10).astype(float) - scene.image).mean()
    assert err95 < err75 < err10
    assert err75 < 0.05 * (PAPER - INK)  # artefacts, not a different picture
    with pytest.raises(ImageError, match="quality"):
        synth.jpeg(scene.image, 101)
    with pytest.raises(ImageError, match="uint8"):
        synth.jpeg(scene.image.astype(np.float32), 75)


# ----------------------------------------------------------------------------- the corpus


@pytest.fixture(scope="module")
def corpus() -> list[synth.BoardVariant]:
    return synth.board_variants(seed=0)


def test_corpus_covers_what_detection_must_handle(corpus: list[synth.BoardVariant]) -> None:
    names = [v.name for v in corpus]
    assert names == list(synth.BOARD_VARIANTS)
    boards = [v.board for v in corpus if isinstance(v.board, CircleGridBoard)]
    assert len(boards) == len(corpus)
    ratios = {round(b.dots_mm() / b.pitch, 2) for b in boards}
    assert {0.15, 0.3, 0.5, 0.66, 0.85} <= ratios
    assert {b.layout for b in boards} == {"symmetric", "asymmetric"}
    sizes = {v.image.shape[:2] for v in corpus}
    assert {(240, 320), (480, 640), (2160, 3840)} <= sizes
    assert {v.jpeg_quality for v in corpus} == {None, 75}
    assert any(abs(v.scene.pose.tilt_deg) >= 30.0 for v in corpus)
    assert any(v.scene.effects["light_on_dark"] for v in corpus)
    assert any(v.scene.effects["table_texture"] > 0 for v in corpus)
    assert any(v.scene.marks for v in corpus)
    by_name = {v.name: v for v in corpus}
    assert by_name["fiducials_barrel"].enlarged.sum() == 4
    assert by_name["fiducials_barrel"].scene.camera.k1 <= -0.3
    origin = by_name["origin_as_wide_as_pitch"]
    assert np.flatnonzero(origin.enlarged).tolist() == [0]
    assert origin.scene.dot_diameters_mm[0] == origin.board.pitch
    assert (by_name["asymmetric_4x11"].board.cols, by_name["asymmetric_4x11"].board.rows) == (
        4,
        11,
    )


def test_every_variant_renders_with_its_truth_in_the_image(
    corpus: list[synth.BoardVariant],
) -> None:
    """Every dot lies wholly in its image, and at each true centre the image is as dark
    (light, for light dots) as the local ink, not the paper."""
    for v in corpus:
        camera = v.scene.camera
        grey = v.image if v.image.ndim == 2 else v.image.mean(axis=2)
        assert grey.shape == (camera.height, camera.width), v.name
        assert v.truth_px.shape == (v.board.n_points, 2), v.name
        assert v.enlarged.shape == (v.board.n_points,), v.name
        np.testing.assert_array_equal(v.truth_px, v.scene.dot_centres_px)
        assert v.scene.dots_in_view(margin_px=1.0).all(), v.name
        light = bool(v.scene.effects["light_on_dark"])
        # A window as wide as the distance between neighbouring dots' centres.
        step = np.linalg.norm(np.diff(v.truth_px[:2], axis=0)) / 2.0
        reach = max(3, round(float(step)))
        for c in np.rint(v.truth_px).astype(int):
            win = grey[c[1] - reach : c[1] + reach + 1, c[0] - reach : c[0] + reach + 1]
            lo, hi = np.percentile(win, [2, 98])
            at = float(grey[c[1], c[0]])
            if light:
                assert at > hi - 0.3 * (hi - lo), v.name
            else:
                assert at < lo + 0.3 * (hi - lo), v.name


def test_corpus_is_deterministic_and_picks_by_name(corpus: list[synth.BoardVariant]) -> None:
    subset = synth.board_variants(seed=0, names=["webcam_320x240_jpeg", "rotated_90"])
    assert [v.name for v in subset] == ["webcam_320x240_jpeg", "rotated_90"]
    by_name = {v.name: v for v in corpus}
    for v in subset:
        np.testing.assert_array_equal(v.image, by_name[v.name].image)
        np.testing.assert_array_equal(v.truth_px, by_name[v.name].truth_px)
    other = synth.board_variant("webcam_320x240_jpeg", seed=1)
    assert not np.array_equal(other.truth_px, subset[0].truth_px)
    assert other.scene.dots_in_view(margin_px=1.0).all()
    with pytest.raises(ValueError, match="no board variant"):
        synth.board_variant("chessboard")
