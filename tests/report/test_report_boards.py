"""The calibration report for every board type and for partial views: chessboards and ChArUco
boards rendered through a homography, whole and cut by the image's edge or covered by a
hand, their detections (the ids of the corners in view, their pixels) calibrated for real,
and every table, text and figure of the report read back.

The detections are the rendered boards' own corners (their true pixels, with a little
noise): these tests are of the report, not of a detector."""

from __future__ import annotations

import csv
import io
import json
import types
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from conftest import decode_png
from planarcal import report
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.calib.detection import BoardDetection
from planarcal.report import drawing
from planarcal.report.point_names import grid_shape

F64 = NDArray[np.float64]
SIZE = (1280, 720)
TABLE_GREY = 140
HAND_GREY = 95


# ------------------------------------------------------------------------------------------
# rendered views


def _page(board: Any, legacy: bool | None, px_per_mm: float) -> tuple[NDArray[np.uint8], F64]:
    """The board's ink drawn on white paper (a quiet zone of a square round it), and the
    matrix mapping board mm to the page's pixels."""
    ink = board.ink(legacy) if isinstance(board, CharucoBoard) else board.ink()
    x0, y0, x1, y1 = ink.field
    margin = float(board.pitch)
    w = int(np.ceil((x1 - x0 + 2 * margin) * px_per_mm))
    h = int(np.ceil((y1 - y0 + 2 * margin) * px_per_mm))
    page = np.full((h, w), 255, np.uint8)
    # Pixel centres at integers: mm m lands at (m - origin) * scale - 0.5.
    to_page = np.array(
        [
            [px_per_mm, 0.0, (margin - x0) * px_per_mm - 0.5],
            [0.0, px_per_mm, (margin - y0) * px_per_mm - 0.5],
            [0.0, 0.0, 1.0],
        ]
    )
    shift = 4
    for rx0, ry0, rx1, ry1 in ink.rects:
        a = _apply(to_page, np.array([[rx0, ry0], [rx1, ry1]])) + 0.5
        cv2.rectangle(
            page,
            tuple(np.rint(a[0] * 16).astype(int)),
            tuple(np.rint(a[1] * 16 - 16).astype(int)),
            0,
            -1,
            cv2.LINE_8,
            shift,
        )
    for cx, cy, r, black in ink.circles:
        c = _apply(to_page, np.array([[cx, cy]]))[0]
        cv2.circle(
            page,
            tuple(np.rint(c * 16).astype(int)),
            round(r * px_per_mm * 16),
            0 if black else 255,
            -1,
            cv2.LINE_AA,
            shift,
        )
    return page, to_page


def _apply(h: F64, points: F64) -> F64:
    p = np.column_stack([points, np.ones(len(points))]) @ h.T
    return np.asarray(p[:, :2] / p[:, 2:], dtype=np.float64)


class View:
    """A board rendered in a SIZE image through the homography that puts its outer corners
    at `quad` (px), with a grey "hand" covering the polygon `hand` (px) if given."""

    def __init__(
        self,
        board: Any,
        quad: list[tuple[float, float]],
        *,
        legacy: bool | None = None,
        hand: list[tuple[float, float]] | None = None,
        seed: int = 0,
    ) -> None:
        self.board = board
        w_mm, h_mm = board.extent
        x0, y0 = (0.0, 0.0) if isinstance(board, CharucoBoard) else (-board.pitch, -board.pitch)
        corners_mm = np.array(
            [[x0, y0], [x0 + w_mm, y0], [x0 + w_mm, y0 + h_mm], [x0, y0 + h_mm]], np.float32
        )
        self.h = cv2.getPerspectiveTransform(corners_mm, np.array(quad, np.float32)).astype(
            np.float64
        )
        page, to_page = _page(board, legacy, 6.0)
        warp = self.h @ np.linalg.inv(to_page)
        image = cv2.warpPerspective(
            page, warp, SIZE, flags=cv2.INTER_AREA, borderValue=TABLE_GREY
        ).astype(np.float64)
        mask = cv2.warpPerspective(np.full_like(page, 255), warp, SIZE, flags=cv2.INTER_NEAREST)
        image = np.where(mask > 0, image, TABLE_GREY)
        covered = np.zeros(SIZE[::-1], np.uint8)
        if hand is not None:
            cv2.fillPoly(covered, [np.array(hand, np.int32)], 255)
            image[covered > 0] = HAND_GREY
        rng = np.random.default_rng(seed)
        noisy = image + rng.normal(0.0, 2.0, image.shape)
        self.image = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
        self.true_px = _apply(self.h, board.world_points())
        x, y = self.true_px.T
        margin = 10.0  # px: a corner this close to the edge is not found whole
        inside = (x > margin) & (x < SIZE[0] - margin) & (y > margin) & (y < SIZE[1] - margin)
        under_hand = (
            covered[
                np.clip(np.rint(y), 0, SIZE[1] - 1).astype(int),
                np.clip(np.rint(x), 0, SIZE[0] - 1).astype(int),
            ]
            > 0
        )
        self.in_image = inside
        self.covered_ids = np.flatnonzero(inside & under_hand)
        self.ids = np.flatnonzero(inside & ~under_hand).astype(np.intp)
        self.noise_px = rng.normal(0.0, 0.03, (len(self.ids), 2))

    def detection(self, **fields: Any) -> BoardDetection:
        """The board's corners in view, as its detector would report them."""
        px = self.true_px[self.ids] + self.noise_px
        return BoardDetection(
            board=self.board,
            image_points=px,
            image_size=SIZE,
            method="rendered",
            residual_rms_px=0.03,
            ids=self.ids,
            **fields,
        )


CHESS = ChessboardBoard(9, 6, 25.0)
CHARUCO = CharucoBoard(8, 6, 30.0, 22.0, "DICT_4X4_50")  # an even number of rows: two layouts
BIG_CHESS = ChessboardBoard(15, 10, 20.0, origin_marker=True)


@pytest.fixture(scope="module")
def chess_view() -> View:
    """A chessboard seen whole, tilted, in the middle of the image."""
    return View(CHESS, [(300, 140), (1010, 170), (960, 600), (330, 640)])


@pytest.fixture(scope="module")
def charuco_view() -> View:
    """A ChArUco board seen whole, printed in OpenCV's legacy layout."""
    return View(CHARUCO, [(260, 110), (1000, 90), (1050, 650), (240, 620)], legacy=True)


@pytest.fixture(scope="module")
def corner_view() -> View:
    """A ChArUco board in the image's top-left corner, cut by the image's left edge, a hand
    over part of it: a partial view that leaves most of the image to extrapolation."""
    return View(
        CHARUCO,
        [(-150, 30), (420, 10), (450, 420), (-120, 440)],
        hand=[(150, 190), (300, 170), (330, 330), (170, 360)],
        seed=1,
    )


@pytest.fixture(scope="module")
def corner_detection(corner_view: View) -> BoardDetection:
    return corner_view.detection(layout="current", orientation="marker")


@pytest.fixture(scope="module")
def corner_cal(corner_detection: BoardDetection) -> Calibration:
    return Calibration.from_detection(corner_detection)


def test_the_views_are_what_the_tests_need(
    chess_view: View, charuco_view: View, corner_view: View
) -> None:
    """The premise: whole boards seen whole; the corner view cut by the edge and covered by
    the hand, with corners of both kinds in the image."""
    assert len(chess_view.ids) == CHESS.n_points and len(charuco_view.ids) == CHARUCO.n_points
    cut = CHARUCO.n_points - int(corner_view.in_image.sum())
    assert cut >= 5 and len(corner_view.covered_ids) >= 3
    assert 12 <= len(corner_view.ids) < CHARUCO.n_points - 8
    # The board is drawn where its corners are said to be: black and white about each.
    for k in corner_view.ids:
        x, y = np.rint(corner_view.true_px[k]).astype(int)
        patch = corner_view.image[y - 8 : y + 9, x - 8 : x + 9]
        assert patch.min() < 70 and patch.max() > 170, k


# ------------------------------------------------------------------------------------------
# whole boards of other types


@pytest.mark.parametrize("which", ["chess", "charuco"])
def test_the_summaries_name_the_board_and_its_corners(
    which: str, chess_view: View, charuco_view: View
) -> None:
    view = chess_view if which == "chess" else charuco_view
    detection = view.detection(layout="legacy" if which == "charuco" else None)
    cal = Calibration.from_detection(detection)
    board = view.board
    text = report.summary_text(cal, detection)
    assert f"Board: {board.describe()}" in text
    assert f"Found all {board.n_points} corners in the 1280 x 720 image (rendered finder, " in text
    assert "dots" not in text.split("\n")[1]  # no polarity: a corner board has none
    worst = int(np.argmax(cal.reprojection_errors_px))
    assert f"(corner {detection.ids[worst]})" in text
    assert "each corner predicted in the image" in text and "each dot" not in text
    out = report.summary_json(cal, detection)
    assert json.loads(json.dumps(out, allow_nan=False)) == out
    assert out["board_type"] == board.kind and out["board_description"] == board.describe()
    assert out["point_name"] == "corner" and out["n_board_points"] == board.n_points
    assert out["partial"] is False and "point_ids" not in out
    assert out["board"]["type"] == board.kind
    found = out["detection"]
    assert "polarity" not in found and "dot_sizes" not in found
    assert found["n_points_found"] == board.n_points and found["partial"] is False


def test_a_charuco_detection_says_which_layout_it_found(charuco_view: View) -> None:
    detection = charuco_view.detection(layout="legacy")
    cal = Calibration.from_detection(detection)
    assert "Printed layout found: legacy (OpenCV's before 4.6)" in report.summary_text(
        cal, detection
    )
    assert report.summary_json(cal, detection)["detection"]["layout"] == "legacy"
    label = drawing.detection_label(detection)
    assert label[0] == f"{CHARUCO.describe()}, rendered finder, legacy layout"
    assert "labels: each corner's id, k = row x cols + col" in label


def test_points_csv_names_the_corners_by_their_ids(corner_cal: Calibration) -> None:
    rows = list(csv.reader(io.StringIO(report.points_csv(corner_cal))))
    header, body = rows[0], rows[1:]
    assert header[:3] == ["corner", "row", "col"] and len(body) == len(corner_cal.world_points)
    ids = [int(r[0]) for r in body]
    assert ids == [int(k) for k in getattr(corner_cal, "point_ids", ids)]
    world = CHARUCO.world_points()
    cols = CHARUCO.squares_x - 1
    for r in body:
        k = int(r[0])
        assert (int(r[1]), int(r[2])) == divmod(k, cols)
        assert (float(r[3]), float(r[4])) == pytest.approx(tuple(world[k]), abs=1e-6)


# ------------------------------------------------------------------------------------------
# partial views


def test_a_partial_view_says_how_much_was_seen(
    corner_view: View, corner_detection: BoardDetection, corner_cal: Calibration
) -> None:
    seen, total = len(corner_view.ids), CHARUCO.n_points
    missing = np.setdiff1d(np.arange(total), corner_view.ids)
    text = report.summary_text(corner_cal, corner_detection)
    assert f"Found {seen} of the board's {total} corners (a partial view)" in text
    listed = ", ".join(str(k) for k in missing[:20])
    assert f"  not seen: corners {listed}" in text
    out = report.summary_json(corner_cal, corner_detection)
    assert out["partial"] is True and out["n_board_points"] == total
    assert out["point_ids"] == corner_view.ids.tolist()
    assert out["not_seen_ids"] == missing.tolist()
    assert out["detection"]["n_points_found"] == seen and out["detection"]["partial"] is True
    assert out["detection"]["orientation"] == "origin marker"


def test_a_partial_calibration_alone_still_says_so(corner_cal: Calibration) -> None:
    """Without its detection (a calibration loaded from its file), the calibration's own
    point ids tell the report which corners it holds."""
    if getattr(corner_cal, "point_ids", None) is None:
        pytest.skip("this Calibration does not carry its point ids yet")
    text = report.summary_text(corner_cal)
    seen = len(corner_cal.world_points)
    assert f"Calibrated from {seen} of the board's {CHARUCO.n_points} corners (a partial view)" in (
        text
    )
    assert report.summary_json(corner_cal)["point_ids"] == [int(k) for k in corner_cal.point_ids]


def test_a_view_in_a_corner_carries_the_extrapolation_warning(
    corner_cal: Calibration, corner_detection: BoardDetection, chess_view: View
) -> None:
    """The points cover a corner of the image: the summaries carry the calibration's warning
    that the rest is extrapolated, with its predicted error there; a board in the middle of
    the view has none."""
    ex = getattr(corner_cal, "extrapolation", None)
    if ex is None:
        pytest.skip("this Calibration does not measure its extrapolation yet")
    assert ex.warning is not None
    assert f"Warning: {ex.warning}" in report.summary_text(corner_cal, corner_detection)
    out = report.summary_json(corner_cal, corner_detection)["extrapolation"]
    assert out["warning"] == ex.warning and out["covered_share"] < 0.3
    middle = Calibration.from_detection(chess_view.detection())
    assert report.summary_json(middle)["extrapolation"]["warning"] is None
    assert "extrapolated" not in report.summary_text(middle)


def _orange(picture: NDArray[np.uint8]) -> NDArray[np.bool_]:
    """The pixels of the not-seen marks' orange (BGR 0, 140, 255), antialiased over grey."""
    b, g, r = (picture[:, :, k].astype(int) for k in range(3))
    return np.asarray((r - b > 90) & (g - b > 40) & (r - g > 40), dtype=np.bool_)


def test_the_detection_figure_draws_the_corners_not_seen(
    corner_view: View, corner_detection: BoardDetection, corner_cal: Calibration
) -> None:
    """The covered corners, inside the image, are drawn where the calibration puts them
    (orange diamonds); the corners off the image are not; a whole board has none."""
    drawn = drawing.draw_detection(corner_view.image, corner_detection, calibration=corner_cal)
    orange = _orange(drawn)
    r = 14  # the diamond's outline, about a corner's circle across
    for k in corner_view.covered_ids:
        x, y = np.rint(corner_view.true_px[k]).astype(int)
        assert orange[y - r : y + r + 1, x - r : x + r + 1].any(), k
    for k in corner_view.ids:
        x, y = np.rint(corner_view.true_px[k]).astype(int)
        assert not orange[y - 3 : y + 4, x - 3 : x + 4].any(), k
    label = drawing.detection_label(corner_detection, not_seen_drawn=len(corner_view.covered_ids))
    seen = len(corner_view.ids)
    assert (
        f"partial view: {seen} of the board's {CHARUCO.n_points} corners seen; orange diamonds: "
        f"{len(corner_view.covered_ids)} not seen, where the fit through those seen puts them"
    ) in label
    # Without the calibration: a homography through the corners seen puts them there too.
    alone = _orange(drawing.draw_detection(corner_view.image, corner_detection))
    assert all(
        alone[y - r : y + r + 1, x - r : x + r + 1].any()
        for x, y in np.rint(corner_view.true_px[corner_view.covered_ids]).astype(int)
    )


def test_a_whole_board_has_no_marks_of_points_not_seen(chess_view: View) -> None:
    drawn = drawing.draw_detection(chess_view.image, chess_view.detection())
    assert _orange(drawn).sum() < 10
    assert not any(
        "partial view" in line for line in drawing.detection_label(chess_view.detection())
    )


def _label_width(drawn: NDArray[np.uint8], at: F64, pitch: float) -> int:
    """The width of the green label written up and right of the point at `at` (px)."""
    bgr = drawn.astype(np.int32)
    green = bgr[:, :, 1] - np.maximum(bgr[:, :, 0], bgr[:, :, 2]) > 60
    x, y = at
    box = green[int(y - 0.6 * pitch) : int(y), int(x) : int(x + 1.2 * pitch)]
    columns = np.flatnonzero(box.any(axis=0))
    assert columns.size, "no label beside the point"
    return int(columns[-1] - columns[0] + 1)


def test_each_point_is_labelled_with_its_id_not_its_place_in_the_list() -> None:
    """A marked chessboard seen in part, the top of it out of view: a corner's label is its
    id's digits wide (three), not its place among the points found (fewer)."""
    view = View(
        BIG_CHESS,
        [(-50, -1200), (1300, -1180), (1260, 660), (-10, 650)],
        seed=2,
    )
    detection = view.detection(orientation="marker")
    assert detection.partial
    drawn = drawing.draw_detection(np.full((720, 1280), 128, np.uint8), detection)
    ids, pts = detection.ids, detection.image_points
    j = int(np.flatnonzero((ids >= 100) & (pts[:, 1] > 60) & (pts[:, 0] < 1100))[0])
    assert len(str(j)) < len(str(ids[j]))
    width = _label_width(drawn, pts[j], detection.pitch_px)
    scale = 0.35 * max(0.5, 1280 / 1280.0)
    (as_id, _), _ = cv2.getTextSize(str(ids[j]), cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    (as_place, _), _ = cv2.getTextSize(str(j), cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    assert abs(width - as_id) < abs(width - as_place), (width, as_id, as_place)


def test_write_report_of_a_partial_view(
    corner_view: View, corner_detection: BoardDetection, corner_cal: Calibration, tmp_path: Path
) -> None:
    written = report.write_report(
        corner_cal, tmp_path, image=corner_view.image, detection=corner_detection
    )
    assert {p.name for p in written} == {
        "points.csv",
        "summary.json",
        "deviations.png",
        "lens.png",
        "uncertainty.png",
        "detection.png",
    }
    for p in written:
        if p.suffix == ".png":
            picture = decode_png(p.read_bytes())
            assert picture.std() > 10, p.name
    detection_png = decode_png((tmp_path / "detection.png").read_bytes())
    assert _orange(detection_png).sum() > 20  # the covered corners drawn
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["point_ids"] == corner_view.ids.tolist()


def test_a_partial_circle_grid_keeps_its_dots(tmp_path: Path) -> None:
    """A circle grid seen in part (the UCL plate's case): dots, their polarity, their ids."""
    board = CircleGridBoard(14, 10, 20.0)
    view = View(board, [(-200, 80), (1100, 60), (1150, 700), (-180, 690)], seed=3)
    detection = view.detection(polarity="dark")
    cal = Calibration.from_detection(detection)
    text = report.summary_text(cal, detection)
    seen = len(view.ids)
    assert f"Found {seen} of the board's 140 dots (a partial view)" in text
    assert "dark dots" in text
    rows = list(csv.DictReader(io.StringIO(report.points_csv(cal, detection))))
    assert [int(r["dot"]) for r in rows] == view.ids.tolist()
    assert all((int(r["row"]), int(r["col"])) == divmod(int(r["dot"]), 14) for r in rows)
    assert drawing.detection_label(detection)[0] == "14 x 10 board, rendered finder, dark dots"
    picture = decode_png(report.deviation_figure(cal))
    assert picture.std() > 10


# ------------------------------------------------------------------------------------------
# boards of no grid: the report asks the board, never assumes


def test_grid_shapes_come_from_the_boards() -> None:
    assert grid_shape(CHESS) == (9, 6)
    assert grid_shape(CHARUCO) == (7, 5)
    assert grid_shape(CircleGridBoard(4, 11, 10.0, layout="asymmetric")) == (4, 11)
    assert grid_shape(None) is None
    assert grid_shape(types.SimpleNamespace(n_points=7)) is None


def test_a_board_of_no_grid_is_drawn_by_its_neighbours() -> None:
    """A board whose points are no rows and columns (a hexagonal one, a stand-in here): its
    points are labelled by their ids and joined to their nearest neighbours."""
    r3 = np.sqrt(3.0)
    hexagon = np.array([[0, 0], [2, 0], [1, r3], [-1, r3], [-2, 0], [-1, -r3], [1, -r3]]) * 10
    hex_board = types.SimpleNamespace(
        kind="hexagons",
        point_name="point",
        n_points=7,
        pitch=20.0,
        world_points=lambda: hexagon.astype(np.float64),
        describe=lambda: "seven points in a hexagon",
    )
    ids = np.array([0, 1, 2, 3, 4, 5])  # one not seen
    px = hexagon[ids] * 8 + [640, 360]
    detection = types.SimpleNamespace(
        board=hex_board,
        image_points=px.astype(np.float64),
        image_size=SIZE,
        method="stand-in",
        residual_rms_px=0.0,
        ids=ids,
        pitch_px=160.0,
    )
    drawn = drawing.draw_detection(np.full((720, 1280), 128, np.uint8), detection)
    bgr = drawn.astype(int)  # the lattice's blue (255, 160, 0), antialiased over grey
    lattice = (bgr[:, :, 0] - bgr[:, :, 2] > 100) & (bgr[:, :, 1] - bgr[:, :, 2] > 40)
    middle = np.rint(0.5 * (px[1] + px[2])).astype(int)  # between neighbours 1 and 2
    assert lattice[middle[1] - 2 : middle[1] + 3, middle[0] - 2 : middle[0] + 3].any()
    # 1 and 5 are no neighbours; between them runs only the line 0-6, and 6 was not seen.
    apart = np.rint(0.5 * (px[1] + px[5])).astype(int)
    assert not lattice[apart[1] - 4 : apart[1] + 5, apart[0] - 4 : apart[0] + 5].any()
    six = np.rint(hexagon[6] * 8 + [640, 360]).astype(int)  # drawn as not seen
    assert _orange(drawn)[six[1] - 30 : six[1] + 31, six[0] - 30 : six[0] + 31].any()
    label = drawing.detection_label(detection)
    assert label[0] == "seven points in a hexagon, stand-in finder"
    assert "partial view: 6 of the board's 7 points seen" in label[2]
    assert "labels: each point's id, as the board numbers them" in label


# ------------------------------------------------------------------------------------------
# the failure figure, whatever the detector kept


def test_a_failure_without_a_record(chess_view: View) -> None:
    message = "no chessboard of 9 x 6 inner corners found: try more light"
    picture = decode_png(report.detection_failure_figure(chess_view.image, None, message))
    assert picture.std() > 10
    assert "(no record of what the search saw)" in report.detection_failure_text(None, message)


@pytest.mark.parametrize(
    "record",
    [
        types.SimpleNamespace(board=CHESS, image_size=SIZE),
        types.SimpleNamespace(board=CHARUCO, image_size=SIZE, markers=("ids 0-17",)),
        object(),
        types.SimpleNamespace(
            board=CHESS,
            image_size="not a size",
            blobs=[types.SimpleNamespace(polarity="dark", centres_px="junk", diameters_px=None)],
            candidates=[
                types.SimpleNamespace(method="m", points_px=[[np.nan, 1.0]], reason="r"),
                types.SimpleNamespace(points_px=[[10.0, 20.0], [30.0, 40.0]]),
            ],
        ),
    ],
    ids=["chessboard", "charuco", "nothing", "malformed"],
)
def test_a_failure_with_another_kind_of_record(record: Any, chess_view: View) -> None:
    """Another detector's record: drawn and written as far as it has the circle grid's parts,
    the board it looked for named by its description; never a crash."""
    message = "the board was not found"
    text = report.detection_failure_text(record, message)
    assert text.startswith("Error: the board was not found")
    board = getattr(record, "board", None)
    if board is not None and isinstance(getattr(record, "image_size", None), tuple):
        assert f"Looking for a {board.describe()} in the 1280 x 720 image." in text.replace(
            "\n", " "
        )
    picture = decode_png(report.detection_failure_figure(chess_view.image, record, message))
    assert picture.std() > 10
    if hasattr(record, "candidates"):
        assert "1. ?:" in text  # the well-formed candidate, with no method of its own
