//! Point transforms: the native transform_points and OpenCV's perspectiveTransform.

use numpy::{PyArrayDyn, PyArrayMethods};
use planarcal_core::{invert, Coord, Homography, Orientation, PointReport, Projective};
use pyo3::prelude::*;

use crate::convert::{
    f64_array, flag, float_array, matrix3, point_count, points2, text, uninit_array, ArrayArg,
    Floats,
};
use crate::errors::{invalid, no_image, to_py};

/// Above this many points a transform runs with the GIL released.
pub const DETACH_MIN_POINTS: usize = 4096;

/// What to do with points that have no image.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum OnInvalid {
    Raise,
    Fill,
}

pub fn on_invalid(value: &str, fill_name: &str) -> PyResult<OnInvalid> {
    match value {
        "raise" => Ok(OnInvalid::Raise),
        v if v == fill_name => Ok(OnInvalid::Fill),
        v => Err(invalid(format!(
            "invalid must be \"raise\" or \"{fill_name}\", got {v:?}"
        ))),
    }
}

/// Runs `work` on the calling thread for small batches, with the GIL released for large ones.
pub fn maybe_detach<T: Send>(py: Python<'_>, n: usize, work: impl FnOnce() -> T + Send) -> T {
    if n >= DETACH_MIN_POINTS {
        py.detach(work)
    } else {
        work()
    }
}

/// A new array of the given shape, filled by `fill` (with the GIL released when it holds many
/// points) before Python can see it. It is not zeroed first: that costs 10% at 10^4 points.
/// `fill` must write every element; the kernels it wraps (apply_all, map_indexed) write
/// every index of an output as long as their input, which is checked here to match it.
pub fn new_array<'py, T: numpy::Element + Coord, R: Send>(
    py: Python<'py>,
    shape: &[usize],
    input_len: usize,
    points: usize,
    fill: impl FnOnce(&mut [T]) -> R + Send,
) -> PyResult<(Bound<'py, PyArrayDyn<T>>, R)> {
    let len: usize = shape.iter().product();
    if len != input_len {
        return Err(invalid(format!(
            "internal error: output of {len} values for an input of {input_len}"
        )));
    }
    // SAFETY: fresh, C-contiguous, aligned and not yet visible to Python (no other
    // reference can alias it); every element is written by `fill` (see above).
    let out = unsafe { uninit_array::<T>(py, shape) }?;
    let slice = unsafe { out.as_slice_mut() }.map_err(|e| invalid(format!("output: {e}")))?;
    let report = maybe_detach(py, points, || fill(slice));
    Ok((out, report))
}

/// transform_points(h, points, inverse=False, invalid="raise")
/// --
///
/// Points (N x 2, float64) mapped through H (or H^-1); no-image points raise or become NaN.
#[pyfunction]
pub fn transform_points<'py>(
    py: Python<'py>,
    h: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
    inverse: &Bound<'py, PyAny>,
    invalid: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let inverse = flag(inverse, "inverse")?;
    let mode = on_invalid(text(invalid, "invalid")?.to_str()?, "nan")?;
    let mut m = matrix3(h, "h")?;
    if inverse {
        m = invert(&m).map_err(to_py)?;
    }
    let t = Homography::from_matrix(&m).map_err(to_py)?;
    let pts = points2(points, "points")?;
    let src = pts.as_points();
    let n = src.len();
    let (out, report) = new_array::<f64, _>(py, &[n, 2], 2 * n, n, |o| {
        t.apply_all(src, o.as_chunks_mut::<2>().0, Orientation::Oriented)
    })?;
    if mode == OnInvalid::Raise && report.invalid() > 0 {
        return Err(no_image(&report, n, "points", None));
    }
    Ok(out)
}

fn project<'py, T, const S: usize, const D: usize>(
    py: Python<'py>,
    m: &[f64],
    src: &ArrayArg<'py, T>,
) -> PyResult<(Bound<'py, PyArrayDyn<T>>, PointReport)>
where
    T: numpy::Element + Coord,
{
    let p = Projective::<S, D>::from_row_major(m).map_err(to_py)?;
    let input = src.values().as_chunks::<S>().0;
    let mut shape = src.shape.clone();
    if let Some(last) = shape.last_mut() {
        *last = D;
    }
    // D values out for each point's S values in.
    new_array::<T, _>(py, &shape, input.len() * D, input.len(), |o| {
        p.apply_all(input, o.as_chunks_mut::<D>().0, Orientation::Unoriented)
    })
}

/// perspective_transform(src, m)
/// --
///
/// OpenCV's perspectiveTransform: same shape and float dtype out; None for empty input.
#[pyfunction]
pub fn perspective_transform<'py>(
    py: Python<'py>,
    src: &Bound<'py, PyAny>,
    m: &Bound<'py, PyAny>,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    let src = float_array(src, "src")?;
    let shape = match &src {
        Floats::F32(a) => a.shape.clone(),
        Floats::F64(a) => a.shape.clone(),
    };
    let scn = match shape.last() {
        Some(&c @ (2 | 3)) if shape.len() >= 2 => c,
        _ => {
            return Err(invalid(format!(
                "src must hold 2-D or 3-D points, shape (N, 2), (N, 1, 2), (1, N, 2) or the same \
                 with 3; got {shape:?}"
            )))
        }
    };
    let n = point_count(&shape, scn, "src")?;
    let m = f64_array(m, "m")?;
    let dcn = match m.shape.as_slice() {
        [rows, cols] if *cols == scn + 1 && (*rows == 3 || *rows == 4) => rows - 1,
        s => {
            return Err(invalid(format!(
                "m must be {r} x {c} (or {r2} x {c}) for {scn}-D points, got shape {s:?}",
                r = scn + 1,
                c = scn + 1,
                r2 = if scn == 2 { 4 } else { 3 },
            )))
        }
    };
    if n == 0 {
        return Ok(None);
    }
    let mv = m.values();
    macro_rules! run {
        ($a:expr, $t:ty) => {
            match (scn, dcn) {
                (2, 2) => project::<$t, 2, 2>(py, mv, $a).map(|(o, r)| (o.into_any(), r)),
                (2, 3) => project::<$t, 2, 3>(py, mv, $a).map(|(o, r)| (o.into_any(), r)),
                (3, 2) => project::<$t, 3, 2>(py, mv, $a).map(|(o, r)| (o.into_any(), r)),
                _ => project::<$t, 3, 3>(py, mv, $a).map(|(o, r)| (o.into_any(), r)),
            }
        };
    }
    let (out, report) = match &src {
        Floats::F32(a) => run!(a, f32),
        Floats::F64(a) => run!(a, f64),
    }?;
    if report.invalid() > 0 {
        return Err(no_image(&report, n, "points", None));
    }
    Ok(Some(out))
}
