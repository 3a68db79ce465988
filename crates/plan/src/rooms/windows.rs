//! Windows: stretches of an outer wall where its points stop between a sill and a head, with
//! wall below and above. The wall's points are binned 10 cm along the face by 10 cm of height;
//! a column is a window column when a run of empty height bins at least 0.5 m tall starts
//! `min_sill_height` or more above the floor, with points under and over it. Runs of window
//! columns at least `min_window_width` long are windows.

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
    let mut out = Vec::new();
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
            let (a, b) = (f.at(start as f64 * BIN), f.at((c as f64 * BIN).min(f.len)));
            let mid = geom::scale(geom::add(a, b), 0.5);
            let inside = geom::sub(mid, geom::scale(f.solid_normal(), 0.05));
            out.push(Window {
                id: String::new(),
                a,
                b,
                width: geom::dist(a, b),
                sill_z: story.floor_z + sills[sills.len() / 2],
                head_z: story.floor_z + heads[heads.len() / 2],
                room: spaces
                    .rooms
                    .iter()
                    .find(|r| super::segment::contains(&r.polygon, inside))
                    .map(|r| r.id.clone()),
            });
        }
    }
    for (n, w) in out.iter_mut().enumerate() {
        w.id = format!("L{}-W{}", story.level, n + 1);
    }
    out
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
