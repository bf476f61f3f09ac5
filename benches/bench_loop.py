"""The whole per-frame loop on a 1280 x 720 video, stage by stage (issue 6's targets).

A video of the paper's setup with ten parts moving across the table (rendered by
planarcal.synth, 40 distinct frames looped to --frames, MPEG-4 part 2 in .mp4) is run through

1. decoding alone (cv2.VideoCapture.read, grey), the floor any loop stands on;
2. planarcal's Tracker: decode on its reader thread, detect (the paper's chain with sub-pixel
   outlines), map every centroid in one core call, keep IDs, and serialise each frame to its
   JSON line, as `planarcal run` does.

It prints frames per second, each stage's time per frame, and the share of the per-frame
work spent in planarcal's own code (its Python, its NumPy calls and its Rust core: everything
but OpenCV's decode and image filters). The share comes from a second pass over the same video
with the same work done in sequence on one thread (decode, then Tracker.process and the JSON
line), every cv2 function timed through a wrapper: planarcal's time is the rest, the wrappers'
own cost included (an upper bound). Targets: at least 200 frames per second; planarcal's share
under 10 %.

Run: python benches/bench_loop.py [--frames 2000] [--markdown]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from reporting import cpu_model, load_average, table_lines

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.live.tracker import Tracker

DISTINCT = 40


def parts(k: int) -> list[synth.SceneObject]:
    """Ten parts moving across the table, frame k."""
    out = []
    for i in range(10):
        x = 20.0 + 24.0 * i + 0.8 * k
        y = 30.0 + 14.0 * i + 0.5 * k * (1 if i % 2 else -1) + 40.0
        kind = ("nut", "washer", "disc", "bolt")[i % 4]
        out.append(synth.SceneObject(kind, (x, y), angle_deg=7.0 * i + 2.0 * k, size_mm=8.0))
    return out


def make_video(path: Path, frames: int) -> None:
    clip = [
        synth.render_scene(
            synth.PAPER_CAMERA,
            synth.PAPER_POSE,
            board=None,
            objects=parts(k),
            seed=k,
            **synth.PAPER_EFFECTS,
        ).image
        for k in range(DISTINCT)
    ]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (1280, 720), False)
    for k in range(frames):
        # Back and forth, so the parts move smoothly and their IDs can be kept.
        period = 2 * DISTINCT - 2
        j = k % period
        writer.write(clip[j if j < DISTINCT else period - j])
    writer.release()


def decode_only(path: Path) -> tuple[int, float, list[np.ndarray]]:
    cap = cv2.VideoCapture(str(path))
    n, frames = 0, []
    t0 = time.perf_counter()
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        if n < 200:
            frames.append(grey)
        n += 1
    elapsed = time.perf_counter() - t0
    cap.release()
    return n, elapsed, frames


def timed_split(cal: Calibration, path: Path) -> tuple[int, float, float, float]:
    """(frames, decode s, OpenCV s, planarcal s) of the loop's work done in sequence on one
    thread: each frame decoded (cv2.VideoCapture.read + grey), then Tracker.process and its
    JSON line; every cv2 function planarcal calls is timed through a wrapper, and planarcal's
    own time is the rest of process + serialise (the wrappers' own cost included: an upper
    bound)."""
    spent = [0.0]
    originals: dict[str, Any] = {}

    def timed(f: Any) -> Any:
        def call(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return f(*args, **kwargs)
            finally:
                spent[0] += time.perf_counter() - t0

        return call

    for name in dir(cv2):
        f = getattr(cv2, name)
        if type(f).__name__ == "builtin_function_or_method":
            originals[name] = f
            setattr(cv2, name, timed(f))
    decode = work = 0.0
    frames = 0
    try:
        tracker = Tracker(cal, path)
        cap = cv2.VideoCapture(str(path))
        while True:
            t0 = time.perf_counter()
            ok, frame = cap.read()
            if not ok:
                break
            grey = originals["cvtColor"](frame, cv2.COLOR_BGR2GRAY)
            t1 = time.perf_counter()
            tracker.process(grey, frames, 0.0).to_json()
            t2 = time.perf_counter()
            decode += t1 - t0
            work += t2 - t1
            frames += 1
        cap.release()
        tracker.close()
    finally:
        for name, f in originals.items():
            setattr(cv2, name, f)
    return frames, decode, spent[0], work - spent[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=2000)
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    scene = synth.paper_scene(0).calibration
    cal = Calibration.from_detection(detect_board(scene.image, synth.PAPER_BOARD))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "parts.mp4"
        make_video(path, args.frames)
        n, decode_s, _ = decode_only(path)
        lines = 0
        serialise_s = 0.0
        start = time.perf_counter()
        with Tracker(cal, path) as tracker:
            for result in tracker:
                t0 = time.perf_counter()
                line = result.to_json()
                serialise_s += time.perf_counter() - t0
                lines += len(line) > 0
        wall = time.perf_counter() - start
        p_frames, p_decode, p_opencv, p_own = timed_split(cal, path)
    stats = tracker.stats
    per = 1e3 / stats.frames
    stages = stats.stage_s
    fps = stats.frames / wall
    decode_ms = 1e3 * decode_s / n
    opencv_ms = 1e3 * p_opencv / p_frames
    own_ms = 1e3 * p_own / p_frames
    share = own_ms / (own_ms + opencv_ms + 1e3 * p_decode / p_frames)
    print(
        f"Machine: {cpu_model()}, load {load_average()}; OpenCV {cv2.__version__}, "
        f"{cv2.getNumThreads()} threads"
    )
    print(
        f"{stats.frames} frames of 1280 x 720, {stats.objects / stats.frames:.1f} parts per frame"
    )
    print()
    rows = [
        ["decode alone (cv2.VideoCapture + grey)", f"{n / decode_s:.0f}", f"{decode_ms:.3f}", ""],
        ["whole loop (Tracker + JSON lines)", f"{fps:.0f}", f"{1e3 * wall / stats.frames:.3f}", ""],
        ["  waiting for the reader (decode)", "", f"{stages['read'] * per:.3f}", ""],
        ["  detect", "", f"{stages['detect'] * per:.3f}", ""],
        ["  map (one core call per frame)", "", f"{stages['map'] * per:.3f}", ""],
        ["  track (IDs)", "", f"{stages['track'] * per:.3f}", ""],
        ["  serialise (JSON line)", "", f"{serialise_s * per:.3f}", ""],
        ["in sequence: decode", "", f"{1e3 * p_decode / p_frames:.3f}", ""],
        ["in sequence: OpenCV's image filters", "", f"{opencv_ms:.3f}", ""],
        ["in sequence: planarcal's own code", "", f"{own_ms:.3f}", f"{100 * share:.1f} % of all"],
    ]
    for line in table_lines(
        ["stage", "fps", "ms / frame", "share"], [False, True, True, True], rows, args.markdown
    ):
        print(line)
    print()
    ok = fps >= 200 and share < 0.10
    print(
        f"Targets: {fps:.0f} fps >= 200; planarcal's share {100 * share:.1f} % < 10 %: "
        f"{'PASS' if ok else 'FAIL'}"
    )


if __name__ == "__main__":
    main()
