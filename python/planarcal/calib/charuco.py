"""A printed ChArUco board: a chessboard whose white squares hold ArUco markers, laid out and
numbered exactly as OpenCV's ``cv2.aruco.CharucoBoard``.

``squares_x`` x ``squares_y`` squares of ``square`` mm, markers ``marker`` mm wide from one of
OpenCV's predefined dictionaries (by name: ``"DICT_4X4_50"`` ... ``"DICT_7X7_1000"``,
``"DICT_ARUCO_ORIGINAL"``, ``"DICT_APRILTAG_16h5"`` ...; OpenCV's enum value, e.g. 6 for
``DICT_5X5_250``, is taken too and stored as the name). The board's points are its
(squares_x - 1) x (squares_y - 1) inner chessboard corners; corner k = r * (squares_x - 1) + c
is at ((c + 1) * square, (r + 1) * square), in mm from the board's top-left outer corner, X
across and Y down, OpenCV's ids and object points. Every marker has its id, so any part of
the board in view identifies itself.

Two layouts are in use: OpenCV before 4.6 started the chessboard differently when the number
of rows is even (``legacy=True``); 4.6 and later (``legacy=False``) always put a black square
at the top left. For an odd number of rows they are the same board. ``legacy=None`` (the
default) is "either": detection finds which, and says so; printing and rendering draw the
current one.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, ClassVar

import cv2
import numpy as np
from numpy.typing import NDArray

from planarcal import arguments
from planarcal.calib.board_ink import BoardInk, cell_runs
from planarcal.calib.square_corners import SquareCorners
from planarcal.errors import BoardError

F64 = NDArray[np.float64]

MAX_SQUARES_PER_SIDE = 1000


def _dictionary_names() -> tuple[str, ...]:
    """OpenCV's predefined dictionaries, by the names its documentation uses (the AprilTag
    ones as ``DICT_APRILTAG_16h5``; the all-capitals aliases are accepted too)."""
    names = [n for n in dir(cv2.aruco) if n.startswith("DICT_")]
    ids: dict[int, str] = {}
    for n in sorted(names):
        value = int(getattr(cv2.aruco, n))
        # Prefer the documentation's spelling (lower-case 'h' in the AprilTag names).
        if value not in ids or any(ch.islower() for ch in n):
            ids[value] = n
    return tuple(ids[v] for v in sorted(ids))


DICTIONARIES = _dictionary_names()
"""The dictionary names CharucoBoard takes, in OpenCV's enum order."""


def dictionary_id(name: str | int) -> int:
    """OpenCV's enum value of a predefined dictionary, given by name or by that value (as
    files written with ``cv2.aruco.getPredefinedDictionary(6)`` state it); BoardError naming
    the choices."""
    if isinstance(name, str) and name.startswith("DICT_") and hasattr(cv2.aruco, name):
        return int(getattr(cv2.aruco, name))
    if (
        isinstance(name, int | np.integer)
        and not isinstance(name, bool)
        and any(int(getattr(cv2.aruco, n)) == int(name) for n in DICTIONARIES)
    ):
        return int(name)
    raise BoardError(
        f"dictionary must be one of OpenCV's predefined ArUco dictionaries "
        f"({', '.join(DICTIONARIES)}), got {name!r}"
    )


def dictionary_name(value: int) -> str:
    """The documentation's name of a dictionary's enum value."""
    for n in DICTIONARIES:
        if int(getattr(cv2.aruco, n)) == value:
            return n
    raise BoardError(f"no predefined ArUco dictionary has the value {value}")


@functools.lru_cache(maxsize=64)
def _dictionary(value: int) -> Any:
    return cv2.aruco.getPredefinedDictionary(value)


@dataclasses.dataclass(frozen=True)
class CharucoBoard(SquareCorners):
    """OpenCV's ChArUco board (see the module): `squares_x` x `squares_y` squares of
    `square` mm, markers of `marker` mm from `dictionary`; `legacy` None (either layout),
    True (OpenCV before 4.6) or False (4.6 and later)."""

    squares_x: int = 7
    squares_y: int = 5
    square: float = 30.0
    marker: float = 22.0
    dictionary: str = "DICT_5X5_100"
    legacy: bool | None = None

    kind: ClassVar[str] = "charuco"
    point_name: ClassVar[str] = "corner"
    first_corner_squares: ClassVar[int] = 1  # OpenCV's origin: the board's outer corner

    def __post_init__(self) -> None:
        for name in ("squares_x", "squares_y"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise BoardError(f"{name} must be a whole number of squares, got {value!r}")
            if not 2 <= value <= MAX_SQUARES_PER_SIDE:
                raise BoardError(
                    f"{name} must be between 2 and {MAX_SQUARES_PER_SIDE} squares, got {value}"
                )
        for name in ("square", "marker"):
            try:
                arguments.positive(name, getattr(self, name), BoardError)
            except BoardError:
                raise BoardError(
                    f"{name} must be a positive length in mm, got {getattr(self, name)!r}"
                ) from None
        if self.marker >= self.square:
            raise BoardError(
                f"markers of {self.marker:g} mm do not fit squares of {self.square:g} mm: the "
                "marker must be smaller than the square"
            )
        if self.legacy is not None and not isinstance(self.legacy, bool):
            raise BoardError(f"legacy must be None, True or False, got {self.legacy!r}")
        value = dictionary_id(self.dictionary)
        object.__setattr__(self, "dictionary", dictionary_name(value))
        available = len(_dictionary(value).bytesList)
        if self.n_markers > available:
            raise BoardError(
                f"a {self.squares_x} x {self.squares_y} ChArUco board needs {self.n_markers} "
                f"markers; {self.dictionary} has {available}"
            )

    @property
    def cols(self) -> int:
        """Inner corners along a row."""
        return self.squares_x - 1

    @property
    def rows(self) -> int:
        """Inner corners down a column."""
        return self.squares_y - 1

    @property
    def n_markers(self) -> int:
        return (self.squares_x * self.squares_y) // 2

    @property
    def orientation_fixed(self) -> bool:
        return True

    @property
    def layouts_differ(self) -> bool:
        """Whether the legacy and current layouts are different boards (an even number of
        rows)."""
        return self.squares_y % 2 == 0

    def opencv_board(self, legacy: bool | None = None) -> Any:
        """OpenCV's ``cv2.aruco.CharucoBoard`` of this board in mm, in the given layout (by
        default this board's, the current one when it is None)."""
        use = self.legacy if legacy is None else legacy
        board = cv2.aruco.CharucoBoard(
            (int(self.squares_x), int(self.squares_y)),
            float(self.square),
            float(self.marker),
            _dictionary(dictionary_id(self.dictionary)),
        )
        board.setLegacyPattern(bool(use))
        return board

    def opencv_dictionary(self) -> Any:
        return _dictionary(dictionary_id(self.dictionary))

    def marker_corners(self, legacy: bool | None = None) -> F64:
        """Each marker's four corners in mm, (n_markers, 4, 2), in id order, OpenCV's
        (top-left, top-right, bottom-right, bottom-left as printed)."""
        obj = np.asarray(self.opencv_board(legacy).getObjPoints(), np.float64)
        return obj[:, :, :2]

    @property
    def extent(self) -> tuple[float, float]:
        return (self.squares_x * float(self.square), self.squares_y * float(self.square))

    def ink(self, legacy: bool | None = None) -> BoardInk:
        """The black squares and the markers' black cells (the current layout unless this
        board, or `legacy`, says otherwise)."""
        s = float(self.square)
        corners = self.marker_corners(legacy)
        # Markers sit in the white squares; the black ones are the other colour of the
        # chessboard (which colour starts the top-left is the two layouts' difference).
        white = sum(map(sum, {(int(q[0, 0] // s), int(q[0, 1] // s)) for q in corners[:1]})) % 2
        rects = [
            (i * s, j * s, (i + 1) * s, (j + 1) * s)
            for j in range(self.squares_y)
            for i in range(self.squares_x)
            if (i + j) % 2 != white
        ]
        dictionary = self.opencv_dictionary()
        bits = int(dictionary.markerSize) + 2  # the marker's cells with its black border
        cell = float(self.marker) / bits
        parts = [np.array(rects, np.float64).reshape(-1, 4)]
        for marker_id, q in enumerate(corners):
            image = cv2.aruco.generateImageMarker(dictionary, marker_id, bits)
            parts.append(cell_runs(image < 128, float(q[0, 0]), float(q[0, 1]), cell))
        w, h = self.extent
        return BoardInk(np.vstack(parts), np.zeros((0, 4)), (0.0, 0.0, w, h))

    def describe(self) -> str:
        """One line for people: 'ChArUco 7 x 5 squares of 30 mm, markers 22 mm, DICT_5X5_100'."""
        layout = {None: "", True: ", legacy layout", False: ", current layout"}[self.legacy]
        return (
            f"ChArUco {self.squares_x} x {self.squares_y} squares of {self.square:g} mm, "
            f"markers {self.marker:g} mm, {self.dictionary}{layout}"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "type": self.kind,
            "squares_x": int(self.squares_x),
            "squares_y": int(self.squares_y),
            "square_mm": float(self.square),
            "marker_mm": float(self.marker),
            "dictionary": self.dictionary,
            "legacy": self.legacy,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CharucoBoard:
        try:
            return cls(
                squares_x=data["squares_x"],
                squares_y=data["squares_y"],
                square=data["square_mm"],
                marker=data["marker_mm"],
                dictionary=data["dictionary"],
                legacy=data.get("legacy"),
            )
        except (KeyError, TypeError, AttributeError) as e:
            raise BoardError(f"not a ChArUco board description ({e!r}): {data!r}") from None
