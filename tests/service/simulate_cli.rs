//! `asbuilt simulate` as users run it: the files it writes read back, and bad options fail in
//! one line.

use std::process::{Command, Output};

fn asbuilt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_asbuilt"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// A fresh folder inside a temporary directory that is removed when the guard drops.
fn out_dir(name: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join(name);
    (tmp, dir)
}

#[test]
fn static_scan_writes_cloud_poses_and_truth() {
    let (_tmp, dir) = out_dir("static");
    let d = dir.to_str().unwrap();
    let out = asbuilt(&[
        "simulate",
        "--building",
        "rotated_l",
        "--points",
        "20000",
        "--seed",
        "3",
        "--registration-error",
        "0.01,0.1",
        "--noise",
        "0.002",
        "--offset",
        "500000,4100000,-20",
        "--out",
        d,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info = asbuilt(&[
        "info",
        dir.join("cloud.ply").to_str().unwrap(),
        "--poses",
        dir.join("poses.json").to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
    // Rays that leave through the L's windows measure nothing and are not replaced.
    let points: usize = text
        .split("points: ")
        .nth(1)
        .and_then(|r| r.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|n| n.parse().ok())
        .expect("a point count");
    assert!((19_000..=20_000).contains(&points), "{text}");
    assert!(text.contains("poses: 3"), "{text}");
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["type"], "FeatureCollection");
    assert_eq!(truth["truth"]["building"], "rotated_l");
    let story = &truth["features"][0];
    assert_eq!(story["properties"]["kind"], "story");
    // World coordinates: the offset is kept.
    let x = story["geometry"]["coordinates"][0][0][0].as_f64().unwrap();
    assert!((x - 500_000.0).abs() < 50.0, "{x}");
    let walls = truth["truth"]["stories"][0]["walls"].as_array().unwrap();
    assert!(walls.iter().all(|w| w["model"] == "line"));
}

#[test]
fn mobile_ascii_scan_writes_a_trajectory() {
    let (_tmp, dir) = out_dir("mobile");
    let d = dir.to_str().unwrap();
    let out = asbuilt(&[
        "simulate",
        "--building",
        "curved_lobby",
        "--points",
        "5000",
        "--mobile",
        "--ascii",
        "--out",
        d,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let head = std::fs::read(dir.join("cloud.ply")).unwrap();
    assert!(head.starts_with(b"ply\nformat ascii 1.0\n"));
    let info = asbuilt(&[
        "info",
        dir.join("cloud.ply").to_str().unwrap(),
        "--trajectory",
        dir.join("trajectory.json").to_str().unwrap(),
    ]);
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
    let truth = std::fs::read_to_string(dir.join("truth.json")).unwrap();
    assert!(
        truth.contains("\"model\":\"arc\""),
        "the lobby has an arc wall"
    );
}

#[test]
fn bad_options_fail_in_one_line() {
    let (_tmp, dir) = out_dir("bad");
    let d = dir.to_str().unwrap();
    for (args, want) in [
        (vec!["--building", "castle"], "unknown building `castle`"),
        (
            vec!["--building", "square_room", "--offset", "1,2"],
            "--offset takes 3",
        ),
        (
            vec!["--building", "square_room", "--registration-error", "x,1"],
            "--registration-error",
        ),
        (vec!["--building", "square_room", "--points", "0"], "points"),
    ] {
        let mut all = vec!["simulate", "--out", d];
        all.extend(args);
        let out = asbuilt(&all);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(want), "{err:?} should mention {want:?}");
    }
}

#[test]
fn the_readme_command_line_simulates_plans_and_reports_stage_times() {
    let (_tmp, dir) = out_dir("readme");
    let d = dir.to_str().unwrap();
    let sim = asbuilt(&[
        "simulate",
        "--building",
        "square_room",
        "--points",
        "150000",
        "--out",
        d,
    ]);
    assert!(sim.status.success(), "{sim:?}");
    let (geojson, svg) = (dir.join("plan.geojson"), dir.join("plan.svg"));
    let plan = asbuilt(&[
        "plan",
        dir.join("cloud.ply").to_str().unwrap(),
        "--poses",
        dir.join("poses.json").to_str().unwrap(),
        "-o",
        geojson.to_str().unwrap(),
        "--svg",
        svg.to_str().unwrap(),
        "--ifc",
        dir.join("plan.ifc").to_str().unwrap(),
        "--rooms",
        dir.join("rooms.csv").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&plan.stderr);
    assert!(plan.status.success(), "{err}");
    // The closing report: what was found, then every stage's time.
    assert!(err.contains("150000 points (ply), 1 story"), "{err}");
    assert!(err.contains("timings (ms):"), "{err}");
    for stage in [
        "read", "stories", "samples", "label", "fit", "write", "total",
    ] {
        assert!(
            err.lines().any(|l| l.trim_start().starts_with(stage)),
            "no {stage} time in {err}"
        );
    }
    let plan: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&geojson).unwrap()).unwrap();
    assert_eq!(plan["floorplan"]["input"]["points"], 150000);
    assert_eq!(plan["floorplan"]["input"]["scans"], 1);
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
    // The IFC has a storey per story of the GeoJSON; the schedule a row per room.
    let ifc = std::fs::read_to_string(dir.join("plan.ifc")).unwrap();
    let kinds = |kind: &str| {
        plan["features"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["properties"]["kind"] == kind)
            .count()
    };
    assert_eq!(ifc.matches("=IFCBUILDINGSTOREY(").count(), kinds("story"));
    assert_eq!(ifc.matches("=IFCSPACE(").count(), kinds("room"));
    let csv = std::fs::read_to_string(dir.join("rooms.csv")).unwrap();
    assert!(csv.starts_with("level,room,area_m2,"), "{csv}");
    assert_eq!(csv.lines().count(), 1 + kinds("room"), "{csv}");
}
