//! How the pipeline reports progress and learns it should stop. Callers (the CLI's progress bar,
//! the service's worker) implement [`Progress`]; the pipeline knows nothing of them.

use crate::cancel::Cancel;

/// The stages, in pipeline order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stage {
    Read,
    Stories,
    Samples,
    Smoothing,
    Labeling,
    Cleanup,
    Fitting,
    Write,
}

impl Stage {
    /// The stage's name in reports and `timings_ms`.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Read => "read",
            Stage::Stories => "stories",
            Stage::Samples => "samples",
            Stage::Smoothing => "smoothing",
            Stage::Labeling => "label",
            Stage::Cleanup => "cleanup",
            Stage::Fitting => "fit",
            Stage::Write => "write",
        }
    }
}

/// Receives progress. `fraction` is the whole run's progress in [0, 1].
pub trait Progress: Send {
    fn report(&mut self, stage: Stage, fraction: f64);

    /// The token the run checks inside every long loop; the default never stops. Asked once
    /// per run, so it must be a clone of what the caller raises.
    fn cancel(&self) -> Cancel {
        Cancel::never()
    }

    /// True once the caller wants the run to stop.
    fn cancelled(&self) -> bool {
        self.cancel().is_stopped()
    }
}

/// Ignores progress and never cancels.
pub struct NoProgress;

impl Progress for NoProgress {
    fn report(&mut self, _: Stage, _: f64) {}
}
