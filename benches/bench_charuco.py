"""ChArUco detection (``planarcal.calib.detect_charuco``) measured against OpenCV's
``cv2.aruco.CharucoDetector`` (default parameters, the right printed layout) (issue 22).
Three sections:

1. **Real photographs** in ``../shared/data/real`` (skipped with a note when absent): the
   Azure Kinect 14 x 9 DICT_5X5_250 board (4096 x 3072 partial views and a 1024 x 1024 IR
   frame), the TriFinger 5 x 7 AprilTag 16h5 board (720 x 540, barrel distortion) and the
   pyCamSet 20 x 20 DICT_4X4_1000 close-ups (even rows, current layout; blur and glare).
   Per set: images, images with a detection, corners found by each (summed), images where
   planarcal finds fewer corners than OpenCV (target 0), corners with a wrong id (each
   corner against the local homography of its found neighbours within two squares: more
   than a third of a square off; target 0), local residual RMS (px; each corner against
   that homography, only the corners both find, for each finder: no truth, the lens and the
   paper's bending included, lower is closer to the grid), median time of each.
2. **Renders** with exact truth (OpenCV's generateImage warped by a known homography and
   area-averaged, tests/calib/test_charuco_renders.py): six boards (DICT_4X4/5X5/6X6,
   AprilTag, 5 x 7 to 20 x 14, markers 0.6-0.83 of the square) at 1280 x 720 or 800 x 600,
   straight and tilted by 35 degrees, sharp, blurred by 0.8 and 1.5 px, with sensor noise.
   Per blur: corners found, wrong ids (more than half a square from the truth), RMS error
   against the truth over all corners each finds and over the corners both find.
3. **Timing**: worst of 3 runs (wall clock, with the CPU time of that run beside it, as
   other work on the machine stretches wall-clock times) on 1280 x 720 images with no board
   (noise, a texture of random blobs and squares), a typical 720p board view, a 720p view
   of a 20 x 14 board (140 markers), a 5312 x 2988 photo of a 14 x 9 board and 5312 x 2988
   noise; PASS/FAIL against the issue's bounds (any 720p image 2 s, typical 720p 0.2 s,
   a 5312 x 2988 photo 8 s).

Deterministic (fixed seeds). Run from the repository root::

    python benches/bench_charuco.py             # everything (about 3 minutes on 2 cores)
    python benches/bench_charuco.py --markdown  # as Markdown
    python benches/bench_charuco.py --only real renders timing

The exit status is 0 whatever the outcome.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests" / "calib"))

from reporting import Output, cpu_model, load_average  # noqa: E402
from test_charuco_renders import (  # noqa: E402
    local_residuals,
    render_charuco,
    view_homography,
)

from planarcal.calib.charuco import CharucoBoard  # noqa: E402
from planarcal.calib.detect_charuco import detect_charuco  # noqa: E402
from planarcal.errors import BoardError, BoardNotFoundError  # noqa: E402

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]
REAL = HERE.parent.parent / "shared" / "data" / "real"
LIMIT_720P, LIMIT_BIG, LIMIT_TYPICAL = 2.0, 8.0, 0.2

REAL_SETS = {
    "charuco-microsoft-5x5-14x9": CharucoBoard(14, 9, 40, 30, "DICT_5X5_250"),
    "charuco-odri-apriltag16h5-5x7": CharucoBoard(5, 7, 40, 30, "DICT_APRILTAG_16h5"),
    "charuco-rlav440-4x4-20x20": CharucoBoard(20, 20, 4, 3.2, "DICT_4X4_1000"),
}


@dataclasses.dataclass
class Found:
    ids: NDArray[np.intp]
    points: F64
    seconds: float
    layout: str | None = None


def planarcal_corners(image: U8, board: CharucoBoard) -> Found:
    start = time.perf_counter()
    try:
        d = detect_charuco(image, board)
    except (BoardNotFoundError, BoardError):
        return Found(np.zeros(0, np.intp), np.zeros((0, 2)), time.perf_counter() - start)
    return Found(d.ids, d.image_points, time.perf_counter() - start, d.layout)


def opencv_corners(image: U8, board: CharucoBoard, legacy: bool) -> Found:
    start = time.perf_counter()
    detector = cv2.aruco.CharucoDetector(board.opencv_board(legacy))
    corners, ids, _, _ = detector.detectBoard(image)
    seconds = time.perf_counter() - start
    if ids is None:
        return Found(np.zeros(0, np.intp), np.zeros((0, 2)), seconds)
    order = np.argsort(ids.ravel())
    return Found(ids.ravel()[order].astype(np.intp), corners.reshape(-1, 2)[order], seconds)


def rms(values: F64) -> float:
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if len(values) else float("nan")


def real_section(out: Output) -> None:
    out.heading("Real photographs: corners found, wrong ids, local residual, time")
    if not REAL.is_dir():
        out.note(f"(skipped: {REAL} is absent)")
        return
    rows = []
    detail = []
    for name, board in REAL_SETS.items():
        folder = REAL / name
        photos = sorted(p for p in folder.iterdir() if p.suffix in (".jpg", ".jpeg", ".png"))
        n_found = ours_total = cv_total = fewer = wrong = 0
        t_ours, t_cv, res_ours, res_cv = [], [], [], []
        for photo in photos:
            image = cv2.imread(str(photo), cv2.IMREAD_GRAYSCALE)
            ours = planarcal_corners(image, board)
            cv_found = opencv_corners(image, board, False)
            n_found += len(ours.ids) > 0
            ours_total += len(ours.ids)
            cv_total += len(cv_found.ids)
            missing = len(np.setdiff1d(cv_found.ids, ours.ids))
            fewer += len(ours.ids) < len(cv_found.ids)
            _, off = local_residuals(board, ours.ids, ours.points)
            bad = int(np.count_nonzero(off > 1 / 3))
            wrong += bad
            t_ours.append(ours.seconds)
            t_cv.append(cv_found.seconds)
            common = np.intersect1d(ours.ids, cv_found.ids)
            if len(common) >= 9:
                pick = Found(common, ours.points[np.isin(ours.ids, common)], 0)
                pick_cv = Found(common, cv_found.points[np.isin(cv_found.ids, common)], 0)
                res_ours.append(local_residuals(board, pick.ids, pick.points)[0])
                res_cv.append(local_residuals(board, pick_cv.ids, pick_cv.points)[0])
            detail.append(
                [
                    f"{name}/{photo.name}",
                    f"{image.shape[1]}x{image.shape[0]}",
                    f"{len(ours.ids)} / {len(cv_found.ids)}",
                    str(missing),
                    str(bad),
                    ours.layout or "-",
                    f"{ours.seconds:.3f} / {cv_found.seconds:.3f}",
                ]
            )
        rows.append(
            [
                name,
                str(len(photos)),
                f"{n_found}",
                f"{ours_total} / {cv_total}",
                str(fewer),
                str(wrong),
                f"{rms(np.concatenate(res_ours)):.3f} / {rms(np.concatenate(res_cv)):.3f}"
                if res_ours
                else "-",
                f"{np.median(t_ours):.3f} / {np.median(t_cv):.3f}",
            ]
        )
    out.table(
        [
            "set",
            "images",
            "detected",
            "corners planarcal / OpenCV",
            "images with fewer",
            "wrong ids",
            "local residual RMS px (common corners) planarcal / OpenCV",
            "median s planarcal / OpenCV",
        ],
        rows,
    )
    out.note("Per photograph:")
    out.table(
        [
            "photo",
            "size",
            "corners planarcal / OpenCV",
            "OpenCV's missing",
            "wrong ids",
            "layout",
            "s planarcal / OpenCV",
        ],
        detail,
    )


RENDER_BOARDS = [
    (CharucoBoard(7, 5, 30, 22, "DICT_5X5_100"), (1280, 720)),
    (CharucoBoard(14, 9, 40, 30, "DICT_5X5_250"), (1280, 720)),
    (CharucoBoard(10, 8, 20, 15, "DICT_4X4_100"), (1280, 720)),
    (CharucoBoard(5, 7, 40, 30, "DICT_APRILTAG_16h5"), (1280, 720)),
    (CharucoBoard(9, 6, 25, 15, "DICT_6X6_250"), (1280, 720)),
    (CharucoBoard(20, 14, 10, 8, "DICT_4X4_250"), (800, 600)),
]


def renders_section(out: Output) -> None:
    out.heading("Renders: error against the truth (px)")
    rows = []
    for blur in (0.0, 0.8, 1.5):
        ours_err, cv_err, ours_common, cv_common = [], [], [], []
        n_ours = n_cv = wrong_ours = wrong_cv = 0
        for seed, (board, size) in enumerate(RENDER_BOARDS):
            for tilt in (0, 35):
                hom = view_homography(
                    board, size, fill=0.8, tilt_x=tilt, tilt_y=tilt / 2, turn=12 + 40 * seed
                )
                image, truth = render_charuco(
                    board, hom, size, blur=blur, noise=2.0 if blur else 0.0, seed=seed
                )
                square_px = np.linalg.norm(truth[1] - truth[0])
                ours = planarcal_corners(image, board)
                cv_found = opencv_corners(image, board, False)
                e_ours = np.linalg.norm(ours.points - truth[ours.ids], axis=1)
                e_cv = np.linalg.norm(cv_found.points - truth[cv_found.ids], axis=1)
                wrong_ours += int(np.count_nonzero(e_ours > square_px / 2))
                wrong_cv += int(np.count_nonzero(e_cv > square_px / 2))
                n_ours += len(ours.ids)
                n_cv += len(cv_found.ids)
                ours_err.append(e_ours)
                cv_err.append(e_cv)
                ours_common.append(e_ours[np.isin(ours.ids, cv_found.ids)])
                cv_common.append(e_cv[np.isin(cv_found.ids, ours.ids)])
        rows.append(
            [
                f"blur {blur:g} px" + (", noise 2" if blur else ""),
                f"{n_ours} / {n_cv}",
                f"{wrong_ours} / {wrong_cv}",
                f"{rms(np.concatenate(ours_err)):.4f} / {rms(np.concatenate(cv_err)):.4f}",
                f"{rms(np.concatenate(ours_common)):.4f} / {rms(np.concatenate(cv_common)):.4f}",
            ]
        )
    out.table(
        [
            f"{len(RENDER_BOARDS) * 2} views",
            "corners planarcal / OpenCV",
            "wrong ids",
            "RMS all found",
            "RMS common corners",
        ],
        rows,
    )


def _texture(size: tuple[int, int], seed: int) -> U8:
    rng = np.random.default_rng(seed)
    w, h = size
    image = np.full((h, w), 128, np.uint8)
    for _ in range(3000):
        x, y = int(rng.integers(0, w)), int(rng.integers(0, h))
        s = int(rng.integers(3, 40))
        colour = int(rng.integers(0, 256))
        if rng.random() < 0.5:
            cv2.rectangle(image, (x, y), (x + s, y + s), colour, -1)
        else:
            cv2.circle(image, (x, y), s // 2, colour, -1)
    return np.asarray(cv2.GaussianBlur(image, (0, 0), 0.8), np.uint8)


def timing_section(out: Output) -> None:
    out.heading("Timing: worst of 3 runs (s)")
    rng = np.random.default_rng(7)
    typical_board = CharucoBoard(7, 5, 30, 22, "DICT_5X5_100")
    many = CharucoBoard(20, 14, 10, 8, "DICT_4X4_250")
    big = CharucoBoard(14, 9, 40, 30, "DICT_5X5_250")
    size = (1280, 720)
    typical, _ = render_charuco(
        typical_board,
        view_homography(typical_board, size, fill=0.6, tilt_x=25, turn=10),
        size,
        blur=0.8,
        noise=2.0,
    )
    many_img, _ = render_charuco(
        many, view_homography(many, size, fill=0.85, tilt_x=20, turn=5), size, blur=0.8, noise=2.0
    )
    big_size = (5312, 2988)
    big_img, _ = render_charuco(
        big,
        view_homography(big, big_size, fill=0.6, tilt_x=30, turn=-8),
        big_size,
        blur=1.5,
        noise=2.0,
    )
    cases: list[tuple[str, Callable[[], U8], CharucoBoard, float]] = [
        (
            "720p noise",
            lambda: rng.integers(0, 256, (720, 1280)).astype(np.uint8),
            typical_board,
            LIMIT_720P,
        ),
        ("720p texture, no board", lambda: _texture(size, 3), typical_board, LIMIT_720P),
        ("720p typical board view (7 x 5)", lambda: typical, typical_board, LIMIT_TYPICAL),
        ("720p 20 x 14 board, 140 markers", lambda: many_img, many, LIMIT_720P),
        ("5312 x 2988 board photo (14 x 9)", lambda: big_img, big, LIMIT_BIG),
        (
            "5312 x 2988 noise",
            lambda: rng.integers(0, 256, (2988, 5312)).astype(np.uint8),
            big,
            LIMIT_BIG,
        ),
    ]
    rows = []
    for name, make, board, limit in cases:
        image = make()
        worst, worst_cpu, corners = 0.0, 0.0, 0
        for _ in range(3):
            cpu = time.process_time()
            found = planarcal_corners(image, board)
            cpu = time.process_time() - cpu
            if found.seconds > worst:
                worst, worst_cpu = found.seconds, cpu
            corners = len(found.ids)
        rows.append(
            [
                name,
                f"{worst:.3f}",
                f"{worst_cpu:.3f}",
                str(corners),
                f"{limit:g}",
                "PASS" if worst <= limit else "FAIL",
            ]
        )
    out.table(["image", "worst s", "its CPU s", "corners", "bound s", "result"], rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--markdown", action="store_true", help="print Markdown tables")
    parser.add_argument(
        "--only", nargs="+", choices=("real", "renders", "timing"), help="some sections"
    )
    args = parser.parse_args()
    out = Output(args.markdown)
    sections = {"real": real_section, "renders": renders_section, "timing": timing_section}
    for name, section in sections.items():
        if args.only is None or name in args.only:
            section(out)
    out.note(
        f"OpenCV {cv2.__version__}; {cpu_model()}, {cv2.getNumThreads()} OpenCV threads; "
        f"load {load_average()}"
    )


if __name__ == "__main__":
    main()
