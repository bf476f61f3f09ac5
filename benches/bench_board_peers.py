"""planarcal's chessboard and ChArUco detectors beside the Rust crates ``chess-corners``
and ``calib-targets`` through their Python bindings (PyPI ``chess-corners``, ``calib-targets``)
(issue 22: choose the detector by measurement).

The peers are not dependencies of planarcal: install them in a separate environment::

    python -m venv --system-site-packages /tmp/peerenv
    /tmp/peerenv/bin/pip install chess-corners calib-targets
    /tmp/peerenv/bin/python benches/bench_board_peers.py [--markdown]

Without them the bench says so and exits 0. Sections:

1. **Chessboard corners on renders** (``planarcal.synth.render_scene``, exact truth): sharp,
   blur 0.8 px + noise 2, tilted 40 degrees through a lens with k1 = -0.15; two boards.
   Per finder: corners found (within a third of a square of a true corner), extra corners
   (further than that from every true corner), RMS error against the nearest true corner,
   median time of 3 runs. ``chess-corners`` finds corners only (no board, no ids); it runs
   with its default refiner (centre of mass) and with its saddle-point refiner (the most
   accurate of its refiners here). ``calib-targets`` labels a grid (``detect_chessboard``),
   with its default ChESS configuration and with the saddle-point refiner. OpenCV's
   ``findChessboardCornersSB`` (EXHAUSTIVE | ACCURACY) is beside them for reference.
2. **Chessboards on real photographs** (``../shared/data/real/chess-perfanalytics-*``):
   images where the whole board is found (all corners labelled; for ``chess-corners``: a
   corner within 2 px of each of planarcal's), the local residual RMS (each corner against
   the homography of its found neighbours within two squares: no truth, the lens and the
   paper's bending included, lower is closer to the grid) over each finder's own corners
   and, comparable, over the corners it and planarcal both find (within 2 px of each
   other; each against its neighbours among those corners only), median time.
3. **ChArUco on renders**: corners found, wrong ids (more than a third of a square from the
   truth of their id), RMS error against the truth of their id, median time of 3 runs;
   planarcal, ``calib_targets.detect_charuco`` (default and saddle-point refiner) and
   ``cv2.aruco.CharucoDetector`` for reference.
4. **ChArUco on real photographs** (``../shared/data/real/charuco-*``): corners found
   (summed), wrong ids (a corner more than a third of a square from the homography of its
   neighbours), local residual RMS (own corners, and corners both find), median time.

Deterministic; about 2-3 minutes on 2 cores. Exit status 0 whatever the outcome.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from importlib.metadata import version
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "python"))

try:
    import calib_targets
    import chess_corners
except ImportError as missing:
    print(
        f"bench_board_peers: {missing.name} is not installed; nothing measured. Install the "
        "peers in a separate environment:\n"
        "  python -m venv --system-site-packages /tmp/peerenv\n"
        "  /tmp/peerenv/bin/pip install chess-corners calib-targets\n"
        "  /tmp/peerenv/bin/python benches/bench_board_peers.py"
    )
    sys.exit(0)

import planarcal  # noqa: E402
from planarcal.errors import BoardError, BoardNotFoundError, BoardTurnedError  # noqa: E402
from planarcal.synth import render_scene  # noqa: E402
from planarcal.synth.camera import CameraModel, PlanePose  # noqa: E402

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]
REAL = HERE.parent.parent / "shared" / "data" / "real"
RUNS = 3

# A finder returns (grid coordinates in squares or None, points (N,2) px); for ChArUco the
# grid is the board id of each point.
Finder = Callable[[U8], tuple[Any, F64]]


# -- output -----------------------------------------------------------------------------


def table(title: str, header: Sequence[str], rows: Sequence[Sequence[str]], md: bool) -> None:
    print()
    if md:
        print(f"**{title}**\n")
        print("| " + " | ".join(header) + " |")
        print("|" + "|".join("---" for _ in header) + "|")
        for row in rows:
            print("| " + " | ".join(row) + " |")
        return
    print(title)
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print("  ".join(str(c).ljust(w) for c, w in zip(row, widths, strict=True)))


def fmt(value: float, digits: int = 4) -> str:
    return "-" if not np.isfinite(value) else f"{value:.{digits}f}"


def timed(finder: Finder, image: U8, runs: int) -> tuple[Any, F64, float]:
    """The finder's result and its median wall-clock time over `runs` runs."""
    times = []
    result: tuple[Any, F64] = (None, np.zeros((0, 2)))
    for _ in range(runs):
        start = time.perf_counter()
        result = finder(image)
        times.append(time.perf_counter() - start)
    return result[0], result[1], statistics.median(times)


# -- the finders ------------------------------------------------------------------------


def saddle_strategy() -> dict[str, Any]:
    refiner = chess_corners.ChessRefiner.saddle_point(chess_corners.SaddlePointConfig())
    return {"chess": {"ring": "canonical", "refiner": refiner.to_dict()}}


def chess_corners_finder(saddle: bool) -> Finder:
    config = chess_corners.DetectorConfig()
    if saddle:
        wire = config.to_dict()
        wire["strategy"] = saddle_strategy()
        config = chess_corners.DetectorConfig.from_dict(wire)
    detector = chess_corners.Detector(config)

    def find(image: U8) -> tuple[Any, F64]:
        return None, np.asarray(detector.detect(image).xy, dtype=np.float64)

    return find


def targets_chess_config(saddle: bool) -> Any:
    config = calib_targets.ChessConfig()
    if not saddle:
        return config
    wire = config.to_dict()
    wire["strategy"] = saddle_strategy()
    return calib_targets.ChessConfig.from_dict(wire)


def targets_chessboard_finder(saddle: bool) -> Finder:
    chess_cfg = targets_chess_config(saddle)

    def find(image: U8) -> tuple[Any, F64]:
        result = calib_targets.detect_chessboard(image, chess_cfg=chess_cfg)
        if result is None:
            return np.zeros((0, 2)), np.zeros((0, 2))
        grid = np.array([[c.grid.u, c.grid.v] for c in result.corners], dtype=np.float64)
        points = np.array([tuple(c.position) for c in result.corners], dtype=np.float64)
        return grid.reshape(-1, 2), points.reshape(-1, 2)

    return find


def planarcal_finder(board: Any) -> Finder:
    world = board.world_points() / board_square(board)

    def find(image: U8) -> tuple[Any, F64]:
        try:
            try:
                found = planarcal.detect_board(image, board)
            except BoardTurnedError:  # a portrait photo of a landscape description: as seen
                found = planarcal.detect_board(image, board, turned=True)
        except (BoardError, BoardNotFoundError):
            return np.zeros(0, dtype=np.intp), np.zeros((0, 2))
        ids = np.asarray(found.ids, dtype=np.intp)
        if board.kind == "charuco":
            return ids, np.asarray(found.image_points, dtype=np.float64)
        return world[ids], np.asarray(found.image_points, dtype=np.float64)

    return find


def opencv_sb_finder(board: Any) -> Finder:
    flags = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    world = board.world_points() / board.square

    def find(image: U8) -> tuple[Any, F64]:
        ok, corners = cv2.findChessboardCornersSB(image, (board.cols, board.rows), flags=flags)
        if not ok:
            return np.zeros((0, 2)), np.zeros((0, 2))
        return world, corners.reshape(-1, 2).astype(np.float64)

    return find


def board_square(board: Any) -> float:
    return float(board.square)


def targets_charuco_finder(board: Any, saddle: bool) -> Finder:
    spec = calib_targets.CharucoBoardSpec(
        rows=board.squares_y,
        cols=board.squares_x,
        cell_size=float(board.square),
        marker_size_rel=float(board.marker) / float(board.square),
        dictionary=board.dictionary,
    )
    params = calib_targets.CharucoDetectorParams(board=spec, chess=targets_chess_config(saddle))
    world = board.world_points()

    def find(image: U8) -> tuple[Any, F64]:
        try:
            result = calib_targets.detect_charuco(image, params=params)
        except Exception:  # the binding raises on "no board"; any failure is "none found"
            return np.zeros(0, dtype=np.intp), np.zeros((0, 2))
        ids, points = [], []
        for corner in result.corners:
            # The corner's own board position names it; -1 when no planarcal id is there.
            offset = np.linalg.norm(world - np.asarray(tuple(corner.target_position)), axis=1)
            ids.append(int(np.argmin(offset)) if offset.min() < 1e-3 * board.square else -1)
            points.append(tuple(corner.position))
        return np.asarray(ids, dtype=np.intp), np.asarray(points, np.float64).reshape(-1, 2)

    return find


def opencv_charuco_finder(board: Any, legacy: bool) -> Finder:
    detector = cv2.aruco.CharucoDetector(board.opencv_board(legacy))

    def find(image: U8) -> tuple[Any, F64]:
        corners, ids, _, _ = detector.detectBoard(image)
        if ids is None or len(ids) == 0:
            return np.zeros(0, dtype=np.intp), np.zeros((0, 2))
        return ids.reshape(-1).astype(np.intp), corners.reshape(-1, 2).astype(np.float64)

    return find


# -- measures ---------------------------------------------------------------------------


def local_residuals(grid: F64, points: F64) -> tuple[F64, F64]:
    """Each point's distance from the homography of its found neighbours within two
    squares (at least five, itself left out), in px and in squares (NaN where too few)."""
    px = np.full(len(points), np.nan)
    squares = np.full(len(points), np.nan)
    for n in range(len(points)):
        d = np.max(np.abs(grid - grid[n]), axis=1)
        near = (d <= 2.01) & (d > 0)
        if near.sum() < 5:
            continue
        h, _ = cv2.findHomography(grid[near], points[near], 0)
        if h is None:
            continue
        predicted = cv2.perspectiveTransform(grid[n].reshape(1, 1, 2), h).reshape(2)
        unit = cv2.perspectiveTransform((grid[n] + [[1, 0], [0, 1]]).reshape(-1, 1, 2), h)
        square_px = np.linalg.norm(unit.reshape(-1, 2) - predicted, axis=1).min()
        px[n] = np.linalg.norm(predicted - points[n])
        squares[n] = px[n] / square_px
    return px, squares


class Paired:
    """Local residuals of a finder's corners and planarcal's on the corners both find (at
    the same place within 2 px), each against the homography of its neighbours among those
    common corners only: a corner's residual depends on which neighbours were found, so only
    the same set compares fairly (an extra corner at a bent edge changes its neighbours')."""

    def __init__(self) -> None:
        self.own: list[float] = []
        self.other: list[float] = []

    def add(self, mine: tuple[F64, F64], reference: tuple[F64, F64] | None) -> None:
        """`mine`, `reference`: (grid in squares, image points) of a finder and planarcal."""
        if reference is None or len(mine[1]) == 0 or len(reference[1]) == 0:
            return
        d = np.linalg.norm(mine[1][:, None] - reference[1][None], axis=2)
        nearest = d.argmin(axis=1)
        both = d.min(axis=1) <= 2.0
        own_px, own_sq = local_residuals(mine[0][both], mine[1][both])
        ref_px, ref_sq = local_residuals(reference[0][nearest][both], reference[1][nearest][both])
        keep = (own_sq <= 1 / 3) & (ref_sq <= 1 / 3)  # NaN (too few neighbours) is dropped
        self.own.extend(own_px[keep].tolist())
        self.other.extend(ref_px[keep].tolist())

    def cell(self) -> str:
        return f"{fmt(rms(self.own), 3)} / {fmt(rms(self.other), 3)} ({len(self.own)})"


def rms(values: Sequence[float] | F64) -> float:
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if len(values) else float("nan")


def square_px(truth: F64, board: Any) -> float:
    """The board's square in px near its points (median spacing of neighbouring truths)."""
    d = np.linalg.norm(truth[:, None] - truth[None], axis=2)
    d[d == 0] = np.inf
    return float(np.median(d.min(axis=1)))


# -- scenes -----------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Scene:
    name: str
    image: U8
    truth: F64  # (N,2) px by point id


def scenes(board: Any) -> list[Scene]:
    centre = board.world_points().mean(axis=0)
    look = (float(centre[0]), float(centre[1]))
    straight = PlanePose(distance_mm=500.0, look_at_mm=look)
    tilted = PlanePose(distance_mm=500.0, tilt_deg=40.0, tilt_axis_deg=20.0, look_at_mm=look)
    specs = [
        ("sharp", CameraModel(), straight, 0.0, 0.0),
        ("blur 0.8 + noise 2", CameraModel(), straight, 0.8, 2.0),
        ("tilt 40, k1 -0.15", CameraModel(k1=-0.15), tilted, 0.5, 1.0),
    ]
    out = []
    for name, camera, pose, blur, noise in specs:
        rendered = render_scene(
            camera=camera, pose=pose, board=board, blur_sigma_px=blur, noise_sigma=noise, seed=7
        )
        image = np.ascontiguousarray(rendered.image, dtype=np.uint8)
        out.append(Scene(name, image, np.asarray(rendered.points_px, dtype=np.float64)))
    return out


def real_images(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in {".jpg", ".jpeg", ".png"})


def grey(path: Path) -> U8:
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise SystemExit(f"cannot read {path}")
    return np.ascontiguousarray(image)


# -- sections ---------------------------------------------------------------------------


def chess_finders(board: Any) -> dict[str, Finder]:
    return {
        "planarcal": planarcal_finder(board),
        "chess-corners (default)": chess_corners_finder(saddle=False),
        "chess-corners (saddle)": chess_corners_finder(saddle=True),
        "calib-targets chessboard": targets_chessboard_finder(saddle=False),
        "calib-targets chessboard (saddle)": targets_chessboard_finder(saddle=True),
        "OpenCV SB (reference)": opencv_sb_finder(board),
    }


def chess_renders(md: bool) -> None:
    rows = []
    for board in (planarcal.ChessboardBoard(9, 6, 25.0), planarcal.ChessboardBoard(7, 11, 18.0)):
        for scene in scenes(board):
            limit = square_px(scene.truth, board) / 3
            for name, finder in chess_finders(board).items():
                finder(scene.image)  # warm up (first-call allocation, imports)
                _, points, seconds = timed(finder, scene.image, RUNS)
                if len(points):
                    d = np.linalg.norm(points[:, None] - scene.truth[None], axis=2).min(axis=1)
                else:
                    d = np.zeros(0)
                near = d <= limit
                rows.append(
                    [
                        f"{board.cols}x{board.rows}",
                        scene.name,
                        name,
                        f"{int(near.sum())}/{len(scene.truth)}",
                        str(int((~near).sum())),
                        fmt(rms(d[near])),
                        f"{seconds * 1000:.0f}",
                    ]
                )
    header = ["board", "scene", "finder", "found", "extra", "RMS px", "ms"]
    table("Chessboard corners on renders (1280 x 720)", header, rows, md)


def chess_real(md: bool) -> None:
    sets = {
        "chess-perfanalytics-4x7": planarcal.ChessboardBoard(4, 7, 60.0),
        "chess-perfanalytics-6x9": planarcal.ChessboardBoard(6, 9, 80.0),
    }
    rows = []
    for folder, board in sets.items():
        paths = real_images(REAL / folder) if (REAL / folder).is_dir() else []
        if not paths:
            rows.append([folder, "absent", "-", "-", "-", "-"])
            continue
        finders = chess_finders(board)
        found = dict.fromkeys(finders, 0)
        residuals: dict[str, list[float]] = {k: [] for k in finders}
        paired = {k: Paired() for k in finders}
        times: dict[str, list[float]] = {k: [] for k in finders}
        for path in paths:
            image = grey(path)
            reference: tuple[F64, F64] | None = None
            mine_ref: tuple[F64, F64] | None = None
            for name, finder in finders.items():
                grid, points, seconds = timed(finder, image, 1)
                times[name].append(seconds)
                if name == "planarcal" and len(points) == board.n_points:
                    reference = (grid, points)
                if grid is None:  # corners only: those beside planarcal's, on its grid
                    if reference is None or len(points) == 0:
                        continue
                    d = np.linalg.norm(reference[1][:, None] - points[None], axis=2)
                    close = d.min(axis=1) <= 2.0
                    if close.all():
                        found[name] += 1
                    grid = reference[0][close]
                    points = points[d.argmin(axis=1)][close]
                elif len(points) == board.n_points:
                    found[name] += 1
                if len(points):
                    px = local_residuals(grid, points)[0]
                    residuals[name].extend(px.tolist())
                    if name == "planarcal":
                        mine_ref = (grid, points)
                    paired[name].add((grid, points), mine_ref)
        for name in finders:
            rows.append(
                [
                    folder,
                    name,
                    f"{found[name]}/{len(paths)}",
                    fmt(rms(residuals[name]), 3),
                    paired[name].cell(),
                    f"{statistics.median(times[name]) * 1000:.0f}",
                ]
            )
    header = [
        "photos",
        "finder",
        "whole board",
        "local residual RMS px",
        "on corners both find: it / planarcal (n)",
        "median ms",
    ]
    table("Chessboards on real photographs", header, rows, md)


def charuco_finders(board: Any, legacy: bool) -> dict[str, Finder]:
    return {
        "planarcal": planarcal_finder(board),
        "calib-targets charuco": targets_charuco_finder(board, saddle=False),
        "calib-targets charuco (saddle)": targets_charuco_finder(board, saddle=True),
        "OpenCV CharucoDetector (reference)": opencv_charuco_finder(board, legacy),
    }


def charuco_renders(md: bool) -> None:
    boards = [
        planarcal.CharucoBoard(10, 7, 30.0, 22.0, "DICT_5X5_100"),
        planarcal.CharucoBoard(7, 5, 40.0, 30.0, "DICT_APRILTAG_36h11"),
    ]
    rows = []
    for board in boards:
        for scene in scenes(board):
            limit = square_px(scene.truth, board) / 3
            for name, finder in charuco_finders(board, legacy=False).items():
                finder(scene.image)
                ids, points, seconds = timed(finder, scene.image, RUNS)
                known = ids >= 0
                d = np.full(len(ids), np.inf)
                d[known] = np.linalg.norm(points[known] - scene.truth[ids[known]], axis=1)
                right = d <= limit
                rows.append(
                    [
                        f"{board.squares_x}x{board.squares_y} {board.dictionary}",
                        scene.name,
                        name,
                        f"{len(ids)}/{board.n_points}",
                        str(int((~right).sum())),
                        fmt(rms(d[right])),
                        f"{seconds * 1000:.0f}",
                    ]
                )
    header = ["board", "scene", "finder", "corners", "wrong ids", "RMS px", "ms"]
    table("ChArUco on renders (1280 x 720)", header, rows, md)


def charuco_real(md: bool) -> None:
    # Layout as each set's SOURCE.md and benches/bench_charuco.py read it.
    sets = {
        "charuco-microsoft-5x5-14x9": planarcal.CharucoBoard(14, 9, 40, 30, "DICT_5X5_250"),
        "charuco-odri-apriltag16h5-5x7": planarcal.CharucoBoard(5, 7, 40, 30, "DICT_APRILTAG_16h5"),
        "charuco-rlav440-4x4-20x20": planarcal.CharucoBoard(20, 20, 4, 3.2, "DICT_4X4_1000"),
    }
    rows = []
    for folder, board in sets.items():
        paths = real_images(REAL / folder) if (REAL / folder).is_dir() else []
        if not paths:
            rows.append([folder, "absent", "-", "-", "-", "-", "-"])
            continue
        finders = charuco_finders(board, legacy=False)
        corners = dict.fromkeys(finders, 0)
        wrong = dict.fromkeys(finders, 0)
        residuals: dict[str, list[float]] = {k: [] for k in finders}
        paired = {k: Paired() for k in finders}
        times: dict[str, list[float]] = {k: [] for k in finders}
        grid = board.world_points() / board.square
        for path in paths:
            image = grey(path)
            mine_ref: tuple[F64, F64] | None = None
            for name, finder in finders.items():
                ids, points, seconds = timed(finder, image, 1)
                times[name].append(seconds)
                corners[name] += len(ids)
                wrong[name] += int((ids < 0).sum())
                known = ids >= 0
                if known.sum():
                    px, squares = local_residuals(grid[ids[known]], points[known])
                    wrong[name] += int((squares > 1 / 3).sum())
                    residuals[name].extend(px[squares <= 1 / 3].tolist())
                    seen = (grid[ids[known]], points[known])
                    if name == "planarcal":
                        mine_ref = seen
                    paired[name].add(seen, mine_ref)
        for name in finders:
            rows.append(
                [
                    f"{folder} ({len(paths)})",
                    name,
                    str(corners[name]),
                    str(wrong[name]),
                    fmt(rms(residuals[name]), 3),
                    paired[name].cell(),
                    f"{statistics.median(times[name]) * 1000:.0f}",
                ]
            )
    header = [
        "photos",
        "finder",
        "corners",
        "wrong ids",
        "local residual RMS px",
        "on corners both find: it / planarcal (n)",
        "median ms",
    ]
    table("ChArUco on real photographs", header, rows, md)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--markdown", action="store_true", help="print Markdown tables")
    args = parser.parse_args()
    versions = (
        f"chess-corners {_version('chess-corners')}, calib-targets {_version('calib-targets')}, "
        f"OpenCV {cv2.__version__}"
    )
    print(f"bench_board_peers: {versions}")
    start = time.perf_counter()
    chess_renders(args.markdown)
    chess_real(args.markdown)
    charuco_renders(args.markdown)
    charuco_real(args.markdown)
    print(f"\n(total {time.perf_counter() - start:.0f} s)")


def _version(package: str) -> str:
    return version(package)


if __name__ == "__main__":
    main()
