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
    stop: AtomicU8,
    /// Raised with the first stop reason; the pipeline checks it inside its loops.
    cancel: Cancel,
}

impl Default for Shared {
    fn default() -> Self {
        Shared {
            latest: Mutex::default(),
            stop: AtomicU8::default(),
            cancel: Cancel::new(),
        }
    }
}

impl Shared {
    /// The latest stage and fraction reported.
    pub fn latest(&self) -> (Option<Stage>, f64) {
        *self.latest.lock().expect("progress lock")
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
