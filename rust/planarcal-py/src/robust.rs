//! Robust estimation: the native estimate_homography_robust (one problem or a batch), the
//! robust methods of OpenCV's findHomography, and what they return, RobustResult.
//!
//! The options arrive as the objects the caller passed: this module converts them to the
//! core's types, raising an ArgumentError that names the argument, and the core checks their
//! ranges (RobustOptions::validate), before any point is looked at. The search always runs
//! with the GIL released: even a small problem draws hundreds of samples.

use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use planarcal_core::{
    estimate_robust_batch_interruptible, estimate_robust_interruptible, try_collect, try_filled,
    with_unit_h33, Method, Point, RobustOptions, RobustResult as CoreResult, StopReason, MAX_ITERS,
};
use pyo3::exceptions::PyOverflowError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyFloat, PyList, PyString, PyTuple, PyType};
use pyo3::{intern, IntoPyObjectExt};

use crate::convert::{f64_array, iterate, points2, shown, Points2};
use crate::errors::{invalid, to_py};
use crate::estimate::{matrix_out, HomographyAndMask};
use crate::signals::Signals;

/// The outcome of a robust fit.
///
/// ``H`` is None when no homography was found (``stop_reason == "no_consensus"``), for
/// example when every correspondence is an outlier; check ``success`` (or ``H is None``)
/// before using it.
#[pyclass(frozen, module = "planarcal", name = "RobustResult")]
pub struct RobustResult {
    /// dst ~ H src (3 x 3, oriented, H[2, 2] = 1 as estimate_homography returns it).
    #[pyo3(get, name = "H")]
    h: Option<Py<PyArray2<f64>>>,
    /// (N,) bool: within ``threshold`` of the final H (all False without one).
    #[pyo3(get)]
    inliers: Py<PyArray1<bool>>,
    /// The number of inliers: ``inliers.sum()``.
    #[pyo3(get)]
    n_inliers: usize,
    /// Iterations: minimal samples that passed the sample checks (OpenCV's count).
    #[pyo3(get)]
    iterations: usize,
    stop: StopReason,
    /// RMS transfer error of the inliers under H, in destination units (NaN without H).
    #[pyo3(get)]
    rms_inlier_error: f64,
    /// The inlier threshold of the mask (LMedS derives it from its inliers' scale).
    #[pyo3(get)]
    threshold: f64,
    /// New best models that were locally optimised.
    #[pyo3(get)]
    local_optimizations: usize,
    /// The model rests on little: fewer than 10 inliers, or inliers along a line or in a
    /// small patch of the points' spread; H fits them but may be far off elsewhere.
    #[pyo3(get)]
    poorly_constrained: bool,
    /// Correspondences: the length of ``inliers``.
    n: usize,
}

impl RobustResult {
    fn from_core(py: Python<'_>, r: CoreResult) -> Self {
        RobustResult {
            h: r.h.map(|h| matrix_out(py, &h).unbind()),
            n: r.inliers.len(),
            inliers: PyArray1::from_vec(py, r.inliers).unbind(),
            n_inliers: r.n_inliers,
            iterations: r.iterations,
            stop: r.stop,
            rms_inlier_error: r.rms_inlier_error,
            threshold: r.threshold,
            local_optimizations: r.lo_runs,
            poorly_constrained: r.poorly_constrained,
        }
    }
}

fn stop_reason(name: &str) -> PyResult<StopReason> {
    [
        StopReason::Converged,
        StopReason::MaxIterations,
        StopReason::NoConsensus,
    ]
    .into_iter()
    .find(|s| s.name() == name)
    .ok_or_else(|| {
        invalid(format!(
            "stop_reason must be \"converged\", \"max_iterations\" or \"no_consensus\", \
             got {name:?}"
        ))
    })
}

/// Python's `format(value, ".4g")`, as the repr has always printed the errors.
fn short(py: Python<'_>, value: f64) -> PyResult<String> {
    PyFloat::new(py, value)
        .call_method1(intern!(py, "__format__"), (".4g",))?
        .extract()
}

#[pymethods]
impl RobustResult {
    #[new]
    #[pyo3(signature = (H, inliers, n_inliers, iterations, stop_reason, rms_inlier_error,
        threshold, local_optimizations, poorly_constrained=false))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn py_new(
        H: Option<Bound<'_, PyArray2<f64>>>,
        inliers: Bound<'_, PyArray1<bool>>,
        n_inliers: usize,
        iterations: usize,
        stop_reason: &str,
        rms_inlier_error: f64,
        threshold: f64,
        local_optimizations: usize,
        poorly_constrained: bool,
    ) -> PyResult<Self> {
        Ok(RobustResult {
            h: H.map(Bound::unbind),
            n: inliers.len(),
            inliers: inliers.unbind(),
            n_inliers,
            iterations,
            stop: self::stop_reason(stop_reason)?,
            rms_inlier_error,
            threshold,
            local_optimizations,
            poorly_constrained,
        })
    }

    /// Why the search stopped: ``"converged"`` (the confidence was reached),
    /// ``"max_iterations"`` (``max_iters`` iterations were run first: the result may still be
    /// right, but is not certified) or ``"no_consensus"`` (no model had more support than
    /// chance gives; ``H`` is None).
    #[getter]
    fn stop_reason(&self) -> &'static str {
        self.stop.name()
    }

    /// Whether a homography was found.
    #[getter]
    fn success(&self) -> bool {
        self.h.is_some()
    }

    /// The fraction of the correspondences that are inliers (0 without any).
    #[getter]
    fn inlier_ratio(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.n_inliers as f64 / self.n as f64
        }
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        Ok(format!(
            "RobustResult(success={}, n_inliers={} of {}, iterations={}, stop_reason='{}', \
             rms_inlier_error={}, threshold={})",
            if self.success() { "True" } else { "False" },
            self.n_inliers,
            self.n,
            self.iterations,
            self.stop.name(),
            short(py, self.rms_inlier_error)?,
            short(py, self.threshold)?,
        ))
    }

    /// Pickling: the class and the constructor's arguments.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyType>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let r = slf.get();
        let args = (
            r.h.as_ref().map(|h| h.bind(py)),
            r.inliers.bind(py),
            r.n_inliers,
            r.iterations,
            r.stop.name(),
            r.rms_inlier_error,
            r.threshold,
            r.local_optimizations,
            r.poorly_constrained,
        );
        Ok((slf.get_type(), args.into_pyobject(py)?))
    }
}

fn method(obj: &Bound<'_, PyAny>) -> PyResult<Method> {
    if let Ok(name) = obj.cast::<PyString>() {
        match name.to_str()? {
            "msac" => return Ok(Method::Msac),
            "lmeds" => return Ok(Method::Lmeds),
            _ => {}
        }
    }
    Err(invalid(format!(
        "method must be \"msac\" or \"lmeds\", got {}",
        shown(obj)
    )))
}

/// A real number (Python's or NumPy's, anything with `__float__`; not bool, str or bytes).
fn real(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    let not_a_number = || invalid(format!("{name} must be a number, got {}", shown(obj)));
    if obj.is_instance_of::<PyBool>()
        || obj.is_instance_of::<PyString>()
        || obj.is_instance_of::<PyBytes>()
    {
        return Err(not_a_number());
    }
    obj.extract::<f64>().map_err(|_| not_a_number())
}

/// An integer (Python's or NumPy's, anything with `__index__`; not bool) as `T`; one that
/// does not fit `T` gives `Err(None)`, anything else an ArgumentError naming it.
fn integer<'py, T>(obj: &Bound<'py, PyAny>, name: &str) -> Result<T, Option<PyErr>>
where
    T: for<'a> FromPyObject<'a, 'py, Error = PyErr>,
{
    let not_an_integer = || {
        Some(invalid(format!(
            "{name} must be an integer, got {}",
            shown(obj)
        )))
    };
    if obj.is_instance_of::<PyBool>() {
        return Err(not_an_integer());
    }
    obj.extract::<T>().map_err(|e| {
        if e.is_instance_of::<PyOverflowError>(obj.py()) {
            None
        } else {
            not_an_integer()
        }
    })
}

/// max_iters as a count: the core checks the range (RobustOptions::validate); a value its
/// type cannot hold is out of that range here.
fn max_iters(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    let out_of_range = || {
        let k = obj.str().map(|s| s.to_string()).unwrap_or_default();
        invalid(format!(
            "max_iters must be between 1 and {MAX_ITERS} (the search stops sooner once the \
             confidence is reached), got {k}"
        ))
    };
    match integer::<i64>(obj, "max_iters") {
        Ok(k) => usize::try_from(k).map_err(|_| out_of_range()),
        Err(Some(e)) => Err(e),
        Err(None) => Err(out_of_range()),
    }
}

fn seed(obj: &Bound<'_, PyAny>) -> PyResult<u64> {
    integer::<u64>(obj, "seed").map_err(|e| {
        e.unwrap_or_else(|| {
            let s = obj.str().map(|s| s.to_string()).unwrap_or_default();
            invalid(format!("seed must be an integer in [0, 2**64), got {s}"))
        })
    })
}

/// The caller's options in the core's types, converted in the order the Python API lists
/// them, then their ranges checked by the core, before any point is converted: a bad option is
/// reported as such, and once for a whole batch.
fn options(
    threshold: &Bound<'_, PyAny>,
    confidence: &Bound<'_, PyAny>,
    max_iters_arg: &Bound<'_, PyAny>,
    seed_arg: Option<&Bound<'_, PyAny>>,
    method_arg: &Bound<'_, PyAny>,
    scores: Option<&Bound<'_, PyAny>>,
) -> PyResult<RobustOptions> {
    let method = method(method_arg)?;
    let o = RobustOptions {
        threshold: real(threshold, "threshold")?,
        confidence: real(confidence, "confidence")?,
        max_iters: max_iters(max_iters_arg)?,
        seed: seed_arg.map(seed).transpose()?.unwrap_or(0),
        scores: scores_arg(scores)?,
        method,
        parallel: true,
    };
    o.validate().map_err(to_py)?;
    Ok(o)
}

fn scores_arg(scores: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Vec<f64>>> {
    let Some(s) = scores.filter(|s| !s.is_none()) else {
        return Ok(None);
    };
    let arr = f64_array(s, "scores")?;
    if arr.shape.len() != 1 {
        return Err(invalid(format!(
            "scores must be a 1-D array (one number per correspondence), got shape {:?}",
            arr.shape
        )));
    }
    Ok(Some(
        try_collect(arr.values().iter().copied()).map_err(to_py)?,
    ))
}

/// estimate_homography_robust(src, dst, threshold, confidence, max_iters, seed, scores, method)
/// --
///
/// The robust fit, a planarcal.RobustResult; the options as the caller passed them.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn estimate_homography_robust<'py>(
    py: Python<'py>,
    src: &Bound<'py, PyAny>,
    dst: &Bound<'py, PyAny>,
    threshold: &Bound<'py, PyAny>,
    confidence: &Bound<'py, PyAny>,
    max_iters: &Bound<'py, PyAny>,
    seed: &Bound<'py, PyAny>,
    scores: Option<&Bound<'py, PyAny>>,
    method: &Bound<'py, PyAny>,
) -> PyResult<RobustResult> {
    let o = options(threshold, confidence, max_iters, Some(seed), method, scores)?;
    let (s, d) = (points2(src, "src")?, points2(dst, "dst")?);
    let (s, d) = (s.as_points(), d.as_points());
    let signals = Signals::new();
    let r = py
        .detach(|| estimate_robust_interruptible(s, d, &o, &|| signals.poll()))
        .map_err(|e| signals.error(e, ""))?;
    Ok(RobustResult::from_core(py, r))
}

/// estimate_homography_robust_batch(problems, threshold, confidence, max_iters, seed, method)
/// --
///
/// One RobustResult per (src, dst) pair of the iterable, the problems solved in parallel; a
/// problem with bad input raises, naming its index.
#[pyfunction]
pub fn estimate_homography_robust_batch<'py>(
    py: Python<'py>,
    problems: &Bound<'py, PyAny>,
    threshold: &Bound<'py, PyAny>,
    confidence: &Bound<'py, PyAny>,
    max_iters: &Bound<'py, PyAny>,
    seed: &Bound<'py, PyAny>,
    method: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyList>> {
    let o = options(threshold, confidence, max_iters, Some(seed), method, None)?;
    let mut borrowed: Vec<(Points2<'py>, Points2<'py>)> = Vec::new();
    let pairs = iterate(problems, "problems", "an iterable of (src, dst) pairs")?;
    for (i, item) in pairs.enumerate() {
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
    let signals = Signals::new();
    let results = py.detach(|| estimate_robust_batch_interruptible(&views, &o, &|| signals.poll()));
    let out = PyList::empty(py);
    for (i, r) in results.into_iter().enumerate() {
        let r = r.map_err(|e| signals.error(e, &format!("problems[{i}]: ")))?;
        out.append(RobustResult::from_core(py, r).into_bound_py_any(py)?)?;
    }
    Ok(out)
}

/// find_homography_robust(src, dst, method, threshold, max_iters, confidence, ordered)
/// --
///
/// OpenCV's robust findHomography: (H with H[2,2] = 1, or None; mask N x 1 uint8). `method` is
/// "msac" or "lmeds", the options as the caller passed them; `ordered` says the points come
/// best first (USAC_PROSAC's contract).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn find_homography_robust<'py>(
    py: Python<'py>,
    src: &Bound<'py, PyAny>,
    dst: &Bound<'py, PyAny>,
    method: &Bound<'py, PyAny>,
    threshold: &Bound<'py, PyAny>,
    max_iters: &Bound<'py, PyAny>,
    confidence: &Bound<'py, PyAny>,
    ordered: bool,
) -> PyResult<HomographyAndMask<'py>> {
    let mut o = options(threshold, confidence, max_iters, None, method, None)?;
    let (s, d) = (points2(src, "srcPoints")?, points2(dst, "dstPoints")?);
    let (s, d) = (s.as_points(), d.as_points());
    if ordered {
        o.scores = Some(try_collect((0..s.len()).map(|i| -(i as f64))).map_err(to_py)?);
    }
    let signals = Signals::new();
    let r = match py.detach(|| estimate_robust_interruptible(s, d, &o, &|| signals.poll())) {
        Ok(r) => r,
        // No sample of such a set can fit: OpenCV's answer, no homography and an empty mask.
        Err(e) if e.is_degenerate() => {
            let zeros = try_filled(0u8, s.len()).map_err(to_py)?;
            let mask = PyArray1::from_vec(py, zeros).reshape([s.len(), 1])?;
            return Ok((None, mask));
        }
        Err(e) => return Err(signals.error(e, "")),
    };
    let n = r.inliers.len();
    let h = r.h.as_ref().and_then(with_unit_h33);
    let mask = if h.is_some() {
        try_collect(r.inliers.iter().map(|&b| u8::from(b)))
    } else {
        try_filled(0u8, n)
    }
    .map_err(to_py)?;
    let mask = PyArray1::from_vec(py, mask).reshape([n, 1])?;
    Ok((h.map(|h| matrix_out(py, &h)), mask))
}
