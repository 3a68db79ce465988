//! Windows: stretches of an outer wall where its points stop between a sill and a head, with
//! wall below and above. The wall's points are binned 10 cm along the face by 10 cm of height;
//! a column is a window column when a run of empty height bins at least 0.5 m tall starts
//! `min_sill_height` or more above the floor, with points under and over it. Runs of window
//! columns at least `min_window_width` long are windows. The bins place each edge within
//! 10 cm; a second pass over the points near each window moves its jambs to the last wall
//! point beside the gap and its sill and head to the last point below and above it, each
//! within one bin of where the bins put it (so a stray point in the glass moves an edge at
//! most one bin).

use super::faces::Face;
use super::gaps::{ring_box, BoxIndex};
use super::{RoomsParams, StoryPoints};
use crate::geom;
use crate::plan::{Spaces, StoryPlan, Window};

const BIN: f64 = 0.1;

/// Every window in the story's outer faces.
pub(crate) fn find(
    story: &StoryPlan,
    faces: &[Face],
    points: &StoryPoints<'_>,
    spaces: &Spaces,
    params: &RoomsParams,
) -> Vec<Window> {
    let outer: Vec<&Face> = faces
        .iter()
        .filter(|f| f.outer && f.len >= params.min_window_width)
        .collect();
    let height = story.ceiling_z - story.floor_z;
    if outer.is_empty() || height.is_nan() || height <= 1.0 {
        return Vec::new();
    }
    let rows = (height / BIN).ceil() as usize;
    let mut grids: Vec<Vec<bool>> = outer.iter().map(|f| vec![false; cols(f) * rows]).collect();
    let boxes: Vec<[f64; 4]> = outer
        .iter()
        .map(|f| {
            let n = geom::scale(f.solid_normal(), 0.1);
            ring_box(&[
                geom::sub(f.a, n),
                geom::add(f.a, n),
                geom::sub(f.b, n),
                geom::add(f.b, n),
            ])
        })
        .collect();
    let index = BoxIndex::new(&boxes);
    // A very dense cloud is read in a stride: 10 cm bins stay well filled.
    let stride = (points.xyz.len() / 4_000_000).max(1);
    for q in points.xyz.iter().step_by(stride) {
        let z = q[2] as f64 - story.floor_z;
        if !(0.0..height).contains(&z) {
            continue;
        }
        let p = [q[0] as f64, q[1] as f64];
        for &k in index.near(p) {
            let f = outer[k];
            let t = f.param(p);
            let s = geom::dot(geom::sub(p, f.a), f.solid_normal());
            // On the face, or just in front of it; not the reveal behind.
            if t < 0.0 || t >= f.len || !(-0.03..=0.03).contains(&s) {
                continue;
            }
            let c = (t / BIN) as usize;
            let r = ((z / BIN) as usize).min(rows - 1);
            grids[k][c * rows + r] = true;
        }
    }
    let mut found: Vec<Found> = Vec::new();
    for (k, f) in outer.iter().enumerate() {
        let columns: Vec<Option<(f64, f64)>> = (0..cols(f))
            .map(|c| opening(&grids[k][c * rows..(c + 1) * rows], params))
            .collect();
        let mut c = 0;
        while c < columns.len() {
            if columns[c].is_none() {
                c += 1;
                continue;
            }
            let start = c;
            while c < columns.len() && columns[c].is_some() {
                c += 1;
            }
            let width = (c - start) as f64 * BIN;
            if width < params.min_window_width {
                continue;
            }
            let mut sills: Vec<f64> = columns[start..c].iter().flatten().map(|o| o.0).collect();
            let mut heads: Vec<f64> = columns[start..c].iter().flatten().map(|o| o.1).collect();
            sills.sort_by(f64::total_cmp);
            heads.sort_by(f64::total_cmp);
            let (t0, t1) = (start as f64 * BIN, (c as f64 * BIN).min(f.len));
            let (sill, head) = (sills[sills.len() / 2], heads[heads.len() / 2]);
            found.push(Found {
                face: k,
                bins: [t0, t1, sill, head],
                // Each edge's last point, from where the bins put it (nothing seen yet).
                edges: [t0, t1, sill, head],
                seen: [false; 4],
            });
        }
    }
    refine(&mut found, &outer, story, points, stride);
    let mut out = Vec::new();
    for w in &found {
        let f = outer[w.face];
        let [t0, t1, sill, head] = w.edges;
        let (a, b) = (f.at(t0), f.at(t1));
        let mid = geom::scale(geom::add(a, b), 0.5);
        let inside = geom::sub(mid, geom::scale(f.solid_normal(), 0.05));
        out.push(Window {
            id: String::new(),
            a,
            b,
            width: geom::dist(a, b),
            sill_z: story.floor_z + sill,
            head_z: story.floor_z + head,
            room: spaces
                .rooms
                .iter()
                .find(|r| super::segment::contains(&r.polygon, inside))
                .map(|r| r.id.clone()),
        });
    }
    for (n, w) in out.iter_mut().enumerate() {
        w.id = format!("L{}-W{}", story.level, n + 1);
    }
    out
}

/// A window the bins found on outer face `face`: `bins` are its jambs along the face and its
/// sill and head above the floor as the bins give them, `edges` the same refined by the points.
struct Found {
    face: usize,
    bins: [f64; 4],
    edges: [f64; 4],
    seen: [bool; 4],
}

/// Moves each window's edges to the last point of the wall around it: the jambs to the wall
/// points between the sill and head nearest the gap, the sill and head to the points over the
/// gap's width nearest it, each searched only in the bin outside the bins' edge.
fn refine(
    found: &mut [Found],
    outer: &[&Face],
    story: &StoryPlan,
    points: &StoryPoints<'_>,
    stride: usize,
) {
    if found.is_empty() {
        return;
    }
    let boxes: Vec<[f64; 4]> = found
        .iter()
        .map(|w| {
            let f = outer[w.face];
            let n = geom::scale(f.solid_normal(), 0.1);
            let (a, b) = (f.at(w.bins[0] - BIN), f.at(w.bins[1] + BIN));
            ring_box(&[
                geom::sub(a, n),
                geom::add(a, n),
                geom::sub(b, n),
                geom::add(b, n),
            ])
        })
        .collect();
    let index = BoxIndex::new(&boxes);
    for q in points.xyz.iter().step_by(stride) {
        let z = q[2] as f64 - story.floor_z;
        let p = [q[0] as f64, q[1] as f64];
        for &k in index.near(p) {
            let w = &mut found[k];
            let f = outer[w.face];
            let s = geom::dot(geom::sub(p, f.a), f.solid_normal());
            if !(-0.03..=0.03).contains(&s) {
                continue;
            }
            let t = f.param(p);
            let [t0, t1, sill, head] = w.bins;
            let between = z > sill && z < head;
            let over = t > t0 && t < t1;
            // Each edge keeps the point nearest the gap within one bin outside it.
            if between && t >= t0 - BIN && t < t0 {
                take(w, 0, t, |new, old| new > old);
            }
            if between && t > t1 && t <= t1 + BIN {
                take(w, 1, t, |new, old| new < old);
            }
            if over && z >= sill - BIN && z < sill {
                take(w, 2, z, |new, old| new > old);
            }
            if over && z > head && z <= head + BIN {
                take(w, 3, z, |new, old| new < old);
            }
        }
    }
}

/// Sets edge `e` of `w` to `v` when it is the first point seen or `nearer` than the last.
fn take(w: &mut Found, e: usize, v: f64, nearer: impl Fn(f64, f64) -> bool) {
    if !w.seen[e] || nearer(v, w.edges[e]) {
        w.edges[e] = v;
        w.seen[e] = true;
    }
}

fn cols(f: &Face) -> usize {
    ((f.len / BIN).ceil() as usize).max(1)
}

/// The sill and head heights (above the floor) of a column's window: the tallest run of empty
/// bins at least 0.5 m tall starting `min_sill_height` up, with points under and over it, in a
/// column whose other bins are mostly filled (so a sparsely seen wall is no window).
fn opening(column: &[bool], params: &RoomsParams) -> Option<(f64, f64)> {
    let rows = column.len();
    let filled = column.iter().filter(|b| **b).count();
    let mut best: Option<(usize, usize)> = None;
    let mut r = 0;
    while r < rows {
        if column[r] {
            r += 1;
            continue;
        }
        let start = r;
        while r < rows && !column[r] {
            r += 1;
        }
        let closed = start > 0 && r < rows;
        if closed && best.is_none_or(|(s, e)| r - start > e - s) {
            best = Some((start, r));
        }
    }
    let (s, e) = best?;
    let (sill, head) = (s as f64 * BIN, e as f64 * BIN);
    let rest = rows - (e - s);
    let dense = filled as f64 >= 0.6 * rest as f64;
    (head - sill >= 0.5 && sill >= params.min_sill_height && dense).then_some((sill, head))
}
