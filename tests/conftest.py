"""Shared fixtures: the paper's tables (from ../shared, skipped where absent) and the
hypothesis profile."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeAlias

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "default",
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile("default")

# The type of pytest's record_property fixture (a property's name and value), which pytest
# does not export under a name.
RecordProperty: TypeAlias = Callable[[str, object], None]

# The project's shared material (the paper's tables, real photographs): ../shared beside the
# checkout, or wherever PLANARCAL_SHARED points. The package itself never needs it.
SHARED = Path(
    os.environ.get("PLANARCAL_SHARED", Path(__file__).resolve().parents[1].parent / "shared")
)


@pytest.fixture(scope="session")
def paper_tables() -> dict[str, Any]:
    path = SHARED / "paper" / "paper_tables.json"
    if not path.exists():
        pytest.skip(f"the paper's tables are not here ({path}): ../shared is absent")
    data: dict[str, Any] = json.loads(path.read_text())
    return data


def decode_png(png: bytes) -> Any:
    """A PNG file's bytes decoded by OpenCV (BGR), checked to be a PNG that decodes."""
    assert png.startswith(b"\x89PNG")
    picture = cv2.imdecode(np.frombuffer(png, dtype=np.uint8), cv2.IMREAD_COLOR)
    assert picture is not None
    return np.asarray(picture)
