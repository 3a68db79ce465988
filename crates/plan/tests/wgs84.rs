//! The WGS84 copy of a plan (io::wgs84, proj4rs) against an independent transformation: PROJ
//! itself, through python3 and pyproj. Every position must land within 1 cm of pyproj's.

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};

use asbuilt_plan::io::{self, geojson, poses, wgs84};
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
use asbuilt_plan::Params;
use serde_json::{json, Value};

const UTM33_WKT: &str = concat!(
    r#"PROJCS["WGS 84 / UTM zone 33N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84","#,
    r#"6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich","#,
    r#"0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],"#,
    r#"AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],"#,
    r#"PARAMETER["central_meridian",15],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting","#,
    r#"500000],PARAMETER["false_northing",0],UNIT["metre",1,AUTHORITY["EPSG","9001"]],"#,
    r#"AXIS["Easting",EAST],AXIS["Northing",NORTH],AUTHORITY["EPSG","32633"]]"#
);

const SCRIPT: &str = r#"
import json, sys
from pyproj import Transformer
out = []
for crs, xys in json.load(sys.stdin):
    t = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
    out.append([list(t.transform(x, y)) for x, y in xys])
print(json.dumps(out))
"#;

/// pyproj's longitude and latitude for each (crs, positions) job; `None` when python3 with
/// pyproj is missing outside CI (under CI that fails).
fn pyproj(jobs: &[(String, Vec<[f64; 2]>)]) -> Option<Vec<Vec<[f64; 2]>>> {
    let probe = Command::new("python3")
        .args(["-c", "import pyproj"])
        .output();
    if !matches!(&probe, Ok(o) if o.status.success()) {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must have python3 with pyproj (.ci/run's pip line)"
        );
        eprintln!("skipping the pyproj check: python3 has no pyproj (pip install pyproj)");
        return None;
    }
    let mut child = Command::new("python3")
        .args(["-c", SCRIPT])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let input = serde_json::to_vec(&json!(jobs)).unwrap();
    child.stdin.take().unwrap().write_all(&input).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "pyproj failed");
    Some(serde_json::from_slice(&out.stdout).unwrap())
}

/// Metres between two WGS84 positions a few centimetres apart (local flat earth).
fn metres(a: [f64; 2], b: [f64; 2]) -> f64 {
    let lat = a[1].to_radians();
    let dx = (a[0] - b[0]).to_radians() * 6_378_137.0 * lat.cos();
    let dy = (a[1] - b[1]).to_radians() * 6_378_137.0;
    dx.hypot(dy)
}

fn positions(v: &Value, out: &mut Vec<[f64; 2]>) {
    if let Some(items) = v.as_array() {
        if let [Value::Number(x), Value::Number(y), ..] = items.as_slice() {
            out.push([x.as_f64().unwrap(), y.as_f64().unwrap()]);
        } else {
            items.iter().for_each(|i| positions(i, out));
        }
    }
}

fn all_positions(doc: &Value) -> Vec<[f64; 2]> {
    let mut out = Vec::new();
    for f in doc["features"].as_array().unwrap() {
        positions(&f["geometry"]["coordinates"], &mut out);
    }
    out
}

#[test]
fn a_grid_in_five_projections_lands_within_1_cm_of_pyproj() {
    // Transverse Mercator on WGS84 and ETRS89, Swiss oblique Mercator with a datum shift,
    // French Lambert conformal conic; a 2 km grid around a point inside each.
    let centres = [
        ("EPSG:32633", 500_123.45, 5_700_321.12),
        ("EPSG:25832", 690_000.5, 5_335_000.25),
        ("EPSG:2056", 2_600_000.0, 1_200_000.0),
        ("EPSG:2154", 652_000.0, 6_862_000.0),
        ("EPSG:3006", 674_000.0, 6_580_000.0),
    ];
    let jobs: Vec<(String, Vec<[f64; 2]>)> = centres
        .iter()
        .map(|&(crs, x, y)| {
            let grid = (0..25)
                .map(|i| {
                    let (dx, dy) = (f64::from(i % 5) * 500.0, f64::from(i / 5) * 500.0);
                    [x - 1000.0 + dx + 0.123, y - 1000.0 + dy + 0.456]
                })
                .collect();
            (crs.to_string(), grid)
        })
        .collect();
    let Some(truth) = pyproj(&jobs) else { return };
    for ((crs, xys), want) in jobs.iter().zip(&truth) {
        let t = wgs84::ToWgs84::new(crs).unwrap();
        let worst = xys
            .iter()
            .zip(want)
            .map(|(&[x, y], &w)| metres(t.lon_lat(x, y).unwrap(), w))
            .fold(0.0, f64::max);
        eprintln!("{crs}: worst {:.2} mm from pyproj", worst * 1000.0);
        assert!(worst < 0.01, "{crs}: {worst} m from pyproj");
    }
}

fn path(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("asbuilt-wgs84-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn a_georeferenced_las_scan_plans_to_wgs84_within_1_cm_of_pyproj() {
    // A room in UTM 33N, written as LAS 1.4 with the CRS as WKT, planned from the file.
    let sim = simulate(
        BuildingKind::RotatedL,
        &ScanOptions {
            points: 200_000,
            seed: 3,
            offset: [500_321.0, 5_700_123.0, 112.0],
            ..Default::default()
        },
    )
    .unwrap();
    let asbuilt_plan::cloud::Viewpoints::Static(sim_poses) = &sim.cloud.viewpoints else {
        panic!("static scans have poses")
    };
    let sidecar = path("poses.json");
    poses::write_poses(&sidecar, sim_poses, sim.cloud.origin).unwrap();
    let las_path = path("room.las");
    let mut b = las::Builder::from((1, 4));
    b.point_format = las::point::Format::new(6).unwrap();
    let t = |offset| las::Transform {
        scale: 0.001,
        offset,
    };
    let o = sim.cloud.origin;
    b.transforms = las::Vector {
        x: t(o[0]),
        y: t(o[1]),
        z: t(o[2]),
    };
    let mut header = b.into_header().unwrap();
    header.set_wkt_crs(UTM33_WKT.as_bytes().to_vec()).unwrap();
    let mut w = las::Writer::from_path(&las_path, header).unwrap();
    for (i, p) in sim.cloud.xyz.iter().enumerate() {
        let [x, y, z] = [0, 1, 2].map(|k| o[k] + f64::from(p[k]));
        w.write_point(las::Point {
            x,
            y,
            z,
            point_source_id: sim.cloud.scan_ids[sim.cloud.scan[i] as usize] as u16,
            gps_time: Some(i as f64 * 0.001),
            return_number: 1,
            number_of_returns: 1,
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();

    let mut cloud = io::read_cloud(&las_path).unwrap();
    poses::load_poses(&mut cloud, &sidecar).unwrap();
    let plan = asbuilt_plan::plan(&cloud, &Params::default(), &mut NoProgress).unwrap();
    assert_eq!(plan.crs.as_deref(), Some(UTM33_WKT));
    let source = geojson::to_geojson(&plan);
    let copy = wgs84::to_wgs84_geojson(&plan);
    assert_eq!(
        copy["floorplan"]["georeferenced"], true,
        "{}",
        copy["floorplan"]
    );
    assert_eq!(copy["floorplan"]["crs"], "OGC:CRS84");
    assert_eq!(copy["floorplan"]["source_crs"], UTM33_WKT);
    let (from, to) = (all_positions(&source), all_positions(&copy));
    assert_eq!(from.len(), to.len());
    assert!(from.len() > 10, "{} positions", from.len());
    let Some(truth) = pyproj(&[("EPSG:32633".into(), from.clone())]) else {
        return;
    };
    let worst = to
        .iter()
        .zip(&truth[0])
        .map(|(&a, &b)| metres(a, b))
        .fold(0.0, f64::max);
    eprintln!(
        "plan of {} positions: worst {:.2} mm from pyproj",
        to.len(),
        worst * 1000.0
    );
    assert!(worst < 0.01, "{worst} m from pyproj");
    // The same copy is the `plan.wgs84.geojson` output.
    let out = io::outputs::by_file("plan.wgs84.geojson").unwrap();
    let bytes = (out.write)(&plan).unwrap();
    let parsed: Value = serde_json::from_slice(&bytes).unwrap();
    assert_eq!(parsed, copy);
}

#[test]
fn an_e57_carries_its_crs_from_coordinate_metadata() {
    // A few points in UTM 33N, with and without coordinateMetadata.
    for (meta, want) in [(Some(" EPSG:32633 "), Some("EPSG:32633")), (None, None)] {
        let p = path(&format!("crs-{}.e57", want.is_some()));
        let mut w = e57::E57Writer::from_file(&p, "asbuilt").unwrap();
        w.set_coordinate_metadata(meta.map(String::from));
        let prototype = vec![
            e57::Record::CARTESIAN_X_F64,
            e57::Record::CARTESIAN_Y_F64,
            e57::Record::CARTESIAN_Z_F64,
        ];
        let mut pc = w.add_pointcloud("scan", prototype).unwrap();
        for i in 0..20 {
            let f = f64::from(i);
            use e57::RecordValue::Double;
            pc.add_point(vec![
                Double(500_000.0 + f),
                Double(5_700_000.0 + f),
                Double(f),
            ])
            .unwrap();
        }
        pc.finalize().unwrap();
        w.finalize().unwrap();
        let cloud = io::read_cloud(&p).unwrap();
        assert_eq!(cloud.crs.as_deref(), want, "{meta:?}");
        if let Some(crs) = want {
            let [lon, lat] = wgs84::ToWgs84::new(crs)
                .unwrap()
                .lon_lat(500_000.0, 5_700_000.0)
                .unwrap();
            // The central meridian of zone 33 is 15° east; 5,700 km north is about 51.4°.
            assert!(
                (lon - 15.0).abs() < 1e-9 && (51.0..52.0).contains(&lat),
                "{lon} {lat}"
            );
        }
    }
}
