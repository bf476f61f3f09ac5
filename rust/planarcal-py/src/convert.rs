//! Arguments in: validate shape and dtype, borrow a C-contiguous float64 (or float32) buffer
//! without copying, copy only what has to be converted (other dtypes, strided views, lists).

use numpy::{
    PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyModule;

use crate::errors::invalid;

static NUMPY: PyOnceLock<Py<PyModule>> = PyOnceLock::new();

fn numpy(py: Python<'_>) -> PyResult<&Bound<'_, PyModule>> {
    NUMPY
        .get_or_try_init(py, || PyModule::import(py, "numpy").map(Bound::unbind))
        .map(|m| m.bind(py))
}

/// Values of an array argument in C order, borrowed from NumPy when they already are.
pub enum Values<'py, T: numpy::Element> {
    Borrowed(PyReadonlyArrayDyn<'py, T>),
    Owned(Vec<T>),
}

impl<T: numpy::Element> Values<'_, T> {
    pub fn as_slice(&self) -> &[T] {
        match self {
            // A C-contiguous array always gives its slice; an empty slice is the safe fallback.
            Values::Borrowed(a) => a.as_slice().unwrap_or(&[]),
            Values::Owned(v) => v,
        }
    }
}

/// A real-valued array argument with its shape.
pub struct ArrayArg<'py, T: numpy::Element> {
    pub values: Values<'py, T>,
    pub shape: Vec<usize>,
}

/// Any array-like as a NumPy array of a real dtype (integer or floating), else a clear error.
fn real_ndarray<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyUntypedArray>> {
    let py = obj.py();
    let arr = match obj.cast::<PyUntypedArray>() {
        Ok(a) => a.clone(),
        Err(_) => {
            let converted = numpy(py)?
                .call_method1(intern!(py, "asarray"), (obj,))
                .map_err(|e| {
                    invalid(format!(
                        "{name} must be an array of numbers; converting {} failed: {e}",
                        type_name(obj)
                    ))
                })?;
            converted.cast_into::<PyUntypedArray>().map_err(|_| {
                invalid(format!(
                    "{name} must be an array of numbers, got {}",
                    type_name(obj)
                ))
            })?
        }
    };
    let kind = arr.dtype().kind();
    if !matches!(kind, b'f' | b'i' | b'u') {
        return Err(invalid(format!(
            "{name} must hold real numbers (integer or floating), got dtype {}",
            arr.dtype()
        )));
    }
    Ok(arr)
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "an object".into())
}

fn borrow_or_copy<'py, T: numpy::Element + Copy>(
    a: &Bound<'py, PyArrayDyn<T>>,
    name: &str,
) -> PyResult<Values<'py, T>> {
    let ro = a
        .try_readonly()
        .map_err(|e| invalid(format!("{name} cannot be read: {e}")))?;
    if ro.is_c_contiguous() {
        Ok(Values::Borrowed(ro))
    } else {
        Ok(Values::Owned(ro.as_array().iter().copied().collect()))
    }
}

/// The argument as float64 values.
pub fn f64_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<ArrayArg<'py, f64>> {
    // Fast path: already a float64 ndarray.
    if let Ok(a) = obj.cast::<PyArrayDyn<f64>>() {
        return Ok(ArrayArg {
            shape: a.shape().to_vec(),
            values: borrow_or_copy(a, name)?,
        });
    }
    let arr = real_ndarray(obj, name)?;
    let shape = arr.shape().to_vec();
    let py = obj.py();
    let converted = numpy(py)?.call_method1(
        intern!(py, "ascontiguousarray"),
        (&arr, intern!(py, "float64")),
    )?;
    let a = converted
        .cast::<PyArrayDyn<f64>>()
        .map_err(|_| invalid(format!("{name} could not be converted to float64")))?;
    Ok(ArrayArg {
        shape,
        values: borrow_or_copy(a, name)?,
    })
}

/// float32 input stays float32 (OpenCV's perspectiveTransform keeps the input dtype).
pub enum Floats<'py> {
    F32(ArrayArg<'py, f32>),
    F64(ArrayArg<'py, f64>),
}

pub fn float_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Floats<'py>> {
    if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        return Ok(Floats::F32(ArrayArg {
            shape: a.shape().to_vec(),
            values: borrow_or_copy(a, name)?,
        }));
    }
    f64_array(obj, name).map(Floats::F64)
}

/// Number of points in an array of shape (N, D), (N, 1, D) or (1, N, D).
pub fn point_count(shape: &[usize], dims: usize, name: &str) -> PyResult<usize> {
    match *shape {
        [n, d] if d == dims => Ok(n),
        [n, 1, d] if d == dims => Ok(n),
        [1, n, d] if d == dims => Ok(n),
        _ => Err(invalid(format!(
            "{name} must have shape (N, {dims}), (N, 1, {dims}) or (1, N, {dims}), got {shape:?}"
        ))),
    }
}

/// A points argument as (x, y) pairs.
pub struct Points2<'py>(pub ArrayArg<'py, f64>);

impl Points2<'_> {
    pub fn as_points(&self) -> &[[f64; 2]] {
        self.0.values.as_slice().as_chunks::<2>().0
    }
}

pub fn points2<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Points2<'py>> {
    let arg = f64_array(obj, name)?;
    point_count(&arg.shape, 2, name)?;
    Ok(Points2(arg))
}

/// A 3 x 3 matrix argument.
pub fn matrix3(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<nalgebra::Matrix3<f64>> {
    let arg = f64_array(obj, name)?;
    if arg.shape != [3, 3] {
        return Err(invalid(format!(
            "{name} must be a 3 x 3 matrix, got shape {:?}",
            arg.shape
        )));
    }
    Ok(nalgebra::Matrix3::from_row_slice(arg.values.as_slice()))
}
