"""Printed chessboards and ChArUco boards (planarcal.report.printable, `planarcal board
--type`): the PDF rasterised by PDFium (pypdfium2) at a known scale and read by OpenCV's own
detectors (``cv2.aruco.CharucoDetector`` with the right ids, ``cv2.findChessboardCornersSB``),
each corner where the board's world point says, at exact scale; the SVG drawing the same
shapes as the PDF; the page's text telling the options that give the board back; and the
command line naming the board types the same way everywhere.
"""

from __future__ import annotations

import re
import shlex
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal import cli
from planarcal.calib.board import CircleGridBoard, Layout
from planarcal.calib.boards import Board
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.commands import board_from
from planarcal.report.printable import (
    CHECK_BAR_MM,
    PT_PER_MM,
    PrintLayout,
    board_options,
    page_refusal,
    write_board,
)

pdfium = pytest.importorskip("pypdfium2", reason="pypdfium2 (the test extra) rasterises PDFs")

F64 = NDArray[np.float64]
SVG = "{http://www.w3.org/2000/svg}"
NUMBER = r"-?\d+(?:\.\d+)?"


# --------------------------------------------------------------------------- helpers


def rasterise(path: Path, px_per_mm: float) -> NDArray[np.uint8]:
    """The PDF's page as grey levels, ``px_per_mm`` pixels to the mm exactly.

    PDFium maps the page onto a bitmap of ceil(size * scale) pixels: the scale is set a
    hair under the wanted one so that a page of whole pixels at ``px_per_mm`` gets exactly
    that many (its MediaBox is single precision inside PDFium), and the size is checked."""
    document = pdfium.PdfDocument(str(path))
    try:
        page = document[0]
        width_mm = page.get_width() / PT_PER_MM
        height_mm = page.get_height() / PT_PER_MM
        bitmap = page.render(scale=px_per_mm / PT_PER_MM * (1 - 1e-6), grayscale=True)
        grey = np.array(bitmap.to_numpy(), dtype=np.uint8)
    finally:
        document.close()
    grey = grey.reshape(grey.shape[0], grey.shape[1], -1)[:, :, 0]
    assert grey.shape == (round(height_mm * px_per_mm), round(width_mm * px_per_mm))
    assert abs(width_mm * px_per_mm - grey.shape[1]) < 1e-3  # whole pixels: an exact scale
    return grey


def to_pixels(layout: PrintLayout, world: F64, px_per_mm: float) -> F64:
    """Where world points (mm) are in the raster, OpenCV's convention (a pixel's centre at
    its integer coordinates; PDFium's pixel (i, j) covers [i, i + 1) x [j, j + 1))."""
    return layout.to_page(world) * px_per_mm - 0.5


def crop(
    grey: NDArray[np.uint8], layout: PrintLayout, px_per_mm: float, pad_mm: float
) -> tuple[NDArray[np.uint8], F64]:
    """The raster around the board's field (``pad_mm`` more on each side) and the crop's
    top-left corner in the raster: the detectors' time grows with the image."""
    x0, y0, x1, y1 = layout.field_box_mm
    left = max(int((x0 - pad_mm) * px_per_mm), 0)
    top = max(int((y0 - pad_mm) * px_per_mm), 0)
    right = int((x1 + pad_mm) * px_per_mm)
    bottom = int((y1 + pad_mm) * px_per_mm)
    return np.ascontiguousarray(grey[top:bottom, left:right]), np.array([left, top], float)


def pdf_content(path: Path) -> str:
    data = path.read_bytes()
    stream = re.search(rb"/Length (\d+) /Filter /FlateDecode >>\nstream\n", data)
    assert stream is not None
    raw = data[stream.end() : stream.end() + int(stream.group(1))]
    return zlib.decompress(raw).decode("latin-1")


def pdf_shapes(content: str) -> tuple[F64, F64]:
    """The filled rectangles (N, 4: x0, y0, x1, y1) and discs (M, 4: cx, cy, r, black) of
    the content stream, in page mm (its user units, under the one cm operator)."""
    rect = re.compile(rf"^({NUMBER}) ({NUMBER}) m ({NUMBER}) \2 l \3 ({NUMBER}) l \1 \4 l h$")
    disc = re.compile(rf"^(1 g )?({NUMBER}) ({NUMBER}) m .* c h f( 0 g)?$")
    rects, discs = [], []
    for line in content.splitlines():
        if (m := rect.match(line)) is not None:
            rects.append([float(m.group(i)) for i in (1, 2, 3, 4)])
        elif (m := disc.match(line)) is not None:
            # The path starts at the disc's rightmost point, (cx + r, cy); its first curve
            # ends at the bottom, (cx, cy + r).
            numbers = [float(v) for v in re.findall(NUMBER, line.removeprefix("1 g "))]
            right_x, cy = numbers[0], numbers[1]
            cx = numbers[6]
            discs.append([cx, cy, right_x - cx, 0.0 if m.group(1) else 1.0])
    return np.array(rects).reshape(-1, 4), np.array(discs).reshape(-1, 4)


def svg_shapes(path: Path) -> tuple[F64, F64]:
    """The SVG's board: its one path's rectangles and its marker discs, as pdf_shapes."""
    root = ET.parse(path).getroot()
    board = root.find(f".//{SVG}g[@id='board']")
    assert board is not None and board.get("fill") == "#000000"
    paths = board.findall(f"{SVG}path")
    assert len(paths) == 1
    d = paths[0].get("d", "")
    one = re.compile(rf"M({NUMBER}) ({NUMBER})H({NUMBER})V({NUMBER})H\1Z")
    rects = []
    parts = re.findall(r"M[^Z]*Z", d)
    assert " ".join(parts) == d
    for part in parts:
        m = one.fullmatch(part)
        assert m is not None, part
        rects.append([float(v) for v in m.groups()])
    discs = [
        [
            float(c.get("cx", "nan")),
            float(c.get("cy", "nan")),
            float(c.get("r", "nan")),
            0.0 if c.get("fill") == "#ffffff" else 1.0,
        ]
        for c in board.findall(f"{SVG}circle")
    ]
    return np.array(rects).reshape(-1, 4), np.array(discs).reshape(-1, 4)


def page_text(path: Path) -> str:
    """The PDF's info block, its lines joined by spaces."""
    return " ".join(re.findall(r"\((.*?)\) Tj", pdf_content(path)))


def ink_on_page(board: ChessboardBoard | CharucoBoard, layout: PrintLayout) -> tuple[F64, F64]:
    """``board.ink()`` moved to the page as the layout says: what must be drawn."""
    ink = board.ink()
    ox, oy = layout.field_offset_mm
    rects = ink.rects + np.array([ox, oy, ox, oy])
    discs = ink.circles + np.array([ox, oy, 0.0, 0.0])
    return rects, discs


def matched(found: F64, expected: F64) -> F64:
    """``found`` reordered to ``expected``'s order, by nearest point (each used once)."""
    distances = np.linalg.norm(found[None, :, :] - expected[:, None, :], axis=2)
    order = distances.argmin(axis=1)
    assert len(set(order.tolist())) == len(expected)
    return np.asarray(found[order], np.float64)


def parsed_board(words: list[str], command: str = "calibrate") -> Board:
    """The board a command line's board options describe, as the command reads them."""
    head = ["board", "-o", "b.pdf"] if command == "board" else [command, "x.png", "-o", "c.json"]
    return board_from(cli.build_parser().parse_args([*head, *words]))


# --------------------------------------------------------------------------- ChArUco

PX_PER_MM = 5.0  # 127 dpi: A4 is 1050 x 1485 pixels

CHARUCO_BOARDS = [
    # dictionary, squares across and down (an even and an odd number of rows), square,
    # marker, layout
    CharucoBoard(5, 8, 25.0, 18.0, "DICT_4X4_50"),
    CharucoBoard(6, 5, 30.0, 22.0, "DICT_5X5_100"),
    CharucoBoard(7, 6, 24.0, 18.0, "DICT_6X6_250", legacy=True),
    CharucoBoard(5, 7, 30.0, 20.0, "DICT_ARUCO_ORIGINAL"),
    CharucoBoard(4, 6, 35.0, 26.0, "DICT_APRILTAG_36h11"),
    CharucoBoard(8, 11, 15.0, 12.0, "DICT_7X7_1000"),
]


@pytest.mark.parametrize("board", CHARUCO_BOARDS, ids=lambda b: f"{b.dictionary}-{b.squares_y}")
def test_charuco_page_is_read_by_opencv(tmp_path: Path, board: CharucoBoard) -> None:
    layout = write_board(board, tmp_path / "board.pdf", page="A4")
    grey = rasterise(layout.path, PX_PER_MM)
    detector = cv2.aruco.CharucoDetector(board.opencv_board(bool(board.legacy)))
    corners, ids, _, marker_ids = detector.detectBoard(grey)
    # Every marker and every corner, with OpenCV's ids.
    assert marker_ids is not None and sorted(marker_ids.ravel()) == list(range(board.n_markers))
    assert ids is not None and sorted(ids.ravel()) == list(range(board.n_points))
    # Each where the board's world point is printed, at exact scale.
    expected = to_pixels(layout, board.world_points()[ids.ravel()], PX_PER_MM)
    error = np.linalg.norm(corners.reshape(-1, 2) - expected, axis=1)
    assert error.max() < 0.15, error.max()


def test_charuco_legacy_layout_is_another_board(tmp_path: Path) -> None:
    """An even number of rows: the page printed in the current layout is read in it, not in
    the legacy one (whose corners between markers are elsewhere), and the other way round."""
    for legacy in (False, True):
        board = CharucoBoard(6, 6, 25.0, 19.0, "DICT_5X5_100", legacy=legacy)
        layout = write_board(board, tmp_path / f"board-{legacy}.pdf", page="A4")
        grey = rasterise(layout.path, PX_PER_MM)
        found = {}
        for reading in (False, True):
            detector = cv2.aruco.CharucoDetector(board.opencv_board(reading))
            _, ids, _, _ = detector.detectBoard(grey)
            found[reading] = 0 if ids is None else len(ids)
        assert found[legacy] == board.n_points
        assert found[not legacy] < board.n_points // 2, found


# --------------------------------------------------------------------------- chessboard

CHESSBOARDS = [
    ChessboardBoard(8, 5, 20.0, origin_marker=True),
    ChessboardBoard(6, 9, 17.5),
    ChessboardBoard(5, 5, 22.0, origin_marker=True),
]
CHESS_PX_PER_MM = 4.0  # 101.6 dpi: findChessboardCornersSB's time grows with the image


@pytest.mark.parametrize("board", CHESSBOARDS, ids=lambda b: f"{b.cols}x{b.rows}")
def test_chessboard_page_is_read_by_opencv_at_exact_scale(
    tmp_path: Path, board: ChessboardBoard
) -> None:
    layout = write_board(board, tmp_path / "board.pdf", page="A4")
    grey = rasterise(layout.path, CHESS_PX_PER_MM)
    part, corner = crop(grey, layout, CHESS_PX_PER_MM, pad_mm=10.0)
    found, corners = cv2.findChessboardCornersSB(
        part, (board.cols, board.rows), flags=cv2.CALIB_CB_ACCURACY
    )
    assert found, "OpenCV does not read the printed chessboard"
    expected = to_pixels(layout, board.world_points(), CHESS_PX_PER_MM)
    seen = matched(corners.reshape(-1, 2) + corner, expected)
    # Every corner where its world point is printed: the scale and the origin exact.
    error = np.linalg.norm(seen - expected, axis=1)
    assert error.max() < 0.1, error.max()
    # The distance between neighbouring corners is the square, to a fraction of a pixel.
    square_px = board.square * CHESS_PX_PER_MM
    grid = seen.reshape(board.rows, board.cols, 2)
    along = np.linalg.norm(np.diff(grid, axis=1), axis=2)
    down = np.linalg.norm(np.diff(grid, axis=0), axis=2)
    assert abs(along.mean() - square_px) < 0.02 and abs(down.mean() - square_px) < 0.02
    assert np.abs(np.concatenate([along.ravel(), down.ravel()]) - square_px).max() < 0.15

    # The marker's dots, each the colour its square is not, where the board says.
    ink = board.ink()
    assert len(ink.circles) == (3 if board.origin_marker else 0)
    for cx, cy, r, black in ink.circles:
        x, y = to_pixels(layout, np.array([[cx, cy]]), CHESS_PX_PER_MM)[0]
        dot = grey[round(y), round(x)]
        around = grey[round(y), round(x + 1.5 * r * CHESS_PX_PER_MM)]  # in the same square
        assert (dot, around) == ((0, 255) if black else (255, 0))


def test_check_bar_measures_100_mm_on_a_chessboard_page(tmp_path: Path) -> None:
    board = ChessboardBoard(6, 4, 25.0, origin_marker=True)
    layout = write_board(board, tmp_path / "board.pdf", page="A4")
    px_per_mm = 10.0
    grey = rasterise(layout.path, px_per_mm).astype(float)
    (x0, y0), (x1, _) = layout.bar_start_mm, layout.bar_end_mm
    assert x1 - x0 == pytest.approx(CHECK_BAR_MM, abs=1e-9)
    # Across the ticks 1.5 mm under the bar: 11 dark runs, their ink-weighted centres.
    row = round((y0 + 1.5) * px_per_mm - 0.5)
    left = int((x0 - 2.0) * px_per_mm)
    darkness = 255.0 - grey[row, left : int((x1 + 2.0) * px_per_mm)]
    runs = np.flatnonzero(np.diff(np.concatenate([[0], darkness > 0, [0]]).astype(int)))
    centres = []
    for start, stop in zip(runs[::2], runs[1::2], strict=True):
        weights = darkness[start:stop]
        centres.append(left + (np.arange(start, stop) * weights).sum() / weights.sum())
    assert len(centres) == 11
    assert abs(centres[-1] - centres[0] - CHECK_BAR_MM * px_per_mm) < 0.05
    assert abs(centres[0] - (x0 * px_per_mm - 0.5)) < 0.05


# --------------------------------------------------------------------------- SVG and PDF


@pytest.mark.parametrize(
    "board",
    [CHESSBOARDS[0], CHESSBOARDS[1], CHARUCO_BOARDS[0], CHARUCO_BOARDS[2]],
    ids=["chess-marker", "chess", "charuco", "charuco-legacy"],
)
def test_svg_and_pdf_draw_the_same_board(
    tmp_path: Path, board: ChessboardBoard | CharucoBoard
) -> None:
    pdf = write_board(board, tmp_path / "board.pdf", page="A3")
    svg = write_board(board, tmp_path / "board.svg", page="A3")
    assert (pdf.page_size_mm, pdf.field_offset_mm) == (svg.page_size_mm, svg.field_offset_mm)
    pdf_rects, pdf_discs = pdf_shapes(pdf_content(pdf.path))
    svg_rects, svg_discs = svg_shapes(svg.path)
    # The same numbers, written alike.
    np.testing.assert_array_equal(pdf_rects, svg_rects)
    np.testing.assert_allclose(pdf_discs, svg_discs, rtol=0, atol=1e-9)
    # And what the board's ink says, where the layout puts it.
    rects, discs = ink_on_page(board, pdf)
    np.testing.assert_allclose(pdf_rects, rects, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pdf_discs, discs, rtol=0, atol=1e-9)
    # The field centred on the page, inside the margins with everything else.
    ink = board.ink()
    centre = np.array(
        pdf.to_page([[(ink.field[0] + ink.field[2]) / 2, (ink.field[1] + ink.field[3]) / 2]])
    )[0]
    np.testing.assert_allclose(centre, np.array(pdf.page_size_mm) / 2, rtol=0, atol=1e-9)
    ux0, uy0, ux1, uy1 = pdf.usable_box_mm
    cx0, cy0, cx1, cy1 = pdf.content_box_mm
    assert ux0 <= cx0 and uy0 <= cy0 and cx1 <= ux1 and cy1 <= uy1


# --------------------------------------------------------------------------- page and text


@pytest.mark.parametrize(
    "board",
    [CHESSBOARDS[0], CHESSBOARDS[1], CHARUCO_BOARDS[1], CHARUCO_BOARDS[2]],
    ids=["chess-marker", "chess", "charuco", "charuco-legacy"],
)
def test_page_tells_the_options_that_give_the_board_back(
    tmp_path: Path, board: ChessboardBoard | CharucoBoard
) -> None:
    layout = write_board(board, tmp_path / "board.pdf", page="A3")
    text = page_text(layout.path)
    assert 'PRINT AT 100% / "ACTUAL SIZE"' in text and "must measure 100 mm" in text
    command = re.search(r"calibrate with: planarcal calibrate PHOTO -o cal\.json (.*?) PRINT", text)
    assert command is not None, text
    assert parsed_board(shlex.split(command.group(1))) == board
    assert board.describe() in layout.path.read_bytes().decode("latin-1")  # the title


def test_a_long_text_moves_the_board_off_centre_rather_than_off_the_page(tmp_path: Path) -> None:
    # 125 x 200 mm of squares leave 38.5 mm above and below on A4: too little for the text
    # under the centred board; together they fit.
    board = CHARUCO_BOARDS[0]
    layout = write_board(board, tmp_path / "board.svg", page="A4")
    assert layout.orientation == "portrait"
    fx0, fy0, fx1, fy1 = layout.field_box_mm
    ty0 = layout.text_box_mm[1]
    assert fy1 < ty0  # the text under the board, not on it
    assert abs((fx0 + fx1) / 2 - 105.0) < 1e-9 and (fy0 + fy1) / 2 < 297.0 / 2 - 1.0
    ux0, uy0, ux1, uy1 = layout.usable_box_mm
    cx0, cy0, cx1, cy1 = layout.content_box_mm
    assert ux0 <= cx0 and uy0 <= cy0 and cx1 <= ux1 and cy1 <= uy1


@pytest.mark.parametrize(
    ("board", "smaller"),
    [
        (CharucoBoard(), CharucoBoard(6, 5, 30.0, 22.0, "DICT_5X5_100")),
        (ChessboardBoard(origin_marker=True), ChessboardBoard(6, 6, 25.0, origin_marker=True)),
        (CharucoBoard(3, 3, 300.0, 200.0), CharucoBoard(3, 3, 60.5, 40.33)),
    ],
    ids=["charuco", "chessboard", "charuco-scaled"],
)
def test_a_board_too_large_is_refused_with_one_that_fits(
    tmp_path: Path, board: Board, smaller: Board
) -> None:
    message = page_refusal(board, "A4")
    assert message is not None
    assert "does not fit on A4" in message and "its squares span" in message
    # The board offered is the one named, and fits.
    if isinstance(smaller, CharucoBoard):
        named = (
            f"CharucoBoard({smaller.squares_x}, {smaller.squares_y}, square={smaller.square:g}, "
            f"marker={smaller.marker:g}, dictionary='{smaller.dictionary}')"
        )
    else:
        assert isinstance(smaller, ChessboardBoard)
        named = f"ChessboardBoard({smaller.cols}, {smaller.rows}, square={smaller.square:g}"
    assert message.rsplit("fits A4: ", 1)[1].startswith(named), message
    assert page_refusal(smaller, "A4") is None
    write_board(smaller, tmp_path / "smaller.pdf", page="A4")


# --------------------------------------------------------------------------- the command line


def run(capsys: pytest.CaptureFixture[str], *words: str) -> tuple[int, str, str]:
    code = cli.main(list(words))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize(
    "board",
    [
        CircleGridBoard(),
        CircleGridBoard(4, 11, 15.0, diameter=10.0, origin_marker=True, layout="asymmetric"),
        CircleGridBoard(16, 14, 5.0, fiducials=(69, 74, 149, 154)),
        CircleGridBoard(8, 6, 20.0, diameter=8.0, fiducials=(9,), fiducial_diameter=14.0),
        ChessboardBoard(),
        ChessboardBoard(7, 4, 12.5, origin_marker=True),
        CharucoBoard(),
        CharucoBoard(9, 14, 20.0, 15.5, "DICT_APRILTAG_36h11", legacy=False),
        CharucoBoard(6, 6, 25.0, 19.0, "DICT_4X4_50", legacy=True),
    ],
    ids=lambda b: b.describe(),
)
def test_board_options_read_back(board: Board) -> None:
    assert parsed_board(board_options(board)) == board
    assert parsed_board(board_options(board, for_printing=True), "board") == board
    intrinsics = ["intrinsics", "a.png", "b.png", "c.png", "-o", "i.yaml"]
    args = cli.build_parser().parse_args([*intrinsics, *board_options(board)])
    assert board_from(args) == board


def test_each_type_has_its_own_defaults() -> None:
    assert parsed_board([]) == CircleGridBoard()
    assert parsed_board(["--type", "chessboard"]) == ChessboardBoard()
    assert parsed_board(["--type", "chessboard"], "board") == ChessboardBoard(origin_marker=True)
    assert parsed_board(["--type", "charuco"]) == CharucoBoard()
    assert parsed_board(["--type", "charuco"], "board") == CharucoBoard()
    # The dictionary in any case; --legacy's words.
    charuco = parsed_board(["--type", "charuco", "--dictionary", "dict_4x4_50", "--legacy", "no"])
    assert charuco == CharucoBoard(dictionary="DICT_4X4_50", legacy=False)


# Refused by every command that takes a board; the marker's by `planarcal board` only (a
# chessboard to be found has no marker unless told).
@pytest.mark.parametrize(
    ("words", "said"),
    [
        (["--type", "hexagons"], "invalid choice"),
        (["--type", "charuco", "--cols", "5"], "did you mean --squares-x"),
        (["--type", "charuco", "--origin-marker"], "--origin-marker does not apply"),
        (["--type", "chessboard", "--pitch", "20"], "did you mean --square?"),
        (["--type", "chessboard", "--marker", "5"], "--marker does not apply"),
        (["--type", "chessboard", "--diameter", "5"], "--diameter does not apply"),
        (["--square", "20"], "did you mean --pitch?"),
        (["--squares-y", "5"], "did you mean --rows?"),
        (["--type", "charuco", "--dictionary", "DICT_9X9_1"], "predefined ArUco dictionaries"),
        (["--type", "charuco", "--marker", "30"], "marker must be smaller than the square"),
        (["--type", "charuco", "--squares-x", "30", "--dictionary", "DICT_4X4_50"], "has 50"),
        (["--type", "chessboard", "--cols", "2"], "between 3 and 1000 inner corners"),
    ],
)
def test_options_that_do_not_describe_the_board_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], words: list[str], said: str
) -> None:
    out = tmp_path / "board.pdf"
    commands = [
        ["board", "-o", str(out)],
        ["calibrate", str(tmp_path / "x.png"), "-o", str(tmp_path / "c.json")],
    ]
    for command in commands:
        try:
            code, _, err = run(capsys, *command, *words)
        except SystemExit as e:  # argparse's own refusals
            code, err = int(str(e.code)), capsys.readouterr().err
        assert code == 2, err
        assert said in err and "Traceback" not in err
    assert not out.exists()


def test_board_command_prints_each_type(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "charuco.svg"
    code, printed, _ = run(
        capsys,
        "board",
        "--type",
        "charuco",
        "--squares-x",
        "5",
        "--squares-y",
        "6",
        "--square",
        "25",
        "--marker",
        "18",
        "--dictionary",
        "DICT_4X4_50",
        "-o",
        str(out),
    )
    assert code == 0
    board = CharucoBoard(5, 6, 25.0, 18.0, "DICT_4X4_50")
    assert f"wrote {out}: {board.describe()}, on A4 portrait." in printed
    assert "current layout" in printed  # an even number of rows: which layout is printed
    calibrate = re.search(r"Calibrate with: planarcal calibrate PHOTO -o cal\.json (.*)", printed)
    assert calibrate is not None and parsed_board(shlex.split(calibrate.group(1))) == board
    rects, _ = svg_shapes(out)
    layout = write_board(board, tmp_path / "again.svg", page="A4")
    np.testing.assert_array_equal(rects, ink_on_page(board, layout)[0])

    # A board too large for the page asked for: refused, with a command that prints one that
    # fits, which runs.
    code, _, err = run(capsys, "board", "--type", "chessboard", "--page", "A4", "-o", str(out))
    assert code == 1 and "does not fit on A4" in err
    offered = re.search(r"`planarcal (board .*?)`", err)
    assert offered is not None
    code, printed, _ = run(capsys, *shlex.split(offered.group(1)))
    assert code == 0 and "on A4" in printed and "--origin-marker" in printed


# --------------------------------------------------------------------------- layout's shortcuts


def _random_boards(seed: int, n: int) -> list[Board]:
    """Boards of every type with varied counts, sizes, markers and layouts."""
    rng = np.random.default_rng(seed)
    boards: list[Board] = []
    while len(boards) < n:
        kind = ("circles", "chessboard", "charuco")[len(boards) % 3]
        cols, rows = (int(v) for v in rng.integers(3, 40, size=2))
        pitch = float(np.round(rng.uniform(1.0, 40.0), 2))
        if kind == "circles":
            layout: Layout = "asymmetric" if rng.random() < 0.5 else "symmetric"
            spacing = pitch * (np.sqrt(2.0) if layout == "asymmetric" else 1.0)
            diameter = None if rng.random() < 0.3 else float(rng.uniform(0.2, 0.6) * spacing)
            marked = bool(rng.random() < 0.6)
            marker = None
            if marked and rng.random() < 0.5:
                low = 0.1 * spacing if diameter is None else 1.2 * diameter
                marker = float(rng.uniform(low, spacing))
            boards.append(CircleGridBoard(cols, rows, pitch, diameter, marked, marker, layout))
        elif kind == "chessboard":
            boards.append(
                ChessboardBoard(cols, rows, pitch, origin_marker=bool(rng.random() < 0.5))
            )
        else:
            cols, rows = min(cols, 20), min(rows, 20)
            boards.append(
                CharucoBoard(cols, rows, pitch, pitch * 0.7, "DICT_6X6_1000", legacy=rows % 3 == 0)
            )
    return boards


def test_the_layout_measures_a_board_as_it_draws_it(tmp_path: Path) -> None:
    """The layout places a board by its extent and the box of its marks, found without
    drawing them (a board of a million dots is tried on many pages): the same numbers as the
    board's own and as the shapes drawn."""
    from planarcal.report.printable.layout import extent  # noqa: PLC0415 (the shortcut itself)

    for board in _random_boards(seed=22, n=90):
        assert extent(board) == board.extent, board
        page = f"{int(board.extent[0]) + 200}x{int(board.extent[1]) + 200}"
        layout = write_board(board, tmp_path / "board.svg", page=page)
        ex, ey = board.extent
        fx0, fy0, fx1, fy1 = layout.field_box_mm
        assert abs(fx1 - fx0 - ex) < 1e-9 and abs(fy1 - fy0 - ey) < 1e-9
        root = ET.parse(layout.path).getroot()
        if isinstance(board, CircleGridBoard):
            # Every dot inside the field; the page's content box is what is drawn.
            dots = root.findall(f".//{SVG}g[@id='dots']/{SVG}circle")
            cx = np.array([float(c.get("cx", "nan")) for c in dots])
            cy = np.array([float(c.get("cy", "nan")) for c in dots])
            r = np.array([float(c.get("r", "nan")) for c in dots])
            box = ((cx - r).min(), (cy - r).min(), (cx + r).max(), (cy + r).max())
            assert len(dots) == board.n_points
        else:
            rects, _ = svg_shapes(layout.path)
            box = (rects[:, 0].min(), rects[:, 1].min(), rects[:, 2].max(), rects[:, 3].max())
            np.testing.assert_allclose(box, layout.field_box_mm, rtol=0, atol=1e-9)
            ink = board.ink()
            field = np.array(ink.field) + np.tile(layout.field_offset_mm, 2)
            np.testing.assert_allclose(field, layout.field_box_mm, rtol=0, atol=1e-9)
        # (The file's numbers are written to 1e-9 mm.)
        assert fx0 - 1e-8 <= box[0] and fy0 - 1e-8 <= box[1]
        assert box[2] <= fx1 + 1e-8 and box[3] <= fy1 + 1e-8
        content = layout.content_box_mm
        assert content[0] - 1e-8 <= box[0] and content[1] - 1e-8 <= box[1]
        assert box[2] <= content[2] + 1e-8 and box[3] <= content[3] + 1e-8
