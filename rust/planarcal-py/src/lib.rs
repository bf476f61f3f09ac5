//! planarcal._core: the bindings of planarcal-core. Each function validates its arguments,
//! borrows NumPy buffers without copying, releases the GIL for large work, and returns NumPy
//! arrays it allocated itself. The public API and its documentation live in Python.

mod contours;
mod convert;
mod dot_centres;
mod errors;
mod estimate;
mod lens;
mod part_pose;
mod plane_model;
mod reprojection;
mod robust;
mod signals;
mod tracking;
mod transform;

use pyo3::prelude::*;

/// Called by Python's os.register_at_fork in a forked child: see planarcal_core::threads.
#[pyfunction]
fn _after_fork_in_child() {
    planarcal_core::forked_child();
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<lens::RadialLens>()?;
    m.add_class::<lens::LensStd>()?;
    m.add_class::<plane_model::FittedPlane>()?;
    m.add_class::<tracking::Tracks>()?;
    m.add_class::<robust::RobustResult>()?;
    m.add_function(wrap_pyfunction!(tracking::frame_json, m)?)?;
    m.add_function(wrap_pyfunction!(contours::measure_contours, m)?)?;
    m.add_function(wrap_pyfunction!(contours::reading_order, m)?)?;
    m.add_function(wrap_pyfunction!(contours::median_grey, m)?)?;
    m.add_function(wrap_pyfunction!(dot_centres::refine_dot_centres, m)?)?;
    m.add_function(wrap_pyfunction!(estimate::estimate_homography, m)?)?;
    m.add_function(wrap_pyfunction!(estimate::find_homography, m)?)?;
    m.add_function(wrap_pyfunction!(robust::estimate_homography_robust, m)?)?;
    m.add_function(wrap_pyfunction!(
        robust::estimate_homography_robust_batch,
        m
    )?)?;
    m.add_function(wrap_pyfunction!(robust::find_homography_robust, m)?)?;
    m.add_function(wrap_pyfunction!(transform::transform_points, m)?)?;
    m.add_function(wrap_pyfunction!(transform::perspective_transform, m)?)?;
    m.add_function(wrap_pyfunction!(reprojection::reprojection_errors, m)?)?;
    m.add_function(wrap_pyfunction!(reprojection::error_stats, m)?)?;
    m.add_function(wrap_pyfunction!(part_pose::part_samples, m)?)?;
    m.add_function(wrap_pyfunction!(part_pose::part_poses, m)?)?;
    m.add_function(wrap_pyfunction!(part_pose::local_maps, m)?)?;
    m.add_function(wrap_pyfunction!(part_pose::area_centroids, m)?)?;
    m.add_function(wrap_pyfunction!(part_pose::part_axes, m)?)?;
    m.add("SAMPLES_PER_PART", planarcal_core::SAMPLE_OFFSETS.len())?;
    m.add("MIN_ANISOTROPY", planarcal_core::MIN_ANISOTROPY)?;
    m.add("EDGE_SIGMA_PX", planarcal_core::EDGE_SIGMA_PX)?;
    m.add("MAX_ANGLE_SIGMA_DEG", planarcal_core::MAX_ANGLE_SIGMA_DEG)?;
    m.add_function(wrap_pyfunction!(_after_fork_in_child, m)?)?;
    Ok(())
}
