//! The bridge between a pipeline on a blocking thread and its async worker: the pipeline
//! writes its stage and fraction here; the heartbeat reads them and sets the stop reason.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use asbuilt_plan::progress::{Progress, Stage};
use asbuilt_plan::Cancel;

/// Why a run should stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stop {
    /// The job was cancelled, deleted or taken by another worker.
    Lost = 1,
    /// The server is shutting down: hand the job back.
    Shutdown = 2,
    /// The job's time limit passed.
    TimeLimit = 3,
}

/// State shared by the pipeline thread and the worker.
pub struct Shared {
    latest: Mutex<(Option<Stage>, f64)>,
    detail: Mutex<Detail>,
    stop: AtomicU8,
    /// Raised with the first stop reason; the pipeline checks it inside its loops.
    cancel: Cancel,
}

impl Default for Shared {
    fn default() -> Self {
        Shared {
            latest: Mutex::default(),
            detail: Mutex::default(),
            stop: AtomicU8::default(),
            cancel: Cancel::new(),
        }
    }
}

/// What a run reports beside its stage and fraction: the bytes of the cloud read, and which
/// story runs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Detail {
    /// Bytes read and the file's size.
    pub read: Option<(u64, u64)>,
    /// The story (from 1) and the number of stories.
    pub story: Option<(usize, usize)>,
}

impl Detail {
    /// As stored with the job (`progress_detail`) and shown in its `read` and `story`.
    pub fn to_json(self) -> Option<serde_json::Value> {
        if self == Detail::default() {
            return None;
        }
        Some(serde_json::json!({
            "read": self.read.map(|(bytes, total)| serde_json::json!({"bytes": bytes, "total": total})),
            "story": self.story.map(|(number, count)| serde_json::json!({"number": number, "count": count})),
        }))
    }
}

impl Shared {
    /// The latest stage and fraction reported.
    pub fn latest(&self) -> (Option<Stage>, f64) {
        *self.latest.lock().expect("progress lock")
    }

    /// The latest bytes read and story reported.
    pub fn detail(&self) -> Detail {
        *self.detail.lock().expect("progress lock")
    }

    /// Asks the run to stop; the first reason wins.
    pub fn stop(&self, why: Stop) {
        let _ = self
            .stop
            .compare_exchange(0, why as u8, Ordering::SeqCst, Ordering::SeqCst);
        self.cancel.cancel();
    }

    /// Why the run was asked to stop, if it was.
    pub fn stopped(&self) -> Option<Stop> {
        match self.stop.load(Ordering::SeqCst) {
            1 => Some(Stop::Lost),
            2 => Some(Stop::Shutdown),
            3 => Some(Stop::TimeLimit),
            _ => None,
        }
    }
}

/// The [`Progress`] a worker hands its pipeline.
pub struct JobProgress {
    pub shared: Arc<Shared>,
    pub deadline: Instant,
}

impl Progress for JobProgress {
    fn report(&mut self, stage: Stage, fraction: f64) {
        *self.shared.latest.lock().expect("progress lock") = (Some(stage), fraction);
    }

    fn read(&mut self, bytes: u64, total: u64) {
        self.shared.detail.lock().expect("progress lock").read = Some((bytes, total));
    }

    fn story(&mut self, number: usize, count: usize) {
        self.shared.detail.lock().expect("progress lock").story = Some((number, count));
    }

    /// The shared flag, with the job's deadline: the pipeline stops at the deadline on its own
    /// (the heartbeat also raises the flag then, within a beat).
    fn cancel(&self) -> Cancel {
        self.shared.cancel.clone().with_deadline(self.deadline)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use asbuilt_plan::Cancelled;
    use std::time::Duration;

    #[test]
    fn first_stop_reason_wins_and_the_deadline_stops() {
        let shared = Arc::new(Shared::default());
        let mut p = JobProgress {
            shared: shared.clone(),
            deadline: Instant::now() + Duration::from_secs(60),
        };
        p.report(Stage::Labeling, 0.5);
        assert_eq!(shared.latest(), (Some(Stage::Labeling), 0.5));
        assert_eq!(shared.detail().to_json(), None);
        p.read(10, 40);
        p.story(2, 3);
        assert_eq!(
            shared.detail().to_json().unwrap(),
            serde_json::json!({"read": {"bytes": 10, "total": 40}, "story": {"number": 2, "count": 3}})
        );
        assert!(!p.cancelled());
        // The token the pipeline took before the stop sees it.
        let taken = p.cancel();
        shared.stop(Stop::Shutdown);
        shared.stop(Stop::Lost);
        assert!(p.cancelled());
        assert_eq!(taken.check(), Err(Cancelled::ByCaller));
        assert_eq!(shared.stopped(), Some(Stop::Shutdown));
        let late = JobProgress {
            shared: Arc::new(Shared::default()),
            deadline: Instant::now(),
        };
        assert_eq!(late.cancel().check(), Err(Cancelled::TimeLimit));
        assert!(late.cancelled());
    }
}
