"""A rendered video of a work cell, for ``planarcal live --source`` without a camera.

:func:`write_live_video` films the cell of :mod:`planarcal.synth.cell` with a fixed 1280 x 720
camera (:data:`LIVE_CAMERA`: the cell camera's lens and focal length on a 16:9 sensor) over a
work area three boards wide. First the board lies at ``placements`` places (the cell's: the
middle, then the corners), held still at each for ``hold_s`` seconds, carried between them in
a few frames and then off the table; then parts (nuts, bolts and washers) ride across the
table on a conveyor, slowly, for ``parts_s`` seconds. A user captures a placement at each
still, calibrates, registers and watches the parts, as with a real camera.

Everything is known exactly: :class:`LiveVideo` records each still's frames and the board's
pose there (table and plane frame), and every part's position on every frame (table mm, the
plane frame a calibration reports in, the exact pixel), with the :class:`Cell` for the rest
(the camera, its pose, the mapping from table to pixels).

What it costs: each distinct image is rendered once (a held still once, the parts at
:data:`PARTS_STEPS_PER_S` positions a second, each held until the next) without noise; each
frame then gets its own sensor noise (cheap) and is written as Motion JPEG in an AVI
(OpenCV's built-in encoder, present in every build), at :data:`JPEG_QUALITY`. The whole
file is written atomically.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.calib.boards import Board
from planarcal.errors import ArgumentError, ImageError
from planarcal.files import atomic_write
from planarcal.synth.camera import CameraModel
from planarcal.synth.cell import CELL_CAMERA, PAPER_MARGIN_MM, Cell, cell_board, render_cell
from planarcal.synth.objects import ObjectKind, SceneObject
from planarcal.synth.paper import PAPER_EFFECTS
from planarcal.synth.render import render_scene

F64 = NDArray[np.float64]

LIVE_CAMERA = CameraModel(
    width=1280, height=720, focal_px=CELL_CAMERA.focal_px, k1=CELL_CAMERA.k1, k2=CELL_CAMERA.k2
)
"""The video's camera: :data:`~planarcal.synth.cell.CELL_CAMERA`'s focal length and lens at
1280 x 720 (a webcam's HD mode)."""

MOVE_S = 0.4
"""How long the board takes from one place to the next, and off the table (s)."""

PARTS_STEPS_PER_S = 2.5
"""How many distinct positions of the parts a second of video shows (each held until the next)."""

BELT_SPEED_MM_S = 20.0
"""The conveyor's speed (mm/s), along the table's +x."""

BELT_SPACING_MM = 110.0
"""The distance between parts along each lane of the conveyor (mm, about)."""

JPEG_QUALITY = 75
"""The Motion JPEG quality (OpenCV's scale, 0-100): the board's points come through it within
a few hundredths of a pixel."""

MAX_FRAMES = 1200
"""The longest video written (frames): two minutes at 10 frames a second (the file, some
200 kB a frame, is held in memory once to be written atomically)."""

# Each frame's sensor noise (grey levels), added to the noise-free render.
_NOISE_SIGMA = float(PAPER_EFFECTS["noise_sigma"])
_EFFECTS = {**PAPER_EFFECTS, "noise_sigma": 0.0}
_SUPERSAMPLE = 2
# The conveyor's two lanes (fractions of the work area's height) and what rides on them: the
# demo's parts (planarcal.synth.demo), in turn.
_LANES = (0.38, 0.62)
# Each kind's size and length (mm, SceneObject's), a little larger than the demo's.
_PARTS: Mapping[ObjectKind, tuple[float, float | None]] = {
    "nut": (13.0, None),
    "bolt": (8.0, 40.0),
    "washer": (16.0, None),
}
_KINDS: tuple[ObjectKind, ...] = tuple(_PARTS)
# A part's greatest extent from its centroid, or near it (mm).
_REACH_MM = max(length or size for size, length in _PARTS.values())


@dataclasses.dataclass(frozen=True, eq=False)
class HeldPlacement:
    """The board held still at one place: on ``frames`` (a range of frame indices), with the
    cell's placement ``index`` (its image, noise-free, and truth: ``Cell.placements``).

    ``name``: where ("middle", "top left", ...); ``centre_mm``, ``angle_deg``: the board's
    printed field's centre and its angle on the table; ``pose``: its pose in the plane frame
    as a calibration reports it, (angle_deg, (x, y) offset mm) (:meth:`Cell.true_pose`);
    ``points_px``: each board point's exact pixel (id order)."""

    index: int
    name: str
    frames: range
    centre_mm: tuple[float, float]
    angle_deg: float
    pose: tuple[float, tuple[float, float]]
    points_px: F64


@dataclasses.dataclass(frozen=True, eq=False)
class PartsTruth:
    """The parts on the conveyor, frame by frame from ``first_frame`` (before it: the board,
    no parts) to the video's end. The same ``count`` parts on every frame, in the same order:
    ``kinds`` and ``angles_deg`` (each part's axis on the table, from +x towards +y; a bolt's
    the only one visible). For frame ``first_frame + i``: ``table_mm[i]`` (count, 2), each
    part's centroid on the table; ``plane_mm[i]`` the same in the plane frame (the first
    placement's board frame, a calibration's); ``pixels_px[i]`` its exact pixel;
    ``in_view[i]`` whether it lies wholly inside the image; ``in_area[i]`` whether its
    centroid lies in the work area (where the placements calibrate). Parts out of view ride
    the conveyor's return, off the image."""

    first_frame: int
    kinds: tuple[ObjectKind, ...]
    angles_deg: F64
    table_mm: F64
    plane_mm: F64
    pixels_px: F64
    in_view: NDArray[np.bool_]
    in_area: NDArray[np.bool_]

    @property
    def count(self) -> int:
        return len(self.kinds)

    def row(self, frame: int) -> int:
        """The row of ``frame`` (a frame index of the video) in the per-frame arrays."""
        if isinstance(frame, bool) or not isinstance(frame, int | np.integer):
            raise ArgumentError(f"frame must be a frame index, got {frame!r}")
        i = int(frame) - self.first_frame
        if not 0 <= i < len(self.table_mm):
            raise ArgumentError(
                f"frame {frame} shows no parts (they are on frames {self.first_frame} to "
                f"{self.first_frame + len(self.table_mm) - 1})"
            )
        return i


@dataclasses.dataclass(frozen=True, eq=False)
class LiveVideo:
    """A video written by :func:`write_live_video` and its truth (see the module).

    ``path``; ``fps``; ``frame_count``; ``board``; ``placements``: where the board is held
    still, in order (:class:`HeldPlacement`); ``parts``: the conveyor's parts per frame
    (:class:`PartsTruth`); ``cell``: the camera (:data:`LIVE_CAMERA`), its pose over the
    table, the work area and each placement's noise-free image, with the table and plane
    frames' truth (:meth:`Cell.pixel_of`, :meth:`Cell.truth_plane_mm`); ``noise_sigma``:
    each frame's sensor noise (grey levels, fresh on every frame); ``seed``."""

    path: Path
    fps: float
    frame_count: int
    board: Board
    placements: tuple[HeldPlacement, ...]
    parts: PartsTruth
    cell: Cell
    noise_sigma: float
    seed: int

    @property
    def size(self) -> tuple[int, int]:
        """The frames' (width, height) in pixels."""
        return (self.cell.camera.width, self.cell.camera.height)

    @property
    def duration_s(self) -> float:
        return self.frame_count / self.fps


def write_live_video(
    path: str | os.PathLike[str],
    *,
    board: Board | str = "circles",
    placements: int = 3,
    fps: float = 10.0,
    hold_s: float = 2.0,
    parts_s: float = 6.0,
    seed: int = 0,
) -> LiveVideo:
    """Write the work cell's video to ``path`` (an ``.avi``: Motion JPEG, 1280 x 720 BGR,
    ``fps`` frames a second) and return it with its truth (:class:`LiveVideo`).

    ``board``: a board or a cell board type's name ("circles", "chessboard", "charuco":
    :data:`~planarcal.synth.cell.CELL_BOARDS`); ``placements``: how many places it is held
    at (1 to 9, :func:`~planarcal.synth.cell.render_cell`'s), each for ``hold_s`` seconds,
    with :data:`MOVE_S` seconds between them; then the parts for ``parts_s`` seconds.
    ``seed`` draws the placements' jitter, the parts and the noise.

    Raises ArgumentError for bad arguments (a name not ending in .avi, a count, a duration
    out of range), OSError where the file cannot be written.
    """
    target = Path(os.fspath(path))
    if target.suffix.lower() != ".avi":
        raise ArgumentError(f"path must name an .avi file (Motion JPEG in AVI), got {str(path)!r}")
    shown = cell_board(board)
    if isinstance(placements, bool) or not isinstance(placements, int | np.integer):
        raise ArgumentError(f"placements must be a whole number, got {placements!r}")
    rate = arguments.positive("fps", fps)
    if not 1.0 <= rate <= 120.0:
        raise ArgumentError(f"fps must be 1 to 120, got {fps!r}")
    hold = _frames("hold_s", hold_s, rate)
    parts_frames = _frames("parts_s", parts_s, rate)
    move = max(3, round(MOVE_S * rate))
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ArgumentError(f"seed must be a non-negative whole number, got {seed!r}")
    total = int(placements) * hold + int(placements) * move + parts_frames
    if total > MAX_FRAMES:
        raise ArgumentError(f"the video would have {total:,} frames, more than {MAX_FRAMES:,}")

    cell = render_cell(
        shown,
        int(placements),
        camera=LIVE_CAMERA,
        seed=int(seed),
        effects=_EFFECTS,
        supersample=_SUPERSAMPLE,
    )
    rng = np.random.default_rng([int(seed), 24])
    period = hold + move  # a placement's frames: held, then carried to the next place
    held = tuple(
        HeldPlacement(
            index=k,
            name=p.name,
            frames=range(k * period, k * period + hold),
            centre_mm=p.centre_mm,
            angle_deg=p.angle_deg,
            pose=cell.true_pose(k),
            points_px=np.array(p.scene.points_px, np.float64),
        )
        for k, p in enumerate(cell.placements)
    )
    parts = _conveyor(cell, len(held) * period, parts_frames, rate, rng)
    # Rendered as they are written: one distinct image in memory at a time.
    images = itertools.chain(
        _board_images(cell, hold, move, rng), _parts_images(cell, parts, rate, rng)
    )
    _write(target, images, rate, rng)
    return LiveVideo(
        path=target,
        fps=rate,
        frame_count=total,
        board=shown,
        placements=held,
        parts=parts,
        cell=cell,
        noise_sigma=_NOISE_SIGMA,
        seed=int(seed),
    )


def _frames(name: str, seconds: float, fps: float) -> int:
    """A duration as a whole number of frames, at least one."""
    value = arguments.positive(name, seconds)
    if value > MAX_FRAMES:
        raise ArgumentError(f"{name} must be at most {MAX_FRAMES} s, got {seconds!r}")
    return max(1, round(value * fps))


def _board_images(
    cell: Cell, hold: int, move: int, rng: np.random.Generator
) -> Iterator[tuple[NDArray[np.uint8], int]]:
    """The board's images and how many frames show each: each placement's still, held, then
    the board carried to the next place (after the last, off the table)."""
    for k, p in enumerate(cell.placements):
        yield p.image, hold
        goal = _off_the_table(cell, k) if k + 1 == len(cell.placements) else None
        for image in _moving_board(cell, k, goal, move, rng):
            yield image, 1


def _render(cell: Cell, rng: np.random.Generator, **scene: object) -> NDArray[np.uint8]:
    """The cell's camera's noise-free image of a scene on its table."""
    rendered = render_scene(
        cell.camera,
        cell.pose,
        paper_margin_mm=PAPER_MARGIN_MM,
        seed=int(rng.integers(0, 2**31)),
        supersample=_SUPERSAMPLE,
        **_EFFECTS,  # type: ignore[arg-type]
        **scene,  # type: ignore[arg-type]
    )
    return rendered.image


def _moving_board(
    cell: Cell,
    k: int,
    goal: tuple[float, float, float] | None,
    count: int,
    rng: np.random.Generator,
) -> Iterator[NDArray[np.uint8]]:
    """The ``count`` images of the board carried from placement k to the next (or to
    ``goal``: the field's centre and angle), easing in and out."""
    start = cell.placements[k]
    if goal is None:
        nxt = cell.placements[k + 1]
        goal = (nxt.centre_mm[0], nxt.centre_mm[1], nxt.angle_deg)
    x0, y0, a0 = start.centre_mm[0], start.centre_mm[1], start.angle_deg
    x1, y1, a1 = goal
    fx0, fy0, fx1, fy1 = cell.board.ink().field
    field_centre = np.array([(fx0 + fx1) / 2.0, (fy0 + fy1) / 2.0])
    for j in range(1, count + 1):
        s = j / (count + 1)
        s = s * s * (3.0 - 2.0 * s)  # smoothstep: set down and picked up gently
        angle = a0 + s * (a1 - a0)
        centre = np.array([x0 + s * (x1 - x0), y0 + s * (y1 - y0)])
        a = math.radians(angle)
        turn = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        origin = centre - turn @ field_centre
        yield _render(
            cell,
            rng,
            board=cell.board,
            board_origin_mm=(float(origin[0]), float(origin[1])),
            board_angle_deg=angle,
        )


def _off_the_table(cell: Cell, k: int) -> tuple[float, float, float]:
    """Where the board is carried after placement k, the last: away from the work area's
    centre (up the image from the middle), to where its paper lies wholly beyond one edge of
    the image."""
    p = cell.placements[k]
    w, h = cell.area_mm
    away = np.array(p.centre_mm) - np.array([w / 2.0, h / 2.0])
    norm = float(np.hypot(*away))
    direction = away / norm if norm > 1.0 else np.array([0.0, -1.0])
    half_w, half_h = 0.5 * np.array(cell.board_size_mm)
    corners = np.array([[-half_w, -half_h], [half_w, -half_h], [half_w, half_h], [-half_w, half_h]])
    a = math.radians(p.angle_deg)
    paper = corners @ np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
    size = np.array([cell.camera.width, cell.camera.height], np.float64)
    reach = 0.0
    while reach < 10.0 * (w + h):
        centre = np.array(p.centre_mm) + reach * direction
        px = cell.pixel_of(paper + centre)
        if ((px < 0.0).all(axis=0) | (px > size - 1.0).all(axis=0)).any():
            break
        reach += 10.0
    centre = np.array(p.centre_mm) + 1.2 * reach * direction  # the last frame clear of it too
    return (float(centre[0]), float(centre[1]), p.angle_deg)


def _belt(cell: Cell) -> tuple[float, float]:
    """The conveyor's run along x (table mm): from out of sight on the left to out of sight
    on the right of the image, over both lanes."""
    w, h = cell.area_mm
    xs = np.linspace(-2.0 * w, 3.0 * w, 1001)
    seen = []
    for lane in _LANES:
        px = cell.pixel_of(np.column_stack([xs, np.full_like(xs, lane * h)]))
        inside = (
            (px[:, 0] >= 0) & (px[:, 0] <= cell.camera.width - 1)
            & (px[:, 1] >= 0) & (px[:, 1] <= cell.camera.height - 1)
        )  # fmt: skip
        seen.append(xs[inside])
    visible = np.concatenate(seen)
    return float(visible.min() - 2.0 * _REACH_MM), float(visible.max() + 2.0 * _REACH_MM)


def _conveyor(
    cell: Cell, first: int, frames: int, fps: float, rng: np.random.Generator
) -> PartsTruth:
    """The parts riding the conveyor on ``frames`` frames from ``first``: two lanes of parts
    ``BELT_SPACING_MM`` apart (staggered, each a little off its lane's line and at its own
    angle), moving along +x at ``BELT_SPEED_MM_S``, each position held for the frames of one
    step (``PARTS_STEPS_PER_S``) and wrapping round off the image."""
    lo, hi = _belt(cell)
    run = hi - lo
    per_lane = max(1, round(run / BELT_SPACING_MM))
    gap = run / per_lane
    w, h = cell.area_mm
    starts, ys, kinds, angles = [], [], [], []
    for j, lane in enumerate(_LANES):
        for i in range(per_lane):
            starts.append(i * gap + (j * 0.5 + float(rng.uniform(-0.1, 0.1))) * gap)
            ys.append(lane * h + float(rng.uniform(-0.03, 0.03)) * h)
            kinds.append(_KINDS[(i + j) % len(_KINDS)])
            angles.append(float(rng.uniform(-90.0, 90.0)))
    hold = max(1, round(fps / PARTS_STEPS_PER_S))
    # Each frame shows the position of its step's first frame.
    times = np.array([(f - f % hold) / fps for f in range(frames)])
    x = lo + np.mod(np.array(starts)[None, :] + BELT_SPEED_MM_S * times[:, None], run)
    table = np.stack([x, np.broadcast_to(np.array(ys), x.shape)], axis=-1)
    flat = table.reshape(-1, 2)
    pixels = cell.pixel_of(flat).reshape(table.shape)
    margin = _REACH_MM / 2.0 + 4.0  # mm: the part's half-length and its bolt head
    edges = [
        cell.pixel_of(flat + np.array(offset)).reshape(table.shape)
        for offset in ((-margin, 0.0), (margin, 0.0), (0.0, -margin), (0.0, margin))
    ]
    in_view = np.ones(x.shape, dtype=bool)
    for e in edges:
        in_view &= (e[..., 0] >= 0) & (e[..., 0] <= cell.camera.width - 1)
        in_view &= (e[..., 1] >= 0) & (e[..., 1] <= cell.camera.height - 1)
    in_area = (x >= 0.0) & (x <= w) & (table[..., 1] >= 0.0) & (table[..., 1] <= h)
    return PartsTruth(
        first_frame=first,
        kinds=tuple(kinds),
        angles_deg=np.array(angles, np.float64),
        table_mm=np.ascontiguousarray(table, dtype=np.float64),
        plane_mm=cell.truth_plane_mm(table),
        pixels_px=pixels,
        in_view=in_view,
        in_area=in_area,
    )


def _parts_images(
    cell: Cell, parts: PartsTruth, fps: float, rng: np.random.Generator
) -> Iterator[tuple[NDArray[np.uint8], int]]:
    """Each distinct image of the parts (one per step) and how many frames show it."""
    hold = max(1, round(fps / PARTS_STEPS_PER_S))
    frames = len(parts.table_mm)
    for start in range(0, frames, hold):
        objects = [
            SceneObject(
                kind,
                (float(x), float(y)),
                angle_deg=float(a),
                size_mm=_PARTS[kind][0],
                length_mm=_PARTS[kind][1],
            )
            for kind, (x, y), a in zip(
                parts.kinds, parts.table_mm[start], parts.angles_deg, strict=True
            )
        ]
        yield _render(cell, rng, board=None, objects=objects), min(hold, frames - start)


def _write(
    target: Path,
    pieces: Iterable[tuple[NDArray[np.uint8], int]],
    fps: float,
    rng: np.random.Generator,
) -> None:
    """Encode the frames (each piece's image shown its count of frames, each frame with its
    own noise) as Motion JPEG in an AVI, then put the file at ``target`` atomically."""
    size = (LIVE_CAMERA.width, LIVE_CAMERA.height)
    with tempfile.TemporaryDirectory(prefix="planarcal-video-") as folder:
        scratch = os.path.join(folder, "video.avi")
        # OpenCV's own Motion JPEG writer: in every build, with or without FFmpeg.
        writer = cv2.VideoWriter(
            scratch, cv2.CAP_OPENCV_MJPEG, cv2.VideoWriter.fourcc(*"MJPG"), fps, size, True
        )
        try:
            if not writer.isOpened():
                raise ImageError("OpenCV cannot write Motion JPEG video (its MJPEG writer is off)")
            writer.set(cv2.VIDEOWRITER_PROP_QUALITY, JPEG_QUALITY)
            for image, count in pieces:
                base = image.astype(np.float32) + 0.5
                for _ in range(count):
                    noise = rng.standard_normal(image.shape, dtype=np.float32)
                    noisy = np.clip(base + _NOISE_SIGMA * noise, 0.0, 255.0).astype(np.uint8)
                    writer.write(cv2.cvtColor(noisy, cv2.COLOR_GRAY2BGR))
        finally:
            writer.release()
        data = Path(scratch).read_bytes()
    atomic_write(target, data)
