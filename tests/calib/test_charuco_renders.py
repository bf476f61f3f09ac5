"""Rendered ChArUco images with exact corner truth, for the ChArUco detector's tests and
benches/bench_charuco.py: OpenCV's own ``generateImage`` of the board at high resolution,
warped by a known homography onto a 4x finer grid and area-averaged down, so that every
pixel is the mean of the board over its area (the inner corners' truth is exact: the
homography of their board positions). Tested here: the truth lands on the corners
``cv2.findChessboardCornersSB`` measures on a plain chessboard render made the same way.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.calib.charuco import CharucoBoard

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]

SUPERSAMPLE = 4


def view_homography(
    board: CharucoBoard,
    size: tuple[int, int],
    *,
    fill: float = 0.7,
    tilt_x: float = 0.0,
    tilt_y: float = 0.0,
    turn: float = 0.0,
    shift: tuple[float, float] = (0.0, 0.0),
    focal_px: float | None = None,
) -> F64:
    """Board mm -> image px for a pinhole camera looking at the board's centre, the board
    tilted by tilt_x / tilt_y degrees and turned by `turn` degrees in its plane, its width
    `fill` of the image's (before the tilt), moved by `shift` (fractions of the image)."""
    w, h = size
    f = focal_px if focal_px is not None else 1.2 * max(w, h)
    k = np.array(
        [[f, 0, (w - 1) / 2 + shift[0] * w], [0, f, (h - 1) / 2 + shift[1] * h], [0, 0, 1]]
    )
    ex, ey = board.extent
    distance = f * ex / (fill * w)
    ax, ay, az = (math.radians(a) for a in (tilt_x, tilt_y, turn))
    rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
    ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    rz = np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])
    r = rx @ ry @ rz
    centre = np.array([[1, 0, -ex / 2], [0, 1, -ey / 2], [0, 0, 1]])
    h_mm = k @ np.column_stack([r[:, 0], r[:, 1], [0, 0, distance]]) @ centre
    return np.asarray(h_mm / h_mm[2, 2], np.float64)


def render_charuco(
    board: CharucoBoard,
    homography: F64,
    size: tuple[int, int],
    *,
    legacy: bool = False,
    blur: float = 0.0,
    noise: float = 0.0,
    background: int = 110,
    seed: int = 0,
) -> tuple[U8, F64]:
    """The board seen through `homography` (board mm -> px, pixel centres at integers) in
    an image of `size` (w, h): 8-bit grey, white paper one square wide around the board on a
    `background` grey, then Gaussian `blur` (sigma px) and sensor `noise` (sigma grey levels).
    Returns the image and every inner corner's true pixel position (board.world_points()
    order)."""
    w, h = size
    s = SUPERSAMPLE
    jac = np.linalg.norm(homography[:2, :2], axis=0).max() / abs(homography[2, 2])
    px_per_mm = max(2.0, 1.5 * s * jac)
    square_px = max(8, math.ceil(board.square * px_per_mm))
    g = square_px / board.square  # source px per mm
    margin = square_px
    out = (board.squares_x * square_px + 2 * margin, board.squares_y * square_px + 2 * margin)
    source = board.opencv_board(legacy).generateImage(out, marginSize=margin, borderBits=1)
    # Source pixel-centre coordinates -> board mm -> final px -> supersampled px.
    to_mm = np.array(
        [[1 / g, 0, 0.5 / g - board.square], [0, 1 / g, 0.5 / g - board.square], [0, 0, 1]]
    )
    to_up = np.array([[s, 0, 0.5 * s - 0.5], [0, s, 0.5 * s - 0.5], [0, 0, 1]])
    m = to_up @ homography @ to_mm
    big = cv2.warpPerspective(
        source,
        m,
        (w * s, h * s),
        flags=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=background,
    )
    image = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA).astype(np.float64)
    if blur > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur)
    if noise > 0:
        image = image + np.random.default_rng(seed).normal(0.0, noise, image.shape)
    grey = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    world = board.world_points()
    truth = cv2.perspectiveTransform(world.reshape(-1, 1, 2), homography).reshape(-1, 2)
    return grey, np.asarray(truth, np.float64)


def test_render_truth_matches_opencv_chessboard_corners() -> None:
    # A board whose markers are tiny: nearly a chessboard, which findChessboardCornersSB
    # measures to a few hundredths of a pixel on a sharp render.
    board = CharucoBoard(7, 5, 30.0, 4.0, "DICT_4X4_50")
    size = (960, 720)
    hom = view_homography(board, size, fill=0.75, tilt_x=20, tilt_y=-15, turn=10)
    image, truth = render_charuco(board, hom, size)
    found, corners = cv2.findChessboardCornersSB(image, (6, 4), flags=cv2.CALIB_CB_ACCURACY)
    assert found
    corners = corners.reshape(-1, 2)
    d = np.linalg.norm(corners[:, None, :] - truth[None, :, :], axis=2).min(axis=1)
    assert np.sqrt(np.mean(d**2)) < 0.1


def local_residuals(board: CharucoBoard, ids: NDArray[np.intp], points: F64) -> tuple[F64, F64]:
    """Each corner's distance from the homography of its found neighbours within two
    squares (at least five, itself left out), in px and in squares (NaN where too few): a
    corner more than a third of a square off has a wrong id."""
    grid = board.world_points() / board.square
    px = np.full(len(ids), np.nan)
    squares = np.full(len(ids), np.nan)
    for n, k in enumerate(ids):
        d = np.max(np.abs(grid[ids] - grid[k]), axis=1)
        near = (d <= 2.01) & (d > 0)
        if near.sum() < 5:
            continue
        h, _ = cv2.findHomography(grid[ids][near], points[near], 0)
        if h is None:
            continue
        predicted = cv2.perspectiveTransform(grid[k].reshape(1, 1, 2), h).reshape(2)
        unit = cv2.perspectiveTransform((grid[k] + [[1, 0], [0, 1]]).reshape(-1, 1, 2), h)
        square_px = np.linalg.norm(unit.reshape(-1, 2) - predicted, axis=1).min()
        px[n] = np.linalg.norm(predicted - points[n])
        squares[n] = px[n] / square_px
    return px, squares
