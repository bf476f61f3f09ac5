//! The one place core errors become Python exceptions. The classes are planarcal's own, defined
//! once in Python (`planarcal/errors.py`, under the root `planarcal.Error`) and looked up here
//! on first use; all are ValueError subclasses (the input is at fault). Errors that name a point
//! carry it as attributes, `index` and `point_set` ("src" / "dst"), after the message: the
//! classes take them positionally, so every error here is made lazily, without the GIL. A
//! buffer the core could not allocate is MemoryError, not one of planarcal's.

use planarcal_core::{
    HomographyError as CoreError, LensError, PointFailure, PointReport, PointSet, POINT_FAILURES,
};
use pyo3::exceptions::PyMemoryError;
use pyo3::import_exception;
use pyo3::PyErr;

import_exception!(planarcal.errors, ArgumentError);
import_exception!(planarcal.errors, ArgumentTypeError);
import_exception!(planarcal.errors, HomographyError);
import_exception!(planarcal.errors, DegenerateError);
import_exception!(planarcal.errors, PointAtInfinityError);
import_exception!(planarcal.errors, LensModelError);

/// The Python name of a point set: the parameter names of the correspondence functions.
fn set_name(set: PointSet) -> &'static str {
    match set {
        PointSet::Source => "src",
        PointSet::Destination => "dst",
    }
}

/// The exception arguments: the message, then `index` and `point_set` (None where unknown).
type Args = (String, Option<usize>, Option<&'static str>);

fn args(message: String, index: Option<usize>, set: Option<PointSet>) -> Args {
    (message, index, set.map(set_name))
}

/// A lens error: homography problems keep their own types.
pub fn lens_to_py(e: LensError) -> PyErr {
    match e {
        LensError::Homography(h) => to_py(h),
        LensError::OutsideModel { index, .. } => {
            LensModelError::new_err(args(e.to_string(), Some(index), None))
        }
        other => LensModelError::new_err(args(other.to_string(), None, None)),
    }
}

/// A core error as the Python exception of its kind: ArgumentError for a malformed argument,
/// DegenerateError for geometry that determines no homography, else HomographyError.
pub fn to_py(e: CoreError) -> PyErr {
    to_py_in(e, "")
}

/// As `to_py`, the message after `context` (say which of several problems failed). A buffer
/// the core could not allocate is Python's MemoryError, as NumPy's own would be.
pub fn to_py_in(e: CoreError, context: &str) -> PyErr {
    let (set, index) = e.point();
    if matches!(e, CoreError::OutOfMemory { .. }) {
        return PyMemoryError::new_err(format!("{context}{e}"));
    }
    let a = args(format!("{context}{e}"), index, set);
    if e.is_invalid_argument() {
        ArgumentError::new_err(a)
    } else if e.is_degenerate() {
        DegenerateError::new_err(a)
    } else {
        HomographyError::new_err(a)
    }
}

/// An argument of the wrong type (a number where a flag or a name belongs), named by the
/// caller: an ArgumentTypeError, both a ValueError and a TypeError.
pub fn wrong_type(message: impl Into<String>) -> PyErr {
    ArgumentTypeError::new_err(args(message.into(), None, None))
}

/// A bad argument, named by the caller (shape, dtype, option value).
pub fn invalid(message: impl Into<String>) -> PyErr {
    ArgumentError::new_err(args(message.into(), None, None))
}

/// A bad array argument called `name`: when it is one of the point sets of a correspondence
/// problem ("src", OpenCV's "srcPoints", "problems[3] src", ...) the error says which.
pub fn invalid_arg(name: &str, message: impl Into<String>) -> PyErr {
    let last = name.rsplit(' ').next().unwrap_or(name);
    let set = match last {
        "src" | "srcPoints" => Some(PointSet::Source),
        "dst" | "dstPoints" => Some(PointSet::Destination),
        _ => None,
    };
    ArgumentError::new_err(args(message.into(), None, set))
}

/// The exception for points that failed as `failure` (the first of a batch): beyond the lens
/// model's valid radius is the lens model's error, the rest are points without an image.
fn failed(failure: Option<PointFailure>, a: Args) -> PyErr {
    match failure {
        Some(PointFailure::OutsideLens) => LensModelError::new_err(a),
        _ => PointAtInfinityError::new_err(a),
    }
}

/// The error for a batch of `total` pixels of which some have no place on the plane, naming
/// the first; None if all have one.
pub fn no_place(report: &PointReport, total: usize) -> Option<PyErr> {
    let (index, failure) = report.first?;
    let message = format!(
        "{} of {total} pixels have no place on the plane; the first is point {index}, which {}",
        report.invalid(),
        failure.describe_pixel()
    );
    Some(failed(Some(failure), args(message, Some(index), None)))
}

/// The error for a batch in which some points had no image under a homography (`set`: the
/// points were that set of a correspondence problem).
pub fn no_image(report: &PointReport, total: usize, what: &str, set: Option<PointSet>) -> PyErr {
    let parts: Vec<String> = POINT_FAILURES
        .into_iter()
        .filter(|&kind| report.count(kind) > 0)
        .map(|kind| format!("{} {}", report.count(kind), kind.describe()))
        .collect();
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
    let message = format!(
        "{} of {total} {what} have no image under this homography ({}){first}{hint}",
        report.invalid(),
        parts.join(", "),
    );
    let index = report.first.map(|(i, _)| i);
    failed(report.first.map(|(_, f)| f), args(message, index, set))
}
