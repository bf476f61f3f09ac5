"""The synchronous sinks: ``StreamOutput`` writes each line to an open file descriptor
(stdout, a pipe) in one ``write``; ``FileOutput`` appends to a file, so that a crash leaves
only whole lines and a second run does not destroy the first one's record.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import stat
import sys

from planarcal.errors import OutputError
from planarcal.live.output_sink import Output
from planarcal.live.output_spec import SPEC_HELP

__all__ = ["FileOutput", "StreamOutput"]


class StreamOutput(Output):
    """Lines written to an open file descriptor (stdout, a pipe), synchronously: one
    ``write`` per line, so a line of up to PIPE_BUF bytes (4 KiB on Linux) is never
    interleaved with another writer's, and nothing sits in a user-space buffer to be lost
    on a crash (there is nothing to flush).

    A reader that has gone (EPIPE) makes the stream ``broken``: the error is counted once
    and every further line is dropped, because writing on would only fail again. When the
    stream is stdout (descriptor 1), descriptor 1 is then pointed at the null device, as
    Python's documentation advises, so that the interpreter's own flush of sys.stdout at
    exit does not print a BrokenPipeError traceback."""

    def __init__(self, fd: int, name: str, *, close_fd: bool = False) -> None:
        super().__init__(name)
        self._fd: int | None = fd
        self._close_fd = close_fd
        self._broken = False
        if fd == 1:
            # Whatever was printed to sys.stdout before must come out first.
            with contextlib.suppress(Exception):
                sys.stdout.flush()

    @property
    def broken(self) -> bool:
        return self._broken

    def _send(self, data: bytes) -> bool:
        with self._lock:
            if self._closing or self._fd is None:
                return self._drop(cause=f"a line sent after {self.spec} was closed")
            if self._broken:
                return self._drop()
            fd = self._fd
            view = memoryview(data)
            written = 0
            try:
                while written < len(data):
                    try:
                        written += os.write(fd, view[written:])
                    except BlockingIOError:
                        if written == 0:
                            # A non-blocking descriptor that is full: drop rather than wait.
                            return self._drop(
                                f"{self.spec} is full (non-blocking); line dropped",
                                full_buffer=True,
                            )
                        # Half a line is out: finish it, or the framing is lost.
                        select.select([], [fd], [])
            except BrokenPipeError as e:
                self._broken = True
                self._on_broken()
                return self._drop(
                    f"the reader of {self.spec} has gone ({e.strerror}); "
                    "every further line is dropped",
                    error=True,
                )
            except OSError as e:
                reason = f"cannot write to {self.spec}: {e.strerror or e}"
                if written and not self._undo_partial(fd, written):
                    self._broken = True
                    reason += "; half a line was written, so every further line is dropped"
                return self._drop(reason, error=True)
            self._n_sent += 1
            self._n_bytes += written
            return True

    def _undo_partial(self, fd: int, written: int) -> bool:
        """Removes the first `written` bytes of a line whose write failed, if the destination
        allows it (a file does, a pipe does not). True when the stream ends on a line
        boundary again."""
        return False

    def _on_broken(self) -> None:
        if self._fd == 1:
            with contextlib.suppress(OSError):
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, 1)
                os.close(devnull)

    def _close(self) -> None:
        with self._lock:
            fd, self._fd = self._fd, None
        if fd is not None and self._close_fd:
            self._sync(fd)
            with contextlib.suppress(OSError):
                os.close(fd)

    def _sync(self, fd: int) -> None:
        """Nothing for a stream: os.write leaves no user-space buffer to flush."""


class FileOutput(StreamOutput):
    """Lines appended to a file, created if absent.

    Appended, not truncated: running ``planarcal run -o positions.jsonl`` again must not
    destroy the previous hours of record; each line carries its timestamp, so runs stay
    apart. And not written through a temporary file renamed at the end (``files.atomic_write``):
    a stream is read while it grows (``tail -f``) and must hold everything up to a crash.
    Instead each line goes out in one ``write`` on a descriptor opened with O_APPEND, so a
    crash of the process leaves only complete lines (the data is in the kernel as soon as
    ``send`` returns). ``close`` also asks the disk to persist the file (fsync), once, not per
    line: hundreds of fsyncs per second would slow the loop for the sake of a power cut.

    A failed write (a full disk) is counted and the line dropped; if half of it reached the
    file, the file is cut back to the previous line end so that appending resumes on a line
    boundary. A file whose last line is unterminated when opened (a previous run's power
    cut) gets a newline first, for the same reason."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        name = os.fspath(path)
        if not name:
            raise OutputError(f"empty output: {SPEC_HELP}")
        directory = os.path.dirname(name) or "."
        if not os.path.isdir(directory):
            raise FileNotFoundError(
                errno.ENOENT, f"cannot open output file {name!r}: no directory {directory!r}"
            )
        flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_CLOEXEC", 0)
        flags |= getattr(os, "O_BINARY", 0)
        try:
            # The umask's mode, as open() would give (and as files.atomic_write gives).
            fd = os.open(name, flags, 0o666)
        except OSError as e:
            raise type(e)(
                e.errno, f"cannot open output file {name!r} for appending: {e.strerror}"
            ) from None
        try:
            self._terminate_last_line(fd, name)
        except OSError as e:
            os.close(fd)
            raise type(e)(e.errno, f"cannot append to output file {name!r}: {e.strerror}") from None
        super().__init__(fd, name, close_fd=True)

    @staticmethod
    def _terminate_last_line(fd: int, name: str) -> None:
        info = os.fstat(fd)
        if not (info.st_size and stat.S_ISREG(info.st_mode)):
            return
        try:
            with open(name, "rb") as f:
                f.seek(-1, os.SEEK_END)
                last = f.read(1)
        except OSError:  # a write-only file: cannot look, so do not guess
            return
        if last != b"\n":
            os.write(fd, b"\n")

    def _undo_partial(self, fd: int, written: int) -> bool:
        try:
            os.ftruncate(fd, os.fstat(fd).st_size - written)
        except OSError:
            return False
        return True

    def _sync(self, fd: int) -> None:
        with contextlib.suppress(OSError):
            os.fsync(fd)
