//! Sub-pixel object outlines (planarcal_core::outline): the per-object hot spot of object
//! location, one call per object.

use numpy::{PyArray1, PyArrayMethods};
use planarcal_core::outline::{area_centroid, refine_outline, Grey};
use pyo3::prelude::*;

use crate::convert::{float_array, points2, Floats};
use crate::errors::invalid;

/// refine_outline(grey, outline)
/// --
///
/// (outline (K x 2), area, cx, cy): each point of `outline` (K x 2, in `grey`'s pixel
/// coordinates) moved to the steepest grey-level change along its normal in `grey` (H x W
/// float32, e.g. a lightly smoothed region), and the enclosed area and centroid. Outlines of
/// fewer than 12 points are returned as given.
#[pyfunction]
pub fn refine_outline_px<'py>(
    py: Python<'py>,
    grey: &Bound<'py, PyAny>,
    outline: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyAny>, f64, f64, f64)> {
    let Floats::F32(img) = float_array(grey, "grey")? else {
        return Err(invalid("grey must be a float32 image (H x W)"));
    };
    let (height, width) = match img.shape[..] {
        [h, w] => (h, w),
        _ => {
            return Err(invalid(format!(
                "grey must be two-dimensional (H x W), got shape {:?}",
                img.shape
            )))
        }
    };
    let mut points = points2(outline, "outline")?.as_points().to_vec();
    if let Some(i) = points
        .iter()
        .position(|p| !(p[0].is_finite() && p[1].is_finite()))
    {
        return Err(invalid(format!("outline point {i} is not finite")));
    }
    let pixels = img.values();
    refine_outline(
        Grey {
            pixels,
            width,
            height,
        },
        &mut points,
    );
    let (area, [cx, cy]) = area_centroid(&points);
    let flat: Vec<f64> = points.iter().flatten().copied().collect();
    let out = PyArray1::from_vec(py, flat).reshape([points.len(), 2])?;
    Ok((out.into_any(), area, cx, cy))
}
