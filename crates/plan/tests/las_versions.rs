//! LAS 1.0 to 1.4 read with scale and offset applied, `point_source_id` as the scan and
//! `gps_time` as the time; the CRS, from WKT or GeoTIFF keys, reaches `floorplan.crs`.

use std::path::{Path, PathBuf};

use asbuilt_plan::cloud::PointCloud;
use asbuilt_plan::io::{self, geojson, poses};
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
use asbuilt_plan::Params;

const WKT: &str =
    "PROJCS[\"ETRS89 / UTM zone 32N\",GEOGCS[\"ETRS89\"],AUTHORITY[\"EPSG\",\"25832\"]]";

fn path(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("asbuilt-las-versions-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn transforms(offset: [f64; 3]) -> las::Vector<las::Transform> {
    let t = |offset| las::Transform {
        scale: 0.001,
        offset,
    };
    las::Vector {
        x: t(offset[0]),
        y: t(offset[1]),
        z: t(offset[2]),
    }
}

/// A GeoKeyDirectoryTag holding ProjectedCRSGeoKey (3072) = `epsg`.
fn geotiff_vlr(epsg: u16) -> las::Vlr {
    let keys: [u16; 8] = [1, 1, 0, 1, 3072, 0, 1, epsg];
    las::Vlr {
        user_id: "LASF_Projection".into(),
        record_id: 34735,
        description: "GeoKeyDirectoryTag".into(),
        data: keys.iter().flat_map(|k| k.to_le_bytes()).collect(),
    }
}

/// Writes `cloud` (world = origin + local) as LAS `minor` in point `format`.
fn write(path: &Path, cloud: &PointCloud, minor: u8, format: u8, crs: Option<&str>) {
    let mut b = las::Builder::from((1, minor));
    b.point_format = las::point::Format::new(format).unwrap();
    b.transforms = transforms(cloud.origin);
    if crs == Some("geotiff") {
        b.vlrs.push(geotiff_vlr(25832));
    }
    let mut header = b.into_header().unwrap();
    if crs == Some("wkt") {
        header.set_wkt_crs(WKT.as_bytes().to_vec()).unwrap();
    }
    let mut w = las::Writer::from_path(path, header).unwrap();
    let has_time = w.header().point_format().has_gps_time;
    let has_color = w.header().point_format().has_color;
    for (i, p) in cloud.xyz.iter().enumerate() {
        let [x, y, z] = [0, 1, 2].map(|k| cloud.origin[k] + f64::from(p[k]));
        w.write_point(las::Point {
            x,
            y,
            z,
            point_source_id: cloud
                .scan
                .get(i)
                .map_or(0, |&s| cloud.scan_ids[s as usize] as u16),
            gps_time: has_time.then_some(i as f64 * 0.001),
            color: has_color.then_some(las::Color::new(10, 20, 30)),
            return_number: 1,
            number_of_returns: 1,
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();
}

#[test]
fn every_version_reads_with_scale_offset_scans_and_times() {
    let origin = [512_000.0, 5_400_000.0, 200.0];
    let pts: Vec<[f64; 3]> = (0..40)
        .map(|i| {
            let f = f64::from(i);
            [
                origin[0] + 1.25 + f,
                origin[1] + 2.5 - f * 0.5,
                origin[2] + f * 0.1,
            ]
        })
        .collect();
    let mut cloud = PointCloud::from_world(&pts);
    cloud.scan_ids = vec![11, 4];
    cloud.scan = (0..40).map(|i| u16::from(i % 2 == 1)).collect();
    for (minor, format) in [(0, 1), (1, 1), (2, 3), (3, 1), (4, 6), (4, 0)] {
        let p = path(&format!("v1{minor}-f{format}.las"));
        write(&p, &cloud, minor, format, None);
        let c = io::read_cloud(&p).unwrap();
        let at = format!("LAS 1.{minor} format {format}");
        assert_eq!(c.source.format, "las", "{at}");
        assert!(
            c.source
                .details
                .starts_with(&format!("LAS 1.{minor}, point format {format}")),
            "{at}: {}",
            c.source.details
        );
        assert_eq!(c.len(), 40, "{at}");
        for (a, b) in c.xyz.iter().zip(&pts) {
            for k in 0..3 {
                let world = c.origin[k] + f64::from(a[k]);
                assert!((world - b[k]).abs() < 1e-3, "{at}: {world} vs {}", b[k]);
            }
        }
        assert_eq!(
            c.scan_ids,
            vec![11, 4],
            "{at}: point_source_id names the scans"
        );
        assert_eq!(c.scan, cloud.scan, "{at}");
        let has_time = format != 0;
        assert_eq!(
            c.time.len(),
            if has_time { 40 } else { 0 },
            "{at}: gps_time"
        );
        if has_time {
            assert!((c.time[39] - 0.039).abs() < 1e-12, "{at}");
        }
        assert_eq!(c.crs, None, "{at}");
        assert_eq!(c.source.units, "m (assumed)", "{at}");

        // With static poses the times are not read; the points and scans are the same.
        let sidecar = path(&format!("v1{minor}-f{format}.poses.json"));
        std::fs::write(
            &sidecar,
            r#"{"scans": [{"index": 11, "position": [512001, 5400002, 201.5], "quaternion": [1, 0, 0, 0]},
                          {"index": 4, "position": [512003, 5400001, 201.5], "quaternion": [1, 0, 0, 0]}]}"#,
        )
        .unwrap();
        let posed = io::read_scan(
            &p,
            Some((io::SidecarKind::Poses, &sidecar)),
            &io::ReadOptions::default(),
        )
        .unwrap();
        assert!(posed.time.is_empty(), "{at}: a posed scan kept its times");
        assert_eq!((&posed.xyz, &posed.scan), (&c.xyz, &c.scan), "{at}");
    }
}

#[test]
fn the_crs_reaches_the_plan_from_wkt_and_geotiff_keys() {
    // A georeferenced room, planned from LAS 1.4 with a WKT CRS and from LAS 1.2 with
    // GeoTIFF keys; the plan and its GeoJSON carry the CRS.
    let sim = simulate(
        BuildingKind::SquareRoom,
        &ScanOptions {
            points: 150_000,
            seed: 5,
            offset: [512_345.0, 5_432_100.0, 230.0],
            ..Default::default()
        },
    )
    .unwrap();
    let asbuilt_plan::cloud::Viewpoints::Static(sim_poses) = &sim.cloud.viewpoints else {
        panic!("static scans have poses")
    };
    let sidecar = path("room-poses.json");
    poses::write_poses(&sidecar, sim_poses, sim.cloud.origin).unwrap();
    for (minor, format, crs, want) in [
        (4, 6, "wkt", WKT.to_string()),
        (2, 1, "geotiff", "EPSG:25832".to_string()),
    ] {
        let p = path(&format!("room-{crs}.las"));
        write(&p, &sim.cloud, minor, format, Some(crs));
        let mut cloud = io::read_cloud(&p).unwrap();
        assert_eq!(cloud.crs.as_deref(), Some(want.as_str()), "{crs}");
        let from = if crs == "wkt" { "WKT" } else { "GeoTIFF keys" };
        assert!(
            cloud.source.details.contains(&format!("CRS from {from}")),
            "{}",
            cloud.source.details
        );
        poses::load_poses(&mut cloud, &sidecar).unwrap();
        let plan = asbuilt_plan::plan(&cloud, &Params::default(), &mut NoProgress).unwrap();
        assert_eq!(plan.stories.len(), 1, "{crs}");
        assert_eq!(
            plan.crs.as_deref(),
            Some(want.as_str()),
            "{crs}: floorplan.crs"
        );
        let doc = geojson::to_geojson(&plan);
        let text = doc.to_string();
        assert!(
            text.contains(&serde_json::to_string(&want).unwrap()),
            "{crs}: the GeoJSON carries the CRS"
        );
    }
}
