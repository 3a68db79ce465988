//! The terminal progress bar, as a [`Progress`] the pipeline can drive.

use std::io::IsTerminal;

use asbuilt_plan::progress::{Progress, Stage};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Steps of the bar; the pipeline reports fractions, the bar wants integers.
const STEPS: u64 = 1000;

/// A progress bar on stderr when stderr is a terminal, hidden otherwise (logs and pipes stay
/// clean).
pub struct Bar(ProgressBar);

impl Bar {
    pub fn new(quiet: bool) -> Bar {
        let target = if !quiet && std::io::stderr().is_terminal() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        };
        let bar = ProgressBar::with_draw_target(Some(STEPS), target);
        if let Ok(style) =
            ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {percent:>3}% {msg}")
        {
            bar.set_style(style.progress_chars("=> "));
        }
        Bar(bar)
    }

    pub fn finish(&self) {
        self.0.finish_and_clear();
    }
}

impl Progress for Bar {
    fn report(&mut self, stage: Stage, fraction: f64) {
        self.0.set_message(stage.name());
        self.0
            .set_position((fraction.clamp(0.0, 1.0) * STEPS as f64) as u64);
    }
}
