//! What a worker runs: [`Pipeline`] turns a job's files into result files. [`PlanPipeline`] is
//! the real one (`asbuilt-plan`); tests and `--fake-pipeline-ms` substitute others.

use std::path::{Path, PathBuf};

use asbuilt_plan::io::outputs::{Output, OUTPUTS};
use asbuilt_plan::io::ReadOptions;
use asbuilt_plan::progress::{Progress, Stage};
use asbuilt_plan::FloorPlan;
use asbuilt_plan::{plan_decoded, plan_scan, Cancelled, Params, Planned, RunError, Scan};

use super::early::EarlyCloud;
use crate::errors::JobCode;
use crate::queue::JobId;

/// The sidecar kinds are the pipeline's own.
pub use asbuilt_plan::io::SidecarKind;

/// A job's inputs, as local files.
#[derive(Debug, Clone)]
pub struct JobInput {
    pub job: JobId,
    pub cloud: PathBuf,
    pub sidecar: Option<(SidecarKind, PathBuf)>,
    pub params: Params,
    /// Clouds with more points fail with `too_many_points`.
    pub max_points: u64,
    /// The client's georeference, if it gave one.
    pub georeference: Option<asbuilt_plan::georef::Georeference>,
    /// The cloud, read as the upload arrived (`cloud` is then not fetched).
    pub early: Option<EarlyCloud>,
}

/// A finished run's files and summary.
#[derive(Debug, Clone)]
pub struct JobResults {
    /// `floorplan.input`: points, format, scans.
    pub input: serde_json::Value,
    /// Stage name → milliseconds, pipeline order, `total` last.
    pub timings_ms: Vec<(String, u64)>,
    /// Every result file of `asbuilt_plan::io::outputs::OUTPUTS`, in its order.
    pub files: Vec<(&'static Output, Vec<u8>)>,
}

impl JobResults {
    /// The summary and every result file of `plan`.
    pub fn of(plan: &FloorPlan) -> Result<JobResults, PipelineFailure> {
        let files = OUTPUTS
            .iter()
            .map(|o| {
                (o.write)(plan)
                    .map(|bytes| (o, bytes))
                    .map_err(|e| PipelineFailure::new(JobCode::OutputFailed, e))
            })
            .collect::<Result<_, _>>()?;
        Ok(JobResults {
            input: serde_json::to_value(&plan.input).unwrap_or_default(),
            timings_ms: plan.timings_ms.clone(),
            files,
        })
    }
}

/// Why a run failed: a stable code and a message for the user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PipelineFailure {
    pub code: JobCode,
    pub message: String,
}

impl PipelineFailure {
    pub fn new(code: JobCode, message: impl Into<String>) -> PipelineFailure {
        PipelineFailure {
            code,
            message: message.into(),
        }
    }

    /// A failure the pipeline named by its code. A code the service does not know is a bug
    /// on one side or the other, reported as such.
    pub fn from_pipeline(code: &str, message: impl Into<String>) -> PipelineFailure {
        match JobCode::parse(code) {
            Some(code) => PipelineFailure::new(code, message),
            None => PipelineFailure::new(
                JobCode::PipelinePanic,
                format!("{} (unknown code `{code}`)", message.into()),
            ),
        }
    }

    /// The pipeline stopped because `Progress::cancel` said so.
    pub fn cancelled() -> PipelineFailure {
        PipelineFailure::stopped(Cancelled::ByCaller)
    }

    /// The pipeline stopped on its flag (`cancelled`) or its deadline (`time_limit`).
    pub fn stopped(why: Cancelled) -> PipelineFailure {
        PipelineFailure::from_pipeline(why.code(), why.to_string())
    }

    /// True when the run was stopped from outside rather than failing on its own.
    pub fn is_stop(&self) -> bool {
        matches!(self.code, JobCode::Cancelled | JobCode::TimeLimit)
    }
}

/// Runs one job, synchronously, on a blocking thread. Must check `progress.cancel()` often
/// enough that a stop lands within a second.
pub trait Pipeline: Send + Sync + 'static {
    fn run(
        &self,
        input: &JobInput,
        progress: &mut dyn Progress,
    ) -> Result<JobResults, PipelineFailure>;

    /// True when [`JobInput::early`] is used; uploads are then read as they arrive.
    fn reads_early(&self) -> bool {
        false
    }
}

/// The point-count limit, shared by every pipeline.
pub fn check_points(points: u64, max: u64) -> Result<(), PipelineFailure> {
    match points > max {
        true => Err(too_many_points(points, max)),
        false => Ok(()),
    }
}

fn too_many_points(points: u64, max: u64) -> PipelineFailure {
    PipelineFailure::new(
        JobCode::TooManyPoints,
        format!("the cloud has {points} points; this server accepts at most {max}"),
    )
}

/// The real pipeline: `asbuilt_plan`'s front door, then GeoJSON, SVG and DXF.
pub struct PlanPipeline;

/// Messages from readers name the file; the user knows it as "the cloud", not a server path.
fn hide_path(message: String, path: &Path, name: &str) -> String {
    message.replace(&path.display().to_string(), name)
}

impl Pipeline for PlanPipeline {
    fn reads_early(&self) -> bool {
        true
    }

    fn run(
        &self,
        input: &JobInput,
        progress: &mut dyn Progress,
    ) -> Result<JobResults, PipelineFailure> {
        let scan = Scan {
            cloud: &input.cloud,
            sidecar: input.sidecar.as_ref().map(|(k, p)| (*k, p.as_path())),
            read: ReadOptions::default(),
            params: &input.params,
            stream: None,
            max_points: Some(input.max_points),
            georeference: input.georeference.clone(),
        };
        let planned = match input.early.as_ref().and_then(EarlyCloud::take) {
            Some(d) => plan_decoded(&scan, d.cloud, d.read_ms, progress),
            None => plan_scan(&scan, progress),
        };
        let Planned { plan, .. } = planned.map_err(|e| failure(e, input))?;
        progress.report(Stage::Write, 1.0);
        JobResults::of(&plan)
    }
}

/// The job's failure: stops as stops, the limit in the server's words, and every message with
/// the server's paths replaced by the names the client knows.
fn failure(e: RunError, input: &JobInput) -> PipelineFailure {
    if let Some(c) = e.cancelled() {
        return PipelineFailure::stopped(c);
    }
    if let RunError::TooManyPoints { points, max } = e {
        return too_many_points(points, max);
    }
    let mut message = hide_path(e.to_string(), &input.cloud, "cloud");
    if let Some((kind, path)) = &input.sidecar {
        message = sidecar_message(message, path, *kind);
    }
    PipelineFailure::from_pipeline(e.code(), message)
}

/// A reader names a sidecar's problem `PATH: poses: why`; the client knows the file as its
/// part, so it reads `poses: why` or `trajectory: why`, not `poses: poses: why`.
fn sidecar_message(message: String, path: &Path, kind: SidecarKind) -> String {
    let named = format!("{}: poses: ", path.display());
    let message = message.replace(&named, &format!("{}: ", kind.name()));
    hide_path(message, path, kind.name())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sidecar_error_names_its_part_once() {
        let path = Path::new("/data/jobs/x/sidecar.json");
        let said = "/data/jobs/x/sidecar.json: poses: not valid pose JSON: no `scans` array";
        assert_eq!(
            sidecar_message(said.into(), path, SidecarKind::Poses),
            "poses: not valid pose JSON: no `scans` array"
        );
        assert_eq!(
            sidecar_message(said.into(), path, SidecarKind::Trajectory),
            "trajectory: not valid pose JSON: no `scans` array"
        );
        let other = "the cloud has points of scan 0 but /data/jobs/x/sidecar.json has none";
        assert_eq!(
            sidecar_message(other.into(), path, SidecarKind::Poses),
            "the cloud has points of scan 0 but poses has none"
        );
    }
}
