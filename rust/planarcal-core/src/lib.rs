//! planarcal-core: planar homography estimation and batch point mapping in pure Rust.
//!
//! The pipeline, one module an idea: `correspondences` validates a problem and normalises it
//! (`normalize`), rejecting geometry that cannot determine a homography (`degeneracy`); a
//! linear solver fits H (`dlt`: normalised DLT and plain SVD DLT; `a33`: the paper's a33 = 1
//! least squares); `refine` polishes it by Levenberg-Marquardt; `orientation` fixes its sign
//! and scale. `transform` maps points through it in batches and `reprojection` measures the
//! fit; `threads` keeps them off the thread pool in forked children. `estimate` ties these
//! together. Beyond the homography, `lens` models radial distortion, `plane_model` fits it
//! jointly with H, `uncertainty` maps pixels through that fit with their covariance, and
//! `leave_one_out` gives the honest error of each point; `mapper` maps the production loop's
//! pixels to the plane in batches at memory speed, with the same answers; `contours` measures a
//! frame's traced object outlines (`image`, `smooth`, `outline`: moved to the grey-level edge,
//! sub-pixel)
//! and `tracking` keeps their IDs from frame to frame.
//! Geometry is f64; nothing panics on user input.

pub mod a33;
pub mod contours;
pub mod correspondences;
pub mod degeneracy;
pub mod dlt;
pub mod dot_centres;
pub mod error;
pub mod estimate;
pub mod image;
pub mod leave_one_out;
pub mod lens;
pub mod mapper;
pub mod normalize;
pub mod orientation;
pub mod outline;
pub mod plane_model;
pub mod refine;
pub mod reprojection;
pub mod robust;
pub mod smooth;
pub mod threads;
pub mod tracking;
pub mod transform;
pub mod uncertainty;

#[cfg(test)]
mod testing;

/// A 2-D point (x, y).
pub type Point = [f64; 2];

pub use error::{HomographyError, PointSet, Result};
pub use estimate::{
    estimate, estimate_homography, refine_homography, with_unit_h33, Estimate, Solver,
    UnknownSolver,
};
pub use refine::RefineReport;
pub use reprojection::{reprojection_errors_into, ErrorStats};
pub use robust::{
    estimate_robust, estimate_robust_batch, Method, RobustOptions, RobustResult, StopReason,
};
pub use transform::{invert, Homography, Orientation, PointStatus, Projective, TransformReport};
