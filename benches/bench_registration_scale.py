"""How the registration to the robot scales with its number of pairs (issue 21).

A touch-point CSV of N dot pairs (dots drawn at random from the paper's 14 x 10 board, each
touched with 0.05 mm of noise per axis, mirrored robot; 45k rows is about 0.7 MB, under the
reader's 1 MiB cap), for N = 100, 1k, 10k, 45k:

- read: ``read_touch_csv`` of the file;
- register: ``Calibration.register`` (the fit, the leave-one-out errors, the outlier search);
- load: ``RobotFrame.from_dict`` of its dict (the refit a calibration file's load makes);
- and, up to --reference-max pairs, the leave-one-out errors refitted one point at a time,
  the way they were computed before (quadratic), for comparison.

Before issue 21 a 45k-row file did not finish in 600 s and 20k pairs took 237 s to load.

Run: python benches/bench_registration_scale.py [--sizes 100 1000 10000 45000]
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from planarcal.calib.calibration import Calibration
from planarcal.robot.outliers import leave_one_out
from planarcal.robot.registration import RobotFrame
from planarcal.robot.touch_csv import read_touch_csv
from planarcal.robot.transform_fit import apply, fit

F64 = NDArray[np.float64]

CALIBRATION = Path(__file__).parent.parent / "tests" / "robot" / "data" / "calibration_v2.json"
TOUCH_NOISE_MM = 0.05


def _robot_matrix() -> F64:
    a = math.radians(-127.0)
    m = np.eye(3)
    m[:2, :2] = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]) @ np.diag(
        [1.0, -1.0]
    )
    m[:2, 2] = (412.0, -233.0)
    return m


def _write_csv(path: Path, cal: Calibration, n: int, rng: np.random.Generator) -> None:
    assert cal.board is not None
    dots = rng.integers(0, cal.board.n_points, n)
    robot = apply(_robot_matrix(), cal.board.world_points()[dots])
    robot += rng.normal(0.0, TOUCH_NOISE_MM, robot.shape)
    rows = "".join(f"{d},{x:.2f},{y:.2f}\n" for d, (x, y) in zip(dots, robot, strict=True))
    path.write_text("dot,robot_x,robot_y\n" + rows)


def _reference_leave_one_out(plane: F64, robot: F64, reflected: bool) -> F64:
    """The quadratic way: refit without each point (rigid), one fit at a time."""
    n = len(plane)
    out = np.empty(n)
    for i in range(n):
        keep = np.arange(n) != i
        m = fit(plane[keep], robot[keep], "rigid", reflected)
        out[i] = float(np.hypot(*(apply(m, plane[i : i + 1])[0] - robot[i])))
    return out


def _row(cal: Calibration, path: Path, n: int, reference_max: int) -> str:
    """One table row: the timings of N pairs read, registered, loaded and left out."""
    t = time.perf_counter()
    touches = read_touch_csv(path)
    t_read = time.perf_counter() - t
    t = time.perf_counter()
    frame = cal.register(touches.robot, dots=touches.dots).robot_frame
    t_register = time.perf_counter() - t
    assert frame is not None
    data = frame.to_dict()
    t = time.perf_counter()
    RobotFrame.from_dict(data)
    t_load = time.perf_counter() - t
    plane, robot = frame.plane_mm, frame.robot_mm
    t = time.perf_counter()
    fast = leave_one_out(plane, robot, "rigid", frame.reflected)
    t_loo = time.perf_counter() - t
    reference = difference = "-"
    if n <= reference_max:
        t = time.perf_counter()
        slow = _reference_leave_one_out(plane, robot, frame.reflected)
        reference = f"{time.perf_counter() - t:.2f} s"
        difference = f"{float(np.abs(fast - slow).max()):.1e} mm"
    return (
        f"| {n} | {path.stat().st_size / 1024:.0f} KiB | {t_read:.2f} s | {t_register:.2f} s "
        f"| {t_load:.2f} s | {t_loo * 1000:.1f} ms | {reference} | {difference} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 10_000, 45_000])
    parser.add_argument(
        "--reference-max",
        type=int,
        default=10_000,
        help="largest N for the one-point-at-a-time leave-one-out",
    )
    args = parser.parse_args()
    cal = Calibration.load(CALIBRATION)
    rng = np.random.default_rng(0)
    print(
        "| pairs | CSV size | read | register | load (refit) | leave-one-out | "
        "the same refitted one at a time | largest difference |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as folder:
        for n in args.sizes:
            path = Path(folder) / f"touch_{n}.csv"
            _write_csv(path, cal, n, rng)
            print(_row(cal, path, n, args.reference_max), flush=True)


if __name__ == "__main__":
    main()
