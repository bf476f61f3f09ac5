//! Robust estimation: the native estimate_homography_robust (one problem or a batch) and the
//! robust methods of OpenCV's findHomography. The search always runs with the GIL released:
//! even a small problem draws hundreds of samples.

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use planarcal_core::{
    estimate_robust, estimate_robust_batch, with_unit_h33, Method, Point, RobustOptions,
    RobustResult,
};
use pyo3::prelude::*;
use pyo3::types::PyList;

use crate::convert::{f64_array, points2, Points2};
use crate::errors::{invalid, to_py, to_py_in};
use crate::estimate::{matrix_out, HomographyAndMask};

/// (H or None, inlier mask (N,) bool, n_inliers, iterations, stop, rms, threshold, lo_runs).
type ResultTuple<'py> = (
    Option<Bound<'py, PyArray2<f64>>>,
    Bound<'py, PyArray1<bool>>,
    usize,
    usize,
    &'static str,
    f64,
    f64,
    usize,
);

fn method(name: &str) -> PyResult<Method> {
    match name {
        "msac" => Ok(Method::Msac),
        "lmeds" => Ok(Method::Lmeds),
        other => Err(invalid(format!(
            "method must be \"msac\" or \"lmeds\", got {other:?}"
        ))),
    }
}

/// Checks the numbers Python passed before they are narrowed to the core's types.
fn options(
    threshold: f64,
    confidence: f64,
    max_iters: i64,
    seed: u64,
    method_name: &str,
) -> PyResult<RobustOptions> {
    if max_iters <= 0 {
        return Err(invalid(format!(
            "max_iters must be at least 1, got {max_iters}"
        )));
    }
    Ok(RobustOptions {
        threshold,
        confidence,
        max_iters: usize::try_from(max_iters).unwrap_or(usize::MAX),
        seed,
        scores: None,
        method: method(method_name)?,
        parallel: true,
    })
}

fn scores_arg(scores: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Vec<f64>>> {
    let Some(s) = scores else {
        return Ok(None);
    };
    if s.is_none() {
        return Ok(None);
    }
    let arr = f64_array(s, "scores")?;
    if arr.shape.len() != 1 {
        return Err(invalid(format!(
            "scores must be a 1-D array (one number per correspondence), got shape {:?}",
            arr.shape
        )));
    }
    Ok(Some(arr.values().to_vec()))
}

fn result_tuple<'py>(py: Python<'py>, r: RobustResult) -> ResultTuple<'py> {
    (
        r.h.map(|h| matrix_out(py, &h)),
        PyArray1::from_vec(py, r.inliers),
        r.n_inliers,
        r.iterations,
        r.stop.name(),
        r.rms_inlier_error,
        r.threshold,
        r.lo_runs,
    )
}

/// estimate_homography_robust(src, dst, threshold=3.0, confidence=0.999, max_iters=10000,
///     seed=0, scores=None, method="msac")
/// --
///
/// The robust fit as a tuple (see planarcal.RobustResult).
#[pyfunction]
#[pyo3(signature = (src, dst, threshold = 3.0, confidence = 0.999, max_iters = 10_000,
    seed = 0, scores = None, method = "msac"))]
#[allow(clippy::too_many_arguments)]
pub fn estimate_homography_robust<'py>(
    py: Python<'py>,
    src: &Bound<'py, PyAny>,
    dst: &Bound<'py, PyAny>,
    threshold: f64,
    confidence: f64,
    max_iters: i64,
    seed: u64,
    scores: Option<&Bound<'py, PyAny>>,
    method: &str,
) -> PyResult<ResultTuple<'py>> {
    let mut o = options(threshold, confidence, max_iters, seed, method)?;
    o.scores = scores_arg(scores)?;
    let (s, d) = (points2(src, "src")?, points2(dst, "dst")?);
    let (s, d) = (s.as_points(), d.as_points());
    let r = py.detach(|| estimate_robust(s, d, &o)).map_err(to_py)?;
    Ok(result_tuple(py, r))
}

/// estimate_homography_robust_batch(problems, threshold=3.0, confidence=0.999,
///     max_iters=10000, seed=0, method="msac")
/// --
///
/// One result tuple per (src, dst) pair, the problems solved in parallel; a problem with bad
/// input raises, naming its index.
#[pyfunction]
#[pyo3(signature = (problems, threshold = 3.0, confidence = 0.999, max_iters = 10_000,
    seed = 0, method = "msac"))]
pub fn estimate_homography_robust_batch<'py>(
    py: Python<'py>,
    problems: &Bound<'py, PyAny>,
    threshold: f64,
    confidence: f64,
    max_iters: i64,
    seed: u64,
    method: &str,
) -> PyResult<Bound<'py, PyList>> {
    let o = options(threshold, confidence, max_iters, seed, method)?;
    let mut borrowed: Vec<(Points2<'py>, Points2<'py>)> = Vec::new();
    for (i, item) in problems.try_iter()?.enumerate() {
        let item = item?;
        let pair: (Bound<'py, PyAny>, Bound<'py, PyAny>) = item.extract().map_err(|_| {
            invalid(format!(
                "problems[{i}] must be a (src, dst) pair of point arrays"
            ))
        })?;
        let s = points2(&pair.0, &format!("problems[{i}] src"))?;
        let d = points2(&pair.1, &format!("problems[{i}] dst"))?;
        borrowed.push((s, d));
    }
    let views: Vec<(&[Point], &[Point])> = borrowed
        .iter()
        .map(|(s, d)| (s.as_points(), d.as_points()))
        .collect();
    let results = py.detach(|| estimate_robust_batch(&views, &o));
    let out = PyList::empty(py);
    for (i, r) in results.into_iter().enumerate() {
        let r = r.map_err(|e| to_py_in(e, &format!("problems[{i}]: ")))?;
        out.append(result_tuple(py, r))?;
    }
    Ok(out)
}

/// find_homography_robust(src, dst, method, threshold, max_iters, confidence, ordered)
/// --
///
/// OpenCV's robust findHomography: (H with H[2,2] = 1, or None; mask N x 1 uint8). `ordered`
/// says the points come best first (USAC_PROSAC's contract).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn find_homography_robust<'py>(
    py: Python<'py>,
    src: &Bound<'py, PyAny>,
    dst: &Bound<'py, PyAny>,
    method: &str,
    threshold: f64,
    max_iters: i64,
    confidence: f64,
    ordered: bool,
) -> PyResult<HomographyAndMask<'py>> {
    let mut o = options(threshold, confidence, max_iters, 0, method)?;
    let (s, d) = (points2(src, "srcPoints")?, points2(dst, "dstPoints")?);
    let (s, d) = (s.as_points(), d.as_points());
    if ordered {
        o.scores = Some((0..s.len()).map(|i| -(i as f64)).collect());
    }
    let r = py.detach(|| estimate_robust(s, d, &o)).map_err(to_py)?;
    let n = r.inliers.len();
    let h = r.h.as_ref().and_then(with_unit_h33);
    let mask: Vec<u8> = if h.is_some() {
        r.inliers.iter().map(|&b| u8::from(b)).collect()
    } else {
        vec![0; n]
    };
    let mask = PyArray1::from_vec(py, mask).reshape([n, 1])?;
    Ok((h.map(|h| matrix_out(py, &h)), mask))
}
