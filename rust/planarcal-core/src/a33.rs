//! The paper's estimator (its Eq. 4-5): fix a33 = 1 and solve the remaining eight entries by
//! linear least squares over all points,
//!     X a11 + Y a12 + a13 - x X a31 - x Y a32 = x
//!     X a21 + Y a22 + a23 - y X a31 - y Y a32 = y.
//! The least-squares problem is the paper's, in the caller's coordinates; it is solved by
//! Householder QR with the columns scaled to unit norm, which changes the conditioning of the
//! computation, not its minimiser.

use nalgebra::{DMatrix, DVector, Matrix3};

use crate::alloc;
use crate::correspondences::Correspondences;
use crate::error::{HomographyError, Result};

/// |h33| below this fraction of the largest |w| over the data: the source
/// origin is (nearly) on the horizon, where a33 = 1 cannot normalise H.
pub const H33_TOL: f64 = 1e-6;

/// Fails when the homography (estimated without the a33 = 1 constraint) has h33 near zero,
/// relative to w over the data (a ratio that does not depend on H's scale).
pub fn check_h33(reference: &Matrix3<f64>, c: &Correspondences) -> Result<()> {
    let wmax = c
        .src
        .iter()
        .map(|p| crate::orientation::w_of(reference, p).abs())
        .fold(0.0, f64::max);
    let relative = reference[(2, 2)].abs() / wmax;
    if relative < H33_TOL {
        return Err(HomographyError::H33NearZero { relative });
    }
    Ok(())
}

/// The a33 = 1 least-squares homography, in the caller's coordinates. Refuses when the
/// estimated relative rounding error of the solution exceeds `max_forward_error`.
pub fn a33_least_squares(c: &Correspondences, max_forward_error: f64) -> Result<Matrix3<f64>> {
    let n = c.len();
    let mut a = DMatrix::from_vec(2 * n, 8, alloc::filled(0.0, 2 * n * 8)?);
    let mut b = DVector::from_vec(alloc::filled(0.0, 2 * n)?);
    for (i, (s, d)) in c.src.iter().zip(c.dst).enumerate() {
        let (sx, sy, dx, dy) = (s[0], s[1], d[0], d[1]);
        let row1 = [sx, sy, 1.0, 0.0, 0.0, 0.0, -dx * sx, -dx * sy];
        let row2 = [0.0, 0.0, 0.0, sx, sy, 1.0, -dy * sx, -dy * sy];
        for k in 0..8 {
            a[(2 * i, k)] = row1[k];
            a[(2 * i + 1, k)] = row2[k];
        }
        b[2 * i] = dx;
        b[2 * i + 1] = dy;
    }
    // Column equilibration: unknown k is solved as a_k * scale_k.
    let mut scale = [0.0; 8];
    for (k, s) in scale.iter_mut().enumerate() {
        let norm = a.column(k).norm();
        *s = if norm > 0.0 { 1.0 / norm } else { 1.0 };
        a.column_mut(k).scale_mut(*s);
    }
    let qr = a.qr();
    let r = qr.r();
    let diag: Vec<f64> = (0..8).map(|k| r[(k, k)].abs()).collect();
    let (lo, hi) = diag
        .iter()
        .fold((f64::INFINITY, 0.0_f64), |(l, h), &d| (l.min(d), h.max(d)));
    let forward = f64::EPSILON * hi / lo;
    if !(forward <= max_forward_error) {
        return Err(HomographyError::IllConditioned {
            solver: "a33",
            forward_error: forward,
        });
    }
    qr.q_tr_mul(&mut b);
    let rhs = b.rows(0, 8).into_owned();
    let x = r
        .solve_upper_triangular(&rhs)
        .ok_or(HomographyError::IllConditioned {
            solver: "a33",
            forward_error: f64::INFINITY,
        })?;
    let p: Vec<f64> = (0..8).map(|k| x[k] * scale[k]).collect();
    Ok(Matrix3::new(
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], 1.0,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{relative_h_error, sample_problem};

    #[test]
    fn recovers_an_exact_homography() {
        for &(n, spread, offset) in &[(4, 1.0, 0.0), (30, 700.0, 50.0), (100, 0.01, 1.0)] {
            let (src, dst, truth) = sample_problem(n, spread, offset);
            let c = Correspondences::new(&src, &dst).unwrap();
            let h = a33_least_squares(&c, 1e-4).unwrap();
            assert_eq!(h[(2, 2)], 1.0);
            assert!(relative_h_error(&h, &truth) < 1e-10, "n={n}");
        }
    }

    #[test]
    fn minimises_the_papers_algebraic_residual() {
        // With noise the solution is the least-squares minimiser: perturbing any entry of H
        // (a33 held at 1) can only increase the sum of squared equation residuals.
        let (src, mut dst, _) = sample_problem(40, 100.0, 10.0);
        for (i, d) in dst.iter_mut().enumerate() {
            d[0] += ((i * 7) as f64).sin() * 0.3;
            d[1] += ((i * 3) as f64).cos() * 0.3;
        }
        let c = Correspondences::new(&src, &dst).unwrap();
        let h = a33_least_squares(&c, 1e-4).unwrap();
        let residual = |h: &Matrix3<f64>| -> f64 {
            src.iter()
                .zip(&dst)
                .map(|(s, d)| {
                    let w = h[(2, 0)] * s[0] + h[(2, 1)] * s[1] + h[(2, 2)];
                    let ex = h[(0, 0)] * s[0] + h[(0, 1)] * s[1] + h[(0, 2)] - d[0] * w;
                    let ey = h[(1, 0)] * s[0] + h[(1, 1)] * s[1] + h[(1, 2)] - d[1] * w;
                    ex * ex + ey * ey
                })
                .sum()
        };
        let best = residual(&h);
        for k in 0..8 {
            for step in [1e-7, -1e-7] {
                let mut p = h;
                p[(k / 3, k % 3)] += step * p[(k / 3, k % 3)].abs().max(1e-6);
                assert!(residual(&p) >= best, "entry {k}");
            }
        }
    }

    #[test]
    fn h33_near_zero_is_refused() {
        // The horizon of this homography passes through the source origin.
        let h = Matrix3::new(1.0, 0.2, 5.0, 0.1, 1.0, 3.0, 1e-3, 2e-3, 0.0);
        let src = [[100.0, 0.0], [200.0, 10.0], [150.0, 80.0], [120.0, 40.0]];
        let dst: Vec<[f64; 2]> = src.iter().map(|p| crate::testing::project(&h, p)).collect();
        let c = Correspondences::new(&src, &dst).unwrap();
        assert!(matches!(
            check_h33(&h, &c),
            Err(HomographyError::H33NearZero { .. })
        ));
    }
}
