//! Sub-pixel dot centres (planarcal_core::dot_centres), every dot of a board in one call with
//! the GIL released: the per-dot work of board detection.

use numpy::{PyArray1, PyArrayMethods};
use planarcal_core::{refine_dot_centres as refine, DotCentre, InkImage};
use pyo3::prelude::*;

use crate::convert::{f64_array, float_array, point_count, ArrayArg, Floats};
use crate::errors::invalid;

/// (centres, areas, status) as NumPy arrays.
type Refined<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>);

/// refine_dot_centres(ink_dark, points, diameters)
/// --
///
/// (centres, areas, status) of the dark dots of `ink_dark` (an H x W image, float32 or
/// float64; other real dtypes are converted to float64) starting at `points` (float64 N x 2,
/// px) with approximate `diameters` (N, px, finite and >= 0). centres: float64 (N, 2), px;
/// areas: float64 (N,), the ink's area, px^2; status: uint8 (N,), 0 where refined, else why
/// not (1 cut by the image border, 2 no paper around it, 3 too small to measure, 4 no contrast
/// with its background, 5 no ink, 6 its grey levels lead away from it), the dot then keeping its
/// starting point and pi (d / 2)^2.
#[pyfunction]
pub fn refine_dot_centres<'py>(
    py: Python<'py>,
    ink_dark: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
    diameters: &Bound<'py, PyAny>,
) -> PyResult<Refined<'py>> {
    let image = float_array(ink_dark, "ink_dark")?;
    let shape = match &image {
        Floats::F32(a) => &a.shape,
        Floats::F64(a) => &a.shape,
    };
    let (height, width) = match shape[..] {
        [h, w] if h > 0 && w > 0 => (h, w),
        _ => {
            return Err(invalid(format!(
                "ink_dark must be a non-empty two-dimensional image (H x W), got shape {shape:?}"
            )))
        }
    };
    let pts = f64_array(points, "points")?;
    let n = point_count(&pts.shape, 2, "points")?;
    let d = f64_array(diameters, "diameters")?;
    if d.shape != [n] {
        return Err(invalid(format!(
            "diameters must have shape ({n},), one per point, got {:?}",
            d.shape
        )));
    }
    let points = pts.values().as_chunks::<2>().0;
    let found = match &image {
        Floats::F32(a) => run(py, a, width, height, points, d.values()),
        Floats::F64(a) => run(py, a, width, height, points, d.values()),
    }?;
    let centres: Vec<f64> = found.iter().flat_map(|c| c.centre).collect();
    let areas: Vec<f64> = found.iter().map(|c| c.area).collect();
    let status: Vec<u8> = found.iter().map(|c| c.status.code()).collect();
    Ok((
        PyArray1::from_vec(py, centres).reshape([n, 2])?.into_any(),
        PyArray1::from_vec(py, areas).into_any(),
        PyArray1::from_vec(py, status).into_any(),
    ))
}

/// The core on a borrowed image, the GIL released; its errors (bad points or diameters) are
/// bad arguments.
fn run<T: numpy::Element + Copy + Into<f64> + Sync>(
    py: Python<'_>,
    image: &ArrayArg<'_, T>,
    width: usize,
    height: usize,
    points: &[[f64; 2]],
    diameters: &[f64],
) -> PyResult<Vec<DotCentre>> {
    let image = InkImage {
        pixels: image.values(),
        width,
        height,
    };
    py.detach(|| refine(image, points, diameters))
        .map_err(|e| invalid(e.to_string()))
}
