//! Object IDs from frame to frame (planarcal_core::tracking): one call per frame; and each
//! frame's JSON line (planarcal_core::FrameObjects).

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1};
use planarcal_core::{try_collect, FrameObjects, Tracks as CoreTracks};
use pyo3::prelude::*;

use crate::convert::{f64_array, points2};
use crate::errors::{invalid, to_py};

/// Tracks(max_jump, max_missing)
/// --
///
/// The live tracks of the production loop: nearest-neighbour association on the plane,
/// closest pairs first, within max_jump; a track unseen for more than max_missing frames
/// ends.
#[pyclass(module = "planarcal._core")]
pub struct Tracks {
    inner: CoreTracks,
}

#[pymethods]
impl Tracks {
    #[new]
    fn new(max_jump: f64, max_missing: u64) -> PyResult<Self> {
        if !(max_jump.is_finite() && max_jump > 0.0) {
            return Err(invalid(format!(
                "max_jump must be a finite number > 0, got {max_jump}"
            )));
        }
        Ok(Tracks {
            // More frames than u32 holds is forever (over two years at 60 fps).
            inner: CoreTracks::new(max_jump, max_missing.min(u32::MAX as u64) as u32),
        })
    }

    /// update(positions)
    /// --
    ///
    /// The IDs (int64, one per row) of one frame's objects at `positions` (N x 2); the tracks
    /// then move to them.
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        positions: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let pts = points2(positions, "positions")?;
        let ids = self.inner.update(pts.as_points()).map_err(to_py)?;
        let ids = try_collect(ids.into_iter().map(|id| id as i64)).map_err(to_py)?;
        Ok(PyArray1::from_vec(py, ids))
    }

    /// live()
    /// --
    ///
    /// (ids int64 (n,), positions float64 (n, 2)) of the live tracks.
    fn live<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyArray1<i64>>, Bound<'py, PyAny>)> {
        let n = self.inner.len();
        let ids = PyArray1::from_iter(py, self.inner.live().map(|(id, _)| id as i64));
        let flat: Vec<f64> = self.inner.live().flat_map(|(_, p)| p).collect();
        Ok((
            ids,
            PyArray1::from_vec(py, flat).reshape([n, 2])?.into_any(),
        ))
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }
}

/// frame_json(index, timestamp, ids, centroids_px, world_mm, std_mm, angles_deg, coords)
/// --
///
/// One frame's compact JSON line (no newline): {"frame", "t", "coords", "objects": [{"id",
/// "px", "mm", "std_mm", "angle_deg"}, ...]}, the objects by ID (ids: int64 (n,);
/// centroids_px, world_mm: n x 2; std_mm, angles_deg: n; coords: the frame of reference
/// of mm and angle_deg), positions to 1e-3 px and 1e-4 mm, std to 1e-5 mm, angles to
/// 1e-2 degree, the time to the microsecond; a value that is not finite is written as null.
#[pyfunction]
#[allow(clippy::too_many_arguments)] // one per field of the line, as the loop holds them
pub fn frame_json(
    index: i64,
    timestamp: f64,
    ids: PyReadonlyArray1<'_, i64>,
    centroids_px: &Bound<'_, PyAny>,
    world_mm: &Bound<'_, PyAny>,
    std_mm: &Bound<'_, PyAny>,
    angles_deg: &Bound<'_, PyAny>,
    coords: &str,
) -> PyResult<String> {
    let ids = ids.as_slice().map_err(|e| invalid(format!("ids: {e}")))?;
    let (px, mm) = (
        points2(centroids_px, "centroids_px")?,
        points2(world_mm, "world_mm")?,
    );
    let std = f64_array(std_mm, "std_mm")?;
    let angles = f64_array(angles_deg, "angles_deg")?;
    FrameObjects {
        index,
        time: timestamp,
        ids,
        centroids_px: px.as_points(),
        world_mm: mm.as_points(),
        std_mm: std.values(),
        angles_deg: angles.values(),
        coords,
    }
    .json_line()
    .map_err(|e| invalid(e.to_string()))
}
