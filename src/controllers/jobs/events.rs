//! `GET /v1/jobs/{id}/events`: server-sent events. Each `job` event carries the whole job
//! (as `GET /v1/jobs/{id}`) whenever its status, stage or progress changes; the stream ends
//! after a terminal status, or with a `deleted` event.
//!
//! Each `job` event's `id` names the state it shows. A client that reconnects with
//! `Last-Event-ID` (browsers do by themselves) is sent only states after that one; when that
//! was the job's final state, the answer is `204`, which tells a browser to stop reconnecting.

use std::convert::Infallible;
use std::time::Duration;

use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use tokio::sync::broadcast;

use crate::app::AppState;
use crate::auth::Tenant;
use crate::errors::ApiError;
use crate::queue::{Job, JobId};
use crate::views::JobView;

/// Without a change notice (another process's worker), the job is re-read this often.
const POLL: Duration = Duration::from_secs(1);

struct Watch {
    state: AppState,
    tenant: String,
    id: JobId,
    changes: broadcast::Receiver<JobId>,
    /// The id of the last state sent (or the client's `Last-Event-ID`).
    last: Option<String>,
    first: bool,
    done: bool,
}

impl Watch {
    /// Waits for a change notice about this job, the poll interval, or shutdown (false).
    async fn wait(&mut self) -> bool {
        let deadline = tokio::time::sleep(POLL);
        tokio::pin!(deadline);
        loop {
            tokio::select! {
                _ = &mut deadline => return true,
                _ = self.state.shutdown.cancelled() => return false,
                got = self.changes.recv() => match got {
                    Ok(id) if id == self.id => return true,
                    Ok(_) => {}
                    Err(broadcast::error::RecvError::Lagged(_)) => return true,
                    Err(broadcast::error::RecvError::Closed) => return false,
                },
            }
        }
    }

    async fn next(mut self) -> Option<(Result<Event, Infallible>, Watch)> {
        if self.done {
            return None;
        }
        loop {
            if !self.first && !self.wait().await {
                return None;
            }
            self.first = false;
            let job = match self.state.store.get(Some(&self.tenant), self.id).await {
                Ok(Some(job)) => job,
                Ok(None) => {
                    self.done = true;
                    let event = Event::default().event("deleted").data(self.id.to_string());
                    return Some((Ok(event), self));
                }
                Err(e) => {
                    tracing::warn!(job = %self.id, error = %e, "event stream read failed");
                    continue;
                }
            };
            let key = state_id(&job);
            if self.last.as_ref() == Some(&key) {
                // Nothing new; a terminal state the client already has ends the stream.
                if job.status.is_terminal() {
                    return None;
                }
                continue;
            }
            self.last = Some(key.clone());
            self.done = job.status.is_terminal();
            let event = Event::default()
                .event("job")
                .id(key)
                .json_data(JobView::new(&job, &self.state.config))
                .unwrap_or_else(|_| Event::default().event("job"));
            return Some((Ok(event), self));
        }
    }
}

/// The id of a job's visible state: its status, stage and progress (to 0.1 %).
fn state_id(job: &Job) -> String {
    format!(
        "{}.{}.{}",
        job.status.as_str(),
        job.stage.as_deref().unwrap_or("-"),
        (job.progress * 1000.0) as u64
    )
}

pub async fn events(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let job = super::load(&state, &tenant, &id).await?;
    let last = headers
        .get("last-event-id")
        .and_then(|v| v.to_str().ok())
        .map(|v| v.trim().to_string())
        .filter(|v| !v.is_empty() && v.len() <= 200);
    if job.status.is_terminal() && last.as_deref() == Some(state_id(&job).as_str()) {
        return Ok(StatusCode::NO_CONTENT.into_response());
    }
    let watch = Watch {
        changes: state.changes.subscribe(),
        state,
        tenant,
        id: job.id,
        last,
        first: true,
        done: false,
    };
    let stream = futures_util::stream::unfold(watch, Watch::next);
    Ok(Sse::new(stream)
        .keep_alive(KeepAlive::new().interval(Duration::from_secs(15)))
        .into_response())
}
