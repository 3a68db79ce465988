//! What creating a job and re-planning one share: the query's options (parameters, metadata,
//! callback), the `Idempotency-Key`, and recording the job.

use asbuilt_plan::georef::Georeference;
use asbuilt_plan::Params;
use axum::http::header::LOCATION;
use axum::http::{HeaderMap, HeaderName, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use sha2::{Digest, Sha256};

use crate::app::AppState;
use crate::errors::{ApiError, Code};
use crate::queue::{Idempotency, Inserted, Job, JobMeta, NewJob};
use crate::storage::keys;
use crate::views::JobView;

/// The header a client sets to make a create safe to retry.
pub const IDEMPOTENCY_KEY: &str = "idempotency-key";
/// Set on the answer to a retry that returned the first job.
pub const REPLAYED: HeaderName = HeaderName::from_static("idempotent-replayed");

/// Limits on what a client attaches to a job.
pub const MAX_EXTERNAL_REF: usize = 200;
pub const MAX_TAGS: usize = 20;
pub const MAX_TAG: usize = 64;
pub const MAX_IDEMPOTENCY_KEY: usize = 255;

/// The query string of a create or re-plan, checked before a byte of the body is stored.
#[derive(Debug, Default)]
pub struct Options {
    pub filename: Option<String>,
    /// `section.name=value` parameter overrides.
    pub overrides: Vec<String>,
    pub meta: JobMeta,
    /// `callback_url` as given; checked by [`callback`].
    pub callback_url: Option<String>,
    /// The georeference's fields given in the query (`crs`, `anchor`, ...); checked by
    /// [`georeference`].
    pub georeference: Option<Georeference>,
}

/// The query's georeference fields, in the API's names.
pub const GEOREF_FIELDS: [&str; 5] = [
    "crs",
    "anchor",
    "anchor_at",
    "north_rotation",
    "height_datum",
];

impl Options {
    /// Sorts the query's pairs into options; parameters are checked by name, value and range.
    pub fn parse(pairs: Vec<(String, String)>) -> Result<Options, ApiError> {
        let mut o = Options::default();
        for (key, value) in pairs {
            match key.as_str() {
                "filename" => o.filename = Some(clean_filename(&value)),
                "external_ref" => {
                    if o.meta.external_ref.is_some() {
                        return Err(ApiError::param("external_ref", "give one `external_ref`"));
                    }
                    o.meta.external_ref = Some(check_external_ref(&value)?);
                }
                "tag" => add_tag(&mut o.meta.tags, &value)?,
                "callback_url" => {
                    if o.callback_url.is_some() {
                        return Err(ApiError::param("callback_url", "give one `callback_url`"));
                    }
                    o.callback_url = Some(value);
                }
                field if GEOREF_FIELDS.contains(&field) => {
                    set_georef_field(
                        o.georeference.get_or_insert_with(Default::default),
                        field,
                        &value,
                    )?;
                }
                _ => {
                    Params::check_override(&format!("{key}={value}"))
                        .map_err(|e| super::create::params_error(&e, Some(key.as_str())))?;
                    o.overrides.push(format!("{key}={value}"));
                }
            }
        }
        Ok(o)
    }
}

/// Sets one georeference field from its query text: numbers comma-separated for `anchor`
/// (`lon,lat,height`) and `anchor_at` (`x,y,z`).
fn set_georef_field(g: &mut Georeference, field: &str, value: &str) -> Result<(), ApiError> {
    let once = |given: bool| match given {
        true => Err(ApiError::param(field, format!("give one `{field}`"))),
        false => Ok(()),
    };
    let triple = |what: &str| -> Result<[f64; 3], ApiError> {
        let nums: Vec<f64> = value
            .split(',')
            .map(|s| s.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| ApiError::param(field, format!("three numbers: {what}")))?;
        <[f64; 3]>::try_from(nums)
            .map_err(|_| ApiError::param(field, format!("three numbers: {what}")))
    };
    match field {
        "crs" => {
            once(g.crs.is_some())?;
            g.crs = Some(value.to_string());
        }
        "anchor" => {
            once(g.anchor.is_some())?;
            g.anchor = Some(triple(
                "longitude,latitude,height (degrees, degrees, metres)",
            )?);
        }
        "anchor_at" => {
            once(g.anchor_at.is_some())?;
            g.anchor_at = Some(triple("x,y,z in the scan's metres")?);
        }
        "north_rotation" => {
            once(g.north_rotation.is_some())?;
            let deg = value.trim().parse::<f64>().map_err(|_| {
                ApiError::param(
                    field,
                    "degrees clockwise from true north to the local +y axis",
                )
            })?;
            g.north_rotation = Some(deg);
        }
        _ => {
            once(g.height_datum.is_some())?;
            g.height_datum = Some(value.to_string());
        }
    }
    Ok(())
}

/// The job's georeference: from the query or a `georeference` part (not both), checked; a
/// field at fault is named (`422 invalid_parameter`).
pub fn georeference(
    query: Option<Georeference>,
    part: Option<Georeference>,
) -> Result<Option<Georeference>, ApiError> {
    let g = match (query, part) {
        (Some(_), Some(_)) => {
            return Err(ApiError::param(
                "georeference",
                "give the georeference in the query (crs, anchor, ...) or as a `georeference` \
                 part, not both",
            ))
        }
        (g, None) | (None, g) => g,
    };
    if let Some(g) = &g {
        g.check()
            .map_err(|e| ApiError::param(e.field, format!("georeference: {}", e.message)))?;
    }
    Ok(g)
}

/// Keeps a display name: the last path segment, printable, at most 200 characters.
pub fn clean_filename(raw: &str) -> String {
    let last = raw.rsplit(['/', '\\']).next().unwrap_or_default();
    last.chars().filter(|c| !c.is_control()).take(200).collect()
}

/// An external reference: 1 to 200 characters, none of them control characters.
pub fn check_external_ref(value: &str) -> Result<String, ApiError> {
    let n = value.chars().count();
    if n == 0 || n > MAX_EXTERNAL_REF || value.chars().any(char::is_control) {
        return Err(ApiError::param(
            "external_ref",
            format!("1 to {MAX_EXTERNAL_REF} characters, no control characters"),
        ));
    }
    Ok(value.to_string())
}

/// Adds a tag (1 to 64 ASCII letters, digits or `-_.:/=@`), once; at most 20 tags.
pub fn add_tag(tags: &mut Vec<String>, value: &str) -> Result<(), ApiError> {
    let ok_char = |c: char| c.is_ascii_alphanumeric() || "-_.:/=@".contains(c);
    let n = value.chars().count();
    if n == 0 || n > MAX_TAG || !value.chars().all(ok_char) {
        return Err(ApiError::param(
            "tag",
            format!("a tag is 1 to {MAX_TAG} letters, digits or - _ . : / = @"),
        ));
    }
    if !tags.iter().any(|t| t == value) {
        if tags.len() == MAX_TAGS {
            return Err(ApiError::param("tag", format!("at most {MAX_TAGS} tags")));
        }
        tags.push(value.to_string());
    }
    Ok(())
}

/// The job's callback URL: the one given, else the tenant's default; checked against the
/// tenant's secret and the allow-list before anything is stored.
pub async fn callback(
    state: &AppState,
    tenant: &str,
    given: Option<String>,
) -> Result<Option<String>, ApiError> {
    let Some(raw) = given.or_else(|| state.webhooks.default_url(tenant).map(str::to_string)) else {
        return Ok(None);
    };
    state
        .webhooks
        .check_callback(tenant, &raw)
        .await
        .map(Some)
        .map_err(|e| ApiError::param("callback_url", e))
}

/// The request's `Idempotency-Key`: 1 to 255 visible ASCII characters.
pub fn idempotency_key(headers: &HeaderMap) -> Result<Option<String>, ApiError> {
    let mut values = headers.get_all(IDEMPOTENCY_KEY).iter();
    let Some(value) = values.next() else {
        return Ok(None);
    };
    let bad = || {
        ApiError::param(
            "Idempotency-Key",
            format!("one header of 1 to {MAX_IDEMPOTENCY_KEY} visible ASCII characters"),
        )
    };
    if values.next().is_some() {
        return Err(bad());
    }
    let key = value.to_str().map_err(|_| bad())?;
    if key.is_empty()
        || key.len() > MAX_IDEMPOTENCY_KEY
        || !key.bytes().all(|b| b.is_ascii_graphic())
    {
        return Err(bad());
    }
    Ok(Some(key.to_string()))
}

/// What a request asked for, as a hash: a retry with the same key must ask for the same.
pub struct Fingerprint<'a> {
    pub params: &'a Params,
    /// The cloud's SHA-256, or for a re-plan the job re-planned.
    pub cloud: String,
    /// The sidecar's kind and SHA-256, when one came with the request.
    pub sidecar: Option<(&'a str, String)>,
    pub meta: &'a JobMeta,
    pub callback_url: Option<&'a str>,
    pub georeference: Option<&'a Georeference>,
}

impl Fingerprint<'_> {
    pub fn hash(&self) -> String {
        let mut doc = serde_json::json!({
            "params": self.params.to_json(),
            "cloud": self.cloud,
            "sidecar": self.sidecar,
            "external_ref": self.meta.external_ref,
            "tags": self.meta.tags,
            "callback_url": self.callback_url,
        });
        // Only when given, so the hashes of requests without one stay as they were.
        if let Some(g) = self.georeference {
            doc["georeference"] = serde_json::json!(g);
        }
        Sha256::digest(doc.to_string().as_bytes())
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    }
}

/// Records `job` (whose blobs are already stored under its id) and answers: `202` and the new
/// job, or with an idempotency key already used, `200` and the first job when the request is
/// the same, `422 idempotency_key_reused` when it is not. Whatever the answer, blobs that no
/// job keeps are deleted.
pub async fn record(
    state: &AppState,
    job: NewJob,
    prior: Option<Job>,
) -> Result<Response, ApiError> {
    let id = job.id;
    let discard = || async {
        if let Err(e) = state.blobs.delete_prefix(&keys::job_prefix(id)).await {
            tracing::error!(job = %id, error = %e, "removing an upload no job keeps");
        }
    };
    if let Some(prior) = prior {
        discard().await;
        return replay(state, prior, job.idempotency.as_ref());
    }
    let cap = state.config.max_queued;
    let tenant = job.tenant.clone();
    let key = job.idempotency.clone();
    let source = job.replan_of.map(|(s, _)| s);
    let inserted = match state.store.insert(job, cap).await {
        Ok(i) => i,
        Err(e) => {
            discard().await;
            return Err(e.into());
        }
    };
    let job = match inserted {
        Inserted::Created(job) => *job,
        Inserted::QueueFull => {
            discard().await;
            return Err(super::create::queue_full(cap));
        }
        Inserted::SourceGone => {
            discard().await;
            let source = source.unwrap_or(id);
            return Err(super::missing(state, &tenant, source).await);
        }
        Inserted::KeyTaken => {
            // A concurrent request with the same key won the race.
            discard().await;
            let Some(key) = key.as_ref() else {
                return Err(ApiError::internal("a job without a key collided on one"));
            };
            let Some(first) = state.store.by_idempotency_key(&tenant, &key.key).await? else {
                return Err(ApiError::internal(
                    "an idempotency key collided with no job",
                ));
            };
            return replay(state, first, Some(key));
        }
    };
    // A re-plan uploaded nothing.
    if !job.is_replan() {
        state.metrics.upload(job.upload.bytes);
    }
    state.queued.notify_one();
    state.changed(job.id);
    tracing::info!(job = %job.id, bytes = job.upload.bytes, replan = job.is_replan(), "job queued");
    Ok((
        StatusCode::ACCEPTED,
        [(LOCATION, format!("/v1/jobs/{}", job.id))],
        Json(JobView::new(&job, &state.config)),
    )
        .into_response())
}

/// The answer to a retry: the first job, or a refusal when the request differs.
pub fn replay(
    state: &AppState,
    first: Job,
    key: Option<&Idempotency>,
) -> Result<Response, ApiError> {
    let asked = key.map(|k| k.request_hash.as_str());
    let had = first.idempotency.as_ref().map(|k| k.request_hash.as_str());
    if asked != had {
        return Err(ApiError::new(
            Code::IdempotencyKeyReused,
            format!(
                "this Idempotency-Key was used for job {} with a different request (cloud, \
                 sidecar, parameters or metadata); use a new key for a new job",
                first.id
            ),
        ));
    }
    tracing::info!(job = %first.id, "idempotent retry: the first job answered");
    Ok((
        StatusCode::OK,
        [
            (
                LOCATION,
                HeaderValue::from_str(&format!("/v1/jobs/{}", first.id)).expect("ascii"),
            ),
            (REPLAYED, HeaderValue::from_static("true")),
        ],
        Json(JobView::new(&first, &state.config)),
    )
        .into_response())
}

/// The tenant's job already made with `key`, looked up before anything is stored.
pub async fn prior(
    state: &AppState,
    tenant: &str,
    key: Option<&str>,
) -> Result<Option<Job>, ApiError> {
    match key {
        Some(k) => Ok(state.store.by_idempotency_key(tenant, k).await?),
        None => Ok(None),
    }
}
