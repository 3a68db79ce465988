//! `DELETE /v1/jobs/{id}`: cancel if queued or running, then delete everything the job owns.

use axum::extract::{Path, State};
use axum::http::StatusCode;

use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::ApiError;
use crate::worker::retire;

pub async fn delete(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    let id = super::parse_id(&id)?;
    // Cancelling takes the lease away; the worker notices at its next heartbeat and stops.
    let Some(job) = state.store.cancel(&tenant, id).await? else {
        return Err(super::missing(&state, &tenant, id).await);
    };
    state.store.delete(id).await?;
    state.early.forget(id);
    // A re-plan may still read this job's upload; it stays until the last reader goes.
    retire::remove_blobs(&state, id, job.input_job)
        .await
        .map_err(ApiError::internal)?;
    state.changed(id);
    tracing::info!(job = %id, "job deleted");
    Ok(StatusCode::NO_CONTENT)
}
