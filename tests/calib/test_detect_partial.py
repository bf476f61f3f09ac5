"""Partial views of circle grids (issue 22): a board whose visible part identifies itself
(fiducial dots, an origin marker with enough of the lattice, a lattice as large as the board)
is read from the dots in view, with their ids; an ambiguous one is refused saying so.

Real photographs: the UCL metal plate (../shared/data/real/ucl-dotty-metal, BSD 3-Clause,
see its SOURCE.md): 16 x 14 dots 5 mm apart, four of them enlarged (ids 69, 74, 149, 154:
rows 4 and 9, columns 5 and 10, as every whole view of it shows), cropped so that the image
edge cuts off a row or a column, and with dots painted over (glare). Renders: planarcal.synth
with the fiducials drawn enlarged, posed with part of the board outside the image.
"""

from __future__ import annotations

import functools
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from conftest import SHARED
from planarcal import cli, synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.calib.detection import BoardDetection
from planarcal.calib.dot_sizes import clipped_paper_share
from planarcal.calib.grid_search import Lattice
from planarcal.calib.partial_view import place_partial
from planarcal.errors import BoardError, BoardMismatchError, BoardNotFoundError
from planarcal.synth.occluders import hand

UCL = SHARED / "data" / "real" / "ucl-dotty-metal"
UCL_NAMES = ("14_09_35", "14_10_22", "14_12_04", "14_13_46")
UCL_FIDUCIALS = (69, 74, 149, 154)
UCL_BOARD = CircleGridBoard(16, 14, 5.0, fiducials=UCL_FIDUCIALS)
UCL_PLAIN = CircleGridBoard(16, 14, 5.0)

F64 = NDArray[np.float64]


def _ucl(name: str) -> NDArray[np.uint8]:
    path = UCL / f"{name}_left_image.png"
    if not path.exists():
        pytest.skip(f"the UCL photographs are not here ({UCL}): ../shared is absent")
    return _read(path)


@functools.cache
def _read(path: Path) -> NDArray[np.uint8]:
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    assert image is not None, path
    return np.asarray(image)


@functools.cache
def _whole(name: str) -> BoardDetection:
    """The whole plate's detection, the reference a partial view is compared with."""
    det = detect_board(_ucl(name), UCL_BOARD)
    assert not det.partial
    return det


def _same_dots(part: BoardDetection, whole: BoardDetection, offset: tuple[int, int]) -> F64:
    """How far each dot of a partial view (of an image cropped at `offset`) lies from the same
    id in the whole view, px; the plate's fiducials are symmetric under a half turn, so the
    rule that reads a whole board (dot 0 nearest the image's top-left) reads both."""
    assert np.all(np.diff(part.ids) > 0)
    got = part.image_points + np.asarray(offset, dtype=np.float64)
    return np.asarray(np.hypot(*(got - whole.image_points[part.ids]).T))


# ------------------------------------------------------------------------------------------
# The board's description


def test_fiducials_are_part_of_the_description() -> None:
    board = CircleGridBoard(16, 14, 5.0, 2.0, fiducials=[154, 69, 149, 74])  # type: ignore[arg-type]
    assert board.fiducials == UCL_FIDUCIALS  # sorted, a tuple (the board stays hashable)
    assert hash(board) == hash(CircleGridBoard(16, 14, 5.0, 2.0, fiducials=UCL_FIDUCIALS))
    data = board.to_dict()
    assert data["fiducials"] == list(UCL_FIDUCIALS) and data["fiducial_diameter_mm"] is None
    assert CircleGridBoard.from_dict(data) == board
    assert "4 fiducial dot(s) (ids 69, 74, 149, 154)" in board.describe()
    # Drawn enlarged (as an origin marker would be, by default), in print and render alike.
    d = board.dot_diameters()
    assert d[69] == pytest.approx(3.0) and d[0] == 2.0 and (d == 2.0).sum() == 220
    circles = board.ink().circles
    assert np.allclose(2.0 * circles[UCL_FIDUCIALS, 2], 3.0)
    sized = CircleGridBoard(16, 14, 5.0, 2.0, fiducials=(69,), fiducial_diameter=4.0)
    assert sized.dot_diameters()[69] == 4.0 and sized.extent == (79.0, 69.0)
    assert CircleGridBoard.from_dict(sized.to_dict()) == sized


def test_a_board_without_fiducials_is_described_as_before() -> None:
    board = CircleGridBoard(14, 10, 20.0, 10.0, origin_marker=True)
    assert set(board.to_dict()) == {
        "cols",
        "rows",
        "pitch_mm",
        "diameter_mm",
        "origin_marker",
        "marker_diameter_mm",
        "layout",
    }
    assert board.describe() == "14 x 10 dots of 10 mm, 20 mm apart, origin marker"
    assert CircleGridBoard.from_dict(board.to_dict()) == board


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"fiducials": (3, 3)}, "named twice"),
        ({"fiducials": (224,)}, "does not exist"),
        ({"fiducials": (-1,)}, "does not exist"),
        ({"fiducials": (True,)}, "not a dot id"),
        ({"fiducials": (1.5,)}, "not a dot id"),
        ({"fiducials": 7}, "sequence of dot ids"),
        ({"fiducials": "69"}, "sequence of dot ids"),
        ({"fiducial_diameter": 3.0}, "no fiducials"),
        ({"fiducials": (5,), "fiducial_diameter": 2.1, "diameter": 2.0}, "1.2 times"),
        ({"fiducials": (5,), "fiducial_diameter": 6.0}, "at most the distance"),
        ({"fiducials": (0,), "origin_marker": True}, "origin marker"),
    ],
)
def test_a_wrong_fiducial_description_is_refused(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(BoardError, match=match):
        CircleGridBoard(16, 14, 5.0, **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "fiducials", ["abc", None, [1.5], [500], {"a": 1}, [[69]]], ids=lambda v: repr(v)
)
def test_a_damaged_fiducials_entry_in_a_saved_description_is_a_board_error(
    fiducials: object,
) -> None:
    data = {**UCL_BOARD.to_dict(), "fiducials": fiducials}
    with pytest.raises(BoardError):
        CircleGridBoard.from_dict(data)


def test_the_paper_check_counts_the_found_dots_only() -> None:
    """The overexposure check (the paper midway between neighbours along a row) on a partial
    view looks between found neighbours only, by id."""
    board = CircleGridBoard(4, 3, 10.0)
    ink = np.full((40, 60), 255.0, dtype=np.float32)  # paper clipped everywhere
    ids = np.array([0, 1, 2, 5, 6, 11], dtype=np.intp)
    points = board.world_points()[ids] + 5.0
    assert clipped_paper_share(ink, points, board, ids) == 1.0
    ink[:, 11:] = 100.0  # the paper between dots 0 and 1 alone stays clipped
    assert clipped_paper_share(ink, points, board, ids) == pytest.approx(1 / 3)
    assert clipped_paper_share(ink, points[[0, 3, 5]], board, ids[[0, 3, 5]]) == 0.0


def test_fiducials_fix_the_orientation_only_where_they_break_the_symmetry() -> None:
    # The UCL plate's four fiducials are symmetric under a half turn: two readings remain.
    assert not UCL_BOARD.orientation_fixed and len(UCL_BOARD.reading_symmetries()) == 2
    lopsided = CircleGridBoard(16, 14, 5.0, fiducials=(69, 74, 150))
    assert lopsided.orientation_fixed and len(lopsided.reading_symmetries()) == 1
    assert len(CircleGridBoard(6, 6, 10.0).reading_symmetries()) == 4
    turns = CircleGridBoard(6, 6, 10.0, fiducials=(7, 10, 25, 28)).reading_symmetries()
    assert len(turns) == 4  # a square's four fiducials in a square: every quarter turn
    world = CircleGridBoard(6, 6, 10.0).world_points()
    for perm in turns:  # each a rigid turn of the dots onto themselves
        assert np.allclose(
            np.linalg.norm(world[perm] - world[perm][7], axis=1),
            np.linalg.norm(world - world[7], axis=1),
        )


# ------------------------------------------------------------------------------------------
# Placing a lattice on the board (no image)


def _sub_lattice(board: CircleGridBoard, cols: range, rows: range) -> tuple[Lattice, F64]:
    """The lattice of the board's dots in `cols` x `rows`, seen straight on (image = world)."""
    nodes = np.array([(c, r) for r in rows for c in cols], dtype=np.int64)
    ids = nodes[:, 1] * board.cols + nodes[:, 0]
    lattice = Lattice(nodes - nodes.min(axis=0), ids.astype(np.intp))
    return lattice, board.world_points()[ids]


def test_a_lattice_with_fiducials_fits_one_way_a_plain_one_many() -> None:
    board = CircleGridBoard(16, 14, 5.0, fiducials=(69, 74, 150))  # orientation fixed
    lattice, centres = _sub_lattice(board, range(3, 13), range(2, 10))  # 69, 74 and 150
    usable = np.ones(len(centres), dtype=bool)
    enlarged = np.isin(lattice.blob, board.fiducials)
    fit = place_partial(lattice.nodes, centres, usable, enlarged, board)
    assert fit.ways == 1 and len(fit.readings) == 1
    assert np.array_equal(fit.readings[0], lattice.blob)
    plain = CircleGridBoard(16, 14, 5.0)
    fit = place_partial(lattice.nodes, centres, usable, np.zeros_like(usable), plain)
    # Every offset, along and across (a half turn gives the same set of dots).
    assert fit.ways == (16 - 10 + 1) * (14 - 8 + 1) + (16 - 8 + 1) * (14 - 10 + 1)
    # Mirrored (the board seen from behind): no placement.
    fit = place_partial(lattice.nodes, centres * [-1, 1], usable, enlarged, board)
    assert fit.ways == 0
    # An enlarged dot where the board has none: no placement either.
    wrong = np.roll(enlarged, 3)
    assert place_partial(lattice.nodes, centres, usable, wrong, board).ways == 0
    # One fiducial in a small window could be any of the three, turned: ambiguous.
    small, at = _sub_lattice(board, range(3, 9), range(2, 7))
    one = np.isin(small.blob, board.fiducials)
    assert one.sum() == 1
    assert place_partial(small.nodes, at, np.ones(len(at), bool), one, board).ways > 1


def test_a_lattice_as_large_as_the_board_fits_one_way_even_without_marks() -> None:
    plain = CircleGridBoard(10, 8, 25.0)
    lattice, centres = _sub_lattice(plain, range(10), range(8))
    keep = ~np.isin(lattice.blob, [11, 12, 13, 40, 41, 55])  # glare: more than max_holes
    usable = np.ones(int(keep.sum()), dtype=bool)
    fit = place_partial(lattice.nodes[keep], centres[keep], usable, ~usable, plain)
    assert fit.ways == 1 and len(fit.readings) == 2  # the board's half turn: one reading
    assert any(np.array_equal(r, lattice.blob[keep]) for r in fit.readings)


# ------------------------------------------------------------------------------------------
# The UCL plate, real photographs


@pytest.mark.parametrize("name", UCL_NAMES)
def test_the_ucl_plate_with_fiducials_reads_as_without(name: str) -> None:
    with_fiducials = _whole(name)
    plain = detect_board(_ucl(name), UCL_PLAIN)
    assert np.array_equal(with_fiducials.image_points, plain.image_points)
    assert np.flatnonzero(with_fiducials.enlarged).tolist() == list(UCL_FIDUCIALS)
    assert with_fiducials.orientation == plain.orientation == "ambiguous"


# Each photograph cut on two sides, every side in two photographs (the suite's time).
SIDES = ("top", "left", "bottom", "right")
CUTS = [(name, SIDES[(2 * i + j) % 4]) for i, name in enumerate(UCL_NAMES) for j in (0, 1)]


@pytest.mark.parametrize(("name", "side"), CUTS)
def test_the_ucl_plate_with_a_row_cut_off_by_the_image_edge(name: str, side: str) -> None:
    """Cropped just inside the outermost dot on one side: the image edge cuts that row (or
    column) off, wholly or partly (the plate is tilted), and the rest is read with its ids."""
    image, whole = _ucl(name), _whole(name)
    pts = whole.image_points
    axis = 1 if side in ("top", "bottom") else 0
    if side in ("top", "left"):
        cut = int(pts[:, axis].min()) + 3
        crop = image[cut:] if axis else image[:, cut:]
        offset = (0, cut) if axis else (cut, 0)
    else:
        cut = int(np.ceil(pts[:, axis].max())) - 3
        crop = image[:cut] if axis else image[:, :cut]
        offset = (0, 0)
    start = time.perf_counter()
    part = detect_board(np.ascontiguousarray(crop), UCL_BOARD)
    elapsed = time.perf_counter() - start
    gone = np.flatnonzero(pts[:, axis] < cut if side in ("top", "left") else pts[:, axis] > cut)
    assert part.partial and not set(gone) & set(part.ids.tolist())
    assert len(part.ids) >= 224 - 16 - 4, len(part.ids)
    gaps = _same_dots(part, whole, offset)
    print(
        f"{name} {side}: {len(part.ids)} of 224 dots, RMS {part.residual_rms_px:.3f} px, "
        f"against the whole view max {gaps.max():.3f} px, {elapsed:.2f} s"
    )
    assert np.median(gaps) < 0.02 and gaps.max() < 0.5
    assert part.sizes is not None and part.sizes.diameter_mm == pytest.approx(
        whole.sizes.diameter_mm if whole.sizes else 0.0, rel=0.03
    )


@pytest.mark.parametrize("name", UCL_NAMES)
def test_the_ucl_plate_with_dots_lost_to_glare(name: str) -> None:
    """A regular dot, a fiducial and the corner dot painted over with the paper's white:
    the others are read, the lost ones left out."""
    image, whole = _ucl(name).copy(), _whole(name)
    lost = [100, 69, 0]
    for k in lost:
        centre = tuple(int(v) for v in np.rint(whole.image_points[k]))
        cv2.circle(image, centre, int(0.45 * whole.pitch_px), 255, -1)
    part = detect_board(image, UCL_BOARD)
    assert not set(lost) & set(part.ids.tolist())
    assert len(part.ids) >= 224 - len(lost) - 1
    gaps = _same_dots(part, whole, (0, 0))
    assert gaps.max() < 0.05


def test_the_ucl_plate_described_without_fiducials_with_a_dot_lost_to_glare() -> None:
    """The whole-board finder refuses the plate with a dot lost (it cannot measure the dot
    it fills in); the partial reading takes it, as its lattice is as large as the board."""
    name = UCL_NAMES[1]
    image, whole = _ucl(name).copy(), _whole(name)
    centre = tuple(int(v) for v in np.rint(whole.image_points[100]))
    cv2.circle(image, centre, int(0.45 * whole.pitch_px), 255, -1)
    plain = detect_board(image, UCL_PLAIN)
    assert plain.partial and 100 not in plain.ids
    assert _same_dots(plain, whole, (0, 0)).max() < 0.05


def test_the_ucl_plate_with_an_object_across_it() -> None:
    """A dark bar over columns 6 to 8 splits the lattice in two: both halves are read."""
    name = UCL_NAMES[0]
    image, whole = _ucl(name).copy(), _whole(name)
    pts = whole.image_points
    bar = np.array([pts[6], pts[8], pts[8 + 16 * 13], pts[6 + 16 * 13]])
    middle = bar.mean(axis=0)
    cv2.fillConvexPoly(image, np.rint(middle + 1.25 * (bar - middle)).astype(np.int32), 60)
    part = detect_board(image, UCL_BOARD)
    covered = {r * 16 + c for r in range(14) for c in (6, 7, 8)}
    assert set(part.ids.tolist()) == set(range(224)) - covered
    gaps = _same_dots(part, whole, (0, 0))
    regular = ~np.isin(part.ids, UCL_FIDUCIALS)  # the fiducials beside the bar lose paper
    assert gaps[regular].max() < 0.1


def test_an_ambiguous_cut_of_the_ucl_plate_without_its_fiducials_is_refused() -> None:
    name = UCL_NAMES[0]
    image, whole = _ucl(name), _whole(name)
    cut = int(np.sort(whole.image_points[:, 1])[60])  # three rows or so gone
    crop = np.ascontiguousarray(image[cut:])
    with pytest.raises(BoardNotFoundError) as err:
        detect_board(crop, UCL_PLAIN)
    message = str(err.value)
    assert "partial and ambiguous" in message and "of the board's 224 dots seen" in message
    assert "fiducial" in message and "whole board in view" in message
    assert "enlarged dot(s) seen" in message  # the plate's fiducials, not described
    diagnostics = err.value.diagnostics
    assert diagnostics is not None and diagnostics.partial_views
    # Described with its fiducials, the same crop is read.
    part = detect_board(crop, UCL_BOARD)
    assert part.partial and _same_dots(part, whole, (0, cut)).max() < 0.5


# ------------------------------------------------------------------------------------------
# Renders with exact truth


FIDUCIAL_BOARD = CircleGridBoard(14, 10, 20.0, 10.0, fiducials=(31, 38, 101))


def _errors(det: BoardDetection, scene: synth.RenderedScene) -> F64:
    return np.asarray(np.hypot(*(det.image_points - scene.dot_centres_px[det.ids]).T))


@pytest.mark.parametrize("look", [(300, 90), (-60, 90), (130, -50), (130, 230)])
def test_a_rendered_fiducial_board_partly_outside_the_image(look: tuple[int, int]) -> None:
    pose = synth.PlanePose(distance_mm=420, tilt_deg=20, roll_deg=15, look_at_mm=look)
    camera = synth.CameraModel(k1=-0.1)
    scene = synth.render_scene(
        camera, pose, board=FIDUCIAL_BOARD, blur_sigma_px=0.8, noise_sigma=2.0, seed=6
    )
    in_view = scene.dots_in_view(margin_px=0)
    assert 40 < in_view.sum() < FIDUCIAL_BOARD.n_points
    start = time.perf_counter()
    det = detect_board(scene.image, FIDUCIAL_BOARD)
    assert time.perf_counter() - start < 6.0  # 2 s on an idle machine; others share it
    assert det.partial and in_view[det.ids].all()
    # Every dot clear of the border is found, or nearly (one may be too close to measure).
    missed = set(np.flatnonzero(scene.dots_in_view(margin_px=3))) - set(det.ids.tolist())
    assert len(missed) <= 1, missed
    assert det.orientation == "marker"  # these fiducials fix the reading
    err = _errors(det, scene)
    assert err.max() < 0.06 and np.sqrt(np.mean(err**2)) < 0.02
    assert det.sizes is not None and det.sizes.diameter_mm == pytest.approx(10.0, rel=0.03)
    assert det.enlarged.sum() == np.isin(det.ids, FIDUCIAL_BOARD.fiducials).sum()


def test_fiducials_rendered_as_enlarged_dots_are_read_from_the_description() -> None:
    """The renderer's enlarged_dots (a plain board with some dots drawn larger) and a board
    described with those dots as fiducials: the same page, read from part of it."""
    plain = CircleGridBoard(14, 10, 20.0, 10.0)
    enlarged = dict.fromkeys(FIDUCIAL_BOARD.fiducials, FIDUCIAL_BOARD.fiducial_diameter_mm)
    pose = synth.PlanePose(distance_mm=400, tilt_deg=25, roll_deg=-20, look_at_mm=(40, 120))
    scene = synth.render_scene(
        synth.CameraModel(k1=-0.15, k2=0.03),
        pose,
        board=plain,
        enlarged_dots=enlarged,
        blur_sigma_px=1.0,
        noise_sigma=3.0,
        seed=11,
    )
    in_view = scene.dots_in_view()
    assert not in_view.all()
    det = detect_board(scene.image, FIDUCIAL_BOARD)
    assert det.partial and in_view[det.ids].all() and len(det.ids) >= in_view.sum() - 2
    assert _errors(det, scene).max() < 0.06
    # Described plain, the view still spans the board's rows and columns (the image cuts its
    # corners): it fits one way up to a half turn, read by the rule for a plain board.
    read = detect_board(scene.image, plain)
    assert read.orientation == "ambiguous" and len(read.ids) == len(det.ids)
    truth = scene.dot_centres_px
    turned = plain.n_points - 1 - read.ids
    assert (
        min(
            np.abs(read.image_points - truth[read.ids]).max(),
            np.abs(read.image_points - truth[turned]).max(),
        )
        < 0.06
    )


def test_a_rendered_fiducial_board_under_a_hand_and_glare() -> None:
    pose = synth.PlanePose(distance_mm=520, tilt_deg=15, look_at_mm=(130, 90))
    objects = hand((40.0, 60.0), angle_deg=-30.0, size_mm=70.0)
    scene = synth.render_scene(
        synth.CameraModel(),
        pose,
        board=FIDUCIAL_BOARD,
        objects=objects,
        glare=((900.0, 300.0, 40.0),),
        blur_sigma_px=0.8,
        noise_sigma=2.0,
        seed=8,
    )
    visible = scene.points_visible()
    assert 60 < visible.sum() < FIDUCIAL_BOARD.n_points - 10
    det = detect_board(scene.image, FIDUCIAL_BOARD)
    assert det.partial and len(det.ids) >= visible.sum() - 10
    # The dots that a finger cuts are left out (their blobs are dots' parts), as are the
    # few beside them left without enough neighbours to check them against.
    assert any("left out" in w for w in det.warnings)
    err = _errors(det, scene)
    assert np.median(err) < 0.02 and err.max() < 0.5  # the worst: half washed out by glare


def test_a_partial_view_is_held_to_the_stated_dot_size() -> None:
    pose = synth.PlanePose(distance_mm=420, tilt_deg=10, look_at_mm=(300, 90))
    scene = synth.render_scene(synth.CameraModel(), pose, board=FIDUCIAL_BOARD, seed=1)
    det = detect_board(scene.image, FIDUCIAL_BOARD)
    assert det.partial and det.sizes is not None and det.sizes.tolerance is not None
    wrong = CircleGridBoard(14, 10, 20.0, 14.0, fiducials=(31, 38, 101), fiducial_diameter=17)
    with pytest.raises(BoardMismatchError, match="the diameter or the pitch is wrong"):
        detect_board(scene.image, wrong)


MARKER_BOARD = CircleGridBoard(9, 7, 25.0, 12.0, origin_marker=True)


@pytest.mark.parametrize("look", [(40, 40), (100, 30), (200, 40)])
def test_a_marker_board_cut_off_is_read_when_the_view_fixes_it(look: tuple[int, int]) -> None:
    pose = synth.PlanePose(distance_mm=250 if look[0] < 150 else 330, tilt_deg=15, look_at_mm=look)
    scene = synth.render_scene(
        synth.CameraModel(), pose, board=MARKER_BOARD, blur_sigma_px=0.8, noise_sigma=2.0, seed=3
    )
    assert not scene.dots_in_view().all()
    det = detect_board(scene.image, MARKER_BOARD)
    assert det.partial and det.orientation == "marker"
    assert _errors(det, scene).max() < 0.05


def test_a_marker_board_cut_off_without_its_marker_is_ambiguous() -> None:
    pose = synth.PlanePose(distance_mm=330, tilt_deg=15, look_at_mm=(40, 140))
    scene = synth.render_scene(
        synth.CameraModel(), pose, board=MARKER_BOARD, blur_sigma_px=0.8, noise_sigma=2.0, seed=3
    )
    assert not scene.dots_in_view()[0]
    with pytest.raises(BoardNotFoundError, match="partial and ambiguous") as err:
        detect_board(scene.image, MARKER_BOARD)
    assert "let its enlarged dots be seen" in str(err.value)


def test_a_plain_board_cut_off_is_refused_as_partial_and_ambiguous() -> None:
    board = CircleGridBoard(14, 10, 20.0, 10.0)
    pose = synth.PlanePose(distance_mm=420, look_at_mm=(300, 90))
    scene = synth.render_scene(synth.CameraModel(), pose, board=board, blur_sigma_px=0.8, seed=6)
    seen = int(scene.dots_in_view().sum())
    with pytest.raises(BoardNotFoundError) as err:
        detect_board(scene.image, board)
    message = str(err.value)
    assert f"{seen} of the board's 140 dots seen" in message
    assert "partial and ambiguous" in message
    assert "origin marker" in message and "fiducial" in message
    assert "whole board in view" in message


def test_a_plain_board_in_full_view_with_glare_is_read_without_the_lost_dots() -> None:
    """More dots lost than a whole board may miss (one in fifty): the lattice is still as
    large as the board, so it fits one way (up to the board's half turn)."""
    board = CircleGridBoard(14, 10, 20.0, 10.0)
    pose = synth.PlanePose(distance_mm=560, tilt_deg=10, look_at_mm=(130, 90))
    clean = synth.render_scene(synth.CameraModel(), pose, board=board, blur_sigma_px=0.8, seed=2)
    image = clean.image.copy()
    lost = [20, 21, 50, 66, 67, 90]
    for k in lost:
        centre = tuple(int(v) for v in np.rint(clean.dot_centres_px[k]))
        cv2.circle(image, centre, 14, 225, -1)
    det = detect_board(image, board)
    assert det.partial and det.orientation == "ambiguous"
    flipped = board.n_points - 1 - det.ids  # the half-turned reading, if that was the rule's
    truth = clean.dot_centres_px
    err = min(
        np.abs(det.image_points - truth[det.ids]).max(),
        np.abs(det.image_points - truth[flipped]).max(),
    )
    assert err < 0.05
    assert len(det.ids) == board.n_points - len(lost)


# --------------------------------------------------------------------------- the command line


def test_the_command_line_reads_a_cut_off_plate_by_its_fiducials(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`planarcal calibrate --fiducials` reads the plate with four columns cut off by the
    image's edge, saves the dots it saw by id, and refuses the same view described without
    them, saying how to describe them."""
    crop = tmp_path / "crop.png"
    cv2.imwrite(str(crop), _ucl("14_09_35")[:, 620:])
    board = ["--cols", "16", "--rows", "14", "--pitch", "5"]
    out = tmp_path / "cal.json"
    assert (
        cli.main(["calibrate", str(crop), *board, "--fiducials", "69,74,149,154", "-o", str(out)])
        == 0
    )
    cal = Calibration.load(out)
    assert cal.board == UCL_BOARD
    ids = np.asarray(cal.point_ids)
    assert 150 < len(ids) < 224 and 0 not in ids and {69, 74, 149, 154} <= set(ids.tolist())
    capsys.readouterr()
    assert cli.main(["calibrate", str(crop), *board, "-o", str(tmp_path / "no.json")]) == 1
    said = capsys.readouterr().err
    assert "partial and ambiguous" in said and "--fiducials K,K" in said
