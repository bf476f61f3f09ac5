"""Progress of long work (a folder of images, a camera's frames, a bench, a fuzz campaign),
drawn by tqdm on stderr only when stderr is a terminal: never on stdout (which carries --json
and the tables), and nothing at all in a pipe, a log file or a test's captured output."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Iterator
from types import TracebackType
from typing import Protocol, TextIO, TypeVar

# tqdm ships no type information (no py.typed); its bars are typed by Bar below.
from tqdm import tqdm  # type: ignore[import-untyped]

T = TypeVar("T")


class Bar(Protocol):
    """A bar advanced by hand (work that is not one loop over an iterable)."""

    def update(self, n: int = 1) -> object: ...

    def close(self) -> None: ...

    def __enter__(self) -> Bar: ...

    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        traceback: TracebackType | None,
    ) -> object: ...


def drawn(stream: TextIO | None = None) -> bool:
    """Whether a bar is drawn on ``stream`` (stderr by default): a terminal that can move
    back to the start of a line (TERM=dumb ones, such as an editor's shell, print every
    redraw as a new line). NO_COLOR needs nothing: the bars have no colour."""
    stream = sys.stderr if stream is None else stream
    try:
        terminal = stream.isatty()
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False
    return terminal and os.environ.get("TERM") != "dumb"


def progress(
    iterable: Iterable[T],
    *,
    desc: str,
    total: int | None = None,
    unit: str = "it",
    leave: bool = False,
    stream: TextIO | None = None,
) -> Iterator[T]:
    """``iterable``'s items, with a bar counting them on ``stream`` (stderr by default,
    looked up at the call so that a redirected sys.stderr is honoured) when drawn() says so;
    otherwise the items alone. ``total`` where len(iterable) does not tell; ``leave``
    keeps the finished bar (a bench's record), else it is erased (a command's output stays
    what it was)."""
    if not drawn(stream):
        yield from iterable
        return
    stream = sys.stderr if stream is None else stream
    # Closed (erased unless leave) when the loop ends, breaks or raises.
    yield from tqdm(
        iterable, desc=desc, total=total, unit=unit, leave=leave, file=stream, **_width(stream)
    )


def counter(
    *,
    desc: str,
    total: int | None = None,
    unit: str = "it",
    leave: bool = False,
    stream: TextIO | None = None,
) -> Bar:
    """A bar advanced with update(n), for work that is not one loop (a campaign's units
    reported by its workers); with nothing drawn where drawn() says no."""
    return _bar(desc=desc, total=total, unit=unit, leave=leave, stream=stream)


def note(text: str, stream: TextIO | None = None) -> None:
    """A line of text on ``stream`` (stderr by default) above any bar under way, which is
    redrawn below it (a plain print would be overwritten by the bar's next redraw)."""
    stream = sys.stderr if stream is None else stream
    if drawn(stream):
        tqdm.write(text, file=stream)
    else:
        print(text, file=stream, flush=True)


def _bar(*, desc: str, total: int | None, unit: str, leave: bool, stream: TextIO | None) -> Bar:
    stream = sys.stderr if stream is None else stream
    bar: Bar = tqdm(
        desc=desc,
        total=total,
        unit=unit,
        leave=leave,
        file=stream,
        disable=not drawn(stream),
        **_width(stream),
    )
    return bar


def _width(stream: TextIO) -> dict[str, object]:
    """Follow the terminal's width when it is resized; a terminal that reports no size (a
    bare pseudo-terminal, some serial consoles) gets 80 x 24, where tqdm would hide the bar
    (it hides bars below the terminal's last row, and takes such a terminal for 0 rows)."""
    try:
        columns = os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, OSError, ValueError):
        columns = 0
    return {"dynamic_ncols": True} if columns > 0 else {"ncols": 80, "nrows": 24}
