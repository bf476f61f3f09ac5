//! Sub-pixel object outlines: each traced outline point moved along its normal to the
//! grey-level edge, then the enclosed area and its centroid.
//!
//! Traced contour pixels sit a pixel or so outside an object's edge and are quantised to whole
//! pixels; beside a raised part's dark walls they wander between the top's edge and the
//! wall's. The steepest grey-level change across the outline does not: it is found on a
//! profile sampled along the normal (bilinear, every `STEP` px within `REACH` px) as the
//! centroid of the slope peak above half its height. (A parabola through the largest slope
//! and its neighbours cannot place an edge inside a pixel: along an axis the bilinear profile
//! is straight within a pixel, its slopes tie, and the parabola snaps to a sample. On noisy
//! discs the centroid's centres are 4x closer, 0.010 against 0.041 px.) The centroid needs no
//! finer sampling than half a pixel: the region is smoothed to a sigma of at least 1 px, and
//! on those discs every 0.25 px gives the same mean error to 1e-4 px, at twice the cost. This is the per-frame hot spot of
//! object location, hence in the core, its profiles sampled four at a time with AVX2, in f64
//! (f32 is no faster: the gathers, not the arithmetic, set the pace).

use crate::Point;

/// How far either side of a traced point its edge is looked for, px, and the sampling step.
pub const REACH: f64 = 3.0;
pub const STEP: f64 = 0.5;
/// Samples per profile: -REACH to REACH inclusive.
const SAMPLES: usize = 13;
const _: () = assert!((SAMPLES - 1) as f64 * STEP == 2.0 * REACH);
/// The tangent at a point spans this many points either side: steady on a pixel staircase.
const TANGENT_SPAN: usize = 3;
/// Outlines shorter than this are too coarse for normals: left as traced.
pub const MIN_POINTS: usize = 12;

/// A grey image (row-major f32, e.g. a lightly smoothed region around one object).
#[derive(Clone, Copy)]
pub struct Grey<'a> {
    pub pixels: &'a [f32],
    pub width: usize,
    pub height: usize,
}

impl Grey<'_> {
    /// Bilinear sample at (x, y) known to lie inside [0, w - 1) x [0, h - 1): no clamping.
    #[inline(always)]
    fn sample_inside(&self, x: f64, y: f64) -> f64 {
        let w = self.width;
        // floor() is one instruction with AVX and stays in the float registers (an integer's
        // round trip through cvtsi2sd chains every sample to the one before).
        let (xf, yf) = (x.floor(), y.floor());
        let (x0, y0) = (xf as usize, yf as usize);
        let (fx, fy) = (x - xf, y - yf);
        let i = y0 * w + x0;
        // One bounds check for the 2 x 2 block (x0 + 1 < w and y0 + 1 < h by the caller).
        let (row0, row1) = (&self.pixels[i..i + 2], &self.pixels[i + w..i + w + 2]);
        let top = row0[0] as f64 * (1.0 - fx) + row0[1] as f64 * fx;
        let bottom = row1[0] as f64 * (1.0 - fx) + row1[1] as f64 * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Bilinear sample at (x, y), clamped to the image (at least 2 x 2).
    #[inline(always)]
    fn sample(&self, x: f64, y: f64) -> f64 {
        let (w, h) = (self.width, self.height);
        let x = x.clamp(0.0, (w - 1) as f64);
        let y = y.clamp(0.0, (h - 1) as f64);
        let x0 = (x.floor() as usize).min(w - 2);
        let y0 = (y.floor() as usize).min(h - 2);
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let p = |r: usize, c: usize| self.pixels[r * w + c] as f64;
        let top = p(y0, x0) * (1.0 - fx) + p(y0, x0 + 1) * fx;
        let bottom = p(y0 + 1, x0) * (1.0 - fx) + p(y0 + 1, x0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// Moves each outline point (in the image's coordinates) to its edge, in place. Points whose
/// steepest change is at either end of their profile or whose profile is flat (no edge near
/// them), or whose tangent is undefined, stay where they are. Returns false (and changes nothing) when the outline is
/// too short or the image smaller than 2 x 2.
pub fn refine_outline(grey: Grey<'_>, outline: &mut [Point]) -> bool {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && grey.pixels.len() < i32::MAX as usize {
        // SAFETY: the CPU supports AVX2, checked just above, and pixel indices fit an i32.
        return unsafe { refine_outline_avx2(grey, outline) };
    }
    refine_outline_body(grey, outline, |p, n, profile| {
        profile_inside(grey, p, n, profile)
    })
}

/// The same search compiled with AVX2 (VEX encodings: the float <-> integer conversions carry
/// no false dependency from one sample to the next), its profiles sampled four at a time
/// (`profile_inside_avx2`). No FMA: the bits are those of the plain build.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn refine_outline_avx2(grey: Grey<'_>, outline: &mut [Point]) -> bool {
    refine_outline_body(grey, outline, |p, n, profile| {
        // SAFETY: AVX2 is enabled here; the body calls this only for profiles whose ends lie
        // inside the image, and pixel indices fit an i32 (checked by the caller).
        unsafe { profile_inside_avx2(grey, p, n, profile) }
    })
}

type Profile = [f64; SAMPLES];

/// The offsets along the normal of a profile's samples.
const OFFSETS: Profile = {
    let mut s = [0.0; SAMPLES];
    let mut j = 0;
    while j < SAMPLES {
        s[j] = -REACH + j as f64 * STEP;
        j += 1;
    }
    s
};

/// The samples the vectorised profile takes four at a time (the last is taken on its own).
const GROUPED: usize = SAMPLES - 1;
const _: () = assert!(GROUPED.is_multiple_of(4));

/// The profile through `p` along `n`, both of whose ends lie inside [0, w - 1) x [0, h - 1).
#[inline(always)]
fn profile_inside(grey: Grey<'_>, p: Point, n: [f64; 2], profile: &mut Profile) {
    for (v, s) in profile.iter_mut().zip(OFFSETS) {
        *v = grey.sample_inside(p[0] + s * n[0], p[1] + s * n[1]);
    }
}

/// profile_inside, four samples at a time (the last on its own): each sample's two pixel pairs (top and bottom
/// row) are gathered as one 64-bit load each, then interpolated in the same operations, in
/// the same order, as `Grey::sample_inside` (the same bits).
///
/// # Safety
/// AVX2 must be available; both ends of the profile must lie inside [0, w - 1) x [0, h - 1)
/// (every sample then lies between them, so x0 + 1 < w and y0 + 1 < h); the image's pixel
/// count must fit an i32.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn profile_inside_avx2(grey: Grey<'_>, p: Point, n: [f64; 2], profile: &mut Profile) {
    use std::arch::x86_64::*;
    let base = grey.pixels.as_ptr() as *const i64;
    let (px, py) = (_mm256_set1_pd(p[0]), _mm256_set1_pd(p[1]));
    let (nx, ny) = (_mm256_set1_pd(n[0]), _mm256_set1_pd(n[1]));
    let one = _mm256_set1_pd(1.0);
    let width = _mm_set1_epi32(grey.width as i32);
    let row = _mm256_set1_epi64x(grey.width as i64);
    // [l0 r0 l1 r1 l2 r2 l3 r3] -> [l0 l1 l2 l3 r0 r1 r2 r3]
    let split = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
    let groups = profile[..GROUPED].chunks_exact_mut(4);
    for (out, s) in groups.zip(OFFSETS[..GROUPED].chunks_exact(4)) {
        let s = _mm256_loadu_pd(s.as_ptr());
        let x = _mm256_add_pd(px, _mm256_mul_pd(s, nx));
        let y = _mm256_add_pd(py, _mm256_mul_pd(s, ny));
        let (xf, yf) = (_mm256_floor_pd(x), _mm256_floor_pd(y));
        let (fx, fy) = (_mm256_sub_pd(x, xf), _mm256_sub_pd(y, yf));
        let index = _mm_add_epi32(
            _mm_mullo_epi32(_mm256_cvttpd_epi32(yf), width),
            _mm256_cvttpd_epi32(xf),
        );
        let index = _mm256_cvtepi32_epi64(index);
        // Pixels i and i + 1, then i + w and i + w + 1, as one 8-byte load each (scale 4: a
        // pixel is 4 bytes).
        let top = _mm256_i64gather_epi64::<4>(base, index);
        let bottom = _mm256_i64gather_epi64::<4>(base, _mm256_add_epi64(index, row));
        let top = _mm256_permutevar8x32_ps(_mm256_castsi256_ps(top), split);
        let bottom = _mm256_permutevar8x32_ps(_mm256_castsi256_ps(bottom), split);
        let lerp = |pair: __m256, f: __m256d| {
            let left = _mm256_cvtps_pd(_mm256_castps256_ps128(pair));
            let right = _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(pair));
            _mm256_add_pd(
                _mm256_mul_pd(left, _mm256_sub_pd(one, f)),
                _mm256_mul_pd(right, f),
            )
        };
        let (t, b) = (lerp(top, fx), lerp(bottom, fx));
        let v = _mm256_add_pd(
            _mm256_mul_pd(t, _mm256_sub_pd(one, fy)),
            _mm256_mul_pd(b, fy),
        );
        _mm256_storeu_pd(out.as_mut_ptr(), v);
    }
    let last = OFFSETS[GROUPED];
    profile[GROUPED] = grey.sample_inside(p[0] + last * n[0], p[1] + last * n[1]);
}

#[inline(always)]
fn refine_outline_body(
    grey: Grey<'_>,
    outline: &mut [Point],
    inside: impl Fn(Point, [f64; 2], &mut Profile),
) -> bool {
    let n = outline.len();
    if n < MIN_POINTS || grey.width < 2 || grey.height < 2 {
        return false;
    }
    if grey.pixels.len() != grey.width * grey.height {
        return false;
    }
    let traced = outline.to_vec();
    let mut profile: Profile = [0.0; SAMPLES];
    // Strictly below the last pixel centre, so x0 + 1 and y0 + 1 stay in the image.
    let wmax = (grey.width - 1) as f64;
    let hmax = (grey.height - 1) as f64;
    for i in 0..n {
        // Around the closed outline (n > TANGENT_SPAN), without a division.
        let ahead = traced[if i + TANGENT_SPAN < n {
            i + TANGENT_SPAN
        } else {
            i + TANGENT_SPAN - n
        }];
        let behind = traced[if i >= TANGENT_SPAN {
            i - TANGENT_SPAN
        } else {
            i + n - TANGENT_SPAN
        }];
        let (tx, ty) = (ahead[0] - behind[0], ahead[1] - behind[1]);
        let len = (tx * tx + ty * ty).sqrt();
        if !(len > 0.0) {
            continue;
        }
        let (nx, ny) = (ty / len, -tx / len);
        let p = traced[i];
        // The profile's ends: when both are well inside, no sample needs clamping (the
        // samples lie on the segment between them).
        let (ax, ay) = (p[0] - REACH * nx, p[1] - REACH * ny);
        let (bx, by) = (p[0] + REACH * nx, p[1] + REACH * ny);
        let within = |x: f64, y: f64| x >= 0.0 && y >= 0.0 && x < wmax && y < hmax;
        if within(ax, ay) && within(bx, by) {
            inside(p, [nx, ny], &mut profile);
        } else {
            for (v, s) in profile.iter_mut().zip(OFFSETS) {
                *v = grey.sample(p[0] + s * nx, p[1] + s * ny);
            }
        }
        // The largest |slope| between neighbouring samples, the first if tied.
        let mut best = 0;
        let mut best_slope = f64::NEG_INFINITY;
        let slope = |j: usize| (profile[j + 1] - profile[j]).abs();
        for j in 0..SAMPLES - 1 {
            let sl = slope(j);
            if sl > best_slope {
                best_slope = sl;
                best = j;
            }
        }
        // A flat profile has no edge: its slopes are the interpolation's rounding (1e-16 of
        // the grey level), nothing to follow.
        if best == 0 || best == SAMPLES - 2 || !(best_slope > 1e-9 * profile[best].abs()) {
            continue;
        }
        // The centroid of the slope peak above half its height: the contiguous run of slopes
        // about the largest (a second edge beyond a dip below half is not this one), each
        // weighted by its height above half. The slope between samples j and j + 1 sits half
        // a step past sample j.
        let half = 0.5 * best_slope;
        let (mut lo, mut hi) = (best, best);
        while lo > 0 && slope(lo - 1) > half {
            lo -= 1;
        }
        while hi + 1 < SAMPLES - 1 && slope(hi + 1) > half {
            hi += 1;
        }
        let (mut sw, mut sj) = (0.0, 0.0);
        for j in lo..=hi {
            let w = slope(j) - half;
            sw += w;
            sj += w * j as f64;
        }
        let centre = if sw > 0.0 { sj / sw } else { best as f64 };
        let at = -REACH + (centre + 0.5) * STEP;
        outline[i] = [p[0] + at * nx, p[1] + at * ny];
    }
    true
}

/// Area (absolute) and centroid of a closed polygon by the shoelace formula; the mean of the
/// points when the area is zero.
pub fn area_centroid(polygon: &[Point]) -> (f64, Point) {
    let n = polygon.len();
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let [x, y] = polygon[i];
        let [xn, yn] = polygon[(i + 1) % n];
        let cross = x * yn - xn * y;
        a += cross;
        cx += (x + xn) * cross;
        cy += (y + yn) * cross;
    }
    if a == 0.0 || n == 0 {
        let k = n.max(1) as f64;
        let sx: f64 = polygon.iter().map(|p| p[0]).sum();
        let sy: f64 = polygon.iter().map(|p| p[1]).sum();
        return (0.0, [sx / k, sy / k]);
    }
    let area = 0.5 * a;
    ((area).abs(), [cx / (6.0 * area), cy / (6.0 * area)])
}

/// The central second moments of the area a closed polygon encloses, over that area:
/// [mu20, mu11, mu02] / area, in the polygon's units squared (px^2), by Green's theorem over
/// its edges (the area's own moments, as OpenCV's cv2.moments gives them for a contour, not
/// the scatter of its vertices, which would weigh a side by how densely it is sampled). The
/// same for either winding. Zeros for a polygon enclosing no area (a point or a line: no
/// axis to speak of).
pub fn central_moments(polygon: &[Point]) -> [f64; 3] {
    let n = polygon.len();
    if n < 3 {
        return [0.0; 3];
    }
    // About the vertices' mean: the sums then do not cancel digits the polygon's position
    // in the image would cost (a part 1000 px from the origin, 20 px across).
    let k = n as f64;
    let mx = polygon.iter().map(|p| p[0]).sum::<f64>() / k;
    let my = polygon.iter().map(|p| p[1]).sum::<f64>() / k;
    let (mut a, mut sx, mut sy, mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for i in 0..n {
        let (x, y) = (polygon[i][0] - mx, polygon[i][1] - my);
        let next = polygon[if i + 1 < n { i + 1 } else { 0 }];
        let (xn, yn) = (next[0] - mx, next[1] - my);
        let cross = x * yn - xn * y;
        a += cross;
        sx += (x + xn) * cross;
        sy += (y + yn) * cross;
        sxx += (x * x + x * xn + xn * xn) * cross;
        syy += (y * y + y * yn + yn * yn) * cross;
        sxy += (x * yn + 2.0 * x * y + 2.0 * xn * yn + xn * y) * cross;
    }
    if !(a != 0.0 && a.is_finite()) {
        return [0.0; 3];
    }
    // Twice the signed area; the raw moments over the area: the winding's sign cancels.
    let (cx, cy) = (sx / (3.0 * a), sy / (3.0 * a));
    let (xx, xy, yy) = (sxx / (6.0 * a), sxy / (12.0 * a), syy / (6.0 * a));
    [xx - cx * cx, xy - cx * cy, yy - cy * cy]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bright disc of radius r about (cx, cy) on a darker background, its edge blurred
    /// (a logistic profile, symmetric like a lens's blur), sampled on a w x h grid.
    fn disc(w: usize, h: usize, c: Point, r: f64) -> Vec<f32> {
        let mut img = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let d = (x as f64 - c[0]).hypot(y as f64 - c[1]) - r;
                let v = 100.0 + 70.0 / (1.0 + (d / 0.7).exp());
                img[y * w + x] = v as f32;
            }
        }
        img
    }

    #[test]
    fn a_disc_outline_moves_to_its_edge_and_its_centroid_is_the_centre() {
        let (w, h, c, r) = (80, 70, [40.3, 33.7], 15.0);
        let img = disc(w, h, c, r);
        // A traced outline a pixel outside the edge, on whole pixels.
        let mut outline: Vec<Point> = (0..120)
            .map(|k| {
                let t = k as f64 / 120.0 * std::f64::consts::TAU;
                [
                    (c[0] + (r + 1.2) * t.cos()).round(),
                    (c[1] + (r + 1.2) * t.sin()).round(),
                ]
            })
            .collect();
        outline.dedup();
        let grey = Grey {
            pixels: &img,
            width: w,
            height: h,
        };
        assert!(refine_outline(grey, &mut outline));
        for p in &outline {
            let d = (p[0] - c[0]).hypot(p[1] - c[1]);
            // Bilinear profiles put each point's edge within half a pixel; the centroid
            // averages that out.
            assert!((d - r).abs() < 0.5, "{d}");
        }
        let (area, centre) = area_centroid(&outline);
        assert!(
            (centre[0] - c[0]).abs() < 0.05 && (centre[1] - c[1]).abs() < 0.05,
            "{centre:?}"
        );
        assert!((area / (std::f64::consts::PI * r * r) - 1.0).abs() < 0.03);
    }

    #[test]
    fn the_vectorised_search_gives_the_plain_search_s_bits() {
        // A noisy disc, points near and at the border (clamped profiles), a flat patch.
        let (w, h, c, r) = (64, 48, [30.2, 25.9], 17.0);
        let mut img = disc(w, h, c, r);
        for (i, v) in img.iter_mut().enumerate() {
            *v += ((i * 7919) % 13) as f32 * 0.37;
        }
        for row in 0..10 {
            img[row * w..row * w + 20].fill(120.0);
        }
        let outline: Vec<Point> = (0..150)
            .map(|k| {
                let t = k as f64 / 150.0 * std::f64::consts::TAU;
                [c[0] + (r + 0.9) * t.cos(), c[1] + (r + 0.9) * t.sin()]
            })
            .chain((0..20).map(|k| [k as f64 * 0.7, 0.4 + k as f64 * 0.2]))
            .collect();
        let grey = Grey {
            pixels: &img,
            width: w,
            height: h,
        };
        let mut plain = outline.clone();
        assert!(refine_outline_body(grey, &mut plain, |p, n, profile| {
            profile_inside(grey, p, n, profile)
        }));
        let mut fast = outline.clone();
        assert!(refine_outline(grey, &mut fast));
        assert_eq!(plain, fast);
        assert_ne!(plain, outline);
    }

    #[test]
    fn points_on_a_flat_image_stay_where_they_are() {
        let img = vec![77.0f32; 40 * 30];
        let grey = Grey {
            pixels: &img,
            width: 40,
            height: 30,
        };
        let outline: Vec<Point> = (0..40)
            .map(|k| {
                let t = k as f64 / 40.0 * std::f64::consts::TAU;
                [20.3 + 9.0 * t.cos(), 15.1 + 9.0 * t.sin()]
            })
            .collect();
        let mut moved = outline.clone();
        assert!(refine_outline(grey, &mut moved));
        assert_eq!(moved, outline);
    }

    #[test]
    fn short_outlines_and_tiny_images_are_left_alone() {
        let img = vec![0.0f32; 4];
        let mut few = vec![[0.0, 0.0]; 5];
        let grey = Grey {
            pixels: &img,
            width: 2,
            height: 2,
        };
        assert!(!refine_outline(grey, &mut few));
        let square = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
        let (a, c) = area_centroid(&square);
        assert_eq!((a, c), (4.0, [1.0, 1.0]));
    }

    /// The moments' principal axis, degrees in [-90, 90), from +x towards +y.
    fn axis_deg(m: [f64; 3]) -> f64 {
        let a = 0.5 * (2.0 * m[1]).atan2(m[0] - m[2]).to_degrees();
        if a >= 90.0 {
            a - 180.0
        } else {
            a
        }
    }

    /// `local` turned by `deg` and moved to `at`.
    fn placed(local: &[Point], deg: f64, at: Point) -> Vec<Point> {
        let (s, c) = deg.to_radians().sin_cos();
        local
            .iter()
            .map(|p| [at[0] + c * p[0] - s * p[1], at[1] + s * p[0] + c * p[1]])
            .collect()
    }

    #[test]
    fn a_turned_rectangle_has_its_known_moments_and_axis() {
        // L x W: variances L^2 / 12 along its length, W^2 / 12 across, far from the origin.
        let (l, w) = (30.0, 12.0);
        let local = [
            [-l / 2.0, -w / 2.0],
            [l / 2.0, -w / 2.0],
            [l / 2.0, w / 2.0],
            [-l / 2.0, w / 2.0],
        ];
        for deg in [-89.0, -60.0, -12.5, 0.0, 33.0, 45.0, 71.0] {
            let poly = placed(&local, deg, [1500.25, 900.5]);
            let m = central_moments(&poly);
            let (s, c) = f64::to_radians(deg).sin_cos();
            let (big, small) = (l * l / 12.0, w * w / 12.0);
            let want = [
                big * c * c + small * s * s,
                (big - small) * s * c,
                big * s * s + small * c * c,
            ];
            for (got, want) in m.iter().zip(want) {
                assert!((got - want).abs() < 1e-9, "{deg}: {m:?} {want}");
            }
            assert!((axis_deg(m) - deg).abs() < 1e-9, "{deg}");
            // Clockwise, the same.
            let mut back = poly.clone();
            back.reverse();
            let r = central_moments(&back);
            assert!(r.iter().zip(m).all(|(a, b)| (a - b).abs() < 1e-9));
        }
    }

    #[test]
    fn an_ellipse_polygon_has_its_axis_and_a_disc_none() {
        // A 2:1 ellipse (semi-axes 20, 10) in 720 vertices: variances a^2 / 4, b^2 / 4.
        let ellipse: Vec<Point> = (0..720)
            .map(|k| {
                let t = k as f64 / 720.0 * std::f64::consts::TAU;
                [20.0 * t.cos(), 10.0 * t.sin()]
            })
            .collect();
        for deg in [-75.0, -30.0, 10.0, 88.0] {
            let m = central_moments(&placed(&ellipse, deg, [300.0, 200.0]));
            let (l1, l2) = eigen(m);
            assert!((l1 / 100.0 - 1.0).abs() < 1e-4 && (l2 / 25.0 - 1.0).abs() < 1e-4);
            assert!((axis_deg(m) - deg).abs() < 1e-9, "{deg}: {m:?}");
        }
        // A disc's (and a regular polygon's) moments are isotropic: no axis.
        let disc: Vec<Point> = (0..360)
            .map(|k| {
                let t = k as f64 / 360.0 * std::f64::consts::TAU;
                [50.0 + 15.0 * t.cos(), 40.0 + 15.0 * t.sin()]
            })
            .collect();
        let m = central_moments(&disc);
        assert!((m[0] - m[2]).abs() < 1e-9 && m[1].abs() < 1e-9, "{m:?}");
        assert!((m[0] / (15.0 * 15.0 / 4.0) - 1.0).abs() < 1e-3);
    }

    /// The eigenvalues of [[m0, m1], [m1, m2]], largest first.
    fn eigen(m: [f64; 3]) -> (f64, f64) {
        let (mean, half) = (
            0.5 * (m[0] + m[2]),
            (0.25 * (m[0] - m[2]).powi(2) + m[1] * m[1]).sqrt(),
        );
        (mean + half, mean - half)
    }

    #[test]
    fn degenerate_polygons_have_zero_moments() {
        assert_eq!(central_moments(&[]), [0.0; 3]);
        assert_eq!(central_moments(&[[1.0, 2.0], [3.0, 4.0]]), [0.0; 3]);
        let line = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]];
        assert_eq!(central_moments(&line), [0.0; 3]);
        assert_eq!(
            central_moments(&[[f64::NAN, 0.0], [1.0, 0.0], [0.0, 1.0]]),
            [0.0; 3]
        );
    }
}
