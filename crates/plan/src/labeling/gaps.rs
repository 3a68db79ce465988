//! Vertices filled into short gaps of a row of samples (beyond the paper).
//!
//! A wall seen sparsely, or the face of a thin wall on a grid as coarse as the wall (8 cm voxels
//! on 10 cm cells), leaves its row of samples with holes a few samples long. Delaunay then
//! spans each hole with one long edge, the graph gets no pole pair there, and fitting finds too
//! few samples on the face to give it a model: the face is cut by a diagonal. A hole is filled
//! with vertices on the row's line when it is short (at most [`MAX_GAP`] sample spacings, far
//! less than a door) and the row runs on straight on both sides of it.

use super::mesh::{Mesh, NONE};
use crate::geom::{self, P2};

/// The longest hole filled, in sample spacings: 0.36 m at 8 cm, well under a 0.7 m door.
pub(crate) const MAX_GAP: f64 = 4.5;

/// A neighbour continues the row when it lies within this many spacings of the hole's end...
const NEAR: f64 = 1.5;

/// ...within this angle of the hole's direction (cos 10°)...
const MIN_COS: f64 = 0.985;

/// ...and within this many spacings of the hole's line. On a lattice, a step along the row
/// and one across lies at 18° from a hole three steps long: such an edge crosses from one face
/// of a thin wall to the other, and must not be filled.
const ON_LINE: f64 = 0.2;

/// A vertex beside the hole within this many spacings means the hole is no hole.
const CLEAR: f64 = 0.5;

/// The vertices to add to `mesh` (built on samples alone): for every hole, points a spacing
/// apart on the segment across it, each with the segment's normal (turned like its ends').
pub(crate) fn fill(mesh: &Mesh) -> (Vec<P2>, Vec<P2>) {
    let ns = mesh.n_samples;
    let v = &mesh.vertices;
    let Some(h) = spacing(mesh) else {
        return (Vec::new(), Vec::new());
    };
    let adjacent = adjacency(mesh);
    let continues = |a: usize, dir: P2| {
        adjacent[a].iter().any(|&p| {
            let d = geom::sub(v[p], v[a]);
            let len = geom::norm(d);
            len > 0.0
                && len <= NEAR * h
                && geom::dot(d, dir) >= MIN_COS * len
                && geom::cross(d, dir).abs() <= ON_LINE * h
        })
    };
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let across = mesh.neighbors[t][k];
            // Each edge once: from the triangle of lower index, or the only one.
            if across != NONE && (across as usize) < t {
                continue;
            }
            let (s, q) = (tri[(k + 1) % 3] as usize, tri[(k + 2) % 3] as usize);
            if s >= ns || q >= ns {
                continue;
            }
            let len = geom::dist(v[s], v[q]);
            if len <= NEAR * h || len > MAX_GAP * h {
                continue;
            }
            let u = geom::scale(geom::sub(v[q], v[s]), 1.0 / len);
            // The apexes on both sides keep clear of the segment.
            let apexes = std::iter::once(tri[k] as usize).chain(
                (across != NONE)
                    .then(|| {
                        let other = mesh.triangles[across as usize];
                        other
                            .iter()
                            .map(|&x| x as usize)
                            .find(|&x| x != s && x != q)
                    })
                    .flatten(),
            );
            let crowded = apexes
                .filter(|&a| a < ns)
                .any(|a| geom::cross(u, geom::sub(v[a], v[s])).abs() < CLEAR * h);
            if crowded || !continues(s, [-u[0], -u[1]]) || !continues(q, u) {
                continue;
            }
            let mut normal = [-u[1], u[0]];
            let ends = geom::add(mesh.normals[s], mesh.normals[q]);
            if geom::dot(normal, ends) < 0.0 {
                normal = [-normal[0], -normal[1]];
            }
            let steps = (len / h).round().max(2.0) as usize;
            for i in 1..steps {
                points.push(geom::add(
                    v[s],
                    geom::scale(u, len * i as f64 / steps as f64),
                ));
                normals.push(normal);
            }
        }
    }
    (points, normals)
}

/// The median over sample vertices of their shortest edge to another sample: the spacing of
/// the rows. `None` without edges.
pub(super) fn spacing(mesh: &Mesh) -> Option<f64> {
    let ns = mesh.n_samples;
    let mut shortest = vec![f64::INFINITY; ns];
    for tri in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
            if a < ns && b < ns {
                let d = geom::dist(mesh.vertices[a], mesh.vertices[b]);
                shortest[a] = shortest[a].min(d);
                shortest[b] = shortest[b].min(d);
            }
        }
    }
    let mut d: Vec<f64> = shortest.into_iter().filter(|d| d.is_finite()).collect();
    if d.is_empty() {
        return None;
    }
    let mid = d.len() / 2;
    let h = *d.select_nth_unstable_by(mid, f64::total_cmp).1;
    (h > 0.0).then_some(h)
}

/// Per vertex, the vertices it shares an edge with.
fn adjacency(mesh: &Mesh) -> Vec<Vec<usize>> {
    let mut adj = vec![Vec::new(); mesh.vertices.len()];
    for tri in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
            if !adj[a].contains(&b) {
                adj[a].push(b);
            }
            if !adj[b].contains(&a) {
                adj[b].push(a);
            }
        }
    }
    adj
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row along y = 0 every 0.1 m from x = 0 to 2, without the samples strictly between
    /// `hole.0` and `hole.1`, and a whole second row at y = 3 so the samples enclose area.
    fn rows(hole: (f64, f64)) -> Mesh {
        let mut pts = Vec::new();
        let mut nrm = Vec::new();
        for i in 0..=20 {
            let x = i as f64 * 0.1;
            if x <= hole.0 + 1e-9 || x >= hole.1 - 1e-9 {
                pts.push([x, 0.0]);
                nrm.push([0.0, 1.0]);
            }
            pts.push([x, 3.0]);
            nrm.push([0.0, -1.0]);
        }
        Mesh::build(&pts, &nrm).unwrap()
    }

    #[test]
    fn a_short_hole_in_a_straight_row_is_filled_a_spacing_apart() {
        // Samples at 0.8 and 1.2: three missing, 0.4 m = 4 spacings.
        let (pts, nrm) = fill(&rows((0.8, 1.2)));
        let mut xs: Vec<f64> = pts.iter().map(|p| p[0]).collect();
        xs.sort_by(f64::total_cmp);
        assert_eq!(xs.len(), 3, "{pts:?}");
        for (x, want) in xs.iter().zip([0.9, 1.0, 1.1]) {
            assert!((x - want).abs() < 1e-9, "{xs:?}");
        }
        assert!(pts.iter().all(|p| p[1].abs() < 1e-9));
        // The row's normals point up (+y): so do the filled ones.
        assert!(nrm
            .iter()
            .all(|n| n[0].abs() < 1e-9 && (n[1] - 1.0).abs() < 1e-9));
    }

    #[test]
    fn an_edge_from_one_face_of_a_thin_wall_to_the_other_is_not_filled() {
        // Faces 0.08 m apart sampled every 0.08 m; the lower one stops at x = 0.4, the upper
        // one starts at x = 0.64: the 0.25 m edge between their ends runs at 18° to both.
        let mut pts = Vec::new();
        for i in 0..=12 {
            let x = i as f64 * 0.08;
            pts.push([x, if x <= 0.4 + 1e-9 { 0.0 } else { 3.0 }]);
            if x >= 0.64 - 1e-9 {
                pts.push([x, 0.08]);
            }
        }
        let m = Mesh::build(&pts, &[]).unwrap();
        let (added, _) = fill(&m);
        assert!(added.is_empty(), "{added:?}");
    }

    #[test]
    fn a_door_wide_hole_is_left_open() {
        // 0.6 m = 6 spacings: more than MAX_GAP.
        let (pts, _) = fill(&rows((0.6, 1.2)));
        assert!(pts.is_empty(), "{pts:?}");
    }

    #[test]
    fn a_row_that_turns_or_ends_is_not_bridged() {
        // An L: a row along y = 0 up to x = 1, then a row along x = 1.3 from y = 0.3 up. The
        // 0.42 m edge from (1, 0) to (1.3, 0.3) does not continue either row.
        let mut pts = Vec::new();
        for i in 0..=10 {
            pts.push([i as f64 * 0.1, 0.0]);
            pts.push([1.3, 0.3 + i as f64 * 0.1]);
        }
        pts.push([0.0, 2.0]);
        let m = Mesh::build(&pts, &[]).unwrap();
        let (added, _) = fill(&m);
        assert!(added.is_empty(), "{added:?}");
    }

    #[test]
    fn the_other_face_of_a_thin_wall_keeps_its_holes_filled_but_not_crossed() {
        // Two faces 0.08 m apart, sampled every 0.08 m, the lower one with a hole of three
        // samples: it is filled on its own line, never across to the upper face.
        let mut pts = Vec::new();
        for i in 0..=25 {
            let x = i as f64 * 0.08;
            pts.push([x, 0.08]);
            if !(9..=11).contains(&i) {
                pts.push([x, 0.0]);
            }
        }
        pts.push([1.0, 3.0]);
        let m = Mesh::build(&pts, &[]).unwrap();
        let (added, _) = fill(&m);
        assert_eq!(added.len(), 3, "{added:?}");
        for (p, i) in added.iter().zip([9.0, 10.0, 11.0]) {
            assert!(
                p[1].abs() < 1e-9 && (p[0] - 0.08 * i).abs() < 1e-9,
                "{added:?}"
            );
        }
    }
}
