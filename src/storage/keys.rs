//! The blob layout. Every key is built here from a validated [`JobId`] and fixed names.

use crate::queue::JobId;

/// Everything a job owns.
pub fn job_prefix(id: JobId) -> String {
    format!("jobs/{id}")
}

/// The uploaded cloud.
pub fn cloud(id: JobId) -> String {
    format!("jobs/{id}/input/cloud")
}

/// The pose or trajectory sidecar, when one was uploaded.
pub fn sidecar(id: JobId) -> String {
    format!("jobs/{id}/input/sidecar.json")
}

/// The results' folder.
pub fn result_prefix(id: JobId) -> String {
    format!("jobs/{id}/result")
}

/// One result file; `name` is one of [`RESULTS`].
pub fn result(id: JobId, name: &str) -> String {
    debug_assert!(RESULTS.iter().any(|(n, _)| *n == name));
    format!("jobs/{id}/result/{name}")
}

/// The result files and their media types.
pub const RESULTS: [(&str, &str); 3] = [
    ("plan.geojson", "application/geo+json"),
    ("plan.svg", "image/svg+xml"),
    ("plan.dxf", "application/dxf"),
];
