//! How jobs look on the wire (the `Job` schema of `openapi/asbuilt.yaml`).

use serde::Serialize;

use crate::queue::{Job, JobError, JobStatus, UploadInfo};

/// A job as the API shows it.
#[derive(Debug, Serialize)]
pub struct JobView {
    pub id: String,
    pub status: JobStatus,
    pub stage: Option<String>,
    pub progress: f64,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    pub updated_at: String,
    pub attempts: u32,
    pub upload: UploadInfo,
    pub input: Option<serde_json::Value>,
    pub timings_ms: Option<serde_json::Value>,
    pub parameters: serde_json::Value,
    pub error: Option<JobError>,
    pub links: Links,
}

/// Where to find the job's parts.
#[derive(Debug, Serialize)]
pub struct Links {
    #[serde(rename = "self")]
    pub this: String,
    pub events: String,
    /// Present once the job succeeded.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub geojson: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub svg: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dxf: Option<String>,
}

/// RFC 3339 in UTC with milliseconds.
pub fn timestamp(ms: i64) -> String {
    chrono::DateTime::from_timestamp_millis(ms)
        .unwrap_or_default()
        .to_rfc3339_opts(chrono::SecondsFormat::Millis, true)
}

impl From<&Job> for JobView {
    fn from(job: &Job) -> JobView {
        let base = format!("/v1/jobs/{}", job.id);
        let done = job.status == JobStatus::Succeeded;
        let result = |name: &str| done.then(|| format!("{base}/{name}"));
        JobView {
            id: job.id.to_string(),
            status: job.status,
            stage: job.stage.clone(),
            progress: job.progress,
            created_at: timestamp(job.created_at),
            started_at: job.started_at.map(timestamp),
            finished_at: job.finished_at.map(timestamp),
            updated_at: timestamp(job.updated_at),
            attempts: job.attempts,
            upload: job.upload.clone(),
            input: job.input.clone(),
            timings_ms: job.timings.clone(),
            parameters: job.params.clone(),
            error: job.error.clone(),
            links: Links {
                events: format!("{base}/events"),
                geojson: result("plan.geojson"),
                svg: result("plan.svg"),
                dxf: result("plan.dxf"),
                this: base,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamps_are_rfc3339_utc() {
        assert_eq!(timestamp(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(timestamp(1_700_000_000_123), "2023-11-14T22:13:20.123Z");
    }
}
