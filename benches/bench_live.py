"""The live setup page's update rate and latency (issue 24): `planarcal live` run as a user
runs it, on the demo's rendered cell (planarcal.synth.live_video) at 1280 x 720 and 30
frames a second, measured from outside over loopback.

Two sources cut from the cell video: the board held at its three placements (the set-up and
register views: the board found on every frame), and the parts on the conveyor (the watch
view: every part located). Per view, over WINDOW_S seconds:

* shown/s: the JPEG frames a client of the MJPEG stream (the page's <img>) received per
  second, against the source's 30;
* drawn, analysed/s: the server's own rates (GET /api/state's stats): frames drawn and
  encoded, and frames analysed (the board found, focus and exposure measured; or the parts
  located and tracked);
* latency: the server's mean time from a frame read to its drawing (and to its analysis);
* state ms: GET /api/state's round trip, median and 95th percentile (the page polls it
  every 250 ms).

Then the actions' times: capture (a full-resolution detection), the error map after it,
calibrate from three placements (fit, report figures), save, pick, a touch.

Run: python benches/bench_live.py [--window 10] [--markdown]
"""

from __future__ import annotations

import argparse
import contextlib
import http.client
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import cv2
from reporting import Output, cpu_model, load_average, table_lines

from planarcal.synth.live_video import LiveVideo, write_live_video

FPS = 30.0
WINDOW_S = 10.0
BOARD_ARGS = ("--cols", "9", "--rows", "7", "--pitch", "20")


def cut(video: LiveVideo, frames: list[int], path: Path) -> Path:
    """The video's ``frames`` (in order) as their own video."""
    capture = cv2.VideoCapture(str(video.path))
    images = []
    for _ in range(video.frame_count):
        ok, image = capture.read()
        if not ok:
            break
        images.append(image)
    capture.release()
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), FPS, (1280, 720))
    for k in frames:
        writer.write(images[k])
    writer.release()
    return path


class Server:
    """`planarcal live` in a child process on a free loopback port."""

    def __init__(self, args: list[str], cwd: Path) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "planarcal", "live", "--port", "0", *args],
            cwd=cwd,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            env=dict(os.environ, PYTHONUNBUFFERED="1"),
        )
        assert self.process.stdout is not None
        url = urlsplit(self.process.stdout.readline().strip())
        self.host, self.port = url.hostname or "127.0.0.1", url.port or 0

    def call(self, method: str, path: str, body: Any = None) -> tuple[int, Any, float]:
        """(status, answer, seconds)."""
        start = time.perf_counter()
        connection = http.client.HTTPConnection(self.host, self.port, timeout=120)
        data = None if body is None else json.dumps(body).encode()
        connection.request(method, path, body=data, headers={"Content-Type": "application/json"})
        response = connection.getresponse()
        payload = response.read()
        seconds = time.perf_counter() - start
        connection.close()
        kind = response.getheader("Content-Type", "")
        return response.status, json.loads(payload) if "json" in kind else payload, seconds

    def state(self) -> dict[str, Any]:
        return self.call("GET", "/api/state")[1]

    def stop(self) -> None:
        self.process.terminate()
        self.process.wait(timeout=30)


@contextlib.contextmanager
def serving(args: list[str], cwd: Path) -> Iterator[Server]:
    server = Server(args, cwd)
    try:
        yield server
    finally:
        server.stop()


def stream_rate(server: Server, seconds: float) -> float:
    """JPEG frames per second a client of the MJPEG stream receives."""
    connection = http.client.HTTPConnection(server.host, server.port, timeout=30)
    connection.request("GET", "/api/stream.mjpg")
    response = connection.getresponse()
    count, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        line = response.fp.readline()
        if line.startswith(b"Content-Length:"):
            length = int(line.split(b":")[1])
            response.fp.readline()
            response.fp.read(length)
            count += 1
    elapsed = time.perf_counter() - start
    connection.close()
    return count / elapsed


def measure_view(server: Server, seconds: float) -> dict[str, float]:
    """The view's rates and latencies over ``seconds``, the stream read on a thread while
    the state is polled as the page polls it."""
    rate: list[float] = []
    reader = threading.Thread(target=lambda: rate.append(stream_rate(server, seconds)))
    reader.start()
    trips, stats = [], []
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        _, state, took = server.call("GET", "/api/state")
        trips.append(took)
        stats.append(state["stats"])
        time.sleep(0.25)
    reader.join()
    later = stats[len(stats) // 4 :]  # after the first rates settle

    def median(key: str) -> float:
        values = [s[key] for s in later if s[key] is not None]
        return statistics.median(values) if values else float("nan")

    trips.sort()
    return {
        "shown": rate[0],
        "drawn": median("fps"),
        "analysed": median("detect_fps"),
        "latency": median("latency_ms"),
        "analysis_latency": median("detect_latency_ms"),
        "state_ms": 1000 * statistics.median(trips),
        "state_p95_ms": 1000 * trips[int(0.95 * (len(trips) - 1))],
    }


def wait(server: Server, test: Any, timeout: float = 60.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        state = server.state()
        if test(state):
            return state
        time.sleep(0.05)
    raise TimeoutError("the state never came")


def actions(server: Server, video: LiveVideo) -> list[tuple[str, float]]:
    """The actions' times on the board source: capture x3, calibrate, save, pick, touch."""
    out = []
    for k, held in enumerate(video.placements):
        origin = held.points_px[0]

        def here(state: dict[str, Any], at: Any = origin) -> bool:
            d = state["detection"]
            return bool(d["found"]) and abs(d["origin_px"][0] - at[0]) < 3

        while True:
            wait(server, here)
            status, answer, took = server.call("POST", "/api/capture")
            if status == 200 and len(answer["placements"]) == k + 1:
                break
        out.append((f"capture placement {k + 1} (with its error map)", took))
    status, _, took = server.call("POST", "/api/calibrate", {})
    assert status == 200
    out.append(("calibrate from 3 placements (fit, report figures)", took))
    status, _, took = server.call("POST", "/api/save")
    out.append(("save the calibration file", took))
    server.call("POST", "/api/mode", {"mode": "register"})
    first = video.placements[0].points_px
    wait(
        server,
        lambda s: s["detection"]["found"] and abs(s["detection"]["origin_px"][0] - first[0][0]) < 3,
    )
    status, _, took = server.call("POST", "/api/pick", {"x": first[10][0], "y": first[10][1]})
    out.append(("pick a dot", took))
    status, _, took = server.call("POST", "/api/touches", {"id": 10, "robot": [1.0, 2.0]})
    out.append(("add a touch (with the refit)", took))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--window", type=float, default=WINDOW_S)
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    out = Output(args.markdown)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        video = write_live_video(folder / "cell.avi", fps=FPS, hold_s=4.0, parts_s=8.0)
        held = [k for p in video.placements for k in p.frames]
        board = cut(video, held, folder / "board.avi")
        parts = cut(
            video, list(range(video.parts.first_frame, video.frame_count)), folder / "parts.avi"
        )
        rows = []
        with serving(
            ["--source", str(board), "--calibration", "cell.json", *BOARD_ARGS], folder
        ) as s:
            wait(s, lambda st: st["detection"]["found"])
            for view in ("setup", "register"):
                s.call("POST", "/api/mode", {"mode": view})
                rows.append((view, "board at 3 placements", measure_view(s, args.window)))
            s.call("POST", "/api/mode", {"mode": "setup"})
            timed = actions(s, video)
        with serving(["--source", str(parts), "--calibration", "cell.json"], folder) as s:
            wait(s, lambda st: len(st["watch"]["parts"]) > 0)
            rows.append(
                (
                    "watch",
                    f"{len(video.parts.kinds)} parts on a conveyor",
                    measure_view(s, args.window),
                )
            )
    print(f"Machine: {cpu_model()}, {os.cpu_count()} cores; load {load_average()}")
    out.heading(
        f"The live page at 1280 x 720, a {FPS:g} fps source, measured over loopback "
        f"({args.window:g} s per view)"
    )
    head = [
        "view",
        "source",
        "shown/s",
        "drawn/s",
        "analysed/s",
        "latency ms (drawn)",
        "latency ms (analysed)",
        "state ms (median)",
        "state ms (p95)",
    ]
    body = [
        [
            v,
            src,
            f"{m['shown']:.1f}",
            f"{m['drawn']:.1f}",
            f"{m['analysed']:.1f}",
            f"{m['latency']:.0f}",
            f"{m['analysis_latency']:.0f}",
            f"{m['state_ms']:.1f}",
            f"{m['state_p95_ms']:.1f}",
        ]
        for v, src, m in rows
    ]
    print("\n".join(table_lines(head, [k >= 2 for k in range(len(head))], body, args.markdown)))
    out.heading("Actions (one call each, over loopback)")
    print(
        "\n".join(
            table_lines(
                ["action", "s"], [False, True], [[a, f"{t:.3f}"] for a, t in timed], args.markdown
            )
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
