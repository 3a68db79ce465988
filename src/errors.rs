//! API errors: every error response is `{"error": {"code", "message", "param"?}}` with a code
//! from [`CODES`]. Codes are a promise to clients: add new ones, never rename.

use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;

/// Every request error code, its HTTP status, and what it means.
pub const CODES: &[(&str, u16, &str)] = &[
    (
        "invalid_request",
        400,
        "The request is malformed (bad query string, body or header).",
    ),
    (
        "invalid_multipart",
        400,
        "The multipart body could not be read.",
    ),
    ("unauthorized", 401, "No API key, or an unknown one."),
    (
        "not_found",
        404,
        "No such job for this API key (other tenants' jobs are not found either).",
    ),
    ("route_not_found", 404, "No such endpoint."),
    (
        "method_not_allowed",
        405,
        "The endpoint exists but not with this method.",
    ),
    (
        "result_not_ready",
        409,
        "The job has not succeeded (yet), so it has no result.",
    ),
    (
        "payload_too_large",
        413,
        "The upload or one of its parts is over the size limit; nothing was kept.",
    ),
    (
        "unsupported_format",
        415,
        "The upload is not a point cloud format asbuilt reads (PLY, E57, LAS/LAZ, XYZ/PTS).",
    ),
    (
        "missing_cloud",
        422,
        "The request has no cloud (empty body, or no `cloud` part).",
    ),
    (
        "invalid_parameter",
        422,
        "A parameter is unknown or has a bad value; `param` names it.",
    ),
    (
        "invalid_sidecar",
        422,
        "The poses or trajectory part is not a JSON object.",
    ),
    (
        "internal",
        500,
        "Something failed on the server; the log has the detail.",
    ),
    (
        "unavailable",
        503,
        "The server is shutting down or its storage does not answer.",
    ),
];

/// Every code a failed job can carry in `error.code`, and what it means.
pub const JOB_CODES: &[(&str, &str)] = &[
    (
        "unknown_format",
        "The file's content is not a format the readers know.",
    ),
    ("invalid_file", "The cloud file is damaged or inconsistent."),
    (
        "invalid_poses",
        "The pose or trajectory sidecar does not fit the cloud.",
    ),
    ("io_error", "The cloud could not be read from storage."),
    (
        "too_many_points",
        "The cloud has more points than the server's limit.",
    ),
    (
        "invalid_parameter",
        "A parameter was rejected by the pipeline.",
    ),
    ("empty_cloud", "The cloud has no points."),
    ("bad_cloud", "The cloud is inconsistent."),
    ("no_stories", "No story (floor and ceiling pair) was found."),
    ("samples_failed", "Wall sampling failed."),
    ("smoothing_failed", "Sample smoothing failed."),
    ("labeling_failed", "Inside/outside labeling failed."),
    ("boundary_failed", "Boundary tracing failed."),
    ("fitting_failed", "Wall fitting failed."),
    ("no_plan", "No story produced a plan."),
    ("output_failed", "A result file could not be written."),
    (
        "time_limit",
        "The job ran longer than the server's time limit.",
    ),
    (
        "worker_lost",
        "The job's worker stopped responding too many times.",
    ),
    (
        "pipeline_panic",
        "The pipeline crashed on this input (a bug: please report it).",
    ),
];

/// Messages and parameter names echo what the client sent; past these many characters they are
/// cut, so a hostile request cannot make its answer huge.
const MAX_MESSAGE: usize = 1000;
const MAX_PARAM: usize = 200;

fn clip(text: String, max: usize) -> String {
    match text.char_indices().nth(max) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text,
    }
}

/// An error answered to a request.
#[derive(Debug)]
pub struct ApiError {
    pub status: StatusCode,
    pub code: &'static str,
    pub message: String,
    /// The parameter at fault, for `invalid_parameter`.
    pub param: Option<String>,
}

#[derive(Serialize)]
struct Body<'a> {
    error: Inner<'a>,
}

#[derive(Serialize)]
struct Inner<'a> {
    code: &'a str,
    message: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    param: Option<&'a str>,
}

impl ApiError {
    /// An error with the status its code has in [`CODES`].
    pub fn new(code: &'static str, message: impl Into<String>) -> ApiError {
        let status = CODES
            .iter()
            .find(|(c, _, _)| *c == code)
            .map(|&(_, s, _)| StatusCode::from_u16(s).expect("valid status in CODES"))
            .unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        debug_assert!(CODES.iter().any(|(c, _, _)| *c == code), "{code}");
        ApiError {
            status,
            code,
            message: clip(message.into(), MAX_MESSAGE),
            param: None,
        }
    }

    /// `invalid_parameter`, naming the parameter.
    pub fn param(name: impl Into<String>, message: impl Into<String>) -> ApiError {
        let mut e = ApiError::new("invalid_parameter", message);
        e.param = Some(clip(name.into(), MAX_PARAM));
        e
    }

    pub fn not_found() -> ApiError {
        ApiError::new("not_found", "no such job")
    }

    /// A server-side failure: logged in full, answered in general terms.
    pub fn internal(detail: impl std::fmt::Display) -> ApiError {
        tracing::error!(%detail, "internal error");
        ApiError::new("internal", "internal error; see the server log")
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = Body {
            error: Inner {
                code: self.code,
                message: &self.message,
                param: self.param.as_deref(),
            },
        };
        (self.status, Json(body)).into_response()
    }
}

impl From<crate::queue::StoreError> for ApiError {
    fn from(e: crate::queue::StoreError) -> Self {
        ApiError::internal(e)
    }
}

impl From<crate::storage::BlobError> for ApiError {
    fn from(e: crate::storage::BlobError) -> Self {
        ApiError::internal(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_unique_and_statuses_valid() {
        let mut seen = std::collections::HashSet::new();
        for (code, status, what) in CODES {
            assert!(seen.insert(*code), "duplicate {code}");
            assert!(StatusCode::from_u16(*status).is_ok());
            assert!(!what.is_empty());
        }
        assert_eq!(ApiError::new("payload_too_large", "x").status, 413);
        assert_eq!(ApiError::param("samples.cell_size", "x").status, 422);
        let long = ApiError::param("k".repeat(10_000), "m".repeat(10_000));
        assert_eq!(long.param.unwrap().chars().count(), MAX_PARAM + 1);
        assert_eq!(long.message.chars().count(), MAX_MESSAGE + 1);
        assert_eq!(clip("é".repeat(3), 2), "éé…");
    }
}
