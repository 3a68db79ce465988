//! `/v1/jobs`: upload, show, list, events, results, delete.

pub mod cancel;
pub mod create;
pub mod delete;
pub mod deliveries;
pub mod direct;
mod drain;
pub mod events;
pub mod list;
mod pace;
pub mod replan;
pub mod results;
pub mod show;
mod sniff;
pub mod submit;
pub mod uploads;

use axum::http::{HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;

use crate::app::AppState;
use crate::errors::{ApiError, Code};
use crate::queue::{Job, JobId};

/// Stores an upload session's record as JSON under `key`: tus and direct uploads keep their
/// state in the blob store, so any API process can serve the next call.
pub async fn put_json<T: Serialize>(
    state: &AppState,
    key: &str,
    value: &T,
) -> Result<(), ApiError> {
    let bytes = serde_json::to_vec(value).map_err(ApiError::internal)?;
    state.blobs.put(key, bytes.into()).await?;
    Ok(())
}

/// `201 Created` with `body`, and `Location` naming what was created.
pub fn created(body: serde_json::Value, location: String) -> Result<Response, ApiError> {
    let mut r = (StatusCode::CREATED, axum::Json(body)).into_response();
    let at = HeaderValue::try_from(location).map_err(ApiError::internal)?;
    r.headers_mut().insert("location", at);
    Ok(r)
}

/// Parses a path id; an invalid one is simply not found.
pub fn parse_id(raw: &str) -> Result<JobId, ApiError> {
    raw.parse()
        .map_err(|e: crate::queue::InvalidJobId| ApiError::new(Code::NotFound, e.to_string()))
}

/// The tenant's job, or `not_found` (also for other tenants' jobs), or `expired`.
pub async fn load(state: &AppState, tenant: &str, raw: &str) -> Result<Job, ApiError> {
    let id = parse_id(raw)?;
    match state.store.get(Some(tenant), id).await? {
        Some(job) => Ok(job),
        None => Err(missing(state, tenant, id).await),
    }
}

/// The answer for a job the tenant does not have: `expired` (410) when retention removed it,
/// else `not_found`.
pub async fn missing(state: &AppState, tenant: &str, id: JobId) -> ApiError {
    match state.store.expired_at(tenant, id).await {
        Ok(Some(at)) => ApiError::new(
            Code::Expired,
            format!(
                "the job expired at {} and its data was deleted (retention: {} h)",
                crate::views::timestamp(at),
                state.config.retention_hours
            ),
        ),
        Ok(None) => ApiError::not_found(),
        Err(e) => e.into(),
    }
}
