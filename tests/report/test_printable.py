"""Printable boards (planarcal.report.printable): exact page size, exact dots, the 100 mm check bar,
layout inside the margins, refusal of boards that do not fit, atomic writes.

The SVG is checked by parsing it; the PDF by parsing its structure and content stream (the
same shapes, in mm under one `cm` matrix) and, where poppler's pdftoppm is installed, by
rasterising it and measuring dots and ticks in pixels. The SVG is also rasterised when
librsvg's rsvg-convert is installed. Both layouts (symmetric and OpenCV's asymmetric grid)
are checked dot by dot, and `planarcal board` is run in process, its files parsed back.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from planarcal import cli
from planarcal.calib.board import LAYOUTS, CircleGridBoard, Layout
from planarcal.errors import BoardError
from planarcal.report.printable import (
    CHECK_BAR_MM,
    PAGE_SIZES,
    PT_PER_MM,
    PrintLayout,
    page_size,
    write_board,
)

SVG = "{http://www.w3.org/2000/svg}"
TOL = 1e-6  # mm

DEFAULT = CircleGridBoard()  # the paper's board: 14 x 10 dots, 10 mm, 20 mm apart
MARKED = CircleGridBoard(cols=7, rows=5, pitch=20.0, diameter=10.0, origin_marker=True)
SMALL = CircleGridBoard(cols=4, rows=3, pitch=8.0, diameter=4.0, origin_marker=True)
ODD = CircleGridBoard(cols=5, rows=4, pitch=12.7, diameter=6.35, origin_marker=True)
# OpenCV's asymmetric circle grid (its sample's 4 x 11): rows 15 mm apart, 30 mm along a row.
ASYMMETRIC = CircleGridBoard(
    cols=4, rows=11, pitch=15.0, diameter=10.0, origin_marker=True, layout="asymmetric"
)


# --------------------------------------------------------------------------- helpers


def svg_root(path: Path) -> ET.Element:
    return ET.parse(path).getroot()


def svg_circles(root: ET.Element) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Centres (N, 2) and radii (N,) of the dots, in document order."""
    circles = root.findall(f".//{SVG}g[@id='dots']/{SVG}circle")
    centres = np.array([[float(c.get("cx", "nan")), float(c.get("cy", "nan"))] for c in circles])
    radii = np.array([float(c.get("r", "nan")) for c in circles])
    ids = [c.get("id") for c in circles]
    assert ids == [f"dot-{k}" for k in range(len(circles))]
    return centres, radii


def svg_line(root: ET.Element, element_id: str) -> tuple[float, float, float, float, float]:
    line = root.find(f".//{SVG}line[@id='{element_id}']")
    assert line is not None, element_id
    return (
        float(line.get("x1", "nan")),
        float(line.get("y1", "nan")),
        float(line.get("x2", "nan")),
        float(line.get("y2", "nan")),
        float(line.get("stroke-width", "nan")),
    )


def all_text(root: ET.Element) -> str:
    return "\n".join("".join(t.itertext()) for t in root.iter(f"{SVG}text"))


def info_text(root: ET.Element) -> str:
    """The info block's lines joined by spaces: a sentence wrapped over lines reads whole."""
    return " ".join(
        "".join(t.itertext()) for t in root.iter(f"{SVG}text") if t.get("class") == "info"
    )


def pdf_parts(path: Path) -> tuple[bytes, list[float], str]:
    """(the whole file, the MediaBox, the inflated content stream), after checking the
    cross-reference table points at every object."""
    data = path.read_bytes()
    assert data.startswith(b"%PDF-1.")
    assert data.rstrip().endswith(b"%%EOF")
    startxref = int(re.findall(rb"startxref\s+(\d+)", data)[-1])
    assert data[startxref:].startswith(b"xref")
    table = data[startxref:].split(b"trailer")[0].split(b"\n")
    count = int(table[1].split()[1])
    for number in range(1, count):
        offset = int(table[2 + number].split()[0])
        assert data[offset:].startswith(f"{number} 0 obj".encode()), number
    match = re.search(rb"/MediaBox \[([^\]]*)\]", data)
    assert match is not None
    media_box = [float(v) for v in match.group(1).split()]
    stream = re.search(rb"/Length (\d+) /Filter /FlateDecode >>\nstream\n", data)
    assert stream is not None
    start = stream.end()
    raw = data[start : start + int(stream.group(1))]
    assert data[start + len(raw) :].startswith(b"\nendstream")
    return data, media_box, zlib.decompress(raw).decode("latin-1")


NUMBER = r"-?\d+(?:\.\d+)?"


def pdf_ctm(content: str) -> NDArray[np.float64]:
    """The content's one `cm` matrix, as a 3 x 3 mapping user space to points."""
    match = re.search(
        rf"q ({NUMBER}) ({NUMBER}) ({NUMBER}) ({NUMBER}) ({NUMBER}) ({NUMBER}) cm", content
    )
    assert match is not None
    a, b, c, d, e, f = (float(v) for v in match.groups())
    return np.array([[a, c, e], [b, d, f], [0.0, 0.0, 1.0]])


def pdf_circles(content: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Centres and radii (user space) of the filled four-arc paths, in drawing order: the
    centre is the middle of the arcs' end points and every end point must lie on the circle
    at a quarter turn from the last."""
    centres, radii = [], []
    for line in content.splitlines():
        if not line.endswith(" c h f"):
            continue
        values = [float(v) for v in re.findall(NUMBER, line)]
        assert len(values) == 2 + 4 * 6, line
        start = np.array(values[:2])
        ends = [np.array(values[2 + 6 * i + 4 : 2 + 6 * i + 6]) for i in range(4)]
        centre = (start + ends[1]) / 2
        r = float(np.linalg.norm(start - centre))
        for point in ends:
            assert abs(np.linalg.norm(point - centre) - r) < 1e-8
        np.testing.assert_allclose(ends[3], start, atol=1e-12)
        # The control points are the quarter circle's: kappa * r along the tangents.
        kappa = 4 * (np.sqrt(2) - 1) / 3
        np.testing.assert_allclose(values[2:4], [start[0], start[1] + kappa * r], atol=1e-8)
        centres.append(centre)
        radii.append(r)
    return np.array(centres), np.array(radii)


def pdf_lines(content: str) -> list[tuple[float, float, float, float, float]]:
    """(x1, y1, x2, y2, width) of every stroked segment, user space."""
    pattern = rf"^({NUMBER}) w ({NUMBER}) ({NUMBER}) m ({NUMBER}) ({NUMBER}) l S$"
    found = re.findall(pattern, content, re.MULTILINE)
    return [(float(x1), float(y1), float(x2), float(y2), float(w)) for w, x1, y1, x2, y2 in found]


def expected_centres(layout: PrintLayout) -> NDArray[np.float64]:
    offset = np.array(layout.field_offset_mm, dtype=np.float64)
    centres: NDArray[np.float64] = layout.board.world_points() + offset
    return centres


def inside(
    box: tuple[float, float, float, float], frame: tuple[float, float, float, float]
) -> bool:
    return (
        box[0] >= frame[0] - TOL
        and box[1] >= frame[1] - TOL
        and box[2] <= frame[2] + TOL
        and box[3] <= frame[3] + TOL
    )


def dark_blobs(gray: NDArray[np.uint8]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Darkness-weighted centroids (pixel centres at integer + 0.5) and areas in pixels of
    the dark connected regions."""
    mask = (gray < 128).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    darkness = (255.0 - gray.astype(np.float64)) / 255.0
    centroids, areas = [], []
    for i in range(1, n):
        x, y, w, h = stats[i, :4]
        pad = 2
        window = darkness[y - pad : y + h + pad, x - pad : x + w + pad]
        region = labels[y - pad : y + h + pad, x - pad : x + w + pad]
        # The region and its anti-aliased rim, but no neighbour.
        near = cv2.dilate((region == i).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        weights = window * near
        ys, xs = np.mgrid[y - pad : y + h + pad, x - pad : x + w + pad]
        total = weights.sum()
        centroids.append(
            [(weights * (xs + 0.5)).sum() / total, (weights * (ys + 0.5)).sum() / total]
        )
        areas.append(total)
    return np.array(centroids), np.array(areas)


def check_raster(gray: NDArray[np.uint8], layout: PrintLayout, px_per_mm: float) -> None:
    """The dots at their places and sizes, and the check bar's end ticks 100 mm apart."""
    w, h = layout.page_size_mm
    assert gray.shape == (round(h * px_per_mm), round(w * px_per_mm))
    centroids, areas = dark_blobs(gray)
    expected = expected_centres(layout) * px_per_mm
    assert isinstance(layout.board, CircleGridBoard)
    diameters = layout.board.dot_diameters()
    for k, (point, d) in enumerate(zip(expected, diameters, strict=True)):
        distance = np.linalg.norm(centroids - point, axis=1)
        j = int(np.argmin(distance))
        assert distance[j] / px_per_mm < 0.02, (k, distance[j] / px_per_mm)  # 20 micrometres
        measured_d = 2 * np.sqrt(areas[j] / np.pi) / px_per_mm
        assert abs(measured_d - d) < 0.03, (k, measured_d, d)
    # A row through the bar's ticks, 1 mm below the bar: 11 ticks, the end ones 100 mm apart.
    x0, yb = layout.bar_start_mm
    row = gray[round((yb + 1.0) * px_per_mm)].astype(np.float64)
    lo, hi = round((x0 - 5) * px_per_mm), round((x0 + CHECK_BAR_MM + 5) * px_per_mm)
    darkness = (255.0 - row[lo:hi]) / 255.0
    runs, current = [], []
    for i, v in enumerate(darkness):
        if v > 0.05:
            current.append(i)
        elif current:
            runs.append(current)
            current = []
    assert len(runs) == 11, len(runs)
    centres = [
        lo + sum((i + 0.5) * darkness[i] for i in run) / sum(darkness[i] for i in run)
        for run in runs
    ]
    spacing = np.diff(centres) / px_per_mm
    np.testing.assert_allclose(spacing, 10.0, atol=0.05)
    assert abs((centres[-1] - centres[0]) / px_per_mm - CHECK_BAR_MM) < 0.05
    assert abs(centres[0] / px_per_mm - x0) < 0.05


# --------------------------------------------------------------------------- page sizes


def test_page_sizes_and_parser() -> None:
    for name in ("A4", "A3", "A2", "A1", "A0", "letter", "legal", "tabloid"):
        assert name in PAGE_SIZES
    assert page_size("A4") == (210.0, 297.0)
    assert page_size("a4") == page_size(" A4 ") == (210.0, 297.0)
    assert page_size("LETTER") == page_size("Letter") == (215.9, 279.4)
    assert page_size("tabloid") == (279.4, 431.8)
    assert page_size("300x400") == (300.0, 400.0)
    assert page_size("400 X 300 mm") == (400.0, 300.0)
    assert page_size("297.5\u00d7420") == (297.5, 420.0)
    for bad in ("A9", "", "300x", "x400", "0x400", "300x400x5", "-300x400", "1e3x400"):
        with pytest.raises(ValueError, match="page"):
            page_size(bad)


# --------------------------------------------------------------------------- SVG, exactly


@pytest.mark.parametrize(
    "board", [MARKED, DEFAULT, ODD, ASYMMETRIC], ids=["marked", "default", "odd", "asymmetric"]
)
def test_svg_is_exact(tmp_path: Path, board: CircleGridBoard) -> None:
    page = "A3" if board is DEFAULT else "A4"
    layout = write_board(board, tmp_path / "board.svg", page=page)
    assert layout.format == "svg" and layout.path == tmp_path / "board.svg"
    root = svg_root(layout.path)
    w, h = layout.page_size_mm
    assert sorted((w, h)) == sorted(PAGE_SIZES[page])
    assert root.get("width") == f"{w:g}mm" and root.get("height") == f"{h:g}mm"
    assert [float(v) for v in root.get("viewBox", "").split()] == [0.0, 0.0, w, h]

    # Every dot: exact centre and radius, in world order.
    centres, radii = svg_circles(root)
    assert len(centres) == board.n_points
    np.testing.assert_allclose(centres, expected_centres(layout), rtol=0, atol=TOL)
    np.testing.assert_allclose(radii, board.dot_diameters() / 2, rtol=0, atol=TOL)
    np.testing.assert_allclose(layout.to_page(board.world_points()), expected_centres(layout))
    # The dot field is centred on the page.
    span = board.world_points().max(axis=0)
    np.testing.assert_allclose(
        np.array(layout.field_offset_mm) + span / 2, [w / 2, h / 2], atol=TOL
    )
    ex, ey = board.extent
    fx0, fy0, fx1, fy1 = layout.field_box_mm
    assert abs((fx1 - fx0) - ex) < TOL and abs((fy1 - fy0) - ey) < TOL
    assert abs((fx0 + fx1) / 2 - w / 2) < TOL and abs((fy0 + fy1) / 2 - h / 2) < TOL

    # The check bar: 100 mm from its 0 tick to its 100 tick, ticks every 10 mm.
    x1, y1, x2, y2, _ = svg_line(root, "bar")
    assert abs(x2 - x1 - 100.0) < TOL and y1 == y2
    assert abs(x1 - layout.bar_start_mm[0]) < TOL and abs(y1 - layout.bar_start_mm[1]) < TOL
    assert abs(layout.bar_length_mm - 100.0) < TOL
    ticks = [svg_line(root, f"tick-{i}") for i in range(11)]
    np.testing.assert_allclose([t[0] for t in ticks], x1 + 10.0 * np.arange(11), atol=TOL)
    assert all(t[0] == t[2] and t[1] == y1 for t in ticks)
    labels = [root.find(f".//{SVG}text[@id='tick-label-{i}']") for i in range(11)]
    assert [lab.text if lab is not None else None for lab in labels] == [
        *(str(10 * i) for i in range(10)),
        "100 mm",
    ]

    # Everything inside the margins, nothing over the dots.
    usable = layout.usable_box_mm
    assert inside(layout.content_box_mm, usable)
    assert inside(layout.field_box_mm, usable) and inside(layout.text_box_mm, usable)
    for circle in root.iter(f"{SVG}circle"):
        cx, cy, r = (float(circle.get(a, "nan")) for a in ("cx", "cy", "r"))
        assert inside((cx - r, cy - r, cx + r, cy + r), usable)
    for line in root.iter(f"{SVG}line"):
        lx1, ly1, lx2, ly2 = (float(line.get(a, "nan")) for a in ("x1", "y1", "x2", "y2"))
        half = float(line.get("stroke-width", "nan")) / 2
        assert inside(
            (
                min(lx1, lx2) - half,
                min(ly1, ly2) - half,
                max(lx1, lx2) + half,
                max(ly1, ly2) + half,
            ),
            usable,
        )
    for polygon in root.iter(f"{SVG}polygon"):
        xy = np.array([[float(v) for v in p.split(",")] for p in polygon.get("points", "").split()])
        assert inside((*xy.min(axis=0), *xy.max(axis=0)), usable)
        assert polygon.get("stroke") is None  # arrowheads are filled, not stroked
    for element in root.iter(f"{SVG}text"):
        x, y = float(element.get("x", "nan")), float(element.get("y", "nan"))
        assert inside((x, y, x, y), usable)
    bar_box = (x1, y1, x2, y1 + 3.5)
    assert not _overlap(bar_box, layout.field_box_mm)
    assert not _overlap(layout.text_box_mm, layout.field_box_mm)
    assert not _overlap(layout.text_box_mm, bar_box)

    # The text says what the board is and how to print it.
    text = all_text(root)
    assert f"{board.cols} x {board.rows} dots" in text
    assert f"dots {board.dots_mm():g} mm, pitch {board.pitch:g} mm" in text
    assert f"page {page} {layout.orientation} ({w:g} x {h:g} mm)" in text
    assert "100%" in text and "ACTUAL SIZE" in text and "100 mm" in text
    assert ("origin: the" in text) == board.origin_marker
    assert f"{board.layout} grid:" in text
    if board.layout == "asymmetric":
        pitch, along = board.pitch, 2 * board.pitch
        assert f"rows {pitch:g} mm apart, dots {along:g} mm apart along a row" in info_text(root)


def _overlap(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def test_axes_show_origin_and_directions(tmp_path: Path) -> None:
    layout = write_board(MARKED, tmp_path / "board.svg")
    root = svg_root(layout.path)
    ox, oy = layout.field_offset_mm
    fx0, fy0, _, _ = layout.field_box_mm

    def points(element_id: str) -> NDArray[np.float64]:
        polygon = root.find(f".//{SVG}polygon[@id='{element_id}']")
        assert polygon is not None
        return np.array(
            [[float(v) for v in p.split(",")] for p in polygon.get("points", "").split()]
        )

    # The X arrow points right above the field, the Y arrow down left of it.
    x_tip = points("x-arrow")[0]
    y_tip = points("y-arrow")[0]
    assert x_tip[0] > ox and x_tip[1] < fy0
    assert y_tip[1] > oy and y_tip[0] < fx0
    # The origin's ticks sit on dot 0's centre lines, outside the field.
    tx1, ty1, tx2, ty2, _ = svg_line(root, "origin-x-tick")
    assert tx1 == tx2 == pytest.approx(ox, abs=TOL) and max(ty1, ty2) < fy0
    tx1, ty1, tx2, ty2, _ = svg_line(root, "origin-y-tick")
    assert ty1 == ty2 == pytest.approx(oy, abs=TOL) and max(tx1, tx2) < fx0
    labels = {t.get("id"): "".join(t.itertext()) for t in root.iter(f"{SVG}text")}
    assert labels["x-label"] == "X" and labels["y-label"] == "Y"
    assert "origin" in labels["origin-label"]


def test_origin_marker(tmp_path: Path) -> None:
    board = CircleGridBoard(
        cols=5, rows=4, pitch=20.0, diameter=8.0, origin_marker=True, marker_diameter=14.0
    )
    layout = write_board(board, tmp_path / "board.svg")
    _, radii = svg_circles(svg_root(layout.path))
    assert radii[0] == 7.0 and np.all(radii[1:] == 4.0)
    assert "the 14 mm dot" in all_text(svg_root(layout.path))
    # The field box uses the marker's size on every side, as board.extent does.
    fx0, fy0, fx1, fy1 = layout.field_box_mm
    assert (fx1 - fx0, fy1 - fy0) == pytest.approx(board.extent, abs=TOL)
    plain = write_board(
        CircleGridBoard(cols=5, rows=4, pitch=20.0, diameter=8.0), tmp_path / "plain.svg"
    )
    _, radii = svg_circles(svg_root(plain.path))
    assert np.all(radii == 4.0)


@pytest.mark.parametrize("grid", LAYOUTS)
def test_marker_as_large_as_the_neighbour_distance(tmp_path: Path, grid: Layout) -> None:
    spacing = CircleGridBoard(pitch=20.0, layout=grid).neighbour_distance
    board = CircleGridBoard(
        cols=5,
        rows=4,
        pitch=20.0,
        diameter=8.0,
        origin_marker=True,
        marker_diameter=spacing,
        layout=grid,
    )
    printed = write_board(board, tmp_path / "board.svg")
    root = svg_root(printed.path)
    centres, radii = svg_circles(root)
    np.testing.assert_allclose(centres, expected_centres(printed), rtol=0, atol=TOL)
    np.testing.assert_allclose(radii, board.dot_diameters() / 2, rtol=0, atol=TOL)
    assert radii[0] == pytest.approx(spacing / 2, abs=TOL)
    # The marker stays clear of every other dot.
    gaps = np.linalg.norm(centres[1:] - centres[0], axis=1) - radii[0] - radii[1:]
    assert gaps.min() > 1.0
    # The field reaches the marker's radius past the outer centres, on every side (as
    # board.extent does), and everything stays inside the margins, the text off the field.
    fx0, fy0, fx1, fy1 = printed.field_box_mm
    assert (fx1 - fx0, fy1 - fy0) == pytest.approx(board.extent, abs=TOL)
    assert (fx0, fy0) == pytest.approx(tuple(centres[0] - spacing / 2), abs=TOL)
    assert inside(printed.content_box_mm, printed.usable_box_mm)
    assert not _overlap(printed.text_box_mm, printed.field_box_mm)
    assert f"origin: the {spacing:.10g} mm dot" in info_text(root)


def test_unstated_diameter_prints_dots_half_the_neighbour_distance(tmp_path: Path) -> None:
    # No diameter is no statement: the board prints as `planarcal board` would without
    # --diameter, dots as wide as the gaps between them.
    unstated = CircleGridBoard(cols=5, rows=4, pitch=24.0)
    stated = dataclasses.replace(unstated, diameter=12.0)
    write_board(unstated, tmp_path / "unstated.svg")
    write_board(stated, tmp_path / "stated.svg")
    radii = [
        svg_circles(ET.parse(tmp_path / n).getroot())[1] for n in ("unstated.svg", "stated.svg")
    ]
    assert np.allclose(radii[0], 6.0) and np.array_equal(radii[0], radii[1])


# --------------------------------------------------------------------------- PDF


@pytest.mark.parametrize("board", [MARKED, ODD, ASYMMETRIC], ids=["marked", "odd", "asymmetric"])
def test_pdf_is_exact(tmp_path: Path, board: CircleGridBoard) -> None:
    layout = write_board(board, tmp_path / "board.pdf", page="letter", orientation="portrait")
    assert layout.format == "pdf" and layout.orientation == "portrait"
    assert layout.page_size_mm == (215.9, 279.4)
    data, media_box, content = pdf_parts(layout.path)
    w, h = layout.page_size_mm
    np.testing.assert_allclose(media_box, [0, 0, w * 72 / 25.4, h * 72 / 25.4], rtol=0, atol=1e-6)
    np.testing.assert_allclose(layout.page_size_pt, media_box[2:], rtol=0, atol=1e-6)
    assert b"/PrintScaling /None" in data

    # One matrix takes mm (y down from the top) to points (y up from the bottom).
    ctm = pdf_ctm(content)
    np.testing.assert_allclose(
        ctm,
        np.array([[PT_PER_MM, 0, 0], [0, -PT_PER_MM, h * PT_PER_MM], [0, 0, 1]]),
        rtol=1e-12,
        atol=1e-6,
    )

    centres, radii = pdf_circles(content)
    assert len(centres) == board.n_points
    np.testing.assert_allclose(centres, expected_centres(layout), rtol=0, atol=TOL)
    np.testing.assert_allclose(radii, board.dot_diameters() / 2, rtol=0, atol=TOL)
    # In points on the page: (x, h - y) * 72 / 25.4.
    in_pt = (ctm @ np.column_stack([centres, np.ones(len(centres))]).T).T[:, :2]
    want = expected_centres(layout)
    want_pt = np.column_stack([want[:, 0] * 72 / 25.4, (h - want[:, 1]) * 72 / 25.4])
    np.testing.assert_allclose(in_pt, want_pt, rtol=0, atol=TOL * PT_PER_MM)

    # The bar: the one 0.3 mm segment 100 mm long where the layout says; ticks 10 mm apart.
    lines = pdf_lines(content)
    bars = [ln for ln in lines if abs(ln[2] - ln[0] - 100.0) < TOL and ln[1] == ln[3]]
    assert len(bars) == 1
    x1, y1, _, _, width = bars[0]
    assert width == 0.3
    assert (x1, y1) == pytest.approx(layout.bar_start_mm, abs=TOL)
    ticks = sorted(
        ln[0] for ln in lines if ln[4] == 0.2 and ln[0] == ln[2] and abs(ln[1] - y1) < TOL
    )
    np.testing.assert_allclose(ticks, x1 + 10.0 * np.arange(11), atol=TOL)

    # The text, in the standard Courier fonts.
    assert b"/BaseFont /Courier" in data
    shown = " ".join(re.findall(r"\((.*?)\) Tj", content))
    assert (
        f"{board.cols} x {board.rows} dots" in shown and "ACTUAL SIZE" in shown and "100%" in shown
    )

    # The same drawing as the SVG: same shapes, same places.
    svg = write_board(board, tmp_path / "board.svg", page="letter", orientation="portrait")
    assert svg.field_offset_mm == layout.field_offset_mm and svg.bar_start_mm == layout.bar_start_mm
    svg_centres, _ = svg_circles(svg_root(svg.path))
    np.testing.assert_allclose(svg_centres, centres, rtol=0, atol=TOL)


def test_pdf_rasterised_scale(tmp_path: Path) -> None:
    if shutil.which("pdftoppm") is None:
        pytest.skip("pdftoppm (poppler-utils) is not installed: the PDF is not rasterised")
    dpi = 254  # 10 pixels per mm
    layout = write_board(SMALL, tmp_path / "board.pdf", page="A5")
    subprocess.run(
        [
            "pdftoppm",
            "-r",
            str(dpi),
            "-gray",
            "-png",
            "-singlefile",
            str(layout.path),
            str(tmp_path / "page"),
        ],
        check=True,
        timeout=60,
    )
    image = cv2.imread(str(tmp_path / "page.png"), cv2.IMREAD_GRAYSCALE)
    assert image is not None
    check_raster(np.asarray(image, dtype=np.uint8), layout, dpi / 25.4)


def test_svg_rasterised_scale(tmp_path: Path) -> None:
    if shutil.which("rsvg-convert") is None:
        pytest.skip("rsvg-convert (librsvg) is not installed: the SVG is not rasterised")
    dpi = 254
    layout = write_board(SMALL, tmp_path / "board.svg", page="A5")
    subprocess.run(
        [
            "rsvg-convert",
            "-d",
            str(dpi),
            "-p",
            str(dpi),
            "-b",
            "white",
            "-o",
            str(tmp_path / "page.png"),
            str(layout.path),
        ],
        check=True,
        timeout=60,
    )
    image = cv2.imread(str(tmp_path / "page.png"), cv2.IMREAD_GRAYSCALE)
    assert image is not None
    check_raster(np.asarray(image, dtype=np.uint8), layout, dpi / 25.4)


# --------------------------------------------------------------------------- fitting


def test_board_that_does_not_fit_is_refused(tmp_path: Path) -> None:
    target = tmp_path / "board.pdf"
    with pytest.raises(BoardError) as caught:
        write_board(DEFAULT, target, page="A4")
    message = str(caught.value)
    assert "270 x 190 mm" in message  # the dots' extent
    assert "190 x 277 mm" in message and "277 x 190 mm" in message  # A4's usable sizes
    assert "either orientation" in message
    assert "smallest ISO A page that fits is A3, in landscape" in message  # A4's family
    assert "tabloid, in landscape, is the smallest standard page" in message
    assert not target.exists() and list(tmp_path.iterdir()) == []
    with pytest.raises(BoardError, match="smallest that fits is tabloid, in landscape"):
        write_board(DEFAULT, target, page="letter")
    # The suggestion is right: A3 holds it, with a 10 mm margin.
    layout = write_board(DEFAULT, target, page="A3")
    assert layout.orientation == "landscape"


def test_refusal_beyond_a0_suggests_a_custom_page(tmp_path: Path) -> None:
    board = CircleGridBoard(cols=50, rows=40, pitch=25.0, diameter=12.0)
    with pytest.raises(BoardError) as caught:
        write_board(board, tmp_path / "big.svg", page="A0")
    match = re.search(r"custom page of at least (\d+x\d+) mm", str(caught.value))
    assert match is not None, str(caught.value)
    layout = write_board(board, tmp_path / "big.svg", page=match.group(1))
    assert inside(layout.content_box_mm, layout.usable_box_mm)


def test_fixed_orientation_that_does_not_fit(tmp_path: Path) -> None:
    wide = CircleGridBoard(cols=12, rows=3, pitch=20.0, diameter=10.0)
    with pytest.raises(BoardError, match="fits in landscape"):
        write_board(wide, tmp_path / "b.svg", page="A4", orientation="portrait")
    layout = write_board(wide, tmp_path / "b.svg", page="A4", orientation="landscape")
    assert layout.page_size_mm == (297.0, 210.0)


def test_auto_orientation(tmp_path: Path) -> None:
    wide = CircleGridBoard(cols=10, rows=4, pitch=20.0, diameter=10.0)
    tall = CircleGridBoard(cols=4, rows=10, pitch=20.0, diameter=10.0)
    square = CircleGridBoard(cols=4, rows=4, pitch=20.0, diameter=10.0)
    assert write_board(wide, tmp_path / "w.svg").orientation == "landscape"
    assert write_board(tall, tmp_path / "t.svg").orientation == "portrait"
    assert write_board(square, tmp_path / "s.svg").orientation == "portrait"  # a tie
    layout = write_board(wide, tmp_path / "w.svg")
    assert layout.page_size_mm == (297.0, 210.0)
    # Both fit for the small board: each orientation when asked.
    portrait = write_board(square, tmp_path / "p.svg", orientation="portrait")
    landscape = write_board(square, tmp_path / "l.svg", orientation="landscape")
    assert portrait.page_size_mm == (210.0, 297.0) and landscape.page_size_mm == (297.0, 210.0)
    # Only landscape fits the paper's board on A3.
    assert write_board(DEFAULT, tmp_path / "d.svg", page="A3").orientation == "landscape"


def test_custom_pages_and_margins(tmp_path: Path) -> None:
    layout = write_board(MARKED, tmp_path / "c.svg", page="300x400", orientation="portrait")
    assert layout.page == "300x400" and layout.page_size_mm == (300.0, 400.0)
    # Custom pages turn like standard ones: this wide board has more room in landscape.
    assert write_board(MARKED, tmp_path / "a.svg", page="300x400").page_size_mm == (400.0, 300.0)
    root = svg_root(layout.path)
    assert root.get("width") == "300mm" and root.get("height") == "400mm"
    same = write_board(MARKED, tmp_path / "t.svg", page=(300, 400), orientation="portrait")
    assert (
        same.page_size_mm == layout.page_size_mm and same.field_offset_mm == layout.field_offset_mm
    )
    turned = write_board(MARKED, tmp_path / "l.pdf", page="400x300", orientation="landscape")
    _, media_box, _ = pdf_parts(turned.path)
    np.testing.assert_allclose(media_box[2:], [400 * 72 / 25.4, 300 * 72 / 25.4], atol=1e-6)
    # A wide margin is kept clear; one too wide leaves no room.
    wide_margin = write_board(MARKED, tmp_path / "m.svg", page="A3", margin_mm=40.0)
    assert wide_margin.usable_box_mm[0] == 40.0
    assert inside(wide_margin.content_box_mm, wide_margin.usable_box_mm)
    with pytest.raises(BoardError, match="inside 70 mm margins"):
        write_board(MARKED, tmp_path / "m.svg", page="A4", margin_mm=70.0)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="margin"):
            write_board(MARKED, tmp_path / "m.svg", margin_mm=bad)
    with pytest.raises(ValueError, match="orientation"):
        write_board(MARKED, tmp_path / "m.svg", orientation="sideways")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="unknown page"):
        write_board(MARKED, tmp_path / "m.svg", page="B9")


@pytest.mark.parametrize("page", ["A5", "A4", "letter", "legal", "A3", "tabloid"])
def test_everything_inside_the_margins(tmp_path: Path, page: str) -> None:
    boards = [SMALL, MARKED, ODD, CircleGridBoard(cols=3, rows=12, pitch=15.0, diameter=7.0)]
    for board in boards:
        for orientation in ("portrait", "landscape"):
            try:
                layout = write_board(board, tmp_path / "b.svg", page=page, orientation=orientation)
            except BoardError:
                continue
            assert inside(layout.content_box_mm, layout.usable_box_mm), (page, board, orientation)
            centres, _ = svg_circles(svg_root(layout.path))
            np.testing.assert_allclose(centres, expected_centres(layout), rtol=0, atol=TOL)


# --------------------------------------------------------------------------- files


def test_bad_suffix(tmp_path: Path) -> None:
    for name in ("board.png", "board", "board.svg.txt"):
        with pytest.raises(ValueError, match=r"\.svg or \.pdf"):
            write_board(MARKED, tmp_path / name)
    assert list(tmp_path.iterdir()) == []
    assert write_board(MARKED, tmp_path / "BOARD.SVG").format == "svg"
    assert write_board(MARKED, str(tmp_path / "board.Pdf")).format == "pdf"


def test_replaces_an_existing_file(tmp_path: Path) -> None:
    target = tmp_path / "board.svg"
    target.write_text("old")
    write_board(MARKED, target)
    first = target.read_bytes()
    assert first.startswith(b"<?xml")
    write_board(SMALL, target, page="A5")
    assert target.read_bytes() != first
    assert len(svg_circles(svg_root(target))[0]) == SMALL.n_points
    assert [p.name for p in tmp_path.iterdir()] == ["board.svg"]
    # A plain open() would give these permissions.
    umask = os.umask(0o022)
    os.umask(umask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask


def test_failed_write_leaves_the_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "board.pdf"
    target.write_bytes(b"old board")

    def refuse(src: object, dst: object) -> None:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(PermissionError, match=r"board\.pdf"):
        write_board(MARKED, target)
    assert target.read_bytes() == b"old board"
    assert [p.name for p in tmp_path.iterdir()] == ["board.pdf"]


def test_unwritable_paths(tmp_path: Path) -> None:
    missing = tmp_path / "no" / "such" / "dir" / "board.svg"
    with pytest.raises(FileNotFoundError, match=r"board\.svg") as caught:
        write_board(MARKED, missing)
    assert caught.value.filename == str(missing)
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    with pytest.raises(OSError, match=r"board\.pdf"):
        write_board(MARKED, a_file / "board.pdf")
    # A directory where the file should go: nothing is left behind.
    (tmp_path / "taken.svg").mkdir()
    with pytest.raises(OSError, match=r"taken\.svg"):
        write_board(MARKED, tmp_path / "taken.svg")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "taken.svg"]


_WRITE_INTO = """
import sys
from planarcal.calib.board import CircleGridBoard
from planarcal.report.printable import write_board
try:
    write_board(CircleGridBoard(cols=7, rows=5, origin_marker=True), sys.argv[1])
except PermissionError as e:
    print(e)
    sys.exit(3)
"""


def test_read_only_directory(tmp_path: Path) -> None:
    directory = tmp_path / "ro"
    directory.mkdir()
    target = directory / "board.svg"
    directory.chmod(0o555)
    try:
        if os.geteuid() != 0:
            with pytest.raises(PermissionError, match=r"ro/board\.svg") as caught:
                write_board(MARKED, target)
            assert caught.value.filename == str(target)
        else:
            # Root writes anywhere; without CAP_DAC_OVERRIDE it is held to the permissions.
            setpriv = shutil.which("setpriv")
            if setpriv is None:
                pytest.skip("running as root without setpriv: cannot make a directory read-only")
            result = subprocess.run(
                [
                    setpriv,
                    "--bounding-set=-dac_override,-dac_read_search",
                    "--",
                    *(sys.executable, "-c", _WRITE_INTO, str(target)),
                ],
                capture_output=True,
                text=True,
                timeout=60,
            )
            assert result.returncode == 3, result.stdout + result.stderr
            assert "Permission denied" in result.stdout and str(target) in result.stdout
        assert list(directory.iterdir()) == []
    finally:
        directory.chmod(0o755)


# --------------------------------------------------------------------------- the command line


def run_board_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, *options: str
) -> tuple[Path, str]:
    """`planarcal board OPTIONS -o tmp_path/name`, in process: (the file, what it printed)."""
    out = tmp_path / name
    assert cli.main(["board", *options, "-o", str(out)]) == 0
    return out, capsys.readouterr().out


def test_board_command_prints_an_origin_marker_by_default(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, printed = run_board_command(tmp_path, capsys, "board.svg", "--cols", "5", "--rows", "4")
    root = svg_root(out)
    centres, radii = svg_circles(root)
    # The default dots are half the 20 mm pitch, the marker 1.5 times that.
    board = CircleGridBoard(cols=5, rows=4, pitch=20.0, diameter=10.0, origin_marker=True)
    np.testing.assert_allclose(centres - centres[0], board.world_points(), rtol=0, atol=TOL)
    np.testing.assert_allclose(radii, board.dot_diameters() / 2, rtol=0, atol=TOL)
    assert radii[0] == 7.5 and np.all(radii[1:] == 5.0)
    assert "origin: the 15 mm dot" in info_text(root)
    assert "origin marker" in printed
    # --origin-marker is still accepted, and asks for what is the default: the same page.
    again, _ = run_board_command(
        tmp_path, capsys, "again.svg", "--cols", "5", "--rows", "4", "--origin-marker"
    )
    assert again.read_bytes() == out.read_bytes()


def test_board_command_without_origin_marker(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, printed = run_board_command(
        tmp_path, capsys, "board.pdf", "--cols", "5", "--rows", "4", "--no-origin-marker"
    )
    _, _, content = pdf_parts(out)
    centres, radii = pdf_circles(content)
    board = CircleGridBoard(cols=5, rows=4, pitch=20.0, diameter=10.0)
    np.testing.assert_allclose(centres - centres[0], board.world_points(), rtol=0, atol=TOL)
    np.testing.assert_allclose(radii, 5.0, rtol=0, atol=TOL)
    shown = " ".join(re.findall(r"\((.*?)\) Tj", content))
    assert "origin: dot 0, top left" in shown and "origin: the" not in shown
    assert "origin marker" not in printed
    # Both at once is a malformed command line.
    with pytest.raises(SystemExit) as caught:
        cli.main(["board", "--origin-marker", "--no-origin-marker", "-o", str(out)])
    assert caught.value.code == 2


def test_board_command_marker_as_large_as_the_pitch(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    options = ("--cols", "5", "--rows", "4", "--diameter", "8")
    out, _ = run_board_command(tmp_path, capsys, "board.pdf", *options, "--marker-diameter", "20")
    _, _, content = pdf_parts(out)
    centres, radii = pdf_circles(content)
    board = CircleGridBoard(
        cols=5, rows=4, pitch=20.0, diameter=8.0, origin_marker=True, marker_diameter=20.0
    )
    np.testing.assert_allclose(centres - centres[0], board.world_points(), rtol=0, atol=TOL)
    np.testing.assert_allclose(radii, board.dot_diameters() / 2, rtol=0, atol=TOL)
    assert radii[0] == pytest.approx(10.0, abs=TOL)
    # Larger than the distance to its neighbours: refused in one line, nothing written.
    refused = tmp_path / "refused.pdf"
    code = cli.main(["board", *options, "--marker-diameter", "20.5", "-o", str(refused)])
    assert code == 2 and not refused.exists()  # a board that cannot be: a malformed command
    assert "at most the distance to its neighbours" in capsys.readouterr().err


def test_board_command_asymmetric_layout(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    options = ("--layout", "asymmetric", "--cols", "4", "--rows", "11", "--pitch", "15")
    out, printed = run_board_command(tmp_path, capsys, "board.pdf", *options, "--diameter", "10")
    data, media_box, content = pdf_parts(out)
    board = CircleGridBoard(
        cols=4, rows=11, pitch=15.0, diameter=10.0, origin_marker=True, layout="asymmetric"
    )
    # OpenCV's asymmetric grid exactly: dot (c, r) at ((2 c + r % 2) * 15, r * 15) mm.
    centres, radii = pdf_circles(content)
    np.testing.assert_allclose(centres - centres[0], board.world_points(), rtol=0, atol=TOL)
    np.testing.assert_allclose(radii, board.dot_diameters() / 2, rtol=0, atol=TOL)
    # The dot field centred on the page, the check bar below it, 100 mm.
    page_mm = np.array(media_box[2:]) / PT_PER_MM
    field_centre = centres[0] + board.world_points().max(axis=0) / 2
    np.testing.assert_allclose(field_centre, page_mm / 2, rtol=0, atol=TOL)
    bars = [ln for ln in pdf_lines(content) if abs(ln[2] - ln[0] - 100.0) < TOL and ln[1] == ln[3]]
    assert len(bars) == 1 and bars[0][1] > centres[:, 1].max()
    # The page and the command say the layout and what the pitch measures in it.
    shown = " ".join(re.findall(r"\((.*?)\) Tj", content))
    assert "asymmetric grid: rows 15 mm apart, dots 30 mm apart along a row" in shown
    assert "rows 15 mm apart, dots 30 mm apart along a row" in printed
    assert b"asymmetric grid" in data  # the document's title: board.describe()

    # The page is chosen by the real extent: 7 dots along a row span 13 pitches (281 mm with
    # the marker), too wide for A4, where the symmetric grid's 6 pitches fit.
    wide, printed = run_board_command(
        tmp_path, capsys, "wide.svg", "--layout", "asymmetric", "--cols", "7", "--rows", "5"
    )
    assert "on A3 landscape" in printed
    centres, _ = svg_circles(svg_root(wide))
    wide_grid = CircleGridBoard(cols=7, rows=5, diameter=None, layout="asymmetric")
    np.testing.assert_allclose(centres - centres[0], wide_grid.world_points(), rtol=0, atol=TOL)
    _, printed = run_board_command(tmp_path, capsys, "square.svg", "--cols", "7", "--rows", "5")
    assert "on A4 " in printed


@pytest.mark.parametrize(
    ("options", "diameter"),
    [
        ((), 10.0),
        (("--pitch", "30"), 15.0),
        (("--layout", "asymmetric", "--pitch", "10"), 10.0 * np.sqrt(2.0) / 2),
        (("--diameter", "6"), 6.0),
    ],
    ids=["paper", "pitch-30", "asymmetric", "given"],
)
def test_board_command_diameter_default(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    options: tuple[str, ...],
    diameter: float,
) -> None:
    out, printed = run_board_command(
        tmp_path, capsys, "board.svg", "--cols", "5", "--rows", "4", "--no-origin-marker", *options
    )
    _, radii = svg_circles(svg_root(out))
    np.testing.assert_allclose(radii, diameter / 2, rtol=0, atol=TOL)
    defaulted = "--diameter" not in options
    assert ("half the distance between neighbouring dots" in printed) == defaulted
    if defaulted:
        assert f"Dot diameter {diameter:g} mm" in printed


def test_board_command_help_states_the_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as caught:
        cli.main(["board", "--help"])
    assert caught.value.code == 0
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps the help
    assert "--diameter DIAMETER dot diameter (default: half the distance between" in text
    assert "--no-origin-marker" in text and "--layout {symmetric,asymmetric}" in text
