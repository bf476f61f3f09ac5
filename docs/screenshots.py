"""The live guide's screenshots of `planarcal live`'s page, taken in a headless Chromium driving
the page as a user would, on the demo's rendered cell video (the browser test's own steps:
tests/web/live_server.py's LivePage).

Usage (needs planarcal[live], selenium, and Debian's chromium and chromium-driver):

    python docs/screenshots.py

writes, at 1600 x 1000:

* docs/images/live-setup.png: three placements captured and calibrated, the error map and
  the calibration's summary in view;
* docs/images/live-register.png: touch points entered by clicking dots, the fit judged;
* docs/images/live-watch.png: the parts located in the robot's frame.

All three are 256-colour PNGs when each stays under 400 kB, else JPEGs."""

from __future__ import annotations

import io
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from PIL import Image

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "web"))

from live_server import (  # noqa: E402 - the tests' harness, found above
    VIDEO_BOARD_ARGS,
    WINDOW,
    LivePage,
    browser_missing,
    cell_video,
    live_server,
    robot_of,
)

IMAGES = HERE / "images"
MAX_PNG_BYTES = 400_000
TOUCHED = (0, 8, 54, 62)


def shot(page: LivePage) -> np.ndarray:
    """The page as shown (BGR)."""
    image = cv2.imdecode(np.frombuffer(page.driver.get_screenshot_as_png(), np.uint8), 1)
    assert image is not None and image.shape[:2] == (WINDOW[1], WINDOW[0]), image.shape
    return image


def palette_png(image: np.ndarray) -> bytes:
    """A 256-colour PNG: the page is flat colours and a grey image, so a palette keeps it
    sharp at a third of a true-colour PNG's size (no dithering: it would only add noise)."""
    rgb = Image.fromarray(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
    quantised = rgb.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    out = io.BytesIO()
    quantised.save(out, format="PNG", optimize=True)
    return out.getvalue()


def write(shots: dict[str, np.ndarray]) -> None:
    """Each shot as name.png, or all as name.jpg when a PNG would be too large (one format
    for the three, whatever the run: the live guide names them)."""
    encoded = {name: palette_png(image) for name, image in shots.items()}
    suffix = ".png"
    if max(len(png) for png in encoded.values()) > MAX_PNG_BYTES:
        suffix = ".jpg"
        for name, image in shots.items():
            ok, jpg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 85])
            assert ok
            encoded[name] = jpg.tobytes()
    for name, data in encoded.items():
        for stale in (IMAGES / f"{name}.png", IMAGES / f"{name}.jpg"):
            stale.unlink(missing_ok=True)
        path = IMAGES / f"{name}{suffix}"
        path.write_bytes(data)
        print(f"{path.relative_to(HERE.parent)}: {len(data)} bytes")


def scroll_to(page: LivePage, element_id: str) -> None:
    page.driver.execute_script(
        "document.getElementById(arguments[0]).scrollIntoView({block: 'start'});", element_id
    )


def board_still(page: LivePage) -> None:
    """Waits until the video is well inside a hold of the board (not the last, which the
    parts follow: the drawn detection trails the frames by a few)."""
    video = page.video
    holds = [p.frames for p in video.placements[:-1]]

    def inside(state: dict[str, Any]) -> bool:
        index = state["stats"]["frames"] % video.frame_count
        return bool(state["detection"]["found"]) and any(
            h.start + 5 <= index < h.stop - 10 for h in holds
        )

    page.server.wait_for("the board held", inside, 60)
    time.sleep(0.5)  # the stream shows it


def main() -> int:
    missing = browser_missing()
    if missing:
        print(missing, file=sys.stderr)
        return 1
    IMAGES.mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="planarcal-screens-") as tmp:
        folder = Path(tmp)
        video = cell_video(folder)
        # The source by its name (the page shows it): the server runs in the folder.
        args = ["--source", video.path.name, "--calibration", "cell.json", *VIDEO_BOARD_ARGS]
        with live_server(args, folder) as server:
            page = LivePage(server, video)
            try:
                page.open()
                page.capture_all()
                page.calibrate()
                page.save(folder / "cell.json")
                scroll_to(page, "capture")
                board_still(page)
                shots = {"live-setup": shot(page)}

                page.tab("register")
                board = video.board.world_points()
                for point in TOUCHED:
                    page.pick(point)
                    page.touch(point, robot_of(board[point].tolist()))
                board_still(page)
                page.pick(31)  # a fifth dot picked, its coordinates still to type
                shots["live-register"] = shot(page)
                page.register(folder / "cell.json")

                page.tab("watch")
                page.parts(at_least=4)
                shots["live-watch"] = shot(page)
            finally:
                page.quit()
    write(shots)
    return 0


if __name__ == "__main__":
    sys.exit(main())
