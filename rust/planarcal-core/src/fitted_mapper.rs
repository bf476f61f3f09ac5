//! A fitted plane ready to map pixels: each pixel's place on the plane by the fast
//! `PlaneMapper`, and its uncertainty from the fit (`uncertainty::world_covariance`) and from
//! the model's bias (`with_model_sigma`: what the fit's covariance cannot see, an error shared
//! by a pixel and its neighbours, given in px per coordinate). The bindings' `FittedPlane`
//! maps through it, so positions and their errors come from one call into the core, with the
//! reference's failures (`InversePlane::map`) on the same pixels.

use std::sync::OnceLock;

use nalgebra::Matrix2;
use rayon::prelude::*;

use crate::lens::LensError;
use crate::mapper::{checked_size, PlaneMapper};
use crate::plane_model::{MatP, PlaneFit};
use crate::point_failure::PointReport;
use crate::threads;
use crate::uncertainty::{covariance_at, InversePlane};
use crate::Point;

/// From this many points the uncertainties are computed on rayon's threads (a point's costs
/// about 0.2 us, so this is about a millisecond of work); each point's result is its own, so
/// the split does not change it.
const PARALLEL_MIN_POINTS: usize = 4_096;

/// Points per parallel task.
const CHUNK_POINTS: usize = 1_024;

/// Why mapped pixels' uncertainty cannot be given.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum UncertaintyError {
    /// The pixels' own noise is negative, NaN or infinite.
    #[error("pixel_sigma must be a finite number >= 0, got {0}")]
    InvalidPixelSigma(f64),
    /// The model's bias is negative, NaN or infinite.
    #[error("the model's bias (model_sigma_px) must be a finite number >= 0, got {0}")]
    InvalidModelSigma(f64),
    /// As many parameters as coordinates: the residuals say nothing of the noise.
    #[error(
        "the fit has no residual degrees of freedom (as many parameters as coordinates), so \
         its uncertainty cannot be estimated: use more points"
    )]
    NoResidualDof,
}

/// A fit, and the fast mapper of its model over the image it was fitted on.
#[derive(Debug, Clone)]
pub struct FittedMapper {
    fit: PlaneFit,
    image_size: [f64; 2],
    /// The reference inverse within the image: it checks the model at construction, and the
    /// mapper falls back on it.
    reference: InversePlane,
    /// The fit's parameter covariance; None without residual degrees of freedom.
    covariance: Option<MatP>,
    /// The model's bias, px per coordinate: added to every pixel's own noise in quadrature.
    model_sigma: f64,
    /// Built on first use: its lens inverse costs about a millisecond (twice a fit), and a
    /// calibration fits several models to keep one.
    mapper: OnceLock<PlaneMapper>,
}

impl FittedMapper {
    /// Maps pixels of a width x height image (`image_size`, px) through `fit`'s model, refusing
    /// those 5 % beyond its farthest corner as `InversePlane::within_image` does; refused if the
    /// size is not one or the model has no inverse.
    pub fn new(fit: PlaneFit, image_size: [f64; 2]) -> Result<Self, LensError> {
        let [width, height] = checked_size(image_size)?;
        let reference = InversePlane::new(&fit.model)?.within_image(width, height);
        let covariance = (fit.dof > 0).then(|| fit.covariance());
        Ok(FittedMapper {
            fit,
            image_size,
            reference,
            covariance,
            model_sigma: 0.0,
            mapper: OnceLock::new(),
        })
    }

    /// This mapper with the model's bias `sigma_px` (px per coordinate, isotropic in the
    /// image): the error a pixel's mapping has beyond the fit's covariance, because the model
    /// (the lens, or the dot centres it was fitted to) is off by a smooth field the residuals
    /// do not show. Every uncertainty then adds it to the pixel's own noise in quadrature:
    /// sigma^2 = pixel_sigma^2 + sigma_px^2. Refused unless finite and >= 0.
    pub fn with_model_sigma(mut self, sigma_px: f64) -> Result<Self, UncertaintyError> {
        if !(sigma_px >= 0.0 && sigma_px.is_finite()) {
            return Err(UncertaintyError::InvalidModelSigma(sigma_px));
        }
        self.model_sigma = sigma_px;
        Ok(self)
    }

    /// The model's bias, px per coordinate (0 unless `with_model_sigma` set it).
    pub fn model_sigma(&self) -> f64 {
        self.model_sigma
    }

    /// The fit it maps through.
    pub fn fit(&self) -> &PlaneFit {
        &self.fit
    }

    /// The fast mapper (built on the first call).
    pub fn mapper(&self) -> &PlaneMapper {
        self.mapper.get_or_init(|| {
            PlaneMapper::from_reference(&self.fit.model, self.image_size, self.reference, None)
        })
    }

    /// Maps `px` into `out` (mm), NaN where a pixel has no place on the plane, and reports
    /// those: `PlaneMapper::map_into`.
    pub fn map_into(&self, px: &[Point], out: &mut [Point]) -> PointReport {
        self.mapper().map_into(px, out)
    }

    /// Whether uncertainties can be given with pixels of `pixel_sigma` px noise per coordinate.
    pub fn check_uncertainty(&self, pixel_sigma: f64) -> Result<(), UncertaintyError> {
        self.parameter_covariance(pixel_sigma).map(|_| ())
    }

    /// As `map_into`, with each point's 1-sigma error in `std` (mm): the square root of the
    /// trace of its covariance (`world_covariance`, the pixel's noise `pixel_sigma` and the
    /// model's bias added in quadrature), the RMS distance from the truth. NaN where the
    /// pixel has no place on the plane. Maps the first min of the three lengths.
    pub fn map_with_std_into(
        &self,
        px: &[Point],
        pixel_sigma: f64,
        out: &mut [Point],
        std: &mut [f64],
    ) -> Result<PointReport, UncertaintyError> {
        self.map_with(px, pixel_sigma, out, std, |c| {
            c.map_or(f64::NAN, |c| c.trace().sqrt())
        })
    }

    /// As `map_into`, with each point's covariance (mm^2, row-major 2 x 2) in `cov`:
    /// `world_covariance`, with the pixel's noise and the model's bias in quadrature. NaN
    /// where the pixel has no place on the plane.
    pub fn map_with_covariance_into(
        &self,
        px: &[Point],
        pixel_sigma: f64,
        out: &mut [Point],
        cov: &mut [[f64; 4]],
    ) -> Result<PointReport, UncertaintyError> {
        self.map_with(px, pixel_sigma, out, cov, |c| {
            let c = c.unwrap_or(Matrix2::from_element(f64::NAN));
            [c[(0, 0)], c[(0, 1)], c[(1, 0)], c[(1, 1)]]
        })
    }

    fn parameter_covariance(&self, pixel_sigma: f64) -> Result<&MatP, UncertaintyError> {
        if !(pixel_sigma >= 0.0 && pixel_sigma.is_finite()) {
            return Err(UncertaintyError::InvalidPixelSigma(pixel_sigma));
        }
        self.covariance
            .as_ref()
            .ok_or(UncertaintyError::NoResidualDof)
    }

    /// Maps, then writes `each` of every point's covariance (None where it has none) into
    /// `extra`.
    fn map_with<T: Send>(
        &self,
        px: &[Point],
        pixel_sigma: f64,
        out: &mut [Point],
        extra: &mut [T],
        each: impl Fn(Option<Matrix2<f64>>) -> T + Sync,
    ) -> Result<PointReport, UncertaintyError> {
        let cov = self.parameter_covariance(pixel_sigma)?;
        // The model's bias moves a pixel's place as its own noise does: through d(world)/d(px).
        let pixel_sigma = pixel_sigma.hypot(self.model_sigma);
        let n = px.len().min(out.len()).min(extra.len());
        let (px, out, extra) = (&px[..n], &mut out[..n], &mut extra[..n]);
        let report = self.map_into(px, out);
        let fill = |world: &[Point], extra: &mut [T]| {
            for (w, e) in world.iter().zip(extra.iter_mut()) {
                let mapped = !w[0].is_nan();
                *e = each(
                    mapped
                        .then(|| covariance_at(&self.fit, cov, *w, pixel_sigma))
                        .flatten(),
                );
            }
        };
        if n < PARALLEL_MIN_POINTS || !threads::pool_allowed() {
            fill(out, extra);
        } else {
            out.par_chunks(CHUNK_POINTS)
                .zip(extra.par_chunks_mut(CHUNK_POINTS))
                .for_each(|(w, e)| fill(w, e));
        }
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lens::RadialLens;
    use crate::plane_model::{fit_plane, LensParams, PlaneModel};
    use crate::uncertainty::world_covariance;
    use nalgebra::Matrix3;

    const SIZE: [f64; 2] = [1280.0, 720.0];

    /// A 14 x 10 grid at 20 mm seen through a k1 = -0.06 lens, with pseudo-noise of about
    /// 0.1 px, fitted with the lens model `free`.
    fn fitted(free: LensParams) -> PlaneFit {
        let model = PlaneModel {
            h: Matrix3::new(2.0, 0.05, 330.0, -0.03, 2.02, 160.0, 2e-5, -3e-5, 1.0),
            lens: RadialLens {
                centre: [639.5, 359.5],
                scale: 0.5 * SIZE[0].hypot(SIZE[1]),
                k1: if free == LensParams::None { 0.0 } else { -0.06 },
                k2: 0.0,
            },
        };
        let (mut world, mut image, mut k) = (Vec::new(), Vec::new(), 1u64);
        for r in 0..10 {
            for c in 0..14 {
                let w = [c as f64 * 20.0, r as f64 * 20.0];
                let d = model.world_to_image(w).unwrap(); // ok: test-only, in front
                let mut noise = || {
                    k = k
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    ((k >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.35
                };
                world.push(w);
                image.push([d[0] + noise(), d[1] + noise()]);
            }
        }
        fit_plane(&world, &image, free, SIZE).unwrap() // ok: test-only, a good problem
    }

    /// Pixels over and beyond the image, far beyond the lens's reach, and non-finite.
    fn pixels() -> Vec<Point> {
        let mut px: Vec<Point> = (0..3000)
            .map(|i| {
                let (a, b) = (
                    (i as f64 * 0.618_034).fract(),
                    (i as f64 * 0.414_214).fract(),
                );
                [-300.0 + 1880.0 * a, -200.0 + 1120.0 * b]
            })
            .collect();
        px.extend([
            [f64::NAN, 3.0],
            [1e5, 360.0],
            [-3000.0, -3000.0],
            [639.5, 359.5],
        ]);
        px
    }

    #[test]
    fn positions_and_errors_are_the_references() {
        for free in [LensParams::None, LensParams::K1, LensParams::K1K2Centre] {
            let fit = fitted(free);
            let reference = InversePlane::new(&fit.model)
                .unwrap() // ok: test-only, an invertible model
                .within_image(SIZE[0], SIZE[1]);
            let mapper = FittedMapper::new(fit, SIZE).unwrap(); // ok: test-only
            let px = pixels();
            let (mut out, mut std) = (vec![[0.0; 2]; px.len()], vec![0.0; px.len()]);
            let report = mapper
                .map_with_std_into(&px, 0.1, &mut out, &mut std)
                .unwrap(); // ok: test-only, dof > 0
            let mut cov = vec![[0.0; 4]; px.len()];
            let mut again = vec![[0.0; 2]; px.len()];
            mapper
                .map_with_covariance_into(&px, 0.1, &mut again, &mut cov)
                .unwrap(); // ok: test-only
            let (mut failed, mut first) = (0, None);
            for (i, p) in px.iter().enumerate() {
                match reference.map(*p) {
                    Ok(w) => {
                        let d = (out[i][0] - w[0]).hypot(out[i][1] - w[1]);
                        assert!(d <= 1e-10 * w[0].hypot(w[1]).max(1.0), "{p:?}: {d:e}");
                        let c = world_covariance(&fit, w, 0.1).unwrap(); // ok: test-only
                        assert!((std[i] / c.trace().sqrt() - 1.0).abs() < 1e-9);
                        assert_eq!(std[i], (cov[i][0] + cov[i][3]).sqrt());
                        assert_eq!(out[i], again[i]);
                    }
                    Err(f) => {
                        failed += 1;
                        first = first.or(Some((i, f)));
                        assert!(out[i][0].is_nan() && std[i].is_nan() && cov[i][0].is_nan());
                    }
                }
            }
            assert_eq!((report.invalid(), report.first), (failed, first));
            assert_eq!(report.non_finite, 1);
            // Only a lens model refuses pixels beyond the image.
            assert_eq!(report.outside_lens > 0, free != LensParams::None);
        }
    }

    #[test]
    fn large_batches_give_the_same_bits_as_small_ones() {
        let mapper = FittedMapper::new(fitted(LensParams::K1), SIZE).unwrap(); // ok: test-only
        let px: Vec<Point> = pixels()
            .into_iter()
            .cycle()
            .take(3 * PARALLEL_MIN_POINTS)
            .collect();
        let (mut out, mut std) = (vec![[0.0; 2]; px.len()], vec![0.0; px.len()]);
        mapper
            .map_with_std_into(&px, 0.0, &mut out, &mut std)
            .unwrap(); // ok: test-only
        for start in (0..px.len()).step_by(1000) {
            let end = (start + 1000).min(px.len());
            let (mut o, mut s) = (vec![[0.0; 2]; end - start], vec![0.0; end - start]);
            mapper
                .map_with_std_into(&px[start..end], 0.0, &mut o, &mut s)
                .unwrap(); // ok: test-only
            for k in 0..o.len() {
                assert_eq!(o[k][0].to_bits(), out[start + k][0].to_bits());
                assert_eq!(s[k].to_bits(), std[start + k].to_bits());
            }
        }
    }

    #[test]
    fn the_models_bias_adds_to_the_pixels_noise_in_quadrature() {
        let plain = FittedMapper::new(fitted(LensParams::K1), SIZE).unwrap(); // ok: test-only
        assert_eq!(plain.model_sigma(), 0.0);
        let biased = plain.clone().with_model_sigma(0.03).unwrap(); // ok: test-only, valid
        assert_eq!(biased.model_sigma(), 0.03);
        let px = pixels();
        let n = px.len();
        let run = |m: &FittedMapper, sigma: f64| {
            let (mut out, mut std) = (vec![[0.0; 2]; n], vec![0.0; n]);
            m.map_with_std_into(&px, sigma, &mut out, &mut std).unwrap(); // ok: test-only
            (out, std)
        };
        let (out, std) = run(&biased, 0.04);
        let (same_out, same_std) = run(&plain, 0.05);
        let (plain_out, plain_std) = run(&plain, 0.0);
        for k in 0..n {
            // Positions are untouched; the std is that of a pixel noise of hypot(0.04, 0.03).
            assert_eq!(out[k][0].to_bits(), plain_out[k][0].to_bits());
            if std[k].is_nan() {
                assert!(same_std[k].is_nan());
                continue;
            }
            assert!((std[k] / same_std[k] - 1.0).abs() < 1e-12, "{k}");
            assert!(std[k] > plain_std[k]);
            assert_eq!(out[k][1].to_bits(), same_out[k][1].to_bits());
        }
        for bad in [-0.1, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                plain.clone().with_model_sigma(bad),
                Err(UncertaintyError::InvalidModelSigma(_))
            ));
        }
    }

    #[test]
    fn uncertainty_needs_a_sane_pixel_noise_and_spare_degrees_of_freedom() {
        let mapper = FittedMapper::new(fitted(LensParams::K1), SIZE).unwrap(); // ok: test-only
        let (px, mut out, mut std) = ([[600.0, 300.0]], [[0.0; 2]], [0.0]);
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                mapper.map_with_std_into(&px, bad, &mut out, &mut std),
                Err(UncertaintyError::InvalidPixelSigma(_))
            ));
        }
        let mut exact = fitted(LensParams::None);
        exact.dof = 0;
        let mapper = FittedMapper::new(exact, SIZE).unwrap(); // ok: test-only
        assert_eq!(
            mapper.map_with_std_into(&px, 0.0, &mut out, &mut std),
            Err(UncertaintyError::NoResidualDof)
        );
        // Positions alone need neither.
        assert_eq!(mapper.map_into(&px, &mut out).invalid(), 0);
        assert!(matches!(
            FittedMapper::new(fitted(LensParams::K1), [0.0, 720.0]),
            Err(LensError::InvalidImageSize { .. })
        ));
    }
}
