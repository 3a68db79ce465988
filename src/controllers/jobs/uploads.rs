//! Resumable uploads, the tus 1.0 core protocol (<https://tus.io/protocols/resumable-upload>):
//! `POST /v1/uploads` opens a session for `Upload-Length` bytes, each `PATCH` appends at
//! `Upload-Offset`, `HEAD` tells where to resume, and `POST /v1/uploads/{id}/job` turns the
//! complete upload into a job (query as for `POST /v1/jobs`). `DELETE` ends a session.
//!
//! tus rather than parts with offsets: its clients (tus-js-client, Uppy, tus-py-client) already
//! resume after a dropped connection, and an append-only offset leaves nothing to reconcile.
//! Each `PATCH` is kept as one object named by its offset, so any store works (S3 cannot
//! append); bytes that arrived before a connection dropped are kept, as tus expects. The
//! session is blobs only (`uploads/<id>/`); the sweeper removes sessions past their expiry.

use axum::body::Body;
use axum::extract::{Path, Query, Request, State};
use axum::http::header::CONTENT_TYPE;
use axum::http::{HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use futures_util::{stream, StreamExt, TryStreamExt};
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use super::create::{finish_params, queue_full, too_large, Received};
use super::pace::Paced;
use super::sniff::sniff;
use super::submit::{self, Fingerprint, Options};
use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::{ApiError, Code};
use crate::queue::{now_ms, Idempotency, JobId, NewJob, UploadInfo};
use crate::storage::{keys, BlobError, ByteStream};

/// The protocol version spoken, sent on every answer.
const TUS_VERSION: &str = "1.0.0";

/// A session's record.
#[derive(Serialize, Deserialize)]
struct Session {
    tenant: String,
    length: u64,
    expires_ms: i64,
}

fn tus_headers(mut r: Response, offset: Option<u64>, length: u64) -> Response {
    let h = r.headers_mut();
    h.insert("tus-resumable", HeaderValue::from_static(TUS_VERSION));
    h.insert("upload-length", HeaderValue::from(length));
    if let Some(o) = offset {
        h.insert("upload-offset", HeaderValue::from(o));
    }
    h.insert("cache-control", HeaderValue::from_static("no-store"));
    r
}

fn conflict(message: String) -> ApiError {
    ApiError::new(Code::UploadConflict, message)
}

fn number(headers: &HeaderMap, name: &str) -> Result<u64, ApiError> {
    headers
        .get(name)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok())
        .ok_or_else(|| {
            ApiError::new(
                Code::InvalidRequest,
                format!("the `{name}` header must be a whole number of bytes"),
            )
        })
}

fn session_view(id: JobId, s: &Session, offset: u64) -> serde_json::Value {
    serde_json::json!({
        "id": id.to_string(),
        "offset": offset,
        "length": s.length,
        "expires_at": crate::views::timestamp(s.expires_ms),
    })
}

/// The tenant's session (another tenant's, or an expired one, is not found) and its offset.
async fn load(
    state: &AppState,
    tenant: &str,
    raw: &str,
) -> Result<(JobId, Session, u64), ApiError> {
    let id = super::parse_id(raw)?;
    let Some(blob) = state.blobs.get(&keys::upload_session(id)).await? else {
        return Err(ApiError::not_found());
    };
    let bytes: Vec<u8> = blob
        .stream
        .try_fold(Vec::new(), |mut v, c| async move {
            v.extend_from_slice(&c);
            Ok(v)
        })
        .await
        .map_err(ApiError::internal)?;
    let session: Session = serde_json::from_slice(&bytes).map_err(ApiError::internal)?;
    if session.tenant != tenant || session.expires_ms <= now_ms() {
        return Err(ApiError::not_found());
    }
    let offset = offset_of(state, id).await?;
    Ok((id, session, offset))
}

/// The bytes received: the parts, end to end.
async fn offset_of(state: &AppState, id: JobId) -> Result<u64, ApiError> {
    let parts = state.blobs.list(&keys::upload_parts(id)).await?;
    Ok(parts.iter().map(|(_, n)| n).sum())
}

/// `POST /v1/uploads`: opens a session for `Upload-Length` bytes.
pub async fn open(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let Tenant(tenant) = tenant?;
    let length = number(&headers, "upload-length")?;
    if length > state.config.max_upload_bytes {
        return Err(too_large(state.config.max_upload_bytes));
    }
    let id = JobId::new();
    let session = Session {
        tenant,
        length,
        expires_ms: now_ms() + state.config.upload_session_ms(),
    };
    super::put_json(&state, &keys::upload_session(id), &session).await?;
    let r = super::created(session_view(id, &session, 0), format!("/v1/uploads/{id}"))?;
    Ok(tus_headers(r, Some(0), length))
}

/// `HEAD /v1/uploads/{id}`: where to resume.
pub async fn head(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    Path(raw): Path<String>,
) -> Result<Response, ApiError> {
    let Tenant(tenant) = tenant?;
    let (_, session, offset) = load(&state, &tenant, &raw).await?;
    Ok(tus_headers(
        StatusCode::OK.into_response(),
        Some(offset),
        session.length,
    ))
}

/// `GET /v1/uploads/{id}`: the session as JSON (the same facts as `HEAD`).
pub async fn show(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    Path(raw): Path<String>,
) -> Result<Response, ApiError> {
    let Tenant(tenant) = tenant?;
    let (id, session, offset) = load(&state, &tenant, &raw).await?;
    let r = axum::Json(session_view(id, &session, offset)).into_response();
    Ok(tus_headers(r, Some(offset), session.length))
}

/// A body that ends, rather than fails, when the connection drops: what arrived is kept.
fn keep_what_arrived(body: Body, dropped: Arc<AtomicBool>) -> ByteStream<'static> {
    body.into_data_stream()
        .take_while(move |chunk| {
            let ok = chunk.is_ok();
            if !ok {
                dropped.store(true, Ordering::Relaxed);
            }
            std::future::ready(ok)
        })
        .map(|c| c.map_err(std::io::Error::other))
        .boxed()
}

/// `PATCH /v1/uploads/{id}`: appends the body at `Upload-Offset`, which must be the offset
/// `HEAD` reports. The upload time limits apply to each `PATCH`.
pub async fn append(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    Path(raw): Path<String>,
    request: Request,
) -> Result<Response, ApiError> {
    let Tenant(tenant) = tenant?;
    let (id, session, offset) = load(&state, &tenant, &raw).await?;
    let headers = request.headers();
    let media = headers
        .get(CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or_default();
    if media != "application/offset+octet-stream" {
        return Err(ApiError::new(
            Code::InvalidRequest,
            "a PATCH body must be `Content-Type: application/offset+octet-stream`",
        ));
    }
    let at = number(headers, "upload-offset")?;
    if at != offset {
        return Err(conflict(format!(
            "`Upload-Offset` is {at} but the upload has {offset} bytes; HEAD tells where to resume"
        )));
    }
    let config = &state.config;
    let tripped = Arc::new(AtomicBool::new(false));
    let dropped = Arc::new(AtomicBool::new(false));
    let paced = Paced::new(
        request.into_body().into_data_stream(),
        Duration::from_secs(config.upload_idle_timeout_secs),
        config.upload_min_rate,
        tripped.clone(),
    );
    let body = keep_what_arrived(Body::from_stream(paced), dropped.clone());
    let room = session.length - offset;
    let stored = match state
        .blobs
        .put_stream(&keys::upload_part(id, offset), body, room)
        .await
    {
        Ok(s) => s,
        Err(BlobError::TooLarge { .. }) => {
            return Err(conflict(format!(
                "the PATCH goes past `Upload-Length` ({} bytes)",
                session.length
            )))
        }
        Err(e) => return Err(e.into()),
    };
    if stored.bytes == 0 {
        let _ = state
            .blobs
            .delete_prefix(&keys::upload_part(id, offset))
            .await;
    }
    let offset = offset + stored.bytes;
    if tripped.load(Ordering::Relaxed) || dropped.load(Ordering::Relaxed) {
        tracing::info!(upload = %id, offset, "upload PATCH cut short; its bytes are kept");
    }
    Ok(tus_headers(
        StatusCode::NO_CONTENT.into_response(),
        Some(offset),
        session.length,
    ))
}

/// `DELETE /v1/uploads/{id}`: ends the session and removes its bytes (tus termination).
pub async fn remove(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    Path(raw): Path<String>,
) -> Result<Response, ApiError> {
    let Tenant(tenant) = tenant?;
    let (id, _, _) = load(&state, &tenant, &raw).await?;
    state.blobs.delete_prefix(&keys::upload_prefix(id)).await?;
    Ok(StatusCode::NO_CONTENT.into_response())
}

/// `POST /v1/uploads/{id}/job`: a job from the complete upload. The query is that of
/// `POST /v1/jobs`; the parts are copied, end to end, to the job's cloud (sniffed and hashed
/// as any upload), then the session is removed.
pub async fn commit(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    Path(raw): Path<String>,
    Query(pairs): Query<Vec<(String, String)>>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let Tenant(tenant) = tenant?;
    let (upload, session, offset) = load(&state, &tenant, &raw).await?;
    if offset != session.length {
        return Err(conflict(format!(
            "the upload has {offset} of its {} bytes; send the rest first",
            session.length
        )));
    }
    let options = Options::parse(pairs)?;
    let key = submit::idempotency_key(&headers)?;
    let callback_url = submit::callback(&state, &tenant, options.callback_url.clone()).await?;
    let georeference = submit::georeference(options.georeference.clone(), None)?;
    let prior = submit::prior(&state, &tenant, key.as_deref()).await?;
    let cap = state.config.max_queued;
    if prior.is_none() && cap > 0 && state.store.queued_count(&tenant).await? >= cap as u64 {
        return Err(queue_full(cap));
    }
    let (_, params) = finish_params(Received::default(), &options.overrides)?;
    let id = JobId::new();
    let parts = state.blobs.list(&keys::upload_parts(upload)).await?;
    let blobs = state.blobs.clone();
    let whole: ByteStream<'static> = stream::iter(parts)
        .then(move |(key, _)| {
            let blobs = blobs.clone();
            async move {
                match blobs.get(&key).await {
                    Ok(Some(b)) => Ok(b.stream),
                    Ok(None) => Err(std::io::Error::other(format!("{key} went missing"))),
                    Err(e) => Err(std::io::Error::other(e.to_string())),
                }
            }
        })
        .try_flatten()
        .boxed();
    let stored = async {
        let (format, whole) = sniff(whole).await?;
        let stored = state
            .blobs
            .put_stream(&keys::cloud(id), whole, state.config.max_upload_bytes)
            .await?;
        Ok::<_, ApiError>((stored, format))
    }
    .await;
    let (stored, format) = match stored {
        Ok(s) => s,
        Err(e) => {
            let _ = state.blobs.delete_prefix(&keys::job_prefix(id)).await;
            return Err(e);
        }
    };
    let idempotency = key.map(|key| Idempotency {
        key,
        request_hash: Fingerprint {
            params: &params,
            cloud: stored.sha256.clone(),
            sidecar: None,
            meta: &options.meta,
            callback_url: callback_url.as_deref(),
            georeference: georeference.as_ref(),
        }
        .hash(),
    });
    let job = NewJob {
        id,
        tenant,
        params: params.to_json(),
        upload: UploadInfo {
            filename: options.filename,
            bytes: stored.bytes,
            sha256: stored.sha256,
            format: format.to_string(),
            sidecar: None,
            georeference,
        },
        max_attempts: state.config.max_attempts,
        meta: options.meta,
        idempotency,
        replan_of: None,
        callback_url,
    };
    let response = submit::record(&state, job, prior).await?;
    // The job owns its copy now.
    if let Err(e) = state
        .blobs
        .delete_prefix(&keys::upload_prefix(upload))
        .await
    {
        tracing::warn!(upload = %upload, error = %e, "removing a committed upload session");
    }
    Ok(response)
}

/// Removes sessions past their expiry; returns how many (the sweeper calls this).
pub async fn expire(state: &AppState) -> anyhow::Result<usize> {
    let now = now_ms();
    let mut removed = 0;
    for (key, _) in state.blobs.list(keys::UPLOADS).await? {
        let Some(raw) = key.strip_prefix("uploads/") else {
            continue;
        };
        let (raw, direct) = match (
            raw.strip_suffix("/session.json"),
            raw.strip_suffix("/direct.json"),
        ) {
            (Some(raw), _) => (raw, false),
            (_, Some(raw)) => (raw, true),
            _ => continue,
        };
        let Ok(id) = raw.parse::<JobId>() else {
            continue;
        };
        let Some(blob) = state.blobs.get(&key).await? else {
            continue;
        };
        let bytes: Vec<u8> = blob
            .stream
            .try_fold(Vec::new(), |mut v, c| async move {
                v.extend_from_slice(&c);
                Ok(v)
            })
            .await?;
        if direct {
            removed += usize::from(super::direct::expire_one(state, id, &bytes, now).await);
            continue;
        }
        let expired =
            serde_json::from_slice::<Session>(&bytes).map_or(true, |s| s.expires_ms <= now);
        if expired {
            state.blobs.delete_prefix(&keys::upload_prefix(id)).await?;
            tracing::info!(upload = %id, "upload session expired; its bytes were removed");
            removed += 1;
        }
    }
    Ok(removed)
}
