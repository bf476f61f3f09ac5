//! Sign and scale conventions. A homography between a plane and a camera image is oriented:
//! every point the camera sees has w > 0 (it is in front), so a fit whose own source points
//! straddle the horizon (w of both signs) cannot describe a real view and is refused.
//! Returned matrices have the fit's points at w > 0 and |h33| = 1 (h33 = +1 whenever the
//! source origin is on the visible side, the usual case); when h33 is negligible, ||H|| = 1.

use nalgebra::Matrix3;

use crate::error::{HomographyError, Result};
use crate::Point;

/// |h33| below this fraction of the largest |w| over the data is treated as zero.
const H33_NEGLIGIBLE: f64 = 1e-14;

/// ||H||_F without overflow or underflow (entries can reach 1e200 at extreme scales).
pub fn frobenius(h: &Matrix3<f64>) -> f64 {
    let m = h.amax();
    if m > 0.0 && m.is_finite() {
        m * (h / m).norm()
    } else {
        h.norm()
    }
}

#[inline(always)]
pub fn w_of(h: &Matrix3<f64>, p: &Point) -> f64 {
    h[(2, 0)] * p[0] + h[(2, 1)] * p[1] + h[(2, 2)]
}

/// Orients H so the source points have w > 0 and scales it by the convention above. H is
/// divided once, by |h33| (or by its norm): its entries can span 1e-250 to 1e250 at extreme
/// coordinate scales, and an intermediate normalisation would underflow the small ones.
pub fn orient_and_scale(h: &Matrix3<f64>, src: &[Point]) -> Result<Matrix3<f64>> {
    for (k, v) in h.iter().enumerate() {
        if !v.is_finite() {
            // nalgebra stores column-major.
            return Err(HomographyError::NonFiniteMatrix {
                row: k % 3,
                col: k / 3,
            });
        }
    }
    let norm = frobenius(h);
    if !(norm > 0.0) {
        return Err(HomographyError::Singular { ratio: 0.0 });
    }
    let (mut pos, mut neg, mut wmax) = (0usize, 0usize, 0.0_f64);
    for p in src {
        let w = w_of(h, p);
        wmax = wmax.max(w.abs());
        if w > 0.0 {
            pos += 1;
        } else {
            neg += 1;
        }
    }
    let sign = if pos >= neg { 1.0 } else { -1.0 };
    if pos != 0 && neg != 0 {
        // Name a point on the minority side.
        let index = src
            .iter()
            .position(|p| sign * w_of(h, p) <= 0.0)
            .unwrap_or(0);
        return Err(HomographyError::MixedOrientation {
            index,
            behind: pos.min(neg),
            total: src.len(),
        });
    }
    let h33 = h[(2, 2)].abs();
    // A true division, so h33 / |h33| is exactly +-1 (multiplying by 1 / |h33| is not).
    Ok(if h33 > H33_NEGLIGIBLE * wmax {
        h / h33 * sign
    } else {
        h / norm * sign
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flips_sign_so_points_are_in_front() {
        let h = Matrix3::new(-2.0, 0.0, 0.0, 0.0, -2.0, 0.0, 0.0, 0.0, -2.0);
        let src = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        let o = orient_and_scale(&h, &src).unwrap();
        assert_eq!(o, Matrix3::identity());
    }

    #[test]
    fn origin_behind_the_horizon_gives_h33_minus_one() {
        // w = x - 1: the data (x > 1) are in front, the origin behind.
        let h = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, -1.0);
        let src = [[2.0, 0.0], [3.0, 0.0], [2.0, 1.0], [3.0, 1.0]];
        let o = orient_and_scale(&h, &src).unwrap();
        assert_eq!(o[(2, 2)], -1.0);
        assert!(src.iter().all(|p| w_of(&o, p) > 0.0));
    }

    #[test]
    fn straddling_the_horizon_is_refused() {
        let h = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, -1.0);
        let src = [[2.0, 0.0], [3.0, 0.0], [0.0, 1.0], [3.0, 1.0]];
        assert_eq!(
            orient_and_scale(&h, &src),
            Err(HomographyError::MixedOrientation {
                index: 2,
                behind: 1,
                total: 4
            })
        );
    }

    #[test]
    fn non_finite_and_zero_matrices_are_refused() {
        let mut h = Matrix3::identity();
        h[(1, 2)] = f64::NAN;
        assert_eq!(
            orient_and_scale(&h, &[[0.0, 0.0]]),
            Err(HomographyError::NonFiniteMatrix { row: 1, col: 2 })
        );
        assert!(orient_and_scale(&Matrix3::zeros(), &[[0.0, 0.0]]).is_err());
    }
}
