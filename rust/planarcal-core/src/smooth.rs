//! A light Gaussian smoothing of one rectangle of an 8-bit frame into f32, the grey levels the
//! sub-pixel outline search samples (sigma 1 px steadies the gradient against sensor noise
//! without merging neighbouring edges).
//!
//! Only the rectangle is computed, from the frame's real pixels around it; past the frame's
//! border the frame is mirrored about its edge pixel (OpenCV's BORDER_REFLECT_101, the
//! default of its filters), so a rectangle at the border smooths as OpenCV would.

use crate::alloc;
use crate::error::Result;
use crate::image::{GreyU8, Rect};

/// The kernel's half-width: four sigmas.
const RADIUS: usize = 4;
const TAPS: usize = 2 * RADIUS + 1;

/// exp(-k^2 / 2) for k = -4..4, normalised to sum 1 (sigma 1 px).
fn kernel() -> [f32; TAPS] {
    let mut k = [0.0f64; TAPS];
    for (i, v) in k.iter_mut().enumerate() {
        let d = i as f64 - RADIUS as f64;
        *v = (-0.5 * d * d).exp();
    }
    let sum: f64 = k.iter().sum();
    k.map(|v| (v / sum) as f32)
}

/// Index `i` (which may lie outside [0, n)) mirrored into the frame, the edge pixel not
/// repeated (OpenCV's BORDER_REFLECT_101); a single pixel is its own mirror.
pub(crate) fn reflect_101(i: isize, n: usize) -> usize {
    let n = n as isize;
    if n == 1 {
        return 0;
    }
    let mut i = i;
    // Repeated for frames narrower than the kernel (OpenCV's borderInterpolate).
    while !(0..n).contains(&i) {
        i = if i < 0 { -i } else { 2 * (n - 1) - i };
    }
    i as usize
}

/// Room in `out` and `scratch` for `gaussian_region` of `rect` (a region as large as the
/// frame is hundreds of megabytes), so that it allocates nothing that can fail.
pub fn reserve_region(rect: Rect, out: &mut Vec<f32>, scratch: &mut Vec<f32>) -> Result<()> {
    let (rw, rh) = (rect.width(), rect.height());
    let wanted = |v: &Vec<f32>, n: usize| n.saturating_sub(v.len());
    let across = rw.saturating_mul(rh.saturating_add(2 * RADIUS));
    alloc::reserve(scratch, wanted(scratch, across))?;
    alloc::reserve(out, wanted(out, rw.saturating_mul(rh)))
}

/// The rectangle `rect` of `image`, smoothed by a Gaussian of sigma 1 px, into `out` (resized
/// to rect.width() x rect.height(), row-major); `scratch` holds the first pass (both buffers
/// are reused from call to call). `rect` must lie inside the image and the image's pixels
/// must number width x height; otherwise `out` is left empty and false returned.
pub fn gaussian_region(
    image: GreyU8<'_>,
    rect: Rect,
    out: &mut Vec<f32>,
    scratch: &mut Vec<f32>,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        return unsafe { gaussian_region_avx2(image, rect, out, scratch) };
    }
    gaussian_region_body(image, rect, out, scratch)
}

/// The same code compiled for AVX2: eight lanes a multiply-add instead of four. No FMA: the
/// bits are the plain build's.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn gaussian_region_avx2(
    image: GreyU8<'_>,
    rect: Rect,
    out: &mut Vec<f32>,
    scratch: &mut Vec<f32>,
) -> bool {
    gaussian_region_body(image, rect, out, scratch)
}

#[inline(always)]
fn gaussian_region_body(
    image: GreyU8<'_>,
    rect: Rect,
    out: &mut Vec<f32>,
    across: &mut Vec<f32>,
) -> bool {
    out.clear();
    let (w, h) = (image.width, image.height);
    if image.pixels.len() != w * h
        || rect.x0 >= rect.x1
        || rect.y0 >= rect.y1
        || rect.x1 > w
        || rect.y1 > h
    {
        return false;
    }
    let k = kernel();
    let (rw, rh) = (rect.width(), rect.height());
    // The horizontal pass over the rectangle's rows and RADIUS rows either side.
    let mut line = vec![0.0f32; rw + 2 * RADIUS];
    // Every value of both buffers is written below: resizing them is enough.
    across.resize(rw * (rh + 2 * RADIUS), 0.0);
    let inner = rect.x0 >= RADIUS && rect.x1 + RADIUS <= w;
    for (r, row_out) in across.chunks_exact_mut(rw).enumerate() {
        let y = reflect_101(rect.y0 as isize + r as isize - RADIUS as isize, h);
        let row = &image.pixels[y * w..(y + 1) * w];
        if inner {
            for (v, &p) in line
                .iter_mut()
                .zip(&row[rect.x0 - RADIUS..rect.x1 + RADIUS])
            {
                *v = p as f32;
            }
        } else {
            for (j, v) in line.iter_mut().enumerate() {
                let x = reflect_101(rect.x0 as isize + j as isize - RADIUS as isize, w);
                *v = row[x] as f32;
            }
        }
        for (o, w) in row_out.iter_mut().zip(line.windows(TAPS)) {
            let w: &[f32; TAPS] = w.try_into().unwrap_or(&[0.0; TAPS]);
            *o = taps(&k, w);
        }
    }
    // The vertical pass.
    out.resize(rw * rh, 0.0);
    for (r, row_out) in out.chunks_exact_mut(rw).enumerate() {
        let rows = &across[r * rw..(r + TAPS) * rw];
        for (c, o) in row_out.iter_mut().enumerate() {
            let column: [f32; TAPS] = std::array::from_fn(|t| rows[t * rw + c]);
            *o = taps(&k, &column);
        }
    }
    true
}

/// The kernel applied to nine values, summed in order (the compiler vectorises the loops
/// around it, across pixels).
#[inline(always)]
fn taps(k: &[f32; TAPS], v: &[f32; TAPS]) -> f32 {
    let mut acc = 0.0;
    for t in 0..TAPS {
        acc += k[t] * v[t];
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Direct 2-D convolution with mirrored borders, in f64: the reference.
    fn reference(image: GreyU8<'_>, rect: Rect) -> Vec<f64> {
        let k = kernel();
        let mut out = Vec::new();
        for y in rect.y0..rect.y1 {
            for x in rect.x0..rect.x1 {
                let mut s = 0.0;
                for (i, &ki) in k.iter().enumerate() {
                    for (j, &kj) in k.iter().enumerate() {
                        let yy = reflect_101(y as isize + i as isize - 4, image.height);
                        let xx = reflect_101(x as isize + j as isize - 4, image.width);
                        s += ki as f64 * kj as f64 * image.pixels[yy * image.width + xx] as f64;
                    }
                }
                out.push(s);
            }
        }
        out
    }

    fn frame(w: usize, h: usize) -> Vec<u8> {
        (0..w * h)
            .map(|i| ((i * 7919 + (i / w) * 31) % 251) as u8)
            .collect()
    }

    #[test]
    fn matches_a_direct_convolution_inside_and_at_the_borders() {
        let (w, h) = (23, 17);
        let px = frame(w, h);
        let image = GreyU8 {
            pixels: &px,
            width: w,
            height: h,
        };
        let mut out = Vec::new();
        for rect in [
            Rect {
                x0: 5,
                y0: 5,
                x1: 15,
                y1: 11,
            },
            Rect {
                x0: 0,
                y0: 0,
                x1: 23,
                y1: 17,
            },
            Rect {
                x0: 20,
                y0: 1,
                x1: 23,
                y1: 3,
            },
            Rect {
                x0: 0,
                y0: 14,
                x1: 1,
                y1: 17,
            },
        ] {
            assert!(gaussian_region(image, rect, &mut out, &mut Vec::new()));
            let want = reference(image, rect);
            assert_eq!(out.len(), want.len());
            for (a, b) in out.iter().zip(&want) {
                assert!((*a as f64 - b).abs() < 1e-3, "{rect:?}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn a_flat_frame_stays_flat_and_bad_rectangles_are_refused() {
        let mut scratch = Vec::new();
        let px = vec![77u8; 12 * 9];
        let image = GreyU8 {
            pixels: &px,
            width: 12,
            height: 9,
        };
        let mut out = Vec::new();
        assert!(gaussian_region(
            image,
            Rect {
                x0: 0,
                y0: 0,
                x1: 12,
                y1: 9
            },
            &mut out,
            &mut scratch
        ));
        assert!(out.iter().all(|v| (v - 77.0).abs() < 1e-4));
        assert!(!gaussian_region(
            image,
            Rect {
                x0: 3,
                y0: 0,
                x1: 13,
                y1: 9
            },
            &mut out,
            &mut scratch
        ));
        assert!(!gaussian_region(
            image,
            Rect {
                x0: 3,
                y0: 4,
                x1: 3,
                y1: 9
            },
            &mut out,
            &mut scratch
        ));
        assert!(out.is_empty());
        let one = [9u8];
        let single = GreyU8 {
            pixels: &one,
            width: 1,
            height: 1,
        };
        assert!(gaussian_region(
            single,
            Rect {
                x0: 0,
                y0: 0,
                x1: 1,
                y1: 1
            },
            &mut out,
            &mut scratch
        ));
        assert!((out[0] - 9.0).abs() < 1e-4);
    }
}
