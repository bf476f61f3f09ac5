//! Object IDs from frame to frame: nearest-neighbour association on the plane.
//!
//! Each object of a frame takes the ID of the nearest live track within `max_jump` (closest
//! pairs first, so two objects never share a track); objects left over start new tracks; a
//! track unseen for more than `max_missing` frames ends. Positions are in the plane's units
//! (mm), where distances mean the same everywhere in the image.

use std::collections::HashMap;

use crate::alloc;
use crate::error::Result;
use crate::Point;

/// The live tracks and the association's limits.
#[derive(Clone, Debug)]
pub struct Tracks {
    max_jump: f64,
    max_missing: u32,
    ids: Vec<u64>,
    positions: Vec<Point>,
    missed: Vec<u32>,
    next_id: u64,
}

impl Tracks {
    /// No tracks yet; the first ID given is 1. Objects that move more than `max_jump`
    /// between frames (or whose position is not finite) start new tracks.
    pub fn new(max_jump: f64, max_missing: u32) -> Self {
        Tracks {
            max_jump,
            max_missing,
            ids: Vec::new(),
            positions: Vec::new(),
            missed: Vec::new(),
            next_id: 1,
        }
    }

    /// The IDs of one frame's objects at `positions` (one per object, in order); the tracks
    /// then move to this frame's positions, and those not seen age. OutOfMemory, with the
    /// tracks as they were, when the frame's buffers cannot be allocated.
    pub fn update(&mut self, positions: &[Point]) -> Result<Vec<u64>> {
        let (n, m) = (positions.len(), self.ids.len());
        let mut pairs = self.pairs_within_reach(positions)?;
        // Closest first; equal distances in object, then track, order.
        pairs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut ids = alloc::filled(0u64, n)?;
        let mut matched = alloc::filled(false, m)?;
        // Room for this frame's tracks before any is changed: a failure leaves them as they were.
        alloc::reserve(&mut self.ids, n)?;
        alloc::reserve(&mut self.positions, n)?;
        alloc::reserve(&mut self.missed, n)?;
        let mut left = n.min(m);
        for (_, i, j) in pairs {
            if left == 0 {
                break;
            }
            if ids[i] != 0 || matched[j] {
                continue;
            }
            ids[i] = self.ids[j];
            matched[j] = true;
            left -= 1;
        }
        for id in ids.iter_mut().filter(|id| **id == 0) {
            *id = self.next_id;
            self.next_id += 1;
        }
        // Unseen tracks age (and end past max_missing); this frame's objects are the tracks
        // seen now.
        let mut k = 0;
        for j in 0..m {
            let missed = self.missed[j] + 1;
            if matched[j] || missed > self.max_missing {
                continue;
            }
            self.ids[k] = self.ids[j];
            self.positions[k] = self.positions[j];
            self.missed[k] = missed;
            k += 1;
        }
        self.ids.truncate(k);
        self.positions.truncate(k);
        self.missed.truncate(k);
        self.ids.extend_from_slice(&ids);
        self.positions.extend_from_slice(positions);
        self.missed.resize(self.ids.len(), 0);
        Ok(ids)
    }

    /// Every (distance, object, track) within max_jump. The tracks are binned in cells of
    /// max_jump, so each object is compared with those of its cell and the 8 round it: a
    /// frame of 10^5 objects takes milliseconds, where comparing every pair took minutes.
    fn pairs_within_reach(&self, positions: &[Point]) -> Result<Vec<(f64, usize, usize)>> {
        let mut pairs = Vec::new();
        let mut consider = |i: usize, p: &Point, j: usize| -> Result<()> {
            let q = &self.positions[j];
            let d = (p[0] - q[0]).hypot(p[1] - q[1]);
            // NaN compares false: never matched.
            if d <= self.max_jump {
                if pairs.len() == pairs.capacity() {
                    let more = pairs.len().max(16);
                    alloc::reserve(&mut pairs, more)?;
                }
                pairs.push((d, i, j));
            }
            Ok(())
        };
        // A cell a hair wider than the reach: two points within it are in neighbouring cells
        // whatever the rounding of the division.
        let cell = self.max_jump * (1.0 + 1e-6);
        if !(cell > 0.0 && cell.is_finite()) {
            for (i, p) in positions.iter().enumerate() {
                for j in 0..self.positions.len() {
                    consider(i, p, j)?;
                }
            }
            return Ok(pairs);
        }
        // Saturating casts: far-off coordinates share the edge cells, still compared exactly.
        let bin = |p: &Point| ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64);
        let finite = |p: &Point| p[0].is_finite() && p[1].is_finite();
        let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
        grid.try_reserve(self.positions.len())
            .map_err(|_| alloc::out_of_memory::<((i64, i64), Vec<usize>)>(self.positions.len()))?;
        for (j, q) in self.positions.iter().enumerate().filter(|(_, q)| finite(q)) {
            let bucket = grid.entry(bin(q)).or_default();
            alloc::reserve(bucket, 1)?;
            bucket.push(j);
        }
        for (i, p) in positions.iter().enumerate().filter(|(_, p)| finite(p)) {
            let (cx, cy) = bin(p);
            let mut cells: Vec<(i64, i64)> = (-1..=1)
                .flat_map(|dx| {
                    (-1..=1).map(move |dy| (cx.saturating_add(dx), cy.saturating_add(dy)))
                })
                .collect();
            // At the saturated edge neighbours repeat: compare their tracks once.
            cells.sort_unstable();
            cells.dedup();
            for key in cells {
                for &j in grid.get(&key).into_iter().flatten() {
                    consider(i, p, j)?;
                }
            }
        }
        Ok(pairs)
    }

    /// The live tracks: (ID, last position), in no particular order.
    pub fn live(&self) -> impl Iterator<Item = (u64, Point)> + '_ {
        self.ids.iter().copied().zip(self.positions.iter().copied())
    }

    /// Live tracks.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// No live track.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn objects_keep_their_ids_as_they_move() {
        let mut t = Tracks::new(5.0, 2);
        assert_eq!(t.update(&[[0.0, 0.0], [10.0, 0.0]]).unwrap(), vec![1, 2]);
        // Listed the other way round, each a little further on.
        assert_eq!(t.update(&[[11.0, 1.0], [1.0, 1.0]]).unwrap(), vec![2, 1]);
        // One jumps too far: a new track; the old one lives on unseen.
        assert_eq!(t.update(&[[30.0, 0.0], [2.0, 1.0]]).unwrap(), vec![3, 1]);
        assert_eq!(t.len(), 3);
    }

    #[test]
    fn the_closest_pair_wins_and_unseen_tracks_end() {
        let mut t = Tracks::new(5.0, 1);
        t.update(&[[0.0, 0.0]]).unwrap();
        // Two candidates for track 1: the nearer takes it.
        assert_eq!(t.update(&[[3.0, 0.0], [1.0, 0.0]]).unwrap(), vec![2, 1]);
        t.update(&[]).unwrap();
        assert_eq!(t.len(), 2);
        t.update(&[]).unwrap();
        assert!(t.is_empty());
        // An object that was never matched cannot take an ended track's ID.
        assert_eq!(t.update(&[[1.0, 0.0]]).unwrap(), vec![3]);
    }

    #[test]
    fn the_grid_pairs_what_comparing_every_pair_does() {
        // Brute force against the grid, on random frames with clusters, cell edges, far-off
        // and non-finite positions; and a frame of 10^5 objects, each kept by its track
        // (comparing every pair took minutes: benches, not this test, time it).
        let mut rng = crate::Pcg32::new(5, 5);
        for round in 0..200 {
            let jump = [0.5, 3.0, 1e-300, 1e300, f64::INFINITY, 0.0][round % 6];
            let mut frame = |n: usize| -> Vec<Point> {
                (0..n)
                    .map(|k| match k % 7 {
                        0 => [f64::NAN, 1.0],
                        1 => [1e300, -1e300],
                        2 => [3.0 * (k / 7) as f64, 0.0], // on cell edges
                        _ => [rng.unit() * 20.0, rng.unit() * 20.0],
                    })
                    .collect()
            };
            let (a, b) = (frame(40), frame(45));
            let mut grid = Tracks::new(jump, 3);
            let mut brute = grid.clone();
            grid.update(&a).unwrap();
            brute.update(&a).unwrap();
            let mut want = Vec::new();
            for (i, p) in b.iter().enumerate() {
                for (j, q) in brute.positions.iter().enumerate() {
                    let d = (p[0] - q[0]).hypot(p[1] - q[1]);
                    if d <= jump {
                        want.push((d, i, j));
                    }
                }
            }
            let mut got = grid.pairs_within_reach(&b).unwrap();
            let key = |x: &(f64, usize, usize)| (x.1, x.2);
            got.sort_unstable_by_key(key);
            want.sort_unstable_by_key(key);
            assert_eq!(got, want, "max_jump {jump}");
        }
        let many: Vec<Point> = (0..100_000)
            .map(|k| [(k % 400) as f64 * 10.0, (k / 400) as f64 * 10.0])
            .collect();
        let mut t = Tracks::new(5.0, 2);
        let first = t.update(&many).unwrap();
        assert_eq!(t.update(&many).unwrap(), first);
    }

    #[test]
    fn non_finite_positions_start_their_own_tracks() {
        let mut t = Tracks::new(5.0, 3);
        t.update(&[[0.0, 0.0]]).unwrap();
        assert_eq!(t.update(&[[f64::NAN, 0.0]]).unwrap(), vec![2]);
        let live: Vec<u64> = t.live().map(|(id, _)| id).collect();
        assert_eq!(live, vec![1, 2]);
    }
}
