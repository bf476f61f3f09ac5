"""`planarcal live`'s page in a real headless Chromium (selenium), end to end as the issue
says: from the rendered cell video, the page shows the board, three placements are captured
by clicking, calibration is run and saved, a registration is entered by clicking dots and
typing coordinates, and the parts appear with their coordinates. Skipped where Chromium or
its driver is not installed (nothing is downloaded at test time)."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from live_server import (
    VIDEO_BOARD_ARGS,
    LivePage,
    LiveServer,
    browser_missing,
    cell_video,
    live_server,
    robot_of,
)

from planarcal.calib.calibration import Calibration
from planarcal.synth.live_video import LiveVideo

pytest.importorskip("starlette", reason="the live page needs the extra planarcal[live]")
_missing = browser_missing()
if _missing:
    pytest.skip(_missing, allow_module_level=True)

# Corners and the middle of the 9 x 7 board: a fit that is not near one line.
TOUCHED = (0, 8, 54, 62, 31)
NONE = "\u2013"  # the page's dash for no value (a round part's angle)


@pytest.fixture(scope="module")
def video(tmp_path_factory: pytest.TempPathFactory) -> LiveVideo:
    return cell_video(tmp_path_factory.mktemp("browser-video"))


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("browser-cell")


@pytest.fixture(scope="module")
def server(video: LiveVideo, folder: Path) -> Iterator[LiveServer]:
    args = ["--source", str(video.path), "--calibration", "cell.json", *VIDEO_BOARD_ARGS]
    with live_server(args, folder) as running:
        yield running


@pytest.fixture(scope="module")
def page(server: LiveServer, video: LiveVideo) -> Iterator[LivePage]:
    browser = LivePage(server, video)
    try:
        yield browser
    finally:
        browser.quit()


def _numbers(text: str) -> list[float]:
    return [float(n) for n in re.findall(r"-?\d+(?:\.\d+)?", text)]


def test_1_the_page_shows_the_live_image_and_the_board(page: LivePage) -> None:
    page.open()
    assert page.natural_width("live") == 1280
    assert page.by_id("tab-setup").get_attribute("aria-selected") == "true"
    assert re.search(r"Found: \d+ of 63 dots", page.text("detection")), page.text("detection")


def test_2_three_placements_are_captured_by_clicking(page: LivePage, video: LiveVideo) -> None:
    page.capture_all()
    rows = page.css("#placements li[data-index]")
    assert [row.find_element("css selector", ".placement-name").text for row in rows] == [
        f"placement-{k}.png" for k in (1, 2, 3)
    ]
    assert all("63 points" in row.text for row in rows)
    # Each captured where the board was held (not on its way): its outline's corners are
    # dots where the video holds the board.
    placements = page.server.ok("GET", "/api/state")["placements"]
    for k, held in enumerate(video.placements):
        for corner in placements[k]["outline_px"]:
            nearest = np.min(np.hypot(*(held.points_px - corner).T))
            assert nearest < 1.0, (k, corner, nearest)
    assert page.natural_width("coverage") > 0
    assert "mm" in page.text("coverage-text")


def test_3_calibrate_and_save_write_the_file(page: LivePage, folder: Path) -> None:
    page.calibrate()
    assert "Placements: 3" in page.text("summary")
    assert len(page.css("#figures img")) >= 3
    page.save(folder / "cell.json")
    loaded = Calibration.load(folder / "cell.json")
    assert loaded.robot_frame is None
    assert page.message() == ""


def test_4_a_registration_is_entered_by_clicking_dots(
    page: LivePage, video: LiveVideo, folder: Path
) -> None:
    page.tab("register")
    board = video.board.world_points()
    for point in TOUCHED:
        picked = page.pick(point)
        # The page names the dot clicked, and where it found it: within a pixel or two of
        # the truth (the click is at whole CSS pixels of a scaled image).
        assert f"dot {point}" in picked["text"], picked
        truth = video.placements[picked["placement"]].points_px[point]
        image_px = _numbers(picked["text"].split("image")[1])[:2]
        assert math.dist(image_px, truth) < 3.0, (image_px, truth)
        page.touch(point, robot_of(board[point].tolist()))
    rows = page.rows("touches")
    assert sorted(int(row["id"]) for row in rows) == sorted(TOUCHED)
    for row in rows:  # id, the robot's x, y, z as typed, image px, residual mm
        point = int(row["cells"][0])
        assert _numbers(row["cells"][1]) == pytest.approx(robot_of(board[point].tolist()))
        assert abs(float(row["cells"][3])) < 0.1, row
    quality = page.text("registration")
    assert re.search(r"Quality: (excellent|good)", quality), quality
    assert "Outliers" not in quality
    page.register(folder / "cell.json")
    registered = Calibration.load(folder / "cell.json")
    assert registered.robot_frame is not None
    got = registered.robot_frame.to_robot(board[20][None])[0]
    assert got[:2] == pytest.approx(robot_of(board[20].tolist())[:2], abs=0.05)
    assert page.message() == ""


def test_5_watch_shows_the_parts_with_their_coordinates(page: LivePage, video: LiveVideo) -> None:
    page.tab("watch")
    rows = page.parts(at_least=3)
    # Every part shown is where one of the video's parts is on some frame, in the robot's
    # frame (the plane frame is the first placement's board frame, as the touches were).
    truth = video.parts.plane_mm.reshape(-1, 2)
    robot = np.array([robot_of(p.tolist())[:2] for p in truth])
    for row in rows:
        shown = np.array([float(row[1]), float(row[2])])
        assert np.min(np.hypot(*(robot - shown).T)) < 0.3, row
    for row in rows:  # id, x, y, angle (none for a round part), std
        x, y, angle, std = row[1:]
        assert math.isfinite(float(x)) and math.isfinite(float(y)), row
        assert float(std) > 0 and (angle == NONE or math.isfinite(float(angle))), row
    assert "robot coordinates" in page.text("parts-caption")
    stats = page.definitions("stats")
    assert float(stats["fps"]) > 0 and int(stats["frames"]) > 0, stats


def test_6_no_javascript_errors(page: LivePage) -> None:
    assert page.browser_errors() == []
