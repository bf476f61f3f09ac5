//! How much support chance gives a wrong model: its 4 sample points, plus each other point
//! agreeing with probability `delta` (binomial; here its Poisson limit, and the Gaussian limit
//! of that where the Poisson terms would underflow). A model needs more than this before it
//! counts as found.

/// Beyond this mean, the Poisson tail is summed by its Gaussian limit.
const POISSON_MAX_MEAN: f64 = 200.0;

/// The least support i among n points that a wrong model reaches with probability below
/// `limit`; n + 1 (no support will do) when chance alone covers the points.
pub fn minimum_support(n: usize, delta: f64, limit: f64) -> usize {
    // Four points fit exactly, and say nothing: the caller who gives no more gets their fit.
    if n <= 4 {
        return n;
    }
    let others = n - 4;
    let lambda = others as f64 * delta.clamp(0.0, 1.0);
    let beyond = if lambda > POISSON_MAX_MEAN {
        // P(X >= lambda + z sqrt(lambda)) <= exp(-z^2 / 2) for the Gaussian limit.
        let z = (2.0 * (1.0 / limit).ln()).sqrt();
        (lambda + z * lambda.sqrt()).ceil() as usize + 1
    } else {
        let (mut term, mut below) = ((-lambda).exp(), 0.0);
        let mut j = 0;
        // P(X >= j) = 1 - P(X < j)
        while j <= others && 1.0 - below >= limit {
            below += term;
            j += 1;
            term *= lambda / j as f64;
        }
        j.max(1)
    };
    if beyond > others {
        n + 1
    } else {
        4 + beyond
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn support_grows_with_chance_and_with_the_points() {
        assert!(minimum_support(100, 0.01, 0.05) >= 6);
        assert!(minimum_support(1000, 0.01, 0.05) > minimum_support(100, 0.01, 0.05));
        assert!(minimum_support(1000, 0.01, 1e-6) > minimum_support(1000, 0.01, 0.05));
        assert_eq!(minimum_support(4, 0.01, 0.05), 4);
        // Chance covering every point: nothing is support.
        assert_eq!(minimum_support(300, 1.0, 0.01), 301);
        // Large means take the Gaussian limit, and stay sensible (0.5% of 200,000 is 1,000).
        let big = minimum_support(200_000, 0.005, 1e-6);
        assert!((1_100..1_300).contains(&big), "{big}");
    }

    #[test]
    fn the_poisson_tail_is_right() {
        // lambda = 2: P(X >= 6) = 0.0166, P(X >= 7) = 0.0045; the sample's 4 come on top.
        assert_eq!(minimum_support(104, 0.02, 0.01), 4 + 7);
        assert_eq!(minimum_support(104, 0.02, 0.02), 4 + 6);
    }
}
