"""A real `planarcal live` for the tests: the command in a child process on a free loopback
port, its URL read from its first line, and a small JSON client for its API."""

from __future__ import annotations

import contextlib
import json
import os
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

from planarcal.synth.live_video import LiveVideo, write_live_video

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
