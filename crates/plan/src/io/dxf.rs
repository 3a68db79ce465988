//! Writes a FloorPlan as dxf.
