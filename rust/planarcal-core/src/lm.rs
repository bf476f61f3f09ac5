//! The one Levenberg-Marquardt loop every refiner in the crate runs: `refine` (the
//! homography's transfer error) and `plane_model` (the plane seen through a lens, and its
//! leave-one-out refits). After PoseLib's `lm_impl.h`: the loop is written once, generic over
//! the problem, and a refiner supplies only its normal equations and its options, so a fix
//! to the damping or to a stopping rule reaches every fit.
//!
//! The problem gives J^T J, J^T r and the cost in one call: the refiners accumulate them in
//! one pass over the points, so a cost-only pass for each trial would cost nearly as much as
//! the whole, while rejected trials (the only ones whose J^T J goes unused) are rare from the
//! good starts the refiners have.

use nalgebra::{SMatrix, SVector};

/// The Gauss-Newton normal equations at a point: J^T J, J^T r and the cost sum r^2.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Normal<const N: usize> {
    pub jtj: SMatrix<f64, N, N>,
    pub jtr: SVector<f64, N>,
    pub cost: f64,
}

/// A least-squares problem in N parameters. The parameters add (x + step): every refiner here
/// has Euclidean ones; a rotation would need PoseLib's `step` as well.
pub(crate) trait LeastSquares<const N: usize> {
    /// The normal equations at x; None where the model is undefined there (a point behind
    /// the camera), which the loop treats as a step that failed. A fixed parameter is one
    /// whose row and column of J^T J are the identity's and whose J^T r entry is zero: its
    /// step is then zero.
    fn normal_equations(&self, x: &SVector<f64, N>) -> Option<Normal<N>>;
}

/// How the damping lambda moves.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Damping {
    /// Nielsen's rule (Madsen, Nielsen & Tingleff 2004, eq. 3.14): lambda starts at
    /// `tau` max diag(J^T J), is scaled by max(1/3, 1 - (2 rho - 1)^3) after a step that lowers
    /// the cost (rho: the actual over the predicted decrease) and grows 2, 4, 8 ... fold after
    /// each failure. It follows how well the quadratic model predicts, so it wastes few trials.
    Nielsen { tau: f64 },
    /// Fixed factors (Marquardt 1963): lambda starts at `initial`, is multiplied by `up` after
    /// a failure and by `down` (not below `min`) after a step that lowers the cost.
    Factors {
        initial: f64,
        up: f64,
        down: f64,
        min: f64,
    },
}

/// The loop's settings; each refiner keeps its own (see its `OPTIONS`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Options {
    /// Linearisations at most.
    pub max_iterations: usize,
    pub damping: Damping,
    /// Once lambda reaches this, no step lowers the cost: x is the minimum to rounding.
    pub max_damping: f64,
    /// The damping is lambda diag(J^T J) (Marquardt), so each parameter is damped in its own
    /// units; this floor on the diagonal keeps a parameter the data barely touch damped.
    pub diagonal_floor: f64,
    /// Stop before an iteration once the cost is at or below this: for exact data the rest is
    /// rounding. `f64::NEG_INFINITY` never stops here.
    pub cost_floor: f64,
    /// Converged when a step lowers the cost by at most this fraction of it.
    pub gain_tol: f64,
    /// Converged when a step is at most `step_tol` (|x| + `step_offset`): it would change x
    /// only by rounding.
    pub step_tol: f64,
    /// See `step_tol`: the size below which |x| counts as zero.
    pub step_offset: f64,
    /// Whether such a step is tried first, and the loop stops only once one lowers the cost
    /// (a failed one is damped like any other). That costs evaluations at the end, but moves
    /// x off a point where a parameter has no gradient yet (the distortion centre when
    /// k1 = k2 = 0 exactly), which would otherwise stay singular. False: stop before it.
    pub try_small_steps: bool,
}

/// Why the loop stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Stop {
    /// The cost is at or below `cost_floor`.
    CostFloor,
    /// A step lowered the cost by at most `gain_tol` of it.
    SmallGain,
    /// The step was within `step_tol`.
    SmallStep,
    /// lambda reached `max_damping` without a step that lowers the cost.
    NoDescent,
    /// `max_iterations` ran.
    MaxIterations,
}

/// What the loop found.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Summary<const N: usize> {
    /// The parameters reached: never costlier than the start.
    pub x: SVector<f64, N>,
    /// The normal equations at `x` (its cost among them).
    pub at: Normal<N>,
    /// The cost at the start.
    pub initial_cost: f64,
    /// Linearisations run (each may try several lambdas).
    pub iterations: usize,
    /// Read by the tests; kept for diagnosis, as no refiner reports it yet.
    #[cfg_attr(not(test), allow(dead_code))]
    pub stop: Stop,
}

/// lambda and Nielsen's growth factor nu.
struct Lambda {
    value: f64,
    nu: f64,
}

impl Lambda {
    /// After a failed step: false once lambda has reached `max_damping` (or is NaN).
    fn grow(&mut self, o: &Options) -> bool {
        match o.damping {
            Damping::Nielsen { .. } => {
                self.value *= self.nu;
                self.nu *= 2.0;
            }
            Damping::Factors { up, .. } => self.value *= up,
        }
        self.value < o.max_damping
    }

    /// After a step that lowered the cost by `gain` where the damped model predicted
    /// `predicted`.
    fn shrink(&mut self, o: &Options, gain: f64, predicted: f64) {
        match o.damping {
            Damping::Nielsen { .. } => {
                let rho = gain / predicted.max(f64::MIN_POSITIVE);
                self.value *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                self.nu = 2.0;
            }
            Damping::Factors { down, min, .. } => self.value = (self.value * down).max(min),
        }
    }
}

/// Minimises the problem's cost from `x0`; None when it cannot be evaluated at `x0`.
pub(crate) fn minimize<P: LeastSquares<N>, const N: usize>(
    problem: &P,
    x0: SVector<f64, N>,
    o: &Options,
) -> Option<Summary<N>> {
    let mut x = x0;
    let mut cur = problem.normal_equations(&x)?;
    let initial_cost = cur.cost;
    let mut lambda = Lambda {
        value: match o.damping {
            Damping::Nielsen { tau } => tau * (0..N).map(|k| cur.jtj[(k, k)]).fold(0.0, f64::max),
            Damping::Factors { initial, .. } => initial,
        },
        nu: 2.0,
    };
    let mut iterations = 0;
    let stop = 'outer: loop {
        if iterations >= o.max_iterations {
            break Stop::MaxIterations;
        }
        if !(cur.cost > o.cost_floor) {
            break Stop::CostFloor;
        }
        iterations += 1;
        // Damped solves at this linearisation until one lowers the cost.
        loop {
            let mut a = cur.jtj;
            let mut damping = SVector::<f64, N>::zeros();
            for k in 0..N {
                damping[k] = lambda.value * cur.jtj[(k, k)].max(o.diagonal_floor);
                a[(k, k)] += damping[k];
            }
            let Some(chol) = a.cholesky() else {
                if !lambda.grow(o) {
                    break 'outer Stop::NoDescent;
                }
                continue;
            };
            let step = chol.solve(&(-cur.jtr));
            let small = step.norm() <= o.step_tol * (x.norm() + o.step_offset);
            if small && !o.try_small_steps {
                break 'outer Stop::SmallStep;
            }
            let trial_x = x + step;
            match problem.normal_equations(&trial_x) {
                // `<` is false for a NaN or infinite trial cost, which fails like any other.
                Some(trial) if trial.cost < cur.cost => {
                    let gain = cur.cost - trial.cost;
                    // The decrease of the (doubled) cost the damped model predicts.
                    let predicted = step.dot(&(step.component_mul(&damping) - cur.jtr));
                    lambda.shrink(o, gain, predicted);
                    let converged = gain <= o.gain_tol * cur.cost;
                    x = trial_x;
                    cur = trial;
                    if converged {
                        break 'outer Stop::SmallGain;
                    }
                    if small {
                        break 'outer Stop::SmallStep;
                    }
                    break;
                }
                _ => {
                    if !lambda.grow(o) {
                        break 'outer Stop::NoDescent;
                    }
                }
            }
        }
    };
    Some(Summary {
        x,
        at: cur,
        initial_cost,
        iterations,
        stop,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};

    /// Rosenbrock's valley as least squares: r = (10 (y - x^2), 1 - x), minimum 0 at (1, 1).
    struct Rosenbrock;

    impl LeastSquares<2> for Rosenbrock {
        fn normal_equations(&self, p: &Vector2<f64>) -> Option<Normal<2>> {
            let r = Vector2::new(10.0 * (p[1] - p[0] * p[0]), 1.0 - p[0]);
            let j = Matrix2::new(-20.0 * p[0], 10.0, -1.0, 0.0);
            Some(Normal {
                jtj: j.transpose() * j,
                jtr: j.transpose() * r,
                cost: r.norm_squared(),
            })
        }
    }

    const OPTIONS: Options = Options {
        max_iterations: 100,
        damping: Damping::Factors {
            initial: 1e-3,
            up: 10.0,
            down: 0.1,
            min: 1e-12,
        },
        max_damping: 1e16,
        diagonal_floor: 1e-30,
        cost_floor: f64::NEG_INFINITY,
        gain_tol: 1e-14,
        step_tol: 1e-13,
        step_offset: 1.0,
        try_small_steps: false,
    };

    #[test]
    fn both_dampings_find_the_valley_floor() {
        for damping in [OPTIONS.damping, Damping::Nielsen { tau: 1e-3 }] {
            let o = Options { damping, ..OPTIONS };
            let s = minimize(&Rosenbrock, Vector2::new(-1.2, 1.0), &o).unwrap();
            assert!(
                (s.x - Vector2::new(1.0, 1.0)).norm() < 1e-7,
                "{damping:?}: {s:?}"
            );
            assert!(s.at.cost < 1e-14 && s.at.cost < s.initial_cost);
            assert!(s.iterations < o.max_iterations);
            assert_ne!(s.stop, Stop::MaxIterations);
        }
    }

    #[test]
    fn each_stopping_rule_is_reported() {
        let start = Vector2::new(-1.2, 1.0);
        let capped = Options {
            max_iterations: 3,
            ..OPTIONS
        };
        let s = minimize(&Rosenbrock, start, &capped).unwrap();
        assert_eq!((s.stop, s.iterations), (Stop::MaxIterations, 3));
        let floor = Options {
            cost_floor: 1e3,
            ..OPTIONS
        };
        let s = minimize(&Rosenbrock, start, &floor).unwrap();
        assert_eq!((s.stop, s.iterations), (Stop::CostFloor, 0));
        assert_eq!(s.x, start);
        // At the minimum the step is zero: not taken, or tried and failed until lambda is spent.
        let s = minimize(&Rosenbrock, Vector2::new(1.0, 1.0), &OPTIONS).unwrap();
        assert_eq!((s.stop, s.iterations), (Stop::SmallStep, 1));
        let tried = Options {
            try_small_steps: true,
            ..OPTIONS
        };
        let s = minimize(&Rosenbrock, Vector2::new(1.0, 1.0), &tried).unwrap();
        assert_eq!((s.stop, s.iterations), (Stop::NoDescent, 1));
    }

    /// Undefined everywhere but the start: every step fails.
    struct Cliff;

    impl LeastSquares<1> for Cliff {
        fn normal_equations(&self, x: &SVector<f64, 1>) -> Option<Normal<1>> {
            (x[0] == 0.0).then(|| Normal {
                jtj: SMatrix::<f64, 1, 1>::new(1.0),
                jtr: SVector::<f64, 1>::new(-1.0),
                cost: 1.0,
            })
        }
    }

    #[test]
    fn a_start_no_step_improves_comes_back_unchanged() {
        for damping in [OPTIONS.damping, Damping::Nielsen { tau: 1e-6 }] {
            // No step test: it would stop the loop once lambda makes the steps tiny.
            let o = Options {
                damping,
                step_tol: 0.0,
                ..OPTIONS
            };
            let s = minimize(&Cliff, SVector::<f64, 1>::zeros(), &o).unwrap();
            assert_eq!((s.stop, s.iterations, s.x[0]), (Stop::NoDescent, 1, 0.0));
            assert_eq!(s.at.cost, s.initial_cost);
        }
        assert!(minimize(&Cliff, SVector::<f64, 1>::new(1.0), &OPTIONS).is_none());
    }
}
