//! Stage 5b (§3.4): the boundary between inside and outside triangles, as closed rings grouped
//! into polygons with holes. Watertight by construction; [`Boundary::check`] proves it.

use serde::Serialize;

use crate::labeling::LabeledMesh;

/// A closed ring of mesh vertex indices (the first vertex is not repeated).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ring {
    pub vertices: Vec<u32>,
    /// Shoelace area: positive for exteriors (CCW), negative for holes (CW).
    pub signed_area: f64,
}

/// One edge-connected inside region: an exterior ring and its holes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BoundaryPolygon {
    pub exterior: Ring,
    pub holes: Vec<Ring>,
}

/// All boundary polygons of a story.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Boundary {
    pub polygons: Vec<BoundaryPolygon>,
}

/// Why the boundary could not be traced.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BoundaryError {
    #[error("no inside triangles: the story has no enclosed floor area")]
    NothingInside,
    #[error("boundary is not watertight: {0}")]
    NotWatertight(String),
}

/// Traces the rings between inside and outside triangles.
pub fn trace_boundary(labeled: &LabeledMesh) -> Result<Boundary, BoundaryError> {
    if !labeled.inside.iter().any(|&i| i) {
        return Err(BoundaryError::NothingInside);
    }
    Err(BoundaryError::NotWatertight("stage not built yet".into()))
}
