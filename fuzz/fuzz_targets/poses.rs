#![no_main]
//! The pose and trajectory sidecar parsers, and attaching them to a small cloud.

use asbuilt_plan::cloud::PointCloud;
use asbuilt_plan::io::poses;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let mut cloud = PointCloud {
        xyz: vec![[0.0; 3]; 4],
        scan: vec![0, 0, 1, 1],
        scan_ids: vec![0, 1],
        time: vec![0.0, 0.5, 1.0, 1.5],
        ..Default::default()
    };
    if let Ok(p) = poses::parse_poses(text) {
        if poses::attach_poses(&mut cloud, p).is_ok() {
            assert!(cloud.check().is_ok());
        }
    }
    if let Ok(t) = poses::parse_trajectory(text) {
        if poses::attach_trajectory(&mut cloud, t).is_ok() {
            assert!(cloud.check().is_ok());
        }
    }
});
