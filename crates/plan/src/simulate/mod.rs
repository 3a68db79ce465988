//! A scanner simulator: synthetic buildings with exact ground truth, scanned by static or mobile
//! scanners. Used by tests, benchmarks and `asbuilt simulate`.
//!
//! - `buildings.rs`: the buildings (walls, doors with lintels, windows, columns, tables) and
//!   their truth.
//! - `scanner.rs`: analytic ray casting against wall segments and arcs, floors and ceilings.
//! - `truth.rs`: the ground truth per story, exact lines and arcs.
//! - [`random`]: random buildings (rooms, corridors, closets, columns, bays, any rotation) for
//!   property tests, scanned with [`scan`].
//! - [`simulate`] scans a building: points, scan indices, poses or a trajectory, all in a local
//!   frame whose origin is the requested world offset.
//!
//! Every run is deterministic from its seed: each block of rays has its own ChaCha stream, so
//! the result does not depend on how rayon schedules the blocks.

pub(crate) mod buildings;
mod multilevel;
pub mod phone;
pub mod random;
pub(crate) mod rects;
pub(crate) mod rooms;
pub(crate) mod scanner;
pub(crate) mod truth;

use rand::Rng;
use rand_distr::Normal;
use rayon::prelude::*;

pub use buildings::{Building, BuildingKind};
pub use truth::{Truth, TruthDoor, TruthRoom, TruthStory, TruthWall, TruthWindow};

use crate::cloud::{PointCloud, ScanPose, SourceInfo, TrajectorySample, Viewpoints};
use crate::geom::{self, P2};
use buildings::StoryModel;

/// Static scanner heads stand this high above the floor.
pub const STATION_HEIGHT: f64 = 1.5;
/// A mobile scanner is carried this high above the floor.
pub const MOBILE_HEIGHT: f64 = 1.2;
/// Walking speed of the mobile scanner, m/s.
pub const MOBILE_SPEED: f64 = 1.0;
/// Trajectory samples per second.
pub const TRAJECTORY_RATE: f64 = 20.0;
/// Rays per random stream.
const BLOCK: usize = 4096;
/// At most this many points in one run (20 M is the largest the issue asks for).
pub const MAX_POINTS: usize = 200_000_000;

/// How to scan a building.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanOptions {
    /// Points to generate in total (rays that hit nothing are not replaced).
    pub points: usize,
    /// Seed of the random generator: the same seed gives the same cloud.
    pub seed: u64,
    /// Standard deviation of the range noise, metres.
    pub noise: f64,
    /// Per-scan registration error of static scans: a horizontal shift of this many metres in a
    /// random direction and a yaw of this many degrees (random sign) about the scanner.
    /// Scan 0 of each story is the reference and stays exact.
    pub registration: Option<(f64, f64)>,
    /// A mobile scanner walking the route instead of static stations.
    pub mobile: bool,
    /// World coordinates of the building's origin (a large value tests georeferenced input).
    pub offset: [f64; 3],
    /// Reduce the cloud to the centres of the occupied voxels of this size, metres, as an
    /// occupancy map or a downsampling tool does (each keeps its first point's scan and time).
    /// `None` keeps every point, unless the building is a voxelised class.
    pub voxel: Option<f64>,
    /// What the cloud keeps of how it was scanned.
    pub keep: Keep,
}

/// What a simulated cloud keeps of how it was scanned (the scanners stay in
/// [`Simulation::scanners`] either way).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Keep {
    /// Scan ids with their poses, or times with the trajectory.
    #[default]
    Poses,
    /// Scan ids or times, no poses or trajectory: a merged export.
    ScanIds,
    /// Plain x, y, z in shuffled order: no ids, no times, no order to find scans by.
    Plain,
}

impl Keep {
    /// Every mode, by its command-line name.
    pub const ALL: [(&'static str, Keep); 3] = [
        ("poses", Keep::Poses),
        ("scan-ids", Keep::ScanIds),
        ("plain", Keep::Plain),
    ];

    /// Looks a mode up by name.
    pub fn from_name(name: &str) -> Option<Keep> {
        Keep::ALL.iter().find(|(n, _)| *n == name).map(|(_, k)| *k)
    }
}

impl Default for ScanOptions {
    fn default() -> Self {
        ScanOptions {
            points: 1_000_000,
            seed: 1,
            noise: 0.0,
            registration: None,
            mobile: false,
            offset: [0.0; 3],
            voxel: None,
            keep: Keep::Poses,
        }
    }
}

/// Why a scan could not be simulated.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SimulateError {
    /// An option is outside its range.
    #[error("invalid simulation option `{name}`: {why}")]
    BadOption {
        /// The option's name.
        name: &'static str,
        /// What is wrong.
        why: String,
    },
}

/// A scanned building: the cloud (local frame, origin = offset, with poses or a trajectory
/// attached) and the ground truth (same frame).
#[derive(Debug, Clone)]
pub struct Simulation {
    /// The simulated scan.
    pub cloud: PointCloud,
    /// The ground truth, in the cloud's frame.
    pub truth: Truth,
    /// Where the scanners really were (poses or trajectory, local frame), whatever the cloud
    /// keeps.
    pub scanners: Viewpoints,
}

/// Builds `kind` and scans it.
pub fn simulate(kind: BuildingKind, options: &ScanOptions) -> Result<Simulation, SimulateError> {
    // A kind that stands for a voxelised cloud is voxelised unless the options say otherwise.
    let options = ScanOptions {
        voxel: options.voxel.or(kind.voxel()),
        ..options.clone()
    };
    scan(&kind.build(), &options)
}

/// Scans any building, named or not.
pub fn scan(building: &Building, options: &ScanOptions) -> Result<Simulation, SimulateError> {
    check(options)?;
    let mut cloud = if options.mobile {
        scan_mobile(building, options)
    } else {
        scan_static(building, options)
    };
    if let Some(size) = options.voxel {
        voxelize(&mut cloud, size);
    }
    cloud.origin = options.offset;
    cloud.source = SourceInfo {
        format: "memory".into(),
        details: format!(
            "simulated {}, {} scanner, seed {}",
            building.name,
            if options.mobile { "mobile" } else { "static" },
            options.seed
        ),
        skipped: 0,
        skipped_reason: None,
        units: "m".into(),
    };
    let truth = Truth {
        building: building.name.clone(),
        origin: options.offset,
        stories: building.stories.iter().map(|s| s.truth.clone()).collect(),
    };
    let scanners = cloud.viewpoints.clone();
    match options.keep {
        Keep::Poses => {}
        Keep::ScanIds => cloud.viewpoints = Viewpoints::None,
        Keep::Plain => {
            cloud.viewpoints = Viewpoints::None;
            cloud.scan = Vec::new();
            cloud.scan_ids = Vec::new();
            cloud.time = Vec::new();
            shuffle(&mut cloud.xyz, options.seed);
        }
    }
    Ok(Simulation {
        cloud,
        truth,
        scanners,
    })
}

/// Shuffles the points (Fisher-Yates, seeded), so their order tells nothing of the scans.
fn shuffle(xyz: &mut [[f32; 3]], seed: u64) {
    let mut rng = scanner::block_rng(seed, u64::MAX - 1);
    for i in (1..xyz.len()).rev() {
        let j = rng.random_range(0..=i);
        xyz.swap(i, j);
    }
}

fn check(o: &ScanOptions) -> Result<(), SimulateError> {
    let bad = |name, why: String| Err(SimulateError::BadOption { name, why });
    if o.points == 0 || o.points > MAX_POINTS {
        return bad(
            "points",
            format!("must be from 1 to {MAX_POINTS}, not {}", o.points),
        );
    }
    if !(o.noise.is_finite() && (0.0..=1.0).contains(&o.noise)) {
        return bad("noise", format!("must be from 0 to 1 m, not {}", o.noise));
    }
    if let Some((t, r)) = o.registration {
        if !(t.is_finite()
            && (0.0..=1.0).contains(&t)
            && r.is_finite()
            && (0.0..=10.0).contains(&r))
        {
            return bad(
                "registration_error",
                format!("must be 0-1 m and 0-10 degrees, not {t} m, {r} degrees"),
            );
        }
    }
    if let Some(v) = o.voxel {
        if !(v.is_finite() && (0.001..=1.0).contains(&v)) {
            return bad("voxel", format!("must be from 0.001 to 1 m, not {v}"));
        }
    }
    if !o.offset.iter().all(|c| c.is_finite() && c.abs() < 1.0e9) {
        return bad(
            "offset",
            format!("must be finite and below 1e9 m, not {:?}", o.offset),
        );
    }
    Ok(())
}

/// Replaces the points by the centres of the occupied cubes of a `size` grid, in the order each
/// cube was first hit; each centre keeps that first point's scan slot and time.
fn voxelize(cloud: &mut PointCloud, size: f64) {
    let mut seen = std::collections::HashSet::with_capacity(cloud.len() / 4);
    let key = |p: &[f32; 3]| p.map(|c| (c as f64 / size).floor() as i64);
    let mut keep = Vec::with_capacity(cloud.len() / 4);
    for (i, p) in cloud.xyz.iter().enumerate() {
        if seen.insert(key(p)) {
            keep.push(i);
        }
    }
    let xyz = keep
        .iter()
        .map(|&i| key(&cloud.xyz[i]).map(|k| ((k as f64 + 0.5) * size) as f32))
        .collect();
    cloud.xyz = xyz;
    if !cloud.scan.is_empty() {
        cloud.scan = keep.iter().map(|&i| cloud.scan[i]).collect();
    }
    if !cloud.time.is_empty() {
        cloud.time = keep.iter().map(|&i| cloud.time[i]).collect();
    }
}

/// A yaw rotation as a `[w, x, y, z]` quaternion.
fn yaw(angle: f64) -> [f64; 4] {
    [(angle / 2.0).cos(), 0.0, 0.0, (angle / 2.0).sin()]
}

struct Station<'a> {
    story: &'a StoryModel,
    position: [f64; 3],
    heading: f64,
    /// Registration error: yaw about the scanner, then a horizontal shift.
    error_yaw: f64,
    error_shift: P2,
    points: usize,
}

fn scan_static(building: &Building, o: &ScanOptions) -> PointCloud {
    let mut rng = scanner::block_rng(o.seed, u64::MAX);
    let total: usize = building.stories.iter().map(|s| s.stations.len()).sum();
    let mut stations = Vec::with_capacity(total);
    for story in &building.stories {
        for (k, xy) in story.stations.iter().enumerate() {
            let (error_yaw, error_shift) = match o.registration {
                Some((t, r)) if k > 0 => {
                    let dir: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                    (sign * r.to_radians(), [t * dir.cos(), t * dir.sin()])
                }
                _ => (0.0, [0.0, 0.0]),
            };
            let n = stations.len();
            stations.push(Station {
                story,
                position: [xy[0], xy[1], story.floor_z + STATION_HEIGHT],
                heading: rng.random_range(0.0..std::f64::consts::TAU),
                error_yaw,
                error_shift,
                points: o.points / total + usize::from(n < o.points % total),
            });
        }
    }
    let noise = (o.noise > 0.0).then(|| Normal::new(0.0, o.noise).expect("valid sigma"));
    let blocks: Vec<(usize, usize, usize)> = stations
        .iter()
        .enumerate()
        .flat_map(|(k, s)| {
            (0..s.points.div_ceil(BLOCK)).map(move |b| (k, b, BLOCK.min(s.points - b * BLOCK)))
        })
        .collect();
    let chunks: Vec<Vec<[f32; 3]>> = blocks
        .par_iter()
        .map(|&(k, b, n)| {
            let s = &stations[k];
            let mut rng = scanner::block_rng(o.seed, ((k as u64) << 32) | b as u64);
            let (sin, cos) = s.error_yaw.sin_cos();
            (0..n)
                .filter_map(|_| scanner::measure(s.story, s.position, &mut rng, noise.as_ref()))
                .filter(|p| {
                    s.story
                        .capture
                        .is_none_or(|c| c.keeps(*p, s.position, s.story.ceiling_z))
                })
                .map(|p| {
                    let v = [p[0] - s.position[0], p[1] - s.position[1]];
                    [
                        (s.position[0] + cos * v[0] - sin * v[1] + s.error_shift[0]) as f32,
                        (s.position[1] + sin * v[0] + cos * v[1] + s.error_shift[1]) as f32,
                        p[2] as f32,
                    ]
                })
                .collect()
        })
        .collect();
    let mut cloud = PointCloud::default();
    let len = chunks.iter().map(Vec::len).sum();
    cloud.xyz.reserve_exact(len);
    cloud.scan.reserve_exact(len);
    for (&(k, _, _), chunk) in blocks.iter().zip(chunks) {
        cloud
            .scan
            .extend(std::iter::repeat_n(k as u16, chunk.len()));
        cloud.xyz.extend(chunk);
    }
    cloud.scan_ids = (0..stations.len() as u32).collect();
    cloud.viewpoints = Viewpoints::Static(
        stations
            .iter()
            .enumerate()
            .map(|(k, s)| ScanPose {
                index: k as u32,
                position: [
                    s.position[0] + s.error_shift[0],
                    s.position[1] + s.error_shift[1],
                    s.position[2],
                ],
                quaternion: yaw(s.heading + s.error_yaw),
            })
            .collect(),
    );
    cloud
}

/// A story's route as (start time, duration) within the whole walk; stories follow each other
/// with a one-second pause on the stairs.
fn schedule(building: &Building) -> Vec<(f64, f64)> {
    let mut t = 0.0;
    building
        .stories
        .iter()
        .map(|s| {
            let d = route_length(&s.route) / MOBILE_SPEED;
            let slot = (t, d);
            t += d + 1.0;
            slot
        })
        .collect()
}

fn route_length(route: &[P2]) -> f64 {
    route.windows(2).map(|w| geom::dist(w[0], w[1])).sum()
}

/// The point `dist` metres along the route, and the heading there.
fn along(route: &[P2], dist: f64) -> (P2, f64) {
    let mut left = dist.max(0.0);
    for w in route.windows(2) {
        let len = geom::dist(w[0], w[1]);
        let heading = (w[1][1] - w[0][1]).atan2(w[1][0] - w[0][0]);
        if left <= len && len > 0.0 {
            return (
                geom::add(w[0], geom::scale(geom::sub(w[1], w[0]), left / len)),
                heading,
            );
        }
        left -= len;
    }
    let n = route.len();
    let heading = if n > 1 {
        (route[n - 1][1] - route[n - 2][1]).atan2(route[n - 1][0] - route[n - 2][0])
    } else {
        0.0
    };
    (route[n - 1], heading)
}

fn scan_mobile(building: &Building, o: &ScanOptions) -> PointCloud {
    let slots = schedule(building);
    let walk: f64 = slots.iter().map(|s| s.1).sum();
    let noise = (o.noise > 0.0).then(|| Normal::new(0.0, o.noise).expect("valid sigma"));
    // Points per story in proportion to the time spent there.
    let mut blocks = Vec::new();
    let mut assigned = 0;
    for (k, (story, &(t0, d))) in building.stories.iter().zip(&slots).enumerate() {
        let n = if k + 1 == slots.len() {
            o.points - assigned
        } else {
            ((o.points as f64) * d / walk).round() as usize
        };
        assigned += n;
        for b in 0..n.div_ceil(BLOCK) {
            blocks.push((k, story, t0, d, n, b));
        }
    }
    let chunks: Vec<(Vec<[f32; 3]>, Vec<f64>)> = blocks
        .par_iter()
        .map(|&(k, story, t0, d, n, b)| {
            let mut rng = scanner::block_rng(o.seed, ((k as u64) << 32) | b as u64);
            let mut xyz = Vec::with_capacity(BLOCK);
            let mut time = Vec::with_capacity(BLOCK);
            for i in b * BLOCK..((b + 1) * BLOCK).min(n) {
                let f = (i as f64 + 0.5) / n as f64;
                let (xy, _) = along(&story.route, f * d * MOBILE_SPEED);
                let origin = [xy[0], xy[1], story.floor_z + MOBILE_HEIGHT];
                let p = scanner::measure(story, origin, &mut rng, noise.as_ref()).filter(|p| {
                    story
                        .capture
                        .is_none_or(|c| c.keeps(*p, origin, story.ceiling_z))
                });
                if let Some(p) = p {
                    xyz.push(p.map(|c| c as f32));
                    time.push(t0 + f * d);
                }
            }
            (xyz, time)
        })
        .collect();
    let mut cloud = PointCloud::default();
    for (xyz, time) in chunks {
        cloud.xyz.extend(xyz);
        cloud.time.extend(time);
    }
    let mut samples = Vec::new();
    for (story, &(t0, d)) in building.stories.iter().zip(&slots) {
        let n = (d * TRAJECTORY_RATE).ceil().max(1.0) as usize;
        for i in 0..=n {
            let f = i as f64 / n as f64;
            let (xy, heading) = along(&story.route, f * d * MOBILE_SPEED);
            samples.push(TrajectorySample {
                t: t0 + f * d,
                position: [xy[0], xy[1], story.floor_z + MOBILE_HEIGHT],
                quaternion: yaw(heading),
            });
        }
    }
    cloud.viewpoints = Viewpoints::Trajectory(samples);
    cloud
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn static_scan_is_deterministic_and_on_the_surfaces() {
        let opts = ScanOptions {
            points: 20_000,
            seed: 7,
            ..Default::default()
        };
        let a = simulate(BuildingKind::SquareRoom, &opts).unwrap();
        let b = simulate(BuildingKind::SquareRoom, &opts).unwrap();
        assert_eq!(a.cloud.xyz, b.cloud.xyz);
        assert_eq!(a.cloud.len(), 20_000);
        a.cloud.check().unwrap();
        // Every point lies on a wall, the floor or the ceiling of the 6 × 5 × 2.6 room.
        for p in &a.cloud.xyz {
            let on = |v: f32, lo: f32, hi: f32| (v - lo).abs() < 1e-4 || (v - hi).abs() < 1e-4;
            assert!(
                on(p[0], 0.0, 6.0) || on(p[1], 0.0, 5.0) || on(p[2], 0.0, 2.6),
                "{p:?}"
            );
        }
        let c = simulate(BuildingKind::SquareRoom, &ScanOptions { seed: 8, ..opts }).unwrap();
        assert_ne!(a.cloud.xyz, c.cloud.xyz);
    }

    #[test]
    fn registration_error_moves_scans_rigidly() {
        let opts = ScanOptions {
            points: 30_000,
            registration: Some((0.05, 0.0)),
            ..Default::default()
        };
        let sim = simulate(BuildingKind::RotatedL, &opts).unwrap();
        let Viewpoints::Static(poses) = &sim.cloud.viewpoints else {
            panic!("no poses")
        };
        let station = BuildingKind::RotatedL.build().stories[0].stations[1];
        let moved = geom::dist([poses[1].position[0], poses[1].position[1]], station);
        assert!((moved - 0.05).abs() < 1e-9, "{moved}");
        assert_eq!(
            poses[0].position[0],
            BuildingKind::RotatedL.build().stories[0].stations[0][0]
        );
    }

    #[test]
    fn mobile_points_carry_times_within_the_trajectory() {
        let opts = ScanOptions {
            points: 10_000,
            mobile: true,
            offset: [500_000.0, 4_000_000.0, 100.0],
            ..Default::default()
        };
        let sim = simulate(BuildingKind::SquareRoom, &opts).unwrap();
        sim.cloud.check().unwrap();
        let Viewpoints::Trajectory(path) = &sim.cloud.viewpoints else {
            panic!("no path")
        };
        assert_eq!(sim.cloud.time.len(), sim.cloud.len());
        let (t0, t1) = (path[0].t, path[path.len() - 1].t);
        assert!((t1 - t0 - 10.0).abs() < 1e-9, "a 10 m loop at 1 m/s");
        assert!(sim.cloud.time.iter().all(|&t| t >= t0 && t <= t1));
        assert!(sim.cloud.time.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(sim.cloud.origin, opts.offset);
    }

    #[test]
    fn voxels_are_distinct_centres_keeping_their_first_scan() {
        let opts = ScanOptions {
            points: 20_000,
            voxel: Some(0.1),
            ..Default::default()
        };
        let sim = simulate(BuildingKind::SquareRoom, &opts).unwrap();
        sim.cloud.check().unwrap();
        assert!(sim.cloud.len() < 20_000);
        let keys: std::collections::HashSet<[i64; 3]> = sim
            .cloud
            .xyz
            .iter()
            .map(|p| {
                // Every coordinate is an odd multiple of 5 cm: a voxel centre.
                for c in p {
                    let k = (*c as f64 / 0.05).round();
                    assert!(
                        (*c as f64 - 0.05 * k).abs() < 1e-5 && k as i64 % 2 != 0,
                        "{p:?}"
                    );
                }
                p.map(|c| (c as f64 / 0.1).floor() as i64)
            })
            .collect();
        assert_eq!(keys.len(), sim.cloud.len(), "no voxel twice");
        assert_eq!(sim.cloud.scan.len(), sim.cloud.len());
        let bad = ScanOptions {
            voxel: Some(0.0),
            ..Default::default()
        };
        assert!(simulate(BuildingKind::SquareRoom, &bad).is_err());
    }

    #[test]
    fn a_ceiling_capture_records_nothing_low() {
        let opts = ScanOptions {
            points: 20_000,
            ..Default::default()
        };
        let sim = simulate(BuildingKind::CeilingOnly, &opts).unwrap();
        let low = rooms::CEILING_CAPTURE_ABOVE as f32;
        assert!(sim.cloud.xyz.iter().all(|p| p[2] >= low));
        assert!(sim.cloud.len() > 5_000);
        // Walls are seen lower in some places than in others.
        let wall = |p: &&[f32; 3]| p[2] < 3.0;
        let lowest = sim
            .cloud
            .xyz
            .iter()
            .filter(wall)
            .map(|p| p[2])
            .fold(9.0, f32::min);
        assert!(lowest < 1.6, "{lowest}");
        let Viewpoints::Static(poses) = &sim.scanners else {
            panic!("static poses")
        };
        // The ceiling is there only near the phone; nothing lies farther from it.
        let reach = |p: &[f32; 3]| {
            poses
                .iter()
                .map(|s| (p[0] as f64 - s.position[0]).hypot(p[1] as f64 - s.position[1]))
                .fold(f64::MAX, f64::min)
        };
        let ceiling: Vec<f64> = sim
            .cloud
            .xyz
            .iter()
            .filter(|p| p[2] > 3.95)
            .map(reach)
            .collect();
        assert!(ceiling.len() > 1_000);
        assert!(ceiling
            .iter()
            .all(|&d| d <= rooms::CEILING_CAPTURE_REACH + 1e-3));
        // The walls run on beyond it.
        assert!(sim.cloud.xyz.iter().filter(wall).any(|p| reach(p) > 4.0));
    }

    #[test]
    fn kept_modes_strip_what_they_should() {
        let opts = |keep| ScanOptions {
            points: 20_000,
            keep,
            ..Default::default()
        };
        let full = simulate(BuildingKind::RotatedL, &opts(Keep::Poses)).unwrap();
        let ids = simulate(BuildingKind::RotatedL, &opts(Keep::ScanIds)).unwrap();
        let plain = simulate(BuildingKind::RotatedL, &opts(Keep::Plain)).unwrap();
        assert!(matches!(full.cloud.viewpoints, Viewpoints::Static(_)));
        assert_eq!(full.scanners, full.cloud.viewpoints);
        assert_eq!(ids.cloud.viewpoints, Viewpoints::None);
        assert_eq!(ids.cloud.scan, full.cloud.scan);
        assert_eq!(ids.scanners, full.scanners);
        assert!(plain.cloud.scan.is_empty() && plain.cloud.scan_ids.is_empty());
        plain.cloud.check().unwrap();
        // The same points in another order.
        assert_ne!(plain.cloud.xyz, full.cloud.xyz);
        let key = |p: &[f32; 3]| p.map(f32::to_bits);
        let mut a: Vec<_> = plain.cloud.xyz.iter().map(key).collect();
        let mut b: Vec<_> = full.cloud.xyz.iter().map(key).collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b);
        let mobile = simulate(
            BuildingKind::SquareRoom,
            &ScanOptions {
                mobile: true,
                ..opts(Keep::ScanIds)
            },
        )
        .unwrap();
        assert_eq!(mobile.cloud.viewpoints, Viewpoints::None);
        assert_eq!(mobile.cloud.time.len(), mobile.cloud.len());
        assert!(matches!(mobile.scanners, Viewpoints::Trajectory(_)));
        assert_eq!(Keep::from_name("scan-ids"), Some(Keep::ScanIds));
    }

    #[test]
    fn bad_options_are_named() {
        let err = simulate(
            BuildingKind::SquareRoom,
            &ScanOptions {
                points: 0,
                ..Default::default()
            },
        );
        assert!(matches!(
            err,
            Err(SimulateError::BadOption { name: "points", .. })
        ));
        let err = simulate(
            BuildingKind::SquareRoom,
            &ScanOptions {
                noise: f64::NAN,
                ..Default::default()
            },
        );
        assert!(matches!(
            err,
            Err(SimulateError::BadOption { name: "noise", .. })
        ));
    }
}
