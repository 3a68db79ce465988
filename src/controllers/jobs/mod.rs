//! `/v1/jobs`: upload, show, list, events, results, delete.

pub mod create;
pub mod delete;
mod drain;
pub mod events;
pub mod list;
mod pace;
pub mod results;
pub mod show;
mod sniff;

use crate::app::AppState;
use crate::errors::{ApiError, Code};
use crate::queue::{Job, JobId};

/// Parses a path id; an invalid one is simply not found.
pub fn parse_id(raw: &str) -> Result<JobId, ApiError> {
    raw.parse()
        .map_err(|e: crate::queue::InvalidJobId| ApiError::new(Code::NotFound, e.to_string()))
}

/// The tenant's job, or `not_found` (also for other tenants' jobs).
pub async fn load(state: &AppState, tenant: &str, raw: &str) -> Result<Job, ApiError> {
    let id = parse_id(raw)?;
    state
        .store
        .get(Some(tenant), id)
        .await?
        .ok_or_else(ApiError::not_found)
}
