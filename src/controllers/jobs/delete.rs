//! `DELETE /v1/jobs/{id}`: cancel if queued or running, then delete everything the job owns.

use axum::extract::{Path, State};
use axum::http::StatusCode;

use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::ApiError;
use crate::storage::keys;

pub async fn delete(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    let id = super::parse_id(&id)?;
    // Cancelling takes the lease away; the worker notices at its next heartbeat and stops.
    state
        .store
        .cancel(&tenant, id)
        .await?
        .ok_or_else(ApiError::not_found)?;
    state.store.delete(id).await?;
    state.blobs.delete_prefix(&keys::job_prefix(id)).await?;
    state.changed(id);
    tracing::info!(job = %id, "job deleted");
    Ok(StatusCode::NO_CONTENT)
}
