"""Partial views of a circle grid with fiducial dots (issue 22), on the real UCL metal-plate
photographs (../shared/data/real/ucl-dotty-metal: 16 x 14 dots 5 mm apart, fiducials 69, 74,
149 and 154). Each photograph is read whole, then:

* cropped on each side so that the image edge cuts off the outermost 1, 20 or 40 dot centres
  (a row or column cut off, wholly or partly: the plate is tilted);
* with dots painted over in white (glare): a regular dot (100), a fiducial (69), the corner
  (0), then four at once;
* with a dark bar laid across columns 6 to 8 (an object splitting the lattice in two).

For each view: the dots read (of 224), the largest distance of a dot from the same id in the
whole view (px; the crop's offset added back), the homography RMS (the lens bends the plate:
the whole view's is 2.3-2.6 px) and the time. Then the same crops with the plate described
without its fiducials: read where the part in view still spans the plate, refused as partial
and ambiguous otherwise. Run from the repository root::

    python benches/bench_partial_circles.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.detect import detect_circle_grid
from planarcal.calib.detection import BoardDetection
from planarcal.errors import BoardNotFoundError

UCL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real" / "ucl-dotty-metal"
BOARD = CircleGridBoard(16, 14, 5.0, fiducials=(69, 74, 149, 154))
PLAIN = CircleGridBoard(16, 14, 5.0)
SIDES = ("top", "bottom", "left", "right")
DEPTHS = (1, 20, 40)


def crop(
    image: NDArray[np.uint8], pts: NDArray[np.float64], side: str, depth: int
) -> tuple[NDArray[np.uint8], tuple[int, int]]:
    """The image cut `depth` dot centres into `side`, and the crop's offset (x, y)."""
    axis = 1 if side in ("top", "bottom") else 0
    values = np.sort(pts[:, axis])
    if side in ("top", "left"):
        cut = int(values[depth - 1]) + 3
        out = image[cut:] if axis else image[:, cut:]
        return np.ascontiguousarray(out), ((0, cut) if axis else (cut, 0))
    cut = int(np.ceil(values[::-1][depth - 1])) - 3
    out = image[:cut] if axis else image[:, :cut]
    return np.ascontiguousarray(out), (0, 0)


def row(
    label: str,
    whole: BoardDetection,
    image: NDArray[np.uint8],
    offset: tuple[int, int],
    board: CircleGridBoard,
) -> str:
    start = time.perf_counter()
    try:
        det = detect_circle_grid(image, board)
    except BoardNotFoundError as e:
        why = "partial and ambiguous" if "partial and ambiguous" in str(e) else "not found"
        return f"{label:<28} | {'refused: ' + why:>33} | {time.perf_counter() - start:5.2f}"
    elapsed = time.perf_counter() - start
    got = det.image_points + np.asarray(offset, dtype=np.float64)
    gap = float(np.hypot(*(got - whole.image_points[det.ids]).T).max())
    return (
        f"{label:<28} | {len(det.ids):4d} dots | max {gap:6.3f} px | "
        f"RMS {det.residual_rms_px:5.3f} | {elapsed:5.2f}"
    )


def main() -> int:
    names = sorted(UCL.glob("*_left_image.png"))
    if not names:
        print(f"the UCL photographs are not here ({UCL})")
        return 0
    print(
        "view                         | dots read, worst distance from the whole view, "
        "homography RMS | s"
    )
    for path in names:
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        whole = detect_circle_grid(image, BOARD)
        pts = whole.image_points
        print(f"{path.name}: whole, {len(whole.ids)} dots, RMS {whole.residual_rms_px:.3f} px")
        for side in SIDES:
            for depth in DEPTHS:
                part, offset = crop(image, pts, side, depth)
                print(row(f"  {side} cut, {depth} gone", whole, part, offset, BOARD))
        radius = int(0.45 * whole.pitch_px)
        for lost in ([100], [69], [0], [100, 101, 117, 69]):
            painted = image.copy()
            for k in lost:
                cv2.circle(painted, tuple(int(v) for v in np.rint(pts[k])), radius, 255, -1)
            print(row(f"  glare on {lost}", whole, painted, (0, 0), BOARD))
        barred = image.copy()
        bar = np.array([pts[6], pts[8], pts[8 + 16 * 13], pts[6 + 16 * 13]])
        middle = bar.mean(axis=0)
        cv2.fillConvexPoly(barred, np.rint(middle + 1.25 * (bar - middle)).astype(np.int32), 60)
        print(row("  bar over columns 6-8", whole, barred, (0, 0), BOARD))
        for side in ("top", "left"):
            for depth in DEPTHS:
                part, offset = crop(image, pts, side, depth)
                print(row(f"  plain: {side} cut, {depth} gone", whole, part, offset, PLAIN))
    return 0


if __name__ == "__main__":
    sys.exit(main())
