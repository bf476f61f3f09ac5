"""The fuzzing campaign: hostile inputs to every public entry point, counted (issue 15).

Each numeric entry point (estimate_homography with every solver, findHomography with every
flag, perspectiveTransform, transform_points, reprojection_errors, reprojection_stats, the
robust estimator and its batch, the tracker's core) gets --per-entry inputs (10^6 by default);
the image and file entry points (detect_board, Calibration.load, CameraIntrinsics.load_yaml,
locate_objects, Tracker.process, the registration to a robot, the calibration-file editor)
--per-file-entry; the sessions (a trigger server on loopback sockets with hostile clients,
`planarcal run` in a child over a hostile source) --per-session-entry. The inputs and the
judge of each call are tests/fuzz_inputs.py's (the suite's tests/test_fuzz_short.py runs a
few thousand of each).

The calls run in --workers worker processes, each watched by this one: a worker that dies is
a crash, one whose current call makes no progress for --hang-s seconds is a hang (its Python
stack is dumped, then it is killed); either way the input is rebuilt from its index and a
reproducer written to --findings (default /tmp/fuzz_findings/), with one for the first few
findings of every other kind. Memory: each worker's peak RSS.

    python benches/bench_fuzz.py                        # the full campaign (minutes to hours)
    python benches/bench_fuzz.py --per-entry 200000     # as large as fits
    python benches/bench_fuzz.py --quick                # 20000 / 200 / 20 inputs, minutes
    python benches/bench_fuzz.py --rust 100000          # also the core's proptest at that scale

Targets: 0 panics crossing into Python, 0 crashes, 0 hangs, 0 degenerate inputs given an H,
0 corrupt files accepted, 0 confident wrong answers (a registration of the wrong hand or
beyond 5 x its own std_mm of the truth, an edited file loaded with another meaning), 0 silent
losses (a request, a frame or a whole run lost without a word) (and 0 exceptions that are not
planarcal's, 0 results the docs rule out).
"""

from __future__ import annotations

import argparse
import faulthandler
import multiprocessing as mp
import os
import resource
import signal
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
TESTS = HERE.parent / "tests"
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(TESTS))

from reporting import cpu_model, load_average, table_lines  # noqa: E402

from fuzz_inputs import ENTRIES, NUMERIC_ENTRIES, SESSION_ENTRIES, Tally, judge  # noqa: E402
from planarcal.progress import counter, note  # noqa: E402

NUMERIC_UNIT = 5000
FILE_UNIT = 100
SESSION_UNIT = 5


def _self_test_case(rng: Any) -> Any:
    """--self-test's entry point: about 3% of its calls abort the process (a crash), 2% sleep
    forever (a hang), the rest return; the watcher must count exactly those (the case's note
    says which it is)."""
    import fuzz_inputs  # noqa: PLC0415

    u = float(rng.random())
    kind = "crash" if u < 0.03 else "hang" if u < 0.05 else ""

    def call() -> None:
        if kind == "crash":
            os.abort()
        if kind == "hang":
            time.sleep(1e6)

    return fuzz_inputs.Case(call, (), {}, lambda out: None, kind)


SELF_TEST = "self_test"


@dataclass
class Unit:
    entry: str
    start: int
    stop: int


@dataclass
class EntryReport:
    tally: Tally = field(default_factory=Tally)
    crashes: list[int] = field(default_factory=list)
    hangs: list[int] = field(default_factory=list)
    peak_rss_kib: int = 0
    seconds: float = 0.0


def worker(
    seed: int,
    tasks: Any,
    results: Any,
    heartbeat: Any,
    log_path: str,
) -> None:
    """Runs units until told to stop. `heartbeat` holds the index of the call under way, so the
    watcher knows which input a crash or a hang belongs to."""
    import fuzz_inputs  # noqa: PLC0415 (in the spawned process)

    log = open(log_path, "w")  # noqa: SIM115 (faulthandler writes to it until the end)
    faulthandler.enable(log)
    faulthandler.register(signal.SIGUSR1, file=log, all_threads=True)
    fuzz_inputs.ENTRIES[SELF_TEST] = _self_test_case
    while (unit := tasks.get()) is not None:
        tally = Tally()
        heartbeat[1], heartbeat[2] = unit.start, unit.stop
        for index, case in fuzz_inputs.cases(unit.entry, seed, unit.start, unit.stop):
            heartbeat[0] = index
            tally.add(index, *judge(case))
        heartbeat[0] = -1
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        results.put((unit, tally, rss))


def write_reproducer(folder: Path, entry: str, seed: int, index: int, what: str) -> Path:
    safe = entry.replace(".", "_")
    path = folder / f"{safe}_{what.split(':')[0].split()[0]}_{index}.py"
    path.write_text(
        f"# {entry}, seed {seed}, case {index}: {what}\n"
        f"# Run: PYTHONPATH={HERE.parent / 'python'} python {path}\n"
        "import sys\n"
        f"sys.path.insert(0, {str(TESTS)!r})\n"
        "import fuzz_inputs\n\n"
        f"case = fuzz_inputs.case_at({entry!r}, {seed}, {index})\n"
        "print(case.describe())\n"
        "print(fuzz_inputs.judge(case))\n"
    )
    return path


class Campaign:
    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.ctx = mp.get_context("spawn")
        self.findings = Path(args.findings)
        self.findings.mkdir(parents=True, exist_ok=True)
        self.reports: dict[str, EntryReport] = {}

    def run_entry(self, entry: str, count: int) -> EntryReport:
        """Every input of one entry point, on fresh workers (so peak RSS is this entry's)."""
        report = EntryReport()
        unit = {True: NUMERIC_UNIT, False: FILE_UNIT}[entry in NUMERIC_ENTRIES]
        unit = SESSION_UNIT if entry in SESSION_ENTRIES else unit
        pending = [Unit(entry, a, min(a + unit, count)) for a in range(0, count, unit)]
        tasks = self.ctx.Queue()
        # Written synchronously: a worker that dies right after reporting a unit (a crash in
        # its next) must not take the report with it, as a Queue's feeder thread would.
        results = self.ctx.SimpleQueue()
        for u in pending:
            tasks.put(u)
        outstanding = len(pending)
        started = time.perf_counter()
        workers = [self._start(tasks, results, k) for k in range(self.args.workers)]
        # The inputs judged so far (a unit's when it reports, a crash's or hang's at once).
        with counter(desc=f"  {entry}", total=count, unit="input") as bar:
            while outstanding:
                judged = report.tally.inputs
                if not results.empty():
                    u, tally, rss = results.get()
                    report.tally.merge(tally)
                    report.peak_rss_kib = max(report.peak_rss_kib, rss)
                    outstanding -= 1
                else:
                    time.sleep(0.2)
                    for k, w in enumerate(workers):
                        outstanding += self._watch(entry, w, tasks, report)
                        if not w[0].is_alive():
                            workers[k] = self._start(tasks, results, k)
                bar.update(report.tally.inputs - judged)
        for _ in workers:
            tasks.put(None)
        for w in workers:
            w[0].join(30)
            if w[0].is_alive():
                w[0].kill()
        report.seconds = time.perf_counter() - started
        return report

    def _start(self, tasks: Any, results: Any, k: int) -> list[Any]:
        # The index of the call under way (-1 between units), and its unit's start and stop.
        heartbeat = self.ctx.Array("q", [-1, 0, 0], lock=False)
        log = str(self.findings / f"worker{k}.log")
        p = self.ctx.Process(
            target=worker, args=(self.args.seed, tasks, results, heartbeat, log), daemon=True
        )
        p.start()
        # [process, heartbeat, (last index seen, when it changed), log]
        return [p, heartbeat, (-1, time.monotonic()), log]

    def _watch(self, entry: str, w: list[Any], tasks: Any, report: EntryReport) -> int:
        """A crash or a hang of worker `w`: counted, reproduced, and the rest of its unit given
        back to the queue. Returns how many units were added."""
        p, heartbeat, (last, since), log = w
        index, start, stop = heartbeat[0], heartbeat[1], heartbeat[2]
        now = time.monotonic()
        if not p.is_alive():
            if index == -1:  # between units: nothing lost (the caller starts another worker)
                return 0
            report.crashes.append(index)
            what = f"crash: exit code {p.exitcode}"
        elif index != last:
            w[2] = (index, now)
            return 0
        elif index == -1 or now - since < self.args.hang_s:
            return 0
        else:
            os.kill(p.pid, signal.SIGUSR1)  # faulthandler: the hung call's stack into the log
            time.sleep(1.0)
            p.kill()
            p.join()
            report.hangs.append(index)
            what = f"hang: no progress for {self.args.hang_s:g} s"
        tail = Path(log).read_text(errors="replace")[-3000:]
        path = write_reproducer(self.findings, entry, self.args.seed, index, what)
        path.with_suffix(".log").write_text(tail)
        note(f"  {entry} case {index}: {what} -> {path}", stream=sys.stdout)  # above the bar
        # The unit that held the case goes back to the queue without it.
        again = [Unit(entry, start, index), Unit(entry, index + 1, stop)]
        added = 0
        for u in again:
            if u.stop > u.start:
                tasks.put(u)
                added += 1
        # The lost unit's other cases are counted when rerun; the crashing one here.
        report.tally.inputs += 1
        return added - 1

    def count_of(self, entry: str) -> int:
        if entry in SESSION_ENTRIES:
            return int(self.args.per_session_entry)
        count: int = self.args.per_entry if entry in NUMERIC_ENTRIES else self.args.per_file_entry
        return count

    def run(self, entries: Sequence[str]) -> None:
        for entry in entries:
            count = self.count_of(entry)
            print(f"{entry}: {count} inputs ...", flush=True)
            report = self.run_entry(entry, count)
            self.reports[entry] = report
            self._write_finding_reproducers(entry, report)
            t = report.tally
            print(
                f"  {t.inputs} inputs in {report.seconds:.0f} s: {dict(t.outcomes)}",
                flush=True,
            )

    def _write_finding_reproducers(self, entry: str, report: EntryReport) -> None:
        seen: set[str] = set()
        for index, outcome, detail in report.tally.findings:
            if (outcome, detail[:60]) in seen:  # type: ignore[comparison-overlap]
                continue
            seen.add((outcome, detail[:60]))  # type: ignore[arg-type]
            write_reproducer(self.findings, entry, self.args.seed, index, f"{outcome}: {detail}")


def table(reports: dict[str, EntryReport], markdown: bool) -> list[str]:
    headers = [
        "entry point", "inputs", "results", "clean errors", "unclean errors (type: count)",
        "panics", "crashes", "hangs", "bad results", "degenerate given H", "corrupt accepted",
        "confident wrong answers", "silent losses", "peak RSS MiB", "time s",
    ]  # fmt: skip
    rows = []
    for entry, r in reports.items():
        o = r.tally.outcomes
        unclean = ", ".join(f"{k}: {v}" for k, v in r.tally.unclean_types.most_common()) or "0"
        rows.append(
            [
                entry,
                f"{r.tally.inputs:,}",
                f"{o['result']:,}",
                f"{o['error']:,}",
                unclean,
                str(o["panic"]),
                str(len(r.crashes)),
                str(len(r.hangs) + o["hang"]),
                str(o["bad_result"]),
                str(o["degenerate_h"]),
                str(o["corrupt_accepted"]),
                str(o["wrong_answer"]),
                str(o["silent_loss"]),
                f"{r.peak_rss_kib / 1024:.0f}",
                f"{r.seconds:.0f}",
            ]
        )
    right = [False, True, True, True, False] + [True] * 10
    return table_lines(headers, right, rows, markdown)


def verdict(reports: dict[str, EntryReport]) -> str:
    total = {
        "panics": sum(r.tally.outcomes["panic"] for r in reports.values()),
        "crashes": sum(len(r.crashes) for r in reports.values()),
        "hangs": sum(len(r.hangs) + r.tally.outcomes["hang"] for r in reports.values()),
        "degenerate given H": sum(r.tally.outcomes["degenerate_h"] for r in reports.values()),
        "corrupt accepted": sum(r.tally.outcomes["corrupt_accepted"] for r in reports.values()),
        "confident wrong answers": sum(r.tally.outcomes["wrong_answer"] for r in reports.values()),
        "silent losses": sum(r.tally.outcomes["silent_loss"] for r in reports.values()),
    }
    others = {
        "unclean errors": sum(r.tally.outcomes["unclean"] for r in reports.values()),
        "bad results": sum(r.tally.outcomes["bad_result"] for r in reports.values()),
    }
    met = all(v == 0 for v in total.values())
    says = ", ".join(f"{v} {k}" for k, v in {**total, **others}.items())
    return f"{'targets met' if met else 'TARGETS MISSED'}: {says} (targets: 0 each)"


def run_rust(cases: int) -> str:
    """The core's proptest of hostile inputs at `cases` cases a property."""
    command = ["cargo", "test", "--release", "-p", "planarcal-core", "--test", "hostile_inputs"]
    started = time.perf_counter()
    done = subprocess.run(
        command,
        cwd=HERE.parent,
        env={**os.environ, "PROPTEST_CASES": str(cases)},
        capture_output=True,
        text=True,
        check=False,
    )
    summary = [
        line for line in done.stdout.splitlines() if line.startswith(("test ", "test result"))
    ]
    return (
        f"PROPTEST_CASES={cases} {' '.join(command)} ({time.perf_counter() - started:.0f} s):\n"
        + "\n".join(summary or done.stderr.splitlines()[-20:])
    )


def self_test(args: argparse.Namespace) -> None:
    """The watcher itself: an entry point that crashes and hangs on known cases, which must be
    counted exactly (each reproducer written, the rest of every unit still run)."""
    import fuzz_inputs  # noqa: PLC0415

    fuzz_inputs.ENTRIES[SELF_TEST] = _self_test_case
    args.per_file_entry, args.hang_s = 120, 3.0
    expected = Counter(c.note for _, c in fuzz_inputs.cases(SELF_TEST, args.seed, 0, 120))
    campaign = Campaign(args)
    campaign.run([SELF_TEST])
    report = campaign.reports[SELF_TEST]
    got = (len(report.crashes), len(report.hangs), report.tally.inputs)
    want = (expected["crash"], expected["hang"], 120)
    print(f"crashes, hangs, inputs: {got}, expected {want}")
    if got != want:
        raise SystemExit("the watcher miscounted")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--per-entry", type=int, default=1_000_000)
    parser.add_argument("--per-file-entry", type=int, default=3000)
    parser.add_argument("--per-session-entry", type=int, default=200)
    parser.add_argument("--quick", action="store_true", help="20000 / 200 / 20 inputs an entry")
    parser.add_argument("--only", nargs="+", choices=list(ENTRIES), default=list(ENTRIES))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=15)
    parser.add_argument("--hang-s", type=float, default=60.0)
    parser.add_argument("--findings", default="/tmp/fuzz_findings")
    parser.add_argument("--rust", type=int, metavar="CASES", help="also run the core's proptest")
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--self-test", action="store_true", help="check the crash/hang watcher")
    args = parser.parse_args()
    if args.quick:
        args.per_entry, args.per_file_entry, args.per_session_entry = 20_000, 200, 20
    if args.self_test:
        self_test(args)
        return
    campaign = Campaign(args)
    started = time.perf_counter()
    campaign.run(args.only)
    print()
    print(f"planarcal fuzzing campaign, seed {args.seed}, {args.workers} workers, {cpu_model()}")
    print(f"load {load_average()}; {time.perf_counter() - started:.0f} s in all")
    print("\n".join(table(campaign.reports, args.markdown)))
    print(verdict(campaign.reports))
    print(f"reproducers: {args.findings}/")
    if args.rust:
        print(run_rust(args.rust))


if __name__ == "__main__":
    main()
