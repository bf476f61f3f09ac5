//! Homography estimation: the native API and OpenCV's method-0 findHomography.

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use planarcal_core::{estimate_homography as core_estimate, with_unit_h33, Solver};
use pyo3::prelude::*;

use crate::convert::{flag, points2, text};
use crate::errors::{invalid, to_py};

/// OpenCV's (H or None, mask) pair.
pub type HomographyAndMask<'py> = (Option<Bound<'py, PyArray2<f64>>>, Bound<'py, PyArray2<u8>>);

/// Above this many points (or with refinement) the fit runs with the GIL released.
const DETACH_MIN_POINTS: usize = 256;

pub fn matrix_out<'py>(py: Python<'py>, h: &nalgebra::Matrix3<f64>) -> Bound<'py, PyArray2<f64>> {
    let rows: Vec<Vec<f64>> = (0..3)
        .map(|r| (0..3).map(|c| h[(r, c)]).collect())
        .collect();
    // Three rows of three: from_vec2 cannot fail on equal lengths.
    PyArray2::from_vec2(py, &rows).unwrap_or_else(|_| PyArray2::zeros(py, [3, 3], false))
}

fn fit(
    py: Python<'_>,
    src: &[[f64; 2]],
    dst: &[[f64; 2]],
    solver: Solver,
    refine: bool,
) -> planarcal_core::Result<nalgebra::Matrix3<f64>> {
    if refine || src.len() >= DETACH_MIN_POINTS {
        py.detach(|| core_estimate(src, dst, solver, refine))
    } else {
        core_estimate(src, dst, solver, refine)
    }
}

/// estimate_homography(src, dst, solver="normalized_dlt", refine=False)
/// --
///
/// H (3 x 3, float64) with dst ~ H src; raises ArgumentError / HomographyError / DegenerateError.
#[pyfunction]
pub fn estimate_homography<'py>(
    py: Python<'py>,
    src: &Bound<'py, PyAny>,
    dst: &Bound<'py, PyAny>,
    solver: &Bound<'py, PyAny>,
    refine: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let refine = flag(refine, "refine")?;
    let solver: Solver = text(solver, "solver")?
        .to_str()?
        .parse()
        .map_err(|e: planarcal_core::UnknownSolver| invalid(e.to_string()))?;
    let (s, d) = (points2(src, "src")?, points2(dst, "dst")?);
    let h = fit(py, s.as_points(), d.as_points(), solver, refine).map_err(to_py)?;
    Ok(matrix_out(py, &h))
}

/// find_homography(src, dst)
/// --
///
/// OpenCV's findHomography(method=0): (H with H[2,2] = 1, or None if degenerate; mask N x 1).
#[pyfunction]
pub fn find_homography<'py>(
    py: Python<'py>,
    src: &Bound<'py, PyAny>,
    dst: &Bound<'py, PyAny>,
) -> PyResult<HomographyAndMask<'py>> {
    let (s, d) = (points2(src, "srcPoints")?, points2(dst, "dstPoints")?);
    let n = s.as_points().len();
    let result = fit(
        py,
        s.as_points(),
        d.as_points(),
        Solver::NormalizedDlt,
        true,
    );
    let h = match result {
        Ok(h) => with_unit_h33(&h),
        Err(e) if e.is_degenerate() => None,
        Err(e) => return Err(to_py(e)),
    };
    let fill = u8::from(h.is_some());
    let mask = PyArray1::from_vec(py, vec![fill; n]).reshape([n, 1])?;
    Ok((h.map(|h| matrix_out(py, &h)), mask))
}
