//! The plane seen through a lens (planarcal_core::plane_model): a fitted model that maps
//! pixels to the plane with their uncertainty, and its leave-one-out predictions.

use nalgebra::Matrix2;
use numpy::{PyArray1, PyArrayMethods};
use planarcal_core::{
    fit_plane, leave_one_out, plane_fit_at, predicted_loo_covariance, world_covariance,
    InversePlane, LensParams, MapFailure, PlaneFit, PlaneModel, Point, RadialLens,
};
use pyo3::prelude::*;

use crate::convert::{matrix3, points2};
use crate::errors::{invalid, lens_to_py, no_place, LensModelError};
use crate::estimate::matrix_out;
use crate::transform::{maybe_detach, on_invalid, OnInvalid};

/// A homography from the plane (mm) to ideal pixels and a radial lens, fitted to points.
#[pyclass(frozen, module = "planarcal._core")]
pub struct FittedPlane {
    fit: PlaneFit,
    inverse: InversePlane,
    world: Vec<Point>,
    image: Vec<Point>,
}

fn lens_params(name: &str) -> PyResult<LensParams> {
    LensParams::from_name(name).ok_or_else(|| {
        invalid(format!(
            "lens must be one of \"none\", \"k1\", \"k1k2\", \"k1k2c\", got {name:?}"
        ))
    })
}

fn size(image_size: (f64, f64)) -> [f64; 2] {
    [image_size.0, image_size.1]
}

fn pairs(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<Point>> {
    Ok(points2(obj, name)?.as_points().to_vec())
}

fn array2<'py>(py: Python<'py>, rows: Vec<f64>, cols: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    let mut shape = vec![rows.len() / cols.iter().product::<usize>()];
    shape.extend_from_slice(cols);
    Ok(PyArray1::from_vec(py, rows).reshape(shape)?.into_any())
}

fn map_error(failure: MapFailure, index: usize, failed: usize, total: usize) -> PyErr {
    let message = format!(
        "{failed} of {total} pixels have no place on the plane; the first is point {index}, \
         which {}",
        failure.describe()
    );
    no_place(failure, index, message)
}

impl FittedPlane {
    fn new(fit: PlaneFit, world: Vec<Point>, image: Vec<Point>, size: [f64; 2]) -> PyResult<Self> {
        let inverse = InversePlane::new(&fit.model)
            .map_err(lens_to_py)?
            .within_image(size[0], size[1]);
        Ok(FittedPlane {
            fit,
            inverse,
            world,
            image,
        })
    }

    /// The world points of pixels whose uncertainty is asked for: checks pixel_sigma and that
    /// the fit has residual degrees of freedom, and raises for pixels that cannot be mapped.
    fn map_for_uncertainty(
        &self,
        py: Python<'_>,
        px: &Bound<'_, PyAny>,
        pixel_sigma: f64,
    ) -> PyResult<Vec<f64>> {
        if !(pixel_sigma >= 0.0 && pixel_sigma.is_finite()) {
            return Err(invalid(format!(
                "pixel_sigma must be a finite number >= 0, got {pixel_sigma}"
            )));
        }
        if self.fit.dof == 0 {
            return Err(LensModelError::new_err(
                "the fit has no residual degrees of freedom (as many parameters as \
                 coordinates), so its uncertainty cannot be estimated: use more points",
            ));
        }
        let pts = points2(px, "px")?;
        let pts = pts.as_points();
        let (world, first, failed) = maybe_detach(py, pts.len(), || self.map_all(pts));
        if let Some((i, f)) = first {
            return Err(map_error(f, i, failed, pts.len()));
        }
        Ok(world)
    }

    /// Maps pixels to world points, with the failures' first index and count.
    fn map_all(&self, px: &[Point]) -> (Vec<f64>, Option<(usize, MapFailure)>, usize) {
        let mut out = Vec::with_capacity(2 * px.len());
        let (mut first, mut failed) = (None, 0);
        for (i, d) in px.iter().enumerate() {
            match self.inverse.map(*d) {
                Ok(w) => out.extend_from_slice(&w),
                Err(f) => {
                    failed += 1;
                    first = first.or(Some((i, f)));
                    out.extend_from_slice(&[f64::NAN, f64::NAN]);
                }
            }
        }
        (out, first, failed)
    }
}

#[pymethods]
impl FittedPlane {
    /// fit(world, image, lens, image_size)
    /// --
    ///
    /// Fits H and the lens parameters named by `lens` ("none", "k1", "k1k2", "k1k2c").
    #[staticmethod]
    fn fit(
        py: Python<'_>,
        world: &Bound<'_, PyAny>,
        image: &Bound<'_, PyAny>,
        lens: &str,
        image_size: (f64, f64),
    ) -> PyResult<Self> {
        let free = lens_params(lens)?;
        let (w, d) = (pairs(world, "world")?, pairs(image, "image")?);
        let fit = py
            .detach(|| fit_plane(&w, &d, free, size(image_size)))
            .map_err(lens_to_py)?;
        FittedPlane::new(fit, w, d, size(image_size))
    }

    /// at(h, lens_centre, lens_scale, k1, k2, world, image, lens, image_size)
    /// --
    ///
    /// A model with given parameters (read back from a file) and its figures on the points.
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn at(
        h: &Bound<'_, PyAny>,
        lens_centre: (f64, f64),
        lens_scale: f64,
        k1: f64,
        k2: f64,
        world: &Bound<'_, PyAny>,
        image: &Bound<'_, PyAny>,
        lens: &str,
        image_size: (f64, f64),
    ) -> PyResult<Self> {
        let free = lens_params(lens)?;
        let model = PlaneModel {
            h: matrix3(h, "h")?,
            lens: RadialLens {
                centre: [lens_centre.0, lens_centre.1],
                scale: lens_scale,
                k1,
                k2,
            },
        };
        let (w, d) = (pairs(world, "world")?, pairs(image, "image")?);
        let fit = plane_fit_at(&model, &w, &d, free, size(image_size)).map_err(lens_to_py)?;
        FittedPlane::new(fit, w, d, size(image_size))
    }

    /// World (mm) -> ideal pixels, 3 x 3, oriented.
    #[getter]
    fn homography<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        matrix_out(py, &self.fit.model.h).into_any()
    }

    /// (centre_x, centre_y, scale, k1, k2) of the lens, px.
    #[getter]
    fn lens(&self) -> (f64, f64, f64, f64, f64) {
        let l = self.fit.model.lens;
        (l.centre[0], l.centre[1], l.scale, l.k1, l.k2)
    }

    /// The free lens parameters' name.
    #[getter]
    fn lens_params(&self) -> &'static str {
        self.fit.free.name()
    }

    /// Standard deviations of (k1, k2, centre_x, centre_y) from the covariance (0 if fixed).
    #[getter]
    fn lens_std(&self) -> (f64, f64, f64, f64) {
        let c = self.fit.covariance();
        let s = self.fit.params.frame.scale;
        (
            c[(8, 8)].sqrt(),
            c[(9, 9)].sqrt(),
            s * c[(10, 10)].sqrt(),
            s * c[(11, 11)].sqrt(),
        )
    }

    /// Sum of squared residuals, px^2.
    #[getter]
    fn cost(&self) -> f64 {
        self.fit.cost
    }

    /// Residual degrees of freedom, 2 n - parameters.
    #[getter]
    fn dof(&self) -> usize {
        self.fit.dof
    }

    /// Residual standard deviation per coordinate, px (NaN with no degrees of freedom).
    #[getter]
    fn sigma(&self) -> f64 {
        self.fit.sigma()
    }

    #[getter]
    fn iterations(&self) -> usize {
        self.fit.iterations
    }

    /// image_to_world(px, invalid="raise")
    /// --
    ///
    /// Pixels (N x 2) -> plane (N x 2, mm): undistort, then H^-1.
    #[pyo3(signature = (px, invalid = "raise"))]
    fn image_to_world<'py>(
        &self,
        py: Python<'py>,
        px: &Bound<'py, PyAny>,
        invalid: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let mode = on_invalid(invalid, "nan")?;
        let pts = points2(px, "px")?;
        let pts = pts.as_points();
        let (out, first, failed) = maybe_detach(py, pts.len(), || self.map_all(pts));
        if let (OnInvalid::Raise, Some((i, f))) = (mode, first) {
            return Err(map_error(f, i, failed, pts.len()));
        }
        array2(py, out, &[2])
    }

    /// world_to_image(mm)
    /// --
    ///
    /// Plane (N x 2, mm) -> pixels (N x 2), lens included; NaN for points not in front.
    fn world_to_image<'py>(
        &self,
        py: Python<'py>,
        mm: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let pts = points2(mm, "mm")?;
        let pts = pts.as_points();
        let m = self.fit.model;
        let out: Vec<f64> = maybe_detach(py, pts.len(), || {
            pts.iter()
                .flat_map(|w| m.world_to_image(*w).unwrap_or([f64::NAN; 2]))
                .collect()
        });
        array2(py, out, &[2])
    }

    /// world_covariance(px, pixel_sigma=0.0)
    /// --
    ///
    /// Covariance (N x 2 x 2, mm^2) of the plane points the pixels map to: the fit's
    /// uncertainty, plus the pixels' own noise of pixel_sigma px per coordinate.
    #[pyo3(signature = (px, pixel_sigma = 0.0))]
    fn world_covariance<'py>(
        &self,
        py: Python<'py>,
        px: &Bound<'py, PyAny>,
        pixel_sigma: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let world = self.map_for_uncertainty(py, px, pixel_sigma)?;
        let fit = &self.fit;
        let out: Vec<f64> = maybe_detach(py, world.len() / 2, || {
            world
                .chunks_exact(2)
                .flat_map(|w| {
                    let c = world_covariance(fit, [w[0], w[1]], pixel_sigma)
                        .unwrap_or(Matrix2::from_element(f64::NAN));
                    [c[(0, 0)], c[(0, 1)], c[(1, 0)], c[(1, 1)]]
                })
                .collect()
        });
        array2(py, out, &[2, 2])
    }

    /// image_to_world_std(px, pixel_sigma=0.0)
    /// --
    ///
    /// (mm (N x 2), std_mm (N,)) in one pass: each pixel's place on the plane and its
    /// 1-sigma error (sqrt of the covariance's trace); raises like image_to_world.
    #[pyo3(signature = (px, pixel_sigma = 0.0))]
    fn image_to_world_std<'py>(
        &self,
        py: Python<'py>,
        px: &Bound<'py, PyAny>,
        pixel_sigma: f64,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let world = self.map_for_uncertainty(py, px, pixel_sigma)?;
        let fit = &self.fit;
        let std: Vec<f64> = maybe_detach(py, world.len() / 2, || {
            world
                .chunks_exact(2)
                .map(|w| {
                    world_covariance(fit, [w[0], w[1]], pixel_sigma)
                        .map_or(f64::NAN, |c| c.trace().sqrt())
                })
                .collect()
        });
        Ok((
            array2(py, world, &[2])?,
            PyArray1::from_vec(py, std).into_any(),
        ))
    }

    /// leave_one_out()
    /// --
    ///
    /// (image_px, world_mm), each N x 2: point i under the fit without it, its world point
    /// in the image and its measured pixel on the plane (NaN where the rest cannot be fitted).
    fn leave_one_out<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let loo = py.detach(|| leave_one_out(&self.fit, &self.world, &self.image));
        let image: Vec<f64> = loo.iter().flat_map(|p| p.image_px).collect();
        let world: Vec<f64> = loo.iter().flat_map(|p| p.world_mm).collect();
        Ok((array2(py, image, &[2])?, array2(py, world, &[2])?))
    }

    /// predicted_loo_covariance()
    /// --
    ///
    /// N x 2 x 2 (mm^2): the covariance each point's leave-one-out error should have if the
    /// model is right and the residuals are its noise.
    fn predicted_loo_covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        if self.fit.dof == 0 {
            return Err(LensModelError::new_err(
                "the fit has no residual degrees of freedom: use more points",
            ));
        }
        let out: Vec<f64> = predicted_loo_covariance(&self.fit, &self.world)
            .into_iter()
            .flat_map(|c| {
                let c = c.unwrap_or(Matrix2::from_element(f64::NAN));
                [c[(0, 0)], c[(0, 1)], c[(1, 0)], c[(1, 1)]]
            })
            .collect();
        array2(py, out, &[2, 2])
    }

    /// undistort(px)
    /// --
    ///
    /// Real pixels (N x 2) -> ideal pixels; NaN beyond the model's valid radius.
    fn undistort<'py>(
        &self,
        py: Python<'py>,
        px: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let pts = points2(px, "px")?;
        let lens = self.fit.model.lens;
        let out: Vec<f64> = pts
            .as_points()
            .iter()
            .flat_map(|d| lens.undistort(*d).unwrap_or([f64::NAN; 2]))
            .collect();
        array2(py, out, &[2])
    }

    /// distort(px)
    /// --
    ///
    /// Ideal pixels (N x 2) -> the real pixels the lens shows them at.
    fn distort<'py>(&self, py: Python<'py>, px: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let pts = points2(px, "px")?;
        let lens = self.fit.model.lens;
        let out: Vec<f64> = pts
            .as_points()
            .iter()
            .flat_map(|u| lens.distort(*u))
            .collect();
        array2(py, out, &[2])
    }

    /// The largest distance from the lens centre (px) the model can undistort.
    #[getter]
    fn valid_radius(&self) -> f64 {
        self.fit.model.lens.valid_radius()
    }
}
