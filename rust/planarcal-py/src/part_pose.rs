//! Each part's centroid on the plane and its axis (planarcal_core::part_pose): the production
//! loop's per-part arithmetic, one call per frame. The GIL is kept: a frame holds a few
//! parts, microseconds of work.

use numpy::{PyArray1, PyArrayMethods};
use planarcal_core::{
    part_poses as core_part_poses, part_samples as core_part_samples, try_collect, LocalMap,
    PartAxis, SAMPLE_OFFSETS,
};
use pyo3::prelude::*;

use crate::convert::{f64_array, ArrayArg};
use crate::errors::{invalid, to_py};

type Out<'py> = Bound<'py, PyAny>;

/// A float64 array of `shape` holding `values` (C order).
fn array<'py>(py: Python<'py>, values: Vec<f64>, shape: &[usize]) -> PyResult<Out<'py>> {
    Ok(PyArray1::from_vec(py, values).reshape(shape)?.into_any())
}

/// The argument as float64, of shape `rows` x `tail` (`rows` None: any number of rows).
fn rows_of<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    rows: Option<usize>,
    tail: &[usize],
    what: &str,
) -> PyResult<ArrayArg<'py, f64>> {
    let arg = f64_array(obj, name)?;
    let ok = arg.shape.len() == 1 + tail.len()
        && arg.shape[1..] == *tail
        && rows.is_none_or(|n| arg.shape[0] == n);
    if !ok {
        let want = match rows {
            Some(n) => format!("({n}, {})", dims(tail)),
            None => format!("(n, {})", dims(tail)),
        };
        let want = want.replace(", )", ")");
        return Err(invalid(format!(
            "{name} must be {what}, shape {want}, got {:?}",
            arg.shape
        )));
    }
    Ok(arg)
}

fn dims(tail: &[usize]) -> String {
    tail.iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

fn checked_step(step_px: f64) -> PyResult<f64> {
    if step_px.is_finite() && step_px > 0.0 {
        Ok(step_px)
    } else {
        Err(invalid(format!(
            "step_px must be a finite number > 0, got {step_px}"
        )))
    }
}

fn as_points<'a>(arg: &'a ArrayArg<'_, f64>) -> &'a [[f64; 2]] {
    arg.values().as_chunks::<2>().0
}

fn as_moments<'a>(arg: &'a ArrayArg<'_, f64>) -> &'a [[f64; 3]] {
    arg.values().as_chunks::<3>().0
}

/// The mapped samples (7 n, 2) of n parts, checked.
fn samples_of<'py>(obj: &Bound<'py, PyAny>, n: usize) -> PyResult<ArrayArg<'py, f64>> {
    let k = SAMPLE_OFFSETS.len() * n;
    rows_of(
        obj,
        "samples_mm",
        Some(k),
        &[2],
        &format!("one 2-D position per sample point (7 per part, {n} parts)"),
    )
}

/// part_samples(centroids_px, step_px)
/// --
///
/// The points (7 n, 2) at which to map n parts' centroids (n, 2) to get the mapping's
/// derivatives there: blocks of n, the centres, then +x, -x, +y, -y, +x+y, -x-y by step_px.
#[pyfunction]
pub fn part_samples<'py>(
    py: Python<'py>,
    centroids_px: &Bound<'py, PyAny>,
    step_px: f64,
) -> PyResult<Out<'py>> {
    let c = rows_of(centroids_px, "centroids_px", None, &[2], "px")?;
    let step = checked_step(step_px)?;
    let samples = core_part_samples(as_points(&c), step).map_err(to_py)?;
    let n = samples.len();
    let flat = try_collect(samples.into_iter().flatten()).map_err(to_py)?;
    array(py, flat, &[n, 2])
}

/// part_poses(samples_mm, moments_px, areas_px, step_px)
/// --
///
/// Each of n parts' pose from its mapped samples (7 n, 2, from part_samples at step_px), its
/// image area's central second moments (n, 3: [mu20, mu11, mu02] / area, px^2) and its area
/// (n,): (centroids on the plane (n, 2), Jacobians (n, 2, 2), angles_deg (n,), axes_px
/// (n, 2), anisotropy (n,), sigma_deg (n,)).
#[pyfunction]
pub fn part_poses<'py>(
    py: Python<'py>,
    samples_mm: &Bound<'py, PyAny>,
    moments_px: &Bound<'py, PyAny>,
    areas_px: &Bound<'py, PyAny>,
    step_px: f64,
) -> PyResult<(Out<'py>, Out<'py>, Out<'py>, Out<'py>, Out<'py>, Out<'py>)> {
    let m = rows_of(moments_px, "moments_px", None, &[3], "[mu20, mu11, mu02]")?;
    let n = m.shape[0];
    let areas = rows_of(areas_px, "areas_px", Some(n), &[], "one area per part")?;
    let samples = samples_of(samples_mm, n)?;
    let step = checked_step(step_px)?;
    let poses = core_part_poses(as_points(&samples), as_moments(&m), areas.values(), step)
        .map_err(|e| invalid(e.to_string()))?;
    let centroids = poses.iter().flat_map(|p| p.centroid).collect();
    let jac = poses.iter().flat_map(|p| p.local.jacobian).flatten();
    let axes = axes_arrays(py, poses.iter().map(|p| p.axis), n)?;
    Ok((
        array(py, centroids, &[n, 2])?,
        array(py, jac.collect(), &[n, 2, 2])?,
        axes.0,
        axes.1,
        axes.2,
        axes.3,
    ))
}

/// local_maps(samples_mm, step_px)
/// --
///
/// The mapping near each of n parts from its mapped samples (7 n, 2, from part_samples at
/// step_px): (positions (n, 2), Jacobians (n, 2, 2), second derivatives (n, 2, 3):
/// [d2/dx2, d2/dxdy, d2/dy2] of each output coordinate).
#[pyfunction]
pub fn local_maps<'py>(
    py: Python<'py>,
    samples_mm: &Bound<'py, PyAny>,
    step_px: f64,
) -> PyResult<(Out<'py>, Out<'py>, Out<'py>)> {
    let all = rows_of(samples_mm, "samples_mm", None, &[2], "2-D positions")?;
    let k = SAMPLE_OFFSETS.len();
    if all.shape[0] % k != 0 {
        return Err(invalid(format!(
            "samples_mm must hold 7 mapped points per part, got {} points",
            all.shape[0]
        )));
    }
    let n = all.shape[0] / k;
    let step = checked_step(step_px)?;
    let pts = as_points(&all);
    let maps: Vec<LocalMap> = (0..n)
        .filter_map(|i| LocalMap::from_samples(pts, n, i, step))
        .collect();
    Ok((
        array(py, maps.iter().flat_map(|l| l.position).collect(), &[n, 2])?,
        array(
            py,
            maps.iter().flat_map(|l| l.jacobian).flatten().collect(),
            &[n, 2, 2],
        )?,
        array(
            py,
            maps.iter().flat_map(|l| l.hessian).flatten().collect(),
            &[n, 2, 3],
        )?,
    ))
}

/// area_centroids(positions, jacobians, hessians, moments_px)
/// --
///
/// Each part's centroid on the plane (n, 2) from the mapping near its image centroid
/// (positions (n, 2), Jacobians (n, 2, 2), second derivatives (n, 2, 3), as local_maps gives
/// them) and its image area's central second moments (n, 3); NaN where not finite.
#[pyfunction]
pub fn area_centroids<'py>(
    py: Python<'py>,
    positions: &Bound<'py, PyAny>,
    jacobians: &Bound<'py, PyAny>,
    hessians: &Bound<'py, PyAny>,
    moments_px: &Bound<'py, PyAny>,
) -> PyResult<Out<'py>> {
    let pos = rows_of(positions, "positions", None, &[2], "2-D positions")?;
    let n = pos.shape[0];
    let jac = rows_of(jacobians, "jacobians", Some(n), &[2, 2], "one per part")?;
    let hes = rows_of(hessians, "hessians", Some(n), &[2, 3], "one per part")?;
    let m = rows_of(
        moments_px,
        "moments_px",
        Some(n),
        &[3],
        "[mu20, mu11, mu02]",
    )?;
    let (jv, hv) = (jac.values(), hes.values());
    let out = (0..n).flat_map(|i| {
        let j = &jv[4 * i..4 * i + 4];
        let h = &hv[6 * i..6 * i + 6];
        LocalMap {
            position: as_points(&pos)[i],
            jacobian: [[j[0], j[1]], [j[2], j[3]]],
            hessian: [[h[0], h[1], h[2]], [h[3], h[4], h[5]]],
        }
        .area_centroid(as_moments(&m)[i])
    });
    array(py, out.collect(), &[n, 2])
}

/// part_axes(moments_px, areas_px, jacobians=None)
/// --
///
/// Each part's axis from its image moments (n, 3), its area (n,) and the mapping's Jacobian
/// at its centroid (n, 2, 2; None: the image's own frame): (angles_deg (n,), axes_px (n, 2),
/// anisotropy (n,), sigma_deg (n,)).
#[pyfunction]
#[pyo3(signature = (moments_px, areas_px, jacobians=None))]
pub fn part_axes<'py>(
    py: Python<'py>,
    moments_px: &Bound<'py, PyAny>,
    areas_px: &Bound<'py, PyAny>,
    jacobians: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Out<'py>, Out<'py>, Out<'py>, Out<'py>)> {
    let m = rows_of(moments_px, "moments_px", None, &[3], "[mu20, mu11, mu02]")?;
    let n = m.shape[0];
    let areas = rows_of(areas_px, "areas_px", Some(n), &[], "one area per part")?;
    let jac = match jacobians {
        Some(j) => Some(rows_of(j, "jacobian", Some(n), &[2, 2], "one per part")?),
        None => None,
    };
    let (mv, av) = (as_moments(&m), areas.values());
    let axes = (0..n).map(|i| {
        let j = match &jac {
            Some(j) => {
                let v = &j.values()[4 * i..4 * i + 4];
                [[v[0], v[1]], [v[2], v[3]]]
            }
            None => [[1.0, 0.0], [0.0, 1.0]],
        };
        PartAxis::new(mv[i], av[i], j)
    });
    axes_arrays(py, axes, n)
}

/// (angles_deg, axes_px, anisotropy, sigma_deg) arrays of n axes.
fn axes_arrays<'py>(
    py: Python<'py>,
    axes: impl Iterator<Item = PartAxis>,
    n: usize,
) -> PyResult<(Out<'py>, Out<'py>, Out<'py>, Out<'py>)> {
    let (mut angles, mut dirs, mut aniso, mut sigma) = (
        Vec::with_capacity(n),
        Vec::with_capacity(2 * n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    for a in axes {
        angles.push(a.angle_deg);
        dirs.extend(a.axis_px);
        aniso.push(a.anisotropy);
        sigma.push(a.sigma_deg);
    }
    Ok((
        array(py, angles, &[n])?,
        array(py, dirs, &[n, 2])?,
        array(py, aniso, &[n])?,
        array(py, sigma, &[n])?,
    ))
}
