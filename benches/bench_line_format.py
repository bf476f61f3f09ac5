"""What a frame's line costs the loop: formatting (json from the core, csv, a template) and
handing it to a server with clients connected, per frame, for 1 to 100 parts.

Frames of n parts (random positions, IDs out of order, every third part without an angle)
are formatted over and over; each figure is the median of 7 repeats of 2,000 frames, in
microseconds per frame, and for the formats also per part. The server figure is ``send``
of a JSON line to a ServerOutput on loopback with 2 clients reading, and ``answer`` in
trigger mode with no request waiting (what the loop pays between triggers). For scale: at
100 frames per second the loop has 10,000 us per frame.

Run: python benches/bench_line_format.py [--markdown]
"""

from __future__ import annotations

import argparse
import functools
import socket
import statistics
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from reporting import cpu_model, load_average, table_lines

from planarcal.live.line_format import line_format
from planarcal.live.output_server import ServerOutput
from planarcal.live.tracker import FrameResult

REPEATS = 7
FRAMES = 2000


def frame(n: int, seed: int = 0) -> FrameResult:
    rng = np.random.default_rng(seed)
    ids = rng.permutation(np.arange(1, n + 1)).astype(np.int64)
    angles = rng.uniform(-90, 90, n)
    angles[::3] = np.nan
    return FrameResult(
        1234,
        time.time(),
        ids,
        rng.uniform(0, 1280, (n, 2)),
        rng.uniform(0, 300, (n, 2)),
        rng.uniform(0.001, 0.05, n),
        rng.uniform(100, 5000, n),
        angles,
        "robot",
    )


def per_frame_us(work: Callable[[], object]) -> float:
    """Median over REPEATS of the time of one call, microseconds."""
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        for _ in range(FRAMES):
            work()
        times.append((time.perf_counter() - t0) / FRAMES * 1e6)
    return statistics.median(times)


def drain(port: int, stop: threading.Event) -> None:
    with socket.create_connection(("127.0.0.1", port)) as conn:
        conn.settimeout(0.2)
        while not stop.is_set():
            try:
                if not conn.recv(1 << 16):
                    return
            except TimeoutError:
                pass


def server_figures(line: str) -> tuple[float, float]:
    """send() of `line` to 2 reading clients, and answer() with no request, us per call."""
    stop = threading.Event()
    with ServerOutput("127.0.0.1", 0, max_pending_lines=1 << 16) as server:
        readers = [
            threading.Thread(target=drain, args=(server.port, stop), daemon=True) for _ in (1, 2)
        ]
        for r in readers:
            r.start()
        server.wait_clients(2, timeout=5)
        send = per_frame_us(lambda: server.send(line))
        stop.set()
    with ServerOutput("127.0.0.1", 0, trigger_word="TRIGGER") as server:
        answer = per_frame_us(lambda: server.answer(time.time(), lambda: line))
    return send, answer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    formats = {
        "json": line_format("json"),
        "csv": line_format("csv"),
        "template": line_format(template="{id},{x:.2f},{y:.2f},{angle:.1f}"),
    }
    rows = []
    for n in (1, 10, 30, 100):
        f = frame(n)
        row = [str(n)]
        for fmt in formats.values():
            us = per_frame_us(functools.partial(fmt.frame, f))
            row.append(f"{us:.1f} ({us / n:.2f}/part)")
        send, answer = server_figures(formats["json"].frame(f))
        row += [f"{send:.1f}", f"{answer:.2f}"]
        rows.append(row)
    header = ["parts", "json us", "csv us", "template us", "send 2 clients us", "answer idle us"]
    print(f"# {cpu_model()}, load {load_average()}; median of {REPEATS} x {FRAMES} frames")
    for line in table_lines(header, [True] * len(header), rows, args.markdown):
        print(line)


if __name__ == "__main__":
    main()
