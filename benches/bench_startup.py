"""Start-up time of the command line: a fresh process for each run, as a user starts it, the
median of many, interleaved so that the machine's other load falls on every case alike.
`python -c pass` is the floor no command can go below; "every command's modules" is what
each command loaded before they were imported lazily (issue 21). The CPU time (user + system)
of each process is given beside its wall time: on a machine busy with other work the wall
time grows with the wait for a core, the CPU time much less.

    python benches/bench_startup.py [--repeats 21] [--markdown]
"""

from __future__ import annotations

import argparse
import resource
import shutil
import statistics
import subprocess
import sys
import time

from reporting import cpu_model, load_average, table_lines

PY = sys.executable
# Every command's module: all that `planarcal --help` imported before issue 21.
EVERY_COMMAND = (
    "import planarcal.commands.board, planarcal.commands.calibrate, "
    "planarcal.commands.intrinsics, planarcal.commands.locate, planarcal.commands.run, "
    "planarcal.commands.demo, planarcal.robot.register_command"
)


def cases() -> list[tuple[str, list[str]]]:
    script = shutil.which("planarcal")
    cli = [script] if script is not None else [PY, "-m", "planarcal"]
    return [
        ("python -c pass (the floor)", [PY, "-c", "pass"]),
        ("python -c 'import planarcal'", [PY, "-c", "import planarcal"]),
        ("planarcal --version", [*cli, "--version"]),
        ("planarcal --help", [*cli, "--help"]),
        ("python -m planarcal --version", [PY, "-m", "planarcal", "--version"]),
        ("planarcal calibrate --help", [*cli, "calibrate", "--help"]),
        ("every command's modules", [PY, "-c", EVERY_COMMAND]),
    ]


def once(argv: list[str]) -> tuple[float, float]:
    """(wall, CPU) seconds of one run of `argv` in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=21, help="runs of each case (21)")
    parser.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    args = parser.parse_args()
    todo = cases()
    for _, argv in todo:  # warm the file cache: the first start reads everything from disk
        once(argv)
    walls: dict[str, list[float]] = {name: [] for name, _ in todo}
    cpus: dict[str, list[float]] = {name: [] for name, _ in todo}
    for _ in range(args.repeats):
        for name, argv in todo:
            wall, cpu = once(argv)
            walls[name].append(wall)
            cpus[name].append(cpu)
    floor = statistics.median(walls[todo[0][0]])
    rows = []
    for name, _ in todo:
        median = statistics.median(walls[name])
        rows.append(
            [
                name,
                f"{median * 1e3:.0f}",
                f"{min(walls[name]) * 1e3:.0f}",
                f"{(median - floor) * 1e3:+.0f}",
                f"{statistics.median(cpus[name]) * 1e3:.0f}",
            ]
        )
    headers = ["command", "median (ms)", "best (ms)", "above the floor (ms)", "CPU, median (ms)"]
    for line in table_lines(headers, [False, True, True, True, True], rows, args.markdown):
        print(line)
    print()
    print(f"{args.repeats} runs of each, a fresh process each time; {cpu_model()}")
    print(f"Python {sys.version.split()[0]}; load {load_average()}")


if __name__ == "__main__":
    main()
