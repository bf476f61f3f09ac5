"""Writing files atomically: the new content appears complete under its name, or not at all.
A crash, a kill or a full disk mid-write leaves any previous file untouched and no debris
behind.

On Linux the content goes to an anonymous file in the target's directory (``O_TMPFILE``),
which the kernel deletes if the process dies before it has a name. Only once it is complete
and on disk is it linked in under a temporary name and at once renamed over the target. Where
``O_TMPFILE`` is refused (another OS, a filesystem without it) a named temporary file beside
the target is written instead. A process killed while writing that one leaves it behind (as
every save did before anonymous files were used), and one killed in the tens of microseconds
between the link and the rename leaves the complete content under the temporary name; so
each save first removes the temporary files of its own target untouched for a minute."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import secrets
import stat
import time
from collections.abc import Iterator
from pathlib import Path

# Write only, created here or not at all (no race with another writer's temporary file).
_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)

# Where a process's open files can be named, to link an anonymous file in (Linux).
_PROC_FD = "/proc/self/fd"
# Linux without O_TMPFILE opens the directory itself (EISDIR); filesystems without it say
# EOPNOTSUPP (= ENOTSUP on Linux), some EINVAL.
_ANONYMOUS_REFUSED = frozenset({errno.EOPNOTSUPP, errno.ENOTSUP, errno.EISDIR, errno.EINVAL})

# A temporary file untouched this long is a dead writer's: a live one writes it continuously
# and renames it within milliseconds. Generous, so that a slow disk never loses a save.
STALE_TEMPORARY_S = 60.0
_TOKEN_HEX = 12  # secrets.token_hex(6)


def atomic_write(path: str | os.PathLike[str], data: bytes | str) -> Path:
    """Writes `data` (text as UTF-8) to `path`: the file appears complete, flushed to disk,
    or not at all, and nothing else is left in the directory. A new file gets the permissions
    a plain open() would give (0o666 less the umask); a file replaced keeps its permission
    bits. Raises OSError of the errno's subclass, its ``filename`` the path, when it cannot be
    written."""
    target = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        raise FileNotFoundError(
            errno.ENOENT, f"cannot write (no directory {str(directory)!r})", str(target)
        )
    remove_stale_temporaries(target)
    tmp: Path | None = None
    try:
        mode = _mode_to_keep(target)
        fd = _open_anonymous(directory)
        if fd is None:
            fd, tmp = _create_temporary(target, directory)
        try:
            _write_all(fd, payload)
            if mode is not None:
                _set_mode(fd, tmp, mode)
            os.fsync(fd)
            if tmp is None:
                _replace_with_anonymous(fd, target, directory)
        finally:
            os.close(fd)
        if tmp is not None:
            os.replace(tmp, target)
            tmp = None
        _sync_directory(directory)
    except OSError as e:
        # OSError(errno, ...) is the errno's subclass (PermissionError, IsADirectoryError...).
        raise OSError(e.errno, f"cannot write ({e.strerror or e})", str(target)) from None
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):  # it vanished, or the directory did
                os.unlink(tmp)
    return target


def temporary_name_pattern(target: str | os.PathLike[str]) -> re.Pattern[str]:
    """The names atomic_write gives the temporary files of `target`: ``.<name>.<hex>.tmp``."""
    name = Path(target).name
    return re.compile(rf"\.{re.escape(name)}\.[0-9a-f]{{{_TOKEN_HEX}}}\.tmp")


def remove_stale_temporaries(
    target: str | os.PathLike[str], older_than_s: float = STALE_TEMPORARY_S
) -> list[Path]:
    """Removes the temporary files of `target` that dead writers left beside it (regular
    files named as atomic_write names them, unmodified for `older_than_s`); the paths removed.
    Best effort: whatever cannot be listed or removed is left."""
    target = Path(target)
    directory = target.parent if str(target.parent) else Path(".")
    pattern = temporary_name_pattern(target)
    deadline = time.time() - older_than_s
    removed: list[Path] = []
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    for entry in entries:
        if not pattern.fullmatch(entry.name):
            continue
        with contextlib.suppress(OSError):
            info = entry.stat(follow_symlinks=False)
            if stat.S_ISREG(info.st_mode) and info.st_mtime < deadline:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
    return removed


def _mode_to_keep(target: Path) -> int | None:
    """The permission bits of the regular file `target` replaces, or None if there is none."""
    try:
        info = os.lstat(target)
    except OSError:  # absent; anything else fails again, named, when it is replaced
        return None
    return stat.S_IMODE(info.st_mode) & 0o777 if stat.S_ISREG(info.st_mode) else None


def _set_mode(fd: int, tmp: Path | None, mode: int) -> None:
    if hasattr(os, "fchmod"):
        os.fchmod(fd, mode)
    elif tmp is not None:  # Windows before Python 3.13: only the read-only bit means anything
        os.chmod(tmp, mode)


def _write_all(fd: int, payload: bytes) -> None:
    view = memoryview(payload)
    while view:
        view = view[os.write(fd, view) :]


def _open_anonymous(directory: Path) -> int | None:
    """A nameless file in `directory` opened for writing (mode 0o666 and the umask), or None
    where the OS or the filesystem cannot make one or name it later."""
    flags = getattr(os, "O_TMPFILE", 0)
    if not flags or not os.path.isdir(_PROC_FD):
        return None
    try:
        # Not O_EXCL: that would forbid ever linking it in.
        return os.open(directory, flags | os.O_WRONLY | _CLOEXEC, 0o666)
    except OSError as e:
        if e.errno in _ANONYMOUS_REFUSED:
            return None
        raise


def _replace_with_anonymous(fd: int, target: Path, directory: Path) -> None:
    """Puts the anonymous file open as `fd` in place of `target`: linked in under a new
    temporary name, renamed over `target` at once. A kill between the two leaves the
    temporary name (complete content), so nothing else happens between them."""
    # os.link follows the /proc symlink to the file only through linkat(AT_SYMLINK_FOLLOW),
    # which it calls when given a directory descriptor (plain link() fails with EXDEV).
    proc_fd = os.open(_PROC_FD, os.O_RDONLY | os.O_DIRECTORY | _CLOEXEC)
    try:
        for candidate in _temporary_names(target, directory):
            try:
                os.link(str(fd), candidate, src_dir_fd=proc_fd, follow_symlinks=True)
            except FileExistsError:
                continue
            try:
                os.replace(candidate, target)
            except OSError:
                with contextlib.suppress(OSError):
                    os.unlink(candidate)
                raise
            return
    finally:
        os.close(proc_fd)
    raise _no_free_name(directory)


def _create_temporary(target: Path, directory: Path) -> tuple[int, Path]:
    """A new file beside `target`, opened for writing: (its descriptor, its path). Mode 0o666
    and the umask, as open() would give (tempfile.mkstemp would give 0o600)."""
    for candidate in _temporary_names(target, directory):
        try:
            return os.open(candidate, _FLAGS | _CLOEXEC, 0o666), candidate
        except FileExistsError:
            continue
    raise _no_free_name(directory)


def _temporary_names(target: Path, directory: Path) -> Iterator[Path]:
    """Names to try, in turn, for a temporary file of `target` (see temporary_name_pattern)."""
    for _ in range(100):
        yield directory / f".{target.name}.{secrets.token_hex(_TOKEN_HEX // 2)}.tmp"


def _no_free_name(directory: Path) -> OSError:
    # Unreachable in practice: 100 collisions of 48 random bits.
    return FileExistsError(errno.EEXIST, "no free temporary name", str(directory))


def _sync_directory(directory: Path) -> None:
    """Puts the rename on disk too, so the save survives a power cut once this returns.
    Best effort: some systems (Windows) cannot open a directory."""
    with contextlib.suppress(OSError):
        fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
