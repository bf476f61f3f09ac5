//! Sub-pixel centres of a board's dark dots from their grey levels, every dot in one call: the
//! per-dot work of board detection (planarcal.calib.dot_centres), which in Python cost about 1.5 ms
//! a dot.
//!
//! Each dot's centre is the centroid of its darkness, 1 - pixel / background, divided by the
//! ink's darkness and clipped to [0, 1], over a disc around the dot, where the background is a
//! plane fitted (robustly) to a ring of paper around it and the ink's darkness is the median of
//! the disc's darkest quarter. Edge pixels count by how much ink they see, so the estimate is
//! sub-pixel without thresholds. Where the dot's solid pixels show that the ink's light is not
//! the paper's scaled (flare and sheen on a real photograph), the ink gets a plane of its own.
//! Three passes: each sizes the dot and re-centres the disc on it.
//!
//! The windows follow each dot's own size, not the grid's pitch; pixels near the other dots
//! (their radius * 1.1 + 1.5 px) are left out of both the disc and the ring, so dots that
//! nearly touch do not pull each other. A dot that cannot be measured keeps the centre it came
//! with, and its [`DotStatus`] says why.
//!
//! The arithmetic is that of the Python implementation it replaces (NumPy's percentile and
//! median, OpenCV's float32 Gaussian blur and 3 x 3 dilation), so the centres agree with it to
//! rounding.

use std::cmp::Ordering;
use std::f64::consts::PI;

use nalgebra::{Matrix3, Vector2, Vector3};
use rayon::prelude::*;

use crate::smooth::reflect_101;
use crate::threads::pool_allowed;
use crate::Point;

/// Pixels within a neighbouring dot's radius times this, plus [`NEIGHBOUR_MARGIN_PX`], are
/// that dot's (its measured size may be a little small; blur spreads its ink).
pub const NEIGHBOUR_RADIUS_SCALE: f64 = 1.1;
/// See [`NEIGHBOUR_RADIUS_SCALE`], px.
pub const NEIGHBOUR_MARGIN_PX: f64 = 1.5;

/// Each pass sizes the dot and re-centres the windows on it.
const PASSES: usize = 3;
/// Fits of the ring's plane, each dropping the pixels far below the one before.
const PLANE_FITS: usize = 3;
/// The MAD of normal noise times this is its standard deviation.
const MAD_TO_SIGMA: f64 = 1.4826;
/// Ring pixels this many (robust) standard deviations below the plane are not paper.
const REJECT_SIGMAS: f64 = 3.0;
const MIN_RING_PIXELS: usize = 6;
const MIN_INSIDE_PIXELS: usize = 4;
/// The ink must darken the paper by more than this fraction.
const MIN_CONTRAST: f64 = 0.05;
/// On the smoothed coverage: above SOLID is ink, below CLEAR is paper, between is the edge.
const SOLID: f64 = 0.8;
const CLEAR: f64 = 0.2;
/// The ink's own plane needs this many solid pixels (see [`ink_plane`]) ...
const MIN_INK_PLANE_PIXELS: usize = 12;
/// ... and a slope this far from the paper's scaled (chi-square, 2 dof, p = 0.001).
const INK_PLANE_CHI2: f64 = 13.82;
/// From this many dots on, the thread pool: a dot of 20 px costs some 50 us, more than waking
/// the pool (measured on two cores: 2 dots, 33 us a dot against 83 us on one thread).
const PARALLEL_MIN_DOTS: usize = 2;

/// A grey image in which the dots are dark, row-major, `width` pixels a row; the pixel type is
/// any that converts to f64 exactly (f32, f64, u8).
#[derive(Clone, Copy)]
pub struct InkImage<'a, T> {
    /// `width * height` grey levels.
    pub pixels: &'a [T],
    /// Pixels a row.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

/// Whether a dot was refined and, if not, why.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum DotStatus {
    /// Its centre and area were measured.
    Refined = 0,
    /// Its disc reaches beyond the image.
    CutByBorder = 1,
    /// Fewer than 6 pixels of its ring are free of other dots and inside the image.
    NoPaper = 2,
    /// Fewer than 4 pixels of its disc are free of other dots.
    TooSmall = 3,
    /// Its darkest quarter is not 5 % darker than the paper around it.
    NoContrast = 4,
    /// No pixel of its disc carries any ink.
    NoInk = 5,
    /// Its measured centre moved farther from the starting point than the dot is large.
    LedAway = 6,
}

impl DotStatus {
    /// Every status, by code.
    pub const ALL: [DotStatus; 7] = [
        DotStatus::Refined,
        DotStatus::CutByBorder,
        DotStatus::NoPaper,
        DotStatus::TooSmall,
        DotStatus::NoContrast,
        DotStatus::NoInk,
        DotStatus::LedAway,
    ];

    /// The status as a number (0 = refined), the binding's encoding.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// Why the dot was not refined, as a phrase ("cut by the image border").
    pub fn reason(self) -> &'static str {
        match self {
            DotStatus::Refined => "refined",
            DotStatus::CutByBorder => "cut by the image border",
            DotStatus::NoPaper => "no paper around it",
            DotStatus::TooSmall => "too small to measure",
            DotStatus::NoContrast => "no contrast with its background",
            DotStatus::NoInk => "no ink",
            DotStatus::LedAway => "its grey levels lead away from it",
        }
    }
}

/// One dot's measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DotCentre {
    /// The centre, px; the starting point where not refined.
    pub centre: Point,
    /// The ink's area, px^2 (coverage-weighted); pi r^2 of the starting size where not refined.
    pub area: f64,
    /// Refined, or why not.
    pub status: DotStatus,
}

/// Input that cannot be measured at all (a dot that cannot be is a [`DotStatus`], not an
/// error).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DotCentresError {
    /// The image has no pixels.
    #[error("the image must have at least one pixel, got {width} x {height}")]
    EmptyImage { width: usize, height: usize },

    /// The pixel buffer does not hold width x height pixels.
    #[error("the image's {pixels} pixels do not fill {width} x {height}")]
    ImageSize {
        pixels: usize,
        width: usize,
        height: usize,
    },

    /// Points and diameters differ in number.
    #[error("there must be one diameter per point: {points} points, {diameters} diameters")]
    LengthMismatch { points: usize, diameters: usize },

    /// A starting point is NaN or infinite.
    #[error("point {index} is not finite: ({x}, {y})")]
    NonFinitePoint { index: usize, x: f64, y: f64 },

    /// A diameter is negative, NaN or infinite.
    #[error("diameter {index} must be a finite number of pixels >= 0, got {value}")]
    InvalidDiameter { index: usize, value: f64 },
}

/// The sub-pixel centre and ink area of each dark dot starting at `points` with approximate
/// `diameters` (px; a blob's size is enough), in the order given. Dots are measured in
/// parallel when there are enough of them; the results do not depend on it.
pub fn refine_dot_centres<T: Copy + Into<f64> + Sync>(
    image: InkImage<'_, T>,
    points: &[Point],
    diameters: &[f64],
) -> Result<Vec<DotCentre>, DotCentresError> {
    let (width, height) = (image.width, image.height);
    if width == 0 || height == 0 {
        return Err(DotCentresError::EmptyImage { width, height });
    }
    if width.checked_mul(height) != Some(image.pixels.len()) {
        return Err(DotCentresError::ImageSize {
            pixels: image.pixels.len(),
            width,
            height,
        });
    }
    if points.len() != diameters.len() {
        return Err(DotCentresError::LengthMismatch {
            points: points.len(),
            diameters: diameters.len(),
        });
    }
    if let Some((index, p)) = points
        .iter()
        .enumerate()
        .find(|(_, p)| !(p[0].is_finite() && p[1].is_finite()))
    {
        return Err(DotCentresError::NonFinitePoint {
            index,
            x: p[0],
            y: p[1],
        });
    }
    if let Some((index, &value)) = diameters
        .iter()
        .enumerate()
        .find(|(_, d)| !(d.is_finite() && **d >= 0.0))
    {
        return Err(DotCentresError::InvalidDiameter { index, value });
    }
    let radii: Vec<f64> = diameters.iter().map(|d| 0.5 * d).collect();
    let measure = |scratch: &mut Scratch, k: usize| measure_dot(image, points, &radii, k, scratch);
    let n = points.len();
    let found = if n >= PARALLEL_MIN_DOTS && pool_allowed() {
        (0..n)
            .into_par_iter()
            .map_init(Scratch::default, measure)
            .collect()
    } else {
        let mut scratch = Scratch::default();
        (0..n).map(|k| measure(&mut scratch, k)).collect()
    };
    Ok(found)
}

/// Buffers one dot's measurement needs, reused from dot to dot.
#[derive(Default)]
struct Scratch {
    /// The other dots whose pixels could reach this one's windows: x, y, exclusion radius.
    neighbours: Vec<[f64; 3]>,
    /// Per window pixel, row-major: RING / INSIDE flags.
    class: Vec<u8>,
    /// Per window pixel: the grey level.
    grey: Vec<f64>,
    /// Per window pixel: the darkness.
    darkness: Vec<f64>,
    /// The ring's pixels (grey level, dx, dy), their residuals from the plane and whether the
    /// next fit keeps them.
    ring: Vec<[f64; 3]>,
    resid: Vec<f64>,
    keep: Vec<bool>,
    /// Values being ranked (percentile, medians), as rank keys.
    ranked: Vec<u64>,
    /// Per window pixel: the coverage by the ink.
    coverage: Vec<f64>,
    /// Coverage and its smoothing (f32, as OpenCV blurs it), and the blur's first pass.
    cover: Vec<f32>,
    smooth: Vec<f32>,
    across: Vec<f32>,
    /// Per window pixel: in the edge band, then in the band widened by a pixel.
    band: Vec<bool>,
    wide: Vec<bool>,
    /// The dilation's first pass.
    rows: Vec<bool>,
}

const RING: u8 = 1;
const INSIDE: u8 = 2;

/// Dot `k`, its failures as a status.
fn measure_dot<T: Copy + Into<f64>>(
    image: InkImage<'_, T>,
    points: &[Point],
    radii: &[f64],
    k: usize,
    scratch: &mut Scratch,
) -> DotCentre {
    let (start, radius) = (points[k], radii[k]);
    // The dots whose pixels could reach this one's windows.
    scratch.neighbours.clear();
    for (j, (p, &r)) in points.iter().zip(radii).enumerate() {
        let reach = 3.0 * radius + 2.0 * r + 8.0;
        if j != k && distance_cmp(p[0] - start[0], p[1] - start[1], reach) == Some(Ordering::Less) {
            let exclusion = r * NEIGHBOUR_RADIUS_SCALE + NEIGHBOUR_MARGIN_PX;
            scratch.neighbours.push([p[0], p[1], exclusion]);
        }
    }
    match refine_fast(image, start, radius, scratch) {
        Ok((centre, area)) => DotCentre {
            centre,
            area,
            status: DotStatus::Refined,
        },
        Err(status) => DotCentre {
            centre: start,
            area: PI * radius * radius,
            status,
        },
    }
}

/// [`refine_one`], compiled for AVX2 where the CPU has it (twice the lanes a vector
/// instruction; no fused multiply-adds, so the same bits as the plain build).
fn refine_fast<T: Copy + Into<f64>>(
    image: InkImage<'_, T>,
    start: Point,
    radius: f64,
    s: &mut Scratch,
) -> Result<(Point, f64), DotStatus> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        return unsafe { refine_avx2(image, start, radius, s) };
    }
    refine_one(image, start, radius, s)
}

/// [`refine_one`] for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn refine_avx2<T: Copy + Into<f64>>(
    image: InkImage<'_, T>,
    start: Point,
    radius: f64,
    s: &mut Scratch,
) -> Result<(Point, f64), DotStatus> {
    refine_one(image, start, radius, s)
}

/// The three passes over one dot (its neighbours in `scratch.neighbours`): its centre and ink
/// area, or why not.
#[inline(always)]
fn refine_one<T: Copy + Into<f64>>(
    image: InkImage<'_, T>,
    start: Point,
    radius: f64,
    s: &mut Scratch,
) -> Result<(Point, f64), DotStatus> {
    let (w, h) = (image.width, image.height);
    let [mut cx, mut cy] = start;
    let mut radius = radius.max(1.0);
    let mut total = 0.0;
    for _ in 0..PASSES {
        let ring_in = radius + (0.3 * radius).max(2.0);
        let ring_out = ring_in + (0.3 * radius).max(2.5);
        // The disc must be in the image; the ring may be cut by the border.
        if !(cx - ring_in >= 0.0
            && cy - ring_in >= 0.0
            && cx + ring_in <= (w - 1) as f64
            && cy + ring_in <= (h - 1) as f64)
        {
            return Err(DotStatus::CutByBorder);
        }
        // Whole pixels, clamped to the image (the disc test above keeps them ordered).
        let x0 = (cx - ring_out).floor().max(0.0) as usize;
        let x1 = ((cx + ring_out).ceil() + 1.0).min(w as f64) as usize;
        let y0 = (cy - ring_out).floor().max(0.0) as usize;
        let y1 = ((cy + ring_out).ceil() + 1.0).min(h as f64) as usize;
        let win = Window {
            x0,
            y0,
            width: x1 - x0,
            height: y1 - y0,
        };
        classify(win, [cx, cy], ring_in, ring_out, s);
        let ring_count = s.class.iter().filter(|&&c| c == RING).count();
        let inside_count = s.class.iter().filter(|&&c| c == INSIDE).count();
        if ring_count < MIN_RING_PIXELS {
            return Err(DotStatus::NoPaper);
        }
        if inside_count < MIN_INSIDE_PIXELS {
            return Err(DotStatus::TooSmall);
        }
        // The grey levels, then the ring's plane.
        s.grey.clear();
        for y in y0..y1 {
            let row = &image.pixels[y * w + x0..y * w + x1];
            s.grey.extend(row.iter().map(|&v| v.into()));
        }
        let paper = ring_plane(win, [cx, cy], s);
        darkness(win, [cx, cy], paper, &s.grey, &mut s.darkness);
        let Some(core) = ink_level(s) else {
            return Err(DotStatus::NoContrast);
        };
        let (sum, sx, sy) = ink_weights(win, [cx, cy], paper, core, s);
        total = sum;
        if !(total > 0.0) {
            return Err(DotStatus::NoInk);
        }
        cx = sx / total;
        cy = sy / total;
        radius = (total / PI).sqrt();
    }
    let moved = (cx - start[0]).hypot(cy - start[1]);
    if !(cx.is_finite() && cy.is_finite()) || moved > (0.75 * radius).max(2.0) {
        return Err(DotStatus::LedAway);
    }
    Ok(([cx, cy], total))
}

/// The pixels [x0, x0 + width) x [y0, y0 + height) of one pass.
#[derive(Clone, Copy)]
struct Window {
    x0: usize,
    y0: usize,
    width: usize,
    height: usize,
}

impl Window {
    fn len(&self) -> usize {
        self.width * self.height
    }
}

/// Marks each window pixel RING (ring_in <= r <= ring_out from the centre), INSIDE (r <
/// ring_in) or neither, leaving out the neighbours' pixels.
#[inline(always)]
fn classify(win: Window, centre: Point, ring_in: f64, ring_out: f64, s: &mut Scratch) {
    let [cx, cy] = centre;
    let (inner, outer) = (Reach::new(ring_in), Reach::new(ring_out));
    s.class.clear();
    s.class.reserve(win.len());
    for row in 0..win.height {
        let dy = (win.y0 + row) as f64 - cy;
        s.class.extend((0..win.width).map(|col| {
            let dx = (win.x0 + col) as f64 - cx;
            match inner.cmp(dx, dy) {
                Some(Ordering::Less) => INSIDE,
                Some(_) => match outer.cmp(dx, dy) {
                    Some(Ordering::Greater) | None => 0,
                    Some(_) => RING,
                },
                None => 0,
            }
        }));
    }
    // A neighbour's pixels (distance <= its exclusion radius) are neither; only its bounding
    // box can hold any.
    for &[ox, oy, reach] in &s.neighbours {
        let theirs = Reach::new(reach);
        let clamp = |v: f64, lo: usize, n: usize| (v.max(lo as f64) as usize).min(lo + n) - lo;
        let c0 = clamp((ox - reach).floor() - 1.0, win.x0, win.width);
        let c1 = clamp((ox + reach).ceil() + 2.0, win.x0, win.width);
        let r0 = clamp((oy - reach).floor() - 1.0, win.y0, win.height);
        let r1 = clamp((oy + reach).ceil() + 2.0, win.y0, win.height);
        for row in r0..r1 {
            let dy = (win.y0 + row) as f64 - oy;
            for col in c0..c1 {
                let dx = (win.x0 + col) as f64 - ox;
                if theirs.cmp(dx, dy) != Some(Ordering::Greater) {
                    s.class[row * win.width + col] = 0;
                }
            }
        }
    }
}

/// hypot(dx, dy) compared with `t`, as libm's hypot (which NumPy's calls) compares.
fn distance_cmp(dx: f64, dy: f64, t: f64) -> Option<Ordering> {
    Reach::new(t).cmp(dx, dy)
}

/// A distance `t` to compare hypot(dx, dy) with, quickly: the squared distance decides unless
/// it is within a relative 1e-9 of t^2 (far beyond the rounding of either), where hypot itself
/// does.
#[derive(Clone, Copy)]
struct Reach {
    t: f64,
    below: f64,
    above: f64,
}

impl Reach {
    fn new(t: f64) -> Reach {
        let (below, above) = if t > 1e-100 && t < 1e100 {
            (t * t * (1.0 - 1e-9), t * t * (1.0 + 1e-9))
        } else {
            (f64::NEG_INFINITY, f64::INFINITY)
        };
        Reach { t, below, above }
    }

    #[inline(always)]
    fn cmp(&self, dx: f64, dy: f64) -> Option<Ordering> {
        let d2 = dx * dx + dy * dy;
        if d2 < self.below {
            Some(Ordering::Less)
        } else if d2 > self.above {
            Some(Ordering::Greater)
        } else {
            dx.hypot(dy).partial_cmp(&self.t)
        }
    }
}

/// The plane a + b dx + c dy fitted to the ring's grey levels (in `s.grey`), ignoring dark
/// intruders (a neighbouring dot, the board's edge, a printed mark): pixels far below a fit
/// (3 robust standard deviations) are dropped and the plane refitted, up to three fits.
#[inline(always)]
fn ring_plane(win: Window, centre: Point, s: &mut Scratch) -> Vector3<f64> {
    let [cx, cy] = centre;
    s.ring.clear();
    let rows = s
        .class
        .chunks_exact(win.width)
        .zip(s.grey.chunks_exact(win.width));
    for (row, (class, values)) in rows.enumerate() {
        let dy = (win.y0 + row) as f64 - cy;
        for (col, (&c, &v)) in class.iter().zip(values).enumerate() {
            if c == RING {
                s.ring.push([v, (win.x0 + col) as f64 - cx, dy]);
            }
        }
    }
    s.keep.clear();
    s.keep.resize(s.ring.len(), true);
    let mut coef = Vector3::zeros();
    for _ in 0..PLANE_FITS {
        coef = least_squares_plane(&s.ring, &s.keep);
        s.resid.clear();
        s.resid.extend(
            s.ring
                .iter()
                .map(|&[v, dx, dy]| v - (coef[0] + dx * coef[1] + dy * coef[2])),
        );
        s.ranked.clear();
        s.ranked.extend(
            s.resid
                .iter()
                .zip(&s.keep)
                .filter(|(_, &k)| k)
                .map(|(r, _)| rank_key(r.abs())),
        );
        let spread = MAD_TO_SIGMA * median(&mut s.ranked) + 1e-6;
        let floor = -REJECT_SIGMAS * spread;
        let kept = s.resid.iter().filter(|&&r| r > floor).count();
        let same = s.resid.iter().zip(&s.keep).all(|(&r, &k)| (r > floor) == k);
        if kept < MIN_RING_PIXELS || same {
            break;
        }
        for (k, &r) in s.keep.iter_mut().zip(&s.resid) {
            *k = r > floor;
        }
    }
    coef
}

/// The least-squares plane through the kept ring pixels (value, dx, dy): the normal
/// equations, solved by Cholesky; a (near-)singular system (the pixels on one line) gets the
/// minimum-norm solution, as NumPy's lstsq gives.
fn least_squares_plane(ring: &[[f64; 3]], keep: &[bool]) -> Vector3<f64> {
    let mut ata = Matrix3::zeros();
    let mut atb = Vector3::zeros();
    for (&[v, dx, dy], _) in ring.iter().zip(keep).filter(|(_, &k)| k) {
        let a = Vector3::new(1.0, dx, dy);
        ata += a * a.transpose();
        atb += a * v;
    }
    // Scaled to a unit diagonal, a well-posed system has pivots of order 1.
    let d = Vector3::from_fn(|i, _| {
        let v = ata[(i, i)];
        if v > 0.0 {
            1.0 / v.sqrt()
        } else {
            0.0
        }
    });
    let scaled = Matrix3::from_fn(|i, j| ata[(i, j)] * d[i] * d[j]);
    if d.iter().all(|&v| v > 0.0) {
        if let Some(chol) = scaled.cholesky() {
            let l = chol.l();
            if (0..3).all(|i| l[(i, i)] * l[(i, i)] > 1e-20) {
                let y = chol.solve(&atb.component_mul(&d));
                return y.component_mul(&d);
            }
        }
    }
    // The pseudo-inverse of the normal matrix, tiny eigenvalues dropped.
    match ata.try_symmetric_eigen(1e-15, 200) {
        Some(eig) => {
            let largest = eig.eigenvalues.iter().fold(0.0f64, |m, &v| m.max(v.abs()));
            let mut x = Vector3::zeros();
            for i in 0..3 {
                let l = eig.eigenvalues[i];
                if l.abs() > largest * 1e-12 && l != 0.0 {
                    let u = eig.eigenvectors.column(i);
                    x += u * (u.dot(&atb) / l);
                }
            }
            if x.iter().all(|v| v.is_finite()) {
                x
            } else {
                Vector3::zeros()
            }
        }
        None => Vector3::zeros(),
    }
}

/// Each pixel's darkness from its grey level: 1 - pixel / background where the background
/// plane is positive, else 0.
#[inline(always)]
fn darkness(win: Window, centre: Point, plane: Vector3<f64>, grey: &[f64], out: &mut Vec<f64>) {
    out.clear();
    out.extend(window_points(win, centre).zip(grey).map(|((dx, dy), &v)| {
        let background = at(plane, dx, dy);
        1.0 - if background > 0.0 {
            v / background
        } else {
            1.0
        }
    }));
}

/// A plane a + b dx + c dy at (dx, dy), summed in that order.
#[inline(always)]
fn at(plane: Vector3<f64>, dx: f64, dy: f64) -> f64 {
    plane[0] + plane[1] * dx + plane[2] * dy
}

/// Each window pixel's (dx, dy) from the centre, row-major.
#[inline(always)]
fn window_points(win: Window, centre: Point) -> impl Iterator<Item = (f64, f64)> {
    let [cx, cy] = centre;
    (0..win.height).flat_map(move |row| {
        let dy = (win.y0 + row) as f64 - cy;
        (0..win.width).map(move |col| ((win.x0 + col) as f64 - cx, dy))
    })
}

/// The ink's darkness: the median of the disc's pixels at or above their 75th percentile;
/// None without contrast.
#[inline(always)]
fn ink_level(s: &mut Scratch) -> Option<f64> {
    s.ranked.clear();
    s.ranked.extend(
        s.class
            .iter()
            .zip(&s.darkness)
            .filter(|(&c, _)| c == INSIDE)
            .map(|(_, &v)| rank_key(v)),
    );
    if s.ranked.iter().any(|&k| !from_key(k).is_finite()) {
        return None;
    }
    let p75 = percentile(&mut s.ranked, 0.75);
    s.ranked.retain(|&k| from_key(k) >= p75);
    let core = median(&mut s.ranked);
    (core > MIN_CONTRAST).then_some(core)
}

/// Coverage of each disc pixel by the ink, and its sums: (total, sum of x * weight, sum of y *
/// weight).
///
/// Only the edge band carries sub-pixel information; the interior counts as exactly 1 and the
/// outside as exactly 0, so sensor noise there adds nothing. The three are told apart on a
/// smoothed copy of the coverage (sigma 1 px), where noise cannot flip them; the band
/// (smoothed coverage 0.2 to 0.8, widened by a pixel) keeps each pixel's measured, linear
/// coverage.
///
/// The coverage is first the darkness over the ink's (`core`), which takes the ink to be the
/// paper's light scaled, as a rendering has it. On a photograph it need not be (flare, the
/// camera's black level, the ink's sheen add light of their own), and then a light gradient
/// pulls the centre; where the solid pixels show it ([`ink_plane`]), the coverage is
/// (paper - pixel) / (paper - ink) between the paper's plane and the ink's own.
#[inline(always)]
fn ink_weights(
    win: Window,
    centre: Point,
    paper: Vector3<f64>,
    core: f64,
    s: &mut Scratch,
) -> (f64, f64, f64) {
    s.coverage.clear();
    s.coverage
        .extend(s.darkness.iter().map(|&d| (d / core).clamp(0.0, 1.0)));
    smooth_coverage(win, s);
    if let Some(ink) = ink_plane(win, centre, paper, core, s) {
        s.coverage.clear();
        s.coverage.extend(
            window_points(win, centre)
                .zip(&s.grey)
                .map(|((dx, dy), &v)| {
                    let background = at(paper, dx, dy);
                    let c = (background - v) / (background - at(ink, dx, dy));
                    if c.is_nan() {
                        0.0
                    } else {
                        c.clamp(0.0, 1.0)
                    }
                }),
        );
        smooth_coverage(win, s);
    }
    s.band.clear();
    s.band.extend(s.smooth.iter().map(|&v| {
        // Neither solid nor clear (NaN included, as in NumPy).
        let (solid, clear) = (v as f64 > SOLID, (v as f64) < CLEAR);
        !(solid || clear)
    }));
    dilate3x3(&s.band, win.width, win.height, &mut s.wide, &mut s.rows);
    let (mut total, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for row in 0..win.height {
        let (y, span) = (
            (win.y0 + row) as f64,
            row * win.width..(row + 1) * win.width,
        );
        let (mut line_total, mut line_x) = (0.0, 0.0);
        let pixels = s.class[span.clone()]
            .iter()
            .zip(&s.wide[span.clone()])
            .zip(&s.coverage[span.clone()])
            .zip(&s.smooth[span]);
        for (col, (((&c, &wide), &coverage), &smooth)) in pixels.enumerate() {
            if c != INSIDE {
                continue;
            }
            let weight = if wide {
                coverage
            } else if smooth as f64 > SOLID {
                1.0
            } else {
                0.0
            };
            line_total += weight;
            line_x += weight * (win.x0 + col) as f64;
        }
        total += line_total;
        sx += line_x;
        sy += line_total * y;
    }
    (total, sx, sy)
}

/// The plane through the grey levels of the disc's solid pixels (smoothed coverage above
/// SOLID), when the data call for it: at least [`MIN_INK_PLANE_PIXELS`] of them, and a slope
/// that differs from what the paper's light scaled by the ink gives, (1 - core) times the
/// paper's slope, beyond the fit's own noise ([`INK_PLANE_CHI2`]). Otherwise None: a small
/// dot's few solid pixels, or a rendering whose ink is the paper's light scaled, keep the
/// ratio, which is exact there and steadier.
fn ink_plane(
    win: Window,
    centre: Point,
    paper: Vector3<f64>,
    core: f64,
    s: &mut Scratch,
) -> Option<Vector3<f64>> {
    s.ring.clear();
    let pixels = window_points(win, centre)
        .zip(&s.grey)
        .zip(s.class.iter().zip(&s.smooth));
    for (((dx, dy), &v), (&c, &smooth)) in pixels {
        if c == INSIDE && smooth as f64 > SOLID {
            s.ring.push([v, dx, dy]);
        }
    }
    let count = s.ring.len();
    if count < MIN_INK_PLANE_PIXELS {
        return None;
    }
    s.keep.clear();
    s.keep.resize(count, true);
    let ink = least_squares_plane(&s.ring, &s.keep);
    let mut normal = Matrix3::zeros();
    let mut squares = 0.0;
    for &[v, dx, dy] in &s.ring {
        let a = Vector3::new(1.0, dx, dy);
        normal += a * a.transpose();
        squares += (v - a.dot(&ink)).powi(2);
    }
    let variance = squares / (count - 3) as f64;
    let gap = Vector2::new(ink[1], ink[2]) - (1.0 - core) * Vector2::new(paper[1], paper[2]);
    // A singular covariance (no noise at all) makes any gap significant.
    let chi2 = normal
        .try_inverse()
        .map(|inv| inv.fixed_view::<2, 2>(1, 1) * variance)
        .and_then(|cov| cov.try_inverse())
        .map_or(f64::INFINITY, |info| gap.dot(&(info * gap)));
    (chi2 > INK_PLANE_CHI2).then_some(ink)
}

/// The coverage in f32, blurred into `s.smooth`.
#[inline(always)]
fn smooth_coverage(win: Window, s: &mut Scratch) {
    s.cover.clear();
    s.cover.extend(s.coverage.iter().map(|&c| c as f32));
    gaussian_blur_sigma1(
        &s.cover,
        win.width,
        win.height,
        &mut s.smooth,
        &mut s.across,
    );
}

/// OpenCV's Gaussian kernel for sigma 1 px in float32 (cv2.getGaussianKernel(9, 1.0,
/// cv2.CV_32F)): exp(-k^2 / 2), k = -4..4, normalised as OpenCV does, to the last bit.
fn gaussian_kernel() -> [f32; 9] {
    let v: [f64; 4] = std::array::from_fn(|i| {
        let x = 2.0 * i as f64 - 8.0;
        (x * x * -0.125).exp()
    });
    let sum = (v[0] + v[1] + v[2] + v[3]) * 2.0 + 1.0;
    let mul = 1.0 / sum;
    let side: [f32; 4] = v.map(|t| (t * mul) as f32);
    [
        side[0], side[1], side[2], side[3], mul as f32, side[3], side[2], side[1], side[0],
    ]
}

/// cv2.GaussianBlur(input, (0, 0), 1.0) of a `width` x `height` float32 image into `out`, in
/// OpenCV's arithmetic: a 9-tap kernel, borders mirrored (BORDER_REFLECT_101), a horizontal
/// pass summing the taps left to right, then a vertical pass summing symmetric pairs outwards
/// from the centre, all in f32; an image one pixel wide (or high) is not blurred that way.
/// OpenCV's SIMD builds may differ in the last bit (they fuse multiply-adds).
#[inline(always)]
fn gaussian_blur_sigma1(
    input: &[f32],
    width: usize,
    height: usize,
    out: &mut Vec<f32>,
    across: &mut Vec<f32>,
) {
    let k = gaussian_kernel();
    across.clear();
    if width == 1 {
        across.extend_from_slice(input);
    } else {
        let mut line = vec![0.0f32; width + 8];
        for row in input.chunks_exact(width) {
            // The row, mirrored 4 pixels past either end.
            line[4..4 + width].copy_from_slice(row);
            for j in (0..4).chain(width + 4..width + 8) {
                line[j] = row[reflect_101(j as isize - 4, width)];
            }
            // acc = k0 v0, then acc += k_t v_t for t = 1..8, pixel by pixel (vectorised across
            // pixels, not reordered).
            let start = across.len();
            across.extend(line[..width].iter().map(|&v| k[0] * v));
            let acc = &mut across[start..];
            for t in 1..9 {
                for (a, &v) in acc.iter_mut().zip(&line[t..t + width]) {
                    *a += k[t] * v;
                }
            }
        }
    }
    out.clear();
    if height == 1 {
        out.extend_from_slice(across);
        return;
    }
    for y in 0..height {
        let row = |t: isize| {
            let r = reflect_101(y as isize + t, height);
            &across[r * width..(r + 1) * width]
        };
        let start = out.len();
        out.extend(row(0).iter().map(|&v| k[4] * v));
        let acc = &mut out[start..];
        for t in 1..5 {
            let (below, above) = (row(t as isize), row(-(t as isize)));
            for ((a, &b), &c) in acc.iter_mut().zip(below).zip(above) {
                *a += k[4 + t] * (b + c);
            }
        }
    }
}

/// cv2.dilate of a mask by a 3 x 3 square: a pixel is set when any of its neighbours within
/// the image is (pixels outside count as unset); `across` holds the first pass.
#[inline(always)]
fn dilate3x3(
    mask: &[bool],
    width: usize,
    height: usize,
    out: &mut Vec<bool>,
    across: &mut Vec<bool>,
) {
    across.clear();
    across.extend_from_slice(mask);
    for (line, row) in across.chunks_exact_mut(width).zip(mask.chunks_exact(width)) {
        for (o, &v) in line[1..].iter_mut().zip(row) {
            *o |= v;
        }
        for (o, &v) in line.iter_mut().zip(&row[1..]) {
            *o |= v;
        }
    }
    out.clear();
    out.resize(mask.len(), false);
    for (y, line) in out.chunks_exact_mut(width).enumerate() {
        for r in y.saturating_sub(1)..(y + 2).min(height) {
            for (o, &v) in line.iter_mut().zip(&across[r * width..(r + 1) * width]) {
                *o |= v;
            }
        }
    }
}

/// A key whose unsigned order is the order of the numbers (-0 just below +0; NaN beyond the
/// infinities): ranking integers is quicker than ranking floats.
fn rank_key(v: f64) -> u64 {
    let bits = v.to_bits();
    if bits >> 63 == 1 {
        !bits
    } else {
        bits | 1 << 63
    }
}

/// The number of a [`rank_key`].
fn from_key(key: u64) -> f64 {
    f64::from_bits(if key >> 63 == 1 {
        key & !(1 << 63)
    } else {
        !key
    })
}

/// The q-quantile (0 <= q <= 1) of the numbers whose [`rank_key`]s are `keys` as NumPy's
/// percentile computes it by default (linear interpolation between the two ranks around
/// (n - 1) q, NumPy's formula to the last bit); `keys` are reordered. NaN when empty; the
/// numbers must not be NaN.
fn percentile(keys: &mut [u64], q: f64) -> f64 {
    let n = keys.len();
    if n == 0 {
        return f64::NAN;
    }
    let virtual_index = (n - 1) as f64 * q;
    let lo = virtual_index.floor();
    let gamma = virtual_index - lo;
    let lo = (lo as usize).min(n - 1);
    let (_, &mut a, above) = keys.select_nth_unstable(lo);
    let b = above.iter().copied().min().unwrap_or(a);
    let (a, b) = (from_key(a), from_key(b));
    let diff = b - a;
    if gamma >= 0.5 {
        b - diff * (1.0 - gamma)
    } else {
        a + diff * gamma
    }
}

/// The median of the numbers whose [`rank_key`]s are `keys` as NumPy computes it (the mean of
/// the two middle values of an even count; NaN if any is NaN, or none); `keys` are reordered.
fn median(keys: &mut [u64]) -> f64 {
    let n = keys.len();
    if n == 0 || keys.iter().any(|&k| from_key(k).is_nan()) {
        return f64::NAN;
    }
    let (below, &mut upper, _) = keys.select_nth_unstable(n / 2);
    if n % 2 == 1 {
        from_key(upper)
    } else {
        let lower = below.iter().copied().max().unwrap_or(upper);
        (from_key(lower) + from_key(upper)) / 2.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PAPER: f64 = 200.0;
    const INK: f64 = 40.0;

    /// A w x h image of paper with dark discs (centre, radius), each pixel's ink the disc's
    /// area over it (16 x 16 samples a pixel).
    fn render(w: usize, h: usize, discs: &[(Point, f64)]) -> Vec<f32> {
        let mut px = vec![PAPER as f32; w * h];
        for &([cx, cy], r) in discs {
            let (x0, x1) = ((cx - r - 2.0).max(0.0) as usize, (cx + r + 3.0) as usize);
            let (y0, y1) = ((cy - r - 2.0).max(0.0) as usize, (cy + r + 3.0) as usize);
            for y in y0..y1.min(h) {
                for x in x0..x1.min(w) {
                    let mut hits = 0;
                    for i in 0..16 {
                        for j in 0..16 {
                            let sx = x as f64 - 0.5 + (j as f64 + 0.5) / 16.0;
                            let sy = y as f64 - 0.5 + (i as f64 + 0.5) / 16.0;
                            if (sx - cx).hypot(sy - cy) < r {
                                hits += 1;
                            }
                        }
                    }
                    let cover = hits as f64 / 256.0;
                    px[y * w + x] -= ((PAPER - INK) * cover) as f32;
                }
            }
        }
        px
    }

    fn image(px: &[f32], w: usize, h: usize) -> InkImage<'_, f32> {
        InkImage {
            pixels: px,
            width: w,
            height: h,
        }
    }

    #[test]
    fn a_disc_is_found_at_its_centre_and_its_area() {
        let (w, h) = (80, 70);
        for (c, r) in [
            ([40.3, 33.7], 10.0),
            ([35.55, 36.21], 6.5),
            ([41.9, 30.05], 2.0),
        ] {
            let px = render(w, h, &[(c, r)]);
            let start = [c[0].round() + 0.4, c[1].round() - 0.4];
            let found = refine_dot_centres(image(&px, w, h), &[start], &[2.0 * r]).unwrap();
            let dot = found[0];
            assert_eq!(dot.status, DotStatus::Refined);
            let err = (dot.centre[0] - c[0]).hypot(dot.centre[1] - c[1]);
            assert!(err < 0.01, "r = {r}: centre off by {err} px");
            let area = PI * r * r;
            assert!(
                (dot.area - area).abs() < 0.03 * area,
                "{} vs {area}",
                dot.area
            );
        }
    }

    #[test]
    fn light_of_its_own_on_the_ink_does_not_pull_a_dot() {
        // A photograph's grey level: light (a gradient of 2 % a pixel) times the reflectance,
        // plus flare that does not scale with it, so the ink is not the paper's light scaled.
        let (w, h) = (80, 70);
        let (c, r) = ([40.3, 33.7], 10.0);
        let flat = render(w, h, &[(c, r)]);
        let px: Vec<f32> = flat
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let cover = (PAPER - v as f64) / (PAPER - INK);
                let light = 1.0 + 0.02 * ((i % w) as f64 - c[0]);
                (light * (20.0 * cover + 200.0 * (1.0 - cover)) + 40.0) as f32
            })
            .collect();
        let start = [c[0].round() + 0.4, c[1].round() - 0.4];
        let dot = refine_dot_centres(image(&px, w, h), &[start], &[2.0 * r]).unwrap()[0];
        assert_eq!(dot.status, DotStatus::Refined);
        let err = (dot.centre[0] - c[0]).hypot(dot.centre[1] - c[1]);
        assert!(err < 0.01, "centre off by {err} px");
    }

    #[test]
    fn a_neighbour_close_by_does_not_pull_a_dot() {
        let (w, h) = (90, 60);
        let (a, b) = ([35.3, 30.6], [59.8, 30.2]);
        let px = render(w, h, &[(a, 10.0), (b, 10.0)]);
        let found = refine_dot_centres(
            image(&px, w, h),
            &[[35.0, 31.0], [60.0, 30.0]],
            &[20.0, 20.0],
        )
        .unwrap();
        for (dot, c) in found.iter().zip([a, b]) {
            assert_eq!(dot.status, DotStatus::Refined);
            assert!((dot.centre[0] - c[0]).hypot(dot.centre[1] - c[1]) < 0.01);
        }
    }

    #[test]
    fn dots_that_cannot_be_measured_keep_their_start_and_say_why() {
        let (w, h) = (80, 70);
        let px = render(w, h, &[([3.0, 35.0], 6.0), ([50.0, 35.0], 6.0)]);
        let blank = vec![PAPER as f32; w * h];
        let cases: [(&[f32], Point, f64, DotStatus); 4] = [
            (&px, [3.0, 35.0], 12.0, DotStatus::CutByBorder),
            (&blank, [40.0, 35.0], 12.0, DotStatus::NoContrast),
            // Starting between the dots, far from both: the window sees no ink of its own.
            (&px, [26.0, 35.0], 4.0, DotStatus::NoContrast),
            (&px, [50.0, 35.0], 12.0, DotStatus::Refined),
        ];
        for (pixels, start, d, want) in cases {
            let dot = refine_dot_centres(image(pixels, w, h), &[start], &[d]).unwrap()[0];
            assert_eq!(dot.status, want, "{start:?}");
            if want != DotStatus::Refined {
                assert_eq!(dot.centre, start);
                assert_eq!(dot.area, PI * d * d / 4.0);
            }
        }
        // A dot walled in by neighbours on every side: its ring is all theirs.
        let ring: Vec<Point> = (0..12)
            .map(|i| {
                let t = i as f64 / 12.0 * std::f64::consts::TAU;
                [40.0 + 9.0 * t.cos(), 35.0 + 9.0 * t.sin()]
            })
            .collect();
        let mut points = vec![[40.0, 35.0]];
        points.extend(&ring);
        let mut diameters = vec![8.0];
        diameters.extend(vec![6.0; ring.len()]);
        let found = refine_dot_centres(image(&blank, w, h), &points, &diameters).unwrap();
        assert_eq!(found[0].status, DotStatus::NoPaper);
        // A dot no larger than its neighbours' margins.
        let points = [[40.0, 35.0], [41.0, 35.0]];
        let found = refine_dot_centres(image(&blank, w, h), &points, &[1.0, 6.0]).unwrap();
        assert_eq!(found[0].status, DotStatus::TooSmall);
    }

    #[test]
    fn a_start_on_another_dot_leads_away() {
        // Starting beside a small dot, on paper: its ink pulls the centre onto it, farther
        // than the dot is large (a blob that was not a dot, next to one).
        let (w, h) = (80, 70);
        let px = render(w, h, &[([40.0, 35.0], 3.0)]);
        let start = [44.5, 35.0];
        let dot = refine_dot_centres(image(&px, w, h), &[start], &[6.0]).unwrap()[0];
        assert_eq!(dot.status, DotStatus::LedAway);
        assert_eq!(dot.centre, start);
    }

    #[test]
    fn bad_input_is_an_error() {
        let px = vec![0.0f32; 12];
        let img = image(&px, 4, 3);
        assert_eq!(
            refine_dot_centres(image(&px, 0, 3), &[], &[]),
            Err(DotCentresError::EmptyImage {
                width: 0,
                height: 3
            })
        );
        assert!(matches!(
            refine_dot_centres(image(&px, 5, 3), &[], &[]),
            Err(DotCentresError::ImageSize { .. })
        ));
        assert!(matches!(
            refine_dot_centres(img, &[[1.0, 1.0]], &[]),
            Err(DotCentresError::LengthMismatch { .. })
        ));
        assert!(matches!(
            refine_dot_centres(img, &[[1.0, 1.0], [f64::NAN, 1.0]], &[2.0, 2.0]),
            Err(DotCentresError::NonFinitePoint { index: 1, .. })
        ));
        for d in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                refine_dot_centres(img, &[[1.0, 1.0]], &[d]),
                Err(DotCentresError::InvalidDiameter { index: 0, .. })
            ));
        }
        assert_eq!(refine_dot_centres(img, &[], &[]), Ok(vec![]));
        // Dots anywhere (off the image, of size 0) are refused as dots, not as input.
        let found = refine_dot_centres(img, &[[-50.0, 1e9], [1.5, 1.0]], &[0.0, 1e6]).unwrap();
        assert!(found.iter().all(|d| d.status == DotStatus::CutByBorder));
    }

    #[test]
    fn many_dots_give_the_same_answers_in_parallel_and_in_turn() {
        let (w, h) = (200, 160);
        let discs: Vec<(Point, f64)> = (0..20)
            .map(|i| {
                let (r, c) = ((i / 5) as f64, (i % 5) as f64);
                ([30.0 + 35.0 * c + 0.1 * r, 25.0 + 35.0 * r + 0.07 * c], 8.0)
            })
            .collect();
        let px = render(w, h, &discs);
        let points: Vec<Point> = discs
            .iter()
            .map(|(c, _)| [c[0] + 0.5, c[1] - 0.3])
            .collect();
        let diameters = vec![16.0; points.len()];
        let all = refine_dot_centres(image(&px, w, h), &points, &diameters).unwrap();
        for (k, dot) in all.iter().enumerate() {
            let one = refine_dot_centres(image(&px, w, h), &points[k..k + 1], &diameters[k..k + 1])
                .unwrap()[0];
            assert_eq!(one.status, DotStatus::Refined);
            // Alone, no neighbour is masked: the same centre to rounding.
            assert!((one.centre[0] - dot.centre[0]).abs() < 1e-9);
            assert!((dot.centre[0] - discs[k].0[0]).hypot(dot.centre[1] - discs[k].0[1]) < 0.01);
        }
    }

    #[test]
    fn the_avx2_build_gives_the_plain_builds_bits() {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            let (w, h) = (60, 50);
            let mut px = render(w, h, &[([30.4, 24.7], 9.0), ([12.0, 25.0], 4.0)]);
            // Noise from a little LCG, and a lighting gradient.
            let mut state = 12345u64;
            for (i, v) in px.iter_mut().enumerate() {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                *v +=
                    ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 6.0 - (i % w) as f32 * 0.4;
            }
            let img = image(&px, w, h);
            let mut s = Scratch::default();
            s.neighbours.push([12.0, 25.0, 4.0 * 1.1 + 1.5]);
            let plain = refine_one(img, [30.0, 25.0], 9.0, &mut s);
            // SAFETY: the CPU supports AVX2, checked just above.
            let fast = unsafe { refine_avx2(img, [30.0, 25.0], 9.0, &mut s) };
            let bits = |r: Result<(Point, f64), DotStatus>| {
                r.map(|([x, y], a)| [x.to_bits(), y.to_bits(), a.to_bits()])
            };
            assert!(plain.is_ok());
            assert_eq!(bits(plain), bits(fast));
        }
    }

    #[test]
    fn a_plane_through_pixels_on_one_line_is_the_minimum_norm_fit() {
        // dy is 1 throughout: the constant and dy columns are one, and np.linalg.lstsq
        // splits their coefficient evenly: [5, 2, 5].
        let ring: Vec<[f64; 3]> = (-2..4)
            .map(|i| [10.0 + 2.0 * i as f64, i as f64, 1.0])
            .collect();
        let plane = least_squares_plane(&ring, &[true; 6]);
        for (got, want) in plane.iter().zip([5.0, 2.0, 5.0]) {
            assert!((got - want).abs() < 1e-9, "{plane:?}");
        }
        // A full-rank ring: the exact plane.
        let ring: Vec<[f64; 3]> = (0..12)
            .map(|i| {
                let (dx, dy) = ((i % 4) as f64 - 1.5, (i / 4) as f64 - 1.0);
                [100.0 - 3.0 * dx + 0.5 * dy, dx, dy]
            })
            .collect();
        let plane = least_squares_plane(&ring, &[true; 12]);
        assert!((plane - Vector3::new(100.0, -3.0, 0.5)).norm() < 1e-12);
    }

    #[test]
    fn the_kernel_is_opencvs_to_the_bit() {
        // cv2.getGaussianKernel(9, 1.0, cv2.CV_32F).view(np.uint32)
        let want: [u32; 9] = [
            0x390c54e2, 0x3b913926, 0x3d5d25cd, 0x3e77c75d, 0x3ecc4252, 0x3e77c75d, 0x3d5d25cd,
            0x3b913926, 0x390c54e2,
        ];
        assert_eq!(gaussian_kernel().map(f32::to_bits), want);
    }

    #[test]
    fn the_blur_is_a_mirrored_convolution() {
        let (w, h) = (11, 7);
        let input: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 17) as f32 / 17.0).collect();
        let (mut out, mut across) = (Vec::new(), Vec::new());
        gaussian_blur_sigma1(&input, w, h, &mut out, &mut across);
        let k = gaussian_kernel();
        for y in 0..h {
            for x in 0..w {
                let mut want = 0.0f64;
                for i in 0..9 {
                    for j in 0..9 {
                        let yy = reflect_101(y as isize + i as isize - 4, h);
                        let xx = reflect_101(x as isize + j as isize - 4, w);
                        want += k[i] as f64 * k[j] as f64 * input[yy * w + xx] as f64;
                    }
                }
                assert!((out[y * w + x] as f64 - want).abs() < 1e-6);
            }
        }
        // One row: blurred along it only; one pixel: itself.
        gaussian_blur_sigma1(&input[..w], w, 1, &mut out, &mut across);
        assert_eq!(out.len(), w);
        gaussian_blur_sigma1(&[0.25], 1, 1, &mut out, &mut across);
        assert_eq!(out, [0.25]);
    }

    #[test]
    fn dilation_counts_only_pixels_inside() {
        let mask = [
            false, false, false, false, //
            false, false, false, true, //
            false, false, false, false,
        ];
        let mut out = Vec::new();
        dilate3x3(&mask, 4, 3, &mut out, &mut Vec::new());
        let set: Vec<usize> = (0..12).filter(|&i| out[i]).collect();
        assert_eq!(set, [2, 3, 6, 7, 10, 11]);
    }

    #[test]
    fn percentile_and_median_are_numpys() {
        // np.percentile([...], 75), np.median([...])
        let keys = |v: &[f64]| v.iter().map(|&x| rank_key(x)).collect::<Vec<u64>>();
        let mut v = keys(&[3.0, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0, 6.0]);
        assert_eq!(percentile(&mut v, 0.75), 5.25);
        assert_eq!(median(&mut v), 3.5);
        let mut odd = keys(&[7.0, -2.0, 0.5]);
        assert_eq!(percentile(&mut odd, 0.75), 3.75);
        assert_eq!(median(&mut odd), 0.5);
        assert_eq!(percentile(&mut keys(&[2.5]), 0.75), 2.5);
        assert_eq!(median(&mut keys(&[-0.0, -1e-300, f64::INFINITY])), -0.0);
        assert!(median(&mut []).is_nan());
        assert!(median(&mut keys(&[1.0, f64::NAN, 2.0])).is_nan());
        // The keys rank as the numbers do, and give them back.
        let mut numbers = [
            -f64::INFINITY,
            -3.5,
            -1e-300,
            -0.0,
            0.0,
            1e-300,
            2.0,
            f64::INFINITY,
        ];
        let mut shuffled = keys(&[
            2.0,
            -0.0,
            f64::INFINITY,
            -3.5,
            1e-300,
            0.0,
            -f64::INFINITY,
            -1e-300,
        ]);
        shuffled.sort_unstable();
        let back: Vec<f64> = shuffled.iter().map(|&k| from_key(k)).collect();
        numbers.sort_by(f64::total_cmp);
        assert_eq!(
            back.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            numbers.map(f64::to_bits)
        );
    }

    #[test]
    fn distances_compare_as_hypot_does() {
        for (dx, dy, t) in [
            (3.0, 4.0, 5.0),
            (3.0, 4.0, 5.0 + 1e-15),
            (0.1, 0.2, 0.3),
            (1e-200, 0.0, 0.0),
        ] {
            assert_eq!(distance_cmp(dx, dy, t), f64::hypot(dx, dy).partial_cmp(&t));
        }
        assert_eq!(distance_cmp(f64::NAN, 0.0, 1.0), None);
    }
}
