//! The one place core errors become Python exceptions. All are ValueError subclasses: the
//! input is at fault. Their __module__ is `planarcal`, where users import them from.

use planarcal_core::lens::LensError;
use planarcal_core::{HomographyError as CoreError, PointStatus, TransformReport};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::PyErr;

create_exception!(
    planarcal,
    HomographyError,
    PyValueError,
    "The input cannot give a homography, or a homography cannot be applied to it."
);
create_exception!(
    planarcal,
    DegenerateError,
    HomographyError,
    "The points are well-formed but their geometry does not determine a homography."
);
create_exception!(
    planarcal,
    PointAtInfinityError,
    HomographyError,
    "Points that map to infinity or behind the horizon, or that are not finite."
);

create_exception!(
    planarcal,
    LensModelError,
    PyValueError,
    "A lens-distortion model that cannot be fitted or applied: no image size to centre it on, \
     a distortion that folds the image over, a point outside the model's valid radius."
);

/// A lens error: homography problems keep their own types.
pub fn lens_to_py(e: LensError) -> PyErr {
    match e {
        LensError::Homography(h) => to_py(h),
        other => LensModelError::new_err(other.to_string()),
    }
}

pub fn to_py(e: CoreError) -> PyErr {
    if e.is_degenerate() {
        DegenerateError::new_err(e.to_string())
    } else {
        HomographyError::new_err(e.to_string())
    }
}

/// A bad argument, named by the caller (shape, dtype, option value).
pub fn invalid(message: impl Into<String>) -> PyErr {
    HomographyError::new_err(message.into())
}

/// The error for a batch in which some points had no image.
pub fn no_image(report: &TransformReport, total: usize, what: &str) -> PyErr {
    let mut parts = Vec::new();
    for (count, status) in [
        (report.non_finite, PointStatus::NonFinite),
        (report.at_infinity, PointStatus::AtInfinity),
        (report.behind_horizon, PointStatus::BehindHorizon),
    ] {
        if count > 0 {
            parts.push(format!("{count} {}", status.describe()));
        }
    }
    let first = report
        .first
        .map(|(i, s)| format!("; the first is point {i}, which {}", s.describe()))
        .unwrap_or_default();
    // Every point behind: almost surely a reversed sign, not a camera looking backwards.
    let hint = if total > 0 && report.behind_horizon == total {
        ". Every point is behind the horizon, so the sign of H is probably reversed: OpenCV's \
         H[2,2] = 1 scaling reverses it when the source origin lies beyond the horizon. Pass -H, \
         or use the H that estimate_homography returns (oriented so its points are in front)"
    } else {
        ""
    };
    PointAtInfinityError::new_err(format!(
        "{} of {total} {what} have no image under this homography ({}){first}{hint}",
        report.invalid(),
        parts.join(", "),
    ))
}
