//! E57 record layouts beyond plain cartesian doubles: spherical coordinates, scaled integers,
//! invalid-state fields and a per-scan pose, written with the `e57` crate and read back.

use asbuilt_plan::cloud::Viewpoints;
use asbuilt_plan::io;

/// A scratch folder removed when dropped.
struct Scratch(std::path::PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Scan 0: 8 spherical points (single precision), the one at i = 5 marked invalid. Scan 1: 8
/// scaled-integer cartesian points under a pose turning 180° about z and moving by (10, 20, 1.5),
/// the one at i = 3 marked invalid.
fn write_file(path: &std::path::Path) {
    let mut w = e57::E57Writer::from_file(path, "asbuilt test").unwrap();
    let prototype = vec![
        e57::Record::SPHERICAL_RANGE_F32,
        e57::Record::SPHERICAL_AZIMUTH_F32,
        e57::Record::SPHERICAL_ELEVATION_F32,
        e57::Record::SPHERICAL_INVALID_STATE,
        e57::Record::INTENSITY_U16,
    ];
    let mut pc = w.add_pointcloud("spherical", prototype).unwrap();
    for i in 0..8 {
        let f = i as f32;
        use e57::RecordValue::*;
        pc.add_point(vec![
            Single(1.0 + f),
            Single(f * 0.3),
            Single(f * 0.1 - 0.3),
            Integer(i64::from(i == 5)),
            Integer(i64::from(i) * 100),
        ])
        .unwrap();
    }
    pc.finalize().unwrap();
    let scaled = |name| e57::Record {
        name,
        data_type: e57::RecordDataType::ScaledInteger {
            min: -100_000,
            max: 100_000,
            scale: 0.001,
            offset: 0.0,
        },
    };
    let prototype = vec![
        scaled(e57::RecordName::CartesianX),
        scaled(e57::RecordName::CartesianY),
        scaled(e57::RecordName::CartesianZ),
        e57::Record::CARTESIAN_INVALID_STATE,
    ];
    let mut pc = w.add_pointcloud("scaled", prototype).unwrap();
    pc.set_transform(Some(e57::Transform {
        rotation: e57::Quaternion {
            w: 0.0,
            x: 0.0,
            y: 0.0,
            z: 1.0,
        },
        translation: e57::Translation {
            x: 10.0,
            y: 20.0,
            z: 1.5,
        },
    }));
    for i in 0..8i64 {
        use e57::RecordValue::*;
        pc.add_point(vec![
            ScaledInteger(i * 1000),
            ScaledInteger(-i * 500),
            ScaledInteger(1200),
            Integer(i64::from(i == 3) * 2),
        ])
        .unwrap();
    }
    pc.finalize().unwrap();
    w.finalize().unwrap();
}

#[test]
fn spherical_and_scaled_scans_read_with_poses_and_invalid_points_skipped() {
    let dir = Scratch(std::env::temp_dir().join(format!("asbuilt-e57-{}", std::process::id())));
    std::fs::create_dir_all(&dir.0).unwrap();
    let path = dir.0.join("layouts.e57");
    write_file(&path);
    let c = io::read_cloud(&path).unwrap();
    assert_eq!(c.source.format, "e57");
    assert_eq!(c.len(), 14, "16 points, 2 marked invalid");
    assert_eq!(c.source.skipped, 2);
    assert_eq!(c.scan_ids, vec![0, 1]);
    let world = |k: usize| [0, 1, 2].map(|a| c.origin[a] + f64::from(c.xyz[k][a]));
    // Scan 0 in order, i = 5 left out: spherical to cartesian, no pose.
    let valid: Vec<i32> = (0..8).filter(|&i| i != 5).collect();
    for (k, &i) in valid.iter().enumerate() {
        let f = i as f32;
        let (r, az, el) = (
            f64::from(1.0 + f),
            f64::from(f * 0.3),
            f64::from(f * 0.1 - 0.3),
        );
        let expect = [
            r * el.cos() * az.cos(),
            r * el.cos() * az.sin(),
            r * el.sin(),
        ];
        let got = world(k);
        for a in 0..3 {
            assert!(
                (got[a] - expect[a]).abs() < 1e-5,
                "point {i}: {got:?} vs {expect:?}"
            );
        }
        assert_eq!(c.scan[k], 0);
    }
    // Scan 1, i = 3 left out: (i, -i/2, 1.2) turned about z and moved.
    let valid: Vec<i32> = (0..8).filter(|&i| i != 3).collect();
    for (k, &i) in valid.iter().enumerate() {
        let f = f64::from(i);
        let expect = [10.0 - f, 20.0 + 0.5 * f, 2.7];
        let got = world(7 + k);
        for a in 0..3 {
            assert!(
                (got[a] - expect[a]).abs() < 1e-5,
                "point {i}: {got:?} vs {expect:?}"
            );
        }
        assert_eq!(c.scan[7 + k], 1);
    }
    // Both scanner origins are kept for the lines of sight.
    let Viewpoints::Static(poses) = &c.viewpoints else {
        panic!("no poses")
    };
    assert_eq!(poses.len(), 2);
    let origin = |p: usize| [0, 1, 2].map(|a| c.origin[a] + poses[p].position[a]);
    assert!(origin(0).iter().all(|v| v.abs() < 1e-9), "{:?}", origin(0));
    let o1 = origin(1);
    assert!(
        (o1[0] - 10.0).abs() < 1e-9 && (o1[1] - 20.0).abs() < 1e-9 && (o1[2] - 1.5).abs() < 1e-9
    );
}
