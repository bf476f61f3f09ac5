//! Fast batch mapping of pixels to the plane: the production loop's kernel.
//!
//! `InversePlane::map` is the reference: undistort by Newton's method, then H^-1, with three
//! ways to fail. `PlaneMapper` gives the same answers, and fails on exactly the same points
//! with the same kinds, at a few nanoseconds a point:
//!
//! * The lens inverse is made cheap at construction. The ideal point of a distorted pixel d
//!   is c + (d - c) q, where q = r_u / r_d is a smooth function of t = (|d - c| / scale)^2.
//!   A least-squares polynomial in t approximates q and one to three Newton steps on
//!   q (1 + k1 t q^2 + k2 t^2 q^4) = 1 polish it (each squares the error). The cheapest
//!   (degree, steps) pair whose pixels agree with `RadialLens::undistort` to a tolerance
//!   (1e-10 px, or 1e-13 of the radius beyond 1,000 px) at every radius of a dense grid is
//!   kept. Its domain is the radius the mapper must serve (5 % beyond the image's farthest
//!   corner, as `within_image`), shrunk when the lens folds over near it (the inverse has a
//!   square-root singularity at the fold, where no polynomial converges); pixels beyond it
//!   are undistorted by Newton. If no pair passes, every pixel is.
//! * The kernel is branch-free: AVX2 + FMA registers, eight points at a time in two
//!   independent chains, where the CPU has them (explicit intrinsics: left to itself the
//!   compiler interleaves four chains and spills), else the same arithmetic point by point.
//!   The polynomial runs by Estrin's scheme (a short dependency chain); the last Newton
//!   step's division folds into H^-1's (the step's new q is a fraction num / den, and the
//!   ideal point (c den + (d - c) num, den) is homogeneous), so a point costs one division,
//!   lens or not. Each point is tested against conditions that imply the reference succeeds
//!   on it (inside the domain, comfortably in front of the horizon, a finite result); a point
//!   that fails them is written as NaN and redone by `InversePlane::map` itself, which decides
//!   its value or its failure. So failures, and results at the edge of one, are the
//!   reference's own, by construction.
//! * Every point's result depends on that point alone, and fused multiply-adds are written
//!   out (`mul_add`, correctly rounded in every build): any chunking, any thread count, the
//!   vector or the scalar build, bit for bit.

use std::ops::{Add, BitAnd, Div, Mul};

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::lens::{LensError, RadialLens};
use crate::plane_model::PlaneModel;
use crate::point_failure::{PointFailure, PointReport};
use crate::threads;
use crate::transform::PARALLEL_MIN_POINTS;
use crate::uncertainty::InversePlane;
use crate::Point;

/// Points per parallel task (each task's results are independent of the split).
const CHUNK_POINTS: usize = 8_192;

/// The largest number of polynomial coefficients a kernel evaluates.
const MAX_COEFFICIENTS: usize = 10;

/// The (coefficients, Newton steps) kernels, cheapest first (a degree costs about one
/// multiply-add a point; a Newton step seven operations and, but for the last, a division).
/// Each has two compiled kernels, with and without the k2 term (`dispatch!`, which lists the
/// same pairs).
const CANDIDATES: [(usize, usize); 9] = [
    (4, 1),
    (6, 1),
    (8, 1),
    (10, 1),
    (4, 2),
    (6, 2),
    (8, 2),
    (6, 3),
    (9, 3),
];

/// Radii checked on each of two rays from the lens centre.
const GRID: usize = 4096;

/// The two rays the check grid runs along (unit directions from the lens centre).
const RAYS: [Point; 2] = [[1.0, 0.0], [-0.6, 0.8]];

/// Near the horizon w -> 0 and the mapping is ill-conditioned (w's rounding, a few eps of
/// its scale S = (|m20| + |m21| + |m22|)(1 + |u0| + |u1|), is amplified by S / w). A point is
/// left to the reference unless w exceeds this fraction of S (the reference refuses below
/// 8 eps of it) and lies `HORIZON_PIXELS_PER_ERROR` times the undistortion's tolerance from
/// the horizon. Clean points then agree with the reference to about 1e-9 relative at worst
/// (typically 1e-15); the rest, which map hundreds of times farther than the camera's working
/// area, get the reference's own answers.
const HORIZON_BAND: f64 = 1e-6;
const HORIZON_PIXELS_PER_ERROR: f64 = 1e9;

/// A result beyond this magnitude (mm) is redone by the reference, which rejects overflows.
const LARGE: f64 = 1e300;

/// How a mapper undistorts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Undistortion {
    /// The lens is ideal: pixels go straight through H^-1.
    None,
    /// A polynomial in the squared radius, then Newton steps, out to `radius_px` from the lens
    /// centre; beyond it (where the lens may fold over, or past the image) by Newton.
    Polynomial {
        /// The polynomial's degree in r^2.
        degree: usize,
        /// Newton steps after it.
        newton_steps: usize,
        /// How far from the lens centre it serves, px.
        radius_px: f64,
        /// The largest difference from `RadialLens::undistort` on the check grid, px.
        max_error_px: f64,
        /// What the check required, px.
        tolerance_px: f64,
    },
    /// Newton's method for every point (no polynomial met the tolerance).
    Newton,
}

impl Undistortion {
    /// The choice in words, for reports.
    pub fn describe(&self) -> String {
        match *self {
            Undistortion::None => "none (ideal lens)".into(),
            Undistortion::Polynomial {
                degree,
                newton_steps,
                radius_px,
                max_error_px,
                ..
            } => format!(
                "polynomial of degree {degree} in r^2 + {newton_steps} Newton step{} within \
                 {radius_px:.1} px of the lens centre (max error {max_error_px:.1e} px), Newton \
                 beyond",
                if newton_steps == 1 { "" } else { "s" }
            ),
            Undistortion::Newton => "Newton's method at every point".into(),
        }
    }
}

/// The constants of the fast path.
#[derive(Debug, Clone, Copy)]
struct Fast {
    /// H^-1, rows.
    m: [[f64; 3]; 3],
    /// H^-1 (cx, cy, 1): where the lens centre maps, homogeneous.
    b: [f64; 3],
    /// H^-1's first two columns times the lens scale.
    ms: [[f64; 2]; 3],
    /// |m20| + |m21| + |m22|: the reference's scale of w, per unit of (1 + |u0| + |u1|).
    row2: f64,
    centre: Point,
    /// 1 / scale, and the centre over the scale.
    inv_s: f64,
    centre_s: Point,
    /// 2 k1, 4 k2, 3 k1, 5 k2: the Newton step's coefficients.
    k1x2: f64,
    k2x4: f64,
    k1x3: f64,
    k2x5: f64,
    /// The polynomial undistorts where t <= t_max.
    t_max: f64,
    /// The polynomial kernels' horizon test: w must exceed this times den (`Poly::point`).
    front: f64,
    /// The polynomial in t, constant term first.
    coef: [f64; MAX_COEFFICIENTS],
}

/// The arithmetic a kernel runs on: one f64 (the portable build) or eight in two AVX2
/// registers. Every operation is correctly rounded IEEE arithmetic (fused multiply-adds
/// written out), so both give the same bits.
trait Lane: Copy + Add<Output = Self> + Mul<Output = Self> + Div<Output = Self> {
    type Mask: Copy + BitAnd<Output = Self::Mask>;
    fn splat(v: f64) -> Self;
    /// self * a + b, rounded once.
    fn mul_add(self, a: Self, b: Self) -> Self;
    fn abs(self) -> Self;
    /// self > o (false where either is NaN).
    fn gt(self, o: Self) -> Self::Mask;
}

impl Lane for f64 {
    type Mask = bool;
    #[inline(always)]
    fn splat(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        f64::mul_add(self, a, b)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> bool {
        self > o
    }
}

/// A compiled fast path: pixels to world points, and whether the reference is sure to succeed
/// on each and to agree.
trait FastPath {
    fn point<L: Lane>(f: &Fast, x: L, y: L) -> (L, L, L::Mask);

    /// The undistortion's ratio r_u / r_d at t (the squared distorted radius in units of
    /// the lens scale), as (num, den): den > 0 short of the fold.
    fn ratio<L: Lane>(f: &Fast, t: L) -> (L, L);
}

/// The ideal lens: the pixel straight through H^-1.
struct NoLens;

impl FastPath for NoLens {
    #[inline(always)]
    fn point<L: Lane>(f: &Fast, x: L, y: L) -> (L, L, L::Mask) {
        let s = L::splat;
        let m = &f.m;
        let v0 = s(m[0][0]).mul_add(x, s(m[0][1]).mul_add(y, s(m[0][2])));
        let v1 = s(m[1][0]).mul_add(x, s(m[1][1]).mul_add(y, s(m[1][2])));
        let v2 = s(m[2][0]).mul_add(x, s(m[2][1]).mul_add(y, s(m[2][2])));
        let iw = s(1.0) / v2;
        let (w0, w1) = (v0 * iw, v1 * iw);
        // The reference's own scale. A non-finite pixel makes it or w NaN or infinite, and
        // the tests false.
        let scale = s(f.row2) * (s(1.0) + x.abs() + y.abs());
        let clean = v2.gt(s(HORIZON_BAND) * scale) & s(LARGE).gt(w0.abs() + w1.abs());
        (w0, w1, clean)
    }

    fn ratio<L: Lane>(_: &Fast, _: L) -> (L, L) {
        (L::splat(1.0), L::splat(1.0))
    }
}

/// One Newton step on h(q) = q (1 + k1 a + k2 a^2) - 1, a = t q^2, as a fraction:
/// q - h / h' = (q h' - h) / h' = (1 + q a (2 k1 + 4 k2 a)) / (1 + a (3 k1 + 5 k2 a)).
#[inline(always)]
fn newton<L: Lane, const K2: bool>(f: &Fast, t: L, q: L) -> (L, L) {
    let s = L::splat;
    let a = t * (q * q);
    if K2 {
        let num = (q * a).mul_add(s(f.k2x4).mul_add(a, s(f.k1x2)), s(1.0));
        let den = a.mul_add(s(f.k2x5).mul_add(a, s(f.k1x3)), s(1.0));
        (num, den)
    } else {
        // k2 = 0 (the common one-term lens): two multiply-adds fewer.
        (
            (q * a).mul_add(s(f.k1x2), s(1.0)),
            a.mul_add(s(f.k1x3), s(1.0)),
        )
    }
}

/// The polynomial with coefficients c[..N] (constant first, N <= 10) at t by Estrin's
/// scheme: pairs c[2i] + c[2i + 1] t, then pairs of those with t^2, t^4, t^8; a chain of about
/// log2(N) multiply-adds where Horner's is N long. (N is a constant: the tests fold away.)
#[inline(always)]
fn polynomial<L: Lane, const N: usize>(c: &[f64; MAX_COEFFICIENTS], t: L) -> L {
    if N <= 2 {
        return pair::<L, N>(c, t, 0);
    }
    let t2 = t * t;
    let q0 = pair::<L, N>(c, t, 1).mul_add(t2, pair::<L, N>(c, t, 0));
    if N <= 4 {
        return q0;
    }
    let q1 = if N > 6 {
        pair::<L, N>(c, t, 3).mul_add(t2, pair::<L, N>(c, t, 2))
    } else {
        pair::<L, N>(c, t, 2)
    };
    let t4 = t2 * t2;
    let r0 = q1.mul_add(t4, q0);
    if N <= 8 {
        return r0;
    }
    pair::<L, N>(c, t, 4).mul_add(t4 * t4, r0)
}

/// c[2i] + c[2i + 1] t, or c[2i] alone when it is the last coefficient.
#[inline(always)]
fn pair<L: Lane, const N: usize>(c: &[f64; MAX_COEFFICIENTS], t: L, i: usize) -> L {
    if 2 * i + 1 < N {
        L::splat(c[2 * i + 1]).mul_add(t, L::splat(c[2 * i]))
    } else {
        L::splat(c[2 * i])
    }
}

/// N polynomial coefficients, then STEPS Newton steps; K2: whether the lens has a k2 term.
struct Poly<const N: usize, const STEPS: usize, const K2: bool>;

impl<const N: usize, const STEPS: usize, const K2: bool> FastPath for Poly<N, STEPS, K2> {
    #[inline(always)]
    fn ratio<L: Lane>(f: &Fast, t: L) -> (L, L) {
        let mut q = polynomial::<L, N>(&f.coef, t);
        for _ in 1..STEPS {
            let (num, den) = newton::<L, K2>(f, t, q);
            q = num / den;
        }
        // The last step left as a fraction.
        newton::<L, K2>(f, t, q)
    }

    #[inline(always)]
    fn point<L: Lane>(f: &Fast, x: L, y: L) -> (L, L, L::Mask) {
        let s = L::splat;
        let (dx, dy) = f.offset(x, y);
        let t = dx.mul_add(dx, dy * dy);
        // The ideal point is c + s d num / den: H^-1 takes (c den + s d num, den) to
        // den H^-1 (c, 1) + num (s H^-1) (d, 0), whose second part is ready early.
        let (m, b) = (&f.ms, &f.b);
        let e0 = s(m[0][0]).mul_add(dx, s(m[0][1]) * dy);
        let e1 = s(m[1][0]).mul_add(dx, s(m[1][1]) * dy);
        let e2 = s(m[2][0]).mul_add(dx, s(m[2][1]) * dy);
        let (num, den) = Self::ratio(f, t);
        let v0 = num.mul_add(e0, den * s(b[0]));
        let v1 = num.mul_add(e1, den * s(b[1]));
        let v2 = num.mul_add(e2, den * s(b[2]));
        let iw = s(1.0) / v2;
        let (w0, w1) = (v0 * iw, v1 * iw);
        // A non-finite pixel makes t NaN or infinite: outside. den > 0 short of the fold;
        // then v2 > front den is the reference's w beyond the horizon band.
        let clean = s(f.t_max).gt(t)
            & den.gt(s(0.0))
            & v2.gt(s(f.front) * den)
            & s(LARGE).gt(w0.abs() + w1.abs());
        (w0, w1, clean)
    }
}

/// The AVX2 + FMA lanes: eight f64 at a time, in two registers.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, Div, Mul};

    use super::{Fast, FastPath, Lane};
    use crate::Point;

    // SAFETY (every `unsafe` block below): these are only ever inlined into `chunk`, a
    // function compiled for AVX2 and FMA, which runs only where the CPU has both.

    /// Two vectors of four, each operation applied to both in turn: two independent chains
    /// of dependent operations in flight hide part of their latency (20 % faster than one
    /// here; four spill registers and gain nothing).
    #[derive(Clone, Copy)]
    pub(super) struct V([__m256d; 2]);

    #[derive(Clone, Copy)]
    pub(super) struct M([__m256d; 2]);

    /// Points a block holds.
    const BLOCK: usize = 8;

    macro_rules! pairwise {
        ($f:ident($($arg:expr),+)) => {
            [$f($($arg[0]),+), $f($($arg[1]),+)]
        };
    }

    impl Add for V {
        type Output = Self;
        #[inline(always)]
        fn add(self, o: Self) -> Self {
            // SAFETY: see above.
            V(unsafe { pairwise!(_mm256_add_pd(self.0, o.0)) })
        }
    }

    impl Mul for V {
        type Output = Self;
        #[inline(always)]
        fn mul(self, o: Self) -> Self {
            // SAFETY: see above.
            V(unsafe { pairwise!(_mm256_mul_pd(self.0, o.0)) })
        }
    }

    impl Div for V {
        type Output = Self;
        #[inline(always)]
        fn div(self, o: Self) -> Self {
            // SAFETY: see above.
            V(unsafe { pairwise!(_mm256_div_pd(self.0, o.0)) })
        }
    }

    impl BitAnd for M {
        type Output = Self;
        #[inline(always)]
        fn bitand(self, o: Self) -> Self {
            // SAFETY: see above.
            M(unsafe { pairwise!(_mm256_and_pd(self.0, o.0)) })
        }
    }

    #[inline(always)]
    unsafe fn greater(a: __m256d, b: __m256d) -> __m256d {
        _mm256_cmp_pd::<_CMP_GT_OQ>(a, b)
    }

    impl Lane for V {
        type Mask = M;
        #[inline(always)]
        fn splat(v: f64) -> Self {
            // SAFETY: see above.
            V([unsafe { _mm256_set1_pd(v) }; 2])
        }
        #[inline(always)]
        fn mul_add(self, a: Self, b: Self) -> Self {
            // SAFETY: see above.
            V(unsafe { pairwise!(_mm256_fmadd_pd(self.0, a.0, b.0)) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            let sign = Self::splat(-0.0).0;
            // SAFETY: see above.
            V(unsafe { pairwise!(_mm256_andnot_pd(sign, self.0)) })
        }
        #[inline(always)]
        fn gt(self, o: Self) -> M {
            // SAFETY: see above.
            M(unsafe { pairwise!(greater(self.0, o.0)) })
        }
    }

    /// A block of points: deinterleaved (each vector of four holds points 0, 2, 1, 3 of its
    /// half), mapped, interleaved back (NaN where not clean); whether all were clean.
    #[inline(always)]
    fn block<P: FastPath>(f: &Fast, src: &[Point; BLOCK], out: &mut [Point; BLOCK]) -> bool {
        // SAFETY: see above; the loads and stores stay within the blocks' 2 BLOCK f64.
        unsafe {
            let p = src.as_ptr().cast::<f64>();
            let a = [_mm256_loadu_pd(p), _mm256_loadu_pd(p.add(8))];
            let b = [_mm256_loadu_pd(p.add(4)), _mm256_loadu_pd(p.add(12))];
            let x = V(pairwise!(_mm256_unpacklo_pd(a, b)));
            let y = V(pairwise!(_mm256_unpackhi_pd(a, b)));
            let (V(w0), V(w1), M(clean)) = P::point(f, x, y);
            let nan = [_mm256_set1_pd(f64::NAN); 2];
            let w0 = pairwise!(_mm256_blendv_pd(nan, w0, clean));
            let w1 = pairwise!(_mm256_blendv_pd(nan, w1, clean));
            let lo = pairwise!(_mm256_unpacklo_pd(w0, w1));
            let hi = pairwise!(_mm256_unpackhi_pd(w0, w1));
            let o = out.as_mut_ptr().cast::<f64>();
            _mm256_storeu_pd(o, lo[0]);
            _mm256_storeu_pd(o.add(4), hi[0]);
            _mm256_storeu_pd(o.add(8), lo[1]);
            _mm256_storeu_pd(o.add(12), hi[1]);
            _mm256_movemask_pd(_mm256_and_pd(clean[0], clean[1])) == 0b1111
        }
    }

    /// Maps a chunk a block at a time (the last few points padded), NaN where the fast path
    /// is not sure; returns whether it was sure of all.
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn chunk<P: FastPath>(f: &Fast, src: &[Point], out: &mut [Point]) -> bool {
        let (blocks, src_tail) = src.as_chunks::<BLOCK>();
        let (out_blocks, out_tail) = out.as_chunks_mut::<BLOCK>();
        let mut all = true;
        for (s, o) in blocks.iter().zip(out_blocks.iter_mut()) {
            all &= block::<P>(f, s, o);
        }
        let used = src_tail.len().min(out_tail.len());
        if used > 0 {
            let (mut s, mut o) = ([[0.0; 2]; BLOCK], [[0.0; 2]; BLOCK]);
            s[..used].copy_from_slice(&src_tail[..used]);
            let clean = block::<P>(f, &s, &mut o);
            out_tail[..used].copy_from_slice(&o[..used]);
            // The padding's own verdict does not count.
            all &= clean || o[..used].iter().all(|p| !p[0].is_nan());
        }
        all
    }
}

impl Fast {
    /// A pixel's offset from the lens centre, in units of the lens scale.
    #[inline(always)]
    fn offset<L: Lane>(&self, x: L, y: L) -> (L, L) {
        let s = L::splat;
        (
            x.mul_add(s(self.inv_s), s(-self.centre_s[0])),
            y.mul_add(s(self.inv_s), s(-self.centre_s[1])),
        )
    }

    /// Maps a chunk point by point, NaN where the fast path is not sure; returns whether it
    /// was sure of all.
    fn chunk_portable<P: FastPath>(&self, src: &[Point], out: &mut [Point]) -> bool {
        let mut all = true;
        for (p, o) in src.iter().zip(out.iter_mut()) {
            let (w0, w1, clean) = P::point(self, p[0], p[1]);
            *o = if clean { [w0, w1] } else { [f64::NAN; 2] };
            all &= clean;
        }
        all
    }

    /// The chunk kernel: in AVX2 + FMA registers where the CPU has them, else point by point,
    /// with the same bits either way.
    fn chunk<P: FastPath>(&self, src: &[Point], out: &mut [Point]) -> bool {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA, checked just above.
            return unsafe { avx2::chunk::<P>(self, src, out) };
        }
        self.chunk_portable::<P>(src, out)
    }
}

/// Which compiled kernel a mapper runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kernel {
    NoLens,
    Poly {
        coefficients: usize,
        steps: usize,
        k2: bool,
    },
    /// Every point by the reference.
    Reference,
}

/// Evaluates `$body` with the type `$p` naming the kernel's `FastPath`, or `$otherwise` when
/// the kernel has no compiled fast path. The pairs are `CANDIDATES` (a test checks each has
/// its arms).
macro_rules! dispatch {
    ($kernel:expr, $p:ident => $body:expr, _ => $otherwise:expr) => {
        dispatch!(@arms $kernel, $p, $body, $otherwise,
            (4, 1), (6, 1), (8, 1), (10, 1), (4, 2), (6, 2), (8, 2), (6, 3), (9, 3))
    };
    (@arms $kernel:expr, $p:ident, $body:expr, $otherwise:expr,
        $(($n:literal, $s:literal)),*) => {
        match $kernel {
            Kernel::NoLens => {
                type $p = NoLens;
                $body
            }
            $(Kernel::Poly { coefficients: $n, steps: $s, k2: true } => {
                type $p = Poly<$n, $s, true>;
                $body
            }
            Kernel::Poly { coefficients: $n, steps: $s, k2: false } => {
                type $p = Poly<$n, $s, false>;
                $body
            })*
            _ => $otherwise,
        }
    };
}

/// Pixels -> plane (mm) through a fitted model, fast, over the region of one image.
#[derive(Debug, Clone, Copy)]
pub struct PlaneMapper {
    model: PlaneModel,
    image_size: [f64; 2],
    reference: InversePlane,
    fast: Fast,
    kernel: Kernel,
    undistortion: Undistortion,
}

impl PlaneMapper {
    /// A mapper for pixels of a width x height image: it agrees with
    /// `InversePlane::new(model)?.within_image(width, height)` on every pixel.
    pub fn new(model: &PlaneModel, image_size: [f64; 2]) -> Result<Self, LensError> {
        Self::with_tolerance(model, image_size, None)
    }

    /// As `new`, with the undistortion's tolerance (px) overridden (tests force the Newton
    /// fallback with 0).
    fn with_tolerance(
        model: &PlaneModel,
        image_size: [f64; 2],
        tolerance_px: Option<f64>,
    ) -> Result<Self, LensError> {
        let [width, height] = checked_size(image_size)?;
        let reference = InversePlane::new(model)?.within_image(width, height);
        Ok(Self::from_reference(
            model,
            image_size,
            reference,
            tolerance_px,
        ))
    }

    /// The mapper of `reference`, which is `InversePlane::new(model)` within an image of
    /// `image_size` (checked): it vouches for the model, so nothing here can fail.
    pub(crate) fn from_reference(
        model: &PlaneModel,
        image_size: [f64; 2],
        reference: InversePlane,
        tolerance_px: Option<f64>,
    ) -> Self {
        let [width, height] = image_size;
        let hinv = reference.hinv();
        let m = [0, 1, 2].map(|r| [0, 1, 2].map(|c| hinv[(r, c)]));
        let lens = model.lens;
        let [cx, cy] = lens.centre;
        let mut fast = Fast {
            m,
            b: m.map(|row| row[0] * cx + row[1] * cy + row[2]),
            row2: m[2][0].abs() + m[2][1].abs() + m[2][2].abs(),
            ms: m.map(|row| [row[0] * lens.scale, row[1] * lens.scale]),
            centre: lens.centre,
            inv_s: 1.0 / lens.scale,
            centre_s: [cx / lens.scale, cy / lens.scale],
            k1x2: 2.0 * lens.k1,
            k2x4: 4.0 * lens.k2,
            k1x3: 3.0 * lens.k1,
            k2x5: 5.0 * lens.k2,
            t_max: -1.0,
            front: f64::INFINITY,
            coef: [0.0; MAX_COEFFICIENTS],
        };
        let (kernel, undistortion) = if lens.is_identity() {
            (Kernel::NoLens, Undistortion::None)
        } else {
            // The same limit as InversePlane::within_image, and no farther than the fold.
            let limit = 1.05 * lens.reach(width, height);
            let radius = limit.min(lens.valid_radius()) * (1.0 - 1e-9);
            fit_undistortion(&mut fast, &lens, radius, tolerance_px)
                .unwrap_or((Kernel::Reference, Undistortion::Newton))
        };
        PlaneMapper {
            model: *model,
            image_size,
            reference,
            fast,
            kernel,
            undistortion,
        }
    }

    /// The model it maps through.
    pub fn model(&self) -> &PlaneModel {
        &self.model
    }

    /// The image size (width, height) it serves, px.
    pub fn image_size(&self) -> [f64; 2] {
        self.image_size
    }

    /// How it inverts the lens.
    pub fn undistortion(&self) -> Undistortion {
        self.undistortion
    }

    /// The world point (mm) pixel d sees: `InversePlane::map`'s answer, by the fast path.
    pub fn map(&self, d: Point) -> Result<Point, PointFailure> {
        let f = &self.fast;
        let mut out = [[0.0; 2]];
        let clean = dispatch!(self.kernel, P => f.chunk::<P>(&[d], &mut out), _ => false);
        if clean {
            Ok(out[0])
        } else {
            self.reference.map(d)
        }
    }

    /// Maps every pixel of `px` into `out` (mm), NaN where a pixel has no place on the plane,
    /// and reports those. Maps the first min(px.len(), out.len()) points (callers pass equal
    /// lengths). Large batches are split over rayon's threads; the results are the same, bit
    /// for bit, whatever the split.
    pub fn map_into(&self, px: &[Point], out: &mut [Point]) -> PointReport {
        let n = px.len().min(out.len());
        let (px, out) = (&px[..n], &mut out[..n]);
        if n < PARALLEL_MIN_POINTS || !threads::pool_allowed() {
            return self.map_chunk(0, px, out);
        }
        px.par_chunks(CHUNK_POINTS)
            .zip(out.par_chunks_mut(CHUNK_POINTS))
            .enumerate()
            .map(|(c, (s, o))| self.map_chunk(c * CHUNK_POINTS, s, o))
            .collect::<Vec<_>>()
            .into_iter()
            .fold(PointReport::default(), PointReport::then)
    }

    /// One chunk: the fast kernel, then the reference on the points it was not sure of.
    fn map_chunk(&self, start: usize, px: &[Point], out: &mut [Point]) -> PointReport {
        let f = &self.fast;
        let all = dispatch!(self.kernel, P => f.chunk::<P>(px, out), _ => {
            out.fill([f64::NAN; 2]);
            false
        });
        let mut report = PointReport::default();
        if all {
            return report;
        }
        for (k, (p, o)) in px.iter().zip(out.iter_mut()).enumerate() {
            // The fast path never writes NaN for a point it is sure of.
            if o[0].is_nan() {
                match self.reference.map(*p) {
                    Ok(w) => *o = w,
                    Err(failure) => report.record(start + k, failure),
                }
            }
        }
        report
    }
}

/// `image_size` if it is one: (width, height) of at least a pixel each, finite.
pub(crate) fn checked_size(image_size: [f64; 2]) -> Result<[f64; 2], LensError> {
    let [width, height] = image_size;
    if !(width >= 1.0 && height >= 1.0 && width.is_finite() && height.is_finite()) {
        return Err(LensError::InvalidImageSize { width, height });
    }
    Ok(image_size)
}

/// Finds the cheapest polynomial kernel that undistorts to the tolerance out to `radius` px
/// (shrinking the radius while none does), fills its constants into `fast`, and describes it.
fn fit_undistortion(
    fast: &mut Fast,
    lens: &RadialLens,
    radius: f64,
    tolerance_px: Option<f64>,
) -> Option<(Kernel, Undistortion)> {
    if !(radius > 0.0 && radius.is_finite()) {
        return None;
    }
    let mut radius = radius;
    for _ in 0..12 {
        let tolerance = tolerance_px.unwrap_or(1e-10_f64.max(1e-13 * radius));
        if let Some(found) = fit_at_radius(fast, lens, radius, tolerance) {
            return Some(found);
        }
        radius *= 0.93;
    }
    None
}

/// The cheapest candidate that passes the check out to `radius` px, if any.
fn fit_at_radius(
    fast: &mut Fast,
    lens: &RadialLens,
    radius: f64,
    tolerance: f64,
) -> Option<(Kernel, Undistortion)> {
    // The reference on the grid: RadialLens::undistort itself. A radius it refuses (beyond
    // the fold) cannot be served by the fast path.
    let mut grid = Vec::with_capacity(RAYS.len() * (GRID + 1));
    for ray in RAYS {
        for i in 0..=GRID {
            let r = radius * i as f64 / GRID as f64;
            let d = [lens.centre[0] + r * ray[0], lens.centre[1] + r * ray[1]];
            grid.push((d, lens.undistort(d)?));
        }
    }
    // The farthest ideal point from the centre: bounds the reference's scale of w.
    let reach = grid
        .iter()
        .map(|(_, u)| (u[0] - lens.centre[0]).hypot(u[1] - lens.centre[1]))
        .fold(0.0, f64::max);
    // The exact ratio q = r_u / r_d at the fitting nodes, by the reference's Newton on the
    // normalised radius (a lens of unit scale centred at the origin).
    let unit = RadialLens {
        centre: [0.0, 0.0],
        scale: 1.0,
        ..*lens
    };
    let t_max = (radius * fast.inv_s).powi(2);
    for (coefficients, steps) in CANDIDATES {
        let nodes = 32 + 8 * coefficients;
        let mut ts = Vec::with_capacity(nodes);
        let mut ratios = Vec::with_capacity(nodes);
        for j in 0..nodes {
            let x = (std::f64::consts::PI * (j as f64 + 0.5) / nodes as f64).cos();
            let t = 0.5 * (1.0 + x) * t_max;
            let rho = t.sqrt();
            let q = if rho > 0.0 {
                unit.undistort([rho, 0.0])?[0] / rho
            } else {
                1.0
            };
            ts.push(t);
            ratios.push(q);
        }
        let v = DMatrix::from_fn(nodes, coefficients, |j, k| ts[j].powi(k as i32));
        // Bounded and unordered: nalgebra's plain svd() iterates until convergence and
        // panics on a NaN singular value.
        let Some(svd) = v.try_svd_unordered(true, true, f64::EPSILON, 10_000) else {
            continue;
        };
        let Ok(c) = svd.solve(&DVector::from_vec(ratios), 1e-15) else {
            continue;
        };
        if !c.iter().all(|x| x.is_finite()) {
            continue;
        }
        let mut f = *fast;
        f.coef = [0.0; MAX_COEFFICIENTS];
        for (k, value) in c.iter().enumerate() {
            f.coef[k] = *value;
        }
        let kernel = Kernel::Poly {
            coefficients,
            steps,
            k2: lens.k2 != 0.0,
        };
        // The kernel's own arithmetic: the ideal point c + d num / den.
        let ratio = |t: f64| dispatch!(kernel, P => P::ratio(&f, t), _ => (f64::NAN, 1.0));
        let s = lens.scale;
        let mut max_error: f64 = 0.0;
        for (d, u) in &grid {
            let (dx, dy) = f.offset(d[0], d[1]);
            let (num, den) = ratio(dx.mul_add(dx, dy * dy));
            let q = s * num / den;
            let e = (f.centre[0] + dx * q - u[0]).hypot(f.centre[1] + dy * q - u[1]);
            // NaN fails too, and so does a fold inside the domain.
            if !(e <= tolerance && den > 0.0) {
                max_error = f64::INFINITY;
                break;
            }
            max_error = max_error.max(e);
        }
        if max_error <= tolerance {
            let [cx, cy] = f.centre;
            let max_scale = f.row2 * (1.0 + cx.abs() + cy.abs() + 1.5 * reach);
            let slack = HORIZON_PIXELS_PER_ERROR * (f.m[2][0].abs() + f.m[2][1].abs()) * tolerance;
            // Within the checked radius (the offset's rounding is far inside the margin of
            // 1e-9 the radius keeps from the limit).
            f.t_max = t_max;
            f.front = HORIZON_BAND * max_scale + slack;
            *fast = f;
            return Some((
                kernel,
                Undistortion::Polynomial {
                    degree: coefficients - 1,
                    newton_steps: steps,
                    radius_px: radius,
                    max_error_px: max_error,
                    tolerance_px: tolerance,
                },
            ));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transform::invert;
    use nalgebra::Matrix3;

    const W: f64 = 1280.0;
    const H: f64 = 720.0;

    /// A deterministic uniform generator on [0, 1).
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }

        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.next()
        }
    }

    fn lens(k1: f64, k2: f64, centre: Point) -> RadialLens {
        RadialLens {
            centre,
            scale: 0.5 * W.hypot(H),
            k1,
            k2,
        }
    }

    fn paper_h() -> Matrix3<f64> {
        Matrix3::new(2.0, 0.05, 330.0, -0.03, 2.02, 160.0, 2e-5, -3e-5, 1.0)
    }

    /// A model whose horizon crosses the image (pixels left of x ~ 400 see no plane).
    fn horizon_h() -> Matrix3<f64> {
        let hinv = Matrix3::new(0.5, 0.01, -100.0, 0.02, 0.6, -50.0, 1e-3, 2e-4, -0.4);
        hinv.try_inverse().unwrap() // ok: test-only, an invertible matrix
    }

    fn random_model(rng: &mut Rng) -> PlaneModel {
        let h = if rng.next() < 0.3 {
            horizon_h()
        } else {
            Matrix3::new(
                rng.range(1.5, 2.5),
                rng.range(-0.2, 0.2),
                rng.range(100.0, 500.0),
                rng.range(-0.2, 0.2),
                rng.range(1.5, 2.5),
                rng.range(50.0, 300.0),
                rng.range(-5e-4, 5e-4),
                rng.range(-5e-4, 5e-4),
                1.0,
            )
        };
        let l = if rng.next() < 0.15 {
            RadialLens::identity(W, H).unwrap() // ok: test-only, a valid size
        } else {
            lens(
                rng.range(-0.3, 0.25),
                rng.range(-0.1, 0.15),
                [rng.range(620.0, 660.0), rng.range(340.0, 380.0)],
            )
        };
        PlaneModel { h, lens: l }
    }

    /// Pixels over and beyond the image, on the horizon, at the limit radius, non-finite.
    fn pixels(model: &PlaneModel, rng: &mut Rng, n: usize) -> Vec<Point> {
        let mut px: Vec<Point> = (0..n)
            .map(|_| [rng.range(-0.3 * W, 1.3 * W), rng.range(-0.3 * H, 1.3 * H)])
            .collect();
        let l = model.lens;
        let limit = 1.05 * l.reach(W, H);
        for f in [1.0 - 1e-12, 1.0, 1.0 + 1e-12, 0.999, 1.001] {
            px.push([l.centre[0] + limit * f, l.centre[1]]);
            px.push([l.centre[0] - 0.6 * limit * f, l.centre[1] + 0.8 * limit * f]);
        }
        // Ideal pixels on the horizon (and just either side), seen through the lens.
        let hinv = invert(&model.h).unwrap(); // ok: test-only, an invertible model
        let (a, b, c) = (hinv[(2, 0)], hinv[(2, 1)], hinv[(2, 2)]);
        if a.abs() > 1e-12 {
            for y in [0.0, 100.0, 360.0, 719.0] {
                let x = -(b * y + c) / a;
                for dx in [-1e-9, -1e-12, 0.0, 1e-12, 1e-9, 1e-6] {
                    px.push(l.distort([x + dx, y]));
                }
            }
        }
        px.extend([
            [f64::NAN, 1.0],
            [1.0, f64::INFINITY],
            [f64::NEG_INFINITY, f64::NAN],
            [1e300, 1e300],
            [-1e200, 5.0],
            l.centre,
        ]);
        px
    }

    /// How far the fast answer is from the reference's, relative to the answer's size.
    fn relative(a: Point, b: Point) -> f64 {
        (a[0] - b[0]).hypot(a[1] - b[1]) / b[0].hypot(b[1]).max(1.0)
    }

    fn check_against_reference(model: &PlaneModel, px: &[Point]) -> f64 {
        let mapper = PlaneMapper::new(model, [W, H]).unwrap();
        let reference = InversePlane::new(model).unwrap().within_image(W, H);
        let mut out = vec![[0.0; 2]; px.len()];
        let report = mapper.map_into(px, &mut out);
        let mut expected = PointReport::default();
        let mut worst: f64 = 0.0;
        for (i, p) in px.iter().enumerate() {
            let single = mapper.map(*p);
            match (reference.map(*p), single) {
                (Ok(r), Ok(f)) => {
                    worst = worst.max(relative(f, r));
                    assert_eq!(out[i], f, "batch and single differ at {p:?}");
                }
                (Err(r), Err(f)) => {
                    assert_eq!(r, f, "{p:?} under {model:?}");
                    assert!(out[i][0].is_nan() && out[i][1].is_nan());
                    expected.record(i, r);
                }
                (r, f) => panic!("{p:?}: reference {r:?}, mapper {f:?} under {model:?}"),
            }
        }
        assert_eq!(report, expected);
        worst
    }

    #[test]
    fn agrees_with_the_reference_on_random_models_and_pixels() {
        let mut rng = Rng(7);
        let mut worst: f64 = 0.0;
        for _ in 0..60 {
            let model = random_model(&mut rng);
            let px = pixels(&model, &mut rng, 3000);
            worst = worst.max(check_against_reference(&model, &px));
        }
        // About 1e-11 here; 1e-9 is the bound the horizon band guarantees.
        assert!(worst <= 1e-10, "worst relative difference {worst:e}");
    }

    #[test]
    fn the_paper_lens_is_a_low_degree_polynomial_over_the_whole_region() {
        let model = PlaneModel {
            h: paper_h(),
            lens: lens(-0.06, 0.0, [639.5, 359.5]),
        };
        let mapper = PlaneMapper::new(&model, [W, H]).unwrap();
        let limit = 1.05 * model.lens.reach(W, H);
        match mapper.undistortion() {
            Undistortion::Polynomial {
                degree,
                newton_steps,
                radius_px,
                max_error_px,
                tolerance_px,
            } => {
                assert!(degree <= 7 && newton_steps == 1, "{degree} {newton_steps}");
                assert!(radius_px >= limit * (1.0 - 1e-8), "{radius_px} {limit}");
                assert!(max_error_px <= tolerance_px && tolerance_px <= 1e-10);
            }
            other => panic!("{other:?}"),
        }
        let mut rng = Rng(3);
        let px = pixels(&model, &mut rng, 5000);
        assert!(check_against_reference(&model, &px) <= 1e-12);
    }

    #[test]
    fn pixels_of_the_image_all_take_the_fast_path() {
        for l in [
            lens(-0.06, 0.0, [639.5, 359.5]),
            lens(-0.26, 0.14, [644.0, 355.0]),
            RadialLens::identity(W, H).unwrap(),
        ] {
            let model = PlaneModel {
                h: paper_h(),
                lens: l,
            };
            let mapper = PlaneMapper::new(&model, [W, H]).unwrap();
            let mut rng = Rng(1);
            let px: Vec<Point> = (0..10_000)
                .map(|_| [rng.range(-0.5, W - 0.5), rng.range(-0.5, H - 0.5)])
                .collect();
            let mut out = vec![[0.0; 2]; px.len()];
            let f = &mapper.fast;
            let all = dispatch!(mapper.kernel, U => f.chunk::<U>(&px, &mut out), _ => false);
            assert!(all, "{:?}", mapper.undistortion());
        }
    }

    #[test]
    fn a_lens_that_folds_inside_the_region_is_served_up_to_the_fold() {
        // k1 = -0.5 folds at about 0.54 of the scale, well inside the image.
        let model = PlaneModel {
            h: paper_h(),
            lens: lens(-0.5, 0.0, [640.0, 360.0]),
        };
        let mapper = PlaneMapper::new(&model, [W, H]).unwrap();
        let valid = model.lens.valid_radius();
        match mapper.undistortion() {
            Undistortion::Polynomial { radius_px, .. } => assert!(radius_px < valid),
            other => panic!("{other:?}"),
        }
        // Rings from inside the fast region to beyond the fold.
        let mut px = Vec::new();
        for i in 0..2000 {
            let r = valid * (0.5 + 0.6 * i as f64 / 2000.0);
            let a = i as f64 * 0.37;
            px.push([640.0 + r * a.cos(), 360.0 + r * a.sin()]);
        }
        check_against_reference(&model, &px);
        let (mut out, reference) = (vec![[0.0; 2]; px.len()], InversePlane::new(&model).unwrap());
        let report = mapper.map_into(&px, &mut out);
        assert!(report.outside_lens > 300, "{report:?}");
        assert!(reference.map([640.0 + 1.01 * valid, 360.0]).is_err());
    }

    #[test]
    fn without_a_polynomial_every_pixel_takes_newton() {
        let model = PlaneModel {
            h: horizon_h(),
            lens: lens(-0.1, 0.03, [645.0, 352.0]),
        };
        let mapper = PlaneMapper::with_tolerance(&model, [W, H], Some(0.0)).unwrap();
        assert_eq!(mapper.undistortion(), Undistortion::Newton);
        let px = pixels(&model, &mut Rng(5), 2000);
        let reference = InversePlane::new(&model).unwrap().within_image(W, H);
        let mut out = vec![[0.0; 2]; px.len()];
        let report = mapper.map_into(&px, &mut out);
        assert!(report.behind_horizon > 0 && report.non_finite > 0 && report.outside_lens > 0);
        for (p, o) in px.iter().zip(&out) {
            match reference.map(*p) {
                Ok(w) => assert_eq!(w, *o),
                Err(_) => assert!(o[0].is_nan() && o[1].is_nan()),
            }
        }
    }

    #[test]
    fn an_ideal_lens_maps_like_the_reference_to_rounding_error() {
        let model = PlaneModel {
            h: horizon_h(),
            lens: RadialLens::identity(W, H).unwrap(),
        };
        assert_eq!(
            PlaneMapper::new(&model, [W, H]).unwrap().undistortion(),
            Undistortion::None
        );
        let px = pixels(&model, &mut Rng(9), 5000);
        // Rounding only: FMA against the reference's separate multiplies and adds.
        let worst = check_against_reference(&model, &px);
        assert!(worst <= 1e-12, "{worst:e}");
    }

    #[test]
    fn results_do_not_depend_on_the_thread_count_or_the_split() {
        let model = PlaneModel {
            h: horizon_h(),
            lens: lens(-0.06, 0.01, [641.0, 357.0]),
        };
        let mapper = PlaneMapper::new(&model, [W, H]).unwrap();
        let px = pixels(&model, &mut Rng(11), 3 * PARALLEL_MIN_POINTS + 17);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap(); // ok: test-only
            let mut out = vec![[0.0; 2]; px.len()];
            let report = pool.install(|| mapper.map_into(&px, &mut out));
            (out, report)
        };
        let (one, r1) = run(1);
        let (three, r3) = run(3);
        assert_eq!(r1, r3);
        assert!(r1.invalid() > 0);
        assert_eq!(bits(&one), bits(&three));
        // Small calls, one point at a time, give the same bits.
        let single: Vec<Point> = px
            .iter()
            .map(|p| mapper.map(*p).unwrap_or([f64::NAN; 2]))
            .collect();
        assert_eq!(bits(&single), bits(&one));
    }

    fn bits(v: &[Point]) -> Vec<[u64; 2]> {
        v.iter().map(|p| [p[0].to_bits(), p[1].to_bits()]).collect()
    }

    #[test]
    fn the_vector_and_the_scalar_builds_give_the_same_bits() {
        let mut rng = Rng(13);
        let mut compared = 0;
        for _ in 0..30 {
            let model = random_model(&mut rng);
            let mapper = PlaneMapper::new(&model, [W, H]).unwrap();
            // Not a multiple of the vector block: the padded tail is compared too.
            let px = pixels(&model, &mut rng, 1001);
            let (mut a, mut b) = (vec![[0.0; 2]; px.len()], vec![[0.0; 2]; px.len()]);
            let f = &mapper.fast;
            let (clean_a, clean_b) = dispatch!(mapper.kernel, P => (
                f.chunk::<P>(&px, &mut a),
                f.chunk_portable::<P>(&px, &mut b),
            ), _ => continue);
            assert_eq!(clean_a, clean_b);
            assert_eq!(bits(&a), bits(&b), "{:?}", mapper.undistortion());
            compared += 1;
        }
        assert!(compared >= 20, "{compared}");
    }

    #[test]
    fn every_candidate_has_a_compiled_kernel() {
        for (coefficients, steps) in CANDIDATES {
            assert!(coefficients <= MAX_COEFFICIENTS);
            for k2 in [false, true] {
                let kernel = Kernel::Poly {
                    coefficients,
                    steps,
                    k2,
                };
                assert!(dispatch!(kernel, U => std::mem::size_of::<U>() == 0, _ => false));
            }
        }
    }

    #[test]
    fn a_bad_image_size_is_refused() {
        let model = PlaneModel {
            h: paper_h(),
            lens: lens(-0.06, 0.0, [639.5, 359.5]),
        };
        assert!(matches!(
            PlaneMapper::new(&model, [f64::NAN, 720.0]),
            Err(LensError::InvalidImageSize { .. })
        ));
    }
}
