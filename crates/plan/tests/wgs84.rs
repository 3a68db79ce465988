//! The WGS84 copy of a plan (io::wgs84, proj4rs) against an independent transformation: PROJ
//! itself, through python3 and pyproj. Every position must land within 1 cm of pyproj's: for
//! projected CRSs (scans that declare one as LAS WKT, LAS GeoTIFF keys or E57 coordinate
//! metadata, or a CRS the caller gives), and for a caller's local frame (anchor, rotation to
//! north, height), checked against PROJ's topocentric (east, north, up) conversion.

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};

use asbuilt_plan::cloud::{ScanPose, Viewpoints};
use asbuilt_plan::georef::Georeference;
use asbuilt_plan::io::{self, geojson, poses, wgs84};
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
use asbuilt_plan::{FloorPlan, Params};
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
    lands_within_1_cm_of_pyproj(&plan, UTM33_WKT, "EPSG:32633");
}

/// The plan's WGS84 copy against pyproj's transformation of the plan's own positions from
/// `truth_crs`; `source_crs` is what the copy must name.
fn lands_within_1_cm_of_pyproj(plan: &FloorPlan, source_crs: &str, truth_crs: &str) {
    let source = geojson::to_geojson(plan);
    assert_eq!(source["floorplan"]["crs"], source_crs);
    let copy = wgs84::to_wgs84_geojson(plan);
    assert_eq!(
        copy["floorplan"]["georeferenced"], true,
        "{}",
        copy["floorplan"]
    );
    assert_eq!(copy["floorplan"]["crs"], "OGC:CRS84");
    assert_eq!(copy["floorplan"]["source_crs"], source_crs);
    let (from, to) = (all_positions(&source), all_positions(&copy));
    assert_eq!(from.len(), to.len());
    assert!(from.len() > 10, "{} positions", from.len());
    // The same copy is the `plan.wgs84.geojson` output.
    let out = io::outputs::by_file("plan.wgs84.geojson").unwrap();
    let bytes = (out.write)(plan).unwrap();
    let parsed: Value = serde_json::from_slice(&bytes).unwrap();
    assert_eq!(parsed, copy);
    let Some(truth) = pyproj(&[(truth_crs.into(), from.clone())]) else {
        return;
    };
    let worst = to
        .iter()
        .zip(&truth[0])
        .map(|(&a, &b)| metres(a, b))
        .fold(0.0, f64::max);
    eprintln!(
        "{truth_crs}: plan of {} positions, worst {:.2} mm from pyproj",
        to.len(),
        worst * 1000.0
    );
    assert!(worst < 0.01, "{worst} m from pyproj");
}

/// A simulated room at a UTM 32N (ETRS89) position, with its static poses.
fn room_at_utm32(points: usize, seed: u64) -> (asbuilt_plan::PointCloud, Vec<ScanPose>) {
    let sim = simulate(
        BuildingKind::RotatedL,
        &ScanOptions {
            points,
            seed,
            offset: [691_234.0, 5_334_567.0, 410.0],
            ..Default::default()
        },
    )
    .unwrap();
    let Viewpoints::Static(poses) = &sim.cloud.viewpoints else {
        panic!("static scans have poses")
    };
    let poses = poses.clone();
    (sim.cloud, poses)
}

/// A GeoTIFF key directory (LAS `LASF_Projection` record 34735) naming a projected EPSG code.
fn geotiff_keys(epsg: u16) -> Vec<u8> {
    // Version 1.1.0 with 3 keys: model type projected, raster type pixel-is-area, the CRS.
    let words: [u16; 16] = [1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, epsg];
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

#[test]
fn a_las_with_an_epsg_code_plans_to_wgs84_within_1_cm_of_pyproj() {
    // LAS 1.2 as most survey software writes it: the CRS as GeoTIFF keys, no WKT.
    let (cloud, sim_poses) = room_at_utm32(150_000, 5);
    let sidecar = path("poses-32.json");
    poses::write_poses(&sidecar, &sim_poses, cloud.origin).unwrap();
    let las_path = path("room-epsg.las");
    let mut b = las::Builder::from((1, 2));
    b.point_format = las::point::Format::new(1).unwrap();
    let t = |offset| las::Transform {
        scale: 0.001,
        offset,
    };
    let o = cloud.origin;
    b.transforms = las::Vector {
        x: t(o[0]),
        y: t(o[1]),
        z: t(o[2]),
    };
    b.vlrs.push(las::Vlr {
        user_id: "LASF_Projection".into(),
        record_id: 34735,
        description: "GeoKeyDirectoryTag".into(),
        data: geotiff_keys(25832),
    });
    let header = b.into_header().unwrap();
    let mut w = las::Writer::from_path(&las_path, header).unwrap();
    for (i, p) in cloud.xyz.iter().enumerate() {
        let [x, y, z] = [0, 1, 2].map(|k| o[k] + f64::from(p[k]));
        w.write_point(las::Point {
            x,
            y,
            z,
            point_source_id: cloud.scan_ids[cloud.scan[i] as usize] as u16,
            gps_time: Some(i as f64 * 0.001),
            return_number: 1,
            number_of_returns: 1,
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();

    let mut read = io::read_cloud(&las_path).unwrap();
    assert_eq!(read.crs.as_deref(), Some("EPSG:25832"));
    poses::load_poses(&mut read, &sidecar).unwrap();
    let plan = asbuilt_plan::plan(&read, &Params::default(), &mut NoProgress).unwrap();
    lands_within_1_cm_of_pyproj(&plan, "EPSG:25832", "EPSG:25832");
}

#[test]
fn an_e57_with_coordinate_metadata_plans_to_wgs84_within_1_cm_of_pyproj() {
    // The poses travel in the E57 itself; its coordinateMetadata names the CRS.
    let (mut cloud, _) = room_at_utm32(150_000, 6);
    cloud.crs = Some("EPSG:25832".into());
    let e57_path = path("room.e57");
    io::export::write_e57(&e57_path, &cloud).unwrap();
    let read = io::read_cloud(&e57_path).unwrap();
    assert_eq!(read.crs.as_deref(), Some("EPSG:25832"));
    assert!(matches!(read.viewpoints, Viewpoints::Static(_)));
    let plan = asbuilt_plan::plan(&read, &Params::default(), &mut NoProgress).unwrap();
    lands_within_1_cm_of_pyproj(&plan, "EPSG:25832", "EPSG:25832");
}

const TOPOCENTRIC: &str = r#"
import json, math, sys
from pyproj import Transformer
out = []
for (lon, lat, h, at, rot, xys) in json.load(sys.stdin):
    # East, north, up at the anchor back to the ellipsoid: PROJ's topocentric conversion.
    t = Transformer.from_pipeline(
        f"+proj=pipeline +step +inv +proj=topocentric +ellps=WGS84 +lon_0={lon} +lat_0={lat} +h_0={h} "
        "+step +inv +proj=cart +ellps=WGS84 +step +proj=unitconvert +xy_in=rad +xy_out=deg")
    a = math.radians(rot)
    res = []
    for x, y in xys:
        dx, dy = x - at[0], y - at[1]
        e = dx * math.cos(a) + dy * math.sin(a)
        n = -dx * math.sin(a) + dy * math.cos(a)
        lo, la, _ = t.transform(e, n, 0.0)
        res.append([lo, la])
    out.append(res)
print(json.dumps(out))
"#;

/// pyproj's longitude and latitude of local positions in each frame, through the topocentric
/// (east, north, up) conversion; `None` when pyproj is missing outside CI.
fn pyproj_local(frames: &[(Georeference, Vec<[f64; 2]>)]) -> Option<Vec<Vec<[f64; 2]>>> {
    pyproj(&[])?;
    let jobs: Vec<Value> = frames
        .iter()
        .map(|(g, xys)| {
            let [lon, lat, h] = g.anchor.unwrap();
            json!([
                lon,
                lat,
                h,
                g.anchor_at.unwrap_or_default(),
                g.north_rotation.unwrap_or(0.0),
                xys
            ])
        })
        .collect();
    let mut child = Command::new("python3")
        .args(["-c", TOPOCENTRIC])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let input = serde_json::to_vec(&jobs).unwrap();
    child.stdin.take().unwrap().write_all(&input).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "pyproj failed");
    Some(serde_json::from_slice(&out.stdout).unwrap())
}

fn frames() -> Vec<Georeference> {
    // Zürich with a datum, San Francisco turned west, Sydney upside down and 2 km up, Tromsø.
    let frame = |anchor, at: Option<[f64; 3]>, rot: Option<f64>| Georeference {
        anchor: Some(anchor),
        anchor_at: at,
        north_rotation: rot,
        height_datum: Some("EPSG:5728".into()),
        ..Default::default()
    };
    vec![
        frame(
            [8.5417, 47.3769, 408.0],
            Some([100.0, -50.0, 1.2]),
            Some(12.5),
        ),
        frame([-122.4194, 37.7749, 15.0], None, Some(-75.0)),
        frame(
            [151.2093, -33.8688, 2000.0],
            Some([-20.0, 35.5, 0.0]),
            Some(190.0),
        ),
        frame([18.9553, 69.6492, 0.0], None, None),
    ]
}

#[test]
fn a_local_frame_lands_within_1_cm_of_pyprojs_topocentric_conversion() {
    // Each frame: a 600 m square grid of local positions around its anchor.
    let jobs: Vec<(Georeference, Vec<[f64; 2]>)> = frames()
        .into_iter()
        .map(|g| {
            let [ax, ay, _] = g.anchor_at.unwrap_or_default();
            let grid = (0..49)
                .map(|i| {
                    let (dx, dy) = (f64::from(i % 7) * 100.0, f64::from(i / 7) * 100.0);
                    [ax - 300.0 + dx + 0.37, ay - 300.0 + dy - 0.21]
                })
                .collect();
            (g, grid)
        })
        .collect();
    let Some(truth) = pyproj_local(&jobs) else {
        return;
    };
    for ((g, xys), want) in jobs.iter().zip(&truth) {
        g.check().unwrap();
        let t = g.to_wgs84().unwrap();
        let worst = xys
            .iter()
            .zip(want)
            .map(|(&[x, y], &w)| metres(t.lon_lat(x, y).unwrap(), w))
            .fold(0.0, f64::max);
        eprintln!("{:?}: worst {:.2} mm from pyproj", g.anchor, worst * 1000.0);
        assert!(worst < 0.01, "{g:?}: {worst} m from pyproj");
    }
}

#[test]
fn a_plan_in_a_given_local_frame_lands_within_1_cm_and_declares_it() {
    // A room in its scanner's own metres, placed by the caller: anchor, rotation, datum.
    let sim = simulate(
        BuildingKind::SquareRoom,
        &ScanOptions {
            points: 60_000,
            seed: 2,
            ..Default::default()
        },
    )
    .unwrap();
    let g = frames().remove(0);
    let params = Params::default();
    let p = path("local.ply");
    io::ply::write_ply(&p, &sim.cloud, io::ply::Encoding::BinaryLittleEndian).unwrap();
    let scan = asbuilt_plan::Scan {
        cloud: &p,
        sidecar: None,
        read: io::ReadOptions::default(),
        params: &params,
        stream: None,
        max_points: None,
        georeference: Some(g.clone()),
    };
    let plan = asbuilt_plan::plan_scan(&scan, &mut NoProgress)
        .unwrap()
        .plan;
    let doc = geojson::to_geojson(&plan);
    let meta = &doc["floorplan"];
    assert_eq!(meta["georeference"]["source"], "given");
    assert_eq!(meta["georeference"]["anchor"], json!(g.anchor.unwrap()));
    assert_eq!(meta["georeference"]["north_rotation"], 12.5);
    assert_eq!(meta["georeference"]["height_datum"], "EPSG:5728");
    let crs = meta["crs"].as_str().unwrap();
    assert!(
        crs.starts_with("+proj=ortho ") && crs.contains("+alpha=12.5"),
        "{crs}"
    );
    let copy = wgs84::to_wgs84_geojson(&plan);
    assert_eq!(
        copy["floorplan"]["georeferenced"], true,
        "{}",
        copy["floorplan"]
    );
    assert_eq!(copy["floorplan"]["georeference"], meta["georeference"]);
    let (from, to) = (all_positions(&doc), all_positions(&copy));
    assert!(from.len() > 10);
    let Some(truth) = pyproj_local(&[(g, from)]) else {
        return;
    };
    let worst = to
        .iter()
        .zip(&truth[0])
        .map(|(&a, &b)| metres(a, b))
        .fold(0.0, f64::max);
    eprintln!("local plan: worst {:.2} mm from pyproj", worst * 1000.0);
    assert!(worst < 0.01, "{worst} m from pyproj");
}

#[test]
fn a_given_crs_replaces_the_scans_own_and_says_so() {
    // The E57 says UTM 33N (WGS84); the caller knows better: ETRS89 / UTM 32N.
    let (mut cloud, _) = room_at_utm32(30_000, 7);
    cloud.crs = Some("EPSG:32633".into());
    let p = path("wrong-crs.e57");
    io::export::write_e57(&p, &cloud).unwrap();
    let params = Params::default();
    let scan = asbuilt_plan::Scan {
        cloud: &p,
        sidecar: None,
        read: io::ReadOptions::default(),
        params: &params,
        stream: None,
        max_points: None,
        georeference: Some(Georeference::of_crs("EPSG:25832")),
    };
    let plan = asbuilt_plan::plan_scan(&scan, &mut NoProgress)
        .unwrap()
        .plan;
    assert_eq!(
        plan.crs.as_deref(),
        Some("EPSG:32633"),
        "what the scan said"
    );
    assert!(
        plan.notes
            .iter()
            .any(|n| n.contains("replaces the CRS the scan declares (EPSG:32633)")),
        "{:?}",
        plan.notes
    );
    let doc = geojson::to_geojson(&plan);
    assert_eq!(doc["floorplan"]["georeference"]["source"], "given");
    lands_within_1_cm_of_pyproj(&plan, "EPSG:25832", "EPSG:25832");
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
