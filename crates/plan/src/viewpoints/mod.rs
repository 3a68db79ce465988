//! Where the scanner stood, when the input does not say (beyond the paper, which assumes poses
//! are known or goes without). Labeling (§3.3) forces inside every triangle that lines of
//! sight cross, and sampling (§3.1) orients normals toward the scanner; without viewpoints
//! neither happens and the plan rests on geometry alone.
//!
//! - Static scans with scan ids but no poses: each scan's blind cone under the tripod gives
//!   its scanner position (`cone`).
//! - A mobile scan with times but no trajectory: the same cone, fitted to the points of short
//!   time windows, gives the path (`path`). It is reported, but the plan rests on open space
//!   (below): lines of sight from a path guessed between located windows cut walls.
//! - Plain x, y, z: `open_space` places pseudo-viewpoints in the open space each story's wall
//!   samples enclose, after sampling, where floor or ceiling points were scanned.
//!
//! Estimated static positions are used exactly as given ones; [`ViewpointsReport`] says which
//! are which, with a residual per scan.

pub(crate) mod cone;
pub(crate) mod open_space;
pub(crate) mod path;
pub(crate) mod raster;

use std::ops::Range;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cloud::{PointCloud, ScanPose, TrajectorySample, Viewpoints};
use crate::params::{within, ParamRange};

/// Parameters of [`estimate`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ViewpointsParams {
    /// Estimate scanner positions when the input gives none (static scans with scan ids,
    /// mobile scans with times). `false` plans on geometry alone, as without poses before.
    pub estimate: bool,
    /// Points of each scan (spread evenly over it) that the estimate looks at.
    pub max_points_per_scan: usize,
    /// Points per time window of a mobile scan (of the evenly thinned cloud).
    pub window_points: usize,
    /// Plain x, y, z (no poses, scan ids or times): place pseudo-viewpoints in the open space
    /// the wall samples enclose (`open_space`), and a mobile scan without its trajectory too
    /// (its estimated path is only reported). `false` plans plain clouds on geometry alone and
    /// mobile ones from the estimated path.
    pub open_space: bool,
    /// Pseudo-viewpoints stand at least this far from every wall sample, metres.
    pub open_space_clearance: f64,
    /// Pseudo-viewpoints stand at least this far apart, metres.
    pub open_space_spacing: f64,
    /// A place is enclosed when at most this fraction of the directions from it leave the wall
    /// samples without meeting one (doorways, windows and gaps let a few through).
    pub open_space_max_escape: f64,
}

impl Default for ViewpointsParams {
    fn default() -> Self {
        ViewpointsParams {
            estimate: true,
            max_points_per_scan: 20_000,
            window_points: 8_000,
            open_space: true,
            open_space_clearance: 0.4,
            open_space_spacing: 3.0,
            open_space_max_escape: 0.2,
        }
    }
}

/// A parameter out of range.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ViewpointsError {
    /// A parameter is outside its range.
    #[error("invalid viewpoints parameter `{name}`: {why}")]
    BadParam {
        /// The parameter's name.
        name: &'static str,
        /// What is wrong.
        why: String,
    },
}

/// The accepted values of [`ViewpointsParams`] (see [`crate::params::ParamRange`]).
pub const RANGES: &[ParamRange] = &[
    ParamRange::new("max_points_per_scan", 1_000.0, 10_000_000.0, ""),
    ParamRange::new("window_points", 500.0, 1_000_000.0, ""),
    ParamRange::new("open_space_clearance", 0.1, 10.0, "m"),
    ParamRange::new("open_space_spacing", 0.5, 100.0, "m"),
    ParamRange::new("open_space_max_escape", 0.0, 1.0, ""),
];

impl ViewpointsParams {
    /// Checks every value; the error names the parameter.
    pub fn check(&self) -> Result<(), ViewpointsError> {
        let check = |name, v: f64| {
            within(RANGES, name, v).map_err(|(name, why)| ViewpointsError::BadParam { name, why })
        };
        check("max_points_per_scan", self.max_points_per_scan as f64)?;
        check("window_points", self.window_points as f64)?;
        check("open_space_clearance", self.open_space_clearance)?;
        check("open_space_spacing", self.open_space_spacing)?;
        check("open_space_max_escape", self.open_space_max_escape)
    }
}

/// Where the viewpoints of a plan came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewpointSource {
    /// Poses or a trajectory came with the input (sidecar or E57).
    Given,
    /// Estimated from the points (scan ids or times, no poses).
    Estimated,
    /// Some scans' poses were given and the others estimated.
    Mixed,
    /// Pseudo-viewpoints placed in open space (plain x, y, z).
    OpenSpace,
    /// None: the plan rests on geometry alone.
    None,
}

/// One static scan's viewpoint, as reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScanViewpoint {
    /// The scan's index as the input names it.
    pub index: u32,
    /// True when the position was estimated from the points.
    pub estimated: bool,
    /// Scanner position, local frame; `None` when it could not be estimated.
    pub position: Option<[f64; 3]>,
    /// Estimated positions: root mean square distance of the blind-spot edge from the fitted
    /// cone, metres (horizontal).
    pub residual: Option<f64>,
    /// Estimated positions: the fraction of azimuth sectors whose edge lies on the cone.
    pub support: Option<f64>,
    /// Points of the scan.
    pub points: u64,
}

/// A mobile scan's path, as reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PathReport {
    /// True when the path was estimated, not given.
    pub estimated: bool,
    /// Samples of the path.
    pub samples: usize,
    /// Estimated paths: time windows, and those whose scanner position was found.
    pub windows: usize,
    /// Windows whose scanner position was found.
    pub located: usize,
    /// Estimated paths: median residual of the windows' cone fits, metres.
    pub residual: Option<f64>,
    /// Estimated paths: the path's length, metres.
    pub length: Option<f64>,
    /// The path in time order, local frame, thinned for drawing ([`thin_path`]).
    pub positions: Vec<[f64; 3]>,
}

/// Spacing of a reported path's positions, metres: finer than a plan's detail at a glance.
pub const PATH_STEP: f64 = 0.25;
/// The most positions a path report holds; a longer path is thinned further.
pub const MAX_PATH_POSITIONS: usize = 2000;

/// A path's positions for drawing: the first, then each one at least [`PATH_STEP`] from the
/// last kept, and the last; at most [`MAX_PATH_POSITIONS`] (every k-th kept beyond that).
pub fn thin_path(path: impl Iterator<Item = [f64; 3]>) -> Vec<[f64; 3]> {
    let mut kept: Vec<[f64; 3]> = Vec::new();
    let mut last = None;
    for p in path.filter(|p| p.iter().all(|c| c.is_finite())) {
        last = Some(p);
        let far = kept.last().is_none_or(|q| {
            let (dx, dy, dz) = (p[0] - q[0], p[1] - q[1], p[2] - q[2]);
            dx * dx + dy * dy + dz * dz >= PATH_STEP * PATH_STEP
        });
        if far {
            kept.push(p);
        }
    }
    if let Some(p) = last {
        if kept.last() != Some(&p) {
            kept.push(p);
        }
    }
    if kept.len() > MAX_PATH_POSITIONS {
        let k = kept.len().div_ceil(MAX_PATH_POSITIONS - 1);
        let end = *kept.last().expect("a position");
        kept = kept.into_iter().step_by(k).collect();
        if kept.last() != Some(&end) {
            kept.push(end);
        }
    }
    kept
}

/// One story's pseudo-viewpoints (plain x, y, z).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OpenSpaceStory {
    /// The story's level.
    pub level: usize,
    /// Pseudo-viewpoints placed, local frame.
    pub viewpoints: Vec<[f64; 2]>,
    /// Wall samples that some pseudo-viewpoint sees.
    pub samples_seen: usize,
    /// Wall samples of the story.
    pub samples: usize,
}

/// What the plan's viewpoints are and how much of the plan rests on them
/// (`floorplan.input.viewpoints`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewpointsReport {
    /// Where the viewpoints came from.
    pub source: ViewpointSource,
    /// Static scans, one per scan id.
    pub scans: Vec<ScanViewpoint>,
    /// A mobile scan's path.
    pub path: Option<PathReport>,
    /// Plain x, y, z: per story.
    pub open_space: Vec<OpenSpaceStory>,
    /// Fraction of the plan's open area that viewpoint evidence (lines of sight, poses, the
    /// path) forced inside; the rest was labelled from the wall geometry alone.
    pub rests_on: Option<f64>,
}

impl Default for ViewpointsReport {
    fn default() -> Self {
        ViewpointsReport {
            source: ViewpointSource::None,
            scans: Vec::new(),
            path: None,
            open_space: Vec::new(),
            rests_on: None,
        }
    }
}

/// Viewpoints for a cloud that came without (some of) them, and the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// The viewpoints to plan with instead of the cloud's; `None` to use the cloud's own.
    pub viewpoints: Option<Viewpoints>,
    /// What to report of them.
    pub report: ViewpointsReport,
}

/// Places pseudo-viewpoints in `story`'s open space for plain x, y, z (see [`open_space`]):
/// `samples` get them as viewpoints, each sample the ones that see it. A story without a
/// floor seen lets more directions escape. `max_range` is the scanner range of sampling. The
/// samples are marked `moving` when the cloud is a mobile scan (its path unknown).
pub fn place_open_space(
    cloud: &PointCloud,
    story: &crate::stories::Story,
    samples: &mut crate::samples::WallSamples,
    params: &ViewpointsParams,
    max_range: f64,
) -> OpenSpaceStory {
    let escape = story.open_space_max_escape(params.open_space_max_escape);
    let params = ViewpointsParams {
        open_space_max_escape: escape,
        ..params.clone()
    };
    samples.moving = cloud.is_mobile();
    open_space::place(&cloud.xyz, story, samples, &params, max_range)
}

/// Looks at what the cloud says about its scanners and estimates what it does not say.
pub fn estimate(cloud: &PointCloud, params: &ViewpointsParams) -> Estimate {
    let counts = scan_counts(cloud);
    if let Some(report) = given_report(&cloud.viewpoints, &counts) {
        return Estimate {
            viewpoints: None,
            report,
        };
    }
    match &cloud.viewpoints {
        _ if !params.estimate => Estimate {
            viewpoints: None,
            report: ViewpointsReport::default(),
        },
        Viewpoints::Static(poses) => estimate_static(cloud, Some(poses), &counts, params),
        // A trajectory is always given (above).
        Viewpoints::None | Viewpoints::Trajectory(_) => {
            if cloud.is_mobile() {
                path::estimate_path(cloud, params)
            } else if !cloud.scan_ids.is_empty() && !cloud.scan.is_empty() {
                estimate_static(cloud, None, &counts, params)
            } else {
                Estimate {
                    viewpoints: None,
                    report: ViewpointsReport::default(),
                }
            }
        }
    }
}

/// The report for viewpoints the cloud came with, or `None` when some are missing.
/// `counts` holds the points per scan slot.
pub(crate) fn given_report(viewpoints: &Viewpoints, counts: &[u64]) -> Option<ViewpointsReport> {
    match viewpoints {
        Viewpoints::Static(poses) if poses.iter().all(|p| finite(p.position)) => {
            Some(ViewpointsReport {
                source: ViewpointSource::Given,
                scans: poses
                    .iter()
                    .enumerate()
                    .map(|(slot, p)| given(p, counts.get(slot).copied().unwrap_or(0)))
                    .collect(),
                ..Default::default()
            })
        }
        Viewpoints::Trajectory(samples) => Some(ViewpointsReport {
            source: ViewpointSource::Given,
            path: Some(PathReport {
                estimated: false,
                samples: samples.len(),
                windows: 0,
                located: 0,
                residual: None,
                length: None,
                positions: thin_path(samples.iter().map(|s| s.position)),
            }),
            ..Default::default()
        }),
        _ => None,
    }
}

fn finite(p: [f64; 3]) -> bool {
    p.iter().all(|c| c.is_finite())
}

fn given(p: &ScanPose, points: u64) -> ScanViewpoint {
    ScanViewpoint {
        index: p.index,
        estimated: false,
        position: Some(p.position),
        residual: None,
        support: None,
        points,
    }
}

/// Points per scan slot.
fn scan_counts(cloud: &PointCloud) -> Vec<u64> {
    let mut counts = vec![0u64; cloud.scan_ids.len()];
    count_scans(&mut counts, &cloud.scan);
    counts
}

/// Adds the points of `scan` (slots) to `counts`, for clouds read in pieces.
pub(crate) fn count_scans(counts: &mut [u64], scan: &[u16]) {
    for &s in scan {
        if let Some(c) = counts.get_mut(s as usize) {
            *c += 1;
        }
    }
}

/// Locates every scan without a (finite) pose from its own points.
fn estimate_static(
    cloud: &PointCloud,
    poses: Option<&Vec<ScanPose>>,
    counts: &[u64],
    params: &ViewpointsParams,
) -> Estimate {
    let slots = cloud.scan_ids.len();
    let known = |slot: usize| {
        poses
            .and_then(|p| p.get(slot))
            .filter(|p| finite(p.position))
    };
    let unknown: Vec<bool> = (0..slots).map(|s| known(s).is_none()).collect();
    let thinned = thin_scans(
        &cloud.scan,
        &cloud.xyz,
        counts,
        &unknown,
        params.max_points_per_scan,
    );
    let cones: Vec<Option<cone::Cone>> = thinned
        .par_iter()
        .map(|t| cone::locate(t, &cone::ConeParams::default()))
        .collect();
    let mut out = Vec::with_capacity(slots);
    let mut scans = Vec::with_capacity(slots);
    for (slot, cone) in cones.into_iter().enumerate() {
        let index = cloud.scan_ids[slot];
        let points = counts.get(slot).copied().unwrap_or(0);
        if let Some(p) = known(slot) {
            out.push(*p);
            scans.push(given(p, points));
            continue;
        }
        let position = cone.map(|c| c.apex).unwrap_or([f64::NAN; 3]);
        out.push(ScanPose {
            index,
            position,
            quaternion: [1.0, 0.0, 0.0, 0.0],
        });
        scans.push(ScanViewpoint {
            index,
            estimated: true,
            position: cone.map(|c| c.apex),
            residual: cone.map(|c| c.residual),
            support: cone.map(|c| c.support as f64 / cone::ConeParams::default().sectors as f64),
            points,
        });
    }
    let any_given = scans.iter().any(|s| !s.estimated);
    let located = scans.iter().filter(|s| s.position.is_some()).count();
    if located == 0 {
        // Nothing to see from: plan on geometry (and open space) instead.
        return Estimate {
            viewpoints: None,
            report: ViewpointsReport {
                scans,
                ..Default::default()
            },
        };
    }
    Estimate {
        viewpoints: Some(Viewpoints::Static(out)),
        report: ViewpointsReport {
            source: if any_given {
                ViewpointSource::Mixed
            } else {
                ViewpointSource::Estimated
            },
            scans,
            ..Default::default()
        },
    }
}

/// The fewest points in a part of [`thin_scans`].
const THIN_PART: usize = 1 << 20;

/// An even subsample of at most `cap` points (at least 2) of each scan slot `wanted` says:
/// every `stride`-th point of the slot in cloud order from its first, the stride the least
/// power of two that leaves no more than `cap`. That is what keeping every point, and every
/// other one whenever the slot fills, keeps as the points arrive; here the slots' `counts`
/// give the strides up front, so the cloud is read in parts on all cores, each part starting
/// from how many points of each slot came before it.
fn thin_scans(
    scan: &[u16],
    xyz: &[[f32; 3]],
    counts: &[u64],
    wanted: &[bool],
    cap: usize,
) -> Vec<Vec<[f32; 3]>> {
    let (slots, cap) = (counts.len(), cap.max(2) as u64);
    let stride: Vec<u64> = counts
        .iter()
        .map(|&n| {
            let mut s = 1u64;
            while n.div_ceil(s) > cap {
                s *= 2;
            }
            s
        })
        .collect();
    let wanted = |s: usize| s < slots && wanted.get(s).copied().unwrap_or(false);
    // A few parts a core, so that the parts' counts (a number a slot each) stay small however
    // many scans there are.
    let n = scan.len().min(xyz.len());
    let part = THIN_PART.max(n.div_ceil(4 * rayon::current_num_threads().max(1)));
    let parts: Vec<Range<usize>> = (0..n).step_by(part).map(|s| s..(s + part).min(n)).collect();
    let part_counts: Vec<Vec<u64>> = parts
        .par_iter()
        .map(|r| {
            let mut c = vec![0u64; slots];
            count_scans(&mut c, &scan[r.clone()]);
            c
        })
        .collect();
    // Each part's place in every slot's order: the slot's points in the parts before it.
    let mut before = vec![0u64; slots];
    let starts: Vec<Vec<u64>> = part_counts
        .iter()
        .map(|c| {
            let start = before.clone();
            before.iter_mut().zip(c).for_each(|(b, n)| *b += n);
            start
        })
        .collect();
    let kept: Vec<Vec<Vec<[f32; 3]>>> = parts
        .par_iter()
        .zip(starts)
        .map(|(r, mut order)| {
            let mut out = vec![Vec::new(); slots];
            for k in r.clone() {
                let s = scan[k] as usize;
                if !wanted(s) {
                    continue;
                }
                // A power of two: a mask says what a division would.
                if order[s] & (stride[s] - 1) == 0 {
                    out[s].push(xyz[k]);
                }
                order[s] += 1;
            }
            out
        })
        .collect();
    let mut thinned = vec![Vec::new(); slots];
    for part in kept {
        thinned.iter_mut().zip(part).for_each(|(t, p)| t.extend(p));
    }
    thinned
}

/// Notes for the user: where the viewpoints came from when they were not all given, and how
/// much of the plan rests on them.
pub fn describe(report: &ViewpointsReport) -> Vec<String> {
    let mut notes = Vec::new();
    let share = report
        .rests_on
        .map(|f| format!("{:.0} % of the open area", 100.0 * f))
        .unwrap_or_else(|| "none of the open area".into());
    match report.source {
        ViewpointSource::Given => return notes,
        ViewpointSource::Estimated | ViewpointSource::Mixed if !report.scans.is_empty() => {
            let est: Vec<&ScanViewpoint> = report.scans.iter().filter(|s| s.estimated).collect();
            let located: Vec<&ScanViewpoint> = est
                .iter()
                .copied()
                .filter(|s| s.position.is_some())
                .collect();
            let mut res: Vec<f64> = located.iter().filter_map(|s| s.residual).collect();
            res.sort_by(f64::total_cmp);
            let median = res.get(res.len() / 2).copied().unwrap_or(0.0);
            notes.push(format!(
                "no scanner pose was given for {} of {} scans: {} were located from the blind spot under the scanner (median residual {:.1} cm) and are used as poses",
                est.len(),
                report.scans.len(),
                located.len(),
                100.0 * median
            ));
            let lost: Vec<String> = est
                .iter()
                .filter(|s| s.position.is_none())
                .map(|s| s.index.to_string())
                .collect();
            if !lost.is_empty() {
                notes.push(format!(
                    "scans {} could not be located: their points give no line of sight",
                    lost.join(", ")
                ));
            }
            notes.push(format!(
                "{share} was forced inside by lines of sight from these viewpoints; the rest was labelled from the wall geometry"
            ));
        }
        ViewpointSource::Estimated => {
            if let Some(p) = &report.path {
                notes.push(format!(
                    "no trajectory was given: the mobile scanner's path was estimated from the points' times ({} of {} time windows located, {:.1} m long) and is used as the trajectory",
                    p.located,
                    p.windows,
                    p.length.unwrap_or(0.0)
                ));
                notes.push(format!(
                    "{share} was forced inside by lines of sight from the estimated path; the rest was labelled from the wall geometry"
                ));
            }
        }
        ViewpointSource::OpenSpace => {
            let placed: usize = report.open_space.iter().map(|s| s.viewpoints.len()).sum();
            let given = match (&report.path, report.scans.len()) {
                (Some(p), _) if p.estimated => format!(
                    "no trajectory was given: the mobile scanner's path was estimated from the points' times ({} of {} time windows located, {:.1} m long) and is reported but not used, since lines of sight from it cut walls where the scanner turned unseen; instead",
                    p.located,
                    p.windows,
                    p.length.unwrap_or(0.0)
                ),
                (_, 0) => "no scanner poses, scan ids or times were given".to_string(),
                (_, n) => format!(
                    "no scanner pose was given and none of the {n} scans could be located from the blind spot under the scanner"
                ),
            };
            notes.push(format!(
                "{given}: {placed} pseudo-viewpoints were placed in the open space the wall samples enclose (far from every wall, where floor or ceiling points were scanned) and used as scanner positions"
            ));
            notes.push(format!(
                "{share} was forced inside by lines of sight from these pseudo-viewpoints; the rest was labelled from the wall geometry"
            ));
        }
        ViewpointSource::None | ViewpointSource::Mixed => {
            notes.push(
                "no scanner poses were given and none could be estimated: the plan rests on the wall geometry alone"
                    .into(),
            );
        }
    }
    notes
}

/// Trajectory samples from positions at times, as a mobile path.
pub(crate) fn trajectory(points: &[(f64, [f64; 3])]) -> Vec<TrajectorySample> {
    points
        .iter()
        .map(|&(t, position)| TrajectorySample {
            t,
            position,
            quaternion: [1.0, 0.0, 0.0, 0.0],
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_estimated_path_set_aside_for_open_space_is_said_so() {
        let report = ViewpointsReport {
            source: ViewpointSource::OpenSpace,
            path: Some(PathReport {
                estimated: true,
                samples: 10,
                windows: 12,
                located: 10,
                residual: Some(0.01),
                length: Some(42.0),
                positions: Vec::new(),
            }),
            open_space: vec![OpenSpaceStory {
                level: 0,
                viewpoints: vec![[1.0, 1.0], [4.0, 1.0]],
                samples_seen: 5,
                samples: 5,
            }],
            rests_on: Some(0.9),
            ..Default::default()
        };
        let notes = describe(&report).join("\n");
        assert!(
            notes.contains("estimated from the points' times (10 of 12"),
            "{notes}"
        );
        assert!(notes.contains("reported but not used"), "{notes}");
        assert!(notes.contains("2 pseudo-viewpoints were placed"), "{notes}");
        assert!(!notes.contains("used as the trajectory"), "{notes}");
    }

    /// An even subsample of at most `cap` items per slot, whatever order the items arrive in:
    /// when a slot is full, every other item is dropped and the slot keeps every second item
    /// from then on.
    struct Thinned<T> {
        cap: usize,
        slots: Vec<ThinSlot<T>>,
    }

    struct ThinSlot<T> {
        stride: u64,
        seen: u64,
        items: Vec<T>,
    }

    impl<T> Thinned<T> {
        fn new(cap: usize, slots: usize) -> Thinned<T> {
            Thinned {
                cap: cap.max(2),
                slots: (0..slots)
                    .map(|_| ThinSlot {
                        stride: 1,
                        seen: 0,
                        items: Vec::new(),
                    })
                    .collect(),
            }
        }

        fn push(&mut self, slot: usize, item: T) {
            let cap = self.cap;
            let Some(s) = self.slots.get_mut(slot) else {
                return;
            };
            // The stride is a power of two: a mask says what a division would, at a fraction of
            // its cost (this runs for every point of a cloud).
            if s.seen & (s.stride - 1) == 0 {
                if s.items.len() == cap {
                    let mut k = 0;
                    s.items.retain(|_| {
                        k += 1;
                        k % 2 == 1
                    });
                    s.stride *= 2;
                }
                if s.seen & (s.stride - 1) == 0 {
                    s.items.push(item);
                }
            }
            s.seen += 1;
        }
    }

    #[test]
    fn thinning_keeps_an_even_subsample() {
        let mut t = Thinned::new(10, 2);
        for k in 0..100u32 {
            t.push(0, k);
        }
        t.push(1, 7);
        t.push(5, 1);
        // 100 items into 10 places: every 16th, from the first.
        assert_eq!(t.slots[0].items, vec![0, 16, 32, 48, 64, 80, 96]);
        assert_eq!(t.slots[1].items, vec![7]);
    }

    #[test]
    fn thinning_in_parts_keeps_what_thinning_as_the_points_arrive_keeps() {
        // Scans interleaved in runs, across several parts; slot 2 not wanted, slot 9 unknown.
        let n = 3 * THIN_PART + 12_345;
        let scan: Vec<u16> = (0..n)
            .map(|k| match (k / 1000) % 7 {
                0 | 3 => 0,
                1 | 5 => 1,
                2 => 2,
                4 => 3,
                _ => 9,
            })
            .collect();
        let xyz: Vec<[f32; 3]> = (0..n).map(|k| [k as f32, 0.0, 0.0]).collect();
        let wanted = [true, true, false, true];
        let mut counts = vec![0u64; 4];
        count_scans(&mut counts, &scan);
        for cap in [2, 1000, 20_000, 10_000_000] {
            let mut reference = Thinned::new(cap, 4);
            for (&s, p) in scan.iter().zip(&xyz) {
                if wanted.get(s as usize).copied().unwrap_or(false) {
                    reference.push(s as usize, *p);
                }
            }
            let thinned = thin_scans(&scan, &xyz, &counts, &wanted, cap);
            assert_eq!(thinned.len(), 4);
            for (slot, t) in thinned.iter().enumerate() {
                assert_eq!(t, &reference.slots[slot].items, "cap {cap}, slot {slot}");
                assert!(t.len() <= cap.max(2));
            }
            assert!(thinned[2].is_empty());
            assert!(!thinned[0].is_empty());
        }
    }

    #[test]
    fn given_poses_are_reported_as_given() {
        let cloud = PointCloud {
            xyz: vec![[0.0; 3]; 3],
            scan: vec![0, 0, 1],
            scan_ids: vec![4, 9],
            viewpoints: Viewpoints::Static(vec![
                ScanPose {
                    index: 4,
                    position: [1.0, 2.0, 1.5],
                    quaternion: [1.0, 0.0, 0.0, 0.0],
                },
                ScanPose {
                    index: 9,
                    position: [3.0, 2.0, 1.5],
                    quaternion: [1.0, 0.0, 0.0, 0.0],
                },
            ]),
            ..Default::default()
        };
        let e = estimate(&cloud, &ViewpointsParams::default());
        assert_eq!(e.viewpoints, None);
        assert_eq!(e.report.source, ViewpointSource::Given);
        assert_eq!(e.report.scans.len(), 2);
        assert_eq!(e.report.scans[0].points, 2);
        assert_eq!(e.report.scans[1].position, Some([3.0, 2.0, 1.5]));
        assert!(!e.report.scans[1].estimated);
    }

    #[test]
    fn scans_without_poses_are_located() {
        let at = [[2.0, 2.0], [5.5, 3.5]];
        let mut cloud = PointCloud::default();
        for (k, a) in at.iter().enumerate() {
            let pts = cone::tests::scan_room(*a, -55.0);
            cloud.scan.extend(std::iter::repeat_n(k as u16, pts.len()));
            cloud.xyz.extend(pts);
        }
        cloud.scan_ids = vec![10, 11];
        let e = estimate(&cloud, &ViewpointsParams::default());
        assert_eq!(e.report.source, ViewpointSource::Estimated);
        let Some(Viewpoints::Static(poses)) = &e.viewpoints else {
            panic!("no poses: {e:?}")
        };
        for (p, a) in poses.iter().zip(at) {
            let err = crate::geom::dist([p.position[0], p.position[1]], a);
            assert!(err < 0.02, "{err}");
        }
        assert_eq!(poses[1].index, 11);
        assert!(e
            .report
            .scans
            .iter()
            .all(|s| s.estimated && s.residual.unwrap() < 0.02));
        // Switched off: nothing is estimated.
        let off = ViewpointsParams {
            estimate: false,
            ..Default::default()
        };
        assert_eq!(estimate(&cloud, &off).viewpoints, None);
    }

    #[test]
    fn a_path_is_thinned_to_steps_keeping_its_ends() {
        // 10 m walked in 1 cm steps, then standing still, then a NaN.
        let walk = (0..=1000).map(|k| [k as f64 * 0.01, 2.0, 1.5]);
        let still = std::iter::repeat_n([10.0, 2.0, 1.5], 50);
        let bad = std::iter::once([f64::NAN, 0.0, 0.0]);
        let kept = thin_path(walk.chain(still).chain(bad));
        assert!(
            (39..=42).contains(&kept.len()),
            "every 25 cm over 10 m: {}",
            kept.len()
        );
        assert_eq!(kept[0], [0.0, 2.0, 1.5]);
        assert_eq!(*kept.last().unwrap(), [10.0, 2.0, 1.5]);
        assert!(kept
            .windows(2)
            .all(|w| (w[1][0] - w[0][0]) >= PATH_STEP - 1e-9));
        // A very long path stays within the cap, ends included.
        let long = thin_path((0..=100_000).map(|k| [k as f64 * 0.3, 0.0, 0.0]));
        assert!(long.len() <= MAX_PATH_POSITIONS, "{}", long.len());
        assert_eq!(long[0][0], 0.0);
        assert_eq!(long.last().unwrap()[0], 30_000.0);
        assert!(thin_path(std::iter::empty()).is_empty());
    }
}
