"""Every board type planarcal reads, as one type: a layout (its points' ids and world mm,
what its page shows, whether it fixes its own orientation) that a detector of its kind finds
in an image (planarcal.calib.detection). Everything after detection works on point ids and
world points, whatever the type ("Boards as plug-ins").

Each layout has ``kind`` ("circles", "chessboard", "charuco"), ``point_name`` ("dot",
"corner"), ``n_points``, ``world_points()`` (id -> mm), ``pitch`` (the distance between
neighbouring points), ``extent``, ``orientation_fixed``, ``ink()``, ``describe()``,
``to_dict()`` and ``from_dict()``.
"""

from __future__ import annotations

from typing import Any

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.errors import BoardError

Board = CircleGridBoard | ChessboardBoard | CharucoBoard
"""Any board planarcal reads."""

BOARD_CLASSES: dict[str, type[CircleGridBoard] | type[ChessboardBoard] | type[CharucoBoard]] = {
    "circles": CircleGridBoard,
    "chessboard": ChessboardBoard,
    "charuco": CharucoBoard,
}
BOARD_TYPES: tuple[str, ...] = tuple(BOARD_CLASSES)
"""The board types by name, as the CLI's ``--type`` and the file's ``board.type`` name them."""


def is_board(value: object) -> bool:
    return isinstance(value, CircleGridBoard | ChessboardBoard | CharucoBoard)


def board_from_dict(data: Any) -> Board:
    """The board a to_dict() description gives (``type`` "circles" when absent, as files
    written before there were other types); BoardError if it is not one."""
    if not isinstance(data, dict):
        raise BoardError(f"a board description must be a JSON object, got {data!r}")
    kind = data.get("type", "circles")
    cls = BOARD_CLASSES.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise BoardError(f"board type must be one of {', '.join(BOARD_TYPES)}, got {kind!r}")
    return cls.from_dict({k: v for k, v in data.items() if k != "type"})
