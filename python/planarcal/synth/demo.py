"""The built-in example: the paper's whole method on a rendered scene of its setup.

planarcal.synth renders the paper's board (or, with ``board="chessboard"`` or ``"charuco"``,
a board of that type in its place: :data:`planarcal.synth.paper.PAPER_BOARDS`) seen by a
1280 x 720 webcam through a plastic lens (barrel distortion), with blur, sensor noise and
uneven lighting, then the same view with 3 bolts and 7 nuts at the positions of the paper's
Table 5. The demo runs the pipeline a user
runs on real images: find the board, calibrate, report, locate the objects in millimetres
with their error bars and angles, register the board to a robot from six touched dots, and,
because the scene is rendered, says how far every result is from the truth. With a report
directory it writes what a user's run would (the report's figures, the calibration file, the
images and the objects drawn on theirs), and it ends with the commands to run on a camera.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.boards import BOARD_TYPES, Board
from planarcal.calib.calibration import Calibration
from planarcal.calib.detection import detect_board
from planarcal.errors import ArgumentError, BoardError, MissingDependencyError
from planarcal.files import atomic_write
from planarcal.live.objects import locate_objects
from planarcal.report import summary_text, write_report
from planarcal.report.drawing import draw_objects, png_bytes
from planarcal.report.figure import require_matplotlib
from planarcal.report.printable.options import board_options
from planarcal.synth import paper_data
from planarcal.synth.objects import ObjectKind

REPORT_EXAMPLE = "demo-report"
"""The directory the demo's closing lines suggest for ``planarcal demo --report``."""

NEXT_STEPS = (
    "On your own camera:",
    "  planarcal board -o board.pdf    # print at 100%; it names a board for A4 or letter",
    "  planarcal calibrate photo.png -o calib.json --report report",
    "  planarcal locate objects.png --calibration calib.json --annotate located.png",
    "  (or, frame after frame: planarcal run --source 0 --calibration calib.json)",
)
"""The demo's last lines: the commands a user runs on a real camera, the demo's steps."""


def run(seed: int = 0, report: str | os.PathLike[str] | None = None, board: str = "circles") -> str:
    """The demo's report, as text; with ``report``, a directory (created if need be), also
    its files there: the calibration report (``planarcal.report.write_report``: the figures,
    the per-point table and summary.json), the calibration (calib.json), the rendered images
    (board.png, objects.png) and the objects located, drawn on theirs (located.png), each
    written atomically. ``board``: the board type in the scene ("circles", the paper's
    board; "chessboard"; "charuco": see :data:`planarcal.synth.paper.PAPER_BOARDS`)."""
    if board not in BOARD_TYPES:
        raise BoardError(f"board must be one of {', '.join(BOARD_TYPES)}, got {board!r}")
    out: list[str] = []
    say = out.append
    start = time.perf_counter()
    scene = synth.paper_scene(seed=seed, board=board)
    board_view, objects_view = scene.calibration, scene.objects
    shown = board_view.board
    assert shown is not None  # paper_scene always renders its board in the first view
    cam, pose, fx = board_view.camera, board_view.pose, board_view.effects
    say("planarcal demo: the paper's setup, rendered with exact ground truth (planarcal.synth)")
    say(
        f"  {_board_words(shown)} seen by a {cam.width} x {cam.height} "
        f"camera from {pose.distance_mm:g} mm, tilted {pose.tilt_deg:g} degrees, through a lens "
        f"with barrel distortion (k1 = {cam.k1:g}); blur {fx['blur_sigma_px']:g} px, noise "
        f"{fx['noise_sigma']:g} grey levels, uneven lighting"
    )
    say("")

    # 1. Calibration from the board image.
    detection = detect_board(board_view.image, shown)
    cal = Calibration.from_detection(detection)
    plain = Calibration.from_detection(detection, lens="none")
    say("1. Calibration image")
    say(summary_text(cal, detection))
    if isinstance(shown, CircleGridBoard):
        centre_err = np.linalg.norm(
            detection.image_points[:, None] - board_view.dot_centres_px[None], axis=2
        ).min(axis=1)
        what = "Dot centres"
    else:  # each corner against its own id's truth
        ids = np.asarray(detection.ids, dtype=np.intp)
        centre_err = np.linalg.norm(detection.image_points - board_view.points_px[ids], axis=1)
        what = f"Corners ({len(ids)} of {shown.n_points})"
    say(
        f"{what} against the truth: {np.sqrt(np.mean(centre_err**2)):.4f} px RMS, "
        f"{centre_err.max():.4f} px at most."
    )
    p = plain.stats
    say(
        f"A homography alone (the paper's model): mean {p.mean:.3f} px, max {p.max:.3f} px, "
        f"leave-one-out {plain.summary().loo_mean_mm:.3f} mm. The paper, on its real setup: "
        f"mean {paper_data.REPORTED_MEAN_PX} px, max {paper_data.REPORTED_MAX_PX} px: the "
        "lens's barrel distortion, which a homography cannot model, dominates both; the lens "
        "model fitted with H removes it."
    )
    truth = _points_between(shown)
    pixels = board_view.project(truth)
    for name, c in (("with the lens model", cal), ("a homography alone", plain)):
        err = np.hypot(*(c.image_to_world(pixels) - truth).T)
        say(
            f"Mapping error over the board against the truth, {name}: {err.mean():.4f} mm "
            f"mean, {err.max():.4f} mm max."
        )
    say("")

    # 2. Objects, located in millimetres.
    located = locate_objects(objects_view.image, cal)
    truth_mm = objects_view.object_centroids_mm
    kinds = [o.kind for o in objects_view.objects]
    say(f"2. Objects image: {len(located)} objects found ({len(truth_mm)} placed)")
    true_angles = [o.angle_deg if o.kind == "bolt" else math.nan for o in objects_view.objects]
    errors, matched = _object_rows(located, truth_mm, kinds, true_angles, say)
    if errors:
        say(
            f"   Located within {np.mean(errors):.3f} mm of the truth on average, "
            f"{max(errors):.3f} mm at worst; the 1-sigma said {_rms(_std_of(located)):.3f} mm "
            f"(RMS), the errors are {_rms(np.array(errors)):.3f} mm RMS. Angles: the part's "
            "axis in degrees from the board's x towards its y; '-': too round for one."
        )
    say("")

    # 3. The robot's frame, from six dots its tool touched.
    point = "dots" if isinstance(shown, CircleGridBoard) else "corners"
    say(f"3. Robot frame: six {point} touched by a robot's tool (simulated: 0.05 mm of noise)")
    dots = _touched(shown)
    robot_truth = _ROBOT
    touched = _apply(robot_truth, cal.board.world_points()[dots]) if cal.board else None
    assert touched is not None
    rng = np.random.default_rng(seed)
    registered = cal.register(touched + rng.normal(0.0, 0.05, touched.shape), dots=dots)
    frame = registered.robot_frame
    assert frame is not None
    say(f"   {frame.summary().splitlines()[-1]}")
    in_robot = locate_objects(objects_view.image, registered, frame="robot")
    robot_errors, angle_errors = [], []
    for o, j in zip(in_robot, matched, strict=True):
        assert o.world_mm is not None
        robot_errors.append(float(np.hypot(*(_apply(robot_truth, truth_mm[j]) - o.world_mm))))
        if o.angle_deg is not None and not math.isnan(true_angles[j]):
            turned = _axis_through(robot_truth, true_angles[j])
            angle_errors.append(abs((o.angle_deg - turned + 90.0) % 180.0 - 90.0))
    say(
        f"   Parts in robot mm within {np.mean(robot_errors):.3f} mm of the truth on average, "
        f"{max(robot_errors):.3f} mm at worst (1-sigma {_rms(_std_of(in_robot)):.3f} mm RMS); "
        f"the bolts' angles within {max(angle_errors, default=math.nan):.2f} degree."
    )
    say("")
    say(f"Rendered, calibrated, located and registered in {time.perf_counter() - start:.1f} s.")
    if report is None:
        extra = _report_extra()
        again = "" if board == "circles" else f" --board {board}"
        say(
            f"To see the figures and the images: planarcal demo{again} --report "
            f"{REPORT_EXAMPLE}{extra}"
        )
    else:
        written = write_report(cal, report, image=board_view.image, detection=detection)
        folder = Path(report)
        written += [
            cal.save(folder / "calib.json"),
            atomic_write(folder / "board.png", png_bytes(board_view.image)),
            atomic_write(folder / "objects.png", png_bytes(objects_view.image)),
            atomic_write(
                folder / "located.png", png_bytes(draw_objects(objects_view.image, located))
            ),
        ]
        say(f"Wrote to {folder}: {', '.join(p.name for p in written)}")
    out += _next_steps(shown)
    return "\n".join(out)


def _object_rows(
    located: Sequence[Any],
    truth_mm: NDArray[np.float64],
    kinds: Sequence[str],
    true_angles: Sequence[float],
    say: Callable[[str], None],
) -> tuple[list[float], list[int]]:
    """Says a header, then one row per located object (matched to the nearest true one: its
    kind, pixel, position, truth, error, 1-sigma and angles); returns the errors and the
    matches."""
    say(
        f"   {'object':<7}{'kind':<6}{'image px':>18}{'located mm':>20}{'true mm':>18}"
        f"{'error':>9}{'1-sigma':>9}{'angle':>8}{'true':>7}"
    )
    errors, matched = [], []
    for o in located:
        assert o.world_mm is not None and o.world_std_mm is not None
        gap = np.linalg.norm(truth_mm - np.asarray(o.world_mm), axis=1)
        j = int(gap.argmin())
        errors.append(float(gap[j]))
        matched.append(j)
        say(
            f"   ID:{o.id:<4}{kinds[j]:<6}{o.centroid_px[0]:>9.1f}{o.centroid_px[1]:>9.1f}"
            f"{o.world_mm[0]:>10.2f}{o.world_mm[1]:>10.2f}"
            f"{truth_mm[j][0]:>9.1f}{truth_mm[j][1]:>9.1f}{gap[j]:>6.3f} mm"
            f"{o.world_std_mm:>9.3f}{_angle(o.angle_deg):>8}{_angle(true_angles[j]):>7}"
        )
    return errors, matched


def _report_extra() -> str:
    """What the figures need, said now rather than after the next run: the report extra."""
    try:
        require_matplotlib()
    except MissingDependencyError:
        return " (after: pip install 'planarcal[report]')"
    return ""


def _next_steps(board: Board) -> list[str]:
    """NEXT_STEPS, for a board other than a circle grid with its options spelt out."""
    steps = list(NEXT_STEPS)
    if isinstance(board, CircleGridBoard):
        return steps
    printing = " ".join(board_options(board, for_printing=True))
    steps[1] = f"  planarcal board {printing} -o board.pdf    # print at 100%"
    options = " ".join(board_options(board))
    steps[2] = f"  planarcal calibrate photo.png {options} -o calib.json --report report"
    return steps


def _board_words(board: Board) -> str:
    """The board in the demo's opening line."""
    if isinstance(board, CircleGridBoard):
        return (
            f"{board.cols} x {board.rows} board ({board.diameter:g} "
            f"mm dots, {board.pitch:g} mm apart)"
        )
    return board.describe()


def _points_between(board: Board) -> NDArray[np.float64]:
    """A 40 x 30 grid of points over the board's points (mm), where the mapping is tested."""
    if isinstance(board, CircleGridBoard):
        grid = np.mgrid[0 : board.cols - 1 : 40j, 0 : board.rows - 1 : 30j].reshape(2, -1).T
        return np.asarray(grid * board.pitch, np.float64)
    pts = board.world_points()
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    grid = np.mgrid[0:1:40j, 0:1:30j].reshape(2, -1).T
    return np.asarray(lo + grid * (hi - lo), np.float64)


def _touched(board: Board) -> list[int]:
    """The six points the demo's robot touches: the four corners of the board's points and
    two inside (for the paper's board, the dots its first version touched)."""
    if isinstance(board, CircleGridBoard):
        dots = [0, board.cols - 1, board.cols * board.rows - 1, board.cols * (board.rows - 1)]
        return [*dots, board.cols * (board.rows // 3) + board.cols // 3, board.cols * 6 + 9]
    pts = board.world_points()
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    at = [(0, 0), (1, 0), (1, 1), (0, 1), (1 / 3, 1 / 3), (2 / 3, 3 / 4)]
    return [int(np.argmin(np.hypot(*(pts - (lo + np.array(f) * (hi - lo))).T))) for f in at]


# The demo's robot: its base frame seen from above is the board's mirror image, turned by
# -127 degrees and offset, as a robot beside the table would have it.
_ROBOT = np.array(
    [
        [math.cos(math.radians(-127.0)), math.sin(math.radians(-127.0)), 412.0],
        [math.sin(math.radians(-127.0)), -math.cos(math.radians(-127.0)), -233.0],
        [0.0, 0.0, 1.0],
    ]
)


def _apply(m: NDArray[np.float64], points: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.asarray(points @ m[:2, :2].T + m[:2, 2], dtype=np.float64)


def _axis_through(m: NDArray[np.float64], angle_deg: float) -> float:
    a = math.radians(angle_deg)
    d = m[:2, :2] @ np.array([math.cos(a), math.sin(a)])
    return math.degrees(math.atan2(d[1], d[0]))


def _angle(value: float | None) -> str:
    if value is None or math.isnan(value):
        return "-"
    return f"{(value + 90.0) % 180.0 - 90.0:.1f}"


def _std_of(objects: list[Any]) -> NDArray[np.float64]:
    return np.array([o.world_std_mm for o in objects], dtype=np.float64)


def _rms(values: NDArray[np.float64]) -> float:
    return float(np.sqrt(np.mean(values**2))) if len(values) else math.nan


PLACEMENT_STEP_MM = 5.0
"""How densely ``run_placements`` samples the work area against the truth (mm)."""


def run_placements(
    count: int = 6,
    seed: int = 0,
    report: str | os.PathLike[str] | None = None,
    board: str = "circles",
) -> str:
    """The demo of a work area larger than the board (``planarcal demo --placements N``): a
    work cell three boards wide (:func:`planarcal.synth.render_cell`), the board photographed
    at ``count`` places (2 to 9: the middle, the corners, the sides), calibrated from all the
    images together (``Calibration.from_detections``), then parts located over the whole
    area; says, against the truth, each placement's pose, the mapping's error over the whole
    area and the parts' errors, beside what the middle placement alone (today's single-image
    calibration, extrapolated) gives. With ``report``, a directory, also writes the
    calibration report (the middle placement's detection drawn), calib.json, every placement's
    image (placement-K.png), the parts' image and the parts located, drawn on it."""
    if board not in BOARD_TYPES:
        raise BoardError(f"board must be one of {', '.join(BOARD_TYPES)}, got {board!r}")
    if isinstance(count, bool) or not isinstance(count, int) or not 2 <= count <= 9:
        raise ArgumentError(f"placements must be 2 to 9, got {count!r}")
    out: list[str] = []
    say = out.append
    start = time.perf_counter()
    cell = synth.render_cell(board, count, seed=seed)
    shown, cam, pose = cell.board, cell.camera, cell.pose
    fx = cell.placements[0].scene.effects
    w, h = cell.area_mm
    say(
        f"planarcal demo --placements {count}: a work area three boards wide, calibrated from "
        f"{count} placements of one board (planarcal.synth, exact ground truth)"
    )
    say(
        f"  {_board_words(shown)}, laid at {count} places on a {w:g} x {h:g} mm work area "
        f"(3 x 3 of its {cell.board_size_mm[0]:g} x {cell.board_size_mm[1]:g} mm sheet), one "
        f"image each, seen by a {cam.width} x {cam.height} camera from "
        f"{pose.distance_mm:.0f} mm, tilted {pose.tilt_deg:g} degrees, through a lens with "
        f"barrel distortion (k1 = {cam.k1:g}, k2 = {cam.k2:g}); blur "
        f"{fx['blur_sigma_px']:g} px, noise {fx['noise_sigma']:g} grey levels, uneven lighting"
    )
    say("")

    # 1. The placements, calibrated together; the middle one alone beside them.
    names = [p.name for p in cell.placements]
    detections = [detect_board(p.image, shown) for p in cell.placements]
    cal = Calibration.from_detections(detections, reference=cell.reference, names=names)
    alone = Calibration.from_detection(detections[cell.reference])
    say(f"1. Calibration from the {count} images together")
    say(summary_text(cal, detections[cell.reference]))
    say("")
    say("   Each placement's pose in the plane (the middle placement's board frame) against the")
    say("   truth:")
    say(
        f"   {'placement':<18}{'angle deg':>10}{'offset mm':>20}{'true deg':>10}"
        f"{'true mm':>20}{'error mm':>10}{'RMS px':>8}"
    )
    for p in cal.placements:
        angle, offset = cell.true_pose(p.index)
        gap = math.hypot(p.offset_mm[0] - offset[0], p.offset_mm[1] - offset[1])
        say(
            f"   {p.index:<3}{p.name:<15}{p.angle_deg:>10.3f}{p.offset_mm[0]:>10.2f}"
            f"{p.offset_mm[1]:>10.2f}{angle:>10.3f}{offset[0]:>10.2f}{offset[1]:>10.2f}"
            f"{gap:>10.4f}{p.rms_px:>8.3f}"
        )
    say("")

    # 2. The mapping over the whole work area, against the truth.
    table = cell.area_points(PLACEMENT_STEP_MM)
    pixels, truth = cell.pixel_of(table), cell.truth_plane_mm(table)
    say(
        f"2. Mapping over the whole work area against the truth (a point every "
        f"{PLACEMENT_STEP_MM:g} mm, {len(table):,} points, each from its exact pixel):"
    )
    area_errors = {}
    for name, c in ((f"the {count} placements together", cal), ("the middle one alone", alone)):
        mm, std = c.image_to_world(pixels, return_std=True, pixel_sigma=0.0)
        err = np.hypot(*(mm - truth).T)
        area_errors[name] = err
        say(
            f"   {name + ':':<32}mean {err.mean():.4f} mm, worst {err.max():.4f} mm; predicted "
            f"1-sigma {_rms(std):.4f} mm RMS against {_rms(err):.4f} mm (lens: {c.lens_model})"
        )
    say(
        "   One image calibrates where its board lay; beyond it the mapping is extrapolated, "
        "and its 1-sigma does not know how far off it is. The placements tie the lens down "
        "over the whole area."
    )
    if alone.lens_note:
        say(f"   (The middle board alone: {alone.lens_note}.)")
    say("")

    # 3. Parts anywhere in the work area, located with each calibration.
    parts = _cell_parts(cell)
    objects_view = synth.render_scene(
        cam, pose, board=None, objects=parts, seed=seed + 1, **_tones_and_effects(fx)
    )
    located = locate_objects(objects_view.image, cal)
    truth_mm = cell.truth_plane_mm(objects_view.object_centroids_mm)
    kinds = [o.kind for o in parts]
    true_angles = [
        o.angle_deg - cell.placements[cell.reference].angle_deg if o.kind == "bolt" else math.nan
        for o in parts
    ]
    say(f"3. Parts over the whole work area: {len(located)} found ({len(parts)} placed)")
    errors, _ = _object_rows(located, truth_mm, kinds, true_angles, say)
    alone_located = locate_objects(objects_view.image, alone)
    alone_errors = [
        float(np.linalg.norm(truth_mm - np.asarray(o.world_mm), axis=1).min())
        for o in alone_located
        if o.world_mm is not None
    ]
    if errors:
        say(
            f"   Located within {np.mean(errors):.3f} mm of the truth on average, "
            f"{max(errors):.3f} mm at worst (1-sigma {_rms(_std_of(located)):.3f} mm RMS); with "
            f"the middle placement alone: {np.mean(alone_errors):.3f} mm on average, "
            f"{max(alone_errors):.3f} mm at worst."
        )
    say("")
    say(f"Rendered, calibrated and located in {time.perf_counter() - start:.1f} s.")
    again = "" if board == "circles" else f" --board {board}"
    if report is None:
        extra = _report_extra()
        say(
            f"To see the figures and the images: planarcal demo --placements {count}{again} "
            f"--report {REPORT_EXAMPLE}{extra}"
        )
    else:
        reference = cell.placements[cell.reference]
        written = write_report(
            cal,
            report,
            image=reference.image,
            detection=detections[cell.reference],
            placement_images=[p.image for p in cell.placements],
        )
        folder = Path(report)
        written.append(cal.save(folder / "calib.json"))
        written += [
            atomic_write(folder / f"placement-{p.index}.png", png_bytes(p.image))
            for p in cell.placements
        ]
        written += [
            atomic_write(folder / "objects.png", png_bytes(objects_view.image)),
            atomic_write(
                folder / "located.png", png_bytes(draw_objects(objects_view.image, located))
            ),
        ]
        say(f"Wrote to {folder}: {', '.join(p.name for p in written)}")
    out += _placement_steps(shown, names)
    return "\n".join(out)


def _cell_parts(cell: synth.Cell) -> list[synth.SceneObject]:
    """Twelve parts spread over the whole work area (table mm): nuts, bolts and washers on a
    4 x 3 grid, at varied angles."""
    w, h = cell.area_mm
    kinds: list[tuple[ObjectKind, float, float | None]] = [
        ("nut", 8.0, None),
        ("bolt", 6.0, 30.0),
        ("washer", 8.0, None),
    ]
    parts = []
    for k, (ax, ay) in enumerate((x, y) for y in (0.16, 0.5, 0.84) for x in (0.1, 0.37, 0.63, 0.9)):
        kind, size, length = kinds[k % 3]
        parts.append(
            synth.SceneObject(
                kind, (ax * w, ay * h), angle_deg=17.0 * k - 40.0, size_mm=size, length_mm=length
            )
        )
    return parts


def _tones_and_effects(effects: Any) -> dict[str, Any]:
    """render_scene's tone and effect arguments from a scene's recorded effects."""
    names = (
        "table_grey",
        "paper_grey",
        "ink_grey",
        "metal_grey",
        "blur_sigma_px",
        "noise_sigma",
        "lighting_gradient",
        "lighting_angle_deg",
        "vignette",
    )
    return {name: effects[name] for name in names}


def _placement_steps(board: Board, names: Sequence[str]) -> list[str]:
    """NEXT_STEPS for several placements: the board's options spelt out, one image per place."""
    steps = list(NEXT_STEPS)
    printing = " ".join(board_options(board, for_printing=True))
    steps[1] = f"  planarcal board {printing} -o board.pdf    # print at 100%"
    images = " ".join(f"{name.replace(' ', '-')}.png" for name in names)
    options = " ".join(board_options(board))
    steps[2] = (
        f"  planarcal calibrate {images} {options} -o calib.json --report report"
        "    # the board laid flat at each place, the camera fixed"
    )
    return steps
