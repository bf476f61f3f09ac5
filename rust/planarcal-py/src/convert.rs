//! Arguments in: validate shape and dtype, borrow a C-contiguous, aligned float64 (or
//! float32) buffer without copying; let NumPy copy whatever has to be converted (other dtypes,
//! strided, misaligned or byte-swapped arrays, lists) into a fresh array that is all three.

use std::ptr;

use numpy::npyffi::{get_type_object, npy_intp, NpyTypes, PY_ARRAY_API};
use numpy::{
    PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyModule;

use crate::errors::{invalid_arg, wrong_type};

static NUMPY: PyOnceLock<Py<PyModule>> = PyOnceLock::new();

fn numpy(py: Python<'_>) -> PyResult<&Bound<'_, PyModule>> {
    NUMPY
        .get_or_try_init(py, || PyModule::import(py, "numpy").map(Bound::unbind))
        .map(|m| m.bind(py))
}

/// A real-valued array argument: a borrowed C-contiguous, aligned buffer and its shape.
pub struct ArrayArg<'py, T: numpy::Element> {
    array: PyReadonlyArrayDyn<'py, T>,
    pub shape: Vec<usize>,
}

impl<T: numpy::Element> ArrayArg<'_, T> {
    /// The values in C order.
    pub fn values(&self) -> &[T] {
        // `borrow` admits only arrays whose slice exists: the fallback is unreachable.
        self.array.as_slice().unwrap_or(&[])
    }
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
                    invalid_arg(
                        name,
                        format!(
                            "{name} must be an array of numbers; converting {} failed: {e}",
                            type_name(obj)
                        ),
                    )
                })?;
            converted.cast_into::<PyUntypedArray>().map_err(|_| {
                invalid_arg(
                    name,
                    format!("{name} must be an array of numbers, got {}", type_name(obj)),
                )
            })?
        }
    };
    let kind = arr.dtype().kind();
    if !matches!(kind, b'f' | b'i' | b'u') {
        return Err(invalid_arg(
            name,
            format!(
                "{name} must hold real numbers (integer or floating), got dtype {}",
                arr.dtype()
            ),
        ));
    }
    Ok(arr)
}

/// `repr(obj)` for a message (the type's name if even that fails).
pub fn shown(obj: &Bound<'_, PyAny>) -> String {
    obj.repr()
        .map(|r| r.to_string())
        .unwrap_or_else(|_| obj.get_type().to_string())
}

/// A True/False option (Python's bool or NumPy's bool_), else an ArgumentTypeError naming it.
pub fn flag(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<bool> {
    obj.extract::<bool>()
        .map_err(|_| wrong_type(format!("{name} must be True or False, got {}", shown(obj))))
}

/// A text option, else an ArgumentTypeError naming it.
pub fn text<'a, 'py>(
    obj: &'a Bound<'py, PyAny>,
    name: &str,
) -> PyResult<&'a Bound<'py, pyo3::types::PyString>> {
    obj.cast::<pyo3::types::PyString>()
        .map_err(|_| wrong_type(format!("{name} must be a string, got {}", shown(obj))))
}

/// An iterable argument's iterator, else an ArgumentTypeError naming it.
pub fn iterate<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    what: &str,
) -> PyResult<Bound<'py, pyo3::types::PyIterator>> {
    obj.try_iter()
        .map_err(|_| wrong_type(format!("{name} must be {what}, got {}", shown(obj))))
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "an object".into())
}

/// Borrows the array's buffer, which must be C-contiguous and aligned; None otherwise.
fn borrow<'py, T: numpy::Element>(
    a: &Bound<'py, PyArrayDyn<T>>,
    name: &str,
) -> PyResult<Option<ArrayArg<'py, T>>> {
    if !(a.is_c_contiguous() && a.is_aligned()) {
        return Ok(None);
    }
    let ro = a
        .try_readonly()
        .map_err(|e| invalid_arg(name, format!("{name} cannot be read: {e}")))?;
    if ro.as_slice().is_err() {
        return Ok(None);
    }
    Ok(Some(ArrayArg {
        shape: a.shape().to_vec(),
        array: ro,
    }))
}

/// A fresh C-contiguous, aligned copy of a real-valued array-like, as `dtype`.
fn fresh_copy<'py, T: numpy::Element>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    dtype: &str,
) -> PyResult<ArrayArg<'py, T>> {
    let arr = real_ndarray(obj, name)?;
    let py = obj.py();
    let kwargs = pyo3::types::PyDict::new(py);
    kwargs.set_item(intern!(py, "dtype"), dtype)?;
    kwargs.set_item(intern!(py, "order"), intern!(py, "C"))?;
    kwargs.set_item(intern!(py, "copy"), true)?;
    let copy = numpy(py)?.call_method(intern!(py, "array"), (&arr,), Some(&kwargs))?;
    let a = copy
        .cast::<PyArrayDyn<T>>()
        .map_err(|_| invalid_arg(name, format!("{name} could not be converted to {dtype}")))?;
    borrow(a, name)?.ok_or_else(|| invalid_arg(name, format!("{name} could not be copied")))
}

/// The argument as float64 values.
pub fn f64_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<ArrayArg<'py, f64>> {
    // Fast path: a float64 ndarray that can be borrowed as it is.
    if let Ok(a) = obj.cast::<PyArrayDyn<f64>>() {
        if let Some(arg) = borrow(a, name)? {
            return Ok(arg);
        }
    }
    fresh_copy(obj, name, "float64")
}

/// An 8-bit image argument (uint8 only: other dtypes would be rounded or clipped silently),
/// borrowed when C-contiguous, else copied into a C-contiguous array.
pub fn u8_image<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<ArrayArg<'py, u8>> {
    let Ok(a) = obj.cast::<PyArrayDyn<u8>>() else {
        let what = real_ndarray(obj, name)
            .map(|a| format!("dtype {}", a.dtype()))
            .unwrap_or_else(|_| type_name(obj));
        return Err(invalid_arg(
            name,
            format!("{name} must be an 8-bit (uint8) image, got {what}"),
        ));
    };
    match borrow(a, name)? {
        Some(arg) => Ok(arg),
        None => fresh_copy(obj, name, "uint8"),
    }
}

/// float32 input stays float32 (OpenCV's perspectiveTransform keeps the input dtype).
pub enum Floats<'py> {
    F32(ArrayArg<'py, f32>),
    F64(ArrayArg<'py, f64>),
}

pub fn float_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Floats<'py>> {
    if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        return match borrow(a, name)? {
            Some(arg) => Ok(Floats::F32(arg)),
            None => fresh_copy(obj, name, "float32").map(Floats::F32),
        };
    }
    f64_array(obj, name).map(Floats::F64)
}

/// Number of points in an array of shape (N, D), (N, 1, D) or (1, N, D).
pub fn point_count(shape: &[usize], dims: usize, name: &str) -> PyResult<usize> {
    match *shape {
        [n, d] if d == dims => Ok(n),
        [n, 1, d] if d == dims => Ok(n),
        [1, n, d] if d == dims => Ok(n),
        _ => Err(invalid_arg(
            name,
            format!(
            "{name} must have shape (N, {dims}), (N, 1, {dims}) or (1, N, {dims}), got {shape:?}"
        ),
        )),
    }
}

/// A points argument as (x, y) pairs.
pub struct Points2<'py>(pub ArrayArg<'py, f64>);

impl Points2<'_> {
    pub fn as_points(&self) -> &[[f64; 2]] {
        self.0.values().as_chunks::<2>().0
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
    let values = arg.values();
    if arg.shape != [3, 3] || values.len() != 9 {
        return Err(invalid_arg(
            name,
            format!("{name} must be a 3 x 3 matrix, got shape {:?}", arg.shape),
        ));
    }
    Ok(nalgebra::Matrix3::from_row_slice(values))
}

/// A new C-contiguous array of `shape`, its elements not yet written. NumPy's failure to
/// allocate it is a MemoryError (rust-numpy's own constructors panic on it).
///
/// # Safety
/// The caller must write every element before Python can read the array.
pub unsafe fn uninit_array<'py, T: numpy::Element>(
    py: Python<'py>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let mut dims = shape
        .iter()
        .map(|&d| npy_intp::try_from(d))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|_| pyo3::exceptions::PyMemoryError::new_err(format!("shape {shape:?}")))?;
    // SAFETY: NumPy's documented constructor; it steals the dtype reference, and the null
    // strides and data ask it to allocate a C-contiguous buffer itself.
    let raw = unsafe {
        PY_ARRAY_API.PyArray_NewFromDescr(
            py,
            get_type_object(py, NpyTypes::PyArray_Type),
            T::get_dtype(py).into_dtype_ptr(),
            dims.len() as std::os::raw::c_int,
            dims.as_mut_ptr(),
            ptr::null_mut(),
            ptr::null_mut(),
            0,
            ptr::null_mut(),
        )
    };
    // SAFETY: a new reference, or null with the Python error set (MemoryError, ValueError for
    // a shape too large); an array of T's dtype when not null.
    let any = unsafe { Bound::from_owned_ptr_or_err(py, raw) }?;
    Ok(unsafe { any.cast_into_unchecked() })
}
