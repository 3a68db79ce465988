//! Scores a floor plan against ground truth: area IoU, boundary distance, completeness,
//! watertightness and arc radius error.
