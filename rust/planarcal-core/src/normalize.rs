//! Hartley normalisation: an isotropic similarity that moves a point set's centroid to the
//! origin and scales it to an RMS distance of sqrt(2). Every linear solve runs on normalised
//! points, which keeps the normal matrix well conditioned whatever the units and offsets.

use nalgebra::Matrix3;

use crate::Point;

/// First and second moments of a point set, computed in two passes (centroid first) so that
/// large offsets do not cancel the spread.
#[derive(Debug, Clone, Copy)]
pub struct PointStats {
    pub n: usize,
    pub centroid: [f64; 2],
    /// Scatter matrix of the centred points: sums of u_x^2, u_x u_y, u_y^2.
    pub sxx: f64,
    pub sxy: f64,
    pub syy: f64,
    /// Largest squared distance from the centroid, and the point that has it.
    pub max_sq: f64,
    pub argmax: usize,
}

impl PointStats {
    pub fn of(points: &[Point]) -> Self {
        let n = points.len();
        let (mut mx, mut my) = (0.0, 0.0);
        for p in points {
            mx += p[0];
            my += p[1];
        }
        let inv_n = if n > 0 { 1.0 / n as f64 } else { 0.0 };
        let (cx, cy) = (mx * inv_n, my * inv_n);
        let (mut sxx, mut sxy, mut syy, mut max_sq, mut argmax) = (0.0, 0.0, 0.0, 0.0, 0);
        for (i, p) in points.iter().enumerate() {
            let (ux, uy) = (p[0] - cx, p[1] - cy);
            sxx += ux * ux;
            sxy += ux * uy;
            syy += uy * uy;
            let d = ux * ux + uy * uy;
            if d > max_sq {
                max_sq = d;
                argmax = i;
            }
        }
        PointStats {
            n,
            centroid: [cx, cy],
            sxx,
            sxy,
            syy,
            max_sq,
            argmax,
        }
    }

    /// Mean squared distance from the centroid.
    pub fn mean_sq(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.sxx + self.syy) / self.n as f64
        }
    }
}

/// The similarity x' = scale * (x - centre).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Normalization {
    pub centre: [f64; 2],
    pub scale: f64,
}

impl Normalization {
    /// Hartley's normalisation of a point set; None when all points coincide.
    pub fn from_stats(stats: &PointStats) -> Option<Self> {
        let ms = stats.mean_sq();
        // Below this the spread is lost in the rounding of the coordinates themselves.
        let magnitude = stats.centroid[0].abs().max(stats.centroid[1].abs());
        if !(ms > 0.0) || ms.sqrt() <= 1e-14 * magnitude {
            return None;
        }
        let scale = (2.0 / ms).sqrt();
        scale.is_finite().then_some(Normalization {
            centre: stats.centroid,
            scale,
        })
    }

    #[inline(always)]
    pub fn apply(&self, p: &Point) -> Point {
        [
            self.scale * (p[0] - self.centre[0]),
            self.scale * (p[1] - self.centre[1]),
        ]
    }

    /// The matrix T with T (x, y, 1)^T = (x', y', 1)^T.
    pub fn matrix(&self) -> Matrix3<f64> {
        let s = self.scale;
        Matrix3::new(
            s,
            0.0,
            -s * self.centre[0],
            0.0,
            s,
            -s * self.centre[1],
            0.0,
            0.0,
            1.0,
        )
    }

    /// T^-1, written out rather than inverted so it carries no rounding of its own.
    pub fn inverse_matrix(&self) -> Matrix3<f64> {
        let r = 1.0 / self.scale;
        Matrix3::new(
            r,
            0.0,
            self.centre[0],
            0.0,
            r,
            self.centre[1],
            0.0,
            0.0,
            1.0,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn normalised_points_have_zero_mean_and_rms_sqrt2() {
        let pts = [
            [1e6, 2e6],
            [1e6 + 3.0, 2e6],
            [1e6, 2e6 + 5.0],
            [1e6 + 7.0, 2e6 + 1.0],
        ];
        let stats = PointStats::of(&pts);
        let t = Normalization::from_stats(&stats).unwrap();
        let q: Vec<Point> = pts.iter().map(|p| t.apply(p)).collect();
        let (mx, my) = q.iter().fold((0.0, 0.0), |a, p| (a.0 + p[0], a.1 + p[1]));
        assert!(mx.abs() < 1e-9 && my.abs() < 1e-9);
        let ms = q.iter().map(|p| p[0] * p[0] + p[1] * p[1]).sum::<f64>() / 4.0;
        assert_relative_eq!(ms, 2.0, epsilon = 1e-12);
    }

    #[test]
    fn matrix_and_inverse_agree() {
        let t = Normalization {
            centre: [3.0, -4.0],
            scale: 0.25,
        };
        let prod = t.matrix() * t.inverse_matrix();
        assert_relative_eq!(prod, Matrix3::identity(), epsilon = 1e-15);
        let p = t.apply(&[7.0, 8.0]);
        let m = t.matrix() * nalgebra::Vector3::new(7.0, 8.0, 1.0);
        assert_relative_eq!(p[0], m[0]);
        assert_relative_eq!(p[1], m[1]);
    }

    #[test]
    fn coincident_points_cannot_be_normalised() {
        let pts = [[5.0, 5.0]; 6];
        assert!(Normalization::from_stats(&PointStats::of(&pts)).is_none());
        // A spread lost in rounding counts as coincident too.
        let pts = [[1e20, 1.0], [1e20 + 1.0, 1.0], [1e20, 1.0], [1e20, 1.0]];
        assert!(Normalization::from_stats(&PointStats::of(&pts)).is_none());
    }
}
