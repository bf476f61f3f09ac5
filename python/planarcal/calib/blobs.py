"""Dark, filled, elliptical blobs in a grey image: the candidates for a board's dots.

The image is thresholded at many grey levels, as OpenCV's SimpleBlobDetector does (a dot is
darker than its surroundings at some level whatever the lighting), but each level is read by
connected components and their moments in bulk, so the cost does not grow with the number of
shapes in view: a 1280 x 720 frame of pure noise costs what a board photograph does. A
component is kept when it is a filled ellipse: its area matches the ellipse of its second
moments (a ring, a digit or a stroke does not), its axes are within 1:3 and it does not touch
the image's border. A blob is a component seen at two or more levels, one inside the other.

Memory: a level needs its mask (1 byte a pixel) and its labels (4, or 2 where a large image's
components fit 16 bits); a small image's levels are read two at a time, a large one's one at
a time, with OpenCV's statistics (tens of bytes a component per thread) taken of the
components of a dot's size alone, so the search needs a few bytes a pixel above the image,
whatever its size and content. Levels whose masks are the same are read once.
"""

from __future__ import annotations

import dataclasses
import math
from concurrent.futures import ThreadPoolExecutor
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

F64 = NDArray[np.float64]

# Grey levels tried: every 15th (a dot 30 grey levels darker than its paper spans two).
LEVELS = tuple(range(15, 250, 15))
# A filled ellipse's area over the area of the ellipse of its moments: 1 (digitised: near 1).
FILL_RANGE = (0.8, 1.2)
# Second-moment ratio (minor / major): 1:3 axes at most.
MIN_INERTIA_RATIO = 1.0 / 9.0
# Above this many pixels the levels are read one at a time, with 16-bit labels where they fit,
# and the statistics are taken of the components of a dot's size alone.
LARGE_IMAGE_PX = 1 << 24
# Candidates' bounding-box pixels whose moments are summed at a time.
MOMENT_BATCH_PX = 1 << 21
# Pixels of a large image's labels counted at a time.
LABEL_BLOCK_PX = 1 << 20


@dataclasses.dataclass(frozen=True)
class Blobs:
    """Blob centres (N, 2) px, equivalent diameters (N,) px and how many grey levels each
    was seen at (N,)."""

    centres: F64
    diameters: F64
    levels: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.diameters)

    def subset(self, keep: NDArray[np.bool_] | NDArray[np.intp]) -> Blobs:
        return Blobs(self.centres[keep], self.diameters[keep], self.levels[keep])


def find_blobs(
    image: NDArray[np.uint8], min_diameter: float, max_diameter: float, *, dark: bool = True
) -> Blobs:
    """The dark blobs of `image` (light ones with ``dark=False``: those of 255 - image, found
    without making that copy) whose equivalent diameter is in [min_diameter, max_diameter]
    px, each seen at two or more grey levels."""
    area_range = (np.pi / 4 * min_diameter**2, np.pi / 4 * max_diameter**2)

    width = _LabelWidth()

    def at_level(level: int) -> tuple[F64, F64]:
        return _level_components(image, level, area_range, dark, width)

    # The masks are nested, so two levels whose masks hold as many pixels have the same mask
    # and the same components: each distinct mask is read once. A mask that is empty or
    # whole has no component that does not touch the border (a blank or saturated image
    # costs nothing).
    inked = _inked_pixels(image, dark)
    distinct = sorted({inked[level]: level for level in reversed(LEVELS)}.items())
    to_read = [level for count, level in distinct if 0 < count < image.size]
    if image.size > LARGE_IMAGE_PX:
        read = [at_level(level) for level in to_read]
    else:
        # OpenCV releases the GIL: the levels are read side by side.
        with ThreadPoolExecutor(max_workers=2) as pool:
            read = list(pool.map(at_level, to_read))
    by_count = {inked[level]: found for level, found in zip(to_read, read, strict=True)}
    nothing = (np.zeros((0, 2)), np.zeros(0))
    per_level = [by_count.get(inked[level], nothing) for level in LEVELS]
    # Chain each level's components to the previous level's at the same place.
    groups: list[NDArray[np.intp]] = []
    n_groups = 0
    prev_xy, prev_group = np.zeros((0, 2)), np.zeros(0, dtype=np.intp)
    for xy, d in per_level:
        group = np.full(len(d), -1, dtype=np.intp)
        if len(d) and len(prev_xy):
            nearest, dist = _nearest(xy, prev_xy)
            near = np.flatnonzero(dist <= 0.25 * d + 1.0)
            # Two components of one level joined to one chain: the nearer keeps it.
            near = near[np.lexsort((dist[near], prev_group[nearest[near]]))]
            _, first = np.unique(prev_group[nearest[near]], return_index=True)
            keep = near[first]
            group[keep] = prev_group[nearest[keep]]
        fresh = group < 0
        group[fresh] = n_groups + np.arange(int(fresh.sum()))
        n_groups += int(fresh.sum())
        groups.append(group)
        prev_xy, prev_group = xy, group
    if not n_groups:
        return Blobs(np.zeros((0, 2)), np.zeros(0), np.zeros(0, np.int64))
    every = np.concatenate(groups)
    xy_all = np.concatenate([xy for xy, _ in per_level])
    d_all = np.concatenate([d for _, d in per_level])
    c = np.bincount(every, minlength=n_groups)
    seen = c >= 2
    centres = np.column_stack(
        [np.bincount(every, xy_all[:, i], minlength=n_groups) / np.maximum(c, 1) for i in (0, 1)]
    )[seen]
    diameters = (np.bincount(every, d_all, minlength=n_groups) / np.maximum(c, 1))[seen]
    return _one_per_place(Blobs(centres, diameters, c[seen].astype(np.int64)))


def _inked_pixels(image: NDArray[np.uint8], dark: bool) -> NDArray[np.int64]:
    """For each level 0..256, how many pixels are darker than it (of 255 - image where not
    `dark`): the size of its mask."""
    # calcHist counts in float32, exact to 2^24: a block of rows at a time keeps it exact.
    rows = max(1, (1 << 22) // max(1, image.shape[1]))
    hist = np.zeros(256, dtype=np.int64)
    for top in range(0, image.shape[0], rows):
        block = image[top : top + rows]
        hist += cv2.calcHist([block], [0], None, [256], [0, 256]).ravel().astype(np.int64)
    if not dark:
        hist = hist[::-1]
    return np.concatenate([[0], np.cumsum(hist)])


@dataclasses.dataclass
class _LabelWidth:
    """Whether a large image's labels need 32 bits: set once a level of the search has more
    components than 16 bits number, so that the levels after it do not try 16 first."""

    wide: bool = False


def _level_components(
    image: NDArray[np.uint8],
    level: int,
    area_range: tuple[float, float],
    dark: bool,
    width: _LabelWidth,
) -> tuple[F64, F64]:
    """Centres (K, 2) and equivalent diameters (K,) of the filled ellipses darker than
    `level` (of 255 - image where not `dark`)."""
    h, w = image.shape
    if dark:
        _, mask = cv2.threshold(image, level - 1, 1, cv2.THRESH_BINARY_INV)
    else:  # 255 - image < level
        _, mask = cv2.threshold(image, 255 - level, 1, cv2.THRESH_BINARY)
    # The mask is handed over: a large image's is rewritten in place.
    found = _sized_components(mask, area_range, width)
    del mask
    labels, ids, boxes, pixels, centroids = found
    x0, y0, bw, bh = boxes.T
    area = pixels.astype(np.float64)
    ok = (x0 > 0) & (y0 > 0) & (x0 + bw < w) & (y0 + bh < h)
    # An ellipse fills at least half its bounding box (pi/8 at 1:3 and 45 degrees, digitised).
    ok &= area >= 0.38 * bw * bh
    if not ok.any():
        return np.zeros((0, 2)), np.zeros(0)
    ids, x0, y0, bw, bh, area = ids[ok], x0[ok], y0[ok], bw[ok], bh[ok], area[ok]
    centres = np.asarray(centroids[ok], dtype=np.float64)
    keep = np.zeros(len(ids), dtype=bool)
    # Second moments of the candidates, in bulk over their bounding boxes' pixels, a batch
    # of candidates at a time (the pixel arrays take 50 bytes a pixel).
    sizes = (bw * bh).astype(np.int64)
    ends = np.cumsum(sizes)
    first = 0
    while first < len(ids):
        last = max(
            first + 1, int(np.searchsorted(ends, ends[first] - sizes[first] + MOMENT_BATCH_PX))
        )
        batch = slice(first, last)
        keep[batch] = _filled_components(
            labels,
            ids[batch],
            x0[batch],
            y0[batch],
            bw[batch],
            bh[batch],
            centres[batch],
            area[batch],
        )
        first = last
    return centres[keep], np.sqrt(4.0 * area[keep] / np.pi)


def _filled_components(
    labels: NDArray[Any],
    ids: NDArray[np.intp],
    x0: NDArray[Any],
    y0: NDArray[Any],
    bw: NDArray[Any],
    bh: NDArray[Any],
    centres: F64,
    area: F64,
) -> NDArray[np.bool_]:
    """Which of these components (labels `ids`, bounding boxes, centroids, areas) are filled
    ellipses, by their second moments over their pixels."""
    sizes = (bw * bh).astype(np.int64)
    owner = np.repeat(np.arange(len(ids)), sizes)
    offset = np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    px = x0[owner] + offset % bw[owner]
    py = y0[owner] + offset // bw[owner]
    mine = labels[py, px] == ids[owner]
    owner = owner[mine]
    dx = px[mine] - centres[owner, 0]
    dy = py[mine] - centres[owner, 1]
    k = len(ids)
    sxx = np.bincount(owner, dx * dx, minlength=k) / area + 1.0 / 12.0
    syy = np.bincount(owner, dy * dy, minlength=k) / area + 1.0 / 12.0
    sxy = np.bincount(owner, dx * dy, minlength=k) / area
    return _filled_ellipses(area, sxx, syy, sxy)


def _sized_components(
    mask: NDArray[Any], area_range: tuple[float, float], width: _LabelWidth
) -> tuple[NDArray[Any], NDArray[np.intp], NDArray[Any], NDArray[Any], F64]:
    """The 8-connected components of `mask` whose area is in `area_range`: the labels image,
    their labels (K,), bounding boxes (K, 4: left, top, width, height), areas (K,) px and
    centroids (K, 2), by OpenCV's connectedComponentsWithStats.

    A large image's are measured on a mask of them alone (OpenCV's statistics take tens of
    bytes per component for each of its threads' stripes, and a noise image has a million
    components per 16 Mpx): the same components, the same statistics. MemoryError where
    OpenCV runs out of memory (it raises cv2.error)."""
    low, high = math.ceil(area_range[0]), math.floor(area_range[1])
    try:
        if mask.size > LARGE_IMAGE_PX:
            count = _keep_sized_only(mask, low, high, width)
            narrow = _LabelWidth(wide=count >= 2**16 - 1)
            _, labels, stats, centroids = _with_stats(mask, narrow)
        else:
            _, labels, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
    except cv2.error as e:
        if e.code != cv2.Error.StsNoMem:
            raise
        h, w = mask.shape
        raise MemoryError(
            f"not enough memory to search a {w} x {h} image for dots (OpenCV: {e.err})"
        ) from None
    pixels = stats[:, cv2.CC_STAT_AREA]
    # The area test first, on the integer areas: a noise image has a million components a
    # level, and only those of a dot's size need the rest.
    ids = np.flatnonzero((pixels >= low) & (pixels <= high))
    ids = ids[ids > 0]  # 0 is the background
    found = (np.asarray(labels), ids, stats[ids, :4], pixels[ids], centroids[ids])
    return cast(tuple[NDArray[Any], NDArray[np.intp], NDArray[Any], NDArray[Any], F64], found)


def _keep_sized_only(mask: NDArray[Any], low: int, high: int, width: _LabelWidth) -> int:
    """Clears the components of `mask` (in place) that have fewer than `low` or more than
    `high` pixels, found from OpenCV's labels alone (no statistics), a block of rows at a
    time; how many are left."""
    labels = _labels(mask, width)
    h, w = labels.shape
    n = int(labels.max()) + 1
    rows = max(1, LABEL_BLOCK_PX // w)
    blocks = [slice(top, top + rows) for top in range(0, h, rows)]
    pixels = np.zeros(n, dtype=np.int64)
    for block in blocks:
        pixels += np.bincount(labels[block].ravel(), minlength=n)
    sized = (pixels >= low) & (pixels <= high)
    sized[0] = False  # the background
    for block in blocks:
        mask[block] = sized[labels[block]]
    return int(sized.sum())


def _with_stats(mask: NDArray[Any], width: _LabelWidth) -> tuple[Any, ...]:
    """cv2.connectedComponentsWithStats(mask), with 16-bit labels where they fit (while
    labelling, a component can take several: the final count does not tell)."""
    if not width.wide:
        try:
            return tuple(cv2.connectedComponentsWithStats(mask, connectivity=8, ltype=cv2.CV_16U))
        except cv2.error as e:
            if e.code == cv2.Error.StsNoMem:
                raise
            width.wide = True
    return tuple(cv2.connectedComponentsWithStats(mask, connectivity=8, ltype=cv2.CV_32S))


def _labels(mask: NDArray[Any], width: _LabelWidth) -> NDArray[Any]:
    """OpenCV's 8-connected labels of `mask`: 16-bit where they fit, else 32-bit."""
    if not width.wide:
        try:
            _, labels = cv2.connectedComponents(mask, connectivity=8, ltype=cv2.CV_16U)
            return np.asarray(labels)
        except cv2.error as e:
            if e.code == cv2.Error.StsNoMem:
                raise
            width.wide = True  # more labels than 16 bits number
    _, labels = cv2.connectedComponents(mask, connectivity=8, ltype=cv2.CV_32S)
    return np.asarray(labels)


def _filled_ellipses(area: F64, sxx: F64, syy: F64, sxy: F64) -> NDArray[np.bool_]:
    """Which shapes of these areas and second moments (each pixel a unit square, its own
    1/12 included) are filled ellipses of moderate elongation: a filled ellipse with semi-axes
    a, b has second moments a^2/4, b^2/4 and area pi a b."""
    half_trace = 0.5 * (sxx + syy)
    root = np.sqrt(np.maximum(0.25 * (sxx - syy) ** 2 + sxy**2, 0.0))
    major, minor = half_trace + root, np.maximum(half_trace - root, 1e-12)
    fill = area / (4.0 * np.pi * np.sqrt(major * minor))
    keep: NDArray[np.bool_] = (
        (fill >= FILL_RANGE[0]) & (fill <= FILL_RANGE[1]) & (minor / major >= MIN_INERTIA_RATIO)
    )
    return keep


def _nearest(a: F64, b: F64) -> tuple[NDArray[np.intp], F64]:
    """For each point of `a`, the index of the nearest point of `b` and its distance."""
    dist, index = cKDTree(b).query(a)
    return np.asarray(index, dtype=np.intp), np.asarray(dist, dtype=np.float64)


def _one_per_place(blobs: Blobs) -> Blobs:
    """Blobs whose centres lie within each other's radius are one blob seen twice (a chain of
    levels broken by a level where it merged with a neighbour): keep the one seen at most
    levels."""
    if len(blobs) < 2:
        return blobs
    xy, d = blobs.centres, blobs.diameters
    # Pairs closer than the larger one's radius: each blob's ball of its own radius finds the
    # pairs where it is the larger.
    balls = cKDTree(xy).query_ball_point(xy, r=0.5 * d)
    clashes = [[j for j in ball if j != i] for i, ball in enumerate(balls)]
    rank = np.empty(len(d), dtype=np.intp)
    rank[np.argsort(-blobs.levels, kind="stable")] = np.arange(len(d))
    others: dict[int, set[int]] = {}
    for i, js in enumerate(clashes):
        for j in js:
            others.setdefault(i, set()).add(j)
            others.setdefault(j, set()).add(i)
    kept = np.ones(len(d), dtype=bool)
    for i in sorted(others, key=lambda k: rank[k]):
        if any(kept[j] and rank[j] < rank[i] for j in others[i]):
            kept[i] = False
    return blobs.subset(np.flatnonzero(kept))
