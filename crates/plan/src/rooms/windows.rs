//! Windows: stretches of an outer wall where its points stop between a sill and a head, with
//! wall below and above. The wall's points are binned 10 cm along the face by 10 cm of height;
//! a column is a window column when a run of empty height bins at least 0.5 m tall starts
//! `min_sill_height` or more above the floor, with points under and over it. Runs of window
//! columns are window pieces, except on stretches pairing took as an interior wall's face;
//! pieces of one window split by a bend of the fitted wall are joined. The bins place each
//! edge within 10 cm, or miss columns seen too sparsely; a second pass over the points near
//! each window moves its jambs to the last wall point beside the gap and its sill and head to
//! the last point below and above it (`refine`). Windows at least `min_window_width` wide are
//! kept.

use super::faces::Face;
use super::gaps::{ring_box, BoxIndex};
use super::pairing::Coverage;
use super::{RoomsParams, StoryPoints};
use crate::geom::{self, P2};
use crate::plan::{Spaces, StoryPlan, Window};

const BIN: f64 = 0.1;

/// Every window in the story's outer faces. `covered` is what of each face pairing took as one
/// face of an interior wall (see `pairing::pair`): no window there.
pub(crate) fn find(
    story: &StoryPlan,
    faces: &[Face],
    covered: &Coverage,
    points: &StoryPoints<'_>,
    spaces: &Spaces,
    params: &RoomsParams,
) -> Vec<Window> {
    let outer: Vec<(usize, &Face)> = faces
        .iter()
        .enumerate()
        .filter(|(_, f)| f.outer && f.len >= BIN)
        .collect();
    let height = story.ceiling_z - story.floor_z;
    if outer.is_empty() || height.is_nan() || height <= 1.0 {
        return Vec::new();
    }
    let rows = (height / BIN).ceil() as usize;
    let empty =
        || -> Vec<Vec<u32>> { outer.iter().map(|(_, f)| vec![0; cols(f) * rows]).collect() };
    let boxes: Vec<[f64; 4]> = outer
        .iter()
        .map(|(_, f)| band_box(f.a, f.b, f.solid_normal()))
        .collect();
    let index = BoxIndex::new(&boxes);
    // A very dense cloud is read in a stride: 10 cm bins stay well filled. Both cores count a
    // share each, summed after.
    let stride = (points.xyz.len() / 4_000_000).max(1);
    // With a margin: `z` is a difference, rounded.
    let heights = story.floor_z - 0.1..=story.ceiling_z + 0.1;
    let grids = points.fold(
        stride,
        heights,
        empty,
        |grids, q| {
            let z = q[2] as f64 - story.floor_z;
            if !(0.0..height).contains(&z) {
                return;
            }
            let p = [q[0] as f64, q[1] as f64];
            for &k in index.near(p) {
                let f = outer[k].1;
                let t = f.param(p);
                let s = geom::dot(geom::sub(p, f.a), f.solid_normal());
                // On the face, or just in front of it; not the reveal behind.
                if t < 0.0 || t >= f.len || !(-BAND..=BAND).contains(&s) {
                    continue;
                }
                let c = (t / BIN) as usize;
                let r = ((z / BIN) as usize).min(rows - 1);
                grids[k][c * rows + r] += 1;
            }
        },
        |mut a, b| {
            for (x, y) in a.iter_mut().zip(b) {
                x.iter_mut().zip(y).for_each(|(u, v)| *u += v);
            }
            a
        },
    );
    let mut pieces: Vec<Piece> = Vec::new();
    for (k, &(i, f)) in outer.iter().enumerate() {
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
            let (t0, t1) = (start as f64 * BIN, (c as f64 * BIN).min(f.len));
            let middle = (t0 + t1) / 2.0;
            if covered[i]
                .iter()
                .any(|&(lo, hi)| lo <= middle && middle <= hi)
            {
                continue;
            }
            let mut sills: Vec<f64> = columns[start..c].iter().flatten().map(|o| o.0).collect();
            let mut heads: Vec<f64> = columns[start..c].iter().flatten().map(|o| o.1).collect();
            sills.sort_by(f64::total_cmp);
            heads.sort_by(f64::total_cmp);
            pieces.push(Piece {
                a: f.at(t0),
                b: f.at(t1),
                normal: f.solid_normal(),
                sill: sills[sills.len() / 2],
                head: heads[heads.len() / 2],
            });
        }
    }
    let mut windows = merge(pieces);
    refine(&mut windows, story, points, stride);
    let mut out = Vec::new();
    for p in windows {
        let width = geom::dist(p.a, p.b);
        // The refined sill is held to the same floor as the bins' (lower gaps are doors).
        if width < params.min_window_width
            || p.head - p.sill < 0.5
            || p.sill < params.min_sill_height
        {
            continue;
        }
        let mid = geom::scale(geom::add(p.a, p.b), 0.5);
        let inside = geom::sub(mid, geom::scale(p.normal, 0.05));
        out.push(Window {
            id: String::new(),
            a: p.a,
            b: p.b,
            width,
            sill_z: story.floor_z + p.sill,
            head_z: story.floor_z + p.head,
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

/// Points this close to a face's line (either side) are on it, m.
const BAND: f64 = 0.03;
/// How far beyond the bins' edges a jamb is looked for, m: columns of the window the bins
/// missed (seen too sparsely to tell) lie between.
const JAMB_REACH: f64 = 0.5;
/// How far beyond the bins' sill and head they are looked for, m.
const HEIGHT_REACH: f64 = 0.3;

/// The box around the stretch `a`-`b` of a face and the band either side of it.
fn band_box(a: P2, b: P2, normal: P2) -> [f64; 4] {
    let n = geom::scale(normal, 0.1);
    ring_box(&[
        geom::sub(a, n),
        geom::add(a, n),
        geom::sub(b, n),
        geom::add(b, n),
    ])
}

/// A window or a piece of one in plan coordinates: its ends, the face's normal into the wall,
/// and its sill and head above the floor.
#[derive(Debug, Clone, Copy)]
struct Piece {
    a: P2,
    b: P2,
    normal: P2,
    sill: f64,
    head: f64,
}

/// Joins the pieces of one window: the fitted wall may bend where the window left it without
/// samples, splitting the window over two faces, and a column seen through at one height only
/// may split it in one face. Pieces on one line (within 6° and 10 cm), at most two bins apart,
/// with sills and heads within 30 cm, are one window; its sill and head are the pieces' means
/// weighted by width (the points then refine them).
fn merge(mut pieces: Vec<Piece>) -> Vec<Piece> {
    let mut joined = true;
    while joined {
        joined = false;
        'pairs: for i in 0..pieces.len() {
            for j in i + 1..pieces.len() {
                if let Some(p) = join(&pieces[i], &pieces[j]) {
                    pieces[i] = p;
                    pieces.swap_remove(j);
                    joined = true;
                    break 'pairs;
                }
            }
        }
    }
    pieces
}

/// The one window `p` and `q` are pieces of, if they are.
fn join(p: &Piece, q: &Piece) -> Option<Piece> {
    let u = geom::normalize(geom::sub(p.b, p.a))?;
    let v = geom::normalize(geom::sub(q.b, q.a)).unwrap_or(u);
    let n = [-u[1], u[0]];
    let lateral = |x: P2| geom::dot(geom::sub(x, p.a), n).abs();
    if geom::cross(u, v).abs() > 0.1
        || geom::dot(u, v) < 0.0
        || lateral(q.a).max(lateral(q.b)) > 0.1
        || (p.sill - q.sill).abs() > 0.3
        || (p.head - q.head).abs() > 0.3
    {
        return None;
    }
    let s1 = geom::dist(p.a, p.b);
    let t = |x: P2| geom::dot(geom::sub(x, p.a), u);
    let (t0, t1) = (t(q.a).min(t(q.b)), t(q.a).max(t(q.b)));
    let gap = (t0 - s1).max(-t1);
    if gap > 2.0 * BIN + 1e-6 {
        return None;
    }
    let (wp, wq) = (s1, t1 - t0);
    let mean = |x: f64, y: f64| (x * wp + y * wq) / (wp + wq).max(1e-9);
    let at = |t: f64| geom::add(p.a, geom::scale(u, t));
    Some(Piece {
        a: at(t0.min(0.0)),
        b: at(t1.max(s1)),
        normal: p.normal,
        sill: mean(p.sill, q.sill),
        head: mean(p.head, q.head),
    })
}

/// Moves each window's edges to the last point of the wall around the gap: each jamb to the
/// wall point nearest the gap among those at the window's middle heights, within
/// `JAMB_REACH` outside the bins' jamb; the sill to the highest point over the gap's width
/// from `HEIGHT_REACH` below the bins' sill to one bin above it, and the head to the lowest
/// from one bin below the bins' head to `HEIGHT_REACH` above it (a stray point in the glass
/// moves either at most a bin). Where no point is found the bins' edge stays.
fn refine(windows: &mut [Piece], story: &StoryPlan, points: &StoryPoints<'_>, stride: usize) {
    if windows.is_empty() {
        return;
    }
    // Per window: its direction and length, and the edges found [t0, t1, sill, head].
    let frames: Vec<(P2, f64)> = windows
        .iter()
        .map(|w| {
            let len = geom::dist(w.a, w.b);
            let u = geom::normalize(geom::sub(w.b, w.a)).unwrap_or([1.0, 0.0]);
            (u, len)
        })
        .collect();
    let empty = || vec![[None; 4]; windows.len()];
    let boxes: Vec<[f64; 4]> = windows
        .iter()
        .zip(&frames)
        .map(|(w, &(u, len))| {
            let a = geom::sub(w.a, geom::scale(u, JAMB_REACH));
            let b = geom::add(w.a, geom::scale(u, len + JAMB_REACH));
            band_box(a, b, w.normal)
        })
        .collect();
    let index = BoxIndex::new(&boxes);
    // The nearest point to each edge: the same whichever core found it.
    const PICK: [fn(f64, f64) -> f64; 4] = [f64::max, f64::min, f64::max, f64::min];
    // Every height read below, with a margin: `z` is a difference, rounded.
    let edges_z = || windows.iter().flat_map(|w| [w.sill, w.head]);
    let low = edges_z().fold(f64::INFINITY, f64::min);
    let high = edges_z().fold(f64::NEG_INFINITY, f64::max);
    let heights =
        story.floor_z + low - HEIGHT_REACH - 0.1..=story.floor_z + high + HEIGHT_REACH + 0.1;
    let edges: Vec<[Option<f64>; 4]> = points.fold(
        stride,
        heights,
        empty,
        |edges, q| {
            let z = q[2] as f64 - story.floor_z;
            let p = [q[0] as f64, q[1] as f64];
            // One branch, taken for nearly every point: few lie near a window.
            if !index.any_near(p) {
                return;
            }
            for &k in index.near(p) {
                let w = &windows[k];
                let (u, len) = frames[k];
                let d = geom::sub(p, w.a);
                if !(-BAND..=BAND).contains(&geom::dot(d, w.normal)) {
                    continue;
                }
                let t = geom::dot(d, u);
                let between = z > w.sill + BIN && z < w.head - BIN;
                // The sill and head are read a bin in from the jambs the bins gave, as a jamb
                // may still lie a few centimetres inside the window there.
                let over = t > BIN.min(len / 4.0) && t < len - BIN.min(len / 4.0);
                let e = &mut edges[k];
                if between && (-JAMB_REACH..0.02).contains(&t) {
                    keep(&mut e[0], t, PICK[0]);
                }
                if between && t > len - 0.02 && t <= len + JAMB_REACH {
                    keep(&mut e[1], t, PICK[1]);
                }
                if over && (w.sill - HEIGHT_REACH..w.sill + BIN).contains(&z) {
                    keep(&mut e[2], z, PICK[2]);
                }
                if over && z > w.head - BIN && z <= w.head + HEIGHT_REACH {
                    keep(&mut e[3], z, PICK[3]);
                }
            }
        },
        |mut a, b| {
            for (x, y) in a.iter_mut().zip(b) {
                for (j, v) in y.iter().enumerate() {
                    if let Some(v) = v {
                        keep(&mut x[j], *v, PICK[j]);
                    }
                }
            }
            a
        },
    );
    for ((w, &(u, len)), e) in windows.iter_mut().zip(&frames).zip(&edges) {
        let (t0, t1) = (e[0].unwrap_or(0.0), e[1].unwrap_or(len));
        let a = w.a;
        w.a = geom::add(a, geom::scale(u, t0));
        w.b = geom::add(a, geom::scale(u, t1));
        w.sill = e[2].unwrap_or(w.sill);
        w.head = e[3].unwrap_or(w.head);
    }
}

/// Keeps the better of `v` and what `slot` holds, as `pick` says.
fn keep(slot: &mut Option<f64>, v: f64, pick: fn(f64, f64) -> f64) {
    *slot = Some(slot.map_or(v, |old| pick(old, v)));
}

fn cols(f: &Face) -> usize {
    ((f.len / BIN).ceil() as usize).max(1)
}

/// The points an empty run would hold were it wall (the column's mean count per wall bin times
/// the run's bins) must be at least this for the run to be a window: with points falling at
/// random, such a run is empty by chance with probability e^-10 ≈ 5e-5, so a wall seen
/// sparsely (far, at a grazing angle) shows no windows while a sparse cloud's tall windows stay.
const MIN_EXPECTED_POINTS: f64 = 10.0;

/// The sill and head heights (above the floor) of a column's window: the tallest run of empty
/// bins at least 0.5 m tall starting `min_sill_height` up, with points under and over it, in a
/// column whose other bins are mostly filled, and filled densely enough that the run is no
/// chance gap in a sparsely seen wall.
fn opening(column: &[u32], params: &RoomsParams) -> Option<(f64, f64)> {
    let rows = column.len();
    let filled = column.iter().filter(|&&n| n > 0).count();
    let mut best: Option<(usize, usize)> = None;
    let mut r = 0;
    while r < rows {
        if column[r] > 0 {
            r += 1;
            continue;
        }
        let start = r;
        while r < rows && column[r] == 0 {
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
    let mean = column.iter().map(|&n| n as f64).sum::<f64>() / rest.max(1) as f64;
    let dense = filled as f64 >= 0.6 * rest as f64 && mean * (e - s) as f64 >= MIN_EXPECTED_POINTS;
    (head - sill >= 0.5 && sill >= params.min_sill_height && dense).then_some((sill, head))
}
