//! The 2D Eigencrust graph (§3.3, design note §2.2-2.4): one node per triangle, positive edges
//! between adjacent triangles that should share a label, negative edges between the two poles of
//! each sample, weighted with the paper's eq. (1) when the poles share an edge.

use super::mesh::{Mesh, NONE};
use crate::geom::{self, P2};

/// A weighted graph over triangles. Each unordered pair appears once.
#[derive(Debug, Clone, Default)]
pub(crate) struct Graph {
    /// `(u, v, w)` with `u < v`; `w > 0` asks for equal labels, `w < 0` for opposite ones.
    pub edges: Vec<(u32, u32, f64)>,
    /// Negative edges between adjacent poles (eq. (1)).
    pub negative_adjacent: usize,
    /// Negative edges between non-adjacent poles (Eigencrust's −exp(4 + 4 cos φ)).
    pub negative_apart: usize,
}

/// Per triangle: circumcentre and circumradius (infinite for a zero-area triangle).
fn circumcircle(mesh: &Mesh, t: usize) -> (P2, f64) {
    let [a, b, c] = mesh.corners(t);
    let ab = geom::sub(b, a);
    let ac = geom::sub(c, a);
    let d = 2.0 * geom::cross(ab, ac);
    if d <= 0.0 {
        return ([f64::NAN; 2], f64::INFINITY);
    }
    let (lb, lc) = (geom::dot(ab, ab), geom::dot(ac, ac));
    let ux = (ac[1] * lb - ab[1] * lc) / d;
    let uy = (ab[0] * lc - ac[0] * lb) / d;
    // |ab||bc||ca| / (4 area) is accurate for slivers, where the centre offset is not.
    let r = geom::norm(ab) * geom::norm(ac) * geom::dist(b, c) / d;
    ([a[0] + ux, a[1] + uy], r)
}

/// cos and sin of the angle at the apex of triangle `t` opposite its edge `k`.
fn apex_angle(mesh: &Mesh, t: usize, k: usize) -> (f64, f64) {
    let tri = mesh.triangles[t];
    let p = mesh.vertices[tri[k] as usize];
    let a = geom::sub(mesh.vertices[tri[(k + 1) % 3] as usize], p);
    let b = geom::sub(mesh.vertices[tri[(k + 2) % 3] as usize], p);
    let n = geom::norm(a) * geom::norm(b);
    if n <= 0.0 {
        return (1.0, 0.0);
    }
    (geom::dot(a, b) / n, geom::cross(a, b).abs() / n)
}

/// cos φ for adjacent triangles `t` and its neighbour across edge `k`: φ = γ_u + γ_v, the sum
/// of the angles opposite the shared edge (design note §2.2, stable for slivers).
fn cos_phi_adjacent(mesh: &Mesh, t: usize, k: usize, u: usize) -> f64 {
    let ku = (0..3)
        .find(|&j| mesh.neighbors[u][j] == t as u32)
        .unwrap_or(0);
    let (cu, su) = apex_angle(mesh, t, k);
    let (cv, sv) = apex_angle(mesh, u, ku);
    (cu * cv - su * sv).clamp(-1.0, 1.0)
}

/// sin θ of a sample's normal against the edge direction; 0 for a corner or a missing normal.
fn sin_theta(normal: P2, edge: P2) -> f64 {
    let (nn, ne) = (geom::norm(normal), geom::norm(edge));
    if nn > 0.0 && ne > 0.0 {
        (geom::cross(normal, edge) / (nn * ne)).abs().min(1.0)
    } else {
        0.0
    }
}

/// For each vertex, the triangles around it (CSR layout: `offsets`, `tris`).
pub(crate) fn vertex_triangles(mesh: &Mesh) -> (Vec<u32>, Vec<u32>) {
    let nv = mesh.vertices.len();
    let mut offsets = vec![0u32; nv + 1];
    for tri in &mesh.triangles {
        for &v in tri {
            offsets[v as usize + 1] += 1;
        }
    }
    for i in 0..nv {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut tris = vec![0u32; offsets[nv] as usize];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for &v in tri {
            tris[fill[v as usize] as usize] = t as u32;
            fill[v as usize] += 1;
        }
    }
    (offsets, tris)
}

/// The poles of sample `s` (design note §2.3): the incident triangle with the largest
/// circumradius, and the largest on the other side of `s`.
fn poles(
    mesh: &Mesh,
    s: usize,
    around: &[u32],
    circles: &[(P2, f64)],
) -> Option<(u32, Option<u32>)> {
    let p = mesh.vertices[s];
    let p1 = *around
        .iter()
        .filter(|&&t| circles[t as usize].1.is_finite())
        .max_by(|&&a, &&b| circles[a as usize].1.total_cmp(&circles[b as usize].1))?;
    let dir1 = geom::sub(circles[p1 as usize].0, p);
    let p2 = around
        .iter()
        .filter(|&&t| {
            let (c, r) = circles[t as usize];
            r.is_finite() && geom::dot(geom::sub(c, p), dir1) < 0.0
        })
        .max_by(|&&a, &&b| circles[a as usize].1.total_cmp(&circles[b as usize].1))
        .copied();
    Some((p1, p2))
}

/// Builds the Eigencrust graph. With `adjacent_poles_only`, pole pairs that do not share an
/// edge get no negative edge (reading (b) of the design note).
pub(crate) fn build_graph(mesh: &Mesh, adjacent_poles_only: bool) -> Graph {
    let nt = mesh.triangles.len();
    let circles: Vec<(P2, f64)> = (0..nt).map(|t| circumcircle(mesh, t)).collect();
    let (offsets, tris) = vertex_triangles(mesh);
    let mut negative: Vec<(u32, u32, f64)> = Vec::new();
    let mut graph = Graph::default();
    for s in 0..mesh.n_samples {
        let around = &tris[offsets[s] as usize..offsets[s + 1] as usize];
        let Some((p1, Some(p2))) = poles(mesh, s, around, &circles) else {
            continue;
        };
        let (u, v) = (p1.min(p2), p1.max(p2));
        if let Some(k) = (0..3).find(|&k| mesh.neighbors[u as usize][k] == v) {
            // Eq. (1): the shared edge s1s2 and the normals at its ends.
            let tri = mesh.triangles[u as usize];
            let (s1, s2) = (tri[(k + 1) % 3] as usize, tri[(k + 2) % 3] as usize);
            let edge = geom::sub(mesh.vertices[s2], mesh.vertices[s1]);
            let cos_phi = cos_phi_adjacent(mesh, u as usize, k, v as usize);
            let theta =
                2.0 * sin_theta(mesh.normals[s1], edge) + 2.0 * sin_theta(mesh.normals[s2], edge);
            negative.push((u, v, -(4.0 + 4.0 * cos_phi + theta).exp()));
            graph.negative_adjacent += 1;
        } else if !adjacent_poles_only {
            let ((cu, ru), (cv, rv)) = (circles[u as usize], circles[v as usize]);
            let dc = geom::sub(cu, cv);
            let cos_phi =
                ((geom::dot(dc, dc) - ru * ru - rv * rv) / (2.0 * ru * rv)).clamp(-1.0, 1.0);
            let cos_phi = if cos_phi.is_finite() { cos_phi } else { 1.0 };
            negative.push((u, v, -(4.0 + 4.0 * cos_phi).exp()));
            graph.negative_apart += 1;
        }
    }
    // Several samples share a pole pair: keep one edge per pair.
    negative.sort_unstable_by_key(|&(u, v, _)| (u, v));
    negative.dedup_by_key(|&mut (u, v, _)| (u, v));
    graph.negative_adjacent = negative
        .iter()
        .filter(|&&(u, v, _)| mesh.neighbors[u as usize].contains(&v))
        .count();
    graph.negative_apart = negative.len() - graph.negative_adjacent;
    let mut edges = Vec::with_capacity(3 * nt / 2 + negative.len());
    for t in 0..nt {
        for k in 0..3 {
            let u = mesh.neighbors[t][k];
            if u == NONE || (u as usize) < t {
                continue;
            }
            // Negative wins over positive on the same pair.
            if negative
                .binary_search_by_key(&(t as u32, u), |&(a, b, _)| (a, b))
                .is_ok()
            {
                continue;
            }
            let cos_phi = cos_phi_adjacent(mesh, t, k, u as usize);
            edges.push((t as u32, u, (4.0 - 4.0 * cos_phi).exp()));
        }
    }
    edges.extend(negative);
    graph.edges = edges;
    graph
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intersection_angle_of_adjacent_circles_matches_the_centre_formula() {
        // φ = γ_u + γ_v must equal the angle from the circumcentres (design note §2.2).
        let pts: Vec<P2> = (0..40)
            .map(|i| {
                let x = (i as f64 * 0.618_034).fract() * 10.0;
                let y = (i as f64 * 0.414_214 + 0.3).fract() * 7.0;
                [x, y]
            })
            .collect();
        let m = Mesh::build(&pts, &[]).unwrap();
        let mut checked = 0;
        for t in 0..m.triangles.len() {
            for k in 0..3 {
                let u = m.neighbors[t][k];
                if u == NONE {
                    continue;
                }
                let ((cu, ru), (cv, rv)) = (circumcircle(&m, t), circumcircle(&m, u as usize));
                let dc = geom::sub(cu, cv);
                let by_centres = (geom::dot(dc, dc) - ru * ru - rv * rv) / (2.0 * ru * rv);
                let by_angles = cos_phi_adjacent(&m, t, k, u as usize);
                assert!(
                    (by_centres - by_angles).abs() < 1e-6,
                    "{by_centres} vs {by_angles}"
                );
                checked += 1;
            }
        }
        assert!(checked > 100);
    }

    #[test]
    fn circumradius_is_the_distance_to_each_corner() {
        let pts = [[0.0, 0.0], [3.0, 0.1], [1.0, 2.0], [2.5, 2.5], [0.2, 3.0]];
        let m = Mesh::build(&pts, &[]).unwrap();
        for t in 0..m.triangles.len() {
            let (c, r) = circumcircle(&m, t);
            for p in m.corners(t) {
                assert!((geom::dist(c, p) - r).abs() < 1e-9 * r.max(1.0));
            }
        }
    }

    #[test]
    fn wall_edges_get_strong_negative_and_open_space_strong_positive_weights() {
        // Two parallel walls 4 m apart, densely sampled, normals across the walls.
        let mut pts = Vec::new();
        let mut nrm = Vec::new();
        for i in 0..=40 {
            let x = i as f64 * 0.1;
            pts.push([x, 0.0]);
            nrm.push([0.0, 1.0]);
            pts.push([x, 4.0]);
            nrm.push([0.0, -1.0]);
        }
        let m = Mesh::build(&pts, &nrm).unwrap();
        let g = build_graph(&m, false);
        assert!(g.negative_adjacent + g.negative_apart > 0);
        let (pos, neg): (Vec<&(u32, u32, f64)>, Vec<_>) = g.edges.iter().partition(|e| e.2 > 0.0);
        assert!(pos
            .iter()
            .all(|e| e.2 >= 1.0 - 1e-12 && e.2 <= 8f64.exp() + 1e-6));
        assert!(neg
            .iter()
            .all(|e| e.2 <= -1.0 + 1e-12 && e.2 >= -(12f64.exp()) - 1e-3));
        // Poles lie on opposite sides of a wall: the room between the walls and beyond them.
        let centre = |t: u32| {
            let [a, b, c] = m.corners(t as usize);
            [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0]
        };
        let in_room = |t: u32| {
            let c = centre(t);
            c[1] > 0.0 && c[1] < 4.0 && c[0] > 0.0 && c[0] < 4.0
        };
        let beyond = |t: u32| {
            let c = centre(t);
            c[1] < 0.0 || c[1] > 4.0
        };
        let across = neg
            .iter()
            .filter(|e| (in_room(e.0) && beyond(e.1)) || (in_room(e.1) && beyond(e.0)))
            .count();
        assert!(across * 10 >= neg.len() * 8, "{across} of {}", neg.len());
        // Open space between the walls: adjacent room triangles are strongly tied (φ near π).
        let mut room: Vec<f64> = pos
            .iter()
            .filter(|e| in_room(e.0) && in_room(e.1))
            .map(|e| e.2)
            .collect();
        room.sort_by(f64::total_cmp);
        assert!(
            room[room.len() / 2] > 6f64.exp(),
            "median {}",
            room[room.len() / 2]
        );
        // One edge per pair.
        let mut pairs: Vec<_> = g.edges.iter().map(|e| (e.0, e.1)).collect();
        pairs.sort_unstable();
        let n = pairs.len();
        pairs.dedup();
        assert_eq!(n, pairs.len());
        assert!(g.edges.iter().all(|e| e.0 < e.1));
    }
}
