//! The service end to end, in process, with a synthetic pipeline (the real stages are tested in
//! `service_plan.rs`): uploads, limits, auth, listing, events, cancel, failures, leases,
//! retention, shutdown, metrics, OpenAPI and the page.

mod document;
mod failures;
mod jobs;
mod refusals;
mod uploads;

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use asbuilt::worker::fake::FakePipeline;
use asbuilt::worker::pipeline::{JobInput, JobResults, Pipeline, PipelineFailure};
use asbuilt_plan::progress::Progress;

fn fake(ms: u64) -> Arc<dyn Pipeline> {
    Arc::new(FakePipeline {
        stage_time: Duration::from_millis(ms),
        completions: None,
        spin: false,
    })
}

/// Wraps a pipeline and records when and how each run ended.
#[derive(Default)]
struct Probe {
    ended: Mutex<Vec<(Instant, Result<(), String>)>>,
}

struct Probed(Arc<Probe>, FakePipeline);

impl Pipeline for Probed {
    fn run(
        &self,
        input: &JobInput,
        progress: &mut dyn Progress,
    ) -> Result<JobResults, PipelineFailure> {
        let r = self.1.run(input, progress);
        let outcome = r
            .as_ref()
            .map(|_| ())
            .map_err(|e| e.code.as_str().to_string());
        self.0.ended.lock().unwrap().push((Instant::now(), outcome));
        r
    }
}

fn probed(ms: u64) -> (Arc<Probe>, Arc<dyn Pipeline>) {
    let probe = Arc::new(Probe::default());
    let p = Probed(
        probe.clone(),
        FakePipeline {
            stage_time: Duration::from_millis(ms),
            completions: None,
            spin: false,
        },
    );
    (probe, Arc::new(p))
}
