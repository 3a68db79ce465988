//! Validity of plan polygons: closed rings with area, no crossings, holes inside.

use crate::geom::{self, P2};
use crate::plan::Polygon;

fn orient(a: P2, b: P2, c: P2) -> f64 {
    geom::cross(geom::sub(b, a), geom::sub(c, a))
}

fn on_segment(p: P2, a: P2, b: P2) -> bool {
    orient(a, b, p) == 0.0
        && p[0] >= a[0].min(b[0])
        && p[0] <= a[0].max(b[0])
        && p[1] >= a[1].min(b[1])
        && p[1] <= a[1].max(b[1])
}

/// How two segments meet: not at all, at a single touching point, or crossing/overlapping.
#[derive(PartialEq)]
enum Contact {
    None,
    Touch,
    Cross,
}

fn contact(p1: P2, p2: P2, q1: P2, q2: P2) -> Contact {
    let d1 = orient(q1, q2, p1);
    let d2 = orient(q1, q2, p2);
    let d3 = orient(p1, p2, q1);
    let d4 = orient(p1, p2, q2);
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return Contact::Cross;
    }
    let touches = on_segment(p1, q1, q2)
        || on_segment(p2, q1, q2)
        || on_segment(q1, p1, p2)
        || on_segment(q2, p1, p2);
    if !touches {
        return Contact::None;
    }
    if d1 == 0.0 && d2 == 0.0 {
        // Collinear: they overlap when q's projection onto p covers more than a point.
        let d = geom::sub(p2, p1);
        let len2 = geom::dot(d, d);
        if len2 > 0.0 {
            let t = |q: P2| geom::dot(geom::sub(q, p1), d) / len2;
            let (a, b) = (t(q1).min(t(q2)), t(q1).max(t(q2)));
            if b.min(1.0) - a.max(0.0) > 1e-12 {
                return Contact::Cross;
            }
        }
    }
    Contact::Touch
}

/// Checks that every ring has at least three vertices and positive area, that no ring crosses
/// itself or another, and that holes lie inside their exterior. Rings of different polygons or
/// a hole and its exterior may touch at single points; a ring may not touch itself.
pub fn watertight(polygons: &[Polygon]) -> Result<(), String> {
    if polygons.is_empty() {
        return Err("no polygons".into());
    }
    // (ring id, index in ring, ring length, a, b)
    let mut segs: Vec<(usize, usize, usize, P2, P2)> = Vec::new();
    let mut ring_id = 0;
    for (pi, p) in polygons.iter().enumerate() {
        for (hi, r) in std::iter::once(&p.exterior).chain(&p.holes).enumerate() {
            let mut r = r.clone();
            while r.len() > 1 && r.first() == r.last() {
                r.pop();
            }
            let what = if hi == 0 {
                format!("polygon {pi} exterior")
            } else {
                format!("polygon {pi} hole {}", hi - 1)
            };
            if r.len() < 3 {
                return Err(format!("{what} has {} vertices", r.len()));
            }
            if r.iter().flatten().any(|c| !c.is_finite()) {
                return Err(format!("{what} has a non-finite vertex"));
            }
            if geom::ring_signed_area(&r).abs() <= 0.0 {
                return Err(format!("{what} has zero area"));
            }
            // A hole may touch its exterior at a point (OGC): judge it by a vertex off the
            // exterior's boundary. Crossings are caught below.
            let on_exterior = |q: P2| {
                (0..p.exterior.len()).any(|k| {
                    let (a, b) = (p.exterior[k], p.exterior[(k + 1) % p.exterior.len()]);
                    geom::point_segment_distance(q, a, b) <= 1e-9
                })
            };
            if hi > 0
                && r.iter()
                    .find(|&&q| !on_exterior(q))
                    .is_some_and(|&q| !crate::simulate::rects::point_in_ring(q, &p.exterior))
            {
                return Err(format!("{what} is not inside its exterior"));
            }
            let n = r.len();
            for k in 0..n {
                segs.push((ring_id, k, n, r[k], r[(k + 1) % n]));
            }
            ring_id += 1;
        }
    }
    segs.sort_by(|a, b| a.3[0].min(a.4[0]).total_cmp(&b.3[0].min(b.4[0])));
    for i in 0..segs.len() {
        let (ri, ki, n, a, b) = segs[i];
        let max_x = a[0].max(b[0]);
        for &(rj, kj, _, c, d) in &segs[i + 1..] {
            if c[0].min(d[0]) > max_x {
                break;
            }
            if a[1].max(b[1]) < c[1].min(d[1]) || c[1].max(d[1]) < a[1].min(b[1]) {
                continue;
            }
            let adjacent = ri == rj && ((ki + 1) % n == kj || (kj + 1) % n == ki);
            match contact(a, b, c, d) {
                Contact::None => {}
                Contact::Touch if adjacent || ri != rj => {}
                Contact::Cross if adjacent && n > 3 => {
                    // Adjacent edges share one vertex; anything more is a fold back.
                    return Err(format!("ring {ri} folds back on itself near {a:?}"));
                }
                _ => {
                    return Err(format!(
                        "ring {ri} edge {ki} ({a:?} to {b:?}) meets ring {rj} edge {kj} ({c:?} to {d:?})"
                    ))
                }
            }
        }
    }
    Ok(())
}
