//! Progressive sampling (PROSAC, Chum & Matas 2005) over a ranking of the correspondences,
//! with its stopping rule: the search may stop once, for some prefix U_n of the ranking in
//! which the best model's support is not due to chance, enough samples have been drawn from
//! U_n (or subsets containing it) for `confidence` that an all-inlier sample of U_n would
//! have been found (maximality). With a good ranking the top of it is mostly inliers, and
//! the search ends after hundreds of samples where uniform sampling needs tens of thousands.
//!
//! Two changes of our own. Maximality only speaks of support within U_n, and a second
//! structure (another plane, a repeated pattern) can fill the top of a ranking by local
//! consistency while the true model has more support overall (measured: with an exact
//! second plane of 70% of the inliers' size, small prefixes stopped the search on the wrong
//! plane). So U_n has a floor: at least twice the best model's support, and, for a ranking by
//! neighbourhood consistency, every point with any consistency at all, where every locally
//! consistent structure is. And once a model has chosen U_n, sampling draws from U_n alone
//! (widening to it at once, rather than at PROSAC's pace of one point per sample) until the
//! rule is met; only those samples count.

use super::chance::minimum_support;
use super::sampler::{Pcg32, Prosac};
use super::sprt::Sprt;

/// Chance that a wrong model's support within a prefix reaches the required count.
const NON_RANDOMNESS: f64 = 0.05;
/// Fewest inliers of a model that may stop the search (as many as local optimisation needs).
const MIN_SUPPORT: usize = 8;
/// Prefix sizes tried by the stopping rule grow by this factor (a sparse, O(log n) set).
const PREFIX_GROWTH: f64 = 1.1;

pub struct Progressive {
    /// rank[i]: the original index of the i-th best correspondence.
    rank: Vec<u32>,
    sampler: Prosac,
    /// Samples drawn since progressive sampling began.
    pub drawn: usize,
    /// Samples the stopping rule asks for (infinite until a model qualifies) from the prefix
    /// it chose, and when sampling began to draw from that prefix alone.
    pub needed: f64,
    prefix: u32,
    since: usize,
    /// Samples progressive sampling may draw in all.
    budget: usize,
    floor: usize,
}

impl Progressive {
    /// `samples` bounds the draws: by then sampling is uniform over all points. `floor` is
    /// the smallest prefix the stopping rule may use (see `update`).
    pub fn new(rank: Vec<u32>, samples: usize, floor: usize) -> Self {
        let n = rank.len() as u32;
        Progressive {
            rank,
            sampler: Prosac::new(n, samples.max(1) as u64),
            drawn: 0,
            needed: f64::INFINITY,
            prefix: n,
            since: 0,
            budget: samples,
            floor,
        }
    }

    /// The next minimal sample, as original indices.
    pub fn sample(&mut self, rng: &mut Pcg32, out: &mut [u32; 4]) {
        self.sampler.sample(rng, out);
        *out = out.map(|i| self.rank[i as usize]);
        self.drawn += 1;
    }

    pub fn done(&self) -> bool {
        self.left() <= 0.0
    }

    /// Samples still to draw before the rule is met.
    pub fn left(&self) -> f64 {
        self.needed - (self.drawn - self.since) as f64
    }

    /// Updates the stopping rule for a new best model, given which points are its inliers
    /// (by original index), the SPRT in force and the rate `delta` at which points agree
    /// with a wrong model.
    pub fn update(&mut self, is_inlier: &[bool], sprt: &Sprt, delta: f64, confidence: f64) {
        let total = self.rank.len();
        let survive = 1.0 - (-sprt.log_a).exp();
        let overall = is_inlier.iter().filter(|&&b| b).count();
        let (mut needed, mut prefix) = (f64::INFINITY, total);
        // Only a model whose support over all points is beyond chance may stop the search.
        if overall < minimum_support(total, delta, NON_RANDOMNESS).max(MIN_SUPPORT) {
            self.needed = needed;
            self.prefix = prefix as u32;
            return;
        }
        let mut support = 0usize;
        let mut counted = 0usize;
        let mut size = (2 * overall).max(self.floor).clamp(8.min(total), total);
        loop {
            while counted < size {
                support += usize::from(is_inlier[self.rank[counted] as usize]);
                counted += 1;
            }
            if support >= minimum_support(size, delta, NON_RANDOMNESS) {
                let mut p = survive;
                for j in 0..4 {
                    p *= support.saturating_sub(j) as f64 / (size - j) as f64;
                }
                if p > 0.0 {
                    let k = if p >= 1.0 {
                        1.0
                    } else {
                        ((1.0 - confidence).ln() / (1.0 - p).ln()).ceil().max(1.0)
                    };
                    if k < needed {
                        needed = k;
                        prefix = size;
                    }
                }
            }
            if size == total {
                break;
            }
            size = ((size as f64 * PREFIX_GROWTH).ceil() as usize).clamp(size + 1, total);
        }
        // Sampling draws from the chosen prefix alone until the rule is met (PROSAC's growth
        // steps would put a point from beyond it in every sample); the count starts when the
        // prefix changes.
        if prefix as u32 != self.prefix || !self.needed.is_finite() {
            self.since = self.drawn;
        }
        self.needed = needed;
        self.prefix = prefix as u32;
        // A rule the sample budget cannot meet is no reason to narrow the search: sampling
        // then grows on towards all the points.
        let hold = needed - (self.drawn - self.since) as f64;
        if hold <= self.budget.saturating_sub(self.drawn) as f64 {
            self.sampler.focus(self.prefix, hold.max(0.0) as u64);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clean_top_of_the_ranking_stops_the_search_early() {
        let n = 1000;
        // The top 100 ranked points are inliers; 10% of the rest are.
        let rank: Vec<u32> = (0..n as u32).collect();
        let is_inlier: Vec<bool> = (0..n).map(|i| i < 100 || i % 10 == 0).collect();
        let mut p = Progressive::new(rank, 10_000, 0);
        let sprt = Sprt::new(0.19, 0.001);
        p.update(&is_inlier, &sprt, 0.001, 0.999);
        // A prefix of twice the support (380 points, a third of them inliers) asks for about
        // 600 samples; uniform sampling at 19% inliers would need 5,000.
        assert!(p.left() < 1000.0, "{}", p.left());
        // The same support spread uniformly through the ranking earns no shortcut.
        let spread: Vec<bool> = (0..n).map(|i| i % 5 == 0).collect();
        p.update(&spread, &sprt, 0.001, 0.999);
        assert!(p.left() > 3000.0, "{}", p.left());
    }

    #[test]
    fn a_rival_at_the_top_does_not_stop_the_search() {
        // The top 20 agree with the best model; the next 30 are another structure's.
        let n = 1000;
        let rank: Vec<u32> = (0..n as u32).collect();
        let is_inlier: Vec<bool> = (0..n).map(|i| i < 20 || (50..70).contains(&i)).collect();
        let mut p = Progressive::new(rank, 10_000, 0);
        p.update(&is_inlier, &Sprt::new(0.04, 0.001), 0.001, 0.999);
        // The prefix must hold 80 points, the rival's 30 among them, and sampling reaches it.
        assert!(p.prefix >= 80, "{}", p.prefix);
        assert!(p.sampler.subset() >= 80);
        let mut rng = Pcg32::new(1, 1);
        let mut s = [0u32; 4];
        let before = p.left();
        p.sample(&mut rng, &mut s);
        assert_eq!(p.left(), before - 1.0);
    }
}
