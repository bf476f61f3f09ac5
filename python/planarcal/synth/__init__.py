"""Synthetic photographs of a work plane with known truth: a board, objects, a camera.

Use it to test a setup before a camera is mounted, and as the ground truth of planarcal's
demo and tests. A scene is a flat *table* (the work plane) seen by a pinhole camera with
radial lens distortion. On the table lie, optionally, a printed circle-grid board
(:class:`~planarcal.calib.board.CircleGridBoard` on a sheet of paper: either layout, an origin
marker up to as wide as the dots' spacing, enlarged fiducial dots anywhere in the grid,
printed marks beside the dots) and objects (bolts, nuts, washers, discs, rectangles:
:class:`SceneObject`), flat or standing up off the table. :func:`render_scene` photographs
it and returns the 8-bit image with the exact truth: where every dot centre and every object
centroid lies on the table (mm) and in the image (px), and each dot's printed diameter.

For board detection, :func:`board_variants` renders a corpus of boards with their truth
(dot sizes from 0.15 to 0.85 of the pitch, both layouts, markers and fiducials, printed
marks (:func:`printed_marks`), 320 x 240 to 4K, webcam JPEG (:func:`jpeg`), distortion,
tilt, uneven light, light dots on dark paper, textured tables).

Conventions
-----------
* **Table coordinates** (mm): X and Y on the plane, Z = X x Y pointing *away* from the
  camera (into the table), so a point h mm above the table is (X, Y, -h). A board placed
  with ``board_origin_mm=(0, 0)`` and ``board_angle_deg=0`` has board coordinates equal to
  table coordinates.
* **Pixels**: OpenCV's convention. The centre of pixel (row i, column j) is at (x, y) =
  (j, i); the pixel covers [j - 0.5, j + 0.5] x [i - 0.5, i + 0.5]. The default principal
  point is the image centre, ((width - 1) / 2, (height - 1) / 2).
* **Camera**: OpenCV's frame (x right, y down, z along the optical axis) and its radial
  distortion model on normalised coordinates, x_d = x_u (1 + k1 r^2 + k2 r^4) with
  r^2 = x_u^2 + y_u^2, then pixel = focal_px * x_d + principal. ``cv2.projectPoints`` with
  ``rvec, tvec = pose.rvec_tvec()``, ``camera.matrix()`` and ``camera.dist_coeffs()``
  gives the same pixels as :meth:`CameraModel.project` (which takes points above the table
  too: ``height_mm``).
* **Objects** are silhouettes (unions of convex polygons and discs, less round holes) whose
  *area centroid on the plane* is ``position_mm``, exactly. With ``height_mm`` = h > 0 an
  object is a right prism: the silhouette extruded from the table up to its top face at
  Z = -h, holes going right through. Its truth is the centroid of its top face, the 3-D
  point (X, Y, -h): ``object_centroids_px`` is that point's exact projection (the image of
  the silhouette's centroid for a flat object), ``object_centroids_mm`` its (X, Y) and
  ``object_heights_mm`` its h.

How it renders
--------------
Every pixel is traced back to the table exactly: its position is undistorted (Newton's
method on the radial polynomial, to machine precision), the ray through it is intersected
with the plane, and the material there (table, paper, ink, an object) gives the grey level.
Pixels whose footprint on the plane crosses no boundary (found conservatively from signed
distances to every boundary) take the material at their centre. Each of the others, the
edge pixels, is split into n x n cells (``supersample``, default 8); every cell centre is
traced through the lens to the plane on its own, and the cell is shaded by the exact
fraction of its footprint (the parallelogram the cell maps to) on each side of the nearest
boundary, treated as straight across the cell. The pixel's value is the mean of its cells:
anti-aliasing by area, correct through distortion and perspective; only boundary curvature
within a cell (about 1e-5 of a dot's area at n = 8) and polygon corners are approximated.
Then, in this order: the textures of the table and the paper (added where each material
covers a pixel, its exact share of the pixel counted), uneven lighting (a multiplicative gain
in the image), a Gaussian blur, additive Gaussian noise (seeded), rounding to uint8.

The dots' boundary is that of the dot whose signed distance is the smallest (exact in
either layout, whatever each dot's size: see ``_Dots``). Dots never overlap but may touch
(an origin marker or an enlarged dot as wide as the distance between neighbours): where two
dots come within a cell of each other the cell's ink is the sum of its coverage by each.
Printed marks are flat shapes of ink drawn like flat objects, over the paper and the dots.

Objects with height are rendered just as exactly, in the same table-plane terms. With the
camera centre D mm above the table, over the table point F (its foot), the ray that meets
the table at P crosses the plane of a top at height h at P + (h / D) (F - P). So the rays
that meet the top inside the silhouette S are those whose table point lies in S scaled by
1 / (1 - h / D) about F; and those that meet the object at all (its top or a wall) are those
whose segment between the two planes meets S: for each convex part, the convex hull of the
part and its scaled copy (a polygon, or the hull of two discs), less the rays that go
through a hole at both heights (the through-hole's two discs). Both regions have exact
signed distances, so edge pixels are found and their cells shaded as for flat objects: the
object's top grey (``grey`` or ``metal_grey``) over the top's region, the walls' tone
``side_grey`` over the rest of the object's (default 0.6 x ``table_grey``: upright metal
faces, lit at grazing angles under overhead light, look darker than the bench). The walls
that show are those facing the camera: in the image they lie between the outline of the
object's base and that of its top, on the side towards the camera's nadir (the image of F);
on the far side the top overhangs the base and hides the table, the paper and the dots
there. Inside a nut's or washer's hole the far inner wall shows, and the table beyond it.
A raised object hides everything flat (the board, flat objects). Where raised objects
overlap in the image, the one that the ray meets first (nearest to the camera) is in front;
a cell crossed by the boundary between two of them takes, for the whole cell, the order
that holds at its centre: that occlusion boundary alone is point-sampled at n x n rather
than area-weighted, the one approximation heights add (corners where two outlines meet
are approximated as for polygons). Walls have one tone whatever their direction (no
shading, no shadows, no reflections).

Measured accuracy (tests/synth/test_synth.py, tests/synth/test_synth_boards.py): pixel values agree with
a brute-force reference (1024 point samples per pixel) to 0.002 of the contrast; so they do
where an asymmetric grid's enlarged dots or an origin marker touch their neighbours (0.009
at worst, the reference's own sampling, 0.0002 on average). In an asymmetric grid (dots
23 px), each dot's darkness centroid lies within 0.0015 px of its projected centre, and
an enlarged dot's darkness sums to its area within 0.002 %. With raised objects (walls, a nut's
through-hole, a 30 mm tall disc hiding a 12 mm block that hides a flat disc, through strong
distortion and a 25 degree tilt) they agree with rays followed one by one through the
prisms (32 x 32 jittered rays per pixel) to 0.01 of the contrast, that reference's own
sampling noise (0.0003 on average); where two raised objects meet in the image, to 0.02
(0.04 at n = 4). In a sharp, noise-free, untilted, undistorted render of the paper's board
(dots 21 px across), the intensity-weighted centroid of every dot lies within 0.002 px of
its projected centre (measured: 0.0018 px at worst, 0.0006 px on average, uint8 rounding
and the centroid's own sampling bias included). The same holds for the top of a raised
disc (20 mm across and 20 mm tall, 117 mm from the nadir of a camera 500 mm up: its wall is
11 px wide): the centroid of its top's coverage in the image lies within 0.001 px of the
projection of (X, Y, -h). A full 1280 x 720 render of the paper's calibration image takes
about 0.4 s on a 2-core machine (0.6 s in colour); :func:`paper_scene` renders its two
images in about 0.6 s. Height costs little: with the paper's ten objects on its board, 6 to
6.5 mm tall rather than flat, the render takes about 10 % longer. At 1280 x 720 an
asymmetric grid costs as much as a symmetric one; four enlarged dots add about 15 %, both
textures 45 %, 220 printed strokes (numbers, arrows, text) 55 %. The whole corpus of
:func:`board_variants` renders in about 10 s (4 s of it the 4K image).
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import Literal, NamedTuple, cast

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal.calib.board import CircleGridBoard
from planarcal.errors import BoardError, ImageError

__all__ = [
    "BOARD_VARIANTS",
    "MARK_KINDS",
    "OBJECT_KINDS",
    "PAPER_BOARD",
    "PAPER_CAMERA",
    "PAPER_EFFECTS",
    "PAPER_OBJECTS",
    "PAPER_POSE",
    "BoardVariant",
    "CameraModel",
    "MarkKind",
    "ObjectKind",
    "PaperScene",
    "PlanePose",
    "RenderedScene",
    "SceneObject",
    "Silhouette",
    "View",
    "board_variant",
    "board_variants",
    "jpeg",
    "paper_scene",
    "printed_marks",
    "render_scene",
]

F64 = NDArray[np.float64]

ObjectKind = Literal["bolt", "nut", "washer", "disc", "rectangle"]
"""The shapes :class:`SceneObject` can take."""

OBJECT_KINDS: tuple[ObjectKind, ...] = ("bolt", "nut", "washer", "disc", "rectangle")

# Material indices of the renderer; objects follow from _FIRST_OBJECT on.
_TABLE, _PAPER, _INK, _FIRST_OBJECT = 0, 1, 2, 3

# BGR tints of the materials with color=True (multiplying the grey level).
_TINT_TABLE = (0.90, 1.0, 1.08)
_TINT_PAPER = (0.98, 1.0, 1.01)
_TINT_INK = (1.06, 1.0, 0.96)
_TINT_METAL = (1.03, 1.0, 0.96)

# The default wall tone of raised objects, times the table's: vertical metal faces under
# overhead light, lit at grazing angles, look darker than the bench they stand on.
_SIDE_SHADE = 0.6

# Hexagon across flats, as a multiple of the nominal thread diameter (ISO 4032 / 4017: M8
# nuts and bolt heads are 13 mm across flats).
_HEX_ACROSS_FLATS = 1.6
# Hole diameters: a nut's (the thread's minor diameter) and a washer's, times d.
_NUT_HOLE = 0.85
_WASHER_HOLE = 1.05


def _heights(value: ArrayLike, shape: tuple[int, ...]) -> F64 | None:
    """Heights above the table (mm) for points of leading shape ``shape``, flat (N,); None
    when they are all zero (the plane itself, computed as before heights existed)."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("height_mm must be a number or an array of numbers") from None
    try:
        flat = np.broadcast_to(a, shape).reshape(-1)
    except ValueError:
        raise ValueError(
            f"height_mm must be a scalar or one height per point (shape {shape}), got shape "
            f"{a.shape}"
        ) from None
    bad = np.flatnonzero(~np.isfinite(flat))
    if bad.size:
        raise ValueError(f"height_mm: height {int(bad[0])} is not finite: {float(flat[bad[0]])!r}")
    return None if not flat.any() else np.ascontiguousarray(flat)


def _rotation_2d(angle_deg: float) -> F64:
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


# --------------------------------------------------------------------------- camera and pose


@dataclasses.dataclass(frozen=True)
class PlanePose:
    """Where the table plane is, seen from the camera.

    The camera looks at the table point ``look_at_mm`` (X, Y in mm), which lies on its
    optical axis ``distance_mm`` in front of it (so it appears at the principal point).
    With no tilt and no roll the camera looks straight down the plane's normal, the table's
    X axis runs to the right of the image and Y down it. ``tilt_deg`` then rotates the plane
    about the in-plane axis through ``look_at_mm`` at ``tilt_axis_deg`` from X (towards Y),
    by the right-hand rule in table coordinates (Z into the table); ``roll_deg`` finally
    rotates the scene about the optical axis (positive turns the image clockwise on screen).
    |tilt| must be below 90 degrees (the camera must face the plane).
    """

    distance_mm: float
    tilt_deg: float = 0.0
    tilt_axis_deg: float = 0.0
    roll_deg: float = 0.0
    look_at_mm: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        d = arguments.real("distance_mm", self.distance_mm)
        if d <= 0:
            raise ValueError(
                f"distance_mm must be positive, got {self.distance_mm!r}: a plane at a "
                "distance <= 0 is at or behind the camera"
            )
        tilt = arguments.real("tilt_deg", self.tilt_deg)
        if not abs(tilt) < 90.0:
            raise ValueError(
                f"tilt_deg must be between -90 and 90 (exclusive), got {self.tilt_deg!r}: "
                "at 90 degrees or more the camera sees the plane edge-on or from behind"
            )
        arguments.real("tilt_axis_deg", self.tilt_axis_deg)
        arguments.real("roll_deg", self.roll_deg)
        object.__setattr__(self, "look_at_mm", arguments.pair("look_at_mm", self.look_at_mm))

    def rotation(self) -> F64:
        """R (3 x 3): table coordinates to camera coordinates, X_cam = R X_table + t."""
        a = math.radians(self.tilt_axis_deg)
        axis = np.array([math.cos(a), math.sin(a), 0.0])
        tilt, _ = cv2.Rodrigues(axis * math.radians(self.tilt_deg))
        r = math.radians(self.roll_deg)
        c, s = math.cos(r), math.sin(r)
        roll = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return np.asarray(roll @ tilt, dtype=np.float64)

    def translation(self) -> F64:
        """t (3,): the table origin in camera coordinates (mm)."""
        look = np.array([*self.look_at_mm, 0.0])
        t = np.array([0.0, 0.0, float(self.distance_mm)]) - self.rotation() @ look
        return np.asarray(t, dtype=np.float64)

    def rvec_tvec(self) -> tuple[F64, F64]:
        """OpenCV's (rvec, tvec), each (3, 1) float64, for cv2.projectPoints and the like."""
        rvec, _ = cv2.Rodrigues(self.rotation())
        tvec = np.asarray(self.translation(), dtype=np.float64).reshape(3, 1)
        return np.asarray(rvec, dtype=np.float64).reshape(3, 1), tvec

    def camera_centre_mm(self) -> F64:
        """The camera's optical centre in table coordinates, (3,) (its Z is negative)."""
        return np.asarray(-self.rotation().T @ self.translation(), dtype=np.float64)


@dataclasses.dataclass(frozen=True)
class CameraModel:
    """A pinhole camera with square pixels and OpenCV's two-term radial distortion.

    ``focal_px`` is the focal length in pixels; ``principal`` the principal point in pixels
    (None: the image centre, ((width - 1) / 2, (height - 1) / 2)); ``k1``, ``k2`` the radial
    coefficients on normalised coordinates (k1 < 0: barrel, as in most webcams). The
    distortion must be invertible over the image (no fold-over between the centre and the
    corners). The default focal length, 1070 px, is a Logitech C525's at 1280 x 720 (about
    69 degrees diagonal field of view).
    """

    width: int = 1280
    height: int = 720
    focal_px: float = 1070.0
    principal: tuple[float, float] | None = None
    k1: float = 0.0
    k2: float = 0.0

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise ImageError(f"{name} must be a whole number of pixels, got {value!r}")
            if not 2 <= value <= 65536:
                raise ImageError(f"{name} must be 2 to 65536 pixels, got {value}")
            object.__setattr__(self, name, int(value))
        arguments.positive("focal_px", self.focal_px)
        if self.principal is not None:
            object.__setattr__(self, "principal", arguments.pair("principal", self.principal))
        k1, k2 = arguments.real("k1", self.k1), arguments.real("k2", self.k2)
        if k1 or k2:
            r_corner = self._corner_radius()
            r = np.linspace(0.0, 5.0 * r_corner + 1.0, 200_001)
            rr = r * r
            slope = 1.0 + rr * (3.0 * k1 + 5.0 * k2 * rr)
            distorted = r * (1.0 + rr * (k1 + k2 * rr))
            reach = np.flatnonzero(distorted >= r_corner)
            folds = np.flatnonzero(slope <= 0.0)
            if reach.size == 0 or (folds.size and folds[0] <= reach[0]):
                raise ValueError(
                    f"distortion k1={k1}, k2={k2} folds over inside the image: the radial "
                    "mapping stops increasing before the image corners, so pixels near them "
                    "would see two places at once; use milder coefficients"
                )

    @property
    def cx(self) -> float:
        return (self.width - 1) / 2.0 if self.principal is None else self.principal[0]

    @property
    def cy(self) -> float:
        return (self.height - 1) / 2.0 if self.principal is None else self.principal[1]

    def _corner_radius(self) -> float:
        """Largest normalised (distorted) radius of the image's outer pixel corners."""
        xs = (np.array([-0.5, self.width - 0.5]) - self.cx) / self.focal_px
        ys = (np.array([-0.5, self.height - 0.5]) - self.cy) / self.focal_px
        return float(np.sqrt(np.max(xs**2) + np.max(ys**2)))

    def matrix(self) -> F64:
        """The intrinsic matrix K (3 x 3)."""
        f = float(self.focal_px)
        return np.array([[f, 0.0, self.cx], [0.0, f, self.cy], [0.0, 0.0, 1.0]])

    def dist_coeffs(self) -> F64:
        """OpenCV's distortion vector (k1, k2, p1, p2, k3) = (k1, k2, 0, 0, 0)."""
        return np.array([self.k1, self.k2, 0.0, 0.0, 0.0], dtype=np.float64)

    @property
    def distorted(self) -> bool:
        return bool(self.k1 or self.k2)

    def distort(self, normalized: ArrayLike) -> F64:
        """Undistorted normalised coordinates (..., 2) to distorted ones."""
        p, shape = arguments.points("normalized", normalized)
        r2 = np.sum(p * p, axis=1, keepdims=True)
        out = p * (1.0 + r2 * (self.k1 + self.k2 * r2))
        return np.asarray(out.reshape(*shape, 2), dtype=np.float64)

    def _undistort_scale(self, rd2: F64) -> F64:
        """s with r_u = s r_d for squared distorted radii rd2 (exact, Newton's method)."""
        k1, k2 = float(self.k1), float(self.k2)
        if not (k1 or k2):
            return np.ones_like(rd2)
        rd = np.sqrt(rd2)
        r = rd.copy()
        for _ in range(40):
            rr = r * r
            f = r * (1.0 + rr * (k1 + k2 * rr)) - rd
            f /= 1.0 + rr * (3.0 * k1 + 5.0 * k2 * rr)
            r -= f
            if float(np.max(np.abs(f), initial=0.0)) <= 1e-15 * (1.0 + float(rd.max())):
                break
        else:  # pragma: no cover - the constructor rules out fold-over
            raise ValueError("undistortion did not converge: distortion too strong here")
        return np.asarray(np.divide(r, rd, out=np.ones_like(rd), where=rd > 0.0), np.float64)

    def undistort(self, normalized: ArrayLike) -> F64:
        """Distorted normalised coordinates (..., 2) to undistorted ones (exact inverse of
        :meth:`distort` within the image's radius)."""
        p, shape = arguments.points("normalized", normalized)
        s = self._undistort_scale(np.sum(p * p, axis=1))
        return (p * s[:, None]).reshape(*shape, 2)

    def homography(self, pose: PlanePose) -> F64:
        """The table (mm) -> image (px) homography K [r1 r2 t], scaled so H[2, 2] = 1 (-1 if
        the table origin is behind the camera: points in front keep w > 0).

        It is the exact projection when k1 = k2 = 0; with distortion it is the undistorted
        part (the projection onto the ideal pinhole image, before the lens bends it).
        """
        r = pose.rotation()
        m = np.column_stack([r[:, 0], r[:, 1], pose.translation()])
        h = self.matrix() @ m
        scale = h[2, 2] if abs(h[2, 2]) > 1e-12 * np.abs(h).max() else np.linalg.norm(h)
        return np.asarray(h / abs(scale), dtype=np.float64)

    def project(self, world_xy: ArrayLike, pose: PlanePose, height_mm: ArrayLike = 0.0) -> F64:
        """Table points (..., 2) in mm to pixels (..., 2), exactly, lens distortion included.

        ``height_mm``: how far above the table the points are (mm; a scalar or one height per
        point, shaped like the points' leading dimensions; negative: below it). A point
        (X, Y) at height h is the 3-D table point (X, Y, -h) (table Z points away from the
        camera), as for ``cv2.projectPoints``. Raises ValueError for a point at or behind the
        camera's plane (it has no image).
        """
        p, shape = arguments.points("world_xy", world_xy)
        heights = _heights(height_mm, shape)
        r, t = pose.rotation(), pose.translation()
        cam = p @ r[:, :2].T + t
        if heights is not None:
            cam = cam - heights[:, None] * r[:, 2]
        behind = np.flatnonzero(cam[:, 2] <= 1e-9 * float(pose.distance_mm))
        if behind.size:
            i = int(behind[0])
            where = "" if heights is None else f" at height {float(heights[i])!r} mm"
            raise ValueError(
                f"world point {i} {p[i].tolist()}{where} is behind the camera: it has no image"
            )
        xy = cam[:, :2] / cam[:, 2:]
        if self.distorted:
            r2 = np.sum(xy * xy, axis=1, keepdims=True)
            xy = xy * (1.0 + r2 * (self.k1 + self.k2 * r2))
        px = xy * float(self.focal_px) + np.array([self.cx, self.cy])
        return np.asarray(px.reshape(*shape, 2), dtype=np.float64)

    def image_to_plane(self, pixels: ArrayLike, pose: PlanePose) -> F64:
        """Pixels (..., 2) to the table points (mm) they see: undistort, back-project the
        ray, intersect it with the plane (exact). ValueError if a ray misses the plane."""
        p, shape = arguments.points("pixels", pixels)
        x, y, ok = self._rays_to_plane(
            (p[:, 0] - self.cx) / self.focal_px, (p[:, 1] - self.cy) / self.focal_px, pose
        )
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            raise ValueError(f"pixel {i} {p[i].tolist()} sees above the plane's horizon")
        return np.column_stack([x, y]).reshape(*shape, 2)

    def _rays_to_plane(
        self, xd: F64, yd: F64, pose: PlanePose
    ) -> tuple[F64, F64, NDArray[np.bool_]]:
        """Distorted normalised coordinates (any matching shapes) to table X, Y, and whether
        the ray hits the plane in front of the camera."""
        s = self._undistort_scale(xd * xd + yd * yd)
        xu, yu = xd * s, yd * s
        r = pose.rotation()
        minv = np.linalg.inv(np.column_stack([r[:, 0], r[:, 1], pose.translation()]))
        w = minv[2, 0] * xu + minv[2, 1] * yu + minv[2, 2]
        ok = w > 1e-12
        w = np.where(ok, w, 1.0)
        x = (minv[0, 0] * xu + minv[0, 1] * yu + minv[0, 2]) / w
        y = (minv[1, 0] * xu + minv[1, 1] * yu + minv[1, 2]) / w
        return x, y, ok


@dataclasses.dataclass(frozen=True)
class View:
    """A camera at a pose: the mapping between the table (mm) and the image (px)."""

    camera: CameraModel
    pose: PlanePose

    def project(self, world_xy: ArrayLike, height_mm: ArrayLike = 0.0) -> F64:
        """Table points (..., 2) in mm, ``height_mm`` above the table, to pixels, exactly
        (see CameraModel.project)."""
        return self.camera.project(world_xy, self.pose, height_mm)

    def homography(self) -> F64:
        """The table -> image homography (see CameraModel.homography): exact without
        distortion, else the undistorted part."""
        return self.camera.homography(self.pose)

    def image_to_plane(self, pixels: ArrayLike) -> F64:
        """Pixels to the table points they see (see CameraModel.image_to_plane)."""
        return self.camera.image_to_plane(pixels, self.pose)


# --------------------------------------------------------------------------- objects


class _Circle:
    """A disc (centre, radius) in table mm."""

    def __init__(self, centre: F64, radius: float) -> None:
        self.cx, self.cy, self.radius = float(centre[0]), float(centre[1]), float(radius)
        self.bbox = (
            self.cx - radius,
            self.cx + radius,
            self.cy - radius,
            self.cy + radius,
        )

    def signed_distance(self, x: F64, y: F64) -> F64:
        return np.asarray(np.hypot(x - self.cx, y - self.cy) - self.radius, dtype=np.float64)

    def field(self, x: F64, y: F64) -> tuple[F64, F64, F64]:
        """Signed distance (exact) and the unit outward normal of the nearest boundary."""
        dx, dy = x - self.cx, y - self.cy
        d = np.hypot(dx, dy)
        safe = np.where(d > 0.0, d, 1.0)
        return d - self.radius, np.where(d > 0.0, dx / safe, 1.0), dy / safe

    def polygon(self, n: int) -> F64:
        a = 2.0 * np.pi * np.arange(n) / n
        return np.column_stack(
            [self.cx + self.radius * np.cos(a), self.cy + self.radius * np.sin(a)]
        )

    def lifted(self, centre: F64, grow: float) -> _Circle:
        """This disc scaled by 1 + grow about ``centre`` (see _Raised)."""
        c = np.array([self.cx, self.cy])
        return _Circle(c + grow * (c - centre), (1.0 + grow) * self.radius)


class _ConvexPolygon:
    """A convex polygon in table mm; its signed distance is exact inside and a lower bound
    outside (the largest distance beyond an edge's line), which keeps edge finding
    conservative."""

    def __init__(self, vertices: F64) -> None:
        v = np.asarray(vertices, dtype=np.float64)
        if _signed_area(v) < 0:
            v = v[::-1]
        self.vertices = v
        e = np.roll(v, -1, axis=0) - v
        n = np.column_stack([e[:, 1], -e[:, 0]]) / np.hypot(e[:, 0], e[:, 1])[:, None]
        self.normals = n
        self.offsets = np.sum(n * v, axis=1)
        self.bbox = (
            float(v[:, 0].min()),
            float(v[:, 0].max()),
            float(v[:, 1].min()),
            float(v[:, 1].max()),
        )

    def signed_distance(self, x: F64, y: F64) -> F64:
        n, c = self.normals, self.offsets
        out = n[0, 0] * x + n[0, 1] * y - c[0]
        for i in range(1, len(c)):
            np.maximum(out, n[i, 0] * x + n[i, 1] * y - c[i], out=out)
        return np.asarray(out, dtype=np.float64)

    def field(self, x: F64, y: F64) -> tuple[F64, F64, F64]:
        """Signed distance (as signed_distance) and the outward normal of the edge that gives
        it: exact near the edges, away from the corners."""
        n, c = self.normals, self.offsets
        d = n[:, 0, None] * x.ravel()[None, :] + n[:, 1, None] * y.ravel()[None, :] - c[:, None]
        k = np.argmax(d, axis=0)
        sd = np.take_along_axis(d, k[None, :], axis=0)[0]
        return sd.reshape(x.shape), n[k, 0].reshape(x.shape), n[k, 1].reshape(x.shape)

    def lifted(self, centre: F64, grow: float) -> _ConvexPolygon:
        """This polygon scaled by 1 + grow about ``centre`` (see _Raised)."""
        return _ConvexPolygon(self.vertices + grow * (self.vertices - centre))


class _DiscHull:
    """The convex hull of two discs ``a`` and ``b``: the tangent lines' band between them
    capped by their arcs (a disc alone when one holds the other). Its signed distance is
    exact (the distance to the nearest of the two arcs or the two tangent segments)."""

    def __init__(self, a: _Circle, b: _Circle) -> None:
        self.bbox = (
            min(a.bbox[0], b.bbox[0]),
            max(a.bbox[1], b.bbox[1]),
            min(a.bbox[2], b.bbox[2]),
            max(a.bbox[3], b.bbox[3]),
        )
        self.a, self.b = a, b
        dx, dy = b.cx - a.cx, b.cy - a.cy
        self.length = math.hypot(dx, dy)
        self.single: _Circle | None = None
        if self.length <= abs(b.radius - a.radius) * (1.0 + 1e-12):
            self.single = a if a.radius >= b.radius else b
            return
        self.ux, self.uy = dx / self.length, dy / self.length
        # The upper tangent's outward normal is (sin, cos) in the frame (u, w), w = u turned
        # +90 degrees; it touches a at angle asin(sin) beyond the perpendicular.
        self.sin = (a.radius - b.radius) / self.length
        self.cos = math.sqrt(max(0.0, 1.0 - self.sin * self.sin))

    def signed_distance(self, x: F64, y: F64) -> F64:
        return self.field(x, y)[0]

    def field(self, x: F64, y: F64) -> tuple[F64, F64, F64]:
        """Signed distance (exact) and the unit outward normal of the nearest boundary."""
        if self.single is not None:
            return self.single.field(x, y)
        sd_a, nx_a, ny_a = self.a.field(x, y)
        sd_b, nx_b, ny_b = self.b.field(x, y)
        px, py = x - self.a.cx, y - self.a.cy
        along = px * self.ux + py * self.uy
        across = py * self.ux - px * self.uy
        side = np.where(across >= 0.0, 1.0, -1.0)
        # Position along the tangent segment (direction (cos, -sin) in (u, |w|)): before its
        # point on a (k < 0) the arc of a is nearest, past its point on b the arc of b.
        k = self.cos * along - self.sin * np.abs(across)
        sd_t = self.sin * along + self.cos * np.abs(across) - self.a.radius
        nx_t = self.sin * self.ux - side * self.cos * self.uy
        ny_t = self.sin * self.uy + side * self.cos * self.ux
        on_a, on_b = k < 0.0, k > self.cos * self.length
        sd = np.where(on_a, sd_a, np.where(on_b, sd_b, sd_t))
        nx = np.where(on_a, nx_a, np.where(on_b, nx_b, nx_t))
        ny = np.where(on_a, ny_a, np.where(on_b, ny_b, ny_t))
        return np.asarray(sd, np.float64), np.asarray(nx, np.float64), np.asarray(ny, np.float64)


def _convex_hull(points: F64) -> F64:
    """Convex hull, counter-clockwise (positive area), without collinear or coincident
    vertices (Andrew's monotone chain); vertices closer than 1e-9 of the extent merge."""
    pts = np.unique(np.asarray(points, dtype=np.float64), axis=0)
    tol = 1e-9 * (1.0 + float(np.ptp(pts, axis=0).max()))

    def chain(seq: Iterable[F64]) -> list[F64]:
        out: list[F64] = []
        for q in seq:
            while len(out) >= 2:
                a, b = out[-2], out[-1]
                cross = (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])
                if cross > tol * math.hypot(q[0] - a[0], q[1] - a[1]):
                    break
                out.pop()
            if not out or math.hypot(q[0] - out[-1][0], q[1] - out[-1][1]) > tol:
                out.append(q)
        return out

    lower, upper = chain(pts), chain(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


_Shape = _Circle | _ConvexPolygon
_Primitive = _Circle | _ConvexPolygon | _DiscHull
_Field = tuple[F64, F64, F64]


def _union(a: _Field, b: _Field) -> _Field:
    """The field (signed distance, outward normal) of the union: the nearer boundary inside
    either, exact in sign and 1-Lipschitz (so edge finding stays conservative)."""
    closer = b[0] < a[0]
    return (
        np.where(closer, b[0], a[0]),
        np.where(closer, b[1], a[1]),
        np.where(closer, b[2], a[2]),
    )


def _intersection(a: _Field, b: _Field) -> _Field:
    """The field of the intersection (the larger signed distance; see _union)."""
    return cast("_Field", tuple(-v for v in _union(_complement(a), _complement(b))))


def _complement(a: _Field) -> _Field:
    return (-a[0], -a[1], -a[2])


class _Raised:
    """An object of height h > 0 seen from a camera whose centre is ``distance`` (D) above
    the table at ``foot`` (table X, Y), as regions of the table plane: a ray that meets the
    table at P crosses the top's plane Z = -h at P + (h / D) (foot - P), so

    * it meets the top inside the silhouette S when P lies in S scaled by 1 / (1 - h / D)
      about ``foot`` (``top``: each part and hole so scaled);
    * it meets the solid at all (top or wall) when its segment between the two planes meets
      S: for a convex part K that is the convex hull of K and its scaled copy (``hull``),
      less, for a hole H (inside K, a through-hole), the rays that pass through the hole at
      both planes (H and its scaled copy, both convex, so the whole segment is in the hole).

    Every region is a union, intersection or difference of discs, convex polygons and hulls
    of two discs, all with exact (or conservative) signed distances, so the renderer's
    edge finding and coverage work on them as on flat objects.
    """

    def __init__(
        self,
        parts: list[_Shape],
        holes: list[_Circle],
        height: float,
        foot: F64,
        distance: float,
    ) -> None:
        if holes and len(parts) != 1:  # pragma: no cover - holes only in nuts and washers
            raise ValueError("a raised object with holes must be one convex part")
        self.height, self.distance = float(height), float(distance)
        self.lam = self.height / self.distance
        self.foot = np.asarray(foot, dtype=np.float64)
        grow = self.lam / (1.0 - self.lam)  # the scale factor 1 / (1 - h / D), less 1
        self.parts, self.holes = parts, holes
        self.top: list[_Shape] = [p.lifted(self.foot, grow) for p in parts]
        self.holes_top = [h.lifted(self.foot, grow) for h in holes]
        self.hull: list[_Primitive] = []
        for base, top in zip(parts, self.top, strict=True):
            if isinstance(base, _Circle):
                assert isinstance(top, _Circle)
                self.hull.append(_DiscHull(base, top))
            else:
                assert isinstance(top, _ConvexPolygon)
                hull = _convex_hull(np.vstack([base.vertices, top.vertices]))
                self.hull.append(_ConvexPolygon(hull))
        boxes = np.array([p.bbox for p in self.hull])
        self.bbox = (boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max())

    def fields(self, x: F64, y: F64) -> tuple[_Field, _Field]:
        """The fields of the region whose rays meet the object (hit) and of its top."""
        hit = self.hull[0].field(x, y)
        top = self.top[0].field(x, y)
        for p in self.hull[1:]:
            hit = _union(hit, p.field(x, y))
        for p in self.top[1:]:
            top = _union(top, p.field(x, y))
        for h, ht in zip(self.holes, self.holes_top, strict=True):
            f_ht = ht.field(x, y)
            hit = _intersection(hit, _complement(_intersection(h.field(x, y), f_ht)))
            top = _intersection(top, _complement(f_ht))
        return hit, top

    def classify(
        self, x: F64, y: F64, radius: F64
    ) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
        """At each table point: whether its ray meets the object, meets its top, whether a
        boundary of either region may lie within ``radius`` (conservative), and whether the
        hit region may reach within ``radius``."""
        sd_hit = self.hull[0].signed_distance(x, y)
        for p in self.hull[1:]:
            np.minimum(sd_hit, p.signed_distance(x, y), out=sd_hit)
        sd_top = self.top[0].signed_distance(x, y)
        for p in self.top[1:]:
            np.minimum(sd_top, p.signed_distance(x, y), out=sd_top)
        hit, top = sd_hit < 0.0, sd_top < 0.0
        near = (np.abs(sd_hit) < radius) | (np.abs(sd_top) < radius)
        reach = sd_hit < radius
        for h, ht in zip(self.holes, self.holes_top, strict=True):
            sd_h, sd_ht = h.signed_distance(x, y), ht.signed_distance(x, y)
            hit &= (sd_h >= 0.0) | (sd_ht >= 0.0)
            top &= sd_ht >= 0.0
            near |= (np.abs(sd_h) < radius) | (np.abs(sd_ht) < radius)
        return hit, top & hit, near, reach

    def entry_height(self, x: F64, y: F64) -> F64:
        """How high (mm) the ray that meets the table at (x, y) first meets the object (its
        height for the top, less for a wall), -inf where it misses: for the painter's order
        where two raised objects overlap in the image."""
        vx, vy = self.foot[0] - x, self.foot[1] - y  # the ray rises along P + s v
        best = np.full(x.shape, -np.inf)
        for part in self.parts:
            lo, hi = _line_interval(part, x, y, vx, vy)
            s = np.minimum(hi, self.lam)
            for h in self.holes:
                h_lo, h_hi = _line_interval(h, x, y, vx, vy)
                s = np.where((h_lo < s) & (s < h_hi), h_lo, s)
            ok = (lo <= hi) & (s >= np.maximum(lo, 0.0))
            np.maximum(best, np.where(ok, s * self.distance, -np.inf), out=best)
        return best


def _line_interval(shape: _Shape, x: F64, y: F64, vx: F64, vy: F64) -> tuple[F64, F64]:
    """The interval [lo, hi] of s for which (x, y) + s (vx, vy) lies in the convex shape
    (lo > hi: none; a zero direction gives (-inf, inf) inside, nothing outside)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        if isinstance(shape, _Circle):
            dx, dy = x - shape.cx, y - shape.cy
            a = vx * vx + vy * vy
            b = dx * vx + dy * vy
            c = dx * dx + dy * dy - shape.radius**2
            disc = b * b - a * c
            root = np.sqrt(np.maximum(disc, 0.0))
            moving = a > 0.0
            safe = np.where(moving, a, 1.0)
            lo = np.where(moving, (-b - root) / safe, np.where(c <= 0.0, -np.inf, np.inf))
            hi = np.where(moving, (-b + root) / safe, np.where(c <= 0.0, np.inf, -np.inf))
            empty = moving & (disc < 0.0)
            return np.where(empty, np.inf, lo), np.where(empty, -np.inf, hi)
        lo = np.full(x.shape, -np.inf)
        hi = np.full(x.shape, np.inf)
        for (nx, ny), off in zip(shape.normals, shape.offsets, strict=True):
            num = off - (nx * x + ny * y)
            den = nx * vx + ny * vy
            t = num / np.where(den != 0.0, den, 1.0)
            hi = np.where(den > 0.0, np.minimum(hi, t), hi)
            lo = np.where(den < 0.0, np.maximum(lo, t), lo)
            out = (den == 0.0) & (num < 0.0)
            lo, hi = np.where(out, np.inf, lo), np.where(out, -np.inf, hi)
        return lo, hi


def _signed_area(poly: F64) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _hexagon(across_flats: float) -> F64:
    """A regular hexagon centred at 0 with flats perpendicular to x, counter-clockwise."""
    r = across_flats / math.sqrt(3.0)
    a = np.radians(np.arange(-90.0, 270.0, 60.0))
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


class Silhouette(NamedTuple):
    """An object's outline on the table in mm: ``outer`` (N, 2) counter-clockwise (positive
    shoelace area in X, Y) and ``holes``, each (M, 2), also with positive area, to subtract.
    Circles are regular polygons centred on the circle (so the area centroid is unchanged)."""

    outer: F64
    holes: tuple[F64, ...]


@dataclasses.dataclass(frozen=True)
class SceneObject:
    """An object on the table: its silhouette, placed so that its area centroid is at
    ``position_mm`` (table mm) exactly, turned by ``angle_deg`` (from +X towards +Y).

    ``size_mm`` is the object's nominal size:

    * ``"nut"``: thread diameter d; a regular hexagon 1.6 d across flats (M8: 12.8 mm) with
      a round hole of 0.85 d (the thread's minor diameter, as seen from above), flats
      perpendicular to the X axis at angle 0.
    * ``"bolt"``: thread diameter d; a hexagonal head 1.6 d across flats plus a shank d wide
      and ``length_mm`` long (default 4 d) from the middle of one flat, along +X at angle 0.
    * ``"washer"``: inner diameter d; an annulus of outer diameter 2 d, hole 1.05 d.
    * ``"disc"``: the diameter.
    * ``"rectangle"``: the width (along Y at angle 0); ``length_mm`` (along X) defaults to
      it (a square).

    ``grey`` overrides the renderer's metal grey level for this object's top (0-255).

    ``height_mm`` (default 0: a flat silhouette) makes the object a right prism: the
    silhouette extruded from the table (Z = 0) up to its top face at Z = -height_mm (table Z
    points away from the camera). Holes go right through. Its top face's area centroid is
    then the 3-D point (X, Y, -height_mm) with (X, Y) = ``position_mm``.
    """

    kind: ObjectKind
    position_mm: tuple[float, float]
    angle_deg: float = 0.0
    size_mm: float = 8.0
    length_mm: float | None = None
    grey: float | None = None
    height_mm: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in OBJECT_KINDS:
            raise ValueError(f"kind must be one of {', '.join(OBJECT_KINDS)}; got {self.kind!r}")
        object.__setattr__(self, "position_mm", arguments.pair("position_mm", self.position_mm))
        arguments.real("angle_deg", self.angle_deg)
        arguments.positive("size_mm", self.size_mm)
        if self.length_mm is not None:
            if self.kind not in ("bolt", "rectangle"):
                raise ValueError(f"length_mm applies to bolts and rectangles, not a {self.kind}")
            arguments.positive("length_mm", self.length_mm)
        if self.grey is not None:
            g = arguments.real("grey", self.grey)
            if not 0.0 <= g <= 255.0:
                raise ValueError(f"grey must be a grey level 0-255, got {self.grey!r}")
        height = arguments.real("height_mm", self.height_mm)
        if height < 0.0:
            raise ValueError(
                f"height_mm must be >= 0 (mm above the table; 0 for a flat object), got "
                f"{self.height_mm!r}"
            )

    # Local geometry: the shape before it is centred on its centroid, turned and placed.
    def _local(self) -> tuple[list[F64 | tuple[float, float, float]], list[float], F64]:
        """(parts, hole radii, centroid): parts are convex polygons (vertex arrays) or
        circles (cx, cy, r) whose union is the outline; holes are circles at the origin."""
        d = float(self.size_mm)
        if self.kind == "nut":
            return [_hexagon(_HEX_ACROSS_FLATS * d)], [_NUT_HOLE * d / 2.0], np.zeros(2)
        if self.kind == "washer":
            return [(0.0, 0.0, d)], [_WASHER_HOLE * d / 2.0], np.zeros(2)
        if self.kind == "disc":
            return [(0.0, 0.0, d / 2.0)], [], np.zeros(2)
        if self.kind == "rectangle":
            length = d if self.length_mm is None else float(self.length_mm)
            hx, hy = length / 2.0, d / 2.0
            rect = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
            return [rect], [], np.zeros(2)
        # bolt: head and shank meet along the flat at x = af / 2 (disjoint interiors).
        af = _HEX_ACROSS_FLATS * d
        length = 4.0 * d if self.length_mm is None else float(self.length_mm)
        x0 = af / 2.0
        shank = np.array([[x0, -d / 2], [x0 + length, -d / 2], [x0 + length, d / 2], [x0, d / 2]])
        a_head, a_shank = math.sqrt(3.0) / 2.0 * af * af, length * d
        cx = a_shank * (x0 + length / 2.0) / (a_head + a_shank)
        return [_hexagon(af), shank], [], np.array([cx, 0.0])

    def _place(self, local: F64, centroid: F64) -> F64:
        rot = _rotation_2d(float(self.angle_deg))
        return np.asarray((local - centroid) @ rot.T + np.array(self.position_mm), dtype=float)

    def _primitives(self) -> tuple[list[_Shape], list[_Circle]]:
        """The outline's convex parts and the holes, in table mm, for the renderer."""
        parts, holes, c = self._local()
        outer: list[_Shape] = []
        for part in parts:
            if isinstance(part, tuple):
                centre = self._place(np.array([part[:2]]), c)[0]
                outer.append(_Circle(centre, part[2]))
            else:
                outer.append(_ConvexPolygon(self._place(part, c)))
        centre = self._place(np.zeros((1, 2)), c)[0]
        return outer, [_Circle(centre, r) for r in holes]

    @property
    def hole_diameter_mm(self) -> float | None:
        """Diameter of the round hole (nuts and washers), None for the others."""
        holes = self._local()[1]
        return 2.0 * holes[0] if holes else None

    @property
    def area_mm2(self) -> float:
        """The silhouette's exact area (circles as circles)."""
        parts, holes, _ = self._local()
        area = sum(math.pi * p[2] ** 2 if isinstance(p, tuple) else _signed_area(p) for p in parts)
        return float(area - sum(math.pi * r * r for r in holes))

    def silhouette(self, arc_vertices: int = 360) -> Silhouette:
        """The outline as polygons in table mm (see :class:`Silhouette`); circles become
        regular polygons of ``arc_vertices`` vertices. The renderer draws true circles."""
        if isinstance(arc_vertices, bool) or not isinstance(arc_vertices, int | np.integer):
            raise ValueError(f"arc_vertices must be a whole number, got {arc_vertices!r}")
        if arc_vertices < 8:
            raise ValueError(f"arc_vertices must be at least 8, got {arc_vertices}")
        parts, holes, c = self._local()
        if self.kind == "bolt":
            head, shank = parts
            assert not isinstance(head, tuple) and not isinstance(shank, tuple)
            # Counter-clockwise from the head's bottom vertex; the shank is inserted on the
            # flat at x = af / 2, between head vertices 1 and 2.
            local = np.vstack([head[:2], shank, head[2:]])
        elif isinstance(parts[0], tuple):
            local = _Circle(np.array(parts[0][:2]), parts[0][2]).polygon(int(arc_vertices))
        else:
            local = parts[0]
        hole_polys = tuple(
            self._place(_Circle(np.zeros(2), r).polygon(int(arc_vertices)), c) for r in holes
        )
        return Silhouette(self._place(local, c), hole_polys)


# --------------------------------------------------------------------------- the scene


@dataclasses.dataclass(frozen=True, eq=False)
class RenderedScene:
    """A rendered scene and its truth.

    ``image``: uint8, (height, width) grey or (height, width, 3) BGR.
    ``dot_centres_px``: (rows * cols, 2) float64, the exact projection (lens distortion
    included) of each board dot's centre, in board order (point k = r * cols + c); (0, 2)
    without a board. ``object_centroids_px``: (len(objects), 2), the projection of each
    object's centroid: of its top face, the 3-D point (X, Y, -h) with (X, Y) its
    ``position_mm`` and h its ``height_mm`` (0 for a flat object). Note that the image of a
    circle's or object's centre is not the centroid of its image under perspective or
    distortion: these are the truth a detector's answer should be compared with, its bias
    included.
    ``world_to_image``: the table (mm) -> image (px) homography, scaled so H[2, 2] = 1. It is
    exact when the camera has no distortion; otherwise it is the undistorted part (the ideal
    pinhole image; the pixels differ from it by the lens distortion). ``board_to_image``:
    the same from board coordinates (mm, origin at dot 0), None without a board.
    ``effects``: the image effects and grey levels the scene was rendered with.
    ``dot_diameters_mm``: (rows * cols,), the diameter each dot was printed with, in board
    order (the board's ``dot_diameters()`` with ``enlarged_dots`` applied); (0,) without a
    board. ``marks``: the printed marks, in board coordinates (decoration: no truth).
    """

    image: NDArray[np.uint8]
    dot_centres_px: F64
    object_centroids_px: F64
    objects: tuple[SceneObject, ...]
    board: CircleGridBoard | None
    board_origin_mm: tuple[float, float]
    board_angle_deg: float
    camera: CameraModel
    pose: PlanePose
    world_to_image: F64
    board_to_image: F64 | None
    effects: Mapping[str, float | int | bool]
    dot_diameters_mm: F64 = dataclasses.field(default_factory=lambda: np.zeros(0))
    marks: tuple[SceneObject, ...] = ()

    @property
    def dot_centres_mm(self) -> F64:
        """Board dot centres in table coordinates (mm), (rows * cols, 2), in board order."""
        if self.board is None:
            return np.zeros((0, 2))
        return _board_to_table(
            self.board.world_points(), self.board_origin_mm, self.board_angle_deg
        )

    @property
    def object_centroids_mm(self) -> F64:
        """Object centroids (their ``position_mm``) in table coordinates, (len(objects), 2):
        X and Y of the top face's centroid (of the silhouette's, for a flat object), which
        lies ``object_heights_mm`` above the table."""
        return np.array([o.position_mm for o in self.objects], dtype=np.float64).reshape(-1, 2)

    @property
    def object_heights_mm(self) -> F64:
        """Each object's height above the table (mm), (len(objects),); 0 for flat ones."""
        return np.array([float(o.height_mm) for o in self.objects], dtype=np.float64)

    def truth(self) -> dict[str, F64]:
        """The ground truth as arrays: ``dot_centres_mm``, ``dot_centres_px``,
        ``object_centroids_mm``, ``object_heights_mm``, ``object_centroids_px`` (table mm,
        image px)."""
        return {
            "dot_centres_mm": self.dot_centres_mm,
            "dot_centres_px": self.dot_centres_px.copy(),
            "object_centroids_mm": self.object_centroids_mm,
            "object_heights_mm": self.object_heights_mm,
            "object_centroids_px": self.object_centroids_px.copy(),
        }

    @property
    def view(self) -> View:
        """This scene's camera and pose."""
        return View(self.camera, self.pose)

    def project(self, world_xy: ArrayLike, height_mm: ArrayLike = 0.0) -> F64:
        """Table points (mm), ``height_mm`` above the table (a scalar or one per point), to
        pixels through this scene's camera and pose (exact; see CameraModel.project)."""
        return self.camera.project(world_xy, self.pose, height_mm)

    def dots_in_view(self, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """Whether each dot lies wholly inside the image, ``margin_px`` from its border."""
        if self.board is None:
            return np.zeros(0, dtype=bool)
        m = arguments.real("margin_px", margin_px)
        a = 2.0 * np.pi * np.arange(64) / 64
        ring = np.column_stack([np.cos(a), np.sin(a)])
        pts = self.board.world_points()
        rad = self.dot_diameters_mm / 2.0
        if len(rad) != len(pts):
            rad = self.board.dot_diameters() / 2.0
        outline = (pts[:, None, :] + rad[:, None, None] * ring[None]).reshape(-1, 2)
        px = self.project(_board_to_table(outline, self.board_origin_mm, self.board_angle_deg))
        w, h = self.camera.width, self.camera.height
        inside = (
            (px[:, 0] >= m - 0.5)
            & (px[:, 0] <= w - 0.5 - m)
            & (px[:, 1] >= m - 0.5)
            & (px[:, 1] <= h - 0.5 - m)
        )
        return np.asarray(inside.reshape(len(pts), -1).all(axis=1))


def _board_to_table(points: F64, origin: tuple[float, float], angle_deg: float) -> F64:
    return np.asarray(points @ _rotation_2d(angle_deg).T + np.array(origin), dtype=np.float64)


def _coverage(sd: F64, nx: F64, ny: F64, cell: tuple[F64, F64, F64, F64]) -> F64:
    """Fraction of each cell on the inner side (sd < 0) of a straight boundary.

    The cell is the parallelogram spanned by (ax, ay) and (bx, by) (its footprint on the
    plane) around the point where the signed distance is ``sd`` and the boundary's unit
    normal (nx, ny). Across the boundary, a point uniformly distributed over the cell has a
    distance that is the sum of two uniform variables (the two sides projected on the
    normal): the coverage is their distribution function, which is exact for a straight
    boundary whatever its direction."""
    ax, ay, bx, by = cell
    pa = 0.5 * np.abs(nx * ax + ny * ay)
    pb = 0.5 * np.abs(nx * bx + ny * by)
    hi, lo = np.maximum(pa, pb), np.minimum(pa, pb)
    lo = np.maximum(lo, 1e-12 * hi + 1e-300)
    x = -sd
    cov = 0.5 + x / (2.0 * hi)
    tail = hi + lo - np.abs(x)
    q = tail * tail / (8.0 * hi * lo)
    cov = np.where(x < lo - hi, q, cov)
    cov = np.where(x > hi - lo, 1.0 - q, cov)
    return np.asarray(np.clip(np.where(tail <= 0.0, x > 0.0, cov), 0.0, 1.0), np.float64)


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


class _Dots:
    """A board's dots in board coordinates (mm) and their field: the signed distance to the
    dot whose signed distance is the smallest (not the one with the nearest centre: near a
    larger dot, a smaller neighbour's centre may be nearer), with that dot's outward normal.

    All dots are at least the board's nominal size. The nearest node of the dot lattice, found
    by rounding (exact for equal dots), gives every dot's field at the nominal radius; each
    larger dot (the origin marker, enlarged dots) is then evaluated on its own wherever its
    boundary may lie within ``pad`` of a point, and wins where its signed distance is
    smaller. Farther from it both values exceed ``pad``, so neither the material, the edge
    finding nor any cell's coverage (0) depends on which is kept.

    Dots are disjoint (they may touch), so a cell's ink is the sum of its coverage by each
    dot. Only dots less than 2 ``pad`` apart can both reach a cell within ``pad`` of its
    centre: :meth:`others` gives those dots' fields where they are not the nearest.
    """

    def __init__(self, board: CircleGridBoard, diameters: F64) -> None:
        self.pitch = float(board.pitch)
        self.cols, self.rows = board.cols, board.rows
        self.asymmetric = board.layout == "asymmetric"
        self.radius = float(board.dots_mm()) / 2.0
        pts = board.world_points()
        radii = np.asarray(diameters, dtype=np.float64) / 2.0
        self.larger = [
            (float(pts[k, 0]), float(pts[k, 1]), float(radii[k]))
            for k in np.flatnonzero(radii > self.radius)
        ]
        self.centres, self.radii = pts, radii
        self.gaps = _smallest_gaps(pts, radii)

    def _offset_to_nearest_centre(self, bx: F64, by: F64) -> tuple[F64, F64]:
        """(bx, by) less the nearest dot centre."""
        p = self.pitch
        if not self.asymmetric:
            c = np.clip(np.rint(bx / p), 0, self.cols - 1)
            r = np.clip(np.rint(by / p), 0, self.rows - 1)
            return bx - c * p, by - r * p
        # Dot (c, r) at ((2 c + r % 2) p, r p): the rows alternate between two sets of x.
        # The nearest dot is the nearest in the nearest row or in the nearest row of the
        # other parity (the rows of one parity have the same x: the nearer row wins).
        t = by / p
        r0 = np.clip(np.rint(t), 0, self.rows - 1)
        step = np.where(t >= r0, 1.0, -1.0)
        r1 = r0 + step
        r1 = np.where((r1 < 0) | (r1 > self.rows - 1), r0 - step, r1)
        best: tuple[F64, F64] | None = None
        for r in (r0, r1):
            shift = np.mod(r, 2.0)
            x = (2.0 * np.clip(np.rint((bx / p - shift) / 2.0), 0, self.cols - 1) + shift) * p
            vx, vy = bx - x, by - r * p
            if best is None:
                best = (vx, vy)
            else:
                nearer = np.hypot(vx, vy) < np.hypot(*best)
                best = (np.where(nearer, vx, best[0]), np.where(nearer, vy, best[1]))
        assert best is not None
        return best

    def field(self, bx: F64, by: F64, pad: float) -> tuple[F64, F64, F64]:
        """(sd, nx, ny) in board coordinates (see the class)."""
        vx, vy = self._offset_to_nearest_centre(bx, by)
        rad: F64 | float = self.radius
        if self.larger:
            shape = vx.shape
            vx, vy, bxf, byf = (np.array(a, dtype=np.float64).reshape(-1) for a in (vx, vy, bx, by))
            rad_f = np.full(vx.shape, self.radius)
            points = _PointIndex(bxf, byf)
            for cx, cy, r in self.larger:
                sel = points.near((cx - r, cx + r, cy - r, cy + r), pad)
                if sel.size == 0:
                    continue
                ux, uy = bxf[sel] - cx, byf[sel] - cy
                nearer = np.hypot(ux, uy) - r < np.hypot(vx[sel], vy[sel]) - rad_f[sel]
                sel = sel[nearer]
                vx[sel], vy[sel], rad_f[sel] = ux[nearer], uy[nearer], r
            vx, vy, rad = vx.reshape(shape), vy.reshape(shape), rad_f.reshape(shape)
        d = np.hypot(vx, vy)
        safe = np.where(d > 0.0, d, 1.0)
        return d - rad, np.where(d > 0.0, vx / safe, 1.0), vy / safe

    def others(
        self, bx: F64, by: F64, pad: float, nearest: F64
    ) -> Iterator[tuple[NDArray[np.intp], F64, F64, F64]]:
        """(indices, sd, nx, ny) of each dot that lies within ``pad`` of points (flat) where
        another dot, of signed distance ``nearest``, is the nearest: only dots closer than
        2 pad to a neighbour can."""
        close = np.flatnonzero(self.gaps < 2.0 * pad)
        if close.size == 0:
            return
        points = _PointIndex(bx, by)
        for k in close:
            (cx, cy), r = self.centres[k], float(self.radii[k])
            sel = points.near((cx - r, cx + r, cy - r, cy + r), pad)
            ux, uy = bx[sel] - cx, by[sel] - cy
            d = np.hypot(ux, uy)
            sd = d - r
            keep = (sd < pad) & (sd > nearest[sel])
            d, ux, uy = d[keep], ux[keep], uy[keep]
            safe = np.where(d > 0.0, d, 1.0)
            yield sel[keep], sd[keep], np.where(d > 0.0, ux / safe, 1.0), uy / safe


def _smallest_gaps(centres: F64, radii: F64) -> F64:
    """For each disc, the distance from its edge to the nearest other disc's edge."""
    out = np.empty(len(centres))
    for start in range(0, len(centres), 256):
        part = slice(start, start + 256)
        d = np.linalg.norm(centres[part, None, :] - centres[None], axis=2) - radii[None]
        d[np.arange(d.shape[0]), np.arange(start, start + d.shape[0])] = np.inf
        out[part] = d.min(axis=1) - radii[part]
    return out


class _Scene:
    """The geometry of a scene: which material is where on the table."""

    def __init__(
        self,
        board: CircleGridBoard | None,
        origin: tuple[float, float],
        angle_deg: float,
        margin: float,
        objects: Sequence[SceneObject],
        camera_centre: F64 | None = None,
        dot_diameters: F64 | None = None,
    ) -> None:
        self.board = board
        self.ox, self.oy = origin
        a = math.radians(angle_deg)
        self.cos, self.sin = math.cos(a), math.sin(a)
        if board is not None:
            diameters = board.dot_diameters() if dot_diameters is None else dot_diameters
            self.dots = _Dots(board, diameters)
            pts = board.world_points()
            big = float(np.max(diameters)) / 2.0
            x0, x1 = float(pts[:, 0].min()) - big - margin, float(pts[:, 0].max()) + big + margin
            y0, y1 = float(pts[:, 1].min()) - big - margin, float(pts[:, 1].max()) + big + margin
            self.paper_mid = (0.5 * (x0 + x1), 0.5 * (y0 + y1))
            self.paper_half = (0.5 * (x1 - x0), 0.5 * (y1 - y0))
        # Flat objects (height 0) are layers on the table, drawn in order; raised ones
        # (_Raised) are drawn over them, nearest to the camera in front.
        self.objects: list[tuple[list[_Shape], list[_Circle]]] = []
        self.object_bbox = []
        self.flat: list[int] = []
        self.raised: list[tuple[int, _Raised]] = []
        self.side = _FIRST_OBJECT + len(objects)  # the walls' material
        for i, o in enumerate(objects):
            outer, holes = o._primitives()
            self.objects.append((outer, holes))
            if o.height_mm > 0:
                if camera_centre is None:  # pragma: no cover - render_scene passes it
                    raise ValueError("a raised object needs the camera's position")
                foot, distance = camera_centre[:2], -float(camera_centre[2])
                raised = _Raised(outer, holes, float(o.height_mm), foot, distance)
                self.raised.append((i, raised))
                self.object_bbox.append(raised.bbox)
                continue
            self.flat.append(i)
            boxes = np.array([p.bbox for p in outer])
            self.object_bbox.append(
                (boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max())
            )

    def _board_fields(
        self, x: F64, y: F64, pad: float
    ) -> tuple[tuple[F64, F64, F64], tuple[F64, F64, F64]]:
        """(sd, nx, ny) of the paper and of the dots, in table coordinates; the dots' field is
        exact where a dot's boundary lies within ``pad`` mm (see _Dots.field)."""
        dx, dy = x - self.ox, y - self.oy
        bx = self.cos * dx + self.sin * dy
        by = self.cos * dy - self.sin * dx
        # The paper: a rectangle in board coordinates.
        qx = np.abs(bx - self.paper_mid[0]) - self.paper_half[0]
        qy = np.abs(by - self.paper_mid[1]) - self.paper_half[1]
        along_x = qx >= qy
        sd_p = np.where(along_x, qx, qy)
        nbx = np.where(along_x, np.sign(bx - self.paper_mid[0]), 0.0)
        nby = np.where(along_x, 0.0, np.sign(by - self.paper_mid[1]))
        paper = (sd_p, self.cos * nbx - self.sin * nby, self.sin * nbx + self.cos * nby)
        sd, nbx, nby = self.dots.field(bx, by, pad)
        dots = (sd, self.cos * nbx - self.sin * nby, self.sin * nbx + self.cos * nby)
        return paper, dots

    def _other_dots(
        self, x: F64, y: F64, pad: float, nearest: F64
    ) -> Iterator[tuple[NDArray[np.intp], F64, F64, F64]]:
        """The fields, in table coordinates, of dots near points (flat) other than the
        nearest one (of signed distance ``nearest``): see _Dots.others."""
        dx, dy = x - self.ox, y - self.oy
        bx = self.cos * dx + self.sin * dy
        by = self.cos * dy - self.sin * dx
        for sel, sd, nbx, nby in self.dots.others(bx, by, pad, nearest):
            yield sel, sd, self.cos * nbx - self.sin * nby, self.sin * nbx + self.cos * nby

    def _near_object(self, i: int, points: _PointIndex, pad: float) -> NDArray[np.intp]:
        return points.near(self.object_bbox[i], pad)

    def classify(self, x: F64, y: F64, radius: F64) -> tuple[NDArray[np.int16], NDArray[np.bool_]]:
        """Material index at each table point, and whether a boundary may lie within
        ``radius`` (mm) of it (conservative: it never misses one)."""
        mat = np.zeros(x.shape, dtype=np.int16)
        edge = np.zeros(x.shape, dtype=bool)
        if self.board is not None:
            (sd_p, _, _), (sd_d, _, _) = self._board_fields(x, y, float(radius.max()))
            mat[sd_p < 0.0] = _PAPER
            mat[sd_d < 0.0] = _INK
            edge |= (np.abs(sd_p) < radius) | (np.abs(sd_d) < radius)
        pad = float(radius.max())
        points = _PointIndex(x, y) if self.objects else None
        for i in self.flat:
            assert points is not None
            outer, holes = self.objects[i]
            sel = self._near_object(i, points, pad)
            if sel.size == 0:
                continue
            xs, ys, rs = x.ravel()[sel], y.ravel()[sel], radius.ravel()[sel]
            sd_out = outer[0].signed_distance(xs, ys)
            for p in outer[1:]:
                np.minimum(sd_out, p.signed_distance(xs, ys), out=sd_out)
            inside = sd_out < 0.0
            near = np.abs(sd_out) < rs
            for h in holes:
                sd_h = h.signed_distance(xs, ys)
                inside &= sd_h >= 0.0
                near |= np.abs(sd_h) < rs
            mat.ravel()[sel[inside]] = _FIRST_OBJECT + i
            edge.ravel()[sel[near]] = True
        # Raised objects hide what lies under them. Where two may both be hit, which is in
        # front can change within the footprint: such points are edges too.
        reached = np.zeros(x.shape, dtype=np.int32) if len(self.raised) > 1 else None
        for i, raised in self.raised:
            assert points is not None
            sel = self._near_object(i, points, pad)
            if sel.size == 0:
                continue
            xs, ys, rs = x.ravel()[sel], y.ravel()[sel], radius.ravel()[sel]
            hit, top, near, reach = raised.classify(xs, ys, rs)
            mat.ravel()[sel[hit]] = self.side
            mat.ravel()[sel[top]] = _FIRST_OBJECT + i
            edge.ravel()[sel[near]] = True
            if reached is not None:
                reached.ravel()[sel[reach]] += 1
        if reached is not None:
            edge |= reached > 1
        return mat, edge

    def shade(self, x: F64, y: F64, cell: tuple[F64, F64, F64, F64], lut: F64) -> F64:
        """The value (N, channels) of each cell centred at table point (x, y) with footprint
        ``cell`` (see _coverage): each layer's coverage of the cell, composited in order."""
        out = np.repeat(lut[_TABLE][None, :], x.size, axis=0)
        ax, ay, bx, by = cell
        # Beyond pad (mm) from its centre no boundary touches a cell: its coverage is 0 or 1.
        pad = float(np.max(np.abs(ax) + np.abs(bx) + np.abs(ay) + np.abs(by)))
        if self.board is not None:
            paper, dots = self._board_fields(x, y, pad)
            cov = _coverage(*paper, cell)
            out += (lut[_PAPER][None, :] - out) * cov[:, None]
            cov = _coverage(*dots, cell)
            # Where dots come close, a cell may reach two: the ink is the sum of both.
            shared = False
            for sel, *field in self._other_dots(x, y, pad, dots[0]):
                part = (ax[sel], ay[sel], bx[sel], by[sel])
                cov[sel] += _coverage(field[0], field[1], field[2], part)
                shared = True
            if shared:
                np.minimum(cov, 1.0, out=cov)
            out += (lut[_INK][None, :] - out) * cov[:, None]
        points = _PointIndex(x, y) if self.objects else None
        for i in self.flat:
            assert points is not None
            outer, holes = self.objects[i]
            sel = self._near_object(i, points, pad)
            if sel.size == 0:
                continue
            xs, ys = x[sel], y[sel]
            part = (ax[sel], ay[sel], bx[sel], by[sel])
            sd, nx, ny = outer[0].field(xs, ys)
            for p in outer[1:]:
                sd2, nx2, ny2 = p.field(xs, ys)
                closer = sd2 < sd
                sd, nx, ny = (
                    np.where(closer, a2, a1) for a1, a2 in ((sd, sd2), (nx, nx2), (ny, ny2))
                )
            cov = _coverage(sd, nx, ny, part)
            for h in holes:
                cov = cov * (1.0 - _coverage(*h.field(xs, ys), part))
            out[sel] += (lut[_FIRST_OBJECT + i][None, :] - out[sel]) * cov[:, None]
        if self.raised:
            assert points is not None
            self._shade_raised(x, y, cell, lut, pad, out, points)
        return out

    def _shade_raised(
        self,
        x: F64,
        y: F64,
        cell: tuple[F64, F64, F64, F64],
        lut: F64,
        pad: float,
        out: F64,
        points: _PointIndex,
    ) -> None:
        """Draw the raised objects over ``out`` (in place): each cell gets the wall's tone
        over the fraction of its footprint whose rays meet the object and the top's tone over
        the fraction that meets the top (a part of it). Where two raised objects both cover
        part of a cell they are drawn in the order of the heights at which the ray through
        the cell's centre meets them (the nearer to the camera in front)."""
        ax, ay, bx, by = cell
        side = lut[self.side][None, :]
        layers: list[tuple[int, NDArray[np.intp], F64, F64]] = []
        count = np.zeros(x.shape, dtype=np.int32) if len(self.raised) > 1 else None
        for k, (i, raised) in enumerate(self.raised):
            sel = self._near_object(i, points, pad)
            if sel.size == 0:
                continue
            part = (ax[sel], ay[sel], bx[sel], by[sel])
            hit, top = raised.fields(x[sel], y[sel])
            c_hit = _coverage(*hit, part)
            c_top = np.minimum(_coverage(*top, part), c_hit)
            layers.append((k, sel, c_hit, c_top))
            if count is not None:
                count[sel[c_hit > 0.0]] += 1

        def draw(o: F64, top: F64, c_hit: F64, c_top: F64) -> F64:
            """o under an object: the wall over c_hit of each cell, its top (a part of
            that) over c_top: o (1 - c_hit) + side (c_hit - c_top) + top c_top."""
            o = o + (side - o) * c_hit[:, None]
            return np.asarray(o + (top - side) * c_top[:, None], dtype=np.float64)

        def tone(k: int) -> F64:
            return np.asarray(lut[_FIRST_OBJECT + self.raised[k][0]][None, :], np.float64)

        shared = np.flatnonzero(count > 1) if count is not None else np.zeros(0, np.intp)
        if shared.size == 0:
            for k, sel, c_hit, c_top in layers:
                out[sel] = draw(out[sel], tone(k), c_hit, c_top)
            return
        # Cells that several raised objects cover in part: painter's order in each, by the
        # height at which the ray through the cell's centre meets each object.
        slot = np.full(x.shape, -1, dtype=np.intp)
        slot[shared] = np.arange(shared.size)
        depth = np.full((len(layers), shared.size), -np.inf)
        hits = np.zeros((len(layers), shared.size))
        tops = np.zeros((len(layers), shared.size))
        for m, (k, sel, c_hit, c_top) in enumerate(layers):
            at = slot[sel]
            alone = at < 0
            out[sel[alone]] = draw(out[sel[alone]], tone(k), c_hit[alone], c_top[alone])
            mine, at = sel[~alone], at[~alone]
            depth[m, at] = self.raised[k][1].entry_height(x[mine], y[mine])
            hits[m, at], tops[m, at] = c_hit[~alone], c_top[~alone]
        order = np.argsort(depth, axis=0, kind="stable")  # ties: the later object in front
        tones = np.concatenate([tone(k) for k, *_ in layers])
        cols = np.arange(shared.size)
        o = out[shared]
        for m in order:
            o = draw(o, tones[m], hits[m, cols], tops[m, cols])
        out[shared] = o


def render_scene(
    camera: CameraModel | None = None,
    pose: PlanePose | None = None,
    *,
    board: CircleGridBoard | None = CircleGridBoard(),  # noqa: B008 (frozen, immutable)
    board_origin_mm: tuple[float, float] = (0.0, 0.0),
    board_angle_deg: float = 0.0,
    paper_margin_mm: float = 15.0,
    light_on_dark: bool = False,
    enlarged_dots: Mapping[int, float] | None = None,
    marks: Sequence[SceneObject] = (),
    objects: Sequence[SceneObject] = (),
    table_grey: float = 100.0,
    paper_grey: float = 225.0,
    ink_grey: float = 35.0,
    metal_grey: float = 170.0,
    side_grey: float | None = None,
    blur_sigma_px: float = 0.0,
    noise_sigma: float = 0.0,
    lighting_gradient: float = 0.0,
    lighting_angle_deg: float = 0.0,
    vignette: float = 0.0,
    table_texture: float = 0.0,
    paper_texture: float = 0.0,
    color: bool = False,
    seed: int = 0,
    supersample: int = 8,
) -> RenderedScene:
    """Photograph a table with, optionally, a board and objects on it; see the module's
    docstring for the conventions and the method.

    Geometry: ``camera`` (default :class:`CameraModel()`: 1280 x 720, f = 1070 px, no
    distortion) looks at the table from ``pose`` (default: 500 mm straight above the board's
    centre, or the table origin without a board). ``board`` (default the paper's 14 x 10
    board; None for none) lies with its dot 0 at ``board_origin_mm`` on the table, turned by
    ``board_angle_deg`` (from +X towards +Y), printed on paper reaching ``paper_margin_mm``
    beyond the outer edges of its dots: dark dots on light paper, or light on dark with
    ``light_on_dark=True`` (paper and ink grey levels swapped). Either layout
    (``board.layout``); each dot is as large as ``board.dot_diameters()`` says (the origin
    marker's up to the distance between neighbours: it may then touch them), except the dots
    in ``enlarged_dots`` (dot index -> diameter in mm, at least the board's dots and at most
    ``board.neighbour_distance``): fiducials anywhere in the grid. The board's diameter must
    be known. ``marks`` are decoration printed on the paper: flat shapes (as
    :class:`SceneObject`, ``height_mm`` 0) in *board* coordinates, so they move with the
    board; those without their own ``grey`` are printed in the board's ink (light on dark
    too). They are drawn over the paper and the dots, under the objects, and are no part of
    the objects' truth (see :func:`printed_marks`). ``objects`` lie on top: flat
    ones (``height_mm`` 0) later over earlier, raised ones over everything flat and, among
    themselves, nearer to the camera in front (see the module's docstring). An object must
    be lower than the camera.

    Tones (grey levels 0-255, before lighting): ``table_grey``, ``paper_grey``,
    ``ink_grey``, ``metal_grey`` (objects' tops without their own ``grey``), ``side_grey``
    (the walls of raised objects; None: 0.6 x ``table_grey``, dark upright faces under
    overhead light). ``color=True`` returns BGR, each material's grey level slightly tinted
    (a warm table, white paper, near-black ink, cool metal).

    Textures (standard deviation in grey levels; 0: a uniform material): ``table_texture``
    adds a wood- or carpet-like random pattern (grain, mottling and streaks at a few scales)
    to the table, ``paper_texture`` a finer fibre-and-mottle one to the paper (not to the
    ink or the marks). Both are drawn on the plane, so perspective foreshortens them; their
    finest detail is about two pixels at the image's median scale (fine enough to look
    like grain, coarse enough not to alias), so they depend on the camera and the pose as
    well as on ``seed`` (from which they draw their own streams, not the image noise's).
    They are lit like the material they are on.

    Effects, applied in this order: ``lighting_gradient`` G (gain falling linearly from
    1 + G/2 to 1 - G/2 across the image, the bright side towards ``lighting_angle_deg``,
    measured in the image from +x towards +y) and ``vignette`` V (gain 1 - V (r / r_corner)^2
    around the principal point); Gaussian blur of ``blur_sigma_px`` px; additive Gaussian
    noise of ``noise_sigma`` grey levels drawn from ``numpy.random.default_rng(seed)``;
    rounding and clipping to uint8. The same arguments always give the same image.

    ``supersample``: n for the n x n cells of each edge pixel (1-32; see the module's
    docstring). Cells are shaded by exact coverage, so 4 is already within 0.002 of the
    contrast for 10-pixel dots; more only refines curvature and corners.

    Errors: ValueError for a pose whose plane does not fill the view (its horizon is in the
    image) or for bad objects (one as high as the camera), BoardError for the board's
    placement, ImageError for the image parameters (tones, effects, supersample).
    """
    camera = CameraModel() if camera is None else camera
    if not isinstance(camera, CameraModel):
        raise ValueError(f"camera must be a CameraModel, got {type(camera).__name__}")
    if board is not None and not isinstance(board, CircleGridBoard):
        raise BoardError(f"board must be a CircleGridBoard or None, got {type(board).__name__}")
    origin = arguments.pair("board_origin_mm", board_origin_mm, BoardError)
    angle = arguments.real("board_angle_deg", board_angle_deg, BoardError)
    margin = arguments.real("paper_margin_mm", paper_margin_mm, BoardError)
    if margin < 0:
        raise BoardError(f"paper_margin_mm must be >= 0, got {paper_margin_mm!r}")
    diameters = None if board is None else _dot_diameters(board, enlarged_dots)
    if pose is None:
        centre = np.zeros(2)
        if board is not None:
            middle = np.array([[board.cols - 1, board.rows - 1]]) * (board.pitch / 2.0)
            if board.layout == "asymmetric":
                pts = board.world_points()
                middle = 0.5 * (pts.min(axis=0) + pts.max(axis=0))[None, :]
            centre = _board_to_table(middle, origin, angle)[0]
        pose = PlanePose(500.0, look_at_mm=(float(centre[0]), float(centre[1])))
    if not isinstance(pose, PlanePose):
        raise ValueError(f"pose must be a PlanePose, got {type(pose).__name__}")
    objs = tuple(objects)
    for i, o in enumerate(objs):
        if not isinstance(o, SceneObject):
            raise ValueError(f"objects[{i}] must be a SceneObject, got {type(o).__name__}")
    printed = tuple(marks)
    for i, o in enumerate(printed):
        if not isinstance(o, SceneObject):
            raise ValueError(f"marks[{i}] must be a SceneObject, got {type(o).__name__}")
        if o.height_mm != 0.0:
            raise ValueError(f"marks[{i}] must be flat (height_mm 0): marks are printed")
    tones = {
        name: arguments.real(name, value, ImageError)
        for name, value in (
            ("table_grey", table_grey),
            ("paper_grey", paper_grey),
            ("ink_grey", ink_grey),
            ("metal_grey", metal_grey),
        )
    }
    tones["side_grey"] = (
        _SIDE_SHADE * tones["table_grey"]
        if side_grey is None
        else arguments.real("side_grey", side_grey, ImageError)
    )
    for name, value in tones.items():
        if not 0.0 <= value <= 255.0:
            raise ImageError(f"{name} must be a grey level 0-255, got {value!r}")
    blur = arguments.real("blur_sigma_px", blur_sigma_px, ImageError)
    noise = arguments.real("noise_sigma", noise_sigma, ImageError)
    gradient = arguments.real("lighting_gradient", lighting_gradient, ImageError)
    light_angle = arguments.real("lighting_angle_deg", lighting_angle_deg, ImageError)
    vig = arguments.real("vignette", vignette, ImageError)
    textures = {
        name: arguments.real(name, value, ImageError)
        for name, value in (("table_texture", table_texture), ("paper_texture", paper_texture))
    }
    for name, value in textures.items():
        if not 0.0 <= value <= 255.0:
            raise ImageError(f"{name} must be 0 to 255 grey levels, got {value!r}")
    if not 0.0 <= blur <= 50.0:
        raise ImageError(f"blur_sigma_px must be 0 to 50 px, got {blur_sigma_px!r}")
    if noise < 0.0:
        raise ImageError(f"noise_sigma must be >= 0 grey levels, got {noise_sigma!r}")
    if not 0.0 <= gradient < 2.0:
        raise ImageError(f"lighting_gradient must be in [0, 2), got {lighting_gradient!r}")
    if not 0.0 <= vig < 1.0:
        raise ImageError(f"vignette must be in [0, 1), got {vignette!r}")
    if isinstance(supersample, bool) or not isinstance(supersample, int | np.integer):
        raise ImageError(f"supersample must be a whole number, got {supersample!r}")
    if not 1 <= supersample <= 32:
        raise ImageError(f"supersample must be 1 to 32, got {supersample}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ImageError(f"seed must be a non-negative whole number, got {seed!r}")

    camera_centre = pose.camera_centre_mm()
    for i, o in enumerate(objs):
        if o.height_mm >= -camera_centre[2]:
            raise ValueError(
                f"objects[{i}].height_mm ({o.height_mm!r}) reaches the camera, which is "
                f"{-camera_centre[2]:.6g} mm above the table"
            )
    # Marks are the first flat layers (over the board, under the objects).
    layers = tuple(_mark_on_table(m, origin, angle) for m in printed) + objs
    scene = _Scene(board, origin, angle, margin, layers, camera_centre, diameters)
    lut = _tones(tones, layers, len(printed), light_on_dark=bool(light_on_dark), color=bool(color))
    textured = [
        (k, v)
        for k, v in ((_TABLE, textures["table_texture"]), (_PAPER, textures["paper_texture"]))
        if v > 0.0
    ]
    if textured:
        # One more channel per textured material: the fraction of each pixel it covers.
        shares = np.zeros((len(lut), len(textured)))
        for j, (material, _) in enumerate(textured):
            shares[material, j] = 1.0
        radiance, plane_x, plane_y = _radiance(
            camera, pose, scene, np.hstack([lut, shares]), int(supersample)
        )
        channels = lut.shape[1]
        for j, (material, amplitude) in enumerate(textured):
            pattern = _plane_texture(plane_x, plane_y, material, int(seed)) * amplitude
            covered = pattern * radiance[:, :, channels + j]
            tint = _TINT_TABLE if material == _TABLE else _TINT_PAPER
            for ch in range(channels):
                radiance[:, :, ch] += covered * (tint[ch] if color else 1.0)
        radiance = radiance[:, :, :channels]
    else:
        radiance, _, _ = _radiance(camera, pose, scene, lut, int(supersample))
    if not color:
        radiance = np.ascontiguousarray(radiance[:, :, 0])

    w, h = camera.width, camera.height
    if gradient or vig:
        gain = _lighting(camera, gradient, light_angle, vig)
        radiance *= gain if radiance.ndim == 2 else gain[:, :, None]
    if blur > 0.0:
        radiance = np.asarray(
            cv2.GaussianBlur(
                radiance, (0, 0), sigmaX=blur, sigmaY=blur, borderType=cv2.BORDER_REFLECT
            ),
            dtype=np.float32,
        )
    if noise > 0.0:
        rng = np.random.default_rng(int(seed))
        radiance += rng.normal(0.0, noise, radiance.shape).astype(np.float32)
    image = np.clip(np.rint(radiance), 0, 255).astype(np.uint8)

    h_world = camera.homography(pose)
    if board is not None:
        dots_mm = _board_to_table(board.world_points(), origin, angle)
        dots_px = camera.project(dots_mm, pose)
        b2t = np.array(
            [
                [math.cos(math.radians(angle)), -math.sin(math.radians(angle)), origin[0]],
                [math.sin(math.radians(angle)), math.cos(math.radians(angle)), origin[1]],
                [0.0, 0.0, 1.0],
            ]
        )
        h_board: F64 | None = h_world @ b2t
        assert h_board is not None
        h_board = h_board / h_board[2, 2]
    else:
        dots_px, h_board = np.zeros((0, 2)), None
    centroids = np.array([o.position_mm for o in objs], dtype=np.float64).reshape(-1, 2)
    heights = np.array([float(o.height_mm) for o in objs], dtype=np.float64)
    centroids_px = camera.project(centroids, pose, heights) if len(objs) else np.zeros((0, 2))
    effects: dict[str, float | int | bool] = {
        **tones,
        "blur_sigma_px": blur,
        "noise_sigma": noise,
        "lighting_gradient": gradient,
        "lighting_angle_deg": light_angle,
        "vignette": vig,
        "light_on_dark": bool(light_on_dark),
        "color": bool(color),
        "seed": int(seed),
        "supersample": int(supersample),
        "paper_margin_mm": margin,
        **textures,
    }
    assert image.shape[:2] == (h, w)
    return RenderedScene(
        image=image,
        dot_centres_px=dots_px,
        object_centroids_px=centroids_px,
        objects=objs,
        board=board,
        board_origin_mm=origin,
        board_angle_deg=angle,
        camera=camera,
        pose=pose,
        world_to_image=h_world,
        board_to_image=h_board,
        effects=effects,
        dot_diameters_mm=np.zeros(0) if diameters is None else diameters,
        marks=printed,
    )


def _tones(
    tones: Mapping[str, float],
    objects: Sequence[SceneObject],
    n_marks: int = 0,
    *,
    light_on_dark: bool,
    color: bool,
) -> F64:
    """The material -> value table, (n_materials, 1) grey or (n_materials, 3) BGR. The
    first ``n_marks`` objects are printed marks: the board's ink unless they have a grey."""
    paper, ink = tones["paper_grey"], tones["ink_grey"]
    if light_on_dark:
        paper, ink = ink, paper
    rows: list[tuple[float, tuple[float, float, float]]] = [
        (tones["table_grey"], _TINT_TABLE),
        (paper, _TINT_PAPER),
        (ink, _TINT_INK),
    ]
    for i, o in enumerate(objects):
        if i < n_marks:
            rows.append((ink if o.grey is None else float(o.grey), _TINT_INK))
            continue
        rows.append((tones["metal_grey"] if o.grey is None else float(o.grey), _TINT_METAL))
    rows.append((tones["side_grey"], _TINT_METAL))  # the walls of raised objects
    if not color:
        return np.array([[g] for g, _ in rows], dtype=np.float64)
    return np.asarray(
        np.clip(np.array([[g * t for t in tint] for g, tint in rows]), 0, 255), np.float64
    )


def _radiance(
    camera: CameraModel,
    pose: PlanePose,
    scene: _Scene,
    lut: F64,
    n: int,
) -> tuple[NDArray[np.float32], F64, F64]:
    """The noise-free, evenly lit image in float32, (height, width, channels): pure pixels
    take their material's value, edge pixels the mean over n x n cells, each traced through
    the lens to the plane and shaded by the exact coverage of its footprint; and the table
    points (X, Y) of the pixels' centres."""
    w, h = camera.width, camera.height
    f = float(camera.focal_px)
    # The plane points of the pixel corners.
    xd = ((np.arange(w + 1, dtype=np.float64) - 0.5 - camera.cx) / f)[None, :]
    yd = ((np.arange(h + 1, dtype=np.float64) - 0.5 - camera.cy) / f)[:, None]
    cx, cy, ok = camera._rays_to_plane(xd, yd, pose)
    if not ok.all():
        raise ValueError(
            "the plane does not fill the view: part of the image sees above its horizon "
            f"(tilt {pose.tilt_deg} degrees is too steep for this camera and distance)"
        )
    # Pixel centres (mean of the corners: exact to second order, and only used where the
    # whole footprint, with a margin, lies in one material) and footprint radii.
    px = 0.25 * (cx[:-1, :-1] + cx[1:, :-1] + cx[:-1, 1:] + cx[1:, 1:])
    py = 0.25 * (cy[:-1, :-1] + cy[1:, :-1] + cy[:-1, 1:] + cy[1:, 1:])
    rad = np.hypot(cx[:-1, :-1] - px, cy[:-1, :-1] - py)
    for rows, cols in ((slice(1, None), slice(None, -1)), (slice(None, -1), slice(1, None))):
        np.maximum(rad, np.hypot(cx[rows, cols] - px, cy[rows, cols] - py), out=rad)
    np.maximum(rad, np.hypot(cx[1:, 1:] - px, cy[1:, 1:] - py), out=rad)
    rad = rad * 1.05 + 1e-9
    mat, edge = scene.classify(px, py, rad)
    out = lut[mat].astype(np.float32)
    ey, ex = np.nonzero(edge)
    if ey.size:
        o = (np.arange(n) + 0.5) / n - 0.5
        ou = np.tile(o, n)
        ov = np.repeat(o, n)
        chunk = max(1, 1_000_000 // (n * n))
        for start in range(0, ey.size, chunk):
            iy, ix = ey[start : start + chunk], ex[start : start + chunk]
            su = ((ix[:, None] + ou[None, :]) - camera.cx) / f
            sv = ((iy[:, None] + ov[None, :]) - camera.cy) / f
            sx, sy, sok = camera._rays_to_plane(su, sv, pose)
            assert sok.all()
            # The pixel's Jacobian (plane mm per pixel along u and v) from its corners,
            # scaled to one cell.
            ju_x = 0.5 * (cx[iy, ix + 1] - cx[iy, ix] + cx[iy + 1, ix + 1] - cx[iy + 1, ix]) / n
            ju_y = 0.5 * (cy[iy, ix + 1] - cy[iy, ix] + cy[iy + 1, ix + 1] - cy[iy + 1, ix]) / n
            jv_x = 0.5 * (cx[iy + 1, ix] - cx[iy, ix] + cx[iy + 1, ix + 1] - cx[iy, ix + 1]) / n
            jv_y = 0.5 * (cy[iy + 1, ix] - cy[iy, ix] + cy[iy + 1, ix + 1] - cy[iy, ix + 1]) / n
            cell = tuple(np.repeat(j, n * n) for j in (ju_x, ju_y, jv_x, jv_y))
            values = scene.shade(sx.ravel(), sy.ravel(), cell, lut)  # type: ignore[arg-type]
            out[iy, ix] = values.reshape(len(iy), n * n, -1).mean(axis=1)
    return np.ascontiguousarray(out, dtype=np.float32), px, py


def _lighting(camera: CameraModel, gradient: float, angle_deg: float, vig: float) -> F64:
    """The multiplicative gain of the uneven lighting, (height, width)."""
    w, h = camera.width, camera.height
    x = np.arange(w, dtype=np.float64)[None, :]
    y = np.arange(h, dtype=np.float64)[:, None]
    gain = np.ones((h, w))
    if gradient:
        a = math.radians(angle_deg)
        proj = (x - (w - 1) / 2.0) * math.cos(a) + (y - (h - 1) / 2.0) * math.sin(a)
        extent = 0.5 * ((w - 1) * abs(math.cos(a)) + (h - 1) * abs(math.sin(a)))
        gain = gain * (1.0 + 0.5 * gradient * proj / extent)
    if vig:
        r2 = (x - camera.cx) ** 2 + (y - camera.cy) ** 2
        corner = max(
            (cxx - camera.cx) ** 2 + (cyy - camera.cy) ** 2
            for cxx in (0.0, w - 1.0)
            for cyy in (0.0, h - 1.0)
        )
        gain = gain * (1.0 - vig * r2 / corner)
    return np.asarray(gain, dtype=np.float32)


def _dot_diameters(board: CircleGridBoard, enlarged: Mapping[int, float] | None) -> F64:
    """Each dot's diameter (mm), board order: the board's, with ``enlarged`` applied."""
    diameters = board.dot_diameters()  # BoardError when the board's diameter is unknown
    if enlarged is None:
        return diameters
    if not isinstance(enlarged, Mapping):
        raise BoardError(f"enlarged_dots must map dot indices to diameters, got {enlarged!r}")
    nominal, limit = float(board.dots_mm()), board.neighbour_distance
    for index, value in enlarged.items():
        if isinstance(index, bool) or not isinstance(index, int | np.integer):
            raise BoardError(f"enlarged_dots: {index!r} is not a dot index")
        if not 0 <= index < board.n_points:
            raise BoardError(
                f"enlarged_dots: dot {index} does not exist (the board has {board.n_points})"
            )
        d = arguments.real(f"enlarged_dots[{index}]", value, BoardError)
        if not nominal <= d <= limit:
            raise BoardError(
                f"enlarged_dots[{index}] = {value!r} mm: an enlarged dot must be at least the "
                f"board's dots ({nominal:g} mm) and at most the distance between neighbours "
                f"({limit:g} mm)"
            )
        diameters[int(index)] = d
    return diameters


def _mark_on_table(mark: SceneObject, origin: tuple[float, float], angle: float) -> SceneObject:
    """A mark given in board coordinates, placed on the table with the board."""
    at = _board_to_table(np.array([mark.position_mm]), origin, angle)[0]
    return dataclasses.replace(
        mark, position_mm=(float(at[0]), float(at[1])), angle_deg=float(mark.angle_deg) + angle
    )


# The textures' layers: (cells along u, cells along v, weight), u along the grain.
_TABLE_LAYERS = ((2, 2, 0.35), (4, 4, 0.45), (12, 12, 0.5), (48, 2, 0.7))
_PAPER_LAYERS = ((2, 2, 0.7), (6, 6, 0.4))


def _plane_texture(x: F64, y: F64, material: int, seed: int) -> NDArray[np.float32]:
    """A random texture of unit standard deviation on the table plane, sampled at the table
    points (x, y) (mm, one per pixel): a sum of value-noise layers (white noise on grids of
    2 texels and coarser, cubic-interpolated), each of them normalised, on a grid whose
    texel is the pixels' median footprint, turned by a random angle (the grain's
    direction)."""
    rng = np.random.default_rng([seed, material])  # not the image noise's stream
    turn = rng.uniform(0.0, math.pi)
    c, s = math.cos(turn), math.sin(turn)
    u, v = c * x + s * y, c * y - s * x
    step = np.hypot(np.diff(u[::8], axis=1), np.diff(v[::8], axis=1))
    texel = float(np.median(step))
    u0, v0 = float(u.min()) - 2.0 * texel, float(v.min()) - 2.0 * texel
    nu = math.ceil((float(u.max()) - u0) / texel) + 3
    nv = math.ceil((float(v.max()) - v0) / texel) + 3
    growth = math.sqrt(nu * nv / (4.0 * x.size))  # steep views see far: cap the grid
    if growth > 1.0:
        texel *= growth
        nu, nv = int(nu / growth) + 3, int(nv / growth) + 3
    layers = _TABLE_LAYERS if material == _TABLE else _PAPER_LAYERS
    grid = np.zeros((nv, nu), dtype=np.float32)
    for su, sv, weight in layers:
        coarse = rng.standard_normal((nv // sv + 4, nu // su + 4)).astype(np.float32)
        fine = cv2.resize(
            coarse, (coarse.shape[1] * su, coarse.shape[0] * sv), interpolation=cv2.INTER_CUBIC
        )[:nv, :nu]
        grid += weight * fine / max(float(fine.std()), 1e-6)
    grid /= max(float(grid.std()), 1e-6)
    map_u = ((u - u0) / texel).astype(np.float32)
    map_v = ((v - v0) / texel).astype(np.float32)
    out = cv2.remap(grid, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return np.asarray(out, dtype=np.float32)


# --------------------------------------------------------------------------- printed marks

MarkKind = Literal["numbers", "cell_numbers", "arrows", "text", "crosses", "rings"]
"""The kinds of marks :func:`printed_marks` prints."""

MARK_KINDS: tuple[MarkKind, ...] = (
    "numbers",
    "cell_numbers",
    "arrows",
    "text",
    "crosses",
    "rings",
)

# Seven-segment digits: segments a (top), b (upper right), c (lower right), d (bottom),
# e (lower left), f (upper left), g (middle).
_DIGIT_SEGMENTS: tuple[str, ...] = ("abcdef", "bc", "abged", "abgcd", "fgbc", "afgcd")
_DIGIT_SEGMENTS += ("afgedc", "abc", "abcdefg", "abcdfg")
_DIGIT_WIDTH, _DIGIT_STROKE, _DIGIT_GAP = 0.55, 0.14, 0.25  # times the digit's height


def printed_marks(
    board: CircleGridBoard,
    kinds: MarkKind | Sequence[MarkKind] = MARK_KINDS,
    seed: int = 0,
    *,
    paper_margin_mm: float = 15.0,
    enlarged_dots: Mapping[int, float] | None = None,
) -> tuple[SceneObject, ...]:
    """Ink marks printed on a board's paper, as flat shapes in board coordinates, to pass as
    ``render_scene(marks=...)``: decoration that a detector must ignore, never part of the
    truth. Every shape is a thin rectangle (a :class:`SceneObject`); none touches a dot or
    leaves the paper (``paper_margin_mm`` and ``enlarged_dots`` must be render_scene's).

    ``kinds`` (one or several):

    * ``"numbers"``: column numbers above the first row and row numbers left of the first
      column (from 0), seven-segment digits in the outer half of the paper's margin.
    * ``"cell_numbers"``: dot numbers inside the grid, in the free space between dots (each
      beside the dot whose index it is), in about a third of those spaces (``seed`` picks).
    * ``"arrows"``: axis arrows in the inner half of the margin, along the first row (+X)
      and the first column (+Y), each about three dot spacings long.
    * ``"text"``: a line of text-like bars (letters of random widths and heights, in words)
      in the margin below the grid.
    * ``"crosses"``: small plus marks in about a quarter of the spaces between dots.
    * ``"rings"``: circles around a few dots (about one in ten, at least one), halfway to
      the nearest neighbour.

    The same arguments always give the same marks.
    """
    if not isinstance(board, CircleGridBoard):
        raise BoardError(f"board must be a CircleGridBoard, got {type(board).__name__}")
    wanted = (kinds,) if isinstance(kinds, str) else tuple(kinds)
    for kind in wanted:
        if kind not in MARK_KINDS:
            raise ValueError(f"kinds must be among {', '.join(MARK_KINDS)}; got {kind!r}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be a non-negative whole number, got {seed!r}")
    margin = arguments.real("paper_margin_mm", paper_margin_mm, BoardError)
    outside = {"numbers", "arrows", "text"} & set(wanted)
    if outside and margin <= 0.0:
        raise BoardError(f"{', '.join(sorted(outside))} need a paper margin, got {margin!r}")
    grid = _MarkGrid(board, _dot_diameters(board, enlarged_dots), margin, int(seed))
    makers = {
        "numbers": grid.numbers,
        "cell_numbers": grid.cell_numbers,
        "arrows": grid.arrows,
        "text": grid.text,
        "crosses": grid.crosses,
        "rings": grid.rings,
    }
    marks: list[SceneObject] = []
    for kind in MARK_KINDS:  # a fixed order: the same marks whatever order kinds come in
        if kind in wanted:
            marks.extend(makers[kind]())
    return tuple(marks)


def _bar(start: ArrayLike, end: ArrayLike, width: float) -> SceneObject:
    """A straight stroke ``width`` wide from start to end (its ends square, at the points)."""
    a, b = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    mid, d = 0.5 * (a + b), b - a
    return SceneObject(
        "rectangle",
        (float(mid[0]), float(mid[1])),
        angle_deg=math.degrees(math.atan2(d[1], d[0])),
        size_mm=width,
        length_mm=max(float(np.hypot(*d)), width),
    )


def _number_width(digits: int) -> float:
    """The width of a number of ``digits`` digits, times the digits' height."""
    return digits * _DIGIT_WIDTH + (digits - 1) * _DIGIT_GAP


def _number(value: int, centre: ArrayLike, height: float) -> list[SceneObject]:
    """``value`` in seven-segment digits ``height`` tall, centred on ``centre``."""
    text = str(value)
    w, st = _DIGIT_WIDTH * height, _DIGIT_STROKE * height
    cx, cy = np.asarray(centre, dtype=np.float64)
    left = cx - 0.5 * _number_width(len(text)) * height
    bars = []
    for k, ch in enumerate(text):
        x0 = left + k * (_DIGIT_WIDTH + _DIGIT_GAP) * height + st / 2.0
        x1 = x0 + w - st
        y0, ym, y1 = cy - (height - st) / 2.0, cy, cy + (height - st) / 2.0
        ends = {
            "a": ((x0, y0), (x1, y0)),
            "b": ((x1, y0), (x1, ym)),
            "c": ((x1, ym), (x1, y1)),
            "d": ((x0, y1), (x1, y1)),
            "e": ((x0, ym), (x0, y1)),
            "f": ((x0, y0), (x0, ym)),
            "g": ((x0, ym), (x1, ym)),
        }
        for seg in _DIGIT_SEGMENTS[int(ch)]:
            (ax, ay), (bx, by) = ends[seg]
            # Each stroke reaches half its width past its end points, so corners are filled.
            ux, uy = np.sign(bx - ax), np.sign(by - ay)
            h = st / 2.0
            bars.append(_bar((ax - ux * h, ay - uy * h), (bx + ux * h, by + uy * h), st))
    return bars


class _MarkGrid:
    """Where marks go on a board's paper (board coordinates, mm): bands of the margin
    around the dots, and the free spaces between dots, shared out so that no two kinds of
    marks meet whichever are asked for."""

    # Bands of the margin, as fractions of it out from the dots' outer edges: the arrows'
    # centre line, the numbers' and the text's.
    ARROWS, NUMBERS, TEXT = 0.3, 0.7, 0.5

    def __init__(self, board: CircleGridBoard, diameters: F64, margin: float, seed: int) -> None:
        self.board, self.margin = board, margin
        self.pts = board.world_points()
        self.radii = diameters / 2.0
        self.nominal = float(board.dots_mm())
        big = float(self.radii.max())
        lo, hi = self.pts.min(axis=0), self.pts.max(axis=0)
        self.left, self.top = float(lo[0]) - big, float(lo[1]) - big
        self.right, self.bottom = float(hi[0]) + big, float(hi[1]) + big
        self.x0, self.y0 = float(lo[0]), float(lo[1])
        self.row0 = self.pts[: board.cols]  # the first row's dots
        self.spacing = float(np.min(np.diff(self.row0[:, 0])))  # along a row
        self.holes, self.room, self.owner = self._free_spaces()
        # One draw shares everything out, the same whichever kinds are asked for: a tenth of
        # the dots get rings; of the free spaces clear of them, a third get numbers and a
        # quarter crosses.
        rng = np.random.default_rng([seed, 7])
        self.ringed = np.sort(rng.permutation(len(self.pts))[: max(1, len(self.pts) // 10)])
        self.ring_outer = self.radii + self._ring_band() * 0.45
        clear = self._clear_of_rings()
        order = rng.permutation(len(self.holes))
        order = order[clear[order]]
        n_numbers = max(1, len(order) // 3) if len(order) else 0
        n_crosses = max(1, len(order) // 4) if len(order) > 1 else 0
        self.numbered = np.sort(order[:n_numbers])
        self.crossed = np.sort(order[n_numbers : n_numbers + n_crosses])
        self.text_rng = np.random.default_rng([seed, 8])

    def _free_spaces(self) -> tuple[F64, F64, NDArray[np.intp]]:
        """The points between dots farthest from them (the centres of the squares of four
        dots; in the asymmetric layout the empty lattice points between two dots of a row),
        how far the nearest dot's edge is from each, and the dot each lies beside."""
        b, p = self.board, float(self.board.pitch)
        if b.layout == "asymmetric":
            c, r = np.meshgrid(np.arange(b.cols - 1), np.arange(b.rows))
            holes = np.column_stack([((2 * c + r % 2 + 1) * p).ravel(), (r * p).ravel()])
        else:
            c, r = np.meshgrid(np.arange(b.cols - 1), np.arange(b.rows - 1))
            holes = np.column_stack([((c + 0.5) * p).ravel(), ((r + 0.5) * p).ravel()])
        owner = (r * b.cols + c).ravel()
        gaps = np.linalg.norm(holes[:, None, :] - self.pts[None], axis=2) - self.radii[None]
        return holes, gaps.min(axis=1), owner

    def _ring_band(self) -> F64:
        """For each dot, the gap between its edge and the nearest other dot's."""
        d = np.linalg.norm(self.pts[:, None, :] - self.pts[None], axis=2) - self.radii[None]
        np.fill_diagonal(d, np.inf)
        return np.asarray(d.min(axis=1) - self.radii, dtype=np.float64)

    def _clear_of_rings(self) -> NDArray[np.bool_]:
        """Which free spaces keep their marks (at most 3/4 of their room out) off the rings."""
        c = self.pts[self.ringed]
        d = np.linalg.norm(self.holes[:, None, :] - c[None], axis=2) - self.ring_outer[self.ringed]
        return np.asarray((d > 0.8 * self.room[:, None]).all(axis=1))

    def _cell_digit_height(self) -> float:
        """One height for all numbers between dots: the longest fits in 3/4 of the smallest
        room (its half-diagonal), and none is much larger than a dot."""
        if not len(self.numbered):
            return 0.0
        digits = len(str(int(self.owner[self.numbered].max())))
        half_diagonal = 0.5 * math.hypot(_number_width(digits), 1.0)
        room = float(self.room[self.numbered].min())
        return min(0.75 * room / half_diagonal, 1.2 * self.nominal)

    def numbers(self) -> list[SceneObject]:
        m, b = self.margin, self.board
        # One height for both: column labels as tall as the band allows and narrower than
        # the gap between two of them, row labels as wide as the band and shorter than the
        # rows' spacing.
        h = min(
            0.36 * m,
            0.8 * self.spacing / _number_width(len(str(b.cols - 1))),
            0.36 * m / _number_width(len(str(b.rows - 1))),
            0.8 * float(b.pitch),
        )
        marks: list[SceneObject] = []
        for c, (x, _) in enumerate(self.row0):
            marks += _number(c, (x, self.top - self.NUMBERS * m), h)
        for r in range(b.rows):
            marks += _number(r, (self.left - self.NUMBERS * m, r * float(b.pitch)), h)
        return marks

    def cell_numbers(self) -> list[SceneObject]:
        h = self._cell_digit_height()
        marks: list[SceneObject] = []
        for k in self.numbered:
            marks += _number(int(self.owner[k]), self.holes[k], h)
        return marks

    def arrows(self) -> list[SceneObject]:
        m = self.margin
        width = 0.06 * m
        span_x = min(3.0 * self.spacing, self.right - self.x0)
        span_y = min(3.0 * float(self.board.pitch), self.bottom - self.y0)
        y, x = self.top - self.ARROWS * m, self.left - self.ARROWS * m
        return _arrow((self.x0, y), (self.x0 + span_x, y), width) + _arrow(
            (x, self.y0), (x, self.y0 + span_y), width
        )

    def text(self) -> list[SceneObject]:
        rng = self.text_rng
        m = self.margin
        h = 0.2 * m  # the x-height; ascenders are 1.5 times as tall
        base = self.bottom + self.TEXT * m + h / 2.0  # the line the letters stand on
        x, end = self.left, self.left + 0.8 * (self.right - self.left)
        marks: list[SceneObject] = []
        while True:
            for _ in range(int(rng.integers(2, 8))):
                w = h * float(rng.uniform(0.15, 0.6))
                tall = h * (1.5 if rng.uniform() < 0.3 else 1.0)
                if x + w > end:
                    return marks
                centre = (x + w / 2.0, base - tall / 2.0)
                marks.append(
                    SceneObject("rectangle", centre, angle_deg=90.0, size_mm=w, length_mm=tall)
                )
                x += w + 0.25 * h
            x += 0.8 * h

    def crosses(self) -> list[SceneObject]:
        marks: list[SceneObject] = []
        for k in self.crossed:
            (x, y), arm = self.holes[k], min(0.6 * float(self.room[k]), self.nominal)
            width = 0.2 * arm
            marks += [
                _bar((x - arm, y), (x + arm, y), width),
                _bar((x, y - arm), (x, y + arm), width),
            ]
        return marks

    def rings(self) -> list[SceneObject]:
        """Each ring: 32 chords, the stroke from 0.25 to 0.45 of the gap out from the dot."""
        gaps = self._ring_band()
        chords = 32
        marks: list[SceneObject] = []
        for k in self.ringed:
            width = 0.2 * float(gaps[k])
            rho = float(self.radii[k]) + 0.35 * float(gaps[k])  # the stroke's middle
            length = 2.0 * (rho + width / 2.0) * math.tan(math.pi / chords)
            for a in 2.0 * math.pi * np.arange(chords) / chords:
                centre = self.pts[k] + rho * np.array([math.cos(a), math.sin(a)])
                marks.append(
                    SceneObject(
                        "rectangle",
                        (float(centre[0]), float(centre[1])),
                        angle_deg=math.degrees(a) + 90.0,
                        size_mm=width,
                        length_mm=length,
                    )
                )
        return marks


def _arrow(start: ArrayLike, tip: ArrayLike, width: float) -> list[SceneObject]:
    """A shaft from start to tip and two barbs 30 degrees off it at the tip."""
    a, b = np.asarray(start, dtype=np.float64), np.asarray(tip, dtype=np.float64)
    d = (b - a) / float(np.hypot(*(b - a)))
    barb = 4.0 * width
    bars = [_bar(a, b, width)]
    for turn in (150.0, -150.0):
        t = math.radians(turn)
        back = np.array(
            [d[0] * math.cos(t) - d[1] * math.sin(t), d[0] * math.sin(t) + d[1] * math.cos(t)]
        )
        bars.append(_bar(b + back * width / 2.0, b + back * barb, width))
    return bars


def jpeg(image: NDArray[np.uint8], quality: int = 75) -> NDArray[np.uint8]:
    """``image`` (uint8, grey or BGR) compressed as JPEG at ``quality`` (0-100) and decoded
    again, as a webcam's stream would deliver it: 8 x 8 blocking and ringing at edges, and in
    colour the chroma subsampling. Same shape and dtype."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
        raise ImageError("jpeg needs a uint8 image")
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)):
        raise ImageError(f"jpeg needs a grey or BGR image, got shape {image.shape}")
    if isinstance(quality, bool) or not isinstance(quality, int | np.integer):
        raise ImageError(f"quality must be a whole number 0-100, got {quality!r}")
    if not 0 <= quality <= 100:
        raise ImageError(f"quality must be 0-100, got {quality}")
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 grey or BGR image
        raise ImageError("JPEG encoding failed")
    flag = cv2.IMREAD_GRAYSCALE if image.ndim == 2 else cv2.IMREAD_COLOR
    return np.asarray(cv2.imdecode(data, flag), dtype=np.uint8)


# --------------------------------------------------------------------------- board corpus


@dataclasses.dataclass(frozen=True, eq=False)
class BoardVariant:
    """One image of :func:`board_variants`' corpus and its truth.

    ``image``: uint8, grey or (one variant) BGR, JPEG-compressed where ``jpeg_quality`` is
    set. ``truth_px``: (rows * cols, 2), each dot centre's exact projection, in board order
    (``scene.dot_centres_px``). ``enlarged``: (rows * cols,) bool, the dots printed larger
    than the board's dots (an origin marker, fiducials). ``scene``: everything else (camera,
    pose, diameters, marks, effects); its ``image`` is before JPEG.
    """

    name: str
    description: str
    board: CircleGridBoard
    image: NDArray[np.uint8]
    truth_px: F64
    enlarged: NDArray[np.bool_]
    scene: RenderedScene
    jpeg_quality: int | None = None


class _Shot(NamedTuple):
    """A corpus variant's recipe: the render_scene arguments less the pose, which
    _board_shot frames (see there), and the JPEG quality."""

    board: CircleGridBoard
    camera: CameraModel
    fill: float = 0.8
    tilt_deg: float = 0.0
    board_angle_deg: float = 0.0
    jpeg_quality: int | None = None
    options: Mapping[str, object] = {}


def _board_shot(shot: _Shot, rng: np.random.Generator) -> tuple[RenderedScene, int | None]:
    """Render a corpus shot: the camera aimed at the board's middle (within 2 % of its
    size) from the distance at which the board's paper spans ``fill`` of the image
    (before tilt and lens), tilted about a random in-plane axis, rolled up to 4 degrees;
    noise seeded from rng."""
    board, camera = shot.board, shot.camera
    margin = float(cast("float", shot.options.get("paper_margin_mm", 15.0)))
    pts = board.world_points()
    big = float(np.max(board.dot_diameters())) / 2.0 + margin
    lo, hi = pts.min(axis=0) - big, pts.max(axis=0) + big
    roll = float(rng.uniform(-4.0, 4.0))
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    seen = corners @ _rotation_2d(shot.board_angle_deg + roll).T
    span = np.ptp(seen, axis=0)
    distance = float(camera.focal_px) * max(
        span[0] / (shot.fill * camera.width), span[1] / (shot.fill * camera.height)
    )
    middle = 0.5 * (pts.min(axis=0) + pts.max(axis=0)) + rng.uniform(-0.02, 0.02, 2) * (hi - lo)
    look = _board_to_table(middle[None, :], (0.0, 0.0), shot.board_angle_deg)[0]
    pose = PlanePose(
        distance_mm=distance,
        tilt_deg=shot.tilt_deg,
        tilt_axis_deg=float(rng.uniform(0.0, 360.0)),
        roll_deg=roll,
        look_at_mm=(float(look[0]), float(look[1])),
    )
    options = dict(shot.options)
    options.setdefault("supersample", 4)
    scene = render_scene(
        camera,
        pose,
        board=board,
        board_angle_deg=shot.board_angle_deg,
        seed=int(rng.integers(0, 2**31)),
        **options,  # type: ignore[arg-type]
    )
    return scene, shot.jpeg_quality


def _ratio_shot(ratio: float) -> Callable[[np.random.Generator], _Shot]:
    """A dot diameter / pitch sweep's shot: boards, cameras and lighting vary with it."""
    setups = {
        0.15: (11, 8, 20.0, CameraModel(1280, 720, 1100.0, k1=-0.08, k2=0.01), 5.0),
        0.3: (9, 6, 25.0, CameraModel(1600, 1200, 1500.0, k1=-0.05), 12.0),
        0.5: (7, 5, 30.0, CameraModel(1280, 960, 1000.0, principal=(650.0, 470.0)), 0.0),
        0.66: (8, 11, 12.0, CameraModel(1024, 768, 900.0, k1=-0.1, k2=0.02), 15.0),
        0.85: (10, 7, 10.0, CameraModel(1920, 1080, 1600.0, k1=-0.06), 3.0),
    }
    cols, rows, pitch, camera, tilt = setups[ratio]

    def shot(rng: np.random.Generator) -> _Shot:
        board = CircleGridBoard(cols, rows, pitch, round(ratio * pitch, 6))
        effects = {"blur_sigma_px": 0.6 + ratio, "noise_sigma": 2.0 + 1.5 * ratio}
        return _Shot(board, camera, 0.8, tilt, options={**effects, "vignette": 0.2})

    return shot


def _shot_origin_as_wide_as_pitch(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(10, 10, 20.0, 10.0, origin_marker=True, marker_diameter=20.0)
    effects = {"blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(
        board, CameraModel(1280, 720, 1070.0, k1=-0.1, k2=0.02), 0.85, 6.0, 0.0, None, effects
    )


def _shot_fiducials_barrel(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(16, 14, 10.0, 2.0)
    fiducials = {r * 16 + c: 6.0 for r, c in ((3, 3), (3, 12), (10, 3), (10, 11))}
    camera = CameraModel(640, 480, 420.0, k1=-0.3, k2=0.08)
    effects = {
        "enlarged_dots": fiducials,
        "paper_margin_mm": 6.0,
        "vignette": 0.45,
        "blur_sigma_px": 0.6,
        "noise_sigma": 2.0,
        "supersample": 8,
    }
    return _Shot(board, camera, 0.92, 4.0, options=effects)


def _shot_printed_marks(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(6, 6, 20.0, 13.2)
    marks = printed_marks(board, ("numbers", "cell_numbers", "arrows"), int(rng.integers(0, 1000)))
    effects = {"marks": marks, "blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.1), 0.85, 8.0, options=effects)


def _shot_marks_rings_crosses_text(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(9, 7, 18.0, 7.2)
    marks = printed_marks(board, ("rings", "crosses", "text"), int(rng.integers(0, 1000)))
    effects = {"marks": marks, "blur_sigma_px": 0.7, "noise_sigma": 2.0, "lighting_gradient": 0.2}
    return _Shot(board, CameraModel(1280, 960, 1150.0, k1=-0.08), 0.8, 10.0, options=effects)


def _shot_webcam_320x240(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(7, 5, 25.0, 10.0)
    camera = CameraModel(320, 240, 280.0, k1=-0.18, k2=0.03)
    effects = {"blur_sigma_px": 0.9, "noise_sigma": 3.0, "vignette": 0.3, "supersample": 8}
    return _Shot(board, camera, 0.8, 5.0, jpeg_quality=75, options=effects)


def _shot_webcam_640x480(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(9, 6, 20.0, 10.0)
    camera = CameraModel(640, 480, 560.0, principal=(322.0, 236.0), k1=-0.12, k2=0.02)
    effects = {
        "color": True,
        "blur_sigma_px": 0.8,
        "noise_sigma": 2.5,
        "lighting_gradient": 0.25,
        "lighting_angle_deg": 200.0,
        "vignette": 0.3,
    }
    return _Shot(board, camera, 0.8, 7.0, jpeg_quality=75, options=effects)


def _shot_uhd(rng: np.random.Generator) -> _Shot:
    camera = CameraModel(3840, 2160, 3200.0)
    effects = {"blur_sigma_px": 1.5, "noise_sigma": 1.5}
    return _Shot(PAPER_BOARD, camera, 0.8, 3.0, options=effects)


def _shot_light_on_dark(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(12, 9, 15.0, 7.5)
    effects = {"light_on_dark": True, "table_grey": 140.0, "blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.1), 0.85, 5.0, options=effects)


def _shot_uneven_light(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(11, 8, 20.0, 10.0)
    effects = {
        "lighting_gradient": 1.2,
        "lighting_angle_deg": 30.0,
        "vignette": 0.5,
        "blur_sigma_px": 0.8,
        "noise_sigma": 2.0,
    }
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.05), 0.85, 5.0, options=effects)


def _shot_textured_table(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(8, 6, 20.0, 10.0)
    effects = {
        "table_texture": 25.0,
        "paper_texture": 4.0,
        "table_grey": 120.0,
        "blur_sigma_px": 0.7,
        "noise_sigma": 2.0,
    }
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.08), 0.45, 10.0, options=effects)


def _shot_tilt_35(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(11, 8, 20.0, 10.0)
    effects = {"blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(
        board, CameraModel(1280, 720, 1070.0, k1=-0.1, k2=0.02), 0.6, 35.0, options=effects
    )


def _shot_asymmetric_4x11(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(4, 11, 20.0, 15.0, layout="asymmetric")
    effects = {"blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.1), 0.85, 10.0, options=effects)


def _shot_asymmetric_large(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(9, 17, 8.0, 6.5, layout="asymmetric")
    camera = CameraModel(1920, 1080, 1500.0, k1=-0.08, k2=0.01)
    effects = {"blur_sigma_px": 0.9, "noise_sigma": 2.0, "vignette": 0.2}
    return _Shot(board, camera, 0.85, 8.0, board_angle_deg=90.0, options=effects)


def _shot_rotated_90(rng: np.random.Generator) -> _Shot:
    board = CircleGridBoard(12, 7, 15.0, 7.0)
    effects = {"blur_sigma_px": 0.8, "noise_sigma": 2.0}
    return _Shot(board, CameraModel(1280, 720, 1070.0, k1=-0.1), 0.85, 5.0, 90.0, options=effects)


_VARIANTS: dict[str, tuple[Callable[[np.random.Generator], _Shot], str]] = {
    "ratio_0.15": (
        _ratio_shot(0.15),
        "11 x 8 dots, diameter 0.15 x pitch (3 mm, 20 mm apart), 1280 x 720, mild barrel, "
        "5 degrees tilt",
    ),
    "ratio_0.30": (
        _ratio_shot(0.3),
        "9 x 6 dots, diameter 0.3 x pitch, 1600 x 1200, 12 degrees tilt",
    ),
    "ratio_0.50": (
        _ratio_shot(0.5),
        "7 x 5 dots, diameter 0.5 x pitch (15 mm, 30 mm apart), 1280 x 960, off-centre "
        "principal point, no distortion",
    ),
    "ratio_0.66": (
        _ratio_shot(0.66),
        "8 x 11 dots (portrait), diameter 0.66 x pitch, 1024 x 768, 15 degrees tilt",
    ),
    "ratio_0.85": (
        _ratio_shot(0.85),
        "10 x 7 dots, diameter 0.85 x pitch (8.5 mm, 10 mm apart: 1.5 mm gaps), 1920 x 1080",
    ),
    "origin_as_wide_as_pitch": (
        _shot_origin_as_wide_as_pitch,
        "10 x 10 dots of 0.5 x pitch with an origin dot as wide as the pitch (it reaches "
        "halfway to its neighbours' edges)",
    ),
    "fiducials_barrel": (
        _shot_fiducials_barrel,
        "16 x 14 small dots (2 mm, about 4-6 px) with 4 enlarged fiducials (6 mm) inside the "
        "grid, 640 x 480 wide-angle lens with strong barrel distortion (k1 = -0.3), strong "
        "vignetting",
    ),
    "printed_marks": (
        _shot_printed_marks,
        "6 x 6 dots of 0.66 x pitch with printed row and column numbers, dot numbers "
        "between dots and axis arrows",
    ),
    "marks_rings_crosses_text": (
        _shot_marks_rings_crosses_text,
        "9 x 7 dots of 0.4 x pitch with rings around some dots, crosses between dots and a "
        "line of text below the grid",
    ),
    "webcam_320x240_jpeg": (
        _shot_webcam_320x240,
        "7 x 5 dots at 320 x 240 (dots about 10 px), webcam lens, blur, noise, JPEG q75",
    ),
    "webcam_640x480_jpeg": (
        _shot_webcam_640x480,
        "9 x 6 dots at 640 x 480 in colour (BGR), webcam lens, uneven light, JPEG q75",
    ),
    "uhd_3840x2160": (
        _shot_uhd,
        "the paper's 14 x 10 board at 3840 x 2160 (dots about 60 px), no distortion",
    ),
    "light_on_dark": (
        _shot_light_on_dark,
        "12 x 9 light dots on dark paper, on a mid-grey table",
    ),
    "uneven_light": (
        _shot_uneven_light,
        "11 x 8 dots under a strong lighting gradient (gain 1.6 to 0.4) and 50 % vignetting",
    ),
    "textured_table": (
        _shot_textured_table,
        "8 x 6 dots filling under half the image, on a wood-like textured table (25 grey "
        "levels), textured paper",
    ),
    "tilt_35": (
        _shot_tilt_35,
        "11 x 8 dots tilted 35 degrees about a random axis, webcam lens",
    ),
    "asymmetric_4x11": (
        _shot_asymmetric_4x11,
        "OpenCV's classic asymmetric grid: 4 x 11 dots, rows offset by half a spacing",
    ),
    "asymmetric_large": (
        _shot_asymmetric_large,
        "a 9 x 17 asymmetric grid of small dots turned 90 degrees, 1920 x 1080",
    ),
    "rotated_90": (
        _shot_rotated_90,
        "a 12 x 7 board turned 90 degrees on the table: its rows run down the image",
    ),
}

BOARD_VARIANTS: Mapping[str, str] = {name: text for name, (_, text) in _VARIANTS.items()}
"""The corpus' variants, by name, and what each shows (see :func:`board_variants`)."""


def board_variant(name: str, seed: int = 0) -> BoardVariant:
    """One variant of :func:`board_variants`' corpus, by name."""
    if name not in _VARIANTS:
        raise ValueError(f"no board variant {name!r}; the variants: {', '.join(_VARIANTS)}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be a non-negative whole number, got {seed!r}")
    # Each variant draws from its own stream, so a subset renders as in the whole corpus.
    rng = np.random.default_rng([int(seed), zlib.crc32(name.encode())])
    make, description = _VARIANTS[name]
    shot = make(rng)
    scene, quality = _board_shot(shot, rng)
    image = scene.image if quality is None else jpeg(scene.image, quality)
    board = shot.board
    return BoardVariant(
        name=name,
        description=description,
        board=board,
        image=image,
        truth_px=scene.dot_centres_px.copy(),
        enlarged=np.asarray(scene.dot_diameters_mm > board.dots_mm()),
        scene=scene,
        jpeg_quality=quality,
    )


def board_variants(seed: int = 0, names: Iterable[str] | None = None) -> list[BoardVariant]:
    """A corpus of circle-grid boards to test and benchmark board detection on: every
    variant of :data:`BOARD_VARIANTS` (or those in ``names``, in that order), each rendered
    with its exact truth. The variants sweep the dot diameter / pitch ratio (0.15 to 0.85),
    both layouts, origin markers and fiducials, printed marks, resolutions from 320 x 240 to
    3840 x 2160, webcam JPEG, lens distortion, tilt, lighting, light-on-dark boards and
    textured tables; every dot lies wholly inside its image. The same seed always gives the
    same corpus (about 10 s on two cores for all of it, 4 s of that the 4K image).
    """
    chosen = list(_VARIANTS) if names is None else [names] if isinstance(names, str) else names
    return [board_variant(name, seed) for name in chosen]


# --------------------------------------------------------------------------- the paper's scene

PAPER_BOARD = CircleGridBoard(cols=14, rows=10, pitch=20.0, diameter=10.0)
"""The paper's board: 14 x 10 dots of 10 mm, 20 mm apart, no origin marker."""

PAPER_CAMERA = CameraModel(
    width=1280, height=720, focal_px=1070.0, principal=(644.0, 355.0), k1=-0.12, k2=0.03
)
"""A Logitech C525-like webcam at 1280 x 720: about 69 degrees diagonal field of view
(f = 1070 px), principal point a few pixels off centre, the mild barrel distortion of a
plastic lens (k1 = -0.12, k2 = 0.03: about 40 px inwards at the image corners, up to 3.6 px
at the board's; a homography fitted to the board's exact dot centres is off by 0.5 px on
average, 1.8 px at worst, close to the paper's 0.677 / 1.911 px with its detection noise and
whole-pixel rounding)."""

PAPER_POSE = PlanePose(
    distance_mm=500.0, tilt_deg=3.0, tilt_axis_deg=35.0, roll_deg=0.8, look_at_mm=(135.0, 92.0)
)
"""500 mm above the board's middle, tilted 3 degrees, rolled 0.8 degrees: about 2.1 px/mm,
dots about 21 px across, the board's paper about 640 x 460 px of the 1280 x 720 image."""

PAPER_OBJECTS: tuple[SceneObject, ...] = (
    SceneObject("nut", (98.9, 155.9), angle_deg=12.0, size_mm=8.0),
    SceneObject("nut", (144.3, 138.2), angle_deg=41.0, size_mm=8.0),
    SceneObject("bolt", (33.1, 145.2), angle_deg=-75.0, size_mm=6.0, length_mm=30.0),
    SceneObject("nut", (85.4, 120.1), angle_deg=5.0, size_mm=8.0),
    SceneObject("bolt", (238.4, 128.7), angle_deg=100.0, size_mm=6.0, length_mm=30.0),
    SceneObject("nut", (189.2, 106.3), angle_deg=27.0, size_mm=8.0),
    SceneObject("nut", (132.8, 78.5), angle_deg=50.0, size_mm=8.0),
    SceneObject("bolt", (37.3, 72.0), angle_deg=20.0, size_mm=6.0, length_mm=30.0),
    SceneObject("nut", (109.8, 45.0), angle_deg=18.0, size_mm=8.0),
    SceneObject("nut", (165.7, 37.3), angle_deg=33.0, size_mm=8.0),
)
"""Three M6 x 30 bolts and seven M8 nuts at the paper's Table 5 positions (rounded to
0.1 mm), in board coordinates, inside the calibrated area and at least 5 mm apart."""

PAPER_EFFECTS: Mapping[str, float] = {
    "table_grey": 100.0,
    "paper_grey": 225.0,
    "ink_grey": 35.0,
    "metal_grey": 170.0,
    "blur_sigma_px": 0.8,
    "noise_sigma": 2.5,
    "lighting_gradient": 0.2,
    "lighting_angle_deg": 200.0,
    "vignette": 0.25,
}
"""Grey levels and image effects of the paper scene: a dark-grey bench, white paper, black
ink, bright steel; a lamp on the left (20 % gain gradient), a webcam's vignetting (25 % at
the corners), slight defocus (blur 0.8 px) and sensor noise (2.5 grey levels)."""


class PaperScene(NamedTuple):
    """The demo's pair of images: ``calibration`` (the board alone) and ``objects`` (the
    board removed, the objects in its place), same camera and pose."""

    calibration: RenderedScene
    objects: RenderedScene


def paper_scene(
    seed: int = 0, *, distortion: bool = True, objects: bool = True, color: bool = False
) -> PaperScene:
    """The demo's scene, modelled on the paper's setup; returns (calibration, objects).

    The paper's board (:data:`PAPER_BOARD`, dot 0 at the table origin, so board and table
    coordinates agree) seen by :data:`PAPER_CAMERA` (without its distortion if
    ``distortion=False``) from :data:`PAPER_POSE`, with :data:`PAPER_EFFECTS`. The objects
    image has the same camera, pose and effects, the board removed and
    :data:`PAPER_OBJECTS` on the table (none if ``objects=False``). The noise of the two
    images comes from two streams spawned from ``seed``.
    """
    camera = PAPER_CAMERA
    if not distortion:
        camera = dataclasses.replace(camera, k1=0.0, k2=0.0)
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ImageError(f"seed must be a non-negative whole number, got {seed!r}")
    seeds = [int(s.generate_state(1)[0]) for s in np.random.SeedSequence(int(seed)).spawn(2)]

    def render(
        board: CircleGridBoard | None, things: Sequence[SceneObject], seed: int
    ) -> RenderedScene:
        return _paper_render(camera, PAPER_POSE, board, things, seed, color=color)

    calibration = render(PAPER_BOARD, (), seeds[0])
    scene = render(None, PAPER_OBJECTS if objects else (), seeds[1])
    return PaperScene(calibration, scene)


def random_paper_scene(
    seed: int,
    *,
    px_per_mm: float = 1.9,
    max_tilt_deg: float = 5.0,
    objects: Sequence[SceneObject] = (),
) -> RenderedScene:
    """A random view of the paper's setup, for measuring accuracy over many scenes: the
    paper's board and camera (:data:`PAPER_CAMERA`, its lens distortion included) at the
    distance that gives ``px_per_mm`` at the board's centre, tilted up to ``max_tilt_deg``
    about a random axis, rolled up to 3 degrees, aimed within 10 mm of the board's centre,
    with :data:`PAPER_EFFECTS` (blur, noise, uneven lighting) and seeded noise. The same
    seed always gives the same scene."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ImageError(f"seed must be a non-negative whole number, got {seed!r}")
    rng = np.random.default_rng(int(seed))
    scale = arguments.positive("px_per_mm", px_per_mm)
    tilt = arguments.real("max_tilt_deg", max_tilt_deg)
    if not 0.0 <= tilt <= 60.0:
        raise ValueError(f"max_tilt_deg must be 0 to 60, got {max_tilt_deg!r}")
    board = PAPER_BOARD
    middle = np.array([board.cols - 1, board.rows - 1]) * board.pitch / 2.0
    pose = PlanePose(
        distance_mm=PAPER_CAMERA.focal_px / scale,
        tilt_deg=float(rng.uniform(0.0, tilt)),
        tilt_axis_deg=float(rng.uniform(0.0, 360.0)),
        roll_deg=float(rng.uniform(-3.0, 3.0)),
        look_at_mm=(
            float(middle[0] + rng.uniform(-10.0, 10.0)),
            float(middle[1] + rng.uniform(-10.0, 10.0)),
        ),
    )
    return _paper_render(PAPER_CAMERA, pose, board, objects, int(rng.integers(0, 2**31)))


def _paper_render(
    camera: CameraModel,
    pose: PlanePose,
    board: CircleGridBoard | None,
    objects: Sequence[SceneObject],
    seed: int,
    *,
    color: bool = False,
) -> RenderedScene:
    """render_scene with the paper scene's tones and effects (PAPER_EFFECTS)."""
    e = PAPER_EFFECTS
    return render_scene(
        camera,
        pose,
        board=board,
        objects=objects,
        color=color,
        seed=seed,
        table_grey=e["table_grey"],
        paper_grey=e["paper_grey"],
        ink_grey=e["ink_grey"],
        metal_grey=e["metal_grey"],
        blur_sigma_px=e["blur_sigma_px"],
        noise_sigma=e["noise_sigma"],
        lighting_gradient=e["lighting_gradient"],
        lighting_angle_deg=e["lighting_angle_deg"],
        vignette=e["vignette"],
    )
