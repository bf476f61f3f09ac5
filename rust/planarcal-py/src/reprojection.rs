//! Reprojection errors (Eq. 6) and their statistics (Eq. 7, RMS, max, min).

use numpy::PyArrayDyn;
use planarcal_core::{reprojection_errors_into, ErrorStats, Orientation, PointSet};
use pyo3::prelude::*;

use crate::convert::{matrix3, points2, text};
use crate::errors::{invalid_arg, no_image, to_py};
use crate::transform::{new_array, on_invalid, OnInvalid};

/// reprojection_errors(h, src, dst, invalid="raise")
/// --
///
/// Per-point || dst_i - H src_i || (N, float64, destination units); no-image points raise or are inf.
#[pyfunction]
pub fn reprojection_errors<'py>(
    py: Python<'py>,
    h: &Bound<'py, PyAny>,
    src: &Bound<'py, PyAny>,
    dst: &Bound<'py, PyAny>,
    invalid: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let mode = on_invalid(text(invalid, "invalid")?.to_str()?, "inf")?;
    let m = matrix3(h, "h")?;
    let (s, d) = (points2(src, "src")?, points2(dst, "dst")?);
    let (s, d) = (s.as_points(), d.as_points());
    let n = s.len();
    if d.len() != n {
        return Err(to_py(planarcal_core::HomographyError::LengthMismatch {
            src: n,
            dst: d.len(),
        }));
    }
    let (out, (report, overflow)) = new_array::<f64, _>(py, &[n], n, n, |slice| {
        let report = reprojection_errors_into(&m, s, d, slice, Orientation::Oriented);
        // An error beyond float64's range is +inf too, although the point has an image.
        let overflow = match mode {
            OnInvalid::Raise => slice.iter().position(|e| e.is_infinite()),
            OnInvalid::Fill => None,
        };
        (report, overflow)
    })?;
    let report = report.map_err(to_py)?;
    if mode == OnInvalid::Raise && report.invalid() > 0 {
        return Err(no_image(
            &report,
            n,
            "source points",
            Some(PointSet::Source),
        ));
    }
    if let Some(i) = overflow {
        return Err(invalid_arg(
            "dst",
            format!(
                "the reprojection error of point {i} is beyond float64's range (dst {:?}, H src \
                 maps far from it): scale the coordinates down",
                d[i]
            ),
        ));
    }
    Ok(out)
}

/// error_stats(errors)
/// --
///
/// (count, mean, rms, max, min, argmax, argmin) of a 1-D array of errors.
#[pyfunction]
pub fn error_stats(
    errors: &Bound<'_, PyAny>,
) -> PyResult<(usize, f64, f64, f64, f64, usize, usize)> {
    let arg = crate::convert::f64_array(errors, "errors")?;
    if arg.shape.len() != 1 {
        return Err(crate::errors::invalid(format!(
            "errors must be one-dimensional, got shape {:?}",
            arg.shape
        )));
    }
    if let Some(i) = arg.values().iter().position(|e| e.is_nan()) {
        return Err(crate::errors::invalid(format!(
            "errors[{i}] is NaN: no statistic of these errors would mean anything"
        )));
    }
    let s = ErrorStats::of(arg.values())
        .ok_or_else(|| crate::errors::invalid("errors is empty: no statistics to report"))?;
    Ok((s.count, s.mean, s.rms, s.max, s.min, s.argmax, s.argmin))
}
