//! The streaming mode (`plan --max-memory`) gives the in-memory plan, and the chunked readers
//! give the whole-file readers' points.

use std::path::Path;

use asbuilt_plan::cloud::{PointCloud, ScanPose, Viewpoints};
use asbuilt_plan::io::Sidecar;
use asbuilt_plan::io::{self, chunks, export, ply, poses, ReadOptions};
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
use asbuilt_plan::streaming::{plan_file, StreamingError, StreamingParams};
use asbuilt_plan::{FloorPlan, Params};

/// A small three-story office, written as binary PLY, with its poses in world coordinates.
fn office(dir: &Path, points: usize) -> (PointCloud, Vec<ScanPose>) {
    let sim = simulate(
        BuildingKind::Office3Story,
        &ScanOptions {
            points,
            seed: 3,
            noise: 0.002,
            offset: [412_000.0, 5_300_000.0, 80.0],
            ..Default::default()
        },
    )
    .unwrap();
    let cloud = sim.cloud;
    ply::write_ply(
        &dir.join("cloud.ply"),
        &cloud,
        ply::Encoding::BinaryLittleEndian,
    )
    .unwrap();
    let Viewpoints::Static(local) = &cloud.viewpoints else {
        panic!("static scans have poses")
    };
    let world = local
        .iter()
        .map(|p| ScanPose {
            position: [0, 1, 2].map(|k| p.position[k] + cloud.origin[k]),
            ..*p
        })
        .collect();
    (cloud, world)
}

fn in_memory(path: &Path, world: &[ScanPose], params: &Params) -> FloorPlan {
    let mut cloud = io::read_cloud(path).unwrap();
    poses::attach_poses(&mut cloud, world.to_vec()).unwrap();
    asbuilt_plan::plan(&cloud, params, &mut NoProgress).unwrap()
}

/// The note a streamed plan carries: it holds no points to look for lintels over door gaps.
const NO_LINTELS: &str = "no points held to look for lintels";

/// `plan` as a streamed plan sees it: doors without lintel heights or jambs seen in the points
/// (their ends and widths are compared apart), and the note saying so.
fn without_lintels(plan: &FloorPlan) -> FloorPlan {
    let mut plan = plan.clone();
    plan.notes.retain(|n| !n.contains(NO_LINTELS));
    for story in &mut plan.stories {
        for door in &mut story.spaces.doors {
            door.head_z = None;
            door.a = [0.0; 2];
            door.b = [0.0; 2];
            door.width = 0.0;
        }
    }
    plan
}

/// Everything but the timings and what only the points can tell (lintel heights and the
/// jambs, which a streamed plan does not see and says so once per story with doors: its doors
/// run between the plan's faces, within a few centimetres of the jambs in the points).
fn assert_same_plan(a: &FloorPlan, b: &FloorPlan) {
    for (x, y) in a.stories.iter().zip(&b.stories) {
        assert_eq!(x.spaces.doors.len(), y.spaces.doors.len());
        for (d, e) in x.spaces.doors.iter().zip(&y.spaces.doors) {
            assert!((d.width - e.width).abs() <= 0.3, "{d:?} {e:?}");
            let mid =
                |d: &asbuilt_plan::plan::Door| [(d.a[0] + d.b[0]) / 2.0, (d.a[1] + d.b[1]) / 2.0];
            let (m, n) = (mid(d), mid(e));
            assert!((m[0] - n[0]).hypot(m[1] - n[1]) <= 0.15, "{d:?} {e:?}");
        }
    }
    let doors = |p: &FloorPlan| p.stories.iter().any(|s| !s.spaces.doors.is_empty());
    if doors(b) {
        assert!(
            b.notes.iter().any(|n| n.contains(NO_LINTELS)),
            "{:?}",
            b.notes
        );
    }
    let (a, b) = (&without_lintels(a), &without_lintels(b));
    assert_eq!(a.origin, b.origin);
    assert_eq!(a.crs, b.crs);
    assert_eq!(a.input, b.input);
    assert_eq!(a.parameters, b.parameters);
    assert_eq!(a.notes, b.notes);
    assert_eq!(a.stories.len(), b.stories.len());
    for (x, y) in a.stories.iter().zip(&b.stories) {
        assert_eq!(x.samples, y.samples, "level {}: samples differ", x.level);
        // The underlay too: made by the same counting pass, tile by tile.
        assert!(x.underlay.is_some(), "level {}: no underlay", x.level);
        assert_eq!(
            x.underlay, y.underlay,
            "level {}: underlays differ",
            x.level
        );
        assert_eq!(x, y, "level {}", x.level);
    }
}

#[test]
fn streaming_in_small_tiles_gives_the_in_memory_plan() {
    let dir = tempfile::tempdir().unwrap();
    let (_, world) = office(dir.path(), 120_000);
    let path = dir.path().join("cloud.ply");
    let params = Params {
        emit_samples: true,
        ..Default::default()
    };
    let whole = in_memory(&path, &world, &params);
    assert_eq!(whole.stories.len(), 3);
    // A budget this small cuts the floor into many tiles, so halos and tile edges run
    // through every story.
    let stream = StreamingParams {
        max_memory: 3 << 20,
        temp_dir: Some(dir.path().to_path_buf()),
        ..Default::default()
    };
    let (streamed, report) = plan_file(
        &path,
        &ReadOptions::default(),
        Some(Sidecar::Poses(world.clone())),
        &params,
        &stream,
        &mut NoProgress,
    )
    .unwrap();
    assert!(
        report.tiles.0 * report.tiles.1 >= 4,
        "only {:?} tiles",
        report.tiles
    );
    assert!(report.max_tile_points < 120_000 / 2, "{report:?}");
    assert_eq!(report.points, whole.input.points);
    assert_same_plan(&whole, &streamed);
    assert!(streamed.timings_ms.first().unwrap().0 == "read");
    assert!(streamed.timings_ms.last().unwrap().0 == "total");

    // The tile files are gone.
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with("asbuilt-tiles"))
        .collect();
    assert!(left.is_empty(), "{left:?}");

    // One tile (a budget of plenty) gives the same plan too.
    let (one, report) = plan_file(
        &path,
        &ReadOptions::default(),
        Some(Sidecar::Poses(world)),
        &params,
        &StreamingParams::default(),
        &mut NoProgress,
    )
    .unwrap();
    assert_eq!(report.tiles, (1, 1));
    assert_same_plan(&whole, &one);
}

#[test]
fn chunked_reads_give_the_whole_file_points() {
    let dir = tempfile::tempdir().unwrap();
    let (cloud, _) = office(dir.path(), 150_000);
    let ascii = dir.path().join("ascii.ply");
    ply::write_ply(&ascii, &cloud, ply::Encoding::Ascii).unwrap();
    let las = dir.path().join("cloud.las");
    export::write_las(&las, &cloud, false).unwrap();
    let laz = dir.path().join("cloud.laz");
    export::write_las(&laz, &cloud, true).unwrap();
    for name in ["cloud.ply", "ascii.ply", "cloud.las", "cloud.laz"] {
        let path = dir.path().join(name);
        let options = ReadOptions {
            scale: Some(0.5),
            ..Default::default()
        };
        let whole = io::read_cloud_with(&path, &options).unwrap();
        let chunked = chunks::collect(chunks::open_chunks(&path, &options).unwrap()).unwrap();
        assert_eq!(whole.len(), cloud.len(), "{name}");
        assert_eq!(chunked.origin, whole.origin, "{name}");
        assert!(chunked.xyz == whole.xyz, "{name}: points differ");
        assert_eq!(chunked.scan, whole.scan, "{name}");
        assert_eq!(chunked.scan_ids, whole.scan_ids, "{name}");
        assert_eq!(chunked.source, whole.source, "{name}");
        assert_eq!(chunked.crs, whole.crs, "{name}");
    }
}

#[test]
fn bad_budgets_and_unchunked_formats_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (cloud, world) = office(dir.path(), 30_000);
    let path = dir.path().join("cloud.ply");
    let tiny = StreamingParams {
        max_memory: 64 << 10,
        temp_dir: Some(dir.path().to_path_buf()),
        ..Default::default()
    };
    let err = plan_file(
        &path,
        &ReadOptions::default(),
        Some(Sidecar::Poses(world)),
        &Params::default(),
        &tiny,
        &mut NoProgress,
    )
    .unwrap_err();
    assert!(matches!(err, StreamingError::Budget { .. }), "{err}");
    assert!(err.to_string().contains("too small"), "{err}");

    let e57 = dir.path().join("cloud.e57");
    export::write_e57(&e57, &cloud).unwrap();
    let err = plan_file(
        &e57,
        &ReadOptions::default(),
        None,
        &Params::default(),
        &StreamingParams::default(),
        &mut NoProgress,
    )
    .unwrap_err();
    assert!(
        err.to_string().contains("cannot be read in chunks"),
        "{err}"
    );

    let err = chunks::open_chunks(&dir.path().join("missing.ply"), &ReadOptions::default())
        .err()
        .unwrap();
    assert!(err.to_string().contains("missing.ply"), "{err}");
}

#[test]
fn the_first_pass_stops_at_the_point_limit() {
    let dir = tempfile::tempdir().unwrap();
    office(dir.path(), 30_000);
    let limited = StreamingParams {
        temp_dir: Some(dir.path().to_path_buf()),
        max_points: Some(1_000),
        ..Default::default()
    };
    let err = plan_file(
        &dir.path().join("cloud.ply"),
        &ReadOptions::default(),
        None,
        &Params::default(),
        &limited,
        &mut NoProgress,
    )
    .unwrap_err();
    // Stopped after the chunk that passed the limit.
    let StreamingError::TooManyPoints { points, max } = err else {
        panic!("{err}")
    };
    assert_eq!(max, 1_000);
    assert!(points > 1_000 && points <= 30_000, "{points}");
}
