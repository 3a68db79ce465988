//! Plans with poses, with scan ids but no poses, and from plain x, y, z, and compares them.
//!
//! ```sh
//! cargo run --release -p asbuilt-plan --example viewpoints -- table [--points N] [--seed S]
//!     [--buildings a,b] [--modes poses,scan-ids,plain] [--mobile] [--out DIR]
//!     [--param section.name=value ...]
//! cargo run --release -p asbuilt-plan --example viewpoints -- real CLOUD POSES.json [--out DIR]
//! ```
//!
//! `table` simulates every building in each mode and prints a markdown row per run: IoU against
//! the truth (worst story), the difference to the with-poses plan, and for estimated viewpoints
//! the scanner position error against the simulator's (median and worst, per scan or per path
//! sample). With `--out` every plan is written as `DIR/BUILDING-MODE.geojson` for an OGC
//! validity check (`benches/viewpoints.sh` runs both).
//!
//! `real` plans a real cloud with its pose sidecar and without it, prints the IoU between the
//! two plans per story and each estimated scanner position against the sidecar's.

use asbuilt_plan::cloud::{PointCloud, TrajectorySample, Viewpoints};
use asbuilt_plan::evaluate::{evaluate, iou, EvaluateParams};
use asbuilt_plan::io::{self, geojson, poses};
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::simulate::{simulate, BuildingKind, Keep, ScanOptions};
use asbuilt_plan::{FloorPlan, Params};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("table") => table(&args[1..]),
        Some("real") => real(&args[1..]),
        _ => {
            eprintln!("usage: viewpoints table [...] | viewpoints real CLOUD POSES.json");
            std::process::exit(2);
        }
    }
}

fn flag(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

/// The parameters, with every `--param section.name=value` of the command line applied.
fn params() -> Params {
    let args: Vec<String> = std::env::args().collect();
    let mut p = Params::default();
    for w in args.windows(2).filter(|w| w[0] == "--param") {
        p.set(&w[1]).expect("a parameter");
    }
    p
}

fn plan(cloud: &PointCloud) -> (FloorPlan, f64) {
    let start = std::time::Instant::now();
    let plan = asbuilt_plan::plan(cloud, &params(), &mut NoProgress).expect("a plan");
    (plan, start.elapsed().as_secs_f64())
}

/// Horizontal errors of the estimated positions against the true ones: per scan for static
/// scans, per path sample (against the true path at the same time) for a mobile scan.
fn position_errors(plan: &FloorPlan, truth: &Viewpoints) -> Vec<f64> {
    let v = &plan.input.viewpoints;
    match truth {
        Viewpoints::Static(poses) => v
            .scans
            .iter()
            .filter(|s| s.estimated)
            .map(|s| {
                let t = poses
                    .iter()
                    .find(|p| p.index == s.index)
                    .expect("a true pose");
                s.position.map_or(f64::INFINITY, |p| {
                    (p[0] - t.position[0]).hypot(p[1] - t.position[1])
                })
            })
            .collect(),
        _ => Vec::new(),
    }
}

/// Path errors: each estimated sample against the true trajectory at its time.
fn path_errors(estimated: &[TrajectorySample], truth: &[TrajectorySample]) -> Vec<f64> {
    estimated
        .iter()
        .map(|s| {
            let p = poses::position_at(truth, s.t);
            (p[0] - s.position[0]).hypot(p[1] - s.position[1])
        })
        .collect()
}

fn stats(v: &mut [f64]) -> String {
    if v.is_empty() {
        return "-".into();
    }
    v.sort_by(f64::total_cmp);
    format!(
        "{:.1} / {:.1} cm",
        100.0 * v[v.len() / 2],
        100.0 * v[v.len() - 1]
    )
}

fn table(args: &[String]) {
    let points: usize = flag(args, "--points").map_or(1_500_000, |p| p.parse().unwrap());
    let seed: u64 = flag(args, "--seed").map_or(1, |s| s.parse().unwrap());
    let mobile = args.iter().any(|a| a == "--mobile");
    let out = flag(args, "--out");
    let buildings: Vec<BuildingKind> = match flag(args, "--buildings") {
        Some(list) => list
            .split(',')
            .map(|n| BuildingKind::from_name(n).expect("a building"))
            .collect(),
        None => BuildingKind::ALL.iter().map(|(_, k)| *k).collect(),
    };
    let modes: Vec<Keep> = match flag(args, "--modes") {
        Some(list) => list
            .split(',')
            .map(|n| Keep::from_name(n).expect("a mode"))
            .collect(),
        None => Keep::ALL.iter().map(|(_, k)| *k).collect(),
    };
    if let Some(dir) = &out {
        std::fs::create_dir_all(dir).unwrap();
    }
    println!(
        "| building | scanner | mode | points | IoU (worst story) | IoU vs with poses | viewpoints | position error median / max | rests on | plan s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for kind in buildings {
        let mut with_poses: Option<FloorPlan> = None;
        for &keep in &modes {
            let sim = simulate(
                kind,
                &ScanOptions {
                    points,
                    seed,
                    mobile,
                    keep,
                    ..Default::default()
                },
            )
            .expect("options");
            let (plan, secs) = plan(&sim.cloud);
            let e = evaluate(&plan, &sim.truth, &EvaluateParams::default());
            let vs = with_poses.as_ref().map(|w| {
                w.stories
                    .iter()
                    .zip(&plan.stories)
                    .map(|(a, b)| iou(&a.polygons, &b.polygons, 0.005))
                    .fold(1.0, f64::min)
            });
            let v = &plan.input.viewpoints;
            let mut errors = match (&sim.scanners, keep) {
                (Viewpoints::Trajectory(truth), Keep::ScanIds) => {
                    let est = estimated_path(&sim.cloud);
                    path_errors(&est, truth)
                }
                _ => position_errors(&plan, &sim.scanners),
            };
            let located = match (&v.path, v.scans.is_empty()) {
                (Some(p), _) => format!("path, {} of {} windows", p.located, p.windows),
                (None, false) => format!(
                    "{} of {} scans",
                    v.scans.iter().filter(|s| s.position.is_some()).count(),
                    v.scans.len()
                ),
                (None, true) => format!(
                    "{} pseudo",
                    v.open_space
                        .iter()
                        .map(|s| s.viewpoints.len())
                        .sum::<usize>()
                ),
            };
            println!(
                "| {} | {} | {} | {} | {:.4} | {} | {:?}: {} | {} | {} | {:.1} |",
                kind.name(),
                if mobile { "mobile" } else { "static" },
                Keep::ALL.iter().find(|(_, k)| *k == keep).unwrap().0,
                sim.cloud.len(),
                e.min_iou(),
                vs.map_or("-".into(), |x| format!("{x:.4}")),
                v.source,
                located,
                stats(&mut errors),
                v.rests_on
                    .map_or("-".into(), |f| format!("{:.0} %", 100.0 * f)),
                secs
            );
            if let Some(dir) = &out {
                let name = format!(
                    "{dir}/{}-{}{}.geojson",
                    kind.name(),
                    Keep::ALL.iter().find(|(_, k)| *k == keep).unwrap().0,
                    if mobile { "-mobile" } else { "" }
                );
                std::fs::write(name, geojson::to_geojson_string(&plan)).unwrap();
            }
            if keep == Keep::Poses {
                with_poses = Some(plan);
            }
        }
    }
}

/// The path the pipeline estimates for a mobile cloud without its trajectory.
fn estimated_path(cloud: &PointCloud) -> Vec<TrajectorySample> {
    let e = asbuilt_plan::viewpoints::estimate(cloud, &params().viewpoints);
    match e.viewpoints {
        Some(Viewpoints::Trajectory(t)) => t,
        _ => Vec::new(),
    }
}

fn real(args: &[String]) {
    let path = std::path::Path::new(&args[0]);
    let sidecar = std::path::Path::new(&args[1]);
    let out = flag(args, "--out");
    let bare = io::read_cloud(path).expect("a cloud");
    let mut posed = bare.clone();
    poses::load_poses(&mut posed, sidecar).expect("poses");
    let (with, _) = plan(&posed);
    let (without, secs) = plan(&bare);
    // Plain x, y, z: no scan ids and no times either.
    let mut xyz = bare.clone();
    xyz.scan.clear();
    xyz.scan_ids.clear();
    xyz.time.clear();
    let (plain, plain_secs) = plan(&xyz);
    println!(
        "| story | area with poses m² | area without m² | IoU | area plain x, y, z m² | IoU |"
    );
    println!("|---|---|---|---|---|---|");
    for ((a, b), c) in with
        .stories
        .iter()
        .zip(&without.stories)
        .zip(&plain.stories)
    {
        println!(
            "| {} | {:.2} | {:.2} | {:.4} | {:.2} | {:.4} |",
            a.level,
            a.area(),
            b.area(),
            iou(&a.polygons, &b.polygons, 0.005),
            c.area(),
            iou(&a.polygons, &c.polygons, 0.005)
        );
    }
    println!(
        "plain x, y, z: {:.1} s, valid {}, viewpoints {:?}, rests on {:?}; notes {:#?}",
        plain_secs,
        asbuilt_plan::validity::plan_problems(&plain).is_empty(),
        plain.input.viewpoints.source,
        plain.input.viewpoints.rests_on,
        plain.notes
    );
    println!(
        "\nstories with poses {}, without {}; plan without poses {:.1} s",
        with.stories.len(),
        without.stories.len(),
        secs
    );
    println!("\n| scan | points | estimated x, y, z | sidecar x, y, z | error (xy) | residual | support |");
    println!("|---|---|---|---|---|---|---|");
    let Viewpoints::Static(truth) = &posed.viewpoints else {
        panic!("the sidecar has no static poses")
    };
    let mut errors = Vec::new();
    for s in &without.input.viewpoints.scans {
        let t = truth.iter().find(|p| p.index == s.index).unwrap();
        let o = bare.origin;
        let w = |p: [f64; 3]| format!("{:.3}, {:.3}, {:.3}", p[0] + o[0], p[1] + o[1], p[2] + o[2]);
        let err = s
            .position
            .map(|p| (p[0] - t.position[0]).hypot(p[1] - t.position[1]));
        errors.extend(err);
        println!(
            "| {} | {} | {} | {} | {} | {} | {} |",
            s.index,
            s.points,
            s.position.map_or("not found".into(), w),
            w(t.position),
            err.map_or("-".into(), |e| format!("{:.1} cm", 100.0 * e)),
            s.residual
                .map_or("-".into(), |r| format!("{:.1} cm", 100.0 * r)),
            s.support.map_or("-".into(), |r| format!("{:.2}", r)),
        );
    }
    println!("\nposition error median / max: {}", stats(&mut errors));
    println!("notes without poses: {:#?}", without.notes);
    if let Some(dir) = out {
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            format!("{dir}/with-poses.geojson"),
            geojson::to_geojson_string(&with),
        )
        .unwrap();
        std::fs::write(
            format!("{dir}/without-poses.geojson"),
            geojson::to_geojson_string(&without),
        )
        .unwrap();
        std::fs::write(
            format!("{dir}/plain.geojson"),
            geojson::to_geojson_string(&plain),
        )
        .unwrap();
    }
}
