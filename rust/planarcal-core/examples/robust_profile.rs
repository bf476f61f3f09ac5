//! Profiling aid: runs the robust estimator on a synthetic problem many times.
//! cargo run --release --example robust_profile -- N OUTLIER_FRACTION REPEATS
use planarcal_core::robust::Pcg32;
use planarcal_core::{estimate_robust, RobustOptions};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let out: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0.5);
    let reps: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let mut times = Vec::new();
    let mut iters = Vec::new();
    let mut failures = 0;
    let mut lo = 0;
    for rep in 0..reps {
        let mut rng = Pcg32::new(rep as u64, 7);
        let h = [1.05, -0.1, 20.0, 0.08, 0.95, -30.0, 1e-4, -5e-5, 1.0];
        let mut src = Vec::new();
        let mut dst = Vec::new();
        for i in 0..n {
            let (x, y) = (rng.unit() * 1280.0, rng.unit() * 720.0);
            src.push([x, y]);
            let w = h[6] * x + h[7] * y + h[8];
            let (u, v) = ((h[0] * x + h[1] * y + h[2]) / w, (h[3] * x + h[4] * y + h[5]) / w);
            let g = |r: &mut Pcg32| {
                let (a, b) = (r.unit().max(1e-12), r.unit());
                0.5 * (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
            };
            if (i as f64) < out * n as f64 {
                dst.push([rng.unit() * 1280.0, rng.unit() * 720.0]);
            } else {
                dst.push([u + g(&mut rng), v + g(&mut rng)]);
            }
        }
        let o = RobustOptions { seed: rep as u64, ..Default::default() };
        let t = Instant::now();
        let r = estimate_robust(&src, &dst, &o).unwrap();
        times.push(t.elapsed().as_secs_f64() * 1e6);
        iters.push(r.iterations);
        lo += r.lo_runs;
        let ok = r.h.is_some_and(|e| {
            let k0 = (out * n as f64).ceil() as usize;
            let mut worst = 0.0f64;
            for p in &src[k0.min(n)..] {
                let f = |m: &[f64; 9]| {
                    let w = m[6] * p[0] + m[7] * p[1] + m[8];
                    [(m[0] * p[0] + m[1] * p[1] + m[2]) / w, (m[3] * p[0] + m[4] * p[1] + m[5]) / w]
                };
                let (a, b) = (f(&h), f(&[e[(0,0)], e[(0,1)], e[(0,2)], e[(1,0)], e[(1,1)], e[(1,2)], e[(2,0)], e[(2,1)], e[(2,2)]]));
                worst = worst.max(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt());
            }
            worst < 1.0
        });
        if !ok { failures += 1; }
    }
    times.sort_by(f64::total_cmp);
    println!("per run: full msac {} rejected-tested {} lo {}", planarcal_core::robust::DBG_MSAC.load(std::sync::atomic::Ordering::Relaxed) / reps, planarcal_core::robust::DBG_TESTED.load(std::sync::atomic::Ordering::Relaxed) / reps, lo as f64 / reps as f64);
    iters.sort();
    println!(
        "n={n} outliers={out}: median {:.1} us, p90 {:.1} us, iterations median {}, failures {failures}",
        times[reps / 2],
        times[reps * 9 / 10],
        iters[reps / 2]
    );
}
