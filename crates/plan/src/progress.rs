//! How the pipeline reports progress and learns it should stop. Callers (the CLI's progress bar,
//! the service's worker) implement [`Progress`]; the pipeline knows nothing of them.

use crate::cancel::Cancel;

/// The stages, in pipeline order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stage {
    /// Reading the cloud and its sidecar.
    Read,
    /// Splitting the cloud into stories (§3.1).
    Stories,
    /// Wall samples from the d_s grid (§3.1).
    Samples,
    /// Smoothing the samples (§3.2).
    Smoothing,
    /// Labeling rooms (§3.3).
    Labeling,
    /// Cleaning the labels and tracing the boundary (§3.4).
    Cleanup,
    /// Fitting lines and arcs to the walls (§3.5).
    Fitting,
    /// Rooms, doors, windows and walls with thickness (beyond the paper).
    Rooms,
    /// Writing the outputs.
    Write,
}

/// One row of the stage table: everything the front ends, the page and the API document say
/// about a stage comes from here.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageRow {
    /// The stage this row describes.
    pub stage: Stage,
    /// The name in progress reports, the job's `stage` and `timings_ms`.
    pub name: &'static str,
    /// Its share of one story's progress; the stages before and after the stories take none.
    pub weight: f64,
    /// The job error code a failure in it carries, if it can fail.
    pub error_code: Option<&'static str>,
    /// Steps timed on their own (`timings_ms` keys) just ahead of it.
    pub parts: &'static [&'static str],
}

/// Every stage in pipeline order. Boundary tracing runs within `cleanup`'s share of progress,
/// and its failure is `boundary_failed`; its time is its own key, `boundary`, just ahead of
/// `fit`. The rooms stage cannot fail a story or a job.
pub const STAGES: [StageRow; 9] = [
    row(Stage::Read, "read", 0.0, None, &[]),
    row(Stage::Stories, "stories", 0.0, Some("no_stories"), &[]),
    row(Stage::Samples, "samples", 0.4, Some("samples_failed"), &[]),
    row(
        Stage::Smoothing,
        "smoothing",
        0.1,
        Some("smoothing_failed"),
        &[],
    ),
    row(
        Stage::Labeling,
        "label",
        0.25,
        Some("labeling_failed"),
        &[crate::pipeline::TRIANGULATE],
    ),
    row(Stage::Cleanup, "cleanup", 0.1, Some("boundary_failed"), &[]),
    row(
        Stage::Fitting,
        "fit",
        0.1,
        Some("fitting_failed"),
        &[crate::pipeline::BOUNDARY],
    ),
    // A failure here keeps the story's plan (empty spaces and a note): no job code.
    row(Stage::Rooms, "rooms", 0.05, None, &[]),
    row(Stage::Write, "write", 0.0, Some("output_failed"), &[]),
];

const fn row(
    stage: Stage,
    name: &'static str,
    weight: f64,
    error_code: Option<&'static str>,
    parts: &'static [&'static str],
) -> StageRow {
    StageRow {
        stage,
        name,
        weight,
        error_code,
        parts,
    }
}

impl Stage {
    /// The stage's row in [`STAGES`].
    pub fn row(self) -> &'static StageRow {
        &STAGES[self as usize]
    }

    /// The stage's name in reports and `timings_ms`.
    pub fn name(self) -> &'static str {
        self.row().name
    }

    /// The job error code of a failure in this stage.
    pub fn error_code(self) -> Option<&'static str> {
        self.row().error_code
    }

    /// How far through one story's progress the stage starts: the weights of the stages
    /// before it.
    pub fn start(self) -> f64 {
        STAGES[..self as usize].iter().map(|r| r.weight).sum()
    }

    /// The stage a name refers to.
    pub fn from_name(name: &str) -> Option<Stage> {
        STAGES.iter().find(|r| r.name == name).map(|r| r.stage)
    }
}

/// Every `timings_ms` key the stages report, in order (each stage's parts, then the stage).
pub fn timing_keys() -> impl Iterator<Item = &'static str> {
    STAGES
        .iter()
        .flat_map(|r| r.parts.iter().copied().chain([r.name]))
}

/// Receives progress. `fraction` is the whole run's progress in [0, 1].
pub trait Progress: Send {
    /// Called as the run enters `stage` and as it goes on; `fraction` never decreases.
    fn report(&mut self, stage: Stage, fraction: f64);

    /// Called while the cloud is read (stage `read`, which takes no share of `fraction`):
    /// `bytes` of the file's `total` read so far. The default ignores it.
    fn read(&mut self, _bytes: u64, _total: u64) {}

    /// Called as each story's stages begin: story `number` (from 1) of `count`. The default
    /// ignores it.
    fn story(&mut self, _number: usize, _count: usize) {}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_is_in_pipeline_order_and_story_weights_sum_to_one() {
        for (i, r) in STAGES.iter().enumerate() {
            assert_eq!(r.stage as usize, i, "{}", r.name);
            assert_eq!(Stage::from_name(r.name), Some(r.stage));
        }
        let total: f64 = STAGES.iter().map(|r| r.weight).sum();
        assert!((total - 1.0).abs() < 1e-12, "{total}");
        assert_eq!(Stage::Samples.start(), 0.0);
        assert!((Stage::Labeling.start() - 0.5).abs() < 1e-12);
        assert!((Stage::Write.start() - 1.0).abs() < 1e-12);
        let keys: Vec<&str> = timing_keys().collect();
        assert_eq!(keys[4..6], ["triangulate", "label"]);
        assert_eq!(keys[6..9], ["cleanup", "boundary", "fit"]);
    }
}
