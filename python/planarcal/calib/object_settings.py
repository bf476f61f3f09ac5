"""The object-detection settings a calibration carries: the outline area limits, a region of
interest and the blur that ``detect_objects`` is run with where this camera looks (a
calibration file records them, version 7: ``object_settings``). ``locate``, ``planarcal run``
and the ``Tracker`` use them unless told otherwise, field by field (``detect_options_with``).

Every field is in the image's pixels, and None means detect_objects' own default (areas from
1/5000 of the image to a quarter of it, the whole image, a blur of 1.5 px)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from planarcal import arguments
from planarcal.calib.json_number import is_json_int, is_json_real
from planarcal.camera.intrinsics import MAX_IMAGE_SIDE_PX
from planarcal.errors import ArgumentError

SETTING_FIELDS = ("min_area_px", "max_area_px", "roi", "blur_sigma")
"""The settings' fields, in the order a file writes them; each is also the name of
detect_objects' keyword argument it becomes."""

Roi = tuple[int, int, int, int]


@dataclasses.dataclass(frozen=True)
class ObjectSettings:
    """How objects are detected in this camera's images (None: detect_objects' default).
    ArgumentError (a ValueError) for a value that cannot be one, naming the field."""

    min_area_px: float | None = None
    """The smallest outline area kept, px^2 (>= 0)."""
    max_area_px: float | None = None
    """The largest outline area kept, px^2 (> 0, and at least min_area_px)."""
    roi: Roi | None = None
    """x, y, width, height of the rectangle of the image where objects are kept (by their
    centroid), px: whole numbers, x and y >= 0, width and height >= 1."""
    blur_sigma: float | None = None
    """The Gaussian blur before the edges are traced, px (>= 0; at most the image's side)."""

    def __post_init__(self) -> None:
        # Normalised to what a file holds (floats, a tuple of ints) so that equal settings
        # compare, hash and save the same whichever numbers they were given as.
        low = {"min_area_px": 0.0, "max_area_px": 0.0, "blur_sigma": 0.0}
        for name, floor in low.items():
            value = getattr(self, name)
            if value is None:
                continue
            v = arguments.real(name, value)
            if v < floor or (name == "max_area_px" and v == 0):
                bound = "> 0" if name == "max_area_px" else ">= 0"
                raise ArgumentError(f"{name} must be a number {bound}, got {value!r}")
            object.__setattr__(self, name, v)
        lo, hi = self.min_area_px, self.max_area_px
        if lo is not None and hi is not None and lo > hi:
            raise ArgumentError(
                f"min_area_px ({lo:g} px^2) is above max_area_px ({hi:g} px^2): no outline "
                "could be kept"
            )
        if self.roi is not None:
            object.__setattr__(self, "roi", _roi(self.roi))

    @property
    def is_default(self) -> bool:
        """Whether every field is None (detect_objects' defaults throughout)."""
        return self == ObjectSettings()

    def with_(self, **changes: Any) -> ObjectSettings:
        """These settings with the fields named changed (None: back to the default); a new
        ObjectSettings. ArgumentError for a field that is not one."""
        unknown = sorted(set(changes) - set(SETTING_FIELDS))
        if unknown:
            raise ArgumentError(
                f"unknown object setting {unknown[0]!r} (the settings are "
                f"{', '.join(SETTING_FIELDS)})"
            )
        return dataclasses.replace(self, **changes)

    def check_image_size(self, image_size: tuple[int, int] | None) -> None:
        """ArgumentError unless these settings can be used on images of ``image_size``
        (width, height, px; None: unknown, nothing to check): the roi must lie within the
        image and the blur be at most its larger side."""
        if image_size is None:
            return
        w, h = int(image_size[0]), int(image_size[1])
        if self.roi is not None:
            x, y, rw, rh = self.roi
            if x + rw > w or y + rh > h:
                raise ArgumentError(
                    f"roi {list(self.roi)} (x, y, width, height) reaches beyond the {w} x {h} px "
                    f"image (to x = {x + rw}, y = {y + rh})"
                )
        if self.blur_sigma is not None and self.blur_sigma > max(w, h):
            raise ArgumentError(
                f"blur_sigma {self.blur_sigma:g} px is more than the {w} x {h} px image's side"
            )

    def detect_options(self, image_size: tuple[int, int] | None = None) -> dict[str, Any]:
        """detect_objects' keyword arguments for these settings: only the fields set (the
        others are its defaults). The roi is passed as detect_objects' ``roi`` (a rectangle
        test of each centroid: no mask to build per frame). ``image_size`` (width, height):
        checked as check_image_size does."""
        self.check_image_size(image_size)
        return {k: v for k in SETTING_FIELDS if (v := getattr(self, k)) is not None}

    def scaled(self, factor: float, image_size: tuple[int, int]) -> ObjectSettings:
        """These settings for frames `factor` times as large in each direction (of
        ``image_size``): areas by factor^2, the blur by factor, the roi's edges by factor
        (to whole pixels, within the image). See Calibration.for_frame_size."""
        s = arguments.positive("factor", factor)
        roi = self.roi
        if roi is not None:
            w, h = image_size
            x0, y0 = min(round(roi[0] * s), w - 1), min(round(roi[1] * s), h - 1)
            x1 = min(max(round((roi[0] + roi[2]) * s), x0 + 1), w)
            y1 = min(max(round((roi[1] + roi[3]) * s), y0 + 1), h)
            roi = (x0, y0, x1 - x0, y1 - y0)

        def times(v: float | None, k: float) -> float | None:
            return None if v is None else v * k

        return ObjectSettings(
            times(self.min_area_px, s * s),
            times(self.max_area_px, s * s),
            roi,
            times(self.blur_sigma, s),
        )

    def to_dict(self) -> dict[str, Any]:
        """The settings as a calibration file holds them: every field, null where unset."""
        return {
            "min_area_px": self.min_area_px,
            "max_area_px": self.max_area_px,
            "roi": None if self.roi is None else list(self.roi),
            "blur_sigma": self.blur_sigma,
        }

    @classmethod
    def from_dict(cls, data: Any) -> ObjectSettings:
        """The settings ``to_dict`` gives (a field left out is None). ArgumentError, naming
        the key, for a key that is no setting or a value of the wrong JSON type (a number
        is an int or a float, never a bool or a string; the roi a list of four whole
        numbers), as for a value out of range."""
        if not isinstance(data, Mapping):
            raise ArgumentError(f"object settings must be a JSON object, got {type(data).__name__}")
        for key in data:
            if key not in SETTING_FIELDS:
                raise ArgumentError(
                    f"unknown object setting {key!r} (the settings are {', '.join(SETTING_FIELDS)})"
                )
        values: dict[str, Any] = {}
        for key in SETTING_FIELDS:
            value = data.get(key)
            if value is None:
                continue
            if key == "roi":
                if not (
                    isinstance(value, list | tuple)
                    and len(value) == 4
                    and all(is_json_int(v) for v in value)
                ):
                    raise ArgumentError(
                        f"roi must be null or [x, y, width, height], four whole numbers of "
                        f"px, got {_short(value)}"
                    )
            elif not is_json_real(value):
                raise ArgumentError(f"{key} must be null or a number, got {_short(value)}")
            values[key] = value
        return cls(**values)

    def describe(self) -> str:
        """The settings in words, for a message or a report ("default" where none is set)."""
        parts = []
        if self.min_area_px is not None:
            parts.append(f"min area {self.min_area_px:g} px^2")
        if self.max_area_px is not None:
            parts.append(f"max area {self.max_area_px:g} px^2")
        if self.roi is not None:
            x, y, w, h = self.roi
            parts.append(f"roi {w} x {h} px at ({x}, {y})")
        if self.blur_sigma is not None:
            parts.append(f"blur {self.blur_sigma:g} px")
        return ", ".join(parts) or "default"


def detect_options_with(
    settings: ObjectSettings,
    overrides: Mapping[str, Any],
    image_size: tuple[int, int] | None = None,
) -> dict[str, Any]:
    """detect_objects' keyword arguments: `settings` with each of its fields that
    `overrides` names replaced by the value there (None: detect_objects' default), and
    overrides' other options (``mask``, ``canny``, ...) passed through. ArgumentError if the
    result is not valid settings (an override below zero; a minimum area above the maximum,
    one of them from each)."""
    changes = {k: overrides[k] for k in SETTING_FIELDS if k in overrides}
    merged = settings.with_(**changes)
    rest = {k: v for k, v in overrides.items() if k not in SETTING_FIELDS}
    return {**merged.detect_options(image_size), **rest}


def _roi(value: Any) -> Roi:
    """`value` as (x, y, width, height): four whole numbers (ints, not bools or floats),
    x, y >= 0, width, height >= 1, within MAX_IMAGE_SIDE_PX."""
    try:
        items = list(value)
    except TypeError:
        items = []
    if isinstance(value, str | bytes) or len(items) != 4:
        raise ArgumentError(f"roi must be (x, y, width, height), got {_short(value)}")
    out = []
    for i, (name, v) in enumerate(zip(("x", "y", "width", "height"), items, strict=True)):
        if isinstance(v, bool) or not isinstance(v, int | np.integer):
            raise ArgumentError(f"roi[{i}] ({name}) must be a whole number of px, got {v!r}")
        least = 0 if i < 2 else 1
        if not least <= int(v) <= MAX_IMAGE_SIDE_PX:
            raise ArgumentError(
                f"roi[{i}] ({name}) must be from {least} to {MAX_IMAGE_SIDE_PX} px, got {v!r}"
            )
        out.append(int(v))
    return (out[0], out[1], out[2], out[3])


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
