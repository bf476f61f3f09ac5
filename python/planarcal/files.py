"""Writing files atomically: the new content appears complete under its name, or not at all.
A crash or a full disk mid-write leaves any previous file untouched and no debris behind."""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
from pathlib import Path

# Write only, created here or not at all (no race with another writer's temporary file).
_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)


def atomic_write(path: str | os.PathLike[str], data: bytes | str) -> Path:
    """Writes `data` (text as UTF-8) to `path` through a temporary file in the same directory,
    flushed to disk, then renamed over `path`; the file gets the permissions a plain open()
    would give (0o666 less the umask). Raises OSError of the errno's subclass, its
    ``filename`` the path, when it cannot be written."""
    target = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        raise FileNotFoundError(
            errno.ENOENT, f"cannot write (no directory {str(directory)!r})", str(target)
        )
    tmp: Path | None = None
    try:
        fd, tmp = _create_temporary(target, directory)
        with os.fdopen(fd, "wb") as f:
            f.write(payload)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
        tmp = None
    except OSError as e:
        # OSError(errno, ...) is the errno's subclass (PermissionError, IsADirectoryError...).
        raise OSError(e.errno, f"cannot write ({e.strerror or e})", str(target)) from None
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):  # it vanished, or the directory did
                os.unlink(tmp)
    return target


def _create_temporary(target: Path, directory: Path) -> tuple[int, Path]:
    """A new file beside `target`, opened for writing: (its descriptor, its path). Mode 0o666
    and the umask, as open() would give (tempfile.mkstemp would give 0o600)."""
    for _ in range(100):
        candidate = directory / f".{target.name}.{secrets.token_hex(6)}.tmp"
        try:
            return os.open(candidate, _FLAGS, 0o666), candidate
        except FileExistsError:
            continue
    # Unreachable in practice: 100 collisions of 48 random bits.
    raise FileExistsError(errno.EEXIST, "no free temporary name", str(directory))
