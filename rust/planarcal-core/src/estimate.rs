//! The entry point: validate, solve with the chosen linear solver, optionally refine by
//! Levenberg-Marquardt, check the result is a usable homography, orient and scale it.

use std::fmt;
use std::str::FromStr;

use nalgebra::Matrix3;

use crate::a33::{a33_least_squares, check_h33};
use crate::correspondences::Correspondences;
use crate::dlt::{normalized_dlt, plain_dlt};
use crate::error::{HomographyError, Result};
use crate::orientation::{frobenius, orient_and_scale};
use crate::refine::{levenberg_marquardt, RefineReport};
use crate::Point;

/// The linear solvers, by the names the Python API uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Solver {
    /// Hartley-normalised DLT (the default, and the start of refinement).
    #[default]
    NormalizedDlt,
    /// Plain DLT on raw coordinates: the right singular vector of A for its smallest singular
    /// value (returned scaled like every estimate).
    Svd,
    /// The paper's a33 = 1 linear least squares (its Eq. 4-5).
    A33,
}

impl Solver {
    /// Every solver.
    pub const ALL: [Solver; 3] = [Solver::NormalizedDlt, Solver::Svd, Solver::A33];

    /// Its name, as the bindings spell it.
    pub fn name(self) -> &'static str {
        match self {
            Solver::NormalizedDlt => "normalized_dlt",
            Solver::Svd => "svd",
            Solver::A33 => "a33",
        }
    }
}

impl fmt::Display for Solver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A solver name that is none of [`Solver::ALL`]'s (the name given).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown solver {0:?}; expected one of \"normalized_dlt\", \"svd\", \"a33\"")]
pub struct UnknownSolver(pub String);

impl FromStr for Solver {
    type Err = UnknownSolver;
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        Solver::ALL
            .into_iter()
            .find(|v| v.name() == s)
            .ok_or_else(|| UnknownSolver(s.to_owned()))
    }
}

/// A fitted homography and what refinement did, if it ran.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Oriented (source points at w > 0) and scaled so |h33| = 1 (see `orientation`).
    pub h: Matrix3<f64>,
    /// What refinement did; None when it did not run.
    pub refinement: Option<RefineReport>,
}

/// |det| / ||H||_F^3 of the homography in normalised coordinates below this: singular.
const SINGULAR_TOL: f64 = 1e-10;

/// The raw-coordinate solvers (svd, a33) refuse when rounding alone would perturb their
/// answer by more than this (relative): a final answer must be good to 1e-4...
const LINEAR_MAX_FORWARD_ERROR: f64 = 1e-4;
/// ...while a start for refinement only has to be in the optimum's basin.
const START_MAX_FORWARD_ERROR: f64 = 1e-2;

/// A linear fit, in normalised coordinates or in the caller's.
enum Fit {
    Normalized(Matrix3<f64>),
    Raw(Matrix3<f64>),
}

/// Fits H with dst ~ H src.
pub fn estimate(src: &[Point], dst: &[Point], solver: Solver, refine: bool) -> Result<Estimate> {
    let c = Correspondences::new(src, dst)?;
    let tol = if refine {
        START_MAX_FORWARD_ERROR
    } else {
        LINEAR_MAX_FORWARD_ERROR
    };
    let fit = match solver {
        Solver::NormalizedDlt => Fit::Normalized(normalized_dlt(&c)?),
        Solver::Svd => Fit::Raw(plain_dlt(&c, tol)?),
        Solver::A33 => {
            check_h33(&c.denormalize_h(&normalized_dlt(&c)?), &c)?;
            Fit::Raw(a33_least_squares(&c, tol)?)
        }
    };
    let (h, refinement) = if refine {
        let hn = match fit {
            Fit::Normalized(hn) => hn,
            Fit::Raw(h) => c.normalize_h(&h),
        };
        let (hn, report) = levenberg_marquardt(&c, &hn)?;
        check_not_singular(&hn)?;
        (denormalize(&c, &hn)?, Some(report))
    } else {
        // A raw fit is returned as solved (the paper's a33 = 1 matrix exactly), once checked.
        let h = match fit {
            Fit::Normalized(hn) => {
                check_not_singular(&hn)?;
                denormalize(&c, &hn)?
            }
            Fit::Raw(h) => {
                check_not_singular(&c.normalize_h(&h))?;
                h
            }
        };
        (h, None)
    };
    Ok(Estimate {
        h: orient_and_scale(&h, src)?,
        refinement,
    })
}

/// Refines a given homography (e.g. a robust estimate) on the correspondences by
/// Levenberg-Marquardt, skipping the linear solve; checked, oriented and scaled like
/// `estimate`'s results.
pub fn refine_homography(src: &[Point], dst: &[Point], start: &Matrix3<f64>) -> Result<Estimate> {
    let c = Correspondences::new(src, dst)?;
    let (hn, report) = levenberg_marquardt(&c, &c.normalize_h(start))?;
    check_not_singular(&hn)?;
    Ok(Estimate {
        h: orient_and_scale(&denormalize(&c, &hn)?, src)?,
        refinement: Some(report),
    })
}

/// Fits H with dst ~ H src; see `estimate`.
pub fn estimate_homography(
    src: &[Point],
    dst: &[Point],
    solver: Solver,
    refine: bool,
) -> Result<Matrix3<f64>> {
    estimate(src, dst, solver, refine).map(|e| e.h)
}

/// H in the caller's coordinates, checked to be the normalised fit still: when the two point
/// sets' scales differ by more than f64's range, H's entries overflow or underflow.
fn denormalize(c: &Correspondences, hn: &Matrix3<f64>) -> Result<Matrix3<f64>> {
    let h = c.denormalize_h(hn);
    let (back, fit) = (c.normalize_h(&h), hn / frobenius(hn));
    let back = back / frobenius(&back);
    let drift = (back - fit).norm().min((back + fit).norm());
    if !(drift < 1e-8) {
        return Err(HomographyError::Unrepresentable);
    }
    Ok(h)
}

fn check_not_singular(hn: &Matrix3<f64>) -> Result<()> {
    let norm = hn.norm();
    let ratio = hn.determinant().abs() / (norm * norm * norm);
    if !(ratio > SINGULAR_TOL) {
        return Err(HomographyError::Singular { ratio });
    }
    Ok(())
}

/// An estimate in OpenCV's convention, H[2,2] = 1 (the sign flipped if need be); None when
/// `estimate` found h33 negligible (it then scales H to unit norm instead of |h33| = 1).
pub fn with_unit_h33(h: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    match h[(2, 2)] {
        1.0 => Some(*h),
        -1.0 => Some(-h),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{noisy, relative_h_error, sample_problem, transfer_cost};

    #[test]
    fn solver_names_round_trip() {
        for s in Solver::ALL {
            assert_eq!(s.name().parse::<Solver>().unwrap(), s);
        }
        assert!("ransac".parse::<Solver>().is_err());
    }

    #[test]
    fn every_solver_recovers_exact_data_with_unit_h33() {
        let (src, dst, truth) = sample_problem(50, 300.0, 40.0);
        for solver in Solver::ALL {
            for refine in [false, true] {
                let h = estimate_homography(&src, &dst, solver, refine).unwrap();
                assert!(
                    relative_h_error(&h, &truth) < 1e-10,
                    "{solver} refine={refine}"
                );
                assert_eq!(h[(2, 2)], 1.0);
            }
        }
    }

    #[test]
    fn refinement_beats_every_linear_solver_on_noisy_data() {
        let (src, dst, _) = sample_problem(100, 600.0, 50.0);
        let dst = noisy(&dst, 0.7, 5);
        let gold = estimate(&src, &dst, Solver::NormalizedDlt, true).unwrap();
        let gold_cost = transfer_cost(&gold.h, &src, &dst);
        for solver in Solver::ALL {
            let linear = estimate_homography(&src, &dst, solver, false).unwrap();
            assert!(gold_cost <= transfer_cost(&linear, &src, &dst), "{solver}");
            let refined = estimate_homography(&src, &dst, solver, true).unwrap();
            let cost = transfer_cost(&refined, &src, &dst);
            assert!((cost - gold_cost).abs() <= 1e-9 * gold_cost, "{solver}");
        }
        let report = gold.refinement.unwrap();
        assert!(report.final_cost <= report.initial_cost);
    }

    #[test]
    fn degenerate_inputs_get_typed_errors() {
        let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let line = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]];
        for solver in Solver::ALL {
            assert!(matches!(
                estimate_homography(&square, &line, solver, false),
                Err(HomographyError::Collinear { .. })
            ));
        }
        // Source points on both sides of the horizon of the homography they imply.
        let src = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]];
        let dst = [
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [-40.0, -40.0],
        ];
        let err = estimate_homography(&src, &dst, Solver::NormalizedDlt, false).unwrap_err();
        assert!(err.is_degenerate(), "{err}");
    }

    #[test]
    fn any_magnitude_of_coordinates_is_fitted() {
        let (src, dst, _) = sample_problem(12, 1.0, 0.5);
        for s in [1e-250, 1e-100, 1.0, 1e100, 1e250] {
            for d in [1e-250, 1.0, 1e250] {
                let src: Vec<Point> = src.iter().map(|p| [p[0] * s, p[1] * s]).collect();
                let dst: Vec<Point> = dst.iter().map(|p| [p[0] * d, p[1] * d]).collect();
                if (d / s).log10().abs() > 300.0 || !(d / s).is_finite() {
                    // Entries of H would span 1e500: no f64 matrix holds that.
                    assert_eq!(
                        estimate_homography(&src, &dst, Solver::NormalizedDlt, false),
                        Err(HomographyError::Unrepresentable)
                    );
                    continue;
                }
                for refine in [false, true] {
                    let h = estimate_homography(&src, &dst, Solver::NormalizedDlt, refine)
                        .unwrap_or_else(|e| panic!("scales {s:e} -> {d:e}: {e}"));
                    assert_eq!(h[(2, 2)], 1.0);
                    for (p, q) in src.iter().zip(&dst) {
                        let w = h[(2, 0)] * p[0] + h[(2, 1)] * p[1] + h[(2, 2)];
                        let x = (h[(0, 0)] * p[0] + h[(0, 1)] * p[1] + h[(0, 2)]) / w;
                        assert!(((x - q[0]) / d).abs() < 1e-10, "scales {s:e} -> {d:e}");
                    }
                }
            }
        }
    }

    #[test]
    fn refining_a_start_reaches_the_same_optimum() {
        let (src, dst, _) = sample_problem(80, 400.0, 30.0);
        let dst = noisy(&dst, 0.5, 9);
        let gold = estimate(&src, &dst, Solver::NormalizedDlt, true).unwrap();
        let rough = estimate_homography(&src, &dst, Solver::A33, false).unwrap();
        let refined = refine_homography(&src, &dst, &rough).unwrap();
        assert!(relative_h_error(&refined.h, &gold.h) < 1e-8);
        assert!(refined.refinement.is_some());
    }

    #[test]
    fn unit_h33_convention() {
        let h = Matrix3::new(2.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, -1.0);
        assert_eq!(with_unit_h33(&h).unwrap(), -h);
        let h = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1e-20);
        assert!(with_unit_h33(&h).is_none());
    }
}
