//! SPRT, the sequential probability ratio test of Matas & Chum (2005): a hypothesis is
//! rejected as soon as the points seen make "bad model" more likely than "good model" by the
//! decision threshold A, which is chosen to minimise the expected run time given the inlier
//! ratio of the best model so far (epsilon) and the rate at which points agree with bad
//! models (delta). The termination criterion accounts for the good models SPRT rejects.

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sprt {
    pub epsilon: f64,
    pub delta: f64,
    /// ln(delta / epsilon): an agreeing point's contribution to ln(lambda).
    pub log_in: f64,
    /// ln((1 - delta) / (1 - epsilon)): a disagreeing point's contribution.
    pub log_out: f64,
    /// ln(A), the decision threshold.
    pub log_a: f64,
}

/// The cost of fitting a hypothesis in units of testing one point (measured: the 4-point
/// solve and its checks take about as long as 50 residual tests).
const MODEL_COST: f64 = 50.0;

impl Sprt {
    pub fn new(epsilon: f64, delta: f64) -> Self {
        // Finite before clamping (clamp panics on a NaN bound).
        let epsilon = if epsilon.is_finite() { epsilon } else { 0.1 }.clamp(1e-4, 0.99);
        let delta = if delta.is_finite() { delta } else { 0.01 }.clamp(1e-5, epsilon * 0.9);
        let log_in = (delta / epsilon).ln();
        let log_out = ((1.0 - delta) / (1.0 - epsilon)).ln();
        // C: the expected ln(lambda) increment per point of a bad model.
        let c = (1.0 - delta) * log_out + delta * log_in;
        // A solves A = MODEL_COST * C + 1 + ln(A), by fixed-point iteration.
        let a0 = MODEL_COST * c + 1.0;
        let mut a = a0;
        for _ in 0..20 {
            a = a0 + a.ln();
        }
        Sprt {
            epsilon,
            delta,
            log_in,
            log_out,
            log_a: a.max(1.0 + 1e-9).ln(),
        }
    }

    /// Samples needed for `confidence` that an all-inlier sample was drawn and survived SPRT,
    /// given `inliers` of `n` points (a good model survives with probability 1 - 1/A).
    pub fn iterations_needed(&self, confidence: f64, inliers: usize, n: usize) -> f64 {
        samples_needed(
            confidence,
            all_inliers(inliers, n) * (1.0 - (-self.log_a).exp()),
        )
    }
}

/// The chance that a sample of 4 distinct points out of n are all among the inliers (drawn
/// without replacement: at 7 inliers of 40 it is 2.5 times smaller than (7/40)^4, and the
/// search would stop that much too early).
pub fn all_inliers(inliers: usize, n: usize) -> f64 {
    (0..4)
        .map(|j| inliers.saturating_sub(j) as f64 / n.saturating_sub(j).max(1) as f64)
        .product()
}

/// Samples needed for `confidence` that one with probability `p` was drawn.
pub fn samples_needed(confidence: f64, p: f64) -> f64 {
    if !(p > 0.0) {
        return f64::INFINITY;
    }
    if p >= 1.0 {
        return 1.0;
    }
    ((1.0 - confidence).ln() / (1.0 - p).ln()).ceil().max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn threshold_solves_its_equation_and_grows_with_separation() {
        let s = Sprt::new(0.3, 0.01);
        let a = s.log_a.exp();
        let c = (1.0 - s.delta) * s.log_out + s.delta * s.log_in;
        assert!((a - (MODEL_COST * c + 1.0 + a.ln())).abs() < 1e-9);
        assert!(Sprt::new(0.5, 0.01).log_a > Sprt::new(0.1, 0.01).log_a);
        assert!(s.log_in < 0.0 && s.log_out > 0.0);
    }

    #[test]
    fn iterations_match_the_classic_formula() {
        // 50% inliers, 99% confidence: 72 samples without SPRT (many points: the classic
        // formula); a few more with it; many more with few points.
        assert_eq!(samples_needed(0.99, all_inliers(500_000, 1_000_000)), 72.0);
        let s = Sprt::new(0.5, 0.01);
        let k = s.iterations_needed(0.99, 500_000, 1_000_000);
        assert!((72.0..80.0).contains(&k), "{k}");
        assert!(s.iterations_needed(0.99, 20, 40) > 1.15 * k);
        assert_eq!(samples_needed(0.99, all_inliers(3, 40)), f64::INFINITY);
        assert_eq!(all_inliers(4, 4), 1.0);
    }
}
