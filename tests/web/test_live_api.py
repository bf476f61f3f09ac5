"""`planarcal live`'s JSON API, on a real server (the command in a child process, on a free
loopback port) reading the demo's rendered cell video: set up (capture three placements,
the error map, calibrate, save: the same file as `planarcal calibrate` writes from the
captured frames), register (pick, touch, the fit, save: as `planarcal register`), watch (the
parts in mm, the object settings saved), and the guards (token, body size, bad requests)."""

from __future__ import annotations

import functools
import http.client
import json
import math
import os
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from live_server import EPOCH, VIDEO_BOARD_ARGS, LiveServer, cell_video, live_server

from planarcal.calib.calibration import Calibration
from planarcal.synth.live_video import LiveVideo

pytest.importorskip("starlette", reason="the live page needs the extra planarcal[live]")


@pytest.fixture(scope="module")
def video(tmp_path_factory: pytest.TempPathFactory) -> LiveVideo:
    return cell_video(tmp_path_factory.mktemp("live-video"))


@pytest.fixture(scope="module")
def calibrated(video: LiveVideo, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """A server that has captured the three placements, calibrated and saved: (server,
    folder, the answers of the set-up steps)."""
    folder = tmp_path_factory.mktemp("live-setup")
    args = ["--source", str(video.path), "--calibration", "cell.json", *VIDEO_BOARD_ARGS]
    with live_server(args, folder) as server:
        steps = set_up(server, video)
        yield server, folder, steps


def _near(target: np.ndarray, state: dict[str, Any]) -> bool:
    return _origin_near(state, target)


def _origin_near(state: dict[str, Any], target: np.ndarray, px: float = 3.0) -> bool:
    found = state["detection"]
    return bool(found["found"]) and math.dist(found["origin_px"], target) < px


def set_up(server: LiveServer, video: LiveVideo) -> dict[str, Any]:
    """Captures each held placement, calibrates and saves; the answers on the way."""
    steps: dict[str, Any] = {"refused": []}
    for k, held in enumerate(video.placements):
        while True:
            server.wait_for(f"placement {k} in view", functools.partial(_near, held.points_px[0]))
            status, answer = server.call("POST", "/api/capture")
            if status == 200 and len(answer["placements"]) == k + 1:
                break
            steps["refused"].append((status, answer))
        steps[f"capture {k}"] = answer
        if k == 0:
            status, again = server.call("POST", "/api/capture")
            steps["duplicate"] = (status, again)
    steps["coverage"] = server.call("GET", "/api/coverage.png")
    steps["calibrate"] = server.ok("POST", "/api/calibrate", {"max_error_mm": 0.05})
    steps["save"] = server.ok("POST", "/api/save")
    return steps


def test_the_first_line_is_the_url_and_the_page_is_served(calibrated: Any) -> None:
    server, _, _ = calibrated
    assert server.url.startswith("http://127.0.0.1:")
    page = server.ok("GET", "/")
    assert b"<html" in page.lower() and b"/static/app.js" in page
    assert b"fetch" in server.ok("GET", "/static/app.js")
    frame = cv2.imdecode(np.frombuffer(server.ok("GET", "/api/frame.jpg"), np.uint8), 1)
    assert frame is not None and frame.shape == (720, 1280, 3)


def test_three_placements_make_the_calibration_planarcal_calibrate_makes(
    calibrated: Any, video: LiveVideo
) -> None:
    server, folder, steps = calibrated
    placements = steps["capture 2"]["placements"]
    assert [p["name"] for p in placements] == [f"placement-{k}.png" for k in (1, 2, 3)]
    assert all(p["points"] == 63 for p in placements)
    # A second capture of the same place is refused, naming the placement.
    status, answer = steps["duplicate"]
    assert status == 409 and "placement 1" in answer["error"]
    # The error map after each capture: it shrinks as the area is covered.
    worst = [steps[f"capture {k}"]["coverage"]["worst_mm"] for k in range(3)]
    assert worst[2] < worst[0]
    assert steps["coverage"][0] == 200 and steps["coverage"][1][:8] == b"\x89PNG\r\n\x1a\n"
    cal = steps["calibrate"]["calibration"]
    assert cal["placements"] == 3 and "coverage.png" in cal["figures"]
    assert "Placements: 3" in cal["summary"]
    assert server.ok("GET", "/api/report/coverage.png")[:4] == b"\x89PNG"
    # The captured frames, given to the command, give the same file to the bit.
    names = []
    for k in range(3):
        png = server.ok("GET", f"/api/placements/{k}.png")
        (folder / f"placement-{k + 1}.png").write_bytes(png)
        names.append(f"placement-{k + 1}.png")
    env = dict(os.environ, SOURCE_DATE_EPOCH=EPOCH)
    subprocess.run(
        [
            sys.executable,
            "-m",
            "planarcal",
            "calibrate",
            *names,
            *VIDEO_BOARD_ARGS,
            "-o",
            "cli.json",
        ],
        cwd=folder,
        env=env,
        check=True,
        capture_output=True,
    )
    saved = (folder / "cell.json").read_bytes()
    assert saved == (folder / "cli.json").read_bytes()
    assert server.ok("GET", "/api/calibration.json") == json.loads(saved)
    # And it maps the cell: the parts' true pixels to their true places.
    loaded = Calibration.load(folder / "cell.json")
    parts = video.parts
    inside = parts.in_area
    mm = loaded.image_to_world(parts.pixels_px[inside])
    assert np.max(np.hypot(*(mm - parts.plane_mm[inside]).T)) < 0.1


def test_a_click_picks_a_point_and_touches_register_as_planarcal_register(
    calibrated: Any, video: LiveVideo
) -> None:
    server, folder, _ = calibrated
    server.ok("POST", "/api/mode", {"mode": "register"})
    first = video.placements[0]
    state = server.wait_for(
        "the board at placement 1", lambda s: _origin_near(s, first.points_px[0])
    )
    assert state["mode"] == "register"
    picked = server.ok(
        "POST", "/api/pick", {"x": first.points_px[10][0] + 2.0, "y": first.points_px[10][1]}
    )
    assert picked["id"] == 10 and picked["name"] == "dot 10"
    assert picked["board_mm"] == [20.0, 20.0]
    status, far = server.call("POST", "/api/pick", {"x": 5.0, "y": 5.0})
    assert status == 404 and "dot" in far["error"]

    # The robot's frame: the board turned 90 degrees and moved; z 12 mm everywhere.
    def robot(board_mm: list[float]) -> list[float]:
        x, y = board_mm
        return [300.0 - y, 100.0 + x, 12.0]

    board = video.board.world_points()
    for point in (0, 8, 54, 62):
        state = server.ok(
            "POST", "/api/touches", {"id": point, "robot": robot(board[point].tolist())}
        )
    fit = state["registration"]["fit"]
    assert fit["quality"] in ("excellent", "good") and not fit["outliers"]
    # A mistyped touch is named as the outlier, and saving is refused.
    mistyped = robot(board[31].tolist())
    mistyped[0] += 5.0
    state = server.ok("POST", "/api/touches", {"id": 31, "robot": mistyped})
    assert state["registration"]["fit"]["outliers"] == [31]
    status, refused = server.call("POST", "/api/register", {})
    assert status == 409 and "dot 31" in refused["error"]
    server.ok("DELETE", "/api/touches/31")
    csv_text = server.ok("GET", "/api/touches.csv").decode()
    assert csv_text.splitlines()[0] == "dot,robot_x,robot_y,robot_z"
    # The CSV round trip and the save: the same file as the command writes.
    server.ok(
        "PUT", "/api/touches.csv", raw=csv_text.encode(), headers={"Content-Type": "text/csv"}
    )
    before = (folder / "cell.json").read_bytes()
    (folder / "before.json").write_bytes(before)
    (folder / "touches.csv").write_text(csv_text)
    server.ok("POST", "/api/register", {})
    subprocess.run(
        [
            sys.executable,
            "-m",
            "planarcal",
            "register",
            "--calibration",
            "before.json",
            "--points",
            "touches.csv",
            "-o",
            "cli-registered.json",
        ],
        cwd=folder,
        check=True,
        capture_output=True,
    )
    registered = Calibration.load(folder / "cell.json")
    assert registered.robot_frame is not None
    # The robot frame maps board point 20 where the robot's frame puts it.
    got = registered.robot_frame.to_robot(board[20][None])[0]
    assert np.allclose(got[:2], robot(board[20].tolist())[:2], atol=0.05)
    cli = Calibration.load(folder / "cli-registered.json")
    assert cli.to_dict()["robot_frame"] == registered.to_dict()["robot_frame"]


def test_watch_shows_the_parts_and_saves_the_object_settings(calibrated: Any) -> None:
    server, folder, _ = calibrated
    server.ok("POST", "/api/mode", {"mode": "watch"})
    state = server.wait_for("parts", lambda s: len(s["watch"]["parts"]) >= 3, timeout=90)
    part = state["watch"]["parts"][0]
    assert {"id", "x", "y", "angle_deg", "std_mm", "image_px"} <= set(part)
    assert all(math.isfinite(p["x"]) and p["std_mm"] > 0 for p in state["watch"]["parts"])
    assert state["stats"]["fps"] > 0 and state["stats"]["latency_ms"] > 0
    # Settings that keep no part: none is shown; saved into the file.
    server.ok("POST", "/api/settings", {"min_area_px": 1e6})
    server.wait_for(
        "no parts", lambda s: s["watch"]["parts"] == [] and s["watch"]["message"] is None
    )
    server.ok("POST", "/api/settings/save")
    assert Calibration.load(folder / "cell.json").object_settings.min_area_px == 1e6
    server.ok("POST", "/api/settings", {"min_area_px": None})
    server.wait_for("parts again", lambda s: len(s["watch"]["parts"]) >= 1, timeout=90)
    server.ok("POST", "/api/settings/save")
    assert Calibration.load(folder / "cell.json").object_settings.min_area_px is None


@pytest.mark.parametrize(
    ("method", "path", "body", "status", "words"),
    [
        ("POST", "/api/mode", {"mode": "dance"}, 400, "mode must be one of"),
        ("POST", "/api/touches", {"id": 999, "robot": [0, 0]}, 400, "not on the board"),
        ("POST", "/api/touches", {"id": 1, "robot": [0, "x"]}, 400, "finite number"),
        ("POST", "/api/pick", {"x": float("nan"), "y": 0}, 400, "finite number"),
        ("POST", "/api/calibrate", {"max_error_mm": -1}, 400, "max_error_mm"),
        ("GET", "/api/placements/99.png", None, 404, "no placement 99"),
        ("GET", "/api/report/..%2F..%2Fetc%2Fpasswd", None, 404, "no "),
        ("GET", "/api/report/passwd", None, 404, "no figure"),
        ("PUT", "/api/state", None, 405, "not allowed"),
        ("DELETE", "/api/touches/12345", None, 404, "no touch"),
    ],
)
def test_bad_requests_get_the_reason(
    calibrated: Any, method: str, path: str, body: Any, status: int, words: str
) -> None:
    server, _, _ = calibrated
    got, answer = server.call(method, path, body)
    assert got == status and words in answer["error"], answer


def test_a_malformed_or_oversized_body_is_refused(calibrated: Any) -> None:
    server, _, _ = calibrated
    status, answer = server.call("POST", "/api/mode", raw=b"{not json")
    assert status == 400 and "not JSON" in answer["error"]
    status, answer = server.call("PUT", "/api/touches.csv", raw=b"x" * (2**20 + 1))
    assert status == 413 and "bytes" in answer["error"]


def test_off_loopback_every_request_needs_the_token(video: LiveVideo, tmp_path: Path) -> None:
    args = ["--source", str(video.path), "--host", "0.0.0.0", *VIDEO_BOARD_ARGS]
    with live_server(args, tmp_path) as server:
        token = server.url.split("?token=")[1]
        assert len(token) >= 16
        server.base = server.base.replace(server.base.split("//")[1].split(":")[0], "127.0.0.1")
        for path in ("/", "/api/state", "/static/app.js", "/api/frame.jpg"):
            status, answer = server.call("GET", path)
            assert status == 401 and "token" in answer["error"]
        assert server.call("GET", f"/api/state?token={token}x")[0] == 401
        assert (
            server.call("GET", "/api/state", headers={"Authorization": f"Bearer {token}"})[0] == 200
        )
        status, _ = server.call("GET", f"/?token={token}")
        assert status == 200
        # The cookie is set for the right token only, even where another credential passes.
        port = int(server.base.rsplit(":", 1)[1])
        for query, cookie in ((token, True), (token + "x", False)):
            connection = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
            connection.request(
                "GET", f"/?token={query}", headers={"Authorization": f"Bearer {token}"}
            )
            response = connection.getresponse()
            response.read()
            assert response.status == 200
            assert (response.getheader("set-cookie") is not None) == cookie
            connection.close()


@pytest.mark.parametrize(("sig", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 0)])
def test_ctrl_c_stops_it_and_nothing_is_written_without_a_file(
    video: LiveVideo, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, sig: int, status: int
) -> None:
    cwd, temp = tmp_path / "cwd", tmp_path / "temp"
    cwd.mkdir()
    temp.mkdir()
    monkeypatch.setenv("TMPDIR", str(temp))  # where the session keeps its working files
    server = LiveServer(["--source", str(video.path), *VIDEO_BOARD_ARGS], cwd)
    server.wait_for("a frame", lambda s: s["stats"]["frames"] > 0)
    saved, answer = server.call("POST", "/api/save")
    assert saved == 409 and "--calibration" in answer["error"]
    assert list(temp.iterdir()) != []
    code, err = server.stop(sig)
    assert code == status  # 130: the CLI's status for Ctrl-C
    # One line says so: the server's "stopped", not the CLI's "interrupted" after it; and
    # SIGTERM too stops it cleanly, its working files removed.
    assert err.count("planarcal live: stopped") == 1 and "interrupted" not in err, err
    assert list(cwd.iterdir()) == [] and list(temp.iterdir()) == []


def test_controllers_get_the_watched_frames_and_the_page_lists_them(
    calibrated: Any, video: LiveVideo
) -> None:
    _, folder, _ = calibrated
    with socket.socket() as probe:  # a free port for the controllers' server
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    args = ["--source", str(video.path), "--calibration", "cell.json"]
    with live_server([*args, "-o", f"tcp-listen://127.0.0.1:{port}"], folder) as server:
        state = server.ok("GET", "/api/state")
        assert state["mode"] == "watch"  # the file exists: the page opens on the parts
        with socket.create_connection(("127.0.0.1", port), timeout=30) as controller:
            server.wait_for(
                "the controller", lambda s: len(s["watch"]["output"]["controllers"]) == 1
            )
            reader = controller.makefile("r")
            seen = [json.loads(reader.readline())]
            while not seen[-1]["objects"] and len(seen) < video.frame_count * 2:
                seen.append(json.loads(reader.readline()))  # the parts come after the board
        assert all(line["coords"] in ("board", "robot") for line in seen)
        assert seen[-1]["objects"], "no parts in a whole loop of the video"
        assert server.ok("GET", "/api/state")["watch"]["output"]["sent"] >= len(seen)


def test_touches_on_one_line_need_the_hand_and_get_it(calibrated: Any, video: LiveVideo) -> None:
    _, folder, _ = calibrated
    args = ["--source", str(video.path), "--calibration", "cell.json"]
    with live_server(args, folder) as server:
        board = video.board.world_points()
        for point in (0, 4, 8):  # the board's first row
            x, y = board[point]
            state = server.ok(
                "POST", "/api/touches", {"id": point, "robot": [300.0 - y, 100.0 + x]}
            )
        assert state["registration"]["fit"] is None
        assert "one line" in state["registration"]["message"]
        status, answer = server.call("POST", "/api/handedness", {"handedness": "sideways"})
        assert status == 400 and "handedness must be" in answer["error"]
        state = server.ok("POST", "/api/handedness", {"handedness": "left"})
        assert state["registration"]["handedness"] == "left"
        assert state["registration"]["fit"]["outliers"] == []


def test_where_the_board_is_not_found_the_page_says_why_and_shows_what_was_seen(
    calibrated: Any,
) -> None:
    server, _, _ = calibrated
    server.ok("POST", "/api/mode", {"mode": "setup"})
    state = server.wait_for(
        "a frame without the board",  # the parts' part of the video
        lambda s: not s["detection"]["found"] and bool(s["detection"].get("diagnostics")),
        timeout=90,
    )
    assert "no 9 x 7 circle grid (63 dots) found" in state["detection"]["message"]
    status, png = server.call("GET", "/api/diagnostics.png")
    if status == 404:  # the board came back meanwhile: wait for the next frame without it
        server.wait_for("no board", lambda s: not s["detection"]["found"], timeout=90)
        status, png = server.call("GET", "/api/diagnostics.png")
    assert status == 200 and png[:4] == b"\x89PNG"


def test_a_calibration_of_another_size_is_refused_unless_set_up_anew(
    calibrated: Any, video: LiveVideo
) -> None:
    _, folder, _ = calibrated
    Calibration.load(folder / "cell.json").for_frame_size(640, 360).save(folder / "small.json")
    args = [sys.executable, "-m", "planarcal", "live", "--source", str(video.path)]
    run = subprocess.run(
        [*args, "--calibration", "small.json", "--port", "0"],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert run.returncode == 1 and run.stdout == ""
    assert "640" in run.stderr and "--recalibrate" in run.stderr
    with live_server(
        ["--source", str(video.path), "--calibration", "small.json", "--recalibrate"], folder
    ) as server:
        state = server.ok("GET", "/api/state")
        assert state["mode"] == "setup" and state["calibration"] is None
        assert state["board"]["points"] == 63  # the file's board
    assert Calibration.load(folder / "small.json").image_size == (640, 360)  # not written
