//! Stopping a run from outside: a flag the caller raises, a deadline, or both.
//!
//! The caller makes a [`Cancel`], hands a clone to the run (through [`crate::progress::Progress`]
//! for [`crate::plan()`], as an argument for a stage called alone) and raises it from any thread.
//! Every loop whose length depends on a parameter, or that runs over all the points, checks it
//! often enough that a run stops well within a second of the flag or the deadline; the stage
//! then returns its error's `Cancelled` variant, which [`crate::PlanError`] reports as
//! `cancelled` or `time_limit`.
//!
//! Loops that are one linear pass over a mesh already built by a heavier stage (cleanup, boundary
//! tracing) are checked between stages only: they take a fraction of the stage before them.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// Why a run stopped early.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Cancelled {
    /// The caller raised the flag.
    #[error("cancelled")]
    ByCaller,
    /// The deadline passed.
    #[error("stopped at its time limit")]
    TimeLimit,
}

impl Cancelled {
    /// A stable machine-readable code for the service's error bodies.
    pub fn code(self) -> &'static str {
        match self {
            Cancelled::ByCaller => "cancelled",
            Cancelled::TimeLimit => "time_limit",
        }
    }
}

/// A cheap, clonable stop signal. Clones share the flag. The default never stops.
#[derive(Debug, Clone, Default)]
pub struct Cancel {
    flag: Option<Arc<AtomicBool>>,
    deadline: Option<Instant>,
}

impl Cancel {
    /// Never stops (tests, and callers with nothing to stop them).
    pub fn never() -> Cancel {
        Cancel::default()
    }

    /// A flag nobody has raised yet; raise it with [`Cancel::cancel`] on any clone.
    pub fn new() -> Cancel {
        Cancel {
            flag: Some(Arc::new(AtomicBool::new(false))),
            deadline: None,
        }
    }

    /// The same flag, also stopping at `at` (the earlier deadline wins).
    pub fn with_deadline(mut self, at: Instant) -> Cancel {
        self.deadline = Some(self.deadline.map_or(at, |d| d.min(at)));
        self
    }

    /// Raises the flag: every clone's next check fails. No effect on [`Cancel::never`].
    pub fn cancel(&self) {
        if let Some(f) = &self.flag {
            f.store(true, Ordering::Relaxed);
        }
    }

    /// `Err` once the flag is raised or the deadline has passed. Costs an atomic load and, with
    /// a deadline, a clock read (tens of nanoseconds): call it every few microseconds of work
    /// or more, not per point.
    #[inline]
    pub fn check(&self) -> Result<(), Cancelled> {
        if let Some(f) = &self.flag {
            if f.load(Ordering::Relaxed) {
                return Err(Cancelled::ByCaller);
            }
        }
        match self.deadline {
            Some(d) if Instant::now() >= d => Err(Cancelled::TimeLimit),
            _ => Ok(()),
        }
    }

    /// True once [`Cancel::check`] would fail: for loops that bail out early and let the check
    /// after them report why (inside rayon closures, say).
    #[inline]
    pub fn is_stopped(&self) -> bool {
        self.check().is_err()
    }
}

/// Two tokens are equal when they would stop together: the same flag and the same deadline.
/// (So that option structs holding one can still derive `PartialEq`.)
impl PartialEq for Cancel {
    fn eq(&self, other: &Cancel) -> bool {
        let same_flag = match (&self.flag, &other.flag) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        };
        same_flag && self.deadline == other.deadline
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn clones_share_the_flag_and_the_deadline_stops() {
        let c = Cancel::new();
        let seen_by_run = c.clone();
        assert_eq!(seen_by_run.check(), Ok(()));
        c.cancel();
        assert_eq!(seen_by_run.check(), Err(Cancelled::ByCaller));
        assert!(seen_by_run.is_stopped());

        let never = Cancel::never();
        never.cancel();
        assert_eq!(never.check(), Ok(()));

        let late = Cancel::new().with_deadline(Instant::now() + Duration::from_secs(3600));
        assert_eq!(late.check(), Ok(()));
        let past = late.with_deadline(Instant::now());
        assert_eq!(past.check(), Err(Cancelled::TimeLimit));
        assert_eq!(Cancelled::TimeLimit.code(), "time_limit");
        assert_eq!(Cancelled::ByCaller.code(), "cancelled");
    }

    #[test]
    fn the_earlier_deadline_wins_and_the_flag_beats_the_clock() {
        let now = Instant::now();
        let c = Cancel::new()
            .with_deadline(now)
            .with_deadline(now + Duration::from_secs(60));
        assert_eq!(c.check(), Err(Cancelled::TimeLimit));
        c.cancel();
        assert_eq!(c.check(), Err(Cancelled::ByCaller));
        assert_eq!(Cancel::never(), Cancel::default());
        assert_ne!(Cancel::new(), Cancel::new());
        let a = Cancel::new();
        assert_eq!(a.clone(), a);
    }
}
