//! The minimal solver: the homography through 4 correspondences, by Gaussian elimination of
//! the 8 x 8 system with h33 = 1 (on fixed arrays: no allocation), after cheap checks that
//! reject samples which cannot give a valid homography.
//!
//! Points are expected normalised (centred, unit scale), where h33 = w at the data's centroid
//! is safely away from zero for any model that keeps the data in front.

/// Twice the signed area of the triangle (a, b, c).
#[inline(always)]
fn cross(a: &[f64; 2], b: &[f64; 2], c: &[f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

const TRIPLES: [(usize, usize, usize); 4] = [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)];

/// A sample can give a homography only if no 3 of its points are collinear in either set and
/// every triangle keeps (or every triangle flips) its orientation: a homography with all four
/// points in front of the camera maps orientations consistently. Half of all random samples
/// fail this, for the price of eight cross products.
#[inline]
pub fn sample_is_valid(src: &[[f64; 2]; 4], dst: &[[f64; 2]; 4], min_area: f64) -> bool {
    let mut sign = 0.0;
    for (i, j, k) in TRIPLES {
        let a = cross(&src[i], &src[j], &src[k]);
        let b = cross(&dst[i], &dst[j], &dst[k]);
        if !(a.abs() > min_area && b.abs() > min_area) {
            return false;
        }
        let s = (a * b).signum();
        if sign == 0.0 {
            sign = s;
        } else if s != sign {
            return false;
        }
    }
    true
}

/// The homography (row-major, 9 entries) through the 4 correspondences, oriented so the
/// sample's points have w > 0; None when the system is singular.
pub fn four_point(src: &[[f64; 2]; 4], dst: &[[f64; 2]; 4]) -> Option<[f64; 9]> {
    // Rows: [x y 1 0 0 0 -ux -uy | u] and [0 0 0 x y 1 -vx -vy | v].
    let mut a = [[0.0f64; 9]; 8];
    for i in 0..4 {
        let [x, y] = src[i];
        let [u, v] = dst[i];
        a[2 * i] = [x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, u];
        a[2 * i + 1] = [0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, v];
    }
    // Elimination with partial pivoting.
    for col in 0..8 {
        let mut piv = col;
        let mut best = a[col][col].abs();
        for (row, r) in a.iter().enumerate().skip(col + 1) {
            if r[col].abs() > best {
                best = r[col].abs();
                piv = row;
            }
        }
        if !(best > 1e-12) {
            return None;
        }
        a.swap(col, piv);
        let inv = 1.0 / a[col][col];
        for row in col + 1..8 {
            let f = a[row][col] * inv;
            if f != 0.0 {
                for k in col..9 {
                    a[row][k] -= f * a[col][k];
                }
            }
        }
    }
    let mut h = [0.0f64; 9];
    h[8] = 1.0;
    for row in (0..8).rev() {
        let mut s = a[row][8];
        for k in row + 1..8 {
            s -= a[row][k] * h[k];
        }
        h[row] = s / a[row][row];
    }
    if !h.iter().all(|v| v.is_finite()) {
        return None;
    }
    // Orient: the sample's points in front (w > 0). A consistent sample has one sign of w.
    let w0 = h[6] * src[0][0] + h[7] * src[0][1] + h[8];
    if w0 < 0.0 {
        for v in h.iter_mut() {
            *v = -*v;
        }
    }
    for p in src {
        if !(h[6] * p[0] + h[7] * p[1] + h[8] > 0.0) {
            return None;
        }
    }
    Some(h)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn apply(h: &[f64; 9], p: &[f64; 2]) -> [f64; 2] {
        let w = h[6] * p[0] + h[7] * p[1] + h[8];
        [
            (h[0] * p[0] + h[1] * p[1] + h[2]) / w,
            (h[3] * p[0] + h[4] * p[1] + h[5]) / w,
        ]
    }

    #[test]
    fn maps_the_four_points_exactly() {
        let truth = [1.1, 0.2, 0.1, -0.15, 0.9, -0.05, 0.2, -0.1, 1.0];
        let src = [[-1.0, -0.8], [1.2, -0.9], [0.9, 1.1], [-1.1, 0.7]];
        let dst = src.map(|p| apply(&truth, &p));
        assert!(sample_is_valid(&src, &dst, 1e-9));
        let h = four_point(&src, &dst).unwrap();
        for (p, q) in src.iter().zip(&dst) {
            let r = apply(&h, p);
            assert!((r[0] - q[0]).abs() < 1e-12 && (r[1] - q[1]).abs() < 1e-12);
        }
        for k in 0..9 {
            assert!((h[k] - truth[k]).abs() < 1e-12);
        }
    }

    #[test]
    fn rejects_collinear_and_inconsistent_samples() {
        let sq = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let line = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [0.0, 1.0]];
        assert!(!sample_is_valid(&line, &sq, 1e-9));
        assert!(!sample_is_valid(&sq, &line, 1e-9));
        // Two corners swapped: a "bow tie", no homography with all points in front.
        let twisted = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        assert!(!sample_is_valid(&sq, &twisted, 1e-9));
        // A mirror image is consistent (every orientation flips).
        let mirrored = sq.map(|p| [-p[0], p[1]]);
        assert!(sample_is_valid(&sq, &mirrored, 1e-9));
        assert!(four_point(&sq, &mirrored).is_some());
    }

    #[test]
    fn sample_points_are_in_front() {
        // A homography whose h33 = 1 normalisation leaves the points at w < 0 comes back
        // negated.
        let truth = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 1.0];
        let src = [[-1.0, -0.5], [-0.8, 0.6], [-0.9, 0.1], [-1.3, 0.2]];
        let dst = src.map(|p| apply(&truth, &p));
        let h = four_point(&src, &dst).unwrap();
        assert!(src.iter().all(|p| h[6] * p[0] + h[7] * p[1] + h[8] > 0.0));
    }
}
