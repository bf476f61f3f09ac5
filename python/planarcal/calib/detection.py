"""A board found in an image, whatever its type, and ``detect_board``, which hands the image
to the detector of the board's kind.

A detection is the ids of the board points found (indices into ``board.world_points()``,
0-based), their pixels and, through the board, their world mm: everything after detection
(calibration, its report and file, the live loop) works on these, so a partial view or a new
board type adds no branch there. Each kind's detector lives in its own module, registered in
``DETECTORS``: circle grids (planarcal.calib.detect), chessboards
(planarcal.calib.detect_chessboard) and ChArUco boards (planarcal.calib.detect_charuco).
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planarcal.calib.boards import BOARD_TYPES, Board, is_board
from planarcal.errors import ArgumentError

if TYPE_CHECKING:
    from planarcal.calib.dot_sizes import DotSizes

F64 = NDArray[np.float64]
Orientation = Literal["marker", "pattern", "ambiguous"]

DETECTORS: dict[str, str] = {
    "circles": "planarcal.calib.detect:detect_circle_grid",
    "chessboard": "planarcal.calib.detect_chessboard:detect_chessboard",
    "charuco": "planarcal.calib.detect_charuco:detect_charuco",
}
"""Each board kind's detector, as module:function (imported when first used)."""

AMBIGUOUS_RULE = (
    "no origin marker: dot 0 is the corner dot nearest the image's top-left corner, of the "
    "readings that are not mirrored (the board turned by 180 degrees would look the same)"
)


def detect_board(image: Any, board: Board, **options: Any) -> BoardDetection:
    """Find `board` in `image` (an array, grey or BGR, any real dtype, or a path) with the
    detector of its kind; ``options`` are that detector's (a circle grid's ``polarity`` and
    ``turned``). Raises BoardNotFoundError, saying what was seen, when the board is not found.
    """
    if not is_board(board):
        raise ArgumentError(
            f"board must be one of planarcal's boards ({', '.join(BOARD_TYPES)}), got "
            f"{type(board).__name__}"
        )
    module, name = DETECTORS[board.kind].split(":")
    detector = getattr(importlib.import_module(module), name)
    result: BoardDetection = detector(image, board, **options)
    return result


@dataclasses.dataclass(frozen=True)
class BoardDetection:
    """The board found in an image.

    ``image_points[k]`` is the centre of board point ``ids[k]`` (a dot, a corner) in pixels
    (float64; pixel centres at integer coordinates, as OpenCV); ``ids`` are indices into
    ``board.world_points()``, ascending. A whole board has every id; a partial view those seen.
    """

    board: Board
    image_points: F64
    image_size: tuple[int, int]
    """(width, height) of the image in pixels."""
    method: str
    """Which finder succeeded: for a circle grid "lattice" (planarcal's own) or "opencv"
    (findCirclesGrid's defaults); for a chessboard the OpenCV finder that found its corners
    before planarcal refined them; for a ChArUco board "charuco"."""
    residual_rms_px: float
    """RMS distance of the points from the best homography through them (px)."""
    ids: NDArray[np.intp] = dataclasses.field(default_factory=lambda: np.zeros(0, np.intp))
    """The board points found, ascending indices into ``board.world_points()``; left out,
    every point in order (a whole board)."""
    polarity: Literal["dark", "light"] = "dark"
    """Dark marks on a light board, or light on a dark one."""
    dot_diameters_px: F64 = dataclasses.field(default_factory=lambda: np.zeros(0))
    """A circle grid's dots' equivalent diameters in pixels (from their ink area); empty for
    other boards."""
    refined: NDArray[np.bool_] = dataclasses.field(default_factory=lambda: np.zeros(0, bool))
    """Per point found (matching ids): True where it was refined from the grey levels, False
    where it could not be and keeps a coarser position (a dot its blob's centre, about 0.1-0.5
    px; a ChArUco corner its markers' prediction). A partial view leaves such points out."""
    enlarged: NDArray[np.bool_] = dataclasses.field(default_factory=lambda: np.zeros(0, bool))
    """Per dot found: True for dots clearly larger than their neighbours (a marker,
    fiducials); empty for other boards."""
    orientation: Orientation = "ambiguous"
    """"marker": dot 0 is the origin marker; "pattern": the grid itself can be read only one
    way (an asymmetric grid with an odd number of rows); "ambiguous": neither, and
    ``orientation_rule`` chose the reading."""
    orientation_rule: str = AMBIGUOUS_RULE
    warnings: tuple[str, ...] = ()
    layout: str | None = None
    """Which of a board type's printed layouts was found, where it has several: a ChArUco
    board's "legacy" (OpenCV before 4.6) or "current"; None where there is one."""
    sizes: DotSizes | None = None
    """The dots' sizes measured on the board (mm at the stated pitch), which the board's
    stated diameter and origin marker were checked against (planarcal.calib.dot_sizes)."""

    def __post_init__(self) -> None:
        if len(self.ids) == 0 and len(self.image_points) == self.board.n_points:
            object.__setattr__(self, "ids", np.arange(self.board.n_points, dtype=np.intp))

    @property
    def partial(self) -> bool:
        """Whether only part of the board was found."""
        return len(self.ids) < self.board.n_points

    def world_points(self) -> F64:
        """The found points' world positions in mm, matching image_points."""
        return self.board.world_points()[self.ids]

    @property
    def pitch_px(self) -> float:
        """Median distance between neighbouring points in the image (px)."""
        pts = self.image_points
        if len(pts) < 2:
            return float("nan")
        d, _ = cKDTree(pts).query(pts, k=2)
        return float(np.median(d[:, 1]))
