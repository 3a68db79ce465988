//! `POST /v1/jobs/{id}/cancel`: stop a queued or running job and keep it readable.

use axum::extract::{Path, State};
use axum::Json;

use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::{ApiError, Code};
use crate::queue::JobStatus;
use crate::views::JobView;

pub async fn cancel(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
) -> Result<Json<JobView>, ApiError> {
    let id = super::parse_id(&id)?;
    // The same step as DELETE: the lease goes, and the worker stops at its next heartbeat.
    let Some(job) = state.store.cancel(&tenant, id).await? else {
        return Err(super::missing(&state, &tenant, id).await);
    };
    // A cloud read early for the job is not kept for a worker that will not come.
    state.early.forget(id);
    match job.status {
        JobStatus::Cancelled => {
            state.changed(id);
            tracing::info!(job = %id, "job cancelled");
            Ok(Json(JobView::new(&job, &state.config)))
        }
        // Succeeded or failed before the request came: nothing to stop.
        other => Err(ApiError::new(
            Code::JobFinished,
            format!(
                "the job already {}; only a queued or running job can be cancelled",
                other.as_str()
            ),
        )),
    }
}
