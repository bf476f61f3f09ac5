//! Batch point transforms through a projective matrix. A point whose image is at infinity
//! (w = 0 to within rounding) or, for an oriented homography, behind the horizon (w < 0) is
//! reported and written as NaN, never turned silently into (0, 0) as OpenCV does. Large
//! batches are split over rayon's threads; results do not depend on the thread count.

use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::error::{HomographyError, Result};
use crate::point_failure::{PointFailure, PointReport};
use crate::threads;

/// Below this many points a batch runs on the calling thread: splitting costs more than it saves.
pub const PARALLEL_MIN_POINTS: usize = 32_768;
const CHUNK_POINTS: usize = 8_192;

/// Whether w < 0 is an error (matrices oriented as this crate returns them) or only w = 0 is
/// (matrices of unknown sign, as OpenCV treats them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Orientation {
    /// Points with w < 0 are behind the horizon.
    Oriented,
    /// Only w = 0 fails.
    Unoriented,
}

/// A coordinate type points are read from and written to; arithmetic is always f64.
pub trait Coord: Copy + Send + Sync + 'static {
    /// The type's NaN, written for a point that cannot be mapped.
    const NAN: Self;
    /// As f64.
    fn get(self) -> f64;
    /// From f64 (rounded to the type).
    fn put(v: f64) -> Self;
    /// Neither NaN nor infinite.
    fn is_finite(self) -> bool;
}

impl Coord for f64 {
    const NAN: Self = f64::NAN;
    #[inline(always)]
    fn get(self) -> f64 {
        self
    }
    #[inline(always)]
    fn put(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
}

impl Coord for f32 {
    const NAN: Self = f32::NAN;
    #[inline(always)]
    fn get(self) -> f64 {
        self as f64
    }
    #[inline(always)]
    fn put(v: f64) -> Self {
        v as f32
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
}

/// A projective map from S- to D-dimensional points: a (D + 1) x (S + 1) matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projective<const S: usize, const D: usize> {
    m: [[f64; 4]; 4],
}

/// Relative size of w, against the rounding of its terms, below which w counts as zero.
const W_ROUNDING: f64 = 8.0 * f64::EPSILON;

impl<const S: usize, const D: usize> Projective<S, D> {
    /// From the (D + 1) x (S + 1) entries in row-major order.
    pub fn from_row_major(entries: &[f64]) -> Result<Self> {
        debug_assert!(S <= 3 && D <= 3 && entries.len() == (D + 1) * (S + 1));
        let mut m = [[0.0; 4]; 4];
        for r in 0..=D {
            for c in 0..=S {
                let v = entries.get(r * (S + 1) + c).copied().unwrap_or(f64::NAN);
                if !v.is_finite() {
                    return Err(HomographyError::NonFiniteMatrix { row: r, col: c });
                }
                m[r][c] = v;
            }
        }
        Ok(Projective { m })
    }

    /// The image of one point, or why it has none.
    #[inline(always)]
    pub fn apply<T: Coord>(
        &self,
        p: &[T; S],
        orientation: Orientation,
    ) -> std::result::Result<[f64; D], PointFailure> {
        let mut x = [0.0; S];
        for k in 0..S {
            if !p[k].is_finite() {
                return Err(PointFailure::NonFinite);
            }
            x[k] = p[k].get();
        }
        let row = &self.m[D];
        let mut w = row[S];
        let mut scale = row[S].abs();
        for k in 0..S {
            let t = row[k] * x[k];
            w += t;
            scale += t.abs();
        }
        if !(w.abs() > W_ROUNDING * scale) {
            return Err(PointFailure::AtInfinity);
        }
        if orientation == Orientation::Oriented && w < 0.0 {
            return Err(PointFailure::BehindHorizon);
        }
        let iw = 1.0 / w;
        let mut out = [0.0; D];
        for (d, o) in out.iter_mut().enumerate() {
            let row = &self.m[d];
            let mut v = row[S];
            for k in 0..S {
                v += row[k] * x[k];
            }
            *o = v * iw;
            if !o.is_finite() {
                return Err(PointFailure::AtInfinity);
            }
        }
        Ok(out)
    }

    /// Maps every point of `src` into `out` (same length), NaN where a point has no image.
    pub fn apply_all<T: Coord>(
        &self,
        src: &[[T; S]],
        out: &mut [[T; D]],
        orientation: Orientation,
    ) -> PointReport {
        let run = |start: usize, src: &[[T; S]], out: &mut [[T; D]]| {
            if self.apply_chunk_fast(src, out, orientation) {
                return PointReport::default();
            }
            // Some point has no image: redo the chunk point by point to say which.
            let mut report = PointReport::default();
            for (k, (p, o)) in src.iter().zip(out.iter_mut()).enumerate() {
                match self.apply(p, orientation).and_then(|y| narrow(&y)) {
                    Ok(v) => *o = v,
                    Err(status) => {
                        *o = [T::NAN; D];
                        report.record(start + k, status);
                    }
                }
            }
            report
        };
        let n = src.len().min(out.len());
        let (src, out) = (&src[..n], &mut out[..n]);
        if n < PARALLEL_MIN_POINTS || !threads::pool_allowed() {
            return run(0, src, out);
        }
        src.par_chunks(CHUNK_POINTS)
            .zip(out.par_chunks_mut(CHUNK_POINTS))
            .enumerate()
            .map(|(c, (s, o))| run(c * CHUNK_POINTS, s, o))
            .collect::<Vec<_>>()
            .into_iter()
            .fold(PointReport::default(), PointReport::then)
    }

    /// The branch-free kernel: maps the whole chunk and returns whether every point had a
    /// valid image (non-finite input, w at rounding level, w < 0 when oriented, or an
    /// overflowing result all make it false). Runs the AVX2 build of the kernel where the CPU
    /// has it, as OpenCV does; no FMA, so every path rounds identically.
    fn apply_chunk_fast<T: Coord>(
        &self,
        src: &[[T; S]],
        out: &mut [[T; D]],
        orientation: Orientation,
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { self.apply_chunk_avx2(src, out, orientation) };
        }
        self.apply_chunk_portable(src, out, orientation)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn apply_chunk_avx2<T: Coord>(
        &self,
        src: &[[T; S]],
        out: &mut [[T; D]],
        orientation: Orientation,
    ) -> bool {
        self.apply_chunk_portable(src, out, orientation)
    }

    #[inline(always)]
    fn apply_chunk_portable<T: Coord>(
        &self,
        src: &[[T; S]],
        out: &mut [[T; D]],
        orientation: Orientation,
    ) -> bool {
        let oriented = orientation == Orientation::Oriented;
        let m = &self.m;
        let mut ok = true;
        for (p, o) in src.iter().zip(out.iter_mut()) {
            let mut x = [0.0; S];
            for k in 0..S {
                x[k] = p[k].get();
            }
            let row = &m[D];
            let mut w = row[S];
            let mut scale = row[S].abs();
            for k in 0..S {
                w += row[k] * x[k];
                scale += (row[k] * x[k]).abs();
            }
            let iw = 1.0 / w;
            let mut finite = true;
            for d in 0..D {
                let row = &m[d];
                let mut v = row[S];
                for k in 0..S {
                    v += row[k] * x[k];
                }
                let y = T::put(v * iw);
                finite &= y.is_finite();
                o[d] = y;
            }
            // NaN anywhere makes these comparisons false.
            let w_ok = w.abs() > W_ROUNDING * scale && (!oriented || w > 0.0);
            ok &= w_ok & finite;
        }
        ok
    }
}

/// The image in the output type, or AtInfinity if it overflows that type.
#[inline(always)]
fn narrow<T: Coord, const D: usize>(y: &[f64; D]) -> std::result::Result<[T; D], PointFailure> {
    let mut o = [T::NAN; D];
    for d in 0..D {
        o[d] = T::put(y[d]);
        if !o[d].is_finite() {
            return Err(PointFailure::AtInfinity);
        }
    }
    Ok(o)
}

/// A plane-to-plane homography as a projective map.
pub type Homography = Projective<2, 2>;

impl Homography {
    /// From a 3 x 3 matrix; refused if an entry is not finite.
    pub fn from_matrix(h: &Matrix3<f64>) -> Result<Self> {
        let rows: Vec<f64> = (0..9).map(|k| h[(k / 3, k % 3)]).collect();
        Self::from_row_major(&rows)
    }
}

/// H^-1 (the true inverse, so an oriented H gives an oriented inverse). Fails when H is
/// singular to within the rounding of its determinant.
pub fn invert(h: &Matrix3<f64>) -> Result<Matrix3<f64>> {
    Homography::from_matrix(h)?;
    let det = h.determinant();
    // Sum of the magnitudes of the six products that make up the determinant.
    let mut bound = 0.0;
    for (a, b, c) in [
        (0, 1, 2),
        (1, 2, 0),
        (2, 0, 1),
        (0, 2, 1),
        (1, 0, 2),
        (2, 1, 0),
    ] {
        bound += (h[(0, a)] * h[(1, b)] * h[(2, c)]).abs();
    }
    if !(det.abs() > 64.0 * f64::EPSILON * bound) {
        return Err(HomographyError::Singular {
            ratio: if bound > 0.0 { det.abs() / bound } else { 0.0 },
        });
    }
    // The adjugate over the determinant: exact cofactors, one division.
    let adj = Matrix3::new(
        h[(1, 1)] * h[(2, 2)] - h[(1, 2)] * h[(2, 1)],
        h[(0, 2)] * h[(2, 1)] - h[(0, 1)] * h[(2, 2)],
        h[(0, 1)] * h[(1, 2)] - h[(0, 2)] * h[(1, 1)],
        h[(1, 2)] * h[(2, 0)] - h[(1, 0)] * h[(2, 2)],
        h[(0, 0)] * h[(2, 2)] - h[(0, 2)] * h[(2, 0)],
        h[(0, 2)] * h[(1, 0)] - h[(0, 0)] * h[(1, 2)],
        h[(1, 0)] * h[(2, 1)] - h[(1, 1)] * h[(2, 0)],
        h[(0, 1)] * h[(2, 0)] - h[(0, 0)] * h[(2, 1)],
        h[(0, 0)] * h[(1, 1)] - h[(0, 1)] * h[(1, 0)],
    );
    let inverse = adj / det;
    // A determinant near the subnormal range passes the relative test above, yet dividing by
    // it overflows: no inverse that float64 can hold.
    if !inverse.iter().all(|v| v.is_finite()) {
        return Err(HomographyError::Singular { ratio: 0.0 });
    }
    Ok(inverse)
}

/// Fills out[i] = f(i), in parallel chunks for large batches, `invalid` where f fails.
pub(crate) fn map_indexed<O, F>(out: &mut [O], invalid: O, f: F) -> PointReport
where
    O: Copy + Send + Sync,
    F: Fn(usize) -> std::result::Result<O, PointFailure> + Sync,
{
    let run = |start: usize, chunk: &mut [O]| {
        let mut report = PointReport::default();
        for (k, slot) in chunk.iter_mut().enumerate() {
            match f(start + k) {
                Ok(v) => *slot = v,
                Err(status) => {
                    *slot = invalid;
                    report.record(start + k, status);
                }
            }
        }
        report
    };
    if out.len() < PARALLEL_MIN_POINTS || !threads::pool_allowed() {
        return run(0, out);
    }
    out.par_chunks_mut(CHUNK_POINTS)
        .enumerate()
        .map(|(c, chunk)| run(c * CHUNK_POINTS, chunk))
        .collect::<Vec<_>>()
        .into_iter()
        .fold(PointReport::default(), PointReport::then)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn h() -> Matrix3<f64> {
        Matrix3::new(2.0, 0.1, 5.0, -0.2, 1.5, 7.0, 1e-3, 2e-3, 1.0)
    }

    #[test]
    fn maps_points_like_the_matrix_product() {
        let t = Homography::from_matrix(&h()).unwrap();
        let p = [3.0, -4.0];
        let v = h() * nalgebra::Vector3::new(3.0, -4.0, 1.0);
        let got = t.apply(&p, Orientation::Oriented).unwrap();
        assert!((got[0] - v[0] / v[2]).abs() < 1e-14 && (got[1] - v[1] / v[2]).abs() < 1e-14);
    }

    #[test]
    fn infinity_and_horizon_are_reported_not_zeroed() {
        // w = 1 - x: x = 1 is the horizon, x > 1 is behind it.
        let m = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 1.0);
        let t = Homography::from_matrix(&m).unwrap();
        let src = [[0.5, 0.0], [1.0, 3.0], [2.0, 0.0], [f64::NAN, 0.0]];
        let mut out = [[0.0; 2]; 4];
        let r = t.apply_all(&src, &mut out, Orientation::Oriented);
        assert_eq!(out[0], [1.0, 0.0]);
        assert!(out[1..].iter().all(|p| p[0].is_nan() && p[1].is_nan()));
        assert_eq!(
            r,
            PointReport {
                non_finite: 1,
                at_infinity: 1,
                outside_lens: 0,
                behind_horizon: 1,
                first: Some((1, PointFailure::AtInfinity))
            }
        );
        // Unoriented (OpenCV's convention): only w = 0 is an error.
        let r = t.apply_all(&src, &mut out, Orientation::Unoriented);
        assert_eq!(r.behind_horizon, 0);
        assert_eq!(out[2], [-2.0, 0.0]);
    }

    #[test]
    fn f32_overflow_is_reported() {
        let m = Matrix3::new(1e30, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        let t = Homography::from_matrix(&m).unwrap();
        let mut out = [[0.0f32; 2]; 1];
        let r = t.apply_all(&[[1e10f32, 0.0]], &mut out, Orientation::Unoriented);
        assert_eq!(r.at_infinity, 1);
    }

    #[test]
    fn parallel_and_serial_agree_bit_for_bit() {
        let t = Homography::from_matrix(&h()).unwrap();
        let n = PARALLEL_MIN_POINTS * 3 + 17;
        let src: Vec<[f64; 2]> = (0..n)
            .map(|i| {
                [
                    (i as f64 * 0.37).sin() * 200.0,
                    (i as f64 * 0.11).cos() * 100.0,
                ]
            })
            .collect();
        let mut par = vec![[0.0; 2]; n];
        let report = t.apply_all(&src, &mut par, Orientation::Oriented);
        assert_eq!(report.invalid(), 0);
        for (p, o) in src.iter().zip(&par) {
            assert_eq!(t.apply(p, Orientation::Oriented).unwrap(), *o);
        }
    }

    #[test]
    fn inverse_round_trips_and_singular_is_refused() {
        let hi = invert(&h()).unwrap();
        assert!((hi * h() - Matrix3::identity()).norm() < 1e-14);
        let singular = Matrix3::new(1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 0.0, 1.0);
        assert!(matches!(
            invert(&singular),
            Err(HomographyError::Singular { .. })
        ));
        // Large translations are not singularity.
        let shifted = Matrix3::new(1.0, 0.0, 1e9, 0.0, 1.0, -1e9, 0.0, 0.0, 1.0);
        assert!(invert(&shifted).is_ok());
    }

    #[test]
    fn general_shapes_project() {
        // A 3 x 4 camera matrix projecting 3-D points to the image.
        let p = Projective::<3, 2>::from_row_major(&[
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0,
        ])
        .unwrap();
        assert_eq!(
            p.apply(&[2.0, 4.0, 2.0], Orientation::Oriented).unwrap(),
            [1.0, 2.0]
        );
        assert!(Projective::<2, 2>::from_row_major(&[f64::INFINITY; 9]).is_err());
    }
}
