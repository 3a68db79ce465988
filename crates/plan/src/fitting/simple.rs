//! Validity of rebuilt polygons: simple rings, no crossings between rings, holes inside their
//! exterior, orientation kept. Rings may touch other rings at a shared vertex (a pinch), as
//! OGC allows. Candidate segment pairs come from a uniform grid, so the test is near-linear.

use std::collections::HashMap;

use crate::geom::{self, P2};

/// A segment: ring index and index of its first point in that ring.
pub type SegmentId = (usize, usize);

/// What makes a set of rings invalid.
#[derive(Debug, Clone, PartialEq)]
pub enum Problem {
    /// Two segments cross, overlap, or touch where they may not.
    Crossing(SegmentId, SegmentId),
    /// A ring is degenerate (fewer than 3 points) or lost its orientation.
    BadRing(usize),
    /// A hole (ring index) is not inside its exterior (ring index).
    HoleOutside { hole: usize, exterior: usize },
}

/// Orientation of `c` relative to `a` → `b`: the sign of the cross product.
fn orient(a: P2, b: P2, c: P2) -> f64 {
    geom::cross(geom::sub(b, a), geom::sub(c, a))
}

fn on_segment(a: P2, b: P2, p: P2) -> bool {
    p[0] >= a[0].min(b[0])
        && p[0] <= a[0].max(b[0])
        && p[1] >= a[1].min(b[1])
        && p[1] <= a[1].max(b[1])
}

/// True when segments a–b and c–d intersect other than at an endpoint they share exactly
/// (allowed only when `may_touch`), or overlap along a stretch.
pub fn segments_conflict(a: P2, b: P2, c: P2, d: P2, may_touch: bool) -> bool {
    let (o1, o2, o3, o4) = (
        orient(a, b, c),
        orient(a, b, d),
        orient(c, d, a),
        orient(c, d, b),
    );
    if o1 * o2 < 0.0 && o3 * o4 < 0.0 {
        return true;
    }
    if o1 == 0.0 && o2 == 0.0 {
        // Collinear: conflict when the overlap is longer than a point, or is a point that is not
        // a permitted shared endpoint.
        let axis = if (a[0] - b[0]).abs() >= (a[1] - b[1]).abs() {
            0
        } else {
            1
        };
        let lo = a[axis].min(b[axis]).max(c[axis].min(d[axis]));
        let hi = a[axis].max(b[axis]).min(c[axis].max(d[axis]));
        if lo > hi {
            return false;
        }
        if lo < hi {
            return true;
        }
        let shared = a == c || a == d || b == c || b == d;
        return !(shared && may_touch);
    }
    // A touch: an endpoint of one lies on the other.
    let touches = [
        (o1 == 0.0 && on_segment(a, b, c), c),
        (o2 == 0.0 && on_segment(a, b, d), d),
        (o3 == 0.0 && on_segment(c, d, a), a),
        (o4 == 0.0 && on_segment(c, d, b), b),
    ];
    touches.iter().any(|&(hit, p)| {
        let shared = (p == a || p == b) && (p == c || p == d);
        hit && !(shared && may_touch)
    })
}

/// Even-odd point-in-ring test; `None` when `p` lies on the ring.
fn point_in_ring(p: P2, ring: &[P2]) -> Option<bool> {
    let mut inside = false;
    for i in 0..ring.len() {
        let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
        if orient(a, b, p) == 0.0 && on_segment(a, b, p) {
            return None;
        }
        if (a[1] > p[1]) != (b[1] > p[1])
            && p[0] < a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
        {
            inside = !inside;
        }
    }
    Some(inside)
}

/// Finds every problem in a set of rings. `exterior_of[r]` is `None` for an exterior ring
/// (which must be CCW) and `Some(e)` for a hole of exterior `e` (which must be CW).
pub fn problems(rings: &[Vec<P2>], exterior_of: &[Option<usize>]) -> Vec<Problem> {
    let mut out = Vec::new();
    let mut segments: Vec<(SegmentId, P2, P2)> = Vec::new();
    for (r, ring) in rings.iter().enumerate() {
        let area = geom::ring_signed_area(ring);
        let want_ccw = exterior_of[r].is_none();
        if ring.len() < 3 || !area.is_finite() || (area > 0.0) != want_ccw || area == 0.0 {
            out.push(Problem::BadRing(r));
            continue;
        }
        for i in 0..ring.len() {
            segments.push(((r, i), ring[i], ring[(i + 1) % ring.len()]));
        }
    }
    if segments.is_empty() {
        return out;
    }
    // Grid cell: twice the mean segment length, but no finer than 1/512 of the extent.
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut total = 0.0;
    for (_, a, b) in &segments {
        for p in [a, b] {
            lo = [lo[0].min(p[0]), lo[1].min(p[1])];
            hi = [hi[0].max(p[0]), hi[1].max(p[1])];
        }
        total += geom::dist(*a, *b);
    }
    let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let cell = (2.0 * total / segments.len() as f64)
        .max(extent / 512.0)
        .max(1e-9);
    let key = |p: P2| {
        (
            ((p[0] - lo[0]) / cell).floor() as i64,
            ((p[1] - lo[1]) / cell).floor() as i64,
        )
    };
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (s, (_, a, b)) in segments.iter().enumerate() {
        let (ka, kb) = (key(*a), key(*b));
        for x in ka.0.min(kb.0)..=ka.0.max(kb.0) {
            for y in ka.1.min(kb.1)..=ka.1.max(kb.1) {
                grid.entry((x, y)).or_default().push(s);
            }
        }
    }
    let mut seen = std::collections::HashSet::new();
    let mut cells: Vec<_> = grid.into_iter().collect();
    cells.sort_unstable_by_key(|(k, _)| *k);
    for (_, list) in cells {
        for (x, &s) in list.iter().enumerate() {
            for &t in &list[x + 1..] {
                let ((sid, a, b), (tid, c, d)) = (segments[s], segments[t]);
                let same_ring = sid.0 == tid.0;
                let n = rings[sid.0].len();
                let adjacent = same_ring && ((sid.1 + 1) % n == tid.1 || (tid.1 + 1) % n == sid.1);
                // Neighbours in a ring share a vertex; other rings may touch at a vertex.
                let may_touch = adjacent || !same_ring;
                if segments_conflict(a, b, c, d, may_touch) && seen.insert((s.min(t), s.max(t))) {
                    out.push(Problem::Crossing(sid, tid));
                }
            }
        }
    }
    for (h, ext) in exterior_of.iter().enumerate() {
        let Some(e) = *ext else { continue };
        if out
            .iter()
            .any(|p| matches!(p, Problem::BadRing(r) if *r == h || *r == e))
        {
            continue;
        }
        // Holes may touch their exterior at vertices: judge by the first point off it.
        let verdict = rings[h].iter().find_map(|&p| point_in_ring(p, &rings[e]));
        if verdict == Some(false) {
            out.push(Problem::HoleOutside {
                hole: h,
                exterior: e,
            });
        }
    }
    out.sort_by_key(|p| format!("{p:?}"));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_cases() {
        let (a, b) = ([0.0, 0.0], [2.0, 0.0]);
        assert!(segments_conflict(a, b, [1.0, -1.0], [1.0, 1.0], true)); // cross
        assert!(!segments_conflict(a, b, [1.0, 0.5], [1.0, 1.0], false)); // apart
        assert!(segments_conflict(a, b, [1.0, 0.0], [1.0, 1.0], true)); // T-touch
        assert!(!segments_conflict(a, b, [2.0, 0.0], [3.0, 1.0], true)); // shared end
        assert!(segments_conflict(a, b, [2.0, 0.0], [3.0, 1.0], false));
        assert!(segments_conflict(a, b, [1.0, 0.0], [3.0, 0.0], true)); // overlap
        assert!(segments_conflict(a, b, [2.0, 0.0], [1.0, 0.0], true)); // spike back
        assert!(!segments_conflict(a, b, [2.0, 0.0], [3.0, 0.0], true)); // straight on
    }

    #[test]
    fn rings_valid_and_invalid() {
        let sq = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]];
        let hole = vec![[1.0, 1.0], [1.0, 2.0], [2.0, 2.0], [2.0, 1.0]];
        assert!(problems(&[sq.clone(), hole.clone()], &[None, Some(0)]).is_empty());
        // A hole touching the exterior at a vertex is still valid.
        let touching = vec![[0.0, 0.0], [1.0, 2.0], [2.0, 1.0]];
        assert!(problems(&[sq.clone(), touching], &[None, Some(0)]).is_empty());
        // Bow tie.
        let bow = vec![[0.0, 0.0], [2.0, 2.0], [2.0, 0.0], [0.0, 2.0]];
        assert!(!problems(&[bow], &[None]).is_empty());
        // Hole outside, hole with the wrong orientation, hole crossing the exterior.
        let out_hole = vec![[5.0, 1.0], [5.0, 2.0], [6.0, 2.0], [6.0, 1.0]];
        assert_eq!(
            problems(&[sq.clone(), out_hole], &[None, Some(0)]),
            vec![Problem::HoleOutside {
                hole: 1,
                exterior: 0
            }]
        );
        let mut ccw_hole = hole.clone();
        ccw_hole.reverse();
        assert_eq!(
            problems(&[sq.clone(), ccw_hole], &[None, Some(0)]),
            vec![Problem::BadRing(1)]
        );
        let crossing = vec![[3.0, 1.0], [3.0, 2.0], [5.0, 2.0], [5.0, 1.0]];
        assert_eq!(problems(&[sq, crossing], &[None, Some(0)]).len(), 2);
    }
}
