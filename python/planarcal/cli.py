"""The `planarcal` command line."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from planarcal import __version__


def _demo(_: argparse.Namespace) -> int:
    from planarcal import demo

    print(demo.run())
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="planarcal",
        description="Camera pixels to millimetres on a work plane.",
    )
    parser.add_argument("--version", action="version", version=f"planarcal {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = commands.add_parser(
        "demo",
        help="calibrate on the paper's built-in data and map its objects to millimetres",
        description="Fit the paper's published points with every solver, report the errors, "
        "and map the paper's objects from pixels to millimetres. Needs no camera and no files.",
    )
    demo.set_defaults(run=_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    code: int = args.run(args)
    return code


if __name__ == "__main__":
    sys.exit(main())
