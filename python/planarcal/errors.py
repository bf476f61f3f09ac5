"""The exceptions of planarcal's Python layer. Where the input is at fault they are
ValueErrors, so ``except ValueError`` works for users who do not know the library; the
homography errors of the Rust core (HomographyError and its subclasses) are re-exported here
so one module names them all (LensModelError, for lens models that cannot be fitted or
applied, comes from the core too)."""

from __future__ import annotations

from typing import Any

from planarcal._core import (
    DegenerateError,
    HomographyError,
    LensModelError,
    PointAtInfinityError,
)

__all__ = [
    "BoardError",
    "BoardNotFoundError",
    "CalibrationFileError",
    "CameraError",
    "DegenerateError",
    "FrameSizeError",
    "HomographyError",
    "ImageError",
    "IntrinsicsError",
    "LensModelError",
    "PointAtInfinityError",
]


class BoardError(ValueError):
    """A board description that cannot be a circle grid (sizes, counts, a dot too large)."""


class ImageError(ValueError):
    """An image that cannot be used: unreadable, empty, of the wrong type or shape."""


class BoardNotFoundError(ValueError):
    """The image does not show the board: says what was seen and what to try.

    ``diagnostics`` (a :class:`planarcal.detect.DetectionDiagnostics`, or None) holds what the
    search saw: the blobs of each polarity and each candidate grid with why it was refused;
    ``calibrate --report`` draws it."""

    def __init__(self, message: str, diagnostics: Any = None) -> None:
        super().__init__(message)
        self.diagnostics = diagnostics

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (str(self), self.diagnostics))


class CalibrationFileError(ValueError):
    """A calibration file that cannot be loaded: corrupt, truncated, or of another version."""


class FrameSizeError(ValueError):
    """An image or frame of another size than the calibration was made on: its pixels would
    map to the wrong millimetres. ``frame_size`` and ``calibration_size`` are the two
    (width, height) in px (``calibration_size`` None when the calibration records none)."""

    def __init__(
        self,
        message: str,
        frame_size: tuple[int, int] | None = None,
        calibration_size: tuple[int, int] | None = None,
    ) -> None:
        super().__init__(message)
        self.frame_size = frame_size
        self.calibration_size = calibration_size

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (str(self), self.frame_size, self.calibration_size))


class CameraError(OSError):
    """A camera, video, stream or image folder that cannot be opened or stops delivering."""


class IntrinsicsError(ValueError):
    """Camera intrinsics that cannot be used or estimated: a malformed camera matrix or
    distortion vector, an unreadable OpenCV YAML file, too few or degenerate board views."""
