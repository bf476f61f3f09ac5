"""Random views of the paper's board and of parts through a webcam's lens as it really is:
the distortion centre (the principal point) off the image centre, k1 and k2, and the
tangential terms of a slightly decentred lens element. For measuring whether the error bars
a calibration reports cover the errors it makes (benches/bench_accuracy.py, tests).

:func:`random_webcam_scene` renders a pair like :func:`planarcal.synth.paper_scene`: the
board alone (to calibrate on) and, from the same camera and pose, the board removed and
parts in its place (nuts, washers, discs and bolts at known positions over the board's
area), with the paper scene's effects (blur, noise, uneven lighting).
"""

from __future__ import annotations

import math

import numpy as np

from planarcal.calib.boards import Board
from planarcal.errors import ArgumentError, ImageError
from planarcal.synth.camera import CameraModel
from planarcal.synth.objects import SceneObject
from planarcal.synth.paper import (
    PAPER_BOARD,
    PaperScene,
    paper_board,
    random_board_pose,
    render_paper_look,
)

WEBCAM_FOCAL_PX_PER_WIDTH = 1070.0 / 1280.0
"""A Logitech C525's focal length per pixel of image width (about 69 degrees diagonal)."""

MAX_TANGENTIAL = 1e-3
"""The largest |p1|, |p2| drawn: a webcam's decentring."""


def webcam_camera(
    rng: np.random.Generator,
    size: tuple[int, int] = (1280, 720),
    centre_offset_px: float | None = None,
    max_centre_offset_px: float = 40.0,
) -> CameraModel:
    """A random webcam of ``size`` (width, height): the principal point (the distortion's
    centre) ``centre_offset_px`` from the image centre in a random direction (None: a random
    0 to ``max_centre_offset_px``), barrel k1 in [-0.2, -0.05], k2 in [0, 0.05], p1 and p2
    in [-MAX_TANGENTIAL, MAX_TANGENTIAL]."""
    width, height = size
    offset = (
        float(rng.uniform(0.0, max_centre_offset_px))
        if centre_offset_px is None
        else float(centre_offset_px)
    )
    if not (math.isfinite(offset) and offset >= 0.0):
        raise ArgumentError(f"centre_offset_px must be a finite number >= 0, got {offset!r}")
    angle = float(rng.uniform(0.0, 2.0 * math.pi))
    return CameraModel(
        width=width,
        height=height,
        focal_px=WEBCAM_FOCAL_PX_PER_WIDTH * width,
        principal=(
            (width - 1) / 2.0 + offset * math.cos(angle),
            (height - 1) / 2.0 + offset * math.sin(angle),
        ),
        k1=float(rng.uniform(-0.2, -0.05)),
        k2=float(rng.uniform(0.0, 0.05)),
        p1=float(rng.uniform(-MAX_TANGENTIAL, MAX_TANGENTIAL)),
        p2=float(rng.uniform(-MAX_TANGENTIAL, MAX_TANGENTIAL)),
    )


def scattered_parts(rng: np.random.Generator, n: int = 12) -> tuple[SceneObject, ...]:
    """``n`` parts (M6-M10 nuts, washers, 8-16 mm discs, M5-M6 bolts 20-30 mm long) at
    random positions and angles over the paper board's area, their outlines at least 6 mm
    apart (their bounding circles' gap)."""
    board = PAPER_BOARD
    span = np.array([(board.cols - 1) * board.pitch, (board.rows - 1) * board.pitch])
    kinds = ("nut", "washer", "disc", "bolt")
    placed: list[tuple[np.ndarray, float]] = []
    parts: list[SceneObject] = []
    for _ in range(200 * n):
        if len(parts) == n:
            break
        kind = kinds[len(parts) % len(kinds)]
        if kind == "nut":
            size, length = float(rng.choice([6.0, 8.0, 10.0])), None
            reach = 1.6 * size / math.sqrt(3.0)
        elif kind == "washer":
            size, length = float(rng.choice([5.0, 6.0, 8.0])), None
            reach = size
        elif kind == "disc":
            size, length = float(rng.uniform(8.0, 16.0)), None
            reach = size / 2.0
        else:
            size, length = float(rng.choice([5.0, 6.0])), float(rng.uniform(20.0, 30.0))
            reach = length / 2.0 + 1.6 * size
        centre = rng.uniform([reach, reach], span - reach)
        if any(np.hypot(*(centre - c)) < reach + r + 6.0 for c, r in placed):
            continue
        placed.append((centre, reach))
        parts.append(
            SceneObject(
                kind,  # type: ignore[arg-type]
                (float(centre[0]), float(centre[1])),
                angle_deg=float(rng.uniform(0.0, 360.0)),
                size_mm=size,
                length_mm=length,
            )
        )
    return tuple(parts)


def random_webcam_scene(
    seed: int,
    *,
    size: tuple[int, int] = (1280, 720),
    centre_offset_px: float | None = None,
    max_centre_offset_px: float = 40.0,
    parts: int = 12,
    max_tilt_deg: float = 5.0,
    board: Board | str = "circles",
) -> PaperScene:
    """A random view of the paper's board, and of ``parts`` parts in its place, through a
    random webcam lens (:func:`webcam_camera`; the distortion centre ``centre_offset_px``
    off the image centre, or a random 0 to ``max_centre_offset_px``): returns (calibration,
    objects) like :func:`planarcal.synth.paper_scene`. The board fills the view as in
    :func:`planarcal.synth.random_paper_scene` (1.9 px/mm at 1280 px wide, in proportion at
    other widths), tilted up to ``max_tilt_deg`` about a random axis, rolled up to 3
    degrees, with the paper scene's effects. The same arguments always give the same pair.
    ``board``: another board in the paper board's place (as
    :func:`planarcal.synth.paper_scene`'s); the parts lie over the paper board's area."""
    shown = paper_board(board)
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ImageError(f"seed must be a non-negative whole number, got {seed!r}")
    rng = np.random.default_rng(int(seed))
    camera = webcam_camera(rng, size, centre_offset_px, max_centre_offset_px)
    scale = 1.9 * camera.width / 1280.0
    pose = random_board_pose(rng, float(camera.focal_px) / scale, max_tilt_deg, shown)
    things = scattered_parts(rng, parts)
    seeds = rng.integers(0, 2**31, 2)
    calibration = render_paper_look(camera, pose, shown, (), int(seeds[0]))
    objects = render_paper_look(camera, pose, None, things, int(seeds[1]))
    return PaperScene(calibration, objects)
