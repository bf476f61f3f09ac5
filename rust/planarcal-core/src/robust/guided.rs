//! Neighbourhood consistency, for guided sampling when outliers dominate. A homography is
//! smooth: the points near an inlier in the source that are inliers too map near its
//! destination, while an outlier's destination is unrelated to its source. So an inlier's
//! source neighbours tend to be its destination neighbours too, and an outlier's are so only
//! by chance. (Locality-preserving matching, Ma et al. 2019, uses the same signal to filter
//! matches.) Counting them ranks inliers first, and PROSAC samples in that order.
//!
//! Neighbourhoods come from grids: each point set gets a grid of about two points per cell
//! over its own extent (so the homography's overall scale drops out), and a point's
//! neighbours are those in the 3 x 3 cells around it, about 18 where the points are spread
//! evenly. Where they crowd (a cluster of wrong matches on repeated texture, say), only the
//! NEAREST closest of the first MAX_NEIGHBOURS in the block count: a cell-sized neighbourhood
//! of a cluster is the cluster itself on both sides, which would look consistent, while the
//! nearest few of a randomly paired cluster are not. Where they are sparse (inliers spread
//! among such crowds), the block widens. Linear time: at 5,000 points it costs about as much
//! as 100 minimal samples.

use crate::alloc;
use crate::error::Result;

/// Points per grid cell, on average.
const POINTS_PER_CELL: f64 = 2.0;
/// Cells across a grid at most (memory stays O(n) for any spread of points).
const MAX_CELLS: usize = 1 << 11;
/// Neighbours looked at per point at most: clustered points stay linear time.
const MAX_NEIGHBOURS: usize = 64;
/// Neighbours kept per point where its block is crowded: the nearest.
const NEAREST: usize = 16;
/// A block with more points than this is crowded, with fewer sparse (an even spread puts
/// about 18 in one).
const CROWDED: usize = 32;
const SPARSE: usize = 8;
/// Cells a block reaches out to where the points are sparse (an even spread of inliers among
/// crowds of outliers).
const MAX_REACH: usize = 3;

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
    /// `salt` shuffles the points within each cell (see `neighbourhood_scores`).
    fn new(points: &[[f64; 2]], salt: u32) -> Result<Self> {
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
        let cell = alloc::collect(
            points
                .iter()
                .map(|p| (index(p[0], lo[0], w, cols), index(p[1], lo[1], h, rows))),
        )?;
        let mut start = alloc::filled(0u32, cols * rows + 1)?;
        for &(c, r) in &cell {
            start[r as usize * cols + c as usize + 1] += 1;
        }
        for i in 1..start.len() {
            start[i] += start[i - 1];
        }
        let mut fill = alloc::collect(start.iter().copied())?;
        let mut order = alloc::filled(0u32, points.len())?;
        for (i, &(c, r)) in cell.iter().enumerate() {
            let k = r as usize * cols + c as usize;
            order[fill[k] as usize] = i as u32;
            fill[k] += 1;
        }
        for cell in start.windows(2) {
            order[cell[0] as usize..cell[1] as usize]
                .sort_unstable_by_key(|&i| i.wrapping_mul(salt) ^ (i >> 7));
        }
        Ok(Grid {
            cols,
            rows,
            cell,
            start,
            order,
        })
    }

    /// Appends to `out` the points in the cells within `reach` of point i's cell (3 x 3 for
    /// reach 1; i included), at most `limit` of them, row by row (whole runs of cells copied
    /// at once).
    #[inline]
    fn extend_block(&self, i: usize, reach: usize, limit: usize, out: &mut Vec<u32>) {
        let (c, r) = self.cell[i];
        let (c, r) = (c as usize, r as usize);
        let (c0, c1) = (c.saturating_sub(reach), (c + reach + 1).min(self.cols));
        let mut left = limit;
        for row in r.saturating_sub(reach)..(r + reach + 1).min(self.rows) {
            let (a, b) = (row * self.cols + c0, row * self.cols + c1);
            let (a, b) = (self.start[a] as usize, self.start[b] as usize);
            let take = (b - a).min(left);
            out.extend_from_slice(&self.order[a..a + take]);
            left -= take;
        }
    }

    /// Point i's 3 x 3 block as runs of `order` (one per row), when it is neither sparse nor
    /// crowded: then its points but i are exactly i's neighbours, and need no copying.
    #[inline]
    fn plain_block(&self, i: usize) -> Option<([(usize, usize); 3], usize)> {
        let (c, r) = self.cell[i];
        let (c, r) = (c as usize, r as usize);
        let (c0, c1) = (c.saturating_sub(1), (c + 2).min(self.cols));
        let mut runs = [(0, 0); 3];
        let (mut rows, mut total) = (0, 0);
        for row in r.saturating_sub(1)..(r + 2).min(self.rows) {
            let (a, b) = (row * self.cols + c0, row * self.cols + c1);
            let (a, b) = (self.start[a] as usize, self.start[b] as usize);
            runs[rows] = (a, b);
            rows += 1;
            total += b - a;
        }
        // i is in its own block; the rest are its neighbours (fewer than MAX_NEIGHBOURS).
        let others = total - 1;
        ((SPARSE..=CROWDED).contains(&others)).then_some((runs, rows))
    }

    /// The points of runs (from `plain_block`).
    #[inline]
    fn runs<'a>(
        &'a self,
        (runs, rows): &'a ([(usize, usize); 3], usize),
    ) -> impl Iterator<Item = u32> + 'a {
        runs[..*rows]
            .iter()
            .flat_map(|&(a, b)| self.order[a..b].iter().copied())
    }

    /// Whether points i and j are in the same or adjacent cells.
    #[cfg(test)]
    fn adjacent(&self, i: usize, j: usize) -> bool {
        let ((a, b), (c, d)) = (self.cell[i], self.cell[j]);
        a.abs_diff(c) <= 1 && b.abs_diff(d) <= 1
    }
}

/// Point i's neighbours in `grid` (not i itself), into `out`: the points of its 3 x 3 block,
/// widened (up to MAX_REACH cells each way) where it holds fewer than SPARSE; where it holds
/// more than CROWDED, the NEAREST closest (ties by index) of its first MAX_NEIGHBOURS.
fn neighbours(
    grid: &Grid,
    points: &[[f64; 2]],
    i: usize,
    near: &mut Vec<(f64, u32)>,
    out: &mut Vec<u32>,
) {
    for reach in 1..=MAX_REACH {
        out.clear();
        grid.extend_block(i, reach, MAX_NEIGHBOURS, out);
        // Without i itself. The lists are used as sets (and the crowded cut below is by a
        // total order), so the order this leaves does not matter.
        if let Some(k) = out.iter().position(|&j| j as usize == i) {
            out.swap_remove(k);
        }
        if out.len() >= SPARSE {
            break;
        }
    }
    if out.len() > CROWDED {
        let p = points[i];
        near.clear();
        near.extend(out.iter().map(|&j| {
            let q = points[j as usize];
            ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2), j)
        }));
        near.select_nth_unstable_by(NEAREST - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        out.clear();
        out.extend(near[..NEAREST].iter().map(|e| e.1));
    }
}

/// Each correspondence's neighbourhood consistency: how many of its source neighbours are
/// among its destination neighbours too.
pub fn neighbourhood_scores(src: &[[f64; 2]], dst: &[[f64; 2]]) -> Result<Vec<u32>> {
    // Crowded blocks are cut at MAX_NEIGHBOURS in cell order; the two grids order their cells
    // differently, so that the two cuts are independent samples of a crowd rather than the
    // same points (which would make any crowd look consistent).
    let (gs, gd) = (Grid::new(src, 0x9E37_79B1)?, Grid::new(dst, 0x85EB_CA77)?);
    let mut scores = alloc::filled(0u32, src.len())?;
    // stamp[j] == i + 1: j is a source neighbour of i (a set without clearing or sorting).
    let mut stamp = alloc::filled(0u32, src.len())?;
    let (mut near, mut a, mut b) = (Vec::new(), Vec::new(), Vec::new());
    // Source-cell order: consecutive points share most of their neighbours, which stay in
    // cache.
    for &i in &gs.order {
        let i = i as usize;
        let mark = i as u32 + 1;
        // Where a block is plain (most are), its points are read in place.
        if let Some(block) = gs.plain_block(i) {
            for j in gs.runs(&block) {
                stamp[j as usize] = mark;
            }
        } else {
            neighbours(&gs, src, i, &mut near, &mut a);
            for &j in &a {
                stamp[j as usize] = mark;
            }
        }
        // i is stamped (in its own block) or not; either way it is not its own neighbour.
        stamp[i] = 0;
        scores[i] = if let Some(block) = gd.plain_block(i) {
            gd.runs(&block)
                .map(|j| u32::from(stamp[j as usize] == mark))
                .sum()
        } else {
            neighbours(&gd, dst, i, &mut near, &mut b);
            b.iter()
                .map(|&j| u32::from(stamp[j as usize] == mark))
                .sum()
        };
    }
    Ok(scores)
}

/// The correspondences by descending score, ties by ascending index (a counting sort: the
/// scores are small integers).
pub fn ranking(scores: &[u32]) -> Result<Vec<u32>> {
    let top = scores.iter().copied().max().unwrap_or(0) as usize;
    let mut start = alloc::filled(0u32, top + 2)?;
    for &s in scores {
        start[top - s as usize + 1] += 1;
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut rank = alloc::filled(0u32, scores.len())?;
    for (i, &s) in scores.iter().enumerate() {
        let slot = &mut start[top - s as usize];
        rank[*slot as usize] = i as u32;
        *slot += 1;
    }
    Ok(rank)
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
        let g = Grid::new(&pts, 0x9E37_79B1).unwrap();
        for i in [0, 17, 399] {
            let mut got = Vec::new();
            g.extend_block(i, 1, usize::MAX, &mut got);
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
        let s = neighbourhood_scores(&src, &dst).unwrap();
        let mean = |r: std::ops::Range<usize>| {
            s[r.clone()].iter().map(|&v| f64::from(v)).sum::<f64>() / r.len() as f64
        };
        let (inl, out) = (mean(0..n / 10), mean(n / 10..n));
        assert!(
            inl > 8.0 * out && inl > 0.5,
            "inliers {inl}, outliers {out}"
        );
        // The top of the ranking is mostly inliers.
        let rank = ranking(&s).unwrap();
        let top = rank[..200]
            .iter()
            .filter(|&&i| (i as usize) < n / 10)
            .count();
        assert!(top > 150, "{top} of the top 200 are inliers");
    }

    #[test]
    fn ranking_is_by_descending_score_then_index() {
        assert_eq!(ranking(&[1, 3, 0, 3, 1]).unwrap(), [1, 3, 0, 4, 2]);
        assert_eq!(ranking(&[]).unwrap(), Vec::<u32>::new());
    }

    #[test]
    fn randomly_paired_clusters_do_not_outrank_inliers() {
        let mut rng = Pcg32::new(5, 6);
        let n = 2000;
        let gauss = |r: &mut Pcg32| {
            let (a, b) = (r.unit().max(1e-300), r.unit());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        let (mut src, mut dst) = (Vec::new(), Vec::new());
        for i in 0..n {
            if i < n / 10 {
                let p = [rng.unit() * 1280.0, rng.unit() * 720.0];
                src.push(p);
                dst.push([0.9 * p[0] + 40.0, 1.1 * p[1] - 20.0]);
            } else {
                // Four clusters of wrong matches, 30 px across, paired at random.
                let c = (i % 4) as f64;
                src.push([
                    100.0 + 300.0 * c + 30.0 * gauss(&mut rng),
                    200.0 + 30.0 * gauss(&mut rng),
                ]);
                dst.push([
                    900.0 - 200.0 * c + 30.0 * gauss(&mut rng),
                    500.0 + 30.0 * gauss(&mut rng),
                ]);
            }
        }
        let rank = ranking(&neighbourhood_scores(&src, &dst).unwrap()).unwrap();
        let top = rank[..100]
            .iter()
            .filter(|&&i| (i as usize) < n / 10)
            .count();
        assert!(top > 70, "{top} of the top 100 are inliers");
    }

    #[test]
    fn degenerate_sets_do_not_panic() {
        let same = vec![[1.0, 2.0]; 50];
        let line: Vec<[f64; 2]> = (0..50).map(|i| [i as f64, 0.0]).collect();
        assert_eq!(neighbourhood_scores(&same, &line).unwrap().len(), 50);
        assert_eq!(neighbourhood_scores(&line, &same).unwrap().len(), 50);
    }
}
