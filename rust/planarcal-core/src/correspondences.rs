//! A validated correspondence problem: equal lengths, at least 4 points, finite coordinates,
//! both sets in general position, and the Hartley normalisation of each set.

use nalgebra::Matrix3;

use crate::degeneracy::{
    check_general_position, count_distinct, has_clear_general_position, COLLINEAR_TOL,
};
use crate::error::{HomographyError, PointSet, Result};
use crate::normalize::{Normalization, PointStats};
use crate::Point;

#[derive(Debug, Clone, Copy)]
pub struct Correspondences<'a> {
    pub src: &'a [Point],
    pub dst: &'a [Point],
    pub src_norm: Normalization,
    pub dst_norm: Normalization,
}

/// Fails on the first point with a NaN or infinite coordinate.
pub fn check_finite(points: &[Point], set: PointSet) -> Result<()> {
    match points
        .iter()
        .position(|p| !(p[0].is_finite() && p[1].is_finite()))
    {
        None => Ok(()),
        Some(index) => Err(HomographyError::NonFinitePoint {
            set,
            index,
            x: points[index][0],
            y: points[index][1],
        }),
    }
}

fn normalise_set(points: &[Point], set: PointSet) -> Result<Normalization> {
    check_finite(points, set)?;
    let stats = PointStats::of(points);
    let Some(norm) = Normalization::from_stats(&stats) else {
        return Err(HomographyError::TooFewDistinct {
            set,
            distinct: count_distinct(points)?.min(1),
        });
    };
    if !has_clear_general_position(points, &stats) {
        check_general_position(points, set, COLLINEAR_TOL)?;
    }
    Ok(norm)
}

impl<'a> Correspondences<'a> {
    pub fn new(src: &'a [Point], dst: &'a [Point]) -> Result<Self> {
        if src.len() != dst.len() {
            return Err(HomographyError::LengthMismatch {
                src: src.len(),
                dst: dst.len(),
            });
        }
        if src.len() < 4 {
            return Err(HomographyError::TooFewPoints { got: src.len() });
        }
        let src_norm = normalise_set(src, PointSet::Source)?;
        let dst_norm = normalise_set(dst, PointSet::Destination)?;
        Ok(Correspondences {
            src,
            dst,
            src_norm,
            dst_norm,
        })
    }

    pub fn len(&self) -> usize {
        self.src.len()
    }

    /// The normalised pairs (T_s src_i, T_d dst_i).
    pub fn normalized_pairs(&self) -> impl Iterator<Item = (Point, Point)> + '_ {
        self.src
            .iter()
            .zip(self.dst)
            .map(move |(s, d)| (self.src_norm.apply(s), self.dst_norm.apply(d)))
    }

    /// H in normalised coordinates: T_d H T_s^-1.
    pub fn normalize_h(&self, h: &Matrix3<f64>) -> Matrix3<f64> {
        self.dst_norm.matrix() * h * self.src_norm.inverse_matrix()
    }

    /// H in the caller's coordinates: T_d^-1 H' T_s.
    pub fn denormalize_h(&self, hn: &Matrix3<f64>) -> Matrix3<f64> {
        self.dst_norm.inverse_matrix() * hn * self.src_norm.matrix()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: [Point; 4] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];

    #[test]
    fn rejects_bad_shapes_and_values() {
        assert_eq!(
            Correspondences::new(&SQUARE, &SQUARE[..3]).unwrap_err(),
            HomographyError::LengthMismatch { src: 4, dst: 3 }
        );
        assert_eq!(
            Correspondences::new(&SQUARE[..3], &SQUARE[..3]).unwrap_err(),
            HomographyError::TooFewPoints { got: 3 }
        );
        assert_eq!(
            Correspondences::new(&[], &[]).unwrap_err(),
            HomographyError::TooFewPoints { got: 0 }
        );
        let mut bad = SQUARE;
        bad[2][1] = f64::NAN;
        assert!(matches!(
            Correspondences::new(&SQUARE, &bad).unwrap_err(),
            HomographyError::NonFinitePoint {
                set: PointSet::Destination,
                index: 2,
                ..
            }
        ));
        bad[2][1] = f64::NEG_INFINITY;
        assert!(matches!(
            Correspondences::new(&bad, &SQUARE).unwrap_err(),
            HomographyError::NonFinitePoint {
                set: PointSet::Source,
                index: 2,
                ..
            }
        ));
    }

    #[test]
    fn coincident_points_are_too_few_distinct() {
        let same = [[2.0, 3.0]; 5];
        let five = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.2]];
        assert_eq!(
            Correspondences::new(&five, &same).unwrap_err(),
            HomographyError::TooFewDistinct {
                set: PointSet::Destination,
                distinct: 1
            }
        );
    }

    #[test]
    fn normalisation_round_trips_h() {
        let pts = [[10.0, 20.0], [30.0, 20.0], [30.0, 50.0], [10.0, 50.0]];
        let c = Correspondences::new(&pts, &SQUARE).unwrap();
        let h = Matrix3::new(1.0, 0.2, 3.0, -0.1, 0.9, 4.0, 1e-3, 2e-3, 1.0);
        let back = c.denormalize_h(&c.normalize_h(&h));
        assert!((back - h).norm() < 1e-12);
    }
}
