//! Stage 3 (§3.2): average wall samples across small registration errors.

use serde::{Deserialize, Serialize};

use crate::samples::WallSamples;

/// Parameters of [`smooth_samples`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SmoothingParams {
    /// Expected registration error, metres. `None` turns smoothing off (§3.2: "not necessary if
    /// registration error is smaller than d_s").
    pub registration_error: Option<f64>,
    /// Smoothing distance along ±n, metres; `None` uses 2 × the registration error (§3.2: at
    /// least the registration error, less than the spacing of parallel walls).
    pub distance: Option<f64>,
    /// Extent across n, in cells of d_s (§3.2: 3 d_s).
    pub across_cells: f64,
    /// Maximum normal angle, radians (§3.2: π/8).
    pub max_angle: f64,
}

impl Default for SmoothingParams {
    fn default() -> Self {
        SmoothingParams {
            registration_error: None,
            distance: None,
            across_cells: 3.0,
            max_angle: std::f64::consts::FRAC_PI_8,
        }
    }
}

/// Why smoothing failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SmoothingError {
    #[error("invalid smoothing parameter `{name}`: {why}")]
    BadParam { name: &'static str, why: String },
}

/// Moves each sample to the mean of its smoothing set. `cell_size` is d_s.
pub fn smooth_samples(
    samples: &mut WallSamples,
    cell_size: f64,
    params: &SmoothingParams,
) -> Result<(), SmoothingError> {
    let _ = (samples, cell_size, params);
    Ok(())
}
