//! Waiting for an outcome: one polling loop for every test, and the wait for a tenant's jobs.

use std::future::Future;
use std::time::{Duration, Instant};

use serde_json::Value;

use super::process::Client;

/// Polls `f` every 50 ms until it gives a value or `timeout` passes (then panics naming
/// `what`). Returns the value and how long it took.
pub async fn eventually<T, F, Fut>(what: &str, timeout: Duration, mut f: F) -> (T, Duration)
where
    F: FnMut() -> Fut,
    Fut: Future<Output = Option<T>>,
{
    let start = Instant::now();
    loop {
        if let Some(v) = f().await {
            return (v, start.elapsed());
        }
        assert!(start.elapsed() < timeout, "{what}: not within {timeout:?}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Waits until every job of `client`'s tenant has reached a terminal status; returns them.
pub async fn drain_jobs(client: &Client, timeout: Duration) -> Vec<Value> {
    let (jobs, _) = eventually("every job finished", timeout, || async {
        let jobs = client.jobs().await;
        jobs.iter()
            .all(|j| {
                matches!(
                    j["status"].as_str(),
                    Some("succeeded" | "failed" | "cancelled")
                )
            })
            .then_some(jobs)
    })
    .await;
    jobs
}
