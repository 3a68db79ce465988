//! The pipeline's result: a floor plan per story, in the local frame of the cloud.

use serde::Serialize;

use crate::geom::P2;

/// A polygon with holes. Rings are open (the first point is not repeated); exteriors are CCW and
/// holes CW. Writers close them.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Polygon {
    pub exterior: Vec<P2>,
    pub holes: Vec<Vec<P2>>,
}

/// The geometric model of a wall piece.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "model", rename_all = "lowercase")]
pub enum WallModel {
    Line,
    Arc { center: P2, radius: f64 },
}

/// One fitted wall piece on a story's boundary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Wall {
    pub model: WallModel,
    /// The piece as a polyline on the boundary; arcs are densified (1 cm chord error).
    pub points: Vec<P2>,
    /// Inlier samples supporting the model.
    pub support: usize,
}

impl Wall {
    /// Length of the polyline, metres.
    pub fn length(&self) -> f64 {
        self.points
            .windows(2)
            .map(|w| crate::geom::dist(w[0], w[1]))
            .sum()
    }
}

/// One story's plan.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StoryPlan {
    pub level: usize,
    /// Local-frame heights (add `FloorPlan::origin[2]` for world heights).
    pub floor_z: f64,
    pub ceiling_z: f64,
    pub polygons: Vec<Polygon>,
    pub walls: Vec<Wall>,
    /// Wall sample positions (local), used by `wall_samples` output and the SVG.
    pub samples: Vec<P2>,
}

impl StoryPlan {
    /// Open floor area: exteriors minus holes.
    pub fn area(&self) -> f64 {
        self.polygons
            .iter()
            .map(|p| {
                crate::geom::ring_signed_area(&p.exterior).abs()
                    - p.holes
                        .iter()
                        .map(|h| crate::geom::ring_signed_area(h).abs())
                        .sum::<f64>()
            })
            .sum()
    }
}

/// What was read, as reported in `floorplan.input`.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct InputSummary {
    pub points: u64,
    pub format: String,
    pub scans: usize,
    /// Where the scanner stood: given or estimated, per scan, and how much of the plan rests
    /// on it.
    pub viewpoints: crate::viewpoints::ViewpointsReport,
}

/// A whole floor plan: every story, and how it was made.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FloorPlan {
    /// World coordinates of the local frame; writers add it back.
    pub origin: [f64; 3],
    pub crs: Option<String>,
    pub input: InputSummary,
    /// Every parameter the run used, defaults and derived values included.
    pub parameters: serde_json::Value,
    /// Stage name → milliseconds, in pipeline order.
    pub timings_ms: Vec<(String, u64)>,
    pub stories: Vec<StoryPlan>,
    /// Things worth telling the user (adapted thresholds, skipped stories).
    pub notes: Vec<String>,
}
