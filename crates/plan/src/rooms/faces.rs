//! A story's wall faces: the boundary edges of its polygons, each directed so that the free
//! floor lies on its left (exteriors run counter-clockwise and holes clockwise, so both do).

use crate::geom::{self, P2};
use crate::plan::Polygon;

/// One straight face.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Face {
    pub a: P2,
    pub b: P2,
    /// Unit direction a → b.
    pub u: P2,
    pub len: f64,
    /// On the outer ring of its polygon (not a hole).
    pub outer: bool,
}

impl Face {
    /// The unit normal into the solid side (right of a → b).
    pub fn solid_normal(&self) -> P2 {
        [self.u[1], -self.u[0]]
    }

    /// The point at distance `t` along the face from `a`.
    pub fn at(&self, t: f64) -> P2 {
        geom::add(self.a, geom::scale(self.u, t))
    }

    /// Where `p` projects on the face's line, as a distance from `a`.
    pub fn param(&self, p: P2) -> f64 {
        geom::dot(geom::sub(p, self.a), self.u)
    }
}

/// Nearly straight runs of edges (within 1°) become one face; zero-length edges are skipped.
pub(crate) fn faces(polygons: &[Polygon]) -> Vec<Face> {
    let mut out = Vec::new();
    for p in polygons {
        ring_faces(&p.exterior, true, &mut out);
        for h in &p.holes {
            ring_faces(h, false, &mut out);
        }
    }
    out
}

fn ring_faces(ring: &[P2], outer: bool, out: &mut Vec<Face>) {
    let n = ring.len();
    if n < 3 {
        return;
    }
    let dir = |k: usize| geom::normalize(geom::sub(ring[(k + 1) % n], ring[k]));
    // Start at a corner, so a straight run is never split at the ring's seam.
    let turn = |k: usize| match (dir((k + n - 1) % n), dir(k)) {
        (Some(a), Some(b)) => geom::cross(a, b).abs() > 0.0175 || geom::dot(a, b) < 0.0,
        _ => false,
    };
    let start = (0..n).find(|&k| turn(k)).unwrap_or(0);
    let mut k = 0;
    while k < n {
        let i = (start + k) % n;
        let Some(u0) = dir(i) else {
            k += 1;
            continue;
        };
        let mut j = k + 1;
        while j < n {
            match dir((start + j) % n) {
                Some(u) if geom::cross(u0, u).abs() <= 0.0175 && geom::dot(u0, u) > 0.0 => j += 1,
                None => j += 1,
                _ => break,
            }
        }
        let a = ring[i];
        let b = ring[(start + j) % n];
        if let Some(u) = geom::normalize(geom::sub(b, a)) {
            out.push(Face {
                a,
                b,
                u,
                len: geom::dist(a, b),
                outer,
            });
        }
        k = j;
    }
}
