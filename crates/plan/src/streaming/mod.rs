//! Clouds larger than memory (beyond the paper): the file is read twice, a batch at a time, and
//! never held whole.
//!
//! 1. Pass 1 reads the bounds and a coarse count of points per area; from them the plan cuts
//!    the floor area into tiles small enough for the memory budget.
//! 2. Pass 2 builds the height histogram (the stories, §3.1) and writes every point to the
//!    temporary file of its tile, and of the neighbouring tiles when it lies within two cells
//!    (d_s) of their edge: the halo that completes the neighbourhoods of a tile's edge cells.
//! 3. Each tile is read back twice: once for each story's horizontal bounds (which fix where
//!    its grid lies), then to test the cells whose centres lie in the tile with the in-memory
//!    sampling code. A cell's neighbourhood is whole within its tile and keeps the file's
//!    point order, so every cell gives exactly the sample of the in-memory run; the
//!    density-derived threshold is then taken over the wall-like cells of all tiles.
//! 4. Labeling and the later stages run on the samples, as in memory.
//!
//! The plan is the in-memory one ([`crate::pipeline::plan`] on the whole cloud).

use std::path::PathBuf;
use std::time::Instant;

use crate::cancel::Cancel;
use crate::cloud::PointCloud;
use crate::io::chunks::{open_chunks, PointChunk};
use crate::io::poses::{attach_poses, attach_trajectory, PosesError};
use crate::io::spill::{SpillError, TileStore};
use crate::io::Sidecar;
use crate::io::{check_units, ReadError, ReadOptions, UnitsError};
use crate::params::Params;
use crate::pipeline::{plan_stories, CloudSummary, PlanError, Timings};
use crate::plan::FloorPlan;
use crate::progress::{Progress, Stage};
use crate::samples::{
    check_params, finish_samples, scan_cells, CellScan, CellSource, GridFrame, SamplesError,
    SpacingProbe, StoryBounds, WallSamples,
};
use crate::stories::{HeightHistogram, Story};
use crate::viewpoints;

// The whole run's progress as the passes before the stories start, so the slow passes move the
// bar: pass 1 (the survey) takes the first 30 %, pass 2 (the tile files) the next 20 %, and
// sampling the tiles 30 % more, tile by tile.
/// Progress as pass 1, the survey, starts.
const SURVEY_AT: f64 = 0.0;
/// Progress as pass 2 starts: the height histogram and the tile files.
const SPILL_AT: f64 = 0.3;
/// Progress as the tiles' sampling starts.
const TILES_AT: f64 = 0.5;
/// The share the tiles' sampling takes, spread evenly over the tiles.
const TILES_SHARE: f64 = 0.3;

/// Parameters of [`plan_file`].
#[derive(Debug, Clone, PartialEq)]
pub struct StreamingParams {
    /// The memory the run's data may take, bytes: tiles, buffers, histograms and samples.
    /// The process itself (code, thread stacks) comes on top, some tens of megabytes.
    pub max_memory: u64,
    /// Where the tile files go; the system's temporary folder when `None`.
    pub temp_dir: Option<PathBuf>,
    /// The most points the file may hold; the first pass stops as soon as it reads more.
    pub max_points: Option<u64>,
}

impl Default for StreamingParams {
    fn default() -> Self {
        StreamingParams {
            max_memory: 1 << 30,
            temp_dir: None,
            max_points: None,
        }
    }
}

/// Why a streamed plan could not be made.
#[derive(Debug, thiserror::Error)]
pub enum StreamingError {
    /// The file could not be read.
    #[error(transparent)]
    Read(#[from] ReadError),
    /// A tile file could not be written or read back.
    #[error(transparent)]
    Spill(#[from] SpillError),
    /// The sidecar does not fit the cloud.
    #[error("poses: {0}")]
    Poses(#[from] PosesError),
    /// The coordinates are not in metres.
    #[error(transparent)]
    Units(#[from] UnitsError),
    /// A stage failed.
    #[error("{0}")]
    Plan(#[from] PlanError),
    /// No tiling fits the budget.
    #[error("the memory budget of {budget} bytes is too small: {why}")]
    Budget {
        /// The budget, bytes.
        budget: u64,
        /// What would not fit.
        why: String,
    },
    /// The file holds more points than [`StreamingParams::max_points`].
    #[error("the cloud has more than {max} points, the limit")]
    TooManyPoints {
        /// Points read when the pass stopped.
        points: u64,
        /// The limit.
        max: u64,
    },
}

/// How the streamed run went.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamReport {
    /// Tile columns and rows.
    pub tiles: (usize, usize),
    /// The most points any tile held, halo included.
    pub max_tile_points: u64,
    /// Bytes written to tile files.
    pub spilled_bytes: u64,
    /// Points read.
    pub points: u64,
}

mod survey;
mod tiling;

use survey::Survey;
use tiling::Tiling;

/// Makes the floor plan of the cloud in `path` within `stream.max_memory`. The sidecar's
/// positions are in world coordinates, already scaled to metres.
pub fn plan_file(
    path: &std::path::Path,
    read: &ReadOptions,
    sidecar: Option<Sidecar>,
    params: &Params,
    stream: &StreamingParams,
    progress: &mut dyn Progress,
) -> Result<(FloorPlan, StreamReport), StreamingError> {
    let start = Instant::now();
    let cancel = progress.cancel();
    let stop = || -> Result<(), StreamingError> { Ok(cancel.check().map_err(PlanError::from)?) };
    let mut timings = Timings::default();
    let keep_time = matches!(sidecar, Some(Sidecar::Trajectory(_)));
    let read = ReadOptions {
        keep_time,
        ..read.clone()
    };
    progress.report(Stage::Read, SURVEY_AT);

    // Pass 1: bounds and the coarse count.
    let clock = Instant::now();
    let (survey, mut skeleton, probe) = survey_pass(path, &read, stream.max_points, &stop)?;
    timings.add(Stage::Read.name(), ms(clock));
    if survey.n == 0 {
        return Err(PlanError::EmptyCloud.into());
    }
    attach(&mut skeleton, sidecar, &survey)?;
    // The same spacing as in memory: the probe keeps the same points whatever the order.
    let (params, reported) = params.derive(probe.spacing());
    let params = &params;
    let tiling = Tiling::plan(&survey, &skeleton, params, stream)?;
    stop()?;

    // Pass 2: the height histogram, the units check's sample, and the tile files.
    progress.report(Stage::Read, SPILL_AT);
    let clock = Instant::now();
    let spilled = spill_pass(
        path, &read, &survey, &skeleton, &tiling, params, stream, &stop,
    )?;
    timings.add("tiles", ms(clock));
    let Spilled {
        store,
        hist,
        units,
        scan_counts,
    } = spilled;
    check_units(&PointCloud {
        xyz: units.iter().map(|&z| [0.0, 0.0, z]).collect(),
        ..Default::default()
    })?;
    drop(units);
    let stories = timings.time(Stage::Stories, || hist.stories(&params.stories));
    let stories = stories.map_err(PlanError::from)?;
    drop(hist);
    stop()?;

    // The tiles: each story's bounds, then its cells.
    progress.report(Stage::Samples, TILES_AT);
    let clock = Instant::now();
    let (mut samples, max_tile_points) = sample_tiles(
        &store, &skeleton, &stories, &tiling, params, &cancel, progress, &stop,
    )?;
    timings.add(Stage::Samples.name(), ms(clock));
    let report = StreamReport {
        tiles: (tiling.nx, tiling.ny),
        max_tile_points,
        spilled_bytes: store.bytes(),
        points: survey.n,
    };
    drop(store);

    let mut next = 0;
    let mut sample = |_: &Story, _: &Cancel| {
        let out = samples[next].take().expect("one sampling per story");
        next += 1;
        out
    };
    let mut summary = CloudSummary::of(&skeleton, survey.n);
    // Streaming plans with the viewpoints it is given; it cannot estimate missing ones.
    if let Some(report) = viewpoints::given_report(&skeleton.viewpoints, &scan_counts) {
        summary.viewpoints = report;
    }
    let plan = plan_stories(
        &summary,
        &stories,
        params,
        reported,
        progress,
        timings,
        start,
        &mut sample,
    )?;
    Ok((plan, report))
}

/// Pass 1: reads the whole file once for the survey, the cloud without its points, and the
/// point spacing.
fn survey_pass(
    path: &std::path::Path,
    read: &ReadOptions,
    max_points: Option<u64>,
    stop: &dyn Fn() -> Result<(), StreamingError>,
) -> Result<(Survey, PointCloud, SpacingProbe), StreamingError> {
    let mut chunks = open_chunks(path, read)?;
    let mut chunk = PointChunk::default();
    let mut survey = Survey::default();
    let mut probe = SpacingProbe::default();
    while chunks.next_chunk(&mut chunk)? {
        stop()?;
        survey.add(&chunk);
        // A header may understate its points: the count read is what holds.
        if let Some(max) = max_points.filter(|&max| survey.n > max) {
            return Err(StreamingError::TooManyPoints {
                points: survey.n,
                max,
            });
        }
        probe.add(&chunk.xyz);
    }
    let skeleton = chunks.skeleton()?;
    Ok((survey, skeleton, probe))
}

/// What pass 2 leaves: the tile files, the height histogram, the units check's heights, and
/// the points per scan slot.
struct Spilled {
    store: TileStore,
    hist: HeightHistogram,
    units: Vec<f32>,
    scan_counts: Vec<u64>,
}

/// Pass 2: reads the file again, counting heights and writing every point to its tiles' files.
#[allow(clippy::too_many_arguments)]
fn spill_pass(
    path: &std::path::Path,
    read: &ReadOptions,
    survey: &Survey,
    skeleton: &PointCloud,
    tiling: &Tiling,
    params: &Params,
    stream: &StreamingParams,
    stop: &dyn Fn() -> Result<(), StreamingError>,
) -> Result<Spilled, StreamingError> {
    let mut hist = HeightHistogram::new(survey.lo[2], survey.hi[2], &params.stories)
        .map_err(PlanError::from)?;
    let mut store = TileStore::create(
        tiling.count(),
        stream.temp_dir.as_deref(),
        tiling.buffer,
        !survey.no_scan,
        read.keep_time && survey.has_time,
    )?;
    let step = survey.n.div_ceil(UNITS_SAMPLE as u64).max(1);
    let mut units = Vec::with_capacity(UNITS_SAMPLE);
    let mut index = 0u64;
    // Points per scan slot, for the viewpoints report.
    let mut scan_counts = vec![0u64; skeleton.scan_ids.len()];
    let mut chunk = PointChunk::default();
    let mut chunks = open_chunks(path, read)?;
    while chunks.next_chunk(&mut chunk)? {
        stop()?;
        viewpoints::count_scans(&mut scan_counts, &chunk.scan);
        for (k, p) in chunk.xyz.iter().enumerate() {
            hist.add(p[2]);
            if index.is_multiple_of(step) {
                units.push(p[2]);
            }
            index += 1;
            let scan = chunk.scan.get(k).copied().unwrap_or(0);
            let time = chunk.time.get(k).copied().unwrap_or(0.0);
            let (cols, rows) = tiling.tiles_of(p);
            for ty in rows {
                for tx in cols.clone() {
                    store.push(ty * tiling.nx + tx, *p, scan, time)?;
                }
            }
        }
    }
    drop(chunks);
    store.flush()?;
    Ok(Spilled {
        store,
        hist,
        units,
        scan_counts,
    })
}

/// One story's sampling: its wall samples, or why it could not be sampled.
type StorySamples = Option<Result<WallSamples, SamplesError>>;

/// Pass 3: reads each tile back twice, once for every story's bounds and once to scan the
/// cells it owns; finishes each story's samples. Also gives the most points a tile held.
#[allow(clippy::too_many_arguments)]
fn sample_tiles(
    store: &TileStore,
    skeleton: &PointCloud,
    stories: &[Story],
    tiling: &Tiling,
    params: &Params,
    cancel: &Cancel,
    progress: &mut dyn Progress,
    stop: &dyn Fn() -> Result<(), StreamingError>,
) -> Result<(Vec<StorySamples>, u64), StreamingError> {
    let tile_cloud = |t: usize| -> Result<PointCloud, StreamingError> {
        let pts = store.read(t)?;
        Ok(PointCloud {
            xyz: pts.xyz,
            scan: pts.scan,
            time: pts.time,
            ..skeleton.clone()
        })
    };
    let mut bounds = vec![StoryBounds::default(); stories.len()];
    for t in 0..tiling.count() {
        stop()?;
        let cloud = tile_cloud(t)?;
        for (b, story) in bounds.iter_mut().zip(stories) {
            *b = StoryBounds::merge(*b, StoryBounds::measure(&cloud.xyz, story));
        }
    }
    // Per story: the cells' scans, or why the story cannot be sampled.
    let mut scans: Vec<Result<(GridFrame, Vec<CellScan>), SamplesError>> = bounds
        .iter()
        .zip(stories)
        .map(|(b, story)| {
            check_params(&params.samples, story)?;
            Ok((b.frame(story, params.samples.cell_size)?, Vec::new()))
        })
        .collect();
    let mut max_tile_points = 0;
    for t in 0..tiling.count() {
        stop()?;
        let done = t as f64 / tiling.count() as f64;
        progress.report(Stage::Samples, TILES_AT + TILES_SHARE * done);
        let cloud = tile_cloud(t)?;
        max_tile_points = max_tile_points.max(cloud.len() as u64);
        for (entry, story) in scans.iter_mut().zip(stories) {
            let Ok((frame, list)) = entry else {
                continue;
            };
            let core = tiling.core(t, frame);
            let source = CellSource {
                cloud: &cloud,
                viewpoints: &skeleton.viewpoints,
                spans: None,
            };
            match scan_cells(&source, story, &params.samples, frame, core, cancel) {
                Ok(scan) => list.push(scan),
                Err(SamplesError::Cancelled(c)) => return Err(PlanError::Cancelled(c).into()),
                Err(e) => *entry = Err(e),
            }
        }
    }
    let samples: Vec<StorySamples> = scans
        .into_iter()
        .zip(stories)
        .map(|(entry, story)| {
            Some(entry.and_then(|(frame, list)| {
                finish_samples(
                    skeleton,
                    &skeleton.viewpoints,
                    story,
                    &params.samples,
                    &frame,
                    list,
                )
            }))
        })
        .collect();
    Ok((samples, max_tile_points))
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// The units check looks at this many evenly spaced heights, as [`check_units`] does.
const UNITS_SAMPLE: usize = 100_000;

/// Attaches the sidecar to the cloud's skeleton, as the whole-cloud run attaches it to the cloud.
fn attach(
    skeleton: &mut PointCloud,
    sidecar: Option<Sidecar>,
    survey: &Survey,
) -> Result<(), PosesError> {
    match sidecar {
        None => Ok(()),
        Some(Sidecar::Poses(p)) => {
            let no_scans = skeleton.scan_ids.is_empty();
            attach_poses(skeleton, p)?;
            // Without scan indices one pose sees every point; the tiles carry no slots then.
            if no_scans {
                skeleton.scan.clear();
            }
            Ok(())
        }
        Some(Sidecar::Trajectory(t)) => {
            // The trajectory's span is checked against the points' earliest and latest times.
            skeleton.time = if survey.has_time {
                vec![survey.time.0, survey.time.1]
            } else {
                Vec::new()
            };
            let out = attach_trajectory(skeleton, t);
            skeleton.time.clear();
            out
        }
    }
}
