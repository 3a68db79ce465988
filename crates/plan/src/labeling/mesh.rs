//! The Delaunay triangulation of a story's samples plus four bounding-box corners (§3.3),
//! flattened into index arrays that the later stages walk.

use spade::handles::FixedVertexHandle;
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

use crate::geom::{self, P2};

/// Marks a missing neighbour (a hull edge).
pub const NONE: u32 = u32::MAX;

/// A triangle mesh: samples first, then the four box corners.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Vertex positions; `vertices[n_samples..]` are the four box corners.
    pub vertices: Vec<P2>,
    /// Unit normal per vertex; `[0, 0]` for the box corners.
    pub normals: Vec<P2>,
    /// For each vertex, the sample it came from (`u32::MAX` for corners). Duplicate samples merge.
    pub sample_of: Vec<u32>,
    /// Number of sample vertices (excluding corners).
    pub n_samples: usize,
    /// Counter-clockwise vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// `neighbors[t][k]` is the triangle across the edge opposite `triangles[t][k]`, or [`NONE`].
    pub neighbors: Vec<[u32; 3]>,
}

/// Why a mesh could not be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeshError {
    /// Fewer than 3 distinct samples.
    #[error("too few wall samples to triangulate: {0} (need at least 3 distinct)")]
    TooFewSamples(usize),
    /// A sample's coordinate is not finite or too large.
    #[error("a sample coordinate is not finite or too large: {0:?}")]
    BadCoordinate(P2),
}

/// A vertex handed to spade: its position and where it came from.
#[derive(Debug, Clone, Copy)]
struct Tagged {
    pos: Point2<f64>,
    /// Index into the input points, or `n_points + k` for box corner `k`.
    id: u32,
}

impl HasPosition for Tagged {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.pos
    }
}

impl Mesh {
    /// Triangulates `points` (with their `normals`) plus four box corners. Points are snapped to
    /// a 1 mm grid; points landing on the same grid node merge (one of them is kept).
    pub fn build(points: &[P2], normals: &[P2]) -> Result<Mesh, MeshError> {
        if let Some(bad) = points.iter().find(|p| {
            !(p[0].is_finite() && p[1].is_finite()) || p[0].abs() > 1e9 || p[1].abs() > 1e9
        }) {
            return Err(MeshError::BadCoordinate(*bad));
        }
        if points.len() >= u32::MAX as usize - 8 {
            return Err(MeshError::TooFewSamples(0));
        }
        let (lo, hi) = bounds(points).ok_or(MeshError::TooFewSamples(0))?;
        let diag = geom::dist(lo, hi);
        let margin = (0.1 * diag).max(2.0);
        let n_points = points.len();
        let mut tagged: Vec<Tagged> = points
            .iter()
            .enumerate()
            .map(|(i, p)| Tagged {
                pos: Point2::new(
                    (p[0] * 1000.0).round() / 1000.0,
                    (p[1] * 1000.0).round() / 1000.0,
                ),
                id: i as u32,
            })
            .collect();
        let box_corners = [
            [lo[0] - margin, lo[1] - margin],
            [hi[0] + margin, lo[1] - margin],
            [hi[0] + margin, hi[1] + margin],
            [lo[0] - margin, hi[1] + margin],
        ];
        for (k, c) in box_corners.iter().enumerate() {
            tagged.push(Tagged {
                pos: Point2::new(c[0], c[1]),
                id: (n_points + k) as u32,
            });
        }
        // Bulk loading sorts the points along a space-filling order: much faster than inserting
        // 100k samples one by one.
        let tri: DelaunayTriangulation<Tagged> =
            DelaunayTriangulation::bulk_load(tagged).map_err(|_| MeshError::BadCoordinate(lo))?;
        // Samples first, in input order, then the corners.
        let mut kept: Vec<(u32, usize)> = tri
            .vertices()
            .map(|v| (v.data().id, v.fix().index()))
            .collect();
        kept.sort_unstable();
        let n_samples = kept
            .iter()
            .filter(|(id, _)| (*id as usize) < n_points)
            .count();
        if n_samples < 3 {
            return Err(MeshError::TooFewSamples(n_samples));
        }
        if kept.len() != n_samples + 4 {
            // A corner merged with a sample: impossible with a positive margin, but never index past it.
            return Err(MeshError::BadCoordinate(lo));
        }
        let mut vertex_of_handle = vec![u32::MAX; tri.num_vertices()];
        let mut vertices = Vec::with_capacity(kept.len());
        let mut out_normals = Vec::with_capacity(kept.len());
        let mut sample_of = Vec::with_capacity(kept.len());
        for &(id, h) in &kept {
            vertex_of_handle[h] = vertices.len() as u32;
            let id = id as usize;
            if id < n_points {
                let p = tri.vertex(FixedVertexHandle::from_index(h)).data().pos;
                vertices.push([p.x, p.y]);
                out_normals.push(normals.get(id).copied().unwrap_or([0.0, 0.0]));
                sample_of.push(id as u32);
            } else {
                vertices.push(box_corners[id - n_points]);
                out_normals.push([0.0, 0.0]);
                sample_of.push(u32::MAX);
            }
        }
        Ok(Self::from_spade(
            &tri,
            &vertex_of_handle,
            vertices,
            out_normals,
            sample_of,
            n_samples,
        ))
    }

    fn from_spade(
        tri: &DelaunayTriangulation<Tagged>,
        vertex_of_handle: &[u32],
        vertices: Vec<P2>,
        normals: Vec<P2>,
        sample_of: Vec<u32>,
        n_samples: usize,
    ) -> Mesh {
        let mut face_index = vec![NONE; tri.all_faces().len()];
        let mut triangles = Vec::with_capacity(tri.num_inner_faces());
        for (i, f) in tri.inner_faces().enumerate() {
            face_index[f.fix().index()] = i as u32;
            let v = f.vertices();
            triangles.push(v.map(|h| vertex_of_handle[h.fix().index()]));
        }
        let mut neighbors = vec![[NONE; 3]; triangles.len()];
        for (i, f) in tri.inner_faces().enumerate() {
            // spade's adjacent_edges()[k] runs from vertex k to vertex k+1, so it lies opposite vertex k+2.
            for (k, e) in f.adjacent_edges().iter().enumerate() {
                let across = e.rev().face();
                if let Some(inner) = across.as_inner() {
                    neighbors[i][(k + 2) % 3] = face_index[inner.fix().index()];
                }
            }
        }
        Mesh {
            vertices,
            normals,
            sample_of,
            n_samples,
            triangles,
            neighbors,
        }
    }

    /// True when triangle `t` has a box-corner vertex.
    pub fn touches_corner(&self, t: usize) -> bool {
        self.triangles[t]
            .iter()
            .any(|&v| v as usize >= self.n_samples)
    }

    /// The three corner positions of triangle `t`.
    pub fn corners(&self, t: usize) -> [P2; 3] {
        self.triangles[t].map(|v| self.vertices[v as usize])
    }

    /// Area of triangle `t` (positive: triangles are CCW).
    pub fn area(&self, t: usize) -> f64 {
        let [a, b, c] = self.corners(t);
        geom::cross(geom::sub(b, a), geom::sub(c, a)) / 2.0
    }

    /// Checks orientation and neighbour symmetry; used by tests of every later stage.
    pub fn check(&self) -> Result<(), String> {
        for t in 0..self.triangles.len() {
            if self.area(t) <= 0.0 {
                return Err(format!("triangle {t} is not counter-clockwise"));
            }
            for k in 0..3 {
                let n = self.neighbors[t][k];
                if n != NONE && !self.neighbors[n as usize].contains(&(t as u32)) {
                    return Err(format!(
                        "triangle {t} lists {n} as a neighbour but not vice versa"
                    ));
                }
            }
        }
        Ok(())
    }
}

fn bounds(points: &[P2]) -> Option<(P2, P2)> {
    let first = *points.first()?;
    Some(points.iter().fold((first, first), |(lo, hi), p| {
        (
            [lo[0].min(p[0]), lo[1].min(p[1])],
            [hi[0].max(p[0]), hi[1].max(p[1])],
        )
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_mesh_is_consistent_and_boxed() {
        let pts = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]];
        let m = Mesh::build(&pts, &[[0.0, 1.0]; 5]).unwrap();
        m.check().unwrap();
        assert_eq!(m.n_samples, 5);
        assert_eq!(m.vertices.len(), 9);
        // Euler: a triangulated convex polygon with h hull and i interior vertices has 2i + h - 2 triangles.
        assert_eq!(m.triangles.len(), 2 * 5 + 4 - 2);
        let total: f64 = (0..m.triangles.len()).map(|t| m.area(t)).sum();
        let side = 1.0 + 2.0 * 2.0;
        assert!((total - side * side).abs() < 1e-9);
        for t in 0..m.triangles.len() {
            for k in 0..3 {
                let n = m.neighbors[t][k];
                if n == NONE {
                    continue;
                }
                // The shared edge is the one opposite vertex k: both its ends are in the neighbour.
                let [a, b] = [m.triangles[t][(k + 1) % 3], m.triangles[t][(k + 2) % 3]];
                assert!(
                    m.triangles[n as usize].contains(&a) && m.triangles[n as usize].contains(&b)
                );
            }
        }
    }

    #[test]
    fn duplicates_merge_and_too_few_fail() {
        let pts = [[0.0, 0.0], [0.0002, 0.0], [1.0, 0.0]];
        assert_eq!(Mesh::build(&pts, &[]), Err(MeshError::TooFewSamples(2)));
        assert!(matches!(
            Mesh::build(&[[f64::NAN, 0.0]], &[]),
            Err(MeshError::BadCoordinate(_))
        ));
    }
}
