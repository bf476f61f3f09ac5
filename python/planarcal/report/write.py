"""The report directory: the tables and figures of a calibration, each file written
atomically."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from planarcal.calib.calibration import Calibration
from planarcal.files import atomic_write
from planarcal.report.coverage import coverage_figure, placements_under
from planarcal.report.deviations import deviation_figure
from planarcal.report.drawing import draw_detection, png_bytes
from planarcal.report.figure import require_matplotlib
from planarcal.report.lens import lens_figure
from planarcal.report.points import points_csv
from planarcal.report.summary import residual_note, summary_json
from planarcal.report.uncertainty import uncertainty_figure


def write_report(
    cal: Calibration,
    out_dir: str | os.PathLike[str],
    *,
    image: Any = None,
    detection: Any = None,
    max_error_mm: float | None = None,
    placement_images: Sequence[Any] = (),
) -> list[Path]:
    """Writes points.csv, summary.json, deviations.png, lens.png, uncertainty.png, (with an
    image size) coverage.png, its predicted error over `image` against ``max_error_mm``
    (calib.coverage), and (with an image and its detection) detection.png into `out_dir`
    (created if need be), each atomically; returns the paths written. Any board, whole or
    seen in part: a partial view's detection figure draws the board's other points where the
    calibration puts them. ``placement_images`` (a calibration from several placements: their
    images) are shown together under coverage.png, each board where it lay (their brightest
    pixels: the paper over the table).
    Without matplotlib (the extra ``planarcal[report]``) raises MissingDependencyError before
    writing anything."""
    require_matplotlib()  # before the tables: no half-written report
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = [
        atomic_write(out / "points.csv", points_csv(cal, detection)),
        atomic_write(
            out / "summary.json",
            json.dumps(
                summary_json(cal, detection, max_error_mm=max_error_mm), indent=2, allow_nan=False
            )
            + "\n",
        ),
        atomic_write(out / "deviations.png", deviation_figure(cal)),
        atomic_write(out / "lens.png", lens_figure(cal, image=image)),
        atomic_write(out / "uncertainty.png", uncertainty_figure(cal)),
    ]
    if cal.image_size is not None:
        under = placements_under(placement_images) if len(placement_images) > 1 else image
        figure = coverage_figure(cal, under, max_error_mm=max_error_mm)
        written.append(atomic_write(out / "coverage.png", figure))
    if image is not None and detection is not None:
        drawn = draw_detection(image, detection, residual_note=residual_note(cal), calibration=cal)
        written.append(atomic_write(out / "detection.png", png_bytes(drawn)))
    return written
