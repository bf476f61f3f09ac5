//! Problem generators and measures shared by the unit tests.

use nalgebra::{Matrix3, Vector3};

use crate::Point;

pub fn project(h: &Matrix3<f64>, p: &Point) -> Point {
    let v = h * Vector3::new(p[0], p[1], 1.0);
    [v[0] / v[2], v[1] / v[2]]
}

fn halton(mut i: usize, base: usize) -> f64 {
    let (mut f, mut r) = (1.0, 0.0);
    while i > 0 {
        f /= base as f64;
        r += f * (i % base) as f64;
        i /= base;
    }
    r
}

/// n exact correspondences: source points spread over [offset, offset + spread]^2, mapped by a
/// fixed, well-conditioned homography with perspective. Returns (src, dst, H).
pub fn sample_problem(
    n: usize,
    spread: f64,
    offset: f64,
) -> (Vec<Point>, Vec<Point>, Matrix3<f64>) {
    let unit_to_src = Matrix3::new(spread, 0.0, offset, 0.0, spread, offset, 0.0, 0.0, 1.0);
    let h0 = Matrix3::new(1.1, 0.25, 0.05, -0.2, 0.9, 0.1, 0.3, -0.2, 1.0);
    let unit_to_dst = Matrix3::new(
        2.0 * spread,
        0.0,
        -0.5 * offset,
        0.0,
        2.0 * spread,
        0.3 * offset,
        0.0,
        0.0,
        1.0,
    );
    // ok: test-only module (cfg(test)); a diagonal frame with spread > 0 is invertible.
    let truth = unit_to_dst * h0 * unit_to_src.try_inverse().unwrap(); // ok: see above
    let mut src = Vec::with_capacity(n);
    let mut dst = Vec::with_capacity(n);
    for i in 1..=n {
        let u = [halton(i, 2), halton(i, 3)];
        src.push(project(&unit_to_src, &u));
        dst.push(project(&unit_to_dst, &project(&h0, &u)));
    }
    (src, dst, truth)
}

/// Adds Gaussian noise of the given sigma (deterministic in `seed`).
pub fn noisy(points: &[Point], sigma: f64, seed: u64) -> Vec<Point> {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut uniform = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    points
        .iter()
        .map(|p| {
            let (u1, u2) = (uniform(), uniform());
            let r = (-2.0 * u1.ln()).sqrt() * sigma;
            let t = std::f64::consts::TAU * u2;
            [p[0] + r * t.cos(), p[1] + r * t.sin()]
        })
        .collect()
}

/// || a/|a| - b/|b| ||_F with the signs aligned.
pub fn relative_h_error(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let (a, b) = (a / a.norm(), b / b.norm());
    let s = if a.dot(&b) < 0.0 { -1.0 } else { 1.0 };
    (a - b * s).norm()
}

/// Sum of squared transfer errors in the destination.
pub fn transfer_cost(h: &Matrix3<f64>, src: &[Point], dst: &[Point]) -> f64 {
    src.iter()
        .zip(dst)
        .map(|(s, d)| {
            let p = project(h, s);
            (p[0] - d[0]).powi(2) + (p[1] - d[1]).powi(2)
        })
        .sum()
}
