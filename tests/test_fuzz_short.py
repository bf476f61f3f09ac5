"""The fuzzing campaign's short version (the full one: benches/bench_fuzz.py): thousands of
hostile inputs to every public entry point, from tests/fuzz_inputs.py's seeded generators,
judged there. Targets: no panic crossing into Python, no exception that is not planarcal's,
no result the documentation rules out, no H for a degenerate set, no corrupt file accepted,
and no crash (a sample run in a child process).

The campaign's findings (F1-F7, all fixed) are kept below as their minimal cases."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import fuzz_inputs
import planarcal as pc

SEED = 2026
NUMERIC_CASES = 3000
FILE_CASES = 100
# The outcomes that must never happen (fuzz_inputs' module docstring says what each means).
FAILURES = ("unclean", "panic", "bad_result", "degenerate_h", "corrupt_accepted")


@pytest.mark.parametrize("entry", list(fuzz_inputs.ENTRIES))
def test_hostile_inputs_get_a_clean_answer(entry: str) -> None:
    n = NUMERIC_CASES if entry in fuzz_inputs.NUMERIC_ENTRIES else FILE_CASES
    tally = fuzz_inputs.run(entry, SEED, 0, n)
    assert tally.inputs == n
    failures = {k: tally.outcomes[k] for k in FAILURES if tally.outcomes[k]}
    examples = "\n".join(f"  case {i}: {kind}: {detail}" for i, kind, detail in tally.findings[:8])
    assert not failures, f"{entry}: {failures}\n{examples}"
    # Both ends are exercised: some inputs are refused, some give results.
    assert tally.outcomes["error"] > 0
    assert tally.outcomes["result"] > 0


def test_the_judge_sees_each_kind_of_failure() -> None:
    """The harness itself: each outcome it counts is one it can see."""

    def panic() -> None:
        raise type("PanicException", (BaseException,), {})("boom")

    def raw() -> None:
        raise ZeroDivisionError("x")

    def fine(h: object) -> str | None:
        return fuzz_inputs.h_problem(h)

    collinear = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0], [4.0, 4.0]])
    judge, Case = fuzz_inputs.judge, fuzz_inputs.Case
    assert judge(Case(panic, (), {}, fine))[0] == "panic"
    assert judge(Case(raw, (), {}, fine))[0] == "unclean"
    assert judge(Case(lambda: np.full((3, 3), np.nan), (), {}, fine))[0] == "bad_result"
    assert judge(Case(lambda: np.eye(3), (), {}, fine))[0] == "result"
    degenerate = fuzz_inputs.h_checker(collinear, collinear)
    assert judge(Case(lambda: np.eye(3), (), {}, degenerate))[0] == "degenerate_h"
    all_but_one = collinear.copy()
    all_but_one[2] = [5.0, -3.0]
    assert fuzz_inputs.degenerate_reason(all_but_one) == "collinear but for one point, [5.0, -3.0]"
    assert fuzz_inputs.degenerate_reason(np.array([[0.0, 0], [1, 0], [0, 1], [1, 1]])) is None
    assert judge(Case(pc.estimate_homography, (collinear, collinear), {}, degenerate))[0] == (
        "error"
    )


def test_cases_are_rebuilt_identically_from_their_index() -> None:
    for entry in ("estimate_homography", "findHomography", "estimate_homography_robust"):
        batch = [c.describe() for _, c in fuzz_inputs.cases(entry, SEED, 100, 140)]
        alone = [fuzz_inputs.case_at(entry, SEED, i).describe() for i in (100, 139)]
        assert alone == [batch[0], batch[-1]]


def test_a_sample_runs_in_a_child_without_crashing(tmp_path: Path) -> None:
    """Crashes kill the process rather than raise: a sample of every entry point runs in a
    child with faulthandler on, which must finish and report every input judged."""
    tests = Path(__file__).resolve().parent
    script = textwrap.dedent(f"""
        import faulthandler, sys
        faulthandler.enable()
        sys.path.insert(0, {str(tests)!r})
        import fuzz_inputs
        for entry in fuzz_inputs.ENTRIES:
            n = 300 if entry in fuzz_inputs.NUMERIC_ENTRIES else 20
            tally = fuzz_inputs.run(entry, {SEED + 1}, 0, n)
            print(entry, tally.inputs, tally.outcomes["panic"])
    """)
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=False
    )
    assert done.returncode == 0, done.stderr[-3000:]
    lines = [line.split() for line in done.stdout.splitlines()]
    assert [line[0] for line in lines] == list(fuzz_inputs.ENTRIES)
    for entry, inputs, panics in lines:
        assert int(inputs) == (300 if entry in fuzz_inputs.NUMERIC_ENTRIES else 20)
        assert panics == "0", entry


def test_f1_an_inverse_beyond_float64_is_singular_not_a_bad_entry() -> None:
    # Its determinant and the bound on its rounding are both subnormal: adj / det overflowed.
    h = np.array(
        [
            [0.0, 1131.238578073096, 5e-324],
            [0.0, 7909.705425710727, 5e-324],
            [881.7450953346641, 0.0, 0.0],
        ]
    )
    with pytest.raises(pc.DegenerateError, match="singular"):
        pc.transform_points(h, [[1.0, 2.0]], inverse=True)


@pytest.mark.parametrize(
    "call",
    [
        lambda s, h: pc.estimate_homography(s, 2 * s, None),  # type: ignore[arg-type]
        lambda s, h: pc.estimate_homography(s, 2 * s, "svd", 1),  # type: ignore[arg-type]
        lambda s, h: pc.transform_points(h, s, inverse=None),  # type: ignore[arg-type]
        lambda s, h: pc.transform_points(h, s, invalid=None),  # type: ignore[arg-type]
        lambda s, h: pc.reprojection_errors(h, s, s, invalid=None),  # type: ignore[arg-type]
    ],
)
def test_f2_an_option_of_the_wrong_type_is_an_argument_type_error(call: object) -> None:
    s = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    with pytest.raises(pc.ArgumentTypeError):
        call(s, np.eye(3))  # type: ignore[operator]


def test_f3_stats_of_finite_errors_are_finite() -> None:
    stats = pc.error_stats(np.array([1e300, 1e300]))
    assert stats.rms == 1e300


@pytest.mark.parametrize("problems", [None, 3])
def test_f4_batch_of_a_non_iterable_is_an_argument_type_error(problems: object) -> None:
    with pytest.raises(pc.ArgumentTypeError):
        pc.estimate_homography_robust_batch(problems)  # type: ignore[arg-type]


@pytest.mark.parametrize("frame", [None, [], np.zeros(100, np.uint8)])
def test_f5_tracker_refuses_a_frame_that_is_not_an_image(frame: object) -> None:
    tracker = fuzz_inputs.fixtures().tracker
    with pytest.raises(pc.Error):
        tracker.process(frame)  # type: ignore[arg-type]


F6_FILE = """%YAML 1.2
---
image_width: 1280
image_height: 720
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 900., 0., 640., 0., 910., 360., 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   coJs: 1
   dt: d
   data: [ -0.1, 0.02, 0.001, -0.001, 0. ]
"""


def test_f6_an_opencv_matrix_without_cols_is_refused_without_a_crash(tmp_path: Path) -> None:
    """A damaged `cols` key in an intrinsics file: the load must raise IntrinsicsError, and
    the process must live on (the heap corruption shows as an abort or a segfault, at once or
    at a later free, so the load runs in a child, repeatedly)."""
    path = tmp_path / "camera.yml"
    path.write_text(F6_FILE)
    script = textwrap.dedent(f"""
        import planarcal
        for _ in range(200):
            try:
                planarcal.CameraIntrinsics.load_yaml({str(path)!r})
            except planarcal.IntrinsicsError:
                pass
            else:
                raise SystemExit("loaded")
        print("refused 200 times")
    """)
    # glibc's own checks make a corrupted heap abort at the first free that sees it.
    env = {**os.environ, "MALLOC_CHECK_": "3", "MALLOC_PERTURB_": "165"}
    done = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env=env,
    )
    assert (done.returncode, done.stdout.strip()) == (0, "refused 200 times"), done.stderr[-2000:]


@pytest.mark.parametrize("solver", pc.SOLVERS)
def test_f7_all_but_one_collinear_within_the_core_tolerance_is_degenerate(solver: str) -> None:
    # The bench's case 994382 (seed 15): the source is whole pixels, the destination's first
    # four points lie on one line to 9.4e-12 of their RMS radius.
    src = np.array([[2094, 1289], [2281, 1241], [1533, 1434], [2576, 1165], [1426, 1462]])
    dst = np.array(
        [
            [2184.0539268932484, -253.79535873920528],
            [2397.688518778658, -446.58145687066315],
            [1556.1673684513582, 312.8160621783439],
            [2739.536652726099, -755.0688011498846],
            [1438.2384331856933, 419.2363714080013],
        ]
    )
    assert fuzz_inputs.degenerate_reason(dst) is not None
    with pytest.raises(pc.DegenerateError):
        pc.estimate_homography(src, dst, solver)  # type: ignore[arg-type]
