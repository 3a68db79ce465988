//! Writes a FloorPlan as svg.
