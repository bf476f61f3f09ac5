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
    /// given the inlier ratio epsilon (a good model survives with probability 1 - 1/A).
    pub fn iterations_needed(&self, confidence: f64, inlier_ratio: f64) -> f64 {
        let p_good = inlier_ratio.powi(4) * (1.0 - (-self.log_a).exp());
        if !(p_good > 0.0) {
            return f64::INFINITY;
        }
        if p_good >= 1.0 {
            return 1.0;
        }
        ((1.0 - confidence).ln() / (1.0 - p_good).ln())
            .ceil()
            .max(1.0)
    }
}

/// Samples needed for `confidence`, without SPRT.
pub fn plain_iterations_needed(confidence: f64, inlier_ratio: f64) -> f64 {
    let p = inlier_ratio.powi(4);
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
        // 50% inliers, 99% confidence: 72 samples without SPRT.
        assert_eq!(plain_iterations_needed(0.99, 0.5), 72.0);
        let s = Sprt::new(0.5, 0.01);
        let k = s.iterations_needed(0.99, 0.5);
        assert!((72.0..80.0).contains(&k), "{k}");
        assert_eq!(plain_iterations_needed(0.99, 0.0), f64::INFINITY);
    }
}
