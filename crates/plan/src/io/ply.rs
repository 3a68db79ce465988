//! PLY: ASCII and binary (both endiannesses), streamed, with optional `scan_index` and `time`.

use std::path::Path;

use super::ReadError;
use crate::cloud::PointCloud;

/// Reads a PLY file.
pub fn read_ply(path: &Path) -> Result<PointCloud, ReadError> {
    Err(ReadError::invalid(path, "ply", "PLY reader not built yet"))
}
