"""The numbering pictures (issue 26): for each board type, every id is written once, beside
the pixel of its world point, and that pixel is where the drawn board has the point (found
in the picture by OpenCV: the dots' blobs, the chessboard's squares, the ChArUco corners by
their markers); no two texts overlap, at the documentation's width and at 640 and 1920."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.report.labels import Box
from planarcal.report.numbering import Numbering, draw_numbering, numbering_figure

BOARDS: dict[str, Any] = {
    "circles": CircleGridBoard(7, 5, 20.0),
    "asymmetric": CircleGridBoard(4, 7, 15.0, layout="asymmetric"),
    "chessboard": ChessboardBoard(7, 5, 25.0),
    "charuco": CharucoBoard(7, 5, 30.0, 22.0),
}
WIDTHS = (640, 1000, 1920)


def _distance(box: Box, p: Any) -> float:
    """Pixels from the point `p` to the box (0 inside)."""
    dx = max(box.x0 - p[0], 0.0, p[0] - (box.x1 - 1))
    dy = max(box.y0 - p[1], 0.0, p[1] - (box.y1 - 1))
    return float(np.hypot(dx, dy))


def _found_points(board: Any, image: Any) -> dict[int, Any] | Any:
    """Where OpenCV finds the board's points in the drawn board: for a ChArUco board each
    corner by its id; otherwise the points as a set, (n, 2) px."""
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if board.kind == "circles":
        _, _, _, centroids = cv2.connectedComponentsWithStats((grey < 128).astype(np.uint8))
        return centroids[1:]
    if board.kind == "chessboard":
        ok, corners = cv2.findChessboardCornersSB(grey, (board.cols, board.rows))
        assert ok
        return corners.reshape(-1, 2)
    detector = cv2.aruco.CharucoDetector(board.opencv_board())
    corners, ids, _, _ = detector.detectBoard(grey)
    assert ids is not None
    return {int(i): c for i, c in zip(ids.ravel(), corners.reshape(-1, 2), strict=True)}


@pytest.fixture(scope="module", params=list(BOARDS))
def drawn(request: Any) -> tuple[Any, Numbering]:
    board = BOARDS[request.param]
    return board, draw_numbering(board)


def test_every_id_is_written_once_beside_its_point(drawn: tuple[Any, Numbering]) -> None:
    board, d = drawn
    pts = d.world_px(board.world_points())
    assert sorted(d.labels) == list(range(board.n_points))
    assert len(set(d.labels.values())) == board.n_points  # a box of its own each
    pitch_px = d.px_per_mm * board.pitch
    for k, box in d.labels.items():
        gaps = [_distance(box, p) for p in pts]
        # Its own point is the nearest one, within half a pitch.
        assert int(np.argmin(gaps)) == k, (k, box, gaps[k], min(gaps))
        assert gaps[k] < 0.5 * pitch_px, (k, gaps[k])
        # The id is written there: the labels' blue ink inside the box.
        patch = d.image[box.y0 : box.y1, box.x0 : box.x1].astype(int)
        assert ((patch[..., 0] - patch[..., 2]) > 80).sum() > 5, k


def test_each_point_is_where_the_drawn_board_has_it(drawn: tuple[Any, Numbering]) -> None:
    """The pixel the picture names for world point k is the board's point k as OpenCV
    finds it in the drawn board (0.5 px), and the numbering's orientation is the board's:
    on a chessboard the square down and right of corner (col, row) is black when col + row
    is even (square_is_black), on a ChArUco board OpenCV's own ids name the corners."""
    board, d = drawn
    pts = d.world_px(board.world_points())
    found = _found_points(board, d.board_image)
    if isinstance(found, dict):
        assert sorted(found) == list(range(board.n_points))
        for k, p in found.items():
            assert np.hypot(*(p - pts[k])) < 0.5, (k, p, pts[k])
        return
    assert len(found) == board.n_points
    nearest = np.hypot(*(found[:, None, :] - pts[None, :, :]).transpose(2, 0, 1)).min(axis=0)
    assert nearest.max() < 0.5, nearest.max()
    grey = cv2.cvtColor(d.board_image, cv2.COLOR_BGR2GRAY)
    q = 0.3 * d.px_per_mm * board.pitch
    for k, (x, y) in enumerate(pts):
        row, col = divmod(k, board.cols)
        if board.kind == "circles":
            assert grey[round(y), round(x)] < 60, k  # inside its dot
            continue
        below_right = grey[round(y + q), round(x + q)] < 128
        assert below_right == ((col + row) % 2 == 0), k
        assert (grey[round(y - q), round(x + q)] < 128) != below_right, k


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("name", list(BOARDS))
def test_no_two_texts_overlap(name: str, width: int) -> None:
    board = BOARDS[name]
    d = draw_numbering(board, width)
    h, w = d.image.shape[:2]
    assert w == width
    boxes = d.text_boxes
    clash = [(a, b) for i, a in enumerate(boxes) for b in boxes[i + 1 :] if a.overlaps(b)]
    assert not clash, clash[:3]
    assert all(b.inside(w, h) for b in boxes)
    # The ids, the caption's lines, the axes' letters and the origin's "(0, 0)".
    assert sorted(d.labels) == list(range(board.n_points))
    assert len(boxes) >= board.n_points + 2 + 3
    assert min(b.height for b in d.labels.values()) >= 10  # legible


def test_the_figure_is_the_picture_as_png() -> None:
    board = BOARDS["chessboard"]
    data = numbering_figure(board, 700)
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert image is not None
    assert np.array_equal(image, draw_numbering(board, 700).image)
