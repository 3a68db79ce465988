//! Every story polygon the pipeline emits is OGC-valid, judged independently by GEOS (shapely)
//! on the GeoJSON exactly as written, over the simulator's buildings scanned statically with
//! and without poses and with a mobile scanner.
//!
//! Point counts are low on purpose: sparse scans are where labelings pinch and fitted walls
//! cross, which is what this file is about (the accuracy bounds live in `e2e.rs`).

#[path = "support/geos.rs"]
mod geos;

use asbuilt_plan::cloud::Viewpoints;
use asbuilt_plan::io::geojson;
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
use asbuilt_plan::validity;
use asbuilt_plan::Params;
use rayon::prelude::*;

/// How a building is scanned.
#[derive(Debug, Clone, Copy)]
enum Mode {
    Poses,
    NoPoses,
    Mobile,
}

#[test]
fn simulator_buildings_plan_to_geos_valid_polygons() {
    let runs: Vec<(BuildingKind, usize, Mode)> = [
        (BuildingKind::SquareRoom, 40_000),
        (BuildingKind::RotatedL, 80_000),
        (BuildingKind::CurvedLobby, 120_000),
        (BuildingKind::Office3Story, 200_000),
    ]
    .into_iter()
    .flat_map(|(k, n)| [Mode::Poses, Mode::NoPoses, Mode::Mobile].map(|m| (k, n, m)))
    .collect();
    let plans: Vec<(String, serde_json::Value)> = runs
        .par_iter()
        .map(|&(kind, points, mode)| {
            let name = format!("{} {points} {mode:?}", kind.name());
            let options = ScanOptions {
                points,
                seed: 3,
                mobile: matches!(mode, Mode::Mobile),
                ..Default::default()
            };
            let mut sim = simulate(kind, &options).unwrap();
            if matches!(mode, Mode::NoPoses) {
                sim.cloud.viewpoints = Viewpoints::None;
                sim.cloud.scan.clear();
                sim.cloud.scan_ids.clear();
            }
            let plan = asbuilt_plan::plan(&sim.cloud, &Params::default(), &mut NoProgress)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            // The pipeline's own check (geo) on the coordinates as written.
            let problems = validity::plan_problems(&plan);
            assert!(problems.is_empty(), "{name}: {problems:?}");
            (name, geojson::to_geojson(&plan))
        })
        .collect();
    let (names, docs): (Vec<String>, Vec<serde_json::Value>) = plans.into_iter().unzip();
    let Some(verdicts) = geos::geos_validity(&docs) else {
        return;
    };
    let stories: usize = verdicts.iter().map(Vec::len).sum();
    assert!(stories >= runs.len(), "every run has a story");
    let invalid = geos::invalid_stories(&names, &verdicts);
    assert!(
        invalid.is_empty(),
        "{} of {stories} story polygons are invalid by GEOS:\n{}",
        invalid.len(),
        invalid.join("\n")
    );
}
