"""The `planarcal` command line: board, intrinsics, calibrate, register, check, locate, run,
live, demo.

Exit status: 0 on success; 1 when the job fails on its data (no board in view, a file that
cannot be read or written, an image the memory cannot hold); 2 for a malformed command line
(an unknown option, a value the command refuses: a negative --pitch, --cols 0, a bad -o) or
one asking for what is not installed (`--report` without matplotlib: the line names the
extra); 130 when interrupted (Ctrl-C). Each failure is one line on stderr, never a traceback.

This module is light: `planarcal --help` and `--version` import no numpy, OpenCV or core. A
command's arguments and work live in its module (``planarcal.commands``), imported when the
command is parsed (its own help included) or run.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import Any, NoReturn

from planarcal import __version__

# Each command, in the order `planarcal --help` lists them, with its line there.
COMMANDS = {
    "board": "write a printable board (SVG or PDF) at exact scale",
    "calibrate": "calibrate from an image of the board",
    "intrinsics": "estimate camera intrinsics from several board images",
    "register": "register the calibrated board to a robot's base frame from touch points",
    "check": "check a calibration file (or keep a deliberate edit of it: --accept-edits)",
    "locate": "locate objects in mm with a calibration",
    "run": "the production loop: objects in mm, frame after frame",
    "live": "the live setup page in a browser: aim, focus, calibrate, register, watch",
    "demo": "the whole pipeline on a rendered scene of the paper's setup",
}

# The status of a command that Ctrl-C ended, as a shell reports a process SIGINT killed.
INTERRUPTED = 130


# Where each command's arguments and work live (``add_arguments``/``add_parser`` and ``main``).
_MODULES = {
    "board": "planarcal.commands.board",
    "calibrate": "planarcal.commands.calibrate",
    "intrinsics": "planarcal.commands.intrinsics",
    "register": "planarcal.robot.register_command",
    "check": "planarcal.commands.check",
    "locate": "planarcal.commands.locate",
    "run": "planarcal.commands.run",
    "live": "planarcal.commands.live",
    "demo": "planarcal.commands.demo",
}


def _command_module(name: str) -> ModuleType:
    """The module of the command `name`, imported now: each loads what its command needs
    (numpy, OpenCV, SciPy, the core), which the top-level parser must not."""
    return importlib.import_module(_MODULES[name])


class _Parser(argparse.ArgumentParser):
    """argparse's parser with a malformed command line reported in one line (its usage is
    one `--help` away), exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


class _CommandParser(_Parser):
    """A command's parser, given its arguments when first used (parsing, or its help): the
    top-level parser lists the commands without importing what they need."""

    def __init__(self, *args: Any, command: str = "", **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._command = command

    def _fill(self) -> None:
        name, self._command = self._command, ""
        if not name:
            return
        module = _command_module(name)
        if hasattr(module, "add_arguments"):
            module.add_arguments(self)
        else:  # register keeps its own add_parser(subcommands): it fills this one
            module.add_parser(_Filling(self))
        self.set_defaults(run=module.main)

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        self._fill()
        return super().parse_known_args(args, namespace)

    def format_help(self) -> str:
        self._fill()
        return super().format_help()

    def format_usage(self) -> str:
        self._fill()
        return super().format_usage()


class _Filling:
    """Stands for argparse's subparsers to a command module that adds its own parser
    (``add_parser(subcommands)``): the parser it asks for is the one already listed."""

    def __init__(self, parser: argparse.ArgumentParser) -> None:
        self._parser = parser

    def add_parser(self, name: str, **kwargs: Any) -> argparse.ArgumentParser:
        if "description" in kwargs:
            self._parser.description = kwargs["description"]
        return self._parser


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="planarcal",
        description="Camera pixels to millimetres on a work plane: print a circle-grid board, "
        "calibrate from a picture of it, then locate objects in millimetres.",
    )
    parser.add_argument("--version", action="version", version=f"planarcal {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_CommandParser)
    for name, line in COMMANDS.items():
        commands.add_parser(name, help=line, command=name)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    words = sys.argv[1:] if argv is None else list(argv)
    try:
        return _main(words)
    finally:
        if argv is None and threading.current_thread() is threading.main_thread():
            # The program (not a caller's main([...])) is done and its output flushed: a
            # Ctrl-C now, while Python shuts down, would only print "Exception ignored"
            # tracebacks over a finished job.
            signal.signal(signal.SIGINT, signal.SIG_IGN)


def _main(words: list[str]) -> int:
    try:
        parser = build_parser()
        args = parser.parse_args(words)
        if args.command is None:
            parser.print_help(sys.stderr)
            return 2
        return _run(f"planarcal {args.command}", args.run, args)
    except KeyboardInterrupt:
        # Ctrl-C, perhaps while the command's modules were still loading: one line, no
        # traceback. What was being saved is whole or absent (files.atomic_write).
        name = next((w for w in words if w in COMMANDS), None)
        print(f"planarcal{'' if name is None else ' ' + name}: interrupted", file=sys.stderr)
        return INTERRUPTED


def _run(command: str, work: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """Runs a command: its status, or the failure's in one line on stderr."""
    import cv2  # noqa: PLC0415 (loaded by planarcal.errors already)

    from planarcal.errors import MissingDependencyError  # noqa: PLC0415 (errors loads OpenCV)

    try:
        code = work(args)
        sys.stdout.flush()
    except BrokenPipeError:
        # The reader went away (e.g. `| head`): not an error of ours. Python would complain
        # again when it flushes stdout at exit, so point stdout at nothing first.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except (argparse.ArgumentError, MissingDependencyError) as e:
        # A value the command refuses as malformed, or what this installation lacks.
        print(f"{command}: error: {e}", file=sys.stderr)
        return 2
    except (ValueError, OSError) as e:
        # The job failed on its data; anything else is a bug and keeps its traceback.
        print(f"{command}: error: {e}", file=sys.stderr)
        return 1
    except MemoryError as e:
        print(f"{command}: error: {_out_of_memory(str(e), args)}", file=sys.stderr)
        return 1
    except cv2.error as e:
        # OpenCV's allocator failing, or a C++ std::bad_alloc it passes on; the latter's code
        # and err are an earlier error's (OpenCV sets them on the class), so only its text.
        bad_alloc = str(e) == "std::bad_alloc"
        if not bad_alloc and e.code != cv2.Error.StsNoMem:
            raise
        detail = f"OpenCV: {str(e) if bad_alloc else e.err}"
        print(f"{command}: error: {_out_of_memory(detail, args)}", file=sys.stderr)
        return 1
    return code


def _out_of_memory(detail: str, args: argparse.Namespace) -> str:
    """The line for a job the memory could not hold (``detail``: what ran out, if said),
    with what to try."""
    if "memory" not in detail.lower():
        detail = f"out of memory ({detail})" if detail else "out of memory"
    roi = ", or look at part of it with --roi" if hasattr(args, "roi") else ""
    return (
        f"{detail}: free memory (close other programs), or give a smaller image (scaled "
        f"down, or cropped to the work area){roi}"
    )


if __name__ == "__main__":
    sys.exit(main())
