//! Hartley normalisation: an isotropic similarity that moves a point set's centroid to the
//! origin and scales it to an RMS distance of sqrt(2). Every linear solve runs on normalised
//! points, which keeps the normal matrix well conditioned whatever the units and offsets.

use nalgebra::Matrix3;

use crate::Point;

/// First and second moments of a point set, computed in two passes (centroid first) so that
/// large offsets do not cancel the spread. The moments are of the centred points divided by
/// `unit`, a power of two: 1 for ordinary coordinates, and otherwise chosen so that squares
/// neither overflow (spreads near 1e200) nor underflow (near 1e-200); scaling by a power of
/// two is exact.
#[derive(Debug, Clone, Copy)]
pub struct PointStats {
    pub n: usize,
    pub centroid: [f64; 2],
    pub unit: f64,
    /// Scatter matrix of the centred points in units: sums of u_x^2, u_x u_y, u_y^2.
    pub sxx: f64,
    pub sxy: f64,
    pub syy: f64,
    /// Largest squared distance from the centroid (in units), and the point that has it.
    pub max_sq: f64,
    pub argmax: usize,
}

/// The mean as p0 + mean(p - p0): exact for identical points (plain sums of 0.1 are not),
/// and its sum of small deviations keeps the digits that large offsets would take.
fn centroid(points: &[Point]) -> [f64; 2] {
    let Some(&p0) = points.first() else {
        return [0.0, 0.0];
    };
    let inv_n = 1.0 / points.len() as f64;
    let (mut dx, mut dy) = (0.0, 0.0);
    for p in points {
        dx += p[0] - p0[0];
        dy += p[1] - p0[1];
    }
    let c = [p0[0] + dx * inv_n, p0[1] + dy * inv_n];
    if c[0].is_finite() && c[1].is_finite() {
        return c;
    }
    // Deviations beyond f64's range (coordinates near 1e308 of both signs): p / n cannot
    // overflow.
    points.iter().fold([0.0, 0.0], |acc, p| {
        [acc[0] + p[0] * inv_n, acc[1] + p[1] * inv_n]
    })
}

impl PointStats {
    pub fn of(points: &[Point]) -> Self {
        let [cx, cy] = centroid(points);
        let stats = Self::moments(points, [cx, cy], 1.0);
        let total = stats.sxx + stats.syy;
        // Sums of squares with full precision: neither overflowed nor underflowed.
        if total.is_finite() && total > f64::MIN_POSITIVE / f64::EPSILON {
            return stats;
        }
        let widest = points
            .iter()
            .map(|p| (p[0] - cx).abs().max((p[1] - cy).abs()))
            .fold(0.0, f64::max);
        if !(widest > 0.0 && widest.is_finite()) {
            return stats; // identical points (zero moments), or not finite (rejected elsewhere)
        }
        let unit = 2f64.powi(widest.log2().ceil() as i32);
        Self::moments(points, [cx, cy], unit)
    }

    fn moments(points: &[Point], centroid: [f64; 2], unit: f64) -> Self {
        let [cx, cy] = centroid;
        let inv = 1.0 / unit;
        let (mut sxx, mut sxy, mut syy, mut max_sq, mut argmax) = (0.0, 0.0, 0.0, 0.0, 0);
        for (i, p) in points.iter().enumerate() {
            let (ux, uy) = ((p[0] - cx) * inv, (p[1] - cy) * inv);
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
            n: points.len(),
            centroid,
            unit,
            sxx,
            sxy,
            syy,
            max_sq,
            argmax,
        }
    }

    /// Mean squared distance from the centroid, in units.
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
    /// Hartley's normalisation of a point set; None when all points coincide or their spread
    /// is beyond what a finite scale can normalise.
    pub fn from_stats(stats: &PointStats) -> Option<Self> {
        let ms = stats.mean_sq();
        if !(ms > 0.0) {
            return None;
        }
        let scale = (2.0 / ms).sqrt() / stats.unit;
        (scale.is_finite() && scale > 0.0).then_some(Normalization {
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
        // 1e20 + 1 rounds to 1e20: these points coincide too.
        let pts = [[1e20, 1.0], [1e20 + 1.0, 1.0], [1e20, 1.0], [1e20, 1.0]];
        assert!(Normalization::from_stats(&PointStats::of(&pts)).is_none());
    }

    #[test]
    fn any_magnitude_normalises_to_rms_sqrt2() {
        let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.3, 0.6]];
        for scale in [1e-300, 1e-200, 1e-50, 1.0, 1e50, 1e200, 1e300] {
            for offset in [0.0, 3.0] {
                let pts: Vec<Point> = square
                    .iter()
                    .map(|p| [(p[0] + offset) * scale, (p[1] - offset) * scale])
                    .collect();
                let t = Normalization::from_stats(&PointStats::of(&pts)).unwrap();
                let ms = pts
                    .iter()
                    .map(|p| t.apply(p))
                    .map(|q| q[0] * q[0] + q[1] * q[1])
                    .sum::<f64>()
                    / 5.0;
                assert_relative_eq!(ms, 2.0, epsilon = 1e-12);
            }
        }
    }
}
