//! Stage 4 (§3.3): Delaunay triangulation of the wall samples and 2D Eigencrust inside/outside
//! labeling. See `shared/design/eigencrust-2d.md` for the derivation.

pub mod mesh;

use serde::{Deserialize, Serialize};

pub use mesh::{Mesh, MeshError, NONE};

use crate::samples::WallSamples;

/// Parameters of [`label`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LabelingParams {
    /// Lines of sight needed to force a triangle inside (§3.3: 10).
    pub min_rays: u32,
    /// The central fraction of each pose→sample segment that counts as a line of sight (§3.3: 50%).
    pub ray_fraction: f64,
    /// Use only pole pairs that share an edge as negative edges (reading (b) of the design note).
    pub adjacent_poles_only: bool,
    /// Node count below which the eigenproblem is solved densely (design note §3: ~3000).
    pub dense_below: usize,
    /// Solver: `eigen` (the paper's spectral partition) or `harmonic` (the linear-system variant).
    pub solver: Solver,
}

/// Which partition to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Solver {
    Eigen,
    Harmonic,
}

impl Default for LabelingParams {
    fn default() -> Self {
        LabelingParams {
            min_rays: 10,
            ray_fraction: 0.5,
            adjacent_poles_only: false,
            dense_below: 3000,
            solver: Solver::Eigen,
        }
    }
}

/// A triangulation with an inside/outside label per triangle.
#[derive(Debug, Clone, PartialEq)]
pub struct LabeledMesh {
    pub mesh: Mesh,
    /// Per triangle: true when inside (open floor).
    pub inside: Vec<bool>,
    /// Per triangle: the hard constraint, if any (`Some(true)` forced inside).
    pub forced: Vec<Option<bool>>,
}

/// Why labeling failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LabelingError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("invalid labeling parameter `{name}`: {why}")]
    BadParam { name: &'static str, why: String },
    #[error("the eigen-solver failed: {0}")]
    Solver(String),
}

/// Triangulates the samples and labels every triangle inside or outside.
pub fn label(samples: &WallSamples, params: &LabelingParams) -> Result<LabeledMesh, LabelingError> {
    let points: Vec<_> = samples.samples.iter().map(|s| s.pos).collect();
    let normals: Vec<_> = samples.samples.iter().map(|s| s.normal).collect();
    let mesh = Mesh::build(&points, &normals)?;
    let _ = params;
    let n = mesh.triangles.len();
    let forced: Vec<Option<bool>> = (0..n)
        .map(|t| mesh.touches_corner(t).then_some(false))
        .collect();
    Ok(LabeledMesh {
        mesh,
        inside: vec![false; n],
        forced,
    })
}
