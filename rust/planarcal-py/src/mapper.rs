//! The production loop's mapper (planarcal_core::mapper): a frame's pixels to the plane in
//! one call, into a fresh array or one the caller keeps.

use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use planarcal_core::{MapReport, PlaneMapper as CoreMapper, PlaneModel, RadialLens, Undistortion};
use pyo3::intern;
use pyo3::prelude::*;

use crate::convert::{matrix3, points2};
use crate::errors::{invalid, lens_to_py, no_place};
use crate::estimate::matrix_out;
use crate::plane_model::FittedPlane;
use crate::transform::{maybe_detach, new_array, on_invalid, OnInvalid};

/// Pixels -> plane (mm) through a fitted plane, fast: the same answers as
/// FittedPlane.image_to_world, with the lens inverse precomputed.
#[pyclass(frozen, module = "planarcal._core")]
pub struct PlaneMapper {
    inner: CoreMapper,
}

fn build(model: PlaneModel, image_size: (f64, f64)) -> PyResult<PlaneMapper> {
    let inner = CoreMapper::new(&model, [image_size.0, image_size.1]).map_err(lens_to_py)?;
    Ok(PlaneMapper { inner })
}

fn model(h: nalgebra::Matrix3<f64>, lens: (f64, f64, f64, f64, f64)) -> PlaneModel {
    let (cx, cy, scale, k1, k2) = lens;
    PlaneModel {
        h,
        lens: RadialLens {
            centre: [cx, cy],
            scale,
            k1,
            k2,
        },
    }
}

/// The error for a batch in which some pixels have no place on the plane (the same words as
/// FittedPlane.image_to_world).
fn map_error(report: &MapReport, total: usize) -> Option<PyErr> {
    let (index, failure) = report.first?;
    let message = format!(
        "{} of {total} pixels have no place on the plane; the first is point {index}, which {}",
        report.invalid(),
        failure.describe()
    );
    Some(no_place(failure, index, message))
}

fn dtype_name(obj: &Bound<'_, PyAny>) -> String {
    obj.getattr(intern!(obj.py(), "dtype"))
        .and_then(|d| d.str())
        .map(|s| s.to_string())
        .unwrap_or_else(|_| {
            obj.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        })
}

#[pymethods]
impl PlaneMapper {
    /// PlaneMapper(plane, image_size)
    /// --
    ///
    /// A mapper for pixels of an image of image_size = (width, height) px through a
    /// FittedPlane (refusing, like it, pixels 5 % beyond the image's farthest corner).
    #[new]
    fn new(plane: &Bound<'_, FittedPlane>, image_size: (f64, f64)) -> PyResult<Self> {
        let py = plane.py();
        let h = matrix3(&plane.getattr(intern!(py, "homography"))?, "homography")?;
        let lens = plane.getattr(intern!(py, "lens"))?.extract()?;
        build(model(h, lens), image_size)
    }

    /// from_parameters(h, lens_centre, lens_scale, k1, k2, image_size)
    /// --
    ///
    /// A mapper from a plane's parameters (FittedPlane.homography and FittedPlane.lens).
    #[staticmethod]
    fn from_parameters(
        h: &Bound<'_, PyAny>,
        lens_centre: (f64, f64),
        lens_scale: f64,
        k1: f64,
        k2: f64,
        image_size: (f64, f64),
    ) -> PyResult<Self> {
        let lens = (lens_centre.0, lens_centre.1, lens_scale, k1, k2);
        build(model(matrix3(h, "h")?, lens), image_size)
    }

    /// image_to_world(px, out=None, invalid="raise")
    /// --
    ///
    /// Pixels (N x 2 or N x 1 x 2; float64 C-contiguous is read in place, anything else is
    /// copied first) -> plane (N x 2, mm). With out (float64, C-contiguous, N x 2) the result
    /// is written there and out is returned: no allocation. Pixels with no place on the plane
    /// are NaN; invalid="raise" then raises, naming the first (out is filled all the same).
    #[pyo3(signature = (px, out = None, invalid = "raise"))]
    fn image_to_world<'py>(
        &self,
        py: Python<'py>,
        px: &Bound<'py, PyAny>,
        out: Option<&Bound<'py, PyAny>>,
        invalid: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let mode = on_invalid(invalid, "nan")?;
        let pts = points2(px, "px")?;
        let src = pts.as_points();
        let n = src.len();
        let mapper = &self.inner;
        let (result, report) = match out {
            Some(obj) => {
                let report = map_into_out(py, mapper, src, obj)?;
                (obj.clone(), report)
            }
            None => {
                let (array, report) = new_array::<f64, _>(py, &[n, 2], 2 * n, n, |o| {
                    mapper.map_into(src, o.as_chunks_mut::<2>().0)
                })?;
                (array.into_any(), report)
            }
        };
        if mode == OnInvalid::Raise {
            if let Some(e) = map_error(&report, n) {
                return Err(e);
            }
        }
        Ok(result)
    }

    /// World (mm) -> ideal pixels, 3 x 3: the plane's homography.
    #[getter]
    fn homography<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        matrix_out(py, &self.inner.model().h).into_any()
    }

    /// (centre_x, centre_y, scale, k1, k2) of the lens, px.
    #[getter]
    fn lens(&self) -> (f64, f64, f64, f64, f64) {
        let l = self.inner.model().lens;
        (l.centre[0], l.centre[1], l.scale, l.k1, l.k2)
    }

    /// (width, height) of the image whose pixels the mapper serves, px.
    #[getter]
    fn image_size(&self) -> (f64, f64) {
        let [w, h] = self.inner.image_size();
        (w, h)
    }

    /// How the lens is inverted: a description of the polynomial (or Newton's method).
    #[getter]
    fn approximation(&self) -> String {
        self.inner.undistortion().describe()
    }

    /// The polynomial's largest error against Newton's inverse on its check grid, px (0 where
    /// the lens is ideal or inverted by Newton itself).
    #[getter]
    fn max_error_px(&self) -> f64 {
        match self.inner.undistortion() {
            Undistortion::Polynomial { max_error_px, .. } => max_error_px,
            _ => 0.0,
        }
    }

    fn __repr__(&self) -> String {
        let [w, h] = self.inner.image_size();
        format!(
            "PlaneMapper(image_size=({w}, {h}), lens inverse: {})",
            self.inner.undistortion().describe()
        )
    }
}

/// Maps into a caller's array, which must be float64, C-contiguous, aligned, writeable and
/// of shape (N, 2), and must not share memory with the pixels.
fn map_into_out(
    py: Python<'_>,
    mapper: &CoreMapper,
    src: &[[f64; 2]],
    obj: &Bound<'_, PyAny>,
) -> PyResult<MapReport> {
    let n = src.len();
    let Ok(array) = obj.cast::<PyArrayDyn<f64>>() else {
        return Err(invalid(format!(
            "out must be a float64 numpy array of shape ({n}, 2), got {}",
            dtype_name(obj)
        )));
    };
    if array.shape() != [n, 2] {
        return Err(invalid(format!(
            "out must have shape ({n}, 2) to match px, got {:?}",
            array.shape()
        )));
    }
    if !(array.is_c_contiguous() && array.is_aligned()) {
        return Err(invalid(
            "out must be C-contiguous and aligned (np.empty((n, 2)) is); a view or a \
             transposed array would be written through a copy",
        ));
    }
    let mut rw = array.try_readwrite().map_err(|e| {
        invalid(format!(
            "out cannot be written ({e}): it must be writeable and must not share memory with px"
        ))
    })?;
    let dst = rw
        .as_slice_mut()
        .map_err(|e| invalid(format!("out: {e}")))?;
    Ok(maybe_detach(py, n, || {
        mapper.map_into(src, dst.as_chunks_mut::<2>().0)
    }))
}
