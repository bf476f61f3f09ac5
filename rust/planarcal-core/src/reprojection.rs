//! Reprojection errors (the paper's Eq. 6), e_i = || dst_i - H src_i ||, and their statistics
//! (mean, its Eq. 7; RMS; max; min). A source point with no image has an infinite error.

use nalgebra::Matrix3;

use crate::correspondences::check_finite;
use crate::error::{HomographyError, PointSet, Result};
use crate::point_failure::PointReport;
use crate::transform::{map_indexed, Homography, Orientation};
use crate::Point;

/// Per-point errors into `out`; +inf where the source point has no image (see the report).
/// Non-finite points are bad input, not points without an image: they fail, named.
pub fn reprojection_errors_into(
    h: &Matrix3<f64>,
    src: &[Point],
    dst: &[Point],
    out: &mut [f64],
    orientation: Orientation,
) -> Result<PointReport> {
    if src.len() != dst.len() || out.len() != src.len() {
        return Err(HomographyError::LengthMismatch {
            src: src.len(),
            dst: dst.len(),
        });
    }
    let t = Homography::from_matrix(h)?;
    check_finite(src, PointSet::Source)?;
    check_finite(dst, PointSet::Destination)?;
    Ok(map_indexed(out, f64::INFINITY, |i| {
        let d = &dst[i];
        let p = t.apply(&src[i], orientation)?;
        Ok((p[0] - d[0]).hypot(p[1] - d[1]))
    }))
}

/// Summary statistics of a set of errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorStats {
    /// Errors summarised.
    pub count: usize,
    /// Their mean.
    pub mean: f64,
    /// Their root mean square.
    pub rms: f64,
    /// The largest.
    pub max: f64,
    /// The smallest.
    pub min: f64,
    /// The index of the largest.
    pub argmax: usize,
    /// The index of the smallest.
    pub argmin: usize,
}

impl ErrorStats {
    /// None for an empty set.
    pub fn of(errors: &[f64]) -> Option<Self> {
        let first = *errors.first()?;
        let mut s = ErrorStats {
            count: errors.len(),
            mean: 0.0,
            rms: 0.0,
            max: first,
            min: first,
            argmax: 0,
            argmin: 0,
        };
        let (mut sum, mut sum_sq) = (0.0, 0.0);
        for (i, &e) in errors.iter().enumerate() {
            sum += e;
            sum_sq += e * e;
            if e > s.max {
                s.max = e;
                s.argmax = i;
            }
            if e < s.min {
                s.min = e;
                s.argmin = i;
            }
        }
        let n = errors.len() as f64;
        s.mean = sum / n;
        s.rms = (sum_sq / n).sqrt();
        if s.max.is_finite() && !(s.mean.is_finite() && s.rms.is_finite()) {
            // Finite errors whose sum or sum of squares overflows: the same figures, scaled
            // by the largest (at most 1 each, so nothing overflows).
            let (mut sum, mut sum_sq) = (0.0, 0.0);
            for &e in errors {
                let r = e / s.max;
                sum += r;
                sum_sq += r * r;
            }
            s.mean = s.max * (sum / n);
            s.rms = s.max * (sum_sq / n).sqrt();
        }
        Some(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::point_failure::PointFailure;

    #[test]
    fn statistics_of_huge_finite_errors_are_finite() {
        let s = ErrorStats::of(&[1e300, 1e300, 0.0, 3e300]).unwrap();
        assert!((s.mean / 1.25e300 - 1.0).abs() < 1e-15, "{}", s.mean);
        assert!(s.rms.is_finite() && (s.rms / 1.6583123951777e300 - 1.0).abs() < 1e-12);
        let s = ErrorStats::of(&[1.0, f64::INFINITY]).unwrap();
        assert!(s.mean.is_infinite() && s.rms.is_infinite());
    }

    #[test]
    fn errors_are_euclidean_distances() {
        let h = Matrix3::new(1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        let src = [[0.0, 0.0], [1.0, 1.0]];
        let dst = [[4.0, 4.0], [2.0, 1.0]];
        let mut e = [0.0; 2];
        let r = reprojection_errors_into(&h, &src, &dst, &mut e, Orientation::Oriented).unwrap();
        assert_eq!(r.invalid(), 0);
        assert_eq!(e, [5.0, 0.0]);
        let s = ErrorStats::of(&e).unwrap();
        assert_eq!(
            (s.mean, s.max, s.min, s.argmax, s.argmin),
            (2.5, 5.0, 0.0, 0, 1)
        );
        assert!((s.rms - (12.5f64).sqrt()).abs() < 1e-15);
        assert!(ErrorStats::of(&[]).is_none());
    }

    #[test]
    fn points_without_an_image_have_infinite_error() {
        let h = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 1.0);
        let mut e = [0.0; 2];
        let r = reprojection_errors_into(
            &h,
            &[[0.0, 0.0], [1.0, 0.0]],
            &[[0.0, 0.0], [0.0, 0.0]],
            &mut e,
            Orientation::Oriented,
        )
        .unwrap();
        assert_eq!(e, [0.0, f64::INFINITY]);
        assert_eq!(r.first, Some((1, PointFailure::AtInfinity)));
    }

    #[test]
    fn non_finite_points_are_named_with_their_set() {
        let h = Matrix3::identity();
        let good = [[0.0, 0.0], [1.0, 0.0]];
        let bad = [[0.0, 0.0], [f64::NAN, 0.0]];
        let mut e = [0.0; 2];
        for (src, dst, set) in [
            (&good, &bad, PointSet::Destination),
            (&bad, &good, PointSet::Source),
        ] {
            assert!(matches!(
                reprojection_errors_into(&h, src, dst, &mut e, Orientation::Oriented),
                Err(HomographyError::NonFinitePoint { set: s, index: 1, .. }) if s == set
            ));
        }
    }
}
