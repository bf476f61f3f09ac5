"""The board found in a live frame fast enough for a live view. Between two frames the board
moves little, so the search starts in a window around where it was last found (a board a
third of the image wide: a ninth of the pixels to search), at half resolution when that
window is large; only when it is not there is the whole frame searched (at half resolution
first when the frame is large, then at full). Capturing a placement detects again, on the
whole frame at full resolution: the live detection is for the eye, the capture's for the
fit."""

from __future__ import annotations

import dataclasses
from typing import Any

import cv2
import numpy as np

from planarcal.calib.boards import Board
from planarcal.calib.detection import BoardDetection, detect_board
from planarcal.errors import BoardNotFoundError

HALF_FROM_PX = 960
"""Regions at least this wide are searched at half resolution first."""
MARGIN_PITCHES = 2.5
"""The window around the last detection reaches this many pitches beyond its points (the
board's paper margin and a hand's move between frames)."""

Box = tuple[int, int, int, int]


@dataclasses.dataclass
class LiveDetector:
    """Finds ``board`` frame after frame (``detect``), remembering where it was."""

    board: Board
    options: dict[str, Any] = dataclasses.field(default_factory=dict)
    _box: Box | None = None
    _half_failed: bool = False

    def detect(self, frame: Any) -> BoardDetection:
        """The board in ``frame`` (its points in the frame's pixels); BoardNotFoundError, in
        the words of the whole frame's search, when it is not found."""
        height, width = frame.shape[:2]
        if self._box is not None:
            try:
                return self._found(self._search(frame, self._box), frame)
            except BoardNotFoundError:
                self._box = None
        whole = (0, 0, width, height)
        try:
            return self._found(self._search(frame, whole), frame)
        except BoardNotFoundError:
            self._box = None
            raise

    def _found(self, found: BoardDetection, frame: Any) -> BoardDetection:
        height, width = frame.shape[:2]
        margin = MARGIN_PITCHES * found.pitch_px
        (x0, y0), (x1, y1) = found.image_points.min(axis=0), found.image_points.max(axis=0)
        self._box = (
            max(0, int(x0 - margin)),
            max(0, int(y0 - margin)),
            min(width, int(np.ceil(x1 + margin)) + 1),
            min(height, int(np.ceil(y1 + margin)) + 1),
        )
        return found

    def _search(self, frame: Any, box: Box) -> BoardDetection:
        """The board in ``box`` of the frame: at half resolution first when the box is wide
        (unless that failed last time while full resolution found it), then at full."""
        x0, y0, x1, y1 = box
        region = frame[y0:y1, x0:x1]
        scales = (2, 1) if x1 - x0 >= HALF_FROM_PX and not self._half_failed else (1,)
        for scale in scales:
            try:
                found = self._at(region, scale)
            except BoardNotFoundError:
                if scale == 1:
                    raise
                continue
            self._half_failed = scale == 1 and len(scales) == 2
            height, width = frame.shape[:2]
            return dataclasses.replace(
                found,
                image_points=found.image_points + np.array([x0, y0], float),
                image_size=(width, height),
            )
        raise AssertionError("unreachable: the full-resolution search raises")  # pragma: no cover

    def _at(self, region: Any, scale: int) -> BoardDetection:
        if scale == 1:
            return detect_board(region, self.board, **self.options)
        height, width = region.shape[:2]
        small = cv2.resize(region, (width // 2, height // 2), interpolation=cv2.INTER_AREA)
        found = detect_board(small, self.board, **self.options)
        # A half-resolution pixel i spans full pixels 2i and 2i + 1: its centre is 2i + 0.5.
        return dataclasses.replace(
            found,
            image_points=found.image_points * 2.0 + 0.5,
            dot_diameters_px=found.dot_diameters_px * 2.0,
        )


def points_text(detection: BoardDetection) -> str:
    """ "63 of 63 dots" for a detection."""
    board = detection.board
    return f"{len(detection.image_points)} of {board.n_points} {board.point_name}s"
