//! The floor plan as DXF R12: a layer per story, a layer for walls, real ARC entities, metres.

use crate::plan::FloorPlan;

/// Why DXF could not be written.
#[derive(Debug, thiserror::Error)]
#[error("dxf: {0}")]
pub struct DxfError(pub String);

/// The plan as DXF R12 bytes.
pub fn to_dxf(plan: &FloorPlan) -> Result<Vec<u8>, DxfError> {
    let _ = plan;
    Err(DxfError("not built yet".into()))
}
