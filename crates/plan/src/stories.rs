//! Stage 1 (§3.1): split the cloud into stories from a histogram of point heights.
//!
//! Floors and ceilings are the local maxima among the densest histogram bins. The densest bins
//! are those before the greatest discontinuity of the bin counts sorted in descending order.
//! The discontinuity is measured as a ratio between consecutive counts: plain differences favour
//! the gap between the two biggest bins and miss the step down to the wall bins.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::params::{within, ParamRange};

/// Parameters of [`split_stories`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StoriesParams {
    /// Height histogram bin width in metres. The paper leaves it open; 5 cm matches d_s (§3.1).
    /// Range 0.005..=0.5.
    pub bin_size: f64,
    /// Minimum floor-to-ceiling height of a story, metres (§3.1: "typically ~2 meters").
    /// Range 0.5..=10.
    pub min_wall_height: f64,
}

/// The accepted values of [`StoriesParams`] (see [`crate::params::ParamRange`]).
pub const RANGES: &[ParamRange] = &[
    ParamRange::new("bin_size", 0.005, 0.5, "m"),
    ParamRange::new("min_wall_height", 0.5, 10.0, "m"),
];

impl Default for StoriesParams {
    fn default() -> Self {
        StoriesParams {
            bin_size: 0.05,
            min_wall_height: 2.0,
        }
    }
}

/// One story: its floor and ceiling, and the z range of points assigned to it (local frame).
///
/// A story may have several flat ceilings (rooms with a raised ceiling): `wall_top_z` is the
/// lowest at least the minimum wall height above the floor (the paper's rule, and where the
/// wall tests expect walls to reach), `top_z` the highest, and `ceiling_z` the one over most of
/// the story (the densest), which the plan reports. Higher ceilings lie inside `z_min..z_max`,
/// so their walls still belong to the story.
///
/// Beyond the paper, a story's ceiling may slope or be missing (an attic under a pitched roof):
/// `flat_ceiling` is false, the three ceiling heights are where the story's points end, and the
/// wall tests measure each cell against its own top. Its floor may be missing too (a capture
/// of ceilings and upper walls only): `floor_seen` is false and `floor_z` is assumed at the
/// story's lowest points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Story {
    /// 0 is the lowest story.
    pub level: usize,
    /// The floor's local height.
    pub floor_z: f64,
    /// The ceiling's local height.
    pub ceiling_z: f64,
    /// Points with `z_min <= z < z_max` belong to this story (partition levels, §3.1).
    pub z_min: f64,
    /// Upper partition level (exclusive).
    pub z_max: f64,
    /// The lowest ceiling at least the minimum wall height above the floor.
    pub wall_top_z: f64,
    /// The highest ceiling.
    pub top_z: f64,
    /// False when no floor was seen and `floor_z` is assumed.
    pub floor_seen: bool,
    /// False when the ceiling slopes or was not seen.
    pub flat_ceiling: bool,
}

impl Story {
    /// A story with one flat ceiling and a seen floor, as the paper has them.
    pub fn flat(level: usize, floor_z: f64, ceiling_z: f64, z_min: f64, z_max: f64) -> Story {
        Story {
            level,
            floor_z,
            ceiling_z,
            z_min,
            z_max,
            wall_top_z: ceiling_z,
            top_z: ceiling_z,
            floor_seen: true,
            flat_ceiling: true,
        }
    }

    /// Whether a scanner at height `z` stands within this story: in its partition range, not
    /// below its floor (when seen) and, under flat ceilings, not above the highest. A scanner
    /// on a gallery above a double-height room is no viewpoint of the story below: its lines of
    /// sight pass over that story's walls in 3D, and would cut through them in 2D.
    pub fn holds_viewpoint(&self, z: f64) -> bool {
        let above_floor = if self.floor_seen {
            z >= self.z_min && z >= self.floor_z - VIEWPOINT_BELOW_FLOOR
        } else {
            // The floor is unknown: a phone held low sees no lower than the walls it captured.
            true
        };
        above_floor && z < self.z_max && (!self.flat_ceiling || z <= self.top_z)
    }

    /// The share of directions from a pseudo-viewpoint that may escape the wall samples, given
    /// `given` for stories whose floor was seen. A capture without a floor (a phone held up to
    /// the ceiling) sees walls only in part, missing corners and low walls, so more directions
    /// escape through the gaps; its ceiling, which a place must be under, still says where the
    /// room is.
    pub fn open_space_max_escape(&self, given: f64) -> f64 {
        if self.floor_seen {
            given
        } else {
            given.max(FLOORLESS_MAX_ESCAPE)
        }
    }

    /// What was assumed about this story's floor and ceiling, for the plan's notes (heights in
    /// the local frame plus `z0`).
    pub fn assumptions(&self, z0: f64) -> Vec<String> {
        let mut notes = Vec::new();
        if !self.floor_seen {
            notes.push(format!(
                "no floor was seen; the floor is assumed at the lowest points, z {:.2}. The \
                 outline rests on the walls seen under the ceiling; where none was seen it is \
                 closed by straight edges between the walls that were, or on along their lines",
                self.floor_z + z0
            ));
        }
        if !self.flat_ceiling {
            notes.push(format!(
                "no flat ceiling was seen (sloped or missing); walls are tested against each \
                 cell's own top, and the story's points end at z {:.2}",
                self.ceiling_z + z0
            ));
        } else if self.top_z > self.wall_top_z + 0.01 {
            notes.push(format!(
                "ceilings at several heights, z {:.2} to {:.2}; the most common is z {:.2}",
                self.wall_top_z + z0,
                self.top_z + z0,
                self.ceiling_z + z0
            ));
        }
        notes
    }
}

/// The least share of escaping directions a pseudo-viewpoint may have in a story whose floor
/// was not seen. The phone rooms' walls leave gaps of 1.5-3 m at corners, through which about a
/// quarter of the directions from the room's middle escape.
const FLOORLESS_MAX_ESCAPE: f64 = 0.3;

/// A scanner head may stand this far below a story's floor and still be in it (a pose given
/// at the tripod's foot, or a floor found a little high).
const VIEWPOINT_BELOW_FLOOR: f64 = 0.25;

/// Why no stories could be found.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StoriesError {
    /// The cloud holds no points.
    #[error("the cloud is empty")]
    Empty,
    /// A parameter is outside its range.
    #[error("invalid stories parameter `{name}`: {why}")]
    BadParam {
        /// The parameter's name.
        name: &'static str,
        /// What is wrong.
        why: String,
    },
    /// Some point heights are not finite.
    #[error("{0} point heights are not finite")]
    NonFinite(usize),
    /// The heights span more bins than the histogram allows.
    #[error("the heights span {range:.1} m, {bins} bins of the histogram; are there outliers?")]
    TooTall {
        /// The heights' span, metres.
        range: f64,
        /// The histogram bins it would take.
        bins: usize,
    },
    /// No floor or ceiling peak was found.
    #[error("no floor or ceiling found: {0}")]
    NotFound(String),
}

/// The most bins a height histogram may have (about 50 km at 5 cm): beyond it the cloud holds
/// outliers, and the histogram would waste memory.
const MAX_BINS: usize = 1 << 20;

/// A discontinuity must at least be this ratio between consecutive sorted counts; below it the
/// heights are spread evenly and hold no floor or ceiling.
const MIN_JUMP: f64 = 1.5;

/// Finds the stories of a cloud from the heights `z` of its points (local frame).
pub fn split_stories(z: &[f32], params: &StoriesParams) -> Result<Vec<Story>, StoriesError> {
    split_by(z, |v| *v, params)
}

/// Finds the stories of a cloud from its points' local coordinates, without copying the heights
/// out.
pub fn split_cloud_stories(
    xyz: &[[f32; 3]],
    params: &StoriesParams,
) -> Result<Vec<Story>, StoriesError> {
    split_by(xyz, |p| p[2], params)
}

/// [`split_cloud_stories`] with the points' [`Heights`] already measured (in a pass over the
/// points that finds other things too): one pass over the points instead of two.
pub fn split_cloud_stories_within(
    xyz: &[[f32; 3]],
    heights: Heights,
    params: &StoriesParams,
) -> Result<Vec<Story>, StoriesError> {
    split_within(xyz, |p| p[2], heights, params)
}

/// The range of a cloud's finite heights, and how many are not finite: what the stories'
/// histogram is laid over. Heights of parts of a cloud merge into the heights of the whole.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Heights {
    /// The lowest finite height (infinite when none).
    pub lo: f32,
    /// The highest finite height (minus infinity when none).
    pub hi: f32,
    /// Heights that are not finite.
    pub non_finite: usize,
}

impl Default for Heights {
    fn default() -> Self {
        Heights {
            lo: f32::INFINITY,
            hi: f32::NEG_INFINITY,
            non_finite: 0,
        }
    }
}

impl Heights {
    /// Adds one height.
    #[inline]
    pub fn add(&mut self, v: f32) {
        if v.is_finite() {
            self.lo = self.lo.min(v);
            self.hi = self.hi.max(v);
        } else {
            self.non_finite += 1;
        }
    }

    /// The heights of both parts.
    pub fn merge(self, o: Heights) -> Heights {
        Heights {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            non_finite: self.non_finite + o.non_finite,
        }
    }
}

fn split_by<T: Sync>(
    points: &[T],
    z: impl Fn(&T) -> f32 + Sync,
    params: &StoriesParams,
) -> Result<Vec<Story>, StoriesError> {
    check_params(params)?;
    if points.is_empty() {
        return Err(StoriesError::Empty);
    }
    // In blocks with a plain loop inside: a per-item rayon fold does not vectorize.
    let heights = points
        .par_chunks(1 << 16)
        .map(|block| {
            let mut h = Heights::default();
            block.iter().for_each(|p| h.add(z(p)));
            h
        })
        .reduce(Heights::default, Heights::merge);
    split_within(points, z, heights, params)
}

/// The stories of `points`, whose heights are `heights`.
fn split_within<T: Sync>(
    points: &[T],
    z: impl Fn(&T) -> f32 + Sync,
    heights: Heights,
    params: &StoriesParams,
) -> Result<Vec<Story>, StoriesError> {
    check_params(params)?;
    if points.is_empty() {
        return Err(StoriesError::Empty);
    }
    let Heights {
        lo,
        hi,
        non_finite: bad,
    } = heights;
    if bad > 0 {
        return Err(StoriesError::NonFinite(bad));
    }
    // Per-thread histograms over parts of the cloud, merged: no atomics, memory bins × threads.
    let empty = HeightHistogram::new(lo, hi, params)?;
    let part = points
        .len()
        .div_ceil(rayon::current_num_threads().max(1))
        .max(1 << 16);
    let hist = points
        .par_chunks(part)
        .map(|chunk| {
            let mut h = empty.clone();
            chunk.iter().for_each(|p| h.add(z(p)));
            h
        })
        .reduce(
            || empty.clone(),
            |mut a, b| {
                a.merge(&b);
                a
            },
        );
    hist.stories(params)
}

impl StoriesParams {
    /// Checks every value; the error names the parameter.
    pub fn check(&self) -> Result<(), StoriesError> {
        check_params(self)
    }
}

/// The height histogram [`split_stories`] works from, built a point at a time and merged from
/// parts, for clouds read in pieces ([`crate::streaming`]). The bins start at the lowest height,
/// so the lowest and highest (finite) heights must be known first. Any order of adding and
/// merging gives the same histogram: per-bin sums are kept in fixed point.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightHistogram {
    hist: Histogram,
}

impl HeightHistogram {
    /// An empty histogram for heights from `z_lo` to `z_hi` (both finite).
    pub fn new(
        z_lo: f32,
        z_hi: f32,
        params: &StoriesParams,
    ) -> Result<HeightHistogram, StoriesError> {
        check_params(params)?;
        let (z_lo, z_hi, bin) = (z_lo as f64, z_hi as f64, params.bin_size);
        let bins = ((z_hi - z_lo) / bin) as usize + 1;
        if bins > MAX_BINS {
            return Err(StoriesError::TooTall {
                range: z_hi - z_lo,
                bins,
            });
        }
        Ok(HeightHistogram {
            hist: Histogram {
                z_lo,
                z_hi,
                bin,
                count: vec![0; bins],
                sum: vec![0; bins],
            },
        })
    }

    /// Counts one height, which must lie between the histogram's lowest and highest.
    #[inline]
    pub fn add(&mut self, v: f32) {
        let h = &mut self.hist;
        let d = v as f64 - h.z_lo;
        let i = ((d / h.bin) as usize).min(h.count.len() - 1);
        h.count[i] += 1;
        h.sum[i] += (d * SUM_SCALE) as i64 as i128;
    }

    /// Adds the counts of `other`, a histogram over the same heights.
    pub fn merge(&mut self, other: &HeightHistogram) {
        let (a, b) = (&mut self.hist, &other.hist);
        a.count.iter_mut().zip(&b.count).for_each(|(x, y)| *x += y);
        a.sum.iter_mut().zip(&b.sum).for_each(|(x, y)| *x += y);
    }

    /// The stories (§3.1) of the heights counted.
    pub fn stories(&self, params: &StoriesParams) -> Result<Vec<Story>, StoriesError> {
        check_params(params)?;
        let hist = &self.hist;
        if hist.count.iter().all(|&c| c == 0) {
            return Err(StoriesError::Empty);
        }
        let mut tried = Vec::new();
        for dense in hist.dense_sets() {
            let candidates = hist.peaks(&dense);
            match hist.assemble(&candidates, params.min_wall_height) {
                Some(levels) => return Ok(hist.partition(&levels)),
                None => tried.push(describe(&candidates)),
            }
        }
        if let Some(levels) = hist.one_sided(params.min_wall_height) {
            return Ok(hist.partition(&[levels]));
        }
        Err(StoriesError::NotFound(if tried.is_empty() {
            "the heights are spread evenly, with no dense floor or ceiling level".into()
        } else {
            format!(
                "no two dense levels are {} m apart, and no single level has walls of that \
                 height beside it (candidates: {})",
                params.min_wall_height,
                tried.join("; ")
            )
        }))
    }
}

/// Fixed-point scale of the per-bin height sums (heights above the lowest, in 2^-32 m), so that
/// sums do not depend on the order points are added in.
const SUM_SCALE: f64 = 4_294_967_296.0;

fn check_params(params: &StoriesParams) -> Result<(), StoriesError> {
    let check = |name, v: f64| {
        within(RANGES, name, v).map_err(|(name, why)| StoriesError::BadParam { name, why })
    };
    check("bin_size", params.bin_size)?;
    check("min_wall_height", params.min_wall_height)
}

fn describe(candidates: &[Peak]) -> String {
    let zs: Vec<String> = candidates.iter().map(|p| format!("{:.2}", p.z)).collect();
    format!("z = [{}]", zs.join(", "))
}

/// A floor or ceiling candidate: a dense local maximum of the histogram.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Peak {
    z: f64,
    count: u64,
}

/// One story's levels, before partitioning.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Levels {
    floor: f64,
    /// The lowest ceiling (the wall tests' top).
    ceiling: f64,
    /// The densest ceiling (the one reported).
    main: f64,
    /// The highest ceiling.
    top: f64,
    floor_seen: bool,
    flat: bool,
}

/// The share of a story's points below which its top is taken where the ceiling is not flat
/// (a few stray points above a roof must not raise it).
const TOP_QUANTILE: f64 = 0.999;

/// Height histogram with per-bin sums of z, so peaks can be located finer than a bin.
#[derive(Debug, Clone, PartialEq)]
struct Histogram {
    z_lo: f64,
    z_hi: f64,
    bin: f64,
    count: Vec<u64>,
    /// Per bin, the sum of its heights above `z_lo`, in units of 1 / [`SUM_SCALE`] m.
    sum: Vec<i128>,
}

impl Histogram {
    /// Dense bin sets to try, best first: for each discontinuity of the sorted counts, in order
    /// of decreasing ratio, the bins before it. The paper takes only the greatest; trying the
    /// next ones (beyond the paper) rescues clouds whose floor is far denser than the ceiling.
    fn dense_sets(&self) -> Vec<Vec<usize>> {
        let mut order: Vec<usize> = (0..self.count.len())
            .filter(|&i| self.count[i] > 0)
            .collect();
        order.sort_by_key(|&i| std::cmp::Reverse(self.count[i]));
        if order.len() < 2 {
            return vec![order];
        }
        // Ratios between near-empty tail bins are noise (9 points then 2): only steps down to a
        // bin at least as full as the median non-empty bin count.
        let median = self.count[order[order.len() / 2]];
        let mut cuts: Vec<(f64, usize)> = (0..order.len() - 1)
            .filter(|&k| self.count[order[k + 1]] >= median)
            .map(|k| {
                let ratio = self.count[order[k]] as f64 / self.count[order[k + 1]] as f64;
                (ratio, k + 1)
            })
            .filter(|&(ratio, _)| ratio >= MIN_JUMP)
            .collect();
        cuts.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        cuts.into_iter().map(|(_, n)| order[..n].to_vec()).collect()
    }

    /// The dense bins that are local maxima, ascending in z. Each is located at the mean height
    /// of its points and of its dense neighbours' (a floor straddling two bins); sparse
    /// neighbours are left out, as their wall and furniture points would pull the level away.
    fn peaks(&self, dense: &[usize]) -> Vec<Peak> {
        let c = |i: usize| self.count.get(i).copied().unwrap_or(0);
        let mut is_dense = vec![false; self.count.len()];
        dense.iter().for_each(|&i| is_dense[i] = true);
        let mut bins: Vec<usize> = dense
            .iter()
            .copied()
            .filter(|&i| {
                let left = if i == 0 { 0 } else { c(i - 1) };
                c(i) >= left && c(i) > c(i + 1)
            })
            .collect();
        bins.sort_unstable();
        bins.into_iter()
            .map(|i| {
                let window = (i.saturating_sub(1)..(i + 2).min(self.count.len()))
                    .filter(|&k| k == i || is_dense[k]);
                let (n, s) = window.fold((0u64, 0i128), |(n, s), k| (n + c(k), s + self.sum[k]));
                Peak {
                    z: self.z_lo + s as f64 / SUM_SCALE / n as f64,
                    count: c(i),
                }
            })
            .collect()
    }

    /// Turns story levels into stories, with partition levels halfway between one story's
    /// highest ceiling and the next story's floor.
    fn partition(&self, levels: &[Levels]) -> Vec<Story> {
        let n = levels.len();
        (0..n)
            .map(|k| Story {
                level: k,
                floor_z: levels[k].floor,
                ceiling_z: levels[k].main,
                z_min: if k == 0 {
                    self.z_lo
                } else {
                    (levels[k - 1].top + levels[k].floor) / 2.0
                },
                z_max: if k + 1 == n {
                    self.z_hi + self.bin
                } else {
                    (levels[k].top + levels[k + 1].floor) / 2.0
                },
                wall_top_z: levels[k].ceiling,
                top_z: levels[k].top,
                floor_seen: levels[k].floor_seen,
                flat_ceiling: levels[k].flat,
            })
            .collect()
    }

    /// The bin of height `z`, clamped to the histogram.
    fn bin_of(&self, z: f64) -> usize {
        (((z - self.z_lo) / self.bin).max(0.0) as usize).min(self.count.len() - 1)
    }

    /// Points in the bins from `from` on.
    fn count_from(&self, from: usize) -> u64 {
        self.count.iter().skip(from).sum()
    }

    /// The mean height of the bin in which a share `q` of the points in bins `from..` is
    /// reached, counting upward.
    fn quantile_from(&self, from: usize, q: f64) -> Option<f64> {
        let total = self.count_from(from);
        if total == 0 {
            return None;
        }
        let want = (q * total as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        for i in from..self.count.len() {
            seen += self.count[i];
            if seen >= want {
                return Some(self.bin_mean(i));
            }
        }
        None
    }

    /// The mean height of the points in bin `i`.
    fn bin_mean(&self, i: usize) -> f64 {
        self.z_lo + self.sum[i] as f64 / SUM_SCALE / self.count[i].max(1) as f64
    }

    /// Walks the candidates upward (§3.1): the lowest is a floor, its ceiling the lowest
    /// candidate at least `h` above it, and so on. `None` when not even one story is found.
    ///
    /// Beyond the paper, for rooms of different ceiling heights: after a ceiling, a candidate
    /// is the next floor only if some candidate lies `h` above it. Of the candidates that could
    /// be the floor under that next ceiling, the densest is the floor; the others are further
    /// ceilings of the story below, the densest of which is reported. Without this, a second
    /// ceiling height would start a story of its own. Above the last such story, a candidate
    /// with walls and a roof over it but no flat ceiling is the floor of a story under a
    /// sloped roof ([`Self::opens_story`]).
    fn assemble(&self, candidates: &[Peak], h: f64) -> Option<Vec<Levels>> {
        let above = |from: usize, z: f64| (from..candidates.len()).find(|&j| candidates[j].z >= z);
        let mut stories = Vec::new();
        let mut floor = 0;
        while floor < candidates.len() {
            let Some(ceiling) = above(floor + 1, candidates[floor].z + h) else {
                break;
            };
            let next_ceiling = candidates
                .get(ceiling + 1)
                .and_then(|next| above(ceiling + 2, next.z + h));
            let next_floor = next_ceiling.and_then(|c2| {
                (ceiling + 1..c2)
                    .filter(|&j| candidates[j].z <= candidates[c2].z - h)
                    .max_by_key(|&j| (candidates[j].count, std::cmp::Reverse(j)))
            });
            let open = match next_floor {
                Some(_) => None,
                None => {
                    (ceiling + 1..candidates.len()).find(|&j| self.opens_story(candidates, j, h))
                }
            };
            let last_own = open.or(next_floor).unwrap_or(candidates.len()) - 1;
            let main = (ceiling..=last_own)
                .max_by_key(|&j| (candidates[j].count, std::cmp::Reverse(j)))
                .unwrap_or(ceiling);
            stories.push(Levels {
                floor: candidates[floor].z,
                ceiling: candidates[ceiling].z,
                main: candidates[main].z,
                top: candidates[last_own].z,
                floor_seen: true,
                flat: true,
            });
            if let Some(j) = open {
                stories.push(self.open_story(candidates[j].z));
                break;
            }
            match next_floor {
                Some(f) => floor = f,
                None => break,
            }
        }
        (!stories.is_empty()).then_some(stories)
    }

    /// Whether candidate `j`, above the last story's ceiling, is the floor of a story whose
    /// ceiling is not flat: it is the highest dense level, at least as many points lie above it
    /// as in its own bin, and they reach half the minimum wall height `h` above it (knee walls
    /// under a pitched roof are often lower than `h`). A raised ceiling has nothing above it.
    fn opens_story(&self, candidates: &[Peak], j: usize, h: f64) -> bool {
        if j + 1 != candidates.len() {
            return false;
        }
        let z = candidates[j].z;
        let from = self.bin_of(z) + 2;
        self.count_from(from) >= candidates[j].count
            && self
                .quantile_from(from, TOP_QUANTILE)
                .is_some_and(|top| top >= z + h / 2.0)
    }

    /// The levels of a story on the floor at `z` whose ceiling is not flat: its top is where
    /// its points end.
    fn open_story(&self, z: f64) -> Levels {
        let top = self
            .quantile_from(self.bin_of(z) + 2, TOP_QUANTILE)
            .unwrap_or(self.z_hi);
        Levels {
            floor: z,
            ceiling: top,
            main: top,
            top,
            floor_seen: true,
            flat: false,
        }
    }

    /// Beyond the paper: one story from a single dense level, when no floor and ceiling pair
    /// exists. The densest bin (at least [`MIN_JUMP`] times the median non-empty count) is a
    /// floor when more points lie above it than below, else a ceiling.
    /// - A floor whose ceiling slopes or was not seen: no level above is nearly as dense (that
    ///   would be a flat ceiling too low for a story), and its points reach `h` / 2 above it.
    /// - A ceiling over a floor that was not seen (a phone capture of ceilings and upper
    ///   walls): the points below it reach `h` down; the floor is assumed at the lowest of
    ///   them (the 0.1 % quantile, so a stray point does not set it).
    fn one_sided(&self, h: f64) -> Option<Levels> {
        let mut counts: Vec<u64> = self.count.iter().copied().filter(|&c| c > 0).collect();
        if counts.is_empty() {
            return None;
        }
        let mid = counts.len() / 2;
        let median = *counts.select_nth_unstable(mid).1;
        let (i, &peak) = self
            .count
            .iter()
            .enumerate()
            .max_by_key(|&(i, &c)| (c, std::cmp::Reverse(i)))?;
        if (peak as f64) < MIN_JUMP * median as f64 {
            return None;
        }
        let z = self.bin_mean(i);
        let below: u64 = self.count[..i.saturating_sub(1)].iter().sum();
        let above = self.count_from(i + 2);
        if above > below {
            let rival = self
                .count
                .iter()
                .skip(i + 2)
                .any(|&c| c as f64 * MIN_JUMP >= peak as f64);
            let open = self.open_story(z);
            (!rival && open.top >= z + h / 2.0).then_some(open)
        } else {
            let low = self.quantile_from(0, 1.0 - TOP_QUANTILE)?;
            (z - low >= h).then_some(Levels {
                floor: low,
                ceiling: z,
                main: z,
                top: z,
                floor_seen: false,
                flat: true,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Heights of a story: `floor` and `ceiling` slabs of `slab` points each, and `wall` points
    /// spread evenly between them.
    fn story(rng: &mut ChaCha8Rng, z: &mut Vec<f32>, levels: (f32, f32), slab: usize, wall: usize) {
        let (floor, ceiling) = levels;
        for _ in 0..slab {
            z.push(floor + rng.random_range(-0.005..0.005));
            z.push(ceiling + rng.random_range(-0.005..0.005));
        }
        for _ in 0..wall {
            z.push(rng.random_range(floor..ceiling));
        }
    }

    #[test]
    fn two_stories_are_found_with_partition_between() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut z = Vec::new();
        story(&mut rng, &mut z, (0.0, 2.8), 20_000, 30_000);
        story(&mut rng, &mut z, (3.1, 5.9), 15_000, 30_000);
        let stories = split_stories(&z, &StoriesParams::default()).unwrap();
        assert_eq!(stories.len(), 2, "{stories:?}");
        let expect = [(0.0, 2.8), (3.1, 5.9)];
        for (s, (f, c)) in stories.iter().zip(expect) {
            assert!((s.floor_z - f).abs() < 0.02, "{s:?}");
            assert!((s.ceiling_z - c).abs() < 0.02, "{s:?}");
        }
        assert!((stories[0].z_max - 2.95).abs() < 0.02);
        assert_eq!(stories[0].z_max, stories[1].z_min);
        // Every point belongs to exactly one story.
        for v in &z {
            let v = *v as f64;
            let n = stories
                .iter()
                .filter(|s| s.z_min <= v && v < s.z_max)
                .count();
            assert_eq!(n, 1, "z = {v}");
        }
    }

    #[test]
    fn one_story_with_two_ceiling_heights_is_one_story() {
        // Like the real apartment: floor at -1.73, ceilings at 0.77 and 1.35.
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut z = Vec::new();
        // The higher ceiling covers more of the floor, as there.
        story(&mut rng, &mut z, (-1.73, 0.77), 15_000, 30_000);
        story(&mut rng, &mut z, (-1.73, 1.35), 25_000, 30_000);
        let stories = split_stories(&z, &StoriesParams::default()).unwrap();
        assert_eq!(stories.len(), 1, "{stories:?}");
        let s = stories[0];
        assert!((s.floor_z + 1.73).abs() < 0.02, "{s:?}");
        // Walls are tested up to the lower ceiling; the plan reports the common one.
        assert!((s.wall_top_z - 0.77).abs() < 0.02, "{s:?}");
        assert!((s.ceiling_z - 1.35).abs() < 0.02, "{s:?}");
        assert!((s.top_z - 1.35).abs() < 0.02, "{s:?}");
        assert!(s.floor_seen && s.flat_ceiling);
        assert!(s.z_min <= -1.7349 && s.z_max > 1.355, "{s:?}");
        assert!(s.assumptions(0.0)[0].contains("several heights"));
    }

    /// Heights of a story under a pitched roof: a floor slab at `floor`, knee walls up to
    /// `eaves`, and a roof rising evenly from `eaves` to `ridge` (with the gables beneath it).
    fn attic(rng: &mut ChaCha8Rng, z: &mut Vec<f32>, floor: f32, eaves: f32, ridge: f32) {
        for _ in 0..15_000 {
            z.push(floor + rng.random_range(-0.005..0.005));
        }
        for _ in 0..10_000 {
            z.push(rng.random_range(floor..eaves));
        }
        for _ in 0..25_000 {
            z.push(rng.random_range(eaves..ridge));
        }
        // The gables: fewer points the higher, as the triangle narrows.
        for _ in 0..8_000 {
            let t: f32 = rng.random_range(0.0f32..1.0);
            z.push(eaves + (ridge - eaves) * (1.0 - t.sqrt()));
        }
    }

    #[test]
    fn an_attic_under_a_pitched_roof_is_a_story_of_its_own() {
        // The house: a ground floor, a slab, and an attic whose knee walls are under
        // 2 m and whose ceiling slopes. Before, the attic's floor was taken for a second
        // ceiling of the ground floor, and the ground floor's range ran up to the ridge.
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let mut z = Vec::new();
        story(&mut rng, &mut z, (0.0, 2.45), 20_000, 30_000);
        attic(&mut rng, &mut z, 2.6, 3.8, 6.0);
        let stories = split_stories(&z, &StoriesParams::default()).unwrap();
        assert_eq!(stories.len(), 2, "{stories:?}");
        let (ground, top) = (stories[0], stories[1]);
        assert!(
            (ground.ceiling_z - 2.45).abs() < 0.02 && ground.flat_ceiling,
            "{ground:?}"
        );
        assert!((ground.top_z - 2.45).abs() < 0.02, "{ground:?}");
        assert!(
            (top.floor_z - 2.6).abs() < 0.02 && top.floor_seen,
            "{top:?}"
        );
        assert!(!top.flat_ceiling, "{top:?}");
        assert!((top.ceiling_z - 6.0).abs() < 0.05, "{top:?}");
        assert!((ground.z_max - 2.525).abs() < 0.02 && ground.z_max == top.z_min);
        // A scanner on the attic floor belongs to the attic only.
        assert!(top.holds_viewpoint(4.1) && !ground.holds_viewpoint(4.1));
        assert!(ground.holds_viewpoint(1.5) && !top.holds_viewpoint(1.5));
        assert!(top.assumptions(0.0)[0].contains("no flat ceiling"));
    }

    #[test]
    fn a_lone_attic_has_a_floor_and_no_flat_ceiling() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut z = Vec::new();
        attic(&mut rng, &mut z, 0.0, 1.0, 3.2);
        let stories = split_stories(&z, &StoriesParams::default()).unwrap();
        assert_eq!(stories.len(), 1, "{stories:?}");
        let s = stories[0];
        assert!(
            s.floor_z.abs() < 0.02 && s.floor_seen && !s.flat_ceiling,
            "{s:?}"
        );
        assert!((s.ceiling_z - 3.2).abs() < 0.05, "{s:?}");
    }

    #[test]
    fn a_capture_of_ceilings_and_upper_walls_assumes_its_floor() {
        // Like the iPad rooms: a dense ceiling at 4.45, a sparser grid below it, and walls seen
        // from 1.6 m up only.
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let mut z = Vec::new();
        for _ in 0..20_000 {
            z.push(4.45 + rng.random_range(-0.02..0.02));
        }
        for _ in 0..3_000 {
            z.push(3.35 + rng.random_range(-0.05..0.05));
        }
        for _ in 0..20_000 {
            z.push(rng.random_range(1.6..4.45));
        }
        let stories = split_stories(&z, &StoriesParams::default()).unwrap();
        assert_eq!(stories.len(), 1, "{stories:?}");
        let s = stories[0];
        assert!(!s.floor_seen && s.flat_ceiling, "{s:?}");
        assert!((s.ceiling_z - 4.45).abs() < 0.02, "{s:?}");
        assert!((s.floor_z - 1.6).abs() < 0.05, "{s:?}");
        // Without a floor, a scanner below the walls seen is still in the story.
        assert!(s.holds_viewpoint(1.4));
        assert!(s.assumptions(0.0)[0].contains("no floor was seen"));
        // Walls seen over less than the minimum wall height: no story.
        let high: Vec<f32> = z.iter().copied().filter(|&v| v > 2.6).collect();
        assert!(matches!(
            split_stories(&high, &StoriesParams::default()),
            Err(StoriesError::NotFound(_))
        ));
    }

    #[test]
    fn a_raised_ceiling_below_the_next_floor_stays_in_the_lower_story() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut z = Vec::new();
        story(&mut rng, &mut z, (0.0, 2.5), 20_000, 30_000);
        story(&mut rng, &mut z, (0.0, 3.0), 10_000, 20_000);
        story(&mut rng, &mut z, (3.3, 6.0), 30_000, 30_000);
        let stories = split_stories(&z, &StoriesParams::default()).unwrap();
        assert_eq!(stories.len(), 2, "{stories:?}");
        assert!((stories[1].floor_z - 3.3).abs() < 0.02, "{stories:?}");
        assert!((stories[0].z_max - 3.15).abs() < 0.02, "{stories:?}");
    }

    #[test]
    fn three_stories() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut z = Vec::new();
        for k in 0..3 {
            let f = k as f32 * 3.5;
            story(&mut rng, &mut z, (f, f + 3.0), 10_000, 20_000);
        }
        let stories = split_stories(&z, &StoriesParams::default()).unwrap();
        let floors: Vec<f64> = stories.iter().map(|s| s.floor_z).collect();
        assert_eq!(stories.len(), 3, "{floors:?}");
        for (k, f) in floors.iter().enumerate() {
            assert!((f - k as f64 * 3.5).abs() < 0.02, "{floors:?}");
        }
    }

    #[test]
    fn errors_name_the_problem() {
        let p = StoriesParams::default();
        assert_eq!(split_stories(&[], &p), Err(StoriesError::Empty));
        assert_eq!(
            split_stories(&[0.0, f32::NAN], &p),
            Err(StoriesError::NonFinite(1))
        );
        assert!(matches!(
            split_stories(&[0.0, 1.0e9], &p),
            Err(StoriesError::TooTall { .. })
        ));
        let bad = StoriesParams {
            bin_size: 0.0,
            ..p.clone()
        };
        assert!(matches!(
            split_stories(&[0.0], &bad),
            Err(StoriesError::BadParam {
                name: "bin_size",
                ..
            })
        ));
        // Evenly spread heights: no floor, no ceiling.
        let even: Vec<f32> = (0..30_000).map(|i| i as f32 * 1.0e-4).collect();
        assert!(matches!(
            split_stories(&even, &p),
            Err(StoriesError::NotFound(_))
        ));
        // A floor with nothing 2 m above it.
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut z = Vec::new();
        story(&mut rng, &mut z, (0.0, 1.5), 10_000, 10_000);
        assert!(matches!(
            split_stories(&z, &p),
            Err(StoriesError::NotFound(_))
        ));
    }
}
