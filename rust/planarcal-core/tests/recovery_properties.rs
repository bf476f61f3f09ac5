//! Property tests: random well-conditioned homographies and point sets, noise-free, are
//! recovered by every solver; degenerate sets get the error that names them.

use nalgebra::{Matrix3, Vector3};
use planarcal_core::{estimate_homography, HomographyError, Point, PointSet, Solver};
use proptest::prelude::*;

fn project(h: &Matrix3<f64>, p: &Point) -> Point {
    let v = h * Vector3::new(p[0], p[1], 1.0);
    [v[0] / v[2], v[1] / v[2]]
}

fn relative_h_error(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let (a, b) = (a / a.norm(), b / b.norm());
    let s = if a.dot(&b) < 0.0 { -1.0 } else { 1.0 };
    (a - b * s).norm()
}

/// A homography of the unit square with rotation, anisotropic scale, shear and perspective
/// that keeps w within [0.4, 1.6] over the square.
fn unit_homography() -> impl Strategy<Value = Matrix3<f64>> {
    (
        -3.1..3.1f64,
        0.5..2.0f64,
        0.5..2.0f64,
        -0.3..0.3f64,
        -0.5..0.5f64,
        -0.5..0.5f64,
        -0.3..0.3f64,
        -0.3..0.3f64,
    )
        .prop_map(|(angle, sx, sy, shear, tx, ty, px, py)| {
            let (c, s) = (angle.cos(), angle.sin());
            let a = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
                * Matrix3::new(sx, shear, 0.0, 0.0, sy, 0.0, 0.0, 0.0, 1.0);
            let mut h = a;
            h[(0, 2)] = tx;
            h[(1, 2)] = ty;
            h[(2, 0)] = px;
            h[(2, 1)] = py;
            h
        })
}

fn twice_area(a: &Point, b: &Point, c: &Point) -> f64 {
    ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs()
}

/// Unit-square points in general position: any 4-point set has every triangle well away
/// from flat (larger sets are random, and flat only with negligible probability).
fn unit_points(max: usize) -> impl Strategy<Value = Vec<Point>> {
    prop::collection::vec((0.0..1.0f64, 0.0..1.0f64).prop_map(|(x, y)| [x, y]), 4..max).prop_filter(
        "points in general position",
        |pts| {
            let k = pts.len().min(6);
            let mut ok = true;
            for i in 0..k {
                for j in i + 1..k {
                    for l in j + 1..k {
                        ok &= twice_area(&pts[i], &pts[j], &pts[l]) > 0.02;
                    }
                }
            }
            ok
        },
    )
}

/// Maps the unit square to [offset, offset + spread]^2.
fn frame(spread: f64, offset: f64) -> Matrix3<f64> {
    Matrix3::new(spread, 0.0, offset, 0.0, spread, offset, 0.0, 0.0, 1.0)
}

/// (src, dst, H): src in one frame, dst in another, H exact.
fn problem(
    u: &[Point],
    h0: &Matrix3<f64>,
    src_frame: Matrix3<f64>,
    dst_frame: Matrix3<f64>,
) -> (Vec<Point>, Vec<Point>, Matrix3<f64>) {
    let src: Vec<Point> = u.iter().map(|p| project(&src_frame, p)).collect();
    let dst: Vec<Point> = u
        .iter()
        .map(|p| project(&dst_frame, &project(h0, p)))
        .collect();
    let truth = dst_frame * h0 * src_frame.try_inverse().expect("frames are invertible");
    (src, dst, truth)
}

proptest! {
    // 256 cases each by default; PROPTEST_CASES=5000 for a deeper run.
    #![proptest_config(ProptestConfig::default())]

    /// Every solver, with and without refinement, where the raw coordinates are well
    /// conditioned: spreads up to 100, offsets up to the spread. (The plain SVD DLT works on
    /// raw coordinates; at pixel scales with offsets its rounding reaches 1e-8, the reason
    /// the normalised DLT exists. The next property covers the other solvers there.)
    #[test]
    fn every_solver_recovers_exact_homographies(
        u in unit_points(200),
        h0 in unit_homography(),
        spread in 0.5..100.0f64,
        offset in 0.0..1.0f64,
        dst_spread in 0.5..100.0f64,
    ) {
        let (src, dst, truth) = problem(
            &u, &h0, frame(spread, offset * spread), frame(dst_spread, -0.5 * offset * dst_spread));
        for solver in Solver::ALL {
            for refine in [false, true] {
                let h = estimate_homography(&src, &dst, solver, refine)
                    .map_err(|e| TestCaseError::fail(format!("{solver} refine={refine}: {e}")))?;
                let err = relative_h_error(&h, &truth);
                prop_assert!(err < 1e-9, "{} refine={}: relative error {:e}", solver, refine, err);
            }
        }
    }

    /// The paper's a33 solver and refinement from every solver, at pixel scales with offsets.
    #[test]
    fn a33_and_refinement_recover_exact_homographies_at_pixel_scales(
        u in unit_points(200),
        h0 in unit_homography(),
        spread in 1.0..5000.0f64,
        offset in 0.0..2.0f64,
        dst_spread in 1.0..5000.0f64,
    ) {
        let (src, dst, truth) = problem(
            &u, &h0, frame(spread, offset * spread), frame(dst_spread, -0.5 * offset * dst_spread));
        let mut fits = vec![(Solver::A33, false)];
        fits.extend(Solver::ALL.iter().map(|&s| (s, true)));
        for (solver, refine) in fits {
            let h = estimate_homography(&src, &dst, solver, refine)
                .map_err(|e| TestCaseError::fail(format!("{solver} refine={refine}: {e}")))?;
            let err = relative_h_error(&h, &truth);
            prop_assert!(err < 1e-9, "{} refine={}: relative error {:e}", solver, refine, err);
        }
    }

    /// The normalised solver across units and offsets: spreads 1e-3 .. 1e5, offsets up to
    /// 100 times the spread.
    #[test]
    fn normalized_dlt_is_invariant_to_units_and_offsets(
        u in unit_points(300),
        h0 in unit_homography(),
        log_spread in -3.0..5.0f64,
        offset_ratio in -100.0..100.0f64,
        log_dst_spread in -3.0..5.0f64,
        dst_offset_ratio in -100.0..100.0f64,
    ) {
        let (s, d) = (10f64.powf(log_spread), 10f64.powf(log_dst_spread));
        let (src, dst, truth) =
            problem(&u, &h0, frame(s, offset_ratio * s), frame(d, dst_offset_ratio * d));
        for refine in [false, true] {
            let h = estimate_homography(&src, &dst, Solver::NormalizedDlt, refine)
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            let err = relative_h_error(&h, &truth);
            prop_assert!(err < 1e-9, "refine={}: relative error {:e}", refine, err);
            // And the fit reprojects to rounding level, relative to the destination spread.
            for (p, q) in src.iter().zip(&dst) {
                let r = project(&h, p);
                prop_assert!((r[0] - q[0]).abs().max((r[1] - q[1]).abs()) < 1e-9 * d * (1.0 + dst_offset_ratio.abs()));
            }
        }
    }

    /// All points on one line, in either set: Collinear (or TooFewDistinct), never an H.
    #[test]
    fn collinear_sets_are_refused(
        ts in prop::collection::vec(-100.0..100.0f64, 4..60),
        angle in 0.0..3.1f64,
        origin in (-1e4..1e4f64, -1e4..1e4f64),
        in_destination in any::<bool>(),
    ) {
        let line: Vec<Point> = ts.iter()
            .map(|t| [origin.0 + t * angle.cos(), origin.1 + t * angle.sin()])
            .collect();
        let other: Vec<Point> = (0..line.len())
            .map(|i| [(i as f64 * 1.7).sin() * 50.0, (i as f64 * 2.3).cos() * 50.0])
            .collect();
        let (src, dst, set) = if in_destination {
            (&other, &line, PointSet::Destination)
        } else {
            (&line, &other, PointSet::Source)
        };
        for solver in Solver::ALL {
            match estimate_homography(src, dst, solver, false) {
                Err(HomographyError::Collinear { set: s, .. })
                | Err(HomographyError::TooFewDistinct { set: s, .. }) => prop_assert_eq!(s, set),
                other => prop_assert!(false, "{}: expected Collinear, got {:?}", solver, other),
            }
        }
    }

    /// All but one point on a line: AllButOneCollinear naming that point.
    #[test]
    fn all_but_one_collinear_names_the_point(
        ts in prop::collection::hash_set(-1000i32..1000, 3..40),
        off in (-500.0..500.0f64, 5.0..500.0f64),
        at in any::<prop::sample::Index>(),
    ) {
        let mut src: Vec<Point> = ts.iter().map(|&t| [t as f64 * 0.1, 2.0 + t as f64 * 0.05]).collect();
        let k = at.index(src.len() + 1);
        // Off the line y = 2 + x / 2 by a clear margin.
        src.insert(k, [off.0, 2.0 + off.0 * 0.5 + off.1]);
        let dst: Vec<Point> = (0..src.len())
            .map(|i| [(i as f64 * 1.3).sin() * 50.0, (i as f64 * 0.7).cos() * 50.0])
            .collect();
        match estimate_homography(&src, &dst, Solver::NormalizedDlt, false) {
            Err(HomographyError::AllButOneCollinear { set: PointSet::Source, outlier, .. }) => {
                prop_assert_eq!(outlier, k)
            }
            other => prop_assert!(false, "expected AllButOneCollinear, got {:?}", other),
        }
    }

    /// Duplicates that leave fewer than 4 distinct points: TooFewDistinct.
    #[test]
    fn duplicates_leaving_three_points_are_refused(copies in prop::collection::vec(0usize..3, 4..30)) {
        let base = [[0.0, 0.0], [10.0, 0.0], [3.0, 7.0]];
        let src: Vec<Point> = copies.iter().map(|&i| base[i]).collect();
        let dst: Vec<Point> = (0..src.len()).map(|i| [i as f64, (i * i) as f64]).collect();
        for solver in Solver::ALL {
            match estimate_homography(&src, &dst, solver, true) {
                Err(HomographyError::TooFewDistinct { set: PointSet::Source, distinct }) => {
                    prop_assert!(distinct <= 3)
                }
                other => prop_assert!(false, "expected TooFewDistinct, got {:?}", other),
            }
        }
    }

    /// Fewer than 4 points, and NaN or infinity anywhere: typed errors, no panic.
    #[test]
    fn malformed_input_is_refused(n in 0usize..4, bad_at in 0usize..10, bad in prop::sample::select(vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY])) {
        let pts: Vec<Point> = (0..n).map(|i| [i as f64, (i * i) as f64]).collect();
        prop_assert_eq!(
            estimate_homography(&pts, &pts, Solver::NormalizedDlt, false),
            Err(HomographyError::TooFewPoints { got: n })
        );
        let mut src: Vec<Point> = (0..10).map(|i| [i as f64, (i * i % 7) as f64]).collect();
        src[bad_at][bad_at % 2] = bad;
        let dst = src.clone();
        for solver in Solver::ALL {
            let err = estimate_homography(&src, &dst, solver, false).err();
            let named = matches!(
                err,
                Some(HomographyError::NonFinitePoint { set: PointSet::Source, index, .. }) if index == bad_at
            );
            prop_assert!(named, "{}: {:?}", solver, err);
        }
    }
}
