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

/// One result file; `name` is the file of one of `asbuilt_plan::io::outputs::OUTPUTS`.
pub fn result(id: JobId, name: &str) -> String {
    debug_assert!(asbuilt_plan::io::outputs::by_file(name).is_some());
    format!("jobs/{id}/result/{name}")
}

/// Everything a resumable upload session owns.
pub fn upload_prefix(id: JobId) -> String {
    format!("uploads/{id}")
}

/// Every upload session.
pub const UPLOADS: &str = "uploads";

/// The session's record: its tenant, length and expiry.
pub fn upload_session(id: JobId) -> String {
    format!("uploads/{id}/session.json")
}

/// A direct upload's record (its tenant, length, part size, the store's upload id, expiry);
/// its parts are in the store's multipart upload to the future job's [`cloud`].
pub fn direct_upload(id: JobId) -> String {
    format!("uploads/{id}/direct.json")
}

/// The session's parts, one per `PATCH`, named by their offset so they list in order.
pub fn upload_parts(id: JobId) -> String {
    format!("uploads/{id}/parts")
}

/// The part that starts at `offset`.
pub fn upload_part(id: JobId, offset: u64) -> String {
    format!("uploads/{id}/parts/{offset:020}")
}
