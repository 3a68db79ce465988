//! One building, every format, one plan: a simulated office is written as E57 (with its poses
//! inside), LAS, LAZ, binary PLY, ASCII PLY and XYZ, read back through `io::read_cloud` (with the
//! pose sidecar where the format has no poses of its own), and planned. Every plan must agree
//! with the one from binary PLY plus its sidecar, within floating-point noise.
//!
//! The simulated points are first snapped to the 1 mm grid LAS stores, so LAS and LAZ carry the
//! very same coordinates as the other formats; E57 stores scanner-local `f32` coordinates and
//! differs from the others by rounding only.

use std::path::{Path, PathBuf};

use asbuilt_plan::cloud::{PointCloud, Viewpoints};
use asbuilt_plan::io::{self, export, ply, poses, ReadOptions};
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
use asbuilt_plan::{FloorPlan, Params};

/// Plans agree when heights and vertices are this close, metres.
const TOLERANCE: f64 = 1.0e-3;

fn dir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("asbuilt-every-format-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The office, three stories, with 2 mm range noise, moved off the axes and snapped to whole
/// millimetres (LAS's scale). Away from zero, E57's pose arithmetic in `f64` rounds back to the
/// same `f32`; at zero it would leave a residue of 1e-15 m, a different float.
fn office() -> PointCloud {
    const SHIFT: [f64; 3] = [0.25, 0.35, 0.15];
    let sim = simulate(
        BuildingKind::Office3Story,
        &ScanOptions {
            points: 400_000,
            seed: 31,
            noise: 0.002,
            ..Default::default()
        },
    )
    .unwrap();
    let mut cloud = sim.cloud;
    assert_eq!(
        cloud.origin, [0.0; 3],
        "the snapping below assumes a zero origin"
    );
    for p in &mut cloud.xyz {
        // The same arithmetic the LAS reader does: integer × scale + offset.
        *p = [0, 1, 2].map(|k| {
            let mm = ((f64::from(p[k]) + SHIFT[k]) / 0.001).round();
            (mm * 0.001 + 0.0) as f32
        });
    }
    let Viewpoints::Static(poses) = &mut cloud.viewpoints else {
        panic!("static scans have poses")
    };
    for pose in poses {
        pose.position = [0, 1, 2].map(|k| pose.position[k] + SHIFT[k]);
    }
    cloud
}

fn plan(cloud: &PointCloud) -> FloorPlan {
    asbuilt_plan::plan(cloud, &Params::default(), &mut NoProgress).expect("a plan")
}

fn read_with_sidecar(path: &Path, sidecar: &Path, options: &ReadOptions) -> PointCloud {
    let mut cloud = io::read_cloud_with(path, options).unwrap();
    let text = std::fs::read_to_string(sidecar).unwrap();
    poses::attach_poses(&mut cloud, poses::parse_poses(&text).unwrap()).unwrap();
    cloud
}

/// Both plans have the same stories, heights, areas, walls and vertices (within tolerance).
fn assert_same_plan(name: &str, a: &FloorPlan, b: &FloorPlan) {
    assert_eq!(a.stories.len(), b.stories.len(), "{name}: story count");
    for k in 0..3 {
        assert!(
            (a.origin[k] - b.origin[k]).abs() < TOLERANCE,
            "{name}: origin"
        );
    }
    for (s, (x, y)) in a.stories.iter().zip(&b.stories).enumerate() {
        let at = format!("{name}, story {s}");
        assert!((x.floor_z - y.floor_z).abs() < TOLERANCE, "{at}: floor");
        assert!(
            (x.ceiling_z - y.ceiling_z).abs() < TOLERANCE,
            "{at}: ceiling"
        );
        assert!(
            (x.area() - y.area()).abs() < 1.0e-3 * x.area().max(1.0),
            "{at}: area {} vs {}",
            x.area(),
            y.area()
        );
        assert_eq!(x.walls.len(), y.walls.len(), "{at}: wall count");
        assert_eq!(x.polygons.len(), y.polygons.len(), "{at}: polygon count");
        for (p, (pa, pb)) in x.polygons.iter().zip(&y.polygons).enumerate() {
            let rings_a = std::iter::once(&pa.exterior).chain(&pa.holes);
            let rings_b = std::iter::once(&pb.exterior).chain(&pb.holes);
            assert_eq!(pa.holes.len(), pb.holes.len(), "{at}, polygon {p}: holes");
            for (ra, rb) in rings_a.zip(rings_b) {
                assert_eq!(ra.len(), rb.len(), "{at}, polygon {p}: vertex count");
                for (va, vb) in ra.iter().zip(rb) {
                    let d = ((va[0] - vb[0]).powi(2) + (va[1] - vb[1]).powi(2)).sqrt();
                    assert!(d < TOLERANCE, "{at}, polygon {p}: {va:?} vs {vb:?}");
                }
            }
        }
    }
}

#[test]
fn one_building_every_format_one_plan() {
    let sim = office();
    let dir = dir();
    let Viewpoints::Static(sim_poses) = &sim.viewpoints else {
        panic!("static scans have poses")
    };
    let sidecar = dir.join("poses.json");
    poses::write_poses(&sidecar, sim_poses, sim.origin).unwrap();
    let path = |name: &str| dir.join(name);
    export::write_e57(&path("cloud.e57"), &sim).unwrap();
    export::write_las(&path("cloud.las"), &sim, false).unwrap();
    export::write_las(&path("cloud.laz"), &sim, true).unwrap();
    ply::write_ply(&path("cloud.ply"), &sim, ply::Encoding::BinaryLittleEndian).unwrap();
    ply::write_ply(&path("ascii.ply"), &sim, ply::Encoding::Ascii).unwrap();
    export::write_xyz(&path("cloud.xyz"), &sim).unwrap();

    let default = ReadOptions::default();
    let reference = read_with_sidecar(&path("cloud.ply"), &sidecar, &default);
    assert_eq!(reference.len(), sim.len());
    assert_eq!(reference.xyz, sim.xyz, "binary PLY is exact");
    let want = plan(&reference);
    assert_eq!(want.stories.len(), 3, "the office has three stories");

    // E57 carries its own poses: no sidecar.
    let e57 = io::read_cloud(&path("cloud.e57")).unwrap();
    assert_eq!(e57.source.format, "e57");
    assert_eq!(e57.len(), sim.len());
    assert_eq!(e57.scan_ids.len(), sim.scan_ids.len());
    let Viewpoints::Static(embedded) = &e57.viewpoints else {
        panic!("the E57 poses were not kept")
    };
    for (a, b) in embedded.iter().zip(sim_poses) {
        for k in 0..3 {
            let (wa, wb) = (a.position[k] + e57.origin[k], b.position[k] + sim.origin[k]);
            assert!((wa - wb).abs() < 1e-9, "E57 scanner position");
        }
    }
    assert_same_plan("e57 (embedded poses)", &want, &plan(&e57));

    let scan_column = ReadOptions {
        scan_column: Some(3),
        ..Default::default()
    };
    let cases = [
        ("las", "cloud.las", &default),
        ("laz", "cloud.laz", &default),
        ("ascii ply", "ascii.ply", &default),
        ("xyz", "cloud.xyz", &scan_column),
    ];
    for (name, file, options) in cases {
        let cloud = read_with_sidecar(&path(file), &sidecar, options);
        assert_eq!(cloud.len(), sim.len(), "{name}: point count");
        assert_eq!(cloud.scan_ids, reference.scan_ids, "{name}: scans");
        assert_eq!(cloud.xyz, reference.xyz, "{name}: the same coordinates");
        assert_same_plan(name, &want, &plan(&cloud));
    }
    std::fs::remove_dir_all(&dir).ok();
}
