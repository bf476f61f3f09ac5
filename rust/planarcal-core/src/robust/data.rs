//! The correspondences as the robust estimator scores them: normalised (one Hartley similarity
//! for all sources, one for all destinations), as structure-of-arrays, in a fixed random order
//! (SPRT's early decisions assume the points it has seen are a random draw) and in the
//! original order (for drawing samples). Residual tests are division-free:
//! ||d - H s||^2 <= t^2  <=>  |e|^2 <= t^2 w^2 with e = (h1.s - u w, h2.s - v w), w > 0.

use crate::normalize::{Normalization, PointStats};
use crate::Point;

use super::sampler::Pcg32;
use super::sprt::Sprt;

pub struct Data {
    pub n: usize,
    /// Normalised coordinates in the original order.
    pub src: Vec<[f64; 2]>,
    pub dst: Vec<[f64; 2]>,
    /// The same in evaluation order, structure-of-arrays.
    x: Vec<f64>,
    y: Vec<f64>,
    u: Vec<f64>,
    v: Vec<f64>,
    /// order[k]: the original index of the k-th point evaluated; position is its inverse.
    order: Vec<u32>,
    position: Vec<u32>,
    pub src_norm: Normalization,
    pub dst_norm: Normalization,
    /// The squared inlier threshold in normalised destination units.
    pub t2: f64,
    /// Area the middle 90% of the destination points spread over (normalised units).
    pub dst_area: f64,
}

/// How a hypothesis fared against SPRT.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// Rejected after `tested` points, of which `inliers` agreed with it.
    Rejected { tested: usize, inliers: usize },
    /// Every point tested: the model is a candidate.
    Accepted { inliers: usize },
    /// Stopped part-way: clearly on course for less support than the best model (a model
    /// close to it, whose support says nothing about wrong models).
    Outscored,
}

const CHUNK: usize = 16;

/// The range of the middle 90% of the values (selection, not a sort).
fn spread(values: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.collect();
    let lo = (v.len() - 1) / 20;
    let hi = v.len() - 1 - lo;
    let (_, top, _) = v.select_nth_unstable_by(hi, f64::total_cmp);
    let top = *top;
    let (_, bottom, _) = v[..hi].select_nth_unstable_by(lo, f64::total_cmp);
    (top - *bottom).max(1e-12)
}

impl Data {
    /// None when all sources (or all destinations) coincide: nothing to normalise.
    pub fn new(src: &[Point], dst: &[Point], threshold: f64, rng: &mut Pcg32) -> Option<Self> {
        let src_norm = Normalization::from_stats(&PointStats::of(src))?;
        let dst_norm = Normalization::from_stats(&PointStats::of(dst))?;
        let n = src.len();
        let src_n: Vec<[f64; 2]> = src.iter().map(|p| src_norm.apply(p)).collect();
        let dst_n: Vec<[f64; 2]> = dst.iter().map(|p| dst_norm.apply(p)).collect();
        let order = rng.permutation(n);
        let mut position = vec![0u32; n];
        for (k, &i) in order.iter().enumerate() {
            position[i as usize] = k as u32;
        }
        let pick = |a: &[[f64; 2]], c: usize| order.iter().map(|&i| a[i as usize][c]).collect();
        let t = threshold * dst_norm.scale;
        let dst_area = spread(dst_n.iter().map(|p| p[0])) * spread(dst_n.iter().map(|p| p[1]));
        Some(Data {
            n,
            x: pick(&src_n, 0),
            y: pick(&src_n, 1),
            u: pick(&dst_n, 0),
            v: pick(&dst_n, 1),
            src: src_n,
            dst: dst_n,
            order,
            position,
            src_norm,
            dst_norm,
            t2: t * t,
            dst_area,
        })
    }

    /// Whether point k (evaluation order) is an inlier of h at squared threshold t2.
    #[inline(always)]
    fn agrees(&self, h: &[f64; 9], k: usize, t2: f64) -> bool {
        let (x, y) = (self.x[k], self.y[k]);
        let w = h[6] * x + h[7] * y + h[8];
        let ex = h[0] * x + h[1] * y + h[2] - self.u[k] * w;
        let ey = h[3] * x + h[4] * y + h[5] - self.v[k] * w;
        (w > 0.0) & (ex * ex + ey * ey <= t2 * w * w)
    }

    /// SPRT: points are tested in chunks; the model is rejected as soon as the log
    /// likelihood ratio of "bad" to "good" exceeds `log_a`. The sample's own points agree
    /// with any model made from them, so they are no evidence and are left out (counted as
    /// inliers all the same); otherwise a wrong model would get four points of credit.
    /// A model that passes the test but trails `best` (the best model's support) by far
    /// more than chance explains is given up as well (a bail-out test, Capel 2005).
    pub fn sprt(&self, h: &[f64; 9], sample: &[u32; 4], test: &Sprt, best: usize) -> Verdict {
        let (log_in, log_out, log_a) = (test.log_in, test.log_out, test.log_a);
        let pace = best as f64 / self.n as f64;
        let at = sample.map(|i| self.position[i as usize] as usize);
        let mut log_lambda = 0.0;
        let mut inliers = 0;
        let mut k = 0;
        while k < self.n {
            let end = (k + CHUNK).min(self.n);
            let mut agree = 0usize;
            for j in k..end {
                agree += usize::from(self.agrees(h, j, self.t2));
            }
            let own = at.iter().filter(|&&p| p >= k && p < end).count();
            let agree = agree.saturating_sub(own);
            inliers += agree;
            log_lambda += agree as f64 * log_in + (end - k - own - agree) as f64 * log_out;
            k = end;
            if log_lambda > log_a && k < self.n {
                return Verdict::Rejected {
                    tested: k - at.iter().filter(|&&p| p < k).count(),
                    inliers,
                };
            }
            // Behind the best model's pace by 4 standard deviations and 5%.
            let expected = pace * k as f64;
            if expected - inliers as f64 > 4.0 * expected.sqrt() + 0.05 * expected && k < self.n
            {
                return Verdict::Outscored;
            }
        }
        Verdict::Accepted { inliers: inliers + 4 }
    }

    /// Inlier count and MSAC cost (sum of min(r^2, t^2), normalised units) over all points.
    pub fn msac(&self, h: &[f64; 9]) -> (usize, f64) {
        let (mut count, mut cost) = (0, 0.0);
        for k in 0..self.n {
            // Branch-free (min is NaN-safe here: r2 is never NaN, infinite at worst).
            let r2 = self.residual2(h, k);
            count += usize::from(r2 <= self.t2);
            cost += r2.min(self.t2);
        }
        (count, cost)
    }

    /// Squared transfer error of point k (evaluation order); infinite behind the horizon.
    #[inline(always)]
    fn residual2(&self, h: &[f64; 9], k: usize) -> f64 {
        let (x, y) = (self.x[k], self.y[k]);
        let w = h[6] * x + h[7] * y + h[8];
        let iw = 1.0 / w;
        let ex = (h[0] * x + h[1] * y + h[2]) * iw - self.u[k];
        let ey = (h[3] * x + h[4] * y + h[5]) * iw - self.v[k];
        let r2 = ex * ex + ey * ey;
        if w > 0.0 && r2.is_finite() {
            r2
        } else {
            f64::INFINITY
        }
    }

    /// Original indices of the points within squared threshold `t2` of h, in evaluation
    /// order (a fixed random order: any prefix is a random subset).
    pub fn inliers(&self, h: &[f64; 9], t2: f64) -> Vec<u32> {
        // Branch-free: about half the points agree, at random, which defeats prediction.
        let mut out = vec![0u32; self.n];
        let mut count = 0;
        for k in 0..self.n {
            out[count] = self.order[k];
            count += usize::from(self.agrees(h, k, t2));
        }
        out.truncate(count);
        out
    }

    /// A model of normalised coordinates in the caller's units: T_d^-1 H T_s.
    pub fn denormalize(&self, h: &[f64; 9]) -> nalgebra::Matrix3<f64> {
        let m = nalgebra::Matrix3::from_row_slice(h);
        self.dst_norm.inverse_matrix() * m * self.src_norm.matrix()
    }

    /// Squared residuals of all points in evaluation order (LMedS).
    pub fn residuals2_into(&self, h: &[f64; 9], out: &mut Vec<f64>) {
        out.clear();
        out.extend((0..self.n).map(|k| self.residual2(h, k)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn division_free_test_agrees_with_the_residual() {
        let src: Vec<Point> = (0..50)
            .map(|i| [(i * 7 % 13) as f64, (i * 5 % 11) as f64])
            .collect();
        let dst: Vec<Point> = src
            .iter()
            .map(|p| [p[0] * 2.0 + 1.0, p[1] * 2.0 - 3.0])
            .collect();
        let mut rng = Pcg32::new(0, 0);
        let d = Data::new(&src, &dst, 0.5, &mut rng).unwrap();
        let h = [1.0, 0.01, 0.0, 0.0, 1.0, 0.02, 0.05, 0.0, 1.0];
        for k in 0..d.n {
            assert_eq!(d.agrees(&h, k, d.t2), d.residual2(&h, k) <= d.t2, "{k}");
        }
        let (count, cost) = d.msac(&h);
        assert_eq!(count, d.inliers(&h, d.t2).len());
        assert!(cost <= d.n as f64 * d.t2);
    }
}
