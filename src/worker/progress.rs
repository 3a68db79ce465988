//! The bridge between a pipeline on a blocking thread and its async worker: the pipeline
//! writes its stage and fraction here; the heartbeat reads them and sets the stop reason.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use asbuilt_plan::progress::{Progress, Stage};

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
#[derive(Default)]
pub struct Shared {
    latest: Mutex<(Option<Stage>, f64)>,
    stop: AtomicU8,
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

    fn cancelled(&self) -> bool {
        if Instant::now() >= self.deadline {
            self.shared.stop(Stop::TimeLimit);
        }
        self.shared.stopped().is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
        shared.stop(Stop::Shutdown);
        shared.stop(Stop::Lost);
        assert!(p.cancelled());
        assert_eq!(shared.stopped(), Some(Stop::Shutdown));
        let late = JobProgress {
            shared: Arc::new(Shared::default()),
            deadline: Instant::now(),
        };
        assert!(late.cancelled());
        assert_eq!(late.shared.stopped(), Some(Stop::TimeLimit));
    }
}
