//! A profiling harness for the robust estimator, free of Python: seeded synthetic problems
//! (a 1280 x 720 image, pixel noise sigma 0.5, uniform outliers), timed one by one.
//!
//!     cargo run --release --example robust_profile -- [N] [OUTLIER_FRACTION] [PROBLEMS]
//!
//! Prints the median and 90th percentile time, the median number of samples and how many
//! fits missed the truth by more than 1 px anywhere on the inliers. With SKIP set it only
//! builds the problems, so that `valgrind --tool=callgrind` counts of the two runs subtract
//! to the estimator's own instructions (repeatable on a noisy machine).

use std::time::Instant;

use planarcal_core::Pcg32;
use planarcal_core::{estimate_robust, Point, RobustOptions};

const TRUTH: [f64; 9] = [1.05, -0.1, 20.0, 0.08, 0.95, -30.0, 1e-4, -5e-5, 1.0];

fn project(h: &[f64; 9], p: &Point) -> Point {
    let w = h[6] * p[0] + h[7] * p[1] + h[8];
    [
        (h[0] * p[0] + h[1] * p[1] + h[2]) / w,
        (h[3] * p[0] + h[4] * p[1] + h[5]) / w,
    ]
}

fn gaussian(rng: &mut Pcg32, sigma: f64) -> f64 {
    let (a, b) = (rng.unit().max(1e-12), rng.unit());
    sigma * (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
}

/// (src, dst, number of outliers): the outliers come first.
fn problem(n: usize, outlier_fraction: f64, seed: u64) -> (Vec<Point>, Vec<Point>, usize) {
    let mut rng = Pcg32::new(seed, 7);
    let outliers = (outlier_fraction * n as f64).ceil() as usize;
    let (mut src, mut dst) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let p = [rng.unit() * 1280.0, rng.unit() * 720.0];
        let q = project(&TRUTH, &p);
        src.push(p);
        dst.push(if i < outliers {
            [rng.unit() * 1280.0, rng.unit() * 720.0]
        } else {
            [
                q[0] + gaussian(&mut rng, 0.5),
                q[1] + gaussian(&mut rng, 0.5),
            ]
        });
    }
    (src, dst, outliers)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, default: f64| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(default);
    let (n, fraction, count) = (
        arg(1, 1000.0) as usize,
        arg(2, 0.5),
        arg(3, 1000.0) as usize,
    );
    let skip = std::env::var_os("SKIP").is_some();
    let (mut times, mut samples, mut misses) = (Vec::new(), Vec::new(), 0);
    for seed in 0..count as u64 {
        let (src, dst, outliers) = problem(n, fraction, seed);
        if skip {
            continue;
        }
        let options = RobustOptions {
            seed,
            ..Default::default()
        };
        let start = Instant::now();
        let Ok(result) = estimate_robust(&src, &dst, &options) else {
            misses += 1;
            continue;
        };
        times.push(start.elapsed().as_secs_f64() * 1e6);
        samples.push(result.iterations);
        let hit = result.h.is_some_and(|h| {
            let h: [f64; 9] = std::array::from_fn(|k| h[(k / 3, k % 3)]);
            src[outliers..].iter().all(|p| {
                let (a, b) = (project(&h, p), project(&TRUTH, p));
                (a[0] - b[0]).hypot(a[1] - b[1]) < 1.0
            })
        });
        misses += usize::from(!hit);
    }
    if times.is_empty() {
        return;
    }
    times.sort_by(f64::total_cmp);
    samples.sort_unstable();
    let at = |q: f64| times[((times.len() - 1) as f64 * q) as usize];
    println!(
        "n={n} outliers={fraction}: median {:.1} us, p90 {:.1} us, samples (median) {}, \
         missed {misses} of {count}",
        at(0.5),
        at(0.9),
        samples[samples.len() / 2]
    );
}
