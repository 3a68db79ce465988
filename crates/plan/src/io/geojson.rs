//! Writes a FloorPlan as geojson.
