"""The calibration report for every board type and for partial views: chessboards and ChArUco
boards rendered by planarcal.synth (the detection corpus' shots, and a ChArUco board in the
image's corner, cut by its edge, a hand over it), found by detect_board, calibrated for
real, and every table, text and figure of the report read back; and what the report asks of a
board it does not know (no grid) and of a failed search's record of another kind."""

from __future__ import annotations

import csv
import dataclasses
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
from planarcal.calib.detect_chessboard import ChessboardDiagnostics
from planarcal.calib.detection import BoardDetection, detect_board
from planarcal.report import drawing
from planarcal.report.point_names import grid_shape
from planarcal.synth import corpus
from planarcal.synth.camera import CameraModel, PlanePose
from planarcal.synth.occluders import hand
from planarcal.synth.render import RenderedScene, render_scene

F64 = NDArray[np.float64]
SIZE = (1280, 720)
CORNER_BOARD = CharucoBoard(7, 5, 30.0, 22.0, "DICT_5X5_100")


@dataclasses.dataclass(frozen=True)
class Seen:
    """A rendered board, what detect_board found in it and the calibration from that."""

    image: NDArray[np.uint8]
    truth_px: F64
    """Every board point's true pixel, id order."""
    in_view: NDArray[np.bool_]
    """Every board point: whether it lies in the image (a few px inside)."""
    detection: BoardDetection
    cal: Calibration

    @property
    def board(self) -> Any:
        return self.detection.board

    @property
    def not_found_in_view(self) -> NDArray[np.intp]:
        """The ids in the image the detection did not find (under the hand, in glare)."""
        found = np.zeros(len(self.in_view), dtype=bool)
        found[self.detection.ids] = True
        return np.flatnonzero(self.in_view & ~found)


def _seen(image: NDArray[np.uint8], scene: RenderedScene, board: Any) -> Seen:
    detection = detect_board(image, board)
    return Seen(
        image,
        scene.points_px,
        scene.points_in_view(3.0),
        detection,
        Calibration.from_detection(detection),
    )


def _variant(name: str) -> Seen:
    variant = corpus.board_variant(name)
    board = variant.scene.board
    if isinstance(board, CharucoBoard):
        board = dataclasses.replace(board, legacy=None)  # the detector says which it found
    return _seen(variant.image, variant.scene, board)


@pytest.fixture(scope="module")
def chess() -> Seen:
    """A 9 x 6 chessboard seen whole by a webcam."""
    return _variant("chessboard_9x6_webcam")


@pytest.fixture(scope="module")
def charuco() -> Seen:
    """A 6 x 6 ChArUco board printed in OpenCV's legacy layout, seen whole."""
    return _variant("charuco_legacy_6x6")


@pytest.fixture(scope="module")
def marker_hand() -> Seen:
    """A chessboard with an origin marker, a hand over part of it: a partial view."""
    return _variant("chessboard_marker_hand")


@pytest.fixture(scope="module")
def corner() -> Seen:
    """A ChArUco board in the image's top-left corner, cut by its left edge, a hand over
    part of it: a partial view that leaves most of the image to extrapolation."""
    scene = render_scene(
        CameraModel(k1=-0.05),
        PlanePose(600.0, tilt_deg=12.0, tilt_axis_deg=30.0, look_at_mm=(420.0, 180.0)),
        board=CORNER_BOARD,
        objects=hand((135.0, 95.0), -70.0, 38.0, 140.0),
        noise_sigma=2.0,
        blur_sigma_px=0.7,
        supersample=4,
        seed=5,
    )
    return _seen(scene.image, scene, CORNER_BOARD)


def test_the_views_are_what_the_tests_need(
    chess: Seen, charuco: Seen, marker_hand: Seen, corner: Seen
) -> None:
    """The premise: whole boards found whole; the partial views found in part, with corners
    in the image not found (under the hand) and, in the corner view, corners off the
    image."""
    for whole in (chess, charuco):
        assert not whole.detection.partial
    assert charuco.detection.layout == "legacy"
    for partial in (marker_hand, corner):
        assert partial.detection.partial and len(partial.not_found_in_view) >= 2
    assert (~corner.in_view).sum() >= 3
    assert 10 <= len(corner.detection.ids) < CORNER_BOARD.n_points - 4


# ------------------------------------------------------------------------------------------
# whole boards of other types


@pytest.mark.parametrize("which", ["chess", "charuco"])
def test_the_summaries_name_the_board_and_its_corners(
    which: str, chess: Seen, charuco: Seen
) -> None:
    seen = chess if which == "chess" else charuco
    detection, cal, board = seen.detection, seen.cal, seen.board
    w, h = detection.image_size
    text = report.summary_text(cal, detection)
    assert f"Board: {board.describe()}" in text
    assert (
        f"Found all {board.n_points} corners in the {w} x {h} image ({detection.method} finder, "
    ) in text
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


def test_a_charuco_detection_says_which_layout_it_found(charuco: Seen) -> None:
    detection = charuco.detection
    text = report.summary_text(charuco.cal, detection)
    assert "Printed layout found: legacy (OpenCV's before 4.6)" in text
    assert report.summary_json(charuco.cal, detection)["detection"]["layout"] == "legacy"
    label = drawing.detection_label(detection)
    assert label[0] == f"{detection.board.describe()}, {detection.method} finder, legacy layout"
    assert "labels: each corner's id, k = row x cols + col" in label


def test_points_csv_names_the_corners_by_their_ids(corner: Seen) -> None:
    rows = list(csv.reader(io.StringIO(report.points_csv(corner.cal))))
    header, body = rows[0], rows[1:]
    assert header[:3] == ["corner", "row", "col"] and len(body) == len(corner.cal.world_points)
    assert [int(r[0]) for r in body] == corner.detection.ids.tolist()
    world = CORNER_BOARD.world_points()
    cols = CORNER_BOARD.squares_x - 1
    for r in body:
        k = int(r[0])
        assert (int(r[1]), int(r[2])) == divmod(k, cols)
        assert (float(r[3]), float(r[4])) == pytest.approx(tuple(world[k]), abs=1e-6)


# ------------------------------------------------------------------------------------------
# partial views


@pytest.mark.parametrize("which", ["corner", "marker_hand"])
def test_a_partial_view_says_how_much_was_seen(which: str, corner: Seen, marker_hand: Seen) -> None:
    seen = corner if which == "corner" else marker_hand
    detection, board = seen.detection, seen.board
    found, total = len(detection.ids), board.n_points
    missing = np.setdiff1d(np.arange(total), detection.ids)
    text = report.summary_text(seen.cal, detection)
    assert f"Found {found} of the board's {total} corners (a partial view)" in text
    listed = ", ".join(str(k) for k in missing[:20])
    assert f"  not seen: corners {listed}" in text
    out = report.summary_json(seen.cal, detection)
    assert out["partial"] is True and out["n_board_points"] == total
    assert out["point_ids"] == detection.ids.tolist()
    assert out["not_seen_ids"] == missing.tolist()
    assert out["detection"]["n_points_found"] == found and out["detection"]["partial"] is True
    assert out["detection"]["orientation"] == "origin marker"


def test_a_partial_calibration_alone_still_says_so(corner: Seen) -> None:
    """Without its detection (a calibration loaded from its file), the calibration's own
    point ids tell the report which corners it holds."""
    cal = Calibration.from_dict(corner.cal.to_dict())
    text = report.summary_text(cal)
    found = len(cal.world_points)
    assert (
        f"Calibrated from {found} of the board's {CORNER_BOARD.n_points} corners (a partial view)"
    ) in text
    assert report.summary_json(cal)["point_ids"] == corner.detection.ids.tolist()


def test_a_view_in_a_corner_carries_the_extrapolation_warning(corner: Seen, chess: Seen) -> None:
    """The points cover a corner of the image: the summaries carry the calibration's warning
    that the rest is extrapolated, with its predicted error there; a board in the middle of
    the view has none."""
    ex = corner.cal.extrapolation
    assert ex is not None and ex.warning is not None
    assert f"Warning: {ex.warning}" in report.summary_text(corner.cal, corner.detection)
    out = report.summary_json(corner.cal, corner.detection)["extrapolation"]
    assert out["warning"] == ex.warning and out["covered_share"] < 0.15
    assert report.summary_json(chess.cal)["extrapolation"]["warning"] is None
    text = report.summary_text(chess.cal)
    assert "extrapolated" not in text and "Coverage: the points' outline covers" in text


def _orange(picture: NDArray[np.uint8]) -> NDArray[np.bool_]:
    """The pixels of the not-seen marks' orange (BGR 0, 140, 255), antialiased over grey."""
    b, g, r = (picture[:, :, k].astype(int) for k in range(3))
    return np.asarray((r - b > 90) & (g - b > 40) & (r - g > 40), dtype=np.bool_)


def _near(mask: NDArray[np.bool_], at: F64, r: int) -> bool:
    x, y = np.rint(at).astype(int)
    return bool(mask[max(0, y - r) : y + r + 1, max(0, x - r) : x + r + 1].any())


@pytest.mark.parametrize("which", ["corner", "marker_hand"])
def test_the_detection_figure_draws_the_corners_not_seen(
    which: str, corner: Seen, marker_hand: Seen
) -> None:
    """The corners in the image the detector did not find (under the hand) are drawn where
    the calibration puts them (orange diamonds, about a corner's circle across); none on a
    corner found; the label says how many."""
    seen = corner if which == "corner" else marker_hand
    detection = seen.detection
    drawn = drawing.draw_detection(seen.image, detection, calibration=seen.cal)
    orange = _orange(drawn)
    reach = int(1.5 * 0.12 * detection.pitch_px) + 4  # the diamond's outline
    for k in seen.not_found_in_view:
        assert _near(orange, seen.truth_px[k], reach), k
    for k in detection.ids:
        assert not _near(orange, seen.truth_px[k], 2), k
    label = drawing.detection_label(detection, not_seen_drawn=len(seen.not_found_in_view))
    total = seen.board.n_points
    assert (
        f"partial view: {len(detection.ids)} of the board's {total} corners seen; orange "
        f"diamonds: {len(seen.not_found_in_view)} not seen, where the fit through those seen "
        "puts them"
    ) in label
    # Without the calibration: a homography through the corners found puts them there too.
    alone = _orange(drawing.draw_detection(seen.image, detection))
    assert all(_near(alone, seen.truth_px[k], reach) for k in seen.not_found_in_view)


def test_a_whole_board_has_no_marks_of_points_not_seen(chess: Seen) -> None:
    drawn = drawing.draw_detection(chess.image, chess.detection, calibration=chess.cal)
    assert _orange(drawn).sum() < 10
    assert not any("partial view" in line for line in drawing.detection_label(chess.detection))


def _label_width(drawn: NDArray[np.uint8], at: F64, pitch: float) -> int:
    """The width of the green label written up and right of the point at `at` (px)."""
    bgr = drawn.astype(np.int32)
    green = bgr[:, :, 1] - np.maximum(bgr[:, :, 0], bgr[:, :, 2]) > 60
    x, y = at
    box = green[int(y - 0.6 * pitch) : int(y), int(x) : int(x + 1.2 * pitch)]
    columns = np.flatnonzero(box.any(axis=0))
    assert columns.size, "no label beside the point"
    return int(columns[-1] - columns[0] + 1)


def test_each_point_is_labelled_with_its_id_not_its_place_in_the_list(corner: Seen) -> None:
    """A corner whose id has more digits than its place among the corners found (those left
    of it cut off by the image's edge) is labelled with its id (the numbering of the CSV
    files, the API and the summary)."""
    detection = corner.detection
    ids, pts = detection.ids, detection.image_points
    place = [j for j in range(len(ids)) if len(str(j)) < len(str(ids[j]))]
    assert place, "no corner whose place and id differ in width"
    j = place[len(place) // 2]
    drawn = drawing.draw_detection(np.full((720, 1280), 128, np.uint8), detection)
    width = _label_width(drawn, pts[j], detection.pitch_px)
    scale = 0.35 * max(0.5, 1280 / 1280.0)
    (as_id, _), _ = cv2.getTextSize(str(ids[j]), cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    (as_place, _), _ = cv2.getTextSize(str(j), cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    assert abs(width - as_id) < abs(width - as_place), (width, as_id, as_place)


def test_write_report_of_a_partial_view(corner: Seen, tmp_path: Path) -> None:
    written = report.write_report(
        corner.cal, tmp_path, image=corner.image, detection=corner.detection
    )
    assert {p.name for p in written} == {
        "points.csv",
        "summary.json",
        "deviations.png",
        "lens.png",
        "uncertainty.png",
        "coverage.png",
        "detection.png",
    }
    for p in written:
        if p.suffix == ".png":
            picture = decode_png(p.read_bytes())
            assert picture.std() > 10, p.name
    detection_png = decode_png((tmp_path / "detection.png").read_bytes())
    assert _orange(detection_png).sum() > 20  # the corners under the hand drawn
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["point_ids"] == corner.detection.ids.tolist()


def test_a_partial_circle_grid_keeps_its_dots() -> None:
    """A circle grid seen in part (a hand over the paper's board): its detection, built from
    the render's truth of the dots in view, is reported with dots, their polarity, their ids."""
    board = CircleGridBoard(14, 10, 20.0, 10.0)
    scene = render_scene(
        board=board,
        objects=hand((150.0, 90.0), 20.0, 70.0, 150.0),
        noise_sigma=1.0,
        supersample=2,
    )
    ids = np.flatnonzero(scene.points_visible()).astype(np.intp)
    assert 60 <= len(ids) < 135
    detection = BoardDetection(
        board=board,
        image_points=scene.points_px[ids],
        image_size=SIZE,
        method="lattice",
        residual_rms_px=0.0,
        ids=ids,
        polarity="dark",
    )
    cal = Calibration.from_detection(detection)
    text = report.summary_text(cal, detection)
    assert f"Found {len(ids)} of the board's 140 dots (a partial view)" in text
    assert "lattice finder, dark dots" in text
    rows = list(csv.DictReader(io.StringIO(report.points_csv(cal, detection))))
    assert [int(r["dot"]) for r in rows] == ids.tolist()
    assert all((int(r["row"]), int(r["col"])) == divmod(int(r["dot"]), 14) for r in rows)
    assert drawing.detection_label(detection)[0] == "14 x 10 board, lattice finder, dark dots"
    drawn = drawing.draw_detection(scene.image, detection, calibration=cal)
    hidden = np.flatnonzero(scene.points_hidden())
    assert hidden.size and all(_near(_orange(drawn), scene.points_px[k], 12) for k in hidden)


# ------------------------------------------------------------------------------------------
# boards of no grid: the report asks the board, never assumes


def test_grid_shapes_come_from_the_boards() -> None:
    assert grid_shape(ChessboardBoard(9, 6, 25.0)) == (9, 6)
    assert grid_shape(CharucoBoard(8, 6, 30.0, 22.0, "DICT_4X4_50")) == (7, 5)
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


def test_a_failure_without_a_record(chess: Seen) -> None:
    message = "no chessboard of 9 x 6 inner corners found: try more light"
    picture = decode_png(report.detection_failure_figure(chess.image, None, message))
    assert picture.std() > 10
    assert "(no record of what the search saw)" in report.detection_failure_text(None, message)


@pytest.mark.parametrize(
    "record",
    [
        ChessboardDiagnostics(
            ChessboardBoard(9, 6, 25.0),
            SIZE,
            ("findChessboardCornersSB at 1280 x 720: nothing", "findChessboardCorners: 3 x 2"),
            (3, 2),
            np.array([[100, 100], [150, 102], [200, 104], [98, 150], [149, 152], [199, 154.0]]),
        ),
        types.SimpleNamespace(board=CORNER_BOARD, image_size=SIZE, markers=("ids 0-17",)),
        object(),
        types.SimpleNamespace(
            board=ChessboardBoard(9, 6, 25.0),
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
def test_a_failure_with_another_kind_of_record(record: Any, chess: Seen) -> None:
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
    picture = decode_png(report.detection_failure_figure(chess.image, record, message))
    assert picture.std() > 10
    if hasattr(record, "candidates"):
        assert "1. ?:" in text  # the well-formed candidate, with no method of its own
    if isinstance(record, ChessboardDiagnostics):
        assert "Largest grid seen: 3 x 2 points" in text
        assert "Tried:\n- findChessboardCornersSB at 1280 x 720: nothing" in text
