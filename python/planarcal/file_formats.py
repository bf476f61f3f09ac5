"""The format marker of planarcal's calibration file, in a module of its own: the intrinsics
reader recognises a calibration given in its place without importing the calibration code
(which imports the camera package, and so the intrinsics reader)."""

from __future__ import annotations

CALIBRATION_FORMAT = "planarcal-calibration"
"""The ``"format"`` field of every calibration file (calib.calibration_file.FILE_FORMAT)."""
