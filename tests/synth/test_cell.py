"""planarcal.synth.cell: a work cell with the board at several placements, and its truth."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.detection import BoardDetection, detect_board
from planarcal.errors import ArgumentError, PlacementError
from planarcal.synth.cell import (
    CELL_BOARDS,
    PAPER_MARGIN_MM,
    Cell,
    mirrored_detection,
    render_cell,
)

F64 = NDArray[np.float64]


@pytest.fixture(scope="module")
def circles() -> Cell:
    return render_cell("circles", 6, seed=3, raised_mm={4: 10.0}, lifted_mm={5: 3.0})


@pytest.fixture(scope="module")
def chessboard() -> Cell:
    return render_cell("chessboard", 4, seed=5)


def _projected(cell: Cell, table_3d: F64) -> F64:
    """OpenCV's projection of table points (x, y, z) through the cell's camera and pose."""
    rvec, tvec = cell.pose.rvec_tvec()
    px, _ = cv2.projectPoints(
        table_3d.reshape(-1, 1, 3), rvec, tvec, cell.camera.matrix(), cell.camera.dist_coeffs()
    )
    return np.asarray(px.reshape(-1, 2), np.float64)


def _rot(angle_deg: float) -> F64:
    a = math.radians(angle_deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


@pytest.mark.parametrize("name", ["circles", "chessboard"])
def test_flat_boards_truth_is_opencvs_projection_of_their_table_points(
    name: str, request: pytest.FixtureRequest
) -> None:
    cell: Cell = request.getfixturevalue(name)
    for p in cell.placements:
        if not p.flat:
            continue
        table = cell.board.world_points() @ _rot(p.angle_deg).T + np.array(p.origin_mm)
        np.testing.assert_allclose(p.scene.points_mm, table, atol=1e-9)
        opencv = _projected(cell, np.column_stack([table, np.zeros(len(table))]))
        np.testing.assert_allclose(p.scene.points_px, opencv, atol=1e-6)
        np.testing.assert_allclose(cell.pixel_of(table), opencv, atol=1e-6)


@pytest.mark.parametrize("name", ["circles", "chessboard"])
def test_plane_truth_is_the_reference_boards_frame_and_poses_agree(
    name: str, request: pytest.FixtureRequest
) -> None:
    cell: Cell = request.getfixturevalue(name)
    world = cell.board.world_points()
    ref = cell.placements[cell.reference]
    np.testing.assert_allclose(cell.truth_plane_mm(ref.scene.points_mm), world, atol=1e-9)
    for p in cell.placements:
        angle, offset = cell.true_pose(p.index)
        # plane = R(angle) board + offset, the pose a calibration reports.
        expected = world @ _rot(angle).T + np.array(offset)
        np.testing.assert_allclose(cell.truth_plane_mm(p.scene.points_mm), expected, atol=1e-9)
        np.testing.assert_allclose(cell.table_mm(expected), p.scene.points_mm, atol=1e-9)
    assert cell.true_pose(cell.reference) == (0.0, (0.0, 0.0))


def test_rendered_images_show_the_points_at_their_truth(chessboard: Cell) -> None:
    for p in chessboard.placements:
        detection = detect_board(p.image, chessboard.board)
        assert len(detection.ids) == chessboard.board.n_points
        err = np.hypot(*(detection.image_points - p.scene.points_px[detection.ids]).T)
        assert err.max() < 0.1


def test_raised_board_is_rendered_on_its_plane(circles: Cell) -> None:
    p = circles.placements[4]
    assert p.raised_mm == 10.0 and not p.flat
    table = p.scene.points_mm
    opencv = _projected(circles, np.column_stack([table, np.full(len(table), -10.0)]))
    np.testing.assert_allclose(p.scene.points_px, opencv, atol=1e-6)
    flat = circles.pixel_of(table)
    assert np.hypot(*(p.scene.points_px - flat).T).min() > 1.0  # it shows: 10 mm is 2% nearer
    detection = detect_board(p.image, circles.board)
    err = np.hypot(*(detection.image_points - p.scene.points_px[detection.ids]).T)
    assert err.max() < 0.1


def test_lifted_board_is_turned_about_its_edge(circles: Cell) -> None:
    p = circles.placements[5]
    assert p.lifted_mm == 3.0
    x0, _, x1, _ = circles.board.ink().field
    hinge = x0 - PAPER_MARGIN_MM
    width = x1 + PAPER_MARGIN_MM - hinge
    sin_b = 3.0 / width
    cos_b = math.sqrt(1.0 - sin_b**2)
    world = circles.board.world_points()
    along = world[:, 0] - hinge
    # Each point along the board keeps its distance from the hinge, foreshortened on the
    # table, and rises in proportion to it: the +x edge of the paper 3 mm up.
    board_xy = np.column_stack([hinge + along * cos_b, world[:, 1]])
    table = board_xy @ _rot(p.angle_deg).T + np.array(p.origin_mm)
    opencv = _projected(circles, np.column_stack([table, -along * sin_b]))
    np.testing.assert_allclose(p.scene.points_px, opencv, atol=1e-6)
    assert np.hypot(*(p.scene.points_px - circles.pixel_of(p.scene.points_mm)).T).max() > 0.3


def test_placements_are_spread_over_an_area_three_boards_wide(circles: Cell) -> None:
    w, h = circles.area_mm
    bw, bh = circles.board_size_mm
    assert w >= 3 * bw - 1e-9 and h >= 3 * bh - 1e-9
    assert len(circles.placements) == 6 and len(circles.images) == 6
    centres = np.array([p.centre_mm for p in circles.placements])
    # The first in the middle, the next four in the corners (outside the middle third).
    np.testing.assert_allclose(centres[0], [w / 2, h / 2], atol=0.1 * bw)
    for c in centres[1:5]:
        assert abs(c[0] - w / 2) > w / 6 and abs(c[1] - h / 2) > h / 6
    angles = [p.angle_deg for p in circles.placements]
    assert max(angles) - min(angles) > 30.0 and max(abs(a) for a in angles) <= 35.0
    # Every board's paper within the area, every placement on its own image.
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * np.array([bw, bh]) / 2
    for p in circles.placements:
        paper = corners @ _rot(p.angle_deg).T + np.array(p.centre_mm)
        assert (paper >= -1e-9).all() and (paper <= np.array([w, h]) + 1e-9).all()
    assert all(p.scene.points_in_view(2.0).all() for p in circles.placements)
    # The area fills the image: its corners near the image's.
    px = circles.pixel_of(np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]]))
    assert px[:, 0].min() < 0.1 * 1280 and px[:, 0].max() > 0.9 * 1280


def test_distances_to_the_boards(circles: Cell) -> None:
    ref = circles.placements[0]
    assert circles.distance_to_boards_mm(ref.scene.points_mm).max() < 1e-9
    grid = circles.area_points(20.0)
    assert grid.min(axis=0).tolist() == [0.0, 0.0]
    assert grid.max(axis=0).tolist() == list(circles.area_mm)
    d = circles.distance_to_boards_mm(grid)
    assert d.shape == (len(grid),) and (d >= 0).all() and (d > 50.0).any()
    # The raised and lifted boards do not count: their points are far from the flat ones'.
    assert circles.distance_to_boards_mm(circles.placements[4].scene.points_mm).min() > 10.0


def test_explicit_places_and_reference() -> None:
    cell = render_cell("chessboard", [(200.0, 150.0, 0.0), (450.0, 300.0, 20.0)], reference=1)
    assert [p.centre_mm for p in cell.placements] == [(200.0, 150.0), (450.0, 300.0)]
    assert cell.reference == 1 and cell.true_pose(1) == (0.0, (0.0, 0.0))
    angle, _ = cell.true_pose(0)
    assert angle == pytest.approx(-20.0)
    np.testing.assert_allclose(
        cell.truth_plane_mm(cell.placements[1].scene.points_mm),
        cell.board.world_points(),
        atol=1e-9,
    )


def test_mirrored_detection_claims_the_mirror_images_ids(chessboard: Cell) -> None:
    p = chessboard.placements[1]
    detection = detect_board(p.image, chessboard.board)
    wrong = mirrored_detection(detection)
    assert isinstance(wrong, BoardDetection)
    assert (np.diff(wrong.ids) > 0).all() and len(wrong.ids) == len(detection.ids)
    world = chessboard.board.world_points()
    cols = chessboard.board.cols
    for k in (0, 5, 17):
        i = int(np.flatnonzero(wrong.ids == k)[0])
        j = int(np.flatnonzero(detection.ids == (k // cols) * cols + cols - 1 - k % cols)[0])
        np.testing.assert_array_equal(wrong.image_points[i], detection.image_points[j])
    # The same image points, claimed by the mirrored board: far from their truth.
    err = np.hypot(*(wrong.image_points - p.scene.points_px[wrong.ids]).T)
    assert np.median(err) > 20.0
    assert world.shape[0] == len(wrong.ids)


def test_same_seed_same_cell_and_seeds_differ() -> None:
    a = render_cell("chessboard", 1, seed=7, supersample=1)
    b = render_cell("chessboard", 1, seed=7, supersample=1)
    c = render_cell("chessboard", 1, seed=8, supersample=1)
    np.testing.assert_array_equal(a.images[0], b.images[0])
    assert a.placements[0].centre_mm != c.placements[0].centre_mm


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"placements": 0}, "placements must be 1 to 9"),
        ({"placements": 10}, "placements must be 1 to 9"),
        ({"placements": True}, "placements must be a count"),
        ({"placements": [(1.0, 2.0)]}, r"placements\[0\] must be"),
        ({"placements": [(1.0, 2.0, math.nan)]}, "must be finite"),
        ({"board": "hexagons"}, "board must be a board or one of"),
        ({"board": 3}, "board must be a board"),
        ({"area_boards": 2.0}, "area_boards must be 3 to 10"),
        ({"camera": "webcam"}, "camera must be a CameraModel"),
        ({"tilt_deg": 45.0}, "tilt_deg must be 0 to 30"),
        ({"raised_mm": {6: 5.0}}, "placement 6 does not exist"),
        ({"raised_mm": {1: -5.0}}, "must be 0 to 100 mm"),
        ({"raised_mm": [5.0]}, "must map placement indices"),
        ({"lifted_mm": {0: 3.0}}, "reference placement 0 must lie flat"),
        (
            {"board": CircleGridBoard(3, 3, 5.0, 2.0), "lifted_mm": {1: 50.0}},
            "more than the board's paper is wide",
        ),
        ({"reference": 6}, "reference 6 is not a placement"),
        ({"seed": -1}, "seed must be a non-negative"),
        ({"placements": [(-500.0, 0.0, 0.0)]}, "reaches outside the image"),
    ],
)
def test_bad_arguments_raise_argument_error(kwargs: dict[str, object], words: str) -> None:
    args: dict[str, object] = {"board": "chessboard", "placements": 6, "supersample": 1}
    args.update(kwargs)
    with pytest.raises(ArgumentError, match=words):
        render_cell(**args)  # type: ignore[arg-type]


def test_bad_queries_raise_argument_error(chessboard: Cell) -> None:
    with pytest.raises(ArgumentError, match="placement 4 does not exist"):
        chessboard.true_pose(4)
    with pytest.raises(ArgumentError, match="step_mm must be positive"):
        chessboard.area_points(0.0)
    with pytest.raises(ArgumentError, match="detection must be a BoardDetection"):
        mirrored_detection("detection")  # type: ignore[arg-type]
    assert set(CELL_BOARDS) == {"circles", "chessboard", "charuco"}


def test_a_calibration_from_the_cell_maps_the_whole_area_to_its_truth(chessboard: Cell) -> None:
    detections = [detect_board(image, chessboard.board) for image in chessboard.images]
    cal = Calibration.from_detections(detections, reference=chessboard.reference)
    table = chessboard.area_points(20.0)
    mm = cal.image_to_world(chessboard.pixel_of(table))
    err = np.hypot(*(mm - chessboard.truth_plane_mm(table)).T)
    assert err.mean() < 0.02 and err.max() < 0.1
    for p in cal.placements:
        angle, offset = chessboard.true_pose(p.index)
        assert abs(p.angle_deg - angle) < 0.01
        assert np.hypot(*(np.array(p.offset_mm) - offset)) < 0.05
    # The same pixels through the reference board alone, extrapolated: far worse away from it.
    alone = Calibration.from_detection(detections[chessboard.reference])
    far = chessboard.distance_to_boards_mm(table, 1) > 100.0
    alone_err = np.hypot(
        *(alone.image_to_world(chessboard.pixel_of(table)) - chessboard.truth_plane_mm(table)).T
    )
    assert alone_err[far].mean() > 20 * err[far].mean()


@pytest.mark.parametrize(
    ("bad", "looks"),
    [(4, "seen 1.* larger than a board on the plane"), (5, "squeezed .*lifted on one side")],
    ids=["on a 10 mm part", "lifted 3 mm"],
)
def test_a_board_not_flat_is_named(circles: Cell, bad: int, looks: str) -> None:
    images = [*circles.images[:4], circles.images[bad]]
    detections = [detect_board(image, circles.board) for image in images]
    with pytest.raises(PlacementError, match=looks) as caught:
        Calibration.from_detections(detections)
    assert caught.value.placement == 4
    assert "not flat on the plane; take that image again" in str(caught.value)
