//! Hostile inputs for every numeric entry point of the core: any f64 (subnormals, -0.0, +-inf,
//! NaN, magnitudes from 1e-300 to 1e300), 0 to 12 points, duplicates, exactly collinear sets,
//! arbitrary matrices and robust options. Each call must return without panicking, and what
//! it returns must be usable: finite homographies scaled as documented, finite transformed
//! points, errors that are finite or +inf where the report says a point had no image. Exactly
//! collinear or too-few-distinct sets must never be given an H.
//!
//! 256 cases a property by default (so `cargo test` stays fast); at scale:
//! `PROPTEST_CASES=100000 cargo test --release -p planarcal-core --test hostile_inputs`
//! (benches/bench_fuzz.py --rust runs it).

use nalgebra::Matrix3;
use planarcal_core::{
    estimate, estimate_robust, estimate_robust_batch, invert, reprojection_errors_into, ErrorStats,
    Homography, Method, Orientation, Point, RobustOptions, Solver,
};
use proptest::prelude::*;

/// One coordinate: every class of f64 with weight, not only the ordinary ones.
fn hostile_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => 0.0..2000.0f64,
        2 => any::<f64>(),
        2 => (-300i32..=300, any::<bool>(), 1.0..10.0f64)
            .prop_map(|(e, neg, m)| { let v = m * 10f64.powi(e); if neg { -v } else { v } }),
        1 => (1u64..1000, any::<bool>())
            .prop_map(|(k, neg)| { let v = f64::from_bits(k); if neg { -v } else { v } }),
        1 => prop::sample::select(vec![
            0.0, -0.0, f64::INFINITY, f64::NEG_INFINITY, f64::NAN, f64::MAX, f64::MIN,
            f64::MIN_POSITIVE, f64::EPSILON, 1e300, -1e300, 1e-300,
        ]),
    ]
}

fn hostile_point() -> impl Strategy<Value = Point> {
    (hostile_f64(), hostile_f64()).prop_map(|(x, y)| [x, y])
}

/// 0 to 12 points, some repeated (duplicates are where degeneracy hides).
fn hostile_points() -> impl Strategy<Value = Vec<Point>> {
    (
        prop::collection::vec(hostile_point(), 0..12),
        prop::collection::vec(any::<prop::sample::Index>(), 0..4),
    )
        .prop_map(|(mut pts, repeats)| {
            if !pts.is_empty() {
                for r in repeats {
                    let p = pts[r.index(pts.len())];
                    pts.push(p);
                }
            }
            pts
        })
}

/// A source and a destination set of the same length (the usual case), or of any lengths.
fn hostile_pair() -> impl Strategy<Value = (Vec<Point>, Vec<Point>)> {
    prop_oneof![
        4 => hostile_points().prop_flat_map(|src| {
            let n = src.len();
            (Just(src), prop::collection::vec(hostile_point(), n))
        }),
        1 => (hostile_points(), hostile_points()),
    ]
}

/// Points on one line with small integer coordinates (exact in f64, so the set is exactly
/// collinear), optionally with one point off it, or fewer than 4 distinct points: no
/// homography exists for any of them.
fn degenerate_pair() -> impl Strategy<Value = (Vec<Point>, Vec<Point>)> {
    let line = (
        -20i32..20,
        -20i32..20,
        -50i32..50,
        prop::collection::vec(-100i32..100, 4..12),
    );
    let collinear = (line.clone(), any::<bool>()).prop_map(|((a, b, c, ts), src_side)| {
        // a*t, b*t + c: on one line whatever t is.
        let on_line: Vec<Point> = ts
            .iter()
            .map(|&t| [f64::from(a * t), f64::from(b * t + c)])
            .collect();
        let spread: Vec<Point> = ts
            .iter()
            .enumerate()
            .map(|(i, &t)| [f64::from(t), (i * i) as f64])
            .collect();
        if src_side {
            (on_line, spread)
        } else {
            (spread, on_line)
        }
    });
    let few = (
        prop::collection::vec((0.0..2000.0f64, 0.0..2000.0f64), 1..4),
        4usize..10,
    )
        .prop_map(|(distinct, n)| {
            let src: Vec<Point> = (0..n)
                .map(|i| {
                    let p = distinct[i % distinct.len()];
                    [p.0, p.1]
                })
                .collect();
            let dst: Vec<Point> = (0..n).map(|i| [i as f64, (i * i) as f64]).collect();
            (src, dst)
        });
    prop_oneof![collinear, few]
}

fn hostile_matrix() -> impl Strategy<Value = Matrix3<f64>> {
    prop_oneof![
        3 => prop::array::uniform9(hostile_f64()),
        1 => prop::array::uniform9(-2.0..2.0f64),
    ]
    .prop_map(|m| Matrix3::from_row_slice(&m))
}

fn hostile_options() -> impl Strategy<Value = RobustOptions> {
    (
        hostile_f64(),
        prop_oneof![Just(0.0), Just(1.0), Just(0.5), Just(f64::NAN), Just(1.0 - 1e-16), 0.0..1.0f64, hostile_f64()],
        // Small budgets keep the cases fast; the range checks see 0 and beyond the cap.
        prop_oneof![8 => 1usize..64, 1 => Just(0usize), 1 => Just(10_000_001usize), 1 => Just(usize::MAX)],
        any::<u64>(),
        any::<bool>(),
    )
        .prop_map(|(threshold, confidence, max_iters, seed, lmeds)| RobustOptions {
            threshold,
            confidence,
            max_iters,
            seed,
            scores: None,
            method: if lmeds { Method::Lmeds } else { Method::Msac },
            parallel: false,
        })
}

/// A returned H is finite and scaled as documented: |h33| = 1, or unit norm when h33 is
/// negligible.
fn assert_usable_h(h: &Matrix3<f64>, what: &str) {
    assert!(
        h.iter().all(|v| v.is_finite()),
        "{what}: non-finite H {:?}",
        h.transpose().as_slice()
    );
    let unit_h33 = h[(2, 2)].abs() == 1.0;
    let unit_norm = (h.norm() - 1.0).abs() < 1e-9;
    assert!(
        unit_h33 || unit_norm,
        "{what}: H scaled neither |h33| = 1 nor unit norm: {:?}",
        h.transpose().as_slice()
    );
}

proptest! {
    // ProptestConfig::default() reads PROPTEST_CASES (256 when unset).
    #![proptest_config(ProptestConfig::default())]

    #[test]
    fn estimate_never_panics_and_returns_usable_h((src, dst) in hostile_pair(), refine: bool) {
        for solver in Solver::ALL {
            if let Ok(e) = estimate(&src, &dst, solver, refine) {
                assert_usable_h(&e.h, solver.name());
            }
        }
    }

    #[test]
    fn degenerate_sets_are_never_given_an_h((src, dst) in degenerate_pair(), refine: bool) {
        for solver in Solver::ALL {
            let got = estimate(&src, &dst, solver, refine);
            prop_assert!(got.is_err(), "{}: H for a degenerate set: {:?}", solver.name(), got);
        }
        let got = estimate_robust(&src, &dst, &RobustOptions { max_iters: 200, ..Default::default() });
        prop_assert!(got.as_ref().map_or(true, |r| r.h.is_none()), "robust: H for a degenerate set: {:?}", got);
    }

    #[test]
    fn robust_never_panics((src, dst) in hostile_pair(), options in hostile_options()) {
        if let Ok(r) = estimate_robust(&src, &dst, &options) {
            if let Some(h) = &r.h {
                assert_usable_h(h, "estimate_robust");
            }
            prop_assert_eq!(r.inliers.len(), src.len());
            prop_assert_eq!(r.n_inliers, r.inliers.iter().filter(|&&b| b).count());
        }
    }

    #[test]
    fn robust_batch_never_panics(
        problems in prop::collection::vec(hostile_pair(), 0..4),
        options in hostile_options(),
    ) {
        let views: Vec<(&[Point], &[Point])> =
            problems.iter().map(|(s, d)| (s.as_slice(), d.as_slice())).collect();
        let results = estimate_robust_batch(&views, &RobustOptions { parallel: true, ..options });
        prop_assert_eq!(results.len(), problems.len());
        for r in results.iter().flatten() {
            if let Some(h) = &r.h {
                assert_usable_h(h, "estimate_robust_batch");
            }
        }
    }

    #[test]
    fn transforms_give_finite_points_or_errors(h in hostile_matrix(), points in hostile_points()) {
        if let Ok(t) = Homography::from_matrix(&h) {
            for orientation in [Orientation::Oriented, Orientation::Unoriented] {
                for p in &points {
                    if let Ok(q) = t.apply(p, orientation) {
                        prop_assert!(q.iter().all(|v| v.is_finite()), "{:?} -> {:?}", p, q);
                    }
                }
            }
        }
    }

    // Finding F1: `invert` gave an infinite inverse for a matrix with subnormal entries.
    #[test]
    fn inverses_are_finite_or_errors(h in hostile_matrix()) {
        if let Ok(inverse) = invert(&h) {
            prop_assert!(
                inverse.iter().all(|v| v.is_finite()),
                "inverse of {:?} is {:?}", h.transpose().as_slice(), inverse.transpose().as_slice()
            );
        }
    }

    #[test]
    fn reprojection_errors_are_finite_or_reported(
        h in hostile_matrix(),
        (src, dst) in hostile_pair(),
        oriented: bool,
    ) {
        let orientation = if oriented { Orientation::Oriented } else { Orientation::Unoriented };
        let mut out = vec![0.0; src.len()];
        if let Ok(report) = reprojection_errors_into(&h, &src, &dst, &mut out, orientation) {
            let failed = report.non_finite + report.at_infinity + report.behind_horizon;
            let infinite = out.iter().filter(|e| e.is_infinite()).count();
            prop_assert!(out.iter().all(|e| !e.is_nan() && *e >= 0.0), "{:?}", out);
            // An infinite error is a point without an image, or one beyond f64's range.
            prop_assert!(infinite >= failed, "{} reported, {} infinite", failed, infinite);
            if let Some(s) = ErrorStats::of(&out) {
                prop_assert!(!s.max.is_nan() && !s.min.is_nan());
            }
        }
    }
}

/// Finding F7: a destination collinear but for one point to 9.4e-12 of its RMS radius (under
/// the core's own tolerance) was given an H by every solver.
#[test]
fn all_but_one_collinear_within_the_tolerance_is_refused() {
    let src: Vec<Point> = vec![
        [2094.0, 1289.0],
        [2281.0, 1241.0],
        [1533.0, 1434.0],
        [2576.0, 1165.0],
        [1426.0, 1462.0],
    ];
    let dst: Vec<Point> = vec![
        [2184.0539268932484, -253.79535873920528],
        [2397.688518778658, -446.58145687066315],
        [1556.1673684513582, 312.8160621783439],
        [2739.536652726099, -755.0688011498846],
        [1438.2384331856933, 419.2363714080013],
    ];
    for solver in Solver::ALL {
        for refine in [false, true] {
            let got = estimate(&src, &dst, solver, refine);
            assert!(
                got.is_err(),
                "{} (refine {refine}): {:?}",
                solver.name(),
                got
            );
        }
    }
}
