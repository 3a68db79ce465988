//! Periodic upkeep: requeue jobs whose worker died, and delete finished jobs past retention.

use std::time::Duration;

use tokio_util::sync::CancellationToken;

use crate::app::AppState;
use crate::queue::{now_ms, WORKER_LOST};
use crate::worker::retire;

/// How long a job removed by retention still answers `410 expired` (then `404`): 30 days.
pub const TOMBSTONE_MS: i64 = 30 * 24 * 3_600_000;

/// How often the sweeper runs: often enough to notice a lost lease well within its length.
pub fn interval(lease_secs: u64) -> Duration {
    Duration::from_millis((lease_secs * 1000 / 2).clamp(200, 5000))
}

/// Sweeps until `stop` is cancelled.
pub async fn run(state: AppState, stop: CancellationToken) {
    let every = interval(state.config.lease_secs);
    loop {
        if let Err(e) = sweep(&state).await {
            tracing::warn!(error = %e, "sweep failed");
        }
        tokio::select! {
            _ = tokio::time::sleep(every) => {}
            _ = stop.cancelled() => return,
        }
    }
}

/// One pass: expired leases, then retention.
pub async fn sweep(state: &AppState) -> anyhow::Result<()> {
    let expired = state.store.requeue_expired().await?;
    for id in &expired.requeued {
        tracing::warn!(job = %id, "worker lease expired; job requeued");
        state.queued.notify_one();
        state.changed(*id);
    }
    for id in &expired.failed {
        tracing::warn!(job = %id, "worker lease expired too often; job failed");
        state.metrics.failure(WORKER_LOST);
        state.changed(*id);
    }
    let now = now_ms();
    let old = state
        .store
        .finished_before(now - state.config.retention_ms(), 100)
        .await?;
    for id in old {
        let Some(job) = state.store.get(None, id).await? else {
            continue;
        };
        // The row first: whether an upload is still read is answered by the rows left.
        if state.store.expire(id).await? {
            retire::remove_blobs(state, id, job.input_job).await?;
            state.changed(id);
            tracing::info!(job = %id, "retention: job data deleted");
        }
    }
    state.store.forget_expired(now - TOMBSTONE_MS).await?;
    crate::controllers::jobs::uploads::expire(state).await?;
    Ok(())
}
