//! E57 record layouts beyond plain cartesian doubles: spherical coordinates, scaled integers,
//! invalid-state fields and a per-scan pose, written with the `e57` crate and read back.

use asbuilt_plan::cloud::Viewpoints;
use asbuilt_plan::io;

#[path = "support/e57_layouts.rs"]
mod e57_layouts;

/// A scratch folder removed when dropped.
struct Scratch(std::path::PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn spherical_and_scaled_scans_read_with_poses_and_invalid_points_skipped() {
    let dir = Scratch(std::env::temp_dir().join(format!("asbuilt-e57-{}", std::process::id())));
    std::fs::create_dir_all(&dir.0).unwrap();
    let path = dir.0.join("layouts.e57");
    e57_layouts::write_layouts(&path);
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
