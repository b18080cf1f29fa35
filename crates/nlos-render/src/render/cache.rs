//! The visibility cache of [`Visibility::Cached`](crate::Visibility::Cached): for every triangle and
//! measurement, the share of the triangle's level² sub-triangle centroids that see both the measurement's
//! laser spot and its sensor spot (a byte, 255 = all), 0 where the measurement does not light the face.
//!
//! Each centroid's view of the whole wall is one query ([`Bundle::visible_from`]): the wall's distinct spots
//! in a k-d tree, a group of spots settled at once where no triangle reaches the cone of its segments. The
//! answer is the one a shadow ray per centroid and spot gives ([`Scene::visible_live`]), which the tests
//! check pair by pair.

use std::collections::HashMap;

use glam::Vec3;
use rayon::prelude::*;

use super::scene::{Scene, Wall};
use super::soa::BLOCK;
use crate::visibility::bundle::{Bundle, Scratch};
use crate::visibility::wall::WallTree;

/// Bytes of columns computed per round (then written into the cache's blocks, [`CacheLayout`]): 4,096
/// triangles at 4,096 measurements, fewer triangles for larger scans (whole blocks, at least one), so the
/// round's buffer stays at 16 MiB. The unit
/// tests' scenes are small: they use rounds of 64 KiB, so that theirs have many (and ragged last tiles).
#[cfg(not(test))]
const ROUND_BYTES: usize = 1 << 24;
#[cfg(test)]
const ROUND_BYTES: usize = 1 << 16;
/// The transpose from columns to a block's rows works on this many rows at a time: one cache line of each
/// column, read once (columns a scan's width apart share the L1 cache's sets, so a line left for a later
/// pass is gone by then), into 16 KiB of rows.
const TILE: usize = 64;

/// Where the cache keeps the entry of measurement m and block slot `slot`: block by block (`BLOCK` slots,
/// the kernels' blocks), within a block measurement by measurement, within that slot by slot. The block
/// kernels read one block's entries for a few consecutive measurements at a time: in this order those are
/// one contiguous run of memory (in measurement-major order they were rows a whole mesh apart, each read
/// waiting on memory).
#[derive(Debug, Clone, Copy)]
pub(in crate::render) struct CacheLayout {
    pub(in crate::render) triangles: usize,
    pub(in crate::render) measurements: usize,
}

impl CacheLayout {
    /// The first slot of `slot`'s block, and the block's width (`BLOCK`, less for the last block).
    #[inline(always)]
    fn block(&self, slot: usize) -> (usize, usize) {
        let start = slot - slot % BLOCK;
        (start, BLOCK.min(self.triangles - start))
    }

    /// Index of the entry of measurement m and block slot `slot`.
    #[inline(always)]
    pub(in crate::render) fn index(&self, m: usize, slot: usize) -> usize {
        let (start, width) = self.block(slot);
        start * self.measurements + m * width + (slot - start)
    }

    /// The entries of measurement m for the block starting at slot `t0` (a multiple of `BLOCK`), in slot order.
    #[inline(always)]
    pub(in crate::render) fn row(&self, m: usize, t0: usize) -> std::ops::Range<usize> {
        let (start, width) = self.block(t0);
        let first = start * self.measurements + m * width;
        first..first + width
    }

    /// The cache in measurement-major order (entry `m · triangles + slot`), as the GPU backend reads it.
    #[cfg(any(feature = "gpu", test))]
    pub(in crate::render) fn measurement_major(&self, cache: &[u8]) -> Vec<u8> {
        let mut out = vec![0u8; cache.len()];
        for (m, row) in out.chunks_mut(self.triangles.max(1)).enumerate() {
            for t0 in (0..self.triangles).step_by(BLOCK) {
                let r = self.row(m, t0);
                row[t0..t0 + r.len()].copy_from_slice(&cache[r]);
            }
        }
        out
    }
}

/// The wall's distinct spots, and each measurement's laser and sensor spot among them.
fn wall_points(wall: &Wall) -> (Vec<Vec3>, Vec<u32>, Vec<u32>) {
    let mut points = Vec::new();
    let mut seen: HashMap<[u32; 3], u32> = HashMap::new();
    let mut id = |p: Vec3| {
        *seen.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
            points.push(p);
            points.len() as u32 - 1
        })
    };
    let l: Vec<u32> = wall.l.iter().map(|&p| id(p)).collect();
    let s: Vec<u32> = wall.s.iter().map(|&p| id(p)).collect();
    (points, l, s)
}

/// The wall's distinct spots (their coordinates, `axes`), each measurement's laser and sensor spot among them, and whether
/// they are the measurements themselves in order (a confocal scan of distinct spots).
struct Spots<'a> {
    /// The points' x, y and z coordinates, one array each (the per-face side test runs over them).
    axes: [Vec<f32>; 3],
    laser: &'a [u32],
    sensor: &'a [u32],
    confocal: bool,
}

/// One thread's buffers: the bundle query's, each spot's answer and side, each measurement's count and side
/// (+1 lit on the front, −1 on the back, 0 not lit).
struct Buffers {
    scratch: Scratch,
    visible: Vec<bool>,
    spot_side: Vec<i8>,
    count: Vec<u16>,
    side: Vec<i8>,
}

impl Scene {
    /// The cache at sub-triangle `level` (1..=16), in the order of [`CacheLayout`] over the block slots
    /// ([`Scene::mesh_triangle`]).
    pub(in crate::render) fn visibility_cache(&self, level: u32) -> Vec<u8> {
        let nt = self.tris.v0.len();
        let m = self.wall.l.len();
        let mut cache = vec![0u8; nt * m];
        if nt == 0 || m == 0 {
            return cache;
        }
        let (points, laser, sensor) = wall_points(&self.wall);
        let tree = WallTree::new(&points);
        let bundle = self.bvh.as_ref().map(|bvh| Bundle { bvh, wall: &tree });
        let confocal =
            points.len() == m && laser.iter().zip(&sensor).enumerate().all(|(i, (&l, &s))| l as usize == i && s == l);
        let axes = [0, 1, 2].map(|k| points.iter().map(|p| p[k]).collect());
        let spots = Spots { axes, laser: &laser, sensor: &sensor, confocal };
        // Whole blocks per round, at least one, whatever the scan's size.
        let round = (ROUND_BYTES / m).max(BLOCK).next_multiple_of(BLOCK);
        let mut columns = vec![0u8; round.min(nt) * m];
        let mut reported = 0;
        for s0 in (0..nt).step_by(round) {
            let s1 = (s0 + round).min(nt);
            let init = || Buffers {
                scratch: Scratch::default(),
                visible: vec![true; points.len()],
                spot_side: vec![0; points.len()],
                count: vec![0; m],
                side: vec![0; m],
            };
            columns[..(s1 - s0) * m].par_chunks_mut(m).enumerate().for_each_init(init, |buf, (j, column)| {
                self.cache_column(s0 + j, level, bundle.as_ref(), &spots, buf, column);
            });
            // Each block's columns into its rows (one row of `width` entries per measurement), TILE rows at
            // a time so that the rows written stay in the L1 cache.
            let blocks = &mut cache[s0 * m..s1 * m];
            blocks.par_chunks_mut(BLOCK * m).enumerate().for_each(|(b, rows)| {
                let first = b * BLOCK;
                let width = rows.len() / m;
                for m0 in (0..m).step_by(TILE) {
                    let m1 = (m0 + TILE).min(m);
                    for j in 0..width {
                        let col = &columns[(first + j) * m..(first + j + 1) * m];
                        for (r, &v) in (m0..m1).zip(&col[m0..m1]) {
                            rows[r * width + j] = v;
                        }
                    }
                }
            });
            let done = m * s1 / nt;
            self.count_done(done - reported);
            reported = done;
        }
        cache
    }

    /// Where [`Scene::visibility_cache`] keeps each entry.
    pub(in crate::render) fn cache_layout(&self) -> CacheLayout {
        CacheLayout { triangles: self.tris.v0.len(), measurements: self.wall.l.len() }
    }

    /// The cache's column of block slot `slot`: one entry per measurement.
    fn cache_column(
        &self,
        slot: usize,
        level: u32,
        bundle: Option<&Bundle<'_>>,
        spots: &Spots<'_>,
        buf: &mut Buffers,
        column: &mut [u8],
    ) {
        let t = self.mesh_triangle(slot);
        if !self.tris.valid[t] {
            column.fill(0);
            return;
        }
        // Which side of the face each measurement lights: [`Scene::orientation`], from each spot's side (the
        // same arithmetic, `n·(p − v0)`, on the spots' coordinates laid out per axis).
        let (n, v0) = (self.tris.n[t], self.tris.v0[t]);
        let two_sided = self.params.two_sided;
        let [xs, ys, zs] = &spots.axes;
        for (((side, &x), &y), &z) in buf.spot_side.iter_mut().zip(xs).zip(ys).zip(zs) {
            let d = (x - v0.x) * n.x + (y - v0.y) * n.y + (z - v0.z) * n.z;
            *side = i8::from(d > 0.0) - i8::from(d < 0.0 && two_sided);
        }
        if spots.confocal {
            buf.side.copy_from_slice(&buf.spot_side);
        } else {
            for (mi, side) in buf.side.iter_mut().enumerate() {
                let (l, s) = (buf.spot_side[spots.laser[mi] as usize], buf.spot_side[spots.sensor[mi] as usize]);
                *side = if l == s { l } else { 0 };
            }
        }
        let sides = [buf.side.contains(&1), buf.side.contains(&-1)];
        if !(sides[0] || sides[1]) {
            column.fill(0);
            return;
        }
        // A measurement's count grows only where it lights the side tested, so one not lit keeps 0.
        buf.count.fill(0);
        let unit = n.normalize();
        self.centroids(level, |u, v, _| {
            let x = self.point(t, u, v);
            for (sign, lit) in [(1i8, sides[0]), (-1, sides[1])] {
                if !lit {
                    continue;
                }
                if let Some(b) = bundle {
                    b.visible_from(x, unit * f32::from(sign), t as u32, &mut buf.visible, &mut buf.scratch);
                }
                let seen = &buf.visible;
                if spots.confocal {
                    for ((c, &side), &v) in buf.count.iter_mut().zip(&buf.side).zip(seen) {
                        *c += u16::from((side == sign) & v);
                    }
                } else {
                    for (mi, c) in buf.count.iter_mut().enumerate() {
                        let v = seen[spots.laser[mi] as usize] & seen[spots.sensor[mi] as usize];
                        *c += u16::from((buf.side[mi] == sign) & v);
                    }
                }
            }
        });
        let total = level * level;
        if total == 1 {
            // One centroid: the share is 255 or 0.
            for (out, &c) in column.iter_mut().zip(&buf.count) {
                *out = 0u8.wrapping_sub(c as u8);
            }
            return;
        }
        // The share in bytes, rounded: (c · 255 + total / 2) / total for each count c.
        let share: Vec<u8> = (0..=total).map(|c| ((c * 255 + total / 2) / total) as u8).collect();
        for (out, &c) in column.iter_mut().zip(&buf.count) {
            *out = share[usize::from(c)];
        }
    }

    /// The cache as one shadow ray per sub-triangle centroid and spot computes it: the reference the tests
    /// hold [`Scene::visibility_cache`] to.
    #[cfg(test)]
    pub(in crate::render) fn visibility_cache_by_rays(&self, level: u32) -> Vec<u8> {
        let nt = self.tris.v0.len();
        let mut rows = vec![0u8; nt * self.wall.l.len()];
        rows.par_chunks_mut(nt.max(1)).enumerate().for_each(|(m, row)| {
            let fr = self.frame(m);
            for (slot, out) in row.iter_mut().enumerate() {
                let t = self.mesh_triangle(slot);
                if self.orientation(t, &fr).is_none() {
                    continue;
                }
                let mut visible = 0u32;
                self.centroids(level, |u, v, _| {
                    let x = self.point(t, u, v);
                    visible += u32::from(self.visible_live(x, t, &fr));
                });
                let total = level * level;
                *out = ((visible * 255 + total / 2) / total) as u8;
            }
        });
        self.in_cache_layout(&rows)
    }

    /// The cache without occlusion (255 wherever the measurement lights the face): what the tests compare
    /// with to see that a scene shadows.
    #[cfg(test)]
    pub(in crate::render) fn visibility_cache_unshadowed(&self) -> Vec<u8> {
        let nt = self.tris.v0.len();
        let mut rows = vec![0u8; nt * self.wall.l.len()];
        for (m, row) in rows.chunks_mut(nt.max(1)).enumerate() {
            let fr = self.frame(m);
            for (slot, out) in row.iter_mut().enumerate() {
                if self.orientation(self.mesh_triangle(slot), &fr).is_some() {
                    *out = 255;
                }
            }
        }
        self.in_cache_layout(&rows)
    }

    /// A measurement-major cache (entry `m · triangles + slot`) in the order of [`CacheLayout`].
    #[cfg(test)]
    fn in_cache_layout(&self, rows: &[u8]) -> Vec<u8> {
        let layout = self.cache_layout();
        let mut cache = vec![0u8; rows.len()];
        for (m, row) in rows.chunks(layout.triangles.max(1)).enumerate() {
            for (slot, &v) in row.iter().enumerate() {
                cache[layout.index(m, slot)] = v;
            }
        }
        cache
    }
}
