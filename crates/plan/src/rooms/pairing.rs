//! The two faces of a wall paired into a centre line with a thickness.
//!
//! Two faces pair where they run antiparallel, each with its free side facing away from the
//! other, a plausible thickness apart, with solid between them. Pairs are taken thinnest
//! first, and each stretch of a face pairs once: a corridor face opposite many offices pairs
//! piece by piece, each office's face with the stretch of corridor face across from it.

use super::faces::Face;
use super::segment::Free;
use super::RoomsParams;
use crate::geom::{self, P2};

/// A stretch of wall whose two faces were seen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Piece {
    /// The centre line; the first face's free side is on its left.
    pub a: P2,
    pub b: P2,
    /// Unit direction a → b.
    pub u: P2,
    pub thickness: f64,
    /// The two faces (indices into the faces).
    pub faces: [usize; 2],
}

impl Piece {
    /// Unit normal to the left of a → b.
    pub fn left(&self) -> P2 {
        [-self.u[1], self.u[0]]
    }
}

/// Covered stretches of each face, as sorted disjoint intervals of its parameter.
pub(crate) type Coverage = Vec<Vec<(f64, f64)>>;

/// Every paired stretch, and what of each face it covers.
pub(crate) fn pair(faces: &[Face], free: &Free, params: &RoomsParams) -> (Vec<Piece>, Coverage) {
    let cos_max = params.max_angle_deg.to_radians().cos();
    let mut candidates = Vec::new();
    for (i, f) in faces.iter().enumerate() {
        if f.len < params.min_overlap {
            continue;
        }
        let n = f.solid_normal();
        for (j, g) in faces.iter().enumerate().skip(i + 1) {
            if g.len < params.min_overlap || geom::dot(f.u, g.u) > -cos_max {
                continue;
            }
            // g lies behind f, a wall's thickness away.
            let (da, db) = (
                geom::dot(geom::sub(g.a, f.a), n),
                geom::dot(geom::sub(g.b, f.a), n),
            );
            let d = (da + db) / 2.0;
            if d < params.min_thickness || d > params.max_thickness {
                continue;
            }
            let (ta, tb) = (f.param(g.a), f.param(g.b));
            let (lo, hi) = (ta.min(tb).max(0.0), ta.max(tb).min(f.len));
            if hi - lo < params.min_overlap {
                continue;
            }
            candidates.push((d, i, j, lo, hi));
        }
    }
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut covered: Coverage = vec![Vec::new(); faces.len()];
    let mut pieces = Vec::new();
    for (d, i, j, lo, hi) in candidates {
        let (f, g) = (&faces[i], &faces[j]);
        // What is left of [lo, hi] on f once both faces' covered stretches are taken out.
        let mut taken: Vec<(f64, f64)> = covered[i].clone();
        for &(s0, s1) in &covered[j] {
            let (t0, t1) = (f.param(g.at(s0)), f.param(g.at(s1)));
            taken.push((t0.min(t1), t0.max(t1)));
        }
        let n = f.solid_normal();
        for (t0, t1) in remaining(lo, hi, &mut taken) {
            if t1 - t0 < params.min_overlap {
                continue;
            }
            let a = geom::add(f.at(t0), geom::scale(n, d / 2.0));
            let b = geom::add(f.at(t1), geom::scale(n, d / 2.0));
            // Solid between the faces: no free floor along the centre line.
            let solid = [0.1, 0.5, 0.9]
                .iter()
                .all(|&s| !free.contains(geom::add(a, geom::scale(geom::sub(b, a), s))));
            if !solid {
                continue;
            }
            pieces.push(Piece {
                a,
                b,
                u: f.u,
                thickness: d,
                faces: [i, j],
            });
            add(&mut covered[i], (t0, t1));
            let (s0, s1) = (g.param(f.at(t0)), g.param(f.at(t1)));
            add(&mut covered[j], (s0.min(s1), s0.max(s1)));
        }
    }
    (pieces, covered)
}

/// The parts of [lo, hi] outside every interval of `taken` (which it sorts).
pub(crate) fn remaining(lo: f64, hi: f64, taken: &mut [(f64, f64)]) -> Vec<(f64, f64)> {
    taken.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out = Vec::new();
    let mut at = lo;
    for &(s0, s1) in taken.iter() {
        if s1 <= at {
            continue;
        }
        if s0 >= hi {
            break;
        }
        if s0 > at {
            out.push((at, s0));
        }
        at = at.max(s1);
    }
    if at < hi {
        out.push((at, hi));
    }
    out
}

fn add(list: &mut Vec<(f64, f64)>, iv: (f64, f64)) {
    list.push(iv);
    list.sort_by(|a, b| a.0.total_cmp(&b.0));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn remaining_takes_out_covered_stretches() {
        let mut taken = vec![(2.0, 3.0), (0.5, 1.0)];
        assert_eq!(
            remaining(0.0, 4.0, &mut taken),
            vec![(0.0, 0.5), (1.0, 2.0), (3.0, 4.0)]
        );
        assert_eq!(remaining(0.0, 1.0, &mut [(-1.0, 2.0)]), vec![]);
    }
}
