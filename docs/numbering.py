"""The pictures of how each board type's points are numbered, for the documentation.

Usage (from the repository's root)::

    python docs/numbering.py

writes docs/images/numbering-circles.png, numbering-asymmetric.png, numbering-chessboard.png
and numbering-charuco.png: small boards of each type planarcal reads, as printed, each dot or
corner labelled with its id (k = row x cols + col, the order of ``Board.world_points()``),
the origin and the X and Y axes marked (planarcal.report.numbering)."""

from __future__ import annotations

from pathlib import Path

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.charuco import CharucoBoard
from planarcal.calib.chessboard import ChessboardBoard
from planarcal.files import atomic_write
from planarcal.report.numbering import numbering_figure

BOARDS = {
    "circles": CircleGridBoard(7, 5, 20.0),
    "asymmetric": CircleGridBoard(4, 7, 15.0, layout="asymmetric"),
    "chessboard": ChessboardBoard(7, 5, 25.0),
    "charuco": CharucoBoard(7, 5, 30.0, 22.0),
}


def main() -> None:
    out = Path(__file__).resolve().parent / "images"
    out.mkdir(exist_ok=True)
    for name, board in BOARDS.items():
        path = out / f"numbering-{name}.png"
        atomic_write(path, numbering_figure(board, width=900))
        print(f"{path}: {board.describe()}")


if __name__ == "__main__":
    main()
