//! `POST /v1/jobs/{id}/replan`: a new job from a job's stored upload, with other parameters
//! or other poses, without sending the cloud again.
//!
//! The body is empty, or `multipart/form-data` with an optional `params` part and an optional
//! `poses` or `trajectory` part. The new job starts from the job's parameters; a `params` part
//! replaces them, and query parameters apply on top. Without a sidecar part, the job's own
//! sidecar (if any) is kept; without a georeference (query fields or a `georeference` part),
//! the job's own (if any) is kept.

use asbuilt_plan::Params;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Path, Query, Request, State};
use axum::response::Response;

use super::create::{finish_params_from, is_multipart, receive_multipart, Received};
use super::submit::{self, Fingerprint, Options};
use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::{ApiError, Code};
use crate::queue::{Idempotency, JobId, NewJob};
use crate::storage::keys;

pub async fn replan(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(raw): Path<String>,
    query: Result<Query<Vec<(String, String)>>, QueryRejection>,
    request: Request,
) -> Result<Response, ApiError> {
    if state.shutdown.is_cancelled() {
        return Err(ApiError::new(
            Code::Unavailable,
            "the server is shutting down",
        ));
    }
    let source = super::load(&state, &tenant, &raw).await?;
    let Query(pairs) = query.map_err(|e| ApiError::new(Code::InvalidRequest, e.body_text()))?;
    let options = Options::parse(pairs)?;
    if options.filename.is_some() {
        return Err(ApiError::param(
            "filename",
            "a re-plan keeps the upload's file name",
        ));
    }
    let key = submit::idempotency_key(request.headers())?;
    let callback_url = submit::callback(&state, &tenant, options.callback_url.clone()).await?;
    submit::georeference(options.georeference.clone(), None)?;
    let prior = submit::prior(&state, &tenant, key.as_deref()).await?;
    let cap = state.config.max_queued;
    if prior.is_none() && cap > 0 && state.store.queued_count(&tenant).await? >= cap as u64 {
        return Err(super::create::queue_full(cap));
    }
    let id = JobId::new();
    let result = async {
        let received = if is_multipart(&request) {
            let received = receive_multipart(&state, id, request, false).await?;
            if let Some(kind) = received.sidecar {
                super::create::refuse_e57_sidecar(&source.upload.format, kind)?;
            }
            received
        } else {
            let limit = state.config.max_sidecar_bytes as usize;
            let body = axum::body::to_bytes(request.into_body(), limit)
                .await
                .map_err(|e| ApiError::new(Code::InvalidRequest, e.to_string()))?;
            if !body.is_empty() {
                return Err(ApiError::new(
                    Code::InvalidRequest,
                    "a re-plan takes no body, or multipart `params`, `poses` or \
                     `trajectory`, and `georeference` parts; the cloud is the job's stored upload",
                ));
            }
            Received::default()
        };
        let base: Params =
            serde_json::from_value(source.params.clone()).map_err(ApiError::internal)?;
        let (mut received, params) = finish_params_from(received, &options.overrides, base)?;
        received.georeference =
            submit::georeference(options.georeference.clone(), received.georeference.take())?
                .or_else(|| source.upload.georeference.clone());
        if received.sidecar.is_none() {
            // The job's own sidecar comes along, as a copy this job owns.
            if let Some(kind) = source.upload.sidecar.as_deref() {
                let blob = state
                    .blobs
                    .get(&keys::sidecar(source.id))
                    .await?
                    .ok_or_else(|| {
                        ApiError::internal(format!("job {} lost its sidecar", source.id))
                    })?;
                let bytes: Vec<u8> = futures_util::TryStreamExt::try_concat(
                    futures_util::TryStreamExt::map_ok(blob.stream, |b| b.to_vec()),
                )
                .await
                .map_err(ApiError::internal)?;
                state.blobs.put(&keys::sidecar(id), bytes.into()).await?;
                received.sidecar = kind.parse().ok();
            }
        }
        Ok::<_, ApiError>((received, params))
    }
    .await;
    let (received, params) = match result {
        Ok(r) => r,
        Err(e) => {
            let _ = state.blobs.delete_prefix(&keys::job_prefix(id)).await;
            return Err(e);
        }
    };
    let sidecar = received.sidecar.map(|s| s.name());
    let idempotency = key.map(|key| Idempotency {
        key,
        request_hash: Fingerprint {
            params: &params,
            cloud: format!("replan:{}", source.id),
            sidecar: sidecar.zip(received.sidecar_sha256.clone()),
            meta: &options.meta,
            callback_url: callback_url.as_deref(),
            georeference: received.georeference.as_ref(),
        }
        .hash(),
    });
    let mut upload = source.upload.clone();
    upload.sidecar = sidecar.map(str::to_string);
    upload.georeference = received.georeference;
    let job = NewJob {
        id,
        tenant,
        params: params.to_json(),
        upload,
        max_attempts: state.config.max_attempts,
        meta: options.meta,
        idempotency,
        replan_of: Some((source.id, source.input_job)),
        callback_url,
    };
    submit::record(&state, job, prior).await
}
