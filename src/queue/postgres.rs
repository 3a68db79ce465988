//! Job state in PostgreSQL, shared by any number of API and worker processes on any hosts.
//!
//! - Workers claim with `FOR UPDATE SKIP LOCKED`, so two claims never wait on or take the same
//!   row; every later step checks `lease_owner`, so a worker that lost its lease changes nothing.
//! - A trigger notifies the channel `asbuilt_jobs_<schema>` whenever a job becomes queued;
//!   [`JobStore::wait_for_work`] wakes on it, and falls back to polling if the listener is down.
//! - Migrations are versioned and embedded; `asbuilt migrate` applies them, and every other
//!   role checks at start-up ([`JobStore::check_schema`]) that the database matches the binary.

use std::borrow::Cow;
use std::str::FromStr;
use std::sync::Arc;
use std::time::Duration;

use async_trait::async_trait;
use futures_util::future::BoxFuture;
use sqlx::error::BoxDynError;
use sqlx::migrate::{Migrate, Migration, MigrationSource, MigrationType, Migrator};
use sqlx::postgres::{PgConnectOptions, PgListener, PgPool, PgPoolOptions, PgRow};
use sqlx::{ConnectOptions, Row};
use tokio::sync::Notify;

use super::sqlite::{is_unique_violation, json_text};
use super::{
    now_ms, Beat, Delivery, Expired, Heartbeat, Idempotency, Inserted, Job, JobError, JobId,
    JobMeta, JobOutcome, JobStatus, JobStore, ListQuery, NewJob, StoreError, WORKER_LOST,
};

/// The PostgreSQL migrations, in order: (version, description, SQL).
const MIGRATIONS: &[(i64, &str, &str)] = &[
    (
        1,
        "jobs",
        include_str!("../../migrations/postgres/0001_jobs.sql"),
    ),
    (
        2,
        "tenant fairness",
        include_str!("../../migrations/postgres/0002_tenant_fairness.sql"),
    ),
    (
        3,
        "job api",
        include_str!("../../migrations/postgres/0003_job_api.sql"),
    ),
    (
        4,
        "progress detail",
        include_str!("../../migrations/postgres/0004_progress_detail.sql"),
    ),
];

fn migrations() -> Vec<Migration> {
    MIGRATIONS
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
        .collect()
}

/// Hands sqlx the migrations embedded above.
#[derive(Debug)]
struct Embedded;

impl<'s> MigrationSource<'s> for Embedded {
    fn resolve(self) -> BoxFuture<'s, Result<Vec<Migration>, BoxDynError>> {
        Box::pin(async { Ok(migrations()) })
    }
}

const COLUMNS: &str = "id::text AS id, tenant, status, stage, progress, \
     progress_detail::text AS progress_detail, params::text AS params, \
     upload::text AS upload, input::text AS input, timings::text AS timings, error_code, \
     error_message, attempts, max_attempts, created_at, started_at, finished_at, updated_at, \
     external_ref, tags::text AS tags, idempotency_key, request_hash, \
     input_job::text AS input_job, callback_url";

/// The columns a new job sets, and their values as bound by [`PgJobStore::bind_new`].
const NEW_COLUMNS: &str = "id, tenant, status, progress, params, upload, attempts, \
     max_attempts, created_at, updated_at, external_ref, tags, idempotency_key, request_hash, \
     input_job, callback_url, hook_due";
const NEW_VALUES: &str = "$1::uuid, $2, 'queued', 0, $3::jsonb, $4::jsonb, 0, $5, $6, $6, $7, \
     $8::jsonb, $9, $10, $11::uuid, $12, $13";

/// Job state in a PostgreSQL database (one schema of it).
#[derive(Clone)]
pub struct PgJobStore {
    pool: PgPool,
    /// Signalled by the listener task on each notification; created on first wait.
    wake: Arc<tokio::sync::OnceCell<Arc<Notify>>>,
}

/// How long the pool keeps trying to open a connection, at start and for each query.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// Why no connection to the server of `options` could be opened within [`CONNECT_TIMEOUT`],
/// from one last attempt.
async fn unreachable_server(options: &PgConnectOptions) -> StoreError {
    let why = match tokio::time::timeout(CONNECT_TIMEOUT, options.connect()).await {
        Ok(Err(e)) => e.to_string(),
        Ok(Ok(_)) => "it answered only after the timeout".to_string(),
        Err(_) => "it did not answer".to_string(),
    };
    StoreError(format!(
        "no connection to {}:{} within {} s: {why}",
        options.get_host(),
        options.get_port(),
        CONNECT_TIMEOUT.as_secs()
    ))
}

impl PgJobStore {
    /// Connects to `postgres://...`. A `?options=-c search_path=NAME` parameter selects a schema.
    pub async fn connect(url: &str) -> Result<PgJobStore, StoreError> {
        let options = PgConnectOptions::from_str(url)
            .map_err(|e| StoreError(format!("bad database URL: {e}")))?;
        PgJobStore::connect_with(options).await
    }

    /// Connects with explicit options (tests use them to pick a schema).
    pub async fn connect_with(options: PgConnectOptions) -> Result<PgJobStore, StoreError> {
        let pool = PgPoolOptions::new()
            .max_connections(8)
            .acquire_timeout(CONNECT_TIMEOUT)
            .connect_with(options.clone())
            .await;
        let pool = match pool {
            Ok(pool) => pool,
            // The pool retries a refused or failed connection until its timeout, then names
            // only the timeout: one more attempt names the cause.
            Err(sqlx::Error::PoolTimedOut) => return Err(unreachable_server(&options).await),
            Err(e) => return Err(e.into()),
        };
        Ok(PgJobStore {
            pool,
            wake: Arc::new(tokio::sync::OnceCell::new()),
        })
    }

    /// The notification channel of this store's schema.
    async fn channel(&self) -> Result<String, StoreError> {
        let schema: String = sqlx::query_scalar("SELECT current_schema()")
            .fetch_one(&self.pool)
            .await?;
        Ok(format!("asbuilt_jobs_{schema}"))
    }

    /// Starts (once) a task that listens for new work and wakes waiting workers.
    async fn wake_signal(&self) -> Result<Arc<Notify>, StoreError> {
        let store = self.clone();
        self.wake
            .get_or_try_init(|| async move {
                let channel = store.channel().await?;
                let mut listener = PgListener::connect_with(&store.pool).await?;
                listener.listen(&channel).await?;
                let notify = Arc::new(Notify::new());
                let signal = notify.clone();
                tokio::spawn(async move {
                    loop {
                        // recv reconnects after a dropped connection; notifications sent while
                        // it was down are lost, which the polling fallback covers.
                        match listener.recv().await {
                            Ok(_) => signal.notify_waiters(),
                            Err(e) => {
                                tracing::warn!("job listener: {e}; retrying");
                                tokio::time::sleep(Duration::from_secs(1)).await;
                            }
                        }
                    }
                });
                Ok(notify)
            })
            .await
            .cloned()
    }

    fn row_to_job(row: &PgRow) -> Result<Job, StoreError> {
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
            attempts: row.try_get::<i32, _>("attempts")? as u32,
            max_attempts: row.try_get::<i32, _>("max_attempts")? as u32,
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

    /// Binds a new job's values ($1 to $13 of [`NEW_VALUES`]).
    fn bind_new<'q>(
        query: sqlx::query::Query<'q, sqlx::Postgres, sqlx::postgres::PgArguments>,
        job: &NewJob,
        now: i64,
    ) -> Result<sqlx::query::Query<'q, sqlx::Postgres, sqlx::postgres::PgArguments>, StoreError>
    {
        Ok(query
            .bind(job.id.to_string())
            .bind(job.tenant.clone())
            .bind(job.params.to_string())
            .bind(json_text(&job.upload)?)
            .bind(job.max_attempts as i32)
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

    fn row_to_delivery(row: &PgRow) -> Result<Delivery, StoreError> {
        let id: String = row.try_get("id")?;
        let job: String = row.try_get("job_id")?;
        Ok(Delivery {
            id: uuid::Uuid::parse_str(&id).map_err(|e| StoreError(e.to_string()))?,
            job: JobId::from_str(&job).map_err(|e| StoreError(e.to_string()))?,
            event: row.try_get("event")?,
            url: row.try_get("url")?,
            attempt: row.try_get::<i32, _>("attempt")? as u32,
            at: row.try_get("at")?,
            status: row
                .try_get::<Option<i32>, _>("status_code")?
                .map(|s| s as u16),
            error: row.try_get("error")?,
            duration_ms: row.try_get("duration_ms")?,
        })
    }

    fn ids(rows: &[PgRow]) -> Result<Vec<JobId>, StoreError> {
        rows.iter()
            .map(|r| {
                let s: String = r.try_get("id")?;
                JobId::from_str(&s).map_err(|e| StoreError(e.to_string()))
            })
            .collect()
    }
}

/// Compares the applied migrations with the embedded ones.
fn schema_verdict(applied: &[(i64, Vec<u8>)], known: &[Migration]) -> Result<(), StoreError> {
    let newest_known = known.iter().map(|m| m.version).max().unwrap_or(0);
    for (version, checksum) in applied {
        match known.iter().find(|m| m.version == *version) {
            None => {
                return Err(StoreError(format!(
                    "the database schema has migration {version}, newer than this binary \
                     knows (up to {newest_known}); run a newer asbuilt"
                )))
            }
            Some(m) if m.checksum.as_ref() != checksum.as_slice() => {
                return Err(StoreError(format!(
                    "migration {version} ({}) was changed after it was applied",
                    m.description
                )))
            }
            Some(_) => {}
        }
    }
    let missing: Vec<String> = known
        .iter()
        .filter(|m| !applied.iter().any(|(v, _)| *v == m.version))
        .map(|m| m.version.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(StoreError(format!(
            "the database schema lacks migration(s) {}; run `asbuilt migrate`",
            missing.join(", ")
        )));
    }
    Ok(())
}

#[async_trait]
impl JobStore for PgJobStore {
    async fn migrate(&self) -> Result<(), StoreError> {
        // sqlx takes an advisory lock, so concurrent `migrate` runs apply each step once.
        let migrator = Migrator::new(Embedded)
            .await
            .map_err(|e| StoreError(e.to_string()))?;
        migrator
            .run(&self.pool)
            .await
            .map_err(|e| StoreError(e.to_string()))
    }

    async fn check_schema(&self) -> Result<(), StoreError> {
        let mut conn = self.pool.acquire().await?;
        let exists: bool = sqlx::query_scalar(
            "SELECT EXISTS (SELECT 1 FROM pg_tables \
             WHERE schemaname = current_schema() AND tablename = '_sqlx_migrations')",
        )
        .fetch_one(&mut *conn)
        .await?;
        if !exists {
            return Err(StoreError(
                "the database has no asbuilt schema yet; run `asbuilt migrate`".into(),
            ));
        }
        if let Some(v) = conn
            .dirty_version()
            .await
            .map_err(|e| StoreError(e.to_string()))?
        {
            return Err(StoreError(format!(
                "migration {v} failed part-way; fix the database and run `asbuilt migrate`"
            )));
        }
        let applied: Vec<(i64, Vec<u8>)> = conn
            .list_applied_migrations()
            .await
            .map_err(|e| StoreError(e.to_string()))?
            .into_iter()
            .map(|m| (m.version, m.checksum.into_owned()))
            .collect();
        schema_verdict(&applied, &migrations())
    }

    async fn ping(&self) -> Result<(), StoreError> {
        sqlx::query("SELECT 1").execute(&self.pool).await?;
        Ok(())
    }

    async fn wait_for_work(&self, timeout: Duration) {
        match self.wake_signal().await {
            Ok(notify) => {
                let _ = tokio::time::timeout(timeout, notify.notified()).await;
            }
            Err(e) => {
                tracing::warn!("cannot listen for new jobs ({e}); polling");
                tokio::time::sleep(timeout).await;
            }
        }
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
        let mut tx = self.pool.begin().await?;
        if let Some((source, _)) = job.replan_of {
            // Held until commit: a delete of the source waits for this job to be recorded, and
            // then sees it reading the upload.
            let found: Option<i32> =
                sqlx::query_scalar("SELECT 1 FROM jobs WHERE id = $1::uuid FOR SHARE")
                    .bind(source.to_string())
                    .fetch_optional(&mut *tx)
                    .await?;
            if found.is_none() {
                return Ok(Inserted::SourceGone);
            }
        }
        if max_queued > 0 {
            // Concurrent uploads of one tenant (in any process) take turns on the tenant's
            // lock, so the count cannot change between the check and the insert.
            sqlx::query("SELECT pg_advisory_xact_lock(hashtextextended($1, 0))")
                .bind(format!("asbuilt queued {}", job.tenant))
                .execute(&mut *tx)
                .await?;
            let queued: i64 = sqlx::query_scalar(
                "SELECT COUNT(*) FROM jobs WHERE tenant = $1 AND status = 'queued'",
            )
            .bind(&job.tenant)
            .fetch_one(&mut *tx)
            .await?;
            if queued >= max_queued as i64 {
                return Ok(Inserted::QueueFull);
            }
        }
        let sql =
            format!("INSERT INTO jobs ({NEW_COLUMNS}) VALUES ({NEW_VALUES}) RETURNING {COLUMNS}");
        let row = match Self::bind_new(sqlx::query(&sql), &job, now_ms())?
            .fetch_one(&mut *tx)
            .await
        {
            Ok(row) => row,
            Err(e) if is_unique_violation(&e) && job.idempotency.is_some() => {
                return Ok(Inserted::KeyTaken)
            }
            Err(e) => return Err(e.into()),
        };
        tx.commit().await?;
        Self::row_to_job(&row).map(|j| Inserted::Created(Box::new(j)))
    }

    async fn by_idempotency_key(&self, tenant: &str, key: &str) -> Result<Option<Job>, StoreError> {
        let sql = format!("SELECT {COLUMNS} FROM jobs WHERE tenant = $1 AND idempotency_key = $2");
        let row = sqlx::query(&sql)
            .bind(tenant)
            .bind(key)
            .fetch_optional(&self.pool)
            .await?;
        row.as_ref().map(Self::row_to_job).transpose()
    }

    async fn upload_in_use(&self, input_job: JobId) -> Result<bool, StoreError> {
        let used: bool = sqlx::query_scalar(
            "SELECT EXISTS (SELECT 1 FROM jobs WHERE id = $1::uuid) \
             OR EXISTS (SELECT 1 FROM jobs WHERE input_job = $1::uuid)",
        )
        .bind(input_job.to_string())
        .fetch_one(&self.pool)
        .await?;
        Ok(used)
    }

    async fn queued_count(&self, tenant: &str) -> Result<u64, StoreError> {
        let n: i64 =
            sqlx::query_scalar("SELECT COUNT(*) FROM jobs WHERE tenant = $1 AND status = 'queued'")
                .bind(tenant)
                .fetch_one(&self.pool)
                .await?;
        Ok(n as u64)
    }

    async fn get(&self, tenant: Option<&str>, id: JobId) -> Result<Option<Job>, StoreError> {
        let sql = format!(
            "SELECT {COLUMNS} FROM jobs WHERE id = $1::uuid AND ($2::text IS NULL OR tenant = $2)"
        );
        let row = sqlx::query(&sql)
            .bind(id.to_string())
            .bind(tenant)
            .fetch_optional(&self.pool)
            .await?;
        row.as_ref().map(Self::row_to_job).transpose()
    }

    async fn list(&self, q: &ListQuery) -> Result<Vec<Job>, StoreError> {
        let sql = format!(
            "SELECT {COLUMNS} FROM jobs WHERE tenant = $1 AND ($2::text IS NULL OR status = $2) \
             AND ($3::uuid IS NULL OR id < $3::uuid) AND ($5::text IS NULL OR external_ref = $5) \
             AND tags @> $6::jsonb ORDER BY id DESC LIMIT $4"
        );
        let rows = sqlx::query(&sql)
            .bind(&q.tenant)
            .bind(q.status.map(|s| s.as_str()))
            .bind(q.before.map(|b| b.to_string()))
            .bind(q.limit as i64)
            .bind(&q.external_ref)
            .bind(json_text(&q.tags)?)
            .fetch_all(&self.pool)
            .await?;
        rows.iter().map(Self::row_to_job).collect()
    }

    async fn claim(&self, owner: &str, lease_ms: i64) -> Result<Option<Job>, StoreError> {
        let now = now_ms();
        // SKIP LOCKED: a row another worker is claiming right now is passed over, not waited on.
        let sql = format!(
            "UPDATE jobs SET status = 'running', lease_owner = $1, lease_until = $2, \
             attempts = attempts + 1, started_at = COALESCE(started_at, $3), updated_at = $3, \
             stage = NULL, progress = 0 \
             WHERE id = (SELECT q.id FROM jobs q WHERE q.status = 'queued' ORDER BY \
                  (SELECT COUNT(*) FROM jobs r WHERE r.tenant = q.tenant AND r.status = 'running'), \
                  (SELECT MAX(s.started_at) FROM jobs s \
                   WHERE s.tenant = q.tenant AND s.started_at IS NOT NULL) NULLS FIRST, \
                  q.id \
                LIMIT 1 FOR UPDATE SKIP LOCKED) \
             RETURNING {COLUMNS}"
        );
        let row = sqlx::query(&sql)
            .bind(owner)
            .bind(now + lease_ms)
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
            "UPDATE jobs SET lease_until = $1, stage = $2, progress = $3, \
             input = COALESCE($4::jsonb, input), updated_at = $5, progress_detail = $8::jsonb \
             WHERE id = $6::uuid AND status = 'running' AND lease_owner = $7",
        )
        .bind(now + lease_ms)
        .bind(&beat.stage)
        .bind(beat.progress.clamp(0.0, 1.0))
        .bind(beat.input.as_ref().map(|v| v.to_string()))
        .bind(now)
        .bind(id.to_string())
        .bind(owner)
        .bind(beat.detail.as_ref().map(|v| v.to_string()))
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
            "UPDATE jobs SET status = 'succeeded', stage = NULL, progress = 1, input = $1::jsonb, \
             timings = $2::jsonb, lease_owner = NULL, lease_until = NULL, finished_at = $3, \
             updated_at = $3 WHERE id = $4::uuid AND status = 'running' AND lease_owner = $5",
        )
        .bind(outcome.input.to_string())
        .bind(outcome.timings.to_string())
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
            "UPDATE jobs SET status = 'failed', error_code = $1, error_message = $2, \
             stage = COALESCE($6, stage), \
             lease_owner = NULL, lease_until = NULL, finished_at = $3, updated_at = $3 \
             WHERE id = $4::uuid AND status = 'running' AND lease_owner = $5",
        )
        .bind(&error.code)
        .bind(&error.message)
        .bind(now)
        .bind(id.to_string())
        .bind(owner)
        .bind(stage)
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    async fn release(&self, id: JobId, owner: &str) -> Result<bool, StoreError> {
        let done = sqlx::query(
            "UPDATE jobs SET status = 'queued', stage = NULL, progress = 0, \
             attempts = GREATEST(attempts - 1, 0), lease_owner = NULL, lease_until = NULL, \
             updated_at = $1 WHERE id = $2::uuid AND status = 'running' AND lease_owner = $3",
        )
        .bind(now_ms())
        .bind(id.to_string())
        .bind(owner)
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    async fn release_all(&self, prefix: &str) -> Result<Vec<JobId>, StoreError> {
        let ids: Vec<String> = sqlx::query_scalar(
            "UPDATE jobs SET status = 'queued', stage = NULL, progress = 0, \
             attempts = GREATEST(attempts - 1, 0), lease_owner = NULL, lease_until = NULL, \
             updated_at = $1 WHERE status = 'running' AND starts_with(lease_owner, $2) \
             RETURNING id::text",
        )
        .bind(now_ms())
        .bind(prefix)
        .fetch_all(&self.pool)
        .await?;
        ids.iter()
            .map(|s| JobId::from_str(s).map_err(|e| StoreError(e.to_string())))
            .collect()
    }

    async fn requeue_expired(&self) -> Result<Expired, StoreError> {
        let now = now_ms();
        // Several processes may run this at once: each UPDATE re-checks its WHERE on rows another
        // transaction just changed, so a job is requeued or failed once.
        let mut tx = self.pool.begin().await?;
        let failed = sqlx::query(
            "UPDATE jobs SET status = 'failed', error_code = $1, \
             error_message = 'the job''s worker stopped before finishing, ' || attempts || ' times', \
             lease_owner = NULL, lease_until = NULL, finished_at = $2, updated_at = $2 \
             WHERE status = 'running' AND lease_until < $2 AND attempts >= max_attempts \
             RETURNING id::text AS id",
        )
        .bind(WORKER_LOST)
        .bind(now)
        .fetch_all(&mut *tx)
        .await?;
        let requeued = sqlx::query(
            "UPDATE jobs SET status = 'queued', stage = NULL, progress = 0, lease_owner = NULL, \
             lease_until = NULL, updated_at = $1 \
             WHERE status = 'running' AND lease_until < $1 RETURNING id::text AS id",
        )
        .bind(now)
        .fetch_all(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(Expired {
            requeued: Self::ids(&requeued)?,
            failed: Self::ids(&failed)?,
        })
    }

    async fn cancel(&self, tenant: &str, id: JobId) -> Result<Option<Job>, StoreError> {
        let now = now_ms();
        // A running job's worker learns of it at its next heartbeat and stops.
        sqlx::query(
            "UPDATE jobs SET status = 'cancelled', lease_owner = NULL, lease_until = NULL, \
             finished_at = $1, updated_at = $1 \
             WHERE id = $2::uuid AND tenant = $3 AND status IN ('queued', 'running')",
        )
        .bind(now)
        .bind(id.to_string())
        .bind(tenant)
        .execute(&self.pool)
        .await?;
        self.get(Some(tenant), id).await
    }

    async fn delete(&self, id: JobId) -> Result<bool, StoreError> {
        let mut tx = self.pool.begin().await?;
        sqlx::query("DELETE FROM webhook_deliveries WHERE job_id = $1::uuid")
            .bind(id.to_string())
            .execute(&mut *tx)
            .await?;
        let done = sqlx::query("DELETE FROM jobs WHERE id = $1::uuid")
            .bind(id.to_string())
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(done.rows_affected() == 1)
    }

    async fn expire(&self, id: JobId) -> Result<bool, StoreError> {
        let mut tx = self.pool.begin().await?;
        sqlx::query(
            "INSERT INTO job_tombstones (id, tenant, expired_at) \
             SELECT id, tenant, $1 FROM jobs WHERE id = $2::uuid \
             ON CONFLICT (id) DO UPDATE SET expired_at = EXCLUDED.expired_at",
        )
        .bind(now_ms())
        .bind(id.to_string())
        .execute(&mut *tx)
        .await?;
        sqlx::query("DELETE FROM webhook_deliveries WHERE job_id = $1::uuid")
            .bind(id.to_string())
            .execute(&mut *tx)
            .await?;
        let done = sqlx::query("DELETE FROM jobs WHERE id = $1::uuid")
            .bind(id.to_string())
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(done.rows_affected() == 1)
    }

    async fn expired_at(&self, tenant: &str, id: JobId) -> Result<Option<i64>, StoreError> {
        let at = sqlx::query_scalar(
            "SELECT expired_at FROM job_tombstones WHERE id = $1::uuid AND tenant = $2",
        )
        .bind(id.to_string())
        .bind(tenant)
        .fetch_optional(&self.pool)
        .await?;
        Ok(at)
    }

    async fn forget_expired(&self, before_ms: i64) -> Result<u64, StoreError> {
        let done = sqlx::query("DELETE FROM job_tombstones WHERE expired_at < $1")
            .bind(before_ms)
            .execute(&self.pool)
            .await?;
        Ok(done.rows_affected())
    }

    async fn claim_hooks(&self, lease_ms: i64, limit: u32) -> Result<Vec<(Job, u32)>, StoreError> {
        let now = now_ms();
        // SKIP LOCKED: two processes never take the same webhook.
        let sql = format!(
            "UPDATE jobs SET hook_due = $1 WHERE id IN (SELECT id FROM jobs \
             WHERE hook_due IS NOT NULL AND hook_due <= $2 \
             AND status IN ('succeeded', 'failed', 'cancelled') ORDER BY hook_due LIMIT $3 \
             FOR UPDATE SKIP LOCKED) RETURNING {COLUMNS}, hook_attempts"
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
                    r.try_get::<i32, _>("hook_attempts")? as u32,
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
        sqlx::query("UPDATE jobs SET hook_attempts = $1, hook_due = $2 WHERE id = $3::uuid")
            .bind(attempts as i32)
            .bind(next_due)
            .bind(id.to_string())
            .execute(&self.pool)
            .await?;
        Ok(())
    }

    async fn record_delivery(&self, d: &Delivery) -> Result<(), StoreError> {
        sqlx::query(
            "INSERT INTO webhook_deliveries (id, job_id, event, url, attempt, at, status_code, \
             error, duration_ms) VALUES ($1::uuid, $2::uuid, $3, $4, $5, $6, $7, $8, $9)",
        )
        .bind(d.id.to_string())
        .bind(d.job.to_string())
        .bind(&d.event)
        .bind(&d.url)
        .bind(d.attempt as i32)
        .bind(d.at)
        .bind(d.status.map(i32::from))
        .bind(&d.error)
        .bind(d.duration_ms)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    async fn deliveries(&self, id: JobId) -> Result<Vec<Delivery>, StoreError> {
        let rows = sqlx::query(
            "SELECT id::text AS id, job_id::text AS job_id, event, url, attempt, at, \
             status_code, error, duration_ms \
             FROM webhook_deliveries WHERE job_id = $1::uuid ORDER BY at, attempt",
        )
        .bind(id.to_string())
        .fetch_all(&self.pool)
        .await?;
        rows.iter().map(Self::row_to_delivery).collect()
    }

    async fn finished_before(&self, before_ms: i64, limit: u32) -> Result<Vec<JobId>, StoreError> {
        let rows = sqlx::query(
            "SELECT id::text AS id FROM jobs WHERE finished_at IS NOT NULL AND finished_at < $1 \
             ORDER BY finished_at LIMIT $2",
        )
        .bind(before_ms)
        .bind(limit as i64)
        .fetch_all(&self.pool)
        .await?;
        Self::ids(&rows)
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

    fn applied(versions: &[i64]) -> Vec<(i64, Vec<u8>)> {
        let known = migrations();
        versions
            .iter()
            .map(|v| {
                let sum = known
                    .iter()
                    .find(|m| m.version == *v)
                    .map(|m| m.checksum.to_vec())
                    .unwrap_or_default();
                (*v, sum)
            })
            .collect()
    }

    #[test]
    fn schema_check_names_what_to_do() {
        let known = migrations();
        assert!(schema_verdict(&applied(&[1, 2, 3, 4]), &known).is_ok());
        assert!(
            schema_verdict(&applied(&[1]), &known).is_err(),
            "a migration missing"
        );
        let none = schema_verdict(&[], &known).unwrap_err().0;
        assert!(none.contains("run `asbuilt migrate`"), "{none}");
        let newer = schema_verdict(&applied(&[1, 2, 3, 4, 99]), &known)
            .unwrap_err()
            .0;
        assert!(newer.contains("newer than this binary"), "{newer}");
        let changed = schema_verdict(&[(1, vec![0u8; 48])], &known).unwrap_err().0;
        assert!(
            changed.contains("changed after it was applied"),
            "{changed}"
        );
    }
}
