"""Reading a small input file whole, safely: a regular file of at most a given size, or a
clear error. Without these checks a FIFO would wait for a writer for ever, ``/dev/zero`` or
``/dev/urandom`` would never end, and a directory or a huge file would fail slowly or eat
the memory. Every reader of the user's files (calibration, intrinsics, touch points) goes
through :func:`read_regular_file`, with its own size cap and its own exception type."""

from __future__ import annotations

import os
import stat
from pathlib import Path

# O_NONBLOCK: opening a FIFO for reading returns at once instead of waiting for a writer (a
# regular file ignores it); fstat on the opened descriptor then says what it really is, with
# no window for the path to be swapped between a check and the open.
_FLAGS = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO (named pipe), which would wait for a writer"),
    (stat.S_ISCHR, "a character device, which may never end"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def file_kind(mode: int) -> str:
    """What a file of st_mode ``mode`` is, for messages ("a directory", "a FIFO ...")."""
    for test, name in _KINDS:
        if test(mode):
            return name
    return "not a file"


def size_text(n_bytes: int) -> str:
    """A byte count for people: "1 MiB", "64 kiB", "500 bytes"."""
    for unit, size in (("GiB", 2**30), ("MiB", 2**20), ("kiB", 2**10)):
        if n_bytes >= size and n_bytes % size == 0:
            return f"{n_bytes // size} {unit}"
    return f"{n_bytes} bytes"


def read_regular_file(
    path: str | os.PathLike[str], what: str, max_bytes: int, error: type[Exception]
) -> bytes:
    """The bytes of the regular file at ``path``, at most ``max_bytes`` of them.

    Raises ``error`` (the caller's exception type) with a message naming ``what`` the file is
    ("calibration file") and the path: no such file, not a regular file (and what it is
    instead: a directory, a FIFO, a device), over the size cap, or not readable (the OS's
    reason)."""
    name = str(Path(path))
    try:
        fd = os.open(name, _FLAGS)
    except FileNotFoundError:
        raise error(f"no {what} at {name!r}") from None
    except OSError as e:
        raise error(f"cannot read the {what} {name!r}: {e.strerror or e}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise error(
                f"the {what} {name!r} is not a regular file: it is {file_kind(info.st_mode)}"
            )
        if info.st_size > max_bytes:
            raise error(_too_big(what, name, max_bytes))
        with os.fdopen(fd, "rb", closefd=False) as f:
            # One byte more than allowed tells a file that grew since fstat from one that fits.
            data = f.read(max_bytes + 1)
    except OSError as e:
        raise error(f"cannot read the {what} {name!r}: {e.strerror or e}") from None
    finally:
        os.close(fd)
    if len(data) > max_bytes:
        raise error(_too_big(what, name, max_bytes))
    return data


def _too_big(what: str, name: str, max_bytes: int) -> str:
    return f"the {what} {name!r} is over {size_text(max_bytes)}: too large to be one"
