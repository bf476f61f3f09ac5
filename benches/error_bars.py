"""Whether the error bars a calibration reports cover the errors it makes, against rendered
truth: the measurements behind bench_accuracy.py's error-bar section, reusable (the robot
frame's measurement takes the same parts and a mapping of its own).

The figure of merit is the ratio of the RMS actual error to the RMS predicted 1-sigma (both
as RMS distances, mm: std_mm is the square root of the covariance's trace): 1 when the bars
are honest, above 1 when they flatter, below when they are too cautious.

* Board points: random points over the board's area, projected exactly (the renderer's own
  camera) and mapped back through the calibration, as exact pixels (``pixel_sigma=0``).
* Parts: the parts of a rendered scene located by ``locate_objects`` (their centroids from
  the sub-pixel outlines), each matched to the nearest true centroid.
* Parts in the robot frame: the same parts located with ``frame="robot"`` through a
  registration fitted to six touched dots (a random mirrored, turned and offset robot,
  touches with ROBOT_TOUCH_NOISE_MM of noise per axis; ROBOTS_PER_SCENE of them), against
  the truth mapped into the robot's frame.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.live.objects import locate_objects
from planarcal.synth.webcam import random_webcam_scene, scattered_parts

F64 = NDArray[np.float64]

Mapping = Callable[[F64], tuple[F64, F64]]
"""Pixels (N, 2) -> (positions (N, 2), 1-sigma (N,)), in the frame the truth is in."""

# A located part farther than this from every true centroid is not one of them (mm).
MATCH_MM = 3.0

# A robot's repeatability (mm, 1-sigma per axis), and the dots it touches to register:
# the corners and two inside of a cols x rows board, as (col, row).
ROBOT_TOUCH_NOISE_MM = 0.05

# Registrations per scene: each is one draw of the touch noise, whose own error a single draw
# would leave to chance (six touches fix the noise's size to about 25 %).
ROBOTS_PER_SCENE = 8


def _touched_dots(cols: int, rows: int) -> list[int]:
    picks = [(0, 0), (cols - 1, 0), (cols - 1, rows - 1), (0, rows - 1)]
    picks += [(cols // 3, rows // 3), (2 * cols // 3, 2 * rows // 3)]
    return [r * cols + c for c, r in picks]


def random_robot(rng: np.random.Generator) -> F64:
    """A board-to-robot matrix (3 x 3): the board mirrored (a robot's base frame seen from
    above is the mirror image of a board's), turned at random and offset up to 600 mm."""
    a = rng.uniform(-np.pi, np.pi)
    m = np.eye(3)
    m[:2, :2] = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]) @ np.diag([1.0, -1.0])
    m[:2, 2] = rng.uniform(-600.0, 600.0, 2)
    return m


def registered(cal: Calibration, robot: F64, rng: np.random.Generator) -> Calibration:
    """``cal`` registered to ``robot`` (board mm -> robot mm) from six touched dots, each
    reading ROBOT_TOUCH_NOISE_MM off per axis."""
    board = cal.board
    assert board is not None
    dots = _touched_dots(board.cols, board.rows)
    truth = _apply(robot, board.world_points()[dots])
    return cal.register(truth + rng.normal(0.0, ROBOT_TOUCH_NOISE_MM, truth.shape), dots=dots)


def _apply(m: F64, points: F64) -> F64:
    return np.asarray(points @ m[:2, :2].T + m[:2, 2], dtype=np.float64)


def rms(values: Any) -> float:
    a = np.asarray(values, dtype=np.float64)
    return float(np.sqrt(np.mean(a * a))) if a.size else float("nan")


@dataclasses.dataclass
class Errors:
    """Actual errors and predicted 1-sigma (RMS distances, mm) of one category's points."""

    actual: F64
    predicted: F64

    @property
    def ratio(self) -> float:
        """RMS actual error / RMS predicted 1-sigma."""
        return rms(self.actual) / rms(self.predicted)

    @staticmethod
    def pooled(parts: Sequence[Errors]) -> Errors:
        return Errors(
            np.concatenate([p.actual for p in parts]), np.concatenate([p.predicted for p in parts])
        )


def exact_pixels(cal: Calibration) -> Mapping:
    """The calibration's mapping of exact pixels (no detector noise): board points."""
    return lambda px: cal.image_to_world(px, return_std=True, pixel_sigma=0.0)  # type: ignore[no-any-return]


def board_point_errors(
    scene: synth.RenderedScene,
    mapping: Mapping,
    rng: np.random.Generator,
    n: int = 2000,
    to_truth_frame: Callable[[F64], F64] | None = None,
) -> Errors:
    """``n`` random points over the board's area (scene's board): projected exactly, mapped
    by ``mapping``, against the truth (in board mm, or ``to_truth_frame`` of it)."""
    board = scene.board if scene.board is not None else synth.PAPER_BOARD
    span = np.array([(board.cols - 1) * board.pitch, (board.rows - 1) * board.pitch])
    truth = rng.uniform(0.0, 1.0, (n, 2)) * span
    mm, std = mapping(scene.project(truth))
    if to_truth_frame is not None:
        truth = to_truth_frame(truth)
    return Errors(np.hypot(*(mm - truth).T), np.asarray(std, dtype=np.float64))


def part_errors(
    scene: synth.RenderedScene,
    cal: Calibration,
    locate: Callable[[Any, Calibration], list[Any]] | None = None,
    to_truth_frame: Callable[[F64], F64] | None = None,
) -> Errors:
    """The scene's parts located (``locate(image, cal)``, default ``locate_objects``), each
    against the nearest true centroid (board mm, or ``to_truth_frame`` of it); parts not
    within MATCH_MM of one are left out (none are in these scenes)."""
    truth = scene.object_centroids_mm
    if to_truth_frame is not None:
        truth = to_truth_frame(truth)
    found = (locate or locate_objects)(scene.image, cal)
    actual, predicted = [], []
    for o in found:
        assert o.world_mm is not None and o.world_std_mm is not None
        gap = np.hypot(*(truth - np.asarray(o.world_mm)).T)
        j = int(gap.argmin())
        if gap[j] <= MATCH_MM:
            actual.append(float(gap[j]))
            predicted.append(float(o.world_std_mm))
    return Errors(np.array(actual), np.array(predicted))


@dataclasses.dataclass
class SceneErrors:
    """One scene's calibration and each category's errors."""

    name: str
    size: tuple[int, int]
    centre_offset_px: float
    lens_model: str
    board: Errors
    parts: Errors
    robot_parts: Errors
    calibration: Calibration


def measure_pair(
    name: str, pair: synth.PaperScene, rng: np.random.Generator, board_points: int = 2000
) -> SceneErrors:
    """Calibrates on the pair's board image (lens "auto"), registers it to a random robot,
    and measures each category."""
    view = pair.calibration
    assert view.board is not None
    cal = Calibration.from_detection(detect_board(view.image, view.board))
    cam = view.camera
    offset = float(np.hypot(cam.cx - (cam.width - 1) / 2.0, cam.cy - (cam.height - 1) / 2.0))
    robots = [random_robot(rng) for _ in range(ROBOTS_PER_SCENE)]
    return SceneErrors(
        name,
        (cam.width, cam.height),
        offset,
        cal.lens_model,
        board_point_errors(view, exact_pixels(cal), rng, board_points),
        part_errors(pair.objects, cal),
        Errors.pooled(
            [
                part_errors(
                    pair.objects,
                    registered(cal, robot, rng),
                    locate=lambda image, c: locate_objects(image, c, frame="robot"),
                    to_truth_frame=lambda mm, robot=robot: _apply(robot, mm),
                )
                for robot in robots
            ]
        ),
        cal,
    )


SIZES = ((1280, 720), (640, 480))
"""The webcam scenes' resolutions."""


def webcam_pairs(
    n: int, sizes: Sequence[tuple[int, int]] = SIZES, centre_offset_px: float | None = None
) -> list[tuple[str, Any]]:
    """``n`` random webcam scenes per size (distortion centre 0-40 px off, or
    ``centre_offset_px`` off in a random direction; k2, tangential), as (name, pair)."""
    off = "" if centre_offset_px is None else f" {centre_offset_px:g} px off"
    return [
        (
            f"webcam {w}x{h}{off} #{seed}",
            random_webcam_scene(seed, size=(w, h), centre_offset_px=centre_offset_px),
        )
        for w, h in sizes
        for seed in range(n)
    ]


def paper_pairs(n: int) -> list[tuple[str, Any]]:
    """``n`` of today's random paper scenes (random_paper_scene), each with a second image of
    12 scattered parts from the same camera and pose, as (name, pair)."""
    out = []
    for seed in range(n):
        view = synth.random_paper_scene(1000 + seed)
        rng = np.random.default_rng(5000 + seed)
        parts = synth.render_scene(
            view.camera,
            view.pose,
            board=None,
            objects=scattered_parts(rng),
            seed=seed,
            **synth.PAPER_EFFECTS,
        )
        out.append((f"paper #{1000 + seed}", synth.PaperScene(view, parts)))
    return out


def demo_pair() -> list[tuple[str, Any]]:
    """The demo's scene (planarcal demo): the paper's board, and its 10 bolts and nuts."""
    return [("demo", synth.paper_scene(seed=0))]
