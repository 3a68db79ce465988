//! Stage 2 (§3.1): wall samples on a d_s grid, with PCA normals.
//!
//! The story's points are counting-sorted by grid cell (`grid`). A cell's neighbourhood is
//! every point within d_s, horizontally, of its centre, so it is gathered from the 3 × 3 block
//! of cells around it. Per-cell height summaries rule out most cells (open floor, ceiling)
//! before any neighbourhood is gathered; the rest run the tests of `cell` in the paper's
//! order. With scanner poses, `views` orients the normals and drops far samples.

mod bound32;
mod bounds;
mod cell;
mod coverage;
pub(crate) mod grid;
mod rank;
mod shallow;
mod spacing;
mod threshold;
mod views;

use std::ops::Range;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cancel::{Cancel, Cancelled};
use crate::cloud::{PointCloud, Viewpoints};
use crate::geom::P2;
use crate::params::{within, ParamRange};
use crate::stories::Story;
use crate::underlay::{slice_of, DensityPart, Underlay};
pub use bounds::{Blocks, CellRange, GridFrame, StoryBounds};
pub(crate) use cell::FLOORLESS_REACH;
use cell::{Reject, Tests};
use grid::{Carry, Grid, Points, Screen, Summary};
pub use spacing::SpacingProbe;
use threshold::Thresholds;
use views::Views;

/// Parameters of [`sample_walls`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SamplesParams {
    /// Grid cell width d_s, metres (§3.1: "a typical value ... is 5 cm"). Range 0.01..=0.5.
    pub cell_size: f64,
    /// Minimum points in a cell's neighbourhood (§3.1: "|N_g| >= 50"). `None` derives it from
    /// the measured point density (beyond the paper): an eighth of the median neighbourhood
    /// count of the cells whose heights look like a wall, clamped to 10..=50, and lower (down
    /// to 5) where no wall cell within 25 cm is eight times denser (`threshold`).
    /// The values chosen are reported as [`WallSamples::min_points_used`] and
    /// [`WallSamples::min_points_lowest`]. Range 1..=100000.
    pub min_points: Option<usize>,
    /// Minimum vertical support, metres (§3.1: the minimum wall height, ~2 m). Range 0.1..=10.
    pub min_wall_height: f64,
    /// Bins of the neighbourhood's height histogram (§3.1: 16). Range 4..=32.
    pub height_bins: usize,
    /// Non-empty bins required (§3.1: 12 of 16). Range 0..=32, and at most `height_bins`.
    pub min_filled_bins: usize,
    /// Non-empty bins required among the top 4 (§3.1: 3). Range 0..=4.
    pub min_top_bins: usize,
    /// Minimum PCA normal confidence c = 1 - 2λ1/(λ1+λ2) (§3.1: 0.15). Range 0..=1.
    pub min_confidence: f64,
    /// Samples farther than this from every scanner that saw them are dropped, metres (§3.1: 5-10 m).
    /// Range 0.1..=1000.
    pub max_range: f64,
    /// Beyond the paper: scale the filled-bin requirements by the fraction of bins that
    /// `n` evenly spread points are expected to fill, 1 - (1 - 1/bins)^n. Sparse walls
    /// (below about 45 points) otherwise fail the 12-of-16 test by chance. From about 45 points
    /// on the requirements are the paper's. `false` applies the paper's test as written.
    pub density_aware_histogram: bool,
    /// Beyond the paper: widen `cell_size` to a few point spacings where the cloud is coarser
    /// than it (voxel centres, downsampled clouds), as [`crate::Params::derive`] says. The value
    /// used is reported as `cell_size_derived`, with the measured `point_spacing`.
    pub derive_cell_size: bool,
}

/// The accepted values of [`SamplesParams`] (see [`crate::params::ParamRange`]).
pub const RANGES: &[ParamRange] = &[
    ParamRange::new("cell_size", 0.01, 0.5, "m"),
    ParamRange::new("min_points", 1.0, 100_000.0, ""),
    ParamRange::new("min_wall_height", 0.1, 10.0, "m"),
    ParamRange::new("height_bins", 4.0, 32.0, ""),
    ParamRange::new("min_filled_bins", 0.0, 32.0, ""),
    ParamRange::new("min_top_bins", 0.0, 4.0, ""),
    ParamRange::new("min_confidence", 0.0, 1.0, ""),
    ParamRange::new("max_range", 0.1, 1000.0, "m"),
];

impl Default for SamplesParams {
    fn default() -> Self {
        SamplesParams {
            cell_size: 0.05,
            min_points: None,
            min_wall_height: 2.0,
            height_bins: 16,
            min_filled_bins: 12,
            min_top_bins: 3,
            min_confidence: 0.15,
            max_range: 10.0,
            density_aware_histogram: true,
            derive_cell_size: true,
        }
    }
}

/// One wall sample: the median position of a wall cell's neighbourhood, and its PCA normal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WallSample {
    /// Local x, y.
    pub pos: P2,
    /// Unit normal; points toward a scanner that saw it when poses are known.
    pub normal: P2,
    /// PCA confidence c in [0, 1].
    pub confidence: f64,
    /// Indices into [`WallSamples::viewpoints`] of the scanner positions that saw this sample.
    pub seen_from: Vec<u32>,
}

/// A story's wall samples, with the scanner positions that saw them.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WallSamples {
    /// The story's wall samples.
    pub samples: Vec<WallSample>,
    /// Scanner positions (local x, y) that saw this story: static poses, or trajectory positions.
    pub viewpoints: Vec<P2>,
    /// The mobile scanner's path through this story, in time order, a non-finite point where
    /// it has a gap; empty for static scans.
    pub path: Vec<P2>,
    /// The neighbourhood point threshold actually used (given or derived), story-wide.
    pub min_points_used: usize,
    /// The lowest threshold any cell was held to: below the story-wide one where the walls
    /// around were sparser (derived thresholds only).
    pub min_points_lowest: usize,
    /// Cells that passed every test before the range filter, for reports.
    pub cells_tested: usize,
    /// Metres of wall seen too little under the ceiling to stand alone (floorless stories),
    /// kept because it continues a wall seen deeper.
    #[serde(default)]
    pub shallow_kept: f64,
    /// The viewpoints were placed where their straight lines to the samples they list cross no
    /// other wall (pseudo-viewpoints in open space), so labeling need not check it again.
    #[serde(default)]
    pub lines_checked: bool,
    /// The points came from one moving scanner whose path is not known (its lines of sight come
    /// from pseudo-viewpoints): a walker who only stepped into a room saw its faces of the
    /// corridor walls poorly, as along a known path (see the labeling's backs).
    #[serde(default)]
    pub moving: bool,
    /// The story's points at mid-height on this grid, drawn under the plan (not serialized).
    #[serde(skip)]
    pub underlay: Option<Underlay>,
}

/// Why sampling failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SamplesError {
    /// A parameter is outside its range.
    #[error("invalid samples parameter `{name}`: {why}")]
    BadParam {
        /// The parameter's name.
        name: &'static str,
        /// What is wrong.
        why: String,
    },
    /// The story holds no points.
    #[error("story {level} has no points")]
    EmptyStory {
        /// The story's level.
        level: usize,
    },
    /// Some points have non-finite coordinates.
    #[error("{0} points have non-finite coordinates")]
    NonFinite(usize),
    /// The grid would be too large; the text says by how much.
    #[error("{0}")]
    TooLarge(String),
    /// No cell passed the wall tests; `why` says what was seen.
    #[error("story {level}: no cell passed the wall tests ({why})")]
    NoWalls {
        /// The story's level.
        level: usize,
        /// What the cells showed.
        why: String,
    },
    /// No floor was seen, and the walls were seen along too little of the outline they enclose
    /// for it to be more than a guess.
    #[error(
        "story {level}: no floor was seen, and walls were seen along only {seen:.1} m of the \
         {around:.1} m around them (less than {share:.0} %); the rest of the outline would be \
         guessed. The capture needs more of the walls, down to about {reach:.1} m under the \
         ceiling"
    )]
    FewWallsSeen {
        /// The story's level.
        level: usize,
        /// Metres of wall sampled.
        seen: f64,
        /// Perimeter of the samples' convex hull, metres.
        around: f64,
        /// The least share seen, per cent.
        share: f64,
        /// How far under the ceiling a wall must be seen, metres.
        reach: f64,
    },
    /// The run was stopped from outside.
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
}

/// Extracts the wall samples of one story; stops with `Cancelled` once `cancel` says so.
pub fn sample_walls(
    cloud: &PointCloud,
    story: &Story,
    params: &SamplesParams,
    cancel: &Cancel,
) -> Result<WallSamples, SamplesError> {
    check_params(params, story)?;
    let frame = StoryBounds::measure(&cloud.xyz, story).frame(story, params.cell_size)?;
    sample_walls_in(
        cloud,
        &cloud.viewpoints,
        story,
        params,
        &frame,
        None,
        cancel,
    )
}

/// [`sample_walls`] on a grid whose frame is already known (from bounds measured for several
/// stories at once, say).
/// Only the points in `spans` (index ranges, in order; `None` for all) are looked at: the
/// story's points must all lie in them. The scanners are `viewpoints` (the cloud's own, or
/// estimated ones).
pub fn sample_walls_in(
    cloud: &PointCloud,
    viewpoints: &Viewpoints,
    story: &Story,
    params: &SamplesParams,
    frame: &GridFrame,
    spans: Option<&[Range<usize>]>,
    cancel: &Cancel,
) -> Result<WallSamples, SamplesError> {
    check_params(params, story)?;
    let source = CellSource {
        cloud,
        viewpoints,
        spans,
    };
    let scan = scan_cells(&source, story, params, frame, frame.all(), cancel)?;
    finish_samples(cloud, viewpoints, story, params, frame, vec![scan])
}

/// The wall-like cells of one range of a story's grid, with the rejections by reason: the part
/// of sampling that reads points. Cells whose 3 × 3 block leaves `cloud` see only part of
/// their neighbourhood, so callers pass ranges whose blocks `cloud` covers.
pub(crate) struct CellScan {
    /// Wall-like cells in row-major order, each with its id `j * nx + i` in the whole grid.
    found: Vec<(u64, Found)>,
    tally: [usize; 6],
    /// The range's counts for the underlay.
    density: DensityPart,
}

/// The points a range of cells is tested on, and the scanners that saw them.
pub(crate) struct CellSource<'a> {
    pub(crate) cloud: &'a PointCloud,
    pub(crate) viewpoints: &'a Viewpoints,
    /// Index ranges of `cloud` holding the story's points; `None` for all.
    pub(crate) spans: Option<&'a [Range<usize>]>,
}

/// Tests the cells of `core` (a range of `frame`'s cells) on the points of `source`.
pub(crate) fn scan_cells(
    source: &CellSource<'_>,
    story: &Story,
    params: &SamplesParams,
    frame: &GridFrame,
    core: CellRange,
    cancel: &Cancel,
) -> Result<CellScan, SamplesError> {
    let CellSource {
        cloud,
        viewpoints,
        spans,
    } = *source;
    let mut out = CellScan {
        found: Vec::new(),
        tally: [0; 6],
        density: DensityPart::default(),
    };
    if core.is_empty() {
        return Ok(out);
    }
    let tests = Tests::new(story, params);
    let views = Views::new(cloud, viewpoints, story);
    let points = Points {
        xyz: &cloud.xyz,
        scan: &cloud.scan,
        time: &cloud.time,
    };
    let carry = match views.carry() {
        Carry::Times if cloud.time.is_empty() => Carry::Nothing,
        c => c,
    };
    // The lowest a derived threshold may be; the cells' own are applied afterwards.
    let min_points = params.min_points.unwrap_or(threshold::FLOOR);
    let grid = Grid::build(
        points,
        spans,
        story,
        *frame,
        &core,
        carry,
        {
            let coder = tests.bin_coder();
            move |z| coder.code(z)
        },
        |block| prefilter(&tests, block, min_points),
        slice_of(story).map(|z| z as f32),
        cancel,
    )?;
    let scan = Scan {
        grid: &grid,
        tests: &tests,
        views: &views,
        min_points,
        core: &core,
        cancel,
    };
    let rows: Vec<Row> = core
        .j
        .clone()
        .into_par_iter()
        .map_init(Scratch::default, |s, j| scan.row(j, s))
        .collect();
    cancel.check()?;
    for row in rows {
        out.tally
            .iter_mut()
            .zip(row.tally)
            .for_each(|(t, r)| *t += r);
        out.found.extend(row.found);
    }
    out.density = DensityPart {
        range: Some(core),
        counts: grid.density,
    };
    Ok(out)
}

/// Turns the scans of every part of a story's grid (`frame`) into its samples: the adaptive
/// threshold over all wall-like cells, then the range filter; and the parts' counts into the
/// story's underlay. `cloud` gives the viewpoints (its points are not read).
pub(crate) fn finish_samples(
    cloud: &PointCloud,
    viewpoints: &Viewpoints,
    story: &Story,
    params: &SamplesParams,
    frame: &GridFrame,
    mut scans: Vec<CellScan>,
) -> Result<WallSamples, SamplesError> {
    let parts: Vec<DensityPart> = scans
        .iter_mut()
        .map(|s| std::mem::take(&mut s.density))
        .collect();
    let underlay = Underlay::assemble(frame, slice_of(story), &parts);
    drop(parts);
    let views = Views::new(cloud, viewpoints, story);
    let mut tally = [0usize; 6];
    let mut found = Vec::with_capacity(scans.iter().map(|s| s.found.len()).sum());
    let several = scans.len() > 1;
    for scan in scans {
        tally.iter_mut().zip(scan.tally).for_each(|(t, r)| *t += r);
        found.extend(scan.found);
    }
    if several {
        found.sort_by_key(|f| f.0);
    }
    let found: Vec<Found> = found.into_iter().map(|f| f.1).collect();
    let thresholds = match params.min_points {
        Some(n) => Thresholds::fixed(n),
        None => {
            // Shallow cells are not yet walls: they say nothing of how dense walls are.
            let cells: Vec<(threshold::Cell, usize)> = found
                .iter()
                .filter(|f| !f.shallow)
                .map(|f| (f.cell, f.count))
                .collect();
            Thresholds::derive(&cells, params.cell_size)
        }
    };
    let min_points_used = thresholds.global;
    let walls: Vec<&Found> = found
        .iter()
        .filter(|f| f.count >= thresholds.at(f.cell) && (f.low || f.count >= min_points_used))
        .filter(|f| f.sample.is_some())
        .collect();
    let cells_tested = walls.len();
    let near: Vec<&Found> = walls
        .into_iter()
        .filter(|f| f.nearest.is_none_or(|d| d <= params.max_range))
        .collect();
    let candidates: Vec<(&WallSample, bool)> = near
        .iter()
        .filter_map(|f| f.sample.as_ref().map(|s| (s, f.shallow)))
        .collect();
    let keep = shallow::continuing(&candidates, frame.cell);
    let shallow_kept = keep
        .iter()
        .zip(&candidates)
        .filter(|(&k, c)| k && c.1)
        .count() as f64
        * frame.cell;
    let samples: Vec<WallSample> = candidates
        .iter()
        .zip(&keep)
        .filter(|(_, &k)| k)
        .map(|(c, _)| c.0.clone())
        .collect();
    if samples.is_empty() {
        let why = if cells_tested > 0 {
            format!(
                "all {cells_tested} wall cells are over {} m from their scanners",
                params.max_range
            )
        } else {
            describe_rejections(&tally, min_points_used, &found)
        };
        return Err(SamplesError::NoWalls {
            level: story.level,
            why,
        });
    }
    if !story.floor_seen {
        let (seen, around) = coverage::seen_and_around(&samples, params.cell_size);
        if seen < coverage::MIN_SEEN_SHARE * around {
            return Err(SamplesError::FewWallsSeen {
                level: story.level,
                seen,
                around,
                share: coverage::MIN_SEEN_SHARE * 100.0,
                reach: cell::FLOORLESS_REACH * params.min_wall_height,
            });
        }
    }
    Ok(WallSamples {
        samples,
        viewpoints: views.viewpoints,
        path: views.path,
        min_points_used,
        min_points_lowest: thresholds.lowest(),
        cells_tested,
        shallow_kept,
        lines_checked: false,
        moving: false,
        underlay,
    })
}

impl SamplesParams {
    /// Checks every value; the error names the parameter.
    pub fn check(&self) -> Result<(), SamplesError> {
        check_values(self)
    }
}

pub(crate) fn check_params(params: &SamplesParams, story: &Story) -> Result<(), SamplesError> {
    check_values(params)?;
    let bad = |name, why: String| Err(SamplesError::BadParam { name, why });
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !positive(story.wall_top_z - story.floor_z) {
        return bad(
            "story",
            format!(
                "ceiling {} is not above floor {}",
                story.wall_top_z, story.floor_z
            ),
        );
    }
    Ok(())
}

fn check_values(params: &SamplesParams) -> Result<(), SamplesError> {
    let check = |name, v: f64| {
        within(RANGES, name, v).map_err(|(name, why)| SamplesError::BadParam { name, why })
    };
    check("cell_size", params.cell_size)?;
    if let Some(n) = params.min_points {
        check("min_points", n as f64)?;
    }
    check("min_wall_height", params.min_wall_height)?;
    check("height_bins", params.height_bins as f64)?;
    check("min_filled_bins", params.min_filled_bins as f64)?;
    check("min_top_bins", params.min_top_bins as f64)?;
    check("min_confidence", params.min_confidence)?;
    check("max_range", params.max_range)?;
    if params.min_filled_bins > params.height_bins {
        return Err(SamplesError::BadParam {
            name: "min_filled_bins",
            why: format!(
                "{} exceeds height_bins ({})",
                params.min_filled_bins, params.height_bins
            ),
        });
    }
    Ok(())
}

fn describe_rejections(tally: &[usize; 6], min_points: usize, found: &[Found]) -> String {
    let parts: Vec<String> = Reject::ALL
        .iter()
        .zip(tally)
        .filter(|(_, &n)| n > 0)
        .map(|(r, n)| format!("{n} {}", r.describe()))
        .collect();
    let below = found.iter().filter(|f| f.count < min_points).count();
    let mut why = format!("min_points {min_points}; cells: {}", parts.join(", "));
    if below > 0 {
        why.push_str(&format!(", {below} wall-like below min_points"));
    }
    why
}

/// A wall-like cell: its neighbourhood count and, when it passed every test, its sample and
/// the distance to its nearest scanner.
struct Found {
    /// The cell's column and row in the story's grid (tiles share it).
    cell: threshold::Cell,
    count: usize,
    sample: Option<WallSample>,
    nearest: Option<f64>,
    /// Why a wall-like cell gave no sample.
    why: Option<Reject>,
    /// Seen too little under the ceiling to be a wall on its own (floorless stories).
    shallow: bool,
    /// Points in the lower half of the wall's height: only such a cell may be held to a
    /// threshold below the story-wide one (a door gap's lintel is seen high up only).
    low: bool,
}

/// What one grid row yields: wall-like cells and the rejections by reason.
struct Row {
    found: Vec<(u64, Found)>,
    tally: [usize; 6],
}

/// The 3 × 3 block bounds the neighbourhood: a cell is ruled out cheaply when even its
/// block's summary fails the count, vertical-support or filled-bins tests.
fn prefilter(tests: &Tests, block: &Summary, min_points: usize) -> Result<(), Reject> {
    if (block.n as usize) < min_points {
        return Err(Reject::TooFew);
    }
    if ((block.zmax - block.zmin) as f64) < tests.least_support() {
        return Err(Reject::TooShort);
    }
    if tests.local() {
        return Ok(());
    }
    tests.histogram(block.mask, min_points)
}

/// Per-thread buffers for a neighbourhood: its points' places in the grid, the points and
/// their height bins, and what says who saw them.
#[derive(Default)]
struct Scratch {
    /// Where the block's points lie in the grid.
    runs: Vec<Range<usize>>,
    idx: Vec<u32>,
    pts: Vec<[f32; 3]>,
    bins: Vec<u8>,
    slots: Vec<u16>,
    times: Vec<f64>,
    /// For the median: coordinates within the cell's span, as [`rank::key`]s (see
    /// [`rank::keys_where`]).
    within: Vec<i32>,
}

/// Everything a row scan reads.
struct Scan<'a> {
    grid: &'a Grid,
    tests: &'a Tests,
    views: &'a Views<'a>,
    /// The count threshold applied while scanning; the adaptive one is applied afterwards.
    min_points: usize,
    /// The cells to test.
    core: &'a CellRange,
    /// Checked every [`CELLS_PER_CHECK`] cells; a stopped scan returns what it has, and the
    /// caller reports the stop.
    cancel: &'a Cancel,
}

/// Cells tested between cancellation checks: a few milliseconds at the densest.
const CELLS_PER_CHECK: usize = 32;

impl Scan<'_> {
    fn row(&self, j: usize, s: &mut Scratch) -> Row {
        let mut row = Row {
            found: Vec::new(),
            tally: [0; 6],
        };
        let nx = self.grid.frame.nx as u64;
        for i in self.core.i.clone() {
            if (i - self.core.i.start).is_multiple_of(CELLS_PER_CHECK) && self.cancel.is_stopped() {
                break;
            }
            match self.cell(i, j, s) {
                Ok(None) => {}
                Ok(Some(f)) => {
                    if let Some(r) = f.why {
                        row.tally[r as usize] += 1;
                    }
                    row.found.push((j as u64 * nx + i as u64, f))
                }
                Err(r) => row.tally[r as usize] += 1,
            }
        }
        row
    }

    /// Tests cell `(i, j)`. `Ok(None)` for a cell with no points around it.
    fn cell(&self, i: usize, j: usize, s: &mut Scratch) -> Result<Option<Found>, Reject> {
        let g = self.grid;
        match g.screens[g.id(i, j)] {
            Screen::Empty => return Ok(None),
            Screen::Rejected(r) => return Err(r),
            Screen::Candidate => {}
        }
        self.gather(i, j, s);
        let lo = g.frame.corner(i, j);
        let cell = (i as i64, j as i64);
        let count = s.pts.len();
        let wall = match self.tests.run_binned(
            &s.pts,
            &s.bins,
            lo,
            g.frame.cell,
            self.min_points,
            &mut s.within,
            || {
                let block: Vec<[f32; 3]> = g.block_points(i, j).map(|k| g.pts[k]).collect();
                cell::pca_normal(&block)
            },
        ) {
            Ok(w) => w,
            Err(r) if r.wall_like() => {
                let zmin = s.pts.iter().fold(f32::INFINITY, |m, p| m.min(p[2]));
                return Ok(Some(Found {
                    cell,
                    count,
                    sample: None,
                    nearest: None,
                    why: Some(r),
                    shallow: self.tests.shallow(zmin),
                    low: self.tests.seen_low(&s.bins),
                }));
            }
            Err(r) => return Err(r),
        };
        let seen = self.views.observe(
            &s.pts,
            &s.slots,
            &s.times,
            g.frame.cell / 2.0,
            wall.pos,
            wall.normal,
        );
        Ok(Some(Found {
            cell,
            count,
            sample: Some(WallSample {
                pos: wall.pos,
                normal: seen.normal,
                confidence: wall.confidence,
                seen_from: seen.seen_from,
            }),
            nearest: seen.nearest,
            why: None,
            shallow: wall.shallow,
            low: self.tests.seen_low(&s.bins),
        }))
    }

    /// Collects the points within d_s of the centre of cell `(i, j)`, in grid order.
    fn gather(&self, i: usize, j: usize, s: &mut Scratch) {
        let g = self.grid;
        let lo = g.frame.corner(i, j);
        let cell = g.frame.cell;
        let (cx, cy) = (lo[0] + cell / 2.0, lo[1] + cell / 2.0);
        let r2 = cell * cell;
        // About a third of the block's points lie outside the circle, in no pattern: the test
        // decides where the next index goes rather than whether to branch. Room for every
        // point of the block is made once, however many runs it comes in; `idx` only grows,
        // so it is not zeroed again for every cell, and its first `at` entries are this one's.
        g.block_runs(i, j, &mut s.runs);
        let room = s.runs.iter().map(|r| r.len()).sum();
        if s.idx.len() < room {
            s.idx.resize(room, 0);
        }
        let mut at = 0;
        for run in s.runs.iter().cloned() {
            for k in run {
                let p = g.pts[k];
                let (dx, dy) = (p[0] as f64 - cx, p[1] as f64 - cy);
                s.idx[at] = k as u32;
                at += usize::from(dx * dx + dy * dy <= r2);
            }
        }
        let idx = &s.idx[..at];
        s.pts.clear();
        s.pts.extend(idx.iter().map(|&k| g.pts[k as usize]));
        s.bins.clear();
        s.bins.extend(idx.iter().map(|&k| g.bins[k as usize]));
        s.slots.clear();
        if !g.slots.is_empty() {
            s.slots.extend(idx.iter().map(|&k| g.slots[k as usize]));
        }
        s.times.clear();
        if !g.times.is_empty() {
            s.times.extend(idx.iter().map(|&k| g.times[k as usize]));
        }
    }
}

#[cfg(test)]
mod tests;
