//! A frame's traced contours to measured objects (planarcal_core::contours), in one call per
//! frame with the GIL released: the per-object work of object location.

use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use planarcal_core::{
    fewest_points, measure_contours as measure, median_grey as median, reading_order as order,
    try_collect, ContourFilter, GreyU8,
};
use pyo3::prelude::*;
use pyo3::types::PyList;

use crate::convert::{f64_array, points2, u8_image};
use crate::errors::{invalid, to_py};

/// The objects' values, as NumPy arrays (index, area, centroid, bbox), a list of outlines
/// and their moments.
type Measured<'py> = (
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyList>,
    Bound<'py, PyAny>,
);

/// measure_contours(grey, contours, min_area, max_area, keep_border=False, subpixel=True,
///                  outlines=True)
/// --
///
/// (index, area, centroid, bbox, outlines, moments) of the objects among `contours`, in reading order
/// (see reading_order), (int32 arrays of
/// shape (K, 1, 2) or (K, 2), as cv2.findContours traces them in `grey`, an H x W uint8
/// image): those whose enclosed area is within [min_area, max_area] px^2 and, unless
/// keep_border, whose bounding box does not touch the image's border. With subpixel, each
/// outline is moved to the grey-level edge (sub-pixel) and the area, centroid and moments
/// are the refined outline's. index: int64 (n,), positions in `contours`; area: float64 (n,);
/// centroid: float64 (n, 2); bbox: int64 (n, 4), x, y, width, height of the traced contour;
/// outlines: n float64 arrays (K, 2), or an empty list when not asked for (the production
/// loop needs only the centroids and moments); moments: float64 (n, 3), the enclosed area's
/// central second moments over its area, [mu20, mu11, mu02] / area, px^2 (Green's theorem
/// over the outline; zeros for an outline enclosing no area).
#[pyfunction]
#[pyo3(signature = (
    grey, contours, min_area, max_area, keep_border = false, subpixel = true, outlines = true
))]
// The Python signature's keywords, one argument each.
#[allow(clippy::too_many_arguments)]
pub fn measure_contours<'py>(
    py: Python<'py>,
    grey: &Bound<'py, PyAny>,
    contours: &Bound<'py, PyAny>,
    min_area: f64,
    max_area: f64,
    keep_border: bool,
    subpixel: bool,
    outlines: bool,
) -> PyResult<Measured<'py>> {
    let img = u8_image(grey, "grey")?;
    let (height, width) = match img.shape[..] {
        [h, w] if h > 0 && w > 0 => (h, w),
        _ => {
            return Err(invalid(format!(
                "grey must be a two-dimensional image (H x W), got shape {:?}",
                img.shape
            )))
        }
    };
    if min_area.is_nan() || max_area.is_nan() {
        return Err(invalid(format!(
            "min_area and max_area must be numbers, got {min_area} and {max_area}"
        )));
    }
    // Contours too short to enclose min_area are skipped before they are borrowed (a real
    // frame's noise traces many).
    let shortest = fewest_points(min_area);
    let mut held = Vec::new();
    let mut positions = Vec::new();
    for (i, item) in contours.try_iter()?.enumerate() {
        let item = item?;
        let array = item.cast::<PyArrayDyn<i32>>().map_err(|_| {
            invalid(format!(
                "contours[{i}] must be an int32 array of shape (K, 1, 2) or (K, 2), as \
                 cv2.findContours gives"
            ))
        })?;
        let k = match array.shape() {
            [k, 1, 2] | [k, 2] => *k,
            shape => {
                return Err(invalid(format!(
                    "contours[{i}] must have shape (K, 1, 2) or (K, 2), got {shape:?}"
                )))
            }
        };
        if (k as f64) < shortest || k == 0 {
            continue;
        }
        let ro = array
            .try_readonly()
            .map_err(|e| invalid(format!("contours[{i}] cannot be read: {e}")))?;
        if ro.as_slice().is_err() {
            return Err(invalid(format!("contours[{i}] must be C-contiguous")));
        }
        held.push(ro);
        positions.push(i);
    }
    let slices: Vec<&[[i32; 2]]> = held
        .iter()
        .map(|a| a.as_slice().map(|s| s.as_chunks::<2>().0).unwrap_or(&[]))
        .collect();
    let image = GreyU8 {
        pixels: img.values(),
        width,
        height,
    };
    let filter = ContourFilter {
        min_area,
        max_area,
        keep_border,
        subpixel,
    };
    let found = py
        .detach(|| measure(image, &slices, &filter))
        .map_err(to_py)?;
    let n = found.len();
    let index = try_collect(found.iter().map(|o| positions[o.contour] as i64)).map_err(to_py)?;
    let area = try_collect(found.iter().map(|o| o.area)).map_err(to_py)?;
    let centroid = try_collect(found.iter().flat_map(|o| o.centroid)).map_err(to_py)?;
    let bbox = try_collect(found.iter().flat_map(|o| o.bbox)).map_err(to_py)?;
    let moments = try_collect(found.iter().flat_map(|o| o.moments)).map_err(to_py)?;
    let arrays = PyList::empty(py);
    for o in found.iter().filter(|_| outlines) {
        let flat = try_collect(o.outline.iter().flatten().copied()).map_err(to_py)?;
        arrays.append(PyArray1::from_vec(py, flat).reshape([o.outline.len(), 2])?)?;
    }
    Ok((
        PyArray1::from_vec(py, index).into_any(),
        PyArray1::from_vec(py, area).into_any(),
        PyArray1::from_vec(py, centroid).reshape([n, 2])?.into_any(),
        PyArray1::from_vec(py, bbox).reshape([n, 4])?.into_any(),
        arrays,
        PyArray1::from_vec(py, moments).reshape([n, 3])?.into_any(),
    ))
}

/// reading_order(centroids, heights)
/// --
///
/// Indices (int64) of objects in reading order: rows from the top (an object joins a row
/// when its centre is within half the median of `heights` of the row's first), left to right
/// within a row. centroids: N x 2 px; heights: N.
#[pyfunction]
pub fn reading_order<'py>(
    py: Python<'py>,
    centroids: &Bound<'py, PyAny>,
    heights: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let c = points2(centroids, "centroids")?;
    let h = f64_array(heights, "heights")?;
    let points = c.as_points();
    if h.values().len() != points.len() {
        return Err(invalid(format!(
            "heights must hold one value per centroid ({}), got {}",
            points.len(),
            h.values().len()
        )));
    }
    let indices = order(points, h.values()).map_err(to_py)?;
    let indices = try_collect(indices.into_iter().map(|i| i as i64)).map_err(to_py)?;
    Ok(PyArray1::from_vec(py, indices))
}

/// median_grey(grey, row_step=16, col_step=2)
/// --
///
/// The median grey level (an int) of every col_step-th pixel of every row_step-th row of
/// `grey` (H x W uint8).
#[pyfunction]
#[pyo3(signature = (grey, row_step = 16, col_step = 2))]
pub fn median_grey(grey: &Bound<'_, PyAny>, row_step: usize, col_step: usize) -> PyResult<u8> {
    let img = u8_image(grey, "grey")?;
    let [height, width] = img.shape[..] else {
        return Err(invalid(format!(
            "grey must be a two-dimensional image (H x W), got shape {:?}",
            img.shape
        )));
    };
    if row_step == 0 || col_step == 0 {
        return Err(invalid("row_step and col_step must be >= 1"));
    }
    let image = GreyU8 {
        pixels: img.values(),
        width,
        height,
    };
    Ok(median(image, row_step, col_step))
}
