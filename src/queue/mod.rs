//! The durable job queue and job state. [`JobStore`] is the seam: SQLite ([`sqlite`]) is the
//! embedded default; other databases implement the same trait.
//!
//! A job moves `queued → running → succeeded | failed | cancelled`. A worker that claims a job
//! holds a lease (`lease_owner`, `lease_until`) and renews it with [`JobStore::heartbeat`]. A
//! lease that runs out puts the job back in the queue ([`JobStore::requeue_expired`]) until
//! `max_attempts` claims have been spent; then the job fails with [`WORKER_LOST`].

pub mod postgres;
pub mod sqlite;

use std::fmt;
use std::str::FromStr;

use async_trait::async_trait;
use serde::{Deserialize, Serialize};

/// The error code of a job whose workers stopped heartbeating `max_attempts` times.
pub const WORKER_LOST: &str = "worker_lost";

/// A job's identifier: a UUIDv7, so identifiers sort by creation time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct JobId(pub uuid::Uuid);

impl JobId {
    /// A new identifier for a job created now.
    pub fn new() -> JobId {
        JobId(uuid::Uuid::now_v7())
    }
}

impl Default for JobId {
    fn default() -> Self {
        JobId::new()
    }
}

impl fmt::Display for JobId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Hyphenated lower case: the form stored, listed and used in blob keys.
        write!(f, "{}", self.0.hyphenated())
    }
}

impl FromStr for JobId {
    type Err = InvalidJobId;

    /// Only the canonical hyphenated form is accepted, so an id is also a safe path segment.
    fn from_str(s: &str) -> Result<JobId, InvalidJobId> {
        if s.len() != 36 {
            return Err(InvalidJobId);
        }
        let id = uuid::Uuid::parse_str(s).map_err(|_| InvalidJobId)?;
        Ok(JobId(id))
    }
}

/// A string that is not a job identifier.
#[derive(Debug, thiserror::Error)]
#[error("not a job id (expected a UUID such as 0190c1d2-7a3b-7c00-8000-000000000000)")]
pub struct InvalidJobId;

/// Where a job is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JobStatus {
    Queued,
    Running,
    Succeeded,
    Failed,
    Cancelled,
}

impl JobStatus {
    /// Every status, in life order.
    pub const ALL: [JobStatus; 5] = [
        JobStatus::Queued,
        JobStatus::Running,
        JobStatus::Succeeded,
        JobStatus::Failed,
        JobStatus::Cancelled,
    ];

    /// The name stored and shown.
    pub fn as_str(self) -> &'static str {
        match self {
            JobStatus::Queued => "queued",
            JobStatus::Running => "running",
            JobStatus::Succeeded => "succeeded",
            JobStatus::Failed => "failed",
            JobStatus::Cancelled => "cancelled",
        }
    }

    /// True once the job will not change again.
    pub fn is_terminal(self) -> bool {
        matches!(
            self,
            JobStatus::Succeeded | JobStatus::Failed | JobStatus::Cancelled
        )
    }
}

impl FromStr for JobStatus {
    type Err = String;

    fn from_str(s: &str) -> Result<JobStatus, String> {
        JobStatus::ALL
            .into_iter()
            .find(|st| st.as_str() == s)
            .ok_or_else(|| format!("unknown status `{s}`"))
    }
}

/// Why a job failed: a stable code and a human message.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct JobError {
    pub code: String,
    pub message: String,
}

/// What was uploaded, recorded when the job is created.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct UploadInfo {
    /// The name the client gave the file, if any (display only; never used as a path).
    pub filename: Option<String>,
    pub bytes: u64,
    /// Lower-case hex SHA-256 of the uploaded cloud.
    pub sha256: String,
    /// The format detected from the first bytes: `ply`, `e57`, `las`, `xyz`.
    pub format: String,
    /// `poses` or `trajectory` when a sidecar came with the cloud.
    pub sidecar: Option<String>,
    /// Where the scan lies on the earth, when the client gave it (a re-plan keeps it unless
    /// it gives another). Stored with the upload it describes; shown as the job's
    /// `georeference`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub georeference: Option<asbuilt_plan::georef::Georeference>,
}

/// What the client attached to a job to find it again: its own reference and tags.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct JobMeta {
    /// The client's reference (a building id, a level's name); at most 200 characters.
    pub external_ref: Option<String>,
    /// Labels to filter the list by; at most 20 of 64 characters each, no duplicates.
    pub tags: Vec<String>,
}

/// A create request's `Idempotency-Key`, with the fingerprint of what it asked for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Idempotency {
    pub key: String,
    /// Hex SHA-256 over the request's parameters, cloud, sidecar and metadata.
    pub request_hash: String,
}

/// A job as stored. Times are Unix milliseconds.
#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    pub id: JobId,
    pub tenant: String,
    pub status: JobStatus,
    pub stage: Option<String>,
    pub progress: f64,
    /// While running: the bytes read and the story running, as the last heartbeat recorded them.
    pub progress_detail: Option<serde_json::Value>,
    /// The caller's parameter overrides (a JSON object, possibly empty).
    pub params: serde_json::Value,
    pub upload: UploadInfo,
    /// `floorplan.input` once the cloud has been read.
    pub input: Option<serde_json::Value>,
    /// Stage name → milliseconds, once the job succeeded.
    pub timings: Option<serde_json::Value>,
    pub error: Option<JobError>,
    pub attempts: u32,
    pub max_attempts: u32,
    pub created_at: i64,
    pub started_at: Option<i64>,
    pub finished_at: Option<i64>,
    pub updated_at: i64,
    pub meta: JobMeta,
    pub idempotency: Option<Idempotency>,
    /// The job whose stored upload (`jobs/<id>/input/cloud`) this job reads: itself, or the
    /// original upload of a re-plan.
    pub input_job: JobId,
    /// Where completion and failure are POSTed, if anywhere.
    pub callback_url: Option<String>,
}

impl Job {
    /// True when this job re-plans another job's upload.
    pub fn is_replan(&self) -> bool {
        self.input_job != self.id
    }
}

/// A job to create.
#[derive(Debug, Clone, Default)]
pub struct NewJob {
    pub id: JobId,
    pub tenant: String,
    pub params: serde_json::Value,
    pub upload: UploadInfo,
    pub max_attempts: u32,
    pub meta: JobMeta,
    pub idempotency: Option<Idempotency>,
    /// For a re-plan: the job re-planned (it must still exist when this one is recorded) and
    /// the job whose upload is read. `None`: a new upload, stored under this job's own id.
    pub replan_of: Option<(JobId, JobId)>,
    pub callback_url: Option<String>,
}

/// One webhook delivery attempt, as recorded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Delivery {
    pub id: uuid::Uuid,
    pub job: JobId,
    /// `job.succeeded`, `job.failed` or `job.cancelled`.
    pub event: String,
    pub url: String,
    /// 1 for the first attempt.
    pub attempt: u32,
    /// When it was sent, Unix milliseconds.
    pub at: i64,
    /// The receiver's HTTP status, when it answered.
    pub status: Option<u16>,
    /// Why it failed, when it did (no answer, refused target, non-2xx).
    pub error: Option<String>,
    pub duration_ms: i64,
}

/// What [`JobStore::insert`] did.
#[derive(Debug, Clone)]
pub enum Inserted {
    Created(Box<Job>),
    /// The tenant already has `max_queued` queued jobs.
    QueueFull,
    /// The job to re-plan was deleted meanwhile.
    SourceGone,
    /// The tenant already has a job with this `Idempotency-Key`.
    KeyTaken,
}

/// A page of a tenant's jobs, newest first.
#[derive(Debug, Clone, Default)]
pub struct ListQuery {
    pub tenant: String,
    pub status: Option<JobStatus>,
    /// Only jobs older than this one (the previous page's last id).
    pub before: Option<JobId>,
    pub limit: u32,
    /// Only jobs with this external reference.
    pub external_ref: Option<String>,
    /// Only jobs carrying every one of these tags.
    pub tags: Vec<String>,
}

/// What a worker reports with each heartbeat.
#[derive(Debug, Clone)]
pub struct Beat {
    pub stage: Option<String>,
    pub progress: f64,
    /// `floorplan.input`, once known.
    pub input: Option<serde_json::Value>,
    /// The bytes read and the story running (`{"read": .., "story": ..}`), once reported.
    pub detail: Option<serde_json::Value>,
}

/// The answer to a heartbeat.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Heartbeat {
    /// The lease is renewed; carry on.
    Held,
    /// The job was cancelled, deleted or given to another worker: stop and discard the work.
    Lost,
}

/// The outcome of a successful run.
#[derive(Debug, Clone)]
pub struct JobOutcome {
    pub input: serde_json::Value,
    pub timings: serde_json::Value,
}

/// What [`JobStore::requeue_expired`] did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Expired {
    /// Jobs put back in the queue for another attempt.
    pub requeued: Vec<JobId>,
    /// Jobs that had spent their attempts and failed with [`WORKER_LOST`].
    pub failed: Vec<JobId>,
}

/// A database failure. The API shows it as `internal` and logs the detail.
#[derive(Debug, thiserror::Error)]
#[error("job store: {0}")]
pub struct StoreError(pub String);

impl From<sqlx::Error> for StoreError {
    fn from(e: sqlx::Error) -> Self {
        StoreError(e.to_string())
    }
}

/// Job state and the queue. Every method is one atomic step, so several workers (and several
/// processes, on a shared database) can use one store.
#[async_trait]
pub trait JobStore: Send + Sync + 'static {
    /// Applies pending migrations.
    async fn migrate(&self) -> Result<(), StoreError>;
    /// Checks that the database's schema is the one this binary expects (start-up of every
    /// role but `migrate`); the error says what to run. Stores that migrate themselves at
    /// start-up need not check.
    async fn check_schema(&self) -> Result<(), StoreError> {
        Ok(())
    }
    /// Waits until a job may have been queued, or `timeout` passes. Stores shared between
    /// processes wake on the database's notifications; the default just sleeps (polling).
    async fn wait_for_work(&self, timeout: std::time::Duration) {
        tokio::time::sleep(timeout).await;
    }
    /// Checks the database answers (readiness).
    async fn ping(&self) -> Result<(), StoreError>;
    /// Records a new queued job.
    async fn create(&self, job: NewJob) -> Result<Job, StoreError>;
    /// Records a new queued job unless its tenant already has `max_queued` queued jobs (0: no
    /// cap), in one atomic step; `None` when over the cap.
    async fn create_within(&self, job: NewJob, max_queued: u32) -> Result<Option<Job>, StoreError> {
        match self.insert(job, max_queued).await? {
            Inserted::Created(job) => Ok(Some(*job)),
            Inserted::QueueFull => Ok(None),
            other => Err(StoreError(format!("job not created: {other:?}"))),
        }
    }
    /// Records a new queued job in one atomic step, unless its tenant is at `max_queued`
    /// queued jobs (0: no cap), the job it re-plans is gone, or its idempotency key is taken.
    /// A re-plan's source row is held while the job is recorded, so a concurrent delete of
    /// the source either comes first (and this fails) or sees the new job using the upload.
    async fn insert(&self, job: NewJob, max_queued: u32) -> Result<Inserted, StoreError>;
    /// The tenant's job created with this `Idempotency-Key`, if any.
    async fn by_idempotency_key(&self, tenant: &str, key: &str) -> Result<Option<Job>, StoreError>;
    /// True while a job row reads the upload stored under `input_job` (its own or a re-plan).
    async fn upload_in_use(&self, input_job: JobId) -> Result<bool, StoreError>;
    /// How many jobs `tenant` has queued.
    async fn queued_count(&self, tenant: &str) -> Result<u64, StoreError>;
    /// A job by id; `tenant` restricts it to one tenant's jobs.
    async fn get(&self, tenant: Option<&str>, id: JobId) -> Result<Option<Job>, StoreError>;
    /// A tenant's jobs, newest first.
    async fn list(&self, query: &ListQuery) -> Result<Vec<Job>, StoreError>;
    /// Takes a queued job for `owner` with a lease of `lease_ms`, counting an attempt. Fair
    /// across tenants: the tenant with the fewest running jobs goes first, then the one whose
    /// last job started longest ago (never is longest), then the oldest job; so one tenant's
    /// flood of jobs does not starve another's single job.
    async fn claim(&self, owner: &str, lease_ms: i64) -> Result<Option<Job>, StoreError>;
    /// Renews `owner`'s lease and records progress; [`Heartbeat::Lost`] when the job is no
    /// longer running under this owner.
    async fn heartbeat(
        &self,
        id: JobId,
        owner: &str,
        lease_ms: i64,
        beat: &Beat,
    ) -> Result<Heartbeat, StoreError>;
    /// Marks `owner`'s running job succeeded; false when the lease was lost.
    async fn complete(
        &self,
        id: JobId,
        owner: &str,
        outcome: &JobOutcome,
    ) -> Result<bool, StoreError>;
    /// Marks `owner`'s running job failed in `stage` (the stage it stopped in, when known);
    /// false when the lease was lost.
    async fn fail(
        &self,
        id: JobId,
        owner: &str,
        error: &JobError,
        stage: Option<&str>,
    ) -> Result<bool, StoreError>;
    /// Hands `owner`'s running job back to the queue without spending an attempt (shutdown).
    async fn release(&self, id: JobId, owner: &str) -> Result<bool, StoreError>;
    /// Hands back every job still running under an owner that starts with `prefix` (all of a
    /// process's workers, at the end of shutdown), without spending attempts.
    async fn release_all(&self, prefix: &str) -> Result<Vec<JobId>, StoreError>;
    /// Requeues running jobs whose lease ran out, or fails them once attempts are spent.
    async fn requeue_expired(&self) -> Result<Expired, StoreError>;
    /// Cancels a tenant's queued or running job; returns the job as it now is.
    async fn cancel(&self, tenant: &str, id: JobId) -> Result<Option<Job>, StoreError>;
    /// Removes a job's row; true when it existed.
    async fn delete(&self, id: JobId) -> Result<bool, StoreError>;
    /// Removes a job's row for retention, leaving a tombstone (id, tenant, time) so the job
    /// answers "expired" rather than "not found"; true when it existed.
    async fn expire(&self, id: JobId) -> Result<bool, StoreError>;
    /// When `tenant`'s job `id` was removed by retention, if it was.
    async fn expired_at(&self, tenant: &str, id: JobId) -> Result<Option<i64>, StoreError>;
    /// Forgets tombstones older than `before_ms` (those jobs then answer "not found").
    async fn forget_expired(&self, before_ms: i64) -> Result<u64, StoreError>;
    /// Takes up to `limit` finished jobs whose webhook is due, for `lease_ms` (another process
    /// takes them only after that); each with the attempts made so far.
    async fn claim_hooks(&self, lease_ms: i64, limit: u32) -> Result<Vec<(Job, u32)>, StoreError>;
    /// Records that a job's webhook was tried `attempts` times; `next_due` is when to try
    /// again, `None` once delivered or given up.
    async fn hook_tried(
        &self,
        id: JobId,
        attempts: u32,
        next_due: Option<i64>,
    ) -> Result<(), StoreError>;
    /// Records one delivery attempt.
    async fn record_delivery(&self, delivery: &Delivery) -> Result<(), StoreError>;
    /// A job's delivery attempts, oldest first.
    async fn deliveries(&self, id: JobId) -> Result<Vec<Delivery>, StoreError>;
    /// Jobs that finished before `before_ms` (for retention), at most `limit`.
    async fn finished_before(&self, before_ms: i64, limit: u32) -> Result<Vec<JobId>, StoreError>;
    /// How many jobs are in each status (every status, zeros included).
    async fn counts_by_status(&self) -> Result<Vec<(JobStatus, u64)>, StoreError>;
}

/// Milliseconds since the Unix epoch, now.
pub fn now_ms() -> i64 {
    chrono::Utc::now().timestamp_millis()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_round_trip_and_reject_anything_else() {
        let id = JobId::new();
        assert_eq!(id.to_string().parse::<JobId>().unwrap(), id);
        for bad in [
            "",
            "../../etc/passwd",
            "0190c1d27a3b7c008000000000000000",
            "{0190c1d2-7a3b-7c00-8000-000000000000}",
            "0190c1d2-7a3b-7c00-8000-00000000000/",
        ] {
            assert!(bad.parse::<JobId>().is_err(), "{bad}");
        }
    }

    #[test]
    fn later_ids_sort_after_earlier_ones() {
        let a = JobId::new();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let b = JobId::new();
        assert!(a.to_string() < b.to_string());
    }

    #[test]
    fn statuses_parse_from_their_names() {
        for s in JobStatus::ALL {
            assert_eq!(s.as_str().parse::<JobStatus>().unwrap(), s);
        }
        assert!("done".parse::<JobStatus>().is_err());
        assert!(JobStatus::Cancelled.is_terminal() && !JobStatus::Running.is_terminal());
    }
}
