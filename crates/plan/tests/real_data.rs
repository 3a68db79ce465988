//! The real 16-scan apartment (`shared/data/real`), read from its E57 and its merged LAZ.
//! Skipped, with a printed reason, where the folder is absent.

use std::path::{Path, PathBuf};

use asbuilt_plan::cloud::{PointCloud, Viewpoints};
use asbuilt_plan::io::{self, ReadOptions};

const POINTS: usize = 561_113;
/// The README's bounding box, metres, rounded to centimetres.
const LO: [f64; 3] = [-18.22, -9.45, -2.03];
const HI: [f64; 3] = [1.53, 4.88, 1.39];

fn folder() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/real");
    let dir = if dir.is_dir() {
        dir
    } else {
        PathBuf::from("/work/shared/data/real")
    };
    if dir.join("apartment-16scans.e57").is_file() {
        Some(dir)
    } else {
        eprintln!(
            "skipped: the real apartment folder ({}) is absent",
            dir.display()
        );
        None
    }
}

fn world_bounds(c: &PointCloud) -> ([f64; 3], [f64; 3]) {
    let (lo, hi) = c.local_bounds().expect("points");
    (
        [0, 1, 2].map(|k| c.origin[k] + f64::from(lo[k])),
        [0, 1, 2].map(|k| c.origin[k] + f64::from(hi[k])),
    )
}

fn assert_apartment_bounds(c: &PointCloud) {
    let (lo, hi) = world_bounds(c);
    for k in 0..3 {
        assert!(
            (lo[k] - LO[k]).abs() < 0.006,
            "min {k}: {} vs {}",
            lo[k],
            LO[k]
        );
        assert!(
            (hi[k] - HI[k]).abs() < 0.006,
            "max {k}: {} vs {}",
            hi[k],
            HI[k]
        );
    }
}

#[test]
fn the_e57_has_every_point_and_sixteen_poses() {
    let Some(dir) = folder() else { return };
    let c = io::read_cloud(&dir.join("apartment-16scans.e57")).unwrap();
    assert_eq!(c.source.format, "e57");
    assert_eq!(c.len(), POINTS);
    assert_eq!(c.source.skipped, 0);
    assert_eq!(c.scan_ids.len(), 16);
    assert_eq!(c.scan.len(), POINTS);
    assert!(c.source.details.contains("colour"), "{}", c.source.details);
    let Viewpoints::Static(poses) = &c.viewpoints else {
        panic!("E57 poses were not kept")
    };
    assert_eq!(poses.len(), 16);
    // The scanners stand at about z = 0, inside the bounding box.
    for p in poses {
        let w = [0, 1, 2].map(|k| c.origin[k] + p.position[k]);
        assert!(w[2].abs() < 0.5, "scanner height {}", w[2]);
        assert!(
            (LO[0]..=HI[0]).contains(&w[0]) && (LO[1]..=HI[1]).contains(&w[1]),
            "{w:?}"
        );
    }
    // Every scan's points lie around its scanner: the pose was applied.
    let mut n = [0usize; 16];
    for &s in &c.scan {
        n[s as usize] += 1;
    }
    assert!(n.iter().all(|&k| k > 10_000), "{n:?}");
    assert_apartment_bounds(&c);
    assert!(io::check_units(&c).is_ok());
}

#[test]
fn the_laz_has_every_point_and_sixteen_scans() {
    let Some(dir) = folder() else { return };
    let c = io::read_cloud(&dir.join("apartment-merged.laz")).unwrap();
    assert_eq!(c.source.format, "laz");
    assert_eq!(c.len(), POINTS);
    let mut ids = c.scan_ids.clone();
    ids.sort_unstable();
    assert_eq!(ids, (1..=16).collect::<Vec<u32>>());
    assert_eq!(c.scan.len(), POINTS);
    assert_apartment_bounds(&c);
}

#[test]
fn e57_and_laz_agree_point_for_point_per_scan() {
    let Some(dir) = folder() else { return };
    let opts = ReadOptions::default();
    let e = io::read_cloud_with(&dir.join("apartment-16scans.e57"), &opts).unwrap();
    let l = io::read_cloud_with(&dir.join("apartment-merged.laz"), &opts).unwrap();
    // Per-scan centroids match to a millimetre (E57 scan k is LAZ point_source_id k + 1).
    let centroid = |c: &PointCloud, slot_of: &dyn Fn(u32) -> usize| {
        let mut sum = [[0.0f64; 4]; 16];
        for (i, p) in c.xyz.iter().enumerate() {
            let s = slot_of(c.scan_ids[c.scan[i] as usize]);
            for k in 0..3 {
                sum[s][k] += c.origin[k] + f64::from(p[k]);
            }
            sum[s][3] += 1.0;
        }
        sum.map(|s| [s[0] / s[3], s[1] / s[3], s[2] / s[3], s[3]])
    };
    let ce = centroid(&e, &|id| id as usize);
    let cl = centroid(&l, &|id| id as usize - 1);
    for s in 0..16 {
        assert_eq!(ce[s][3], cl[s][3], "scan {s} point count");
        for k in 0..3 {
            assert!((ce[s][k] - cl[s][k]).abs() < 1e-3, "scan {s} axis {k}");
        }
    }
}
