"""An index of points in raster order, in blocks, to find quickly those near a small shape
(a dot, an object): most blocks of the image lie far from it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


class _PointIndex:
    """Points (x, y), flattened, in blocks of consecutive ones with each block's bounding box,
    to find those within a box quickly: the renderer's points come in raster order, so a
    block is a compact patch of the image and most blocks lie far from a small object."""

    BLOCK = 2048

    def __init__(self, x: F64, y: F64) -> None:
        self.x, self.y = x.reshape(-1), y.reshape(-1)
        n, b = self.x.size, self.BLOCK
        fill = (-n) % b
        boxes = []
        for v in (self.x, self.y):
            blocks = np.pad(v, (0, fill), mode="edge").reshape(-1, b) if n else v.reshape(0, b)
            boxes += [blocks.min(axis=1), blocks.max(axis=1)]
        self.x_lo, self.x_hi, self.y_lo, self.y_hi = boxes

    def near(self, box: tuple[float, float, float, float], pad: float) -> NDArray[np.intp]:
        """Indices (ascending) of the points in box (x0, x1, y0, y1) grown by pad."""
        x0, x1, y0, y1 = box[0] - pad, box[1] + pad, box[2] - pad, box[3] + pad
        hit = np.flatnonzero(
            (self.x_hi >= x0) & (self.x_lo <= x1) & (self.y_hi >= y0) & (self.y_lo <= y1)
        )
        idx = (hit[:, None] * self.BLOCK + np.arange(self.BLOCK)[None, :]).reshape(-1)
        idx = idx[idx < self.x.size]
        xs, ys = self.x[idx], self.y[idx]
        return np.asarray(idx[(xs >= x0) & (xs <= x1) & (ys >= y0) & (ys <= y1)], dtype=np.intp)
