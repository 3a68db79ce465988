//! Stage 1 (§3.1): split the cloud into stories from a histogram of point heights.

use serde::{Deserialize, Serialize};

/// Parameters of [`split_stories`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StoriesParams {
    /// Height histogram bin width in metres. The paper leaves it open; 5 cm matches d_s (§3.1).
    pub bin_size: f64,
    /// Minimum floor-to-ceiling height of a story, metres (§3.1: "typically ~2 meters").
    pub min_wall_height: f64,
}

impl Default for StoriesParams {
    fn default() -> Self {
        StoriesParams {
            bin_size: 0.05,
            min_wall_height: 2.0,
        }
    }
}

/// One story: its floor and ceiling, and the z range of points assigned to it (local frame).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Story {
    /// 0 is the lowest story.
    pub level: usize,
    pub floor_z: f64,
    pub ceiling_z: f64,
    /// Points with `z_min <= z < z_max` belong to this story (partition levels, §3.1).
    pub z_min: f64,
    pub z_max: f64,
}

/// Why no stories could be found.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StoriesError {
    #[error("the cloud is empty")]
    Empty,
    #[error("invalid stories parameter `{name}`: {why}")]
    BadParam { name: &'static str, why: String },
    #[error("no floor or ceiling found: {0}")]
    NotFound(String),
}

/// Finds the stories of a cloud from the heights `z` of its points (local frame).
pub fn split_stories(z: &[f32], params: &StoriesParams) -> Result<Vec<Story>, StoriesError> {
    let _ = (z, params);
    Err(StoriesError::NotFound("stage not built yet".into()))
}
