//! The front door: a scan file and its sidecar in, the floor plan with every stage's time out.
//! The CLI (in memory and streamed) and the service's worker call [`plan_scan`] and nothing
//! else, so the point limit, the sidecar's size cap and scale, and the units check hold for all.

use std::path::Path;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::{Duration, Instant};

use crate::cancel::Cancelled;
use crate::cloud::{PointCloud, Viewpoints};
use crate::georef::Georeference;
use crate::io::{self, BytesRead, ReadError, ReadOptions, SidecarKind, UnitsError};
use crate::params::Params;
use crate::pipeline::{self, PlanError};
use crate::plan::FloorPlan;
use crate::progress::{Progress, Stage};
use crate::streaming::{self, StreamReport, StreamingError, StreamingParams};

/// What to plan and how.
#[derive(Debug, Clone)]
pub struct Scan<'a> {
    /// The point cloud file (any format [`io::detect`] knows).
    pub cloud: &'a Path,
    /// The sidecar file beside it, if any.
    pub sidecar: Option<(SidecarKind, &'a Path)>,
    /// How to read the cloud; its `cancel` is replaced by the progress's.
    pub read: ReadOptions,
    /// Every stage's parameters.
    pub params: &'a Params,
    /// Stream the file within this budget instead of holding it whole (`plan --max-memory`).
    pub stream: Option<StreamingParams>,
    /// Clouds with more points are refused, from their header when it tells.
    pub max_points: Option<u64>,
    /// Where the scan lies on the earth, given or overriding what the file declares; checked
    /// with [`Georeference::check`] before the run.
    pub georeference: Option<Georeference>,
}

/// A finished run.
#[derive(Debug, Clone)]
pub struct Planned {
    /// `timings_ms` starts with `read` and ends with `total`, which counts the read.
    pub plan: FloorPlan,
    /// How the streamed run went, when it was streamed.
    pub streamed: Option<StreamReport>,
}

/// Why a scan could not be planned.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The cloud or its sidecar could not be read (the message names the file).
    #[error(transparent)]
    Read(#[from] ReadError),
    /// The cloud has more points than [`Scan::max_points`] allows.
    #[error("the cloud has {points} points, more than the limit of {max}")]
    TooManyPoints {
        /// Points in the cloud (from its header when it tells; streamed, those read when the
        /// count passed the limit).
        points: u64,
        /// The limit.
        max: u64,
    },
    /// The coordinates are not in metres (see [`crate::io::check_units`]).
    #[error(transparent)]
    Units(#[from] UnitsError),
    /// A stage failed.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The streamed run's own failures (tile files, the memory budget).
    #[error(transparent)]
    Streaming(StreamingError),
}

impl RunError {
    /// A stable machine-readable code for the service's error bodies.
    pub fn code(&self) -> &'static str {
        match self {
            RunError::Read(e) => e.code(),
            RunError::TooManyPoints { .. } => "too_many_points",
            RunError::Units(_) => "wrong_units",
            RunError::Plan(e) => e.code(),
            RunError::Streaming(_) => "streaming_failed",
        }
    }

    /// Why the run was stopped from outside, if it was.
    pub fn cancelled(&self) -> Option<Cancelled> {
        match self {
            RunError::Read(ReadError::Cancelled(c, _)) => Some(*c),
            RunError::Plan(e) => e.cancelled(),
            _ => None,
        }
    }
}

impl From<StreamingError> for RunError {
    /// The streamed run's read, units and plan errors are the in-memory run's.
    fn from(e: StreamingError) -> RunError {
        match e {
            StreamingError::Read(e) => RunError::Read(e),
            StreamingError::Units(e) => RunError::Units(e),
            StreamingError::Plan(e) => RunError::Plan(e),
            StreamingError::TooManyPoints { points, max } => {
                RunError::TooManyPoints { points, max }
            }
            e => RunError::Streaming(e),
        }
    }
}

/// Reads the scan, plans it, and times every step, reading included.
///
/// ```
/// use asbuilt_plan::io::ply::{write_ply, Encoding};
/// use asbuilt_plan::io::ReadOptions;
/// use asbuilt_plan::progress::NoProgress;
/// use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
/// use asbuilt_plan::{plan_scan, Params, Scan};
///
/// // A simulated 6 m × 5 m room, written as a PLY file without its scanner poses.
/// let options = ScanOptions { points: 40_000, seed: 1, ..Default::default() };
/// let sim = simulate(BuildingKind::SquareRoom, &options).unwrap();
/// let path = std::env::temp_dir().join(format!("asbuilt-doc-{}.ply", std::process::id()));
/// write_ply(&path, &sim.cloud, Encoding::BinaryLittleEndian).unwrap();
///
/// let params = Params::default();
/// let scan = Scan {
///     cloud: &path,
///     sidecar: None,
///     read: ReadOptions::default(),
///     params: &params,
///     stream: None,
///     max_points: Some(1_000_000),
///     georeference: None,
/// };
/// let planned = plan_scan(&scan, &mut NoProgress).unwrap();
/// std::fs::remove_file(&path).unwrap();
/// assert_eq!(planned.plan.stories.len(), 1);
/// assert!(!planned.plan.stories[0].polygons.is_empty());
/// let steps: Vec<&str> = planned.plan.timings_ms.iter().map(|(k, _)| k.as_str()).collect();
/// assert_eq!((steps[0], *steps.last().unwrap()), ("read", "total"));
/// ```
pub fn plan_scan(scan: &Scan<'_>, progress: &mut dyn Progress) -> Result<Planned, RunError> {
    progress.report(Stage::Read, 0.0);
    let start = Instant::now();
    let read = ReadOptions {
        cancel: progress.cancel(),
        bytes: BytesRead::counting(),
        ..scan.read.clone()
    };
    if let Some(max) = scan.max_points {
        // Refuse an over-limit cloud before the reader allocates it.
        let declared = io::declared_points(scan.cloud, &read.cancel)
            .map_err(|c| ReadError::Cancelled(c, scan.cloud.display().to_string()))?;
        check_points(declared.unwrap_or(0), max)?;
    }
    let planned = match &scan.stream {
        None => {
            let total = std::fs::metadata(scan.cloud).map_or(0, |m| m.len());
            let cloud = read_reporting(
                || io::read_scan(scan.cloud, scan.sidecar, &read),
                &read.bytes,
                total,
                progress,
            )?;
            plan_in_memory(scan, cloud, start, progress)?
        }
        Some(stream) => {
            let sidecar = scan
                .sidecar
                .map(|(kind, path)| io::sidecar::read_scaled(kind, path, read.scale))
                .transpose()?;
            let sidecar_ms = ms(start);
            let stream = StreamingParams {
                max_points: scan.max_points,
                ..stream.clone()
            };
            let (mut plan, report) =
                streaming::plan_file(scan.cloud, &read, sidecar, scan.params, &stream, progress)
                    .map_err(|e| match (e, scan.sidecar) {
                        // A sidecar that does not fit the cloud is named, as in memory.
                        (StreamingError::Poses(e), Some((_, path))) => {
                            RunError::Read(io::sidecar::misfit(path, e))
                        }
                        (e, _) => RunError::from(e),
                    })?;
            add_time(&mut plan, Stage::Read.name(), sidecar_ms);
            Planned {
                plan,
                streamed: Some(report),
            }
        }
    };
    Ok(finish(scan, planned, read.scale))
}

/// Plans a cloud read before the run began, from the bytes of `scan.cloud` as they arrived (the
/// service decodes an upload while it streams in). The sidecar is attached here, and the point
/// limit, the units check and the notes are [`plan_scan`]'s, so the plan is the one
/// [`plan_scan`] makes of the file. `read_ms` is what the read took after the last byte came;
/// `scan.stream` is ignored (the cloud is already whole).
pub fn plan_decoded(
    scan: &Scan<'_>,
    mut cloud: PointCloud,
    read_ms: u64,
    progress: &mut dyn Progress,
) -> Result<Planned, RunError> {
    progress.report(Stage::Read, 0.0);
    let start = Instant::now()
        .checked_sub(Duration::from_millis(read_ms))
        .unwrap_or_else(Instant::now);
    if let Some((kind, file)) = scan.sidecar {
        io::sidecar::read_scaled(kind, file, scan.read.scale)?
            .attach(&mut cloud)
            .map_err(|e| io::sidecar::misfit(file, e))?;
    }
    let planned = plan_in_memory(scan, cloud, start, progress)?;
    Ok(finish(scan, planned, scan.read.scale))
}

/// The in-memory run after the read: the point limit, the units check, the stages.
fn plan_in_memory(
    scan: &Scan<'_>,
    mut cloud: PointCloud,
    start: Instant,
    progress: &mut dyn Progress,
) -> Result<Planned, RunError> {
    // Only a trajectory, or a path estimated for a single moving scanner, reads the points'
    // times; the scans of a merged static survey need none of their 8 bytes a point.
    if !cloud.is_mobile() && !matches!(cloud.viewpoints, Viewpoints::Trajectory(_)) {
        cloud.time = Vec::new();
    }
    if let Some(max) = scan.max_points {
        check_points(cloud.len() as u64, max)?;
    }
    io::check_units(&cloud)?;
    let read_ms = ms(start);
    progress.cancel().check().map_err(PlanError::from)?;
    let mut plan = pipeline::plan(&cloud, scan.params, progress)?;
    add_time(&mut plan, Stage::Read.name(), read_ms);
    Ok(Planned {
        plan,
        streamed: None,
    })
}

/// The notes every run adds: the scale, the given georeference.
fn finish(scan: &Scan<'_>, mut planned: Planned, scale: Option<f64>) -> Planned {
    if let Some(s) = scale {
        planned
            .plan
            .notes
            .push(format!("input coordinates were multiplied by {s}"));
    }
    if let Some(g) = &scan.georeference {
        if let Some(crs) = &planned.plan.crs {
            let short: String = crs.chars().take(60).collect();
            planned.plan.notes.push(format!(
                "the given georeference replaces the CRS the scan declares ({short})"
            ));
        }
        planned.plan.georeference = Some(g.clone());
    }
    planned
}

/// How often the bytes read are passed on: often enough for a moving bar, rarely enough to
/// cost nothing.
const READ_REPORT_EVERY: Duration = Duration::from_millis(200);

/// Runs `read` on a thread of its own, passing the bytes it has read (of `total`) to
/// `progress` every [`READ_REPORT_EVERY`] and once at the end. A panic in `read` is passed on.
fn read_reporting<T: Send>(
    read: impl FnOnce() -> T + Send,
    bytes: &BytesRead,
    total: u64,
    progress: &mut dyn Progress,
) -> T {
    // The readers that decode on this thread (PLY) get the stack a main thread has.
    const STACK: usize = 8 << 20;
    std::thread::scope(|s| {
        let (done, finished) = mpsc::channel::<()>();
        let reader = std::thread::Builder::new()
            .name("asbuilt-read-scan".into())
            .stack_size(STACK)
            .spawn_scoped(s, move || {
                let out = read();
                let _ = done.send(());
                out
            })
            .expect("a thread for the read");
        progress.read(0, total);
        // A timeout reports; a message (or a panic, which drops the sender) ends the wait.
        while let Err(RecvTimeoutError::Timeout) = finished.recv_timeout(READ_REPORT_EVERY) {
            progress.read(bytes.get().min(total), total);
        }
        let out = reader
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        progress.read(bytes.get().min(total), total);
        out
    })
}

fn check_points(points: u64, max: u64) -> Result<(), RunError> {
    match points > max {
        true => Err(RunError::TooManyPoints { points, max }),
        false => Ok(()),
    }
}

fn ms(since: Instant) -> u64 {
    since.elapsed().as_millis() as u64
}

/// Adds `ms` to the stage `name` (first in `timings_ms` when new) and to the total.
fn add_time(plan: &mut FloorPlan, name: &str, ms: u64) {
    match plan.timings_ms.iter_mut().find(|(n, _)| n == name) {
        Some((_, t)) => *t += ms,
        None => plan.timings_ms.insert(0, (name.to_string(), ms)),
    }
    if let Some((_, total)) = plan.timings_ms.iter_mut().find(|(n, _)| n == "total") {
        *total += ms;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::NoProgress;

    fn plan_with(timings: Vec<(&str, u64)>) -> FloorPlan {
        FloorPlan {
            origin: [0.0; 3],
            crs: None,
            georeference: None,
            input: Default::default(),
            parameters: serde_json::json!({}),
            timings_ms: timings.into_iter().map(|(n, t)| (n.into(), t)).collect(),
            stories: vec![],
            notes: vec![],
        }
    }

    /// Records the read and story reports.
    #[derive(Default)]
    struct Recorded {
        reads: Vec<(u64, u64)>,
        stories: Vec<(usize, usize)>,
    }

    impl Progress for Recorded {
        fn report(&mut self, _: Stage, _: f64) {}
        fn read(&mut self, bytes: u64, total: u64) {
            self.reads.push((bytes, total));
        }
        fn story(&mut self, number: usize, count: usize) {
            self.stories.push((number, count));
        }
    }

    /// A simulated 60,000-point square room written as binary PLY in `dir`.
    fn square_room_ply(dir: &Path, seed: u64) -> std::path::PathBuf {
        use crate::simulate::{simulate, BuildingKind, ScanOptions};
        let options = ScanOptions {
            points: 60_000,
            seed,
            ..Default::default()
        };
        let sim = simulate(BuildingKind::SquareRoom, &options).unwrap();
        let path = dir.join("room.ply");
        io::ply::write_ply(&path, &sim.cloud, io::ply::Encoding::BinaryLittleEndian).unwrap();
        path
    }

    #[test]
    fn a_cloud_decoded_beforehand_gives_the_files_plan() {
        let dir = tempfile::tempdir().unwrap();
        let path = square_room_ply(dir.path(), 5);
        let params = Params::default();
        let scan = Scan {
            cloud: &path,
            sidecar: None,
            read: ReadOptions::default(),
            params: &params,
            stream: None,
            max_points: Some(1_000_000),
            georeference: None,
        };
        let untimed = |mut plan: FloorPlan| {
            plan.timings_ms.clear();
            crate::io::geojson::to_geojson_string(&plan)
        };
        let from_file = plan_scan(&scan, &mut NoProgress).unwrap().plan;
        let cloud = io::read_cloud(&path).unwrap();
        let decoded = plan_decoded(&scan, cloud.clone(), 7, &mut NoProgress).unwrap();
        assert!(decoded
            .plan
            .timings_ms
            .iter()
            .any(|(n, t)| n == "read" && *t >= 7));
        assert_eq!(untimed(decoded.plan), untimed(from_file));
        // The limit holds for a decoded cloud too.
        let small = Scan {
            max_points: Some(10),
            ..scan.clone()
        };
        let refused = plan_decoded(&small, cloud, 0, &mut NoProgress).unwrap_err();
        assert_eq!(refused.code(), "too_many_points");
    }

    #[test]
    fn reading_reports_its_bytes_and_each_story_its_number() {
        let dir = tempfile::tempdir().unwrap();
        let path = square_room_ply(dir.path(), 3);
        let total = std::fs::metadata(&path).unwrap().len();
        let params = Params::default();
        let scan = Scan {
            cloud: &path,
            sidecar: None,
            read: ReadOptions::default(),
            params: &params,
            stream: None,
            max_points: None,
            georeference: None,
        };
        let mut seen = Recorded::default();
        let planned = plan_scan(&scan, &mut seen).unwrap();
        assert_eq!(seen.reads.first(), Some(&(0, total)));
        assert_eq!(seen.reads.last(), Some(&(total, total)), "{:?}", seen.reads);
        assert!(seen.reads.windows(2).all(|w| w[0].0 <= w[1].0));
        assert_eq!(seen.stories, vec![(1, 1)]);
        // The story's underlay: walls in the slice are dark, the floor inside pale.
        let story = &planned.plan.stories[0];
        let u = story.underlay.as_ref().expect("an underlay");
        assert!(u.slice_z[0] > story.floor_z && u.slice_z[1] < story.ceiling_z);
        let dark = u.levels.iter().filter(|&&l| l >= 128).count();
        let pale = u.levels.iter().filter(|&&l| l == 1).count();
        assert!(dark > 100 && pale > 10 * dark, "dark {dark}, pale {pale}");
    }

    #[test]
    fn read_time_leads_and_counts_in_the_total() {
        let mut plan = plan_with(vec![("stories", 4), ("total", 10)]);
        add_time(&mut plan, "read", 7);
        assert_eq!(plan.timings_ms[0], ("read".to_string(), 7));
        assert_eq!(plan.timings_ms[2], ("total".to_string(), 17));
        // A streamed run timed its reading already: the sidecar's time is added to it.
        add_time(&mut plan, "read", 3);
        assert_eq!(plan.timings_ms[0], ("read".to_string(), 10));
        assert_eq!(plan.timings_ms[2], ("total".to_string(), 20));
    }

    #[test]
    fn limits_and_units_hold_in_both_modes() {
        let dir = tempfile::tempdir().unwrap();
        // A 2 x 2 x 2.5 km box of points: millimetres read as metres.
        let world: Vec<[f64; 3]> = (0..2000)
            .map(|i| {
                [
                    (i % 2000) as f64,
                    ((i * 7) % 2000) as f64,
                    ((i * 13) % 2500) as f64,
                ]
            })
            .collect();
        let path = dir.path().join("mm.ply");
        let cloud = crate::cloud::PointCloud::from_world(&world);
        io::ply::write_ply(&path, &cloud, io::ply::Encoding::BinaryLittleEndian).unwrap();
        let params = Params::default();
        for stream in [None, Some(StreamingParams::default())] {
            let mut scan = Scan {
                cloud: &path,
                sidecar: None,
                read: ReadOptions::default(),
                params: &params,
                stream: stream.clone(),
                max_points: Some(1999),
                georeference: None,
            };
            let err = plan_scan(&scan, &mut NoProgress).unwrap_err();
            assert_eq!(err.code(), "too_many_points", "{err}");
            scan.max_points = Some(2000);
            let err = plan_scan(&scan, &mut NoProgress).unwrap_err();
            assert_eq!(err.code(), "wrong_units", "{err}");
        }
    }

    #[test]
    fn an_oversized_sidecar_is_refused_in_both_modes() {
        let dir = tempfile::tempdir().unwrap();
        let cloud = dir.path().join("c.xyz");
        std::fs::write(&cloud, "0 0 0\n1 1 1\n").unwrap();
        let poses = dir.path().join("p.json");
        let file = std::fs::File::create(&poses).unwrap();
        file.set_len(io::poses::MAX_POSES_BYTES + 1).unwrap();
        let params = Params::default();
        for stream in [None, Some(StreamingParams::default())] {
            let scan = Scan {
                cloud: &cloud,
                sidecar: Some((SidecarKind::Poses, &poses)),
                read: ReadOptions::default(),
                params: &params,
                stream,
                max_points: None,
                georeference: None,
            };
            let err = plan_scan(&scan, &mut NoProgress).unwrap_err();
            assert_eq!(err.code(), "invalid_poses", "{err}");
            assert!(err.to_string().contains("more than the"), "{err}");
        }
    }
}
