//! Radial lens distortion about a centre: the polynomial model
//!     d = c + (u - c) (1 + k1 rho^2 + k2 rho^4),   rho = |u - c| / s,
//! mapping an ideal (pinhole) pixel u to the pixel d the lens really shows. It is OpenCV's
//! two-term radial model written in pixels: with c the principal point and s the focal
//! length it is exactly OpenCV's (k1, k2); any other fixed scale s (we use the image's
//! half-diagonal, which needs no focal length) only rescales the coefficients.
//!
//! The model is invertible out to the radius where the radial map folds over (its derivative
//! reaches zero); `undistort` refuses points beyond it instead of returning a wrong value.

use crate::error::HomographyError;
use crate::point_failure::PointFailure;
use crate::transform::map_indexed;
use crate::Point;

/// Newton's method on the radial equation converges to rounding in a handful of steps for
/// any valid radius; this bounds the loop on pathological input.
const MAX_NEWTON_STEPS: usize = 50;

/// The two-term radial lens above: where an ideal pixel appears, and back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadialLens {
    /// The distortion centre, px.
    pub centre: Point,
    /// The radius unit s, px (fixed by the image's size, not fitted).
    pub scale: f64,
    /// The rho^2 coefficient.
    pub k1: f64,
    /// The rho^4 coefficient.
    pub k2: f64,
}

/// Why a lens cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LensError {
    #[error(
        "the lens distortion (k1 = {k1:.4}, k2 = {k2:.4}) folds the image over at {radius:.0} px \
         from its centre, inside the {reach:.0} px the image reaches: no lens does that; the \
         board probably covers too little of the image to determine the distortion"
    )]
    /// The radial map folds over inside the image.
    FoldsOver {
        /// The lens's k1.
        k1: f64,
        /// The lens's k2.
        k2: f64,
        /// Where it folds, px from the centre.
        radius: f64,
        /// How far the image reaches from the centre, px.
        reach: f64,
    },

    #[error(
        "point {index} ({x}, {y}) lies beyond the lens model's valid radius ({radius:.0} px from \
         its centre), where the distortion cannot be inverted"
    )]
    /// A point beyond the radius where the model inverts.
    OutsideModel {
        /// The point's index.
        index: usize,
        /// Its x, px.
        x: f64,
        /// Its y, px.
        y: f64,
        /// The valid radius, px.
        radius: f64,
    },

    #[error("the lens model needs {what}, got {value}")]
    /// A lens parameter out of range.
    InvalidLens {
        /// What it must be, in words.
        what: &'static str,
        /// The value given.
        value: f64,
    },

    #[error("the image size must be two positive whole numbers of pixels, got {width} x {height}")]
    /// An image size that is not two positive whole numbers.
    InvalidImageSize {
        /// The width given.
        width: f64,
        /// The height given.
        height: f64,
    },

    #[error(
        "{n} points cannot fit the {model} model ({params} parameters): it needs at least \
         {needed}"
    )]
    /// Fewer points than the model needs.
    TooFewPoints {
        /// Points given.
        n: usize,
        /// The model's name.
        model: &'static str,
        /// Its parameters.
        params: usize,
        /// The points it needs.
        needed: usize,
    },

    #[error(
        "the points do not determine the {model} model: its normal equations are singular \
         (the board covers too little of the image, or too few points)"
    )]
    /// The points do not fix the model.
    Undetermined {
        /// The model's name.
        model: &'static str,
    },

    /// The homography part failed.
    #[error(transparent)]
    Homography(#[from] HomographyError),
}

impl RadialLens {
    /// No distortion, centred on an image of the given size.
    pub fn identity(width: f64, height: f64) -> Result<Self, LensError> {
        if !(width >= 1.0 && height >= 1.0 && width.is_finite() && height.is_finite()) {
            return Err(LensError::InvalidImageSize { width, height });
        }
        Ok(RadialLens {
            centre: [(width - 1.0) / 2.0, (height - 1.0) / 2.0],
            scale: 0.5 * width.hypot(height),
            k1: 0.0,
            k2: 0.0,
        })
    }

    /// Checks the parameters are finite and the scale positive.
    pub fn validate(&self) -> Result<(), LensError> {
        for (what, value) in [
            ("a finite centre x", self.centre[0]),
            ("a finite centre y", self.centre[1]),
            ("a finite k1", self.k1),
            ("a finite k2", self.k2),
        ] {
            if !value.is_finite() {
                return Err(LensError::InvalidLens { what, value });
            }
        }
        if !(self.scale > 0.0 && self.scale.is_finite()) {
            return Err(LensError::InvalidLens {
                what: "a positive, finite scale",
                value: self.scale,
            });
        }
        Ok(())
    }

    /// No distortion at all (k1 = k2 = 0).
    pub fn is_identity(&self) -> bool {
        self.k1 == 0.0 && self.k2 == 0.0
    }

    /// The radial factor f(rho^2) and its derivative in rho^2.
    #[inline(always)]
    pub fn factor(&self, rho2: f64) -> (f64, f64) {
        (
            1.0 + rho2 * (self.k1 + self.k2 * rho2),
            self.k1 + 2.0 * self.k2 * rho2,
        )
    }

    /// Ideal pixel -> distorted pixel.
    #[inline]
    pub fn distort(&self, u: Point) -> Point {
        let s = self.scale;
        let (qx, qy) = ((u[0] - self.centre[0]) / s, (u[1] - self.centre[1]) / s);
        let (f, _) = self.factor(qx * qx + qy * qy);
        [self.centre[0] + s * qx * f, self.centre[1] + s * qy * f]
    }

    /// The normalised radius (in units of `scale`) at which the radial map r (1 + k1 r^2 +
    /// k2 r^4) stops increasing, or infinity when it never does.
    pub fn fold_radius(&self) -> f64 {
        // d/dr [r f(r^2)] = 1 + 3 k1 r^2 + 5 k2 r^4: its smallest positive root in r^2.
        let (a, b) = (5.0 * self.k2, 3.0 * self.k1);
        let roots: [f64; 2] = if a == 0.0 {
            [
                if b < 0.0 { -1.0 / b } else { f64::INFINITY },
                f64::INFINITY,
            ]
        } else {
            let disc = b * b - 4.0 * a;
            if disc < 0.0 {
                [f64::INFINITY; 2]
            } else {
                let sq = disc.sqrt();
                // Numerically stable pair of roots of a t^2 + b t + 1.
                let q = -0.5 * (b + b.signum() * sq);
                if q == 0.0 {
                    [f64::INFINITY; 2]
                } else {
                    [q / a, 1.0 / q]
                }
            }
        };
        let t = roots
            .iter()
            .copied()
            .filter(|t| *t > 0.0)
            .fold(f64::INFINITY, f64::min);
        t.sqrt()
    }

    /// The largest distorted radius (px from the centre) the model can invert.
    pub fn valid_radius(&self) -> f64 {
        let fold = self.fold_radius();
        if fold.is_infinite() {
            return f64::INFINITY;
        }
        self.scale * fold * self.factor(fold * fold).0
    }

    /// Checks that the model is invertible over every distorted radius up to `reach` px (the
    /// image's farthest corner from the centre).
    pub fn check_invertible(&self, reach: f64) -> Result<(), LensError> {
        let valid = self.valid_radius();
        // A fold just past the corner still bends the map flat there: keep a margin.
        if !(valid >= 1.05 * reach) {
            return Err(LensError::FoldsOver {
                k1: self.k1,
                k2: self.k2,
                radius: valid,
                reach,
            });
        }
        Ok(())
    }

    /// The distance from the centre to the farthest pixel corner of a width x height image.
    pub fn reach(&self, width: f64, height: f64) -> f64 {
        let dx = (self.centre[0] + 0.5).max(width - 0.5 - self.centre[0]);
        let dy = (self.centre[1] + 0.5).max(height - 0.5 - self.centre[1]);
        dx.hypot(dy)
    }

    /// Distorts every point of `src` into `out` (the same length), in parallel chunks for
    /// large batches.
    pub fn distort_all(&self, src: &[Point], out: &mut [Point]) {
        let n = src.len().min(out.len());
        map_indexed(&mut out[..n], [f64::NAN; 2], |i| Ok(self.distort(src[i])));
    }

    /// Undistorts every point of `src` into `out` (the same length), in parallel chunks for
    /// large batches: NaN where a point has no ideal pixel (beyond the valid radius, or not
    /// finite). Returns how many have none and the index of the first.
    pub fn undistort_all(&self, src: &[Point], out: &mut [Point]) -> (usize, Option<usize>) {
        let n = src.len().min(out.len());
        let fold = self.fold_radius();
        let report = map_indexed(&mut out[..n], [f64::NAN; 2], |i| {
            self.undistort_within(src[i], fold)
                .filter(|u| u[0].is_finite() && u[1].is_finite())
                // The report's kind goes unused: only the count and the first index do.
                .ok_or(PointFailure::NonFinite)
        });
        (report.invalid(), report.first.map(|(i, _)| i))
    }

    /// The error for point `index`, `d`, which lies beyond the valid radius.
    pub fn outside(&self, index: usize, d: Point) -> LensError {
        LensError::OutsideModel {
            index,
            x: d[0],
            y: d[1],
            radius: self.valid_radius(),
        }
    }

    /// Distorted pixel -> ideal pixel, or None beyond the model's valid radius.
    #[inline]
    pub fn undistort(&self, d: Point) -> Option<Point> {
        self.undistort_within(d, self.fold_radius())
    }

    /// `undistort`, given the lens's `fold_radius` (computed once for a batch).
    #[inline]
    fn undistort_within(&self, d: Point, fold: f64) -> Option<Point> {
        if self.is_identity() {
            return Some(d);
        }
        let s = self.scale;
        let (px, py) = ((d[0] - self.centre[0]) / s, (d[1] - self.centre[1]) / s);
        let rd = px.hypot(py);
        if rd == 0.0 {
            return Some(d);
        }
        let g = |r: f64| r * self.factor(r * r).0;
        if fold.is_finite() && rd >= g(fold) {
            return None;
        }
        // Newton on g(r) = rd from r = rd, kept inside [0, fold) where g is increasing.
        let mut r = rd.min(0.5 * fold);
        for _ in 0..MAX_NEWTON_STEPS {
            let r2 = r * r;
            let gr = r * (1.0 + r2 * (self.k1 + self.k2 * r2)) - rd;
            let dg = 1.0 + r2 * (3.0 * self.k1 + 5.0 * self.k2 * r2);
            let mut next = r - gr / dg;
            if next <= 0.0 {
                next = 0.5 * r;
            } else if next >= fold {
                next = 0.5 * (r + fold);
            }
            let step = (next - r).abs();
            r = next;
            if step <= 4.0 * f64::EPSILON * r {
                break;
            }
        }
        let ratio = r / rd;
        let u = [
            self.centre[0] + s * px * ratio,
            self.centre[1] + s * py * ratio,
        ];
        // Verified, not assumed: the result must distort back onto the input.
        let back = self.distort(u);
        let tol = 1e-9 * (1.0 + s * rd);
        ((back[0] - d[0]).abs() <= tol && (back[1] - d[1]).abs() <= tol).then_some(u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lens(k1: f64, k2: f64) -> RadialLens {
        RadialLens {
            centre: [644.0, 355.0],
            scale: 734.0,
            k1,
            k2,
        }
    }

    #[test]
    fn undistort_inverts_distort_across_the_image() {
        let l = lens(-0.26, 0.14);
        l.check_invertible(800.0).unwrap();
        for i in 0..=64 {
            for j in 0..=36 {
                let u = [i as f64 * 20.0, j as f64 * 20.0];
                let d = l.distort(u);
                let back = l.undistort(d).unwrap();
                assert!((back[0] - u[0]).abs() < 1e-9 && (back[1] - u[1]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn fold_radius_is_where_the_radial_map_stops_rising() {
        for (k1, k2) in [(-0.3, 0.0), (-0.5, 0.1), (0.2, -0.3), (-0.1, -0.05)] {
            let l = lens(k1, k2);
            let f = l.fold_radius();
            let slope = |r: f64| 1.0 + 3.0 * k1 * r * r + 5.0 * k2 * r.powi(4);
            assert!(
                slope(0.999 * f) > 0.0 && slope(1.001 * f) < 0.0,
                "{k1} {k2} {f}"
            );
        }
        assert!(lens(0.1, 0.05).fold_radius().is_infinite());
    }

    #[test]
    fn batches_mark_the_points_without_an_ideal_pixel() {
        let l = lens(-0.5, 0.0);
        let far = [l.centre[0] + 1.01 * l.valid_radius(), l.centre[1]];
        let src = [[500.0, 300.0], far, [f64::NAN, 1.0], [700.0, 400.0]];
        let mut out = [[0.0; 2]; 4];
        assert_eq!(l.undistort_all(&src, &mut out), (2, Some(1)));
        assert!(out[1][0].is_nan() && out[2][0].is_nan());
        let mut back = [[0.0; 2]; 4];
        l.distort_all(&out, &mut back);
        for i in [0, 3] {
            assert!((back[i][0] - src[i][0]).abs() < 1e-9 && (back[i][1] - src[i][1]).abs() < 1e-9);
        }
        let identity = RadialLens::identity(1280.0, 720.0).unwrap(); // ok: test-only
        assert_eq!(
            identity.undistort_all(&src[2..], &mut out[..2]),
            (1, Some(0))
        );
    }

    #[test]
    fn points_beyond_the_fold_are_refused() {
        let l = lens(-0.5, 0.0);
        let valid = l.valid_radius();
        assert!(l.check_invertible(valid * 0.99).is_err());
        assert!(l.check_invertible(valid * 0.9).is_ok());
        let far = [l.centre[0] + 1.01 * valid, l.centre[1]];
        assert!(l.undistort(far).is_none());
    }
}
