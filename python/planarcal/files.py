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
each save first removes the temporary files of its own target untouched for a minute.

What is at the path decides how it is written:

- nothing, or a regular file: the atomic save above;
- a symbolic link (or a chain of them): the file it points to is saved atomically in its own
  directory, and the link stays a link; a dangling link gets its target created, if the
  target's directory exists;
- a FIFO or a character device (``/dev/null``, a terminal), or a link through ``/proc``
  (``/dev/stdout``, ``/dev/fd/1``, which name a process's open file): written directly, in
  place, as a stream is (not atomically: a stream has no previous content to keep, and the
  node itself is never replaced). Opening a FIFO waits for its reader, as any writer would;
- a directory, a block device or a socket: refused (``OSError`` naming what it is), never
  replaced or written."""

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

from planarcal.bounded_read import file_kind

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
# The kernel's own limit on the links followed in one path (Linux's MAXSYMLINKS).
_MAX_LINKS = 40
# A direct write never creates or truncates: the stream is there, and has no content to keep.
# O_APPEND: a regular file reached through /proc (a shell's `>> log`) is added to, not
# overwritten from its start; streams ignore it.
_STREAM_FLAGS = os.O_WRONLY | os.O_APPEND | getattr(os, "O_BINARY", 0)


def atomic_write(path: str | os.PathLike[str], data: bytes | str) -> Path:
    """Writes `data` (text as UTF-8) to `path`: the file appears complete, flushed to disk,
    or not at all, and nothing else is left in the directory. A new file gets the permissions
    a plain open() would give (0o666 less the umask); a file replaced keeps its permission
    bits. A symlink's target is saved and the link kept; a FIFO or a character device is
    written directly; a directory, a block device or a socket is refused (see the module's
    docstring). Raises OSError of the errno's subclass, its ``filename`` the path, when it
    cannot be written."""
    target = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    try:
        resolved, stream = _resolve_links(target)
        info = _stat_or_none(resolved, follow=stream)
    except OSError as e:
        raise OSError(e.errno, f"cannot write ({e.strerror or e})", str(target)) from None
    if stream or (info is not None and not stat.S_ISREG(info.st_mode)):
        _write_in_place(target, resolved, info, payload)
    else:
        _replace_atomically(target, resolved, payload)
    return target


def _replace_atomically(target: Path, resolved: Path, payload: bytes) -> None:
    """Saves `payload` as the regular file (or new file) `resolved`, which `target` names
    (itself, or through symlinks)."""
    directory = resolved.parent if str(resolved.parent) else Path(".")
    if not directory.is_dir():
        raise FileNotFoundError(
            errno.ENOENT, f"cannot write (no directory {str(directory)!r})", str(target)
        )
    remove_stale_temporaries(resolved)
    tmp: Path | None = None
    try:
        mode = _mode_to_keep(resolved)
        fd = _open_anonymous(directory)
        if fd is None:
            fd, tmp = _create_temporary(resolved, directory)
        try:
            _write_all(fd, payload)
            if mode is not None:
                _set_mode(fd, tmp, mode)
            os.fsync(fd)
            if tmp is None:
                _replace_with_anonymous(fd, resolved, directory)
        finally:
            os.close(fd)
        if tmp is not None:
            os.replace(tmp, resolved)
            tmp = None
        _sync_directory(directory)
    except OSError as e:
        # OSError(errno, ...) is the errno's subclass (PermissionError, IsADirectoryError...).
        raise OSError(e.errno, f"cannot write ({e.strerror or e})", str(target)) from None
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):  # it vanished, or the directory did
                os.unlink(tmp)


def _write_in_place(
    target: Path, resolved: Path, info: os.stat_result | None, payload: bytes
) -> None:
    """Writes `payload` straight into the stream `resolved` (a FIFO, a character device, a
    file named through /proc), which `target` names; refuses what must not be written."""
    kind = info.st_mode if info is not None else 0
    if info is None or not (stat.S_ISFIFO(kind) or stat.S_ISCHR(kind) or stat.S_ISREG(kind)):
        what = file_kind(kind) if info is not None else "not there"
        code = errno.EISDIR if stat.S_ISDIR(kind) else errno.EINVAL
        raise OSError(code, f"cannot write: it is {what}, which is never replaced", str(target))
    try:
        fd = os.open(resolved, _STREAM_FLAGS | _CLOEXEC)
        try:
            _write_all(fd, payload)
            if stat.S_ISREG(os.fstat(fd).st_mode):
                os.fsync(fd)
        finally:
            os.close(fd)
    except OSError as e:
        raise OSError(e.errno, f"cannot write ({e.strerror or e})", str(target)) from None


def _resolve_links(target: Path) -> tuple[Path, bool]:
    """The path `target` leads to once the symlinks of its last component are followed, and
    whether that path is a stream: a link inside /proc (``/dev/stdout`` leads to
    ``/proc/self/fd/1``) names an open file, not a place a file can be saved, so it is not
    followed further. Raises OSError (ELOOP) for a loop or too long a chain."""
    path = target
    for _ in range(_MAX_LINKS):
        info = _stat_or_none(path, follow=False)
        if info is None or not stat.S_ISLNK(info.st_mode):
            return path, False
        if _inside_proc(path):
            return path, True
        path = path.parent / os.readlink(path)  # an absolute link replaces the parent
    raise OSError(errno.ELOOP, os.strerror(errno.ELOOP), str(target))


def _inside_proc(path: Path) -> bool:
    """Whether `path`'s directory is in Linux's /proc (whose links name open files)."""
    directory = os.path.realpath(path.parent if str(path.parent) else ".")
    return directory == "/proc" or directory.startswith("/proc/")


def _stat_or_none(path: Path, follow: bool) -> os.stat_result | None:
    """`path`'s status (following a last symlink or not), or None if nothing is there."""
    try:
        return os.stat(path, follow_symlinks=follow)
    except (FileNotFoundError, NotADirectoryError):
        return None


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
