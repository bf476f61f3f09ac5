"""The registration to the robot, measured against exact truth (issue 14).

The paper's rendered scene (synth.paper_scene(0): its board image calibrated, its ten parts
located in the parts image; the board lies at the table's origin, so the parts' true board
positions are known). For each set of touched dots, many random robots: a mirrored rotation
and offset of the board, touches with 0.05 mm of noise per axis (a robot's repeatability),
registered with Calibration.register. Measured at the parts:

- the map's own error (RobotFrame.to_robot of the parts' true board positions against their
  true robot positions) against the 1-sigma it predicts there (RobotFrame.std_mm): RMS, worst,
  and RMS actual / RMS predicted;
- the parts' whole error in robot mm (locate_objects(frame="robot")) against the truth, and
  against the robot-frame 1-sigma it reports (which also holds the board 1-sigma).

Run: python benches/bench_registration.py [--robots 200]
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from numpy.typing import NDArray

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.live.objects import locate_objects

F64 = NDArray[np.float64]

TOUCH_NOISE_MM = 0.05
DOT_SETS = {
    "4 (the corners)": [0, 13, 126, 139],
    "6 (corners + 2)": [0, 13, 126, 139, 46, 93],
    "8 (corners + edges + 2)": [0, 6, 13, 56, 69, 126, 132, 139],
}


def _random_robot(rng: np.random.Generator) -> F64:
    a = rng.uniform(-math.pi, math.pi)
    m = np.eye(3)
    m[:2, :2] = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]) @ np.diag(
        [1.0, -1.0]
    )
    m[:2, 2] = rng.uniform(-600.0, 600.0, 2)
    return m


def _map(m: F64, points: F64) -> F64:
    out: F64 = points @ m[:2, :2].T + m[:2, 2]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=200, help="random robots per dot set")
    args = parser.parse_args()
    scene = synth.paper_scene(0)
    cal = Calibration.from_detection(detect_board(scene.calibration.image, synth.PAPER_BOARD))
    assert cal.board is not None
    found = locate_objects(scene.objects.image, cal)
    seen = np.array([o.world_mm for o in found])
    truth = scene.objects.object_centroids_mm
    truth = truth[[int(np.argmin(np.hypot(*(truth - s).T))) for s in seen]]
    rng = np.random.default_rng(0)
    print(
        "| touched dots | map error at the parts, RMS / worst | predicted (RMS) | actual / "
        "predicted | parts in robot mm, RMS / worst | reported 1-sigma (RMS) |"
    )
    print("|---|---|---|---|---|---|")
    for name, dots in DOT_SETS.items():
        map_err, map_pred, part_err, part_std = [], [], [], []
        for _ in range(args.robots):
            robot = _random_robot(rng)
            touches = _map(robot, cal.board.world_points()[dots])
            touches += rng.normal(0.0, TOUCH_NOISE_MM, touches.shape)
            reg = cal.register(touches, dots=dots)
            frame = reg.robot_frame
            assert frame is not None
            true_robot = _map(robot, truth)
            map_err.append(np.hypot(*(frame.to_robot(truth) - true_robot).T))
            map_pred.append(frame.std_mm(truth))
            located = locate_objects(scene.objects.image, reg, frame="robot")
            mm = np.array([o.world_mm for o in located], dtype=np.float64)
            std = np.array([o.world_std_mm for o in located], dtype=np.float64)
            part_err.append(np.hypot(*(mm - true_robot).T))
            part_std.append(std)
        e, p = np.concatenate(map_err), np.concatenate(map_pred)
        pe, ps = np.concatenate(part_err), np.concatenate(part_std)

        def rms(x: F64) -> float:
            return float(np.sqrt(np.mean(x**2)))

        print(
            f"| {name} | {rms(e):.3f} / {e.max():.3f} mm | {rms(p):.3f} mm | "
            f"{rms(e) / rms(p):.2f} | {rms(pe):.3f} / {pe.max():.3f} mm | {rms(ps):.3f} mm |"
        )


if __name__ == "__main__":
    main()
