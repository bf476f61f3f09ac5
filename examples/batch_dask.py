"""Locate the parts in many images at once on a Dask cluster (dask.distributed).

What it shows: the batch work of a user who has outgrown one machine. One calibration is sent
once to every worker (``Client.scatter(..., broadcast=True)``: it pickles), then one task per
image (``Client.map``) reads the image and locates its parts (``planarcal.locate_objects``),
and the results are gathered into a CSV with one row per part: image, part id, x and y (mm),
1-sigma (mm), angle (degrees, empty for a round part). An image planarcal cannot read is
reported and the others carry on.

By default it renders its own images with exact truth (planarcal.synth: the paper's camera,
3 to 6 nuts, bolts and washers at random places in each), calibrates from a rendered board,
starts a local cluster of ``--workers`` worker processes and checks every position against
the truth. The same code runs on a real cluster: give its scheduler's address, your images
and your calibration file (the workers need planarcal installed, and the image paths must be
readable by every worker, e.g. on a shared file system).

``--scaling 1,2,3,4`` measures the throughput instead: the same images located with a local
cluster of 1, 2, 3 and 4 workers in turn (and once in this process, without Dask), printed as
a table and drawn with ``--figure``.

Run it from the repository root (about 15 s; ``pip install "distributed>=2024.8"``)::

    python examples/batch_dask.py                       # 16 images, 2 workers
    python examples/batch_dask.py --count 64 --workers 4 --csv parts.csv
    python examples/batch_dask.py --images 'photos/*.png' --calibration calib.json \\
        --scheduler tcp://10.0.0.5:8786 --csv parts.csv
    python examples/batch_dask.py --count 48 --scaling 1,2,3,4 \\
        --figure docs/images/dask-scaling.png

It exits with status 1 when an image fails, or (on its own images) a part is missed or lies
further than ``--tolerance-mm`` from the truth.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import glob
import math
import os
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import NamedTuple

import cv2
import numpy as np
from distributed import Client, LocalCluster

import planarcal
from planarcal import synth

CSV_COLUMNS = ("image", "part", "x_mm", "y_mm", "std_mm", "angle_deg")


class ImageResult(NamedTuple):
    """One image's parts (rows of CSV_COLUMNS), or why it could not be read."""

    image: str
    rows: list[tuple[str, int, float, float, float, float | None]]
    error: str | None


def locate_file(path: str, calibration: planarcal.Calibration) -> ImageResult:
    """One image's parts, located through ``calibration``."""
    try:
        parts = planarcal.locate_objects(planarcal.load_image(path), calibration)
    except planarcal.Error as error:  # a bad image fails alone, not the batch
        return ImageResult(path, [], f"{type(error).__name__}: {error}")
    rows = []
    for part in parts:
        # Set by locate_objects; DetectedObject's type also covers detect_objects' results.
        assert part.world_mm is not None and part.world_std_mm is not None
        x, y = part.world_mm
        rows.append((path, part.id, x, y, part.world_std_mm, part.angle_deg))
    return ImageResult(path, rows, None)


def locate_files(paths: Sequence[str], calibration: planarcal.Calibration) -> list[ImageResult]:
    """The task each worker runs: a few images' parts."""
    return [locate_file(path, calibration) for path in paths]


@contextlib.contextmanager
def dask_client(scheduler: str | None, workers: int) -> Iterator[Client]:
    """A client of the scheduler at ``scheduler``, or of a local cluster of ``workers``
    single-threaded worker processes, closed on leaving."""
    # distributed leaves Client's and LocalCluster's constructors and some of their methods
    # unannotated: mypy --strict is told, call by call, that they are untyped.
    if scheduler is not None:
        with Client(scheduler) as client:  # type: ignore[no-untyped-call]
            yield client
        return
    # Processes, one thread each: the Python between OpenCV's and planarcal's calls holds
    # the GIL, so threads of one process would mostly wait for each other.
    with (
        LocalCluster(  # type: ignore[no-untyped-call]
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        Client(cluster) as client,  # type: ignore[no-untyped-call]
    ):
        yield client


def locate_all(
    client: Client,
    paths: Sequence[str],
    calibration: planarcal.Calibration,
    chunk: int,
    workers: list[str] | None = None,
) -> list[ImageResult]:
    """Every image's parts, in the order of ``paths``: one task per ``chunk`` images (on
    ``workers`` only, when given: their addresses)."""
    # Sent once to each worker rather than once with each task. hash=False: a new key each
    # batch, so that releasing an earlier batch's copy cannot cancel this one's tasks.
    shared = client.scatter(  # type: ignore[no-untyped-call]
        calibration, broadcast=True, hash=False
    )
    # A few images per task: one image takes 10-20 ms, and each task costs the scheduler a
    # round trip to a worker. pure=False: a batch asked for again is run again (--scaling).
    chunks = [paths[k : k + chunk] for k in range(0, len(paths), chunk)]
    futures = client.map(locate_files, chunks, calibration=shared, pure=False, workers=workers)
    results: list[list[ImageResult]] = client.gather(futures)  # type: ignore[no-untyped-call]
    return [result for chunk_results in results for result in chunk_results]


def write_csv(path: Path, results: Sequence[ImageResult]) -> int:
    """Writes the parts, one row each; returns how many."""
    rows = [row for result in results for row in result.rows]
    with path.open("w", newline="") as out:
        writer = csv.writer(out)
        writer.writerow(CSV_COLUMNS)
        for image, part, x, y, std, angle in rows:
            writer.writerow(
                [
                    image,
                    part,
                    f"{x:.4f}",
                    f"{y:.4f}",
                    f"{std:.5f}",
                    "" if angle is None else f"{angle:.2f}",
                ]
            )
    return len(rows)


# --- The images of the demo, with their truth ----------------------------------------------

PART_SHAPES: tuple[tuple[synth.ObjectKind, float, float | None], ...] = (
    ("nut", 8.0, None),
    ("bolt", 6.0, 30.0),
    ("washer", 8.0, None),
)
MIN_GAP_MM = 45.0  # between two parts' centroids, so that none touch


def random_parts(rng: np.random.Generator) -> list[synth.SceneObject]:
    """3 to 6 parts at random places on the calibrated board's area (board mm)."""
    wanted = int(rng.integers(3, 7))
    places: list[np.ndarray] = []
    while len(places) < wanted:
        place = rng.uniform((30.0, 25.0), (230.0, 155.0))
        if all(math.dist(place, other) > MIN_GAP_MM for other in places):
            places.append(place)
    parts = []
    for place in places:
        kind, size, length = PART_SHAPES[int(rng.integers(len(PART_SHAPES)))]
        parts.append(
            synth.SceneObject(
                kind,
                (float(place[0]), float(place[1])),
                angle_deg=float(rng.uniform(-90.0, 90.0)),
                size_mm=size,
                length_mm=length,
            )
        )
    return parts


def render_images(
    folder: Path, count: int, seed: int
) -> tuple[planarcal.Calibration, list[str], dict[str, np.ndarray]]:
    """(the calibration, the image paths, each image's true part positions in board mm):
    the paper's camera calibrated from its board, then ``count`` images of random parts,
    written as PNG to ``folder`` with the calibration (calib.json) and the truth
    (truth.csv: image, x_mm, y_mm)."""
    board_view = synth.paper_scene(seed=seed, objects=False).calibration
    calibration = planarcal.Calibration.from_image(board_view.image, synth.PAPER_BOARD)
    calibration.save(folder / "calib.json")
    rng = np.random.default_rng(seed)
    paths, truth = [], {}
    for k in range(count):
        scene = synth.render_paper_look(
            synth.PAPER_CAMERA, synth.PAPER_POSE, None, random_parts(rng), seed + k
        )
        path = str(folder / f"parts-{k:04d}.png")
        cv2.imwrite(path, scene.image)
        paths.append(path)
        truth[path] = scene.object_centroids_mm
    with (folder / "truth.csv").open("w", newline="") as out:
        writer = csv.writer(out)
        writer.writerow(("image", "x_mm", "y_mm"))
        writer.writerows((path, x, y) for path, points in truth.items() for x, y in points)
    return calibration, paths, truth


def check(
    results: Sequence[ImageResult], truth: dict[str, np.ndarray], tolerance_mm: float
) -> list[str]:
    """What is wrong with the results, against each image's truth."""
    problems = []
    worst = 0.0
    for result in results:
        placed = truth[result.image]
        found = np.array([(row[2], row[3]) for row in result.rows]).reshape(-1, 2)
        if len(found) != len(placed):
            problems.append(f"{result.image}: {len(found)} parts found, {len(placed)} placed")
            continue
        gaps = np.linalg.norm(found[:, None] - placed[None], axis=2)
        if sorted(gaps.argmin(axis=1)) != list(range(len(placed))):
            problems.append(f"{result.image}: the parts found are not the parts placed")
        elif gaps.min(axis=1).max() > tolerance_mm:
            problems.append(f"{result.image}: a part {gaps.min(axis=1).max():.3f} mm off")
        worst = max(worst, float(gaps.min(axis=1).max(initial=0.0)))
    print(f"Against the truth: the worst part {worst:.4f} mm off.")
    return problems


# --- --scaling: throughput against the number of workers ------------------------------------


class Throughput(NamedTuple):
    workers: int  # 0: in this process, without Dask
    images_per_s: float


def measure(
    paths: Sequence[str],
    calibration: planarcal.Calibration,
    worker_counts: Sequence[int],
    repeats: int,
    chunk: int,
) -> list[Throughput]:
    """The best of ``repeats`` rounds for each worker count (and for this process alone, as
    0). A round times the batch over ``paths`` in this process, then on the first k workers
    of one local cluster for each k in turn: the machine's other load, which comes and goes,
    then falls on every count alike."""
    best = dict.fromkeys([0, *worker_counts], math.inf)
    with dask_client(None, max(worker_counts)) as client:
        addresses = sorted(client.scheduler_info()["workers"])
        client.run(locate_file, paths[0], calibration)  # every worker's imports, before timing
        for _ in range(repeats):
            for count in best:
                start = time.perf_counter()
                if count == 0:
                    for path in paths:
                        locate_file(path, calibration)
                else:
                    locate_all(client, paths, calibration, chunk, workers=addresses[:count])
                best[count] = min(best[count], time.perf_counter() - start)
    return [Throughput(count, len(paths) / seconds) for count, seconds in best.items()]


def scaling_table(rates: Sequence[Throughput]) -> str:
    """The measurements as a Markdown table."""
    alone = rates[0].images_per_s
    one = next(r.images_per_s for r in rates if r.workers == 1)
    lines = [
        "| workers | images / s | ms / image | speed-up over 1 worker | over no Dask |",
        "|---:|---:|---:|---:|---:|",
        f"| none (one process) | {alone:.1f} | {1e3 / alone:.1f} | | |",
    ]
    lines += [
        f"| {r.workers} | {r.images_per_s:.1f} | {1e3 / r.images_per_s:.1f} | "
        f"{r.images_per_s / one:.2f} | {r.images_per_s / alone:.2f} |"
        for r in rates[1:]
    ]
    return "\n".join(lines)


def draw_scaling(rates: Sequence[Throughput], setting: str, path: Path) -> None:
    """Throughput against workers, beside perfect scaling and this machine's cores."""
    import matplotlib  # noqa: PLC0415 (only --figure needs it)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    clustered = [r for r in rates if r.workers > 0]
    workers = [r.workers for r in clustered]
    one = next(r.images_per_s for r in clustered if r.workers == 1)
    cores = os.cpu_count() or 1
    figure, axes = plt.subplots(figsize=(6.4, 4.0), dpi=150, layout="constrained")
    axes.plot(workers, [w * one for w in workers], "--", color="grey", label="perfect scaling")
    axes.plot(workers, [r.images_per_s for r in clustered], "o-", label="dask.distributed")
    axes.axhline(
        rates[0].images_per_s, color="tab:green", linestyle=":", label="one process, no Dask"
    )
    axes.axvline(cores, color="tab:red", linewidth=0.8, label=f"this machine's {cores} cores")
    axes.set_xticks(workers)
    axes.set_xlabel("worker processes (1 thread each)")
    axes.set_ylabel("images located per second")
    axes.set_ylim(bottom=0)
    title = f"Locating parts with dask.distributed (LocalCluster)\n{setting}"
    axes.set_title(title.replace("; ", "\n"), fontsize=9)
    axes.legend(loc="upper left", fontsize="small")
    figure.savefig(path)
    plt.close(figure)


# --- The command line ---------------------------------------------------------------------


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=16, help="images to render (default 16)")
    parser.add_argument("--workers", type=int, default=2, help="local workers (default 2)")
    parser.add_argument("--chunk", type=int, default=4, help="images per task (default 4)")
    parser.add_argument("--scheduler", help="a running scheduler's address, tcp://HOST:PORT")
    parser.add_argument("--images", help="your images (a glob pattern) instead of rendered ones")
    parser.add_argument("--calibration", type=Path, help="with --images: the calibration file")
    parser.add_argument(
        "--csv", type=Path, default=Path("parts.csv"), help="the parts (default parts.csv)"
    )
    parser.add_argument("--workdir", type=Path, help="keep the rendered images and truth here")
    parser.add_argument("--seed", type=int, default=0, help="the rendered images")
    parser.add_argument(
        "--tolerance-mm", type=float, default=0.15, help="the check (default 0.15 mm)"
    )
    parser.add_argument("--scaling", help="measure throughput with these worker counts: 1,2,4")
    parser.add_argument("--repeats", type=int, default=3, help="--scaling: batches per count")
    parser.add_argument("--figure", type=Path, help="--scaling: draw the figure here (PNG)")
    args = parser.parse_args(argv)
    if (args.images is None) != (args.calibration is None):
        parser.error("--images and --calibration go together")
    return args


def run(args: argparse.Namespace, folder: Path) -> int:
    if args.images is not None:
        paths = sorted(glob.glob(args.images))
        calibration = planarcal.Calibration.load(args.calibration)
        truth = None
    else:
        start = time.perf_counter()
        calibration, paths, truth = render_images(folder, args.count, args.seed)
        print(f"Rendered {len(paths)} images into {folder} in {time.perf_counter() - start:.1f} s.")
    if args.scaling is not None:
        counts = [int(n) for n in args.scaling.split(",")]
        load = os.getloadavg()[0]
        rates = measure(paths, calibration, counts, args.repeats, args.chunk)
        # The machine's other work changes every figure: say how busy it was.
        setting = (
            f"{len(paths)} images of 1280 x 720, {args.chunk} per task, best of {args.repeats} "
            f"rounds; {os.cpu_count()} cores, load average {load:.1f} to "
            f"{os.getloadavg()[0]:.1f}"
        )
        print(setting)
        print(scaling_table(rates))
        if args.figure is not None:
            draw_scaling(rates, setting, args.figure)
            print(f"Wrote {args.figure}")
        return 0

    with dask_client(args.scheduler, args.workers) as client:
        start = time.perf_counter()
        results = locate_all(client, paths, calibration, args.chunk)
        seconds = time.perf_counter() - start
        where = args.scheduler or f"a local cluster of {args.workers} workers"
    rows = write_csv(args.csv, results)
    print(f"Located {rows} parts in {len(paths)} images on {where} in {seconds:.2f} s: {args.csv}")
    problems = [f"{r.image}: {r.error}" for r in results if r.error is not None]
    if truth is not None:
        problems += check(results, truth, args.tolerance_mm)
    for problem in problems:
        print(f"FAIL: {problem}")
    print("FAIL" if problems else "PASS")
    return 1 if problems else 0


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.workdir is not None:
        args.workdir.mkdir(parents=True, exist_ok=True)
        return run(args, args.workdir)
    with tempfile.TemporaryDirectory(prefix="planarcal-batch-") as folder:
        return run(args, Path(folder))


if __name__ == "__main__":
    sys.exit(main())
