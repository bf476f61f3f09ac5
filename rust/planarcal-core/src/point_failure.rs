//! Why a point has no image, and the count of each kind over a batch: the one vocabulary of
//! the point transforms (`transform`), the pixel -> plane mappers (`uncertainty`, `mapper`,
//! `fitted_mapper`) and the lens's batch inverse.

/// Why a point (or pixel) has no image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointFailure {
    /// A coordinate is NaN or infinite.
    NonFinite,
    /// w = 0 to within rounding, or the image overflows: the point maps to infinity.
    AtInfinity,
    /// A pixel beyond the radius where the lens model can be inverted (or beyond the image it
    /// was fitted on).
    OutsideLens,
    /// On the far side of the horizon: w < 0 under an oriented homography; for a pixel, its
    /// ray does not meet the plane in front of the camera.
    BehindHorizon,
}

impl PointFailure {
    /// The failure of a point mapped through a homography, in words, after "point ... ".
    pub fn describe(self) -> &'static str {
        match self {
            PointFailure::NonFinite => "has a non-finite coordinate",
            PointFailure::AtInfinity => "maps to infinity",
            PointFailure::OutsideLens => {
                "lies beyond the image the lens model was fitted on (or its valid radius)"
            }
            PointFailure::BehindHorizon => "lies behind the horizon",
        }
    }

    /// As `describe`, for a pixel seen through the camera: the pixel mappers fold w = 0 and
    /// w < 0 into one failure, which sees no point of the plane.
    pub fn describe_pixel(self) -> &'static str {
        match self {
            PointFailure::AtInfinity | PointFailure::BehindHorizon => {
                "sees no point of the plane (at or beyond its horizon)"
            }
            other => other.describe(),
        }
    }
}

/// Counts of the points a batch could not map, by kind, and the first of them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PointReport {
    /// Points with a NaN or infinite coordinate.
    pub non_finite: usize,
    /// Points mapped to infinity (w = 0).
    pub at_infinity: usize,
    /// Pixels beyond the lens model's valid radius.
    pub outside_lens: usize,
    /// Points behind the horizon.
    pub behind_horizon: usize,
    /// The first failed point's index and why.
    pub first: Option<(usize, PointFailure)>,
}

impl PointReport {
    /// Points not mapped.
    pub fn invalid(&self) -> usize {
        self.non_finite + self.at_infinity + self.outside_lens + self.behind_horizon
    }

    /// The count of points that failed as `failure`.
    pub fn count(&self, failure: PointFailure) -> usize {
        match failure {
            PointFailure::NonFinite => self.non_finite,
            PointFailure::AtInfinity => self.at_infinity,
            PointFailure::OutsideLens => self.outside_lens,
            PointFailure::BehindHorizon => self.behind_horizon,
        }
    }

    /// Counts point `index`, which failed as `failure` (only failed points are recorded, so
    /// the kernels' clean path never comes here).
    pub(crate) fn record(&mut self, index: usize, failure: PointFailure) {
        match failure {
            PointFailure::NonFinite => self.non_finite += 1,
            PointFailure::AtInfinity => self.at_infinity += 1,
            PointFailure::OutsideLens => self.outside_lens += 1,
            PointFailure::BehindHorizon => self.behind_horizon += 1,
        }
        if self.first.is_none() {
            self.first = Some((index, failure));
        }
    }

    /// Joins the report of the batch that follows this one.
    pub(crate) fn then(mut self, next: PointReport) -> Self {
        self.non_finite += next.non_finite;
        self.at_infinity += next.at_infinity;
        self.outside_lens += next.outside_lens;
        self.behind_horizon += next.behind_horizon;
        self.first = self.first.or(next.first);
        self
    }
}

/// Every kind, in the order reports list them.
pub const POINT_FAILURES: [PointFailure; 4] = [
    PointFailure::NonFinite,
    PointFailure::AtInfinity,
    PointFailure::OutsideLens,
    PointFailure::BehindHorizon,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reports_count_each_kind_and_keep_the_first() {
        let mut a = PointReport::default();
        a.record(4, PointFailure::OutsideLens);
        a.record(7, PointFailure::NonFinite);
        let mut b = PointReport::default();
        b.record(9, PointFailure::BehindHorizon);
        b.record(12, PointFailure::AtInfinity);
        let joined = PointReport::default().then(a).then(b);
        assert_eq!(joined.invalid(), 4);
        assert_eq!(joined.first, Some((4, PointFailure::OutsideLens)));
        for kind in POINT_FAILURES {
            assert_eq!(joined.count(kind), 1);
        }
    }

    #[test]
    fn pixels_and_points_say_the_same_but_for_the_horizon() {
        assert_eq!(
            PointFailure::NonFinite.describe_pixel(),
            PointFailure::NonFinite.describe()
        );
        assert_eq!(
            PointFailure::OutsideLens.describe_pixel(),
            PointFailure::OutsideLens.describe()
        );
        assert!(PointFailure::BehindHorizon
            .describe_pixel()
            .starts_with("sees no point of the plane"));
    }
}
