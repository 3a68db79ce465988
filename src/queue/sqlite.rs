//! The embedded job store: one SQLite file in WAL mode, migrations compiled into the binary.

use std::borrow::Cow;
use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

use async_trait::async_trait;
use futures_util::future::BoxFuture;
use sqlx::error::BoxDynError;
use sqlx::migrate::{Migration, MigrationSource, MigrationType, Migrator};
use sqlx::sqlite::{
    SqliteConnectOptions, SqliteJournalMode, SqlitePool, SqlitePoolOptions, SqliteRow,
    SqliteSynchronous,
};
use sqlx::Row;

use super::{
    now_ms, Beat, Delivery, Expired, Heartbeat, Idempotency, Inserted, Job, JobError, JobId,
    JobMeta, JobOutcome, JobStatus, JobStore, ListQuery, NewJob, StoreError, WORKER_LOST,
};

/// The SQLite migrations, in order: (version, description, SQL).
const MIGRATIONS: &[(i64, &str, &str)] = &[
    (
        1,
        "jobs",
        include_str!("../../migrations/sqlite/0001_jobs.sql"),
    ),
    (
        2,
        "tenant fairness",
        include_str!("../../migrations/sqlite/0002_tenant_fairness.sql"),
    ),
    (
        3,
        "job api",
        include_str!("../../migrations/sqlite/0003_job_api.sql"),
    ),
    (
        4,
        "progress detail",
        include_str!("../../migrations/sqlite/0004_progress_detail.sql"),
    ),
];

/// Hands sqlx the migrations embedded above.
#[derive(Debug)]
struct Embedded;

impl<'s> MigrationSource<'s> for Embedded {
    fn resolve(self) -> BoxFuture<'s, Result<Vec<Migration>, BoxDynError>> {
        Box::pin(async {
            Ok(MIGRATIONS
                .iter()
                .map(|&(version, description, sql)| {
                    Migration::new(
                        version,
                        Cow::Borrowed(description),
                        MigrationType::Simple,
                        Cow::Borrowed(sql),
                        false,
                    )
                })
                .collect())
        })
    }
}

/// Job state in an SQLite database.
#[derive(Clone)]
pub struct SqliteJobStore {
    pool: SqlitePool,
}

const COLUMNS: &str =
    "id, tenant, status, stage, progress, progress_detail, params, upload, input, timings, \
     error_code, error_message, attempts, max_attempts, created_at, started_at, finished_at, \
     updated_at, external_ref, tags, idempotency_key, request_hash, input_job, callback_url";

/// The columns a new job sets, in the order [`SqliteJobStore::bind_new`] binds them.
const NEW_COLUMNS: &str = "id, tenant, status, progress, params, upload, attempts, max_attempts, \
     created_at, updated_at, external_ref, tags, idempotency_key, request_hash, input_job, \
     callback_url, hook_due";
const NEW_VALUES: &str = "?, ?, 'queued', 0, ?, ?, 0, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?";

impl SqliteJobStore {
    /// Opens (creating if needed) the database file at `path`.
    pub async fn open(path: &Path) -> Result<SqliteJobStore, StoreError> {
        let options = SqliteConnectOptions::new()
            .filename(path)
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            // FULL: a job answered 202 survives power loss, not just a process crash.
            .synchronous(SqliteSynchronous::Full)
            .busy_timeout(Duration::from_secs(10))
            .foreign_keys(true);
        let pool = SqlitePoolOptions::new()
            .max_connections(8)
            .connect_with(options)
            .await?;
        Ok(SqliteJobStore { pool })
    }

    /// Opens a database given as `sqlite://PATH` or a plain path.
    pub async fn open_url(url: &str) -> Result<SqliteJobStore, StoreError> {
        let path = url
            .strip_prefix("sqlite://")
            .or_else(|| url.strip_prefix("sqlite:"))
            .unwrap_or(url);
        SqliteJobStore::open(Path::new(path)).await
    }

    fn row_to_job(row: &SqliteRow) -> Result<Job, StoreError> {
        let json = |name: &str| -> Result<Option<serde_json::Value>, StoreError> {
            let text: Option<String> = row.try_get(name)?;
            text.map(|t| {
                serde_json::from_str(&t).map_err(|e| StoreError(format!("column {name}: {e}")))
            })
            .transpose()
        };
        let id: String = row.try_get("id")?;
        let status: String = row.try_get("status")?;
        let upload: String = row.try_get("upload")?;
        let error_code: Option<String> = row.try_get("error_code")?;
        let error_message: Option<String> = row.try_get("error_message")?;
        Ok(Job {
            id: JobId::from_str(&id).map_err(|e| StoreError(format!("id {id}: {e}")))?,
            tenant: row.try_get("tenant")?,
            status: JobStatus::from_str(&status).map_err(StoreError)?,
            stage: row.try_get("stage")?,
            progress: row.try_get("progress")?,
            progress_detail: json("progress_detail")?,
            params: json("params")?.unwrap_or_default(),
            upload: serde_json::from_str(&upload)
                .map_err(|e| StoreError(format!("column upload: {e}")))?,
            input: json("input")?,
            timings: json("timings")?,
            error: error_code.map(|code| JobError {
                code,
                message: error_message.unwrap_or_default(),
            }),
            attempts: row.try_get::<i64, _>("attempts")? as u32,
            max_attempts: row.try_get::<i64, _>("max_attempts")? as u32,
            created_at: row.try_get("created_at")?,
            started_at: row.try_get("started_at")?,
            finished_at: row.try_get("finished_at")?,
            updated_at: row.try_get("updated_at")?,
            meta: JobMeta {
                external_ref: row.try_get("external_ref")?,
                tags: serde_json::from_value(json("tags")?.unwrap_or_default())
                    .map_err(|e| StoreError(format!("column tags: {e}")))?,
            },
            idempotency: match (
                row.try_get::<Option<String>, _>("idempotency_key")?,
                row.try_get::<Option<String>, _>("request_hash")?,
            ) {
                (Some(key), hash) => Some(Idempotency {
                    key,
                    request_hash: hash.unwrap_or_default(),
                }),
                _ => None,
            },
            input_job: match row.try_get::<Option<String>, _>("input_job")? {
                Some(s) => {
                    JobId::from_str(&s).map_err(|e| StoreError(format!("input_job: {e}")))?
                }
                None => JobId::from_str(&id).map_err(|e| StoreError(format!("id {id}: {e}")))?,
            },
            callback_url: row.try_get("callback_url")?,
        })
    }

    /// Binds a new job's values to a statement built with [`NEW_VALUES`].
    fn bind_new<'q>(
        query: sqlx::query::Query<'q, sqlx::Sqlite, sqlx::sqlite::SqliteArguments<'q>>,
        job: &NewJob,
        now: i64,
    ) -> Result<sqlx::query::Query<'q, sqlx::Sqlite, sqlx::sqlite::SqliteArguments<'q>>, StoreError>
    {
        Ok(query
            .bind(job.id.to_string())
            .bind(job.tenant.clone())
            .bind(job.params.to_string())
            .bind(json_text(&job.upload)?)
            .bind(job.max_attempts as i64)
            .bind(now)
            .bind(now)
            .bind(job.meta.external_ref.clone())
            .bind(json_text(&job.meta.tags)?)
            .bind(job.idempotency.as_ref().map(|i| i.key.clone()))
            .bind(job.idempotency.as_ref().map(|i| i.request_hash.clone()))
            .bind(job.replan_of.map(|(_, input)| input.to_string()))
            .bind(job.callback_url.clone())
            // A job with a callback owes one once it finishes.
            .bind(job.callback_url.as_ref().map(|_| 0i64)))
    }

    fn row_to_delivery(row: &SqliteRow) -> Result<Delivery, StoreError> {
        let id: String = row.try_get("id")?;
        let job: String = row.try_get("job_id")?;
        Ok(Delivery {
            id: uuid::Uuid::parse_str(&id).map_err(|e| StoreError(e.to_string()))?,
            job: JobId::from_str(&job).map_err(|e| StoreError(e.to_string()))?,
            event: row.try_get("event")?,
            url: row.try_get("url")?,
            attempt: row.try_get::<i64, _>("attempt")? as u32,
            at: row.try_get("at")?,
            status: row
                .try_get::<Option<i64>, _>("status_code")?
                .map(|s| s as u16),
            error: row.try_get("error")?,
            duration_ms: row.try_get("duration_ms")?,
        })
    }
}

/// A JSON column's text.
pub(crate) fn json_text<T: serde::Serialize>(value: &T) -> Result<String, StoreError> {
    serde_json::to_string(value).map_err(|e| StoreError(e.to_string()))
}

/// True when `e` is a unique-index violation (an idempotency key already taken).
pub(crate) fn is_unique_violation(e: &sqlx::Error) -> bool {
    e.as_database_error()
        .is_some_and(|d| d.is_unique_violation())
}

#[async_trait]
impl JobStore for SqliteJobStore {
    async fn migrate(&self) -> Result<(), StoreError> {
        let migrator = Migrator::new(Embedded)
            .await
            .map_err(|e| StoreError(e.to_string()))?;
        migrator
            .run(&self.pool)
            .await
            .map_err(|e| StoreError(e.to_string()))
    }

    async fn ping(&self) -> Result<(), StoreError> {
        sqlx::query("SELECT 1").execute(&self.pool).await?;
        Ok(())
    }

    async fn create(&self, job: NewJob) -> Result<Job, StoreError> {
        let sql =
            format!("INSERT INTO jobs ({NEW_COLUMNS}) VALUES ({NEW_VALUES}) RETURNING {COLUMNS}");
        let row = Self::bind_new(sqlx::query(&sql), &job, now_ms())?
            .fetch_one(&self.pool)
            .await?;
        Self::row_to_job(&row)
    }

    async fn insert(&self, job: NewJob, max_queued: u32) -> Result<Inserted, StoreError> {
        // One statement: SQLite serialises writers, so neither the count nor the source's
        // existence can change under it.
        let sql = format!(
            "INSERT INTO jobs ({NEW_COLUMNS}) SELECT {NEW_VALUES} \
             WHERE (? = 0 OR (SELECT COUNT(*) FROM jobs WHERE tenant = ? AND status = 'queued') < ?) \
             AND (? IS NULL OR EXISTS (SELECT 1 FROM jobs WHERE id = ?)) \
             RETURNING {COLUMNS}"
        );
        let source = job.replan_of.map(|(s, _)| s.to_string());
        let query = Self::bind_new(sqlx::query(&sql), &job, now_ms())?
            .bind(max_queued as i64)
            .bind(job.tenant.clone())
            .bind(max_queued as i64)
            .bind(source.clone())
            .bind(source.clone());
        let row = match query.fetch_optional(&self.pool).await {
            Ok(row) => row,
            Err(e) if is_unique_violation(&e) && job.idempotency.is_some() => {
                return Ok(Inserted::KeyTaken)
            }
            Err(e) => return Err(e.into()),
        };
        if let Some(row) = row {
            return Self::row_to_job(&row).map(|j| Inserted::Created(Box::new(j)));
        }
        // Which condition failed (only the answer's wording depends on it).
        if let Some(source) = source {
            let exists: bool =
                sqlx::query_scalar("SELECT EXISTS (SELECT 1 FROM jobs WHERE id = ?)")
                    .bind(source)
                    .fetch_one(&self.pool)
                    .await?;
            if !exists {
                return Ok(Inserted::SourceGone);
            }
        }
        Ok(Inserted::QueueFull)
    }

    async fn by_idempotency_key(&self, tenant: &str, key: &str) -> Result<Option<Job>, StoreError> {
        let sql = format!("SELECT {COLUMNS} FROM jobs WHERE tenant = ? AND idempotency_key = ?");
        let row = sqlx::query(&sql)
            .bind(tenant)
            .bind(key)
            .fetch_optional(&self.pool)
            .await?;
        row.as_ref().map(Self::row_to_job).transpose()
    }

    async fn upload_in_use(&self, input_job: JobId) -> Result<bool, StoreError> {
        let id = input_job.to_string();
        let used: bool = sqlx::query_scalar(
            "SELECT EXISTS (SELECT 1 FROM jobs WHERE id = ?) \
             OR EXISTS (SELECT 1 FROM jobs WHERE input_job = ?)",
        )
        .bind(&id)
        .bind(&id)
        .fetch_one(&self.pool)
        .await?;
        Ok(used)
    }

    async fn queued_count(&self, tenant: &str) -> Result<u64, StoreError> {
        let n: i64 =
            sqlx::query_scalar("SELECT COUNT(*) FROM jobs WHERE tenant = ? AND status = 'queued'")
                .bind(tenant)
                .fetch_one(&self.pool)
                .await?;
        Ok(n as u64)
    }

    async fn get(&self, tenant: Option<&str>, id: JobId) -> Result<Option<Job>, StoreError> {
        let sql = format!("SELECT {COLUMNS} FROM jobs WHERE id = ? AND (? IS NULL OR tenant = ?)");
        let row = sqlx::query(&sql)
            .bind(id.to_string())
            .bind(tenant)
            .bind(tenant)
            .fetch_optional(&self.pool)
            .await?;
        row.as_ref().map(Self::row_to_job).transpose()
    }

    async fn list(&self, q: &ListQuery) -> Result<Vec<Job>, StoreError> {
        // Every wanted tag is among the job's tags.
        let sql = format!(
            "SELECT {COLUMNS} FROM jobs WHERE tenant = ? AND (? IS NULL OR status = ?) \
             AND (? IS NULL OR id < ?) AND (? IS NULL OR external_ref = ?) \
             AND NOT EXISTS (SELECT 1 FROM json_each(?) w \
                             WHERE w.value NOT IN (SELECT value FROM json_each(jobs.tags))) \
             ORDER BY id DESC LIMIT ?"
        );
        let status = q.status.map(|s| s.as_str());
        let before = q.before.map(|b| b.to_string());
        let tags = serde_json::to_string(&q.tags).map_err(|e| StoreError(e.to_string()))?;
        let rows = sqlx::query(&sql)
            .bind(&q.tenant)
            .bind(status)
            .bind(status)
            .bind(&before)
            .bind(&before)
            .bind(&q.external_ref)
            .bind(&q.external_ref)
            .bind(tags)
            .bind(q.limit as i64)
            .fetch_all(&self.pool)
            .await?;
        rows.iter().map(Self::row_to_job).collect()
    }

    async fn claim(&self, owner: &str, lease_ms: i64) -> Result<Option<Job>, StoreError> {
        let now = now_ms();
        // One statement: SQLite serialises writers, so two workers never take the same row.
        // Each tenant's oldest queued job competes; the tenant order is the trait's.
        let sql = format!(
            "UPDATE jobs SET status = 'running', lease_owner = ?, lease_until = ?, \
             attempts = attempts + 1, started_at = COALESCE(started_at, ?), updated_at = ?, \
             stage = NULL, progress = 0 \
             WHERE id = ( \
                WITH heads AS (SELECT tenant, MIN(id) AS id FROM jobs \
                               WHERE status = 'queued' GROUP BY tenant) \
                SELECT h.id FROM heads h ORDER BY \
                  (SELECT COUNT(*) FROM jobs r WHERE r.tenant = h.tenant AND r.status = 'running'), \
                  (SELECT MAX(s.started_at) FROM jobs s \
                   WHERE s.tenant = h.tenant AND s.started_at IS NOT NULL), \
                  h.id \
                LIMIT 1) \
             AND status = 'queued' RETURNING {COLUMNS}"
        );
        let row = sqlx::query(&sql)
            .bind(owner)
            .bind(now + lease_ms)
            .bind(now)
            .bind(now)
            .fetch_optional(&self.pool)
            .await?;
        row.as_ref().map(Self::row_to_job).transpose()
    }

    async fn heartbeat(
        &self,
        id: JobId,
        owner: &str,
        lease_ms: i64,
        beat: &Beat,
    ) -> Result<Heartbeat, StoreError> {
        let now = now_ms();
        let done = sqlx::query(
            "UPDATE jobs SET lease_until = ?, stage = ?, progress = ?, progress_detail = ?, \
             input = COALESCE(?, input), updated_at = ? \
             WHERE id = ? AND status = 'running' AND lease_owner = ?",
        )
        .bind(now + lease_ms)
        .bind(&beat.stage)
        .bind(beat.progress.clamp(0.0, 1.0))
        .bind(beat.detail.as_ref().map(|v| v.to_string()))
        .bind(beat.input.as_ref().map(|v| v.to_string()))
        .bind(now)
        .bind(id.to_string())
        .bind(owner)
        .execute(&self.pool)
        .await?;
        Ok(if done.rows_affected() == 1 {
            Heartbeat::Held
        } else {
            Heartbeat::Lost
        })
    }

    async fn complete(
        &self,
        id: JobId,
        owner: &str,
        outcome: &JobOutcome,
    ) -> Result<bool, StoreError> {
        let now = now_ms();
        let done = sqlx::query(
            "UPDATE jobs SET status = 'succeeded', stage = NULL, progress = 1, input = ?, \
             timings = ?, lease_owner = NULL, lease_until = NULL, finished_at = ?, updated_at = ? \
             WHERE id = ? AND status = 'running' AND lease_owner = ?",
        )
        .bind(outcome.input.to_string())
        .bind(outcome.timings.to_string())
        .bind(now)
        .bind(now)
        .bind(id.to_string())
        .bind(owner)
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    async fn fail(
        &self,
        id: JobId,
        owner: &str,
        error: &JobError,
        stage: Option<&str>,
    ) -> Result<bool, StoreError> {
        let now = now_ms();
        let done = sqlx::query(
            "UPDATE jobs SET status = 'failed', error_code = ?, error_message = ?, \
             stage = COALESCE(?, stage), \
             lease_owner = NULL, lease_until = NULL, finished_at = ?, updated_at = ? \
             WHERE id = ? AND status = 'running' AND lease_owner = ?",
        )
        .bind(&error.code)
        .bind(&error.message)
        .bind(stage)
        .bind(now)
        .bind(now)
        .bind(id.to_string())
        .bind(owner)
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    async fn release(&self, id: JobId, owner: &str) -> Result<bool, StoreError> {
        let done = sqlx::query(
            "UPDATE jobs SET status = 'queued', stage = NULL, progress = 0, \
             attempts = MAX(attempts - 1, 0), lease_owner = NULL, lease_until = NULL, updated_at = ? \
             WHERE id = ? AND status = 'running' AND lease_owner = ?",
        )
        .bind(now_ms())
        .bind(id.to_string())
        .bind(owner)
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    async fn release_all(&self, prefix: &str) -> Result<Vec<JobId>, StoreError> {
        let rows = sqlx::query(
            "UPDATE jobs SET status = 'queued', stage = NULL, progress = 0, \
             attempts = MAX(attempts - 1, 0), lease_owner = NULL, lease_until = NULL, updated_at = ? \
             WHERE status = 'running' AND substr(lease_owner, 1, length(?)) = ? RETURNING id",
        )
        .bind(now_ms())
        .bind(prefix)
        .bind(prefix)
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| {
                let s: String = r.try_get("id")?;
                JobId::from_str(&s).map_err(|e| StoreError(e.to_string()))
            })
            .collect()
    }

    async fn requeue_expired(&self) -> Result<Expired, StoreError> {
        let now = now_ms();
        let mut tx = self.pool.begin().await?;
        let failed = sqlx::query(
            "UPDATE jobs SET status = 'failed', error_code = ?, \
             error_message = 'the job''s worker stopped before finishing, ' || attempts || ' times', \
             lease_owner = NULL, lease_until = NULL, finished_at = ?, updated_at = ? \
             WHERE status = 'running' AND lease_until < ? AND attempts >= max_attempts RETURNING id",
        )
        .bind(WORKER_LOST)
        .bind(now)
        .bind(now)
        .bind(now)
        .fetch_all(&mut *tx)
        .await?;
        let requeued = sqlx::query(
            "UPDATE jobs SET status = 'queued', stage = NULL, progress = 0, lease_owner = NULL, \
             lease_until = NULL, updated_at = ? \
             WHERE status = 'running' AND lease_until < ? RETURNING id",
        )
        .bind(now)
        .bind(now)
        .fetch_all(&mut *tx)
        .await?;
        tx.commit().await?;
        let ids = |rows: Vec<SqliteRow>| -> Result<Vec<JobId>, StoreError> {
            rows.iter()
                .map(|r| {
                    let s: String = r.try_get("id")?;
                    JobId::from_str(&s).map_err(|e| StoreError(e.to_string()))
                })
                .collect()
        };
        Ok(Expired {
            requeued: ids(requeued)?,
            failed: ids(failed)?,
        })
    }

    async fn cancel(&self, tenant: &str, id: JobId) -> Result<Option<Job>, StoreError> {
        let now = now_ms();
        // A running job's worker learns of it at its next heartbeat and stops.
        sqlx::query(
            "UPDATE jobs SET status = 'cancelled', lease_owner = NULL, lease_until = NULL, \
             finished_at = ?, updated_at = ? \
             WHERE id = ? AND tenant = ? AND status IN ('queued', 'running')",
        )
        .bind(now)
        .bind(now)
        .bind(id.to_string())
        .bind(tenant)
        .execute(&self.pool)
        .await?;
        self.get(Some(tenant), id).await
    }

    async fn delete(&self, id: JobId) -> Result<bool, StoreError> {
        let mut tx = self.pool.begin().await?;
        sqlx::query("DELETE FROM webhook_deliveries WHERE job_id = ?")
            .bind(id.to_string())
            .execute(&mut *tx)
            .await?;
        let done = sqlx::query("DELETE FROM jobs WHERE id = ?")
            .bind(id.to_string())
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(done.rows_affected() == 1)
    }

    async fn expire(&self, id: JobId) -> Result<bool, StoreError> {
        let mut tx = self.pool.begin().await?;
        sqlx::query(
            "INSERT OR REPLACE INTO job_tombstones (id, tenant, expired_at) \
             SELECT id, tenant, ? FROM jobs WHERE id = ?",
        )
        .bind(now_ms())
        .bind(id.to_string())
        .execute(&mut *tx)
        .await?;
        sqlx::query("DELETE FROM webhook_deliveries WHERE job_id = ?")
            .bind(id.to_string())
            .execute(&mut *tx)
            .await?;
        let done = sqlx::query("DELETE FROM jobs WHERE id = ?")
            .bind(id.to_string())
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(done.rows_affected() == 1)
    }

    async fn expired_at(&self, tenant: &str, id: JobId) -> Result<Option<i64>, StoreError> {
        let at =
            sqlx::query_scalar("SELECT expired_at FROM job_tombstones WHERE id = ? AND tenant = ?")
                .bind(id.to_string())
                .bind(tenant)
                .fetch_optional(&self.pool)
                .await?;
        Ok(at)
    }

    async fn forget_expired(&self, before_ms: i64) -> Result<u64, StoreError> {
        let done = sqlx::query("DELETE FROM job_tombstones WHERE expired_at < ?")
            .bind(before_ms)
            .execute(&self.pool)
            .await?;
        Ok(done.rows_affected())
    }

    async fn claim_hooks(&self, lease_ms: i64, limit: u32) -> Result<Vec<(Job, u32)>, StoreError> {
        let now = now_ms();
        let sql = format!(
            "UPDATE jobs SET hook_due = ? WHERE id IN (SELECT id FROM jobs \
             WHERE hook_due IS NOT NULL AND hook_due <= ? \
             AND status IN ('succeeded', 'failed', 'cancelled') ORDER BY hook_due LIMIT ?) \
             RETURNING {COLUMNS}, hook_attempts"
        );
        let rows = sqlx::query(&sql)
            .bind(now + lease_ms)
            .bind(now)
            .bind(limit as i64)
            .fetch_all(&self.pool)
            .await?;
        rows.iter()
            .map(|r| {
                Ok((
                    Self::row_to_job(r)?,
                    r.try_get::<i64, _>("hook_attempts")? as u32,
                ))
            })
            .collect()
    }

    async fn hook_tried(
        &self,
        id: JobId,
        attempts: u32,
        next_due: Option<i64>,
    ) -> Result<(), StoreError> {
        sqlx::query("UPDATE jobs SET hook_attempts = ?, hook_due = ? WHERE id = ?")
            .bind(attempts as i64)
            .bind(next_due)
            .bind(id.to_string())
            .execute(&self.pool)
            .await?;
        Ok(())
    }

    async fn record_delivery(&self, d: &Delivery) -> Result<(), StoreError> {
        sqlx::query(
            "INSERT INTO webhook_deliveries (id, job_id, event, url, attempt, at, status_code, \
             error, duration_ms) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
        )
        .bind(d.id.to_string())
        .bind(d.job.to_string())
        .bind(&d.event)
        .bind(&d.url)
        .bind(d.attempt as i64)
        .bind(d.at)
        .bind(d.status.map(i64::from))
        .bind(&d.error)
        .bind(d.duration_ms)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    async fn deliveries(&self, id: JobId) -> Result<Vec<Delivery>, StoreError> {
        let rows = sqlx::query(
            "SELECT id, job_id, event, url, attempt, at, status_code, error, duration_ms \
             FROM webhook_deliveries WHERE job_id = ? ORDER BY at, attempt",
        )
        .bind(id.to_string())
        .fetch_all(&self.pool)
        .await?;
        rows.iter().map(Self::row_to_delivery).collect()
    }

    async fn finished_before(&self, before_ms: i64, limit: u32) -> Result<Vec<JobId>, StoreError> {
        let rows = sqlx::query(
            "SELECT id FROM jobs WHERE finished_at IS NOT NULL AND finished_at < ? \
             ORDER BY finished_at LIMIT ?",
        )
        .bind(before_ms)
        .bind(limit as i64)
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| {
                let s: String = r.try_get("id")?;
                JobId::from_str(&s).map_err(|e| StoreError(e.to_string()))
            })
            .collect()
    }

    async fn counts_by_status(&self) -> Result<Vec<(JobStatus, u64)>, StoreError> {
        let rows = sqlx::query("SELECT status, COUNT(*) AS n FROM jobs GROUP BY status")
            .fetch_all(&self.pool)
            .await?;
        let mut counts: Vec<(JobStatus, u64)> = JobStatus::ALL.iter().map(|&s| (s, 0)).collect();
        for row in rows {
            let status: String = row.try_get("status")?;
            let n: i64 = row.try_get("n")?;
            let status = JobStatus::from_str(&status).map_err(StoreError)?;
            if let Some(slot) = counts.iter_mut().find(|(s, _)| *s == status) {
                slot.1 = n as u64;
            }
        }
        Ok(counts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::queue::UploadInfo;

    async fn store() -> (tempfile::TempDir, SqliteJobStore) {
        let dir = tempfile::tempdir().unwrap();
        let store = SqliteJobStore::open(&dir.path().join("jobs.db"))
            .await
            .unwrap();
        store.migrate().await.unwrap();
        (dir, store)
    }

    fn new_job(tenant: &str, max_attempts: u32) -> NewJob {
        NewJob {
            id: JobId::new(),
            tenant: tenant.into(),
            params: serde_json::json!({}),
            upload: UploadInfo {
                bytes: 3,
                sha256: "ab".into(),
                format: "ply".into(),
                ..Default::default()
            },
            max_attempts,
            ..Default::default()
        }
    }

    fn beat() -> Beat {
        Beat {
            stage: Some("samples".into()),
            progress: 0.5,
            input: None,
            detail: None,
        }
    }

    #[tokio::test]
    async fn claim_heartbeat_complete() {
        let (_d, s) = store().await;
        let job = s.create(new_job("a", 3)).await.unwrap();
        assert_eq!(job.status, JobStatus::Queued);
        let claimed = s.claim("w1", 10_000).await.unwrap().unwrap();
        assert_eq!((claimed.id, claimed.attempts), (job.id, 1));
        assert!(s.claim("w2", 10_000).await.unwrap().is_none());
        assert_eq!(
            s.heartbeat(job.id, "w2", 10_000, &beat()).await.unwrap(),
            Heartbeat::Lost
        );
        assert_eq!(
            s.heartbeat(job.id, "w1", 10_000, &beat()).await.unwrap(),
            Heartbeat::Held
        );
        let got = s.get(Some("a"), job.id).await.unwrap().unwrap();
        assert_eq!((got.stage.as_deref(), got.progress), (Some("samples"), 0.5));
        let outcome = JobOutcome {
            input: serde_json::json!({"points": 9}),
            timings: serde_json::json!({"total": 1}),
        };
        assert!(!s.complete(job.id, "w2", &outcome).await.unwrap());
        assert!(s.complete(job.id, "w1", &outcome).await.unwrap());
        let got = s.get(None, job.id).await.unwrap().unwrap();
        assert_eq!(got.status, JobStatus::Succeeded);
        assert_eq!(got.input.unwrap()["points"], 9);
        assert!(s.get(Some("b"), job.id).await.unwrap().is_none());
    }

    #[tokio::test]
    async fn expired_leases_requeue_then_fail() {
        let (_d, s) = store().await;
        let job = s.create(new_job("a", 2)).await.unwrap();
        for attempt in 1..=2 {
            let c = s.claim("w", 1).await.unwrap().unwrap();
            assert_eq!(c.attempts, attempt);
            tokio::time::sleep(Duration::from_millis(5)).await;
            let e = s.requeue_expired().await.unwrap();
            if attempt == 1 {
                assert_eq!(e.requeued, vec![job.id]);
            } else {
                assert_eq!(e.failed, vec![job.id]);
            }
        }
        let got = s.get(None, job.id).await.unwrap().unwrap();
        assert_eq!(got.status, JobStatus::Failed);
        assert_eq!(got.error.unwrap().code, WORKER_LOST);
    }

    #[tokio::test]
    async fn release_gives_the_attempt_back_and_cancel_stops_the_worker() {
        let (_d, s) = store().await;
        let job = s.create(new_job("a", 3)).await.unwrap();
        s.claim("w", 10_000).await.unwrap().unwrap();
        assert!(s.release(job.id, "w").await.unwrap());
        let again = s.claim("w", 10_000).await.unwrap().unwrap();
        assert_eq!(again.attempts, 1);
        assert!(s.cancel("b", job.id).await.unwrap().is_none());
        let c = s.cancel("a", job.id).await.unwrap().unwrap();
        assert_eq!(c.status, JobStatus::Cancelled);
        assert_eq!(
            s.heartbeat(job.id, "w", 10_000, &beat()).await.unwrap(),
            Heartbeat::Lost
        );
        assert!(s.delete(job.id).await.unwrap());
        assert!(s.get(None, job.id).await.unwrap().is_none());
    }

    #[tokio::test]
    async fn lists_newest_first_by_tenant_and_status() {
        let (_d, s) = store().await;
        let mut ids = vec![];
        for _ in 0..5 {
            ids.push(s.create(new_job("a", 3)).await.unwrap().id);
        }
        s.create(new_job("b", 3)).await.unwrap();
        let mut q = ListQuery {
            tenant: "a".into(),
            limit: 2,
            ..Default::default()
        };
        let mut seen = vec![];
        loop {
            let page = s.list(&q).await.unwrap();
            if page.is_empty() {
                break;
            }
            q.before = Some(page.last().unwrap().id);
            seen.extend(page.into_iter().map(|j| j.id));
        }
        ids.sort();
        ids.reverse();
        assert_eq!(seen, ids);
        s.claim("w", 10_000).await.unwrap();
        q.before = None;
        q.limit = 10;
        q.status = Some(JobStatus::Running);
        assert_eq!(s.list(&q).await.unwrap().len(), 1);
        let counts = s.counts_by_status().await.unwrap();
        assert_eq!(counts[0], (JobStatus::Queued, 5));
        assert_eq!(counts[1], (JobStatus::Running, 1));
    }
}
