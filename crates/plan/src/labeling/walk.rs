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
    visit: impl FnMut(u32, f64, f64),
) -> WalkEnd {
    walk_steps::<true>(mesh, start, a, b, t0, t_end, visit)
}

/// [`walk`] from `a` (parameter 0) for a visitor that needs only the triangles: the same
/// triangles, in the same order, with the same end.
pub(crate) fn walk_from_start(
    mesh: &Mesh,
    start: u32,
    a: P2,
    b: P2,
    t_end: f64,
    mut visit: impl FnMut(u32),
) -> WalkEnd {
    // The exit test without the parameters holds for an end past the start, in normal range.
    if !(t_end.is_normal() && t_end > 0.0) {
        return walk(mesh, start, a, b, 0.0, t_end, |t, _, _| visit(t));
    }
    walk_steps::<false>(mesh, start, a, b, 0.0, t_end, |t, _, _| visit(t))
}

/// Just under 1, so that `t_end * SHORT * den`, rounded twice, stays below `t_end * den` by more
/// than the division's rounding (see [`exits_short`]).
const SHORT: f64 = 1.0 - 1.0 / (1u64 << 48) as f64;

/// True when `num / den`, rounded, is surely below `t_end` (`short_end` is `t_end * SHORT`,
/// `t_end` positive and normal); false when it may not be. Comparing with one product instead
/// of dividing: the division's latency would hold up every step of a walk, and all but the
/// last step end short. The product `short_end * den` is at most `t_end * den * SHORT * (1 +
/// 2^-53)^2`; below it, `num / den` rounds to at most `t_end * SHORT * (1 + 2^-53)^3 < t_end`.
/// A product that is not a positive normal number (den not positive, or far too small) decides
/// nothing.
#[inline]
fn exits_short(num: f64, den: f64, short_end: f64) -> bool {
    let bound = short_end * den;
    bound >= f64::MIN_POSITIVE && num < bound
}

/// The walk. With `PARAMS`, every step divides to find where the line leaves the triangle,
/// and `visit` gets the parameters; without, the parameters it gets are NaN, and a step
/// divides only when [`exits_short`] cannot tell that the walk goes on (`t0` must then be 0
/// and `t_end` positive and normal). Either way the same triangles are visited: a step's exit
/// is compared with `t_end` on the same rounded quotient.
fn walk_steps<const PARAMS: bool>(
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
    let short_end = t_end * SHORT;
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
        let (num, den) = (geom::cross(geom::sub(p, a), pq), geom::cross(d, pq));
        let ended = if PARAMS {
            let t_out = (num / den).max(t_in);
            visit(t, t_in, t_out);
            t_in = t_out;
            t_out >= t_end
        } else {
            visit(t, f64::NAN, f64::NAN);
            // `t_in` stays 0, below `t_end`: the exit is at or beyond `t_end` exactly when the
            // quotient is.
            !exits_short(num, den, short_end) && num / den >= t_end
        };
        if ended {
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
        match walk_from_start(mesh, start, c, p, 1.0, |_| {}) {
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
    // From the start, every triangle up to the end is visited: no step needs its parameters.
    let whole = lo <= 0.0 && hi.is_normal() && hi > 0.0;
    let mut go = |from: u32| {
        if whole {
            walk_from_start(mesh, from, a, b, hi, &mut visit)
        } else {
            walk(mesh, from, a, b, 0.0, hi, |t, t_in, t_out| {
                if t_out >= lo && t_in <= hi {
                    visit(t);
                }
            })
        }
    };
    match go(start) {
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
                Some((t, _)) => !matches!(go(t), WalkEnd::Missed),
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

    #[test]
    fn a_short_exit_is_never_one_the_division_puts_at_the_end() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let ulps = |x: f64, k: i64| f64::from_bits((x.to_bits() as i64 + k) as u64);
        let mut decided = 0;
        for n in 0..200_000 {
            let t_end: f64 = if n % 2 == 0 {
                rng.random_range(0.3..1.0)
            } else {
                1.0
            };
            let den: f64 = rng.random_range(1e-9..1e3) * if n % 7 == 0 { -1.0 } else { 1.0 };
            // Quotients at the end, a few ulps around it, and anywhere.
            let num = match n % 3 {
                0 => ulps(t_end * den, rng.random_range(-40..40)),
                1 => t_end * den * (1.0 - rng.random_range(0.0..1e-13)),
                _ => den * rng.random_range(-2.0..2.0),
            };
            if exits_short(num, den, t_end * SHORT) {
                decided += 1;
                assert!(num / den < t_end, "{num} / {den} against {t_end}");
            }
        }
        assert!(decided > 50_000, "the product decided only {decided} cases");
        // What is no positive normal product decides nothing.
        for (num, den) in [
            (1.0, 0.0),
            (1.0, -1.0),
            (f64::NAN, 1.0),
            (1.0, f64::NAN),
            (0.0, 1e-320),
        ] {
            assert!(!exits_short(num, den, SHORT), "{num} / {den}");
        }
        assert!(!exits_short(f64::INFINITY, 1.0, SHORT));
    }

    #[test]
    fn a_walk_without_parameters_visits_what_the_walk_with_them_does() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let scattered: Vec<P2> = (0..300)
            .map(|_| [rng.random_range(0.0..10.0), rng.random_range(0.0..10.0)])
            .collect();
        for m in [grid_mesh(), Mesh::build(&scattered, &[]).unwrap()] {
            let span = if m.vertices.len() > 100 { 10.0 } else { 4.0 };
            let mut ends = 0;
            for n in 0..3_000 {
                // Through vertices and along edges on the grid; anywhere among the scattered.
                let at = |r: &mut rand_chacha::ChaCha8Rng| {
                    if n % 2 == 0 {
                        [
                            r.random_range(0..=8) as f64 / 2.0,
                            r.random_range(0..=8) as f64 / 2.0,
                        ]
                    } else {
                        [r.random_range(0.0..span), r.random_range(0.0..span)]
                    }
                };
                let (a, b) = (at(&mut rng), at(&mut rng));
                let Some(start) = locate(&m, a, 0) else {
                    continue;
                };
                let mut exact = Vec::new();
                walk(&m, start, a, b, 0.0, 1.0, |t, _, t_out| {
                    exact.push((t, t_out))
                });
                // Ends anywhere, and exactly at each exit and an ulp either side of it.
                let mut t_ends = vec![rng.random_range(0.01..1.5), 1.0];
                if let Some(&(_, t_out)) = exact.get(rng.random_range(0..exact.len().max(1))) {
                    if t_out.is_normal() && t_out > 0.0 {
                        let up = f64::from_bits(t_out.to_bits() + 1);
                        let down = f64::from_bits(t_out.to_bits() - 1);
                        t_ends.extend([t_out, up, down]);
                        ends += 1;
                    }
                }
                for t_end in t_ends {
                    let mut with = Vec::new();
                    let e1 = walk(&m, start, a, b, 0.0, t_end, |t, _, _| with.push(t));
                    let mut without = Vec::new();
                    let e2 = walk_from_start(&m, start, a, b, t_end, |t| without.push(t));
                    assert_eq!((e1, &with), (e2, &without), "{a:?} -> {b:?} to {t_end}");
                }
            }
            assert!(ends > 1_000, "only {ends} walks ended at an exit");
        }
    }
}
