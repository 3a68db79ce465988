//! Simulates one building, plans it and scores the plan against the exact truth.
//!
//! Run with `cargo run --release -p asbuilt-plan --example score -- office_3story 1500000 12
//! [--no-poses | --plain] [--registration T,R] [--noise S] [--mobile] [--out DIR]`. `--no-poses`
//! keeps the scan ids (and times) but drops the poses or trajectory; `--plain` keeps x, y, z
//! alone, shuffled. With `--out` it writes
//! `plan.geojson` (with samples) and `truth.json` there, for looking at. BUILDING may also be
//! `random_SEED` or `random30_SEED` (simulate/random.rs).
//!
//! `rooms |` rows, one per story whose truth has rooms: rooms found/true (+ plan rooms matching
//! none), rooms within the area bound (1 %, or 0.2 m² under 20 m²), worst area error, door
//! recall and precision (centre within 10 cm, width within 5 cm), the matched doors' largest
//! centre and width errors, and the largest interior wall thickness error, m.
//!
//! `windows |` rows, one per story whose truth or plan has windows: windows found/true (+ plan
//! windows matching none; a match is a centre within 30 cm), recall, precision, and the matched
//! windows' largest centre, width, sill and head errors, m.

use asbuilt_plan::evaluate::{evaluate, EvaluateParams};
use asbuilt_plan::io::geojson;
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::simulate::{random, scan, BuildingKind, Keep, ScanOptions};
use asbuilt_plan::Params;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .map(|i| args[i + 1].clone())
    };
    let building = random::from_name(&args[0])
        .or_else(|| BuildingKind::from_name(&args[0]).map(BuildingKind::build))
        .expect("a building name (or random_SEED, random30_SEED)");
    let (keep, mode) = if args.iter().any(|a| a == "--plain") {
        (Keep::Plain, "plain")
    } else if args.iter().any(|a| a == "--no-poses") {
        (Keep::ScanIds, "scan-ids")
    } else {
        (Keep::Poses, "poses")
    };
    let mut options = ScanOptions {
        keep,
        points: args
            .get(1)
            .and_then(|a| a.parse().ok())
            .unwrap_or(1_000_000),
        seed: args.get(2).and_then(|a| a.parse().ok()).unwrap_or(1),
        mobile: args.iter().any(|a| a == "--mobile"),
        voxel: BuildingKind::from_name(&args[0]).and_then(BuildingKind::voxel),
        ..Default::default()
    };
    let mut params = Params::default();
    if let Some(r) = flag("--registration") {
        let v: Vec<f64> = r.split(',').map(|x| x.parse().unwrap()).collect();
        options.registration = Some((v[0], v[1]));
        params.smoothing.registration_error = Some(v[0]);
    }
    for (i, a) in args.iter().enumerate() {
        if a == "--param" {
            params.set(&args[i + 1]).expect("a parameter");
        }
    }
    if let Some(n) = flag("--noise") {
        options.noise = n.parse().unwrap();
    }
    let sim = scan(&building, &options).expect("options");
    let start = std::time::Instant::now();
    let plan = match asbuilt_plan::plan(&sim.cloud, &params, &mut NoProgress) {
        Ok(plan) => plan,
        Err(e) => {
            println!("row | {} | {mode} | no plan: {e} |", args[0]);
            return;
        }
    };
    let ms = start.elapsed().as_millis();
    let e = evaluate(&plan, &sim.truth, &EvaluateParams::default());
    print!("{}", e.summary());
    println!("plan {ms} ms; notes: {:?}", plan.notes);
    println!("timings_ms: {:?}", plan.timings_ms);
    // One table row: stories found of the truth's, then the worst story's scores.
    let found = e.stories.iter().filter(|s| s.plan_level.is_some()).count();
    // OGC validity of the polygons as written (the pipeline's own test; GEOS in the e2e tests).
    let problems = asbuilt_plan::validity::plan_problems(&plan);
    let valid = problems.is_empty() && e.all_watertight();
    let vp = &plan.input.viewpoints;
    println!(
        "row | {} | {mode} | {}/{} (+{}) | {:.4} | {:.3} | {:.3} | {:.3} | {} | {} | {:?} | {} |",
        args[0],
        found,
        e.stories.len(),
        e.extra_stories,
        e.min_iou(),
        e.max_boundary_p95(),
        e.min_completeness(),
        e.max_height_error(),
        plan.parameters["samples"]["cell_size_derived"],
        if valid { "valid" } else { "INVALID" },
        vp.source,
        vp.rests_on
            .map(|f| format!("{:.2}", f))
            .unwrap_or_else(|| "-".into()),
    );
    // Rooms, doors and wall thickness, one row a story whose truth has rooms.
    for st in &e.stories {
        if let Some(r) = &st.rooms {
            println!(
                "rooms | {} | {mode} | {} | {}/{} (+{}) | {} | {:.2} % | {:.3} | {:.3} | {:.3} | {:.3} | {:.4} |",
                args[0],
                st.level,
                r.matched(),
                r.truth_rooms,
                r.plan_rooms.saturating_sub(r.matched()),
                r.within(),
                100.0 * r.worst_area_error(),
                r.door_recall(),
                r.door_precision(),
                r.door_centre_max,
                r.door_width_max,
                r.thickness_max,
            );
        }
    }
    for st in &e.stories {
        if let Some(w) = &st.windows {
            println!(
                "windows | {} | {mode} | {} | {}/{} (+{}) | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} |",
                args[0],
                st.level,
                w.matched,
                w.truth_windows,
                w.plan_windows.saturating_sub(w.matched),
                w.recall(),
                w.precision(),
                w.centre_max,
                w.width_max,
                w.sill_max,
                w.head_max,
            );
        }
    }
    if let Some(dir) = flag("--out") {
        std::fs::create_dir_all(&dir).unwrap();
        let mut with_samples = plan.clone();
        with_samples.parameters["emit_samples"] = true.into();
        let doc = geojson::to_geojson(&with_samples);
        std::fs::write(format!("{dir}/plan.geojson"), doc.to_string()).unwrap();
        let truth = geojson::to_geojson(&sim.truth.to_floor_plan());
        std::fs::write(format!("{dir}/truth.json"), truth.to_string()).unwrap();
    }
}
