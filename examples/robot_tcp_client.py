"""A robot program that reads planarcal's parts over TCP with nothing but the standard library.

What it shows: the controller's side of ``planarcal run -o tcp-listen://HOST:PORT --format
csv``, as a robot or PLC program does it: open one TCP connection, read a line per frame,
split it on commas, and turn each part's fields into numbers (``read_parts``: ``socket`` and
nothing else, so it ports to a robot language's socket calls). In the csv format a line is
``frame,t,coords,n`` and then ``id,x,y,angle,std`` for each of the n parts; a part too round
for an angle says ``nan``; an error is the line ``ERROR,<message>``. With ``--trigger`` it asks
for each frame (it sends ``TRIGGER`` and reads the one line that answers it), as a robot that
is ready for its next pick does.

For the demo it sets up a cell first (planarcal, not the controller): it renders the paper's
board and a short video of ten parts moving along the table (planarcal.synth, exact truth),
calibrates from the board image and starts ``planarcal run`` on the video as a server, on a
free port of 127.0.0.1. It then reads ``--parts`` parts, prints them, and checks each against
where the part was on that frame. A video file is read as fast as it decodes, not at its
frame rate, so the run is over within a second: the controller connects as soon as the
server says it listens.

Run it from the repository root (about 10 s)::

    python examples/robot_tcp_client.py
    python examples/robot_tcp_client.py --trigger --parts 30

On a real cell, point it at the planarcal run that serves it (started with
``-o tcp-listen://0.0.0.0:5000 --format csv``, with ``--trigger`` for the request mode)::

    python examples/robot_tcp_client.py --connect 192.168.0.20:5000 --parts 10

It exits with status 1 when it receives fewer parts than asked for, an error line, or (in
the demo) a part further than ``--tolerance-mm`` from the truth.
"""

from __future__ import annotations

import argparse
import dataclasses
import queue
import socket
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import NamedTuple

import cv2
import numpy as np

import planarcal
from planarcal import synth

# --- The controller: the Python standard library only -------------------------------------


class Part(NamedTuple):
    """One part of one frame's line: its id, position (mm) and 1-sigma (mm) in the frame of
    reference the line names (``coords``: board, or robot once registered), and its angle
    (degrees; None for a part too round for one)."""

    frame: int
    coords: str
    id: int
    x_mm: float
    y_mm: float
    angle_deg: float | None
    std_mm: float


class StreamError(RuntimeError):
    """planarcal sent an error line (``ERROR,<message>``)."""


FIELDS_PER_PART = 5  # --format csv: id,x,y,angle,std


def parse_line(line: str) -> list[Part]:
    """The parts of one csv line; StreamError for an error line."""
    fields = line.rstrip("\r\n").split(",")
    if fields[0] == "ERROR":
        raise StreamError(fields[1])
    frame, coords, count = int(fields[0]), fields[2], int(fields[3])
    parts = []
    for k in range(count):
        pid, x, y, angle, std = fields[4 + FIELDS_PER_PART * k : 4 + FIELDS_PER_PART * (k + 1)]
        # Check the nan of a round part before using its angle: it is not 0.
        turn = None if angle == "nan" else float(angle)
        parts.append(Part(frame, coords, int(pid), float(x), float(y), turn, float(std)))
    return parts


def read_parts(host: str, port: int, count: int, *, trigger: bool = False) -> list[Part]:
    """At least ``count`` parts from the planarcal run serving at host:port, one frame's line
    at a time (with ``trigger``, one request per line). Fewer if the stream ends first;
    StreamError if planarcal answers with an error line."""
    parts: list[Part] = []
    with socket.create_connection((host, port), timeout=10.0) as connection:
        stream = connection.makefile("rw", encoding="ascii", newline="\n")
        while len(parts) < count:
            if trigger:
                stream.write("TRIGGER\n")
                stream.flush()
            line = stream.readline()
            if not line:  # planarcal closed the connection: its run is over
                break
            parts += parse_line(line)
    return parts


# --- The demo's cell: planarcal renders, calibrates and serves ------------------------------

RENDERS = 10  # distinct positions of the parts in the video
HOLD_FRAMES = 6  # frames each position is held for
STEP_MM = 2.0  # how far the parts move between positions (board x)


def render_cell(folder: Path, seed: int) -> tuple[Path, Path, list[np.ndarray]]:
    """(the calibration file, the video, each frame's true part positions in board mm): the
    paper's board and camera, then the paper's ten parts moving along the board's x."""
    scene = synth.paper_scene(seed=seed, objects=False)
    calibration = planarcal.Calibration.from_image(scene.calibration.image, synth.PAPER_BOARD)
    calibration_file = calibration.save(folder / "calib.json")

    camera = synth.PAPER_CAMERA
    video = folder / "conveyor.avi"
    writer = cv2.VideoWriter(
        str(video), cv2.VideoWriter.fourcc(*"MJPG"), 10.0, (camera.width, camera.height), False
    )
    writer.set(cv2.VIDEOWRITER_PROP_QUALITY, 100)
    truth: list[np.ndarray] = []
    for k in range(RENDERS):
        shift = STEP_MM * (k - RENDERS / 2)
        parts = [
            dataclasses.replace(p, position_mm=(p.position_mm[0] + shift, p.position_mm[1]))
            for p in synth.PAPER_OBJECTS
        ]
        # The paper's camera and lighting over the parts, the board taken away.
        frame = synth.render_paper_look(synth.PAPER_CAMERA, synth.PAPER_POSE, None, parts, seed + k)
        for _ in range(HOLD_FRAMES):
            writer.write(frame.image)
            truth.append(frame.object_centroids_mm)
    writer.release()
    return calibration_file, video, truth


class Server(NamedTuple):
    process: subprocess.Popen[str]
    host: str
    port: int
    log: list[str]


def start_planarcal(video: Path, calibration: Path, *, trigger: bool) -> Server:
    """``planarcal run`` on the video, serving csv lines on a free port of 127.0.0.1; returns
    once it says where it listens (its stderr is kept in ``log``)."""
    command = [
        *(sys.executable, "-m", "planarcal", "run"),
        *("--source", str(video), "--calibration", str(calibration)),
        *("-o", "tcp-listen://127.0.0.1:0", "--format", "csv"),
        *(["--trigger"] if trigger else []),
    ]
    process = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    log: list[str] = []
    address: queue.Queue[str | None] = queue.Queue()

    def read_stderr() -> None:
        assert process.stderr is not None
        for line in process.stderr:
            log.append(line)
            # "planarcal run: listening on 127.0.0.1:PORT[; trigger mode: ...]"
            if line.startswith("planarcal run: listening on "):
                address.put(line.split("listening on ", 1)[1].split(";")[0].strip())
        address.put(None)  # the run ended without listening

    # Drained all along: a full pipe would block planarcal's warnings.
    threading.Thread(target=read_stderr, daemon=True).start()
    spec = address.get(timeout=120.0)
    if spec is None:
        process.wait()
        raise RuntimeError(f"planarcal run did not start: {''.join(log)}")
    host, _, port = spec.rpartition(":")
    return Server(process, host.strip("[]"), int(port), log)


def error_mm(part: Part, truth: list[np.ndarray]) -> float:
    """How far the part is from the nearest part on its frame (mm)."""
    return float(np.hypot(*(truth[part.frame] - (part.x_mm, part.y_mm)).T).min())


def check(parts: list[Part], truth: list[np.ndarray], tolerance_mm: float) -> list[str]:
    """What is wrong with the parts received, against each frame's truth."""
    problems = []
    for frame in sorted({p.frame for p in parts}):
        seen = sum(p.frame == frame for p in parts)
        if seen != len(truth[frame]):
            problems.append(f"frame {frame}: {seen} parts, {len(truth[frame])} placed")
    for p in parts:
        error = error_mm(p, truth)
        if p.coords != "board" or not error <= tolerance_mm:
            problems.append(f"frame {p.frame} part {p.id}: {error:.3f} mm from the truth")
    return problems


def print_parts(parts: list[Part]) -> None:
    for p in parts:
        angle = "round" if p.angle_deg is None else f"{p.angle_deg:6.1f} deg"
        print(
            f"frame {p.frame:3d}  part {p.id:2d}  at ({p.x_mm:8.3f}, {p.y_mm:8.3f}) mm "
            f"+- {p.std_mm:.3f}  {angle}  ({p.coords} frame)"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", type=int, default=20, help="how many parts to read")
    parser.add_argument("--trigger", action="store_true", help="ask for each frame (TRIGGER)")
    parser.add_argument(
        "--connect", metavar="HOST:PORT", help="a planarcal run already serving csv lines"
    )
    parser.add_argument("--seed", type=int, default=0, help="the demo's rendered images")
    parser.add_argument(
        "--tolerance-mm", type=float, default=0.15, help="the demo's check (default 0.15 mm)"
    )
    args = parser.parse_args(argv)

    if args.connect is not None:
        host, _, port = args.connect.rpartition(":")
        parts = read_parts(host.strip("[]"), int(port), args.parts, trigger=args.trigger)
        print_parts(parts)
        return 0 if len(parts) >= args.parts else 1

    with tempfile.TemporaryDirectory(prefix="planarcal-robot-") as folder:
        calibration, video, truth = render_cell(Path(folder), args.seed)
        print(f"Rendered {len(truth)} frames of the paper's 10 parts; calibrated; serving.")
        server = start_planarcal(video, calibration, trigger=args.trigger)
        try:
            parts = read_parts(server.host, server.port, args.parts, trigger=args.trigger)
        except (OSError, StreamError) as error:
            print(f"FAIL: {type(error).__name__}: {error}")
            parts = []
        finally:
            status = server.process.wait(timeout=60.0)
    print_parts(parts)
    problems = check(parts, truth, args.tolerance_mm)
    if len(parts) < args.parts:
        problems.append(f"{len(parts)} parts received, {args.parts} asked for")
    if status != 0:
        problems.append(f"planarcal run exited with status {status}: {server.log[-1:]}")
    for problem in problems:
        print(f"FAIL: {problem}")
    if parts:
        worst = max(error_mm(p, truth) for p in parts)
        print(f"{len(parts)} parts read, the worst {worst:.4f} mm from the truth.")
    print("FAIL" if problems else "PASS")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
