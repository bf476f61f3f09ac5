"""Full camera intrinsics: the pinhole matrix K and OpenCV's lens-distortion model.

A plane's homography alone maps pixels to millimetres on the plane itself; it cannot say
where a ray meets anything *above* the plane (the top of a part, a post), and it absorbs the
lens's distortion only as well as a projective map can (not at all near the image corners).
With the camera's intrinsics both become exact: pixels are first undistorted onto the ideal
pinhole image (same K), the homography of the ideal image is decomposed into the plane's pose
(:func:`planarcal.camera.pose.plane_pose`), and a pixel's ray can then be followed to any
height above the table (:func:`planarcal.camera.pose.points_at_height`).

Conventions (as :mod:`planarcal.synth`):

* **Pixels**: OpenCV's (the centre of pixel (row i, column j) is (x, y) = (j, i)).
* **Normalised coordinates**: (x, y) = K^-1 (u, v, 1), skew included; the distortion model
  acts on them exactly as OpenCV's (radial k1..k6, tangential p1, p2, thin prism s1..s4,
  tilted sensor tauX, tauY: distortion vectors of length 4, 5, 8, 12 or 14).
* **Table coordinates** (mm): X, Y on the plane, Z = X x Y. With a board read unmirrored
  (X along the image's x, Y along its y, as :mod:`planarcal.calib.detect` orders it) Z points away
  from the camera, into the table, and the camera centre has a negative Z.

OpenCV's own point functions ignore the skew term of K and invert the distortion by a
fixed-point iteration that stops after 5 steps (0.8 px off at the corners of the webcam in
OpenCV's calibration tutorial); here the normalisation is exact, every undistorted point is
polished by Newton's method on the forward model until it reproduces its pixel to machine
precision, and is then checked to lie inside the part of the model that can be inverted (see
:meth:`CameraIntrinsics.undistort_points` and :mod:`planarcal.camera.distortion`).

The class lives here, and only here, because pickles name it by this module
(``planarcal.camera.intrinsics.CameraIntrinsics``, through ``__reduce__``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import reprlib
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planarcal import arguments
from planarcal.camera import validation
from planarcal.camera.distortion import (
    COEFF_NAMES,
    Lens,
    apply_projective,
    continuation,
    fold_free_radius,
    newton,
    opencv_guess,
    unfolded,
)
from planarcal.camera.file_storage import read_intrinsics, write_intrinsics
from planarcal.errors import ArgumentError, IntrinsicsError
from planarcal.file_formats import CALIBRATION_FORMAT

__all__ = ["MAX_IMAGE_SIDE_PX", "CameraIntrinsics"]

F64 = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

MAX_IMAGE_SIDE_PX = 1_000_000
"""The widest or tallest image any file may claim, px: far beyond any sensor (the largest
are some 20,000 px a side), so that a size of 1e18 from a corrupt file is refused, not used."""


@dataclasses.dataclass(frozen=True, eq=False)
class CameraIntrinsics:
    """A camera's intrinsic matrix K and OpenCV distortion vector, for images of one size.

    ``matrix``: [[fx, skew, cx], [0, fy, cy], [0, 0, 1]] (pixels). ``dist_coeffs``: OpenCV's
    (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tauX, tauY]]]]); (1, n) and (n, 1)
    arrays are accepted and flattened. ``image_size``: (width, height) of the images the
    intrinsics belong to (K scales with the resolution, so they hold for that size only).
    ``rms_px``, ``n_views`` and ``per_view_rms_px``: the calibration's RMS reprojection
    error, how many views it used, and each view's RMS, when it was estimated here.

    Validated on construction (IntrinsicsError naming the fault); the arrays are read-only
    copies, so an instance can be shared between threads and used as a dict key.
    """

    matrix: F64
    dist_coeffs: F64
    image_size: tuple[int, int]
    rms_px: float | None = None
    n_views: int | None = None
    per_view_rms_px: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "matrix", validation.camera_matrix(self.matrix))
        object.__setattr__(self, "dist_coeffs", validation.dist_coeffs(self.dist_coeffs))
        size = validation.image_size(self.image_size)
        if max(size) > MAX_IMAGE_SIDE_PX:
            raise IntrinsicsError(
                f"image_size {size[0]} x {size[1]} px is beyond any camera (at most "
                f"{MAX_IMAGE_SIDE_PX} px a side)"
            )
        object.__setattr__(self, "image_size", size)
        if self.rms_px is not None:
            object.__setattr__(self, "rms_px", validation.nonnegative_number("rms_px", self.rms_px))
        if self.n_views is not None:
            object.__setattr__(self, "n_views", validation.whole_number("n_views", self.n_views, 1))
        if self.per_view_rms_px is not None:
            try:
                items = list(self.per_view_rms_px)
            except TypeError:
                raise IntrinsicsError(
                    f"per_view_rms_px must be a sequence of numbers, got {self.per_view_rms_px!r}"
                ) from None
            values = tuple(
                validation.nonnegative_number(f"per_view_rms_px[{i}]", v)
                for i, v in enumerate(items)
            )
            if self.n_views is not None and len(values) != self.n_views:
                raise IntrinsicsError(
                    f"per_view_rms_px has {len(values)} values for n_views={self.n_views}"
                )
            object.__setattr__(self, "per_view_rms_px", values)
        object.__setattr__(self, "_lens", Lens.of(self.dist_coeffs))

    # -- identity --------------------------------------------------------------------------

    def _key(self) -> tuple[Any, ...]:
        return (
            self.matrix.tobytes(),
            self.dist_coeffs.tobytes(),
            self.image_size,
            self.rms_px,
            self.n_views,
            self.per_view_rms_px,
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, CameraIntrinsics):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        # Through the constructor, so a copy is validated and its arrays read-only again.
        return (
            CameraIntrinsics,
            (
                np.array(self.matrix),
                np.array(self.dist_coeffs),
                self.image_size,
                self.rms_px,
                self.n_views,
                self.per_view_rms_px,
            ),
        )

    def __repr__(self) -> str:
        rms = "" if self.rms_px is None else f", rms_px={self.rms_px:.4g}"
        views = "" if self.n_views is None else f", n_views={self.n_views}"
        skew = f", skew={self.skew:.6g}" if self.skew else ""
        return (
            f"CameraIntrinsics(fx={self.fx:.6g}, fy={self.fy:.6g}, cx={self.cx:.6g}, "
            f"cy={self.cy:.6g}{skew}, dist_coeffs={np.round(self.dist_coeffs, 6).tolist()}, "
            f"image_size={self.image_size}{rms}{views})"
        )

    # -- parts -----------------------------------------------------------------------------

    @property
    def fx(self) -> float:
        return float(self.matrix[0, 0])

    @property
    def fy(self) -> float:
        return float(self.matrix[1, 1])

    @property
    def cx(self) -> float:
        return float(self.matrix[0, 2])

    @property
    def cy(self) -> float:
        return float(self.matrix[1, 2])

    @property
    def skew(self) -> float:
        return float(self.matrix[0, 1])

    @property
    def _model(self) -> Lens:
        lens: Lens = self.__dict__["_lens"]
        return lens

    @functools.cached_property
    def _fold_free_radius(self) -> float:
        return fold_free_radius(self._model)

    def _normalise(self, px: F64) -> tuple[F64, F64]:
        """Pixels to normalised coordinates, K^-1 exactly (skew included)."""
        y = (px[:, 1] - self.cy) / self.fy
        x = (px[:, 0] - self.cx - self.skew * y) / self.fx
        return x, y

    def _pixels(self, x: F64, y: F64) -> F64:
        return np.column_stack([self.fx * x + self.skew * y + self.cx, self.fy * y + self.cy])

    # -- mappings --------------------------------------------------------------------------

    def undistort_points(self, px: ArrayLike, *, invalid: Literal["raise", "nan"] = "raise") -> F64:
        """Distorted pixel positions (..., 2) -> where the ideal pinhole camera with the same
        K would see them (..., 2): the inverse of :meth:`distort_points`.

        Each point is started from OpenCV's iterative undistortion and finished by Newton's
        method on the forward model until it reproduces its pixel to about 1e-12 of the
        normalised radius (1e-9 px), then checked to lie inside the model's valid region
        (before any fold-over, where the forward map stops being one-to-one). A point that
        cannot be inverted there raises IntrinsicsError naming it: beyond the fold a
        distorted model has either no preimage or a spurious one, and any answer would be
        wrong; with ``invalid="nan"`` such a point is NaN instead (for maps over a whole
        image, where those pixels have no place on the plane).
        """
        if invalid not in ("raise", "nan"):
            raise ArgumentError(f"invalid must be 'raise' or 'nan', got {invalid!r}")
        flat, shape = arguments.points("px", px, IntrinsicsError)
        ux, uy, ok = self._undistort(flat)
        if invalid == "nan":  # a map over the whole image: such pixels have no place
            out = self._pixels(ux, uy)
            out[~ok] = np.nan
            return out.reshape(*shape, 2)
        if not ok.all():
            k = int(np.flatnonzero(~ok)[0])
            n_bad = int((~ok).sum())
            raise IntrinsicsError(
                f"pixel {k} {flat[k].tolist()} cannot be undistorted: it lies beyond where "
                f"the lens model {self._describe_lens()} can be inverted (its fold-over, "
                "where two directions would map to one pixel)"
                + (f"; {n_bad} points in all" if n_bad > 1 else "")
                + ". The model is only valid over the part of the image its calibration "
                "views covered."
            )
        return self._pixels(ux, uy).reshape(*shape, 2)

    def _undistort(self, flat: F64) -> tuple[F64, F64, BoolArray]:
        """Undistorted normalised coordinates of pixels (N, 2), and which are valid."""
        lens = self._model
        x, y = self._normalise(flat)
        if lens.identity or flat.shape[0] == 0:
            return x, y, np.ones(x.shape, dtype=bool)
        behind = np.zeros(x.shape, dtype=bool)
        if lens.untilt is not None:
            x, y, w = apply_projective(lens.untilt, x, y)
            behind = ~(w > 0.0)
        coeffs = np.asarray(self.dist_coeffs[:12], dtype=np.float64)
        gx, gy = opencv_guess(coeffs, x, y)
        bad_guess = ~(np.isfinite(gx) & np.isfinite(gy))
        gx[bad_guess], gy[bad_guess] = x[bad_guess], y[bad_guess]
        ux, uy, ok = newton(lens, x, y, gx, gy)
        ok &= ~behind
        safe = self._fold_free_radius
        ok[ok] = unfolded(lens, ux[ok], uy[ok], safe)
        retry = np.flatnonzero(~ok & ~behind)
        if retry.size:
            rx, ry, rok = continuation(lens, x[retry], y[retry])
            rok[rok] = unfolded(lens, rx[rok], ry[rok], safe)
            ux[retry[rok]], uy[retry[rok]] = rx[rok], ry[rok]
            ok[retry[rok]] = True
        return ux, uy, ok

    def distort_points(self, ideal_px: ArrayLike) -> F64:
        """Ideal pinhole pixel positions (..., 2) -> where the real, distorting camera sees
        them (..., 2): OpenCV's forward model (as cv2.projectPoints of the normalised rays
        K^-1 p, but with K's skew honoured). Points beyond the model's fold-over (see
        :meth:`undistort_points`) raise IntrinsicsError naming the first."""
        flat, shape = arguments.points("ideal_px", ideal_px, IntrinsicsError)
        lens = self._model
        x, y = self._normalise(flat)
        if lens.identity or flat.shape[0] == 0:
            return self._pixels(x, y).reshape(*shape, 2)
        ok = unfolded(lens, x, y, self._fold_free_radius)
        if not ok.all():
            k = int(np.flatnonzero(~ok)[0])
            raise IntrinsicsError(
                f"ideal pixel {k} {flat[k].tolist()} lies beyond the fold-over of the lens "
                f"model {self._describe_lens()}: the model does not describe that direction"
            )
        xd, yd, _ = lens.distort(x, y)
        if lens.tilt is not None:
            xd, yd, _ = apply_projective(lens.tilt, xd, yd)
        return self._pixels(xd, yd).reshape(*shape, 2)

    def check_invertible_over_image(self) -> None:
        """Raise IntrinsicsError unless every pixel of the image can be undistorted.

        The pixels of the image's border are undistorted; for a model whose valid region is
        star-shaped about the principal point (any radially dominated lens) the whole image
        is then valid, since each pixel lies on a segment from the principal point to the
        border. A model fitted to views that never reached the image's corners can fold over
        before them; this says so up front rather than at the first pixel there.
        """
        w, h = self.image_size
        xs = np.arange(w, dtype=np.float64)
        ys = np.arange(h, dtype=np.float64)
        border = np.concatenate(
            [
                np.column_stack([xs, np.zeros(w)]),
                np.column_stack([xs, np.full(w, h - 1.0)]),
                np.column_stack([np.zeros(h), ys]),
                np.column_stack([np.full(h, w - 1.0), ys]),
            ]
        )
        _, _, ok = self._undistort(border)
        if not ok.all():
            first = border[int(np.flatnonzero(~ok)[0])]
            raise IntrinsicsError(
                f"the lens model {self._describe_lens()} cannot be inverted over the whole "
                f"{w} x {h} image: it folds over before {int((~ok).sum())} of the image's "
                f"border pixels, the first at ({first[0]:g}, {first[1]:g})"
            )

    def _describe_lens(self) -> str:
        terms = [f"{n}={v:.6g}" for n, v in zip(COEFF_NAMES, self.dist_coeffs, strict=False) if v]
        return "(" + (", ".join(terms) or "no distortion") + ")"

    # -- JSON ------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready description (plain lists and numbers; see from_dict)."""
        return {
            "camera_matrix": self.matrix.tolist(),
            "dist_coeffs": self.dist_coeffs.tolist(),
            "image_size_px": [self.image_size[0], self.image_size[1]],
            "rms_px": self.rms_px,
            "n_views": self.n_views,
            "per_view_rms_px": None if self.per_view_rms_px is None else list(self.per_view_rms_px),
        }

    @classmethod
    def from_dict(cls, data: Any) -> CameraIntrinsics:
        """The intrinsics described by to_dict(); IntrinsicsError naming the fault when
        ``data`` is not such a description."""
        if not isinstance(data, dict):
            raise IntrinsicsError(f"intrinsics must be a JSON object, got {type(data).__name__}")
        if data.get("format") == CALIBRATION_FORMAT:
            raise IntrinsicsError(
                "this is a planarcal calibration, not camera intrinsics: load it with "
                "Calibration.load (--calibration)"
            )
        missing = [k for k in ("camera_matrix", "dist_coeffs", "image_size_px") if k not in data]
        if missing:
            raise IntrinsicsError(f"intrinsics lack {', '.join(missing)}: got {sorted(data)}")
        matrix = _json_reals(data["camera_matrix"], 2, "camera_matrix")
        dist = _json_reals(data["dist_coeffs"], 1, "dist_coeffs")
        size = data["image_size_px"]
        if not isinstance(size, list | tuple):
            raise IntrinsicsError(
                f"image_size_px must be [width, height], got {reprlib.repr(size)}"
            )
        per_view = data.get("per_view_rms_px")
        if per_view is not None and not isinstance(per_view, list | tuple):
            raise IntrinsicsError(
                f"per_view_rms_px must be a list of numbers, got {reprlib.repr(per_view)}"
            )
        return cls(
            matrix=matrix,
            dist_coeffs=dist,
            image_size=validation.image_size(size),
            rms_px=data.get("rms_px"),
            n_views=data.get("n_views"),
            per_view_rms_px=None if per_view is None else tuple(per_view),
        )

    # -- OpenCV files ----------------------------------------------------------------------

    def save_yaml(self, path: str | os.PathLike[str]) -> Path:
        """Write the intrinsics as OpenCV's calibration sample does (``camera_matrix``,
        ``distortion_coefficients``, ``image_width``, ``image_height``, and
        ``avg_reprojection_error``, ``nr_of_frames``, ``per_view_reprojection_errors`` when
        known), atomically. The format follows the suffix: ``.xml`` XML, ``.json`` JSON,
        anything else YAML. Numbers are written with 17 significant digits, so a loaded file
        gives back exactly these intrinsics.

        The required nodes come last and the distortion vector at the very end: a file cut
        short anywhere then lacks a required node or ends inside one, and load_yaml refuses
        it instead of reading a shortened number.
        """
        return write_intrinsics(self, path)

    @classmethod
    def load_yaml(cls, path: str | os.PathLike[str]) -> CameraIntrinsics:
        """Read intrinsics from an OpenCV calibration file (YAML, XML or JSON as written by
        cv2.FileStorage): OpenCV's calibration sample's nodes ``camera_matrix``,
        ``distortion_coefficients``, ``image_width``, ``image_height`` (and
        ``avg_reprojection_error``, ``nr_of_frames``, ``per_view_reprojection_errors`` if
        present), or the common variants ``cameraMatrix`` / ``K``, ``dist_coeffs`` /
        ``distCoeffs`` / ``D``, ``image_size`` / ``imageSize`` as [width, height]. Matrices
        may be ``!!opencv-matrix`` nodes, ROS-style maps with ``rows``, ``cols``, ``data``, or
        plain (nested) lists.

        IntrinsicsError says which: no such file, a file that is not OpenCV's format
        (corrupt or truncated), or the nodes that are missing or malformed.
        """
        return read_intrinsics(path, cls)


def _json_reals(value: Any, depth: int, key: str) -> F64:
    """A JSON field of finite numbers nested `depth` deep (a list of numbers, or of such
    lists; any depth up to that is accepted, the shape is checked after), as float64;
    IntrinsicsError naming `key` if it holds anything else (a bool, a string, null, a number
    beyond a float, lists nested deeper). Walks no deeper than `depth`."""
    if isinstance(value, list | tuple) and depth > 0:
        rows = [_json_reals(v, depth - 1, key) for v in value]
        if len({r.shape for r in rows}) > 1:
            raise IntrinsicsError(f"intrinsics {key} has rows of different lengths")
        return np.array(rows, dtype=np.float64)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise IntrinsicsError(
            f"intrinsics {key} must be (lists of) numbers, got {reprlib.repr(value)}"
        )
    try:
        number = float(value)
    except OverflowError:
        raise IntrinsicsError(f"intrinsics {key} holds a number beyond a float's range") from None
    if not math.isfinite(number):
        raise IntrinsicsError(f"intrinsics {key} holds {number}: numbers must be finite")
    return np.array(number)
