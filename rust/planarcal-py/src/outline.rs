//! Sub-pixel object outlines (planarcal_core::outline): the per-object hot spot of object
//! location, one call per object.

use numpy::{PyArray1, PyArrayMethods};
use planarcal_core::outline::{area_centroid, refine_outline, Grey};
use pyo3::prelude::*;

use crate::convert::{float_array, points2, Floats};
use crate::errors::invalid;

/// refine_outline_px(grey, outline, origin=(0.0, 0.0))
/// --
///
/// (outline (K x 2), area, cx, cy): each point of `outline` (K x 2, image coordinates)
/// moved to the steepest grey-level change along its normal in `grey` (H x W float32, e.g. a
/// lightly smoothed region whose pixel (0, 0) is the image's `origin`), and the enclosed
/// area and centroid, in image coordinates. Outlines of fewer than 12 points are returned as
/// given.
#[pyfunction]
#[pyo3(signature = (grey, outline, origin = (0.0, 0.0)))]
pub fn refine_outline_px<'py>(
    py: Python<'py>,
    grey: &Bound<'py, PyAny>,
    outline: &Bound<'py, PyAny>,
    origin: (f64, f64),
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
    let (ox, oy) = origin;
    if !(ox.is_finite() && oy.is_finite()) {
        return Err(invalid(format!("origin must be finite, got ({ox}, {oy})")));
    }
    let mut points: Vec<[f64; 2]> = points2(outline, "outline")?
        .as_points()
        .iter()
        .map(|p| [p[0] - ox, p[1] - oy])
        .collect();
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
    let flat: Vec<f64> = points.iter().flat_map(|p| [p[0] + ox, p[1] + oy]).collect();
    let out = PyArray1::from_vec(py, flat).reshape([points.len(), 2])?;
    Ok((out.into_any(), area, cx + ox, cy + oy))
}
