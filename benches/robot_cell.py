"""A simulated robot cell on rendered scenes (issue 14): a fixed camera over a table, the
paper's board lying anywhere on it, a robot whose base frame is a known rotation, offset and
mirror of the table's, touch points with a robot's repeatability (0.05 mm) and one touch on
the wrong dot, and elongated and round parts with known positions and angles.

The cell is calibrated from the board's image, registered to the robot from the touches
(``planarcal register``'s fit), and the parts' image (the board taken away) is located in
the robot's frame. Measured: each part's position and angle against the truth in the robot
frame, whether the wrong touch was named, and how the reported 1-sigma compares with the
actual error.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import detect_board
from planarcal.live.objects import locate_objects
from planarcal.robot import RobotFrame

F64 = NDArray[np.float64]

TOUCH_NOISE_MM = 0.05
"""A typical robot's repeatability (1-sigma per axis)."""

# Parts: (kind, size mm, length mm or None); the first three are elongated (an axis to
# measure), the disc and the nut are not (second moments are isotropic for both).
PARTS = (
    ("rectangle", 8.0, 24.0),
    ("rectangle", 10.0, 20.0),
    ("bolt", 6.0, 30.0),
    ("disc", 14.0, None),
    ("nut", 8.0, None),
)
ELONGATED = ("rectangle", "bolt")


@dataclasses.dataclass(frozen=True)
class Cell:
    """One rendered cell and its truth."""

    board_image: synth.RenderedScene
    parts_image: synth.RenderedScene
    table_to_robot: F64
    """3 x 3: table mm -> robot mm (a proper rotation of a mirrored table, and an offset)."""
    parts_robot_mm: F64
    parts_robot_angle_deg: F64
    """Each part's axis in the robot frame, [-90, 90); NaN where it has none."""


def wrap_deg(angle: F64 | float) -> F64:
    """Angles into [-90, 90) (an axis, not a direction)."""
    return np.asarray((np.asarray(angle) + 90.0) % 180.0 - 90.0, dtype=np.float64)


def _apply(matrix: F64, points: F64) -> F64:
    return np.asarray(points @ matrix[:2, :2].T + matrix[:2, 2], dtype=np.float64)


def make_cell(seed: int) -> Cell:
    """A cell: the board at a random place and angle on the table, the camera over it
    (tilted up to 8 degrees, the paper's lens), a robot frame mirrored, turned and offset,
    the parts scattered over the board's area at random angles."""
    rng = np.random.default_rng(seed)
    board = synth.PAPER_BOARD
    span = np.array([(board.cols - 1) * board.pitch, (board.rows - 1) * board.pitch])
    origin = tuple(float(v) for v in rng.uniform(-300.0, 300.0, 2))
    board_angle = float(rng.uniform(-180.0, 180.0))
    turn = np.radians(board_angle)
    rot = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    centre = np.asarray(origin) + rot @ (span / 2.0)
    pose = synth.PlanePose(
        distance_mm=synth.PAPER_CAMERA.focal_px / 1.9,
        tilt_deg=float(rng.uniform(0.0, 8.0)),
        tilt_axis_deg=float(rng.uniform(0.0, 360.0)),
        roll_deg=float(rng.uniform(-3.0, 3.0)),
        look_at_mm=(float(centre[0]), float(centre[1])),
    )
    effects = dict(
        blur_sigma_px=0.8, noise_sigma=2.0, lighting_gradient=0.15, lighting_angle_deg=30.0
    )
    board_image = synth.render_scene(
        synth.PAPER_CAMERA,
        pose,
        board=board,
        board_origin_mm=origin,
        board_angle_deg=board_angle,
        seed=seed,
        **effects,  # type: ignore[arg-type]
    )
    # The parts where the board was, apart from each other.
    placed: list[synth.SceneObject] = []
    while len(placed) < len(PARTS):
        kind, size, length = PARTS[len(placed)]
        where = origin + rot @ (rng.uniform(0.15, 0.85, 2) * span)
        if any(np.hypot(*(where - np.asarray(p.position_mm))) < 45.0 for p in placed):
            continue
        placed.append(
            synth.SceneObject(
                kind,  # type: ignore[arg-type]
                (float(where[0]), float(where[1])),
                angle_deg=float(rng.uniform(-180.0, 180.0)),
                size_mm=size,
                length_mm=length,
            )
        )
    parts_image = synth.render_scene(
        synth.PAPER_CAMERA,
        pose,
        board=None,
        objects=placed,
        seed=seed + 1,
        **effects,  # type: ignore[arg-type]
    )
    # The robot: seen from above its base frame (z up) is a mirror image of the table's
    # (y down the image); turned and offset.
    phi = np.radians(rng.uniform(-180.0, 180.0))
    linear = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]]) @ np.diag(
        [1.0, -1.0]
    )
    table_to_robot = np.eye(3)
    table_to_robot[:2, :2] = linear
    table_to_robot[:2, 2] = rng.uniform(-600.0, 600.0, 2)
    truth_mm = _apply(table_to_robot, parts_image.object_centroids_mm)
    angles = []
    for part in placed:
        if part.kind not in ELONGATED:
            angles.append(math.nan)
            continue
        t = math.radians(part.angle_deg)
        d = linear @ np.array([math.cos(t), math.sin(t)])
        angles.append(math.degrees(math.atan2(d[1], d[0])))
    return Cell(board_image, parts_image, table_to_robot, truth_mm, wrap_deg(np.array(angles)))


def touch_points(
    cell: Cell, detection: Any, rng: np.random.Generator, count: int = 6, wrong: bool = True
) -> tuple[F64, F64, int | None]:
    """Board mm (the calibration's frame: the detection's numbering of the dots, which for
    a board without an origin marker may be the printed one turned) of `count` dots spread
    over the board, its corners first; the robot's reading at each (the truth plus
    TOUCH_NOISE_MM per axis); and which touch (if `wrong`) landed on a neighbouring dot."""
    board = detection.board
    cols, rows = board.cols, board.rows
    corners = [(0, 0), (cols - 1, 0), (cols - 1, rows - 1), (0, rows - 1)]
    inner = [(cols // 2, rows // 2), (cols // 3, 2 * rows // 3), (2 * cols // 3, rows // 3)]
    picks = [r * cols + c for c, r in (corners + inner)[:count]]
    bad = int(rng.integers(0, count)) if wrong else None
    # The dot the robot touched: the one meant, or for the wrong touch its neighbour.
    touched = list(picks)
    if bad is not None:
        touched[bad] += 1 if touched[bad] % cols == 0 else -1
    # Each detected dot's printed dot: the one whose true image is nearest.
    printed = np.linalg.norm(
        detection.image_points[touched][:, None] - cell.board_image.dot_centres_px[None], axis=2
    ).argmin(axis=1)
    turn = np.radians(cell.board_image.board_angle_deg)
    rot = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    table = board.world_points()[printed] @ rot.T + np.asarray(cell.board_image.board_origin_mm)
    robot = _apply(cell.table_to_robot, table) + rng.normal(0.0, TOUCH_NOISE_MM, table.shape)
    return detection.world_points()[picks], robot, bad


@dataclasses.dataclass(frozen=True)
class CellResult:
    wrong_touch_named: bool
    position_err_mm: F64
    """Per part found, its distance from the truth in the robot frame."""
    predicted_std_mm: F64
    angle_err_deg: F64
    """Per elongated part, |angle - truth| as axes (mod 180)."""
    round_parts_without_angle: int
    round_parts: int
    parts_found: int


def run_cell(seed: int) -> CellResult:
    """Calibrate, register and locate one cell."""
    cell = make_cell(seed)
    rng = np.random.default_rng(seed + 7)
    board = cell.board_image.board
    assert board is not None
    # The board lies at any angle on the table: its frame is taken as found (turned=True).
    detection = detect_board(cell.board_image.image, board, turned=True)
    cal = Calibration.from_detection(detection)
    board_mm, robot_mm, bad = touch_points(cell, detection, rng)
    frame = RobotFrame.fit(board_mm, robot_mm, drop_outliers=True)
    named = bad is not None and frame.outliers == (bad,)
    registered = cal.with_robot_frame(frame)
    found = locate_objects(cell.parts_image.image, registered, frame="robot")
    got = np.array([o.world_mm for o in found]).reshape(-1, 2)
    std = np.array([o.world_std_mm for o in found], dtype=np.float64)
    # Each found part against the nearest true one.
    d = np.linalg.norm(got[:, None] - cell.parts_robot_mm[None], axis=2)
    nearest = d.argmin(axis=1)
    pos_err = d[np.arange(len(got)), nearest]
    angle_err, round_null, rounds = [], 0, 0
    for o, k in zip(found, nearest, strict=True):
        truth = cell.parts_robot_angle_deg[k]
        if math.isnan(truth):
            rounds += 1
            round_null += o.angle_deg is None
        elif o.angle_deg is not None:
            angle_err.append(abs(float(wrap_deg(o.angle_deg - truth))))
        else:
            angle_err.append(math.inf)
    return CellResult(
        named,
        pos_err,
        std,
        np.array(angle_err),
        round_null,
        rounds,
        len(found),
    )
