//! The `asbuilt` binary as users run it: exit codes, one-line errors, help.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn asbuilt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_asbuilt"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A failure must be one line, `asbuilt: <reason>`, and a non-zero exit.
fn assert_one_line_failure(out: &Output) -> String {
    assert!(!out.status.success(), "expected failure");
    let err = stderr(out);
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "not one line: {err}");
    assert!(lines[0].starts_with("asbuilt: "), "{err}");
    lines[0].to_string()
}

/// Writes an ASCII PLY with the given points (and a `scan_index` per point) and returns its path.
fn write_ascii_ply(dir: &Path, name: &str, points: &[([f32; 3], u32)]) -> PathBuf {
    let mut text = format!(
        "ply\nformat ascii 1.0\ncomment written by the asbuilt CLI tests\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\nproperty uint scan_index\nend_header\n",
        points.len()
    );
    for ([x, y, z], scan) in points {
        text.push_str(&format!("{x} {y} {z} {scan}\n"));
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Four points spanning 2 × 3 × 2.5 m, from two scans.
fn small_cloud(dir: &Path) -> PathBuf {
    write_ascii_ply(
        dir,
        "small.ply",
        &[
            ([0.0, 0.0, 0.0], 0),
            ([2.0, 0.0, 0.0], 0),
            ([2.0, 3.0, 2.5], 1),
            ([0.0, 3.0, 2.5], 1),
        ],
    )
}

#[test]
fn help_lists_the_commands_and_plan_options() {
    let out = asbuilt(&["--help"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for cmd in ["plan", "info", "simulate"] {
        assert!(text.contains(cmd), "--help lacks {cmd}: {text}");
    }
    let out = asbuilt(&["plan", "--help"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for opt in [
        "--output",
        "--svg",
        "--dxf",
        "--ifc",
        "--rooms",
        "--geojson",
        "--poses",
        "--trajectory",
        "--params",
        "--param",
        "--registration-error",
        "--scale",
        "--emit-samples",
        "--quiet",
    ] {
        assert!(text.contains(opt), "plan --help lacks {opt}: {text}");
    }
}

#[test]
fn missing_input_fails_in_one_line_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("no-such-scan.ply");
    let output = dir.path().join("plan.geojson");
    let out = asbuilt(&[
        "plan",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--quiet",
    ]);
    let line = assert_one_line_failure(&out);
    assert!(line.contains("no-such-scan.ply"), "{line}");
    // The reason is said once, not again as the error's source.
    let reason = std::fs::File::open(&input).unwrap_err().to_string();
    assert_eq!(line.matches(&*reason).count(), 1, "{line}");
    assert!(!output.exists(), "a failed run must not leave an output");
    assert!(out.stdout.is_empty());

    let out = asbuilt(&["info", input.to_str().unwrap()]);
    let line = assert_one_line_failure(&out);
    assert!(line.contains("no-such-scan.ply"), "{line}");
}

#[test]
fn unknown_parameter_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let input = small_cloud(dir.path());
    let out = asbuilt(&["plan", input.to_str().unwrap(), "--param", "bogus.x=1"]);
    let line = assert_one_line_failure(&out);
    assert!(line.contains("bogus.x"), "{line}");

    let out = asbuilt(&[
        "plan",
        input.to_str().unwrap(),
        "--param",
        "samples.cell_size=wide",
    ]);
    let line = assert_one_line_failure(&out);
    assert!(line.contains("samples.cell_size"), "{line}");

    // Out of range: refused before the cloud is read, naming the parameter.
    let out = asbuilt(&[
        "plan",
        input.to_str().unwrap(),
        "--param",
        "labeling.min_rays=0",
    ]);
    let line = assert_one_line_failure(&out);
    assert!(line.contains("labeling.min_rays"), "{line}");
}

#[test]
fn bad_parameter_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let input = small_cloud(dir.path());
    let params = dir.path().join("run.toml");
    std::fs::write(&params, "[stories]\nbogus = 1\n").unwrap();
    let out = asbuilt(&[
        "plan",
        input.to_str().unwrap(),
        "--params",
        params.to_str().unwrap(),
    ]);
    let line = assert_one_line_failure(&out);
    assert!(line.contains("run.toml"), "{line}");
    assert!(line.contains("bogus"), "{line}");
}

#[test]
fn bad_flags_fail_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    // The input does not exist: each error below must come first, naming its flag.
    let input = dir.path().join("later.ply");
    let input = input.to_str().unwrap();
    let line = assert_one_line_failure(&asbuilt(&["plan", input, "--scale", "0"]));
    assert!(line.contains("--scale"), "{line}");
    let line = assert_one_line_failure(&asbuilt(&["plan", input, "--registration-error=-1"]));
    assert!(line.contains("--registration-error"), "{line}");
    let missing = dir.path().join("absent").join("plan.svg");
    let line = assert_one_line_failure(&asbuilt(&[
        "plan",
        input,
        "--svg",
        missing.to_str().unwrap(),
    ]));
    assert!(line.contains("absent"), "{line}");
    assert!(!line.contains("later.ply"), "{line}");
}

#[test]
fn poses_and_trajectory_are_exclusive() {
    let out = asbuilt(&[
        "plan",
        "x.ply",
        "--poses",
        "p.json",
        "--trajectory",
        "t.json",
    ]);
    // A usage error: clap's exit code 2, and a message naming both flags.
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(
        err.contains("--poses") && err.contains("--trajectory"),
        "{err}"
    );
}

#[test]
fn info_reports_the_cloud_or_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let input = small_cloud(dir.path());
    let out = asbuilt(&["info", input.to_str().unwrap()]);
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("points: 4\n"), "{text}");
    assert!(text.contains("format: ply"), "{text}");
    assert!(text.contains("scans: 2"), "{text}");
    assert!(text.contains("size: 2.000 x 3.000 x 2.500 m"), "{text}");
    // A missing file fails on one line that names it.
    let missing = dir.path().join("missing.ply");
    let line = assert_one_line_failure(&asbuilt(&["info", missing.to_str().unwrap()]));
    assert!(line.contains("missing.ply"), "{line}");
}

/// A one-story room scanned in millimetres, as XYZ text with the scan index in column 3.
fn millimetre_room(dir: &Path) -> PathBuf {
    let mut text = String::from("x y z scan\n");
    for i in 0..200 {
        let t = f64::from(i) / 199.0;
        text.push_str(&format!(
            "{} {} {} {}\n",
            4000.0 * t,
            3000.0 * (1.0 - t),
            2700.0 * t,
            i % 2
        ));
    }
    let path = dir.join("room.txt");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_millimetre_cloud_is_refused_with_the_scale_to_use() {
    let dir = tempfile::tempdir().unwrap();
    let input = millimetre_room(dir.path());
    let line = assert_one_line_failure(&asbuilt(&["plan", input.to_str().unwrap(), "--quiet"]));
    assert!(
        line.contains("room.txt") && line.contains("--scale 0.001"),
        "{line}"
    );

    let out = asbuilt(&["info", input.to_str().unwrap(), "--scan-column", "3"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("format: xyz"), "{text}");
    assert!(text.contains("units: m (assumed)\n"), "{text}");
    assert!(text.contains("units warning:"), "{text}");
    assert!(text.contains("scans: 2 (0, 1)"), "{text}");

    let out = asbuilt(&[
        "info",
        input.to_str().unwrap(),
        "--scale",
        "0.001",
        "--format",
        "xyz",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("units: m (coordinates multiplied by 0.001"),
        "{text}"
    );
    assert!(!text.contains("units warning"), "{text}");
    assert!(text.contains("size: 4.000 x 3.000 x 2.700 m"), "{text}");
}

/// `plan --anchor ... --north-rotation ... --wgs84 FILE`: the plan declares the local frame
/// and its WGS84 copy is placed by it; `--crs` replaces the scan's; bad ones fail in one line
/// naming the flag, before the cloud is read.
#[test]
fn a_georeference_given_on_the_command_line_places_the_plan() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().to_str().unwrap();
    let out = asbuilt(&[
        "simulate",
        "--building",
        "square_room",
        "--points",
        "20000",
        "--seed",
        "4",
        "--out",
        d,
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let cloud = tmp.path().join("cloud.ply");
    let poses = tmp.path().join("poses.json");
    let (geojson, wgs84) = (
        tmp.path().join("p.geojson"),
        tmp.path().join("p.wgs84.geojson"),
    );
    let out = asbuilt(&[
        "plan",
        cloud.to_str().unwrap(),
        "--poses",
        poses.to_str().unwrap(),
        "--anchor",
        "-122.4194,37.7749,15",
        "--north-rotation",
        "-90",
        "--height-datum",
        "EPSG:5703",
        "-o",
        geojson.to_str().unwrap(),
        "--wgs84",
        wgs84.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (plan, copy) = (read(&geojson), read(&wgs84));
    let g = &plan["floorplan"]["georeference"];
    assert_eq!(g["anchor"], serde_json::json!([-122.4194, 37.7749, 15.0]));
    assert_eq!(g["north_rotation"], -90.0);
    assert_eq!(g["height_datum"], "EPSG:5703");
    assert_eq!(g["source"], "given");
    assert_eq!(
        copy["floorplan"]["georeferenced"], true,
        "{}",
        copy["floorplan"]
    );
    // +y points west: a position's local y is metres west of the anchor, x metres north.
    let local = &plan["features"][0]["geometry"]["coordinates"][0][0];
    let world = &copy["features"][0]["geometry"]["coordinates"][0][0];
    let (x, y) = (local[0].as_f64().unwrap(), local[1].as_f64().unwrap());
    let (lon, lat) = (world[0].as_f64().unwrap(), world[1].as_f64().unwrap());
    let east = (lon + 122.4194).to_radians() * 6_378_137.0 * 37.7749f64.to_radians().cos();
    let north = (lat - 37.7749).to_radians() * 6_356_752.0;
    assert!(
        (east + y).abs() < 0.05 && (north - x).abs() < 0.05,
        "({x}, {y}) → {east} E, {north} N"
    );

    let input = cloud.to_str().unwrap();
    let line = assert_one_line_failure(&asbuilt(&["plan", input, "--crs", "EPSG:4326"]));
    assert!(
        line.contains("--crs") && line.contains("geographic"),
        "{line}"
    );
    let line = assert_one_line_failure(&asbuilt(&["plan", input, "--anchor", "8,95,0"]));
    assert!(line.contains("--anchor"), "{line}");
    let out = asbuilt(&["plan", input, "--north-rotation", "3"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--anchor"), "{}", stderr(&out));
}
