"""Every exception planarcal raises, defined here and nowhere else.

``Error`` is the root: ``except planarcal.Error`` catches whatever planarcal raises on purpose.
Where the input is at fault the exception is also a ``ValueError``, so ``except ValueError``
keeps working for code that does not know the library; ``CameraError`` is an ``OSError`` (a
device or a stream failed, not an argument), ``MissingDependencyError`` an ``ImportError`` (an
optional extra is not installed). The Rust bindings raise the classes below too
(``pyo3::import_exception!`` looks them up here), so each class has one definition::

    Error
    ├── ArgumentError            (ValueError) a bad argument: shape, dtype, NaN, option value
    │   ├── ArgumentTypeError    (also TypeError) an argument of the wrong type
    │   └── OpenCVCompatibleArgumentError   (also cv2.error)
    ├── HomographyError          (ValueError) no homography can be estimated or applied
    │   ├── DegenerateError      well-formed points whose geometry determines none
    │   ├── PointAtInfinityError a point with no image (at infinity, behind the horizon)
    │   └── OpenCVCompatibleError           (also cv2.error)
    │       └── OpenCVCompatiblePointAtInfinityError
    ├── LensModelError           (ValueError) a lens model that cannot be fitted or applied
    ├── RegistrationError        (ValueError) point pairs that cannot fix the plane-to-robot map
    ├── BoardError, ImageError, BoardNotFoundError (BoardTurnedError), CalibrationFileError,
    │   FrameSizeError, IntrinsicsError, OutputError, PlacementError          (ValueError)
    │   └── BoardMismatchError (a BoardError) the image contradicts the board's description
    ├── CameraError              (OSError)
    ├── MissingDependencyError   (ImportError) an optional extra is not installed
    ├── NotFoundError            (LookupError, ValueError) no such placement, figure, point
    └── StateError               (RuntimeError) a call the object's state does not allow
        └── BusyError            another change is being made (the live page's one writer)

Errors about one point say which, as attributes, so callers need not parse the message:
``index`` (the point's row in its array) and ``point_set`` (``"src"`` or ``"dst"``, the set of
a correspondence problem; None when the call takes one set of points or the error is about
no particular set).
"""

from __future__ import annotations

from typing import Any

import cv2

__all__ = [
    "ArgumentError",
    "ArgumentTypeError",
    "BoardError",
    "BoardMismatchError",
    "BoardNotFoundError",
    "BoardTurnedError",
    "BusyError",
    "CalibrationFileError",
    "CameraError",
    "DegenerateError",
    "Error",
    "FrameSizeError",
    "HomographyError",
    "ImageError",
    "IntrinsicsError",
    "LensModelError",
    "MissingDependencyError",
    "NotFoundError",
    "OpenCVCompatibleArgumentError",
    "OpenCVCompatibleError",
    "OpenCVCompatiblePointAtInfinityError",
    "OutputError",
    "PlacementError",
    "PointAtInfinityError",
    "RegistrationError",
    "StateError",
]


class Error(Exception):
    """The root of every exception planarcal raises."""


class _PointError(Error):
    """An error that may name the point at fault: ``index`` (its row) and ``point_set``
    (``"src"`` or ``"dst"``), None where it names none. Positional after the message, so the
    bindings can raise it lazily with one argument tuple; pickles with both (BaseException
    keeps the instance dict)."""

    index: int | None
    point_set: str | None

    def __init__(
        self, message: str = "", index: int | None = None, point_set: str | None = None
    ) -> None:
        super().__init__(message)
        self.index = index
        self.point_set = point_set


class ArgumentError(_PointError, ValueError):
    """An argument that cannot be used as given: the wrong shape or dtype, a NaN or infinite
    coordinate, point sets of different lengths, an option value out of its range. Distinct
    from ``HomographyError``, which says the (valid) data determine no homography."""


class ArgumentTypeError(ArgumentError, TypeError):
    """An argument of the wrong type (a bool where a count belongs, a number where a path
    does): also a ``TypeError``, as Python's own type errors are."""


class HomographyError(_PointError, ValueError):
    """The points, though valid arguments, cannot give a homography (fewer than 4, or a
    spread beyond floating point), or a homography cannot be applied to them."""


class DegenerateError(HomographyError):
    """The points are well-formed but their geometry does not determine a homography:
    collinear (``index`` names the one point off the line, if one is), too few distinct, on
    both sides of the horizon of the homography they imply, or a singular fit."""


class PointAtInfinityError(HomographyError):
    """Points that have no image: they map to infinity or behind the horizon, or are not
    finite (where a call maps each point on its own, as ``transform_points``). ``index`` is
    the first such point."""


class LensModelError(_PointError, ValueError):
    """A lens-distortion model that cannot be fitted or applied: no image size to centre it
    on, a distortion that folds the image over, a point outside the model's valid radius
    (``index`` names it)."""


class RegistrationError(Error, ValueError):
    """Point pairs (board mm, robot mm) that cannot fix the board-to-robot transform: too few
    for the model, too clustered or collinear, or a stored registration that does not hold
    together."""


class BoardError(Error, ValueError):
    """A board description that cannot be a circle grid (sizes, counts, a dot too large)."""


class BoardMismatchError(BoardError):
    """The board in the image contradicts its description: its dots, measured on the board
    through the homography, are not the stated size for the stated pitch (the diameter or
    the pitch is wrong), or its origin marker is not the stated size for its dots."""


class PlacementError(Error, ValueError):
    """A placement of the board (one of several images calibrated together) that the plane
    the others define cannot explain: a board not flat on the plane (lifted on one side,
    lying on a part) or a wrong detection. ``placement`` is its index (0-based)."""

    def __init__(self, message: str = "", placement: int | None = None) -> None:
        super().__init__(message)
        self.placement = placement


class ImageError(Error, ValueError):
    """An image that cannot be used: unreadable, empty, of the wrong type or shape."""


class BoardNotFoundError(Error, ValueError):
    """The image does not show the board: says what was seen and what to try.

    ``diagnostics`` (a :class:`planarcal.calib.detect.DetectionDiagnostics`, or None) holds what the
    search saw: the blobs of each polarity and each candidate grid with why it was refused;
    ``calibrate --report`` draws it."""

    def __init__(self, message: str, diagnostics: Any = None) -> None:
        super().__init__(message)
        self.diagnostics = diagnostics

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (str(self), self.diagnostics))


class BoardTurnedError(BoardNotFoundError):
    """The grid found fits the board only turned by 90 degrees (``--cols``/``--rows``
    swapped?), and no origin marker settles which way it lies."""


class CalibrationFileError(Error, ValueError):
    """A calibration file that cannot be loaded: corrupt, truncated, or of another version."""


class FrameSizeError(Error, ValueError):
    """An image or frame of another size than the calibration was made on: its pixels would
    map to the wrong millimetres. ``actual`` (alias ``frame_size``) and ``expected`` (alias
    ``calibration_size``) are the two (width, height) in px (``expected`` None when the
    calibration records none)."""

    def __init__(
        self,
        message: str,
        frame_size: tuple[int, int] | None = None,
        calibration_size: tuple[int, int] | None = None,
    ) -> None:
        super().__init__(message)
        self.frame_size = frame_size
        self.calibration_size = calibration_size

    @property
    def actual(self) -> tuple[int, int] | None:
        """The frame's (width, height) in px."""
        return self.frame_size

    @property
    def expected(self) -> tuple[int, int] | None:
        """The (width, height) in px the calibration was made on, None if it records none."""
        return self.calibration_size

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (str(self), self.frame_size, self.calibration_size))


class CameraError(Error, OSError):
    """A camera, video, stream or image folder that cannot be opened or stops delivering."""


class MissingDependencyError(Error, ImportError):
    """A call needs a package of an optional extra that is not installed (the report's
    figures need matplotlib: ``pip install 'planarcal[report]'``); the message says what to
    install, ``name`` is the missing package."""


class StateError(Error, RuntimeError):
    """A call the object's state does not allow, such as iterating a Tracker a second time:
    the program's order is at fault, not an argument."""


class BusyError(StateError):
    """Another change is being made and did not end in time (the live page makes one change
    at a time): try again."""


class NotFoundError(Error, LookupError, ValueError):
    """What a request names does not exist: a placement, a report figure, a board point (the
    request is at fault: also a ValueError)."""


class IntrinsicsError(Error, ValueError):
    """Camera intrinsics that cannot be used or estimated: a malformed camera matrix or
    distortion vector, an unreadable OpenCV YAML file, too few or degenerate board views."""


class OutputError(Error, ValueError):
    """An output that cannot be used as given: a malformed ``-o`` spec (no port, a port out
    of range, an unknown scheme), a sink parameter out of range, or a line that would break
    the one-JSON-document-per-line framing."""


# The OpenCV drop-ins (planarcal.findHomography, perspectiveTransform) raise these: planarcal
# errors that are also a cv2.error, so code written for OpenCV (``except cv2.error``) still
# catches them.


class OpenCVCompatibleError(HomographyError, cv2.error):
    """A HomographyError that is also a cv2.error, for code written for OpenCV."""


class OpenCVCompatiblePointAtInfinityError(PointAtInfinityError, OpenCVCompatibleError):
    """A PointAtInfinityError that is also a cv2.error."""


class OpenCVCompatibleArgumentError(ArgumentError, cv2.error):
    """An ArgumentError that is also a cv2.error."""
