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
/// `ceiling_z` is the lowest ceiling at least the minimum wall height above the floor (the
/// paper's rule). A story may have higher ceilings too (rooms with a raised ceiling); those
/// lie inside `z_min..z_max`, so their walls still belong to the story.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Story {
    /// 0 is the lowest story.
    pub level: usize,
    pub floor_z: f64,
    pub ceiling_z: f64,
    /// Points with `z_min <= z < z_max` belong to this story (partition levels, §3.1).
    pub z_min: f64,
    pub z_max: f64,
}

/// Why no stories could be found.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StoriesError {
    #[error("the cloud is empty")]
    Empty,
    #[error("invalid stories parameter `{name}`: {why}")]
    BadParam { name: &'static str, why: String },
    #[error("{0} point heights are not finite")]
    NonFinite(usize),
    #[error("the heights span {range:.1} m, {bins} bins of the histogram; are there outliers?")]
    TooTall { range: f64, bins: usize },
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
    let (lo, hi, bad) = points
        .par_chunks(1 << 16)
        .map(|block| {
            let (mut lo, mut hi, mut bad) = (f32::INFINITY, f32::NEG_INFINITY, 0usize);
            for p in block {
                let v = z(p);
                if v.is_finite() {
                    lo = lo.min(v);
                    hi = hi.max(v);
                } else {
                    bad += 1;
                }
            }
            (lo, hi, bad)
        })
        .reduce(
            || (f32::INFINITY, f32::NEG_INFINITY, 0),
            |a, b| (a.0.min(b.0), a.1.max(b.1), a.2 + b.2),
        );
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
            match assemble(&candidates, params.min_wall_height) {
                Some(levels) => return Ok(hist.partition(&levels)),
                None => tried.push(describe(&candidates)),
            }
        }
        Err(StoriesError::NotFound(if tried.is_empty() {
            "the heights are spread evenly, with no dense floor or ceiling level".into()
        } else {
            format!(
                "no two dense levels are {} m apart (candidates: {})",
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

/// Floor, lowest ceiling and highest ceiling of one story, before partitioning.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Levels {
    floor: f64,
    ceiling: f64,
    top: f64,
}

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
                ceiling_z: levels[k].ceiling,
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
            })
            .collect()
    }
}

/// Walks the candidates upward (§3.1): the lowest is a floor, its ceiling the lowest candidate at
/// least `h` above it, and so on. `None` when not even one story is found.
///
/// Beyond the paper, for rooms of different ceiling heights: after a ceiling, a candidate is the
/// next floor only if some candidate lies `h` above it. Of the candidates that could be the
/// floor under that next ceiling, the densest is the floor; the others are further ceilings of
/// the story below. Without this, a second ceiling height would start a story of its own.
fn assemble(candidates: &[Peak], h: f64) -> Option<Vec<Levels>> {
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
        let last_own = next_floor.map_or(candidates.len(), |f| f) - 1;
        stories.push(Levels {
            floor: candidates[floor].z,
            ceiling: candidates[ceiling].z,
            top: candidates[last_own].z,
        });
        match next_floor {
            Some(f) => floor = f,
            None => break,
        }
    }
    (!stories.is_empty()).then_some(stories)
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
        story(&mut rng, &mut z, (-1.73, 0.77), 20_000, 30_000);
        story(&mut rng, &mut z, (-1.73, 1.35), 20_000, 30_000);
        let stories = split_stories(&z, &StoriesParams::default()).unwrap();
        assert_eq!(stories.len(), 1, "{stories:?}");
        let s = stories[0];
        assert!((s.floor_z + 1.73).abs() < 0.02 && (s.ceiling_z - 0.77).abs() < 0.02);
        assert!(s.z_min <= -1.735 && s.z_max > 1.355, "{s:?}");
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
