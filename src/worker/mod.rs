//! Background workers: each claims a queued job, runs the pipeline on a blocking thread while
//! an async heartbeat renews the lease and records progress, then stores the results.

pub mod early;
pub mod fake;
pub mod pipeline;
pub mod progress;
pub mod retire;
pub mod sweeper;

use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use asbuilt_plan::progress::Stage;
use asbuilt_plan::Params;
use bytes::Bytes;
use tokio::task::JoinHandle;
use tokio_util::sync::CancellationToken;

use crate::app::AppState;
use crate::errors::JobCode;
use crate::queue::{Beat, Heartbeat, Job, JobError, JobId, JobOutcome, JobStatus};
use crate::storage::keys;
use pipeline::{JobInput, JobResults, Pipeline, PipelineFailure, SidecarKind};
use progress::{Detail, JobProgress, Shared, Stop};

/// What the workers share.
pub struct Workers {
    pub state: AppState,
    pub pipeline: Arc<dyn Pipeline>,
    /// Names this process's leases.
    pub owner: String,
    /// Scratch space for clouds fetched from a remote store.
    pub work_dir: PathBuf,
    /// Cancelled when the server starts shutting down: take no new jobs.
    pub stop_claiming: CancellationToken,
    /// Cancelled when shutdown stops waiting: hand running jobs back to the queue.
    pub hand_back: CancellationToken,
}

impl Workers {
    /// Starts `n` worker loops.
    pub fn spawn(self: &Arc<Self>, n: usize) -> Vec<JoinHandle<()>> {
        (0..n)
            .map(|i| {
                let w = self.clone();
                tokio::spawn(async move { w.run_loop(i).await })
            })
            .collect()
    }

    fn lease_ms(&self) -> i64 {
        (self.state.config.lease_secs * 1000) as i64
    }

    async fn run_loop(self: Arc<Self>, index: usize) {
        let owner = format!("{}/{index}", self.owner);
        loop {
            if self.stop_claiming.is_cancelled() {
                return;
            }
            match self.state.store.claim(&owner, self.lease_ms()).await {
                Ok(Some(job)) => {
                    tracing::info!(job = %job.id, attempt = job.attempts, worker = %owner, "job started");
                    self.state.changed(job.id);
                    self.state.early.working(true);
                    self.run_job(&owner, job).await;
                    self.state.early.working(false);
                }
                Ok(None) => {
                    tokio::select! {
                        _ = self.state.queued.notified() => {}
                        // Another process's upload: a database notification, or a poll.
                        _ = self.state.store.wait_for_work(Duration::from_secs(1)) => {}
                        _ = self.stop_claiming.cancelled() => return,
                    }
                }
                Err(e) => {
                    tracing::error!(error = %e, "claiming a job");
                    tokio::time::sleep(Duration::from_secs(1)).await;
                }
            }
        }
    }

    async fn run_job(&self, owner: &str, job: Job) {
        let id = job.id;
        let shared = Arc::new(Shared::default());
        let deadline = Instant::now() + Duration::from_secs(self.state.config.job_timeout_secs);
        let beating = tokio::spawn(heartbeat(
            self.state.clone(),
            id,
            owner.to_string(),
            self.lease_ms(),
            shared.clone(),
            self.hand_back.clone(),
            deadline,
        ));
        let scratch = self.work_dir.join(id.to_string());
        let result = match self.prepare(&job, &scratch).await {
            Ok(input) => {
                let pipeline = self.pipeline.clone();
                let mut progress = JobProgress {
                    shared: shared.clone(),
                    deadline,
                };
                // The pipeline is CPU-bound and synchronous: never on the async threads.
                let mut joined = tokio::task::spawn_blocking(move || {
                    std::panic::catch_unwind(AssertUnwindSafe(|| {
                        pipeline.run(&input, &mut progress)
                    }))
                });
                tokio::select! {
                    joined = &mut joined => match joined {
                        Ok(Ok(r)) => r,
                        Ok(Err(_)) | Err(_) => Err(PipelineFailure::new(
                            JobCode::PipelinePanic,
                            "the pipeline crashed on this input; this is a bug, please report it",
                        )),
                    },
                    // Every stage checks its stop token within a second; a pipeline stuck in a
                    // call that cannot be interrupted must not hold the worker too.
                    why = stopped_for(&shared, STOP_GRACE) => {
                        tracing::warn!(
                            job = %id, reason = ?why,
                            "the pipeline did not stop within {STOP_GRACE:?}; its thread is left to finish alone"
                        );
                        Err(PipelineFailure::cancelled())
                    }
                }
            }
            Err(f) => Err(f),
        };
        beating.abort();
        let _ = tokio::fs::remove_dir_all(&scratch).await;
        // The stage it stopped in: the last one reported, or reading when none was.
        let stage = shared.latest().0.unwrap_or(Stage::Read);
        if let Err(e) = self
            .finish(owner, id, job.input_job, shared.stopped(), stage, result)
            .await
        {
            tracing::error!(job = %id, error = %e, "recording the job's end");
        }
        self.state.changed(id);
    }

    /// Turns the job's stored inputs into local files and parameters.
    async fn prepare(
        &self,
        job: &Job,
        scratch: &std::path::Path,
    ) -> Result<JobInput, PipelineFailure> {
        let io = |e: &dyn std::fmt::Display| {
            PipelineFailure::new(JobCode::IoError, format!("reading the upload: {e}"))
        };
        let params: Params = serde_json::from_value(job.params.clone())
            .map_err(|e| PipelineFailure::new(JobCode::InvalidParameter, e.to_string()))?;
        let blobs = &self.state.blobs;
        let fetch = |key: String, name: &str| {
            let local = blobs.local_path(&key).filter(|p| p.is_file());
            let target = scratch.join(name);
            async move {
                match local {
                    Some(p) => Ok::<_, PipelineFailure>(p),
                    None => {
                        tokio::fs::create_dir_all(scratch)
                            .await
                            .map_err(|e| io(&e))?;
                        blobs.download(&key, &target).await.map_err(|e| io(&e))?;
                        Ok(target)
                    }
                }
            }
        };
        // An upload this process read as it arrived needs no fetch, when the read saw the
        // bytes stored; anything else runs from the stored file.
        let early = match self.state.early.take(job.id) {
            Some(pending) if job.input_job == job.id => {
                let expected = job.upload.bytes;
                let metrics = &self.state.metrics;
                match tokio::task::spawn_blocking(move || pending.finish()).await {
                    Ok(Ok(d)) if d.bytes == expected => {
                        metrics.early_read("used");
                        Some(early::EarlyCloud::new(d))
                    }
                    Ok(Ok(d)) => {
                        metrics.early_read("other_bytes");
                        tracing::warn!(job = %job.id, read = d.bytes, stored = expected, "early read saw other bytes; reading the stored upload");
                        None
                    }
                    failed => {
                        let why = match failed {
                            Ok(Err(why)) => why,
                            _ => "the early read's thread was lost".to_string(),
                        };
                        metrics.early_read("failed");
                        tracing::info!(job = %job.id, why = %why, "early read failed; reading the stored upload");
                        None
                    }
                }
            }
            _ => None,
        };
        // A re-plan reads the upload of the job it came from.
        let cloud = match early {
            Some(_) => scratch.join("cloud"),
            None => fetch(keys::cloud(job.input_job), "cloud").await?,
        };
        let sidecar = match job
            .upload
            .sidecar
            .as_deref()
            .and_then(|name| name.parse::<SidecarKind>().ok())
        {
            Some(kind) => Some((kind, fetch(keys::sidecar(job.id), "sidecar.json").await?)),
            None => None,
        };
        Ok(JobInput {
            job: job.id,
            cloud,
            sidecar,
            params,
            max_points: self.state.config.max_points,
            georeference: job.upload.georeference.clone(),
            early,
        })
    }

    /// Removes the results of a job this worker lost, unless another worker has taken the job
    /// over: with several processes, a worker whose lease expired (paused, partitioned) may
    /// learn it only after a successor wrote or is writing the same keys.
    ///
    /// A job deleted while its results were being written loses its whole folder here: the
    /// delete removed the folder before this worker wrote into it again (the soak benchmark
    /// found such folders left behind).
    async fn discard_results(&self, id: JobId, input_job: JobId) -> anyhow::Result<()> {
        let prefix = match self.state.store.get(None, id).await? {
            // Gone: everything it stored, and the upload it read if nobody else reads it.
            None => return retire::remove_blobs(&self.state, id, input_job).await,
            Some(job)
                if matches!(
                    job.status,
                    JobStatus::Queued | JobStatus::Running | JobStatus::Succeeded
                ) =>
            {
                return Ok(())
            }
            Some(_) => keys::result_prefix(id),
        };
        self.state.blobs.delete_prefix(&prefix).await?;
        Ok(())
    }

    async fn finish(
        &self,
        owner: &str,
        id: JobId,
        input_job: JobId,
        stopped: Option<Stop>,
        stage: Stage,
        result: Result<JobResults, PipelineFailure>,
    ) -> anyhow::Result<()> {
        let store = &self.state.store;
        let metrics = &self.state.metrics;
        match (stopped, result) {
            (Some(Stop::Lost), _) => {
                tracing::info!(job = %id, "job cancelled or taken over; its work is discarded");
                self.discard_results(id, input_job).await?;
            }
            (Some(Stop::Shutdown), _) => {
                if store.release(id, owner).await? {
                    tracing::info!(job = %id, "job handed back to the queue");
                }
            }
            (_, Ok(results)) => {
                for (output, bytes) in results.files {
                    self.state
                        .blobs
                        .put(&keys::result(id, output.file), Bytes::from(bytes))
                        .await?;
                }
                let timings: serde_json::Map<String, serde_json::Value> = results
                    .timings_ms
                    .iter()
                    .map(|(k, v)| (k.clone(), (*v).into()))
                    .collect();
                let outcome = JobOutcome {
                    input: results.input,
                    timings: timings.into(),
                };
                if store.complete(id, owner, &outcome).await? {
                    metrics.success(&results.timings_ms);
                    tracing::info!(job = %id, "job succeeded");
                } else {
                    // Cancelled, deleted or taken over while finishing.
                    self.discard_results(id, input_job).await?;
                }
            }
            // Only the time limit is left to have stopped the run; a run that failed on its own
            // reports its own error, even if the deadline passed meanwhile.
            (_, Err(f)) if f.is_stop() => {
                let error = JobError {
                    code: "time_limit".into(),
                    message: format!(
                        "the job ran longer than the limit of {} s",
                        self.state.config.job_timeout_secs
                    ),
                };
                if store.fail(id, owner, &error, Some(stage.name())).await? {
                    metrics.failure(&error.code);
                }
            }
            (_, Err(f)) => {
                tracing::info!(job = %id, code = f.code.as_str(), message = %f.message, "job failed");
                let error = JobError {
                    code: f.code.as_str().to_string(),
                    message: f.message,
                };
                if store.fail(id, owner, &error, Some(stage.name())).await? {
                    metrics.failure(&error.code);
                }
            }
        }
        Ok(())
    }
}

/// How long a worker waits for its pipeline to stop once asked, before leaving the pipeline's
/// thread behind and taking the next job.
pub const STOP_GRACE: Duration = Duration::from_secs(2);

/// Resolves `grace` after the run was asked to stop, with the reason.
async fn stopped_for(shared: &Shared, grace: Duration) -> Stop {
    let why = loop {
        if let Some(why) = shared.stopped() {
            break why;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    tokio::time::sleep(grace).await;
    why
}

/// Renews the lease and records progress until aborted; sets the stop reason when the job is
/// lost, the server hands jobs back, or the time limit passes.
async fn heartbeat(
    state: AppState,
    id: JobId,
    owner: String,
    lease_ms: i64,
    shared: Arc<Shared>,
    hand_back: CancellationToken,
    deadline: Instant,
) {
    // Often enough for cancellation to land within a second, and well within the lease.
    let every = Duration::from_millis((lease_ms as u64 / 3).clamp(50, 250));
    let mut last = (None, -1.0, Detail::default());
    loop {
        tokio::select! {
            _ = tokio::time::sleep(every) => {}
            _ = hand_back.cancelled() => {
                shared.stop(Stop::Shutdown);
                return;
            }
        }
        if Instant::now() >= deadline {
            shared.stop(Stop::TimeLimit);
        }
        let (stage, fraction) = shared.latest();
        let detail = shared.detail();
        let beat = Beat {
            stage: stage.map(|s| s.name().to_string()),
            progress: fraction,
            input: None,
            detail: detail.to_json(),
        };
        match state.store.heartbeat(id, &owner, lease_ms, &beat).await {
            Ok(Heartbeat::Held) => {
                if (stage, fraction, detail) != last {
                    last = (stage, fraction, detail);
                    state.changed(id);
                }
            }
            Ok(Heartbeat::Lost) => {
                shared.stop(Stop::Lost);
                return;
            }
            Err(e) => tracing::warn!(job = %id, error = %e, "heartbeat failed"),
        }
    }
}
