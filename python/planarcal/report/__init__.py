"""The calibration report: the paper's tables and figures, and the honest accuracy figure.

* ``summary_text`` / ``summary_json`` (summary.py): mean, max, min and RMS reprojection error
  (px, Eq. 6-7), the leave-one-out error (mm), the largest deviations dX, dY (mm, Table 4);
  the lens model (its parameters, the models tried and why this one), the figures before and
  after it (a homography alone against the chosen model), the leave-one-out error the
  covariance predicts against the measured one, and the printer-scale correction.
* ``points_csv`` (points.py): the per-point table (Tables 2-4 and the leave-one-out error,
  every point).
* ``deviation_figure`` (deviations.py): the paper's Figure 5 (dX and dY per point) with a
  vector field of the deviations over the board, as PNG.
* ``lens_figure`` (lens.py): the residuals before and after the lens model over the image,
  and the distortion it found, as PNG.
* ``uncertainty_figure`` (uncertainty.py): the 1-sigma position uncertainty (mm) as a heat
  map over the working area, with where it doubles relative to the board's centre, as PNG.
* ``coverage_figure`` / ``draw_coverage`` (coverage.py): the predicted error (mm) over the
  whole image with each placement's outline and the largest region above a limit
  (calib.coverage), as PNG or drawn on an image (the live page's).
* ``write_report`` (write.py): all of these (and the detection drawn on the image, Figure 4,
  drawing.py) into a directory, each file written atomically.
* ``detection_failure_figure`` / ``write_detection_failure`` (failure.py): when the board is
  not found, the image with what the search saw (the blobs, each candidate grid and why it
  was refused) and the error, as PNG.
* printable/: the board itself, printable at exact scale as SVG or PDF.

Every table, text and figure works for any board (planarcal.calib.boards) whole or seen in
part: points are named by the board's word for them and by their ids (point_names.py), and a
partial view's detection figure draws the board's other points where the fit puts them.

The figures share figure.py (the one check that matplotlib, the extra ``planarcal[report]``,
is installed, a figure and its PNG), fits.py (the fit before the lens model) and mapping.py
(where the image's pixels land on the plane). The tables and the summaries need no matplotlib;
every figure raises MissingDependencyError without it.
"""

from planarcal.report.coverage import coverage_figure, draw_coverage
from planarcal.report.deviations import deviation_figure
from planarcal.report.failure import (
    DETECTION_FAILED_PNG,
    detection_failure_figure,
    detection_failure_text,
    write_detection_failure,
)
from planarcal.report.lens import lens_figure
from planarcal.report.points import CSV_COLUMNS, points_csv
from planarcal.report.summary import residual_note, summary_json, summary_text
from planarcal.report.uncertainty import uncertainty_figure
from planarcal.report.write import write_report

__all__ = [
    "CSV_COLUMNS",
    "DETECTION_FAILED_PNG",
    "coverage_figure",
    "detection_failure_figure",
    "detection_failure_text",
    "deviation_figure",
    "draw_coverage",
    "lens_figure",
    "points_csv",
    "residual_note",
    "summary_json",
    "summary_text",
    "uncertainty_figure",
    "write_detection_failure",
    "write_report",
]
