//! The one place that lists the stages in order: cloud in, floor plan out.

use std::sync::Mutex;
use std::time::Instant;

use rayon::prelude::*;

use crate::boundary::{trace_boundary, BoundaryError};
use crate::cancel::{Cancel, Cancelled};
use crate::cleanup::clean_labels;
use crate::cloud::{PointCloud, Viewpoints, NON_FINITE};
use crate::fitting::{fit_walls, FittingError};
use crate::labeling::{label_with_report, LabelingError};
use crate::params::Params;
use crate::plan::{FloorPlan, InputSummary, StoryPlan};
use crate::progress::{Progress, Stage};
use crate::rooms::{find_rooms, Scanner, StoryPoints};
use crate::samples::{
    check_params, sample_walls_in, Blocks, SamplesError, SpacingProbe, StoryBounds, WallSamples,
};
use crate::smoothing::{smooth_samples, SmoothingError};
use crate::stories::{split_cloud_stories_within, Heights, StoriesError, Story};
use crate::validity::{make_valid, Grid};
use crate::viewpoints::{self, OpenSpaceStory, ViewpointSource, ViewpointsReport};

/// Why a plan could not be made. Each variant names the stage.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The cloud holds no points.
    #[error("the cloud is empty")]
    EmptyCloud,
    /// The cloud's arrays disagree (lengths, scan slots); the message says how.
    #[error("the cloud is inconsistent: {0}")]
    BadCloud(String),
    /// Splitting into stories failed (§3.1).
    #[error("stories: {0}")]
    Stories(#[from] StoriesError),
    /// Wall sampling failed (§3.1).
    #[error("wall samples: {0}")]
    Samples(#[from] SamplesError),
    /// Smoothing the samples failed (§3.2).
    #[error("smoothing: {0}")]
    Smoothing(#[from] SmoothingError),
    /// Labeling rooms failed (§3.3).
    #[error("labeling: {0}")]
    Labeling(#[from] LabelingError),
    /// Tracing the boundary failed (§3.4).
    #[error("boundary: {0}")]
    Boundary(#[from] BoundaryError),
    /// Fitting the walls failed (§3.5).
    #[error("fitting: {0}")]
    Fitting(#[from] FittingError),
    /// Every story failed. `code` is their stage's code when they all failed in the same
    /// stage, else `no_plan`; `why` lists each story's failure.
    #[error("no story produced a plan: {why}")]
    NoPlan {
        /// The stage's error code, or `no_plan`.
        code: &'static str,
        /// Each story's failure.
        why: String,
    },
    /// The caller's [`Cancel`] stopped the run (whichever stage it was in).
    #[error("{0}")]
    Cancelled(#[from] Cancelled),
}

impl PlanError {
    /// A stable machine-readable code for the service's error bodies.
    pub fn code(&self) -> &'static str {
        match self {
            PlanError::EmptyCloud => "empty_cloud",
            PlanError::BadCloud(_) => "bad_cloud",
            PlanError::NoPlan { code, .. } => code,
            PlanError::Cancelled(c) => c.code(),
            e => e.stage().and_then(Stage::error_code).unwrap_or("no_plan"),
        }
    }

    /// The stage that failed, for the errors of one stage.
    pub fn stage(&self) -> Option<Stage> {
        match self {
            PlanError::Stories(_) => Some(Stage::Stories),
            PlanError::Samples(_) => Some(Stage::Samples),
            PlanError::Smoothing(_) => Some(Stage::Smoothing),
            PlanError::Labeling(_) => Some(Stage::Labeling),
            // Boundary tracing runs within cleanup.
            PlanError::Boundary(_) => Some(Stage::Cleanup),
            PlanError::Fitting(_) => Some(Stage::Fitting),
            _ => None,
        }
    }

    /// Why the run was stopped from outside, if it was: a stage's own `Cancelled` variant is
    /// the same stop as [`PlanError::Cancelled`].
    pub fn cancelled(&self) -> Option<Cancelled> {
        match self {
            PlanError::Cancelled(c)
            | PlanError::Samples(SamplesError::Cancelled(c))
            | PlanError::Smoothing(SmoothingError::Cancelled(c))
            | PlanError::Labeling(LabelingError::Cancelled(c))
            | PlanError::Fitting(FittingError::Cancelled(c)) => Some(*c),
            _ => None,
        }
    }

    /// Lifts a stage's `Cancelled` to [`PlanError::Cancelled`], so callers match one variant.
    fn lift(self) -> PlanError {
        match self.cancelled() {
            Some(c) => PlanError::Cancelled(c),
            None => self,
        }
    }
}

/// The `timings_ms` key of the Delaunay triangulation, the first part of labeling (§3.3).
pub const TRIANGULATE: &str = "triangulate";
/// The `timings_ms` key of tracing the labeled rooms' boundary (§3.4), timed apart from the
/// cleanup it ends so a slow trace shows as such.
pub const BOUNDARY: &str = "boundary";
/// The `timings_ms` key of the last step: every polygon made OGC-valid on the output grid.
pub const VALIDITY: &str = "validity";
/// The `timings_ms` key of estimating scanner positions the input does not give.
pub const VIEWPOINTS: &str = "viewpoints";

/// Accumulates per-stage wall time in pipeline order.
#[derive(Default)]
pub(crate) struct Timings(Vec<(String, f64)>);

impl Timings {
    pub(crate) fn time<T>(&mut self, stage: Stage, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        self.add(stage.name(), start.elapsed().as_secs_f64() * 1e3);
        out
    }

    /// Adds `ms` to the stage `name`. Fractions are kept until the end, so stages run once per
    /// story do not each lose their sub-millisecond part.
    pub(crate) fn add(&mut self, name: &str, ms: f64) {
        match self.0.iter_mut().find(|(n, _)| n == name) {
            Some((_, total)) => *total += ms,
            None => self.0.push((name.to_string(), ms)),
        }
    }

    fn into_ms(self) -> Vec<(String, u64)> {
        self.0
            .into_iter()
            .map(|(n, ms)| (n, ms.round() as u64))
            .collect()
    }
}

/// What the first stages need of every point, found in one pass over them: the cloud's
/// memory is read once rather than three times.
#[derive(Default)]
struct Survey {
    /// Every coordinate finite.
    finite: bool,
    /// The heights the stories are found over.
    heights: Heights,
    /// The sample the point spacing is measured on.
    probe: SpacingProbe,
}

impl Survey {
    /// Points per block: a block is read three times, from the core's cache after the first.
    const BLOCK: usize = 1 << 16;

    /// One survey a thread, each over a contiguous share of the points. The spacing probe
    /// keeps every point until its sample fills, then thins it level by level: a survey per
    /// rayon split (16 on the 17.4 M-point office) pushed and thinned three times the points
    /// that one a thread does. Every part merges the same in any grouping.
    fn of(xyz: &[[f32; 3]]) -> Survey {
        let fresh = || Survey {
            finite: true,
            ..Survey::default()
        };
        let share = xyz
            .len()
            .div_ceil(rayon::current_num_threads().max(1))
            .max(Self::BLOCK);
        xyz.par_chunks(share)
            .map(|part| {
                let mut s = fresh();
                for block in part.chunks(Self::BLOCK) {
                    s.finite &= block.iter().all(|p| p.iter().all(|c| c.is_finite()));
                    block.iter().for_each(|p| s.heights.add(p[2]));
                    s.probe.add(block);
                }
                s
            })
            .reduce(fresh, Survey::merge)
    }

    fn merge(mut self, o: Survey) -> Survey {
        self.finite &= o.finite;
        self.heights = self.heights.merge(o.heights);
        self.probe.merge(o.probe);
        self
    }
}

/// Runs every stage on `cloud` and returns the floor plan (local coordinates + origin).
///
/// ```
/// use asbuilt_plan::progress::NoProgress;
/// use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
/// use asbuilt_plan::{plan, Params};
///
/// // A simulated 6 m × 5 m room: one story, one room.
/// let options = ScanOptions { points: 40_000, seed: 1, ..Default::default() };
/// let sim = simulate(BuildingKind::SquareRoom, &options).unwrap();
/// let floor_plan = plan(&sim.cloud, &Params::default(), &mut NoProgress).unwrap();
/// assert_eq!(floor_plan.stories.len(), 1);
/// assert_eq!(floor_plan.stories[0].polygons.len(), 1);
/// ```
pub fn plan(
    cloud: &PointCloud,
    params: &Params,
    progress: &mut dyn Progress,
) -> Result<FloorPlan, PlanError> {
    let start = Instant::now();
    let cancel = progress.cancel();
    if cloud.is_empty() {
        return Err(PlanError::EmptyCloud);
    }
    cloud.check_arrays().map_err(PlanError::BadCloud)?;
    let mut timings = Timings::default();
    progress.report(Stage::Stories, 0.0);
    // One pass over the points for the finiteness `check` tests, the heights the stories are
    // found over, and the point spacing, which chooses the grid's scale (and what follows).
    let survey = timings.time(Stage::Samples, || Survey::of(&cloud.xyz));
    if !survey.finite {
        return Err(PlanError::BadCloud(NON_FINITE.into()));
    }
    let spacing = survey.probe.spacing();
    let (params, reported) = params.derive(spacing);
    let params = &params;
    let clock = Instant::now();
    let estimate = viewpoints::estimate(cloud, &params.viewpoints);
    timings.add(VIEWPOINTS, clock.elapsed().as_secs_f64() * 1e3);
    cancel.check()?;
    // Estimated viewpoints are used exactly as given ones, except an estimated mobile path:
    // it is reported, but the labeling takes its lines of sight from pseudo-viewpoints in open
    // space. Between located windows the path is a guess, and where the walker turned unseen
    // (into a room and out) its lines of sight cut walls; on the simulated mobile scans the
    // pseudo-viewpoints planned as well or better (sparse office 0.9794 against 0.9730).
    let path_set_aside = params.viewpoints.open_space
        && matches!(estimate.viewpoints, Some(Viewpoints::Trajectory(_)));
    let seen_from = match &estimate.viewpoints {
        _ if path_set_aside => &Viewpoints::None,
        Some(v) => v,
        None => &cloud.viewpoints,
    };
    // Splitting the stories and measuring their bounds are a few linear passes over the
    // points: checked between them, not inside.
    let stories = timings.time(Stage::Stories, || {
        split_cloud_stories_within(&cloud.xyz, survey.heights, &params.stories)
    })?;
    cancel.check()?;
    // One pass finds where every story's grid lies.
    let (bounds, blocks) = timings.time(Stage::Samples, || {
        StoryBounds::measure_all(&cloud.xyz, &stories)
    });
    cancel.check()?;
    // Plain x, y, z: pseudo-viewpoints in the open space the samples enclose, per story.
    let plain = matches!(seen_from, Viewpoints::None) && params.viewpoints.open_space;
    let open_space = Mutex::new(Vec::new());
    let mut sample = |story: &Story, cancel: &Cancel| {
        let p = &params.samples;
        check_params(p, story)?;
        let frame = bounds[story.level].frame(story, p.cell_size)?;
        let mut samples = sample_walls_in(
            cloud,
            seen_from,
            story,
            p,
            &frame,
            Some(&blocks.spans(story)),
            cancel,
        )?;
        // Timed with sampling.
        if plain {
            let placed = viewpoints::place_open_space(
                cloud,
                story,
                &mut samples,
                &params.viewpoints,
                p.max_range,
            );
            open_space
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push(placed);
            cancel.check()?;
        }
        Ok(samples)
    };
    let mut summary = CloudSummary::of(cloud, cloud.len() as u64);
    summary.viewpoints = estimate.report;
    summary.open_space = Some(&open_space);
    summary.scanners = scanners(seen_from);
    summary.blocks = Some(&blocks);
    plan_stories(
        &summary,
        &stories,
        params,
        reported,
        progress,
        timings,
        start,
        &mut sample,
    )
}

/// What a plan reports of its input, for clouds held whole or read in pieces.
pub(crate) struct CloudSummary<'a> {
    pub cloud: &'a PointCloud,
    /// Points read (the cloud itself may hold none of them).
    pub points: u64,
    /// The viewpoints planned with: given or estimated.
    pub viewpoints: ViewpointsReport,
    /// Plain x, y, z: the pseudo-viewpoints placed per story as the stories are sampled.
    pub open_space: Option<&'a Mutex<Vec<OpenSpaceStory>>>,
    /// The static scanners' positions, for the rooms they stand in.
    pub scanners: Vec<Scanner>,
    /// The height range of each block of the cloud's points, when measured.
    pub blocks: Option<&'a Blocks>,
}

impl<'a> CloudSummary<'a> {
    pub fn of(cloud: &'a PointCloud, points: u64) -> Self {
        CloudSummary {
            cloud,
            points,
            viewpoints: ViewpointsReport::default(),
            open_space: None,
            scanners: scanners(&cloud.viewpoints),
            blocks: None,
        }
    }
}

/// Static scanners' positions, by the index the user gave each scan.
fn scanners(viewpoints: &Viewpoints) -> Vec<Scanner> {
    match viewpoints {
        Viewpoints::Static(poses) => poses
            .iter()
            .map(|p| Scanner {
                index: p.index as usize,
                position: p.position,
            })
            .collect(),
        _ => Vec::new(),
    }
}

/// Every stage after the stories, story by story; `sample` gives a story's wall samples.
/// Stories that fail are noted and skipped; the plan fails only when none succeeds. A stop
/// from `progress`'s [`Cancel`] ends the whole run as [`PlanError::Cancelled`]. `params` are
/// the ones the run uses, `parameters` what the plan reports of them ([`Params::derive`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn plan_stories(
    input: &CloudSummary<'_>,
    stories: &[Story],
    params: &Params,
    mut parameters: serde_json::Value,
    progress: &mut dyn Progress,
    mut timings: Timings,
    start: Instant,
    sample: &mut SampleStory<'_>,
) -> Result<FloorPlan, PlanError> {
    let cloud = input.cloud;
    let cancel = progress.cancel();
    let mut notes = Vec::new();
    let mut plans = Vec::new();
    let mut min_points_used = Vec::new();
    let mut min_points_lowest = Vec::new();
    let mut failures = Vec::new();
    let mut codes = Vec::new();
    // Open area in all, and the part viewpoint evidence forced inside.
    let mut evidence = (0.0, 0.0);
    // The next story is sampled while this one runs its later stages: those run on one core
    // for much of their time (the triangulation, fitting), and sampling fills both. Stories
    // are still sampled one at a time and in order, so one story's grid is held at a time.
    let mut ahead: Option<Sampled> = None;
    for (i, story) in stories.iter().enumerate() {
        let at = |k: f64| (i as f64 + k) / stories.len() as f64;
        progress.story(i + 1, stories.len());
        // What was assumed about the floor or ceiling goes with the story's plan or failure.
        let assumed = story.assumptions(cloud.origin[2]);
        let sampled = match ahead.take() {
            Some(sampled) => sampled,
            None => {
                progress.report(Stage::Samples, at(Stage::Samples.start()));
                Sampled::of(&mut *sample, story, &cancel)
            }
        };
        let next = stories.get(i + 1);
        let (outcome, next) = rayon::join(
            || plan_story(story, sampled, input, params, progress, &mut timings, at),
            || next.map(|s| Sampled::of(&mut *sample, s, &cancel)),
        );
        ahead = next;
        match outcome.map_err(PlanError::lift) {
            Ok(StoryOutcome {
                plan: story_plan,
                min_points_used: used,
                min_points_lowest: lowest,
                notes: story_notes,
                forced,
            }) => {
                evidence.0 += forced.0;
                evidence.1 += forced.1;
                min_points_used.push(used);
                min_points_lowest.push(lowest);
                notes.extend(
                    assumed
                        .into_iter()
                        .chain(story_notes)
                        .map(|n| format!("story {}: {n}", story.level)),
                );
                plans.push(story_plan);
            }
            Err(PlanError::Cancelled(c)) => return Err(PlanError::Cancelled(c)),
            Err(e) => {
                let why = match assumed.is_empty() {
                    true => e.to_string(),
                    false => format!("{e} ({})", assumed.join("; ")),
                };
                notes.push(format!(
                    "story {} (floor z {:.2}) skipped: {why}",
                    story.level,
                    story.floor_z + cloud.origin[2]
                ));
                failures.push(why);
                codes.push(e.code());
            }
        }
    }
    if plans.is_empty() {
        return Err(PlanError::NoPlan {
            code: shared_code(&codes),
            why: failures.join("; "),
        });
    }
    if params.samples.min_points.is_none() {
        parameters["samples"]["min_points_derived"] = serde_json::json!(min_points_used);
        parameters["samples"]["min_points_derived_lowest"] = serde_json::json!(min_points_lowest);
    }
    timings.add("total", start.elapsed().as_secs_f64() * 1e3);
    progress.report(Stage::Write, 1.0);
    let mut viewpoints = input.viewpoints.clone();
    if let Some(placed) = input.open_space {
        viewpoints.open_space =
            std::mem::take(&mut *placed.lock().unwrap_or_else(|p| p.into_inner()));
        let any = viewpoints
            .open_space
            .iter()
            .any(|s| !s.viewpoints.is_empty());
        // Places are only made where no viewpoint was given or estimated, or an estimated
        // path was set aside for them.
        if any {
            viewpoints.source = ViewpointSource::OpenSpace;
        }
    }
    viewpoints.rests_on = (evidence.1 > 0.0).then(|| evidence.0 / evidence.1);
    notes.extend(viewpoints::describe(&viewpoints));
    Ok(FloorPlan {
        origin: cloud.origin,
        crs: cloud.crs.clone(),
        georeference: None,
        input: InputSummary {
            points: input.points,
            format: cloud.source.format.clone(),
            scans: match &cloud.viewpoints {
                crate::cloud::Viewpoints::Static(p) => p.len(),
                _ => viewpoints.scans.len(),
            },
            viewpoints,
        },
        parameters,
        timings_ms: timings.into_ms(),
        stories: plans,
        notes,
    })
}

/// The stories' own failure code when they agree on it, else `no_plan`.
fn shared_code(codes: &[&'static str]) -> &'static str {
    match codes.split_first() {
        Some((first, rest)) if rest.iter().all(|c| c == first) => first,
        _ => "no_plan",
    }
}

/// One story through every stage after `stories`, stopping when `progress`'s cancel says so.
/// Samples one story's walls: from the cloud held in memory, or from a streamed run's tiles.
/// Called once a story, in story order, perhaps on another thread than the plan's.
pub(crate) type SampleStory<'s> =
    dyn FnMut(&Story, &Cancel) -> Result<WallSamples, SamplesError> + Send + 's;

/// A story's samples, and how long taking them took.
struct Sampled {
    samples: Result<WallSamples, SamplesError>,
    ms: f64,
}

impl Sampled {
    fn of(sample: &mut SampleStory<'_>, story: &Story, cancel: &Cancel) -> Sampled {
        let start = Instant::now();
        let samples = sample(story, cancel);
        Sampled {
            samples,
            ms: start.elapsed().as_secs_f64() * 1e3,
        }
    }
}

/// The stages after sampling, on one story's samples.
fn plan_story(
    story: &Story,
    sampled: Sampled,
    input: &CloudSummary<'_>,
    params: &Params,
    progress: &mut dyn Progress,
    timings: &mut Timings,
    at: impl Fn(f64) -> f64,
) -> Result<StoryOutcome, PlanError> {
    let cancel = &progress.cancel();
    let grid = &Grid::world(input.cloud.origin);
    let mut step = |stage: Stage| {
        progress.report(stage, at(stage.start()));
        cancel.check()
    };
    timings.add(Stage::Samples.name(), sampled.ms);
    let mut samples = sampled.samples?;
    step(Stage::Smoothing)?;
    timings.time(Stage::Smoothing, || {
        smooth_samples(
            &mut samples,
            params.samples.cell_size,
            &params.smoothing,
            cancel,
        )
    })?;
    step(Stage::Labeling)?;
    // The triangulation is reported on its own, ahead of the labeling proper.
    timings.add(TRIANGULATE, 0.0);
    let start = Instant::now();
    let (mut labeled, report) = label_with_report(&samples, &params.labeling, cancel)?;
    let mesh_ms = report.timings.mesh_ms;
    timings.add(TRIANGULATE, mesh_ms);
    timings.add(
        Stage::Labeling.name(),
        (start.elapsed().as_secs_f64() * 1e3 - mesh_ms).max(0.0),
    );
    step(Stage::Cleanup)?;
    timings.time(Stage::Cleanup, || {
        clean_labels(&mut labeled, &params.cleanup)
    });
    let forced = forced_area(&labeled);
    let start = Instant::now();
    let boundary = trace_boundary(&labeled);
    timings.add(BOUNDARY, start.elapsed().as_secs_f64() * 1e3);
    let boundary = boundary?;
    step(Stage::Fitting)?;
    let fitted = timings.time(Stage::Fitting, || {
        fit_walls(&labeled, &boundary, &params.fitting, cancel)
    })?;
    let start = Instant::now();
    let traced = boundary.to_polygons(&labeled.mesh);
    let valid = make_valid(&fitted.polygons, &traced, grid);
    timings.add(VALIDITY, start.elapsed().as_secs_f64() * 1e3);
    let mut notes = fitted.notes;
    notes.extend(valid.notes);
    if samples.shallow_kept > 0.0 {
        notes.push(format!(
            "{:.1} m of wall seen less than {:.1} m under the ceiling was kept where it runs on \
             from a wall seen deeper",
            samples.shallow_kept,
            crate::samples::FLOORLESS_REACH * params.samples.min_wall_height
        ));
    }
    let mut plan = StoryPlan {
        level: story.level,
        floor_z: story.floor_z,
        ceiling_z: story.ceiling_z,
        polygons: valid.polygons,
        walls: fitted.walls,
        samples: samples.samples.iter().map(|s| s.pos).collect(),
        spaces: Default::default(),
        underlay: samples.underlay.take(),
    };
    step(Stage::Rooms)?;
    // A story whose rooms cannot be found keeps its plan, with a note.
    let points = StoryPoints {
        xyz: &input.cloud.xyz,
        blocks: input.blocks,
    };
    match timings.time(Stage::Rooms, || {
        find_rooms(&plan, &points, &input.scanners, &params.rooms, grid)
    }) {
        Ok(found) => {
            plan.spaces = found.spaces;
            notes.extend(found.notes);
        }
        Err(e) => notes.push(format!("rooms: {e}; the story has no rooms")),
    }
    Ok(StoryOutcome {
        plan,
        min_points_used: samples.min_points_used,
        min_points_lowest: samples.min_points_lowest,
        notes,
        forced,
    })
}

/// One story's plan and what the run reports of it.
struct StoryOutcome {
    plan: StoryPlan,
    min_points_used: usize,
    /// The lowest threshold any of its cells was held to.
    min_points_lowest: usize,
    notes: Vec<String>,
    /// The inside area that evidence forced inside, and the inside area, m².
    forced: (f64, f64),
}

/// The inside area that evidence forced inside, and the inside area, m².
fn forced_area(labeled: &crate::labeling::LabeledMesh) -> (f64, f64) {
    let mut out = (0.0, 0.0);
    for t in 0..labeled.mesh.triangles.len() {
        if labeled.inside[t] {
            let a = labeled.mesh.area(t).abs();
            out.1 += a;
            if labeled.forced[t] == Some(true) {
                out.0 += a;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stories::split_cloud_stories;

    #[test]
    fn the_survey_finds_what_the_passes_it_replaces_find() {
        use crate::simulate::{simulate, BuildingKind, ScanOptions};
        let options = ScanOptions {
            points: 300_000,
            seed: 2,
            ..Default::default()
        };
        let mut cloud = simulate(BuildingKind::Office3Story, &options)
            .unwrap()
            .cloud;
        let survey = Survey::of(&cloud.xyz);
        assert!(survey.finite && cloud.check().is_ok());
        assert_eq!(survey.probe, SpacingProbe::of(&cloud.xyz));
        assert!(survey.probe.spacing().is_some());
        // One share a thread: the same survey on one thread as on three.
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let other = pool.install(|| Survey::of(&cloud.xyz));
            assert_eq!(other.probe, survey.probe, "{threads} threads");
            assert_eq!(other.heights, survey.heights, "{threads} threads");
        }
        let params = Params::default().stories;
        assert_eq!(
            split_cloud_stories_within(&cloud.xyz, survey.heights, &params).unwrap(),
            split_cloud_stories(&cloud.xyz, &params).unwrap()
        );
        // A non-finite coordinate anywhere is found, as `check` finds it.
        cloud.xyz[123_457][0] = f32::NAN;
        assert!(!Survey::of(&cloud.xyz).finite);
        assert_eq!(cloud.check(), Err(NON_FINITE.to_string()));
        assert_eq!(
            Survey::of(&cloud.xyz).heights,
            Survey::of(&cloud.xyz[..123_457])
                .heights
                .merge(Survey::of(&cloud.xyz[123_457..]).heights)
        );
    }

    #[test]
    fn stories_failing_alike_keep_their_code() {
        assert_eq!(shared_code(&["labeling_failed"]), "labeling_failed");
        assert_eq!(
            shared_code(&["fitting_failed", "fitting_failed"]),
            "fitting_failed"
        );
        assert_eq!(
            shared_code(&["samples_failed", "fitting_failed"]),
            "no_plan"
        );
        assert_eq!(shared_code(&[]), "no_plan");
        let e = PlanError::Boundary(BoundaryError::NothingInside);
        assert_eq!(e.code(), "boundary_failed");
    }

    #[test]
    fn boundary_tracing_has_its_own_time_between_cleanup_and_fit() {
        use crate::progress::NoProgress;
        use crate::simulate::{simulate, BuildingKind, ScanOptions};
        let options = ScanOptions {
            points: 40_000,
            seed: 1,
            ..Default::default()
        };
        let sim = simulate(BuildingKind::SquareRoom, &options).unwrap();
        let plan = plan(&sim.cloud, &Params::default(), &mut NoProgress).unwrap();
        let keys: Vec<&str> = plan.timings_ms.iter().map(|(k, _)| k.as_str()).collect();
        let at = keys
            .iter()
            .position(|k| *k == BOUNDARY)
            .expect("a boundary time");
        assert_eq!(
            keys[at - 1..=at + 1],
            ["cleanup", BOUNDARY, "fit"],
            "{keys:?}"
        );
    }
}
