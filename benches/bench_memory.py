"""Memory growth of the production loop on full-size frames over a long run.

The video of bench_loop.py (the paper's setup, 1280 x 720, ten parts moving across the
table: 40 distinct rendered frames looped back and forth to --frames, MPEG-4 part 2 in .mp4)
is written to a temporary directory and run through planarcal's Tracker, each frame
serialised to its JSON line, as `planarcal run` does. Every --every frames, and at frame
1,000 and the last frame, the loop collects garbage (gc.collect(), so only memory still
referenced counts) and reads the process's resident set size from /proc/self/statm (Linux).
No tracemalloc: it slows the loop too much.

It prints each sample's RSS and its change since the first sample after the warm-up (frame
1,000: decoder buffers, caches and the allocator's arenas have settled by then), and the
growth between frame 1,000 and the last frame, in MiB and in bytes per frame. Target: less
than 4 MiB between frame 1,000 and the end (the 160 x 120 test in tests/live/test_tracker.py
asks the same of 10,000 small frames).

Run: python benches/bench_memory.py [--frames 10000] [--every 500] [--markdown]
"""

from __future__ import annotations

import argparse
import gc
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import cv2

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_loop import make_video
from reporting import cpu_model, load_average, table_lines

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.live.tracker import Tracker

WARMUP = 1_000
"""Frames before the baseline sample: growth is measured from here to the end."""
TARGET_MIB = 4.0
MIB = 2**20
STATM = Path("/proc/self/statm")


def rss_bytes() -> int:
    """The process's resident set size now (Linux: /proc/self/statm's second field)."""
    with STATM.open(encoding="ascii") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def peak_rss_bytes() -> int:
    """The process's largest resident set size so far (Linux reports ru_maxrss in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=10_000)
    parser.add_argument("--every", type=int, default=500, help="frames between RSS samples")
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    if args.frames <= WARMUP:
        parser.error(f"--frames must be more than {WARMUP} (the warm-up)")
    if args.every < 1:
        parser.error("--every must be at least 1")
    if not STATM.exists():
        sys.exit(f"needs {STATM} (Linux) to read the resident set size")

    scene = synth.paper_scene(0).calibration
    cal = Calibration.from_detection(detect_board(scene.image, synth.PAPER_BOARD))
    samples: list[tuple[int, int]] = []  # (frames processed, RSS bytes)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "parts.mp4"
        t0 = time.perf_counter()
        make_video(path, args.frames)
        write_s = time.perf_counter() - t0
        video_mib = path.stat().st_size / MIB
        gc.collect()
        before = rss_bytes()
        frames = 0
        start = time.perf_counter()
        with Tracker(cal, path) as tracker:
            for result in tracker:
                result.to_json()
                frames += 1
                if frames % args.every == 0 or frames in (WARMUP, args.frames):
                    gc.collect()
                    samples.append((frames, rss_bytes()))
        wall = time.perf_counter() - start
    if not samples or samples[-1][0] != frames:  # the video had fewer frames than written
        gc.collect()
        samples.append((frames, rss_bytes()))
    stats = tracker.stats

    print(
        f"Machine: {cpu_model()}, load {load_average()}; OpenCV {cv2.__version__}, "
        f"{cv2.getNumThreads()} threads"
    )
    print(
        f"{stats.frames} frames of 1280 x 720 ({video_mib:.1f} MiB of MPEG-4, written in "
        f"{write_s:.1f} s), {stats.objects / max(stats.frames, 1):.1f} parts per frame; "
        f"undecodable {stats.frames_undecodable}, failed {stats.failed}, dropped "
        f"{stats.frames_dropped}"
    )
    print(
        f"Loop: {stats.frames / wall:.0f} frames per second ({wall:.1f} s, Tracker + JSON "
        f"lines + an RSS sample every {args.every} frames)"
    )
    print()

    base = next(((n, rss) for n, rss in samples if n >= WARMUP), None)
    rows = [["before the loop", f"{before / MIB:.1f}", ""]]
    for n, rss in samples:
        change = "(warm-up)" if base is None or n < base[0] else f"{(rss - base[1]) / MIB:+.2f}"
        rows.append([f"{n:,}", f"{rss / MIB:.1f}", change])
    base_label = f"since frame {base[0]:,}" if base is not None else "since warm-up"
    for line in table_lines(
        ["frames", "RSS MiB", f"change MiB ({base_label})"],
        [True, True, True],
        rows,
        args.markdown,
    ):
        print(line)
    print()

    print(
        f"Peak RSS of the process (ru_maxrss, writing the video included): "
        f"{peak_rss_bytes() / MIB:.1f} MiB"
    )
    if base is None or base[0] >= samples[-1][0]:
        print(f"Too few frames ({frames}) past the warm-up to measure growth: FAIL")
        return
    growth = samples[-1][1] - base[1]
    span = samples[-1][0] - base[0]
    print(
        f"RSS growth between frame {base[0]:,} and frame {samples[-1][0]:,}: "
        f"{growth / MIB:+.2f} MiB, {growth / span:+.0f} bytes per frame"
    )
    ok = growth < TARGET_MIB * MIB
    print(
        f"Target: growth < {TARGET_MIB:g} MiB between frame {WARMUP:,} and the end: "
        f"{'PASS' if ok else 'FAIL'}"
    )


if __name__ == "__main__":
    main()
