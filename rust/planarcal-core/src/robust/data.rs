//! The correspondences as the robust estimator scores them: normalised (one Hartley similarity
//! for all sources, one for all destinations), as structure-of-arrays, in a fixed random order
//! (SPRT's early decisions assume the points it has seen are a random draw) and in the
//! original order (for drawing samples). Residual tests are division-free:
//! ||d - H s||^2 <= t^2  <=>  |e|^2 <= t^2 w^2 with e = (h1.s - u w, h2.s - v w), w > 0.

use crate::alloc;
use crate::error::Result;
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
    /// Area the destination points spread over (normalised units): that of the uniform
    /// rectangle with the same second moments, 12 sqrt(det(covariance)).
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
/// Interleaved partial sums of the MSAC score (they vectorise; a fixed order of adding them
/// keeps the result the same in every build).
const LANES: usize = 4;

/// A public method that runs an AVX2 build of its body where the CPU has it (as OpenCV
/// does; no FMA, so both builds round identically).
macro_rules! with_avx2 {
    ($(#[$doc:meta])* $name:ident, $fast:ident, $body:ident,
     ($($arg:ident: $ty:ty),*) -> $ret:ty) => {
        $(#[$doc])*
        pub fn $name(&self, $($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2, checked just above.
                return unsafe { self.$fast($($arg),*) };
            }
            self.$body($($arg),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        unsafe fn $fast(&self, $($arg: $ty),*) -> $ret {
            self.$body($($arg),*)
        }
    };
}

/// A well-mixed hash of a sample's indices (splitmix64 finaliser).
fn sample_hash(sample: &[u32; 4]) -> u64 {
    let mut z = sample
        .iter()
        .fold(0u64, |acc, &i| acc.rotate_left(17) ^ u64::from(i))
        .wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Whether (x, y) -> (u, v) is within squared distance t2 of h's prediction, division-free.
#[inline(always)]
fn agrees(h: &[f64; 9], x: f64, y: f64, u: f64, v: f64, t2: f64) -> bool {
    let w = h[6] * x + h[7] * y + h[8];
    let ex = h[0] * x + h[1] * y + h[2] - u * w;
    let ey = h[3] * x + h[4] * y + h[5] - v * w;
    (w > 0.0) & (ex * ex + ey * ey <= t2 * w * w)
}

/// Squared transfer error of (x, y) -> (u, v) under h; infinite behind the horizon.
#[inline(always)]
fn residual2(h: &[f64; 9], x: f64, y: f64, u: f64, v: f64) -> f64 {
    let w = h[6] * x + h[7] * y + h[8];
    let iw = 1.0 / w;
    let ex = (h[0] * x + h[1] * y + h[2]) * iw - u;
    let ey = (h[3] * x + h[4] * y + h[5]) * iw - v;
    let r2 = ex * ex + ey * ey;
    // `&`, not `&&`: no branch, so the callers' loops vectorise.
    if (w > 0.0) & (r2 < f64::INFINITY) {
        r2
    } else {
        f64::INFINITY
    }
}

/// Fixed-size blocks of the four coordinate arrays, for loops the compiler can vectorise (no
/// bounds checks inside), and the points left over.
type Blocks<'a, const B: usize> = (
    std::iter::Zip<
        std::iter::Zip<
            std::iter::Zip<std::slice::Iter<'a, [f64; B]>, std::slice::Iter<'a, [f64; B]>>,
            std::slice::Iter<'a, [f64; B]>,
        >,
        std::slice::Iter<'a, [f64; B]>,
    >,
    usize,
);

impl Data {
    /// Points from..to in blocks of B, and where the whole blocks end.
    #[inline(always)]
    fn blocks<const B: usize>(&self, from: usize, to: usize) -> Blocks<'_, B> {
        let (x, _) = self.x[from..to].as_chunks::<B>();
        let (y, _) = self.y[from..to].as_chunks::<B>();
        let (u, _) = self.u[from..to].as_chunks::<B>();
        let (v, _) = self.v[from..to].as_chunks::<B>();
        let whole = from + x.len() * B;
        (x.iter().zip(y).zip(u).zip(v), whole)
    }

    /// None when all sources (or all destinations) coincide: nothing to normalise.
    /// OutOfMemory when its arrays (80 bytes a point) cannot be allocated.
    pub fn new(
        src: &[Point],
        dst: &[Point],
        threshold: f64,
        rng: &mut Pcg32,
    ) -> Result<Option<Self>> {
        let Some(src_norm) = Normalization::from_stats(&PointStats::of(src)) else {
            return Ok(None);
        };
        let dst_stats = PointStats::of(dst);
        let Some(dst_norm) = Normalization::from_stats(&dst_stats) else {
            return Ok(None);
        };
        let n = src.len();
        let src_n = alloc::collect(src.iter().map(|p| src_norm.apply(p)))?;
        let dst_n = alloc::collect(dst.iter().map(|p| dst_norm.apply(p)))?;
        let order = rng.permutation(n)?;
        let mut position = alloc::filled(0u32, n)?;
        for (k, &i) in order.iter().enumerate() {
            position[i as usize] = k as u32;
        }
        let pick =
            |a: &[[f64; 2]], c: usize| alloc::collect(order.iter().map(|&i| a[i as usize][c]));
        let t = threshold * dst_norm.scale;
        // The scatter is in units of `unit`; normalised coordinates are scaled by `scale`.
        let (k, m) = (dst_stats.unit * dst_norm.scale, n as f64);
        let det = (dst_stats.sxx * dst_stats.syy - dst_stats.sxy * dst_stats.sxy).max(0.0);
        let dst_area = (12.0 * det.sqrt() / m * k * k).max(1e-12);
        Ok(Some(Data {
            n,
            x: pick(&src_n, 0)?,
            y: pick(&src_n, 1)?,
            u: pick(&dst_n, 0)?,
            v: pick(&dst_n, 1)?,
            src: src_n,
            dst: dst_n,
            order,
            position,
            src_norm,
            dst_norm,
            t2: t * t,
            dst_area,
        }))
    }

    with_avx2!(
        /// SPRT of a hypothesis made from `sample` (see `sprt_body`).
        sprt, sprt_avx2, sprt_body,
        (h: &[f64; 9], sample: &[u32; 4], test: &Sprt, best: usize) -> Verdict
    );
    with_avx2!(
        /// Inlier count and MSAC cost of h over all points.
        msac, msac_avx2, msac_body, (h: &[f64; 9]) -> (usize, f64)
    );
    with_avx2!(
        /// The points within squared threshold `t2` of h (see `inliers_body`).
        inliers, inliers_avx2, inliers_body, (h: &[f64; 9], t2: f64) -> Result<Vec<u32>>
    );

    /// Whether point k (evaluation order) is an inlier of h at squared threshold t2.
    #[inline(always)]
    fn agrees(&self, h: &[f64; 9], k: usize, t2: f64) -> bool {
        agrees(h, self.x[k], self.y[k], self.u[k], self.v[k], t2)
    }

    /// SPRT: points are tested in chunks; the model is rejected as soon as the log
    /// likelihood ratio of "bad" to "good" exceeds `log_a`. The sample's own points agree
    /// with any model made from them, so they are no evidence and are left out (counted as
    /// inliers all the same); otherwise a wrong model would get four points of credit.
    /// A model that passes the test but trails `best` (the best model's support) by far
    /// more than chance explains is given up as well (a bail-out test, Capel 2005).
    #[inline(always)]
    fn sprt_body(&self, h: &[f64; 9], sample: &[u32; 4], test: &Sprt, best: usize) -> Verdict {
        let (log_in, log_out, log_a) = (test.log_in, test.log_out, test.log_a);
        let pace = best as f64 / self.n as f64;
        let at = sample.map(|i| self.position[i as usize] as usize);
        // Each hypothesis starts at its own chunk, picked from its sample (deterministic),
        // and wraps around: SPRT's error rates assume that different hypotheses see
        // independent points first. With one fixed start, a first chunk that happens to hold
        // no inliers would reject every good model alike.
        let chunks = self.n.div_ceil(CHUNK);
        let first = sample_hash(sample) as usize % chunks;
        let (mut log_lambda, mut inliers, mut tested) = (0.0, 0usize, 0usize);
        for c in (first..chunks).chain(0..first) {
            let (k, end) = (c * CHUNK, ((c + 1) * CHUNK).min(self.n));
            let mut agree = 0usize;
            if end - k == CHUNK {
                let (blocks, _) = self.blocks::<CHUNK>(k, end);
                for (((x, y), u), v) in blocks {
                    let mut lanes = [0u64; CHUNK];
                    for l in 0..CHUNK {
                        lanes[l] = u64::from(agrees(h, x[l], y[l], u[l], v[l], self.t2));
                    }
                    agree = lanes.iter().sum::<u64>() as usize;
                }
            } else {
                for j in k..end {
                    agree += usize::from(self.agrees(h, j, self.t2));
                }
            }
            let own = at.iter().filter(|&&p| p >= k && p < end).count();
            let agree = agree.saturating_sub(own);
            inliers += agree;
            tested += end - k - own;
            log_lambda += agree as f64 * log_in + (end - k - own - agree) as f64 * log_out;
            let more = tested + 4 < self.n;
            if log_lambda > log_a && more {
                return Verdict::Rejected { tested, inliers };
            }
            // Behind the best model's pace by 4 standard deviations and 5%.
            let expected = pace * tested as f64;
            if expected - inliers as f64 > 4.0 * expected.sqrt() + 0.05 * expected && more {
                return Verdict::Outscored;
            }
        }
        Verdict::Accepted {
            inliers: inliers + 4,
        }
    }

    /// Inlier count and MSAC cost (sum of min(r^2, t^2), normalised units) over all points.
    #[inline(always)]
    fn msac_body(&self, h: &[f64; 9]) -> (usize, f64) {
        // Branch-free, in LANES interleaved sums that vectorise (min is NaN-safe here: r2 is
        // never NaN, infinite at worst).
        let t2 = self.t2;
        let (mut count, mut cost) = ([0u64; LANES], [0.0f64; LANES]);
        let (blocks, whole) = self.blocks::<LANES>(0, self.n);
        for (((x, y), u), v) in blocks {
            for l in 0..LANES {
                let r2 = residual2(h, x[l], y[l], u[l], v[l]);
                count[l] += u64::from(r2 <= t2);
                cost[l] += if r2 < t2 { r2 } else { t2 };
            }
        }
        for (l, k) in (whole..self.n).enumerate() {
            let r2 = self.residual2(h, k);
            count[l] += u64::from(r2 <= t2);
            cost[l] += r2.min(t2);
        }
        (count.iter().sum::<u64>() as usize, cost.iter().sum())
    }

    /// Squared transfer error of point k (evaluation order); infinite behind the horizon.
    #[inline(always)]
    fn residual2(&self, h: &[f64; 9], k: usize) -> f64 {
        residual2(h, self.x[k], self.y[k], self.u[k], self.v[k])
    }

    /// Original indices of the points within squared threshold `t2` of h, in evaluation
    /// order (a fixed random order: any prefix is a random subset).
    #[inline(always)]
    fn inliers_body(&self, h: &[f64; 9], t2: f64) -> Result<Vec<u32>> {
        // The tests vectorise; the compaction after them is branch-free, since about half the
        // points agree, at random, which defeats prediction.
        let mut agree = alloc::filled(0u8, self.n)?;
        let (blocks, whole) = self.blocks::<LANES>(0, self.n);
        for ((((x, y), u), v), a) in blocks.zip(agree.as_chunks_mut::<LANES>().0) {
            for l in 0..LANES {
                a[l] = u8::from(agrees(h, x[l], y[l], u[l], v[l], t2));
            }
        }
        for k in whole..self.n {
            agree[k] = u8::from(self.agrees(h, k, t2));
        }
        let mut out = alloc::filled(0u32, self.n)?;
        let mut count = 0;
        for (k, &a) in agree.iter().enumerate() {
            out[count] = self.order[k];
            count += usize::from(a);
        }
        out.truncate(count);
        Ok(out)
    }

    /// A model of normalised coordinates in the caller's units: T_d^-1 H T_s.
    pub fn denormalize(&self, h: &[f64; 9]) -> nalgebra::Matrix3<f64> {
        let m = nalgebra::Matrix3::from_row_slice(h);
        self.dst_norm.inverse_matrix() * m * self.src_norm.matrix()
    }

    /// Squared residuals of all points in evaluation order (LMedS).
    pub fn residuals2_into(&self, h: &[f64; 9], out: &mut Vec<f64>) -> Result<()> {
        out.clear();
        alloc::reserve(out, self.n)?;
        out.extend((0..self.n).map(|k| self.residual2(h, k)));
        Ok(())
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
        let d = Data::new(&src, &dst, 0.5, &mut rng).unwrap().unwrap();
        let h = [1.0, 0.01, 0.0, 0.0, 1.0, 0.02, 0.05, 0.0, 1.0];
        for k in 0..d.n {
            assert_eq!(d.agrees(&h, k, d.t2), d.residual2(&h, k) <= d.t2, "{k}");
        }
        let (count, cost) = d.msac(&h);
        assert_eq!(count, d.inliers(&h, d.t2).unwrap().len());
        assert!(cost <= d.n as f64 * d.t2);
    }
}
