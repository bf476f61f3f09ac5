"""Several copies of one board in one image, each a placement (issue 23): rendered 1280 x 960
images through a distorting lens with blur, noise and uneven light, 2-4 copies of a circle
grid, a chessboard and a ChArUco board (its marker ids repeated in every copy) at different
places and angles; every copy found as it would be alone, and one calibration from them."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal import Calibration, detect_board, detect_board_copies
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import Board
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.calib.detection import BoardDetection
from planarcal.errors import ArgumentError, BoardNotFoundError, BoardTurnedError
from planarcal.synth import PAPER_EFFECTS, PlanePose, render_scene
from planarcal.synth.copies import RenderedCopies, relative_pose, render_copies

F64 = NDArray[np.float64]

BOARDS: dict[str, Board] = {
    "circles": CircleGridBoard(cols=9, rows=7, pitch=20.0, diameter=10.0, origin_marker=True),
    "chessboard": ChessboardBoard(cols=9, rows=6, square=20.0, origin_marker=True),
    "charuco": CharucoBoard(squares_x=9, squares_y=7, square=20.0, marker=15.0),
}
# Each copy's (x, y, angle_deg): the middle of its printed field on the table. Two rows of
# copies, listed in reading order (the table's x runs right in the image, its y down).
PLACES: dict[str, list[tuple[float, float, float]]] = {
    "circles": [
        (160.0, 140.0, 10.0),
        (440.0, 150.0, -25.0),
        (170.0, 390.0, 35.0),
        (460.0, 400.0, -5.0),
    ],
    "chessboard": [(160.0, 140.0, -15.0), (430.0, 130.0, 20.0), (300.0, 370.0, 0.0)],
    "charuco": [
        (160.0, 140.0, 30.0),
        (440.0, 150.0, 5.0),
        (170.0, 390.0, -20.0),
        (460.0, 400.0, 15.0),
    ],
}
EFFECTS = dict(PAPER_EFFECTS)  # blur 0.8 px, noise 2.5, a lamp's gradient, vignetting


@pytest.fixture(scope="module", params=sorted(BOARDS))
def scene(request: pytest.FixtureRequest) -> tuple[RenderedCopies, list[BoardDetection]]:
    kind = str(request.param)
    rendered = render_copies(BOARDS[kind], PLACES[kind], seed=11, effects=EFFECTS)
    return rendered, detect_board_copies(rendered.image, BOARDS[kind])


def _copy_of(rendered: RenderedCopies, detection: BoardDetection) -> int:
    """The rendered copy a detection's points lie nearest to."""
    centre = detection.image_points.mean(axis=0)
    gaps = [np.hypot(*(c.points_px.mean(axis=0) - centre)) for c in rendered.copies]
    return int(np.argmin(gaps))


def test_every_copy_is_found_in_reading_order_with_its_ids_and_points(
    scene: tuple[RenderedCopies, list[BoardDetection]],
) -> None:
    rendered, found = scene
    assert rendered.image.shape == (960, 1280)
    assert [_copy_of(rendered, d) for d in found] == list(range(len(rendered.copies)))
    for d, copy in zip(found, rendered.copies, strict=True):
        assert not d.partial and d.orientation == "marker"
        err = np.hypot(*(d.image_points - copy.points_px[d.ids]).T)
        assert err.max() < 0.05, (copy.index, err.max())


def test_each_copy_is_found_as_it_would_be_alone(
    scene: tuple[RenderedCopies, list[BoardDetection]],
) -> None:
    rendered, found = scene
    board = rendered.board
    kind = board.kind
    k = len(found) - 1  # the copy found last among the others
    alone = render_copies(board, [PLACES[kind][k]], pose=rendered.pose, seed=11, effects=EFFECTS)
    single = detect_board(alone.image, board)
    assert np.array_equal(single.ids, found[k].ids)
    assert np.abs(single.image_points - found[k].image_points).max() <= 0.01


def test_a_calibration_from_the_copies_has_their_poses_and_maps_the_area(
    scene: tuple[RenderedCopies, list[BoardDetection]],
) -> None:
    rendered, found = scene
    cal = Calibration.from_detections(found)
    for p in cal.placements:
        angle, offset = rendered.true_pose(p.index)
        assert abs(p.angle_deg - angle) < 0.02, (p.index, p.angle_deg, angle)
        assert np.hypot(*(np.array(p.offset_mm) - offset)) < 0.05, (p.index, p.offset_mm, offset)
    table, px = _area(rendered)
    err = np.hypot(*(cal.image_to_world(px) - rendered.truth_plane_mm(table)).T)
    assert err.mean() <= 0.02 and err.max() <= 0.1, (err.mean(), err.max())


def _area(rendered: RenderedCopies) -> tuple[F64, F64]:
    """Table points over the box the copies' points span (between the copies too), and their
    exact pixels."""
    points = np.vstack([c.points_mm for c in rendered.copies])
    lo, hi = points.min(axis=0), points.max(axis=0)
    xs, ys = np.meshgrid(np.linspace(lo[0], hi[0], 30), np.linspace(lo[1], hi[1], 24))
    table = np.column_stack([xs.ravel(), ys.ravel()])
    return table, rendered.pixel_of(table)


def test_copies_mix_with_an_image_of_a_single_placement(tmp_path: Path) -> None:
    board = BOARDS["circles"]
    copies = render_copies(board, PLACES["circles"][:2], seed=5, effects=EFFECTS)
    other = render_copies(board, [(300.0, 300.0, 60.0)], pose=copies.pose, seed=6, effects=EFFECTS)
    path = tmp_path / "copies.png"
    assert cv2.imwrite(str(path), cv2.cvtColor(copies.image, cv2.COLOR_GRAY2BGR))
    found = detect_board_copies(path, board)  # a file, read as BGR
    assert len(found) == 2
    cal = Calibration.from_detections(
        [*found, detect_board(other.image, board)], names=["copy 0", "copy 1", "alone"]
    )
    p = cal.placements[2]
    angle, offset = relative_pose(other.copies[0], copies.copies[0])
    assert p.name == "alone"
    assert abs(p.angle_deg - angle) < 0.02
    assert np.hypot(*(np.array(p.offset_mm) - offset)) < 0.05


def test_a_copy_cut_by_the_image_edge_counts_as_a_partial_view() -> None:
    board = BOARDS["charuco"]
    places = PLACES["charuco"][:2]
    whole = render_copies(board, places, seed=7)
    p = whole.pose
    # The camera aimed 150 mm further to +x: the left copy runs off the image's left edge.
    shifted = PlanePose(
        p.distance_mm,
        tilt_deg=p.tilt_deg,
        tilt_axis_deg=p.tilt_axis_deg,
        look_at_mm=(p.look_at_mm[0] + 150.0, p.look_at_mm[1]),
    )
    rendered = render_copies(board, places, pose=shifted, seed=7, effects=EFFECTS)
    w, h = rendered.camera.width, rendered.camera.height
    in_view = rendered.copies[0].in_view(w, h, 5.0)
    assert 10 <= in_view.sum() < board.n_points
    found = detect_board_copies(rendered.image, board)
    assert [_copy_of(rendered, d) for d in found] == [0, 1]
    cut, whole_copy = found
    assert cut.partial and not whole_copy.partial
    assert set(cut.ids) <= set(np.flatnonzero(rendered.copies[0].in_view(w, h)))
    assert len(cut.ids) >= 0.8 * in_view.sum()
    err = np.hypot(*(cut.image_points - rendered.copies[0].points_px[cut.ids]).T)
    assert err.max() < 0.05


def test_max_copies_stops_early() -> None:
    board = BOARDS["chessboard"]
    rendered = render_copies(board, PLACES["chessboard"], seed=3)
    assert len(detect_board_copies(rendered.image, board, max_copies=1)) == 1
    with pytest.raises(ArgumentError, match="max_copies"):
        detect_board_copies(rendered.image, board, max_copies=0)


@pytest.mark.parametrize("kind", sorted(BOARDS))
def test_an_image_without_a_copy_is_refused(kind: str) -> None:
    empty = render_scene(board=None, seed=1, noise_sigma=2.0, blur_sigma_px=0.8)
    with pytest.raises(BoardNotFoundError):
        detect_board_copies(empty.image, BOARDS[kind])


def test_bad_arguments_are_named() -> None:
    with pytest.raises(ArgumentError, match="board must be"):
        detect_board_copies(np.zeros((100, 100), np.uint8), "circles")  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match="overlap"):
        render_copies("circles", [(200.0, 200.0, 0.0), (300.0, 220.0, 10.0)])
    with pytest.raises(ArgumentError, match="unknown effects"):
        render_copies("circles", [(200.0, 200.0, 0.0)], effects={"glow": 1.0})


@pytest.mark.parametrize("kind", sorted(BOARDS))
def test_one_copy_renders_as_render_scene_does(kind: str) -> None:
    board = BOARDS[kind]
    rendered = render_copies(board, [(150.0, 130.0, 12.0)], seed=4, effects=EFFECTS)
    copy = rendered.copies[0]
    scene = render_scene(
        rendered.camera,
        rendered.pose,
        board=board,
        board_origin_mm=copy.origin_mm,
        board_angle_deg=copy.angle_deg,
        seed=4,
        supersample=4,
        **EFFECTS,  # type: ignore[arg-type]
    )
    assert np.array_equal(rendered.image, scene.image)
    assert np.array_equal(copy.points_px, scene.points_px)


def test_a_copy_turned_by_90_degrees_is_named_unless_turned_is_given() -> None:
    board = CircleGridBoard(cols=9, rows=7, pitch=20.0, diameter=10.0)  # no marker
    rendered = render_copies(board, [(160.0, 140.0, 5.0), (420.0, 160.0, 88.0)], seed=2)
    with pytest.raises(BoardTurnedError, match=r"1 of the 2 copies found .* turned=True"):
        detect_board_copies(rendered.image, board)
    found = detect_board_copies(rendered.image, board, turned=True)
    assert [_copy_of(rendered, d) for d in found] == [0, 1]
    for d, copy in zip(found, rendered.copies, strict=True):
        # No marker: each copy is read from the corner its detector's rule names, so compare
        # where its points lie, not their ids.
        gap = np.hypot(*(d.image_points[:, None, :] - copy.points_px[None]).T)
        assert gap.min(axis=1).max() < 0.05
