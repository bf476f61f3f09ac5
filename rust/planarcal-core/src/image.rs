//! An 8-bit grey frame as the core reads it (borrowed, row-major), rectangles of it, and its
//! median grey level (the object detector's edge thresholds scale with it).

/// An 8-bit grey frame, row-major, `width` pixels a row.
#[derive(Clone, Copy)]
pub struct GreyU8<'a> {
    /// `width * height` grey levels.
    pub pixels: &'a [u8],
    /// Pixels a row.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

/// A rectangle of pixels [x0, x1) x [y0, y1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

impl Rect {
    pub fn width(&self) -> usize {
        self.x1 - self.x0
    }
    pub fn height(&self) -> usize {
        self.y1 - self.y0
    }
}

/// The median grey level of every `col_step`-th pixel of every `row_step`-th row (steps >= 1),
/// from their histogram: the whole frame's median to a grey level, reading a fraction of it
/// (a few rows far apart read fewer cache lines than many rows for as many pixels). 0 for an
/// empty frame.
pub fn median_grey(image: GreyU8<'_>, row_step: usize, col_step: usize) -> u8 {
    let (rows, step) = (row_step.max(1), col_step.max(1));
    let (w, h) = (image.width, image.height);
    if w == 0 || h == 0 || image.pixels.len() != w * h {
        return 0;
    }
    // Four histograms, so that runs of one grey level (a flat background) do not chain each
    // count to the one before.
    let mut counts = [[0u32; 256]; 4];
    let mut total = 0usize;
    for row in image.pixels.chunks_exact(w).step_by(rows) {
        let mut groups = row.chunks_exact(4 * step);
        for g in &mut groups {
            counts[0][g[0] as usize] += 1;
            counts[1][g[step] as usize] += 1;
            counts[2][g[2 * step] as usize] += 1;
            counts[3][g[3 * step] as usize] += 1;
        }
        for &v in groups.remainder().iter().step_by(step) {
            counts[0][v as usize] += 1;
        }
        total += row.len().div_ceil(step);
    }
    // The first level at which the cumulative count reaches half the samples.
    let half = total.div_ceil(2);
    let mut seen = 0usize;
    for level in 0..256 {
        seen += counts.iter().map(|c| c[level] as usize).sum::<usize>();
        if seen >= half {
            return level as u8;
        }
    }
    255
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(w: usize, h: usize) -> Vec<u8> {
        (0..w * h)
            .map(|i| ((i * 7919 + (i / w) * 31) % 251) as u8)
            .collect()
    }

    #[test]
    fn the_median_grey_is_that_of_the_sampled_pixels() {
        for (w, h, rows, step) in [(23, 17, 4, 4), (7, 5, 1, 1), (64, 3, 2, 3), (5, 9, 16, 2)] {
            let px = frame(w, h);
            let image = GreyU8 {
                pixels: &px,
                width: w,
                height: h,
            };
            let mut sample: Vec<u8> = (0..h)
                .step_by(rows)
                .flat_map(|y| (0..w).step_by(step).map(move |x| (y, x)))
                .map(|(y, x)| px[y * w + x])
                .collect();
            sample.sort_unstable();
            let want = sample[(sample.len() - 1) / 2];
            assert_eq!(
                median_grey(image, rows, step),
                want,
                "{w} x {h} / {rows}, {step}"
            );
        }
        let empty = GreyU8 {
            pixels: &[],
            width: 0,
            height: 0,
        };
        assert_eq!(median_grey(empty, 4, 4), 0);
    }
}
