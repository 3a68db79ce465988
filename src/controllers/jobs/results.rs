//! `GET /v1/jobs/{id}/plan.{geojson,svg,dxf}`: the results, streamed from storage.

use axum::body::Body;
use axum::extract::{Path, State};
use axum::http::header::{CONTENT_DISPOSITION, CONTENT_LENGTH, CONTENT_TYPE};
use axum::response::{IntoResponse, Response};

use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::{ApiError, Code};
use crate::queue::JobStatus;
use crate::storage::keys;

async fn result(
    state: AppState,
    tenant: String,
    id: String,
    name: &str,
) -> Result<Response, ApiError> {
    let job = super::load(&state, &tenant, &id).await?;
    if job.status != JobStatus::Succeeded {
        return Err(ApiError::new(
            Code::ResultNotReady,
            format!("the job is {}, so it has no {name}", job.status.as_str()),
        ));
    }
    let media = keys::RESULTS
        .iter()
        .find(|(n, _)| *n == name)
        .map_or("application/octet-stream", |(_, m)| m);
    let key = keys::result(job.id, name);
    // With pre-signed URLs configured, the client fetches straight from the object store.
    if let Some(url) = state.blobs.presigned_get(&key).await? {
        return Ok(axum::response::Redirect::temporary(&url).into_response());
    }
    let blob = state.blobs.get(&key).await?.ok_or_else(|| {
        ApiError::internal(format!("job {} succeeded but {name} is missing", job.id))
    })?;
    let disposition = format!("inline; filename=\"{}-{name}\"", job.id);
    Ok((
        [
            (CONTENT_TYPE, media.to_string()),
            (CONTENT_LENGTH, blob.size.to_string()),
            (CONTENT_DISPOSITION, disposition),
        ],
        Body::from_stream(blob.stream),
    )
        .into_response())
}

pub async fn geojson(
    State(s): State<AppState>,
    Tenant(t): Tenant,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    result(s, t, id, "plan.geojson").await
}

pub async fn svg(
    State(s): State<AppState>,
    Tenant(t): Tenant,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    result(s, t, id, "plan.svg").await
}

pub async fn dxf(
    State(s): State<AppState>,
    Tenant(t): Tenant,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    result(s, t, id, "plan.dxf").await
}
