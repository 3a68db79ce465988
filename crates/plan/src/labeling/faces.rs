//! Wall faces in the mesh, and lines of sight that cross them from behind (beyond the paper).
//!
//! §3.3 trusts every line of sight. But an opaque wall hides what lies beyond it: where a
//! scanner recorded points beyond a face that another scanner saw straight from its front, it saw
//! a mirror's image or through glass, and those lines of sight would carve the wall away (the
//! real apartment's bathroom mirror cut the wall between bathroom and kitchen).

use super::mesh::Mesh;
use crate::geom::{self, P2};

/// The longest edge between two vertices of one face, in sample spacings: the holes the gap
/// filler leaves open (longer than [`super::gaps::MAX_GAP`]) are where a face may be open.
const FACE_GAP: f64 = super::gaps::MAX_GAP;

/// Two vertices lie on one face when their normals turn less than this apart (cos 30°)...
const FACE_COS: f64 = 0.866;

/// ...and the edge between them runs along both faces: across each normal by at most this
/// (sin 30°), so a corner's or a step's edge is no face.
const FACE_SIN: f64 = 0.5;

/// Which mesh edges are faces: both ends samples (or filled vertices) whose oriented normals
/// agree and lie across the edge, at most [`FACE_GAP`] spacings apart.
pub(crate) struct Faces {
    max_len: f64,
    /// How far a face must run on past both ends of a crossed edge, metres.
    run: f64,
    /// Per vertex, the vertices it shares a face edge with.
    along: Vec<Vec<u32>>,
    /// Per triangle, bit k set when the edge across from its vertex k is a face: a line of
    /// sight crosses many edges and few faces, so each step tests a bit.
    edges: Vec<u8>,
}

/// A line of sight crosses a face from behind when it meets it at this angle or more (sin 30°).
const FACE_STEEP: f64 = 0.5;

/// A crossed face must run on this many sample spacings past both ends of the crossed edge. A
/// line of sight through a doorway clips the last samples of its jambs in 2D, where the
/// samples' cells straddle the wall's end; a mirror or a pane lies within a wall.
const FACE_RUN: f64 = 4.0;

impl Faces {
    /// The faces of `mesh`, whose samples lie `h` apart along their rows.
    pub(crate) fn of(mesh: &Mesh, h: f64) -> Faces {
        let mut faces = Faces {
            max_len: FACE_GAP * h,
            run: FACE_RUN * h,
            along: Vec::new(),
            edges: vec![0; mesh.triangles.len()],
        };
        let mut along = vec![Vec::new(); mesh.vertices.len()];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                let (u, w) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                if faces.normal(mesh, u, w).is_some() {
                    faces.edges[t] |= 1 << k;
                    along[u as usize].push(w);
                    along[w as usize].push(u);
                }
            }
        }
        for a in &mut along {
            a.sort_unstable();
            a.dedup();
        }
        faces.along = along;
        faces
    }

    /// Whether the face runs on from `u`, away from `prev`, for [`Self::run`] metres: each step
    /// a face edge turning less than 60° from the last.
    fn runs_on(&self, mesh: &Mesh, prev: u32, u: u32) -> bool {
        let v = &mesh.vertices;
        let (mut prev, mut u, mut run) = (prev as usize, u as usize, 0.0);
        // A face edge is at least a hair long, so the walk ends; the cap guards the rest.
        for _ in 0..64 {
            let dir = geom::sub(v[u], v[prev]);
            let next = self.along[u].iter().map(|&z| z as usize).find(|&z| {
                let step = geom::sub(v[z], v[u]);
                geom::dot(step, dir) > 0.5 * geom::norm(step) * geom::norm(dir)
            });
            let Some(z) = next else {
                return false;
            };
            run += geom::dist(v[z], v[u]);
            if run >= self.run {
                return true;
            }
            (prev, u) = (u, z);
        }
        false
    }

    /// The oriented unit normal of the face `u`-`w`, `None` when the edge is no face.
    fn normal(&self, mesh: &Mesh, u: u32, w: u32) -> Option<P2> {
        let (u, w) = (u as usize, w as usize);
        if u >= mesh.n_samples || w >= mesh.n_samples {
            return None;
        }
        let e = geom::sub(mesh.vertices[w], mesh.vertices[u]);
        let len = geom::norm(e);
        let unit = geom::normalize;
        let (nu, nw) = (unit(mesh.normals[u])?, unit(mesh.normals[w])?);
        let along = |n: P2| geom::dot(n, e).abs() <= FACE_SIN * len;
        (len > 0.0
            && len <= self.max_len
            && geom::dot(nu, nw) >= FACE_COS
            && along(nu)
            && along(nw))
        .then(|| unit([nu[0] + nw[0], nu[1] + nw[1]]))
        .flatten()
    }

    /// The faces that the walk `tris` (consecutive triangles of a line of sight from `from`)
    /// crosses steeply with `from` behind them, each running on past both ends of the edge.
    pub(crate) fn crossed_from_behind(
        &self,
        mesh: &Mesh,
        from: P2,
        tris: &[u32],
    ) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for w in tris.windows(2) {
            let (t, next) = (w[0] as usize, w[1]);
            // Most triangles have no face among their edges: settled without the edge's lookup.
            if self.edges[t] == 0 {
                continue;
            }
            let Some(k) = (0..3).find(|&k| mesh.neighbors[t][k] == next) else {
                continue;
            };
            if self.edges[t] & (1 << k) == 0 {
                continue;
            }
            let tri = mesh.triangles[t];
            let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
            let Some(n) = self.normal(mesh, a, b) else {
                continue;
            };
            let (p, q) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
            let mid = [(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0];
            let to = geom::sub(from, mid);
            // Steeply: a line of sight grazing a face (past a column's side) clips its samples
            // in 2D by noise alone.
            if geom::dot(n, to) < -FACE_STEEP * geom::norm(to)
                && self.runs_on(mesh, b, a)
                && self.runs_on(mesh, a, b)
            {
                out.push((a, b));
            }
        }
        out
    }
}
