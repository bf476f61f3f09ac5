//! Neighbourhood consistency, for guided sampling when outliers dominate. A homography is
//! smooth: the points near an inlier in the source that are inliers too map near its
//! destination, while an outlier's destination is unrelated to its source. So an inlier's
//! source neighbours tend to be its destination neighbours too, and an outlier's are so only
//! by chance. (Locality-preserving matching, Ma et al. 2019, uses the same signal to filter
//! matches.) Counting them ranks inliers first, and PROSAC samples in that order.
//!
//! Neighbourhoods are grid blocks, not exact k-nearest sets: each point set gets a grid of
//! about two points per cell over its own extent (so the homography's overall scale drops
//! out), and a point's neighbours are those in the 3 x 3 cells around it, about 18. Linear
//! time, no sorting: at 5,000 points it costs less than 100 minimal samples.

/// Points per grid cell, on average.
const POINTS_PER_CELL: f64 = 2.0;
/// Cells across a grid at most (memory stays O(n) for any spread of points).
const MAX_CELLS: usize = 1 << 11;
/// Neighbours looked at per point at most: clustered points stay linear time.
const MAX_NEIGHBOURS: usize = 64;

/// A uniform grid over a point set.
struct Grid {
    cols: usize,
    rows: usize,
    /// Each point's (column, row).
    cell: Vec<(u32, u32)>,
    /// Points of each cell, as ranges into `order` (counting sort).
    start: Vec<u32>,
    order: Vec<u32>,
}

impl Grid {
    fn new(points: &[[f64; 2]]) -> Self {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let (w, h) = ((hi[0] - lo[0]).max(1e-12), (hi[1] - lo[1]).max(1e-12));
        let size = (w * h * POINTS_PER_CELL / points.len().max(1) as f64)
            .sqrt()
            .max(1e-12);
        let cols = ((w / size) as usize + 1).clamp(1, MAX_CELLS);
        let rows = ((h / size) as usize + 1).clamp(1, MAX_CELLS);
        let index = |v: f64, lo: f64, extent: f64, cells: usize| {
            // Scaled to the cell count, so a degenerate (flat) extent maps to cell 0.
            (((v - lo) / extent * cells as f64) as usize).min(cells - 1) as u32
        };
        let cell: Vec<(u32, u32)> = points
            .iter()
            .map(|p| (index(p[0], lo[0], w, cols), index(p[1], lo[1], h, rows)))
            .collect();
        let mut start = vec![0u32; cols * rows + 1];
        for &(c, r) in &cell {
            start[r as usize * cols + c as usize + 1] += 1;
        }
        for i in 1..start.len() {
            start[i] += start[i - 1];
        }
        let mut fill = start.clone();
        let mut order = vec![0u32; points.len()];
        for (i, &(c, r)) in cell.iter().enumerate() {
            let k = r as usize * cols + c as usize;
            order[fill[k] as usize] = i as u32;
            fill[k] += 1;
        }
        Grid {
            cols,
            rows,
            cell,
            start,
            order,
        }
    }

    /// Calls `f` with the points in the 3 x 3 cells around point i's cell (i included), at
    /// most `limit` of them.
    #[inline]
    fn for_block(&self, i: usize, limit: usize, mut f: impl FnMut(u32)) {
        let (c, r) = self.cell[i];
        let (c, r) = (c as usize, r as usize);
        let (c0, c1) = (c.saturating_sub(1), (c + 2).min(self.cols));
        let mut left = limit;
        for row in r.saturating_sub(1)..(r + 2).min(self.rows) {
            let (a, b) = (row * self.cols + c0, row * self.cols + c1);
            let (a, b) = (self.start[a] as usize, self.start[b] as usize);
            for &j in &self.order[a..b.min(a.saturating_add(left))] {
                f(j);
            }
            left -= (b - a).min(left);
        }
    }

    /// Whether points i and j are in the same or adjacent cells.
    fn adjacent(&self, i: usize, j: usize) -> bool {
        let ((a, b), (c, d)) = (self.cell[i], self.cell[j]);
        a.abs_diff(c) <= 1 && b.abs_diff(d) <= 1
    }
}

/// Each correspondence's neighbourhood consistency: how many of the points in its source
/// neighbourhood are in its destination neighbourhood too.
pub fn neighbourhood_scores(src: &[[f64; 2]], dst: &[[f64; 2]]) -> Vec<u32> {
    let (gs, gd) = (Grid::new(src), Grid::new(dst));
    let mut scores = vec![0u32; src.len()];
    // Source-cell order: consecutive points share most of their neighbours, which stay in
    // cache.
    for &i in &gs.order {
        let i = i as usize;
        let mut count = 0u32;
        gs.for_block(i, MAX_NEIGHBOURS, |j| {
            count += u32::from(j as usize != i && gd.adjacent(i, j as usize));
        });
        scores[i] = count;
    }
    scores
}

/// The correspondences by descending score, ties by ascending index (a counting sort: the
/// scores are small integers).
pub fn ranking(scores: &[u32]) -> Vec<u32> {
    let top = scores.iter().copied().max().unwrap_or(0) as usize;
    let mut start = vec![0u32; top + 2];
    for &s in scores {
        start[top - s as usize + 1] += 1;
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut rank = vec![0u32; scores.len()];
    for (i, &s) in scores.iter().enumerate() {
        let slot = &mut start[top - s as usize];
        rank[*slot as usize] = i as u32;
        *slot += 1;
    }
    rank
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robust::sampler::Pcg32;

    #[test]
    fn blocks_hold_exactly_the_points_of_adjacent_cells() {
        let mut rng = Pcg32::new(1, 2);
        let pts: Vec<[f64; 2]> = (0..400)
            .map(|_| [rng.unit() * 50.0, rng.unit() * 30.0])
            .collect();
        let g = Grid::new(&pts);
        for i in [0, 17, 399] {
            let mut got = Vec::new();
            g.for_block(i, usize::MAX, |j| got.push(j));
            got.sort_unstable();
            let want: Vec<u32> = (0..pts.len() as u32)
                .filter(|&j| g.adjacent(i, j as usize))
                .collect();
            assert_eq!(got, want, "point {i}");
            assert!(got.len() > 5 && got.len() < 40, "{}", got.len());
        }
    }

    #[test]
    fn inliers_outscore_outliers() {
        let mut rng = Pcg32::new(3, 4);
        let n = 5000;
        let src: Vec<[f64; 2]> = (0..n).map(|_| [rng.unit(), rng.unit()]).collect();
        // A perspective map of the unit square, 2.5 times larger: scale drops out.
        let mut dst: Vec<[f64; 2]> = src
            .iter()
            .map(|p| {
                let w = 1.0 + 0.3 * p[0] - 0.2 * p[1];
                [(3.0 * p[0] + 0.5 * p[1]) / w, (2.2 * p[1] - 0.3 * p[0]) / w]
            })
            .collect();
        // 90% outliers.
        for d in dst.iter_mut().skip(n / 10) {
            *d = [rng.unit() * 3.0 - 0.1, rng.unit() * 2.5 - 0.3];
        }
        let s = neighbourhood_scores(&src, &dst);
        let mean = |r: std::ops::Range<usize>| {
            s[r.clone()].iter().map(|&v| f64::from(v)).sum::<f64>() / r.len() as f64
        };
        let (inl, out) = (mean(0..n / 10), mean(n / 10..n));
        assert!(
            inl > 8.0 * out && inl > 0.5,
            "inliers {inl}, outliers {out}"
        );
        // The top of the ranking is mostly inliers.
        let rank = ranking(&s);
        let top = rank[..200]
            .iter()
            .filter(|&&i| (i as usize) < n / 10)
            .count();
        assert!(top > 150, "{top} of the top 200 are inliers");
    }

    #[test]
    fn ranking_is_by_descending_score_then_index() {
        assert_eq!(ranking(&[1, 3, 0, 3, 1]), [1, 3, 0, 4, 2]);
        assert_eq!(ranking(&[]), Vec::<u32>::new());
    }

    #[test]
    fn degenerate_sets_do_not_panic() {
        let same = vec![[1.0, 2.0]; 50];
        let line: Vec<[f64; 2]> = (0..50).map(|i| [i as f64, 0.0]).collect();
        assert_eq!(neighbourhood_scores(&same, &line).len(), 50);
        assert_eq!(neighbourhood_scores(&line, &same).len(), 50);
    }
}
