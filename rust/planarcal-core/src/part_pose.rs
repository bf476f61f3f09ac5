//! Each part's pose in the output frame from the mapping near its image centroid: the
//! arithmetic of the production loop's parts, once per frame on a few parts, moved here from
//! Python/NumPy glue whose per-call overhead outweighed the work.
//!
//! The mapping (lens, plane, lift, registration: whatever the caller composes) is sampled at 7
//! points per part (`part_samples`): the image centroid, a step either side along x and y, and
//! a step either way along the diagonal. From the mapped samples, central differences give the
//! mapping's value, Jacobian and second derivatives there (`LocalMap::from_samples`; error the
//! step squared times the next derivative). From those and the image area's central second
//! moments M ([mu20, mu11, mu02] / area, px^2):
//!
//! * the part's centroid *on the plane* (`LocalMap::area_centroid`): the area integral of the
//!   mapped point weighted by the area scale |det J|, to second order in the part's size,
//!   X = f(c) + J M g + H : M / 2, with g the gradient of log |det J|;
//! * its principal axis in the output frame (`PartAxis::new`): the moments carried through the
//!   Jacobian, C = J M J^T, their major eigenvector as an angle in [-90, 90) degrees from the
//!   frame's +x towards its +y, and the roundness rule that leaves a part without an axis when
//!   its anisotropy is below `MIN_ANISOTROPY` or the angle's 1-sigma from the outline's edge
//!   noise (`EDGE_SIGMA_PX`) exceeds `MAX_ANGLE_SIGMA_DEG`.
//!
//! The reasoning behind each formula is in the Python modules that document them
//! (planarcal.live.local_map and planarcal.live.part_angle). A part whose samples, moments or
//! area are not finite gets NaN throughout; nothing here panics.

use crate::Point;

/// The sample offsets round each centroid, in steps: centre, +x, -x, +y, -y, +x+y, -x-y.
pub const SAMPLE_OFFSETS: [[f64; 2]; 7] = [
    [0.0, 0.0],
    [1.0, 0.0],
    [-1.0, 0.0],
    [0.0, 1.0],
    [0.0, -1.0],
    [1.0, 1.0],
    [-1.0, -1.0],
];

/// Below this (l1 - l2) / (l1 + l2) of the output frame's moments a part is too round for an
/// axis (an ellipse of axes 1.08 : 1).
pub const MIN_ANISOTROPY: f64 = 0.08;

/// The outline's edge noise in the angle's noise model, px.
pub const EDGE_SIGMA_PX: f64 = 0.12;

/// An axis whose 1-sigma from the outline's noise exceeds this is not given, degrees.
pub const MAX_ANGLE_SIGMA_DEG: f64 = 2.0;

/// The mapping's samples for `centroids` (n) and step `step` (px): 7 n points, in blocks of n
/// in the order of `SAMPLE_OFFSETS` (all centres, then all +x, ...). OutOfMemory when there
/// is no room for them.
pub fn part_samples(centroids: &[Point], step: f64) -> crate::Result<Vec<Point>> {
    crate::alloc::collect(SAMPLE_OFFSETS.iter().flat_map(|o| {
        centroids
            .iter()
            .map(move |c| [c[0] + step * o[0], c[1] + step * o[1]])
    }))
}

/// The mapping near one part's image centroid, to second order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalMap {
    /// The image centroid mapped into the output frame.
    pub position: Point,
    /// d(out)/d(px): `jacobian[i][j]` = d out_i / d px_j.
    pub jacobian: [[f64; 2]; 2],
    /// Each output coordinate's second derivatives: `hessian[i]` = [d2/dx2, d2/dxdy, d2/dy2].
    pub hessian: [[f64; 3]; 2],
}

impl LocalMap {
    /// Part `i` of `n` from the mapped samples (7 n points in `part_samples`' order) and the
    /// step they were taken at. None if `samples` does not hold 7 n points or `i >= n`.
    pub fn from_samples(samples: &[Point], n: usize, i: usize, step: f64) -> Option<LocalMap> {
        if i >= n || samples.len() != SAMPLE_OFFSETS.len() * n {
            return None;
        }
        let at = |k: usize| samples[k * n + i];
        let (f0, px, mx, py, my, pp, mm) = (at(0), at(1), at(2), at(3), at(4), at(5), at(6));
        let (h2, hh) = (2.0 * step, step * step);
        let mut jacobian = [[0.0; 2]; 2];
        let mut hessian = [[0.0; 3]; 2];
        for d in 0..2 {
            jacobian[d] = [(px[d] - mx[d]) / h2, (py[d] - my[d]) / h2];
            hessian[d] = [
                (px[d] + mx[d] - 2.0 * f0[d]) / hh,
                (pp[d] + mm[d] - px[d] - mx[d] - py[d] - my[d] + 2.0 * f0[d]) / (2.0 * hh),
                (py[d] + my[d] - 2.0 * f0[d]) / hh,
            ];
        }
        Some(LocalMap {
            position: f0,
            jacobian,
            hessian,
        })
    }

    /// The part's centroid on the plane from its image area's central second moments
    /// ([mu20, mu11, mu02] / area, px^2): f(c) + J M g + H : M / 2. NaN where it is not finite
    /// (a sample without an image, a singular Jacobian).
    pub fn area_centroid(&self, moments: [f64; 3]) -> Point {
        let j = &self.jacobian;
        let (fx, fy) = ([j[0][0], j[1][0]], [j[0][1], j[1][1]]);
        let col = |k: usize| [self.hessian[0][k], self.hessian[1][k]];
        let (fxx, fxy, fyy) = (col(0), col(1), col(2));
        let det = cross(fx, fy);
        // The gradient of log |det J|: d det / dx and d det / dy, over det.
        let gx = (cross(fxx, fy) + cross(fx, fxy)) / det;
        let gy = (cross(fxy, fy) + cross(fx, fyy)) / det;
        let [mu20, mu11, mu02] = moments;
        let (mgx, mgy) = (mu20 * gx + mu11 * gy, mu11 * gx + mu02 * gy);
        let mut out = [0.0; 2];
        for d in 0..2 {
            // J M g (the area scale's lean to one side) + H : M / 2 (the mapping's bend).
            let lean = fx[d] * mgx + fy[d] * mgy;
            let bend = 0.5 * (fxx[d] * mu20 + 2.0 * fxy[d] * mu11 + fyy[d] * mu02);
            out[d] = self.position[d] + lean + bend;
        }
        if out.iter().all(|v| v.is_finite()) {
            out
        } else {
            [f64::NAN; 2]
        }
    }
}

/// The 2-D cross product a_x b_y - a_y b_x.
fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// One part's principal axis in the output frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PartAxis {
    /// Degrees in [-90, 90) from the output frame's +x towards its +y; NaN where the part has
    /// no axis (too round, too noisy, or a singular or non-finite Jacobian).
    pub angle_deg: f64,
    /// The unit direction in the image (px) along which the output frame's axis lies; NaN
    /// where there is no axis.
    pub axis_px: Point,
    /// (l1 - l2) / (l1 + l2) of the output frame's moments (0 for a disc or a square, or where
    /// their trace is not positive); NaN for non-finite input.
    pub anisotropy: f64,
    /// The angle's 1-sigma from the outline's edge noise, degrees (inf for a round part); NaN
    /// for non-finite input.
    pub sigma_deg: f64,
}

/// sigma_e sqrt(P / 2) = LEVER tr(M)^(1/4), the outline's length P taken as 2 pi sqrt(2 tr M)
/// (exact for a disc, close for an ellipse or a rectangle): EDGE_SIGMA_PX sqrt(pi sqrt 2).
fn noise_lever(moments: [f64; 3]) -> f64 {
    let lever = EDGE_SIGMA_PX * (std::f64::consts::PI * std::f64::consts::SQRT_2).sqrt();
    lever * (moments[0] + moments[2]).abs().sqrt().sqrt()
}

impl PartAxis {
    /// The axis of a part with image moments `moments` ([mu20, mu11, mu02] / area, px^2) and
    /// enclosed area `area` (px^2), through the mapping's Jacobian at its centroid.
    pub fn new(moments: [f64; 3], area: f64, jacobian: [[f64; 2]; 2]) -> PartAxis {
        let finite = moments
            .iter()
            .chain(jacobian.iter().flatten())
            .all(|v| v.is_finite())
            && area.is_finite();
        if !finite {
            return PartAxis {
                angle_deg: f64::NAN,
                axis_px: [f64::NAN; 2],
                anisotropy: f64::NAN,
                sigma_deg: f64::NAN,
            };
        }
        let [cxx, cxy, cyy] = moments;
        let [[a0, a1], [b0, b1]] = jacobian;
        // C_out = J M J^T, written out: the enclosed area's second moments on the plane.
        let xx = (a0 * cxx + 2.0 * a1 * cxy) * a0 + a1 * a1 * cyy;
        let yy = (b0 * cxx + 2.0 * b1 * cxy) * b0 + b1 * b1 * cyy;
        let xy = a0 * b0 * cxx + (a0 * b1 + a1 * b0) * cxy + a1 * b1 * cyy;
        let diff = xx - yy;
        let gap = diff.hypot(2.0 * xy);
        let trace = xx + yy;
        let anisotropy = if trace > 0.0 { gap / trace } else { 0.0 };
        let lever = if area > 0.0 {
            noise_lever(moments) / area
        } else {
            f64::INFINITY
        };
        let sigma_deg = if gap > 0.0 {
            (lever * trace / gap).to_degrees()
        } else {
            f64::INFINITY
        };
        // The rule written without a division: sigma <= bar <=> lever trace <= bar area gap.
        let defined = trace > 0.0
            && gap >= MIN_ANISOTROPY * trace
            && noise_lever(moments) * trace <= MAX_ANGLE_SIGMA_DEG.to_radians() * area * gap;
        let det = a0 * b1 - a1 * b0;
        if !(defined && det != 0.0) {
            return PartAxis {
                angle_deg: f64::NAN,
                axis_px: [f64::NAN; 2],
                anisotropy,
                sigma_deg,
            };
        }
        let mut angle_deg = (0.5 * (2.0 * xy).atan2(diff)).to_degrees();
        // Into [-90, 90): atan2 gives (-180, 180], so only +90 needs folding.
        if angle_deg >= 90.0 {
            angle_deg -= 180.0;
        }
        // The image direction: J^-1 applied to the output frame's unit axis (its adjugate,
        // signed by det: the scale goes in the normalisation).
        let (s, c) = angle_deg.to_radians().sin_cos();
        let sign = det.signum();
        let d = [sign * (b1 * c - a1 * s), sign * (a0 * s - b0 * c)];
        let norm = d[0].hypot(d[1]);
        PartAxis {
            angle_deg,
            axis_px: [d[0] / norm, d[1] / norm],
            anisotropy,
            sigma_deg,
        }
    }
}

/// One part's pose: the mapping near it, its centroid on the plane and its axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PartPose {
    /// The mapping near the part's image centroid.
    pub local: LocalMap,
    /// Its centroid on the plane (`LocalMap::area_centroid`).
    pub centroid: Point,
    /// Its axis (`PartAxis::new`).
    pub axis: PartAxis,
}

/// The shapes of `part_poses`' arguments disagree.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PartCountMismatch {
    /// Parts according to the moments.
    pub parts: usize,
    /// Mapped samples (must be 7 per part).
    pub samples: usize,
    /// Areas (must be 1 per part).
    pub areas: usize,
}

impl std::fmt::Display for PartCountMismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} parts (moments) need {} mapped samples and {} areas, got {} and {}",
            self.parts,
            SAMPLE_OFFSETS.len() * self.parts,
            self.parts,
            self.samples,
            self.areas
        )
    }
}

impl std::error::Error for PartCountMismatch {}

/// Every part's pose from the mapped samples (7 n points in `part_samples`' order, taken at
/// `step` px), the image moments (n) and the enclosed areas (n).
pub fn part_poses(
    samples: &[Point],
    moments: &[[f64; 3]],
    areas: &[f64],
    step: f64,
) -> Result<Vec<PartPose>, PartCountMismatch> {
    let n = moments.len();
    if samples.len() != SAMPLE_OFFSETS.len() * n || areas.len() != n {
        return Err(PartCountMismatch {
            parts: n,
            samples: samples.len(),
            areas: areas.len(),
        });
    }
    Ok((0..n)
        .filter_map(|i| {
            let local = LocalMap::from_samples(samples, n, i, step)?;
            Some(PartPose {
                local,
                centroid: local.area_centroid(moments[i]),
                axis: PartAxis::new(moments[i], areas[i], local.jacobian),
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [mu20, mu11, mu02] / area of a w x h rectangle turned by `deg`.
    fn rectangle(w: f64, h: f64, deg: f64) -> [f64; 3] {
        let (l1, l2) = (w * w / 12.0, h * h / 12.0);
        let (s, c) = deg.to_radians().sin_cos();
        [
            l1 * c * c + l2 * s * s,
            (l1 - l2) * s * c,
            l1 * s * s + l2 * c * c,
        ]
    }

    fn affine(a: [[f64; 2]; 2], t: Point) -> impl Fn(Point) -> Point {
        move |p| {
            [
                a[0][0] * p[0] + a[0][1] * p[1] + t[0],
                a[1][0] * p[0] + a[1][1] * p[1] + t[1],
            ]
        }
    }

    #[test]
    fn samples_are_in_blocks_of_parts() {
        let s = part_samples(&[[10.0, 20.0], [30.0, 40.0]], 0.5).unwrap();
        assert_eq!(s.len(), 14);
        assert_eq!(s[0], [10.0, 20.0]);
        assert_eq!(s[1], [30.0, 40.0]);
        assert_eq!(s[2], [10.5, 20.0]);
        assert_eq!(s[5], [29.5, 40.0]);
        assert_eq!(s[6], [10.0, 20.5]);
        assert_eq!(s[12], [9.5, 19.5]);
    }

    #[test]
    fn an_affine_mapping_has_its_matrix_and_no_correction() {
        let a = [[0.5, 0.1], [-0.2, 0.4]];
        let f = affine(a, [3.0, -7.0]);
        let c = [[10.0, 20.0], [300.0, 40.0]];
        let mapped: Vec<Point> = part_samples(&c, 1.0).unwrap().into_iter().map(&f).collect();
        let m = rectangle(40.0, 10.0, 30.0);
        let poses = part_poses(&mapped, &[m, m], &[400.0, 400.0], 1.0).unwrap();
        for (pose, ci) in poses.iter().zip(c) {
            for i in 0..2 {
                for j in 0..2 {
                    assert!((pose.local.jacobian[i][j] - a[i][j]).abs() < 1e-12);
                }
                for k in 0..3 {
                    assert!(pose.local.hessian[i][k].abs() < 1e-9);
                }
                assert!((pose.centroid[i] - f(ci)[i]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn a_turned_rectangle_has_its_angle_and_image_direction() {
        let id = [[1.0, 0.0], [0.0, 1.0]];
        for deg in [-60.0, -5.0, 0.0, 20.0, 75.0] {
            let axis = PartAxis::new(rectangle(40.0, 10.0, deg), 400.0, id);
            assert!((axis.angle_deg - deg).abs() < 1e-9, "{deg}: {axis:?}");
            let (s, c) = f64::to_radians(deg).sin_cos();
            assert!((axis.axis_px[0] - c).abs() < 1e-12 && (axis.axis_px[1] - s).abs() < 1e-12);
            assert!((axis.anisotropy - 15.0 / 17.0).abs() < 1e-12);
            assert!(axis.sigma_deg < MAX_ANGLE_SIGMA_DEG);
        }
        // Through a scaled mirror (det < 0) the angle changes sign; the image direction not.
        let axis = PartAxis::new(
            rectangle(40.0, 10.0, 20.0),
            400.0,
            [[2.0, 0.0], [0.0, -2.0]],
        );
        assert!((axis.angle_deg + 20.0).abs() < 1e-9);
        let (s, c) = 20f64.to_radians().sin_cos();
        assert!((axis.axis_px[0] - c).abs() < 1e-12 && (axis.axis_px[1] - s).abs() < 1e-12);
    }

    #[test]
    fn an_axis_along_y_wraps_to_minus_ninety() {
        let axis = PartAxis::new(rectangle(40.0, 10.0, 90.0), 400.0, [[1.0, 0.0], [0.0, 1.0]]);
        assert_eq!(axis.angle_deg, -90.0);
        let axis = PartAxis::new(rectangle(40.0, 10.0, 95.0), 400.0, [[1.0, 0.0], [0.0, 1.0]]);
        assert!((axis.angle_deg + 85.0).abs() < 1e-9);
    }

    #[test]
    fn a_disc_a_square_and_a_noisy_small_part_have_no_axis() {
        let id = [[1.0, 0.0], [0.0, 1.0]];
        let disc = PartAxis::new([100.0, 0.0, 100.0], 1256.0, id);
        assert!(disc.angle_deg.is_nan() && disc.axis_px[0].is_nan());
        assert_eq!(disc.anisotropy, 0.0);
        assert_eq!(disc.sigma_deg, f64::INFINITY);
        let square = PartAxis::new(rectangle(20.0, 20.0, 30.0), 400.0, id);
        assert!(square.angle_deg.is_nan());
        // The same 1.3 : 1 shape: an axis at 40 px, none at 6 px.
        let big = PartAxis::new(rectangle(40.0, 40.0 / 1.3, 10.0), 40.0 * 40.0 / 1.3, id);
        let small = PartAxis::new(rectangle(6.0, 6.0 / 1.3, 10.0), 6.0 * 6.0 / 1.3, id);
        assert!(big.angle_deg.is_finite() && small.angle_deg.is_nan());
        assert!(small.sigma_deg > MAX_ANGLE_SIGMA_DEG && big.sigma_deg < MAX_ANGLE_SIGMA_DEG);
    }

    #[test]
    fn non_finite_samples_give_nan_not_a_panic() {
        let c = [[5.0, 5.0], [50.0, 5.0]];
        let mut mapped = part_samples(&c, 1.0).unwrap();
        mapped[2 * 2] = [f64::NAN, 1.0]; // the first part's -x sample has no image
        let m = rectangle(40.0, 10.0, 5.0);
        let poses = part_poses(&mapped, &[m, m], &[400.0; 2], 1.0).unwrap();
        let p = poses[0];
        assert!(p.centroid.iter().all(|v| v.is_nan()));
        assert!(p.axis.angle_deg.is_nan() && p.axis.anisotropy.is_nan());
        assert!(p.axis.sigma_deg.is_nan() && p.axis.axis_px.iter().all(|v| v.is_nan()));
        assert!(poses[1].axis.angle_deg.is_finite() && poses[1].centroid[0].is_finite());
        // A singular Jacobian: no centroid correction to trust, no image direction.
        let flat = PartAxis::new(m, 400.0, [[1.0, 0.0], [1.0, 0.0]]);
        assert!(flat.angle_deg.is_nan());
    }

    #[test]
    fn mismatched_counts_are_refused() {
        let err = part_poses(&[[0.0; 2]; 6], &[[1.0, 0.0, 1.0]], &[1.0], 1.0).unwrap_err();
        assert_eq!(err.samples, 6);
        assert!(err.to_string().contains("need 7 mapped samples"));
        assert!(part_poses(&[], &[], &[], 1.0).unwrap().is_empty());
    }
}
