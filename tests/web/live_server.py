"""A real `planarcal live` for the tests: the command in a child process on a free loopback
port, its URL read from its first line, and a small JSON client for its API."""

from __future__ import annotations

import contextlib
import functools
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from planarcal.calib.calibration import Calibration
from planarcal.synth.live_video import LiveVideo, write_live_video

try:  # for the page in a browser only: the API tests run without it
    from selenium import webdriver
    from selenium.common.exceptions import WebDriverException
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    HAVE_SELENIUM = True
except ImportError:
    HAVE_SELENIUM = False

START_TIMEOUT_S = 60.0
EPOCH = "1767225600"  # 2026-01-01: the files' `created`, so that two writes compare
VIDEO_BOARD_ARGS = ("--cols", "9", "--rows", "7", "--pitch", "20")


def cell_video(folder: Path) -> LiveVideo:
    """The demo's cell video, short: three placements held 3 s each, parts for 3 s."""
    return write_live_video(folder / "cell.avi", hold_s=3.0, parts_s=3.0)


class LiveServer:
    """`planarcal live ARGS` running; ``url`` from its first line. Stop with ``stop()``."""

    def __init__(self, args: Sequence[str], cwd: Path) -> None:
        env = dict(os.environ, SOURCE_DATE_EPOCH=EPOCH, PYTHONUNBUFFERED="1")
        self.process = subprocess.Popen(
            [sys.executable, "-m", "planarcal", "live", "--port", "0", *args],
            cwd=cwd,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.url = self._first_line()
        self.base = self.url.split("?")[0].rstrip("/")

    def _first_line(self) -> str:
        got: list[str] = []
        reader = threading.Thread(
            target=lambda: got.append(self.process.stdout.readline() if self.process.stdout else "")
        )
        reader.start()
        reader.join(START_TIMEOUT_S)
        if not got or not got[0].startswith("http://"):
            self.process.kill()
            _, err = self.process.communicate(timeout=10)
            raise AssertionError(f"planarcal live did not print its URL: {got!r}; stderr: {err}")
        return got[0].strip()

    def stop(self, sig: int = signal.SIGINT) -> tuple[int, str]:
        """Stops it as Ctrl-C would; its exit status and stderr."""
        if self.process.poll() is None:
            self.process.send_signal(sig)
        try:
            _, err = self.process.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            self.process.kill()
            _, err = self.process.communicate()
            raise AssertionError(f"planarcal live did not stop on signal {sig}: {err}") from None
        return self.process.returncode, err

    def call(
        self,
        method: str,
        path: str,
        body: Any = None,
        *,
        raw: bytes | None = None,
        headers: dict[str, str] | None = None,
        timeout: float = 120.0,
    ) -> tuple[int, Any]:
        """(status, JSON answer, or the bytes of a non-JSON one)."""
        data = raw if raw is not None else None if body is None else json.dumps(body).encode()
        request = urllib.request.Request(
            self.base + path,
            data=data,
            method=method,
            headers={"Content-Type": "application/json", **(headers or {})},
        )
        try:
            with urllib.request.urlopen(request, timeout=timeout) as r:
                status, payload, kind = r.status, r.read(), r.headers.get("Content-Type", "")
        except urllib.error.HTTPError as e:
            status, payload, kind = e.code, e.read(), e.headers.get("Content-Type", "")
        return status, json.loads(payload) if "json" in kind else payload

    def ok(self, method: str, path: str, body: Any = None, **kwargs: Any) -> Any:
        status, answer = self.call(method, path, body, **kwargs)
        assert status == 200, (method, path, status, answer)
        return answer

    def wait_for(
        self, what: str, test: Callable[[dict[str, Any]], bool], timeout: float = 60.0
    ) -> dict[str, Any]:
        """The first state (GET /api/state) that passes ``test``."""
        deadline = time.monotonic() + timeout
        state: dict[str, Any] = {}
        while time.monotonic() < deadline:
            state = self.ok("GET", "/api/state")
            if test(state):
                return state
            time.sleep(0.1)
        raise AssertionError(f"timed out waiting for {what}; last state: {state}")


@contextlib.contextmanager
def live_server(args: Sequence[str], cwd: Path) -> Iterator[LiveServer]:
    server = LiveServer(args, cwd)
    try:
        yield server
    finally:
        server.stop()


# ---- the page in a real browser (tests/web/test_live_browser.py, docs/screenshots.py) ---------

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
NO_BROWSER = "no chromium/chromedriver: apt-get install chromium chromium-driver"
WINDOW = (1600, 1000)
HOLD_MARGIN_S = (0.3, 1.2)
"""A held placement is acted on from this long after the board arrives to this long before it
leaves (s)."""


def browser_missing() -> str | None:
    """Why the page cannot be driven here (None: it can): no download at test time."""
    if not (shutil.which("chromium") or os.path.exists(CHROMIUM)):
        return NO_BROWSER
    if not (shutil.which("chromedriver") or os.path.exists(CHROMEDRIVER)):
        return NO_BROWSER
    if not HAVE_SELENIUM:
        return "no selenium: pip install selenium"
    return None


def robot_of(board_mm: Sequence[float]) -> list[float]:
    """The robot's frame of the tests: the board turned 90 degrees and moved; z 12 mm."""
    x, y = board_mm[0], board_mm[1]
    return [300.0 - y, 100.0 + x, 12.0]


class LivePage:
    """The page of ``server`` in a headless Chromium, driven as a user would (clicks, typing),
    with the video's truth to know when the board is where."""

    def __init__(self, server: LiveServer, video: LiveVideo) -> None:
        self.server = server
        self.video = video
        options = webdriver.ChromeOptions()
        options.binary_location = shutil_which("chromium", CHROMIUM)
        for argument in (
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--hide-scrollbars",
            f"--window-size={WINDOW[0]},{WINDOW[1]}",
        ):
            options.add_argument(argument)
        options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
        service = Service(shutil_which("chromedriver", CHROMEDRIVER))
        self.driver = webdriver.Chrome(options=options, service=service)
        self.driver.set_page_load_timeout(60)
        # The window's size includes what headless Chromium keeps for its frame: the page's
        # viewport is made WINDOW itself (the screenshots' size).
        inner = self.driver.execute_script("return [window.innerWidth, window.innerHeight];")
        self.driver.set_window_size(2 * WINDOW[0] - int(inner[0]), 2 * WINDOW[1] - int(inner[1]))
        self.log: list[dict[str, Any]] = []

    def quit(self) -> None:
        self.driver.quit()

    # -- small tools ------------------------------------------------------------------------

    def wait(self, what: str, test: Callable[[], Any], timeout: float = 30.0) -> Any:
        """The first true answer of ``test()`` (retried every 0.1 s)."""

        def attempt(_: Any) -> Any:
            try:
                return test()
            except WebDriverException:
                return False  # an element replaced under the test (a redrawn section)

        message = f"timed out waiting for {what}; #message: {self.message()!r}"
        return WebDriverWait(self.driver, timeout, poll_frequency=0.1).until(attempt, message)

    def by_id(self, element_id: str) -> Any:
        return self.driver.find_element(By.ID, element_id)

    def css(self, selector: str) -> list[Any]:
        return list(self.driver.find_elements(By.CSS_SELECTOR, selector))

    def text(self, element_id: str) -> str:
        return str(self.by_id(element_id).text)

    def message(self) -> str:
        """The page's #message (a failed request's error), '' when none is shown."""
        try:
            shown = self.driver.execute_script(
                "const b = document.getElementById('message-bar');"
                "return b && !b.hidden ? document.getElementById('message').textContent : '';"
            )
        except Exception:  # only for the error messages
            return "?"
        return str(shown or "")

    def image_loaded(self, element: Any) -> bool:
        return bool(
            self.driver.execute_script(
                "return arguments[0].complete && arguments[0].naturalWidth > 0;", element
            )
        )

    def natural_width(self, element_id: str) -> int:
        width = self.driver.execute_script(
            "return document.getElementById(arguments[0]).naturalWidth;", element_id
        )
        return int(width or 0)

    def browser_errors(self) -> list[str]:
        """The browser's console errors so far, but Chrome's lines for 4xx answers (the page
        asks for the error map before the first capture and shows a refused pick's reason)."""
        self.log += self.driver.get_log("browser")  # type: ignore[no-untyped-call]
        return [
            str(entry["message"])
            for entry in self.log
            if entry.get("level") == "SEVERE"
            and not (
                "Failed to load resource" in entry["message"] and "status of 4" in entry["message"]
            )
        ]

    def held(self, k: int) -> Callable[[dict[str, Any]], bool]:
        """A test of a state: the board found at held placement ``k``, with time to act on it
        before it moves on (a click's round trip and the detection's lag are a few tenths of
        a second; a capture of a board in motion would be a placement in between). The
        frames read so far give the video's frame (a file source loops without a gap)."""
        held = self.video.placements[k]
        target = held.points_px[0]
        first = held.frames.start + round(HOLD_MARGIN_S[0] * self.video.fps)
        last = held.frames.stop - round(HOLD_MARGIN_S[1] * self.video.fps)

        def test(state: dict[str, Any]) -> bool:
            found = state["detection"]
            frame = state["stats"]["frames"] % self.video.frame_count
            return (
                bool(found["found"])
                and math.dist(found["origin_px"], target) < 3.0
                and first <= frame < last
            )

        return test

    def held_now(self, timeout: float = 60.0) -> int:
        """Waits for the board held still at any placement; its index."""
        tests = [self.held(k) for k in range(len(self.video.placements))]
        state = self.server.wait_for(
            "the board held still", lambda s: any(t(s) for t in tests), timeout
        )
        return next(k for k, t in enumerate(tests) if t(state))

    # -- the steps --------------------------------------------------------------------------

    def open(self) -> None:
        self.driver.get(self.server.url)
        self.wait("the live image", lambda: self.natural_width("live") > 0, 60)
        self.wait("the board found", lambda: "Found" in self.text("detection"), 60)

    def tab(self, mode: str) -> None:
        self.by_id(f"tab-{mode}").click()
        self.wait(
            f"the {mode} view",
            lambda: (
                self.by_id(f"tab-{mode}").get_attribute("aria-selected") == "true"
                and self.by_id(f"view-{mode}").is_displayed()
            ),
        )
        self.server.wait_for(f"mode {mode}", lambda s: s["mode"] == mode, 10)

    def placements(self) -> int:
        return len(self.css("#placements li[data-index]"))

    def capture_all(self) -> None:
        """Clicks Capture while the board is held at each placement in turn."""
        for k in range(len(self.video.placements)):
            for _ in range(5):
                self.server.wait_for(f"placement {k} in view", self.held(k), 60)
                self.by_id("capture").click()
                try:
                    listed = functools.partial(lambda n: self.placements() == n, k + 1)
                    self.wait(f"placement {k + 1} listed", listed, 5)
                    break
                except Exception:  # refused (the board moved on): next pass
                    continue
            assert self.placements() == k + 1, self.message()
        self.wait("the error map", lambda: self.image_loaded(self.by_id("coverage")), 30)

    def calibrate(self) -> None:
        self.by_id("calibrate").click()
        self.wait("the summary", lambda: "Placements: 3" in self.text("summary"), 90)
        figures = self.css("#figures img")
        assert figures, "no figures"
        for figure in figures:  # lazy images load once scrolled to
            self.driver.execute_script("arguments[0].scrollIntoView({block: 'nearest'});", figure)
            self.wait("a figure", functools.partial(self.image_loaded, figure), 30)
        self.driver.execute_script("document.querySelector('.panel').scrollTop = 0;")

    def save(self, path: Path) -> None:
        before = path.stat().st_mtime_ns if path.exists() else None
        self.by_id("save").click()
        self.wait(
            "the file saved",
            lambda: (
                path.exists()
                and path.stat().st_mtime_ns != before
                and "· saved" in self.text("calibration-status")
            ),
        )

    def click_image(self, x_px: float, y_px: float) -> None:
        """Clicks the live image at image pixel (x, y): Selenium 4's offsets are from the
        element's centre, in CSS pixels of its displayed size."""
        live = self.by_id("live")
        size = live.size
        natural = self.driver.execute_script(
            "return [arguments[0].naturalWidth, arguments[0].naturalHeight];", live
        )
        dx = x_px * size["width"] / natural[0] - size["width"] / 2
        dy = y_px * size["height"] / natural[1] - size["height"] / 2
        ActionChains(self.driver).move_to_element_with_offset(
            live, round(dx), round(dy)
        ).click().perform()

    def pick(self, point: int) -> dict[str, Any]:
        """Clicks dot ``point`` on the image where the board is held; what #picked says."""
        for _ in range(6):
            k = self.held_now()
            x, y = self.video.placements[k].points_px[point]
            self.click_image(float(x), float(y))
            try:
                self.wait(
                    f"dot {point} picked",
                    lambda: self.by_id("picked").get_attribute("data-id") == str(point),
                    4,
                )
            except Exception:  # the board moved on under the click: again
                continue
            return {"text": self.text("picked"), "placement": k}
        raise AssertionError(f"dot {point} never picked; #message: {self.message()!r}")

    def touch(self, point: int, robot: Sequence[float]) -> None:
        """Types the robot's coordinates for the picked point and adds it."""
        for field, value in zip(("touch-x", "touch-y", "touch-z"), robot, strict=False):
            box = self.by_id(field)
            box.clear()
            box.send_keys(f"{value:g}")
        self.by_id("touch-add").click()
        self.wait(
            f"touch {point} listed",
            lambda: any(row["id"] == str(point) for row in self.rows("touches")),
        )

    def register(self, path: Path) -> None:
        self.by_id("register").click()
        self.wait(
            "the registration saved",
            lambda: path.exists() and Calibration.load(path).robot_frame is not None,
        )

    def rows(self, table_id: str) -> list[dict[str, Any]]:
        """A table's rows with a data-id, read at once (the page redraws its tables as the
        data changes, so element by element they would go stale): {"id", "cells"}."""
        rows = self.driver.execute_script(
            "return Array.from(document.querySelectorAll('#' + arguments[0] + "
            "' tbody tr[data-id]')).map((r) => ({id: r.dataset.id, "
            "cells: Array.from(r.cells).map((c) => c.textContent.trim())}));",
            table_id,
        )
        return list(rows or [])

    def definitions(self, list_id: str) -> dict[str, str]:
        """A description list's terms and their values, read at once (the page redraws #stats
        with every frame, so element by element they go stale): {term: value}."""
        pairs = self.driver.execute_script(
            "return Array.from(document.querySelectorAll('#' + arguments[0] + ' dt')).map("
            "(t) => [t.textContent.trim(), (t.nextElementSibling || {}).textContent || ''])",
            list_id,
        )
        return {term: value.strip() for term, value in pairs or []}

    def parts(self, at_least: int = 3, timeout: float = 90.0) -> list[list[str]]:
        """The #parts table's rows once it lists ``at_least`` parts (the video loops)."""

        def rows() -> list[list[str]] | None:
            got = [row["cells"] for row in self.rows("parts")]
            return got if len(got) >= at_least else None

        found: list[list[str]] = self.wait(f"{at_least} parts", rows, timeout)
        return found


def shutil_which(name: str, fallback: str) -> str:
    return shutil.which(name) or fallback
