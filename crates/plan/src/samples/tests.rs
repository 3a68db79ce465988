//! Tests of the whole sampling stage on synthetic walls.

use crate::cancel::Cancel;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;
use crate::cloud::{ScanPose, Viewpoints};

fn story() -> Story {
    Story {
        level: 0,
        floor_z: 0.0,
        ceiling_z: 3.0,
        z_min: -0.5,
        z_max: 3.5,
    }
}

/// A 3 m tall wall along x from `x0` to `x0 + 2` at y = `y`, with `density` points per m²
/// (±2 mm of noise across it), on a 2 m deep floor and ceiling of a quarter of that density.
fn wall(
    rng: &mut ChaCha8Rng,
    x0: f32,
    y: f32,
    density: f32,
    scan: u16,
) -> (Vec<[f32; 3]>, Vec<u16>) {
    let mut xyz = Vec::new();
    for _ in 0..(density * 6.0) as usize {
        let x = x0 + rng.random_range(0.0..2.0);
        let z = rng.random_range(0.0..3.0);
        xyz.push([x, y + rng.random_range(-0.002..0.002), z]);
    }
    for _ in 0..(density / 4.0 * 4.0) as usize {
        let x = x0 + rng.random_range(0.0..2.0);
        let yy = y + rng.random_range(-2.0..0.0);
        xyz.push([x, yy, if rng.random_bool(0.5) { 0.0 } else { 3.0 }]);
    }
    let scans = vec![scan; xyz.len()];
    (xyz, scans)
}

fn cloud_of(parts: Vec<(Vec<[f32; 3]>, Vec<u16>)>, poses: &[[f64; 3]]) -> PointCloud {
    let mut cloud = PointCloud::default();
    for (xyz, scan) in parts {
        cloud.xyz.extend(xyz);
        cloud.scan.extend(scan);
    }
    if poses.is_empty() {
        cloud.scan.clear();
    } else {
        cloud.scan_ids = (1..=poses.len() as u32).collect();
        cloud.viewpoints = Viewpoints::Static(
            poses
                .iter()
                .enumerate()
                .map(|(k, &position)| ScanPose {
                    index: k as u32 + 1,
                    position,
                    quaternion: [1.0, 0.0, 0.0, 0.0],
                })
                .collect(),
        );
    }
    cloud.check().unwrap();
    cloud
}

#[test]
fn one_wall_gives_samples_on_its_line_with_the_normal_across_it() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let cloud = cloud_of(vec![wall(&mut rng, 0.0, 0.012, 1000.0, 0)], &[]);
    let out = sample_walls(
        &cloud,
        &story(),
        &SamplesParams::default(),
        &Cancel::never(),
    )
    .unwrap();
    // One sample per 5 cm column along the 2 m wall.
    assert!(
        (35..=41).contains(&out.samples.len()),
        "{}",
        out.samples.len()
    );
    for s in &out.samples {
        assert!((s.pos[1] - 0.012).abs() < 0.003, "{s:?}");
        assert!((-0.01..2.01).contains(&s.pos[0]), "{s:?}");
        // Unoriented without poses: either sign of (0, 1).
        assert!(
            s.normal[0].abs() < 0.05 && s.normal[1].abs() > 0.99,
            "{s:?}"
        );
        assert!(s.confidence > 0.8 && s.seen_from.is_empty());
    }
    assert!(out.viewpoints.is_empty() && out.path.is_empty());
    assert_eq!(out.cells_tested, out.samples.len());
}

#[test]
fn the_threshold_follows_density_and_an_explicit_value_overrides() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let dense = cloud_of(vec![wall(&mut rng, 0.0, 0.012, 1500.0, 0)], &[]);
    let sparse = cloud_of(vec![wall(&mut rng, 0.0, 0.012, 150.0, 0)], &[]);
    let auto = SamplesParams::default();
    let d = sample_walls(&dense, &story(), &auto, &Cancel::never()).unwrap();
    let s = sample_walls(&sparse, &story(), &auto, &Cancel::never()).unwrap();
    assert!(
        d.min_points_used >= 3 * s.min_points_used.min(20),
        "{} vs {}",
        d.min_points_used,
        s.min_points_used
    );
    assert!(s.min_points_used < 50 && d.min_points_used >= 30);
    assert!(s.samples.len() >= 30, "sparse: {}", s.samples.len());
    assert!(d.samples.len() >= 35, "dense: {}", d.samples.len());
    // The paper's 50 finds next to nothing in the sparse copy.
    let paper = SamplesParams {
        min_points: Some(50),
        ..auto
    };
    match sample_walls(&sparse, &story(), &paper, &Cancel::never()) {
        Ok(few) => assert!(few.samples.len() < 10, "{}", few.samples.len()),
        Err(e) => assert!(matches!(e, SamplesError::NoWalls { .. }), "{e}"),
    }
    assert_eq!(
        sample_walls(&dense, &story(), &paper, &Cancel::never())
            .unwrap()
            .min_points_used,
        50
    );
}

#[test]
fn normals_face_the_scanner_that_saw_them() {
    for (pose_y, expect) in [(-1.5, -1.0), (1.5, 1.0)] {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let cloud = cloud_of(
            vec![wall(&mut rng, 0.0, 0.012, 800.0, 0)],
            &[[1.0, pose_y, 1.5]],
        );
        let out = sample_walls(
            &cloud,
            &story(),
            &SamplesParams::default(),
            &Cancel::never(),
        )
        .unwrap();
        assert!(out.samples.len() >= 30);
        assert_eq!(out.viewpoints, vec![[1.0, pose_y]]);
        for s in &out.samples {
            assert!((s.normal[1] - expect).abs() < 0.01, "{s:?}");
            assert_eq!(s.seen_from, vec![0]);
        }
    }
}

#[test]
fn samples_far_from_every_scanner_that_saw_them_are_dropped() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let poses = [[1.0, -1.0, 1.5], [21.0, -1.0, 1.5]];
    let near = wall(&mut rng, 0.0, 0.012, 800.0, 0);
    let far = wall(&mut rng, 20.0, 0.012, 800.0, 1);
    // Each wall seen by the scanner in front of it: both kept.
    let cloud = cloud_of(vec![near.clone(), far.clone()], &poses);
    let out = sample_walls(
        &cloud,
        &story(),
        &SamplesParams::default(),
        &Cancel::never(),
    )
    .unwrap();
    assert!(out.samples.iter().any(|s| s.pos[0] > 20.0));
    assert!(out.samples.iter().any(|s| s.pos[0] < 2.0));
    // The far wall seen only by the first scanner, 19 m away or more: dropped.
    let far_from_0 = (far.0, vec![0; far.1.len()]);
    let cloud = cloud_of(vec![near, far_from_0], &poses);
    let out = sample_walls(
        &cloud,
        &story(),
        &SamplesParams::default(),
        &Cancel::never(),
    )
    .unwrap();
    assert!(out.samples.iter().all(|s| s.pos[0] < 2.1));
    assert!(out.cells_tested > out.samples.len() + 30);
}

#[test]
fn bad_input_gets_errors_not_panics() {
    let p = SamplesParams::default();
    let empty = PointCloud::default();
    assert_eq!(
        sample_walls(&empty, &story(), &p, &Cancel::never()),
        Err(SamplesError::EmptyStory { level: 0 })
    );
    let above = PointCloud {
        xyz: vec![[0.0, 0.0, 10.0]],
        ..Default::default()
    };
    assert_eq!(
        sample_walls(&above, &story(), &p, &Cancel::never()),
        Err(SamplesError::EmptyStory { level: 0 })
    );
    let nan = PointCloud {
        xyz: vec![[0.0, 0.0, 1.0], [f32::NAN, 0.0, 1.0]],
        ..Default::default()
    };
    assert_eq!(
        sample_walls(&nan, &story(), &p, &Cancel::never()),
        Err(SamplesError::NonFinite(1))
    );
    let wide = PointCloud {
        xyz: vec![[0.0, 0.0, 1.0], [1.0e6, 1.0e6, 1.0]],
        ..Default::default()
    };
    assert!(matches!(
        sample_walls(&wide, &story(), &p, &Cancel::never()),
        Err(SamplesError::TooLarge(_))
    ));
    let zero = SamplesParams {
        cell_size: 0.0,
        ..p.clone()
    };
    assert!(matches!(
        sample_walls(&above, &story(), &zero, &Cancel::never()),
        Err(SamplesError::BadParam {
            name: "cell_size",
            ..
        })
    ));
    // A floor alone: cells exist, none is a wall.
    let floor = PointCloud {
        xyz: (0..2000)
            .map(|k| [(k % 40) as f32 * 0.01, (k / 40) as f32 * 0.01, 0.0])
            .collect(),
        ..Default::default()
    };
    let err = sample_walls(&floor, &story(), &p, &Cancel::never()).unwrap_err();
    assert!(err.to_string().contains("too short"), "{err}");
}

#[test]
fn a_mobile_trajectory_orients_normals_and_gives_the_path() {
    use crate::cloud::TrajectorySample;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (xyz, _) = wall(&mut rng, 0.0, 0.012, 800.0, 0);
    // The scanner walks along y = -1 from x = 0 to 2 in 20 s; each point is seen when the
    // scanner passes its x.
    let time: Vec<f64> = xyz.iter().map(|p| 10.0 * p[0] as f64).collect();
    let traj: Vec<TrajectorySample> = (0..=20)
        .map(|k| TrajectorySample {
            t: k as f64,
            position: [0.1 * k as f64, -1.0, 1.5],
            quaternion: [1.0, 0.0, 0.0, 0.0],
        })
        .collect();
    let cloud = PointCloud {
        xyz,
        time,
        viewpoints: Viewpoints::Trajectory(traj),
        ..Default::default()
    };
    cloud.check().unwrap();
    let out = sample_walls(
        &cloud,
        &story(),
        &SamplesParams::default(),
        &Cancel::never(),
    )
    .unwrap();
    assert!(out.samples.len() >= 30);
    assert_eq!(out.path.len(), 21);
    // Viewpoints every centimetre along the 2 m path.
    assert_eq!(out.viewpoints.len(), 201, "{:?}", out.viewpoints.len());
    for s in &out.samples {
        assert!((s.normal[1] + 1.0).abs() < 0.01, "{s:?}");
        assert!(!s.seen_from.is_empty());
        // Seen from the listed viewpoint nearest along the path.
        let v = out.viewpoints[s.seen_from[0] as usize];
        assert!((v[0] - s.pos[0]).abs() <= 0.06, "{s:?} from {v:?}");
    }
}
