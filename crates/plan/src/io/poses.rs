//! The pose sidecars of `shared/design/contract.md` §2: static scan poses and mobile trajectories.
//! Sidecar positions are in the cloud's world frame; attaching converts them to the local frame.

use crate::cloud::{PointCloud, ScanPose, TrajectorySample};

/// Why a sidecar could not be used. Messages name the offending index.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PosesError {
    #[error("not valid pose JSON: {0}")]
    Json(String),
    #[error("{0}")]
    Mismatch(String),
}

/// Parses `{"scans": [{"index", "position", "quaternion"}]}` (world frame).
pub fn parse_poses(text: &str) -> Result<Vec<ScanPose>, PosesError> {
    let _ = text;
    Err(PosesError::Json("pose reader not built yet".into()))
}

/// Parses `{"samples": [{"t", "position", "quaternion"}]}` (world frame).
pub fn parse_trajectory(text: &str) -> Result<Vec<TrajectorySample>, PosesError> {
    let _ = text;
    Err(PosesError::Json("trajectory reader not built yet".into()))
}

/// Attaches world-frame static poses to a cloud whose points name their scans.
pub fn attach_poses(cloud: &mut PointCloud, poses: Vec<ScanPose>) -> Result<(), PosesError> {
    let _ = (cloud, poses);
    Err(PosesError::Mismatch("not built yet".into()))
}

/// Attaches a world-frame trajectory to a cloud whose points carry times.
pub fn attach_trajectory(
    cloud: &mut PointCloud,
    samples: Vec<TrajectorySample>,
) -> Result<(), PosesError> {
    let _ = (cloud, samples);
    Err(PosesError::Mismatch("not built yet".into()))
}
