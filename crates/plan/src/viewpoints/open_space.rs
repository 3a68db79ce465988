//! Pseudo-viewpoints for plain x, y, z (no poses, no scan ids, no times): places in the open
//! floor that the wall samples enclose, used like scanner positions by the labeling.
//!
//! A place qualifies when it is far from every wall sample (`clearance`), the story's floor or
//! ceiling points cover it (outside a building nothing is scanned), and few directions from it
//! escape the samples without meeting a wall (it is enclosed, not in the notch of an L). Places
//! are taken farthest from the walls first, at least `spacing` apart. A wall sample is then
//! seen from every pseudo-viewpoint whose straight line to it crosses no other wall sample,
//! within the scanner range, as a scanner there would have seen it.

use std::collections::HashMap;

use rayon::prelude::*;

use super::raster::Raster;
use super::{OpenSpaceStory, ViewpointsParams};
use crate::geom::{dist, dot, point_segment_distance, sub, P2};
use crate::samples::WallSamples;
use crate::stories::Story;

/// Cell of the wall and cover rasters, metres: two sample cells, so a sampled wall is an
/// unbroken line of marked cells.
const CELL: f64 = 0.1;
/// At most this many raster cells per story (coarser cells beyond).
const MAX_CELLS: usize = 16_000_000;
/// Floor and ceiling points are those within this of the story's floor or lowest ceiling, m.
const BAND: f64 = 0.15;
/// Directions tried from a place to see whether the walls enclose it.
const DIRECTIONS: usize = 72;
/// The last this many metres of a line of sight are judged on the samples themselves, not the
/// raster: its cells are too coarse to tell a sample's own wall from the near face of a thin
/// wall the sample lies behind.
const NEAR: f64 = 0.3;
/// Samples this close to the one seen are its own wall, metres (two sample cells apart).
const OWN: f64 = 0.07;
/// A line of sight crosses a wall when it passes this close to one of its samples, metres: a
/// line crossing a wall sampled every 5 cm passes within 2.5 cm of a sample.
const CROSS: f64 = 0.03;
/// At most this many pseudo-viewpoints see a sample (the nearest).
const MAX_SEEN_FROM: usize = 16;
/// At most this many pseudo-viewpoints per story.
const MAX_VIEWPOINTS: usize = 4_000;

/// Where the story's floor or ceiling was scanned, on the raster of the wall samples.
pub(crate) struct Cover {
    raster: Raster,
}

impl Cover {
    /// Marks the cells of `walls`' raster that hold a floor or ceiling point of `story`.
    fn of(xyz: &[[f32; 3]], story: &Story, walls: &Raster) -> Cover {
        let mut raster = walls.clone();
        raster.occupied.iter_mut().for_each(|o| *o = false);
        let floor = (story.floor_z - BAND, story.floor_z + BAND);
        let ceiling = story.wall_top_z - BAND;
        for p in xyz {
            let z = p[2] as f64;
            if z < story.z_min || z >= story.z_max {
                continue;
            }
            let flat = (z >= floor.0 && z <= floor.1) || z >= ceiling;
            if flat {
                if let Some(i) = raster.index([p[0] as f64, p[1] as f64]) {
                    raster.occupied[i] = true;
                }
            }
        }
        Cover { raster }
    }

    /// True when a cell within one cell of `i` is covered (sparse floors leave holes).
    fn covers(&self, i: usize) -> bool {
        let r = &self.raster;
        let (ci, cj) = ((i % r.nx) as i64, (i / r.nx) as i64);
        (-1..=1).any(|dj| {
            (-1..=1).any(|di| {
                let (a, b) = (ci + di, cj + dj);
                a >= 0
                    && b >= 0
                    && (a as usize) < r.nx
                    && (b as usize) < r.ny
                    && r.occupied[b as usize * r.nx + a as usize]
            })
        })
    }
}

/// Places pseudo-viewpoints in the open space of `story` that `samples` enclose and `xyz` (the
/// cloud's points) cover, and lists for every sample the ones that see it, with its normal
/// turned toward the nearest. `max_range` is the scanner range of sampling.
pub(crate) fn place(
    xyz: &[[f32; 3]],
    story: &Story,
    samples: &mut WallSamples,
    params: &ViewpointsParams,
    max_range: f64,
) -> OpenSpaceStory {
    let mut report = OpenSpaceStory {
        level: story.level,
        viewpoints: Vec::new(),
        samples_seen: 0,
        samples: samples.samples.len(),
    };
    let Some(walls) = Raster::of_points(
        samples.samples.iter().map(|s| s.pos),
        CELL,
        2.0 * CELL,
        MAX_CELLS,
    ) else {
        return report;
    };
    let cover = Cover::of(xyz, story, &walls);
    let places = open_places(&walls, &cover, params);
    if places.is_empty() {
        return report;
    }
    let positions: Vec<P2> = samples.samples.iter().map(|s| s.pos).collect();
    let near = neighbours(&positions, NEAR + CROSS);
    let seen: Vec<Vec<u32>> = positions
        .par_iter()
        .zip(&near)
        .map(|(&pos, near)| {
            let near: Vec<P2> = near.iter().map(|&k| positions[k as usize]).collect();
            seen_from(&walls, &places, pos, &near, max_range)
        })
        .collect();
    for (s, from) in samples.samples.iter_mut().zip(seen) {
        let mut from = from;
        if let Some(&v) = from.first() {
            // Facing the nearest viewpoint, as a scanner's normals face it.
            if dot(s.normal, sub(places[v as usize], s.pos)) < 0.0 {
                s.normal = [-s.normal[0], -s.normal[1]];
            }
            report.samples_seen += 1;
            // A place behind the face saw it through a gap in the wall it stands on, and its
            // line of sight crosses what lies behind the wall (a closed shaft, say).
            from.retain(|&v| dot(s.normal, sub(places[v as usize], s.pos)) >= 0.0);
        }
        from.sort_unstable();
        s.seen_from = from;
    }
    samples.viewpoints = places.clone();
    samples.lines_checked = true;
    report.viewpoints = places;
    report
}

/// The pseudo-viewpoints: open, covered and enclosed places, farthest from the walls first.
fn open_places(walls: &Raster, cover: &Cover, params: &ViewpointsParams) -> Vec<P2> {
    let d = walls.distance();
    let mut order: Vec<usize> = (0..d.len())
        .filter(|&i| d[i] >= params.open_space_clearance && d[i].is_finite())
        .collect();
    order.sort_by(|&a, &b| d[b].total_cmp(&d[a]).then(a.cmp(&b)));
    // Cells already decided: near an accepted place, or in the free disk of a rejected one.
    let mut taken = vec![false; d.len()];
    let mut out = Vec::new();
    let reach = walls.cell * (walls.nx + walls.ny) as f64 * 2.0;
    for i in order {
        if taken[i] || out.len() >= MAX_VIEWPOINTS {
            continue;
        }
        let p = walls.center(i % walls.nx, i / walls.nx);
        let ok = cover.covers(i) && enclosed(walls, p, reach, params.open_space_max_escape);
        if ok {
            out.push(p);
            // What a place sees nearby needs no second viewpoint; a room behind a wall does.
            paint(&mut taken, walls, p, params.open_space_spacing, true);
        } else {
            // The disk free of walls around a rejected place is on the same side of them.
            paint(&mut taken, walls, p, d[i] - walls.cell, false);
        }
    }
    out
}

/// True when at most `max_escape` of the directions from `p` leave the raster without meeting
/// a wall cell.
fn enclosed(walls: &Raster, p: P2, reach: f64, max_escape: f64) -> bool {
    let escaped = (0..DIRECTIONS)
        .filter(|&k| {
            let a = std::f64::consts::TAU * k as f64 / DIRECTIONS as f64;
            walls.first_hit(p, [a.cos(), a.sin()], reach).is_none()
        })
        .count();
    escaped as f64 <= max_escape * DIRECTIONS as f64
}

/// Marks the cells within `radius` of `p`; with `seen`, only those in sight of `p`.
fn paint(taken: &mut [bool], r: &Raster, p: P2, radius: f64, seen: bool) {
    let cells = (radius / r.cell).ceil() as i64;
    let (ci, cj) = (
        ((p[0] - r.lo[0]) / r.cell) as i64,
        ((p[1] - r.lo[1]) / r.cell) as i64,
    );
    for j in (cj - cells).max(0)..=(cj + cells).min(r.ny as i64 - 1) {
        for i in (ci - cells).max(0)..=(ci + cells).min(r.nx as i64 - 1) {
            let c = r.center(i as usize, j as usize);
            let d = dist(c, p);
            let visible = || {
                d < r.cell || {
                    let dir = [(c[0] - p[0]) / d, (c[1] - p[1]) / d];
                    r.first_hit(p, dir, d).is_none()
                }
            };
            if d <= radius && (!seen || visible()) {
                taken[j as usize * r.nx + i as usize] = true;
            }
        }
    }
}

/// Per point, the other points within `r` of it.
fn neighbours(points: &[P2], r: f64) -> Vec<Vec<u32>> {
    let key = |p: P2| ((p[0] / r).floor() as i64, (p[1] / r).floor() as i64);
    let mut cells: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
    for (k, &p) in points.iter().enumerate() {
        cells.entry(key(p)).or_default().push(k as u32);
    }
    points
        .par_iter()
        .enumerate()
        .map(|(k, &p)| {
            let (ci, cj) = key(p);
            let mut out = Vec::new();
            for dj in -1..=1 {
                for di in -1..=1 {
                    for &o in cells.get(&(ci + di, cj + dj)).into_iter().flatten() {
                        if o as usize != k && dist(points[o as usize], p) <= r {
                            out.push(o);
                        }
                    }
                }
            }
            out
        })
        .collect()
}

/// The places (indices, nearest first, at most [`MAX_SEEN_FROM`]) within `max_range` of `pos`
/// whose straight line to it meets no wall: no wall cell short of the last [`NEAR`] metres,
/// and in those no sample (of `near`, the samples around `pos`) but the sample's own wall.
fn seen_from(walls: &Raster, places: &[P2], pos: P2, near: &[P2], max_range: f64) -> Vec<u32> {
    let mut by_range: Vec<(f64, u32)> = places
        .iter()
        .enumerate()
        .map(|(k, &v)| (dist(v, pos), k as u32))
        .filter(|&(d, _)| d <= max_range && d > NEAR)
        .collect();
    by_range.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out = Vec::new();
    for (d, k) in by_range {
        let v = places[k as usize];
        let dir = [(pos[0] - v[0]) / d, (pos[1] - v[1]) / d];
        let open = walls.first_hit(v, dir, d - NEAR).is_none()
            && near
                .iter()
                .all(|&q| dist(q, pos) <= OWN || point_segment_distance(q, v, pos) > CROSS);
        if open {
            out.push(k);
            if out.len() == MAX_SEEN_FROM {
                break;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::samples::WallSample;

    /// Samples every 5 cm along the closed ring `ring`.
    fn ring_samples(ring: &[P2]) -> Vec<WallSample> {
        let mut out = Vec::new();
        for w in 0..ring.len() {
            let (a, b) = (ring[w], ring[(w + 1) % ring.len()]);
            let n = (dist(a, b) / 0.05).round() as usize;
            let along = [(b[0] - a[0]) / dist(a, b), (b[1] - a[1]) / dist(a, b)];
            for k in 0..n {
                let t = k as f64 / n as f64;
                out.push(WallSample {
                    pos: [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])],
                    normal: [-along[1], along[0]],
                    confidence: 1.0,
                    seen_from: Vec::new(),
                });
            }
        }
        out
    }

    /// Floor and ceiling points every 10 cm over the cells of `inside`.
    fn floor(lo: P2, hi: P2, inside: impl Fn(P2) -> bool) -> Vec<[f32; 3]> {
        let mut out = Vec::new();
        let mut y = lo[1];
        while y < hi[1] {
            let mut x = lo[0];
            while x < hi[0] {
                if inside([x, y]) {
                    out.push([x as f32, y as f32, 0.0]);
                    out.push([x as f32, y as f32, 2.7]);
                }
                x += 0.1;
            }
            y += 0.1;
        }
        out
    }

    fn story() -> Story {
        Story::flat(0, 0.0, 2.7, -1.0, 3.0)
    }

    /// An L: an 8 m square without its upper right 4 m quadrant.
    const L: [P2; 6] = [
        [0.0, 0.0],
        [8.0, 0.0],
        [8.0, 4.0],
        [4.0, 4.0],
        [4.0, 8.0],
        [0.0, 8.0],
    ];

    fn in_l(p: P2) -> bool {
        (0.0..8.0).contains(&p[0]) && (0.0..8.0).contains(&p[1]) && !(p[0] > 4.0 && p[1] > 4.0)
    }

    #[test]
    fn pseudo_viewpoints_stand_inside_and_see_every_wall() {
        let mut samples = WallSamples {
            samples: ring_samples(&L),
            ..Default::default()
        };
        let xyz = floor([0.0, 0.0], [8.0, 8.0], in_l);
        let report = place(
            &xyz,
            &story(),
            &mut samples,
            &ViewpointsParams::default(),
            10.0,
        );
        assert!(!report.viewpoints.is_empty());
        for v in &report.viewpoints {
            assert!(in_l(*v), "{v:?} outside the L");
            let wall = samples
                .samples
                .iter()
                .map(|s| dist(s.pos, *v))
                .fold(f64::INFINITY, f64::min);
            assert!(wall >= 0.4, "{v:?} is {wall} m from a wall");
        }
        assert_eq!(samples.viewpoints, report.viewpoints);
        assert_eq!(report.samples, samples.samples.len());
        // Every wall of an L is seen from some place inside it.
        assert_eq!(report.samples_seen, report.samples);
        // Lines of sight stay inside: none crosses the notch.
        for s in &samples.samples {
            for &k in &s.seen_from {
                let v = samples.viewpoints[k as usize];
                for t in 1..20 {
                    let t = t as f64 / 20.0 * 0.95;
                    let p = [v[0] + t * (s.pos[0] - v[0]), v[1] + t * (s.pos[1] - v[1])];
                    assert!(!(p[0] > 4.05 && p[1] > 4.05), "{v:?} -> {:?}", s.pos);
                }
            }
            // Normals face the viewpoints that see them.
            let v = samples.viewpoints[s.seen_from[0] as usize];
            assert!(dot(s.normal, sub(v, s.pos)) > 0.0);
        }
    }

    #[test]
    fn a_room_behind_a_wall_gets_its_own_viewpoint() {
        // Two closed 2.4 m rooms side by side: their centres are closer than the spacing, but
        // neither sees into the other.
        let mut all = ring_samples(&[[0.0, 0.0], [2.4, 0.0], [2.4, 2.4], [0.0, 2.4]]);
        all.extend(ring_samples(&[
            [2.4, 0.0],
            [4.8, 0.0],
            [4.8, 2.4],
            [2.4, 2.4],
        ]));
        let mut samples = WallSamples {
            samples: all,
            ..Default::default()
        };
        let xyz = floor([0.0, 0.0], [4.8, 2.4], |_| true);
        // Wider than both rooms together.
        let params = ViewpointsParams {
            open_space_spacing: 5.0,
            ..Default::default()
        };
        let report = place(&xyz, &story(), &mut samples, &params, 10.0);
        let left = report.viewpoints.iter().filter(|v| v[0] < 2.4).count();
        let right = report.viewpoints.iter().filter(|v| v[0] > 2.4).count();
        assert!(left >= 1 && right >= 1, "{:?}", report.viewpoints);
        assert_eq!(report.samples_seen, report.samples);
    }

    #[test]
    fn the_far_face_of_a_thin_wall_is_not_seen() {
        // A 10 cm partition across a 6 m room, both faces sampled; a place on each side.
        let mut all = ring_samples(&[[0.0, 0.0], [6.0, 0.0], [6.0, 6.0], [0.0, 6.0]]);
        let faces = [2.95, 3.05];
        for y in faces {
            all.extend(ring_samples(&[[0.0, y], [6.0, y]]));
        }
        let mut samples = WallSamples {
            samples: all,
            ..Default::default()
        };
        let xyz = floor([0.0, 0.0], [6.0, 6.0], |_| true);
        let report = place(
            &xyz,
            &story(),
            &mut samples,
            &ViewpointsParams::default(),
            10.0,
        );
        assert!(!report.viewpoints.is_empty());
        for s in &samples.samples {
            if !(s.pos[1] - 2.95)
                .abs()
                .min((s.pos[1] - 3.05).abs())
                .lt(&1e-9)
            {
                continue;
            }
            for &k in &s.seen_from {
                let v = samples.viewpoints[k as usize];
                // Seen only from its own side of the partition.
                assert_eq!(v[1] < 3.0, s.pos[1] < 3.0, "{:?} sees {:?}", v, s.pos);
            }
        }
    }

    #[test]
    fn a_place_behind_a_face_does_not_see_it_through_a_gap() {
        // Rooms at x 0-4 and 6-10 with a closed, unscanned shaft between them; the wall at
        // x = 4 has a 1 m gap, through which the left room's place would see the shaft's far
        // wall, the right room's near face, across the shaft.
        let mut all = ring_samples(&[[0.0, 0.0], [10.0, 0.0], [10.0, 4.0], [0.0, 4.0]]);
        let wall = |x: f64| ring_samples(&[[x, 0.0], [x, 4.0]]);
        all.extend(
            wall(4.0)
                .into_iter()
                .filter(|s| !(1.5..2.5).contains(&s.pos[1])),
        );
        all.extend(wall(6.0));
        let mut samples = WallSamples {
            samples: all,
            ..Default::default()
        };
        let xyz = floor([0.0, 0.0], [10.0, 4.0], |p| p[0] < 4.0 || p[0] > 6.0);
        let report = place(
            &xyz,
            &story(),
            &mut samples,
            &ViewpointsParams::default(),
            20.0,
        );
        assert!(
            report.viewpoints.iter().any(|v| v[0] < 4.0),
            "{:?}",
            report.viewpoints
        );
        assert!(
            report.viewpoints.iter().any(|v| v[0] > 6.0),
            "{:?}",
            report.viewpoints
        );
        let mut far_wall_seen = 0;
        for s in &samples.samples {
            for &k in &s.seen_from {
                let v = samples.viewpoints[k as usize];
                assert!(
                    dot(s.normal, sub(v, s.pos)) >= 0.0,
                    "{v:?} behind {:?}",
                    s.pos
                );
                if (s.pos[0] - 6.0).abs() < 1e-9 && (0.5..3.5).contains(&s.pos[1]) {
                    assert!(v[0] > 6.0, "{v:?} sees {:?} across the shaft", s.pos);
                    far_wall_seen += 1;
                }
            }
        }
        assert!(far_wall_seen > 0);
    }

    #[test]
    fn no_viewpoint_where_nothing_covers_the_floor_or_the_walls_do_not_enclose() {
        // The L's walls, but floor points only in the notch outside it: nowhere qualifies.
        let mut samples = WallSamples {
            samples: ring_samples(&L),
            ..Default::default()
        };
        let notch = floor([4.0, 4.0], [8.0, 8.0], |p| p[0] > 4.2 && p[1] > 4.2);
        let report = place(
            &notch,
            &story(),
            &mut samples,
            &ViewpointsParams::default(),
            10.0,
        );
        assert!(report.viewpoints.is_empty(), "{:?}", report.viewpoints);
        assert!(samples.samples.iter().all(|s| s.seen_from.is_empty()));
        // Two parallel walls, floor everywhere: the space between them is not enclosed.
        let mut open = ring_samples(&[[0.0, 0.0], [4.0, 0.0]]);
        open.extend(ring_samples(&[[0.0, 3.0], [4.0, 3.0]]));
        let mut samples = WallSamples {
            samples: open,
            ..Default::default()
        };
        let everywhere = floor([-1.0, -1.0], [5.0, 4.0], |_| true);
        let report = place(
            &everywhere,
            &story(),
            &mut samples,
            &ViewpointsParams::default(),
            10.0,
        );
        assert!(report.viewpoints.is_empty(), "{:?}", report.viewpoints);
    }
}
