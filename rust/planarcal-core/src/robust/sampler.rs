//! Deterministic sampling: a PCG32 generator (O'Neill 2014; small, fast, and the same stream
//! on every platform), uniform minimal samples, and PROSAC's progressive samples (Chum & Matas
//! 2005) that draw first from the correspondences ranked best.

/// PCG32 (XSH RR 64/32).
#[derive(Debug, Clone)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

impl Pcg32 {
    const MULT: u64 = 6364136223846793005;

    /// A generator for `seed` on stream `stream` (distinct streams never overlap).
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut g = Pcg32 {
            state: 0,
            inc: (stream << 1) | 1,
        };
        g.next_u32();
        g.state = g.state.wrapping_add(seed);
        g.next_u32();
        g
    }

    /// The next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in 0..bound (bound >= 1), without modulo bias (Lemire's method).
    #[inline]
    pub fn below(&mut self, bound: u32) -> u32 {
        let mut m = u64::from(self.next_u32()) * u64::from(bound);
        let mut low = m as u32;
        if low < bound {
            let threshold = bound.wrapping_neg() % bound;
            while low < threshold {
                m = u64::from(self.next_u32()) * u64::from(bound);
                low = m as u32;
            }
        }
        (m >> 32) as u32
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn unit(&mut self) -> f64 {
        f64::from(self.next_u32()) * (1.0 / 4294967296.0)
    }

    /// A Fisher-Yates shuffle of `0..n`.
    pub fn permutation(&mut self, n: usize) -> crate::Result<Vec<u32>> {
        let mut p = crate::alloc::collect(0..n as u32)?;
        for i in (1..n).rev() {
            let j = self.below(i as u32 + 1) as usize;
            p.swap(i, j);
        }
        Ok(p)
    }
}

/// `k` distinct indices uniformly from 0..n (n >= k), into `out`.
#[inline]
pub fn distinct_sample<const K: usize>(rng: &mut Pcg32, n: u32, out: &mut [u32; K]) {
    for i in 0..K {
        loop {
            let v = rng.below(n);
            if !out[..i].contains(&v) {
                out[i] = v;
                break;
            }
        }
    }
}

/// PROSAC: samples drawn from the top-n ranked correspondences, n growing on the schedule of
/// Chum & Matas, so that after `t_n_prime` samples the draw is uniform over all N.
#[derive(Debug, Clone)]
pub struct Prosac {
    n_total: u32,
    /// Current subset size and the sample count at which it grows.
    n: u32,
    t_n: f64,
    t_n_prime: u64,
    samples: u64,
    /// Samples after which PROSAC is plain uniform sampling.
    growth_max: u64,
}

impl Prosac {
    pub const M: u32 = 4;

    pub fn new(n_total: u32, growth_max: u64) -> Self {
        // T_N: expected samples with m points from N among `growth_max` draws; T_n for n = m.
        let m = f64::from(Self::M);
        let mut t_n = growth_max as f64;
        for i in 0..Self::M {
            t_n *= (m - f64::from(i)) / (f64::from(n_total) - f64::from(i));
        }
        Prosac {
            n_total,
            n: Self::M,
            t_n,
            t_n_prime: 1,
            samples: 0,
            growth_max,
        }
    }

    /// Draws uniformly from the `size` best for the next `hold` samples, then grows on from
    /// there on PROSAC's schedule.
    pub fn focus(&mut self, size: u32, hold: u64) {
        let size = size.clamp(Self::M, self.n_total);
        // T_n = T_N C(n, m) / C(N, m), as the schedule would have it at n.
        let mut t_n = self.growth_max as f64;
        for i in 0..Self::M {
            t_n *= (f64::from(size) - f64::from(i)) / (f64::from(self.n_total) - f64::from(i));
        }
        self.n = size;
        self.t_n = t_n;
        self.t_n_prime = self.samples.saturating_add(hold).saturating_add(1);
    }

    /// How many of the best-ranked correspondences samples are drawn from now.
    #[cfg(test)]
    pub fn subset(&self) -> u32 {
        if self.samples >= self.growth_max {
            self.n_total
        } else {
            self.n
        }
    }

    /// The next sample: indices into the ranking (0 = best).
    pub fn sample(&mut self, rng: &mut Pcg32, out: &mut [u32; 4]) {
        self.samples += 1;
        if self.samples >= self.growth_max || self.n >= self.n_total {
            distinct_sample(rng, self.n_total, out);
            return;
        }
        if self.samples >= self.t_n_prime && self.n < self.n_total {
            // Grow the subset: T_{n+1} = T_n (n + 1) / (n + 1 - m); this sample is the
            // newest point n-1 and m-1 others from the first n-1.
            let next = self.t_n * f64::from(self.n + 1) / f64::from(self.n + 1 - Self::M);
            self.t_n_prime += (next - self.t_n).ceil().max(1.0) as u64;
            self.t_n = next;
            self.n += 1;
            let mut rest = [0u32; 3];
            distinct_sample(rng, self.n - 1, &mut rest);
            out[0] = self.n - 1;
            out[1..].copy_from_slice(&rest);
        } else {
            // Between growth steps: uniform over the subset.
            distinct_sample(rng, self.n, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pcg32_matches_the_reference_stream() {
        // pcg32_random_r with initstate 42, initseq 54 (the reference demo's first outputs).
        let mut g = Pcg32::new(42, 54);
        let first: Vec<u32> = (0..6).map(|_| g.next_u32()).collect();
        assert_eq!(
            first,
            [0xa15c02b7, 0x7b47f409, 0xba1d3330, 0x83d2f293, 0xbfa4784b, 0xcbed606e]
        );
    }

    #[test]
    fn below_is_uniform_and_in_range() {
        let mut g = Pcg32::new(1, 1);
        let mut counts = [0u32; 7];
        for _ in 0..70_000 {
            counts[g.below(7) as usize] += 1;
        }
        assert!(
            counts.iter().all(|&c| (9_500..10_500).contains(&c)),
            "{counts:?}"
        );
    }

    #[test]
    fn samples_are_distinct_and_permutations_complete() {
        let mut g = Pcg32::new(3, 0);
        let mut s = [0u32; 4];
        for _ in 0..1000 {
            distinct_sample(&mut g, 5, &mut s);
            let mut t = s;
            t.sort_unstable();
            assert!(t.windows(2).all(|w| w[0] != w[1]) && t[3] < 5);
        }
        let mut p = g.permutation(100).unwrap();
        p.sort_unstable();
        assert_eq!(p, (0..100).collect::<Vec<u32>>());
    }

    #[test]
    fn prosac_starts_with_the_best_and_becomes_uniform() {
        let mut g = Pcg32::new(5, 0);
        let mut p = Prosac::new(1000, 20_000);
        let mut s = [0u32; 4];
        // The paper's first step grows the set to m + 1 = 5 and draws the newest with three.
        p.sample(&mut g, &mut s);
        assert!(s.iter().all(|&i| i < 5) && s.contains(&4), "{s:?}");
        // T'_n grows by ceil(T_{n+1} - T_n) >= 1: at first, one more point per sample.
        let mut early_max = 0;
        for _ in 0..50 {
            p.sample(&mut g, &mut s);
            early_max = early_max.max(*s.iter().max().unwrap_or(&0));
        }
        assert!(
            early_max < 56,
            "early samples stay among the best ({early_max})"
        );
        for _ in 0..30_000 {
            p.sample(&mut g, &mut s);
        }
        let mut seen_high = false;
        for _ in 0..100 {
            p.sample(&mut g, &mut s);
            seen_high |= s.iter().any(|&i| i > 900);
        }
        assert!(seen_high, "late samples reach the whole set");
    }
}
