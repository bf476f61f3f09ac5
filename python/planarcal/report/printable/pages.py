"""Paper sizes: the standard pages by name (ISO A0 to A6, US letter, legal, tabloid), a
custom ``"WxH"`` in mm, the page turned to an orientation, and lengths written for people."""

from __future__ import annotations

import math
import re
from typing import Literal

from planarcal.errors import ArgumentError

Orientation = Literal["auto", "portrait", "landscape"]
"""How a page is turned; "auto": whichever fits with more room around the dots."""


PAGE_SIZES: dict[str, tuple[float, float]] = {
    "A0": (841.0, 1189.0),
    "A1": (594.0, 841.0),
    "A2": (420.0, 594.0),
    "A3": (297.0, 420.0),
    "A4": (210.0, 297.0),
    "A5": (148.0, 210.0),
    "A6": (105.0, 148.0),
    "letter": (215.9, 279.4),
    "legal": (215.9, 355.6),
    "tabloid": (279.4, 431.8),
}
"""Standard paper sizes in mm, (width, height) in portrait. ``page_size`` looks names up
case-insensitively and also accepts a custom ``"WxH"`` in mm."""


_CUSTOM_PAGE = re.compile(
    r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*[x\u00d7*]\s*(\d+(?:\.\d*)?|\.\d+)\s*(?:mm)?\s*$",
    re.IGNORECASE,
)


def page_size(name: str) -> tuple[float, float]:
    """The size (width, height) in mm of a paper named ``name``.

    Standard names (``PAGE_SIZES``: A0 to A6, letter, legal, tabloid) are matched
    case-insensitively and given in portrait. A custom size is ``"WxH"`` in mm (``"300x400"``,
    ``"297.5 x 420 mm"``), returned as written. Anything else is a ValueError listing the
    names.
    """
    return parse_page(name)[1]


def parse_page(name: str) -> tuple[str, tuple[float, float]]:
    """(canonical label, (width, height) in mm) of a page name; ArgumentError if it is none."""
    if not isinstance(name, str):
        raise ArgumentError(
            f"a page is a name like 'A4' or a size like '300x400' (mm), got {name!r}"
        )
    key = name.strip().lower()
    for standard, size in PAGE_SIZES.items():
        if standard.lower() == key:
            return standard, size
    match = _CUSTOM_PAGE.match(name)
    if match is not None:
        width, height = float(match.group(1)), float(match.group(2))
        if width > 0 and height > 0 and math.isfinite(width) and math.isfinite(height):
            return f"{num(width)}x{num(height)}", (width, height)
        raise ArgumentError(f"a custom page must have a positive width and height, got {name!r}")
    raise ArgumentError(
        f"unknown page {name!r}: use one of {', '.join(PAGE_SIZES)} (any case) "
        "or a custom size 'WxH' in mm, e.g. '300x400'"
    )


def oriented(size: tuple[float, float], orientation: str) -> tuple[float, float]:
    """(width, height) of a page turned to portrait (the short side across) or landscape."""
    short, long = sorted(size)
    return (short, long) if orientation == "portrait" else (long, short)


def page_family(name: str) -> str:
    """ "ISO A", "US" or "custom": whose larger page to suggest when a board does not fit."""
    return "ISO A" if re.fullmatch(r"A\d", name) else "US" if name in PAGE_SIZES else "custom"


def num(value: float) -> str:
    """A length for people to read: 10.0 -> '10', 215.9 -> '215.9', 0.1 + 0.2 -> '0.3'."""
    return f"{float(value):.10g}"
