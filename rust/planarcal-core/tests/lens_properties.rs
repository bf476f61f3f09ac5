//! Properties of the lens model and the joint fit, on random cameras, boards and lenses:
//! undistortion inverts distortion wherever the model is valid; exact data is fitted exactly
//! by the model that generated it; every fit's mapping inverts its projection; the
//! leave-one-out prediction of exact data is exact. (Smaller boards where a property refits
//! many times: the suite runs unoptimised in CI.)

use nalgebra::Matrix3;
use planarcal_core::Point;
use planarcal_core::{fit_plane, leave_one_out, InversePlane, LensParams, PlaneModel, RadialLens};
use proptest::prelude::*;

const SIZE: [f64; 2] = [1280.0, 720.0];

/// A board of rows x cols points seen by a camera: similarity + mild perspective, filling a
/// good part of the image around (cx, cy).
fn board_view(
    angle: f64,
    scale: f64,
    centre: Point,
    persp: [f64; 2],
    (cols, rows): (usize, usize),
) -> (Vec<Point>, Matrix3<f64>) {
    let (c, s) = (angle.cos() * scale, angle.sin() * scale);
    // The board spans 260 x 180 mm whatever its number of dots.
    let pitch = [260.0 / (cols - 1) as f64, 180.0 / (rows - 1) as f64];
    let half = [130.0, 90.0];
    let t = Matrix3::new(1.0, 0.0, -half[0], 0.0, 1.0, -half[1], 0.0, 0.0, 1.0);
    let p = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, persp[0], persp[1], 1.0);
    let h = Matrix3::new(c, -s, centre[0], s, c, centre[1], 0.0, 0.0, 1.0) * p * t;
    let mut world = Vec::new();
    for r in 0..rows {
        for k in 0..cols {
            world.push([k as f64 * pitch[0], r as f64 * pitch[1]]);
        }
    }
    (world, h)
}

fn lens_strategy() -> impl Strategy<Value = RadialLens> {
    (
        -0.15f64..0.1,
        -0.05f64..0.05,
        -40.0f64..40.0,
        -30.0f64..30.0,
    )
        .prop_map(|(k1, k2, dx, dy)| {
            let mut l = RadialLens::identity(SIZE[0], SIZE[1]).unwrap();
            l.k1 = k1;
            l.k2 = k2;
            l.centre = [l.centre[0] + dx, l.centre[1] + dy];
            l
        })
}

fn view_strategy(dots: (usize, usize)) -> impl Strategy<Value = (Vec<Point>, Matrix3<f64>)> {
    (
        -3.2f64..3.2,
        1.8f64..3.2,
        560.0f64..720.0,
        300.0f64..420.0,
        -4e-4f64..4e-4,
        -4e-4f64..4e-4,
    )
        .prop_map(move |(a, s, x, y, gx, gy)| board_view(a, s, [x, y], [gx, gy], dots))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    #[test]
    fn undistort_inverts_distort_over_the_image(lens in lens_strategy()) {
        prop_assume!(lens.check_invertible(lens.reach(SIZE[0], SIZE[1])).is_ok());
        for i in 0..=32 {
            for j in 0..=18 {
                let d = [i as f64 * 40.0 - 0.5, j as f64 * 40.0 - 0.5];
                let u = lens.undistort(d).expect("inside the valid radius");
                let back = lens.distort(u);
                prop_assert!((back[0] - d[0]).abs() < 1e-8 && (back[1] - d[1]).abs() < 1e-8);
            }
        }
    }

    #[test]
    fn exact_data_is_fitted_exactly_by_its_own_model(
        lens in lens_strategy(),
        (world, h) in view_strategy((14, 10)),
    ) {
        let truth = PlaneModel { h, lens };
        let image: Vec<Point> = world.iter().map(|w| truth.world_to_image(*w).unwrap()).collect();
        prop_assume!(image.iter().all(|p| p[0] > 0.0 && p[0] < SIZE[0] && p[1] > 0.0 && p[1] < SIZE[1]));
        prop_assume!(lens.check_invertible(lens.reach(SIZE[0], SIZE[1])).is_ok());
        let fit = fit_plane(&world, &image, LensParams::K1K2Centre, SIZE).unwrap();
        prop_assert!(fit.sigma() < 1e-6, "sigma {}", fit.sigma());
        // Mapping inverts projection, inside and beyond the board.
        let inverse = InversePlane::new(&fit.model).unwrap();
        for w in [[0.0, 0.0], [130.0, 90.0], [260.0, 180.0], [-20.0, 200.0]] {
            let d = fit.model.world_to_image(w).unwrap();
            let back = inverse.map(d).unwrap();
            prop_assert!((back[0] - w[0]).abs() < 1e-6 && (back[1] - w[1]).abs() < 1e-6);
        }
    }

    #[test]
    fn leave_one_out_predicts_exact_data_exactly(
        lens in lens_strategy(),
        (world, h) in view_strategy((6, 5)),
    ) {
        let truth = PlaneModel { h, lens };
        let image: Vec<Point> = world.iter().map(|w| truth.world_to_image(*w).unwrap()).collect();
        prop_assume!(lens.check_invertible(lens.reach(SIZE[0], SIZE[1])).is_ok());
        let fit = fit_plane(&world, &image, LensParams::K1K2Centre, SIZE).unwrap();
        for (p, (w, d)) in leave_one_out(&fit, &world, &image).unwrap().iter().zip(world.iter().zip(&image)) {
            prop_assert!((p.image_px[0] - d[0]).abs() < 1e-5 && (p.image_px[1] - d[1]).abs() < 1e-5);
            prop_assert!((p.world_mm[0] - w[0]).abs() < 1e-5 && (p.world_mm[1] - w[1]).abs() < 1e-5);
        }
    }

    #[test]
    fn nested_models_never_fit_worse(
        lens in lens_strategy(),
        (world, h) in view_strategy((8, 6)),
        seed in 0u64..1000,
    ) {
        let truth = PlaneModel { h, lens };
        let mut state = seed.wrapping_mul(0x9E3779B97F4A7C15) | 1;
        let mut noise = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.2
        };
        let image: Vec<Point> = world
            .iter()
            .map(|w| {
                let d = truth.world_to_image(*w).unwrap();
                [d[0] + noise(), d[1] + noise()]
            })
            .collect();
        prop_assume!(lens.check_invertible(lens.reach(SIZE[0], SIZE[1])).is_ok());
        let mut last = f64::INFINITY;
        for free in LensParams::ALL {
            let Ok(fit) = fit_plane(&world, &image, free, SIZE) else { continue };
            // A richer model contains the simpler one: its minimum cannot be higher.
            prop_assert!(fit.cost <= last * (1.0 + 1e-9) + 1e-12, "{:?}: {} > {}", free, fit.cost, last);
            last = fit.cost;
        }
    }
}
