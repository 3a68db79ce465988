//! Direct uploads: with S3 storage, the client sends the cloud straight to the bucket through
//! pre-signed multipart URLs, then makes the job, so a multi-GB scan never passes through the
//! API server.
//!
//! `POST /v1/direct-uploads` (`{"length", "part_size"?}`) starts an S3 multipart upload to
//! the future job's cloud key and answers a pre-signed `PUT` URL per part; the client sends
//! each part (in any order, several at once, again after a failure) and keeps each answer's
//! `ETag`; `POST /v1/direct-uploads/{id}/job` with the ETags joins the parts and makes the job
//! (query as for `POST /v1/jobs`). The server reads the object once to check its format and
//! hash it. `GET` answers the upload with fresh URLs, `DELETE` abandons it. With a local
//! directory for storage every call answers `501 needs_s3`.
//!
//! The record is `uploads/<id>/direct.json`; the sweeper aborts uploads past their expiry, so
//! the store drops their parts.

use axum::body::Bytes;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use futures_util::{StreamExt, TryStreamExt};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::create::{finish_params, queue_full, too_large, Received};
use super::sniff::sniff;
use super::submit::{self, Fingerprint, Options};
use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::{ApiError, Code};
use crate::queue::{now_ms, Idempotency, JobId, NewJob, UploadInfo};
use crate::storage::{keys, DirectUploads};

/// S3's limits: every part but the last at least 5 MiB, at most 5 GiB, at most 10,000 parts.
const MIN_PART: u64 = 5 << 20;
const MAX_PART: u64 = 5 << 30;
const MAX_PARTS: u64 = 10_000;
/// The part size when the client names none: 64 MiB, or larger to stay within 10,000 parts.
const DEFAULT_PART: u64 = 64 << 20;
/// SigV4 pre-signed URLs live at most a week.
const MAX_URL_SECS: u64 = 7 * 24 * 3600;

/// An upload's record.
#[derive(Serialize, Deserialize)]
struct Record {
    tenant: String,
    length: u64,
    part_size: u64,
    /// The store's multipart upload id.
    upload_id: String,
    expires_ms: i64,
}

impl Record {
    fn parts(&self) -> u64 {
        self.length.div_ceil(self.part_size)
    }
}

/// `POST /v1/direct-uploads`' body.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Open {
    length: u64,
    #[serde(default)]
    part_size: Option<u64>,
}

/// `POST /v1/direct-uploads/{id}/job`'s body: each part's `ETag`, as the store answered.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Commit {
    parts: Vec<Part>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Part {
    number: u64,
    etag: String,
}

pub fn needs_s3() -> ApiError {
    ApiError::new(
        Code::NeedsS3,
        "pre-signed uploads go straight to S3 storage, and this server keeps its blobs in a \
         local directory (it would need `--storage s3://BUCKET/PREFIX`); upload with POST \
         /v1/uploads (tus, resumable) or POST /v1/jobs instead",
    )
}

fn direct(state: &AppState) -> Result<&dyn DirectUploads, ApiError> {
    state.blobs.direct().ok_or_else(needs_s3)
}

fn json_body<T: serde::de::DeserializeOwned>(body: &Bytes, shape: &str) -> Result<T, ApiError> {
    serde_json::from_slice(body).map_err(|e| {
        ApiError::new(
            Code::InvalidRequest,
            format!("the body must be JSON {shape}: {e}"),
        )
    })
}

/// The upload as answered: its parts, each with a URL valid until the upload expires (at most
/// a week).
async fn view(
    direct: &dyn DirectUploads,
    id: JobId,
    r: &Record,
) -> Result<serde_json::Value, ApiError> {
    let left_ms = (r.expires_ms - now_ms()).max(1000) as u64;
    let valid = std::time::Duration::from_secs((left_ms / 1000).clamp(1, MAX_URL_SECS));
    let key = keys::cloud(id);
    let mut parts = Vec::with_capacity(r.parts() as usize);
    for n in 1..=r.parts() {
        let offset = (n - 1) * r.part_size;
        let url = direct.part_url(&key, &r.upload_id, n as u32, valid).await?;
        parts.push(serde_json::json!({
            "number": n,
            "offset": offset,
            "length": r.part_size.min(r.length - offset),
            "url": url,
        }));
    }
    let urls_expire = now_ms() + valid.as_millis() as i64;
    Ok(serde_json::json!({
        "id": id.to_string(),
        "length": r.length,
        "part_size": r.part_size,
        "parts": parts,
        "expires_at": crate::views::timestamp(r.expires_ms),
        "urls_expire_at": crate::views::timestamp(urls_expire.min(r.expires_ms)),
        "job": format!("/v1/direct-uploads/{id}/job"),
    }))
}

async fn load(state: &AppState, tenant: &str, raw: &str) -> Result<(JobId, Record), ApiError> {
    let id = super::parse_id(raw)?;
    let Some(blob) = state.blobs.get(&keys::direct_upload(id)).await? else {
        return Err(ApiError::not_found());
    };
    let bytes: Vec<u8> = blob
        .stream
        .map_ok(|b| b.to_vec())
        .try_concat()
        .await
        .map_err(ApiError::internal)?;
    let record: Record = serde_json::from_slice(&bytes).map_err(ApiError::internal)?;
    if record.tenant != tenant || record.expires_ms <= now_ms() {
        return Err(ApiError::not_found());
    }
    Ok((id, record))
}

/// `POST /v1/direct-uploads`: starts an upload of `length` bytes.
pub async fn open(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let Tenant(tenant) = tenant?;
    let direct = direct(&state)?;
    let req: Open = json_body(&body, r#"{"length": BYTES, "part_size": BYTES}"#)?;
    if req.length == 0 {
        return Err(ApiError::param("length", "a cloud of at least 1 byte"));
    }
    if req.length > state.config.max_upload_bytes {
        return Err(too_large(state.config.max_upload_bytes));
    }
    let part_size = req
        .part_size
        .unwrap_or_else(|| DEFAULT_PART.max(req.length.div_ceil(MAX_PARTS)));
    if !(MIN_PART..=MAX_PART).contains(&part_size) {
        return Err(ApiError::param(
            "part_size",
            format!("S3 takes parts of {MIN_PART} to {MAX_PART} bytes (the last may be smaller)"),
        ));
    }
    if req.length.div_ceil(part_size) > MAX_PARTS {
        return Err(ApiError::param(
            "part_size",
            format!(
                "S3 takes at most {MAX_PARTS} parts: at least {} bytes a part for this length",
                req.length.div_ceil(MAX_PARTS)
            ),
        ));
    }
    let id = JobId::new();
    let upload_id = direct.start(&keys::cloud(id)).await?;
    let record = Record {
        tenant,
        length: req.length,
        part_size,
        upload_id,
        expires_ms: now_ms() + state.config.upload_session_ms(),
    };
    super::put_json(&state, &keys::direct_upload(id), &record).await?;
    let body = view(direct, id, &record).await?;
    super::created(body, format!("/v1/direct-uploads/{id}"))
}

/// `GET /v1/direct-uploads/{id}`: the upload, with fresh URLs.
pub async fn show(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    Path(raw): Path<String>,
) -> Result<Response, ApiError> {
    let Tenant(tenant) = tenant?;
    let direct = direct(&state)?;
    let (id, record) = load(&state, &tenant, &raw).await?;
    Ok(axum::Json(view(direct, id, &record).await?).into_response())
}

/// `DELETE /v1/direct-uploads/{id}`: abandons the upload; the store drops its parts.
pub async fn remove(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    Path(raw): Path<String>,
) -> Result<Response, ApiError> {
    let Tenant(tenant) = tenant?;
    let direct = direct(&state)?;
    let (id, record) = load(&state, &tenant, &raw).await?;
    abandon(&state, direct, id, &record).await;
    Ok(StatusCode::NO_CONTENT.into_response())
}

async fn abandon(state: &AppState, direct: &dyn DirectUploads, id: JobId, r: &Record) {
    if let Err(e) = direct.abort(&keys::cloud(id), &r.upload_id).await {
        tracing::warn!(upload = %id, error = %e, "aborting a direct upload");
    }
    if let Err(e) = state.blobs.delete_prefix(&keys::upload_prefix(id)).await {
        tracing::warn!(upload = %id, error = %e, "removing a direct upload's record");
    }
}

/// The ETags of parts 1 to `parts`, in order, each given once.
fn etags(commit: Commit, parts: u64) -> Result<Vec<String>, ApiError> {
    let mut given = commit.parts;
    given.sort_by_key(|p| p.number);
    let numbers: Vec<u64> = given.iter().map(|p| p.number).collect();
    if numbers != (1..=parts).collect::<Vec<_>>() {
        return Err(ApiError::new(
            Code::UploadConflict,
            format!("the upload has parts 1 to {parts}: give each one's `ETag` once"),
        ));
    }
    given
        .into_iter()
        .map(|p| {
            let ok = !p.etag.is_empty()
                && p.etag.len() <= 200
                && p.etag.bytes().all(|b| b.is_ascii_graphic());
            match ok {
                true => Ok(p.etag),
                false => Err(ApiError::param(
                    "etag",
                    format!("part {}: the ETag header the store answered", p.number),
                )),
            }
        })
        .collect()
}

/// `POST /v1/direct-uploads/{id}/job`: joins the parts and makes the job (the query of
/// `POST /v1/jobs`). The job's id is the upload's.
pub async fn commit(
    State(state): State<AppState>,
    tenant: Result<Tenant, ApiError>,
    Path(raw): Path<String>,
    Query(pairs): Query<Vec<(String, String)>>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, ApiError> {
    let Tenant(tenant) = tenant?;
    let direct = direct(&state)?;
    let options = Options::parse(pairs)?;
    let key = submit::idempotency_key(&headers)?;
    let callback_url = submit::callback(&state, &tenant, options.callback_url.clone()).await?;
    let georeference = submit::georeference(options.georeference.clone(), None)?;
    let (_, params) = finish_params(Received::default(), &options.overrides)?;
    let fingerprint = |params| {
        key.clone().map(|key| Idempotency {
            key,
            request_hash: Fingerprint {
                params,
                cloud: format!("direct:{raw}"),
                sidecar: None,
                meta: &options.meta,
                callback_url: callback_url.as_deref(),
                georeference: georeference.as_ref(),
            }
            .hash(),
        })
    };
    // A retry of a commit that made its job answers that job, though the upload is used up.
    if let Some(first) = submit::prior(&state, &tenant, key.as_deref()).await? {
        return submit::replay(&state, first, fingerprint(&params).as_ref());
    }
    let (id, record) = load(&state, &tenant, &raw).await?;
    let commit: Commit = json_body(&body, r#"{"parts": [{"number": 1, "etag": "..."}]}"#)?;
    let etags = etags(commit, record.parts())?;
    let cap = state.config.max_queued;
    if cap > 0 && state.store.queued_count(&tenant).await? >= cap as u64 {
        return Err(queue_full(cap));
    }
    let cloud = keys::cloud(id);
    if let Err(e) = direct.complete(&cloud, &record.upload_id, etags).await {
        // Parts missing or not as the ETags say: the client may send them and try again.
        return Err(ApiError::new(
            Code::UploadConflict,
            format!("the store did not join the parts (a part missing, too small, or not the one its ETag names): {e}"),
        ));
    }
    // The parts are one object now; whatever happens next, the upload is used up.
    let checked = check_object(&state, &cloud, record.length).await;
    let _ = state
        .blobs
        .delete_prefix(&keys::upload_prefix(id))
        .await
        .map_err(|e| tracing::warn!(upload = %id, error = %e, "removing a direct upload's record"));
    let (bytes, sha256, format) = match checked {
        Ok(c) => c,
        Err(e) => {
            let _ = state.blobs.delete_prefix(&keys::job_prefix(id)).await;
            return Err(e);
        }
    };
    let job = NewJob {
        id,
        tenant,
        params: params.to_json(),
        upload: UploadInfo {
            filename: options.filename.clone(),
            bytes,
            sha256,
            format: format.to_string(),
            sidecar: None,
            georeference: georeference.clone(),
        },
        max_attempts: state.config.max_attempts,
        meta: options.meta.clone(),
        idempotency: fingerprint(&params),
        replan_of: None,
        callback_url: callback_url.clone(),
    };
    submit::record(&state, job, None).await
}

/// Reads the joined object once: its length must be the one announced, its format one we
/// read; its SHA-256, as every upload has.
async fn check_object(
    state: &AppState,
    key: &str,
    length: u64,
) -> Result<(u64, String, &'static str), ApiError> {
    let blob = state
        .blobs
        .get(key)
        .await?
        .ok_or_else(|| ApiError::internal("a joined upload is not in the store"))?;
    if blob.size != length {
        return Err(ApiError::new(
            Code::UploadConflict,
            format!(
                "the parts make {} bytes, not the {length} announced",
                blob.size
            ),
        ));
    }
    let (format, mut stream) = sniff(blob.stream).await?;
    let mut hasher = Sha256::new();
    let mut bytes = 0u64;
    while let Some(chunk) = stream.next().await {
        let chunk = chunk.map_err(ApiError::internal)?;
        bytes += chunk.len() as u64;
        hasher.update(&chunk);
    }
    let sha = hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    Ok((bytes, sha, format))
}

/// Aborts the upload of the record at `key` when it is past its expiry; true when it did
/// (the sweeper calls this through `uploads::expire`).
pub async fn expire_one(state: &AppState, id: JobId, bytes: &[u8], now: i64) -> bool {
    let Ok(record) = serde_json::from_slice::<Record>(bytes) else {
        let _ = state.blobs.delete_prefix(&keys::upload_prefix(id)).await;
        return true;
    };
    if record.expires_ms > now {
        return false;
    }
    match state.blobs.direct() {
        Some(direct) => abandon(state, direct, id, &record).await,
        None => {
            let _ = state.blobs.delete_prefix(&keys::upload_prefix(id)).await;
        }
    }
    tracing::info!(upload = %id, "direct upload expired; the store dropped its parts");
    true
}
