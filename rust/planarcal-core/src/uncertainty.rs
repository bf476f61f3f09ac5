//! Mapping pixels to the plane through a fitted `PlaneModel`, and how uncertain the result is.
//!
//! A pixel d maps to the world point w that the model sends to d: undistort, then H^-1. The
//! fit's parameter covariance C (sigma^2 (J^T J)^-1, from `plane_model`) carries over by the
//! implicit function theorem: with F(w, theta) = image(w; theta) - d = 0,
//!     dw/dtheta = -(dF/dw)^-1 dF/dtheta,   Cov(w) = B C B^T,  B = (dF/dw)^-1 dF/dtheta.
//! A pixel measured with its own noise (sigma_px per coordinate) adds
//! sigma_px^2 (dF/dw)^-1 (dF/dw)^-T.

use nalgebra::{Matrix2, Matrix3, Vector3};

use crate::lens::{LensError, RadialLens};
use crate::plane_model::{JacP, MatP, PlaneFit, PlaneModel};
use crate::point_failure::PointFailure;
use crate::transform::invert;
use crate::Point;

/// Pixels -> plane through a model: the inverse homography and the lens.
#[derive(Debug, Clone, Copy)]
pub struct InversePlane {
    hinv: Matrix3<f64>,
    lens: RadialLens,
    /// Pixels farther than this from the lens centre are refused (px).
    limit: f64,
}

impl InversePlane {
    /// The inverse of `model`, refused if its lens or homography has none.
    pub fn new(model: &PlaneModel) -> Result<Self, LensError> {
        model.lens.validate()?;
        Ok(InversePlane {
            hinv: invert(&model.h)?,
            lens: model.lens,
            limit: f64::INFINITY,
        })
    }

    /// Refuses pixels beyond the image the lens was fitted on (by 5 % of the distance to its
    /// farthest corner): a distortion polynomial says nothing about where it has no data.
    pub fn within_image(mut self, width: f64, height: f64) -> Self {
        if !self.lens.is_identity() {
            self.limit = 1.05 * self.lens.reach(width, height);
        }
        self
    }

    /// H^-1: ideal pixels -> world (mm).
    pub(crate) fn hinv(&self) -> &Matrix3<f64> {
        &self.hinv
    }

    /// The world point (mm) pixel d sees.
    #[inline]
    pub fn map(&self, d: Point) -> Result<Point, PointFailure> {
        if !(d[0].is_finite() && d[1].is_finite()) {
            return Err(PointFailure::NonFinite);
        }
        let r = (d[0] - self.lens.centre[0]).hypot(d[1] - self.lens.centre[1]);
        if !(r <= self.limit) {
            return Err(PointFailure::OutsideLens);
        }
        let u = self.lens.undistort(d).ok_or(PointFailure::OutsideLens)?;
        let v = self.hinv * Vector3::new(u[0], u[1], 1.0);
        // The true inverse of an oriented H is oriented: w > 0 in front of the camera.
        let scale = self.hinv.row(2).abs().sum() * (1.0 + u[0].abs() + u[1].abs());
        if !(v[2] > 8.0 * f64::EPSILON * scale) {
            return Err(PointFailure::BehindHorizon);
        }
        let w = [v[0] / v[2], v[1] / v[2]];
        if !(w[0].is_finite() && w[1].is_finite()) {
            return Err(PointFailure::BehindHorizon);
        }
        Ok(w)
    }
}

/// The derivative of the mapped world point by the parameters, B (2 x P), and the inverse of
/// d(image)/d(world), at world point w; None if w is not in front.
fn sensitivity(fit: &PlaneFit, w: Point) -> Option<(JacP, Matrix2<f64>)> {
    let p = fit.params.predict(w)?;
    let inv = p.d_world.try_inverse()?;
    Some((inv * p.d_theta, inv))
}

/// Covariance (mm^2) of the world point that a pixel maps to at world point w: the fit's
/// uncertainty, plus that of the pixel's own measurement noise `pixel_sigma` (px per
/// coordinate) when it is not zero.
pub fn world_covariance(fit: &PlaneFit, w: Point, pixel_sigma: f64) -> Option<Matrix2<f64>> {
    covariance_at(fit, &fit.covariance(), w, pixel_sigma)
}

/// `world_covariance` with the fit's parameter covariance `cov` (`fit.covariance()`) given,
/// for callers that ask at many points.
pub(crate) fn covariance_at(
    fit: &PlaneFit,
    cov: &MatP,
    w: Point,
    pixel_sigma: f64,
) -> Option<Matrix2<f64>> {
    let (b, inv) = sensitivity(fit, w)?;
    Some(b * cov * b.transpose() + inv * inv.transpose() * (pixel_sigma * pixel_sigma))
}

/// The covariance (mm^2) of the error of each point's leave-one-out prediction: the world
/// point its measured pixel maps to under a fit made without it, minus its true position.
/// It is the fit-without-it's uncertainty at the point, (J^T J - J_i^T J_i)^-1 scaled by
/// sigma^2, plus the point's own measurement noise sigma^2 mapped to the plane.
/// OutOfMemory when there is no room for them.
pub fn predicted_loo_covariance(
    fit: &PlaneFit,
    world: &[Point],
) -> crate::Result<Vec<Option<Matrix2<f64>>>> {
    let sigma2 = fit.cost / fit.dof.max(1) as f64;
    // J^T J over the free parameters, recovered from its inverse (kept by the fit).
    let free_jtj = invert_free(&fit.jtj_inv);
    crate::alloc::collect(world.iter().map(|&w| {
        let mut p = fit.params.predict(w)?;
        fit.free.mask(&mut p.d_theta);
        let inv = p.d_world.try_inverse()?;
        let jtj_i = free_jtj? - p.d_theta.transpose() * p.d_theta;
        let without = invert_free(&jtj_i)?;
        let b = inv * p.d_theta;
        Some((b * without * b.transpose() + inv * inv.transpose()) * sigma2)
    }))
}

/// The inverse of a symmetric matrix over the rows and columns that are not all zero (the
/// free parameters), zero elsewhere; None when that block is singular.
fn invert_free(m: &MatP) -> Option<MatP> {
    let n = m.nrows();
    let free: Vec<bool> = (0..n).map(|j| m.row(j).iter().any(|v| *v != 0.0)).collect();
    let mut a = *m;
    for j in 0..n {
        if !free[j] {
            a[(j, j)] = 1.0;
        }
    }
    let d: Vec<f64> = (0..n).map(|j| 1.0 / a[(j, j)].abs().sqrt()).collect();
    let scaled = MatP::from_fn(|i, j| a[(i, j)] * d[i] * d[j]);
    let inv = scaled.cholesky()?.inverse();
    let out = MatP::from_fn(|i, j| {
        if free[i] && free[j] {
            inv[(i, j)] * d[i] * d[j]
        } else {
            0.0
        }
    });
    out.iter().all(|v| v.is_finite()).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plane_model::{fit_plane, LensParams};

    #[test]
    fn mapping_inverts_the_model() {
        let lens = RadialLens {
            centre: [650.0, 352.0],
            scale: 734.0,
            k1: -0.06,
            k2: 0.02,
        };
        let h = Matrix3::new(2.0, 0.05, 330.0, -0.03, 2.02, 160.0, 2e-5, -3e-5, 1.0);
        let model = PlaneModel { h, lens };
        let inv = InversePlane::new(&model).unwrap();
        for w in [[0.0, 0.0], [260.0, 180.0], [-40.0, 300.0]] {
            let back = inv.map(model.world_to_image(w).unwrap()).unwrap();
            assert!((back[0] - w[0]).abs() < 1e-9 && (back[1] - w[1]).abs() < 1e-9);
        }
        assert_eq!(inv.map([f64::NAN, 1.0]), Err(PointFailure::NonFinite));
    }

    #[test]
    fn covariance_shrinks_with_more_points_and_grows_with_noise() {
        let h = Matrix3::new(2.0, 0.0, 330.0, 0.0, 2.0, 160.0, 0.0, 0.0, 1.0);
        let model = PlaneModel {
            h,
            lens: RadialLens::identity(1280.0, 720.0).unwrap(),
        };
        let mut world = Vec::new();
        let mut image = Vec::new();
        let mut k = 0u64;
        for r in 0..10 {
            for c in 0..14 {
                let w = [c as f64 * 20.0, r as f64 * 20.0];
                // Deterministic pseudo-noise of about 0.1 px.
                k = k
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let nx = ((k >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.35;
                let ny = ((k >> 7 & 0xffff) as f64 / 65536.0 - 0.5) * 0.35;
                let d = model.world_to_image(w).unwrap();
                world.push(w);
                image.push([d[0] + nx, d[1] + ny]);
            }
        }
        let fit = fit_plane(&world, &image, LensParams::None, [1280.0, 720.0]).unwrap();
        let centre = world_covariance(&fit, [130.0, 90.0], 0.0).unwrap();
        let corner = world_covariance(&fit, [0.0, 0.0], 0.0).unwrap();
        let outside = world_covariance(&fit, [-200.0, -200.0], 0.0).unwrap();
        assert!(centre.trace() < corner.trace() && corner.trace() < outside.trace());
        let with_pixel = world_covariance(&fit, [130.0, 90.0], 0.1).unwrap();
        assert!(with_pixel.trace() > centre.trace());
        let loo = predicted_loo_covariance(&fit, &world).unwrap();
        assert!(loo
            .iter()
            .all(|c| c.is_some_and(|c| c.trace() > centre.trace())));
    }
}
