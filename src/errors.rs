//! API errors: every error response is `{"error": {"code", "message", "param"?}}` with a
//! [`Code`]. Codes are a promise to clients: add new ones, never rename.

use axum::http::header::{HeaderValue, RETRY_AFTER, WWW_AUTHENTICATE};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;

/// Every request error code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Code {
    InvalidRequest,
    InvalidMultipart,
    Unauthorized,
    NotFound,
    RouteNotFound,
    Expired,
    MethodNotAllowed,
    UploadTimeout,
    ResultNotReady,
    JobFinished,
    UploadConflict,
    NeedsS3,
    PayloadTooLarge,
    UriTooLong,
    RangeNotSatisfiable,
    UnsupportedFormat,
    MissingCloud,
    InvalidParameter,
    InvalidSidecar,
    IdempotencyKeyReused,
    RateLimited,
    QueueFull,
    HeaderTooLarge,
    Internal,
    Unavailable,
}

/// Every code, in the order the OpenAPI document lists them.
pub const CODES: [Code; 25] = [
    Code::InvalidRequest,
    Code::InvalidMultipart,
    Code::Unauthorized,
    Code::NotFound,
    Code::RouteNotFound,
    Code::Expired,
    Code::MethodNotAllowed,
    Code::UploadTimeout,
    Code::ResultNotReady,
    Code::JobFinished,
    Code::UploadConflict,
    Code::NeedsS3,
    Code::PayloadTooLarge,
    Code::UriTooLong,
    Code::RangeNotSatisfiable,
    Code::UnsupportedFormat,
    Code::MissingCloud,
    Code::InvalidParameter,
    Code::InvalidSidecar,
    Code::IdempotencyKeyReused,
    Code::RateLimited,
    Code::QueueFull,
    Code::HeaderTooLarge,
    Code::Internal,
    Code::Unavailable,
];

impl Code {
    /// The code as sent.
    pub fn as_str(self) -> &'static str {
        self.describe().0
    }

    /// The HTTP status it is answered with.
    pub fn status(self) -> StatusCode {
        StatusCode::from_u16(self.describe().1).expect("valid status")
    }

    /// What it means, for documents.
    pub fn meaning(self) -> &'static str {
        self.describe().2
    }

    fn describe(self) -> (&'static str, u16, &'static str) {
        match self {
            Code::InvalidRequest => (
                "invalid_request",
                400,
                "The request is malformed (bad query string, body, header or HTTP framing).",
            ),
            Code::InvalidMultipart => (
                "invalid_multipart",
                400,
                "The multipart body could not be read.",
            ),
            Code::Unauthorized => ("unauthorized", 401, "No API key, or an unknown one."),
            Code::NotFound => (
                "not_found",
                404,
                "No such job for this API key (other tenants' jobs are not found either).",
            ),
            Code::RouteNotFound => ("route_not_found", 404, "No such endpoint."),
            Code::Expired => (
                "expired",
                410,
                "The job finished longer ago than the server's retention, and its data was deleted.",
            ),
            Code::MethodNotAllowed => (
                "method_not_allowed",
                405,
                "The endpoint exists but not with this method.",
            ),
            Code::UploadTimeout => (
                "upload_timeout",
                408,
                "The upload stalled or came in slower than the server's minimum rate; nothing was kept.",
            ),
            Code::ResultNotReady => (
                "result_not_ready",
                409,
                "The job has not succeeded (yet), so it has no result.",
            ),
            Code::JobFinished => (
                "job_finished",
                409,
                "The job already succeeded or failed, so it cannot be cancelled.",
            ),
            Code::UploadConflict => (
                "upload_conflict",
                409,
                "A resumable upload's `Upload-Offset` is not where it stands (HEAD tells), a PATCH goes past its length, or a job was asked of an incomplete upload.",
            ),
            Code::NeedsS3 => (
                "needs_s3",
                501,
                "The endpoint needs the S3 storage back end (pre-signed uploads); this server keeps blobs in a local directory.",
            ),
            Code::PayloadTooLarge => (
                "payload_too_large",
                413,
                "The upload or one of its parts is over the size limit; nothing was kept.",
            ),
            Code::UriTooLong => ("uri_too_long", 414, "The request line is too long."),
            Code::RangeNotSatisfiable => (
                "range_not_satisfiable",
                416,
                "The `Range` asked for starts past the end of the result.",
            ),
            Code::UnsupportedFormat => (
                "unsupported_format",
                415,
                "The upload is not a point cloud format asbuilt reads (PLY, E57, LAS/LAZ, XYZ/PTS).",
            ),
            Code::MissingCloud => (
                "missing_cloud",
                422,
                "The request has no cloud (empty body, or no `cloud` part).",
            ),
            Code::InvalidParameter => (
                "invalid_parameter",
                422,
                "A parameter is unknown or has a bad value; `param` names it.",
            ),
            Code::InvalidSidecar => (
                "invalid_sidecar",
                422,
                "The poses or trajectory part is not valid (the message names the entry and field), or came with an E57, which carries its own poses.",
            ),
            Code::IdempotencyKeyReused => (
                "idempotency_key_reused",
                422,
                "The `Idempotency-Key` was used for another job with a different request.",
            ),
            Code::RateLimited => (
                "rate_limited",
                429,
                "Too many requests from this tenant (or failed keys from this address); `Retry-After` says when to try again.",
            ),
            Code::QueueFull => (
                "queue_full",
                429,
                "This tenant has as many queued jobs as the server allows; `Retry-After` says when to try again.",
            ),
            Code::HeaderTooLarge => (
                "header_too_large",
                431,
                "The request's headers are too large.",
            ),
            Code::Internal => (
                "internal",
                500,
                "Something failed on the server; the log has the detail.",
            ),
            Code::Unavailable => (
                "unavailable",
                503,
                "The server is shutting down or its storage does not answer.",
            ),
        }
    }
}

/// Every code a job's `error.code` can carry. Codes are a promise to clients: add new ones,
/// never rename.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum JobCode {
    UnknownFormat,
    InvalidFile,
    InvalidPoses,
    IoError,
    TooManyPoints,
    WrongUnits,
    InvalidParameter,
    EmptyCloud,
    BadCloud,
    NoStories,
    SamplesFailed,
    SmoothingFailed,
    LabelingFailed,
    BoundaryFailed,
    FittingFailed,
    NoPlan,
    OutputFailed,
    TimeLimit,
    WorkerLost,
    PipelinePanic,
    /// A run stopped on request: the job is `cancelled`, not failed, and shows no error.
    Cancelled,
}

/// Every code a failed job can carry, in the order the OpenAPI document lists them.
pub const JOB_CODES: [JobCode; 20] = [
    JobCode::UnknownFormat,
    JobCode::InvalidFile,
    JobCode::InvalidPoses,
    JobCode::IoError,
    JobCode::TooManyPoints,
    JobCode::WrongUnits,
    JobCode::InvalidParameter,
    JobCode::EmptyCloud,
    JobCode::BadCloud,
    JobCode::NoStories,
    JobCode::SamplesFailed,
    JobCode::SmoothingFailed,
    JobCode::LabelingFailed,
    JobCode::BoundaryFailed,
    JobCode::FittingFailed,
    JobCode::NoPlan,
    JobCode::OutputFailed,
    JobCode::TimeLimit,
    JobCode::WorkerLost,
    JobCode::PipelinePanic,
];

impl JobCode {
    /// The code as sent.
    pub fn as_str(self) -> &'static str {
        self.describe().0
    }

    /// What it means, for documents.
    pub fn meaning(self) -> &'static str {
        self.describe().1
    }

    /// The code a pipeline reported by name, if the service knows it.
    pub fn parse(code: &str) -> Option<JobCode> {
        JOB_CODES
            .into_iter()
            .chain([JobCode::Cancelled])
            .find(|c| c.as_str() == code)
    }

    fn describe(self) -> (&'static str, &'static str) {
        match self {
            JobCode::UnknownFormat => ("unknown_format", "The file's content is not a format the readers know."),
            JobCode::InvalidFile => ("invalid_file", "The cloud file is damaged or inconsistent."),
            JobCode::InvalidPoses => ("invalid_poses", "The pose or trajectory sidecar does not fit the cloud."),
            JobCode::IoError => ("io_error", "The cloud could not be read from storage."),
            JobCode::TooManyPoints => ("too_many_points", "The cloud has more points than the server's limit."),
            JobCode::WrongUnits => ("wrong_units", "The cloud is far too tall for a building in metres: probably millimetres or centimetres."),
            JobCode::InvalidParameter => ("invalid_parameter", "A parameter was rejected by the pipeline."),
            JobCode::EmptyCloud => ("empty_cloud", "The cloud has no points."),
            JobCode::BadCloud => ("bad_cloud", "The cloud is inconsistent."),
            JobCode::NoStories => ("no_stories", "No story (floor and ceiling pair) was found."),
            JobCode::SamplesFailed => ("samples_failed", "Wall sampling failed."),
            JobCode::SmoothingFailed => ("smoothing_failed", "Sample smoothing failed."),
            JobCode::LabelingFailed => ("labeling_failed", "Inside/outside labeling failed."),
            JobCode::BoundaryFailed => ("boundary_failed", "Boundary tracing failed."),
            JobCode::FittingFailed => ("fitting_failed", "Wall fitting failed."),
            JobCode::NoPlan => ("no_plan", "No story produced a plan."),
            JobCode::OutputFailed => ("output_failed", "A result file could not be written."),
            JobCode::TimeLimit => ("time_limit", "The job ran longer than the server's time limit."),
            JobCode::WorkerLost => ("worker_lost", "The job's worker stopped responding too many times."),
            JobCode::PipelinePanic => ("pipeline_panic", "The pipeline crashed on this input (a bug: please report it)."),
            JobCode::Cancelled => ("cancelled", "The job was cancelled."),
        }
    }
}

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
    pub code: Code,
    pub message: String,
    /// The parameter at fault, for `invalid_parameter`.
    pub param: Option<String>,
    /// Seconds for `Retry-After` (429 and 503).
    pub retry_after: Option<u64>,
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
    /// An error with its code's status.
    pub fn new(code: Code, message: impl Into<String>) -> ApiError {
        ApiError {
            status: code.status(),
            code,
            message: clip(message.into(), MAX_MESSAGE),
            param: None,
            retry_after: None,
        }
    }

    /// `invalid_parameter`, naming the parameter.
    pub fn param(name: impl Into<String>, message: impl Into<String>) -> ApiError {
        let mut e = ApiError::new(Code::InvalidParameter, message);
        e.param = Some(clip(name.into(), MAX_PARAM));
        e
    }

    pub fn not_found() -> ApiError {
        ApiError::new(Code::NotFound, "no such job")
    }

    /// A server-side failure: logged in full, answered in general terms.
    pub fn internal(detail: impl std::fmt::Display) -> ApiError {
        tracing::error!(%detail, "internal error");
        ApiError::new(Code::Internal, "internal error; see the server log")
    }

    /// Adds `Retry-After: secs` (at least 1).
    pub fn retry_after(mut self, secs: u64) -> ApiError {
        self.retry_after = Some(secs.max(1));
        self
    }

    /// The body of an error answered outside any handler (HTTP framing errors).
    pub fn body_json(code: Code, message: &str) -> String {
        serde_json::to_string(&Body {
            error: Inner {
                code: code.as_str(),
                message,
                param: None,
            },
        })
        .expect("error bodies serialize")
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = Body {
            error: Inner {
                code: self.code.as_str(),
                message: &self.message,
                param: self.param.as_deref(),
            },
        };
        let mut response = (self.status, Json(body)).into_response();
        let headers = response.headers_mut();
        if self.code == Code::Unauthorized {
            // RFC 7235: a 401 names the scheme it wants.
            headers.insert(
                WWW_AUTHENTICATE,
                HeaderValue::from_static("Bearer realm=\"asbuilt\""),
            );
        }
        if let Some(secs) = self.retry_after {
            headers.insert(RETRY_AFTER, HeaderValue::from(secs));
        }
        response
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
    fn job_codes_parse_back_and_cover_the_pipelines() {
        for code in JOB_CODES.into_iter().chain([JobCode::Cancelled]) {
            assert_eq!(JobCode::parse(code.as_str()), Some(code));
            assert!(!code.meaning().is_empty());
        }
        // Every code the pipeline's stage table can give is one the service documents.
        for row in asbuilt_plan::progress::STAGES {
            if let Some(code) = row.error_code {
                assert!(JobCode::parse(code).is_some(), "{code}");
            }
        }
        assert_eq!(JobCode::parse("time_limit"), Some(JobCode::TimeLimit));
        assert_eq!(JobCode::parse("nonsense"), None);
    }

    #[test]
    fn codes_are_unique_and_statuses_valid() {
        let mut seen = std::collections::HashSet::new();
        for code in CODES {
            assert!(seen.insert(code.as_str()), "duplicate {code:?}");
            assert!(code.status().is_client_error() || code.status().is_server_error());
            assert!(!code.meaning().is_empty());
        }
        assert_eq!(ApiError::new(Code::PayloadTooLarge, "x").status, 413);
        let r = ApiError::new(Code::Unauthorized, "x").into_response();
        assert!(r.headers()[WWW_AUTHENTICATE]
            .to_str()
            .unwrap()
            .starts_with("Bearer"));
        let r = ApiError::new(Code::RateLimited, "x")
            .retry_after(0)
            .into_response();
        assert_eq!(r.headers()[RETRY_AFTER], "1");
        assert_eq!(ApiError::param("samples.cell_size", "x").status, 422);
        let long = ApiError::param("k".repeat(10_000), "m".repeat(10_000));
        assert_eq!(long.param.unwrap().chars().count(), MAX_PARAM + 1);
        assert_eq!(long.message.chars().count(), MAX_MESSAGE + 1);
        assert_eq!(clip("é".repeat(3), 2), "éé…");
    }
}
