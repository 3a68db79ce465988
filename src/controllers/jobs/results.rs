//! `GET /v1/jobs/{id}/{file}`: the results of `asbuilt_plan::io::outputs::OUTPUTS`, streamed
//! from storage.

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
    let media = asbuilt_plan::io::outputs::by_file(name)
        .map_or("application/octet-stream", |o| o.media_type);
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

/// Any result of `asbuilt_plan::io::outputs::OUTPUTS` by its file name: `plan.geojson`, ...
pub async fn file(
    State(s): State<AppState>,
    Tenant(t): Tenant,
    Path((id, file)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    let Some(output) = asbuilt_plan::io::outputs::by_file(&file) else {
        return Err(ApiError::new(Code::RouteNotFound, "no such endpoint"));
    };
    result(s, t, id, output.file).await
}
