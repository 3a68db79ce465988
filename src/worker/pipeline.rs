//! What a worker runs: [`Pipeline`] turns a job's files into result files. [`PlanPipeline`] is
//! the real one (`asbuilt-plan`); tests and `--fake-pipeline-ms` substitute others.

use std::path::{Path, PathBuf};
use std::time::Instant;

use asbuilt_plan::io::ReadOptions;
use asbuilt_plan::io::{self, dxf, geojson, poses, svg};
use asbuilt_plan::progress::{Progress, Stage};
use asbuilt_plan::{Cancelled, Params};

use crate::queue::JobId;

/// Which kind of sidecar came with the cloud.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SidecarKind {
    Poses,
    Trajectory,
}

impl SidecarKind {
    /// The multipart part name, also stored in the job's upload record.
    pub fn name(self) -> &'static str {
        match self {
            SidecarKind::Poses => "poses",
            SidecarKind::Trajectory => "trajectory",
        }
    }

    pub fn from_name(name: &str) -> Option<SidecarKind> {
        match name {
            "poses" => Some(SidecarKind::Poses),
            "trajectory" => Some(SidecarKind::Trajectory),
            _ => None,
        }
    }
}

/// A job's inputs, as local files.
#[derive(Debug, Clone)]
pub struct JobInput {
    pub job: JobId,
    pub cloud: PathBuf,
    pub sidecar: Option<(SidecarKind, PathBuf)>,
    pub params: Params,
    /// Clouds with more points fail with `too_many_points`.
    pub max_points: u64,
}

/// A finished run's files and summary.
#[derive(Debug, Clone)]
pub struct JobResults {
    /// `floorplan.input`: points, format, scans.
    pub input: serde_json::Value,
    /// Stage name → milliseconds, pipeline order, `total` last.
    pub timings_ms: Vec<(String, u64)>,
    pub geojson: Vec<u8>,
    pub svg: Vec<u8>,
    pub dxf: Vec<u8>,
}

/// Why a run failed: a stable code (see `errors::JOB_CODES`) and a message for the user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PipelineFailure {
    pub code: String,
    pub message: String,
}

impl PipelineFailure {
    pub fn new(code: &str, message: impl Into<String>) -> PipelineFailure {
        PipelineFailure {
            code: code.to_string(),
            message: message.into(),
        }
    }

    /// The pipeline stopped because `Progress::cancel` said so.
    pub fn cancelled() -> PipelineFailure {
        PipelineFailure::stopped(Cancelled::ByCaller)
    }

    /// The pipeline stopped on its flag (`cancelled`) or its deadline (`time_limit`).
    pub fn stopped(why: Cancelled) -> PipelineFailure {
        PipelineFailure::new(why.code(), why.to_string())
    }

    /// True when the run was stopped from outside rather than failing on its own.
    pub fn is_stop(&self) -> bool {
        [Cancelled::ByCaller, Cancelled::TimeLimit]
            .iter()
            .any(|c| c.code() == self.code)
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
}

/// The point-count limit, shared by every pipeline.
pub fn check_points(points: u64, max: u64) -> Result<(), PipelineFailure> {
    if points > max {
        return Err(PipelineFailure::new(
            "too_many_points",
            format!("the cloud has {points} points; this server accepts at most {max}"),
        ));
    }
    Ok(())
}

/// The real pipeline: read, attach sidecar, plan, write GeoJSON, SVG and DXF.
pub struct PlanPipeline;

/// Messages from readers name the file; the user knows it as "the cloud", not a server path.
fn hide_path(message: String, path: &Path, name: &str) -> String {
    message.replace(&path.display().to_string(), name)
}

impl Pipeline for PlanPipeline {
    fn run(
        &self,
        input: &JobInput,
        progress: &mut dyn Progress,
    ) -> Result<JobResults, PipelineFailure> {
        progress.report(Stage::Read, 0.0);
        let read_start = Instant::now();
        // Refuse an over-limit cloud before the reader allocates it.
        match io::declared_points(&input.cloud, &progress.cancel()) {
            Ok(Some(n)) => check_points(n, input.max_points)?,
            Ok(None) => {}
            Err(c) => return Err(PipelineFailure::stopped(c)),
        }
        let options = ReadOptions {
            cancel: progress.cancel(),
            ..ReadOptions::default()
        };
        let mut cloud = io::read_cloud_with(&input.cloud, &options).map_err(|e| match e {
            io::ReadError::Cancelled(c, _) => PipelineFailure::stopped(c),
            e => PipelineFailure::new(e.code(), hide_path(e.to_string(), &input.cloud, "cloud")),
        })?;
        check_points(cloud.len() as u64, input.max_points)?;
        if let Some((kind, path)) = &input.sidecar {
            // The readers cap the sidecar's size; the message names the part, not our path.
            let loaded = match kind {
                SidecarKind::Poses => poses::load_poses(&mut cloud, path),
                SidecarKind::Trajectory => poses::load_trajectory(&mut cloud, path),
            };
            loaded.map_err(|e| {
                PipelineFailure::new("invalid_poses", hide_path(e.to_string(), path, kind.name()))
            })?;
        }
        let read_ms = read_start.elapsed().as_millis() as u64;
        if let Err(c) = progress.cancel().check() {
            return Err(PipelineFailure::stopped(c));
        }
        let mut plan = asbuilt_plan::plan(&cloud, &input.params, progress).map_err(|e| match e
            .cancelled()
        {
            Some(c) => PipelineFailure::stopped(c),
            None => PipelineFailure::new(e.code(), e.to_string()),
        })?;
        drop(cloud);
        plan.timings_ms.insert(0, ("read".into(), read_ms));
        if let Some((_, total)) = plan.timings_ms.iter_mut().find(|(n, _)| n == "total") {
            *total += read_ms;
        }
        progress.report(Stage::Write, 1.0);
        let dxf = dxf::to_dxf(&plan)
            .map_err(|e| PipelineFailure::new("output_failed", format!("DXF: {e}")))?;
        Ok(JobResults {
            input: serde_json::to_value(&plan.input).unwrap_or_default(),
            timings_ms: plan.timings_ms.clone(),
            geojson: geojson::to_geojson_string(&plan).into_bytes(),
            svg: svg::to_svg(&plan).into_bytes(),
            dxf,
        })
    }
}
