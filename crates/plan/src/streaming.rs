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
use crate::samples::grid::MAX_CELLS;
use crate::samples::{
    check_params, finish_samples, scan_cells, CellRange, CellScan, GridFrame, SamplesError,
    SpacingProbe, StoryBounds, WallSamples,
};
use crate::stories::{HeightHistogram, Story};
use crate::viewpoints;

/// Parameters of [`plan_file`].
#[derive(Debug, Clone, PartialEq)]
pub struct StreamingParams {
    /// The memory the run's data may take, bytes: tiles, buffers, histograms and samples.
    /// The process itself (code, thread stacks) comes on top, some tens of megabytes.
    pub max_memory: u64,
    /// Where the tile files go; the system's temporary folder when `None`.
    pub temp_dir: Option<PathBuf>,
}

impl Default for StreamingParams {
    fn default() -> Self {
        StreamingParams {
            max_memory: 1 << 30,
            temp_dir: None,
        }
    }
}

/// Why a streamed plan could not be made.
#[derive(Debug, thiserror::Error)]
pub enum StreamingError {
    #[error(transparent)]
    Read(#[from] ReadError),
    #[error(transparent)]
    Spill(#[from] SpillError),
    #[error("poses: {0}")]
    Poses(#[from] PosesError),
    #[error(transparent)]
    Units(#[from] UnitsError),
    #[error("{0}")]
    Plan(#[from] PlanError),
    #[error("the memory budget of {budget} bytes is too small: {why}")]
    Budget { budget: u64, why: String },
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

/// Per-cell cost of a tile's grid in memory, bytes: offsets, summaries, the kept-cell flags and
/// block screens; and [`CELL_BYTES_PER_THREAD`] more for each counting thread's summaries.
const CELL_BYTES: u64 = 24;
const CELL_BYTES_PER_THREAD: u64 = 16;
/// The coarse count grid never has more cells than this (8 MiB of counts).
const MAX_COARSE: usize = 1 << 20;
/// More tiles than this would keep too many files open.
const MAX_TILES: usize = 1024;
/// Memory set aside for what the model does not count: samples, the histogram, reader buffers.
const SLACK: f64 = 0.25;

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
    progress.report(Stage::Read, 0.0);

    // Pass 1: bounds and the coarse count.
    let clock = Instant::now();
    let mut chunks = open_chunks(path, &read)?;
    let mut chunk = PointChunk::default();
    let mut survey = Survey::default();
    let mut probe = SpacingProbe::default();
    while chunks.next_chunk(&mut chunk)? {
        stop()?;
        survey.add(&chunk);
        probe.add(&chunk.xyz);
    }
    let mut skeleton = chunks.skeleton()?;
    drop(chunks);
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
    progress.report(Stage::Read, 0.3);
    let clock = Instant::now();
    let mut hist = HeightHistogram::new(survey.lo[2], survey.hi[2], &params.stories)
        .map_err(PlanError::from)?;
    let mut store = TileStore::create(
        tiling.count(),
        stream.temp_dir.as_deref(),
        tiling.buffer,
        !survey.no_scan,
        keep_time && survey.has_time,
    )?;
    let step = survey.n.div_ceil(UNITS_SAMPLE as u64).max(1);
    let mut units = Vec::with_capacity(UNITS_SAMPLE);
    let mut index = 0u64;
    // Points per scan slot, for the viewpoints report.
    let mut scan_counts = vec![0u64; skeleton.scan_ids.len()];
    let mut chunks = open_chunks(path, &read)?;
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
    timings.add("tiles", ms(clock));
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
    progress.report(Stage::Samples, 0.5);
    let clock = Instant::now();
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
        for (b, story) in bounds.iter_mut().zip(&stories) {
            *b = StoryBounds::merge(*b, StoryBounds::measure(&cloud.xyz, story));
        }
    }
    // Per story: the cells' scans, or why the story cannot be sampled.
    let mut scans: Vec<Result<(GridFrame, Vec<CellScan>), SamplesError>> = bounds
        .iter()
        .zip(&stories)
        .map(|(b, story)| {
            check_params(&params.samples, story)?;
            Ok((b.frame(story, params.samples.cell_size)?, Vec::new()))
        })
        .collect();
    let mut max_tile_points = 0;
    for t in 0..tiling.count() {
        stop()?;
        progress.report(Stage::Samples, 0.5 + 0.3 * t as f64 / tiling.count() as f64);
        let cloud = tile_cloud(t)?;
        max_tile_points = max_tile_points.max(cloud.len() as u64);
        for (entry, story) in scans.iter_mut().zip(&stories) {
            let Ok((frame, list)) = entry else {
                continue;
            };
            let core = tiling.core(t, frame);
            match scan_cells(
                &cloud,
                &skeleton.viewpoints,
                None,
                story,
                &params.samples,
                frame,
                core,
                &cancel,
            ) {
                Ok(scan) => list.push(scan),
                Err(SamplesError::Cancelled(c)) => return Err(PlanError::Cancelled(c).into()),
                Err(e) => *entry = Err(e),
            }
        }
    }
    let mut samples: Vec<Option<Result<WallSamples, SamplesError>>> = scans
        .into_iter()
        .zip(&stories)
        .map(|(entry, story)| {
            Some(entry.and_then(|(_, list)| {
                finish_samples(
                    &skeleton,
                    &skeleton.viewpoints,
                    story,
                    &params.samples,
                    list,
                )
            }))
        })
        .collect();
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

/// What pass 1 learns: count, bounds, times, and points per coarse cell.
struct Survey {
    n: u64,
    lo: [f32; 3],
    hi: [f32; 3],
    has_time: bool,
    /// True when no point carried a scan slot.
    no_scan: bool,
    time: (f64, f64),
    coarse: CoarseGrid,
}

impl Default for Survey {
    fn default() -> Self {
        Survey {
            n: 0,
            lo: [f32::INFINITY; 3],
            hi: [f32::NEG_INFINITY; 3],
            has_time: false,
            no_scan: true,
            time: (f64::INFINITY, f64::NEG_INFINITY),
            coarse: CoarseGrid::new(0.25),
        }
    }
}

impl Survey {
    fn add(&mut self, chunk: &PointChunk) {
        self.n += chunk.len() as u64;
        for p in &chunk.xyz {
            for ((lo, hi), &v) in self.lo.iter_mut().zip(&mut self.hi).zip(p) {
                *lo = lo.min(v);
                *hi = hi.max(v);
            }
            self.coarse.add(p[0], p[1]);
        }
        if !chunk.scan.is_empty() {
            self.no_scan = false;
        }
        for &t in &chunk.time {
            self.has_time = true;
            self.time = (self.time.0.min(t), self.time.1.max(t));
        }
    }
}

/// Points per square of a coarse grid anchored at the local origin. It grows to cover every
/// point and doubles its squares when it would exceed [`MAX_COARSE`] of them.
struct CoarseGrid {
    side: f64,
    /// Index of the first column and row.
    x0: i64,
    y0: i64,
    nx: usize,
    ny: usize,
    counts: Vec<u64>,
}

impl CoarseGrid {
    fn new(side: f64) -> CoarseGrid {
        CoarseGrid {
            side,
            x0: 0,
            y0: 0,
            nx: 0,
            ny: 0,
            counts: Vec::new(),
        }
    }

    #[inline]
    fn index(v: f64, side: f64) -> i64 {
        let t = v / side;
        let i = t as i64;
        if (i as f64) > t {
            i - 1
        } else {
            i
        }
    }

    #[inline]
    fn add(&mut self, x: f32, y: f32) {
        let (ix, iy) = (
            Self::index(x as f64, self.side),
            Self::index(y as f64, self.side),
        );
        let inside = |i: i64, i0: i64, n: usize| i >= i0 && i < i0 + n as i64;
        if !(inside(ix, self.x0, self.nx) && inside(iy, self.y0, self.ny)) {
            self.grow(ix, iy);
            return self.add(x, y);
        }
        let c = (iy - self.y0) as usize * self.nx + (ix - self.x0) as usize;
        self.counts[c] += 1;
    }

    /// Covers square `(ix, iy)`, with room to spare, coarsening as needed.
    fn grow(&mut self, ix: i64, iy: i64) {
        let (mut x0, mut y0, mut x1, mut y1) = if self.counts.is_empty() {
            (ix - 8, iy - 8, ix + 8, iy + 8)
        } else {
            let (x1, y1) = (self.x0 + self.nx as i64, self.y0 + self.ny as i64);
            let (w, h) = (self.nx as i64, self.ny as i64);
            (
                if ix < self.x0 { ix - w / 2 } else { self.x0 },
                if iy < self.y0 { iy - h / 2 } else { self.y0 },
                if ix >= x1 { ix + 1 + w / 2 } else { x1 },
                if iy >= y1 { iy + 1 + h / 2 } else { y1 },
            )
        };
        let mut side = self.side;
        let mut shift = 0;
        while ((x1 - x0) as u128 * (y1 - y0) as u128) > MAX_COARSE as u128 {
            side *= 2.0;
            shift += 1;
            x0 = x0.div_euclid(2);
            y0 = y0.div_euclid(2);
            x1 = (x1 + 1).div_euclid(2);
            y1 = (y1 + 1).div_euclid(2);
        }
        let (nx, ny) = ((x1 - x0) as usize, (y1 - y0) as usize);
        let mut counts = vec![0u64; nx * ny];
        for row in 0..self.ny {
            for col in 0..self.nx {
                let v = self.counts[row * self.nx + col];
                if v == 0 {
                    continue;
                }
                let cx = (self.x0 + col as i64) >> shift;
                let cy = (self.y0 + row as i64) >> shift;
                counts[(cy - y0) as usize * nx + (cx - x0) as usize] += v;
            }
        }
        *self = CoarseGrid {
            side,
            x0,
            y0,
            nx,
            ny,
            counts,
        };
    }

    /// Summed-area table: `sat[(r) * (nx + 1) + c]` is the count of squares left of `c` and
    /// below `r`.
    fn summed(&self) -> Vec<u64> {
        let w = self.nx + 1;
        let mut sat = vec![0u64; w * (self.ny + 1)];
        for r in 0..self.ny {
            let mut row = 0;
            for c in 0..self.nx {
                row += self.counts[r * self.nx + c];
                sat[(r + 1) * w + c + 1] = sat[r * w + c + 1] + row;
            }
        }
        sat
    }

    /// At least the number of points within `[x0, x1) × [y0, y1)`, from the summed table.
    fn at_most(&self, sat: &[u64], x: (f64, f64), y: (f64, f64)) -> u64 {
        let clamp = |i: i64, i0: i64, n: usize| (i - i0).clamp(0, n as i64) as usize;
        let c0 = clamp(Self::index(x.0, self.side), self.x0, self.nx);
        let c1 = clamp(Self::index(x.1, self.side) + 1, self.x0, self.nx);
        let r0 = clamp(Self::index(y.0, self.side), self.y0, self.ny);
        let r1 = clamp(Self::index(y.1, self.side) + 1, self.y0, self.ny);
        if c1 <= c0 || r1 <= r0 {
            return 0;
        }
        let w = self.nx + 1;
        sat[r1 * w + c1] + sat[r0 * w + c0] - sat[r0 * w + c1] - sat[r1 * w + c0]
    }
}

/// The tiles: a regular grid of `nx` × `ny` rectangles over the cloud's horizontal bounds; the
/// outer ones reach out to infinity. A point belongs to every tile within `halo` of it.
struct Tiling {
    nx: usize,
    ny: usize,
    origin: [f64; 2],
    size: [f64; 2],
    halo: f64,
    /// Write buffer per tile file, bytes.
    buffer: usize,
}

impl Tiling {
    /// The fewest tiles whose points and cells each fit the budget.
    fn plan(
        survey: &Survey,
        skeleton: &PointCloud,
        params: &Params,
        stream: &StreamingParams,
    ) -> Result<Tiling, StreamingError> {
        let budget = stream.max_memory;
        let fail = |why: String| StreamingError::Budget { budget, why };
        let cell = params.samples.cell_size;
        if !(cell.is_finite() && cell > 0.0) {
            return Err(PlanError::Samples(crate::samples::SamplesError::BadParam {
                name: "cell_size",
                why: format!("{cell} is not a positive number"),
            })
            .into());
        }
        let halo = 2.0 * cell;
        let record = 12 + 2 * u64::from(!survey.no_scan) + 8 * u64::from(survey.has_time);
        // The tile's points, and the sorted copy of one story's.
        let point_bytes = 2 * record;
        let threads = rayon::current_num_threads().max(1) as u64;
        let cell_bytes = CELL_BYTES + CELL_BYTES_PER_THREAD * threads;
        let fixed = (survey.coarse.counts.len() * 8 * 2) as u64
            + (skeleton.scan_ids.len() * 64) as u64
            + (1 << 20);
        let usable = (budget as f64 * (1.0 - SLACK)) as u64;
        if usable <= fixed {
            return Err(fail(format!(
                "{fixed} bytes go to bookkeeping before any tile"
            )));
        }
        let usable = usable - fixed;
        let lo = [survey.lo[0] as f64, survey.lo[1] as f64];
        let span = [
            (survey.hi[0] as f64 - lo[0]).max(cell),
            (survey.hi[1] as f64 - lo[1]).max(cell),
        ];
        let sat = survey.coarse.summed();
        let mut side = span[0].max(span[1]) * (1.0 + 1e-9);
        let min_side = 4.0 * halo;
        loop {
            let nx = (span[0] / side).ceil().max(1.0) as usize;
            let ny = (span[1] / side).ceil().max(1.0) as usize;
            let size = [span[0] / nx as f64, span[1] / ny as f64];
            let tiles = nx * ny;
            // Each tile file gets a write buffer from a sixteenth of the budget.
            let buffer = ((budget / 16) / tiles as u64).min(1 << 20) as usize;
            let cells_side = |s: f64| ((s + 2.0 * halo) / cell).ceil() as u64 + 3;
            let cells = cells_side(size[0]) * cells_side(size[1]);
            let mut worst = 0;
            for ty in 0..ny {
                for tx in 0..nx {
                    let x = lo[0] + tx as f64 * size[0];
                    let y = lo[1] + ty as f64 * size[1];
                    let n = survey.coarse.at_most(
                        &sat,
                        (x - halo, x + size[0] + halo),
                        (y - halo, y + size[1] + halo),
                    );
                    worst = worst.max(n);
                }
            }
            let need = worst * point_bytes + cells * cell_bytes + (tiles * buffer) as u64;
            let fits = need <= usable && cells <= MAX_CELLS as u64 && buffer >= 4096;
            if fits && tiles <= MAX_TILES {
                return Ok(Tiling {
                    nx,
                    ny,
                    origin: lo,
                    size,
                    halo,
                    buffer,
                });
            }
            if tiles > MAX_TILES || side < min_side {
                return Err(fail(format!(
                    "{} points over {:.0} m × {:.0} m do not split into at most {MAX_TILES} tiles \
                     of {usable} bytes each ({worst} points in the fullest of {nx} × {ny} tiles \
                     need {need} bytes)",
                    survey.n, span[0], span[1]
                )));
            }
            side /= 1.25;
        }
    }

    fn count(&self) -> usize {
        self.nx * self.ny
    }

    /// The column (or row, `k` = 1) of the tile holding coordinate `v`.
    #[inline]
    fn band(&self, v: f64, k: usize) -> usize {
        let n = if k == 0 { self.nx } else { self.ny };
        // Casts saturate: left of the first tile is the first tile.
        (((v - self.origin[k]) / self.size[k]) as usize).min(n - 1)
    }

    /// The columns and rows of the tiles a point goes to: its own, and those within the halo.
    #[inline]
    fn tiles_of(
        &self,
        p: &[f32; 3],
    ) -> (
        std::ops::RangeInclusive<usize>,
        std::ops::RangeInclusive<usize>,
    ) {
        let (x, y) = (p[0] as f64, p[1] as f64);
        (
            self.band(x - self.halo, 0)..=self.band(x + self.halo, 0),
            self.band(y - self.halo, 1)..=self.band(y + self.halo, 1),
        )
    }

    /// The cells of `frame` whose centres lie in tile `t`.
    fn core(&self, t: usize, frame: &GridFrame) -> CellRange {
        let (tx, ty) = (t % self.nx, t / self.nx);
        let centre = |i: usize, k: usize| frame.origin[k] + (i as f64 + 0.5) * frame.cell;
        // Bands grow with the cell index, so each tile's cells are found by bisection.
        let span = |n: usize, k: usize, band: usize| {
            let first = |pred: &dyn Fn(usize) -> bool| {
                let (mut a, mut b) = (0, n);
                while a < b {
                    let m = (a + b) / 2;
                    if pred(m) {
                        a = m + 1;
                    } else {
                        b = m;
                    }
                }
                a
            };
            first(&|i| self.band(centre(i, k), k) < band)..first(&|i| {
                self.band(centre(i, k), k) <= band
            })
        };
        CellRange {
            i: span(frame.nx, 0, tx),
            j: span(frame.ny, 1, ty),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_coarse_grid_counts_every_point_as_it_grows_and_coarsens() {
        let mut g = CoarseGrid::new(0.25);
        let mut n = 0;
        for k in 0..2000 {
            let x = (k as f32) * 0.7 - 300.0;
            let y = (k % 37) as f32 * 11.0 - 50.0;
            g.add(x, y);
            n += 1;
        }
        // Far points force coarsening.
        g.add(1.0e5, -1.0e5);
        n += 1;
        assert_eq!(g.counts.iter().sum::<u64>(), n);
        assert!(g.counts.len() <= MAX_COARSE);
        let sat = g.summed();
        let all = g.at_most(&sat, (-1.0e6, 1.0e6), (-1.0e6, 1.0e6));
        assert_eq!(all, n);
        // A window holds at least the points inside it.
        let inside = (0..2000)
            .filter(|&k| {
                let x = (k as f32) * 0.7 - 300.0;
                (0.0..100.0).contains(&x)
            })
            .count() as u64;
        assert!(g.at_most(&sat, (0.0, 100.0), (-1.0e6, 1.0e6)) >= inside);
    }

    #[test]
    fn tile_cores_partition_the_cells() {
        let tiling = Tiling {
            nx: 3,
            ny: 2,
            origin: [0.0, 0.0],
            size: [1.0, 1.5],
            halo: 0.1,
            buffer: 4096,
        };
        let frame = GridFrame {
            origin: [0.013, -0.02],
            cell: 0.05,
            nx: 61,
            ny: 61,
        };
        let mut owned = vec![0u8; frame.nx * frame.ny];
        for t in 0..tiling.count() {
            let core = tiling.core(t, &frame);
            for j in core.j.clone() {
                for i in core.i.clone() {
                    owned[j * frame.nx + i] += 1;
                }
            }
        }
        assert!(owned.iter().all(|&c| c == 1));
        // A point near a corner goes to the four tiles around it.
        let (cols, rows) = tiling.tiles_of(&[1.05, 1.45, 0.0]);
        assert_eq!((cols, rows), (0..=1, 0..=1));
        let (cols, rows) = tiling.tiles_of(&[2.5, 0.5, 0.0]);
        assert_eq!((cols, rows), (2..=2, 0..=0));
    }
}
