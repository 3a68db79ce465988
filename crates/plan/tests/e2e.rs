//! End to end: simulated buildings with exact ground truth, through `asbuilt_plan::plan`, scored
//! by `evaluate`. The bounds are the issue's: with clean static scans and poses, every story
//! found with floor and ceiling within 2 cm, area IoU ≥ 0.97, boundary p95 ≤ 3 cm, every plan
//! watertight, the lobby's 10 m arc an arc within 1 %; without poses IoU ≥ 0.95; with
//! 1 cm / 0.1° registration error and smoothing on, IoU ≥ 0.95 and p95 ≤ 5 cm.
//!
//! The same bounds hold without poses for the office and the lobby, and with registration
//! error for the lobby and the L.
//!
//! Point counts stay modest so the file runs in well under a minute in a debug build.

use asbuilt_plan::cloud::{PointCloud, Viewpoints};
use asbuilt_plan::evaluate::{evaluate, EvaluateParams, Evaluation};
use asbuilt_plan::io::{ply, poses, read_cloud};
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions, Simulation};
use asbuilt_plan::{FloorPlan, Params};

fn scan(kind: BuildingKind, options: ScanOptions) -> Simulation {
    simulate(kind, &options).expect("valid simulation options")
}

fn plan_and_score(
    cloud: &PointCloud,
    sim: &Simulation,
    params: &Params,
) -> (FloorPlan, Evaluation) {
    let plan = asbuilt_plan::plan(cloud, params, &mut NoProgress)
        .unwrap_or_else(|e| panic!("{}: plan failed: {e}", sim.truth.building));
    let eval = evaluate(&plan, &sim.truth, &EvaluateParams::default());
    eprintln!("{}:\n{}", sim.truth.building, eval.summary());
    (plan, eval)
}

/// The bounds every clean run must meet.
fn assert_clean(e: &Evaluation, name: &str) {
    let s = e.summary();
    assert!(
        e.all_watertight(),
        "{name}: every story found and watertight\n{s}"
    );
    assert_eq!(e.extra_stories, 0, "{name}: no invented stories\n{s}");
    assert!(
        e.max_height_error() <= 0.02,
        "{name}: floors and ceilings within 2 cm\n{s}"
    );
    assert!(e.min_iou() >= 0.97, "{name}: IoU >= 0.97\n{s}");
    assert!(
        e.max_boundary_p95() <= 0.03,
        "{name}: boundary p95 <= 3 cm\n{s}"
    );
}

#[test]
fn square_room_one_scan() {
    let sim = scan(
        BuildingKind::SquareRoom,
        ScanOptions {
            points: 300_000,
            seed: 11,
            ..Default::default()
        },
    );
    let (_, e) = plan_and_score(&sim.cloud, &sim, &Params::default());
    assert_clean(&e, "square room");
    assert!(e.min_completeness() >= 0.95, "{}", e.summary());
}

#[test]
fn office_three_stories() {
    let sim = scan(
        BuildingKind::Office3Story,
        ScanOptions {
            points: 1_500_000,
            seed: 12,
            ..Default::default()
        },
    );
    let (plan, e) = plan_and_score(&sim.cloud, &sim, &Params::default());
    assert_eq!(plan.stories.len(), 3, "{}", e.summary());
    assert_clean(&e, "office");
}

#[test]
fn curved_lobby_arc_radius() {
    let sim = scan(
        BuildingKind::CurvedLobby,
        ScanOptions {
            points: 600_000,
            seed: 13,
            noise: 0.002,
            ..Default::default()
        },
    );
    let (_, e) = plan_and_score(&sim.cloud, &sim, &Params::default());
    assert_clean(&e, "lobby");
    assert_eq!(
        e.stories[0].arcs.len(),
        1,
        "the 10 m wall is the only arc of radius >= 1 m"
    );
    assert!(
        e.worst_arc_error() < 0.01,
        "arc radius within 1 %\n{}",
        e.summary()
    );
}

#[test]
fn rotated_l_with_poses() {
    let sim = scan(
        BuildingKind::RotatedL,
        ScanOptions {
            points: 400_000,
            seed: 14,
            ..Default::default()
        },
    );
    let (_, e) = plan_and_score(&sim.cloud, &sim, &Params::default());
    assert_clean(&e, "rotated L");
}

#[test]
fn rotated_l_without_poses() {
    let mut sim = scan(
        BuildingKind::RotatedL,
        ScanOptions {
            points: 400_000,
            seed: 15,
            ..Default::default()
        },
    );
    let mut cloud = std::mem::take(&mut sim.cloud);
    cloud.viewpoints = Viewpoints::None;
    cloud.scan.clear();
    cloud.scan_ids.clear();
    let (_, e) = plan_and_score(&cloud, &sim, &Params::default());
    assert!(e.all_watertight(), "{}", e.summary());
    assert!(e.max_height_error() <= 0.02, "{}", e.summary());
    assert!(
        e.min_iou() >= 0.95,
        "without poses IoU >= 0.95\n{}",
        e.summary()
    );
}

/// The cloud without its scanner poses: inside comes from geometry alone.
fn without_poses(mut sim: Simulation) -> (PointCloud, Simulation) {
    let mut cloud = std::mem::take(&mut sim.cloud);
    cloud.viewpoints = Viewpoints::None;
    cloud.scan.clear();
    cloud.scan_ids.clear();
    (cloud, sim)
}

#[test]
fn office_without_poses() {
    let (cloud, sim) = without_poses(scan(
        BuildingKind::Office3Story,
        ScanOptions {
            points: 1_500_000,
            seed: 19,
            ..Default::default()
        },
    ));
    let (plan, e) = plan_and_score(&cloud, &sim, &Params::default());
    let s = e.summary();
    assert_eq!(plan.stories.len(), 3, "{s}");
    assert!(e.all_watertight(), "{s}");
    assert!(e.max_height_error() <= 0.02, "{s}");
    assert!(e.min_iou() >= 0.95, "without poses IoU >= 0.95\n{s}");
}

#[test]
fn curved_lobby_without_poses_keeps_its_arc() {
    let (cloud, sim) = without_poses(scan(
        BuildingKind::CurvedLobby,
        ScanOptions {
            points: 600_000,
            seed: 20,
            noise: 0.002,
            ..Default::default()
        },
    ));
    let (_, e) = plan_and_score(&cloud, &sim, &Params::default());
    let s = e.summary();
    assert!(e.all_watertight(), "{s}");
    assert!(e.min_iou() >= 0.95, "without poses IoU >= 0.95\n{s}");
    assert!(e.worst_arc_error() < 0.02, "arc radius within 2 %\n{s}");
}

/// Scans with 1 cm / 0.1° per-scan registration error, plans with smoothing on, and checks
/// the bounds for that case: watertight, IoU >= 0.95, p95 <= 5 cm.
fn registered_and_smoothed(kind: BuildingKind, points: usize, seed: u64) -> Evaluation {
    let sim = scan(
        kind,
        ScanOptions {
            points,
            seed,
            registration: Some((0.01, 0.1)),
            ..Default::default()
        },
    );
    let mut params = Params::default();
    params.smoothing.registration_error = Some(0.01);
    let (_, e) = plan_and_score(&sim.cloud, &sim, &params);
    let s = e.summary();
    assert!(e.all_watertight(), "{s}");
    assert!(e.min_iou() >= 0.95, "registration error: IoU >= 0.95\n{s}");
    assert!(
        e.max_boundary_p95() <= 0.05,
        "registration error: p95 <= 5 cm\n{s}"
    );
    e
}

#[test]
fn lobby_and_l_with_registration_error_and_smoothing() {
    for (kind, points) in [
        (BuildingKind::CurvedLobby, 600_000),
        (BuildingKind::RotatedL, 400_000),
    ] {
        let e = registered_and_smoothed(kind, points, 21);
        assert!(e.worst_arc_error() < 0.02, "{}", e.summary());
    }
}

#[test]
fn rotated_l_georeferenced_through_ply_and_sidecar() {
    // A UTM-sized offset, written to PLY with a pose sidecar and read back as a user would.
    let offset = [512_345.0, 5_432_100.0, 230.0];
    let sim = scan(
        BuildingKind::RotatedL,
        ScanOptions {
            points: 400_000,
            seed: 16,
            offset,
            ..Default::default()
        },
    );
    let dir = std::env::temp_dir().join(format!("asbuilt-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (cloud_path, poses_path) = (dir.join("cloud.ply"), dir.join("poses.json"));
    ply::write_ply(&cloud_path, &sim.cloud, ply::Encoding::BinaryLittleEndian).unwrap();
    let Viewpoints::Static(p) = &sim.cloud.viewpoints else {
        panic!("static scans have poses")
    };
    poses::write_poses(&poses_path, p, sim.cloud.origin).unwrap();
    let mut cloud = read_cloud(&cloud_path).unwrap();
    let sidecar = poses::parse_poses(&std::fs::read_to_string(&poses_path).unwrap()).unwrap();
    poses::attach_poses(&mut cloud, sidecar).unwrap();
    assert_eq!(cloud.len(), sim.cloud.len());
    let (plan, e) = plan_and_score(&cloud, &sim, &Params::default());
    assert_clean(&e, "georeferenced rotated L");
    // The plan stays in the world frame of the input.
    let x = plan.stories[0].polygons[0].exterior[0][0] + plan.origin[0];
    assert!((x - offset[0]).abs() < 100.0, "world x {x}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn office_with_registration_error_and_smoothing() {
    let e = registered_and_smoothed(BuildingKind::Office3Story, 1_200_000, 17);
    assert!(e.max_height_error() <= 0.02, "{}", e.summary());
}

#[test]
fn mobile_scan_of_the_lobby() {
    let sim = scan(
        BuildingKind::CurvedLobby,
        ScanOptions {
            points: 500_000,
            seed: 18,
            mobile: true,
            ..Default::default()
        },
    );
    assert!(matches!(sim.cloud.viewpoints, Viewpoints::Trajectory(_)));
    let (_, e) = plan_and_score(&sim.cloud, &sim, &Params::default());
    assert_clean(&e, "mobile lobby");
    assert!(e.worst_arc_error() < 0.01, "{}", e.summary());
}

#[test]
fn simulation_ground_truth_scores_itself_perfectly() {
    // The evaluation's own sanity: each building's truth, as a plan, matches the truth exactly
    // and is valid. These pass before the pipeline exists.
    for (name, kind) in BuildingKind::ALL {
        let sim = scan(
            kind,
            ScanOptions {
                points: 1000,
                ..Default::default()
            },
        );
        let e = evaluate(
            &sim.truth.to_floor_plan(),
            &sim.truth,
            &EvaluateParams::default(),
        );
        let s = e.summary();
        assert!(e.min_iou() > 0.9999, "{name}\n{s}");
        assert!(e.max_boundary_p95() < 1e-3, "{name}\n{s}");
        assert!(e.min_completeness() > 0.999, "{name}\n{s}");
        assert!(e.all_watertight(), "{name}\n{s}");
        assert_eq!(e.max_height_error(), 0.0, "{name}");
        assert!(e.worst_arc_error() < 1e-12, "{name}\n{s}");
    }
}
