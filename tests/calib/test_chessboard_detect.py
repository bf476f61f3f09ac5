"""detect_chessboard on rendered boards with exact truth (tests/calib/chessboard_scenes.py)
and on real photographs (../shared/data/real, skipped where absent): what it finds against
OpenCV's finders, its corners' accuracy, their ids and order, the origin marker, partial
views, and its errors. Timing is measured in benches/bench_detection.py, not here."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest
from chessboard_scenes import RenderedBoard, look_at_homography, render_board
from numpy.typing import NDArray

from planarcal import synth
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.calib.detect_chessboard import ChessboardDiagnostics, detect_chessboard
from planarcal.calib.detection import detect_board
from planarcal.errors import (
    ArgumentError,
    ArgumentTypeError,
    BoardNotFoundError,
    BoardTurnedError,
    ImageError,
)

F64 = NDArray[np.float64]
SIZE = (1280, 720)
REAL = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"
SB_FLAGS = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
CLASSIC_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE


def render(
    board: ChessboardBoard, *, supersample: int = 6, seed: int = 0, **view: float
) -> RenderedBoard:
    effects = {k: view.pop(k) for k in ("blur_px", "noise", "k") if k in view}
    shift = (view.pop("shift_x", 0.0), view.pop("shift_y", 0.0))
    h = look_at_homography(board.extent, SIZE, shift_px=shift, **view)  # type: ignore[arg-type]
    return render_board(board, h, SIZE, supersample=supersample, seed=seed, **effects)


def rms(errors: F64) -> float:
    return float(np.sqrt(np.mean(np.sum(errors**2, axis=1))))


def opencv_sb(image: NDArray[np.uint8], board: ChessboardBoard) -> F64 | None:
    found, corners = cv2.findChessboardCornersSB(image, (board.cols, board.rows), flags=SB_FLAGS)
    return np.asarray(corners, np.float64).reshape(-1, 2) if found else None


def same_corners(ours: F64, theirs: F64, tolerance_px: float) -> bool:
    """Whether each of our corners lies within tolerance of one of theirs (as sets: the
    orders differ)."""
    gap = np.min(np.hypot(*(ours[:, None] - theirs[None]).transpose(2, 0, 1)), 1)
    return bool(np.max(gap) < tolerance_px)


def opencv_sb_like(
    image: NDArray[np.uint8], board: ChessboardBoard, ours: F64, tolerance_px: float, runs: int = 10
) -> F64 | None:
    """findChessboardCornersSB's answer that has our corners, tried up to `runs` times, else
    its last answer. SB is not deterministic on some photographs (its search is threaded):
    on cam01_05 it returns, one run in four, a board reaching into the holder's shirt."""
    theirs = None
    for _ in range(runs):
        theirs = opencv_sb(image, board)
        if theirs is None or same_corners(ours, theirs, tolerance_px):
            return theirs
    return theirs


def opencv_subpix(image: NDArray[np.uint8], board: ChessboardBoard) -> F64 | None:
    found, corners = cv2.findChessboardCorners(image, (board.cols, board.rows), flags=CLASSIC_FLAGS)
    if not found:
        return None
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 0.001)
    refined = cv2.cornerSubPix(image, corners, (5, 5), (-1, -1), criteria)
    return np.asarray(refined, np.float64).reshape(-1, 2)


def nearest_truth(points: F64, truth: F64) -> F64:
    """Each point's nearest true corner (OpenCV's order may differ from planarcal's)."""
    d = np.hypot(*(points[:, None, :] - truth[None, :, :]).transpose(2, 0, 1))
    return np.asarray(truth[np.argmin(d, axis=1)], np.float64)


# ------------------------------------------------------------------------------------------
# Accuracy on renders


@pytest.mark.parametrize(
    ("tilt", "blur", "noise", "k"),
    [(0.0, 0.0, 0.0, 0.0), (35.0, 0.0, 0.0, 0.0), (60.0, 0.8, 2.0, 0.0), (40.0, 1.2, 3.0, 0.12)],
)
def test_corners_at_least_as_accurate_as_opencv(
    tilt: float, blur: float, noise: float, k: float
) -> None:
    board = ChessboardBoard(9, 6, 25.0)
    scene = render(
        board, tilt_deg=tilt, tilt_axis_deg=30.0, roll_deg=7.0, blur_px=blur, noise=noise, k=k
    )
    det = detect_chessboard(scene.image, board)
    assert det.ids.tolist() == list(range(board.n_points))
    ours = rms(det.image_points - scene.truth[det.ids])
    sb = opencv_sb(scene.image, board)
    subpix = opencv_subpix(scene.image, board)
    assert sb is not None or subpix is not None
    for theirs in (sb, subpix):
        if theirs is not None:
            assert ours <= rms(theirs - nearest_truth(theirs, scene.truth))
    if blur == 0.0 and noise == 0.0:
        assert ours <= 0.03  # the goal on sharp renders


# ------------------------------------------------------------------------------------------
# Ids, order and orientation


def test_colours_fix_the_reading_of_a_board_with_cols_plus_rows_odd() -> None:
    # 9 x 6: the top-left square black, the bottom-right white; turned by 180 degrees in
    # the image, corner 0 is still the one by the black square (far from the image's
    # top-left).
    board = ChessboardBoard(9, 6, 25.0)
    scene = render(board, tilt_deg=20.0, roll_deg=185.0, blur_px=0.7, noise=2.0)
    det = detect_chessboard(scene.image, board)
    assert det.orientation == "pattern"
    assert np.max(np.hypot(*(det.image_points - scene.truth).T)) < 0.1
    assert det.image_points[0, 1] > det.image_points[-1, 1]  # corner 0 is at the bottom


@pytest.mark.parametrize("roll", [4.0, 184.0])
def test_ambiguous_board_reads_corner_0_nearest_the_top_left(roll: float) -> None:
    board = ChessboardBoard(8, 6, 25.0)  # cols + rows even: turned by 180 it looks the same
    scene = render(board, tilt_deg=25.0, roll_deg=roll, blur_px=0.7, noise=2.0)
    det = detect_chessboard(scene.image, board)
    assert det.orientation == "ambiguous"
    assert "top-left" in det.orientation_rule
    corners = scene.truth[[0, board.cols - 1, board.n_points - board.cols, board.n_points - 1]]
    nearest = corners[np.argmin(np.hypot(*corners.T))]
    assert np.hypot(*(det.image_points[0] - nearest)) < 0.1
    # Row-major, unmirrored: corner 1 is one step along X from corner 0, corner `cols` one
    # step along Y, and X x Y points into the image (image y runs down).
    x = det.image_points[1] - det.image_points[0]
    y = det.image_points[board.cols] - det.image_points[0]
    assert x[0] * y[1] - x[1] * y[0] > 0
    truth_ids = np.array(
        [np.argmin(np.hypot(*(scene.truth - p).T)) for p in det.image_points], dtype=np.intp
    )
    expected = truth_ids if roll < 90 else board.n_points - 1 - truth_ids
    assert np.array_equal(expected, np.arange(board.n_points))


def test_board_turned_by_90_degrees_is_refused_unless_turned() -> None:
    board = ChessboardBoard(8, 6, 25.0)
    scene = render(board, tilt_deg=20.0, roll_deg=92.0, blur_px=0.7, noise=2.0)
    with pytest.raises(BoardTurnedError, match=r"found 6 x 8 inner corners.*described 8 x 6"):
        detect_chessboard(scene.image, board)
    det = detect_chessboard(scene.image, board, turned=True)
    assert len(det.ids) == board.n_points
    assert any("turned" in w for w in det.warnings)
    # The same board described the other way round reads without complaint.
    swapped = ChessboardBoard(6, 8, 25.0)
    assert len(detect_chessboard(scene.image, swapped).ids) == board.n_points


def test_detect_board_hands_a_chessboard_to_its_detector() -> None:
    board = ChessboardBoard(7, 5, 30.0)
    scene = render(board, tilt_deg=15.0, blur_px=0.7, noise=2.0)
    det = detect_board(scene.image, board)
    assert det.board == board
    assert det.image_size == SIZE
    assert np.array_equal(det.world_points(), board.world_points()[det.ids])
    assert det.refined.all()
    assert det.residual_rms_px < 0.05


# ------------------------------------------------------------------------------------------
# The origin marker


@pytest.mark.parametrize(("cols", "rows", "roll"), [(9, 6, 150.0), (7, 7, 95.0), (8, 5, -100.0)])
def test_origin_marker_fixes_every_id(cols: int, rows: int, roll: float) -> None:
    board = ChessboardBoard(cols, rows, 25.0, origin_marker=True)
    scene = render(board, tilt_deg=25.0, roll_deg=roll, blur_px=0.7, noise=2.0)
    det = detect_chessboard(scene.image, board)
    assert det.orientation == "marker"
    assert not det.partial
    assert np.max(np.hypot(*(det.image_points - scene.truth).T)) < 0.1
    # The marker is read also where the board is not declared to have one.
    plain = dataclasses.replace(board, origin_marker=False)
    undeclared = detect_chessboard(scene.image, plain)
    assert undeclared.orientation == "marker"
    assert np.max(np.hypot(*(undeclared.image_points - scene.truth).T)) < 0.1


def test_opencv_reads_the_origin_marker_as_planarcal_does() -> None:
    board = ChessboardBoard(9, 6, 25.0, origin_marker=True)
    scene = render(board, tilt_deg=20.0, roll_deg=170.0, blur_px=0.7, noise=2.0)
    found, corners, meta = cv2.findChessboardCornersSBWithMeta(
        scene.image, (board.cols, board.rows), cv2.CALIB_CB_MARKER
    )
    assert found
    assert meta is not None
    assert (meta == 3).sum() == 1  # the black square with the white dot
    assert (meta == 4).sum() == 2  # the white squares with black dots
    # OpenCV's corner 0 is planarcal's; its order runs down planarcal's columns first.
    corners = corners.reshape(board.cols, board.rows, 2).transpose(1, 0, 2).reshape(-1, 2)
    assert np.max(np.hypot(*(corners - scene.truth).T)) < 0.5


def test_marker_board_partly_out_of_view_gives_the_corners_in_view() -> None:
    board = ChessboardBoard(11, 8, 25.0, origin_marker=True)
    scene = render(board, fill=0.8, tilt_deg=25.0, shift_x=450.0, blur_px=0.7, noise=2.0)
    in_view = np.flatnonzero(np.isfinite(scene.truth[:, 0]))
    assert 20 < len(in_view) < board.n_points
    det = detect_chessboard(scene.image, board)
    assert det.partial
    assert det.orientation == "marker"
    assert set(det.ids.tolist()) <= set(in_view.tolist())
    assert len(det.ids) >= len(in_view) - 4  # at most the corners at the image's edge lost
    assert np.max(np.hypot(*(det.image_points - scene.truth[det.ids]).T)) < 0.15


def test_marker_board_partly_covered_leaves_out_the_covered_corners() -> None:
    board = ChessboardBoard(11, 8, 25.0, origin_marker=True)
    scene = render(board, fill=0.7, tilt_deg=20.0, roll_deg=10.0, blur_px=0.7, noise=2.0)
    image = scene.image.copy()
    # A hand over the board's top-left corner (the marker, about the middle, stays in view)
    # and a glare spot near the bottom right.
    cover = scene.truth[board.cols * 1 + 1]
    cv2.circle(image, (round(cover[0]), round(cover[1])), 90, 150, -1)
    glare = scene.truth[board.cols * 6 + 8]
    cv2.circle(image, (round(glare[0]), round(glare[1])), 14, 255, -1)
    det = detect_chessboard(image, board)
    assert det.partial
    assert det.orientation == "marker"
    hidden = np.hypot(*(scene.truth - cover).T) < 86
    assert hidden.sum() >= 3
    assert not set(np.flatnonzero(hidden).tolist()) & set(det.ids.tolist())
    assert board.cols * 6 + 8 not in det.ids
    far = (np.hypot(*(scene.truth - cover).T) > 150) & (np.hypot(*(scene.truth - glare).T) > 50)
    assert set(np.flatnonzero(far).tolist()) <= set(det.ids.tolist())
    assert np.max(np.hypot(*(det.image_points - scene.truth[det.ids]).T)) < 0.15


def test_a_board_described_with_a_marker_it_lacks_is_told_how_to_describe_it() -> None:
    plain = ChessboardBoard(9, 6, 25.0)
    scene = render(plain, tilt_deg=20.0, blur_px=0.7, noise=2.0)
    with pytest.raises(BoardNotFoundError) as info:
        detect_chessboard(scene.image, dataclasses.replace(plain, origin_marker=True))
    message = str(info.value)
    assert "No origin marker was read" in message
    assert "--no-origin-marker" in message
    assert "origin_marker=False" in message
    # Described as it is, the same image is read.
    assert len(detect_chessboard(scene.image, plain).ids) == plain.n_points


def test_plain_board_partly_out_of_view_is_refused_as_ambiguous() -> None:
    board = ChessboardBoard(11, 8, 25.0)
    scene = render(board, fill=0.8, tilt_deg=25.0, shift_x=450.0, blur_px=0.7, noise=2.0)
    with pytest.raises(BoardNotFoundError) as info:
        detect_chessboard(scene.image, board)
    message = str(info.value)
    assert "ambiguous" in message
    assert "origin marker" in message
    assert "ChArUco" in message
    assert isinstance(info.value.diagnostics, ChessboardDiagnostics)
    assert info.value.diagnostics.grid_shape is not None


# ------------------------------------------------------------------------------------------
# What is seen, when it is not the board


def test_a_larger_board_is_named_with_its_size() -> None:
    scene = render(ChessboardBoard(11, 8, 20.0), tilt_deg=15.0, blur_px=0.7, noise=2.0)
    with pytest.raises(BoardNotFoundError, match=r"11 x 8|8 x 11"):
        detect_chessboard(scene.image, ChessboardBoard(9, 6, 20.0))


def test_no_board_says_what_was_seen() -> None:
    rng = np.random.default_rng(3)
    image = cv2.GaussianBlur(rng.integers(0, 256, (480, 640), dtype=np.uint8), (0, 0), 2.0)
    with pytest.raises(BoardNotFoundError, match=r"no chessboard of 9 x 6 inner corners"):
        detect_chessboard(image, ChessboardBoard(9, 6, 25.0))


def test_bad_arguments_are_named() -> None:
    board = ChessboardBoard(9, 6, 25.0)
    with pytest.raises(ArgumentError, match="ChessboardBoard"):
        detect_chessboard(np.zeros((100, 100), np.uint8), "9x6")  # type: ignore[arg-type]
    with pytest.raises(ArgumentTypeError, match="turned"):
        detect_chessboard(np.zeros((100, 100), np.uint8), board, turned="yes")  # type: ignore[arg-type]
    with pytest.raises(ImageError):
        detect_chessboard(np.zeros((4, 4), np.uint8), board)
    with pytest.raises(ImageError):
        detect_chessboard(np.full((50, 50), np.nan), board)
    with pytest.raises(ImageError):
        detect_chessboard("/nonexistent/board.png", board)


def test_float_and_colour_images_are_read_like_8_bit_grey() -> None:
    board = ChessboardBoard(9, 6, 25.0)
    scene = render(board, tilt_deg=20.0, blur_px=0.7, noise=2.0)
    grey = detect_chessboard(scene.image, board)
    colour = detect_chessboard(cv2.cvtColor(scene.image, cv2.COLOR_GRAY2BGR), board)
    unit = detect_chessboard(scene.image.astype(np.float64) / 255.0, board)
    for other in (colour, unit):
        assert np.array_equal(other.ids, grey.ids)
        assert np.max(np.hypot(*(other.image_points - grey.image_points).T)) < 0.02


@pytest.mark.parametrize("name", list(synth.CHESSBOARD_VARIANTS))
def test_synth_corpus_every_visible_corner_with_its_id(name: str) -> None:
    # planarcal.synth's own renderer (another author's, another drawing of the ink): every
    # corner it says is visible is found, with its id, and none that is not.
    variant = synth.board_variant(name, seed=0)
    board = variant.board
    assert isinstance(board, ChessboardBoard)
    det = detect_chessboard(variant.image, board, turned=True)
    assert set(det.ids.tolist()) == set(np.flatnonzero(variant.visible).tolist())
    errors = np.hypot(*(det.image_points - variant.truth_px[det.ids]).T)
    assert np.max(errors) < 0.1
    assert det.partial == (not variant.visible.all())
    if board.origin_marker:
        assert det.orientation == "marker"


# ------------------------------------------------------------------------------------------
# Real photographs


def real_photos() -> list[tuple[Path, tuple[int, int]]]:
    sets = {"chess-perfanalytics-4x7": (4, 7), "chess-perfanalytics-6x9": (6, 9)}
    out = []
    for name, size in sets.items():
        folder = REAL / name
        if folder.is_dir():
            out += [(p, size) for p in sorted(folder.iterdir()) if p.suffix in (".jpg", ".png")]
    return out


PHOTOS = real_photos()


@pytest.mark.skipif(not PHOTOS, reason="no real chessboard photographs in ../shared")
@pytest.mark.parametrize("photo", PHOTOS, ids=[p.name for p, _ in PHOTOS])
def test_real_photo_found_wherever_opencv_finds_it(photo: tuple[Path, tuple[int, int]]) -> None:
    path, (cols, rows) = photo
    read = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    assert read is not None
    grey = np.asarray(read, np.uint8)
    board = ChessboardBoard(cols, rows, 60.0)
    theirs = opencv_sb(grey, board)
    if theirs is None:
        found, corners = cv2.findChessboardCorners(grey, (cols, rows), flags=CLASSIC_FLAGS)
        theirs = corners.reshape(-1, 2).astype(np.float64) if found else None
    if theirs is None:
        pytest.skip("OpenCV finds no board here either")
    det = detect_chessboard(path, board, turned=True)
    assert not det.partial
    # The same corners as OpenCV's (as a set: the orders differ): each within a fifth of a
    # square of one of OpenCV's (its unrefined corners are some pixels off on these blurred
    # large squares), none of them a neighbour's.
    tolerance = 0.2 * det.pitch_px
    again = opencv_sb_like(grey, board, det.image_points[det.refined], tolerance)
    theirs = theirs if again is None else again
    assert same_corners(det.image_points[det.refined], theirs, tolerance)
    assert det.refined.mean() > 0.8
    assert det.orientation in ("pattern", "ambiguous")


def neighbour_residuals(world: F64, image: F64, k: int = 8) -> F64:
    """Each corner's distance from where the homography through its k nearest neighbours
    (on the board, itself left out) puts it: the scatter of corners about a locally plane
    board, measurable without the truth."""
    out = np.zeros(len(world))
    for i in range(len(world)):
        d = np.hypot(*(world - world[i]).T)
        d[i] = np.inf
        near = np.argsort(d)[:k]
        h, _ = cv2.findHomography(world[near], image[near], 0)
        p = cv2.perspectiveTransform(world[i][None, None].astype(np.float64), h)[0, 0]
        out[i] = np.hypot(*(p - image[i]))
    return out


@pytest.mark.skipif(not PHOTOS, reason="no real chessboard photographs in ../shared")
@pytest.mark.parametrize("photo", PHOTOS, ids=[p.name for p, _ in PHOTOS])
def test_real_photo_corners_scatter_no_more_than_opencvs(
    photo: tuple[Path, tuple[int, int]],
) -> None:
    # The accuracy goal on photographs, where no truth is known: each corner's
    # residual against the homography of its neighbours no worse than SB's corners'.
    path, (cols, rows) = photo
    read = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    assert read is not None
    grey = np.asarray(read, np.uint8)
    board = ChessboardBoard(cols, rows, 60.0)
    theirs = opencv_sb(grey, board)
    if theirs is None:
        pytest.skip("findChessboardCornersSB finds no board here")
    det = detect_chessboard(grey, board, turned=True)
    assert not det.partial
    again = opencv_sb_like(grey, board, det.image_points, 0.2 * det.pitch_px)
    theirs = theirs if again is None else again
    # SB's corners in planarcal's order (nearest), for the same board points.
    gap = np.hypot(*(det.image_points[:, None] - theirs[None]).transpose(2, 0, 1))
    matched = theirs[np.argmin(gap, axis=1)]
    world = det.world_points()
    ours = np.sqrt(np.mean(neighbour_residuals(world, det.image_points) ** 2))
    sb = np.sqrt(np.mean(neighbour_residuals(world, matched) ** 2))
    assert ours <= sb
