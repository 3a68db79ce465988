//! Reading clouds and pose sidecars, and writing plans. The only module that touches files.

pub mod dxf;
pub mod geojson;
pub mod ply;
pub mod poses;
pub mod svg;

use std::path::Path;

use crate::cloud::PointCloud;

/// Why a file could not be read. Every variant names the file and, where it helps, the place.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: unrecognised format ({why})")]
    UnknownFormat { path: String, why: String },
    #[error("{path} ({format}): {why}{}", at.as_ref().map(|a| format!(" at {a}")).unwrap_or_default())]
    Invalid {
        path: String,
        format: &'static str,
        why: String,
        at: Option<String>,
    },
    #[error("{path}: poses: {why}")]
    Poses { path: String, why: String },
}

impl ReadError {
    /// Shorthand for a format error without a location.
    pub fn invalid(path: &Path, format: &'static str, why: impl Into<String>) -> ReadError {
        ReadError::Invalid {
            path: path.display().to_string(),
            format,
            why: why.into(),
            at: None,
        }
    }

    /// A stable machine-readable code for the service's error bodies.
    pub fn code(&self) -> &'static str {
        match self {
            ReadError::Io { .. } => "io_error",
            ReadError::UnknownFormat { .. } => "unknown_format",
            ReadError::Invalid { .. } => "invalid_file",
            ReadError::Poses { .. } => "invalid_poses",
        }
    }
}

/// Reads a point cloud, choosing the reader from the file's content.
pub fn read_cloud(path: &Path) -> Result<PointCloud, ReadError> {
    use std::io::Read;
    let io = |source| ReadError::Io {
        path: path.display().to_string(),
        source,
    };
    let mut magic = Vec::with_capacity(4);
    std::fs::File::open(path)
        .map_err(io)?
        .take(4)
        .read_to_end(&mut magic)
        .map_err(io)?;
    if magic == b"ply\n" || magic == b"ply\r" {
        return ply::read_ply(path);
    }
    Err(ReadError::UnknownFormat {
        path: path.display().to_string(),
        why: "only PLY is read so far".into(),
    })
}
