//! Straight-line walks through the triangulation: point location and the triangles a segment
//! crosses (§3.3's lines of sight and mobile path), after Turner's `raytrace_triangulation`.
//!
//! Robustness: which side of the line a→b each vertex lies on is decided by an exact orientation
//! predicate, and a vertex exactly on the line counts as left. That is the same as moving the
//! line an infinitesimal step to the right, so the walk never meets a vertex or runs along an
//! edge: every triangle it enters has exactly one exit edge, and the walk cannot cycle.

use robust::{orient2d, Coord};

use super::mesh::{Mesh, NONE};
use crate::geom::{self, P2};

/// How a walk ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum WalkEnd {
    /// The segment's end lies in this triangle.
    Reached(u32),
    /// The line left the triangulation's hull; the last triangle inside.
    Hull(u32),
    /// The line does not cross the start triangle (it only touches a vertex), or a == b.
    Missed,
}

/// The vertex after each of a triangle's three, counter-clockwise.
const NEXT: [usize; 3] = [1, 2, 0];

/// [`EXIT`]'s entry where the line leaves by no edge.
const NO_EXIT: usize = 3;

/// For each pattern of sides (bit k set when vertex k is left of the line), the edge k→k+1
/// the line leaves by: the first counter-clockwise edge going from right to left.
const EXIT: [u8; 8] = {
    let mut exit = [NO_EXIT as u8; 8];
    let mut m = 0;
    while m < 8 {
        let mut k = 3;
        while k > 0 {
            k -= 1;
            let (here, next) = ((m >> k) & 1, (m >> NEXT[k]) & 1);
            if here == 0 && next == 1 {
                exit[m] = k as u8;
            }
        }
        m += 1;
    }
    exit
};

/// The sides of a triangle's vertices as bits, bit k from `left_of(tri[k])`.
#[inline]
fn sides(tri: [u32; 3], mut left_of: impl FnMut(u32) -> bool) -> u8 {
    u8::from(left_of(tri[0])) | u8::from(left_of(tri[1])) << 1 | u8::from(left_of(tri[2])) << 2
}

/// True when `p` is left of, or on, the directed line a→b.
#[inline]
fn left(a: P2, b: P2, p: P2) -> bool {
    orient2d(
        Coord { x: a[0], y: a[1] },
        Coord { x: b[0], y: b[1] },
        Coord { x: p[0], y: p[1] },
    ) >= 0.0
}

/// Walks the line through `a` and `b` from triangle `start`, which must contain the point at
/// line parameter `t0` (0 at a, 1 at b). Calls `visit(t, t_in, t_out)` for every triangle in
/// order, with the parameters where the line enters and leaves it, until a triangle whose exit
/// lies at or beyond `t_end`.
pub(crate) fn walk(
    mesh: &Mesh,
    start: u32,
    a: P2,
    b: P2,
    t0: f64,
    t_end: f64,
    mut visit: impl FnMut(u32, f64, f64),
) -> WalkEnd {
    let d = geom::sub(b, a);
    if d == [0.0, 0.0] {
        return WalkEnd::Missed;
    }
    let mut t = start;
    let mut t_in = t0;
    let mut tri = mesh.triangles[t as usize];
    // Side of each vertex of the current triangle, a bit each (set: left); carried across the
    // shared edge.
    let mut side = sides(tri, |v| left(a, b, mesh.vertices[v as usize]));
    // A straight line crosses each triangle at most once; the cap only guards against a broken mesh.
    for _ in 0..=mesh.triangles.len() {
        let i = EXIT[side as usize] as usize;
        if i == NO_EXIT {
            return WalkEnd::Missed;
        }
        let (pv, qv) = (tri[i], tri[NEXT[i]]);
        let p = mesh.vertices[pv as usize];
        let q = mesh.vertices[qv as usize];
        let pq = geom::sub(q, p);
        // p is strictly right of the line, so the edge is not parallel to it.
        let t_out = (geom::cross(geom::sub(p, a), pq) / geom::cross(d, pq)).max(t_in);
        visit(t, t_in, t_out);
        if t_out >= t_end {
            return WalkEnd::Reached(t);
        }
        let next = mesh.neighbors[t as usize][NEXT[NEXT[i]]];
        if next == NONE {
            return WalkEnd::Hull(t);
        }
        // The next triangle shares p (right) and q (left); only its third vertex is new.
        let ntri = mesh.triangles[next as usize];
        side = sides(ntri, |v| {
            if v == pv {
                false
            } else if v == qv {
                true
            } else {
                left(a, b, mesh.vertices[v as usize])
            }
        });
        tri = ntri;
        t = next;
        t_in = t_out;
    }
    WalkEnd::Missed
}

impl Mesh {
    /// The triangle containing `p` (either one when `p` is on an edge), found by walking from
    /// triangle `hint`; `None` when `p` is outside the mesh. Nearby hints make it fast.
    pub fn locate(&self, p: P2, hint: usize) -> Option<usize> {
        if self.triangles.is_empty() || !(p[0].is_finite() && p[1].is_finite()) {
            return None;
        }
        locate(self, p, hint.min(self.triangles.len() - 1) as u32).map(|t| t as usize)
    }
}

/// The centroid of triangle `t`.
pub(crate) fn centroid(mesh: &Mesh, t: u32) -> P2 {
    let [a, b, c] = mesh.corners(t as usize);
    [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0]
}

/// The triangle containing `p` (on an edge: either side), walking from `hint`. `None` when `p`
/// lies outside the triangulation.
pub(crate) fn locate(mesh: &Mesh, p: P2, hint: u32) -> Option<u32> {
    // A centroid is strictly inside its triangle, so the walk starts cleanly; a sliver's
    // rounded centroid may not be, so fall back to the hint's neighbours.
    let nb = mesh.neighbors[hint as usize];
    for start in std::iter::once(hint).chain(nb.into_iter().filter(|&n| n != NONE)) {
        let c = centroid(mesh, start);
        if c == p {
            return Some(start);
        }
        match walk(mesh, start, c, p, 0.0, 1.0, |_, _, _| {}) {
            WalkEnd::Reached(t) => return Some(t),
            WalkEnd::Hull(_) => return None,
            WalkEnd::Missed => continue,
        }
    }
    None
}

/// Every triangle the segment a→b crosses between parameters `lo` and `hi` (0 ≤ lo ≤ hi ≤ 1),
/// each once, given the triangle `start` containing `a`. Returns false when the segment's
/// start is degenerate (exactly on a vertex, missing `start`) and could not be recovered.
pub(crate) fn segment_triangles(
    mesh: &Mesh,
    start: u32,
    a: P2,
    b: P2,
    lo: f64,
    hi: f64,
    mut visit: impl FnMut(u32),
) -> bool {
    let mut on = |t: u32, t_in: f64, t_out: f64| {
        if t_out >= lo && t_in <= hi {
            visit(t);
        }
    };
    match walk(mesh, start, a, b, 0.0, hi, &mut on) {
        WalkEnd::Reached(_) | WalkEnd::Hull(_) => true,
        WalkEnd::Missed => {
            // `a` lies on an edge or vertex of `start`, and the (perturbed) line leaves it
            // through another triangle touching `start`: the one where it runs farthest.
            let best = touching(mesh, start)
                .into_iter()
                .filter(|&t| closed_contains(mesh, t, a))
                .filter_map(|t| exit_param(mesh, t, a, b).map(|p| (t, p)))
                .max_by(|x, y| x.1.total_cmp(&y.1));
            match best {
                Some((t, _)) => !matches!(walk(mesh, t, a, b, 0.0, hi, on), WalkEnd::Missed),
                None => false,
            }
        }
    }
}

/// Every triangle sharing a vertex with `t` (including `t`).
fn touching(mesh: &Mesh, t: u32) -> Vec<u32> {
    let mut out = vec![t];
    for &v in &mesh.triangles[t as usize] {
        // Rotate around v one way, and the other way if the hull stops the first.
        for dir in [1, 2] {
            let mut cur = t;
            for _ in 0..mesh.triangles.len() {
                let Some(j) = mesh.triangles[cur as usize].iter().position(|&x| x == v) else {
                    break;
                };
                let next = mesh.neighbors[cur as usize][(j + dir) % 3];
                if next == NONE || next == t {
                    break;
                }
                if !out.contains(&next) {
                    out.push(next);
                }
                cur = next;
            }
        }
    }
    out
}

/// True when `p` is in the closed triangle `t` (exact).
fn closed_contains(mesh: &Mesh, t: u32, p: P2) -> bool {
    let [a, b, c] = mesh.corners(t as usize);
    left(a, b, p) && left(b, c, p) && left(c, a, p)
}

/// The line parameter where the perturbed line a→b leaves triangle `t`, if it crosses it.
fn exit_param(mesh: &Mesh, t: u32, a: P2, b: P2) -> Option<f64> {
    let tri = mesh.triangles[t as usize];
    let i = EXIT[sides(tri, |v| left(a, b, mesh.vertices[v as usize])) as usize] as usize;
    if i == NO_EXIT {
        return None;
    }
    let p = mesh.vertices[tri[i] as usize];
    let pq = geom::sub(mesh.vertices[tri[NEXT[i]] as usize], p);
    Some(geom::cross(geom::sub(p, a), pq) / geom::cross(geom::sub(b, a), pq))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_mesh() -> Mesh {
        // A 5×5 grid: many cocircular quadruples, and lines through vertices and along edges.
        let mut pts = Vec::new();
        for i in 0..5 {
            for j in 0..5 {
                pts.push([i as f64, j as f64]);
            }
        }
        Mesh::build(&pts, &[]).unwrap()
    }

    fn contains(mesh: &Mesh, t: u32, p: P2) -> bool {
        let [a, b, c] = mesh.corners(t as usize);
        let o = |u: P2, v: P2| geom::cross(geom::sub(v, u), geom::sub(p, u)) >= -1e-12;
        o(a, b) && o(b, c) && o(c, a)
    }

    #[test]
    fn locate_finds_the_containing_triangle_from_any_hint() {
        let m = grid_mesh();
        for hint in [
            0,
            m.triangles.len() as u32 / 2,
            m.triangles.len() as u32 - 1,
        ] {
            for p in [[0.3, 0.2], [2.5, 2.5], [3.0, 1.0], [1.5, 3.0], [-1.0, 5.5]] {
                let t = locate(&m, p, hint).unwrap();
                assert!(contains(&m, t, p), "{p:?} not in {t}");
            }
            assert_eq!(locate(&m, [100.0, 0.0], hint), None);
        }
    }

    #[test]
    fn walk_along_grid_lines_covers_the_segment_without_repeats() {
        let m = grid_mesh();
        // Along a grid line (through vertices and along edges), diagonally, and generic.
        for (a, b) in [
            ([0.5, 1.0], [3.5, 1.0]),
            ([0.5, 0.5], [3.5, 3.5]),
            ([0.2, 0.7], [3.9, 2.3]),
            ([4.0, 4.0], [0.0, 0.0]),
        ] {
            let start = locate(&m, a, 0).unwrap();
            let mut seen = Vec::new();
            assert!(segment_triangles(&m, start, a, b, 0.0, 1.0, |t| seen.push(t)));
            let mut dedup = seen.clone();
            dedup.sort_unstable();
            dedup.dedup();
            assert_eq!(dedup.len(), seen.len(), "a triangle was visited twice");
            // Every point of the segment lies in some visited triangle, and the last holds b.
            for k in 0..=50 {
                let p = geom::add(a, geom::scale(geom::sub(b, a), k as f64 / 50.0));
                assert!(
                    seen.iter().any(|&t| contains(&m, t, p)),
                    "{p:?} of {a:?}->{b:?} not covered"
                );
            }
            assert!(contains(&m, *seen.last().unwrap(), b));
        }
    }

    #[test]
    fn the_exit_table_names_the_first_edge_from_right_to_left() {
        for (m, &exit) in EXIT.iter().enumerate() {
            let side = [m & 1 != 0, m & 2 != 0, m & 4 != 0];
            let first = (0..3).find(|&i| !side[i] && side[(i + 1) % 3]);
            assert_eq!(first.unwrap_or(NO_EXIT), exit as usize, "sides {side:?}");
        }
        // All on one side: the line misses the triangle.
        assert_eq!(EXIT[0] as usize, NO_EXIT);
        assert_eq!(EXIT[7] as usize, NO_EXIT);
    }

    #[test]
    fn central_part_skips_the_ends() {
        let m = grid_mesh();
        let (a, b) = ([0.1, 0.3], [3.9, 0.3]);
        let start = locate(&m, a, 0).unwrap();
        let mut seen = Vec::new();
        segment_triangles(&m, start, a, b, 0.25, 0.75, |t| seen.push(t));
        assert!(!seen
            .iter()
            .any(|&t| contains(&m, t, a) || contains(&m, t, b)));
        assert!(seen.iter().any(|&t| contains(&m, t, [2.0, 0.3])));
    }
}
