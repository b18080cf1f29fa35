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
use crate::visibility::bundle::{Bundle, Scratch};
use crate::visibility::wall::WallTree;

/// Bytes of columns computed per round (then written into the measurement-major cache): 4,096 triangles at
/// 4,096 measurements, fewer triangles for larger scans, so the round's buffer stays at 16 MiB. The unit
/// tests' scenes are small: they use rounds of 64 KiB, so that theirs have many (and ragged last tiles).
#[cfg(not(test))]
const ROUND_BYTES: usize = 1 << 24;
#[cfg(test)]
const ROUND_BYTES: usize = 1 << 16;
/// The transpose from columns to rows works on this many rows at a time (one memory page each, at a few
/// thousand triangles: more would miss the TLB on every byte).
const TILE: usize = 16;

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
    /// The cache at sub-triangle `level` (1..=16), measurement-major: entry `m · triangles + slot` for block
    /// slot `slot` ([`Scene::mesh_triangle`]).
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
        // At least one tile of triangles per round, whatever the scan's size.
        let round = (ROUND_BYTES / m).max(TILE);
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
            // Transpose the round's columns into the rows, in tiles that stay in the L1 cache.
            cache.par_chunks_mut(nt * TILE).enumerate().for_each(|(b, rows)| {
                let m0 = b * TILE;
                let nrows = rows.len() / nt;
                for j0 in (s0..s1).step_by(TILE) {
                    for j in j0..(j0 + TILE).min(s1) {
                        let col = &columns[(j - s0) * m + m0..(j - s0) * m + m0 + nrows];
                        for (r, &v) in col.iter().enumerate() {
                            rows[r * nt + j] = v;
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
        let mut cache = vec![0u8; nt * self.wall.l.len()];
        cache.par_chunks_mut(nt.max(1)).enumerate().for_each(|(m, row)| {
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
        cache
    }

    /// The cache without occlusion (255 wherever the measurement lights the face): what the tests compare
    /// with to see that a scene shadows.
    #[cfg(test)]
    pub(in crate::render) fn visibility_cache_unshadowed(&self) -> Vec<u8> {
        let nt = self.tris.v0.len();
        let mut cache = vec![0u8; nt * self.wall.l.len()];
        for (m, row) in cache.chunks_mut(nt.max(1)).enumerate() {
            let fr = self.frame(m);
            for (slot, out) in row.iter_mut().enumerate() {
                if self.orientation(self.mesh_triangle(slot), &fr).is_some() {
                    *out = 255;
                }
            }
        }
        cache
    }
}
