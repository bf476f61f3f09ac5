//! The radial lens (planarcal_core::RadialLens) as one Python class: its parameters, where it
//! shows an ideal pixel (distort) and back (undistort), and how far out it can be inverted.
//! The maths is the core's; this only validates, borrows, releases the GIL and converts.

use planarcal_core::{Point, RadialLens as CoreLens};
use pyo3::prelude::*;
use pyo3::types::{PyTuple, PyType};

use crate::convert::points2;
use crate::errors::{invalid_arg, lens_to_py};
use crate::transform::{new_array, on_invalid, OnInvalid};

/// A two-term radial lens about a centre: the ideal (pinhole) pixel u is shown at
/// d = c + (u - c) (1 + k1 rho^2 + k2 rho^4), rho = |u - c| / scale (OpenCV's k1, k2 when
/// the scale is the focal length in px and the centre the principal point).
#[pyclass(frozen, eq, module = "planarcal._core", name = "RadialLens")]
#[derive(Clone, Copy, PartialEq)]
pub struct RadialLens {
    pub lens: CoreLens,
}

impl RadialLens {
    /// A checked lens (finite parameters, positive scale).
    pub fn checked(lens: CoreLens) -> PyResult<Self> {
        lens.validate().map_err(lens_to_py)?;
        Ok(RadialLens { lens })
    }
}

#[pymethods]
impl RadialLens {
    #[new]
    #[pyo3(signature = (centre_px, scale_px, k1 = 0.0, k2 = 0.0))]
    fn py_new(centre_px: (f64, f64), scale_px: f64, k1: f64, k2: f64) -> PyResult<Self> {
        RadialLens::checked(CoreLens {
            centre: [centre_px.0, centre_px.1],
            scale: scale_px,
            k1,
            k2,
        })
    }

    /// identity(width, height)
    /// --
    ///
    /// No distortion, centred on a width x height image, the half-diagonal its scale.
    #[classmethod]
    fn identity(_cls: &Bound<'_, PyType>, width: f64, height: f64) -> PyResult<Self> {
        CoreLens::identity(width, height)
            .map(|lens| RadialLens { lens })
            .map_err(lens_to_py)
    }

    /// The distortion centre (x, y), px.
    #[getter]
    fn centre_px(&self) -> (f64, f64) {
        (self.lens.centre[0], self.lens.centre[1])
    }

    /// The radius unit, px.
    #[getter]
    fn scale_px(&self) -> f64 {
        self.lens.scale
    }

    /// The rho^2 coefficient.
    #[getter]
    fn k1(&self) -> f64 {
        self.lens.k1
    }

    /// The rho^4 coefficient.
    #[getter]
    fn k2(&self) -> f64 {
        self.lens.k2
    }

    /// The ideal radius, in units of ``scale_px``, where the radial map stops increasing
    /// (the lens folds over beyond it), or infinity when it never does.
    #[getter]
    fn fold_radius(&self) -> f64 {
        self.lens.fold_radius()
    }

    /// The largest distance from the centre (px) of a real pixel the lens can undistort
    /// (the fold seen in the image), or infinity.
    #[getter]
    fn valid_radius(&self) -> f64 {
        self.lens.valid_radius()
    }

    /// distort(ideal_px)
    /// --
    ///
    /// Ideal pixels (N x 2) -> the real pixels (N x 2) the lens shows them at.
    fn distort<'py>(
        &self,
        py: Python<'py>,
        ideal_px: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let pts = points2(ideal_px, "ideal_px")?;
        let src = pts.as_points();
        let n = src.len();
        let lens = self.lens;
        let (out, ()) = new_array::<f64, _>(py, &[n, 2], 2 * n, n, |o| {
            lens.distort_all(src, o.as_chunks_mut::<2>().0)
        })?;
        Ok(out.into_any())
    }

    /// undistort(px, invalid="raise")
    /// --
    ///
    /// Real pixels (N x 2) -> ideal pixels (N x 2). A pixel beyond the valid radius (or not
    /// finite) has none: invalid="raise" raises for the first (LensModelError beyond the
    /// radius, ArgumentError for a non-finite one), invalid="nan" leaves it NaN.
    #[pyo3(signature = (px, invalid = "raise"))]
    fn undistort<'py>(
        &self,
        py: Python<'py>,
        px: &Bound<'py, PyAny>,
        invalid: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let mode = on_invalid(invalid, "nan")?;
        let pts = points2(px, "px")?;
        let src = pts.as_points();
        let n = src.len();
        let lens = self.lens;
        let (out, (_, first)) = new_array::<f64, _>(py, &[n, 2], 2 * n, n, |o| {
            lens.undistort_all(src, o.as_chunks_mut::<2>().0)
        })?;
        if let (OnInvalid::Raise, Some(i)) = (mode, first) {
            let d: Point = src[i];
            if !(d[0].is_finite() && d[1].is_finite()) {
                return Err(invalid_arg(
                    "px",
                    format!("px: point {i} ({}, {}) is not finite", d[0], d[1]),
                ));
            }
            return Err(lens_to_py(lens.outside(i, d)));
        }
        Ok(out.into_any())
    }

    fn __repr__(&self) -> String {
        let l = &self.lens;
        format!(
            "RadialLens(centre_px=({:?}, {:?}), scale_px={:?}, k1={:?}, k2={:?})",
            l.centre[0], l.centre[1], l.scale, l.k1, l.k2
        )
    }

    /// Pickling: the class and the constructor's arguments.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyType>, Bound<'py, PyTuple>)> {
        let l = slf.get().lens;
        let args = ((l.centre[0], l.centre[1]), l.scale, l.k1, l.k2);
        Ok((slf.get_type(), args.into_pyobject(slf.py())?))
    }
}

/// The standard deviations of a fitted lens's parameters (0 for those held fixed).
#[pyclass(frozen, eq, module = "planarcal._core", name = "LensStd")]
#[derive(Clone, Copy, PartialEq)]
pub struct LensStd {
    /// k1's.
    #[pyo3(get)]
    pub k1: f64,
    /// k2's.
    #[pyo3(get)]
    pub k2: f64,
    /// The centre's (x, y), px.
    #[pyo3(get)]
    pub centre_px: (f64, f64),
}

#[pymethods]
impl LensStd {
    #[new]
    #[pyo3(signature = (k1, k2, centre_px))]
    fn py_new(k1: f64, k2: f64, centre_px: (f64, f64)) -> Self {
        LensStd { k1, k2, centre_px }
    }

    fn __repr__(&self) -> String {
        format!(
            "LensStd(k1={:?}, k2={:?}, centre_px=({:?}, {:?}))",
            self.k1, self.k2, self.centre_px.0, self.centre_px.1
        )
    }

    /// Pickling: the class and the constructor's arguments.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyType>, Bound<'py, PyTuple>)> {
        let s = slf.get();
        let args = (s.k1, s.k2, s.centre_px);
        Ok((slf.get_type(), args.into_pyobject(slf.py())?))
    }
}
