//! One plane seen through one lens, calibrated from several placements of a board: the board
//! laid at K places on the plane, each seen in its own image (or several boards in one). Each
//! placement's board frame sits in the plane's at an unknown rotation and translation (its
//! `Pose`); the reference placement's frame is the plane's. The fit is
//!     min over theta, poses  sum_i || image_i - distort(H (R_k(i) board_i + t_k(i))) ||^2,
//! with theta the `plane_model` parameters (H and the lens), so every placement's points
//! constrain the lens where they lie.
//!
//! The poses are solved inside each evaluation (variable projection): for a given theta each
//! pose is an independent 3-parameter Gauss-Newton problem, and the loop over theta (the one
//! `lm` loop) sees the reduced normal equations, the Schur complement
//!     S = A - sum_k B_k D_k^-1 B_k^T
//! of the poses' blocks. S^-1 is theta's covariance with the poses' uncertainty included (the
//! marginal, not the conditional), which is what a pixel far from every placement needs: its
//! error carries how well the placements are tied to the reference.

use nalgebra::{Matrix3, SMatrix, Vector2, Vector3};

use crate::error::HomographyError;
use crate::estimate::{estimate, Solver};
use crate::lens::{LensError, RadialLens};
use crate::lm::{self, LeastSquares};
use crate::plane_model::{
    frame_of, inverse_normal, masked, min_points, Frame, LensParams, MatP, Normal, Params,
    PlaneFit, PlaneModel, VecP, OPTIONS, P,
};
use crate::Point;

/// Where a placement's board lies in the plane: plane = R(angle) board + offset (mm, rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// The board's x axis from the plane's, radians (counter-clockwise from x to y).
    pub angle: f64,
    /// Where the board's origin lies in the plane, mm.
    pub offset: Point,
}

type Jac3 = SMatrix<f64, 2, 3>;
type Blocks = SMatrix<f64, P, 3>;

impl Pose {
    /// The reference's pose: the board's frame is the plane's.
    pub const IDENTITY: Pose = Pose {
        angle: 0.0,
        offset: [0.0, 0.0],
    };

    /// The plane point of board point b.
    #[inline]
    pub fn apply(&self, b: Point) -> Point {
        let (s, c) = self.angle.sin_cos();
        [
            c * b[0] - s * b[1] + self.offset[0],
            s * b[0] + c * b[1] + self.offset[1],
        ]
    }

    /// d(plane point)/d(angle, offset x, offset y) at board point b.
    #[inline]
    fn derivative(&self, b: Point) -> Jac3 {
        let (s, c) = self.angle.sin_cos();
        Jac3::new(
            -s * b[0] - c * b[1],
            1.0,
            0.0,
            c * b[0] - s * b[1],
            0.0,
            1.0,
        )
    }

    fn stepped(&self, d: &Vector3<f64>) -> Pose {
        Pose {
            angle: self.angle + d[0],
            offset: [self.offset[0] + d[1], self.offset[1] + d[2]],
        }
    }
}

/// The points of a placements problem: each board point (mm, in its board's frame), its
/// pixel, and the placement it belongs to (0 .. count).
#[derive(Debug, Clone, Copy)]
pub struct Placed<'a> {
    /// Each point in its board's frame, mm.
    pub board: &'a [Point],
    /// Each point's pixel.
    pub image: &'a [Point],
    /// Each point's placement.
    pub placement: &'a [usize],
    /// How many placements.
    pub count: usize,
    /// The placement whose board frame is the plane's (its pose is the identity).
    pub reference: usize,
}

impl Placed<'_> {
    fn plane_points(&self, poses: &[Pose]) -> Vec<Point> {
        self.board
            .iter()
            .zip(self.placement)
            .map(|(b, &k)| poses[k].apply(*b))
            .collect()
    }
}

/// What a placements fit found.
#[derive(Debug, Clone)]
pub struct PlacementsFit {
    /// The plane's model on the points in the plane's frame, its covariance the marginal one
    /// (the poses' uncertainty included) and its degrees of freedom net of the poses'.
    pub fit: PlaneFit,
    /// Each placement's pose (the reference's the identity).
    pub poses: Vec<Pose>,
    /// Each pose's covariance (angle rad, offset mm), sigma^2 scaled; zero for the reference.
    pub pose_covariance: Vec<Matrix3<f64>>,
    /// Every board point in the plane's frame.
    pub plane_points: Vec<Point>,
}

/// The sums over one placement's points at theta and its pose.
struct PlacementSums {
    /// Its points' share of theta's block, J_theta^T J_theta.
    a: MatP,
    b: Blocks,
    d: Matrix3<f64>,
    g: Vector3<f64>,
    /// Its points' sum of squared residuals, px^2, and how many they are.
    cost: f64,
    n: usize,
}

/// The whole problem's sums: theta's block, each placement's, the cost.
struct Sums {
    a: MatP,
    g: VecP,
    placements: Vec<PlacementSums>,
    cost: f64,
}

struct Problem<'a> {
    frame: Frame,
    placed: Placed<'a>,
    start: Vec<Pose>,
    free: LensParams,
}

const POSE_ITERATIONS: usize = 50;

impl Problem<'_> {
    /// J^T J, J^T r and the cost at theta and the poses; None when a point falls behind.
    fn sums(&self, params: &Params, poses: &[Pose]) -> Option<Sums> {
        let p = &self.placed;
        let mut s = Sums {
            a: MatP::zeros(),
            g: VecP::zeros(),
            placements: (0..p.count)
                .map(|_| PlacementSums {
                    a: MatP::zeros(),
                    b: Blocks::zeros(),
                    d: Matrix3::zeros(),
                    g: Vector3::zeros(),
                    cost: 0.0,
                    n: 0,
                })
                .collect(),
            cost: 0.0,
        };
        for ((b, d), &k) in p.board.iter().zip(p.image).zip(p.placement) {
            let pose = &poses[k];
            let mut pred = params.predict(pose.apply(*b))?;
            self.free.mask(&mut pred.d_theta);
            let r = Vector2::new(pred.image[0] - d[0], pred.image[1] - d[1]);
            let jt = &pred.d_theta;
            let jtj = jt.transpose() * jt;
            s.a += jtj;
            s.g += jt.transpose() * r;
            s.cost += r.norm_squared();
            let ps = &mut s.placements[k];
            ps.a += jtj;
            ps.cost += r.norm_squared();
            ps.n += 1;
            if k != p.reference {
                let jp = pred.d_world * pose.derivative(*b);
                ps.b += jt.transpose() * jp;
                ps.d += jp.transpose() * jp;
                ps.g += jp.transpose() * r;
            }
        }
        s.cost.is_finite().then_some(s)
    }

    /// One placement's cost and normal equations at theta and its pose.
    fn placement_sums(
        &self,
        params: &Params,
        k: usize,
        pose: &Pose,
    ) -> Option<(f64, Matrix3<f64>, Vector3<f64>)> {
        let p = &self.placed;
        let (mut cost, mut d, mut g) = (0.0, Matrix3::zeros(), Vector3::zeros());
        for ((b, px), _) in p
            .board
            .iter()
            .zip(p.image)
            .zip(p.placement)
            .filter(|(_, &j)| j == k)
        {
            let pred = params.predict(pose.apply(*b))?;
            let r = Vector2::new(pred.image[0] - px[0], pred.image[1] - px[1]);
            let jp: Jac3 = pred.d_world * pose.derivative(*b);
            cost += r.norm_squared();
            d += jp.transpose() * jp;
            g += jp.transpose() * r;
        }
        cost.is_finite().then_some((cost, d, g))
    }

    /// Each pose that best fits theta, by Gauss-Newton from the start (halving a step that
    /// does not lower the cost); None when a placement cannot be evaluated.
    fn poses_at(&self, params: &Params) -> Option<Vec<Pose>> {
        let mut poses = self.start.clone();
        for (k, pose) in poses.iter_mut().enumerate() {
            if k == self.placed.reference {
                *pose = Pose::IDENTITY;
                continue;
            }
            let (mut cost, mut d, mut g) = self.placement_sums(params, k, pose)?;
            for _ in 0..POSE_ITERATIONS {
                let Some(step) = d.cholesky().map(|c| -c.solve(&g)) else {
                    break;
                };
                let mut t = 1.0;
                let mut taken = false;
                while t > 1e-6 {
                    let trial = pose.stepped(&(step * t));
                    if let Some((c, dt, gt)) = self.placement_sums(params, k, &trial) {
                        if c <= cost {
                            let small = (cost - c) <= 1e-15 * cost
                                || (step * t).abs().max()
                                    <= 1e-13
                                        * (1.0 + trial.offset[0].abs() + trial.offset[1].abs());
                            (*pose, cost, d, g) = (trial, c, dt, gt);
                            taken = !small;
                            break;
                        }
                    }
                    t *= 0.5;
                }
                if !taken {
                    break;
                }
            }
        }
        Some(poses)
    }

    /// The reduced normal equations (the poses eliminated) at theta and its best poses.
    fn reduced(&self, params: &Params, poses: &[Pose]) -> Option<(Normal, Sums)> {
        let s = self.sums(params, poses)?;
        let mut jtj = s.a;
        let mut jtr = s.g;
        for ps in &s.placements {
            let Some(inv) = ps.d.try_inverse() else {
                continue; // the reference, or a placement with nothing to fix it (refused earlier)
            };
            jtj -= ps.b * inv * ps.b.transpose();
            jtr -= ps.b * inv * ps.g;
        }
        for j in 0..P {
            if jtj.row(j).iter().all(|v| *v == 0.0) {
                jtr[j] = 0.0;
            }
        }
        Some((
            Normal {
                jtj: masked(&jtj, self.free),
                jtr,
                cost: s.cost,
            },
            s,
        ))
    }
}

impl LeastSquares<P> for Problem<'_> {
    fn normal_equations(&self, theta: &VecP) -> Option<Normal> {
        let params = Params {
            theta: *theta,
            frame: self.frame,
        };
        let poses = self.poses_at(&params)?;
        self.reduced(&params, &poses).map(|(n, _)| n)
    }
}

fn behind(total: usize) -> LensError {
    HomographyError::MixedOrientation {
        index: 0,
        behind: 1,
        total,
    }
    .into()
}

fn check(placed: &Placed<'_>, poses: usize, free: LensParams) -> Result<(), LensError> {
    let n = placed.board.len();
    let ok = placed.image.len() == n
        && placed.placement.len() == n
        && poses == placed.count
        && placed.reference < placed.count
        && placed.placement.iter().all(|&k| k < placed.count);
    if !ok {
        return Err(LensError::InvalidLens {
            what: "one placement per point, each below the placements' count",
            value: n as f64,
        });
    }
    // Each placement needs enough points to fix its pose beyond the shared model's.
    let needed = min_points(free) + 2 * (placed.count - 1);
    if n < needed {
        return Err(LensError::TooFewPoints {
            n,
            model: free.name(),
            params: free.count() + 3 * (placed.count - 1),
            needed,
        });
    }
    Ok(())
}

/// Fits H, the free lens parameters and every placement's pose, from `start` poses (the
/// reference's is ignored); `image_size` centres and scales the lens.
pub fn fit_placements(
    placed: Placed<'_>,
    start: &[Pose],
    free: LensParams,
    image_size: [f64; 2],
) -> Result<PlacementsFit, LensError> {
    check(&placed, start.len(), free)?;
    let mut start = start.to_vec();
    start[placed.reference] = Pose::IDENTITY;
    let plane = placed.plane_points(&start);
    let identity = RadialLens::identity(image_size[0], image_size[1])?;
    let frame = frame_of(&plane, placed.image, &identity)?;
    let h = estimate(&plane, placed.image, Solver::NormalizedDlt, true)?.h;
    let theta = Params::of_model(&PlaneModel { h, lens: identity }, frame)?.theta;
    let problem = Problem {
        frame,
        placed,
        start,
        free,
    };
    let solved = lm::minimize(&problem, theta, &OPTIONS).ok_or(behind(placed.board.len()))?;
    let params = Params {
        theta: solved.x,
        frame,
    };
    let lens = params.lens();
    lens.check_invertible(lens.reach(image_size[0], image_size[1]))?;
    let poses = problem
        .poses_at(&params)
        .ok_or(behind(placed.board.len()))?;
    finish(&problem, params, &poses, solved.iterations)
}

/// The fit's figures at given parameters and poses (read back from a file), without refitting.
pub fn placements_fit_at(
    model: &PlaneModel,
    poses: &[Pose],
    placed: Placed<'_>,
    free: LensParams,
    image_size: [f64; 2],
) -> Result<PlacementsFit, LensError> {
    check(&placed, poses.len(), free)?;
    model.lens.validate()?;
    let plane = placed.plane_points(poses);
    let mut identity = RadialLens::identity(image_size[0], image_size[1])?;
    identity.scale = model.lens.scale;
    let frame = frame_of(&plane, placed.image, &identity)?;
    let params = Params::of_model(model, frame)?;
    let problem = Problem {
        frame,
        placed,
        start: poses.to_vec(),
        free,
    };
    finish(&problem, params, poses, 0)
}

/// (J^T J)^-1 scaled so that sigma2 times it is theta's covariance when each placement has
/// its own noise (its residuals' variance): placements are separate images, and one seen
/// worse (blur, light, a board less flat) weighs on the mapping more than the pooled noise
/// says, most of all the reference, which fixes the frame. The sandwich
///     S^-1 (sum_k sigma_k^2 S_k) S^-1,  S_k = A_k - B_k D_k^-1 B_k^T,  S = sum_k S_k,
/// each placement's share of the reduced normal matrix weighted by its own variance (with
/// equal variances it is sigma^2 S^-1). sigma_k^2: its cost over its degrees of freedom, its
/// pose's 3 and its share of theta's parameters taken out.
fn placement_noise_covariance(
    sums: &Sums,
    placed: &Placed<'_>,
    free: LensParams,
    s_inv: &MatP,
    sigma2: f64,
) -> MatP {
    if !(sigma2 > 0.0) {
        return *s_inv;
    }
    let n = placed.board.len() as f64;
    let mut meat = MatP::zeros();
    for (k, ps) in sums.placements.iter().enumerate() {
        let mut share = ps.a;
        if k != placed.reference {
            if let Some(inv) = ps.d.try_inverse() {
                share -= ps.b * inv * ps.b.transpose();
            }
        }
        let pose = if k == placed.reference { 0.0 } else { 3.0 };
        let dof = 2.0 * ps.n as f64 - pose - free.count() as f64 * ps.n as f64 / n;
        let variance = if dof >= 1.0 { ps.cost / dof } else { sigma2 };
        meat += share * variance;
    }
    let cov = s_inv * meat * s_inv;
    if cov.iter().all(|v| v.is_finite()) {
        cov / sigma2
    } else {
        *s_inv
    }
}

fn finish(
    problem: &Problem<'_>,
    params: Params,
    poses: &[Pose],
    iterations: usize,
) -> Result<PlacementsFit, LensError> {
    let placed = &problem.placed;
    let free = problem.free;
    let undetermined = || LensError::Undetermined { model: free.name() };
    let (normal, sums) = problem
        .reduced(&params, poses)
        .ok_or(behind(placed.board.len()))?;
    // Every placement but the reference must fix its pose.
    for (k, ps) in sums.placements.iter().enumerate() {
        if k != placed.reference && ps.d.try_inverse().is_none() {
            return Err(undetermined());
        }
    }
    let s_inv = inverse_normal(&normal.jtj, free).ok_or_else(undetermined)?;
    let n = placed.board.len();
    let dof = 2 * n - free.count() - 3 * (placed.count - 1);
    let sigma2 = if dof == 0 {
        0.0
    } else {
        normal.cost / dof as f64
    };
    let jtj_inv = placement_noise_covariance(&sums, placed, free, &s_inv, sigma2);
    let pose_covariance = sums
        .placements
        .iter()
        .enumerate()
        .map(|(k, ps)| {
            if k == placed.reference {
                return Matrix3::zeros();
            }
            let inv = ps.d.try_inverse().unwrap_or_else(Matrix3::zeros);
            (inv + inv * ps.b.transpose() * s_inv * ps.b * inv) * sigma2
        })
        .collect();
    let plane_points = placed.plane_points(poses);
    let model = params.model(&plane_points)?;
    Ok(PlacementsFit {
        fit: PlaneFit {
            model,
            params,
            free,
            iterations,
            cost: normal.cost,
            dof,
            jtj_inv,
        },
        poses: poses.to_vec(),
        pose_covariance,
        plane_points,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plane_model::fit_plane;
    use crate::uncertainty::world_covariance;

    fn board() -> Vec<Point> {
        let mut out = Vec::new();
        for r in 0..7 {
            for c in 0..9 {
                out.push([c as f64 * 20.0, r as f64 * 20.0]);
            }
        }
        out
    }

    fn truth_model() -> PlaneModel {
        // About 2 px/mm over a 480 x 360 mm area seen at 1280 x 960, with barrel distortion.
        let h = Matrix3::new(2.1, 0.04, 140.0, -0.03, 2.08, 120.0, 1e-5, -2e-5, 1.0);
        let lens = RadialLens {
            centre: [642.0, 476.0],
            scale: 0.5 * 1280f64.hypot(960.0),
            k1: -0.08,
            k2: 0.01,
        };
        PlaneModel { h, lens }
    }

    fn poses() -> Vec<Pose> {
        vec![
            Pose::IDENTITY,
            Pose {
                angle: 0.05,
                offset: [300.0, 10.0],
            },
            Pose {
                angle: -0.1,
                offset: [20.0, 200.0],
            },
            Pose {
                angle: 1.6,
                offset: [460.0, 190.0],
            },
        ]
    }

    struct Scene {
        board: Vec<Point>,
        image: Vec<Point>,
        placement: Vec<usize>,
    }

    fn scene(noise: f64, seed: u64) -> Scene {
        scene_with(&[noise; 4], seed)
    }

    /// Each placement's points with its own pixel noise (1-sigma per coordinate).
    fn scene_with(noise: &[f64; 4], seed: u64) -> Scene {
        let model = truth_model();
        let mut state = seed
            .wrapping_mul(2862933555777941757)
            .wrapping_add(3037000493);
        let mut gauss = || {
            // Sum of 12 uniforms: about normal, unit variance.
            (0..12)
                .map(|_| {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (state >> 11) as f64 / (1u64 << 53) as f64
                })
                .sum::<f64>()
                - 6.0
        };
        let (mut b, mut im, mut pl) = (Vec::new(), Vec::new(), Vec::new());
        for (k, pose) in poses().iter().enumerate() {
            for p in board() {
                let d = model.world_to_image(pose.apply(p)).unwrap();
                b.push(p);
                im.push([d[0] + noise[k] * gauss(), d[1] + noise[k] * gauss()]);
                pl.push(k);
            }
        }
        Scene {
            board: b,
            image: im,
            placement: pl,
        }
    }

    fn rough_start() -> Vec<Pose> {
        poses()
            .iter()
            .map(|p| Pose {
                angle: p.angle + 0.02,
                offset: [p.offset[0] + 4.0, p.offset[1] - 3.0],
            })
            .collect()
    }

    fn placed(s: &Scene) -> Placed<'_> {
        Placed {
            board: &s.board,
            image: &s.image,
            placement: &s.placement,
            count: 4,
            reference: 0,
        }
    }

    #[test]
    fn recovers_the_lens_the_homography_and_every_pose_from_exact_points() {
        let s = scene(0.0, 1);
        let fit = fit_placements(
            placed(&s),
            &rough_start(),
            LensParams::K1K2Centre,
            [1280.0, 960.0],
        )
        .unwrap();
        assert!(fit.fit.cost < 1e-12, "cost {}", fit.fit.cost);
        for (got, want) in fit.poses.iter().zip(poses()) {
            assert!((got.angle - want.angle).abs() < 1e-9, "{got:?} {want:?}");
            assert!((got.offset[0] - want.offset[0]).abs() < 1e-6);
            assert!((got.offset[1] - want.offset[1]).abs() < 1e-6);
        }
        let truth = truth_model();
        assert!((fit.fit.model.lens.k1 - truth.lens.k1).abs() < 1e-8);
        let h = fit.fit.model.h / fit.fit.model.h[(2, 2)];
        assert!((h - truth.h).norm() < 1e-7 * truth.h.norm());
        assert_eq!(fit.fit.dof, 2 * s.board.len() - 12 - 9);
    }

    #[test]
    fn the_marginal_covariance_is_wider_than_the_one_with_the_poses_known() {
        // The same points fitted as one board with their true plane positions (poses known):
        // the placements fit must be less certain, most of all far from the reference.
        let s = scene(0.05, 2);
        let fit =
            fit_placements(placed(&s), &rough_start(), LensParams::K1, [1280.0, 960.0]).unwrap();
        let known =
            fit_plane(&fit.plane_points, &s.image, LensParams::K1, [1280.0, 960.0]).unwrap();
        let far = [470.0, 330.0];
        let near = [80.0, 60.0];
        let joint_far = world_covariance(&fit.fit, far, 0.0).unwrap().trace();
        let known_far = world_covariance(&known, far, 0.0).unwrap().trace();
        let joint_near = world_covariance(&fit.fit, near, 0.0).unwrap().trace();
        assert!(joint_far > 1.5 * known_far, "{joint_far} {known_far}");
        assert!(joint_far > joint_near);
        assert!(fit.pose_covariance[0] == Matrix3::zeros());
        assert!(fit.pose_covariance[3][(1, 1)] > 0.0);
    }

    /// RMS actual / RMS predicted 1-sigma of the mapping at plane point `at`, over 60 noise
    /// draws with each placement's pixel noise `noise`.
    fn honesty_at(at: Point, noise: &[f64; 4], first_seed: u64) -> f64 {
        let truth_px = truth_model().world_to_image(at).unwrap();
        let (mut err2, mut pred2) = (0.0, 0.0);
        for seed in first_seed..first_seed + 60 {
            let s = scene_with(noise, seed);
            let fit = fit_placements(
                placed(&s),
                &rough_start(),
                LensParams::K1K2Centre,
                [1280.0, 960.0],
            )
            .unwrap();
            let inv = crate::uncertainty::InversePlane::new(&fit.fit.model).unwrap();
            let got = inv.map(truth_px).unwrap();
            err2 += (got[0] - at[0]).powi(2) + (got[1] - at[1]).powi(2);
            pred2 += world_covariance(&fit.fit, got, 0.0).unwrap().trace();
        }
        (err2 / pred2).sqrt()
    }

    #[test]
    fn the_predicted_error_is_honest_far_from_the_reference() {
        let ratio = honesty_at([470.0, 330.0], &[0.1; 4], 100);
        assert!((0.75..1.33).contains(&ratio), "actual / predicted {ratio}");
    }

    #[test]
    fn a_reference_seen_worse_than_the_others_widens_the_error_bars_honestly() {
        // The reference ten times as noisy as the others (a blurred image): the pooled noise
        // would understate the error where it lies by about half; each placement's own
        // noise, weighted into the covariance, does not.
        let ratio = honesty_at([80.0, 60.0], &[0.3, 0.03, 0.03, 0.03], 300);
        assert!((0.75..1.33).contains(&ratio), "actual / predicted {ratio}");
    }

    #[test]
    fn a_fit_read_back_has_the_same_figures() {
        let s = scene(0.05, 3);
        let fit = fit_placements(
            placed(&s),
            &rough_start(),
            LensParams::K1K2,
            [1280.0, 960.0],
        )
        .unwrap();
        let again = placements_fit_at(
            &fit.fit.model,
            &fit.poses,
            placed(&s),
            LensParams::K1K2,
            [1280.0, 960.0],
        )
        .unwrap();
        assert!((again.fit.cost - fit.fit.cost).abs() < 1e-9 * fit.fit.cost);
        // The parameters' frames differ (each from its own start): compare in the plane.
        for w in [[80.0, 60.0], [470.0, 330.0]] {
            let a = world_covariance(&fit.fit, w, 0.0).unwrap();
            let b = world_covariance(&again.fit, w, 0.0).unwrap();
            assert!((a - b).norm() < 1e-6 * a.norm(), "{a} {b}");
        }
        for (a, b) in fit.pose_covariance.iter().zip(&again.pose_covariance) {
            assert!((a - b).norm() <= 1e-6 * a.norm(), "{a} {b}");
        }
    }

    #[test]
    fn too_few_points_and_bad_indices_are_refused() {
        let s = scene(0.0, 4);
        let mut bad = placed(&s);
        bad.reference = 4;
        assert!(matches!(
            fit_placements(bad, &poses(), LensParams::K1, [1280.0, 960.0]),
            Err(LensError::InvalidLens { .. })
        ));
        let few = Placed {
            board: &s.board[..3],
            image: &s.image[..3],
            placement: &s.placement[..3],
            count: 1,
            reference: 0,
        };
        assert!(matches!(
            fit_placements(few, &poses()[..1], LensParams::K1, [1280.0, 960.0]),
            Err(LensError::TooFewPoints { .. })
        ));
    }
}
