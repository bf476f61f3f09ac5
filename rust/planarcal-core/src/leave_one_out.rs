//! Leave-one-out: each point predicted by a fit that has not seen it. Residuals flatter a fit
//! (more so the more parameters it has); the leave-one-out errors do not, which makes them
//! both the honest accuracy figure and the judge of whether a lens model's extra parameters
//! are earned. Each refit starts from the full fit, so it converges in a few steps; the
//! points run in parallel.

use rayon::prelude::*;

use crate::alloc;
use crate::error::Result;
use crate::plane_model::{solve, PlaneFit};
use crate::threads;
use crate::uncertainty::InversePlane;
use crate::Point;

/// Point i under the fit without it: where the model puts its world point in the image (px)
/// and where its measured pixel lands on the plane (mm). NaN where the rest cannot be fitted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LooPrediction {
    pub image_px: Point,
    pub world_mm: Point,
}

const NAN2: Point = [f64::NAN, f64::NAN];

const FAILED: LooPrediction = LooPrediction {
    image_px: NAN2,
    world_mm: NAN2,
};

/// The leave-one-out predictions of every point of a fit (OutOfMemory when there is no room
/// for them).
pub fn leave_one_out(
    fit: &PlaneFit,
    world: &[Point],
    image: &[Point],
) -> Result<Vec<LooPrediction>> {
    let one = |i: usize| -> LooPrediction {
        let failed = FAILED;
        let Ok(solved) = solve(fit.params, world, image, fit.free, Some(i)) else {
            return failed;
        };
        let Ok(model) = solved.params.model(world) else {
            return failed;
        };
        let image_px = model.world_to_image(world[i]).unwrap_or(NAN2);
        let world_mm = InversePlane::new(&model)
            .ok()
            .and_then(|inv| inv.map(image[i]).ok())
            .unwrap_or(NAN2);
        LooPrediction { image_px, world_mm }
    };
    let mut out = alloc::filled(FAILED, world.len())?;
    let fill = |(i, slot): (usize, &mut LooPrediction)| *slot = one(i);
    if world.len() >= 16 && threads::pool_allowed() {
        out.par_iter_mut().enumerate().for_each(fill);
    } else {
        out.iter_mut().enumerate().for_each(fill);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lens::RadialLens;
    use crate::plane_model::{fit_plane, LensParams, PlaneModel};
    use nalgebra::Matrix3;

    #[test]
    fn extra_parameters_help_only_when_the_lens_is_there() {
        let h = Matrix3::new(2.0, 0.05, 330.0, -0.03, 2.02, 160.0, 2e-5, -3e-5, 1.0);
        let mut state = 7u64;
        let mut noise = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.1
        };
        let mut world = Vec::new();
        for r in 0..10 {
            for c in 0..14 {
                world.push([c as f64 * 20.0, r as f64 * 20.0]);
            }
        }
        let loo_rms = |image: &[Point], free: LensParams| {
            let fit = fit_plane(&world, image, free, [1280.0, 720.0]).unwrap();
            let loo = leave_one_out(&fit, &world, image).unwrap();
            let sum: f64 = loo
                .iter()
                .zip(image)
                .map(|(p, d)| (p.image_px[0] - d[0]).powi(2) + (p.image_px[1] - d[1]).powi(2))
                .sum();
            (sum / world.len() as f64).sqrt()
        };
        for (k1, lens_wins) in [(-0.08, true), (0.0, false)] {
            let lens = RadialLens {
                k1,
                ..RadialLens::identity(1280.0, 720.0).unwrap()
            };
            let model = PlaneModel { h, lens };
            let image: Vec<Point> = world
                .iter()
                .map(|w| {
                    let d = model.world_to_image(*w).unwrap();
                    [d[0] + noise(), d[1] + noise()]
                })
                .collect();
            let plain = loo_rms(&image, LensParams::None);
            let k1 = loo_rms(&image, LensParams::K1);
            assert_eq!(k1 < plain, lens_wins, "plain {plain} k1 {k1}");
        }
    }
}
