"""Which options the detector of each board kind takes (a circle grid's ``polarity`` and
``turned``, a chessboard's ``turned``, ...): read from the detector's own signature, so that
the command line and the camera's calibration offer an option only where it applies, and a
new detector's options need no table here."""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Mapping
from typing import Any

from planarcal.calib.detection import DETECTORS
from planarcal.errors import ArgumentError


def detector_options(kind: str) -> tuple[str, ...]:
    """The keyword options the detector of board kind `kind` names (not its ``**options``),
    in its signature's order; KeyError for a kind with no detector."""
    module, name = DETECTORS[kind].split(":")
    detector = getattr(importlib.import_module(module), name)
    params = inspect.signature(detector).parameters.values()
    return tuple(p.name for p in params if p.kind is inspect.Parameter.KEYWORD_ONLY)


def check_detector_options(kind: str, options: Mapping[str, Any]) -> None:
    """ArgumentError naming an option the detector of board kind `kind` does not take, and
    those it does (a detector with ``**options`` checks its own)."""
    module, name = DETECTORS[kind].split(":")
    detector = getattr(importlib.import_module(module), name)
    params = inspect.signature(detector).parameters.values()
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params):
        return
    takes = detector_options(kind)
    for option in options:
        if option not in takes:
            what = ", ".join(takes) if takes else "none"
            raise ArgumentError(
                f"the {kind} detector has no option {option!r} (its options: {what})"
            )
