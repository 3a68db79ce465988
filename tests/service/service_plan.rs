//! The whole path with the real pipeline: simulate a scan with `asbuilt simulate`, upload it
//! with its poses, and check the job's GeoJSON against the contract, the SVG and the DXF; then
//! the same through the upload page in headless chromium. These need the readers, simulator
//! and stages, so they pass once those are integrated.

use crate::support::server;

use std::path::Path;
use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

use asbuilt::worker::pipeline::PlanPipeline;
use serde_json::Value;

/// Simulates the office building into `dir`: `cloud.ply` and `poses.json`.
fn simulate(dir: &Path) {
    let out = Command::new(env!("CARGO_BIN_EXE_asbuilt"))
        .args([
            "simulate",
            "--building",
            "office_3story",
            "--points",
            "600000",
            "--out",
        ])
        .arg(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "simulate: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.join("cloud.ply").is_file() && dir.join("poses.json").is_file());
}

fn signed_area(ring: &[Value]) -> f64 {
    ring.windows(2)
        .map(|w| {
            let (a, b) = (&w[0], &w[1]);
            a[0].as_f64().unwrap() * b[1].as_f64().unwrap()
                - b[0].as_f64().unwrap() * a[1].as_f64().unwrap()
        })
        .sum::<f64>()
        / 2.0
}

/// Contract §1: collection, metadata, closed rings with RFC 7946 winding, wall features.
fn check_contract(doc: &Value) {
    assert_eq!(doc["type"], "FeatureCollection");
    let meta = &doc["floorplan"];
    assert_eq!(meta["version"], 1);
    assert_eq!(meta["units"], "m");
    assert!(meta["input"]["points"].as_u64().unwrap() > 0);
    assert!(meta["parameters"]["samples"]["cell_size"].is_number());
    let timings: Vec<&String> = meta["timings_ms"].as_object().unwrap().keys().collect();
    assert_eq!(timings.first().unwrap().as_str(), "read");
    assert_eq!(timings.last().unwrap().as_str(), "total");
    let features = doc["features"].as_array().unwrap();
    let stories: Vec<&Value> = features
        .iter()
        .filter(|f| f["properties"]["kind"] == "story")
        .collect();
    assert!(!stories.is_empty());
    for story in &stories {
        let g = &story["geometry"];
        let polygons: Vec<&Value> = match g["type"].as_str().unwrap() {
            "Polygon" => vec![&g["coordinates"]],
            "MultiPolygon" => g["coordinates"].as_array().unwrap().iter().collect(),
            other => panic!("story geometry {other}"),
        };
        for poly in polygons {
            for (i, ring) in poly.as_array().unwrap().iter().enumerate() {
                let ring = ring.as_array().unwrap();
                assert!(ring.len() >= 4);
                assert_eq!(ring.first(), ring.last(), "closed ring");
                assert!(
                    ring.iter().all(|p| p.as_array().unwrap().len() == 2),
                    "no z"
                );
                let a = signed_area(ring);
                assert!(
                    if i == 0 { a > 0.0 } else { a < 0.0 },
                    "winding of ring {i}: {a}"
                );
            }
        }
        assert!(story["properties"]["area_m2"].as_f64().unwrap() > 1.0);
    }
    let walls: Vec<&Value> = features
        .iter()
        .filter(|f| f["properties"]["kind"] == "wall")
        .collect();
    assert!(!walls.is_empty());
    for w in walls {
        assert_eq!(w["geometry"]["type"], "LineString");
        let model = w["properties"]["model"].as_str().unwrap();
        assert!(model == "line" || model == "arc");
        if model == "arc" {
            assert!(w["properties"]["radius"].as_f64().unwrap() > 0.0);
        }
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn a_simulated_scan_becomes_a_plan_over_http() {
    let s = server::start(Arc::new(PlanPipeline), |c| c.workers = 1).await;
    let scan = s.dir.path().join("scan");
    simulate(&scan);
    let form = reqwest::multipart::Form::new()
        .part(
            "cloud",
            reqwest::multipart::Part::bytes(std::fs::read(scan.join("cloud.ply")).unwrap())
                .file_name("cloud.ply"),
        )
        .part(
            "poses",
            reqwest::multipart::Part::bytes(std::fs::read(scan.join("poses.json")).unwrap()),
        );
    let res = s.post("/v1/jobs").multipart(form).send().await.unwrap();
    assert_eq!(res.status(), 202);
    let job: Value = res.json().await.unwrap();
    assert_eq!(job["upload"]["format"], "ply");
    let id = job["id"].as_str().unwrap();
    let done = s.wait_done(id, Duration::from_secs(300)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["input"]["format"], "ply");
    let doc: Value = s
        .get(&format!("/v1/jobs/{id}/plan.geojson"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    check_contract(&doc);
    let svg = s
        .get(&format!("/v1/jobs/{id}/plan.svg"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(svg.contains("<svg") && svg.contains("Level 0"));
    let dxf = s
        .get(&format!("/v1/jobs/{id}/plan.dxf"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(dxf.contains("AC1009") && dxf.contains("STORY_0") && dxf.ends_with("EOF\n"));
    // ezdxf opens it: a story layer and a walls layer for each story of the plan.
    if let Some(v) = server::ezdxf_summary(dxf.as_bytes()) {
        assert_eq!(
            (&v["version"], &v["insunits"], &v["errors"]),
            (&"AC1009".into(), &6.into(), &0.into()),
            "{v}"
        );
        let levels: Vec<i64> = doc["features"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["properties"]["kind"] == "story")
            .map(|f| f["properties"]["level"].as_i64().unwrap())
            .collect();
        assert!(!levels.is_empty());
        for level in levels {
            for layer in [format!("STORY_{level}"), format!("WALLS_{level}")] {
                assert!(
                    v["layers"].as_array().unwrap().iter().any(|l| *l == *layer),
                    "{layer}: {v}"
                );
                let entities: u64 = v["counts"]
                    .as_object()
                    .unwrap()
                    .iter()
                    .filter(|(k, _)| k.ends_with(&format!("@{layer}")))
                    .map(|(_, n)| n.as_u64().unwrap())
                    .sum();
                assert!(entities > 0, "{layer} is empty: {v}");
            }
        }
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn the_page_draws_a_simulated_scan() {
    if server::browser_missing().is_some() {
        return;
    }
    let s = server::start(Arc::new(PlanPipeline), |c| c.workers = 1).await;
    let scan = s.dir.path().join("scan");
    simulate(&scan);
    let shot = std::env::temp_dir().join("asbuilt-page-simulated.png");
    let poses = scan.join("poses.json");
    let seen =
        server::browser_upload(&s.base, &scan.join("cloud.ply"), Some(&poses), &shot, None).await;
    assert_eq!(seen["status"], "succeeded");
    assert!(seen["walls"].as_u64().unwrap() >= 4, "{seen}");
    // Poses were given: no warning, a green status.
    assert_eq!(seen["viewWarning"], "", "{seen}");
    assert_eq!(seen["statusWarn"], false, "{seen}");
}

/// The point limit is checked against the file's own count before the points are read: a PLY
/// header claiming four billion vertices fails at once with `too_many_points`, not after (or
/// instead of) allocating them; a real LAS over a small limit fails the same way.
#[tokio::test(flavor = "multi_thread")]
async fn over_limit_clouds_fail_before_they_are_read() {
    let s = server::start(Arc::new(PlanPipeline), |c| {
        c.workers = 1;
        c.max_points = 500;
    })
    .await;
    let claim = b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n\
                  property float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0"
        .to_vec();
    let world: Vec<[f64; 3]> = (0..1000)
        .map(|i| [i as f64 * 0.01, (i % 7) as f64, (i % 3) as f64])
        .collect();
    let las = s.dir.path().join("cloud.las");
    asbuilt_plan::io::export::write_las(
        &las,
        &asbuilt_plan::cloud::PointCloud::from_world(&world),
        false,
    )
    .unwrap();
    for (body, points) in [
        (claim, "4000000000"),
        (std::fs::read(&las).unwrap(), "1000"),
    ] {
        let job = s.upload(body).await;
        let done = s
            .wait_done(job["id"].as_str().unwrap(), Duration::from_secs(30))
            .await;
        assert_eq!(done["status"], "failed", "{done}");
        assert_eq!(done["error"]["code"], "too_many_points", "{done}");
        let message = done["error"]["message"].as_str().unwrap();
        assert!(
            message.contains(points) && message.contains("500"),
            "{message}"
        );
    }
}

/// A story's own failure reaches the client with its stage's code, not `no_plan`; and the
/// units check runs for jobs as for the CLI.
#[tokio::test]
async fn failures_carry_the_stage_code_and_the_units_check_runs() {
    let s = server::start(Arc::new(PlanPipeline), |c| c.workers = 1).await;
    let grid = |z: f64, out: &mut Vec<[f64; 3]>| {
        for i in 0..=200 {
            for j in 0..=150 {
                out.push([i as f64 * 0.02, j as f64 * 0.02, z]);
            }
        }
    };
    // Floor, ceiling and one wall: a story is found, but its samples are collinear.
    let mut wall_only = Vec::new();
    grid(0.0, &mut wall_only);
    grid(2.7, &mut wall_only);
    for i in 0..=200 {
        for k in 0..=135 {
            wall_only.push([i as f64 * 0.02, 1.5, k as f64 * 0.02]);
        }
    }
    // The same in millimetres.
    let millimetres: Vec<[f64; 3]> = wall_only.iter().map(|p| p.map(|c| c * 1000.0)).collect();
    for (points, code) in [(wall_only, "labeling_failed"), (millimetres, "wrong_units")] {
        let path = s.dir.path().join(format!("{code}.ply"));
        let cloud = asbuilt_plan::cloud::PointCloud::from_world(&points);
        asbuilt_plan::io::ply::write_ply(
            &path,
            &cloud,
            asbuilt_plan::io::ply::Encoding::BinaryLittleEndian,
        )
        .unwrap();
        let job = s.upload(std::fs::read(&path).unwrap()).await;
        let done = s
            .wait_done(job["id"].as_str().unwrap(), Duration::from_secs(60))
            .await;
        assert_eq!(done["status"], "failed", "{done}");
        assert_eq!(done["error"]["code"], code, "{done}");
    }
}
