"""One error root: every exception planarcal raises is a ``planarcal.Error``, a ``ValueError``
where the input is at fault, and errors about a point say which one as attributes. The calls
are real (the Rust bindings raise the classes of ``planarcal.errors``), nothing is mocked."""

from __future__ import annotations

import inspect
import pickle

import cv2
import numpy as np
import pytest

import planarcal as pc
import planarcal.errors
import planarcal.homography.opencv
import planarcal.live.outputs

# Every exception class planarcal exports, from the package and from planarcal.errors.
EXPORTED = sorted(
    {
        obj
        for module in (pc, planarcal.errors)
        for name in module.__all__
        if inspect.isclass(obj := getattr(module, name)) and issubclass(obj, BaseException)
    },
    key=lambda cls: cls.__name__,
)
# Where something outside the input is at fault: a device or stream (an OSError), the order
# of the calls (a RuntimeError), or a package not installed (an ImportError).
NOT_THE_INPUT = {pc.Error, pc.CameraError, pc.StateError, pc.BusyError, pc.MissingDependencyError}

H = np.array([[1.2, 0.1, 5.0], [-0.05, 0.9, 3.0], [1e-3, 2e-3, 1.0]])
SRC = np.random.default_rng(0).uniform(0, 100, (12, 2))
DST = pc.transform_points(H, SRC)


def _with_nan(a: np.ndarray, index: int) -> np.ndarray:
    a = a.copy()
    a[index, 1] = np.nan
    return a


def test_the_package_and_planarcal_errors_export_the_same_exceptions() -> None:
    from_package = {c for c in EXPORTED if c.__name__ in pc.__all__}
    from_module = {c for c in EXPORTED if c.__name__ in planarcal.errors.__all__}
    assert from_package == from_module
    assert pc.Error in from_package and "Error" in pc.__all__
    assert len(EXPORTED) >= 17


@pytest.mark.parametrize("cls", EXPORTED, ids=lambda c: c.__name__)
def test_every_exported_exception_derives_from_the_root(cls: type[BaseException]) -> None:
    assert issubclass(cls, pc.Error)
    assert cls.__module__ == "planarcal.errors"
    if cls not in NOT_THE_INPUT:
        assert issubclass(cls, ValueError)


def test_the_root_and_the_camera_error() -> None:
    assert pc.Error.__bases__ == (Exception,)
    assert not issubclass(pc.Error, ValueError)
    assert issubclass(pc.CameraError, OSError)
    assert not issubclass(pc.CameraError, ValueError)


def test_the_argument_error_is_not_a_homography_error() -> None:
    assert not issubclass(pc.ArgumentError, pc.HomographyError)
    assert not issubclass(pc.HomographyError, pc.ArgumentError)
    for cls in (pc.DegenerateError, pc.PointAtInfinityError):
        assert issubclass(cls, pc.HomographyError)


def test_names_stay_importable_where_they_were() -> None:
    assert planarcal.live.outputs.OutputError is pc.OutputError
    assert planarcal.homography.opencv.OpenCVCompatibleError is pc.OpenCVCompatibleError
    assert planarcal.homography.opencv.OpenCVCompatiblePointAtInfinityError is (
        pc.OpenCVCompatiblePointAtInfinityError
    )
    assert (
        planarcal.homography.opencv.OpenCVCompatibleArgumentError
        is pc.OpenCVCompatibleArgumentError
    )
    for cls in (
        pc.OpenCVCompatibleError,
        pc.OpenCVCompatiblePointAtInfinityError,
        pc.OpenCVCompatibleArgumentError,
    ):
        assert issubclass(cls, cv2.error)


# -- raised by the bindings ------------------------------------------------------------------


def test_a_wrongly_shaped_src_is_an_argument_error_naming_the_set() -> None:
    with pytest.raises(pc.ArgumentError) as info:
        pc.estimate_homography(np.ones((3, 3)), DST[:3])
    assert not isinstance(info.value, pc.HomographyError)
    assert info.value.point_set == "src"
    assert info.value.index is None
    with pytest.raises(pc.ArgumentError) as info:
        pc.estimate_homography(SRC, np.ones((12, 3)))
    assert info.value.point_set == "dst"


@pytest.mark.parametrize(("in_dst", "index"), [(False, 0), (False, 7), (True, 11)])
def test_a_nan_point_is_an_argument_error_naming_set_and_index(in_dst: bool, index: int) -> None:
    src, dst = (SRC, _with_nan(DST, index)) if in_dst else (_with_nan(SRC, index), DST)
    with pytest.raises(pc.ArgumentError) as info:
        pc.estimate_homography(src, dst)
    assert (info.value.point_set, info.value.index) == ("dst" if in_dst else "src", index)
    # The same error through every entry point that fits or measures correspondences.
    for call in (
        lambda: pc.estimate_homography_robust(src, dst),
        lambda: pc.reprojection_errors(H, src, dst),
        lambda: pc.findHomography(src, dst),
    ):
        with pytest.raises(pc.ArgumentError) as info:
            call()
        assert (info.value.point_set, info.value.index) == ("dst" if in_dst else "src", index)


def test_argument_errors_are_still_caught_as_value_errors() -> None:
    caught = []
    for call in (
        lambda: pc.estimate_homography(np.ones((3, 3)), DST[:3]),
        lambda: pc.estimate_homography(_with_nan(SRC, 2), DST),
        lambda: pc.estimate_homography(SRC, DST, "ransac"),  # type: ignore[arg-type]
        lambda: pc.estimate_homography(SRC, DST[:5]),
        lambda: pc.transform_points(np.ones((2, 2)), SRC),
        lambda: pc.estimate_homography_robust(SRC, DST, threshold=-1.0),
        lambda: pc.error_stats([]),
    ):
        try:
            call()
        except ValueError as e:
            caught.append(e)
    assert len(caught) == 7
    assert all(type(e) is pc.ArgumentError for e in caught)


def test_four_collinear_points_still_raise_homography_error() -> None:
    line = np.c_[np.arange(4.0), 2 * np.arange(4.0) + 1]
    with pytest.raises(pc.HomographyError) as info:
        pc.estimate_homography(line, DST[:4])
    assert isinstance(info.value, pc.DegenerateError)
    assert not isinstance(info.value, pc.ArgumentError)
    assert info.value.point_set == "src"
    # The drop-in returns OpenCV's failure value rather than raising.
    h, mask = pc.findHomography(line, DST[:4])
    assert h is None and not mask.any()


def test_the_point_off_the_line_is_named() -> None:
    line = np.c_[np.arange(6.0), 2 * np.arange(6.0) + 1]
    line[4] = [10.0, -40.0]
    with pytest.raises(pc.DegenerateError) as info:
        pc.estimate_homography(SRC[:6], line)
    assert (info.value.point_set, info.value.index) == ("dst", 4)


def test_too_few_points_is_a_homography_error() -> None:
    with pytest.raises(pc.HomographyError) as info:
        pc.estimate_homography(SRC[:3], DST[:3])
    assert type(info.value) is pc.HomographyError


def test_a_point_without_image_is_named() -> None:
    # w = 1 - x: point 2 (x = 1) maps to infinity.
    h = np.array([[1.0, 0, 0], [0, 1, 0], [-1, 0, 1]])
    pts = np.array([[0.5, 0], [0.2, 0.1], [1, 3], [-3, 2]])
    with pytest.raises(pc.PointAtInfinityError) as info:
        pc.transform_points(h, pts)
    assert (info.value.index, info.value.point_set) == (2, None)
    with pytest.raises(pc.PointAtInfinityError) as info:
        pc.reprojection_errors(h, pts, pts)
    assert (info.value.index, info.value.point_set) == (2, "src")


def test_a_batch_names_the_problem_and_keeps_the_class() -> None:
    problems = [(SRC, DST), (SRC, _with_nan(DST, 5)), (SRC, DST)]
    with pytest.raises(pc.ArgumentError, match=r"^problems\[1\]: destination point 5") as info:
        pc.estimate_homography_robust_batch(problems)
    assert (info.value.point_set, info.value.index) == ("dst", 5)


def test_attributes_survive_pickling() -> None:
    with pytest.raises(pc.ArgumentError) as info:
        pc.findHomography(_with_nan(SRC, 3), DST)
    back = pickle.loads(pickle.dumps(info.value))
    assert type(back) is pc.OpenCVCompatibleArgumentError
    assert (str(back), back.index, back.point_set) == (str(info.value), 3, "src")


# -- raised by the Python layer --------------------------------------------------------------


def test_the_python_layer_raises_into_the_same_root() -> None:
    with pytest.raises(pc.Error) as info:
        pc.load_image("/nonexistent/board.png")
    assert isinstance(info.value, pc.ImageError)
    with pytest.raises(pc.Error) as info:
        planarcal.live.outputs.open_output("tcp://localhost")
    assert isinstance(info.value, pc.OutputError)
    with pytest.raises(pc.Error) as info:
        pc.findHomography(SRC, DST, 99)
    assert isinstance(info.value, pc.ArgumentError) and isinstance(info.value, cv2.error)
    with pytest.raises(pc.Error) as info:
        pc.Calibration(SRC, DST, solver="ransac")  # type: ignore[arg-type]
    assert isinstance(info.value, pc.ArgumentError)


def test_a_frame_of_another_size_says_both_sizes() -> None:
    cal = pc.Calibration(SRC, DST, lens="none", image_size=(640, 480))
    with pytest.raises(pc.FrameSizeError) as info:
        cal.check_image_size((1280, 720))
    assert (info.value.actual, info.value.expected) == ((1280, 720), (640, 480))
    assert isinstance(info.value, pc.Error) and isinstance(info.value, ValueError)
    back = pickle.loads(pickle.dumps(info.value))
    assert (back.actual, back.expected) == ((1280, 720), (640, 480))
