//! `asbuilt plan --max-memory` gives the in-memory plan; `asbuilt bench` reports what it ran.

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

fn asbuilt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_asbuilt"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn ok(out: Output) -> Output {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn plan_without_timings(path: &Path) -> Value {
    let mut doc: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    doc["floorplan"]
        .as_object_mut()
        .unwrap()
        .remove("timings_ms")
        .expect("timings");
    doc
}

#[test]
fn max_memory_streams_to_the_same_plan() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = |p: &str| d.join(p).display().to_string();
    ok(asbuilt(&[
        "simulate",
        "--building",
        "rotated_l",
        "--points",
        "60000",
        "--out",
        &s(""),
    ]));
    let (poses, cloud) = (s("poses.json"), s("cloud.ply"));
    let common = ["--poses", &poses, "--quiet"];
    let mut args = vec!["plan", &cloud];
    args.extend(common);
    let whole = s("whole.geojson");
    let mut a = args.clone();
    a.extend(["-o", &whole]);
    ok(asbuilt(&a));
    let streamed = s("streamed.geojson");
    let timings = s("timings.json");
    let mut b = args.clone();
    b.extend([
        "-o",
        &streamed,
        "--max-memory",
        "3MiB",
        "--timings",
        &timings,
    ]);
    ok(asbuilt(&b));
    // A streamed plan keeps no points to look for lintels over door gaps, the jambs' points
    // or windows: its doors have no `head_z` and run between the plan's faces (within a few
    // centimetres), it has no windows, and a note says so. Everything else is equal.
    let (mut whole, mut streamed) = (
        plan_without_timings(Path::new(&whole)),
        plan_without_timings(Path::new(&streamed)),
    );
    let windows = |v: &Value| {
        v["features"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["properties"]["kind"] == "window")
            .count()
    };
    assert!(windows(&whole) > 0, "rotated_l has windows");
    assert_eq!(windows(&streamed), 0);
    whole["features"]
        .as_array_mut()
        .unwrap()
        .retain(|f| f["properties"]["kind"] != "window");
    let notes = streamed["floorplan"]["notes"].as_array_mut().unwrap();
    let before = notes.len();
    notes.retain(|n| {
        !n.as_str()
            .unwrap()
            .contains("no points held to look for lintels")
    });
    assert_eq!(notes.len() + 1, before, "{notes:?}");
    let mut doors = 0;
    for (w, s) in whole["features"]
        .as_array()
        .unwrap()
        .iter()
        .zip(streamed["features"].as_array_mut().unwrap())
    {
        if w["properties"]["kind"] == "door" {
            doors += 1;
            assert!(w["properties"]["head_z"].is_number(), "{w}");
            assert!(s["properties"]["head_z"].is_null(), "{s}");
            s["properties"]["head_z"] = w["properties"]["head_z"].clone();
            let width = |f: &Value| f["properties"]["width_m"].as_f64().unwrap();
            assert!((width(w) - width(s)).abs() <= 0.3, "{w} {s}");
            s["properties"]["width_m"] = w["properties"]["width_m"].clone();
            s["geometry"] = w["geometry"].clone();
        }
    }
    assert!(doors > 0, "rotated_l has a door");
    assert_eq!(whole, streamed);
    let t: Value = serde_json::from_str(&std::fs::read_to_string(&timings).unwrap()).unwrap();
    for stage in [
        "read",
        "tiles",
        "samples",
        "triangulate",
        "label",
        "write",
        "total",
    ] {
        assert!(t[stage].is_u64(), "{stage} missing from {t}");
    }

    let mut bad = args.clone();
    bad.extend(["--max-memory", "lots"]);
    let out = asbuilt(&bad);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--max-memory"));
}

#[test]
fn bench_reports_stages_memory_and_reads() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let json = d.join("bench.json").display().to_string();
    let cache = d.join("cache").display().to_string();
    let out = ok(asbuilt(&[
        "bench",
        "--sizes",
        "60k",
        "--formats",
        "ply",
        "--max-memory",
        "64MiB",
        "--read-size",
        "60k",
        "--read-formats",
        "ply,xyz",
        "--upload-size",
        "60k",
        "--upload-formats",
        "ply",
        "--cache",
        &cache,
        "--json",
        &json,
    ]));
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(table.contains("| 60k | ply | memory |"), "{table}");
    assert!(table.contains("| 60k | ply | stream 64MiB |"), "{table}");
    assert!(table.contains("| xyz | 60k |"), "{table}");
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let runs = doc["plan_runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    for run in runs {
        assert_eq!(run["points"], 60_000);
        assert!(run["peak_rss_bytes"].as_u64().unwrap() > 1 << 20, "{run}");
        assert!(run["plan_ms"].as_f64().unwrap() > 0.0);
        assert!(run["stages_ms"]["samples"].is_u64(), "{run}");
    }
    assert_eq!(doc["read_runs"].as_array().unwrap().len(), 2);
    // The upload table: the stored file's run and the early read's, each to `succeeded`.
    let uploads = doc["upload_runs"].as_array().unwrap();
    assert_eq!(uploads.len(), 2, "{uploads:?}");
    for (run, early) in uploads.iter().zip([false, true]) {
        assert_eq!(run["early"], early);
        assert!(run["last_byte_to_done_ms"].as_f64().unwrap() > 0.0, "{run}");
    }
    assert!(table.contains("| ply | 60k | yes |"), "{table}");
    // The cloud is cached: a second run simulates nothing.
    let again = ok(asbuilt(&[
        "bench",
        "--sizes",
        "60k",
        "--formats",
        "ply",
        "--no-read-table",
        "--no-upload-table",
        "--cache",
        &cache,
        "--json",
        &json,
    ]));
    assert!(!String::from_utf8_lossy(&again.stderr).contains("simulating"));
}
