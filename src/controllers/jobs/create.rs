//! `POST /v1/jobs`: stream the cloud to storage and queue a job.
//!
//! Two bodies are accepted:
//! - raw: the cloud itself; parameters as `section.name=value` query pairs, plus `filename`;
//! - `multipart/form-data`: a `cloud` part, an optional `poses` or `trajectory` part, an
//!   optional `params` part (JSON or TOML), and an optional `georeference` part (JSON); query
//!   parameters apply on top.
//!
//! The cloud never sits whole in memory. On any refusal, whatever was stored is deleted.

use asbuilt_plan::io::poses;
use asbuilt_plan::params::ParamsError;
use asbuilt_plan::Params;
use axum::body::Body;
use axum::extract::multipart::{Field, MultipartError};
use axum::extract::rejection::QueryRejection;
use axum::extract::{FromRequest, Multipart, Query, Request, State};
use axum::http::header::{CONTENT_LENGTH, CONTENT_TYPE, EXPECT};
use axum::http::StatusCode;
use axum::response::Response;
use bytes::Bytes;
use futures_util::{StreamExt, TryStreamExt};

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use super::drain;
use super::pace::Paced;
use super::sniff::sniff;
use super::submit::{self, clean_filename, Fingerprint, Options};
use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::{ApiError, Code};
use crate::queue::{Idempotency, JobId, NewJob, UploadInfo};
use crate::storage::{keys, BlobError, ByteStream, Stored};
use crate::worker::pipeline::SidecarKind;

/// What a request body delivered.
#[derive(Default)]
pub struct Received {
    pub cloud: Option<(Stored, &'static str)>,
    pub filename: Option<String>,
    pub sidecar: Option<SidecarKind>,
    /// The sidecar's SHA-256, as stored.
    pub sidecar_sha256: Option<String>,
    pub params: Option<Params>,
    /// The `georeference` part, checked.
    pub georeference: Option<asbuilt_plan::georef::Georeference>,
}

pub async fn create(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    query: Result<Query<Vec<(String, String)>>, QueryRejection>,
    request: Request,
) -> Result<Response, ApiError> {
    let expects_continue = request
        .headers()
        .get(EXPECT)
        .is_some_and(|v| v.as_bytes().eq_ignore_ascii_case(b"100-continue"));
    let (parts, body) = request.into_parts();
    // Every read of the body, raw or multipart, goes through the time limits.
    let tripped = Arc::new(AtomicBool::new(false));
    let config = &state.config;
    let body = Body::from_stream(Paced::new(
        body.into_data_stream(),
        Duration::from_secs(config.upload_idle_timeout_secs),
        config.upload_min_rate,
        tripped.clone(),
    ));
    let (body, rest) = drain::split(body);
    let request = Request::from_parts(parts, body);
    let mut result = match tenant {
        Ok(Tenant(tenant)) => accept(&state, tenant, query, request).await,
        Err(e) => {
            drop(request);
            Err(e)
        }
    };
    if tripped.load(Ordering::Relaxed) {
        // Whatever the reader made of the timeout, the answer is the timeout.
        tracing::info!("upload dropped: too slow or stalled");
        result = Err(ApiError::new(
            Code::UploadTimeout,
            format!(
                "the upload stalled or was slower than this server's limits (nothing for {} s, \
                 or under {} bytes/s on average); nothing was kept",
                config.upload_idle_timeout_secs, config.upload_min_rate
            ),
        ));
    }
    if let Err(e) = &result {
        state.metrics.rejected(e.code.as_str());
        // The request (and its body) is gone; read what the client is still sending.
        rest.drain(expects_continue, drain::BUDGET).await;
    }
    result
}

async fn accept(
    state: &AppState,
    tenant: String,
    query: Result<Query<Vec<(String, String)>>, QueryRejection>,
    request: Request,
) -> Result<Response, ApiError> {
    if state.shutdown.is_cancelled() {
        return Err(ApiError::new(
            Code::Unavailable,
            "the server is shutting down",
        ));
    }
    let Query(pairs) = query.map_err(|e| ApiError::new(Code::InvalidRequest, e.body_text()))?;
    // The query (parameters, metadata) and the key are checked before a byte is stored.
    let options = Options::parse(pairs)?;
    let key = submit::idempotency_key(request.headers())?;
    let callback_url = submit::callback(state, &tenant, options.callback_url.clone()).await?;
    submit::georeference(options.georeference.clone(), None)?;
    let prior = submit::prior(state, &tenant, key.as_deref()).await?;
    // A tenant at its cap of queued jobs is told before it uploads (and again, atomically,
    // when the job is created); a retry of a job already made is not a new job.
    let cap = state.config.max_queued;
    if prior.is_none() && cap > 0 && state.store.queued_count(&tenant).await? >= cap as u64 {
        return Err(queue_full(cap));
    }
    let multipart = is_multipart(&request);
    let declared = request
        .headers()
        .get(CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    let limit = state.config.max_upload_bytes;
    let slack = if multipart {
        2 * state.config.max_sidecar_bytes + (1 << 20)
    } else {
        0
    };
    if declared.is_some_and(|n| n > limit.saturating_add(slack)) {
        return Err(too_large(limit));
    }

    let id = JobId::new();
    let received = if multipart {
        receive_multipart(state, id, request, true).await
    } else {
        receive_raw(state, id, request.into_body(), declared)
            .await
            .map(|cloud| Received {
                cloud: Some(cloud),
                ..Default::default()
            })
    };
    let received = received
        .and_then(|r| finish_params(r, &options.overrides))
        .and_then(|(mut r, params)| {
            r.georeference = submit::georeference(options.georeference.clone(), r.georeference)?;
            Ok((r, params))
        });
    let received = match received {
        Ok(r) => r,
        Err(e) => {
            state.early.forget(id);
            if let Err(d) = state.blobs.delete_prefix(&keys::job_prefix(id)).await {
                tracing::error!(job = %id, error = %d, "removing a refused upload");
            }
            return Err(e);
        }
    };
    let (received, params) = received;
    let Some((stored, format)) = received.cloud else {
        let _ = state.blobs.delete_prefix(&keys::job_prefix(id)).await;
        return Err(ApiError::new(
            Code::MissingCloud,
            "the request has no `cloud` part",
        ));
    };
    let sidecar = received.sidecar.map(|s| s.name());
    let idempotency = key.map(|key| Idempotency {
        key,
        request_hash: Fingerprint {
            params: &params,
            cloud: stored.sha256.clone(),
            sidecar: sidecar.zip(received.sidecar_sha256.clone()),
            meta: &options.meta,
            callback_url: callback_url.as_deref(),
            georeference: received.georeference.as_ref(),
        }
        .hash(),
    });
    let job = NewJob {
        id,
        tenant,
        params: params.to_json(),
        upload: UploadInfo {
            filename: received.filename.or(options.filename),
            bytes: stored.bytes,
            sha256: stored.sha256,
            format: format.to_string(),
            sidecar: sidecar.map(str::to_string),
            georeference: received.georeference,
        },
        max_attempts: state.config.max_attempts,
        meta: options.meta,
        idempotency,
        replan_of: None,
        callback_url,
    };
    submit::record(state, job, prior).await
}

/// True for a `multipart/form-data` body.
pub fn is_multipart(request: &Request) -> bool {
    request
        .headers()
        .get(CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|t| t.to_ascii_lowercase().starts_with("multipart/form-data"))
}

/// The part's parameters (if any), then the query's overrides.
pub fn finish_params(r: Received, overrides: &[String]) -> Result<(Received, Params), ApiError> {
    finish_params_from(r, overrides, Params::default())
}

/// The part's parameters, else `base`; then the query's overrides; then the range checks.
pub fn finish_params_from(
    r: Received,
    overrides: &[String],
    base: Params,
) -> Result<(Received, Params), ApiError> {
    let mut params = r.params.clone().unwrap_or(base);
    for o in overrides {
        let key = o.split('=').next().unwrap_or_default();
        params.set(o).map_err(|e| params_error(&e, Some(key)))?;
    }
    // Values out of range are refused now, not by a failed job later.
    params.check().map_err(|e| params_error(&e, None))?;
    Ok((r, params))
}

/// How long a tenant at its cap is asked to wait: about one job's time is a guess, so a short
/// fixed pause that polling clients can live with.
const QUEUE_FULL_RETRY_SECS: u64 = 10;

pub fn queue_full(cap: u32) -> ApiError {
    ApiError::new(
        Code::QueueFull,
        format!("this API key already has {cap} queued jobs, the most this server allows; wait for some to start"),
    )
    .retry_after(QUEUE_FULL_RETRY_SECS)
}

pub fn too_large(limit: u64) -> ApiError {
    ApiError::new(
        Code::PayloadTooLarge,
        format!("the upload is larger than this server's limit of {limit} bytes"),
    )
}

fn blob_error(e: BlobError) -> ApiError {
    match e {
        BlobError::TooLarge { limit } => too_large(limit),
        BlobError::Source(e) => ApiError::new(
            Code::InvalidRequest,
            format!("the upload was interrupted: {e}"),
        ),
        e => ApiError::internal(e),
    }
}

/// `invalid_parameter`, naming the parameter (from the error when it knows it better).
pub fn params_error(e: &ParamsError, key: Option<&str>) -> ApiError {
    let name = match e {
        ParamsError::Unknown(n) | ParamsError::Invalid { name: n, .. } => Some(n.clone()),
        ParamsError::Syntax(s) => Some(s.clone()),
        // serde names the field between backticks.
        ParamsError::File(m) => m.split('`').nth(1).map(str::to_string),
    };
    ApiError::param(
        name.or(key.map(str::to_string))
            .unwrap_or_else(|| "params".into()),
        e.to_string(),
    )
}

/// A raw body of a declared length is also read as it arrives (`worker::early`), so the job's
/// worker may find its points decoded.
async fn receive_raw(
    state: &AppState,
    id: JobId,
    body: Body,
    declared: Option<u64>,
) -> Result<(Stored, &'static str), ApiError> {
    let stream: ByteStream<'static> = body
        .into_data_stream()
        .map_err(std::io::Error::other)
        .boxed();
    let (format, stream) = sniff(stream).await?;
    let Some(feed) = state.early.begin(id, format, declared) else {
        return store_sniffed(state, id, format, stream).await;
    };
    let feed = Arc::new(feed);
    let tap = feed.clone();
    let stream = stream.inspect_ok(move |chunk| tap.push(chunk)).boxed();
    let stored = store_sniffed(state, id, format, stream).await?;
    // The stream (and its clone of the feed) is gone once stored.
    if let Ok(feed) = Arc::try_unwrap(feed) {
        feed.finish(stored.0.bytes);
    }
    Ok(stored)
}

async fn store_sniffed(
    state: &AppState,
    id: JobId,
    format: &'static str,
    stream: ByteStream<'_>,
) -> Result<(Stored, &'static str), ApiError> {
    let stored = state
        .blobs
        .put_stream(&keys::cloud(id), stream, state.config.max_upload_bytes)
        .await
        .map_err(blob_error)?;
    Ok((stored, format))
}

fn multipart_error(e: MultipartError) -> ApiError {
    if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
        return ApiError::new(Code::PayloadTooLarge, e.body_text());
    }
    ApiError::new(Code::InvalidMultipart, e.body_text())
}

/// Reads a small part whole, refusing it past `limit` bytes.
async fn read_small(mut field: Field<'_>, name: &str, limit: u64) -> Result<Bytes, ApiError> {
    let mut buf = Vec::new();
    while let Some(chunk) = field.chunk().await.map_err(multipart_error)? {
        if (buf.len() + chunk.len()) as u64 > limit {
            return Err(ApiError::new(
                Code::PayloadTooLarge,
                format!("the `{name}` part is larger than the limit of {limit} bytes"),
            ));
        }
        buf.extend_from_slice(&chunk);
    }
    Ok(buf.into())
}

/// Parses a sidecar as the pipeline will, so a bad one is refused now (naming the entry and
/// field at fault), not by a failed job after the whole cloud is stored.
pub fn check_sidecar(kind: SidecarKind, bytes: &[u8]) -> Result<(), ApiError> {
    let name = kind.name();
    let text = std::str::from_utf8(bytes).map_err(|_| {
        ApiError::new(
            Code::InvalidSidecar,
            format!("the `{name}` part is not UTF-8 JSON text"),
        )
    })?;
    let parsed = match kind {
        SidecarKind::Poses => poses::parse_poses(text).map(drop),
        SidecarKind::Trajectory => poses::parse_trajectory(text).map(drop),
    };
    parsed.map_err(|e| ApiError::new(Code::InvalidSidecar, format!("the `{name}` part: {e}")))
}

/// An E57 carries a pose per scan and takes no sidecar (`docs/contract.md` §2): sending one
/// is a mistake the client hears about at once, not a job that plans with the wrong poses.
pub fn refuse_e57_sidecar(format: &str, kind: SidecarKind) -> Result<(), ApiError> {
    if format != "e57" {
        return Ok(());
    }
    Err(ApiError::new(
        Code::InvalidSidecar,
        format!(
            "an E57 file carries its own scan poses, so no sidecar is needed \
             (docs/contract.md §2); send the E57 without the `{}` part",
            kind.name()
        ),
    ))
}

/// A `georeference` part: a JSON object of the georeference's fields, checked now so a bad
/// one is refused before the cloud is kept.
pub fn parse_georeference(bytes: &[u8]) -> Result<asbuilt_plan::georef::Georeference, ApiError> {
    let g: asbuilt_plan::georef::Georeference = serde_json::from_slice(bytes).map_err(|e| {
        ApiError::param(
            "georeference",
            format!("the `georeference` part is not a georeference object: {e}"),
        )
    })?;
    submit::georeference(None, Some(g.clone()))?;
    Ok(g)
}

/// Reads a multipart body: the cloud (only when `with_cloud`; a re-plan has its upload), a
/// pose or trajectory sidecar, and parameters.
pub async fn receive_multipart(
    state: &AppState,
    id: JobId,
    request: Request,
    with_cloud: bool,
) -> Result<Received, ApiError> {
    let mut form = Multipart::from_request(request, state)
        .await
        .map_err(|e| ApiError::new(Code::InvalidMultipart, e.body_text()))?;
    let mut got = Received::default();
    let small = state.config.max_sidecar_bytes;
    while let Some(field) = form.next_field().await.map_err(multipart_error)? {
        let name = field.name().unwrap_or_default().to_string();
        match name.as_str() {
            "cloud" if !with_cloud => {
                return Err(ApiError::new(
                    Code::InvalidMultipart,
                    "a re-plan reads the job's stored upload: send no `cloud` part",
                ))
            }
            "cloud" => {
                if got.cloud.is_some() {
                    return Err(ApiError::new(
                        Code::InvalidMultipart,
                        "more than one `cloud` part",
                    ));
                }
                got.filename = field.file_name().map(clean_filename);
                let stream = field.map_err(std::io::Error::other).boxed();
                let (format, stream) = sniff(stream).await?;
                // A sidecar that came first is checked against the format before a byte is kept.
                if let Some(kind) = got.sidecar {
                    refuse_e57_sidecar(format, kind)?;
                }
                got.cloud = Some(store_sniffed(state, id, format, stream).await?);
            }
            "poses" | "trajectory" => {
                if got.sidecar.is_some() {
                    return Err(ApiError::new(
                        Code::InvalidMultipart,
                        "send one `poses` or `trajectory` part, not several",
                    ));
                }
                let kind: SidecarKind = name.parse().map_err(ApiError::internal)?;
                // The cloud, when it came first, is already stored: the caller removes it.
                if let Some((_, format)) = &got.cloud {
                    refuse_e57_sidecar(format, kind)?;
                }
                let bytes = read_small(field, &name, small).await?;
                check_sidecar(kind, &bytes)?;
                let stored = state
                    .blobs
                    .put(&keys::sidecar(id), bytes)
                    .await
                    .map_err(blob_error)?;
                got.sidecar = Some(kind);
                got.sidecar_sha256 = Some(stored.sha256);
            }
            "params" => {
                let bytes = read_small(field, &name, small).await?;
                let text = std::str::from_utf8(&bytes).map_err(|_| {
                    ApiError::param("params", "the `params` part is not UTF-8 text")
                })?;
                let params = Params::from_file_text(text).map_err(|e| params_error(&e, None))?;
                got.params = Some(params);
            }
            "georeference" => {
                if got.georeference.is_some() {
                    return Err(ApiError::new(
                        Code::InvalidMultipart,
                        "more than one `georeference` part",
                    ));
                }
                let bytes = read_small(field, &name, small).await?;
                got.georeference = Some(parse_georeference(&bytes)?);
            }
            other => {
                return Err(ApiError::new(
                    Code::InvalidMultipart,
                    format!(
                        "unknown part `{}`; send cloud, poses or trajectory, params, and \
                         georeference",
                        clean_filename(other)
                    ),
                ))
            }
        }
    }
    Ok(got)
}
