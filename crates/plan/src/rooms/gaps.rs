//! Gaps through walls: where a paired wall stops and free floor goes on along its centre line
//! for a door's width, up to the next face (the other jamb, or a wall across). The points over
//! a gap tell a door (a lintel: something between the door height and the ceiling) from an
//! opening.

use super::faces::Face;
use super::pairing::Piece;
use super::segment::Free;
use super::{RoomsParams, StoryPoints};
use crate::geom::{self, P2};
use crate::plan::StoryPlan;

/// A gap through a wall, from jamb `a` to jamb `b` on the wall's centre line.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Gap {
    pub a: P2,
    pub b: P2,
    /// Unit direction a → b.
    pub u: P2,
    pub width: f64,
    /// The pierced wall's thickness.
    pub depth: f64,
    /// Something spans the gap between the door height and the ceiling.
    pub lintel: bool,
    /// Local height of the lintel's underside, where seen.
    pub head_z: Option<f64>,
    /// Narrower than a door: a crack the plan left between a wall's end and the next face,
    /// always closed, never a door.
    pub crack: bool,
    /// How far the cut reaches past each jamb along the wall until both faces are solid, so a
    /// slanted jamb still closes.
    pub reach: [f64; 2],
    /// The jambs as the points show them, distances from `a` along `u` (see [`lintels`]).
    pub jambs: Option<[f64; 2]>,
    /// Both jambs are ends of one straight wall of one thickness: a doorway in that wall, a
    /// door even where the floor goes around the wall's far end.
    pub in_wall: bool,
    /// The points show the wall standing across the gap under the door height (see
    /// [`lintels`]): a stretch of wall the plan lost, closed like a crack and never a door.
    pub walled: bool,
}

impl Gap {
    pub fn center(&self) -> P2 {
        geom::scale(geom::add(self.a, self.b), 0.5)
    }
    /// Unit normal to the left of a → b.
    pub fn left(&self) -> P2 {
        [-self.u[1], self.u[0]]
    }
    /// The gap's floor from face to face, as a ring (counter-clockwise), reaching into the
    /// jambs along the wall.
    pub fn rect(&self) -> Vec<P2> {
        let (n, h) = (self.left(), self.depth / 2.0);
        let a = geom::sub(self.a, geom::scale(self.u, self.reach[0]));
        let b = geom::add(self.b, geom::scale(self.u, self.reach[1]));
        vec![
            geom::sub(a, geom::scale(n, h)),
            geom::sub(b, geom::scale(n, h)),
            geom::add(b, geom::scale(n, h)),
            geom::add(a, geom::scale(n, h)),
        ]
    }
    /// The jambs and the width the door is reported with: where the points put the jambs when
    /// they were seen, else the plan's faces.
    pub fn door_span(&self) -> (P2, P2, f64) {
        match self.jambs {
            Some([s, e]) => (
                geom::add(self.a, geom::scale(self.u, s)),
                geom::add(self.a, geom::scale(self.u, e)),
                e - s,
            ),
            None => (self.a, self.b, self.width),
        }
    }

    /// Always cut and never a door: a crack, or a stretch of wall the plan lost.
    pub fn closed(&self) -> bool {
        self.crack || self.walled
    }

    /// Points just beyond either face at the gap's middle: in the two rooms it joins.
    pub fn probes(&self) -> [P2; 2] {
        let off = self.depth / 2.0 + 0.05;
        let c = self.center();
        let n = self.left();
        [
            geom::add(c, geom::scale(n, off)),
            geom::sub(c, geom::scale(n, off)),
        ]
    }
}

/// Whether free floor lies just beyond both faces of the pierced wall all along the gap: a
/// door joins two rooms from jamb to jamb. A ray that slipped through a crack in a wall
/// across (at a T junction) and on over a corridor has solid wall beside its first stretch.
fn rooms_beside(gap: &Gap, free: &Free) -> bool {
    const STEP: f64 = 0.05;
    let steps = (gap.width / STEP).floor() as usize;
    // The wall that ends at the first jamb has a room on each side too; a partition flush
    // with a corridor's face, beside a door, has the corridor wall on one side.
    (-1..steps as i64).filter(|&k| k != 0).all(|k| {
        let at = geom::add(gap.a, geom::scale(gap.u, k as f64 * STEP));
        beside(free, at, gap.left(), gap.depth / 2.0 + 0.05) == [true, true]
    })
}

/// Whether the floor `off` to the left and to the right (along `n`) of `at` is free.
fn beside(free: &Free, at: P2, n: P2, off: f64) -> [bool; 2] {
    [1.0, -1.0].map(|k| free.contains(geom::add(at, geom::scale(n, k * off))))
}

/// Whether wall `q` continues wall `p` past a gap ending at `end`: parallel, on the same centre
/// line, as thick, with an end at `end`.
fn continues(p: &Piece, q: &Piece, end: P2) -> bool {
    const ALONG: f64 = 0.1;
    const ACROSS: f64 = 0.03;
    let off_line = |x: P2| geom::dot(geom::sub(x, p.a), p.left()).abs();
    geom::cross(p.u, q.u).abs() < 0.05
        && (p.thickness - q.thickness).abs() <= ACROSS
        && off_line(q.a) <= ACROSS
        && off_line(q.b) <= ACROSS
        && (geom::dist(q.a, end) <= ALONG || geom::dist(q.b, end) <= ALONG)
}

/// Every gap at the ends of the paired walls, once each. Cracks are found first and closed:
/// a door's free path through one (a ray from a partition's end through a crack at a T
/// junction and over the corridor) is no door, and the floor beside a door is looked at with
/// the cracks shut.
pub(crate) fn find(
    pieces: &[Piece],
    faces: &[Face],
    free: &Free,
    params: &RoomsParams,
) -> Vec<Gap> {
    // A piece no longer than it is thick (a blob where walls meet) has no direction to cast in.
    let ends = || {
        pieces
            .iter()
            .filter(|p| geom::dist(p.a, p.b) > p.thickness)
            .flat_map(|p| [(p, p.b, p.u), (p, p.a, geom::scale(p.u, -1.0))])
    };
    let mut out: Vec<Gap> = ends()
        .filter_map(|(p, end, dir)| cast_gap(p, end, dir, faces, free, params))
        .filter(|g| g.crack)
        .map(|mut g| {
            g.reach = [reach(&g, free, -1.0), reach(&g, free, 1.0)];
            g
        })
        .collect();
    let closed = free.closing(out.iter().map(|g| g.rect()).collect());
    for (p, p_end, dir) in ends() {
        let Some(mut gap) = cast_gap(p, p_end, dir, faces, &closed, params) else {
            continue;
        };
        if gap.crack {
            continue;
        }
        gap.reach = [reach(&gap, &closed, -1.0), reach(&gap, &closed, 1.0)];
        // Free floor through the gap and on both sides of it.
        let (origin, width) = (gap.a, gap.width);
        let along = [0.25, 0.5, 0.75]
            .iter()
            .all(|&s| closed.contains(geom::add(origin, geom::scale(dir, width * s))));
        let [l, r] = gap.probes();
        if !along || !closed.contains(l) || !closed.contains(r) || !rooms_beside(&gap, &closed) {
            continue;
        }
        gap.in_wall = pieces.iter().any(|q| continues(p, q, gap.b));
        let twin = out.iter().any(|g| {
            !g.crack
                && geom::dist(g.center(), gap.center()) < 0.1
                && (g.width - gap.width).abs() < 0.1
        });
        if !twin {
            out.push(gap);
        }
    }
    let cracks: Vec<Vec<P2>> = out.iter().filter(|g| g.crack).map(|g| g.rect()).collect();
    out.retain(|g| g.crack || !cracks.iter().any(|r| crosses(g, r)));
    out
}

/// The gap a ray from piece `p`'s end `p_end` along `dir` finds up to the next face, when it
/// starts at the wall's own end and leaves through free floor; a crack only where there is free
/// floor to close. Its reach and whether it is a door are left to the caller.
fn cast_gap(
    p: &Piece,
    p_end: P2,
    dir: P2,
    faces: &[Face],
    free: &Free,
    params: &RoomsParams,
) -> Option<Gap> {
    let (leave, enter, exit) = cast(p_end, dir, faces, params.max_door_width)?;
    // The gap starts at the wall's own end: a square end takes half a thickness, a slanted one
    // (its face joining one of the wall's two faces) up to a thickness. A ray that leaves
    // solid farther on, or through another face, has gone through a wall meeting this one, and
    // what follows is a room.
    let own_end = exit.is_some_and(|k| {
        let joins = |f: &Face| {
            [f.a, f.b]
                .iter()
                .any(|&q| geom::dist(q, faces[k].a) < 0.01 || geom::dist(q, faces[k].b) < 0.01)
        };
        joins(&faces[p.faces[0]]) || joins(&faces[p.faces[1]])
    });
    if leave > p.thickness / 2.0 && !(own_end && leave <= p.thickness) {
        return None;
    }
    // Solid on both sides of the ray's way out: it went through a wall across (thinner than
    // half this one, as a partition fattened by voxels meeting a corridor wall, or through a
    // crack that joins this wall's faces to that wall's far face), and the floor beyond is a
    // room. A slanted end has free floor on one side.
    if leave > 0.01 {
        let mid = geom::add(p_end, geom::scale(dir, leave / 2.0));
        if beside(free, mid, p.left(), p.thickness / 2.0 + 0.03) == [false, false] {
            return None;
        }
    }
    let origin = geom::add(p_end, geom::scale(dir, leave));
    let width = enter - leave;
    let gap = Gap {
        a: origin,
        b: geom::add(p_end, geom::scale(dir, enter)),
        u: dir,
        width,
        depth: p.thickness,
        lintel: false,
        head_z: None,
        crack: width < params.min_door_width,
        reach: [0.05, 0.05],
        jambs: None,
        in_wall: false,
        walled: false,
    };
    // A crack is free floor between the wall's end and the face; solid there is a wall meeting
    // another, nothing to close.
    let open = (0..20).any(|k| {
        let f = (k as f64 + 0.5) / 20.0;
        free.contains(geom::add(origin, geom::scale(dir, width * f)))
    });
    (!gap.crack || open).then_some(gap)
}

/// Whether gap `g`'s centre line passes through the ring `r` (a closed crack) between its jambs.
fn crosses(g: &Gap, r: &[P2]) -> bool {
    const STEP: f64 = 0.01;
    let steps = (g.width / STEP).ceil() as usize;
    (1..steps).any(|k| {
        let at = geom::add(g.a, geom::scale(g.u, k as f64 * STEP));
        geom::point_in_ring(at, r)
    })
}

/// How far past a jamb (`side` -1 at `a`, 1 at `b`) the cut must reach for both faces to be
/// solid: 5 cm beyond the first step where they are, within 50 cm; else 5 cm.
fn reach(g: &Gap, free: &Free, side: f64) -> f64 {
    let (n, h) = (g.left(), g.depth / 2.0 - 0.005);
    let end = if side < 0.0 { g.a } else { g.b };
    for step in 0..50 {
        let s = step as f64 * 0.01;
        let c = geom::add(end, geom::scale(g.u, side * s));
        let both = [1.0, -1.0]
            .iter()
            .all(|&k| !free.contains(geom::add(c, geom::scale(n, k * h))));
        if both {
            return s + 0.05;
        }
    }
    0.05
}

/// Where the ray from `origin` along `dir` leaves solid last and enters solid again (the
/// first face it crosses from the free side, up to `max`): the gap's two ends, as distances,
/// and the face it leaves solid through. A slanted wall end is crossed on the way out and does
/// not count as the far jamb.
fn cast(origin: P2, dir: P2, faces: &[Face], max: f64) -> Option<(f64, f64, Option<usize>)> {
    let mut hits = Vec::new();
    for (k, f) in faces.iter().enumerate() {
        let e = geom::sub(f.b, f.a);
        let denom = geom::cross(dir, e);
        if denom.abs() < 1e-12 {
            continue;
        }
        let w = geom::sub(f.a, origin);
        let t = geom::cross(w, e) / denom;
        let s = geom::cross(w, dir) / denom;
        if t > 1e-4 && t <= max && (-1e-9..=1.0 + 1e-9).contains(&s) {
            hits.push((t, geom::dot(dir, f.solid_normal()) > 0.0, k));
        }
    }
    let enter = hits
        .iter()
        .filter(|h| h.1)
        .map(|h| h.0)
        .fold(f64::INFINITY, f64::min);
    if !enter.is_finite() {
        return None;
    }
    let leave = hits
        .iter()
        .filter(|h| !h.1 && h.0 < enter)
        .max_by(|a, b| a.0.total_cmp(&b.0));
    Some((leave.map_or(0.0, |h| h.0), enter, leave.map(|h| h.2)))
}

/// Looks at the points over each gap: a lintel when enough 10 cm slices along its width hold
/// a point between `min_head_height` above the floor and `ceiling_margin` under the ceiling.
/// Also looks under the door height: where the wall's points stand across nearly all of the
/// gap, the plan lost a stretch of wall there (a face's samples too sparse for a model), and
/// the gap is walled. A lintel hangs under the ceiling on both sides of the gap, which may be
/// lower than the story's (a corridor's dropped ceiling): beside the gap it is the highest
/// points seen there.
pub(crate) fn lintels(
    gaps: &mut [Gap],
    story: &StoryPlan,
    points: &StoryPoints<'_>,
    params: &RoomsParams,
) {
    if gaps.is_empty() {
        return;
    }
    let (z0, z1) = (
        story.floor_z + params.min_head_height,
        story.ceiling_z - params.ceiling_margin,
    );
    if z1 <= z0 {
        return;
    }
    // Slices along each gap, and the heights seen in it.
    let slices: Vec<usize> = gaps
        .iter()
        .map(|g| ((g.width / 0.1).ceil() as usize).max(1))
        .collect();
    let low = (story.floor_z + JAMB_ABOVE_FLOOR, z0);
    // Outward, past the plan's jamb, the points' jamb is looked for as far as a crack reaches:
    // a sliver or island of plan standing in a doorway leaves a crack behind it, and the
    // doorway's real jamb lies beyond both.
    let beyond = params.min_door_width.max(JAMB_SEARCH);
    let bins = (((low.1 - low.0) / WALLED_BIN).ceil() as usize).clamp(1, 32);
    // Ceiling points beside a gap are read up to a little over the story's ceiling.
    let top = story.ceiling_z + params.ceiling_margin;
    let boxes: Vec<[f64; 4]> = gaps
        .iter()
        .map(|g| {
            let mut wide = g.clone();
            wide.reach = [beyond; 2];
            wide.depth = g.depth + 2.0 * BESIDE.1;
            ring_box(&wide.rect())
        })
        .collect();
    let index = BoxIndex::new(&boxes);
    let empty = || Seen {
        lowest: slices.iter().map(|&n| vec![f64::INFINITY; n]).collect(),
        heights: vec![Vec::new(); gaps.len()],
        near_jamb: vec![[Nearest::default(); 2]; gaps.len()],
        low: slices.iter().map(|&n| vec![0; n]).collect(),
        ceiling: vec![[Nearest::default(); 2]; gaps.len()],
    };
    // A very dense cloud is read in a stride: lintels stay well covered. Both cores read a
    // share each; what they saw merges the same in any order.
    let stride = (points.xyz.len() / 8_000_000).max(1);
    let Seen {
        lowest,
        mut heights,
        near_jamb,
        low: walls,
        ceiling,
    } = points.fold(
        stride,
        low.0.min(z0)..=z1.max(low.1),
        empty,
        |seen, q| {
            let z = q[2] as f64;
            let over = (z0..z1).contains(&z);
            let high = (z0 <= z) & (z < top);
            let lower = (low.0 <= z) & (z < low.1);
            let p = [q[0] as f64, q[1] as f64];
            // One branch, taken for nearly every point: few lie near a gap.
            if !((high | lower) & index.any_near(p)) {
                return;
            }
            for &k in index.near(p) {
                let g = &gaps[k];
                let d = geom::sub(p, g.a);
                let (t, s) = (geom::dot(d, g.u), geom::dot(d, g.left()));
                if high {
                    // Over the gap's middle half, a strip of floor on either side.
                    let off = s.abs() - g.depth / 2.0;
                    let middle = (0.25 * g.width..=0.75 * g.width).contains(&t);
                    if middle && (BESIDE.0..=BESIDE.1).contains(&off) {
                        seen.ceiling[k][usize::from(s < 0.0)].offer(z);
                    }
                    if !over {
                        continue;
                    }
                } else {
                    if s.abs() <= g.depth / 2.0 + 0.02 && t > -beyond && t < g.width + beyond {
                        if t < g.width / 2.0 {
                            seen.near_jamb[k][0].offer(t);
                        } else {
                            seen.near_jamb[k][1].offer(-t);
                        }
                        if t >= 0.03 && t <= g.width - 0.03 {
                            let slice =
                                ((t / g.width * slices[k] as f64) as usize).min(slices[k] - 1);
                            let bin = (((z - low.0) / WALLED_BIN) as usize).min(bins - 1);
                            seen.low[k][slice] |= 1 << bin;
                        }
                    }
                    continue;
                }
                // The jambs' own faces are left out; the lintel's faces lie on the wall's.
                if t < 0.03 || t > g.width - 0.03 || s.abs() > g.depth / 2.0 + 0.03 {
                    continue;
                }
                let slice = ((t / g.width * slices[k] as f64) as usize).min(slices[k] - 1);
                seen.lowest[k][slice] = seen.lowest[k][slice].min(z);
                seen.heights[k].push(z);
            }
        },
        Seen::merge,
    );
    for (k, g) in gaps.iter_mut().enumerate() {
        if let [Some(s), Some(e)] = near_jamb[k].map(|n| n.value()) {
            let e = -e;
            // Inside the plan's gap, trust the points only near its faces: farther in, they
            // are something in the doorway. Outward, the plan's jamb may be what is wrong.
            if s <= JAMB_SEARCH
                && e >= g.width - JAMB_SEARCH
                && s >= -beyond
                && e <= g.width + beyond
                && e > s
                && e - s <= params.max_door_width
            {
                g.jambs = Some([s, e]);
            }
        }
        // A slice is walled when points stand in most of its height bins.
        let walled = walls[k]
            .iter()
            .filter(|m| 2 * m.count_ones() as usize > bins)
            .count();
        g.walled = walled as f64 >= WALLED_SHARE * slices[k] as f64;
        // The lower of the two ceilings beside the gap, where seen; a lintel is below it.
        let under = ceiling[k]
            .iter()
            .filter_map(Nearest::value)
            .fold(z1, |u, c| u.min(c - params.ceiling_margin));
        let filled = lowest[k].iter().filter(|&&z| z < under).count() as f64 / slices[k] as f64;
        g.lintel = filled >= params.lintel_coverage;
        if g.lintel {
            let h = &mut heights[k];
            h.sort_by(f64::total_cmp);
            // The underside: a low percentile, above stray points.
            g.head_z = Some(h[h.len() / 20]);
        }
    }
}

/// Wall points this far above the floor and under the door height show the jambs: the floor's
/// own points lie lower.
const JAMB_ABOVE_FLOOR: f64 = 0.3;
/// How far inside the plan's gap from its jamb the points' jamb is looked for, metres: the
/// plan's faces stand a cell or so off, and a voxel grid's faces up to a voxel and a half.
const JAMB_SEARCH: f64 = 0.2;
/// The jamb is the third point nearest the gap, so one or two stray points in the doorway do
/// not move it.
const JAMB_RANK: usize = 3;
/// The strip of floor on either side of a gap whose highest points are the ceiling there, as
/// distances from the wall's face, metres: clear of the jambs' and lintel's own faces.
const BESIDE: (f64, f64) = (0.3, 0.8);
/// Height bins under the door height in which a gap's wall points are counted, metres.
const WALLED_BIN: f64 = 0.2;
/// A gap is walled when this share of its 10 cm slices are: an open door leaf or a plan's jamb
/// a cell off fills a slice or two at its ends, never most of a door's width.
const WALLED_SHARE: f64 = 0.8;

/// What the points over and beside the gaps showed, per gap.
struct Seen {
    /// Per 10 cm slice along the gap: the lowest point over it.
    lowest: Vec<Vec<f64>>,
    /// The heights of the points over it.
    heights: Vec<Vec<f64>>,
    /// The wall's points under the door height nearest the gap on either side.
    near_jamb: Vec<[Nearest; 2]>,
    /// Per 10 cm slice along the gap: the height bins under the door height holding a point
    /// within the wall's thickness, as bits.
    low: Vec<Vec<u32>>,
    /// The highest points beside the gap's middle, on its left and on its right.
    ceiling: Vec<[Nearest; 2]>,
}

impl Seen {
    fn merge(mut self, other: Seen) -> Seen {
        for (a, b) in self.lowest.iter_mut().zip(other.lowest) {
            a.iter_mut().zip(b).for_each(|(x, y)| *x = x.min(y));
        }
        for (a, b) in self.heights.iter_mut().zip(other.heights) {
            a.extend(b);
        }
        for (a, b) in self.low.iter_mut().zip(other.low) {
            a.iter_mut().zip(b).for_each(|(x, y)| *x |= y);
        }
        for (a, b) in self
            .near_jamb
            .iter_mut()
            .zip(other.near_jamb)
            .chain(self.ceiling.iter_mut().zip(other.ceiling))
        {
            for (x, y) in a.iter_mut().zip(b) {
                y.top[..y.n].iter().for_each(|&v| x.offer(v));
            }
        }
        self
    }
}

/// The [`JAMB_RANK`] largest values offered.
#[derive(Debug, Clone, Copy, Default)]
struct Nearest {
    top: [f64; JAMB_RANK],
    n: usize,
}

impl Nearest {
    fn offer(&mut self, v: f64) {
        if self.n < JAMB_RANK {
            self.top[self.n] = v;
            self.n += 1;
        } else {
            let (i, min) = self
                .top
                .iter()
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(b.1))
                .map(|(i, &m)| (i, m))
                .unwrap_or((0, f64::INFINITY));
            if v > min {
                self.top[i] = v;
            }
        }
    }

    /// The smallest of the largest values: the [`JAMB_RANK`]-th largest, once that many came.
    fn value(&self) -> Option<f64> {
        (self.n == JAMB_RANK).then(|| self.top.iter().copied().fold(f64::INFINITY, f64::min))
    }
}

/// The bounding box of a ring: min x, min y, max x, max y.
pub(crate) fn ring_box(r: &[P2]) -> [f64; 4] {
    r.iter()
        .fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |b, p| {
            [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ]
        })
}

/// A coarse grid over boxes, so each point is tested against the nearby ones only.
pub(crate) struct BoxIndex {
    origin: P2,
    /// One over the cell's width: a point's cell costs a multiplication rather than a
    /// division. Boxes and points find their cells the same way, so a point finds every box
    /// that holds it.
    inv: f64,
    nx: usize,
    ny: usize,
    cells: Vec<Vec<usize>>,
    /// Per cell, whether it lists any box.
    occupied: Vec<bool>,
}

impl BoxIndex {
    pub(crate) fn new(boxes: &[[f64; 4]]) -> BoxIndex {
        let lo = [
            boxes.iter().map(|b| b[0]).fold(f64::MAX, f64::min),
            boxes.iter().map(|b| b[1]).fold(f64::MAX, f64::min),
        ];
        let hi = [
            boxes.iter().map(|b| b[2]).fold(f64::MIN, f64::max),
            boxes.iter().map(|b| b[3]).fold(f64::MIN, f64::max),
        ];
        let cell = 0.5;
        let nx = (((hi[0] - lo[0]) / cell).ceil() as usize).clamp(1, 4096);
        let ny = (((hi[1] - lo[1]) / cell).ceil() as usize).clamp(1, 4096);
        let cell = ((hi[0] - lo[0]) / nx as f64)
            .max((hi[1] - lo[1]) / ny as f64)
            .max(1e-6);
        let mut index = BoxIndex {
            origin: lo,
            inv: 1.0 / cell,
            nx,
            ny,
            cells: vec![Vec::new(); nx * ny],
            occupied: Vec::new(),
        };
        for (k, b) in boxes.iter().enumerate() {
            let (i0, j0) = index.cell_of([b[0], b[1]]);
            let (i1, j1) = index.cell_of([b[2], b[3]]);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    index.cells[j * nx + i].push(k);
                }
            }
        }
        index.occupied = index.cells.iter().map(|c| !c.is_empty()).collect();
        index
    }

    fn cell_of(&self, p: P2) -> (usize, usize) {
        let i = ((p[0] - self.origin[0]) * self.inv).floor();
        let j = ((p[1] - self.origin[1]) * self.inv).floor();
        (
            (i.max(0.0) as usize).min(self.nx - 1),
            (j.max(0.0) as usize).min(self.ny - 1),
        )
    }

    /// The cell `p` falls in, and whether `p` lies inside the index at all, without a branch.
    /// Saturating casts give any value a cell; `inside` says whether it is the point's.
    #[inline]
    fn cell(&self, p: P2) -> (bool, usize) {
        let i = (p[0] - self.origin[0]) * self.inv;
        let j = (p[1] - self.origin[1]) * self.inv;
        let inside = (i >= 0.0) & (j >= 0.0) & (i < self.nx as f64) & (j < self.ny as f64);
        let k = (j as usize).min(self.ny - 1) * self.nx + (i as usize).min(self.nx - 1);
        (inside, k)
    }

    /// Whether some box may hold `p`: what [`Self::near`] says by being non-empty, without a
    /// branch. A pass over a story's points asks this first, so its one branch is taken the
    /// same way for nearly every point, whatever order the points come in.
    #[inline]
    pub(crate) fn any_near(&self, p: P2) -> bool {
        let (inside, k) = self.cell(p);
        inside & self.occupied[k]
    }

    /// The boxes listed for `p`'s cell, in order; none outside the index.
    pub(crate) fn near(&self, p: P2) -> &[usize] {
        match self.cell(p) {
            (true, k) => &self.cells[k],
            (false, _) => &[],
        }
    }
}
