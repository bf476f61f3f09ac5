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
//! `leave_one_out` gives the honest error of each point; `mapper` maps pixels to the plane in
//! batches at memory speed, with the same answers, and `fitted_mapper` pairs it with a fit to
//! give each point's uncertainty too (what the bindings map through); `contours` measures a
//! frame's traced object outlines (`image`, `smooth`, `outline`: moved to the grey-level edge,
//! sub-pixel), `tracking` keeps their IDs from frame to frame and `json_line` writes each
//! frame as the production loop's JSON line, and `part_pose` gives each part's centroid on the
//! plane and its axis from the mapping sampled round it. `point_failure` says why a point has
//! no image, for the transforms and the mappers alike.
//! Geometry is f64; nothing panics on user input.
//!
//! The modules are the crate's own; its surface is the items re-exported here.

#![deny(missing_docs)]

mod a33;
mod alloc;
mod contours;
mod correspondences;
mod degeneracy;
mod dlt;
mod dot_centres;
mod error;
mod estimate;
mod fitted_mapper;
mod image;
mod json_line;
mod leave_one_out;
mod lens;
mod lm;
mod mapper;
mod normalize;
mod orientation;
mod outline;
mod part_pose;
mod placements;
mod plane_model;
mod point_failure;
mod refine;
mod reprojection;
mod robust;
mod smooth;
mod threads;
mod tracking;
mod transform;
mod uncertainty;

#[cfg(test)]
mod testing;

/// A 2-D point (x, y).
pub type Point = [f64; 2];

pub use alloc::{collect as try_collect, filled as try_filled};
pub use contours::{fewest_points, measure_contours, reading_order, ContourFilter};
pub use dot_centres::{refine_dot_centres, DotCentre, DotStatus, InkImage};
pub use error::{HomographyError, PointSet, Result};
pub use estimate::{
    estimate, estimate_homography, refine_homography, with_unit_h33, Estimate, Solver,
    UnknownSolver,
};
pub use fitted_mapper::{FittedMapper, UncertaintyError};
pub use image::{median_grey, GreyU8};
pub use json_line::{FrameObjects, ObjectCountMismatch};
pub use leave_one_out::leave_one_out;
pub use lens::{LensError, RadialLens};
pub use mapper::{PlaneMapper, Undistortion};
pub use part_pose::{
    part_poses, part_samples, LocalMap, PartAxis, PartCountMismatch, PartPose, EDGE_SIGMA_PX,
    MAX_ANGLE_SIGMA_DEG, MIN_ANISOTROPY, SAMPLE_OFFSETS,
};
pub use placements::{fit_placements, placements_fit_at, Placed, PlacementsFit, Pose};
pub use plane_model::{fit_plane, plane_fit_at, LensParams, PlaneFit, PlaneModel};
pub use point_failure::{PointFailure, PointReport, POINT_FAILURES};
pub use refine::RefineReport;
pub use reprojection::{reprojection_errors_into, ErrorStats};
pub use robust::{
    estimate_robust, estimate_robust_batch, estimate_robust_batch_interruptible,
    estimate_robust_interruptible, Method, Pcg32, RobustOptions, RobustResult, StopReason,
    StopRequest, MAX_ITERS,
};
pub use threads::forked_child;
pub use tracking::Tracks;
pub use transform::{invert, Coord, Homography, Orientation, Projective};
pub use uncertainty::{predicted_loo_covariance, world_covariance, InversePlane};
