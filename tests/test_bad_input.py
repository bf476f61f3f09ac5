"""Bad input gets a clear Python exception or a correct answer: never a crash, a panic, a hang,
a silent NaN or a wrong answer.

pyo3's PanicException derives from BaseException, so ``pytest.raises(HomographyError)`` does not
catch it: a panic anywhere below fails the test that triggered it.
"""

from __future__ import annotations

import functools
import pickle
from collections.abc import Callable
from typing import Any, Literal

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import planarcal as pc
from synthetic import OPENCV_ROBUST_METHODS, identical

H_TRUE = np.array([[1.2, 0.1, 5.0], [-0.05, 0.9, 3.0], [1e-3, 2e-3, 1.0]])
N = 20

FAST = settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))


def project(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Reference: points through h with NumPy (no checks)."""
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, h.shape[1] - 1)
    q = np.c_[pts, np.ones(len(pts))] @ np.asarray(h, dtype=np.float64).T
    return np.asarray(q[:, :-1] / q[:, -1:], dtype=np.float64)


def problem(n: int = N, seed: int = 0, noise: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    src = rng.uniform(0, 100, (n, 2))
    dst = project(H_TRUE, src) + rng.normal(0, noise, (n, 2))
    return src, dst


SRC, DST = problem()
# Small non-negative integers (they fit uint8), distinct, in general position.
_rng = np.random.default_rng(7)
SRC_INT = _rng.permutation(
    np.stack(np.meshgrid(np.arange(0, 250, 50), np.arange(0, 200, 50)), -1).reshape(-1, 2)
)
DST_INT = np.clip(np.round(project(H_TRUE, SRC_INT)), 0, 255)

SOLVER_REFINE = [
    pytest.param(s, r, id=f"{s}-{'refine' if r else 'linear'}")
    for s in pc.SOLVERS
    for r in (False, True)
]


def message(excinfo: pytest.ExceptionInfo[BaseException]) -> str:
    return str(excinfo.value)


def _pt(src: Any, _dst: Any) -> Any:
    out = pc.perspectiveTransform(src, H_TRUE)
    assert out is not None  # None only for an empty input
    # Compared across input layouts (N, 2), (N, 1, 2), (1, N, 2): shape is tested on its own.
    return out.reshape(-1, 2)


# Every public entry point as f(src, dst) -> a comparable answer.
CALLS: dict[str, Callable[[Any, Any], Any]] = {
    **{
        f"estimate-{s}-{'refine' if r else 'linear'}": functools.partial(
            pc.estimate_homography, solver=s, refine=r
        )
        for s in pc.SOLVERS
        for r in (False, True)
    },
    "transform_points": lambda s, d: pc.transform_points(H_TRUE, s),
    "transform_points-inverse": lambda s, d: pc.transform_points(H_TRUE, d, inverse=True),
    "reprojection_errors": lambda s, d: pc.reprojection_errors(H_TRUE, s, d),
    "reprojection_stats": lambda s, d: tuple(pc.reprojection_stats(H_TRUE, s, d)),
    "findHomography": lambda s, d: pc.findHomography(s, d),
    "perspectiveTransform": _pt,
}


# ------------------------------------------------------------------------------------------
# Degenerate geometry
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("solver", "refine"), SOLVER_REFINE)
@pytest.mark.parametrize("n", [0, 1, 3])
def test_fewer_than_four_points(solver: pc.Solver, refine: bool, n: int) -> None:
    with pytest.raises(pc.HomographyError) as info:
        pc.estimate_homography(SRC[:n], DST[:n], solver, refine)
    assert not isinstance(info.value, pc.DegenerateError)
    assert "at least 4" in message(info)
    assert f"got {n}" in message(info)


@pytest.mark.parametrize("n", [0, 1, 3])
def test_find_homography_fewer_than_four_points_raises_cv_error(n: int) -> None:
    with pytest.raises(pc.HomographyError) as info:
        pc.findHomography(SRC[:n], DST[:n])
    assert isinstance(info.value, cv2.error)
    assert "at least 4" in message(info)
    assert f"got {n}" in message(info)


LINE = np.c_[np.arange(8.0) * 3 - 5, np.arange(8.0) * 1.5 + 2]
SQUARE8 = SRC[:8]


def _all_but_one(outlier: int) -> np.ndarray:
    pts = np.array(LINE, dtype=np.float64)  # a copy
    pts[outlier] = [10.0, -40.0]
    return pts


def _duplicates() -> np.ndarray:
    # 8 points, 3 distinct.
    return np.array([[0, 0], [1, 0], [0, 1], [0, 0], [1, 0], [0, 1], [0, 1], [0, 0]], float)


# (name, src, dst, which set, words the message must contain)
DEGENERATE = [
    ("collinear-src", LINE, SQUARE8, "source", ["lie on one line"]),
    ("collinear-dst", SQUARE8, LINE, "destination", ["lie on one line"]),
    ("all-but-one-src", _all_but_one(5), SQUARE8, "source", ["but one (point 5)", "one line"]),
    ("all-but-one-dst", SQUARE8, _all_but_one(0), "destination", ["but one (point 0)"]),
    ("duplicates-src", _duplicates(), SQUARE8, "source", ["only 3 distinct", "duplicates"]),
    ("duplicates-dst", SQUARE8, _duplicates(), "destination", ["only 3 distinct"]),
    ("all-equal-dst", SQUARE8, np.full((8, 2), 4.0), "destination", ["only 1 distinct"]),
]


@pytest.mark.parametrize(("solver", "refine"), SOLVER_REFINE)
@pytest.mark.parametrize(
    ("src", "dst", "which", "words"), [pytest.param(*c[1:], id=c[0]) for c in DEGENERATE]
)
def test_degenerate_geometry_is_named(
    solver: pc.Solver, refine: bool, src: np.ndarray, dst: np.ndarray, which: str, words: list[str]
) -> None:
    with pytest.raises(pc.DegenerateError) as info:
        pc.estimate_homography(src, dst, solver, refine)
    assert isinstance(info.value, pc.HomographyError)
    assert isinstance(info.value, ValueError)
    msg = message(info)
    assert msg.startswith(f"all {which}") or f"distinct {which} points" in msg
    for w in words:
        assert w in msg
    assert info.value.point_set == {"source": "src", "destination": "dst"}[which]


@pytest.mark.parametrize(("src", "dst"), [pytest.param(c[1], c[2], id=c[0]) for c in DEGENERATE])
def test_find_homography_degenerate_returns_none_and_zero_mask(
    src: np.ndarray, dst: np.ndarray
) -> None:
    h, mask = pc.findHomography(src, dst)
    assert h is None
    assert mask.dtype == np.uint8
    assert mask.shape == (len(src), 1)
    assert not mask.any()


def _straddling_horizon() -> tuple[np.ndarray, np.ndarray]:
    """Exact correspondences under w = 1 - x / 2: point 5 (x = 3) is behind the horizon."""
    h = np.array([[1.0, 0, 0], [0, 1, 0], [-0.5, 0, 1]])
    src = np.array([[0, 0], [1, 0], [0, 1], [1, 1], [0.5, 0.3], [3, 1.0]])
    return src, project(h, src)


@pytest.mark.parametrize(("solver", "refine"), SOLVER_REFINE)
def test_points_straddling_the_horizon(solver: pc.Solver, refine: bool) -> None:
    src, dst = _straddling_horizon()
    with pytest.raises(pc.DegenerateError) as info:
        pc.estimate_homography(src, dst, solver, refine)
    assert "horizon" in message(info)
    assert "source point 5" in message(info)
    assert (info.value.point_set, info.value.index) == ("src", 5)
    h, mask = pc.findHomography(src, dst)
    assert h is None
    assert mask.shape == (6, 1)
    assert not mask.any()


@FAST
@given(
    n=st.integers(4, 20),
    data=st.data(),
    angle=st.floats(0, np.pi),
    origin=st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)),
    spacing=st.floats(0.5, 20),
    offset=st.floats(1, 100),
    in_dst=st.booleans(),
    solver=st.sampled_from(pc.SOLVERS),
)
def test_all_but_one_collinear_names_the_outlier(
    n: int,
    data: st.DataObject,
    angle: float,
    origin: tuple[float, float],
    spacing: float,
    offset: float,
    in_dst: bool,
    solver: pc.Solver,
) -> None:
    ts = np.array(data.draw(st.lists(st.integers(-50, 50), min_size=n, max_size=n, unique=True)))
    outlier = data.draw(st.integers(0, n - 1))
    direction = np.array([np.cos(angle), np.sin(angle)])
    normal = np.array([-direction[1], direction[0]])
    pts = np.asarray(origin) + spacing * ts[:, None] * direction
    pts[outlier] = np.asarray(origin) + spacing * 0.5 * direction + offset * spacing * normal
    good = problem(n, seed=n)[0]
    src, dst = (good, pts) if in_dst else (pts, good)
    with pytest.raises(pc.DegenerateError) as info:
        pc.estimate_homography(src, dst, solver)
    which = "destination" if in_dst else "source"
    assert f"all {which} points but one (point {outlier})" in message(info)
    assert (info.value.point_set, info.value.index) == ("dst" if in_dst else "src", outlier)


# ------------------------------------------------------------------------------------------
# Shapes and lengths
# ------------------------------------------------------------------------------------------

BAD_SHAPES = [(N, 3), (2, N), (2 * N,), (1, 1, N, 2), (N, 2, 1), (N, 1, 3), ()]


def _shaped(shape: tuple[int, ...]) -> np.ndarray:
    return np.resize(SRC, shape) if shape else np.float64(1.0)


@pytest.mark.parametrize("shape", BAD_SHAPES, ids=str)
@pytest.mark.parametrize(
    ("name", "call"),
    [
        ("src", lambda a: pc.estimate_homography(a, DST)),
        ("dst", lambda a: pc.estimate_homography(SRC, a)),
        ("src", lambda a: pc.estimate_homography(a, DST, "a33", True)),
        ("points", lambda a: pc.transform_points(H_TRUE, a)),
        ("points", lambda a: pc.transform_points(H_TRUE, a, inverse=True)),
        ("src", lambda a: pc.reprojection_errors(H_TRUE, a, DST)),
        ("dst", lambda a: pc.reprojection_errors(H_TRUE, SRC, a)),
        ("dst", lambda a: pc.reprojection_stats(H_TRUE, SRC, a)),
        ("srcPoints", lambda a: pc.findHomography(a, DST)),
        ("dstPoints", lambda a: pc.findHomography(SRC, a)),
    ],
)
def test_wrong_point_shapes(shape: tuple[int, ...], name: str, call: Callable[[Any], Any]) -> None:
    with pytest.raises(pc.ArgumentError) as info:
        call(_shaped(shape))
    msg = message(info)
    assert msg.startswith(f"{name} must have shape (N, 2)")
    assert str(list(shape)) in msg
    assert not isinstance(info.value, pc.HomographyError)
    assert info.value.point_set == {"srcPoints": "src", "dstPoints": "dst"}.get(
        name, name if name in ("src", "dst") else None
    )
    if name.endswith("Points"):
        assert isinstance(info.value, cv2.error)


@pytest.mark.parametrize("shape", [(2, N), (2 * N,), (1, 1, N, 2), (N, 2, 1), ()], ids=str)
def test_perspective_transform_wrong_point_shapes(shape: tuple[int, ...]) -> None:
    with pytest.raises(pc.ArgumentError) as info:
        pc.perspectiveTransform(_shaped(shape), H_TRUE)
    assert isinstance(info.value, cv2.error)
    assert message(info).startswith("src must ")
    assert str(list(shape)) in message(info)


def test_perspective_transform_3d_points_need_a_4_column_matrix() -> None:
    with pytest.raises(pc.ArgumentError) as info:
        pc.perspectiveTransform(np.resize(SRC, (N, 1, 3)), H_TRUE)
    assert isinstance(info.value, cv2.error)
    assert "m must be 4 x 4" in message(info)
    assert "[3, 3]" in message(info)


def _valid_points_shape(shape: tuple[int, ...]) -> bool:
    return (len(shape) == 2 and shape[1] == 2) or (
        len(shape) == 3 and shape[2] == 2 and 1 in shape[:2]
    )


@FAST
@given(
    shape=st.lists(st.integers(0, 5), min_size=0, max_size=5)
    .map(tuple)
    .filter(lambda s: not _valid_points_shape(s)),
    dtype=st.sampled_from([np.float64, np.float32, np.int64]),
)
def test_random_invalid_shapes(shape: tuple[int, ...], dtype: type[np.number[Any]]) -> None:
    bad = np.ones(shape, dtype=dtype)
    calls: list[Callable[[], object]] = [
        lambda: pc.estimate_homography(bad, DST),
        lambda: pc.estimate_homography(SRC, bad),
        lambda: pc.transform_points(H_TRUE, bad),
        lambda: pc.reprojection_errors(H_TRUE, bad, DST),
        lambda: pc.reprojection_errors(H_TRUE, SRC, bad),
        lambda: pc.findHomography(bad, DST),
    ]
    for call in calls:
        with pytest.raises(pc.ArgumentError, match=r"must have shape \(N, 2\)"):
            call()
    valid_3d = len(shape) in (2, 3) and shape[-1] == 3 and (len(shape) == 2 or 1 in shape[:2])
    with pytest.raises(pc.ArgumentError, match="m must be 4 x 4" if valid_3d else "src must"):
        pc.perspectiveTransform(bad, H_TRUE)


@pytest.mark.parametrize(
    "call",
    [
        *[
            pytest.param(lambda s, d, sv=sv: pc.estimate_homography(s, d, sv), id=f"estimate-{sv}")
            for sv in pc.SOLVERS
        ],
        pytest.param(lambda s, d: pc.reprojection_errors(H_TRUE, s, d), id="reprojection_errors"),
        pytest.param(lambda s, d: pc.reprojection_stats(H_TRUE, s, d), id="reprojection_stats"),
        pytest.param(lambda s, d: pc.findHomography(s, d), id="findHomography"),
    ],
)
@pytest.mark.parametrize(("ns", "nd"), [(N, 10), (10, N), (3, 5), (0, 4)])
def test_mismatched_lengths(call: Callable[[Any, Any], Any], ns: int, nd: int) -> None:
    with pytest.raises(pc.ArgumentError) as info:
        call(SRC[:ns], DST[:nd])
    assert f"same number of points, got {ns} and {nd}" in message(info)


# ------------------------------------------------------------------------------------------
# NaN and infinity
# ------------------------------------------------------------------------------------------

NONFINITE = [np.nan, np.inf, -np.inf]


def _with(a: np.ndarray, index: int, col: int, value: float) -> np.ndarray:
    a = a.copy()
    a[index, col] = value
    return a


@pytest.mark.parametrize(("solver", "refine"), SOLVER_REFINE)
@pytest.mark.parametrize("value", NONFINITE, ids=str)
@pytest.mark.parametrize("in_dst", [False, True], ids=["src", "dst"])
@pytest.mark.parametrize(("index", "col"), [(0, 0), (7, 1), (N - 1, 0)])
def test_estimate_nonfinite_names_set_and_index(
    solver: pc.Solver, refine: bool, value: float, in_dst: bool, index: int, col: int
) -> None:
    src, dst = (
        (SRC, _with(DST, index, col, value)) if in_dst else (_with(SRC, index, col, value), DST)
    )
    which = "destination" if in_dst else "source"
    with pytest.raises(pc.ArgumentError) as info:
        pc.estimate_homography(src, dst, solver, refine)
    assert not isinstance(info.value, pc.HomographyError)
    assert f"{which} point {index} is not finite" in message(info)
    assert (info.value.point_set, info.value.index) == ("dst" if in_dst else "src", index)
    with pytest.raises(pc.ArgumentError) as info:
        pc.findHomography(src, dst)
    assert isinstance(info.value, cv2.error)
    assert f"{which} point {index} is not finite" in message(info)
    assert (info.value.point_set, info.value.index) == ("dst" if in_dst else "src", index)


@pytest.mark.parametrize("value", NONFINITE, ids=str)
@pytest.mark.parametrize(("index", "col"), [(0, 0), (7, 1), (N - 1, 0)])
def test_transform_nonfinite_point_is_named(value: float, index: int, col: int) -> None:
    pts = _with(SRC, index, col, value)
    with pytest.raises(pc.PointAtInfinityError) as info:
        pc.transform_points(H_TRUE, pts)
    assert f"1 of {N} points" in message(info)
    assert f"the first is point {index}, which has a non-finite coordinate" in message(info)
    assert (info.value.index, info.value.point_set) == (index, None)
    out = pc.transform_points(H_TRUE, pts, invalid="nan")
    assert np.isnan(out[index]).all()
    keep = np.arange(N) != index
    assert np.array_equal(out[keep], pc.transform_points(H_TRUE, SRC)[keep])
    with pytest.raises(pc.PointAtInfinityError) as info:
        pc.perspectiveTransform(pts.reshape(-1, 1, 2), H_TRUE)
    assert isinstance(info.value, cv2.error)
    assert f"the first is point {index}," in message(info)


@pytest.mark.parametrize("value", NONFINITE, ids=str)
@pytest.mark.parametrize("invalid", ["raise", "inf"])
def test_reprojection_nonfinite_source_point_is_refused(
    value: float, invalid: Literal["raise", "inf"]
) -> None:
    """A non-finite point is bad input, not a point without an image: refused in both modes
    (invalid="inf" is for points the homography sends to infinity), naming set and index."""
    src = _with(SRC, 4, 0, value)
    with pytest.raises(pc.ArgumentError) as info:
        pc.reprojection_errors(H_TRUE, src, DST, invalid=invalid)
    assert not isinstance(info.value, pc.PointAtInfinityError)
    assert "source point 4 is not finite" in message(info)
    with pytest.raises(pc.ArgumentError, match="source point 4 is not finite"):
        pc.reprojection_stats(H_TRUE, src, DST)


@pytest.mark.parametrize("value", NONFINITE, ids=str)
def test_reprojection_nonfinite_destination_point_message_names_destination(value: float) -> None:
    with pytest.raises(pc.ArgumentError) as info:
        pc.reprojection_errors(H_TRUE, SRC, _with(DST, 4, 1, value))
    msg = message(info)
    assert "point 4" in msg
    assert "destination" in msg or "dst" in msg
    assert "source point" not in msg


def _nan_masks(n: int) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.bool_, (n, 2), elements=st.booleans())


@FAST
@given(
    data=st.data(),
    n=st.integers(4, 30),
    value=st.sampled_from(NONFINITE),
    solver=st.sampled_from(pc.SOLVERS),
)
def test_random_nonfinite_positions(
    data: st.DataObject, n: int, value: float, solver: pc.Solver
) -> None:
    src, dst = problem(n, seed=n)
    ms, md = data.draw(_nan_masks(n)), data.draw(_nan_masks(n))
    bad_src, bad_dst = src.copy(), dst.copy()
    bad_src[ms], bad_dst[md] = value, value
    rows_s, rows_d = np.flatnonzero(ms.any(1)), np.flatnonzero(md.any(1))

    if len(rows_s) or len(rows_d):
        with pytest.raises(pc.ArgumentError) as info:
            pc.estimate_homography(bad_src, bad_dst, solver)
        expected = (
            f"source point {rows_s[0]} is not finite"
            if len(rows_s)
            else f"destination point {rows_d[0]} is not finite"
        )
        assert expected in message(info)
    else:
        assert np.isfinite(pc.estimate_homography(bad_src, bad_dst, solver)).all()

    out = pc.transform_points(H_TRUE, bad_src, invalid="nan")
    clean = pc.transform_points(H_TRUE, src)
    nan_rows = np.isnan(out).any(1)
    assert np.array_equal(nan_rows, ms.any(1))
    assert np.isnan(out[nan_rows]).all()
    assert np.array_equal(out[~nan_rows], clean[~nan_rows])
    if len(rows_s):
        with pytest.raises(pc.PointAtInfinityError, match=f"the first is point {rows_s[0]},"):
            pc.transform_points(H_TRUE, bad_src)

    # Non-finite points are bad input for reprojection_errors in either mode (invalid="inf"
    # is for points the homography sends to infinity): the first is named, source first.
    for invalid in ("raise", "inf"):
        if len(rows_s) or len(rows_d):
            with pytest.raises(pc.ArgumentError) as info:
                pc.reprojection_errors(H_TRUE, bad_src, bad_dst, invalid=invalid)
            assert expected in message(info)
        else:
            assert np.array_equal(
                pc.reprojection_errors(H_TRUE, bad_src, bad_dst, invalid=invalid),
                pc.reprojection_errors(H_TRUE, src, dst),
            )


# ------------------------------------------------------------------------------------------
# Empty input
# ------------------------------------------------------------------------------------------


def test_empty_inputs() -> None:
    empty = np.zeros((0, 2))
    for solver in pc.SOLVERS:
        with pytest.raises(pc.HomographyError, match=r"at least 4.*got 0"):
            pc.estimate_homography(empty, empty, solver)
    with pytest.raises(pc.HomographyError, match=r"at least 4.*got 0") as info:
        pc.findHomography(empty, empty)
    assert isinstance(info.value, cv2.error)
    for shape in [(0, 2), (0, 1, 2), (1, 0, 2)]:
        out = pc.transform_points(H_TRUE, np.zeros(shape))
        assert out.shape == (0, 2)
        assert out.dtype == np.float64
        errors = pc.reprojection_errors(H_TRUE, np.zeros(shape), np.zeros(shape))
        assert errors.shape == (0,)
    with pytest.raises(pc.ArgumentError, match="empty"):
        pc.reprojection_stats(H_TRUE, empty, empty)
    with pytest.raises(pc.ArgumentError, match="empty"):
        pc.error_stats(np.zeros(0))
    with pytest.raises(pc.ArgumentError, match="empty"):
        pc.error_stats([])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape", [(0, 1, 2), (1, 0, 2), (0, 2), (0, 1, 3)], ids=str)
def test_perspective_transform_empty_returns_none(
    dtype: type[np.floating[Any]], shape: tuple[int, ...]
) -> None:
    m = H_TRUE if shape[-1] == 2 else np.eye(4)
    ours = pc.perspectiveTransform(np.zeros(shape, dtype), m)
    if len(shape) == 3:
        # What the installed OpenCV gives for its own (N, 1, C) layouts: None (4.x) or an
        # empty array of the input's shape and dtype (5.x).
        theirs = cv2.perspectiveTransform(np.zeros(shape, dtype), m)
        if theirs is None:
            assert ours is None
        else:
            assert ours is not None and ours.shape == theirs.shape and ours.dtype == theirs.dtype


# ------------------------------------------------------------------------------------------
# Memory layout, read-only arrays, lists, dtypes: the same answer
# ------------------------------------------------------------------------------------------


def _strided(a: np.ndarray) -> np.ndarray:
    buf = np.full((2 * a.shape[0], *a.shape[1:]), -7.0, a.dtype)
    buf[::2] = a
    return buf[::2]


def _column_strided(a: np.ndarray) -> np.ndarray:
    buf = np.full((*a.shape[:-1], 2 * a.shape[-1]), -7.0, a.dtype)
    buf[..., ::2] = a
    return buf[..., ::2]


def _negative_stride(a: np.ndarray) -> np.ndarray:
    return np.asarray(a[::-1].copy()[::-1])


def _transposed(a: np.ndarray) -> np.ndarray:
    return np.asarray(np.ascontiguousarray(a.T).T)


def _readonly(a: np.ndarray) -> np.ndarray:
    a = a.copy()
    a.flags.writeable = False
    return a


def _readonly_strided(a: np.ndarray) -> np.ndarray:
    a = _strided(a)
    a.flags.writeable = False
    return a


LAYOUTS: dict[str, Callable[[np.ndarray], Any]] = {
    "a[::2]": _strided,
    "columns[::2]": _column_strided,
    "fortran": np.asfortranarray,
    "transposed-view": _transposed,
    "negative-stride": _negative_stride,
    "readonly": _readonly,
    "readonly-strided": _readonly_strided,
    "big-endian": lambda a: a.astype(a.dtype.newbyteorder(">")),
    "N,1,2": lambda a: a.reshape(-1, 1, 2),
    "1,N,2": lambda a: a.reshape(1, -1, 2),
    "N,1,2-strided": lambda a: _strided(a.reshape(-1, 1, 2)),
    "list": lambda a: a.tolist(),
    "tuple": lambda a: tuple(tuple(p) for p in a.tolist()),
    "list-of-arrays": list,
}


@pytest.mark.parametrize("layout", list(LAYOUTS))
@pytest.mark.parametrize("call", list(CALLS))
def test_layout_gives_the_same_answer(layout: str, call: str) -> None:
    f, convert = CALLS[call], LAYOUTS[layout]
    expected = f(SRC, DST)
    got = f(convert(SRC), convert(DST))
    assert identical(got, expected)


@pytest.mark.parametrize("layout", ["fortran", "transposed-view", "readonly", "a[::2]", "list"])
def test_matrix_layout_gives_the_same_answer(layout: str) -> None:
    h = LAYOUTS[layout](H_TRUE)
    assert identical(pc.transform_points(h, SRC), pc.transform_points(H_TRUE, SRC))
    assert identical(
        pc.transform_points(h, DST, inverse=True), pc.transform_points(H_TRUE, DST, inverse=True)
    )
    assert identical(pc.reprojection_errors(h, SRC, DST), pc.reprojection_errors(H_TRUE, SRC, DST))
    assert identical(pc.perspectiveTransform(SRC, h), pc.perspectiveTransform(SRC, H_TRUE))


@pytest.mark.parametrize("layout", ["a[::2]", "fortran", "readonly", "negative-stride"])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_perspective_transform_layout_keeps_dtype_and_answer(
    layout: str, dtype: type[np.floating[Any]]
) -> None:
    pts = SRC.reshape(-1, 1, 2).astype(dtype)
    expected = pc.perspectiveTransform(pts, H_TRUE)
    got = pc.perspectiveTransform(LAYOUTS[layout](pts), H_TRUE)
    assert identical(got, expected)
    assert got is not None and got.dtype == dtype


@pytest.mark.parametrize("dtype", [np.int32, np.int64, np.uint8, np.int16, np.uint64])
@pytest.mark.parametrize("call", list(CALLS))
def test_integer_dtypes_match_float64(dtype: type[np.integer[Any]], call: str) -> None:
    f = CALLS[call]
    assert identical(
        f(SRC_INT.astype(dtype), DST_INT.astype(dtype)),
        f(SRC_INT.astype(np.float64), DST_INT.astype(np.float64)),
    )


@pytest.mark.parametrize("call", [c for c in CALLS if c != "perspectiveTransform"])
def test_float32_is_computed_in_float64(call: str) -> None:
    f = CALLS[call]
    s32, d32 = SRC.astype(np.float32), DST.astype(np.float32)
    assert identical(f(s32, d32), f(s32.astype(np.float64), d32.astype(np.float64)))


def test_integer_matrix_matches_float64() -> None:
    h = np.array([[2, 1, 5], [0, 3, -4], [0, 0, 1]])
    for dtype in (np.int32, np.int64, np.uint8, np.float32):
        hh = np.abs(h).astype(dtype)
        assert identical(
            pc.transform_points(hh, SRC), pc.transform_points(hh.astype(np.float64), SRC)
        )


BAD_DTYPES = {
    "bool": (np.bool_, "bool"),
    "complex": (np.complex128, "complex128"),
    "object": (object, "object"),
    "str": (str, "<U"),
    "bytes": (bytes, "|S"),
    "datetime": ("M8[s]", "datetime64[s]"),
}


def _bad(a: np.ndarray, dtype: Any) -> np.ndarray:
    if dtype in ("M8[s]",):
        return a.astype(np.int64).astype(dtype)
    return a.astype(dtype)


SLOTS: list[tuple[str, str, Callable[[Any], Any]]] = [
    ("estimate-src", "src", lambda a: pc.estimate_homography(a, DST)),
    ("estimate-dst", "dst", lambda a: pc.estimate_homography(SRC, a, "svd", True)),
    ("transform-points", "points", lambda a: pc.transform_points(H_TRUE, a)),
    ("transform-h", "h", lambda a: pc.transform_points(a, SRC)),
    ("reprojection-h", "h", lambda a: pc.reprojection_errors(a, SRC, DST)),
    ("reprojection-src", "src", lambda a: pc.reprojection_errors(H_TRUE, a, DST)),
    ("reprojection-dst", "dst", lambda a: pc.reprojection_errors(H_TRUE, SRC, a)),
    ("stats-dst", "dst", lambda a: pc.reprojection_stats(H_TRUE, SRC, a)),
    ("error_stats", "errors", lambda a: pc.error_stats(a[:, 0])),
    ("cv-findHomography-src", "srcPoints", lambda a: pc.findHomography(a, DST)),
    ("cv-findHomography-dst", "dstPoints", lambda a: pc.findHomography(SRC, a)),
    ("cv-perspective-src", "src", lambda a: pc.perspectiveTransform(a, H_TRUE)),
    ("cv-perspective-m", "m", lambda a: pc.perspectiveTransform(SRC, a)),
]


@pytest.mark.parametrize("bad", list(BAD_DTYPES))
@pytest.mark.parametrize(("slot", "name", "call"), [pytest.param(*s, id=s[0]) for s in SLOTS])
def test_bad_dtypes_are_named(bad: str, slot: str, name: str, call: Callable[[Any], Any]) -> None:
    dtype, shown = BAD_DTYPES[bad]
    arg = _bad(H_TRUE if name in ("h", "m") else SRC, dtype)
    with pytest.raises(pc.ArgumentError) as info:
        call(arg)
    msg = message(info)
    assert msg.startswith(f"{name} must hold real numbers")
    assert f"dtype {shown}" in msg
    if slot.startswith("cv-"):
        assert isinstance(info.value, cv2.error)


@pytest.mark.parametrize(
    "value",
    [
        [[1, 2], [3]],
        [[1, 2], [3, "x"]],
        "points",
        None,
        {"a": 1},
        [[1.0, 2.0], [3.0, None], [1, 1], [2, 2]],
    ],
    ids=["ragged", "string-inside", "str", "None", "dict", "None-inside"],
)
def test_non_arrays_raise_argument_error(value: Any) -> None:
    for call in (
        lambda: pc.estimate_homography(value, DST[:4]),
        lambda: pc.transform_points(H_TRUE, value),
        lambda: pc.transform_points(value, SRC),
        lambda: pc.findHomography(value, DST[:4]),
        lambda: pc.perspectiveTransform(value, H_TRUE),
    ):
        with pytest.raises(pc.ArgumentError, match=r"must (hold real numbers|be an array)"):
            call()


def test_wrongly_typed_options_raise_type_error() -> None:
    with pytest.raises(TypeError):
        pc.estimate_homography(SRC, DST, None)  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        pc.estimate_homography(SRC, DST, refine="yes")  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        pc.transform_points(H_TRUE, SRC, inverse="no")  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        pc.transform_points(H_TRUE, SRC, invalid=None)  # type: ignore[arg-type]


# ------------------------------------------------------------------------------------------
# Unaligned buffers (e.g. np.frombuffer(data, offset=1)): C-contiguous yet not borrowable
# ------------------------------------------------------------------------------------------


def unaligned(a: np.ndarray) -> np.ndarray:
    """A C-contiguous copy of `a` whose data pointer is not aligned for its dtype."""
    raw = b"\0" + np.ascontiguousarray(a).tobytes()
    out = np.frombuffer(raw, dtype=a.dtype, offset=1).reshape(a.shape)
    assert not out.flags.aligned and out.flags.c_contiguous
    return out


def test_unaligned_helper_really_is_unaligned() -> None:
    a = unaligned(SRC)
    assert np.array_equal(a, SRC)
    assert not a.flags.aligned


_UA_SRC, _UA_DST = problem(5000, seed=12345)  # fresh data: no stale buffer holds its image

UNALIGNED_CASES: dict[str, Callable[[Callable[[np.ndarray], np.ndarray]], Any]] = {
    "transform_points-points": lambda u: pc.transform_points(H_TRUE, u(_UA_SRC)),
    "transform_points-h": lambda u: pc.transform_points(u(H_TRUE), _UA_SRC),
    "reprojection_errors-points": lambda u: pc.reprojection_errors(H_TRUE, u(_UA_SRC), _UA_DST),
    "reprojection_errors-h": lambda u: pc.reprojection_errors(u(H_TRUE), _UA_SRC, _UA_DST),
    "estimate_homography": lambda u: pc.estimate_homography(u(_UA_SRC), u(_UA_DST)),
    "findHomography": lambda u: pc.findHomography(u(_UA_SRC), _UA_DST),
    "perspectiveTransform-f64": lambda u: pc.perspectiveTransform(u(_UA_SRC), H_TRUE),
    "perspectiveTransform-f32": lambda u: pc.perspectiveTransform(
        u(_UA_SRC.astype(np.float32)), H_TRUE
    ),
    "perspectiveTransform-m": lambda u: pc.perspectiveTransform(_UA_SRC, u(H_TRUE)),
    "error_stats": lambda u: tuple(pc.error_stats(u(_UA_DST[:, 0]))),
}


@pytest.mark.parametrize("case", list(UNALIGNED_CASES))
def test_unaligned_arrays_give_the_same_answer(case: str) -> None:
    got = UNALIGNED_CASES[case](unaligned)  # before the reference: see _UA_SRC
    expected = UNALIGNED_CASES[case](np.ascontiguousarray)
    assert identical(got, expected)


# ------------------------------------------------------------------------------------------
# Matrices
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("value", NONFINITE, ids=str)
@pytest.mark.parametrize(("row", "col"), [(0, 0), (1, 2), (2, 1), (2, 2)])
def test_nonfinite_matrix_entry_is_located(value: float, row: int, col: int) -> None:
    h = H_TRUE.copy()
    h[row, col] = value
    where = f"non-finite entry at row {row}, column {col}"
    for call in (
        lambda: pc.transform_points(h, SRC),
        lambda: pc.transform_points(h, SRC, inverse=True),
        lambda: pc.transform_points(h, SRC, invalid="nan"),
        lambda: pc.reprojection_errors(h, SRC, DST),
        lambda: pc.reprojection_errors(h, SRC, DST, invalid="inf"),
        lambda: pc.reprojection_stats(h, SRC, DST),
    ):
        with pytest.raises(pc.ArgumentError, match=where):
            call()
    with pytest.raises(pc.ArgumentError, match=where) as info:
        pc.perspectiveTransform(SRC.reshape(-1, 1, 2), h)
    assert isinstance(info.value, cv2.error)


def test_nonfinite_4x4_matrix_entry_is_located() -> None:
    m = np.eye(4)
    m[3, 2] = np.nan
    with pytest.raises(pc.ArgumentError, match="row 3, column 2"):
        pc.perspectiveTransform(np.ones((5, 1, 3)), m)


@pytest.mark.parametrize(
    "h",
    [np.eye(2), np.eye(3, 4), np.eye(3).ravel(), np.eye(4), np.eye(3)[..., None], np.float64(1)],
    ids=["2x2", "3x4", "9-vector", "4x4", "3x3x1", "scalar"],
)
def test_wrong_matrix_shape(h: np.ndarray) -> None:
    shape = str(list(np.shape(h)))
    calls: tuple[Callable[[], object], ...] = (
        lambda: pc.transform_points(h, SRC),
        lambda: pc.transform_points(h, SRC, inverse=True),
        lambda: pc.reprojection_errors(h, SRC, DST),
    )
    for call in calls:
        with pytest.raises(pc.ArgumentError) as info:
            call()
        assert "h must be a 3 x 3 matrix" in message(info)
        assert shape in message(info)


@pytest.mark.parametrize(
    "m", [np.eye(2), np.eye(3).ravel(), np.eye(3, 2), np.eye(4)], ids=["2x2", "9", "3x2", "4x4"]
)
def test_perspective_transform_wrong_matrix_shape(m: np.ndarray) -> None:
    with pytest.raises(pc.ArgumentError) as info:
        pc.perspectiveTransform(SRC.reshape(-1, 1, 2), m)
    assert isinstance(info.value, cv2.error)
    assert "m must be 3 x 3 (or 4 x 3)" in message(info)
    assert str(list(m.shape)) in message(info)


SINGULAR = {
    "rank-2": np.array([[1.0, 2, 3], [2, 4, 6], [0, 0, 1]]),
    "rank-1": np.outer([1.0, 2, 3], [4.0, 5, 6]),
    "zero": np.zeros((3, 3)),
    "dependent-rows": np.array([[1.0, 2, 3], [4, 5, 6], [5, 7, 9]]),
}


@pytest.mark.parametrize("h", list(SINGULAR.values()), ids=list(SINGULAR))
def test_singular_matrix_inverse_is_refused(h: np.ndarray) -> None:
    with pytest.raises(pc.DegenerateError) as info:
        pc.transform_points(h, SRC, inverse=True)
    assert "singular" in message(info)
    assert "no inverse" in message(info)
    with pytest.raises(pc.DegenerateError, match="singular"):
        pc.transform_points(h, SRC, inverse=True, invalid="nan")


def test_singular_matrix_forward_is_the_correct_answer() -> None:
    h = SINGULAR["rank-2"]
    assert np.allclose(pc.transform_points(h, SRC), project(h, SRC), rtol=1e-14, atol=0)


def test_zero_matrix_forward_maps_everything_to_infinity() -> None:
    with pytest.raises(pc.PointAtInfinityError, match=f"{N} of {N} points"):
        pc.transform_points(np.zeros((3, 3)), SRC)
    assert np.isnan(pc.transform_points(np.zeros((3, 3)), SRC, invalid="nan")).all()


# w = 1 - x: x = 1 is the horizon, x > 1 lies behind it.
H_HORIZON = np.array([[1.0, 0, 0], [0, 1, 0], [-1, 0, 1]])
PTS_HORIZON = np.array([[0.5, 0], [1, 3], [2, 0], [0.2, 0.1], [-3, 2], [1.5, -1]])
AT_INFINITY, BEHIND = [1], [2, 5]
NO_IMAGE = sorted(AT_INFINITY + BEHIND)
HAS_IMAGE = [i for i in range(len(PTS_HORIZON)) if i not in NO_IMAGE]


def test_point_at_infinity_or_behind_horizon_is_named() -> None:
    with pytest.raises(pc.PointAtInfinityError) as info:
        pc.transform_points(H_HORIZON, PTS_HORIZON)
    msg = message(info)
    assert "3 of 6 points have no image" in msg
    assert "1 maps to infinity" in msg
    assert "2 lie" in msg or "2 lies" in msg
    assert "behind the horizon" in msg
    assert "the first is point 1, which maps to infinity" in msg
    with pytest.raises(pc.PointAtInfinityError, match="the first is point 1, which lies behind"):
        pc.transform_points(H_HORIZON, PTS_HORIZON[[0, 2, 3]])


def test_invalid_nan_marks_only_points_without_image() -> None:
    out = pc.transform_points(H_HORIZON, PTS_HORIZON, invalid="nan")
    assert out.shape == (6, 2)
    assert np.isnan(out[NO_IMAGE]).all()
    assert np.isfinite(out[HAS_IMAGE]).all()
    assert np.allclose(out[HAS_IMAGE], project(H_HORIZON, PTS_HORIZON[HAS_IMAGE]), rtol=1e-15)


def test_reprojection_errors_invalid_inf() -> None:
    dst = project(H_HORIZON, PTS_HORIZON[[0] * 6]) + np.arange(12).reshape(6, 2)
    errors = pc.reprojection_errors(H_HORIZON, PTS_HORIZON, dst, invalid="inf")
    assert np.isposinf(errors[NO_IMAGE]).all()
    ref = np.hypot(*(project(H_HORIZON, PTS_HORIZON[HAS_IMAGE]) - dst[HAS_IMAGE]).T)
    assert np.allclose(errors[HAS_IMAGE], ref, rtol=1e-14)
    for call in (pc.reprojection_errors, pc.reprojection_stats):
        with pytest.raises(pc.PointAtInfinityError, match="the first is point 1, which maps"):
            call(H_HORIZON, PTS_HORIZON, dst)


@pytest.mark.parametrize("bad", ["bogus", "", "NaN", "ignore", "inf"])
def test_invalid_option_for_transform_points(bad: str) -> None:
    with pytest.raises(pc.ArgumentError) as info:
        pc.transform_points(H_TRUE, SRC, invalid=bad)  # type: ignore[arg-type]
    assert '"raise" or "nan"' in message(info)
    assert repr(bad).replace("'", '"') in message(info)


@pytest.mark.parametrize("bad", ["bogus", "", "Inf", "nan"])
def test_invalid_option_for_reprojection_errors(bad: str) -> None:
    with pytest.raises(pc.ArgumentError) as info:
        pc.reprojection_errors(H_TRUE, SRC, DST, invalid=bad)  # type: ignore[arg-type]
    assert '"raise" or "inf"' in message(info)


@pytest.mark.parametrize("bad", ["ransac", "RANSAC", "", "Normalized_DLT", "dlt"])
def test_unknown_solver_lists_the_valid_ones(bad: str) -> None:
    for refine in (False, True):
        with pytest.raises(pc.ArgumentError) as info:
            pc.estimate_homography(SRC, DST, bad, refine)  # type: ignore[arg-type]
        msg = message(info)
        assert "unknown solver" in msg
        assert f'"{bad}"' in msg
        for s in pc.SOLVERS:
            assert f'"{s}"' in msg


# ------------------------------------------------------------------------------------------
# Extreme magnitudes: the message must not claim what is not true
# ------------------------------------------------------------------------------------------

_QUAD = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1], [0.3, 0.6]])
_QUAD_DST = project(np.array([[2, 0.1, 1], [0.2, 1.5, -1], [0.01, 0.02, 1]]), _QUAD)


@pytest.mark.parametrize("scale", [1e-150, 1e-50, 1e50, 1e150])
def test_large_and_small_coordinates_are_fitted(scale: float) -> None:
    for src, dst in ((_QUAD * scale, _QUAD_DST), (_QUAD, _QUAD_DST * scale)):
        h = pc.estimate_homography(src, dst)
        errors = pc.reprojection_errors(h, src, dst)
        assert errors.max() <= 1e-12 * np.abs(dst).max()


@pytest.mark.parametrize(
    "src",
    [
        _QUAD * 1e-200,
        _QUAD * 1e200,
        1e15 + np.array([[0, 0], [1, 0], [1, 1], [0, 1], [2, 3.0]]) / 8,
    ],
    ids=["1e-200", "1e200", "offset-1e15"],
)
def test_extreme_coordinates_message_is_true(src: np.ndarray) -> None:
    assert len(np.unique(src, axis=0)) == 5
    try:
        h = pc.estimate_homography(src, _QUAD_DST)
    except pc.HomographyError as e:
        msg = str(e)
        assert "only 1 distinct" not in msg
        assert "lie on one line" not in msg
    else:
        errors = pc.reprojection_errors(h, src, _QUAD_DST)
        assert errors.max() <= 1e-9 * np.abs(_QUAD_DST).max()


# ------------------------------------------------------------------------------------------
# error_stats
# ------------------------------------------------------------------------------------------


def test_error_stats_is_correct() -> None:
    e = np.array([0.5, 3.0, 0.25, 2.0])
    s = pc.error_stats(e)
    assert s == pc.ReprojectionStats(4, e.mean(), np.sqrt((e * e).mean()), 3.0, 0.25, 1, 2)
    assert pc.error_stats(e.tolist()) == s
    assert pc.error_stats(_strided(e)) == s


def test_error_stats_with_infinite_error() -> None:
    s = pc.error_stats([1.0, np.inf, 2.0])
    assert s.max == np.inf
    assert s.argmax == 1
    assert s.mean == np.inf
    assert s.min == 1.0
    assert s.argmin == 0


def test_error_stats_wrong_shape() -> None:
    with pytest.raises(pc.ArgumentError, match="one-dimensional"):
        pc.error_stats(np.ones((3, 2)))
    with pytest.raises(pc.ArgumentError, match="one-dimensional"):
        pc.error_stats(np.float64(1))


@pytest.mark.parametrize("index", [0, 2])
def test_error_stats_rejects_nan(index: int) -> None:
    e = np.ones(4)
    e[index] = np.nan
    with pytest.raises(pc.ArgumentError) as info:
        pc.error_stats(e)
    assert "nan" in message(info).lower() or "finite" in message(info)


# ------------------------------------------------------------------------------------------
# perspectiveTransform drop-in
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("value", NONFINITE, ids=str)
def test_perspective_transform_nonfinite_point(dtype: type[np.floating[Any]], value: float) -> None:
    pts = _with(SRC, 3, 0, value).reshape(-1, 1, 2).astype(dtype)
    with pytest.raises(pc.PointAtInfinityError) as info:
        pc.perspectiveTransform(pts, H_TRUE)
    assert isinstance(info.value, cv2.error)
    assert isinstance(info.value, pc.HomographyError)
    assert "the first is point 3, which has a non-finite coordinate" in message(info)


def test_perspective_transform_point_at_infinity_raises() -> None:
    pts = PTS_HORIZON.reshape(-1, 1, 2)
    with pytest.raises(pc.PointAtInfinityError) as info:
        pc.perspectiveTransform(pts, H_HORIZON)
    assert isinstance(info.value, cv2.error)
    assert "1 of 6 points" in message(info)
    assert "the first is point 1, which maps to infinity" in message(info)


def test_perspective_transform_behind_horizon_matches_opencv() -> None:
    # The drop-in is unoriented like OpenCV: only w = 0 has no image.
    pts = PTS_HORIZON[[0, 2, 3, 4, 5]].reshape(-1, 1, 2)
    got = pc.perspectiveTransform(pts, H_HORIZON)
    assert got is not None
    assert np.allclose(got, cv2.perspectiveTransform(pts, H_HORIZON), rtol=1e-14, atol=0)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape", [(N, 1, 2), (1, N, 2), (N, 2)], ids=str)
def test_perspective_transform_keeps_shape_and_dtype(
    dtype: type[np.floating[Any]], shape: tuple[int, ...]
) -> None:
    pts = SRC.astype(dtype).reshape(shape)
    out = pc.perspectiveTransform(pts, H_TRUE)
    assert out is not None
    assert out.shape == shape
    assert out.dtype == dtype
    cv_in = pts.reshape(-1, 1, 2) if len(shape) == 2 else pts
    ref = cv2.perspectiveTransform(cv_in, H_TRUE).reshape(shape)
    rtol = 1e-6 if dtype == np.float32 else 1e-13
    assert np.allclose(out, ref, rtol=rtol, atol=0)


@pytest.mark.parametrize("dtype", [np.int32, np.uint8, np.float16])
def test_perspective_transform_other_real_dtypes_give_float64(dtype: type[np.number[Any]]) -> None:
    pts = SRC_INT.reshape(-1, 1, 2)
    out = pc.perspectiveTransform(pts.astype(dtype), H_TRUE)
    assert identical(out, pc.perspectiveTransform(pts.astype(np.float64), H_TRUE))


M4 = np.array([[1, 0.1, 0, 2], [0, 1, 0.2, 1], [0.1, 0, 1, 0], [0.01, 0.02, 0.03, 1.0]])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape", [(30, 1, 3), (1, 30, 3), (30, 3)], ids=str)
def test_perspective_transform_3d_matches_opencv(
    dtype: type[np.floating[Any]], shape: tuple[int, ...]
) -> None:
    pts = np.random.default_rng(3).uniform(-5, 5, shape).astype(dtype)
    out = pc.perspectiveTransform(pts, M4)
    assert out is not None
    assert out.shape == shape
    assert out.dtype == dtype
    ref = cv2.perspectiveTransform(pts.reshape(-1, 1, 3), M4).reshape(shape)
    rtol = 1e-6 if dtype == np.float32 else 1e-13
    assert np.allclose(out, ref, rtol=rtol, atol=1e-12)
    # And 3-D to 2-D through a 3 x 4 matrix.
    m34 = M4[[0, 1, 3]]
    out2 = pc.perspectiveTransform(pts, m34)
    assert out2 is not None
    assert out2.shape == (*shape[:-1], 2)
    ref2 = cv2.perspectiveTransform(pts.reshape(-1, 1, 3), m34).reshape(out2.shape)
    assert np.allclose(out2, ref2, rtol=rtol, atol=1e-12)


def test_perspective_transform_2d_to_3d_is_the_projective_map() -> None:
    m43 = np.r_[H_TRUE[:2], [[0.3, 0.1, 2.0]], H_TRUE[2:]]
    out = pc.perspectiveTransform(SRC.reshape(-1, 1, 2), m43)
    assert out is not None
    assert out.shape == (N, 1, 3)
    assert np.allclose(out.reshape(-1, 3), project(m43, SRC), rtol=1e-14)


def test_perspective_transform_fills_dst_in_place() -> None:
    pts = SRC.reshape(-1, 1, 2)
    dst = np.full((N, 1, 2), -1.0)
    out = pc.perspectiveTransform(pts, H_TRUE, dst)
    assert out is dst
    assert identical(dst, pc.perspectiveTransform(pts, H_TRUE))
    wrong = np.full((N, 1, 2), -1.0, np.float32)
    out = pc.perspectiveTransform(pts, H_TRUE, wrong)
    assert out is not wrong
    assert (wrong == -1).all()
    assert identical(out, dst)


# ------------------------------------------------------------------------------------------
# findHomography drop-in
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", [1, 2, 3, 7, 99, -1])
def test_find_homography_unknown_method(method: int) -> None:
    with pytest.raises(pc.ArgumentError) as info:
        pc.findHomography(SRC, DST, method)
    assert isinstance(info.value, cv2.error)
    assert f"unknown estimation method {method}" in message(info)


ROBUST = OPENCV_ROBUST_METHODS


@pytest.mark.parametrize("name", ROBUST)
def test_find_homography_robust_methods_keep_opencvs_conventions(name: str) -> None:
    method = getattr(pc, name)
    assert method == getattr(cv2, name)
    h, mask = pc.findHomography(SRC, DST, method)
    assert h is not None and h.shape == (3, 3) and h.dtype == np.float64 and h[2, 2] == 1.0
    assert mask.shape == (N, 1) and mask.dtype == np.uint8 and (mask == 1).all()
    # Collinear points: OpenCV's failure value, None, and an all-zero mask.
    h, mask = pc.findHomography(LINE, SQUARE8, method)
    assert h is None and mask.shape == (8, 1) and not mask.any()


def test_find_homography_fills_the_given_mask() -> None:
    mask = np.full((N, 1), 7, np.uint8)
    h, out = pc.findHomography(SRC, DST, mask=mask)
    assert out is mask
    assert (mask == 1).all()
    assert h is not None
    assert h[2, 2] == 1.0
    ref, _ = cv2.findHomography(SRC, DST, 0)
    assert np.allclose(h, ref, rtol=1e-5, atol=1e-8)
    # Degenerate: the same mask comes back all zeros.
    h, out = pc.findHomography(LINE, SQUARE8, mask=mask[:8])
    assert h is None
    assert not mask[:8].any()
    # A mask of the wrong size is left alone and a new one is returned.
    small = np.full((3, 1), 7, np.uint8)
    h, out = pc.findHomography(SRC, DST, mask=small)
    assert out is not small
    assert (small == 7).all()
    assert out.shape == (N, 1)
    assert (out == 1).all()


def test_find_homography_opencv_layouts() -> None:
    for shape in [(N, 1, 2), (1, N, 2), (N, 2)]:
        for dtype in (np.float32, np.float64):
            s, d = SRC.astype(dtype).reshape(shape), DST.astype(dtype).reshape(shape)
            h, mask = pc.findHomography(s, d)
            assert h is not None
            assert h.dtype == np.float64
            assert h.shape == (3, 3)
            assert mask.shape == (N, 1)
            assert mask.dtype == np.uint8
            assert identical(
                (h, mask), pc.findHomography(s.astype(np.float64), d.astype(np.float64))
            )


# ------------------------------------------------------------------------------------------
# Exceptions themselves
# ------------------------------------------------------------------------------------------


def test_exception_hierarchy() -> None:
    assert issubclass(pc.DegenerateError, pc.HomographyError)
    assert issubclass(pc.PointAtInfinityError, pc.HomographyError)
    assert issubclass(pc.HomographyError, ValueError)
    assert not issubclass(pc.ArgumentError, pc.HomographyError)
    for cls in (pc.ArgumentError, pc.HomographyError, pc.DegenerateError, pc.PointAtInfinityError):
        assert cls.__module__ == "planarcal.errors"


def test_native_errors_pickle() -> None:
    with pytest.raises(pc.DegenerateError) as info:
        pc.estimate_homography(LINE, SQUARE8)
    back = pickle.loads(pickle.dumps(info.value))
    assert type(back) is pc.DegenerateError
    assert str(back) == str(info.value)
    assert back.point_set == info.value.point_set == "src"
