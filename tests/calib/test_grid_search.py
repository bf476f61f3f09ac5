"""The board search's parts on exact inputs: blobs (planarcal.calib.blobs) and lattices with the
board's pattern placed on them (planarcal.calib.grid_search)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import planarcal
from planarcal.calib.blobs import Blobs, find_blobs
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.grid_search import (
    board_pattern,
    fill_holes,
    grow_lattices,
    lattice_extent,
    lattice_to_world,
    place_board,
)

H = np.array([[2.2, 0.4, 120.0], [-0.3, 2.0, 90.0], [6e-4, -4e-4, 1.0]])


def _grid_blobs(board: CircleGridBoard, h: np.ndarray = H, size: float = 18.0) -> Blobs:
    pts = planarcal.transform_points(h, board.world_points())
    pts += 0.02 * np.sin(np.arange(pts.size)).reshape(pts.shape)  # a little lens wobble
    order = np.random.default_rng(0).permutation(len(pts))
    return Blobs(pts[order], np.full(len(pts), size), np.full(len(pts), 5, np.int64))


def _with(blobs: Blobs, centres: np.ndarray, diameters: np.ndarray) -> Blobs:
    return Blobs(
        np.vstack([blobs.centres, centres]),
        np.concatenate([blobs.diameters, diameters]),
        np.concatenate([blobs.levels, np.full(len(diameters), 5, np.int64)]),
    )


def _placed(blobs: Blobs, board: CircleGridBoard) -> np.ndarray:
    lattices = grow_lattices(blobs, 4, 3 * board.n_points)
    placements = [p for lat in lattices for p in place_board(lat, board)]
    assert len(placements) == 1
    return fill_holes(placements[0], blobs.centres)


def _same_up_to_a_reading(found: np.ndarray, board: CircleGridBoard, truth: np.ndarray) -> bool:
    """Whether `found` is the board's points in one of its symmetric readings."""
    world = board.world_points()
    h = planarcal.estimate_homography(world, found)
    return bool(np.abs(planarcal.transform_points(h, world) - found).max() < 0.2) and bool(
        np.linalg.norm(found[:, None] - truth[None], axis=2).min(axis=1).max() < 1e-9
    )


def test_a_shuffled_distorted_grid_is_put_back_in_order() -> None:
    board = CircleGridBoard(7, 5, 20.0, 10.0)
    blobs = _grid_blobs(board)
    found = _placed(blobs, board)
    assert _same_up_to_a_reading(found, board, blobs.centres)


def test_marks_off_the_lattice_and_small_marks_on_it_are_left_out() -> None:
    board = CircleGridBoard(7, 5, 20.0, 10.0)
    blobs = _grid_blobs(board)
    world = board.world_points()
    # Printed numbers beside the dots (off the lattice, dot-sized) and small marks one row
    # above the board (on the lattice, a third of a dot).
    beside = planarcal.transform_points(H, world[::3] + np.array([9.0, 7.0]))
    above = planarcal.transform_points(H, np.column_stack([world[:7, 0], np.full(7, -20.0)]))
    cluttered = _with(
        blobs,
        np.vstack([beside, above]),
        np.concatenate([np.full(len(beside), 16.0), np.full(7, 6.0)]),
    )
    found = _placed(cluttered, board)
    assert _same_up_to_a_reading(found, board, blobs.centres)


def test_an_enlarged_dot_as_wide_as_the_pitch_joins_the_grid() -> None:
    board = CircleGridBoard(6, 6, 20.0, 10.0)
    blobs = _grid_blobs(board)
    sizes = blobs.diameters.copy()
    sizes[3] = 40.0  # twice the others: as wide as the pitch in the image
    found = _placed(Blobs(blobs.centres, sizes, blobs.levels), board)
    assert _same_up_to_a_reading(found, board, blobs.centres)


def test_a_missing_dot_is_filled_in_where_its_neighbours_put_it() -> None:
    board = CircleGridBoard(10, 8, 20.0, 10.0)
    full = _grid_blobs(board)
    truth = planarcal.transform_points(H, board.world_points())
    gone = int(np.argmin(np.linalg.norm(full.centres - truth[34], axis=1)))
    keep = np.arange(len(full)) != gone
    found = _placed(full.subset(keep), board)
    k = int(np.argmin(np.linalg.norm(found - truth[34], axis=1)))
    assert np.linalg.norm(found[k] - truth[34]) < 0.2
    # Two missing dots on an 80-dot board are more than it may miss: no placement.
    twice = keep & (np.arange(len(full)) != (gone + 1) % len(full))
    lattices = grow_lattices(full.subset(twice), 4, 240)
    assert not any(place_board(lat, board) for lat in lattices)


def test_a_larger_grid_fits_the_board_more_than_one_way() -> None:
    big = _grid_blobs(CircleGridBoard(14, 10, 20.0, 10.0))
    (lattice,) = grow_lattices(big, 4, 300)
    assert len(place_board(lattice, CircleGridBoard(10, 8, 20.0, 10.0))) >= 2
    assert len(place_board(lattice, CircleGridBoard(14, 10, 20.0, 10.0))) == 1
    across, down = lattice_extent(lattice, big.centres)
    assert (across, down) == (14, 10)


def test_a_lattice_stops_growing_at_its_limit() -> None:
    big = _grid_blobs(CircleGridBoard(20, 20, 20.0, 10.0), h=np.diag([1.5, 1.5, 1.0]))
    lattices = grow_lattices(big, 4, 100)
    assert 100 <= len(lattices[0].blob) <= 103  # the rest of the grid grows apart


@pytest.mark.parametrize(("cols", "rows"), [(4, 11), (5, 6)])
def test_asymmetric_grids_are_placed_on_their_diagonal_lattice(cols: int, rows: int) -> None:
    board = CircleGridBoard(cols, rows, 15.0, 10.0, layout="asymmetric")
    pattern = board_pattern(board)
    np.testing.assert_allclose(lattice_to_world(board, pattern), board.world_points())
    blobs = _grid_blobs(board)
    found = _placed(blobs, board)
    assert _same_up_to_a_reading(found, board, blobs.centres)


def test_blobs_are_filled_ellipses_of_the_sizes_asked_for() -> None:
    image = np.full((240, 320), 210, np.uint8)
    cv2.circle(image, (40, 40), 12, 30, -1)  # a dot
    cv2.ellipse(image, (120, 40), (16, 8), 30, 0, 360, 30, -1)  # a tilted dot
    cv2.circle(image, (200, 40), 12, 30, 3)  # a ring (a printed "0")
    cv2.rectangle(image, (250, 20), (300, 26), 30, -1)  # a bar (text)
    cv2.circle(image, (40, 150), 1, 30, -1)  # too small
    cv2.circle(image, (160, 160), 60, 30, -1)  # too large for the range asked
    blobs = find_blobs(image, 3.5, 80.0)
    assert len(blobs) == 2
    order = np.argsort(blobs.centres[:, 0])
    np.testing.assert_allclose(blobs.centres[order], [[40, 40], [120, 40]], atol=0.3)
    assert abs(blobs.diameters[order][0] - 25.0) < 2.0


def test_noise_gives_few_blobs() -> None:
    noise = np.random.default_rng(0).integers(0, 256, (480, 640), dtype=np.uint8)
    assert len(find_blobs(noise, 3.5, 400.0)) < 50
