"""The per-point table as CSV: the paper's Tables 2-4 and the leave-one-out error, every
point, with the detection's flags for each dot. Points are numbered as everywhere in
planarcal (the touch CSV, the API, the summary, the detection figure): by their id, k = row x
cols + col on a grid board, 0 the origin; a partial view has the ids of the points seen. The
first column is named by the board's word for its points: "dot" (a circle grid, and points
without a board), "corner" (a chessboard, a ChArUco board)."""

from __future__ import annotations

import csv
import io
import math
from typing import Any

from planarcal.calib.calibration import Calibration
from planarcal.report.drawing import dot_flags
from planarcal.report.point_names import calibration_ids, grid_shape, point_name

CSV_COLUMNS = (
    "dot",
    "row",
    "col",
    "world_x_mm",
    "world_y_mm",
    "image_x_px",
    "image_y_px",
    "reprojected_x_px",
    "reprojected_y_px",
    "error_px",
    "world_after_x_mm",
    "world_after_y_mm",
    "dx_mm",
    "dy_mm",
    "loo_dx_mm",
    "loo_dy_mm",
    "loo_error_mm",
    "loo_error_px",
    "predicted_loo_std_mm",
    "refined",
    "enlarged",
)


def points_csv(cal: Calibration, detection: Any = None) -> str:
    """The per-point table as CSV: the point's id (``dot`` or ``corner``, the board's word:
    k = row x cols + col on a grid, 0 the origin; the row of ``world_points`` without a
    board), its row and column on the board (when it is a grid), world and image
    coordinates, reprojection (Table 3), world after calibration and deviations (Table 4),
    the leave-one-out deviation and error (mm, and px in the image), the leave-one-out error
    the fit's covariance predicts (1-sigma, mm), and whether the detection refined the
    point's centre and found it enlarged (1 / 0; empty when the detection does not say)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow((point_name(cal.board), *CSV_COLUMNS[1:]))
    shape = grid_shape(cal.board)
    ids = calibration_ids(cal, detection)
    n = len(cal.world_points)
    refined = _flag_column(detection, "refined", n)
    enlarged = _flag_column(detection, "enlarged", n)
    for i in range(n):
        row, col = ("", "") if shape is None else divmod(int(ids[i]), shape[0])
        values = [
            *cal.world_points[i],
            *cal.image_points[i],
            *cal.reprojected_px[i],
            cal.reprojection_errors_px[i],
            *cal.world_after_mm[i],
            *cal.deviations_mm[i],
            *cal.loo_deviations_mm[i],
            cal.loo_errors_mm[i],
            cal.loo_errors_px[i],
            cal.predicted_loo_std_mm[i],
        ]
        writer.writerow(
            [
                int(ids[i]),
                row,
                col,
                *(f"{v:.6f}" if math.isfinite(v) else "" for v in values),
                refined[i],
                enlarged[i],
            ]
        )
    return buf.getvalue()


def _flag_column(detection: Any, name: str, n: int) -> list[str]:
    """A per-dot flag as a CSV column of "1" / "0", or of "" when there is none for these
    `n` points."""
    flags = None if detection is None else dot_flags(detection, name)
    if flags is None or len(flags) != n:
        return [""] * n
    return ["1" if f else "0" for f in flags]
