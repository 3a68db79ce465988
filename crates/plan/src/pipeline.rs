//! The one place that lists the stages in order: cloud in, floor plan out.

use std::time::Instant;

use crate::boundary::{trace_boundary, BoundaryError};
use crate::cleanup::clean_labels;
use crate::cloud::PointCloud;
use crate::fitting::{fit_walls, FittingError};
use crate::labeling::{label, LabelingError};
use crate::params::Params;
use crate::plan::{FloorPlan, InputSummary, StoryPlan};
use crate::progress::{Progress, Stage};
use crate::samples::{sample_walls, SamplesError};
use crate::smoothing::{smooth_samples, SmoothingError};
use crate::stories::{split_stories, StoriesError, Story};

/// Why a plan could not be made. Each variant names the stage.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    #[error("the cloud is empty")]
    EmptyCloud,
    #[error("the cloud is inconsistent: {0}")]
    BadCloud(String),
    #[error("stories: {0}")]
    Stories(#[from] StoriesError),
    #[error("wall samples: {0}")]
    Samples(#[from] SamplesError),
    #[error("smoothing: {0}")]
    Smoothing(#[from] SmoothingError),
    #[error("labeling: {0}")]
    Labeling(#[from] LabelingError),
    #[error("boundary: {0}")]
    Boundary(#[from] BoundaryError),
    #[error("fitting: {0}")]
    Fitting(#[from] FittingError),
    #[error("no story produced a plan: {0}")]
    NoPlan(String),
    #[error("cancelled")]
    Cancelled,
}

impl PlanError {
    /// A stable machine-readable code for the service's error bodies.
    pub fn code(&self) -> &'static str {
        match self {
            PlanError::EmptyCloud => "empty_cloud",
            PlanError::BadCloud(_) => "bad_cloud",
            PlanError::Stories(_) => "no_stories",
            PlanError::Samples(_) => "samples_failed",
            PlanError::Smoothing(_) => "smoothing_failed",
            PlanError::Labeling(_) => "labeling_failed",
            PlanError::Boundary(_) => "boundary_failed",
            PlanError::Fitting(_) => "fitting_failed",
            PlanError::NoPlan(_) => "no_plan",
            PlanError::Cancelled => "cancelled",
        }
    }
}

/// Accumulates per-stage wall time in pipeline order.
#[derive(Default)]
struct Timings(Vec<(String, u64)>);

impl Timings {
    fn time<T>(&mut self, stage: Stage, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        let ms = start.elapsed().as_millis() as u64;
        match self.0.iter_mut().find(|(n, _)| n == stage.name()) {
            Some((_, total)) => *total += ms,
            None => self.0.push((stage.name().to_string(), ms)),
        }
        out
    }
}

/// Runs every stage on `cloud` and returns the floor plan (local coordinates + origin).
pub fn plan(
    cloud: &PointCloud,
    params: &Params,
    progress: &mut dyn Progress,
) -> Result<FloorPlan, PlanError> {
    let start = Instant::now();
    if cloud.is_empty() {
        return Err(PlanError::EmptyCloud);
    }
    cloud.check().map_err(PlanError::BadCloud)?;
    let mut timings = Timings::default();
    let mut notes = Vec::new();
    progress.report(Stage::Stories, 0.0);
    let z: Vec<f32> = cloud.xyz.iter().map(|p| p[2]).collect();
    let stories = timings.time(Stage::Stories, || split_stories(&z, &params.stories))?;
    drop(z);
    let mut plans = Vec::new();
    let mut parameters = params.to_json();
    let mut min_points_used = Vec::new();
    let mut failures = Vec::new();
    for (i, story) in stories.iter().enumerate() {
        let at = |k: f64| (i as f64 + k) / stories.len() as f64;
        match plan_story(cloud, story, params, progress, &mut timings, at) {
            Ok((story_plan, used, story_notes)) => {
                min_points_used.push(used);
                notes.extend(
                    story_notes
                        .into_iter()
                        .map(|n| format!("story {}: {n}", story.level)),
                );
                plans.push(story_plan);
            }
            Err(PlanError::Cancelled) => return Err(PlanError::Cancelled),
            Err(e) => {
                notes.push(format!(
                    "story {} (floor z {:.2}) skipped: {e}",
                    story.level,
                    story.floor_z + cloud.origin[2]
                ));
                failures.push(e.to_string());
            }
        }
    }
    if plans.is_empty() {
        return Err(PlanError::NoPlan(failures.join("; ")));
    }
    if params.samples.min_points.is_none() {
        parameters["samples"]["min_points_derived"] = serde_json::json!(min_points_used);
    }
    timings
        .0
        .push(("total".into(), start.elapsed().as_millis() as u64));
    progress.report(Stage::Write, 1.0);
    Ok(FloorPlan {
        origin: cloud.origin,
        crs: cloud.crs.clone(),
        input: InputSummary {
            points: cloud.len() as u64,
            format: cloud.source.format.clone(),
            scans: match &cloud.viewpoints {
                crate::cloud::Viewpoints::Static(p) => p.len(),
                _ => 0,
            },
        },
        parameters,
        timings_ms: timings.0,
        stories: plans,
        notes,
    })
}

fn plan_story(
    cloud: &PointCloud,
    story: &Story,
    params: &Params,
    progress: &mut dyn Progress,
    timings: &mut Timings,
    at: impl Fn(f64) -> f64,
) -> Result<(StoryPlan, usize, Vec<String>), PlanError> {
    let mut step = |stage: Stage, k: f64| {
        progress.report(stage, at(k));
        if progress.cancelled() {
            Err(PlanError::Cancelled)
        } else {
            Ok(())
        }
    };
    step(Stage::Samples, 0.0)?;
    let mut samples = timings.time(Stage::Samples, || {
        sample_walls(cloud, story, &params.samples)
    })?;
    step(Stage::Smoothing, 0.4)?;
    timings.time(Stage::Smoothing, || {
        smooth_samples(&mut samples, params.samples.cell_size, &params.smoothing)
    })?;
    step(Stage::Labeling, 0.5)?;
    let mut labeled = timings.time(Stage::Labeling, || label(&samples, &params.labeling))?;
    step(Stage::Cleanup, 0.8)?;
    timings.time(Stage::Cleanup, || {
        clean_labels(&mut labeled, &params.cleanup)
    });
    let boundary = timings.time(Stage::Cleanup, || trace_boundary(&labeled))?;
    step(Stage::Fitting, 0.9)?;
    let fitted = timings.time(Stage::Fitting, || {
        fit_walls(&labeled, &boundary, &params.fitting)
    })?;
    let plan = StoryPlan {
        level: story.level,
        floor_z: story.floor_z,
        ceiling_z: story.ceiling_z,
        polygons: fitted.polygons,
        walls: fitted.walls,
        samples: samples.samples.iter().map(|s| s.pos).collect(),
    };
    Ok((plan, samples.min_points_used, fitted.notes))
}
