//! Stage 5b (§3.4): the boundary between inside and outside triangles, as closed rings grouped
//! into polygons with holes. Watertight by construction; [`Boundary::check`] proves it.
//!
//! Every edge with an inside triangle on its left and an outside triangle (or the hull) on its
//! right is a directed boundary edge, so exteriors come out counter-clockwise and holes
//! clockwise. Where several inside fans meet at one vertex (a pinch), the tracer stays in the
//! fan it arrived through, and any ring that still visits a vertex twice is split there, so every
//! ring is simple and two rings at most touch at a vertex.

use std::collections::HashMap;

use serde::Serialize;

use crate::cleanup::UnionFind;
use crate::geom::{self, P2};
use crate::labeling::{LabeledMesh, NONE};

/// A closed ring of mesh vertex indices (the first vertex is not repeated).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ring {
    /// The ring's vertices in order.
    pub vertices: Vec<u32>,
    /// Shoelace area: positive for exteriors (CCW), negative for holes (CW).
    pub signed_area: f64,
}

/// One edge-connected inside region: an exterior ring and its holes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BoundaryPolygon {
    /// The outer ring.
    pub exterior: Ring,
    /// The rings of the holes inside it.
    pub holes: Vec<Ring>,
}

/// All boundary polygons of a story.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Boundary {
    /// The polygons, one per edge-connected inside region.
    pub polygons: Vec<BoundaryPolygon>,
}

/// Why the boundary could not be traced.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BoundaryError {
    /// No triangle is labeled inside.
    #[error("no inside triangles: the story has no enclosed floor area")]
    NothingInside,
    /// A traced ring does not close; the text says where.
    #[error("boundary is not watertight: {0}")]
    NotWatertight(String),
}

/// Relative tolerance of the area identity in [`Boundary::check`].
const AREA_TOLERANCE: f64 = 1e-9;

/// Traces the rings between inside and outside triangles.
pub fn trace_boundary(labeled: &LabeledMesh) -> Result<Boundary, BoundaryError> {
    let mesh = &labeled.mesh;
    let n = mesh.triangles.len();
    if labeled.inside.len() != n || mesh.neighbors.len() != n {
        return Err(BoundaryError::NotWatertight(format!(
            "{} labels and {} neighbour entries for {n} triangles",
            labeled.inside.len(),
            mesh.neighbors.len()
        )));
    }
    if !labeled.inside.iter().any(|&i| i) {
        return Err(BoundaryError::NothingInside);
    }
    let is_boundary = |t: usize, k: usize| {
        labeled.inside[t] && {
            let nb = mesh.neighbors[t][k];
            nb == NONE || !labeled.inside[nb as usize]
        }
    };
    // Half-edge (t, k) runs from corner k+1 to corner k+2 of triangle t.
    let start_of = |t: usize, k: usize| mesh.triangles[t][(k + 1) % 3];
    let mut used = vec![false; 3 * n];
    let mut rings = Vec::new();
    for t0 in 0..n {
        for k0 in 0..3 {
            if !is_boundary(t0, k0) || used[3 * t0 + k0] {
                continue;
            }
            let mut ring = Vec::new();
            let (mut t, mut k) = (t0, k0);
            loop {
                used[3 * t + k] = true;
                ring.push(start_of(t, k));
                (t, k) = next_boundary_edge(labeled, t, k)?;
                if (t, k) == (t0, k0) {
                    break;
                }
                if used[3 * t + k] {
                    return Err(BoundaryError::NotWatertight(format!(
                        "tracing from triangle {t0} met triangle {t}'s edge twice"
                    )));
                }
            }
            rings.extend(split_at_repeats(ring));
        }
    }
    let boundary = group(labeled, rings, &is_boundary)?;
    boundary.check(labeled)?;
    Ok(boundary)
}

/// The boundary edge leaving the end vertex of boundary edge (t, k), found by turning around
/// that vertex through the inside triangles of the same fan.
fn next_boundary_edge(
    labeled: &LabeledMesh,
    t: usize,
    k: usize,
) -> Result<(usize, usize), BoundaryError> {
    let mesh = &labeled.mesh;
    let v = mesh.triangles[t][(k + 2) % 3];
    let (mut t, mut k) = (t, (k + 1) % 3);
    // A fan has fewer triangles than the mesh; the bound only guards against corrupt neighbours.
    for _ in 0..=mesh.triangles.len() {
        let nb = mesh.neighbors[t][k];
        if nb == NONE || !labeled.inside[nb as usize] {
            return Ok((t, k));
        }
        // Edge k of t runs v → x; in the neighbour the shared edge runs x → v.
        let x = mesh.triangles[t][(k + 2) % 3];
        let tri = mesh.triangles[nb as usize];
        let Some(j) = (0..3).find(|&j| tri[(j + 1) % 3] == x && tri[(j + 2) % 3] == v) else {
            return Err(BoundaryError::NotWatertight(format!(
                "triangles {t} and {nb} are neighbours but do not share an edge"
            )));
        };
        (t, k) = (nb as usize, (j + 1) % 3);
    }
    Err(BoundaryError::NotWatertight(format!(
        "no boundary edge leaves vertex {v}"
    )))
}

/// Splits a closed vertex cycle into cycles that visit each vertex once. The pieces use the same
/// directed edges, so areas and degrees are unchanged.
fn split_at_repeats(ring: Vec<u32>) -> Vec<Vec<u32>> {
    let mut out = Vec::new();
    let mut stack: Vec<u32> = Vec::with_capacity(ring.len());
    let mut pos: HashMap<u32, usize> = HashMap::new();
    for v in ring {
        if let Some(&p) = pos.get(&v) {
            let piece: Vec<u32> = stack.drain(p..).collect();
            for w in &piece[1..] {
                pos.remove(w);
            }
            stack.push(v);
            out.push(piece);
        } else {
            pos.insert(v, stack.len());
            stack.push(v);
        }
    }
    out.push(stack);
    out
}

/// Shoelace area of a ring of mesh vertices, relative to its first vertex for precision.
fn signed_area(vertices: &[P2], ring: &[u32]) -> f64 {
    let Some(&first) = ring.first() else {
        return 0.0;
    };
    let o = vertices[first as usize];
    let pts: Vec<P2> = ring
        .iter()
        .map(|&v| geom::sub(vertices[v as usize], o))
        .collect();
    geom::ring_signed_area(&pts)
}

/// Groups rings into polygons: each edge-connected inside region has one exterior, and every
/// hole goes to the region on its inner side.
fn group(
    labeled: &LabeledMesh,
    rings: Vec<Vec<u32>>,
    is_boundary: &dyn Fn(usize, usize) -> bool,
) -> Result<Boundary, BoundaryError> {
    let mesh = &labeled.mesh;
    let n = mesh.triangles.len();
    let mut uf = UnionFind::new(n);
    // The triangle on the left of each directed boundary edge.
    let mut left_of: HashMap<(u32, u32), usize> = HashMap::new();
    for t in (0..n).filter(|&t| labeled.inside[t]) {
        for k in 0..3 {
            if is_boundary(t, k) {
                let tri = mesh.triangles[t];
                left_of.insert((tri[(k + 1) % 3], tri[(k + 2) % 3]), t);
            } else {
                uf.union(t as u32, mesh.neighbors[t][k]);
            }
        }
    }
    let mut exteriors: HashMap<u32, usize> = HashMap::new();
    let mut polygons: Vec<BoundaryPolygon> = Vec::new();
    let mut holes = Vec::new();
    for vertices in rings {
        let area = signed_area(&mesh.vertices, &vertices);
        let t = left_of[&(vertices[0], vertices[1 % vertices.len()])];
        let region = uf.find(t as u32);
        let ring = Ring {
            vertices,
            signed_area: area,
        };
        if area > 0.0 {
            if exteriors.insert(region, polygons.len()).is_some() {
                return Err(BoundaryError::NotWatertight(format!(
                    "the region of triangle {t} has two counter-clockwise rings"
                )));
            }
            polygons.push(BoundaryPolygon {
                exterior: ring,
                holes: Vec::new(),
            });
        } else {
            holes.push((region, ring));
        }
    }
    for (region, ring) in holes {
        let Some(&p) = exteriors.get(&region) else {
            return Err(BoundaryError::NotWatertight(format!(
                "a clockwise ring at vertex {} has no exterior",
                ring.vertices[0]
            )));
        };
        polygons[p].holes.push(ring);
    }
    // Largest first, so outputs repeat in a stable, readable order.
    for p in &mut polygons {
        p.holes
            .sort_by(|a, b| a.signed_area.total_cmp(&b.signed_area));
    }
    polygons.sort_by(|a, b| b.exterior.signed_area.total_cmp(&a.exterior.signed_area));
    Ok(Boundary { polygons })
}

impl Boundary {
    /// The traced polygons at their mesh vertices' positions.
    pub fn to_polygons(&self, mesh: &crate::labeling::Mesh) -> Vec<crate::plan::Polygon> {
        let ring = |r: &Ring| -> Vec<P2> {
            r.vertices
                .iter()
                .map(|&v| {
                    mesh.vertices
                        .get(v as usize)
                        .copied()
                        .unwrap_or([f64::NAN; 2])
                })
                .collect()
        };
        self.polygons
            .iter()
            .map(|p| crate::plan::Polygon {
                exterior: ring(&p.exterior),
                holes: p.holes.iter().map(ring).collect(),
            })
            .collect()
    }

    /// Every ring, exteriors and holes, in polygon order.
    pub fn rings(&self) -> impl Iterator<Item = &Ring> {
        self.polygons
            .iter()
            .flat_map(|p| std::iter::once(&p.exterior).chain(&p.holes))
    }

    /// Proves watertightness against the labeling: every ring is closed along boundary edges,
    /// every boundary edge is used exactly once, in-degree equals out-degree at every vertex,
    /// exteriors are CCW and holes CW, and the ring areas sum to the inside area (relative
    /// tolerance 1e-9).
    pub fn check(&self, labeled: &LabeledMesh) -> Result<(), BoundaryError> {
        let bad = |msg: String| Err(BoundaryError::NotWatertight(msg));
        let mesh = &labeled.mesh;
        let n = mesh.triangles.len();
        if labeled.inside.len() != n || mesh.neighbors.len() != n {
            return bad(format!("{} labels for {n} triangles", labeled.inside.len()));
        }
        let mut edges: HashMap<(u32, u32), i64> = HashMap::new();
        let mut inside_area = 0.0;
        for t in 0..n {
            if !labeled.inside[t] {
                continue;
            }
            inside_area += mesh.area(t);
            for k in 0..3 {
                let nb = mesh.neighbors[t][k];
                if nb == NONE || !labeled.inside[nb as usize] {
                    let tri = mesh.triangles[t];
                    *edges
                        .entry((tri[(k + 1) % 3], tri[(k + 2) % 3]))
                        .or_default() += 1;
                }
            }
        }
        let mut degree: HashMap<u32, i64> = HashMap::new();
        let mut total = 0.0;
        for (i, p) in self.polygons.iter().enumerate() {
            for (j, ring) in std::iter::once(&p.exterior).chain(&p.holes).enumerate() {
                let name = format!("polygon {i} ring {j}");
                let m = ring.vertices.len();
                if m < 3 {
                    return bad(format!("{name} has {m} vertices"));
                }
                if let Some(v) = ring
                    .vertices
                    .iter()
                    .find(|&&v| v as usize >= mesh.vertices.len())
                {
                    return bad(format!("{name} names vertex {v}, beyond the mesh"));
                }
                for w in 0..m {
                    let (a, b) = (ring.vertices[w], ring.vertices[(w + 1) % m]);
                    match edges.get_mut(&(a, b)) {
                        Some(c) if *c > 0 => *c -= 1,
                        _ => {
                            return bad(format!(
                                "{name} is open: {a} → {b} is not an unused boundary edge"
                            ))
                        }
                    }
                    *degree.entry(a).or_default() += 1;
                    *degree.entry(b).or_default() -= 1;
                }
                let area = signed_area(&mesh.vertices, &ring.vertices);
                let scale = area.abs().max(f64::MIN_POSITIVE);
                if (area - ring.signed_area).abs() > AREA_TOLERANCE * scale {
                    return bad(format!(
                        "{name} records area {} but encloses {area}",
                        ring.signed_area
                    ));
                }
                if (j == 0) != (area > 0.0) {
                    return bad(format!("{name} has the wrong orientation (area {area})"));
                }
                total += area;
            }
        }
        if let Some(((a, b), _)) = edges.iter().find(|(_, &c)| c != 0) {
            return bad(format!("boundary edge {a} → {b} is in no ring"));
        }
        if let Some((v, d)) = degree.iter().find(|(_, &d)| d != 0) {
            return bad(format!("vertex {v}: out-degree minus in-degree is {d}"));
        }
        if (total - inside_area).abs() > AREA_TOLERANCE * inside_area.max(f64::MIN_POSITIVE) {
            return bad(format!(
                "rings enclose {total} m² but inside triangles cover {inside_area} m²"
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cleanup::tests::{label_by_rings, ring_samples};
    use crate::labeling::Mesh;

    /// A mesh on a 0.5 m lattice covering [-1, 5]², labelled by centroid against `rings`.
    fn lattice(rings: &[Vec<P2>]) -> LabeledMesh {
        let mut pts = Vec::new();
        for i in 0..=12 {
            for j in 0..=12 {
                pts.push([-1.0 + 0.5 * i as f64, -1.0 + 0.5 * j as f64]);
            }
        }
        let normals = vec![[1.0, 0.0]; pts.len()];
        label_by_rings(Mesh::build(&pts, &normals).unwrap(), rings)
    }

    fn ring_points(l: &LabeledMesh, r: &Ring) -> Vec<P2> {
        r.vertices
            .iter()
            .map(|&v| l.mesh.vertices[v as usize])
            .collect()
    }

    #[test]
    fn room_gives_one_ccw_ring_with_the_room_area() {
        let room = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]];
        let (pts, normals) = ring_samples(&room, 0.05);
        let l = label_by_rings(Mesh::build(&pts, &normals).unwrap(), &[room]);
        let b = trace_boundary(&l).unwrap();
        b.check(&l).unwrap();
        assert_eq!(b.polygons.len(), 1);
        let ext = &b.polygons[0].exterior;
        assert_eq!(ext.vertices.len(), pts.len());
        // Corners are cut by half a sample step: 4 triangles of 0.025² / 2 are missing.
        let expected = 12.0 - 4.0 * 0.025 * 0.025 / 2.0;
        assert!(
            (ext.signed_area - expected).abs() < 1e-9,
            "{}",
            ext.signed_area
        );
    }

    #[test]
    fn duplicate_samples_do_not_change_the_boundary() {
        let room = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]];
        let (pts, normals) = ring_samples(&room, 0.05);
        let once = label_by_rings(
            Mesh::build(&pts, &normals).unwrap(),
            std::slice::from_ref(&room),
        );
        let twice_pts: Vec<P2> = pts.iter().flat_map(|&p| [p, p]).collect();
        let twice_n: Vec<P2> = normals.iter().flat_map(|&n| [n, n]).collect();
        let twice = label_by_rings(Mesh::build(&twice_pts, &twice_n).unwrap(), &[room]);
        let (a, b) = (
            trace_boundary(&once).unwrap(),
            trace_boundary(&twice).unwrap(),
        );
        a.check(&once).unwrap();
        b.check(&twice).unwrap();
        assert_eq!(a.polygons.len(), 1);
        assert_eq!(
            ring_points(&once, &a.polygons[0].exterior),
            ring_points(&twice, &b.polygons[0].exterior)
        );
    }

    #[test]
    fn squares_touching_at_a_corner_are_two_polygons() {
        let a = vec![[0.0, 0.0], [1.5, 0.0], [1.5, 1.5], [0.0, 1.5]];
        let b = vec![[1.5, 1.5], [3.0, 1.5], [3.0, 3.0], [1.5, 3.0]];
        let l = lattice(&[a, b]);
        let bd = trace_boundary(&l).unwrap();
        bd.check(&l).unwrap();
        assert_eq!(bd.polygons.len(), 2);
        for p in &bd.polygons {
            assert!(p.holes.is_empty());
            assert!((p.exterior.signed_area - 2.25).abs() < 1e-12);
            let pts = ring_points(&l, &p.exterior);
            assert!(pts.contains(&[1.5, 1.5]));
        }
    }

    #[test]
    fn square_with_a_hole_is_one_polygon_with_a_cw_hole() {
        let outer = vec![[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [0.0, 3.0]];
        let hole = vec![[1.0, 1.0], [2.0, 1.0], [2.0, 2.0], [1.0, 2.0]];
        let l = lattice(&[outer, hole]);
        let bd = trace_boundary(&l).unwrap();
        bd.check(&l).unwrap();
        assert_eq!(bd.polygons.len(), 1);
        assert_eq!(bd.polygons[0].holes.len(), 1);
        assert!((bd.polygons[0].exterior.signed_area - 9.0).abs() < 1e-12);
        assert!((bd.polygons[0].holes[0].signed_area + 1.0).abs() < 1e-12);
    }

    #[test]
    fn hole_touching_exterior_at_a_vertex_is_split_into_two_rings() {
        // A notch [0,1]² is cut from a 3 × 3 room, so the hole [1,2]² meets the outside at
        // vertex (1, 1) only: one region whose boundary pinches there.
        let room = vec![
            [1.0, 0.0],
            [3.0, 0.0],
            [3.0, 3.0],
            [0.0, 3.0],
            [0.0, 1.0],
            [1.0, 1.0],
        ];
        let hole = vec![[1.0, 1.0], [1.0, 2.0], [2.0, 2.0], [2.0, 1.0]];
        let l = lattice(&[room, hole]);
        let bd = trace_boundary(&l).unwrap();
        bd.check(&l).unwrap();
        assert_eq!(bd.polygons.len(), 1);
        let p = &bd.polygons[0];
        assert_eq!(p.holes.len(), 1);
        assert!((p.exterior.signed_area - 8.0).abs() < 1e-12);
        assert!((p.holes[0].signed_area + 1.0).abs() < 1e-12);
        for r in bd.rings() {
            let mut v = r.vertices.clone();
            v.sort_unstable();
            v.dedup();
            assert_eq!(v.len(), r.vertices.len(), "ring repeats a vertex");
        }
        assert!(ring_points(&l, &p.holes[0]).contains(&[1.0, 1.0]));
        assert!(ring_points(&l, &p.exterior).contains(&[1.0, 1.0]));
    }

    #[test]
    fn island_in_a_hole_is_its_own_polygon() {
        let outer = vec![[-0.5, -0.5], [4.5, -0.5], [4.5, 4.5], [-0.5, 4.5]];
        let hole = vec![[0.5, 0.5], [3.5, 0.5], [3.5, 3.5], [0.5, 3.5]];
        let island = vec![[1.5, 1.5], [2.5, 1.5], [2.5, 2.5], [1.5, 2.5]];
        let l = lattice(&[outer, hole, island]);
        let bd = trace_boundary(&l).unwrap();
        bd.check(&l).unwrap();
        assert_eq!(bd.polygons.len(), 2);
        assert_eq!(bd.polygons[0].holes.len(), 1);
        assert!((bd.polygons[0].exterior.signed_area - 25.0).abs() < 1e-12);
        assert!((bd.polygons[1].exterior.signed_area - 1.0).abs() < 1e-12);
    }

    #[test]
    fn nothing_inside_is_an_error() {
        let l = lattice(&[]);
        assert_eq!(trace_boundary(&l), Err(BoundaryError::NothingInside));
        // Collinear samples: every triangle touches a box corner, so nothing can be inside.
        let pts: Vec<P2> = (0..20).map(|i| [0.1 * i as f64, 0.05 * i as f64]).collect();
        let l = label_by_rings(
            Mesh::build(&pts, &vec![[0.0, 1.0]; 20]).unwrap(),
            &[vec![[-1.0, -1.0], [3.0, -1.0], [3.0, 2.0], [-1.0, 2.0]]],
        );
        assert!(l.inside.iter().all(|&i| !i));
        assert_eq!(trace_boundary(&l), Err(BoundaryError::NothingInside));
    }

    #[test]
    fn checker_rejects_broken_boundaries() {
        let room = vec![[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
        let l = lattice(std::slice::from_ref(&room));
        let good = trace_boundary(&l).unwrap();
        good.check(&l).unwrap();
        let fails = |b: &Boundary| matches!(b.check(&l), Err(BoundaryError::NotWatertight(_)));
        // A vertex dropped: the ring jumps over a non-edge.
        let mut open = good.clone();
        open.polygons[0].exterior.vertices.remove(1);
        assert!(fails(&open));
        // Reversed orientation.
        let mut rev = good.clone();
        rev.polygons[0].exterior.vertices.reverse();
        assert!(fails(&rev));
        // A stale area.
        let mut stale = good.clone();
        stale.polygons[0].exterior.signed_area += 1e-3;
        assert!(fails(&stale));
        // A missing ring: boundary edges left unused.
        assert!(fails(&Boundary::default()));
        // The labels changed under the boundary: one more inside triangle.
        let mut l2 = l.clone();
        let t = (0..l2.inside.len())
            .find(|&t| !l2.inside[t] && !l2.mesh.touches_corner(t))
            .unwrap();
        l2.inside[t] = true;
        assert!(good.check(&l2).is_err());
    }
}

#[cfg(test)]
mod random_tests {
    use crate::cancel::Cancel;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::cleanup::{clean_labels, CleanupParams};
    use crate::fitting::{fit_walls, FittingParams};
    use crate::labeling::Mesh;

    #[test]
    fn random_labelings_trace_watertight_and_fit_valid() {
        // Random samples with random labels: pinches everywhere. Tracing must stay watertight
        // and fitting must give a valid plan (or say why), never panic.
        let (mut walls, mut repairs) = (0, 0);
        for seed in 0..30u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let n = 60 + (seed as usize % 4) * 60;
            let pts: Vec<P2> = (0..n)
                .map(|_| [rng.random_range(0.0..5.0), rng.random_range(0.0..5.0)])
                .collect();
            let normals: Vec<P2> = (0..n)
                .map(|_| {
                    let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                    [a.cos(), a.sin()]
                })
                .collect();
            let mesh = Mesh::build(&pts, &normals).unwrap();
            let k = mesh.triangles.len();
            let p_inside = 0.3 + 0.1 * (seed % 5) as f64;
            let forced: Vec<Option<bool>> = (0..k)
                .map(|t| mesh.touches_corner(t).then_some(false))
                .collect();
            let inside = (0..k)
                .map(|t| forced[t].is_none() && rng.random_bool(p_inside))
                .collect();
            let mut l = LabeledMesh {
                mesh,
                inside,
                forced,
            };
            if seed % 2 == 1 {
                clean_labels(
                    &mut l,
                    &CleanupParams {
                        min_region_triangles: 3,
                        ..Default::default()
                    },
                );
            }
            let b = match trace_boundary(&l) {
                Err(BoundaryError::NothingInside) => continue,
                r => r.unwrap(),
            };
            b.check(&l).unwrap();
            for r in b.rings() {
                let mut v = r.vertices.clone();
                v.sort_unstable();
                v.dedup();
                assert_eq!(
                    v.len(),
                    r.vertices.len(),
                    "seed {seed}: ring repeats a vertex"
                );
            }
            let params = FittingParams {
                min_inliers: 4,
                min_component: 3,
                inlier_distance: 0.2,
                inlier_angle: 1.5,
                ..Default::default()
            };
            let f = fit_walls(&l, &b, &params, &Cancel::never())
                .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            let problems = crate::validity::problems(&f.polygons, &crate::validity::Grid::local());
            assert!(problems.is_empty(), "seed {seed}: {problems:?}");
            walls += f.walls.len();
            repairs += f.notes.len();
        }
        eprintln!("random labelings: {walls} walls fitted, {repairs} plans repaired");
        // The test must exercise both the rebuild and the resolution of crossings.
        assert!(walls > 0 && repairs > 0);
    }
}
