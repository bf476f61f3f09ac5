//! The plane seen through a lens (planarcal_core::plane_model): a fitted model that maps
//! pixels to the plane with their uncertainty (planarcal_core::FittedMapper: the fast mapper
//! and the fit's covariance), and its leave-one-out predictions.

use nalgebra::Matrix2;
use numpy::{PyArray1, PyArrayMethods};
use planarcal_core::{
    fit_placements, fit_plane, leave_one_out, placements_fit_at, plane_fit_at,
    predicted_loo_covariance, try_collect, FittedMapper, LensParams, Placed, PlacementsFit,
    PlaneFit, PlaneModel, Point, PointReport, Pose, UncertaintyError,
};
use pyo3::prelude::*;

use crate::convert::{matrix3, points2};
use crate::errors::{invalid, lens_to_py, no_place, to_py, LensModelError};
use crate::estimate::matrix_out;
use crate::lens::{LensStd, RadialLens as PyLens};
use crate::transform::{maybe_detach, new_array, on_invalid, OnInvalid};

/// A homography from the plane (mm) to ideal pixels and a radial lens, fitted to points.
#[pyclass(frozen, module = "planarcal._core")]
pub struct FittedPlane {
    /// The fit, and the fast mapper of its model over the image it was fitted on.
    mapping: FittedMapper,
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

type PlacementsOut<'py> = (
    Bound<'py, FittedPlane>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
);

/// The placements of a problem, checked: one per point, each below `count`.
fn placement_indices(placement: Vec<i64>, n: usize, count: usize) -> PyResult<Vec<usize>> {
    if placement.len() != n {
        return Err(invalid(format!(
            "placement must give one placement per point ({n}), got {}",
            placement.len()
        )));
    }
    placement
        .into_iter()
        .map(|k| {
            usize::try_from(k)
                .ok()
                .filter(|&k| k < count)
                .ok_or_else(|| invalid(format!("placement {k} is not one of 0 .. {count}")))
        })
        .collect()
}

fn poses_in(poses: Vec<(f64, f64, f64)>) -> PyResult<Vec<Pose>> {
    poses
        .into_iter()
        .map(|(angle, x, y)| {
            if angle.is_finite() && x.is_finite() && y.is_finite() {
                Ok(Pose {
                    angle,
                    offset: [x, y],
                })
            } else {
                Err(invalid(format!(
                    "a pose must be finite, got ({angle}, {x}, {y})"
                )))
            }
        })
        .collect()
}

fn uncertainty_to_py(e: UncertaintyError) -> PyErr {
    match e {
        UncertaintyError::InvalidPixelSigma(_) | UncertaintyError::InvalidModelSigma(_) => {
            invalid(e.to_string())
        }
        UncertaintyError::NoResidualDof => LensModelError::new_err(e.to_string()),
    }
}

impl FittedPlane {
    /// Every FittedPlane has an image size (`fit` and `at` take one): the mapper refuses
    /// pixels beyond it as the lens model's, and checks its lens inverse over it. A calibration
    /// without one passes a box around its points with an ideal lens, which maps every pixel
    /// through H^-1 alone: the box then bounds nothing, on either path.
    fn new(fit: PlaneFit, world: Vec<Point>, image: Vec<Point>, size: [f64; 2]) -> PyResult<Self> {
        Ok(FittedPlane {
            mapping: FittedMapper::new(fit, size).map_err(lens_to_py)?,
            world,
            image,
        })
    }

    /// The plane of a placements fit, with its poses (K x 3: angle rad, offset x, y mm) and
    /// their covariances (K x 3 x 3).
    fn placements_out<'py>(
        py: Python<'py>,
        fit: PlacementsFit,
        image: Vec<Point>,
        size: [f64; 2],
    ) -> PyResult<PlacementsOut<'py>> {
        let poses: Vec<f64> = fit
            .poses
            .iter()
            .flat_map(|p| [p.angle, p.offset[0], p.offset[1]])
            .collect();
        let cov: Vec<f64> = fit
            .pose_covariance
            .iter()
            .flat_map(|c| c.transpose().iter().copied().collect::<Vec<_>>())
            .collect();
        let plane = FittedPlane::new(fit.fit, fit.plane_points, image, size)?;
        Ok((
            Bound::new(py, plane)?,
            array2(py, poses, &[3])?,
            array2(py, cov, &[3, 3])?,
        ))
    }

    fn plane_fit(&self) -> &PlaneFit {
        self.mapping.fit()
    }

    /// Pixels -> (N x 2 mm, the N values `map` writes beside them), raising for pixels with
    /// no place on the plane; `map` is the core's, run with the GIL released for large
    /// batches.
    fn map_with<'py, T: Send + Clone>(
        &self,
        py: Python<'py>,
        px: &Bound<'py, PyAny>,
        pixel_sigma: f64,
        fill: T,
        map: impl FnOnce(
                &FittedMapper,
                &[Point],
                &mut [Point],
                &mut [T],
            ) -> Result<PointReport, UncertaintyError>
            + Send,
    ) -> PyResult<(Vec<f64>, Vec<T>)> {
        // Checked before the pixels, as always.
        self.mapping
            .check_uncertainty(pixel_sigma)
            .map_err(uncertainty_to_py)?;
        let pts = points2(px, "px")?;
        let pts = pts.as_points();
        let n = pts.len();
        let (mut world, mut extra) = (vec![[f64::NAN; 2]; n], vec![fill; n]);
        let report = maybe_detach(py, n, || map(&self.mapping, pts, &mut world, &mut extra))
            .map_err(uncertainty_to_py)?;
        if let Some(e) = no_place(&report, n) {
            return Err(e);
        }
        Ok((world.into_flattened(), extra))
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

    /// at(h, lens, world, image, free, image_size)
    /// --
    ///
    /// A model with given parameters (read back from a file): H and the lens (a RadialLens),
    /// with its figures on the points; `free` names the lens parameters counted as fitted.
    #[staticmethod]
    fn at(
        h: &Bound<'_, PyAny>,
        lens: &Bound<'_, PyLens>,
        world: &Bound<'_, PyAny>,
        image: &Bound<'_, PyAny>,
        free: &str,
        image_size: (f64, f64),
    ) -> PyResult<Self> {
        let free = lens_params(free)?;
        let model = PlaneModel {
            h: matrix3(h, "h")?,
            lens: lens.get().lens,
        };
        let (w, d) = (pairs(world, "world")?, pairs(image, "image")?);
        let fit = plane_fit_at(&model, &w, &d, free, size(image_size)).map_err(lens_to_py)?;
        FittedPlane::new(fit, w, d, size(image_size))
    }

    /// fit_placements(board, image, placement, reference, start, lens, image_size)
    /// --
    ///
    /// Fits H, the lens parameters named by `lens` and the in-plane pose of every placement
    /// of a board: `board` (N x 2, mm in each placement's board frame), `image` (N x 2, px),
    /// `placement` (N, the placement of each point), `start` (K x 3: angle rad, offset x, y
    /// mm, from which each pose is solved). The plane's frame is placement `reference`'s.
    /// Returns (the plane on the points in the plane's frame, poses K x 3, their covariances
    /// K x 3 x 3).
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn fit_placements<'py>(
        py: Python<'py>,
        board: &Bound<'py, PyAny>,
        image: &Bound<'py, PyAny>,
        placement: Vec<i64>,
        reference: usize,
        start: Vec<(f64, f64, f64)>,
        lens: &str,
        image_size: (f64, f64),
    ) -> PyResult<PlacementsOut<'py>> {
        let free = lens_params(lens)?;
        let (b, d) = (pairs(board, "board")?, pairs(image, "image")?);
        let start = poses_in(start)?;
        let placement = placement_indices(placement, b.len(), start.len())?;
        let placed = Placed {
            board: &b,
            image: &d,
            placement: &placement,
            count: start.len(),
            reference,
        };
        let fit = py
            .detach(|| fit_placements(placed, &start, free, size(image_size)))
            .map_err(lens_to_py)?;
        FittedPlane::placements_out(py, fit, d, size(image_size))
    }

    /// at_placements(h, lens, board, image, placement, reference, poses, free, image_size)
    /// --
    ///
    /// fit_placements' result at given parameters and poses (read back from a file).
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn at_placements<'py>(
        py: Python<'py>,
        h: &Bound<'py, PyAny>,
        lens: &Bound<'py, PyLens>,
        board: &Bound<'py, PyAny>,
        image: &Bound<'py, PyAny>,
        placement: Vec<i64>,
        reference: usize,
        poses: Vec<(f64, f64, f64)>,
        free: &str,
        image_size: (f64, f64),
    ) -> PyResult<PlacementsOut<'py>> {
        let free = lens_params(free)?;
        let model = PlaneModel {
            h: matrix3(h, "h")?,
            lens: lens.get().lens,
        };
        let (b, d) = (pairs(board, "board")?, pairs(image, "image")?);
        let poses = poses_in(poses)?;
        let placement = placement_indices(placement, b.len(), poses.len())?;
        let placed = Placed {
            board: &b,
            image: &d,
            placement: &placement,
            count: poses.len(),
            reference,
        };
        let fit = placements_fit_at(&model, &poses, placed, free, size(image_size))
            .map_err(lens_to_py)?;
        FittedPlane::placements_out(py, fit, d, size(image_size))
    }

    /// with_model_sigma(sigma_px)
    /// --
    ///
    /// This plane with the model's bias of sigma_px px per coordinate: every uncertainty it
    /// gives (image_to_world_std, world_covariance) adds it to the pixels' own noise in
    /// quadrature. Positions are unchanged.
    fn with_model_sigma(&self, sigma_px: f64) -> PyResult<Self> {
        Ok(FittedPlane {
            mapping: self
                .mapping
                .clone()
                .with_model_sigma(sigma_px)
                .map_err(uncertainty_to_py)?,
            world: self.world.clone(),
            image: self.image.clone(),
        })
    }

    /// The model's bias its uncertainties include, px per coordinate (0 unless set by
    /// with_model_sigma).
    #[getter]
    fn model_sigma_px(&self) -> f64 {
        self.mapping.model_sigma()
    }

    /// World (mm) -> ideal pixels, 3 x 3, oriented.
    #[getter]
    fn homography<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        matrix_out(py, &self.plane_fit().model.h).into_any()
    }

    /// The lens: where it shows an ideal pixel, and back.
    #[getter]
    fn lens(&self) -> PyLens {
        PyLens {
            lens: self.plane_fit().model.lens,
        }
    }

    /// The free lens parameters' name.
    #[getter]
    fn lens_params(&self) -> &'static str {
        self.plane_fit().free.name()
    }

    /// How image_to_world inverts the lens: a description of the checked polynomial (or
    /// Newton's method, or none for an ideal lens).
    #[getter]
    fn lens_inverse(&self) -> String {
        self.mapping.mapper().undistortion().describe()
    }

    /// The standard deviations of the lens's parameters, from the covariance (0 if fixed).
    #[getter]
    fn lens_std(&self) -> LensStd {
        let c = self.plane_fit().covariance();
        let s = self.plane_fit().params.frame.scale;
        LensStd {
            k1: c[(8, 8)].sqrt(),
            k2: c[(9, 9)].sqrt(),
            centre_px: (s * c[(10, 10)].sqrt(), s * c[(11, 11)].sqrt()),
        }
    }

    /// Sum of squared residuals, px^2.
    #[getter]
    fn cost(&self) -> f64 {
        self.plane_fit().cost
    }

    /// Residual degrees of freedom, 2 n - parameters.
    #[getter]
    fn dof(&self) -> usize {
        self.plane_fit().dof
    }

    /// Residual standard deviation per coordinate, px (NaN with no degrees of freedom).
    #[getter]
    fn sigma(&self) -> f64 {
        self.plane_fit().sigma()
    }

    #[getter]
    fn iterations(&self) -> usize {
        self.plane_fit().iterations
    }

    /// image_to_world(px, invalid="raise")
    /// --
    ///
    /// Pixels (N x 2) -> plane (N x 2, mm): undistort, then H^-1, by the fast mapper. Pixels
    /// with no place on the plane are NaN; invalid="raise" then raises, naming the first.
    #[pyo3(signature = (px, invalid = "raise"))]
    fn image_to_world<'py>(
        &self,
        py: Python<'py>,
        px: &Bound<'py, PyAny>,
        invalid: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let mode = on_invalid(invalid, "nan")?;
        let pts = points2(px, "px")?;
        let src = pts.as_points();
        let n = src.len();
        let mapping = &self.mapping;
        let (out, report) = new_array::<f64, _>(py, &[n, 2], 2 * n, n, |o| {
            mapping.map_into(src, o.as_chunks_mut::<2>().0)
        })?;
        if mode == OnInvalid::Raise {
            if let Some(e) = no_place(&report, n) {
                return Err(e);
            }
        }
        Ok(out.into_any())
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
        let m = self.plane_fit().model;
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
    /// uncertainty, plus the pixels' own noise of pixel_sigma px per coordinate and the
    /// model's bias (model_sigma_px), in quadrature.
    #[pyo3(signature = (px, pixel_sigma = 0.0))]
    fn world_covariance<'py>(
        &self,
        py: Python<'py>,
        px: &Bound<'py, PyAny>,
        pixel_sigma: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (_, cov) = self.map_with(py, px, pixel_sigma, [0.0; 4], |m, px, out, cov| {
            m.map_with_covariance_into(px, pixel_sigma, out, cov)
        })?;
        array2(py, cov.into_flattened(), &[2, 2])
    }

    /// image_to_world_std(px, pixel_sigma=0.0)
    /// --
    ///
    /// (mm (N x 2), std_mm (N,)) in one pass: each pixel's place on the plane and its
    /// 1-sigma error (sqrt of world_covariance's trace); raises like image_to_world.
    #[pyo3(signature = (px, pixel_sigma = 0.0))]
    fn image_to_world_std<'py>(
        &self,
        py: Python<'py>,
        px: &Bound<'py, PyAny>,
        pixel_sigma: f64,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let (world, std) = self.map_with(py, px, pixel_sigma, 0.0, |m, px, out, std| {
            m.map_with_std_into(px, pixel_sigma, out, std)
        })?;
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
        let loo = py
            .detach(|| leave_one_out(self.plane_fit(), &self.world, &self.image))
            .map_err(to_py)?;
        let image = try_collect(loo.iter().flat_map(|p| p.image_px)).map_err(to_py)?;
        let world = try_collect(loo.iter().flat_map(|p| p.world_mm)).map_err(to_py)?;
        Ok((array2(py, image, &[2])?, array2(py, world, &[2])?))
    }

    /// predicted_loo_covariance()
    /// --
    ///
    /// N x 2 x 2 (mm^2): the covariance each point's leave-one-out error should have if the
    /// model is right and the residuals are its noise.
    fn predicted_loo_covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        if self.plane_fit().dof == 0 {
            return Err(LensModelError::new_err(
                "the fit has no residual degrees of freedom: use more points",
            ));
        }
        let covariances = predicted_loo_covariance(self.plane_fit(), &self.world).map_err(to_py)?;
        let out = try_collect(covariances.into_iter().flat_map(|c| {
            let c = c.unwrap_or(Matrix2::from_element(f64::NAN));
            [c[(0, 0)], c[(0, 1)], c[(1, 0)], c[(1, 1)]]
        }))
        .map_err(to_py)?;
        array2(py, out, &[2, 2])
    }
}
