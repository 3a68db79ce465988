//! The exact outline of a union of axis-aligned rectangles minus others: rooms, corridors and
//! door openings joined into open floor, with solid columns cut out.
//!
//! The rectangles' edges cut the plane into a grid of cells (coordinate compression); a cell is
//! open when its centre is in an open rectangle and in no solid one. The outline is the set of
//! cell edges between open and solid cells, linked into rings with the open side on the left, so
//! exteriors come out counter-clockwise and holes clockwise, exactly on the input coordinates.

use std::collections::HashMap;

pub use crate::geom::point_in_ring;
use crate::geom::{ring_signed_area, P2};
use crate::plan::Polygon;

/// An axis-aligned rectangle `[x0, x1] × [y0, y1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    pub x0: f64,
    pub y0: f64,
    pub x1: f64,
    pub y1: f64,
}

impl Rect {
    pub fn new(x0: f64, y0: f64, x1: f64, y1: f64) -> Rect {
        Rect {
            x0: x0.min(x1),
            y0: y0.min(y1),
            x1: x0.max(x1),
            y1: y0.max(y1),
        }
    }

    pub fn contains(&self, p: P2) -> bool {
        p[0] > self.x0 && p[0] < self.x1 && p[1] > self.y0 && p[1] < self.y1
    }
}

/// The open region `∪ open − ∪ solid` as polygons with holes (open rings, exteriors CCW, holes CW,
/// no collinear vertices).
pub fn outline(open: &[Rect], solid: &[Rect]) -> Vec<Polygon> {
    let axis = |f: &dyn Fn(&Rect) -> [f64; 2]| {
        let mut v: Vec<f64> = open.iter().chain(solid).flat_map(f).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v
    };
    let xs = axis(&|r| [r.x0, r.x1]);
    let ys = axis(&|r| [r.y0, r.y1]);
    if xs.len() < 2 || ys.len() < 2 {
        return Vec::new();
    }
    let (nx, ny) = (xs.len() - 1, ys.len() - 1);
    let mut cell = vec![false; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let c = [(xs[i] + xs[i + 1]) / 2.0, (ys[j] + ys[j + 1]) / 2.0];
            cell[j * nx + i] =
                open.iter().any(|r| r.contains(c)) && !solid.iter().any(|r| r.contains(c));
        }
    }
    let is_open = |i: isize, j: isize| {
        i >= 0
            && j >= 0
            && (i as usize) < nx
            && (j as usize) < ny
            && cell[j as usize * nx + i as usize]
    };
    // Directed boundary edges between grid vertices, open side on the left.
    let mut out: HashMap<(isize, isize), Vec<(isize, isize)>> = HashMap::new();
    for j in 0..ny as isize {
        for i in 0..nx as isize {
            if !is_open(i, j) {
                continue;
            }
            let mut edge = |a: (isize, isize), b: (isize, isize)| out.entry(a).or_default().push(b);
            if !is_open(i, j - 1) {
                edge((i, j), (i + 1, j));
            }
            if !is_open(i + 1, j) {
                edge((i + 1, j), (i + 1, j + 1));
            }
            if !is_open(i, j + 1) {
                edge((i + 1, j + 1), (i, j + 1));
            }
            if !is_open(i - 1, j) {
                edge((i, j + 1), (i, j));
            }
        }
    }
    let mut starts: Vec<(isize, isize)> = out.keys().copied().collect();
    starts.sort();
    let mut rings: Vec<Vec<P2>> = Vec::new();
    for s in starts {
        while out.get(&s).is_some_and(|v| !v.is_empty()) {
            let mut ring = vec![s];
            let mut prev = s;
            let mut cur = out.get_mut(&s).and_then(Vec::pop).expect("edge");
            while cur != s {
                let dir_in = (cur.0 - prev.0, cur.1 - prev.1);
                let options = out.get_mut(&cur).expect("every vertex has an out edge");
                // At a pinch, turn left first so that the two open cells get separate rings.
                let pick = (0..options.len())
                    .max_by_key(|&k| {
                        let d = (options[k].0 - cur.0, options[k].1 - cur.1);
                        dir_in.0 * d.1 - dir_in.1 * d.0
                    })
                    .expect("an out edge");
                let next = options.swap_remove(pick);
                ring.push(cur);
                prev = cur;
                cur = next;
            }
            let pts: Vec<P2> = ring
                .iter()
                .map(|&(i, j)| [xs[i as usize], ys[j as usize]])
                .collect();
            rings.push(drop_collinear(pts));
        }
    }
    group(rings)
}

/// Removes vertices where the ring goes straight on.
fn drop_collinear(ring: Vec<P2>) -> Vec<P2> {
    let n = ring.len();
    (0..n)
        .filter(|&k| {
            let (a, b, c) = (ring[(k + n - 1) % n], ring[k], ring[(k + 1) % n]);
            let cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]);
            cross != 0.0
        })
        .map(|k| ring[k])
        .collect()
}

/// Groups CCW exteriors with the CW holes inside them.
pub fn group(rings: Vec<Vec<P2>>) -> Vec<Polygon> {
    let (exteriors, holes): (Vec<_>, Vec<_>) =
        rings.into_iter().partition(|r| ring_signed_area(r) > 0.0);
    let mut polygons: Vec<Polygon> = exteriors
        .into_iter()
        .map(|exterior| Polygon {
            exterior,
            holes: Vec::new(),
        })
        .collect();
    for hole in holes {
        // The smallest exterior containing the hole's first vertex's neighbourhood owns it.
        let probe = hole_probe(&hole);
        let owner = polygons
            .iter_mut()
            .filter(|p| point_in_ring(probe, &p.exterior))
            .min_by(|a, b| ring_signed_area(&a.exterior).total_cmp(&ring_signed_area(&b.exterior)));
        if let Some(p) = owner {
            p.holes.push(hole);
        }
    }
    polygons
}

/// A point just inside a hole's solid (to the right of its first edge).
fn hole_probe(hole: &[P2]) -> P2 {
    let (a, b) = (hole[0], hole[1]);
    let m = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
    let d = [b[0] - a[0], b[1] - a[1]];
    let len = d[0].hypot(d[1]).max(1e-12);
    let e = 1e-6;
    [m[0] + d[1] / len * e, m[1] - d[0] / len * e]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_rooms_and_a_door_make_one_polygon() {
        let open = [
            Rect::new(0.0, 0.0, 4.0, 3.0),
            Rect::new(4.2, 0.0, 8.0, 3.0),
            Rect::new(4.0, 1.0, 4.2, 2.0),
        ];
        let polys = outline(&open, &[]);
        assert_eq!(polys.len(), 1);
        assert_eq!(polys[0].exterior.len(), 12);
        let area = ring_signed_area(&polys[0].exterior);
        assert!((area - (12.0 + 3.8 * 3.0 + 0.2)).abs() < 1e-9, "{area}");
    }

    #[test]
    fn a_column_is_a_clockwise_hole() {
        let polys = outline(
            &[Rect::new(0.0, 0.0, 5.0, 5.0)],
            &[Rect::new(2.0, 2.0, 3.0, 3.0)],
        );
        assert_eq!(polys.len(), 1);
        assert_eq!(polys[0].holes.len(), 1);
        assert_eq!(ring_signed_area(&polys[0].holes[0]), -1.0);
        assert_eq!(ring_signed_area(&polys[0].exterior), 25.0);
    }
}
