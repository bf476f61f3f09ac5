//! The plane seen through a lens: a homography H from the plane (mm) to ideal pixels, then
//! radial distortion (`lens`), fitted jointly to matched points by Levenberg-Marquardt:
//!     min  sum_i || image_i - distort(H world_i) ||^2.
//! With no distortion parameters free it is the gold-standard homography fit; with k1, k2
//! (and optionally the distortion centre) free it removes what a homography alone cannot
//! see. The covariance of the parameters (from the residuals and the Jacobian) is kept for
//! `uncertainty`.
//!
//! The parameters: H in normalised coordinates (Hartley's similarity on each side) with
//! h33 = 1 there, k1, k2 about the centre, and the centre's offset from the image centre in
//! units of the lens scale, so every parameter is of order one. The loop is `lm`'s; this
//! module gives it the normal equations, with the fixed parameters masked out.

use nalgebra::{Matrix2, Matrix3, SMatrix, SVector};

use crate::correspondences::Correspondences;
use crate::error::HomographyError;
use crate::estimate::{estimate, Solver};
use crate::lens::{LensError, RadialLens};
use crate::lm::{self, Damping, LeastSquares, Options};
use crate::normalize::Normalization;
use crate::orientation::orient_and_scale;
use crate::Point;

/// Parameters: 8 of H, k1, k2, centre offset (2).
pub const P: usize = 12;
pub type MatP = SMatrix<f64, P, P>;
pub type VecP = SVector<f64, P>;
/// d(image point) / d(parameters): 2 x P.
pub type JacP = SMatrix<f64, 2, P>;

/// The loop's settings: Marquardt's tenfold damping steps, which the leave-one-out refits
/// (started at the full fit) also run.
pub(crate) const OPTIONS: Options = Options {
    max_iterations: 200,
    damping: Damping::Factors {
        initial: 1e-4,
        up: 10.0,
        down: 0.1,
        min: 1e-12,
    },
    max_damping: 1e16,
    diagonal_floor: 1e-30,
    cost_floor: f64::NEG_INFINITY,
    gain_tol: 1e-14,
    step_tol: 1e-13,
    // Every parameter is of order one (see above): 1 is where |theta| counts as zero.
    step_offset: 1.0,
    // From exact data without distortion the first step is rounding, but taking it moves
    // k1, k2 off zero, where the centre has no gradient and J^T J would stay singular.
    try_small_steps: true,
};

/// Which lens parameters are fitted with H.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LensParams {
    /// A homography alone (the lens is taken as ideal, or already removed).
    None,
    /// k1 alone.
    K1,
    /// k1 and k2.
    K1K2,
    /// k1, k2 and the distortion centre.
    K1K2Centre,
}

impl LensParams {
    /// Every choice, simplest first.
    pub const ALL: [LensParams; 4] = [
        LensParams::None,
        LensParams::K1,
        LensParams::K1K2,
        LensParams::K1K2Centre,
    ];

    /// Its name, as the bindings and the calibration file spell it.
    pub fn name(self) -> &'static str {
        match self {
            LensParams::None => "none",
            LensParams::K1 => "k1",
            LensParams::K1K2 => "k1k2",
            LensParams::K1K2Centre => "k1k2c",
        }
    }

    /// The choice of that name, if any.
    pub fn from_name(name: &str) -> Option<Self> {
        LensParams::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Number of free parameters, H's 8 included.
    pub fn count(self) -> usize {
        8 + match self {
            LensParams::None => 0,
            LensParams::K1 => 1,
            LensParams::K1K2 => 2,
            LensParams::K1K2Centre => 4,
        }
    }

    /// Zeroes the columns of a Jacobian that belong to fixed parameters.
    pub fn mask(self, j: &mut JacP) {
        for c in 0..P {
            if !self.free(c) {
                j.column_mut(c).fill(0.0);
            }
        }
    }

    /// Whether parameter j (in the layout above) is free.
    fn free(self, j: usize) -> bool {
        j < self.count().min(10) || (self == LensParams::K1K2Centre && j < P)
    }
}

/// A fitted plane: world (mm) -> ideal pixels by `h`, ideal -> real pixels by `lens`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneModel {
    /// World (mm) to ideal pixels.
    pub h: Matrix3<f64>,
    /// Ideal to real pixels.
    pub lens: RadialLens,
}

impl PlaneModel {
    /// The pixel where the lens shows world point w, or None if w is not in front.
    #[inline]
    pub fn world_to_image(&self, w: Point) -> Option<Point> {
        let h = &self.h;
        let z = h[(2, 0)] * w[0] + h[(2, 1)] * w[1] + h[(2, 2)];
        if !(z > 0.0) {
            return None;
        }
        let u = [
            (h[(0, 0)] * w[0] + h[(0, 1)] * w[1] + h[(0, 2)]) / z,
            (h[(1, 0)] * w[0] + h[(1, 1)] * w[1] + h[(1, 2)]) / z,
        ];
        Some(self.lens.distort(u))
    }
}

/// Coordinates the parameters live in, fixed for one problem.
#[derive(Debug, Clone, Copy)]
pub struct Frame {
    pub world: Normalization,
    pub image: Normalization,
    /// The lens centre the offset parameters are measured from, and the lens scale.
    pub centre0: Point,
    pub scale: f64,
}

/// The parameter vector and its frame.
#[derive(Debug, Clone, Copy)]
pub struct Params {
    pub theta: VecP,
    pub frame: Frame,
}

/// A predicted image point with its derivatives by the parameters and by the world point.
pub struct Prediction {
    pub image: Point,
    pub d_theta: JacP,
    pub d_world: Matrix2<f64>,
}

impl Params {
    /// The parameters of a model, in the frame of these points.
    pub fn of_model(model: &PlaneModel, frame: Frame) -> Result<Self, LensError> {
        let hn = frame.image.matrix() * model.h * frame.world.inverse_matrix();
        let h33 = hn[(2, 2)];
        if !(h33.abs() > 1e-12 * hn.norm()) {
            return Err(HomographyError::H33NearZero {
                relative: h33.abs() / hn.norm(),
            }
            .into());
        }
        let hn = hn / h33;
        let mut theta = VecP::zeros();
        for j in 0..8 {
            theta[j] = hn[(j / 3, j % 3)];
        }
        theta[8] = model.lens.k1;
        theta[9] = model.lens.k2;
        theta[10] = (model.lens.centre[0] - frame.centre0[0]) / frame.scale;
        theta[11] = (model.lens.centre[1] - frame.centre0[1]) / frame.scale;
        Ok(Params { theta, frame })
    }

    pub fn lens(&self) -> RadialLens {
        let (t, f) = (&self.theta, &self.frame);
        RadialLens {
            centre: [
                f.centre0[0] + f.scale * t[10],
                f.centre0[1] + f.scale * t[11],
            ],
            scale: f.scale,
            k1: t[8],
            k2: t[9],
        }
    }

    fn hn(&self) -> Matrix3<f64> {
        let t = &self.theta;
        Matrix3::new(t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], 1.0)
    }

    /// The model in pixels and millimetres (H oriented, |h33| = 1 unless negligible).
    pub fn model(&self, world: &[Point]) -> Result<PlaneModel, LensError> {
        let h = self.frame.image.inverse_matrix() * self.hn() * self.frame.world.matrix();
        Ok(PlaneModel {
            h: orient_and_scale(&h, world)?,
            lens: self.lens(),
        })
    }

    /// The image of world point w and its derivatives; None if w is not in front.
    #[inline]
    pub fn predict(&self, w: Point) -> Option<Prediction> {
        let t = &self.theta;
        let f = &self.frame;
        let [x, y] = f.world.apply(&w);
        let den = t[6] * x + t[7] * y + 1.0;
        if !(den > 0.0) {
            return None;
        }
        let iw = 1.0 / den;
        let xn = (t[0] * x + t[1] * y + t[2]) * iw;
        let yn = (t[3] * x + t[4] * y + t[5]) * iw;
        let si = 1.0 / f.image.scale;
        let u = [xn * si + f.image.centre[0], yn * si + f.image.centre[1]];
        let lens = self.lens();
        let s = lens.scale;
        let q = [(u[0] - lens.centre[0]) / s, (u[1] - lens.centre[1]) / s];
        let rho2 = q[0] * q[0] + q[1] * q[1];
        let (fac, dfac) = lens.factor(rho2);
        let image = [
            lens.centre[0] + s * q[0] * fac,
            lens.centre[1] + s * q[1] * fac,
        ];
        // d(image)/d(u) = f I + 2 f' q q^T.
        let a = Matrix2::new(
            fac + 2.0 * dfac * q[0] * q[0],
            2.0 * dfac * q[0] * q[1],
            2.0 * dfac * q[0] * q[1],
            fac + 2.0 * dfac * q[1] * q[1],
        );
        let g = iw * si;
        // d(u)/d(h0..h7), rows x and y.
        let du = SMatrix::<f64, 2, 8>::from_row_slice(&[
            x * g,
            y * g,
            g,
            0.0,
            0.0,
            0.0,
            -xn * x * g,
            -xn * y * g,
            0.0,
            0.0,
            0.0,
            x * g,
            y * g,
            g,
            -yn * x * g,
            -yn * y * g,
        ]);
        let dh = a * du;
        let mut d_theta = JacP::zeros();
        d_theta.fixed_view_mut::<2, 8>(0, 0).copy_from(&dh);
        d_theta[(0, 8)] = s * q[0] * rho2;
        d_theta[(1, 8)] = s * q[1] * rho2;
        d_theta[(0, 9)] = s * q[0] * rho2 * rho2;
        d_theta[(1, 9)] = s * q[1] * rho2 * rho2;
        // d(image)/d(centre offset) = s ((1 - f) I - 2 f' q q^T).
        d_theta[(0, 10)] = s * (1.0 - fac - 2.0 * dfac * q[0] * q[0]);
        d_theta[(1, 10)] = -s * 2.0 * dfac * q[0] * q[1];
        d_theta[(0, 11)] = d_theta[(1, 10)];
        d_theta[(1, 11)] = s * (1.0 - fac - 2.0 * dfac * q[1] * q[1]);
        // d(u)/d(world) through the normalisations.
        let sw = f.world.scale * g;
        let duw = Matrix2::new(
            (t[0] - xn * t[6]) * sw,
            (t[1] - xn * t[7]) * sw,
            (t[3] - yn * t[6]) * sw,
            (t[4] - yn * t[7]) * sw,
        );
        Some(Prediction {
            image,
            d_theta,
            d_world: a * duw,
        })
    }
}

/// The normal equations of the fit at some parameters; the cost is in px^2.
pub type Normal = lm::Normal<P>;

/// Sums J^T J, J^T r and the cost over the points, skipping point `skip`; None when a point
/// falls behind the camera.
pub fn normal_equations(
    params: &Params,
    world: &[Point],
    image: &[Point],
    skip: Option<usize>,
) -> Option<Normal> {
    let mut jtj = MatP::zeros();
    let mut jtr = VecP::zeros();
    let mut cost = 0.0;
    for (i, (w, d)) in world.iter().zip(image).enumerate() {
        if Some(i) == skip {
            continue;
        }
        let p = params.predict(*w)?;
        let r = nalgebra::Vector2::new(p.image[0] - d[0], p.image[1] - d[1]);
        jtj += p.d_theta.transpose() * p.d_theta;
        jtr += p.d_theta.transpose() * r;
        cost += r.norm_squared();
    }
    cost.is_finite().then_some(Normal { jtj, jtr, cost })
}

/// J^T J restricted to the free parameters: fixed ones get an identity row and column.
pub fn masked(jtj: &MatP, free: LensParams) -> MatP {
    let mut m = *jtj;
    for j in 0..P {
        if !free.free(j) {
            m.row_mut(j).fill(0.0);
            m.column_mut(j).fill(0.0);
            m[(j, j)] = 1.0;
        }
    }
    m
}

/// (J^T J)^-1 over the free parameters (zero elsewhere), or None when singular.
pub fn inverse_normal(jtj: &MatP, free: LensParams) -> Option<MatP> {
    // Scaled to unit diagonal first: the parameters' magnitudes differ.
    let m = masked(jtj, free);
    let d = SVector::<f64, P>::from_fn(|j, _| 1.0 / m[(j, j)].max(f64::MIN_POSITIVE).sqrt());
    let scaled = MatP::from_fn(|i, j| m[(i, j)] * d[i] * d[j]);
    let inv = scaled.cholesky()?.inverse();
    let mut out = MatP::from_fn(|i, j| inv[(i, j)] * d[i] * d[j]);
    if !out.iter().all(|v| v.is_finite()) {
        return None;
    }
    // A condition number beyond what the data can resolve is no better than singular.
    let (lo, hi) = scaled
        .symmetric_eigenvalues()
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &e| {
            (lo.min(e), hi.max(e))
        });
    if !(lo > 1e-13 * hi) {
        return None;
    }
    for j in 0..P {
        if !free.free(j) {
            out.row_mut(j).fill(0.0);
            out.column_mut(j).fill(0.0);
        }
    }
    Some(out)
}

/// What a fit found.
#[derive(Debug, Clone, Copy)]
pub struct PlaneFit {
    /// The fitted model.
    pub model: PlaneModel,
    /// Its parameter vector (the layout above).
    pub params: Params,
    /// Which lens parameters were fitted.
    pub free: LensParams,
    /// Levenberg-Marquardt iterations run.
    pub iterations: usize,
    /// Sum of squared residuals, px^2.
    pub cost: f64,
    /// Degrees of freedom of the residuals: 2 n - free parameters.
    pub dof: usize,
    /// (J^T J)^-1 over the free parameters; the covariance is sigma^2 times it.
    pub jtj_inv: MatP,
}

impl PlaneFit {
    /// The residuals' standard deviation per coordinate, px (sqrt(cost / dof)); NaN when
    /// the points leave no residual degrees of freedom (an exactly determined fit).
    pub fn sigma(&self) -> f64 {
        if self.dof == 0 {
            return f64::NAN;
        }
        (self.cost / self.dof as f64).sqrt()
    }

    /// The parameters' covariance: sigma^2 (J^T J)^-1.
    pub fn covariance(&self) -> MatP {
        self.jtj_inv * (self.cost / self.dof as f64)
    }
}

/// The smallest number of points for a model: a homography needs 4; a lens model needs two
/// residuals to spare beyond its parameters, or the fit cannot tell distortion from noise.
pub fn min_points(free: LensParams) -> usize {
    match free {
        LensParams::None => 4,
        _ => (free.count() + 2).div_ceil(2),
    }
}

/// The frame of a problem: Hartley normalisations of both sets, the image's centre and scale.
pub fn frame_of(
    world: &[Point],
    image: &[Point],
    identity: &RadialLens,
) -> Result<Frame, LensError> {
    let c = Correspondences::new(world, image)?;
    identity.validate()?;
    Ok(Frame {
        world: c.src_norm,
        image: c.dst_norm,
        centre0: identity.centre,
        scale: identity.scale,
    })
}

fn check_count(n: usize, free: LensParams) -> Result<(), LensError> {
    let needed = min_points(free);
    if n < needed {
        return Err(LensError::TooFewPoints {
            n,
            model: free.name(),
            params: free.count(),
            needed,
        });
    }
    Ok(())
}

/// Fits H and the free lens parameters to world (mm) -> image (px) points; `image_size` is
/// (width, height), which centres and scales the lens.
pub fn fit_plane(
    world: &[Point],
    image: &[Point],
    free: LensParams,
    image_size: [f64; 2],
) -> Result<PlaneFit, LensError> {
    check_count(world.len(), free)?;
    let identity = RadialLens::identity(image_size[0], image_size[1])?;
    let frame = frame_of(world, image, &identity)?;
    let h = estimate(world, image, Solver::NormalizedDlt, true)?.h;
    let start = Params::of_model(&PlaneModel { h, lens: identity }, frame)?;
    let fit = solve(start, world, image, free, None)?;
    finish(fit, world, free, image_size)
}

/// The fit's figures at given parameters (e.g. a model read back from a file), without
/// refitting.
pub fn plane_fit_at(
    model: &PlaneModel,
    world: &[Point],
    image: &[Point],
    free: LensParams,
    image_size: [f64; 2],
) -> Result<PlaneFit, LensError> {
    check_count(world.len(), free)?;
    model.lens.validate()?;
    let mut identity = RadialLens::identity(image_size[0], image_size[1])?;
    identity.scale = model.lens.scale;
    let frame = frame_of(world, image, &identity)?;
    let params = Params::of_model(model, frame)?;
    let normal =
        normal_equations(&params, world, image, None).ok_or(HomographyError::MixedOrientation {
            index: 0,
            behind: 1,
            total: world.len(),
        })?;
    let jtj_inv =
        inverse_normal(&normal.jtj, free).ok_or(LensError::Undetermined { model: free.name() })?;
    Ok(PlaneFit {
        model: params.model(world)?,
        params,
        free,
        iterations: 0,
        cost: normal.cost,
        dof: 2 * world.len() - free.count(),
        jtj_inv,
    })
}

fn finish(
    fit: Solved,
    world: &[Point],
    free: LensParams,
    image_size: [f64; 2],
) -> Result<PlaneFit, LensError> {
    let lens = fit.params.lens();
    lens.check_invertible(lens.reach(image_size[0], image_size[1]))?;
    let jtj_inv =
        inverse_normal(&fit.jtj, free).ok_or(LensError::Undetermined { model: free.name() })?;
    let n = world.len() - usize::from(fit.skipped.is_some());
    Ok(PlaneFit {
        model: fit.params.model(world)?,
        params: fit.params,
        free,
        iterations: fit.iterations,
        cost: fit.cost,
        dof: 2 * n - free.count(),
        jtj_inv,
    })
}

/// A converged Levenberg-Marquardt run.
pub struct Solved {
    pub params: Params,
    pub cost: f64,
    pub iterations: usize,
    /// J^T J at the solution over the free parameters (`masked`).
    pub jtj: MatP,
    pub skipped: Option<usize>,
}

/// The fit's residuals as `lm` sees them: over the free parameters, without point `skip`.
struct Residuals<'a> {
    frame: Frame,
    world: &'a [Point],
    image: &'a [Point],
    free: LensParams,
    skip: Option<usize>,
}

impl LeastSquares<P> for Residuals<'_> {
    fn normal_equations(&self, theta: &VecP) -> Option<Normal> {
        let params = Params {
            theta: *theta,
            frame: self.frame,
        };
        let n = normal_equations(&params, self.world, self.image, self.skip)?;
        let mut jtr = n.jtr;
        for j in 0..P {
            if !self.free.free(j) {
                jtr[j] = 0.0;
            }
        }
        Some(Normal {
            jtj: masked(&n.jtj, self.free),
            jtr,
            cost: n.cost,
        })
    }
}

/// Levenberg-Marquardt from `start` over the free parameters, without point `skip`.
pub fn solve(
    start: Params,
    world: &[Point],
    image: &[Point],
    free: LensParams,
    skip: Option<usize>,
) -> Result<Solved, LensError> {
    let problem = Residuals {
        frame: start.frame,
        world,
        image,
        free,
        skip,
    };
    let fit =
        lm::minimize(&problem, start.theta, &OPTIONS).ok_or(HomographyError::MixedOrientation {
            index: 0,
            behind: 1,
            total: world.len(),
        })?;
    Ok(Solved {
        params: Params {
            theta: fit.x,
            frame: start.frame,
        },
        cost: fit.at.cost,
        iterations: fit.iterations,
        jtj: fit.at.jtj,
        skipped: skip,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(lens: RadialLens) -> (Vec<Point>, Vec<Point>, PlaneModel) {
        let h = Matrix3::new(2.0, 0.05, 330.0, -0.03, 2.02, 160.0, 2e-5, -3e-5, 1.0);
        let model = PlaneModel { h, lens };
        let mut world = Vec::new();
        for r in 0..10 {
            for c in 0..14 {
                world.push([c as f64 * 20.0, r as f64 * 20.0]);
            }
        }
        let image = world
            .iter()
            .map(|w| model.world_to_image(*w).unwrap())
            .collect();
        (world, image, model)
    }

    fn lens(k1: f64, k2: f64, centre: Point) -> RadialLens {
        RadialLens {
            centre,
            scale: 0.5 * 1280f64.hypot(720.0),
            k1,
            k2,
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let (world, _, model) = scene(lens(-0.06, 0.02, [644.0, 355.0]));
        let frame = frame_of(
            &world,
            &world,
            &RadialLens::identity(1280.0, 720.0).unwrap(),
        )
        .unwrap();
        let p = Params::of_model(&model, frame).unwrap();
        let w = [137.0, 61.0];
        let pred = p.predict(w).unwrap();
        for j in 0..P {
            let eps = 1e-6 * (1.0 + p.theta[j].abs());
            let (mut a, mut b) = (p, p);
            a.theta[j] += eps;
            b.theta[j] -= eps;
            let (ia, ib) = (a.predict(w).unwrap().image, b.predict(w).unwrap().image);
            for k in 0..2 {
                let fd = (ia[k] - ib[k]) / (2.0 * eps);
                let an = pred.d_theta[(k, j)];
                assert!(
                    (fd - an).abs() <= 1e-5 * (1.0 + an.abs()),
                    "param {j}: {fd} vs {an}"
                );
            }
        }
        for k in 0..2 {
            let eps = 1e-5;
            let (mut wa, mut wb) = (w, w);
            wa[k] += eps;
            wb[k] -= eps;
            let (ia, ib) = (p.predict(wa).unwrap().image, p.predict(wb).unwrap().image);
            for r in 0..2 {
                let fd = (ia[r] - ib[r]) / (2.0 * eps);
                assert!((fd - pred.d_world[(r, k)]).abs() < 1e-6 * (1.0 + fd.abs()));
            }
        }
    }

    #[test]
    fn recovers_an_exact_lens_and_homography() {
        let truth = lens(-0.06, 0.02, [650.0, 350.0]);
        let (world, image, model) = scene(truth);
        let fit = fit_plane(&world, &image, LensParams::K1K2Centre, [1280.0, 720.0]).unwrap();
        assert!(fit.cost < 1e-12, "cost {}", fit.cost);
        assert!((fit.model.lens.k1 - truth.k1).abs() < 1e-7);
        assert!((fit.model.lens.k2 - truth.k2).abs() < 1e-6);
        assert!((fit.model.lens.centre[0] - 650.0).abs() < 1e-4);
        let h = fit.model.h / fit.model.h[(2, 2)];
        assert!((h - model.h).norm() < 1e-6 * model.h.norm());
    }

    #[test]
    fn a_homography_alone_cannot_absorb_radial_distortion() {
        let (world, image, _) = scene(lens(-0.06, 0.0, [639.5, 359.5]));
        let plain = fit_plane(&world, &image, LensParams::None, [1280.0, 720.0]).unwrap();
        let k1 = fit_plane(&world, &image, LensParams::K1, [1280.0, 720.0]).unwrap();
        assert!(plain.sigma() > 0.05, "{}", plain.sigma());
        assert!(k1.sigma() < 1e-8, "{}", k1.sigma());
    }

    #[test]
    fn too_few_points_are_refused_by_name() {
        let (world, image, _) = scene(lens(0.0, 0.0, [639.5, 359.5]));
        let e = fit_plane(
            &world[..6],
            &image[..6],
            LensParams::K1K2Centre,
            [1280.0, 720.0],
        );
        assert!(
            matches!(e, Err(LensError::TooFewPoints { needed: 7, .. })),
            "{e:?}"
        );
    }
}
