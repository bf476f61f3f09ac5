"""The touch-point file of ``planarcal register``: a CSV with a header and one of three column
sets (mm; z optional where shown):

* ``dot,robot_x,robot_y[,robot_z]`` (a circle grid) or ``corner,robot_x,robot_y[,robot_z]``
  (a chessboard or a ChArUco board): the id of the board point the robot's tool touched,
  0-based as ``board.world_points()`` numbers them (k = row x cols + col, 0 the origin
  point);
* ``board_x,board_y,robot_x,robot_y[,robot_z]``: the touched point's board position;
* ``image_x,image_y,robot_x,robot_y``: N-point, where the camera saw (px) the part the robot
  placed.

Forgiving where nothing can be misread: a UTF-8 byte-order mark (Excel's), spaces around
names and numbers, header names in any case and in any order, blank lines, ``#`` comment
lines, and ``;`` or tab as the separator when the header uses it. Everything else is an
ArgumentError naming the file and line: an unknown or missing column, a mix of column sets, a
row of the wrong length, a field that is not a number (a decimal comma is named as such), a
point id that is not a whole number, no points at all.

The id column names the kind of point the robot touched, and ``check_point_name`` holds it to
the calibration's board: a ``dot`` column with a chessboard's calibration (or ``corner`` with a
circle grid's) is refused, not read as the other. The ids mean the same on every board, but a
header naming the other kind of point is the sign of a mix-up a fit cannot see (the CSV of
another cell's board, or the calibration of another board: touches of a 14 x 10 circle grid
read on a 9 x 6 chessboard give a poor fit, or a good one on the wrong points), and renaming
one header word costs the user nothing when it is no mix-up."""

from __future__ import annotations

import csv
import dataclasses
import math
import os
from pathlib import Path
from typing import Literal

import numpy as np

from planarcal.bounded_read import read_regular_file
from planarcal.errors import ArgumentError
from planarcal.robot.transform_fit import F64

Kind = Literal["dot", "corner", "board", "image"]

# The kinds whose board side is a board point's id: the column is the board's point_name.
ID_KINDS: tuple[Kind, ...] = ("dot", "corner")

# The columns naming the board side of each kind, and the robot side they all share.
BOARD_SIDE: dict[Kind, tuple[str, ...]] = {
    "dot": ("dot",),
    "corner": ("corner",),
    "board": ("board_x", "board_y"),
    "image": ("image_x", "image_y"),
}
ROBOT_SIDE = ("robot_x", "robot_y")
ROBOT_Z = "robot_z"

COLUMN_SETS = (
    "dot,robot_x,robot_y[,robot_z]",
    "corner,robot_x,robot_y[,robot_z]",
    "board_x,board_y,robot_x,robot_y[,robot_z]",
    "image_x,image_y,robot_x,robot_y",
)


@dataclasses.dataclass(frozen=True)
class TouchPoints:
    """The pairs a touch-point file holds: ``kind`` of board side, the board side itself
    (``dots`` (N,): the point ids of a ``dot`` or a ``corner`` column, the field named so for
    every board; or ``board`` (N, 2) in mm or px), the robot points (N, 2) mm, their z (N,) or
    None, the file's line number of each pair (for messages) and of its header."""

    kind: Kind
    dots: list[int] | None
    board: F64 | None
    robot: F64
    robot_z: F64 | None
    lines: tuple[int, ...]
    header_line: int = 1

    @property
    def point_name(self) -> str | None:
        """The kind of board point the id column names ("dot", "corner"), or None for
        pairs given as positions."""
        return self.kind if self.kind in ID_KINDS else None

    def describe(self, index: int) -> str:
        """Pair ``index`` as a user finds it in the file: its point ("dot 7", "corner 7"; or
        its row from 0 and its board side) and its line, as the register table names them."""
        where = f"line {self.lines[index]}"
        if self.dots is not None:
            return f"{self.kind} {self.dots[index]} ({where})"
        assert self.board is not None
        x, y = self.board[index]
        unit = "px" if self.kind == "image" else "mm"
        return f"touch {index} ({where}: {x:g}, {y:g} {unit})"


MAX_FILE_BYTES = 2**20
"""The largest touch-point file read (a few dozen lines are a few kB)."""


def read_touch_csv(path: str | os.PathLike[str]) -> TouchPoints:
    """The pairs in the touch-point CSV at ``path``; ArgumentError naming the line for
    anything that cannot be read as one of the column sets, or naming the file if it cannot
    be read at all."""
    name = str(Path(path))
    raw = read_regular_file(path, "touch-point file", MAX_FILE_BYTES, ArgumentError)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise ArgumentError(f"{name}: not a UTF-8 text file ({e.reason})") from None
    rows = [
        (number, line)
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise ArgumentError(
            f"{name} is empty: give a header and one row per point, with the columns "
            + " or ".join(COLUMN_SETS)
        )
    header_line, header_text = rows[0]
    delimiter = _delimiter(header_text)
    header = [h.strip().lower() for h in _split(header_text, delimiter, name, header_line)]
    kind, columns = _kind(header, name, header_line)
    if len(rows) == 1:
        raise ArgumentError(f"{name} has a header but no points (line {header_line})")

    values: dict[str, list[float]] = {c: [] for c in columns}
    lines = []
    for number, line in rows[1:]:
        fields = [f.strip() for f in _split(line, delimiter, name, number)]
        if len(fields) != len(header):
            raise ArgumentError(
                f"{name} line {number}: {len(fields)} fields, the header has {len(header)} "
                f"({','.join(header)})"
            )
        for column, field in zip(header, fields, strict=True):
            values[column].append(_number(field, column, name, number, delimiter))
        lines.append(number)

    robot = np.column_stack([values[c] for c in ROBOT_SIDE])
    z = np.asarray(values[ROBOT_Z]) if ROBOT_Z in values else None
    dots = None
    board = None
    if kind in ID_KINDS:
        dots = []
        for v, number in zip(values[kind], lines, strict=True):
            if not v.is_integer():
                raise ArgumentError(
                    f"{name} line {number}: {kind} {v:g} is not a {kind} index (a whole number)"
                )
            dots.append(int(v))
    else:
        board = np.column_stack([values[c] for c in BOARD_SIDE[kind]])
    return TouchPoints(kind, dots, board, robot, z, tuple(lines), header_line)


def check_point_name(
    touches: TouchPoints,
    point_name: str,
    board_description: str,
    path: str | os.PathLike[str],
    calibration_path: str | os.PathLike[str] | None = None,
) -> None:
    """ArgumentError when the id column of ``touches`` (read from ``path``) names another
    kind of point than the calibration's board has (``point_name``, its ``describe()`` as
    ``board_description``): a ``dot`` column for a chessboard, a ``corner`` column for a
    circle grid. Pairs given as positions name no kind and pass."""
    named = touches.point_name
    if named is None or named == point_name:
        return
    calibration = "the calibration" if calibration_path is None else str(calibration_path)
    raise ArgumentError(
        f"{Path(path)} line {touches.header_line}: its {named!r} column gives {named} ids, but "
        f"the board of {calibration} ({board_description}) has {point_name}s, not {named}s: "
        f"if the robot touched that board, name the column {point_name!r} (the same 0-based "
        "ids, k = row x cols + col), else give the calibration of the board it touched"
    )


def _delimiter(header: str) -> str:
    # The header's own separator: it holds no numbers, so no decimal comma confuses it.
    for candidate in (",", ";", "\t"):
        if candidate in header:
            return candidate
    return ","


def _split(line: str, delimiter: str, name: str, number: int) -> list[str]:
    """The fields of one line; ArgumentError naming it where the csv module cannot read it (a
    field over its size limit, a NUL byte)."""
    try:
        return next(csv.reader([line], delimiter=delimiter))
    except csv.Error as e:
        raise ArgumentError(f"{name} line {number}: not a CSV row ({e})") from None


def _kind(header: list[str], name: str, line: int) -> tuple[Kind, list[str]]:
    """The kind of board side the header names, and its columns; ArgumentError otherwise."""
    accepted = " or ".join(COLUMN_SETS)
    duplicates = sorted({h for h in header if header.count(h) > 1})
    if duplicates:
        raise ArgumentError(f"{name} line {line}: column(s) {', '.join(duplicates)} given twice")
    known = {ROBOT_Z, *ROBOT_SIDE, *(c for cs in BOARD_SIDE.values() for c in cs)}
    unknown = [h for h in header if h not in known]
    if unknown:
        raise ArgumentError(
            f"{name} line {line}: unknown column(s) {', '.join(map(repr, unknown))}; the "
            f"header must be one of {accepted}"
        )
    kinds: list[Kind] = [k for k, cs in BOARD_SIDE.items() if any(c in header for c in cs)]
    if len(kinds) != 1:
        what = (
            "no board side (dot, corner, board_x/board_y or image_x/image_y)"
            if not kinds
            else f"more than one board side ({' and '.join(kinds)} columns)"
        )
        raise ArgumentError(f"{name} line {line}: the header has {what}; use one of {accepted}")
    kind = kinds[0]
    missing = [c for c in (*BOARD_SIDE[kind], *ROBOT_SIDE) if c not in header]
    if missing:
        raise ArgumentError(
            f"{name} line {line}: missing column(s) {', '.join(missing)}; use one of {accepted}"
        )
    if kind == "image" and ROBOT_Z in header:
        raise ArgumentError(
            f"{name} line {line}: robot_z is not used with image_x,image_y (N-point) pairs: "
            "the part's height is not the plane's; drop the column"
        )
    return kind, header


def _number(field: str, column: str, name: str, line: int, delimiter: str) -> float:
    try:
        v = float(field)
    except ValueError:
        hint = ""
        if delimiter != "," and "," in field:
            hint = " (a decimal comma? write a decimal point)"
        raise ArgumentError(
            f"{name} line {line}: {column} {field!r} is not a number{hint}"
        ) from None
    if not math.isfinite(v):
        raise ArgumentError(f"{name} line {line}: {column} {field!r} is not a finite number")
    return v
