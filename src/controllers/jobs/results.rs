//! `GET /v1/jobs/{id}/{file}`: the results of `asbuilt_plan::io::outputs::OUTPUTS`, streamed
//! from storage.
//!
//! A result never changes once its job succeeded, so it carries a strong `ETag` (of the job,
//! its end and the file) and answers `If-None-Match` with `304`; a single `Range` of bytes is
//! answered with `206` (with `If-Range`, only while the `ETag` still matches). The router
//! gzips whole results for clients that accept it, tagging them `"TAG-gzip"`.

use axum::body::Body;
use axum::extract::{Path, State};
use axum::http::header::{
    ACCEPT_RANGES, CONTENT_DISPOSITION, CONTENT_LENGTH, CONTENT_RANGE, CONTENT_TYPE, ETAG,
    IF_NONE_MATCH, IF_RANGE, RANGE,
};
use axum::http::{HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};

use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::{ApiError, Code};
use crate::queue::{Job, JobStatus};
use crate::storage::keys;

/// The result's entity tag: the same bytes always have the same tag, and no two results share
/// one.
fn etag(job: &Job, name: &str) -> String {
    let seed = format!("{}/{}/{name}", job.id, job.finished_at.unwrap_or_default());
    let hex: String = Sha256::digest(seed.as_bytes())[..12]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    format!("\"{hex}\"")
}

/// True when `If-None-Match` names `tag` (or its gzipped form, or is `*`): the client's copy
/// is current.
fn none_match(headers: &HeaderMap, tag: &str) -> bool {
    let gzipped = format!("{}-gzip\"", tag.trim_end_matches('"'));
    headers.get_all(IF_NONE_MATCH).iter().any(|v| {
        v.to_str().is_ok_and(|v| {
            v.split(',')
                .map(|t| t.trim().trim_start_matches("W/"))
                .any(|t| t == "*" || t == tag || t == gzipped)
        })
    })
}

/// What a `Range` header asks for.
#[derive(Debug, PartialEq, Eq)]
enum Wanted {
    Whole,
    Part(u64, u64),
    Unsatisfiable,
}

/// Reads `bytes=A-B`, `bytes=A-` or `bytes=-N` against an object of `size` bytes. Anything
/// else (several ranges, other units, garbage) is ignored and the whole object served, as
/// RFC 9110 allows.
fn wanted(header: Option<&str>, size: u64) -> Wanted {
    let Some(spec) = header.and_then(|h| h.trim().strip_prefix("bytes=")) else {
        return Wanted::Whole;
    };
    if spec.contains(',') {
        return Wanted::Whole;
    }
    let Some((a, b)) = spec.trim().split_once('-') else {
        return Wanted::Whole;
    };
    let (a, b) = (a.trim(), b.trim());
    let range = match (a.parse::<u64>(), b.parse::<u64>()) {
        (Ok(first), Ok(last)) if first <= last => (first, last.min(size.saturating_sub(1))),
        (Ok(first), Err(_)) if b.is_empty() => (first, size.saturating_sub(1)),
        (Err(_), Ok(n)) if a.is_empty() => {
            if n == 0 {
                return Wanted::Unsatisfiable;
            }
            (size.saturating_sub(n), size.saturating_sub(1))
        }
        _ => return Wanted::Whole,
    };
    if size == 0 || range.0 >= size {
        return Wanted::Unsatisfiable;
    }
    Wanted::Part(range.0, range.1)
}

async fn result(
    state: AppState,
    tenant: String,
    id: String,
    name: &str,
    headers: HeaderMap,
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
    let tag = etag(&job, name);
    if none_match(&headers, &tag) {
        return Ok((StatusCode::NOT_MODIFIED, [(ETAG, tag)]).into_response());
    }
    let missing = || ApiError::internal(format!("job {} succeeded but {name} is missing", job.id));
    let disposition = format!("inline; filename=\"{}-{name}\"", job.id);
    // `If-Range` with another tag: the client's part is stale, so it gets the whole file.
    let if_range_ok = headers
        .get(IF_RANGE)
        .is_none_or(|v| v.to_str().is_ok_and(|v| v.trim() == tag));
    let range = headers.get(RANGE).and_then(|v| v.to_str().ok());
    if range.is_some() && if_range_ok {
        let size = state.blobs.size(&key).await?.ok_or_else(missing)?;
        match wanted(range, size) {
            Wanted::Whole => {}
            Wanted::Unsatisfiable => {
                let mut r = ApiError::new(
                    Code::RangeNotSatisfiable,
                    format!("{name} has {size} bytes; ask for a range within them"),
                )
                .into_response();
                let value = HeaderValue::from_str(&format!("bytes */{size}")).expect("ascii");
                r.headers_mut().insert(CONTENT_RANGE, value);
                return Ok(r);
            }
            Wanted::Part(first, last) => {
                let (blob, total) = state
                    .blobs
                    .get_part(&key, first..last + 1)
                    .await?
                    .ok_or_else(missing)?;
                return Ok((
                    StatusCode::PARTIAL_CONTENT,
                    [
                        (CONTENT_TYPE, media.to_string()),
                        (CONTENT_LENGTH, blob.size.to_string()),
                        (CONTENT_RANGE, format!("bytes {first}-{last}/{total}")),
                        (CONTENT_DISPOSITION, disposition),
                        (ETAG, tag),
                        (ACCEPT_RANGES, "bytes".to_string()),
                    ],
                    Body::from_stream(blob.stream),
                )
                    .into_response());
            }
        }
    }
    let blob = state.blobs.get(&key).await?.ok_or_else(missing)?;
    Ok((
        [
            (CONTENT_TYPE, media.to_string()),
            (CONTENT_LENGTH, blob.size.to_string()),
            (CONTENT_DISPOSITION, disposition),
            (ETAG, tag),
            (ACCEPT_RANGES, "bytes".to_string()),
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
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let Some(output) = asbuilt_plan::io::outputs::by_file(&file) else {
        return Err(ApiError::new(Code::RouteNotFound, "no such endpoint"));
    };
    result(s, t, id, output.file, headers).await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_are_read_as_rfc_9110_says() {
        use Wanted::*;
        assert_eq!(wanted(None, 100), Whole);
        assert_eq!(wanted(Some("bytes=0-9"), 100), Part(0, 9));
        assert_eq!(wanted(Some("bytes=90-"), 100), Part(90, 99));
        assert_eq!(wanted(Some("bytes=-10"), 100), Part(90, 99));
        assert_eq!(wanted(Some("bytes=-1000"), 100), Part(0, 99));
        assert_eq!(wanted(Some("bytes=50-1000"), 100), Part(50, 99));
        assert_eq!(wanted(Some("bytes=100-"), 100), Unsatisfiable);
        assert_eq!(wanted(Some("bytes=-0"), 100), Unsatisfiable);
        assert_eq!(wanted(Some("bytes=0-1,5-6"), 100), Whole);
        assert_eq!(wanted(Some("bytes=9-3"), 100), Whole);
        assert_eq!(wanted(Some("items=0-1"), 100), Whole);
        assert_eq!(wanted(Some("bytes=x-y"), 100), Whole);
    }
}
