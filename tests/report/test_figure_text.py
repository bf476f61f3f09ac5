"""The drawn figures' text is legible at every common image size (issue 26): each figure is
drawn on rendered scenes at 640 x 480, 1280 x 720 and 3840 x 2160, and the boxes of the
texts it wrote are measured: none overlaps another, all lie inside the image, none covers a
marked point or a located part, and text grows with the image."""

from __future__ import annotations

import dataclasses
import types
from typing import Any

import cv2
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.quiver import QuiverKey
from matplotlib.text import Text

from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.coverage import Coverage, calibration_coverage, coverage
from planarcal.calib.detect import DetectionDiagnostics, RefusedCandidate, SeenBlobs
from planarcal.calib.detection import BoardDetection, detect_board
from planarcal.live.objects import locate_objects
from planarcal.report import drawing, lens
from planarcal.report.coverage import draw_coverage, placement_labels
from planarcal.report.deviations import deviation_axes
from planarcal.report.failure import detection_failure_axes
from planarcal.report.labels import Box
from planarcal.report.uncertainty import uncertainty_axes

SIZES = ((640, 480), (1280, 720), (3840, 2160))


def _overlapping(boxes: list[Box]) -> list[tuple[Box, Box]]:
    return [(a, b) for i, a in enumerate(boxes) for b in boxes[i + 1 :] if a.overlaps(b)]


def _check(boxes: list[Box], shape: tuple[int, ...]) -> None:
    h, w = shape[:2]
    assert boxes, "no text written"
    assert not _overlapping(boxes), _overlapping(boxes)[:3]
    outside = [b for b in boxes if not b.inside(w, h)]
    assert not outside, outside[:3]


def _resized(image: Any, points: Any, size: tuple[int, int]) -> tuple[Any, Any]:
    """The image stretched to `size` (w, h) and the pixel points with it."""
    h, w = image.shape[:2]
    f = np.array([size[0] / w, size[1] / h])
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA), np.asarray(points) * f


def _detection_at(image: Any, detection: BoardDetection, size: tuple[int, int]) -> Any:
    img, pts = _resized(image, detection.image_points, size)
    return img, dataclasses.replace(detection, image_points=pts, image_size=size)


@pytest.fixture(scope="module")
def paper() -> Any:
    return synth.paper_scene(seed=0)


@pytest.fixture(scope="module")
def paper_detection(paper: Any) -> BoardDetection:
    return detect_board(paper.calibration.image, paper.calibration.board)


@pytest.fixture(scope="module")
def cell() -> tuple[Any, BoardDetection]:
    """A board small in a wide work cell's image."""
    c = synth.render_cell("circles", 1, supersample=2)
    image = c.placements[0].image
    return image, detect_board(image, c.board)


@pytest.fixture(scope="module")
def dense() -> tuple[Any, BoardDetection]:
    """A 20 x 20 board of 400 dots, its detection from the render's truth."""
    board = CircleGridBoard(20, 20, 10.0)
    scene = synth.render_scene(board=board, supersample=2)
    assert scene.points_visible().all()
    detection = BoardDetection(
        board=board,
        image_points=scene.points_px,
        image_size=(scene.image.shape[1], scene.image.shape[0]),
        method="lattice",
        residual_rms_px=0.0,
    )
    return scene.image, detection


def _draw(image: Any, detection: Any, size: tuple[int, int]) -> tuple[Any, list[Box], Any]:
    img, d = _detection_at(image, detection, size)
    boxes: list[Box] = []
    drawn = drawing.draw_detection(img, d, text_boxes=boxes)
    return drawn, boxes, d


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("which", ["paper", "cell", "dense"])
def test_the_detection_figure_text_never_overlaps(
    which: str,
    size: tuple[int, int],
    paper: Any,
    paper_detection: BoardDetection,
    cell: tuple[Any, BoardDetection],
    dense: tuple[Any, BoardDetection],
) -> None:
    image, detection = {
        "paper": (paper.calibration.image, paper_detection),
        "cell": cell,
        "dense": dense,
    }[which]
    drawn, boxes, d = _draw(image, detection, size)
    assert drawn.shape[:2] == (size[1], size[0])
    _check(boxes, drawn.shape)
    # No text covers a dot's centre.
    pts = d.image_points
    for b in boxes:
        inside = (pts[:, 0] > b.x0) & (pts[:, 0] < b.x1 - 1) & (pts[:, 1] > b.y0)
        inside &= pts[:, 1] < b.y1 - 1
        # The caption is written over the image, before anything: it may cover dots.
        if b.y0 > 0.25 * size[1] and b.y1 < 0.75 * size[1]:
            assert not inside.any(), (b, np.flatnonzero(inside))


def test_every_dot_is_labelled_where_there_is_room(
    paper: Any, paper_detection: BoardDetection
) -> None:
    """The paper's 140 dots at 720p and 4K all carry their label: the caption and the axis
    letters are written too, and are more boxes than the dots."""
    for size in SIZES[1:]:
        _, boxes, _ = _draw(paper.calibration.image, paper_detection, size)
        assert len(boxes) >= 140 + 3 + 2, (size, len(boxes))


def test_a_dense_board_is_thinned_evenly_and_says_so(dense: tuple[Any, BoardDetection]) -> None:
    """At 640 x 480 a 20 x 20 board has no room for 400 labels: some are left out, dot 0
    keeps its label, and the caption says how many were written."""
    image, detection = dense
    img, d = _detection_at(image, detection, SIZES[0])
    boxes: list[Box] = []
    drawn = drawing.draw_detection(img, d, text_boxes=boxes)
    assert len(boxes) < 400
    plain = drawing.draw_detection(img, d)
    assert np.array_equal(drawn, plain)  # asking for the boxes changes nothing drawn
    # Dot 0's label is placed (the coarsest sub-grid first): a box touching it.
    x, y = d.image_points[0]
    gap = 0.12 * d.pitch_px + 30
    assert any(b.x0 - gap < x < b.x1 + gap and b.y0 - gap < y < b.y1 + gap for b in boxes)


def test_text_grows_with_the_image(paper: Any, paper_detection: BoardDetection) -> None:
    """The caption's and the dots' text is at least twice as tall at 4K as at 720p, and at
    640 x 480 it is no smaller than legible (a caption line at least 11 px, a label 8)."""
    heights = {}
    for size in SIZES:
        _, boxes, _ = _draw(paper.calibration.image, paper_detection, size)
        hs = sorted(b.height for b in boxes)
        heights[size] = (hs[0], hs[-1])
    small, big = heights[SIZES[1]], heights[SIZES[2]]
    assert big[0] >= 2 * small[0] and big[1] >= 2 * small[1], heights
    assert heights[SIZES[0]][0] >= 8 and heights[SIZES[0]][1] >= 11 + 2, heights


# ------------------------------------------------------------------------------------------
# located parts


def _scaled_objects(objects: list[Any], f: Any) -> list[Any]:
    return [
        dataclasses.replace(
            o,
            contour_px=o.contour_px * f,
            centroid_px=(o.centroid_px[0] * f[0], o.centroid_px[1] * f[1]),
        )
        for o in objects
    ]


@pytest.fixture(scope="module")
def located(paper: Any) -> list[Any]:
    cal = Calibration.from_detection(detect_board(paper.calibration.image, paper.calibration.board))
    return list(locate_objects(paper.objects.image, cal))


def _check_parts(boxes: list[Box], objects: list[Any], shape: tuple[int, ...]) -> None:
    """No overlaps, and no label over a part (the title, written first in the corner where
    it covers the least, excepted)."""
    _check(boxes, shape)
    for o in objects:
        part = drawing._part_box(o)
        covering = [b for b in boxes[1:] if b.overlaps(part)]
        assert not covering, (o.id, covering)


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_located_parts_labels_cover_no_part_and_no_label(
    size: tuple[int, int], paper: Any, located: list[Any]
) -> None:
    image, _ = _resized(paper.objects.image, np.zeros((0, 2)), size)
    h, w = paper.objects.image.shape[:2]
    objects = _scaled_objects(located, np.array([size[0] / w, size[1] / h]))
    boxes: list[Box] = []
    drawn = drawing.draw_objects(
        image, objects, title="Positions in the board frame", text_boxes=boxes
    )
    _check_parts(boxes, objects, drawn.shape)
    assert len(boxes) == 1 + len(objects)  # the title and one full label per part


def _crowd(n: int, size: tuple[int, int]) -> list[Any]:
    """`n` small round parts packed on a grid over the image (a tray of parts)."""
    w, h = size
    cols = int(np.ceil(np.sqrt(n * w / h)))
    rows = int(np.ceil(n / cols))
    r = 0.18 * min(w / cols, h / rows)
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    out = []
    for k in range(n):
        row, col = divmod(k, cols)
        cx, cy = (col + 0.5) * w / cols, (row + 0.5) * h / rows
        contour = np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])
        out.append(
            types.SimpleNamespace(
                id=k + 1,
                contour_px=contour,
                centroid_px=(cx, cy),
                bbox_px=(int(cx - r), int(cy - r), int(2 * r), int(2 * r)),
                world_mm=(10.0 * col, 10.0 * row),
                angle_deg=None,
                axis_px=None,
            )
        )
    return out


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_82_parts_do_not_pile_up(size: tuple[int, int]) -> None:
    """82 parts on one image: every label placed covers no part and no other label; each
    part is named (its full label or its ID, its numbers then in the legend)."""
    objects = _crowd(82, size)
    image = np.full((size[1], size[0]), 110, np.uint8)
    boxes: list[Box] = []
    drawn = drawing.draw_objects(
        image, objects, title="Positions in the robot frame", text_boxes=boxes
    )
    _check_parts(boxes, objects, drawn.shape)
    assert len(boxes) >= 1 + len(objects)


# ------------------------------------------------------------------------------------------
# matplotlib figures: every text drawn, tick labels only where their tick is in view


def _figure_texts(fig: Any) -> list[tuple[str, Any]]:
    """(text, window extent) of every text the figure draws."""
    FigureCanvasAgg(fig)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    ticks: set[int] = set()
    out = []
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            slack = 1e-9 * abs(hi - lo)
            for t in axis.get_major_ticks() + axis.get_minor_ticks():
                for label in (t.label1, t.label2):
                    ticks.add(id(label))
                    shown = label.get_visible() and label.get_text()
                    if shown and lo - slack <= t.get_loc() <= hi + slack:
                        out.append((label.get_text(), label.get_window_extent(renderer)))
    # A quiver's key is no child matplotlib's findobj walks: its text is taken by hand.
    keys = [a.text for ax in fig.axes for a in ax.get_children() if isinstance(a, QuiverKey)]
    for t in [*fig.findobj(Text), *keys]:
        if id(t) in ticks or not t.get_visible() or not t.get_text().strip():
            continue
        box = t.get_window_extent(renderer)
        if box.width > 0 and box.height > 0:
            out.append((t.get_text(), box))
    return out


def _check_figure(fig: Any) -> list[tuple[str, Any]]:
    texts = _figure_texts(fig)
    w, h = fig.canvas.get_width_height()
    clash = [
        (a[0][:40], b[0][:40])
        for i, a in enumerate(texts)
        for b in texts[i + 1 :]
        if a[1].overlaps(b[1])
    ]
    assert not clash, clash[:5]
    outside = [t for t, b in texts if b.x0 < -1 or b.y0 < -1 or b.x1 > w + 1 or b.y1 > h + 1]
    assert not outside, outside[:5]
    return texts


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("lens_model", ["auto", "none"])
def test_the_lens_figure_text_never_overlaps(
    size: tuple[int, int], lens_model: str, paper: Any, paper_detection: BoardDetection
) -> None:
    """The lens figure of the paper's board seen at each size, with and without a lens
    model: no two texts overlap (the scale key sits inside the frame, clear of the titles;
    the legend below the distortion map, clear of its contour labels)."""
    image, d = _detection_at(paper.calibration.image, paper_detection, size)
    if lens_model == "auto":
        cal = Calibration.from_detection(d)
    else:
        cal = Calibration(
            d.world_points(), d.image_points, lens="none", board=d.board, image_size=size
        )
    texts = _check_figure(lens.lens_axes(cal, image=image))
    keys = [t for t, _ in texts if t.endswith(" px") and t[:-3].replace(".", "").isdigit()]
    assert keys, "no scale key"


# ------------------------------------------------------------------------------------------
# the coverage figure (OpenCV): its text panels


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("limit", ["default", "region"])
def test_the_coverage_figure_panels_never_overlap(
    size: tuple[int, int], limit: str, paper: Any, paper_detection: BoardDetection
) -> None:
    image, d = _detection_at(paper.calibration.image, paper_detection, size)
    cal = Calibration.from_detection(d)
    base = calibration_coverage(cal)
    cov = base if limit == "default" else calibration_coverage(cal, 0.5 * base.image_std_mm)
    boxes: list[Box] = []
    drawn = draw_coverage(image, cov, placement_labels(cal), text_boxes=boxes)
    _check(boxes, drawn.shape)
    # The title, the scale, the placement's label, and "next" when there is a region.
    assert len(boxes) == 3 + (cov.region is not None)


def test_crowded_placement_labels_move_off_the_title_and_each_other() -> None:
    """Nine placements, one under the title and two overlapping: every label is written
    where it covers no other panel."""
    w, h = 640, 480
    squares = [
        np.array([[x, y], [x + 90, y], [x + 90, y + 60], [x, y + 60]], dtype=np.float64)
        for x, y in [
            (10, 5),
            (20, 10),
            (200, 150),
            (210, 160),
            (400, 300),
            (100, 380),
            (500, 60),
            (300, 40),
            (520, 400),
        ]
    ]

    def std(px: Any) -> Any:
        return 0.01 + 0.001 * np.hypot(px[:, 0] - 320, px[:, 1] - 240)

    cov: Coverage = coverage(std, (w, h), squares, 0.3)
    labels = [f"{k} placement-{k}" for k in range(len(squares))]
    boxes: list[Box] = []
    drawn = draw_coverage(None, cov, labels, text_boxes=boxes)
    _check(boxes, drawn.shape)
    assert len(boxes) == 2 + len(squares) + (cov.region is not None)


def test_coverage_text_grows_with_the_image(paper: Any, paper_detection: BoardDetection) -> None:
    heights = {}
    for size in SIZES:
        image, d = _detection_at(paper.calibration.image, paper_detection, size)
        boxes: list[Box] = []
        draw_coverage(image, calibration_coverage(Calibration.from_detection(d)), text_boxes=boxes)
        heights[size] = boxes[0].height  # the title's panel
    assert heights[SIZES[2]] >= 2 * heights[SIZES[1]], heights


# ------------------------------------------------------------------------------------------
# the deviation, uncertainty and failure figures (matplotlib)


def _calibration(
    which: str, size: tuple[int, int], paper: Any, paper_detection: Any, cell: Any
) -> Any:
    """The paper's board, a board small in a work cell's image (the uncertainty title's
    warning: seven lines), or the paper's board's first four rows only (a partial view: the
    legend's fifth entry) seen at `size`."""
    image, detection = (paper.calibration.image, paper_detection) if which != "cell" else cell
    _, d = _detection_at(image, detection, size)
    if which == "partial":
        keep = slice(0, 4 * d.board.cols)
        return Calibration(
            d.world_points()[keep], d.image_points[keep], board=d.board, image_size=size
        )
    return Calibration.from_detection(d)


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("which", ["paper", "cell", "partial"])
@pytest.mark.parametrize("figure", ["deviations", "uncertainty"])
def test_the_deviation_and_uncertainty_figures_text_never_overlaps(
    figure: str,
    which: str,
    size: tuple[int, int],
    paper: Any,
    paper_detection: BoardDetection,
    cell: tuple[Any, BoardDetection],
) -> None:
    """No two texts overlap and none leaves the figure: the deviation figure's title in two
    lines (one ran past the left edge), the uncertainty figure taller with a warning's
    lines (they pushed the title off the top and the legend off the bottom)."""
    cal = _calibration(which, size, paper, paper_detection, cell)
    draw = deviation_axes if figure == "deviations" else uncertainty_axes
    texts = _check_figure(draw(cal))
    if figure == "uncertainty":
        assert any(t.startswith("board centre: ") for t, _ in texts)  # the legend is drawn
        assert any(t.startswith("1-sigma position uncertainty on") for t, _ in texts)
    else:
        assert any(t.startswith("Calibration deviation per") for t, _ in texts)


def _search_record(detection: BoardDetection, size: tuple[int, int]) -> DetectionDiagnostics:
    """What a search for a 10 x 8 board in the paper's 14 x 10 one might see, six refused
    candidates over one another."""
    found = detection.image_points
    reasons = (
        "the dots continue past the grid's right edge: the board in view is larger than 10 x 8",
        "not the board's grid: dot 4 is 30.0 px from where a homography puts it",
    )
    return DetectionDiagnostics(
        board=CircleGridBoard(cols=10, rows=8, pitch=20.0, diameter=10.0),
        image_size=size,
        blobs=(
            SeenBlobs("dark", found, np.full(len(found), 0.3 * detection.pitch_px)),
            SeenBlobs("light", found[:5] + 0.5 * detection.pitch_px, np.full(5, 4.0)),
        ),
        candidates=tuple(
            RefusedCandidate(
                "symmetric" if k % 2 else "blobs",
                "dark",
                found[10 * k : 10 * k + 80],
                reasons[k % 2],
            )
            for k in range(6)
        ),
    )


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("record", [True, False], ids=["record", "no-record"])
def test_the_detection_failure_figure_text_never_overlaps(
    size: tuple[int, int], record: bool, paper: Any, paper_detection: BoardDetection
) -> None:
    image, d = _detection_at(paper.calibration.image, paper_detection, size)
    diagnostics = _search_record(d, size) if record else None
    message = f"no 10 x 8 circle grid (80 dots) found in the {size[0]} x {size[1]} image."
    texts = _check_figure(detection_failure_axes(image, diagnostics, message))
    assert any(t == "Board not found" for t, _ in texts)
    assert any(message[:20] in t for t, _ in texts)
