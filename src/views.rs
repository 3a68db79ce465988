//! How jobs look on the wire (the `Job` schema of `openapi/asbuilt.yaml`).

use std::collections::BTreeMap;

use asbuilt_plan::io::outputs::OUTPUTS;
use serde::Serialize;

use crate::config::Config;
use crate::queue::{Delivery, Job, JobError, JobStatus, UploadInfo};

/// A job as the API shows it.
#[derive(Debug, Serialize)]
pub struct JobView {
    pub id: String,
    pub status: JobStatus,
    pub stage: Option<String>,
    pub progress: f64,
    /// While running: bytes of the cloud read, of its size (`{bytes, total}`); null otherwise.
    pub read: Option<serde_json::Value>,
    /// While running: the story whose stages run, from 1, of how many (`{number, count}`).
    pub story: Option<serde_json::Value>,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    pub updated_at: String,
    /// When retention removes the job and its data; null until it finishes.
    pub expires_at: Option<String>,
    pub attempts: u32,
    pub upload: UploadInfo,
    pub input: Option<serde_json::Value>,
    pub timings_ms: Option<serde_json::Value>,
    pub parameters: serde_json::Value,
    pub error: Option<JobError>,
    pub links: Links,
    /// The client's reference, as given at creation.
    pub external_ref: Option<String>,
    /// The client's tags, as given at creation.
    pub tags: Vec<String>,
    /// For a re-plan: the job whose stored upload it reads; null for a job with its own.
    pub source_job: Option<String>,
    /// Where the job's end is POSTed (a signed webhook), if anywhere.
    pub callback_url: Option<String>,
    /// Where the scan lies on the earth, as the client gave it; null when it gave none (the
    /// scan's own CRS, if any, is declared in `plan.geojson`).
    pub georeference: Option<asbuilt_plan::georef::Georeference>,
}

/// Where to find the job's parts.
#[derive(Debug, Serialize)]
pub struct Links {
    #[serde(rename = "self")]
    pub this: String,
    pub events: String,
    /// Each result by its output's name (`geojson`, `svg`, ...), once the job succeeded.
    #[serde(flatten)]
    pub results: BTreeMap<&'static str, String>,
}

/// RFC 3339 in UTC with milliseconds.
pub fn timestamp(ms: i64) -> String {
    chrono::DateTime::from_timestamp_millis(ms)
        .unwrap_or_default()
        .to_rfc3339_opts(chrono::SecondsFormat::Millis, true)
}

impl JobView {
    /// The job as shown by a server with `config` (its retention sets `expires_at`).
    pub fn new(job: &Job, config: &Config) -> JobView {
        let retention_ms = config.retention_ms();
        let base = format!("/v1/jobs/{}", job.id);
        let done = job.status == JobStatus::Succeeded;
        let results = match done {
            true => OUTPUTS
                .iter()
                .map(|o| (o.name, format!("{base}/{}", o.file)))
                .collect(),
            false => BTreeMap::new(),
        };
        let detail = |key: &str| {
            let running = job.status == JobStatus::Running;
            job.progress_detail
                .as_ref()
                .and_then(|d| d.get(key))
                .filter(|v| running && !v.is_null())
                .cloned()
        };
        JobView {
            id: job.id.to_string(),
            status: job.status,
            stage: job.stage.clone(),
            progress: job.progress,
            read: detail("read"),
            story: detail("story"),
            created_at: timestamp(job.created_at),
            started_at: job.started_at.map(timestamp),
            finished_at: job.finished_at.map(timestamp),
            updated_at: timestamp(job.updated_at),
            expires_at: job
                .finished_at
                .map(|at| timestamp(at.saturating_add(retention_ms))),
            attempts: job.attempts,
            // The georeference is stored with the upload but shown on its own.
            upload: UploadInfo {
                georeference: None,
                ..job.upload.clone()
            },
            input: job.input.clone(),
            timings_ms: job.timings.clone(),
            parameters: job.params.clone(),
            error: job.error.clone(),
            links: Links {
                events: format!("{base}/events"),
                results,
                this: base,
            },
            external_ref: job.meta.external_ref.clone(),
            tags: job.meta.tags.clone(),
            source_job: job.is_replan().then(|| job.input_job.to_string()),
            callback_url: job.callback_url.clone(),
            georeference: job.upload.georeference.clone(),
        }
    }
}

/// One webhook delivery attempt, as `GET /v1/jobs/{id}/deliveries` shows it.
#[derive(Debug, Serialize)]
pub struct DeliveryView {
    pub id: String,
    pub event: String,
    pub url: String,
    pub attempt: u32,
    pub at: String,
    pub status: Option<u16>,
    pub error: Option<String>,
    pub duration_ms: i64,
}

impl From<&Delivery> for DeliveryView {
    fn from(d: &Delivery) -> DeliveryView {
        DeliveryView {
            id: d.id.to_string(),
            event: d.event.clone(),
            url: d.url.clone(),
            attempt: d.attempt,
            at: timestamp(d.at),
            status: d.status,
            error: d.error.clone(),
            duration_ms: d.duration_ms,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamps_are_rfc3339_utc() {
        assert_eq!(
            DeliveryView::from(&crate::queue::Delivery {
                id: uuid::Uuid::nil(),
                job: crate::queue::JobId(uuid::Uuid::nil()),
                event: "job.failed".into(),
                url: "https://x/".into(),
                attempt: 2,
                at: 0,
                status: Some(500),
                error: Some("the receiver answered 500".into()),
                duration_ms: 7,
            })
            .at,
            "1970-01-01T00:00:00.000Z"
        );
        assert_eq!(timestamp(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(timestamp(1_700_000_000_123), "2023-11-14T22:13:20.123Z");
    }
}
