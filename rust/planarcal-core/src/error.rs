//! The typed errors of the core. Every failure on user input is one of these, never a panic.

use std::fmt;

/// Which of the two point sets of a correspondence problem an error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointSet {
    /// The points in the plane's own frame (`src`).
    Source,
    /// The points they map to (`dst`).
    Destination,
}

impl fmt::Display for PointSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PointSet::Source => "source",
            PointSet::Destination => "destination",
        })
    }
}

/// Why a homography could not be estimated or applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HomographyError {
    /// The two sets differ in length.
    #[error("source and destination must hold the same number of points, got {src} and {dst}")]
    LengthMismatch {
        /// Source points given.
        src: usize,
        /// Destination points given.
        dst: usize,
    },

    /// Fewer than four correspondences.
    #[error("a homography needs at least 4 point correspondences, got {got}")]
    TooFewPoints {
        /// Correspondences given.
        got: usize,
    },

    /// A coordinate is NaN or infinite.
    #[error("{set} point {index} is not finite: ({x}, {y})")]
    NonFinitePoint {
        /// The set holding the point.
        set: PointSet,
        /// Its index in that set.
        index: usize,
        /// Its x.
        x: f64,
        /// Its y.
        y: f64,
    },

    /// The robust search's scores do not match the points.
    #[error("scores must hold one number per correspondence: {points} points, {scores} scores")]
    ScoresLength {
        /// Correspondences given.
        points: usize,
        /// Scores given.
        scores: usize,
    },

    /// An option is out of its range.
    #[error("{name} must be {expected}, got {value}")]
    InvalidParameter {
        /// The option's name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What it must be, in words.
        expected: &'static str,
    },

    /// A given homography has a NaN or infinite entry.
    #[error("the homography matrix has a non-finite entry at row {row}, column {col}")]
    NonFiniteMatrix {
        /// The entry's row.
        row: usize,
        /// The entry's column.
        col: usize,
    },

    /// Fewer than four distinct points in a set.
    #[error(
        "only {distinct} distinct {set} points (the rest are duplicates); \
         a homography needs at least 4 distinct points, no 3 of them on one line"
    )]
    TooFewDistinct {
        /// The set with too few.
        set: PointSet,
        /// Its distinct points.
        distinct: usize,
    },

    /// H's entries would overflow f64.
    #[error(
        "the homography between these point sets cannot be represented in double precision: \
         their scales differ so much that its entries would overflow; rescale the coordinates"
    )]
    Unrepresentable,

    /// A set too small or too large to normalise.
    #[error(
        "the {set} points' spread ({spread:.1e}) is beyond what floating point can normalise; \
         rescale the coordinates"
    )]
    SpreadOutOfRange {
        /// The set whose spread it is.
        set: PointSet,
        /// Its RMS distance from its centroid.
        spread: f64,
    },

    /// Every point of a set on one line.
    #[error(
        "all {set} points lie on one line (within {relative_deviation:.1e} of their extent); \
         a homography needs at least 4 points, no 3 of them on one line"
    )]
    Collinear {
        /// The set on one line.
        set: PointSet,
        /// Its largest distance from the line over its extent.
        relative_deviation: f64,
    },

    /// Every point of a set but one on one line.
    #[error(
        "all {set} points but one (point {outlier}) lie on one line (within \
         {relative_deviation:.1e} of their extent); a homography needs at least 4 points, \
         no 3 of them on one line"
    )]
    AllButOneCollinear {
        /// The set on one line.
        set: PointSet,
        /// The index of the one point off it.
        outlier: usize,
        /// The others' largest distance from the line over their extent.
        relative_deviation: f64,
    },

    /// The linear system does not fix H.
    #[error(
        "the correspondences do not determine a homography: the linear system is \
         rank-deficient (second-smallest to largest singular value ratio {ratio:.1e})"
    )]
    RankDeficient {
        /// Second-smallest over largest singular value.
        ratio: f64,
    },

    /// Raw coordinates too ill-conditioned for the solver.
    #[error(
        "the {solver} solver cannot resolve this problem in raw coordinates: rounding alone \
         would perturb H by about {forward_error:.1e} (relative); use the normalized_dlt solver, \
         which normalises the points first"
    )]
    IllConditioned {
        /// The solver asked for.
        solver: &'static str,
        /// The relative change in H that rounding alone could make.
        forward_error: f64,
    },

    /// The a33 = 1 parametrisation cannot hold this H.
    #[error(
        "h33 is near zero ({relative:.1e} of the scale of the data): the source origin maps \
         (nearly) to infinity, so the a33 = 1 parametrisation cannot represent this homography; \
         use the normalized_dlt solver"
    )]
    H33NearZero {
        /// |h33| over the scale of the data.
        relative: f64,
    },

    /// Points on both sides of the fitted horizon.
    #[error(
        "the fitted homography puts source point {index} on the other side of the horizon \
         from the rest ({behind} of {total} points): no camera sees such a plane, so the \
         correspondences are inconsistent (outliers or mismatched order?)"
    )]
    MixedOrientation {
        /// A source point on the minority's side.
        index: usize,
        /// Points on that side.
        behind: usize,
        /// All points.
        total: usize,
    },

    /// H collapses the plane and has no inverse.
    #[error(
        "the homography is singular (smallest to largest singular value ratio {ratio:.1e}): \
         it collapses the plane onto a line or a point and has no inverse"
    )]
    Singular {
        /// Smallest over largest singular value.
        ratio: f64,
    },

    /// A buffer proportional to the input could not be allocated.
    #[error(
        "not enough memory: a buffer of {bytes} bytes for this many points could not be \
         allocated"
    )]
    OutOfMemory {
        /// The size of the buffer refused.
        bytes: usize,
    },

    /// The caller asked a long search to stop (Ctrl-C, in Python).
    #[error("interrupted after {iterations} iterations")]
    Interrupted {
        /// Iterations run before the stop.
        iterations: usize,
    },
}

impl HomographyError {
    /// True when an argument is malformed (point sets of different lengths, a non-finite
    /// coordinate or matrix entry, scores of the wrong length, an option out of its range),
    /// as opposed to well-formed data that give no homography.
    pub fn is_invalid_argument(&self) -> bool {
        matches!(
            self,
            HomographyError::LengthMismatch { .. }
                | HomographyError::NonFinitePoint { .. }
                | HomographyError::ScoresLength { .. }
                | HomographyError::InvalidParameter { .. }
                | HomographyError::NonFiniteMatrix { .. }
        )
    }

    /// The point set and the index of the point the error names, where it names them (so
    /// the bindings can hand them on as attributes rather than only in the message).
    pub fn point(&self) -> (Option<PointSet>, Option<usize>) {
        match *self {
            HomographyError::NonFinitePoint { set, index, .. } => (Some(set), Some(index)),
            HomographyError::AllButOneCollinear { set, outlier, .. } => (Some(set), Some(outlier)),
            HomographyError::MixedOrientation { index, .. } => {
                (Some(PointSet::Source), Some(index))
            }
            HomographyError::TooFewDistinct { set, .. }
            | HomographyError::SpreadOutOfRange { set, .. }
            | HomographyError::Collinear { set, .. } => (Some(set), None),
            _ => (None, None),
        }
    }

    /// True when the input is well-formed but its geometry does not determine a homography.
    pub fn is_degenerate(&self) -> bool {
        matches!(
            self,
            HomographyError::TooFewDistinct { .. }
                | HomographyError::Collinear { .. }
                | HomographyError::AllButOneCollinear { .. }
                | HomographyError::RankDeficient { .. }
                | HomographyError::H33NearZero { .. }
                | HomographyError::MixedOrientation { .. }
                | HomographyError::Singular { .. }
        )
    }
}

/// The core's result: a value or a [`HomographyError`].
pub type Result<T, E = HomographyError> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bad_argument_is_never_degenerate_and_names_its_point() {
        let e = HomographyError::NonFinitePoint {
            set: PointSet::Destination,
            index: 7,
            x: f64::NAN,
            y: 0.0,
        };
        assert!(e.is_invalid_argument() && !e.is_degenerate());
        assert_eq!(e.point(), (Some(PointSet::Destination), Some(7)));
        let e = HomographyError::AllButOneCollinear {
            set: PointSet::Source,
            outlier: 5,
            relative_deviation: 0.0,
        };
        assert!(e.is_degenerate() && !e.is_invalid_argument());
        assert_eq!(e.point(), (Some(PointSet::Source), Some(5)));
        let e = HomographyError::TooFewPoints { got: 3 };
        assert!(!e.is_degenerate() && !e.is_invalid_argument());
        assert_eq!(e.point(), (None, None));
    }
}
