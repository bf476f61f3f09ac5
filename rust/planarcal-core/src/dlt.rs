//! The direct linear transform: each correspondence gives two rows of A h = 0, and h is the
//! (right) null vector of A.
//!
//! * `normalized_dlt`: Hartley-normalised points; h is the eigenvector of the smallest
//!   eigenvalue of the 9 x 9 normal matrix M = A^T A, accumulated from 24 sums (M has a fixed
//!   block structure), found by shifted inverse iteration (a 9 x 9 Cholesky, a few triangular
//!   solves) with a full symmetric eigen-decomposition as the fallback, then polished once
//!   with a residual taken from the points rather than from M (forming M squares the
//!   condition number; the polish gives that accuracy back).
//! * `plain_dlt`: the textbook DLT on raw coordinates, h = the right singular vector of A for
//!   the smallest singular value (||h|| = 1). Kept as the reference the normalised solver
//!   improves on; it refuses systems whose raw conditioning would make h mostly rounding.

use nalgebra::{DMatrix, Matrix3, SMatrix, SVector};

use crate::alloc;
use crate::correspondences::Correspondences;
use crate::degeneracy::explain_rank_deficiency;
use crate::error::{HomographyError, Result};

type Mat9 = SMatrix<f64, 9, 9>;
type Vec9 = SVector<f64, 9>;

/// Second-smallest to largest eigenvalue of M below this (singular values 1e-7 apart): the
/// null space is numerically two-dimensional.
const RANK_TOL: f64 = 1e-14;
/// Shift that keeps M + shift I positive definite despite rounding in M.
const SHIFT: f64 = 1e-13;
const MAX_INVERSE_ITERATIONS: usize = 40;

/// Sums of p p^T (p = (X, Y, 1)) weighted by 1, x, y and x^2 + y^2, in the order
/// XX, XY, X, YY, Y, 1.
#[derive(Default)]
struct NormalSums {
    one: [f64; 6],
    x: [f64; 6],
    y: [f64; 6],
    r: [f64; 6],
}

fn sym3(s: &[f64; 6]) -> [[f64; 3]; 3] {
    [[s[0], s[1], s[2]], [s[1], s[3], s[4]], [s[2], s[4], s[5]]]
}

/// M = A^T A for the normalised correspondences.
fn normal_matrix(c: &Correspondences) -> Mat9 {
    let mut s = NormalSums::default();
    for ([sx, sy], [dx, dy]) in c.normalized_pairs() {
        let pp = [sx * sx, sx * sy, sx, sy * sy, sy, 1.0];
        let r = dx * dx + dy * dy;
        for k in 0..6 {
            s.one[k] += pp[k];
            s.x[k] += dx * pp[k];
            s.y[k] += dy * pp[k];
            s.r[k] += r * pp[k];
        }
    }
    let (p, px, py, pr) = (sym3(&s.one), sym3(&s.x), sym3(&s.y), sym3(&s.r));
    let mut m = Mat9::zeros();
    for i in 0..3 {
        for j in 0..3 {
            m[(i, j)] = p[i][j];
            m[(3 + i, 3 + j)] = p[i][j];
            m[(i, 6 + j)] = -px[i][j];
            m[(6 + j, i)] = -px[i][j];
            m[(3 + i, 6 + j)] = -py[i][j];
            m[(6 + j, 3 + i)] = -py[i][j];
            m[(6 + i, 6 + j)] = pr[i][j];
        }
    }
    m
}

/// A^T (A h), computed row by row from the points: its rounding is relative to |A||h|, not
/// to |A|^2 |h| as M h's is.
fn normal_product(c: &Correspondences, h: &Vec9) -> Vec9 {
    let mut g = Vec9::zeros();
    for ([sx, sy], [dx, dy]) in c.normalized_pairs() {
        let p = [sx, sy, 1.0];
        let dot = |o: usize| h[o] * p[0] + h[o + 1] * p[1] + h[o + 2] * p[2];
        let (a, b, w) = (dot(0), dot(3), dot(6));
        let r1 = a - dx * w;
        let r2 = b - dy * w;
        let r3 = -(dx * r1 + dy * r2);
        for k in 0..3 {
            g[k] += r1 * p[k];
            g[3 + k] += r2 * p[k];
            g[6 + k] += r3 * p[k];
        }
    }
    g
}

/// Eigenvector of M's smallest eigenvalue, with the null space checked to be one-dimensional.
fn smallest_eigenvector(c: &Correspondences, m: &Mat9) -> Result<Vec9> {
    let trace = m.trace();
    let shifted = m + Mat9::identity() * (SHIFT * trace);
    if let Some(chol) = shifted.cholesky() {
        // Start away from any special direction; identity-like in normalised coordinates.
        let mut x = Vec9::from_column_slice(&[1.0, 0.01, 0.02, 0.03, 1.0, 0.04, 0.05, 0.06, 1.0]);
        x.normalize_mut();
        for _ in 0..MAX_INVERSE_ITERATIONS {
            let mut y = chol.solve(&x);
            let norm = y.norm();
            if !(norm.is_finite() && norm > 0.0) {
                break;
            }
            y /= norm;
            if y.dot(&x) < 0.0 {
                y.neg_mut();
            }
            let change = (y - x).norm();
            x = y;
            if change < 1e-14 {
                return Ok(polish(c, &chol, x));
            }
        }
    }
    // Slow convergence means the two smallest eigenvalues are close: decide it exactly.
    let eig = m
        .try_symmetric_eigen(f64::EPSILON, 1000)
        .ok_or(HomographyError::RankDeficient { ratio: f64::NAN })?;
    let mut order: Vec<usize> = (0..9).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let (lo, second, hi) = (
        order[0],
        eig.eigenvalues[order[1]],
        eig.eigenvalues[order[8]],
    );
    if !(second > RANK_TOL * hi) {
        let ratio = (second.max(0.0) / hi).sqrt();
        return Err(explain_rank_deficiency(c.src, c.dst, ratio));
    }
    Ok(eig.eigenvectors.column(lo).into_owned())
}

/// One Newton step on the eigen-equation with the residual A^T A x taken from the points.
/// Measured on 20,000 random exact problems (spreads 1e-3..1e5, offsets to 100x): it takes
/// the worst relative error of H from 4e-7 to 1e-9 (a second step gains nothing).
fn polish(
    c: &Correspondences,
    chol: &nalgebra::Cholesky<f64, nalgebra::Const<9>>,
    x: Vec9,
) -> Vec9 {
    let g = normal_product(c, &x);
    let r = g - x * x.dot(&g);
    let mut d = chol.solve(&r);
    d -= x * x.dot(&d);
    let y = (x - d).normalize();
    if y.iter().all(|v| v.is_finite()) {
        y
    } else {
        x
    }
}

/// The normalised DLT, returned in normalised coordinates (T_d H T_s^-1), up to scale.
pub fn normalized_dlt(c: &Correspondences) -> Result<Matrix3<f64>> {
    let m = normal_matrix(c);
    let h = smallest_eigenvector(c, &m)?;
    Ok(Matrix3::from_row_slice(h.as_slice()))
}

/// The plain (unnormalised) DLT by SVD, in the caller's coordinates, ||h|| = 1. Refuses when
/// the estimated relative rounding error of h exceeds `max_forward_error`.
pub fn plain_dlt(c: &Correspondences, max_forward_error: f64) -> Result<Matrix3<f64>> {
    let n = c.len();
    // Two rows a point; a zero row pads the 4-point case to 9 x 9 (nalgebra's SVD is thin).
    let rows = (2 * n).max(9);
    let mut a = DMatrix::from_vec(rows, 9, alloc::filled(0.0, rows * 9)?);
    for (i, (s, d)) in c.src.iter().zip(c.dst).enumerate() {
        let (sx, sy, dx, dy) = (s[0], s[1], d[0], d[1]);
        let r = 2 * i;
        let row1 = [sx, sy, 1.0, 0.0, 0.0, 0.0, -dx * sx, -dx * sy, -dx];
        let row2 = [0.0, 0.0, 0.0, sx, sy, 1.0, -dy * sx, -dy * sy, -dy];
        for k in 0..9 {
            a[(r, k)] = row1[k];
            a[(r + 1, k)] = row2[k];
        }
    }
    // The bidiagonalisation's work vector, one number a row, is allocated inside nalgebra,
    // which cannot fail: the room for it is checked here first.
    drop(alloc::with_capacity::<f64>(rows)?);
    // Unordered: nalgebra's ordering panics on a NaN singular value (an overflowed entry);
    // the order is taken below with total_cmp, and a NaN fails the conditioning test.
    let svd = a
        .try_svd_unordered(false, true, f64::EPSILON, 10_000)
        .ok_or(HomographyError::RankDeficient { ratio: f64::NAN })?;
    let v_t = svd
        .v_t
        .ok_or(HomographyError::RankDeficient { ratio: f64::NAN })?;
    let sv = &svd.singular_values;
    let mut order: Vec<usize> = (0..sv.len()).collect();
    order.sort_by(|&i, &j| sv[i].total_cmp(&sv[j]));
    let (lo, second, hi) = (order[0], sv[order[1]], sv[order[order.len() - 1]]);
    // The null vector's rounding error is about eps * sigma_1 / sigma_8.
    let forward = f64::EPSILON * hi / second;
    if !(forward <= max_forward_error) {
        return Err(HomographyError::IllConditioned {
            solver: "svd",
            forward_error: forward,
        });
    }
    let h: Vec<f64> = v_t.row(lo).iter().copied().collect();
    Ok(Matrix3::from_row_slice(&h))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{project, relative_h_error, sample_problem};

    #[test]
    fn normal_matrix_matches_explicit_a_transpose_a() {
        let (src, dst, _) = sample_problem(7, 1.0, 0.0);
        let c = Correspondences::new(&src, &dst).unwrap();
        let mut a = DMatrix::<f64>::zeros(14, 9);
        for (i, ([sx, sy], [dx, dy])) in c.normalized_pairs().enumerate() {
            let r1 = [sx, sy, 1.0, 0.0, 0.0, 0.0, -dx * sx, -dx * sy, -dx];
            let r2 = [0.0, 0.0, 0.0, sx, sy, 1.0, -dy * sx, -dy * sy, -dy];
            for k in 0..9 {
                a[(2 * i, k)] = r1[k];
                a[(2 * i + 1, k)] = r2[k];
            }
        }
        let explicit = a.transpose() * &a;
        let m = normal_matrix(&c);
        for i in 0..9 {
            for j in 0..9 {
                assert!((explicit[(i, j)] - m[(i, j)]).abs() < 1e-11, "({i},{j})");
            }
        }
        let h = Vec9::from_fn(|i, _| (i as f64 * 0.37).sin());
        let g = normal_product(&c, &h);
        assert!((g - m * h).norm() < 1e-11);
    }

    #[test]
    fn both_dlts_recover_an_exact_homography() {
        for &(n, spread, offset) in &[(4, 1.0, 0.0), (10, 500.0, 100.0), (200, 0.01, 0.5)] {
            let (src, dst, truth) = sample_problem(n, spread, offset);
            let c = Correspondences::new(&src, &dst).unwrap();
            let hn = normalized_dlt(&c).unwrap();
            let h = c.denormalize_h(&hn);
            assert!(relative_h_error(&h, &truth) < 1e-11, "normalized n={n}");
            let h = plain_dlt(&c, 1e-4).unwrap();
            assert!(relative_h_error(&h, &truth) < 1e-9, "plain n={n}");
            let got = project(&h, &src[0]);
            assert!((got[0] - dst[0][0]).abs() < 1e-6 * spread.max(1.0));
        }
    }

    #[test]
    fn plain_dlt_refuses_what_it_cannot_resolve() {
        // Offsets of 1e6 over a spread of 1: raw A is hopelessly conditioned.
        let (src, dst, _) = sample_problem(20, 1.0, 1e6);
        let c = Correspondences::new(&src, &dst).unwrap();
        assert!(matches!(
            plain_dlt(&c, 1e-2),
            Err(HomographyError::IllConditioned { solver: "svd", .. })
        ));
        // The normalised solver has no such trouble.
        assert!(normalized_dlt(&c).is_ok());
    }
}
