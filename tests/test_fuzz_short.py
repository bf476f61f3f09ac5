"""The fuzzing campaign's short version (the full one: benches/bench_fuzz.py): thousands of
hostile inputs to every public entry point, from tests/fuzz_inputs.py's seeded generators,
judged there. Targets: no panic crossing into Python, no exception that is not planarcal's,
no result the documentation rules out, no H for a degenerate set, no corrupt file accepted,
and no crash (a sample run in a child process). Issue 21's entry points besides: the
registration to a robot (no confident wrong answer), every edit of a saved calibration (none
loaded with another meaning), trigger-server sessions and `planarcal run` over damaged
sources (no silent loss, no hang, no traceback).

The campaign's findings (F1-F7 and F9-F13, all fixed) are kept below as their minimal
cases."""

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


# Beside NUMERIC_CASES and FILE_CASES: the registration's cases cost a millisecond or so.
CASES = {"registration": 400}
# Run on their own below: every edit of a file is thousands, a session takes a second.
APART = {"calibration_editor", *fuzz_inputs.SESSION_ENTRIES}


@pytest.mark.parametrize("entry", [e for e in fuzz_inputs.ENTRIES if e not in APART])
def test_hostile_inputs_get_a_clean_answer(entry: str) -> None:
    n = NUMERIC_CASES if entry in fuzz_inputs.NUMERIC_ENTRIES else CASES.get(entry, FILE_CASES)
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
            if entry in fuzz_inputs.SESSION_ENTRIES:
                continue  # sockets and child processes of their own, below
            n = 300 if entry in fuzz_inputs.NUMERIC_ENTRIES else 20
            tally = fuzz_inputs.run(entry, {SEED + 1}, 0, n)
            print(entry, tally.inputs, tally.outcomes["panic"])
    """)
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=False
    )
    assert done.returncode == 0, done.stderr[-3000:]
    lines = [line.split() for line in done.stdout.splitlines()]
    entries = [e for e in fuzz_inputs.ENTRIES if e not in fuzz_inputs.SESSION_ENTRIES]
    assert [line[0] for line in lines] == entries
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


# -- issue 21: the registration, the calibration-file editor, the trigger server, run sources


def _failures(tally: fuzz_inputs.Tally) -> str:
    failures = {k: tally.outcomes[k] for k in FAILURES if tally.outcomes[k]}
    examples = "\n".join(f"  case {i}: {kind}: {detail}" for i, kind, detail in tally.findings[:8])
    return f"{failures}\n{examples}" if failures else ""


def test_every_node_of_a_saved_calibration_edited_is_refused_or_means_the_same() -> None:
    """Every 11th of the editor's edits (each node of a real file with a registration changed
    in type and value, lists shortened and lengthened, keys removed and added): each load
    raises CalibrationFileError or maps a fixed set of pixels to the same board and robot
    mm, and saves again."""
    fx = fuzz_inputs.registered_fixture()
    tally = fuzz_inputs.Tally()
    rng = np.random.default_rng(SEED)
    for index in range(0, len(fx.edits), 11):
        tally.add(index, *fuzz_inputs.judge(fuzz_inputs.case_calibration_edit(rng, index)))
    assert not _failures(tally), _failures(tally)
    assert tally.outcomes["error"] > 0
    assert tally.outcomes["result"] > 0


def test_trigger_server_sessions_lose_no_request() -> None:
    """Hostile clients on loopback (overlong lines, binary, floods, half-closed, resets,
    clients that never read, idle ones beyond the cap), then a well-behaved controller that
    must get its answer; every request exactly one reply."""
    tally = fuzz_inputs.run("trigger_server", SEED, 0, 8)
    assert not _failures(tally), _failures(tally)
    assert tally.outcomes["result"] == 8


@pytest.mark.parametrize("kind", ["video zeroed", "folder vanishing", "folder mixed"])
def test_planarcal_run_over_a_hostile_source_loses_nothing_silently(
    kind: str, tmp_path: Path
) -> None:
    """`planarcal run` in a child over a damaged source: no traceback, no hang, and never
    exit 0 with frames lost and no report of it, or having delivered nothing."""
    plan = fuzz_inputs.source_plan(np.random.default_rng(SEED), kind)
    done = fuzz_inputs.run_on_source(plan, tmp_path / "source")
    assert fuzz_inputs.run_problem(done, plan) is None, done["stderr"][-3000:]


def test_the_judge_sees_wrong_answers_silent_losses_and_hangs() -> None:
    """The new judges, on made-up outcomes: a registration of the wrong hand, one far from
    its truth, a controller without its answer, a request answered twice, a run that says
    nothing of a loss, one that delivered nothing, a traceback, a hang."""
    plane = np.array([[0.0, 0.0], [200.0, 0.0], [0.0, 150.0], [200.0, 150.0], [90.0, 60.0]])
    mirror = np.array([[0.0, 1.0, 300.0], [1.0, 0.0, -50.0], [0.0, 0.0, 1.0]])
    truth = fuzz_inputs.RobotTruth(mirror, True, "rigid", 0.0)
    frame = pc.RobotFrame.fit(plane, truth.apply(plane))
    known = fuzz_inputs.RegistrationCase(truth, plane, True)
    assert fuzz_inputs.registration_error(frame, known) is None
    wrong_hand = fuzz_inputs.RobotTruth(mirror, False, "rigid", 0.0)
    found = fuzz_inputs.registration_error(
        frame, fuzz_inputs.RegistrationCase(wrong_hand, plane, True)
    )
    assert found is not None and found.startswith("wrong answer: reflected")
    moved = mirror.copy()
    moved[0, 2] += 1.0
    far = fuzz_inputs.RegistrationCase(
        fuzz_inputs.RobotTruth(moved, True, "rigid", 0.01), plane, True
    )
    found = fuzz_inputs.registration_error(frame, far)
    assert found is not None and "mm from the truth" in found

    ok: dict[str, object] = {"close_s": 0.1, "alive": [], "controller": {"answer": b"{}"}}
    peer = fuzz_inputs.Peer("half_closed", b"TRIGGER\n" * 2, True, 2)
    answered = {**ok, "peers": [{"lines": [b'{"frame": 1}'] * 2, "end": "eof"}]}
    assert fuzz_inputs.session_problem(answered, [peer], False) is None
    twice = {**ok, "peers": [{"lines": [b'{"frame": 1}'] * 3, "end": "eof"}]}
    assert (fuzz_inputs.session_problem(twice, [peer], False) or "").startswith("bad result")
    short = {**ok, "peers": [{"lines": [b'{"frame": 1}'], "end": "eof"}]}
    assert (fuzz_inputs.session_problem(short, [peer], False) or "").startswith("silent loss")
    lost = {**answered, "controller": {"errors": ["timeout"]}}
    assert (fuzz_inputs.session_problem(lost, [peer], False) or "").startswith("silent loss")
    slow = {**answered, "close_s": 9.0}
    assert (fuzz_inputs.session_problem(slow, [peer], False) or "").startswith("hang")

    plan = fuzz_inputs.SourcePlan("folder mixed", {}, 5)
    run = {"status": 0, "lines": 5, "stderr": "", "readable": 0}
    assert fuzz_inputs.run_problem(run, plan) is None
    quiet = {**run, "lines": 4, "stderr": 'planarcal run: {"read": 4, "frames": 4, "failed": 0}'}
    assert (fuzz_inputs.run_problem(quiet, plan) or "").startswith("silent loss")
    told = {**quiet, "stderr": 'planarcal run: {"read": 5, "frames": 4, "failed": 1}'}
    assert fuzz_inputs.run_problem(told, plan) is None
    nothing = {**run, "lines": 0}
    assert (fuzz_inputs.run_problem(nothing, plan) or "").startswith("silent loss")
    crash = {
        **run,
        "status": 1,
        "stderr": "Traceback (most recent call last):\n  boom\nKeyError: 1",
    }
    assert (fuzz_inputs.run_problem(crash, plan) or "").startswith("unclean")
    assert (fuzz_inputs.run_problem({"timeout": True, "stderr": ""}, plan) or "").startswith("hang")
    judge, Case = fuzz_inputs.judge, fuzz_inputs.Case
    assert judge(Case(lambda: None, (), {}, lambda _: "silent loss: x"))[0] == "silent_loss"
    assert judge(Case(lambda: None, (), {}, lambda _: "wrong answer: x"))[0] == "wrong_answer"
    assert judge(Case(lambda: None, (), {}, lambda _: "hang: x"))[0] == "hang"
    refused = Case(pc.RobotFrame.fit, ([[0.0, 0.0]], [[0.0, 0.0]]), {}, lambda _: None)
    assert judge(refused)[0] == "error"
    untyped = Case(pc.RobotFrame.fit, ([[0.0, 0.0]], [[0.0, 0.0]]), {}, lambda _: None)
    untyped.also = (KeyError,)
    assert judge(untyped)[0] == "unclean"


# The findings of issue 21's entry points on the code before it (F9-F13), as minimal cases.


@pytest.mark.parametrize("offsets", [[0.0] * 6, [0.0, 0.03, -0.04, 0.05, 0.0, 0.02]])
def test_f9_touches_on_one_line_get_no_handedness(offsets: list[float]) -> None:
    # Six dots on a row (or within 0.05 mm of it) fix no hand: the mirror image of the map
    # fits as well, and a part off the line would be placed at its mirror image.
    plane = np.c_[np.linspace(0.0, 200.0, 6), offsets]
    robot = plane[:, ::-1] + [100.0, 50.0]  # a mirror
    with pytest.raises(pc.RegistrationError):
        pc.RobotFrame.fit(plane, robot)


def test_f10_a_robot_coordinate_near_the_largest_float_is_refused() -> None:
    # Its square overflowed: the fit came back as a transform of NaN.
    plane = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 100.0], [100.0, 100.0]])
    robot = plane.copy()
    robot[2, 0] = np.finfo(np.float64).max
    with pytest.raises(pc.ArgumentError):
        pc.RobotFrame.fit(plane, robot)


def test_f11_idle_connections_at_the_cap_do_not_lock_a_controller_out() -> None:
    # Two idle connections held a server of two clients: every controller after them was
    # turned away for as long as they stayed.
    session = fuzz_inputs.trigger_session([], 2, 2, 0.3, 0.01)
    assert "answer" in session["controller"], session["controller"]


def test_f12_an_overlong_request_line_gets_one_reply() -> None:
    # 2 MB and a newline, then TRIGGER: two lines, two replies (an error line went out for
    # each chunk of the long line read while the client still sent it: 30 to 40).
    peer = fuzz_inputs.Peer("huge", b"A" * 2_000_000 + b"\nTRIGGER\n", True, 2)
    session = fuzz_inputs.trigger_session([peer], 0, 4, 0.3, 0.01)
    assert fuzz_inputs.session_problem(session, [peer], False) is None, session["peers"]


def test_f13_a_truncated_video_is_reported_not_taken_for_its_end(tmp_path: Path) -> None:
    # OpenCV's reader ends at the cut as at a normal end: exit 0 with 6 of the 12 frames
    # its header declares, and no word of the rest.
    video = fuzz_inputs.run_sources().video
    plan = fuzz_inputs.SourcePlan("video truncated", {"video.avi": video[: len(video) // 2]}, -1)
    done = fuzz_inputs.run_on_source(plan, tmp_path / "source")
    assert fuzz_inputs.run_problem(done, plan) is None, done["stderr"][-3000:]
