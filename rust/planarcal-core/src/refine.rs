//! Levenberg-Marquardt refinement of the transfer error in the destination image,
//!     min_H  sum_i || dst_i - pi(H src_i) ||^2,
//! the maximum-likelihood ("gold standard") homography for Gaussian noise in the destination.
//! It runs in normalised coordinates (a similarity on each side, so the minimiser is the same)
//! with h33 fixed to 1 there: h33 is then w at the source centroid, which is safely away from
//! zero for any homography that keeps the points in front. The loop is `lm`'s; this module
//! gives it the normal equations, summed in one vectorised pass over the points.

use nalgebra::{Matrix3, SMatrix, SVector};

use crate::alloc;
use crate::correspondences::Correspondences;
use crate::error::Result;
use crate::lm::{self, Damping, LeastSquares, Normal, Options};

type Mat8 = SMatrix<f64, 8, 8>;
type Vec8 = SVector<f64, 8>;

const MAX_ITERATIONS: usize = 100;

/// The loop's settings; `cost_floor` is set per problem.
const OPTIONS: Options = Options {
    max_iterations: MAX_ITERATIONS,
    // The linear estimate is a good start: begin close to Gauss-Newton (Nielsen's tau = 1e-6).
    damping: Damping::Nielsen { tau: 1e-6 },
    max_damping: 1e30,
    diagonal_floor: 1e-300,
    cost_floor: 0.0,
    gain_tol: 1e-13,
    // A step this small changes H below rounding that matters: stop without trying it.
    step_tol: 1e-13,
    step_offset: 1e-13,
    try_small_steps: false,
};

/// The reweighted loop converges linearly, and its last steps move H by far less than the
/// noise: a gain of 1e-8 of the cost leaves H within about 1e-4 sigma of the minimum (the
/// excess cost is of the order of the gain), in 4-7 iterations instead of 10-18.
const CAUCHY_OPTIONS: Options = Options {
    gain_tol: 1e-8,
    ..OPTIONS
};

/// What the refinement did, for diagnostics and tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineReport {
    /// Levenberg-Marquardt iterations run.
    pub iterations: usize,
    /// Sum of squared transfer errors before and after, in the caller's destination units.
    pub initial_cost: f64,
    /// See `initial_cost`.
    pub final_cost: f64,
}

/// Sums a point contributes to the normal equations, weighted by a = 1/w^2: p p^T (XX, XY,
/// X, YY, Y, 1); x^ p q^T and y^ p q^T with q = (X, Y) (XX, XY, YY, X, Y each); (x^2 + y^2)
/// q q^T (XX, XY, YY); J^T r (8); and the squared residual.
const SUMS: usize = 28;
/// Points accumulated side by side in separate lanes, which the compiler turns into vector
/// arithmetic; the lanes are added in a fixed order, so every build gives the same bits.
const LANES: usize = 4;

/// How a point's squared residual r2 counts: its weight in J^T J and J^T r, and its cost
/// (whose derivative in r2 is the weight, so the loop's steps descend that cost).
trait Loss: Copy {
    fn weigh(self, r2: f64) -> (f64, f64);
}

/// Least squares: every point weighs 1 (the multiplications by 1 fold away).
#[derive(Clone, Copy)]
struct Squared;

impl Loss for Squared {
    #[inline(always)]
    fn weigh(self, r2: f64) -> (f64, f64) {
        (1.0, r2)
    }
}

/// The Cauchy kernel of scale c (c2 = c^2): cost c^2 ln(1 + r^2 / c^2), weight
/// 1 / (1 + r^2 / c^2), so points a few c away count little.
#[derive(Clone, Copy)]
struct Cauchy {
    c2: f64,
}

impl Loss for Cauchy {
    #[inline(always)]
    fn weigh(self, r2: f64) -> (f64, f64) {
        let u = r2 / self.c2;
        (1.0 / (1.0 + u), self.c2 * ln_1p(u))
    }
}

/// ln(1 + u) for u >= 0, within a few ulps of `f64::ln_1p`, in plain arithmetic and bit
/// operations that the accumulation loop vectorises (the library call does not, and made
/// the Cauchy refit 2-3x slower than the least-squares one).
#[inline(always)]
fn ln_1p(u: f64) -> f64 {
    const SQRT_2: f64 = std::f64::consts::SQRT_2;
    const MANTISSA: u64 = (1 << 52) - 1;
    let w = 1.0 + u;
    // w = m 2^e with m in [sqrt(1/2), sqrt(2)).
    let bits = w.to_bits();
    let mut e = ((bits >> 52) & 0x7ff) as i64 - 1023;
    let mut m = f64::from_bits((bits & MANTISSA) | 1.0f64.to_bits());
    let high = m >= SQRT_2;
    m = if high { 0.5 * m } else { m };
    e += i64::from(high);
    // ln m = 2 atanh(s), s = (m - 1) / (m + 1), |s| <= 0.172: the series to s^23.
    let s = (m - 1.0) / (m + 1.0);
    let z = s * s;
    let mut series = 1.0 / 23.0;
    for k in (0..11).rev() {
        series = series * z + 1.0 / (2 * k + 1) as f64;
    }
    let ln_w = e as f64 * std::f64::consts::LN_2 + 2.0 * s * series;
    // w rounds 1 + u: ln(w) u / (w - 1) corrects for it (Goldberg), and is u where w = 1;
    // beyond 1 the rounding no longer matters. Infinity and NaN pass through.
    if !(w < f64::INFINITY) {
        w
    } else if u >= 1.0 {
        ln_w
    } else if w == 1.0 {
        u
    } else {
        ln_w * (u / (w - 1.0))
    }
}

/// Point (X, Y, x, y)'s terms under the loss, and whether it is in front (w > 0).
#[inline(always)]
fn terms<L: Loss>(p: &Vec8, [sx, sy, dx, dy]: [f64; 4], loss: L) -> ([f64; SUMS], bool) {
    let w = p[6] * sx + p[7] * sy + 1.0;
    let iw = 1.0 / w;
    let xh = (p[0] * sx + p[1] * sy + p[2]) * iw;
    let yh = (p[3] * sx + p[4] * sy + p[5]) * iw;
    let (rx, ry) = (xh - dx, yh - dy);
    let (weight, cost) = loss.weigh(rx * rx + ry * ry);
    let a = weight * iw * iw;
    let (ax, ay) = (a * sx, a * sy);
    let (axx, axy, ayy) = (ax * sx, ax * sy, ay * sy);
    let r2 = xh * xh + yh * yh;
    let wiw = weight * iw;
    let (ex, ey) = (rx * wiw, ry * wiw);
    let e3 = -(xh * rx + yh * ry) * wiw;
    let t = [
        axx,
        axy,
        ax,
        ayy,
        ay,
        a,
        xh * axx,
        xh * axy,
        xh * ayy,
        xh * ax,
        xh * ay,
        yh * axx,
        yh * axy,
        yh * ayy,
        yh * ax,
        yh * ay,
        r2 * axx,
        r2 * axy,
        r2 * ayy,
        ex * sx,
        ex * sy,
        ex,
        ey * sx,
        ey * sy,
        ey,
        e3 * sx,
        e3 * sy,
        cost,
    ];
    (t, w > 0.0)
}

/// The lane sums over all points; None if a point reaches w <= 0 (or NaN).
#[inline(always)]
fn accumulate<L: Loss>(pts: &[[f64; 4]], p: &Vec8, loss: L) -> Option<[f64; SUMS]> {
    let mut acc = [[0.0f64; LANES]; SUMS];
    let mut front = true;
    let (chunks, tail) = pts.as_chunks::<LANES>();
    for chunk in chunks {
        for (l, &pt) in chunk.iter().enumerate() {
            let (t, ok) = terms(p, pt, loss);
            front &= ok;
            for k in 0..SUMS {
                acc[k][l] += t[k];
            }
        }
    }
    for (l, &pt) in tail.iter().enumerate() {
        let (t, ok) = terms(p, pt, loss);
        front &= ok;
        for k in 0..SUMS {
            acc[k][l] += t[k];
        }
    }
    if !front {
        return None;
    }
    Some(acc.map(|lanes| lanes.iter().sum()))
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_avx2<L: Loss>(pts: &[[f64; 4]], p: &Vec8, loss: L) -> Option<[f64; SUMS]> {
    accumulate(pts, p, loss)
}

/// Cost, J^T J and J^T r at p = (h11 .. h32) with h33 = 1; None if a point reaches w <= 0.
/// `pts` holds the normalised pairs (X, Y, x, y). Runs the AVX2 build where the CPU has it
/// (no FMA: both builds round identically).
fn evaluate<L: Loss>(pts: &[[f64; 4]], p: &Vec8, loss: L) -> Option<Normal<8>> {
    #[cfg(target_arch = "x86_64")]
    let sums = if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        unsafe { accumulate_avx2(pts, p, loss) }
    } else {
        accumulate(pts, p, loss)
    };
    #[cfg(not(target_arch = "x86_64"))]
    let sums = accumulate(pts, p, loss);
    let [a_xx, a_xy, a_x, a_yy, a_y, a_1, bx_xx, bx_xy, bx_yy, bx_x, bx_y, by_xx, by_xy, by_yy, by_x, by_y, c_xx, c_xy, c_yy, g1x, g1y, g1, g2x, g2y, g2, g3x, g3y, cost] =
        sums?;
    let mut jtj = Mat8::zeros();
    let p3 = [[a_xx, a_xy, a_x], [a_xy, a_yy, a_y], [a_x, a_y, a_1]];
    // Rows of p q^T: (X X, X Y), (Y X, Y Y), (X, Y).
    let pq_x = [[bx_xx, bx_xy], [bx_xy, bx_yy], [bx_x, bx_y]];
    let pq_y = [[by_xx, by_xy], [by_xy, by_yy], [by_x, by_y]];
    for i in 0..3 {
        for j in 0..3 {
            jtj[(i, j)] = p3[i][j];
            jtj[(3 + i, 3 + j)] = p3[i][j];
        }
        for j in 0..2 {
            jtj[(i, 6 + j)] = -pq_x[i][j];
            jtj[(6 + j, i)] = -pq_x[i][j];
            jtj[(3 + i, 6 + j)] = -pq_y[i][j];
            jtj[(6 + j, 3 + i)] = -pq_y[i][j];
        }
    }
    jtj[(6, 6)] = c_xx;
    jtj[(6, 7)] = c_xy;
    jtj[(7, 6)] = c_xy;
    jtj[(7, 7)] = c_yy;
    let jtr = Vec8::from_column_slice(&[g1x, g1y, g1, g2x, g2y, g2, g3x, g3y]);
    Some(Normal { jtj, jtr, cost })
}

/// The transfer error over the normalised pairs (X, Y, x, y), under a loss.
struct Transfer<L> {
    pts: Vec<[f64; 4]>,
    loss: L,
}

impl<L: Loss> LeastSquares<8> for Transfer<L> {
    fn normal_equations(&self, p: &Vec8) -> Option<Normal<8>> {
        evaluate(&self.pts, p, self.loss)
    }
}

pub(crate) fn to_params(hn: &Matrix3<f64>) -> Option<Vec8> {
    let h33 = hn[(2, 2)];
    // w at the source centroid must dominate for the h33 = 1 gauge to be well conditioned.
    if !(h33.abs() > 1e-8 * hn.norm()) {
        return None;
    }
    let s = hn / h33;
    Some(Vec8::from_column_slice(&[
        s[(0, 0)],
        s[(0, 1)],
        s[(0, 2)],
        s[(1, 0)],
        s[(1, 1)],
        s[(1, 2)],
        s[(2, 0)],
        s[(2, 1)],
    ]))
}

pub(crate) fn from_params(p: &Vec8) -> Matrix3<f64> {
    Matrix3::new(p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], 1.0)
}

/// Refines a homography given in normalised coordinates; returns it in normalised coordinates
/// (h33 = 1). Never returns a worse fit than it was given: if the start cannot be refined
/// (a point behind the horizon), the start comes back unchanged. OutOfMemory when the
/// points' working copy (32 bytes a point) cannot be allocated.
pub fn levenberg_marquardt(
    c: &Correspondences,
    hn: &Matrix3<f64>,
) -> Result<(Matrix3<f64>, RefineReport)> {
    let to_caller_units = 1.0 / (c.dst_norm.scale * c.dst_norm.scale);
    let unchanged = || {
        (
            *hn,
            RefineReport {
                iterations: 0,
                initial_cost: f64::NAN,
                final_cost: f64::NAN,
            },
        )
    };
    let Some(p) = to_params(hn) else {
        return Ok(unchanged());
    };
    let problem = Transfer {
        pts: alloc::collect(
            c.normalized_pairs()
                .map(|([sx, sy], [dx, dy])| [sx, sy, dx, dy]),
        )?,
        loss: Squared,
    };
    let options = Options {
        // A cost this small is rounding: the data are exact.
        cost_floor: 1e-28 * c.len() as f64,
        ..OPTIONS
    };
    let Some(fit) = lm::minimize(&problem, p, &options) else {
        return Ok(unchanged());
    };
    Ok((
        from_params(&fit.x),
        RefineReport {
            iterations: fit.iterations,
            initial_cost: fit.initial_cost * to_caller_units,
            final_cost: fit.at.cost * to_caller_units,
        },
    ))
}

/// The Cauchy-kernel refit of p (normalised, h33 = 1; see `to_params`) to the normalised
/// pairs (X, Y, x, y) at kernel scale c (c2 = c^2): the least-squares loop, iteratively
/// reweighted. The result is never costlier than p under the kernel; None when the cost
/// cannot be evaluated at p.
pub(crate) fn cauchy_refit(pts: Vec<[f64; 4]>, p: Vec8, c2: f64) -> Option<Vec8> {
    let problem = Transfer {
        pts,
        loss: Cauchy { c2 },
    };
    lm::minimize(&problem, p, &CAUCHY_OPTIONS).map(|fit| fit.x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dlt::normalized_dlt;
    use crate::testing::{noisy, relative_h_error, sample_problem, transfer_cost};

    #[test]
    fn ln_1p_agrees_with_the_library() {
        let mut u = 1e-300;
        while u < 1e300 {
            for v in [u, 1.37 * u, 2.0f64.sqrt() * u - 1e-3 * u] {
                let (fast, exact) = (ln_1p(v), v.ln_1p());
                assert!(
                    (fast - exact).abs() <= 4.0 * f64::EPSILON * exact,
                    "{v}: {fast} vs {exact}"
                );
            }
            u *= 3.1;
        }
        assert_eq!(ln_1p(0.0), 0.0);
        assert_eq!(ln_1p(f64::INFINITY), f64::INFINITY);
        assert!(ln_1p(f64::NAN).is_nan());
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let (src, dst, _) = sample_problem(9, 10.0, 3.0);
        let dst = noisy(&dst, 0.05, 1);
        let c = Correspondences::new(&src, &dst).unwrap();
        let p = to_params(&normalized_dlt(&c).unwrap()).unwrap();
        let pts: Vec<[f64; 4]> = c
            .normalized_pairs()
            .map(|(s, d)| [s[0], s[1], d[0], d[1]])
            .collect();
        let e = evaluate(&pts, &p, Squared).unwrap();
        // The gradient of cost/2 is J^T r.
        for k in 0..8 {
            let h = 1e-6;
            let (mut a, mut b) = (p, p);
            a[k] += h;
            b[k] -= h;
            let fd = (evaluate(&pts, &a, Squared).unwrap().cost
                - evaluate(&pts, &b, Squared).unwrap().cost)
                / (4.0 * h);
            assert!(
                (fd - e.jtr[k]).abs() < 1e-6 * (1.0 + fd.abs()),
                "k={k}: {fd} vs {}",
                e.jtr[k]
            );
        }
    }

    #[test]
    fn refinement_lowers_the_transfer_error_and_stops() {
        let (src, dst, _) = sample_problem(60, 800.0, 100.0);
        let dst = noisy(&dst, 0.5, 2);
        let c = Correspondences::new(&src, &dst).unwrap();
        let start = normalized_dlt(&c).unwrap();
        let (refined, report) = levenberg_marquardt(&c, &start).unwrap();
        let before = transfer_cost(&c.denormalize_h(&start), &src, &dst);
        let after = transfer_cost(&c.denormalize_h(&refined), &src, &dst);
        assert!(after <= before);
        assert!((report.final_cost - after).abs() < 1e-9 * after);
        assert!(report.iterations < MAX_ITERATIONS);
        // At the optimum the gradient vanishes.
        let pts: Vec<[f64; 4]> = c
            .normalized_pairs()
            .map(|(s, d)| [s[0], s[1], d[0], d[1]])
            .collect();
        let e = evaluate(&pts, &to_params(&refined).unwrap(), Squared).unwrap();
        assert!(e.jtr.norm() < 1e-10 * (1.0 + e.cost));
    }

    #[test]
    fn exact_data_stays_exact() {
        let (src, dst, truth) = sample_problem(30, 50.0, 10.0);
        let c = Correspondences::new(&src, &dst).unwrap();
        let (refined, _) = levenberg_marquardt(&c, &normalized_dlt(&c).unwrap()).unwrap();
        assert!(relative_h_error(&c.denormalize_h(&refined), &truth) < 1e-11);
    }
}
