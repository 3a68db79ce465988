//! The real 16-scan apartment (`shared/data/real`), read from its E57 and its merged LAZ, and
//! planned from both. Skipped, with a printed reason, where the folder is absent; under CI
//! (`CI` set) an absent folder fails instead.

use std::path::{Path, PathBuf};

use asbuilt_plan::cloud::{PointCloud, Viewpoints};
use asbuilt_plan::evaluate::{area, iou, watertight};
use asbuilt_plan::geom::P2;
use asbuilt_plan::io::{self, poses, ReadOptions};
use asbuilt_plan::plan::{FloorPlan, Polygon, WallModel};
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::Params;

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
        assert!(
            std::env::var_os("CI").is_none(),
            "the real apartment folder ({}) is absent under CI",
            dir.display()
        );
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

/// Even-odd point in polygon over every ring.
fn inside(polygons: &[Polygon], p: P2) -> bool {
    let mut odd = false;
    for ring in polygons
        .iter()
        .flat_map(|q| std::iter::once(&q.exterior).chain(&q.holes))
    {
        for (i, a) in ring.iter().enumerate() {
            let b = ring[(i + 1) % ring.len()];
            if (a[1] > p[1]) != (b[1] > p[1])
                && p[0] < a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0])
            {
                odd = !odd;
            }
        }
    }
    odd
}

/// What a plan of the apartment must show: one closed story, its floor where the README puts
/// it, every scanner standing inside the open floor, and the long corridor wall fitted as a
/// line. The floor area has no ground truth; 83 m² was seen and checked by eye against the
/// point slice, so the bounds only catch lost rooms or a plan spilling outside.
fn assert_apartment_plan(cloud: &PointCloud, plan: &FloorPlan) {
    assert_eq!(plan.stories.len(), 1, "{:?}", plan.notes);
    let s = &plan.stories[0];
    let floor = plan.origin[2] + s.floor_z;
    assert!((floor + 1.75).abs() < 0.05, "floor at {floor}");
    assert!(s.ceiling_z - s.floor_z >= 2.0);
    watertight(&s.polygons).unwrap();
    let a = area(&s.polygons);
    assert!((70.0..110.0).contains(&a), "area {a} m²");
    let Viewpoints::Static(scanners) = &cloud.viewpoints else {
        panic!("no scanner poses")
    };
    assert_eq!(scanners.len(), 16);
    for p in scanners {
        let at = [p.position[0], p.position[1]];
        assert!(
            inside(&s.polygons, at),
            "scanner at {at:?} is outside the plan"
        );
    }
    // The wall between the kitchen (scan 13) and the bathroom (scan 10) stands. A mirror on its
    // bathroom side showed scan 10 its room beyond the kitchen's face, and those lines of sight
    // had carved the wall away: the two were one room.
    let room_at = |world: P2| {
        let p = [world[0] - plan.origin[0], world[1] - plan.origin[1]];
        s.spaces
            .rooms
            .iter()
            .position(|r| inside(std::slice::from_ref(&r.polygon), p))
    };
    let (kitchen, bathroom) = (room_at([-12.60, -5.43]), room_at([-9.58, -1.72]));
    assert!(
        kitchen.is_some() && bathroom.is_some() && kitchen != bathroom,
        "kitchen room {kitchen:?}, bathroom room {bathroom:?}"
    );
    // The room of scans 7 and 8 is closed off from the bathroom beside it and from the living
    // room. With one RANSAC seed the fitted faces of the thick wall between it and the bathroom
    // crossed, and the repair joined the two through a sliver at the wall's end.
    let (bedroom, living) = (room_at([-6.49, 0.32]), room_at([-1.00, 1.64]));
    assert!(
        bedroom.is_some() && bedroom != bathroom && bedroom != living,
        "room {bedroom:?} of scans 7 and 8, bathroom {bathroom:?}, living room {living:?}"
    );
    let longest_line = s
        .walls
        .iter()
        .filter(|w| matches!(w.model, WallModel::Line))
        .map(|w| w.length())
        .fold(0.0, f64::max);
    assert!(
        longest_line >= 6.0,
        "longest straight wall {longest_line} m"
    );
    assert!(s.walls.len() >= 15, "{} walls", s.walls.len());
}

#[test]
fn e57_and_laz_with_its_sidecar_plan_to_the_same_closed_apartment() {
    let Some(dir) = folder() else { return };
    let params = Params::default();
    let e57 = io::read_cloud(&dir.join("apartment-16scans.e57")).unwrap();
    let mut laz = io::read_cloud(&dir.join("apartment-merged.laz")).unwrap();
    poses::load_poses(&mut laz, &dir.join("apartment-merged.poses.json")).unwrap();
    let from_e57 = asbuilt_plan::plan(&e57, &params, &mut NoProgress).unwrap();
    let from_laz = asbuilt_plan::plan(&laz, &params, &mut NoProgress).unwrap();
    assert_apartment_plan(&e57, &from_e57);
    assert_apartment_plan(&laz, &from_laz);
    // The density-derived threshold is reported with the parameters it replaced.
    let derived = &from_e57.parameters["samples"]["min_points_derived"][0];
    assert!(
        derived.as_u64().is_some_and(|n| (10..50).contains(&n)),
        "{derived}"
    );
    // Same points, same scanners: the two plans cover the same floor (world frame).
    let shift = |plan: &FloorPlan| -> Vec<Polygon> {
        let o = plan.origin;
        let mv = |r: &Vec<P2>| r.iter().map(|p| [p[0] + o[0], p[1] + o[1]]).collect();
        plan.stories[0]
            .polygons
            .iter()
            .map(|q| Polygon {
                exterior: mv(&q.exterior),
                holes: q.holes.iter().map(mv).collect(),
            })
            .collect()
    };
    let overlap = iou(&shift(&from_e57), &shift(&from_laz), 0.01);
    assert!(
        overlap >= 0.97,
        "E57 and LAZ plans overlap by IoU {overlap}"
    );
}

/// The LAZ without its sidecar: the scanners are located from their blind cones (within 10 cm
/// of the sidecar's) and the plan matches the one with poses; as plain x, y, z (no scan ids)
/// the plan rests on pseudo-viewpoints in open space and still holds every real scanner.
#[test]
fn laz_without_its_sidecar_or_scan_ids_plans_close_to_the_plan_with_poses() {
    use asbuilt_plan::viewpoints::ViewpointSource;
    let Some(dir) = folder() else { return };
    let params = Params::default();
    let bare = io::read_cloud(&dir.join("apartment-merged.laz")).unwrap();
    let mut posed = bare.clone();
    poses::load_poses(&mut posed, &dir.join("apartment-merged.poses.json")).unwrap();
    let mut plain = bare.clone();
    plain.scan.clear();
    plain.scan_ids.clear();
    plain.time.clear();
    let with = asbuilt_plan::plan(&posed, &params, &mut NoProgress).unwrap();
    let without = asbuilt_plan::plan(&bare, &params, &mut NoProgress).unwrap();
    let xyz = asbuilt_plan::plan(&plain, &params, &mut NoProgress).unwrap();
    let Viewpoints::Static(truth) = &posed.viewpoints else {
        panic!("no poses in the sidecar")
    };
    let v = &without.input.viewpoints;
    assert_eq!(v.source, ViewpointSource::Estimated);
    assert_eq!(v.scans.len(), 16);
    for s in &v.scans {
        let t = truth.iter().find(|p| p.index == s.index).unwrap();
        let p = s.position.expect("every scan located");
        let err = (p[0] - t.position[0]).hypot(p[1] - t.position[1]);
        assert!(err < 0.10, "scan {}: {err} m off", s.index);
    }
    let story = |p: &FloorPlan| p.stories[0].polygons.clone();
    let overlap = iou(&story(&with), &story(&without), 0.005);
    assert!(overlap >= 0.98, "without the sidecar: IoU {overlap}");
    // The long corridor wall comes out in two runs (5.1 m the longest), so only the open
    // floor is checked: every real scanner stands in it.
    let holds_the_scanners = |plan: &FloorPlan| {
        watertight(&plan.stories[0].polygons).unwrap();
        for p in truth {
            let at = [p.position[0], p.position[1]];
            assert!(
                inside(&plan.stories[0].polygons, at),
                "scanner at {at:?} outside"
            );
        }
    };
    holds_the_scanners(&without);
    // Plain x, y, z.
    let v = &xyz.input.viewpoints;
    assert_eq!(v.source, ViewpointSource::OpenSpace, "{:?}", xyz.notes);
    assert!(v.open_space[0].viewpoints.len() >= 3, "{v:?}");
    assert!(v.rests_on.is_some_and(|f| f > 0.5), "{v:?}");
    assert!(xyz.notes.iter().any(|n| n.contains("pseudo-viewpoints")));
    let overlap = iou(&story(&with), &story(&xyz), 0.005);
    assert!(overlap >= 0.95, "plain x, y, z: IoU {overlap}");
    assert!(asbuilt_plan::validity::plan_problems(&xyz).is_empty());
    holds_the_scanners(&xyz);
}

/// The share of `samples` within `d` metres of a ring of `polygons`.
fn near_outline(polygons: &[Polygon], samples: &[P2], d: f64) -> f64 {
    let near = |p: P2| {
        polygons
            .iter()
            .flat_map(|poly| std::iter::once(&poly.exterior).chain(&poly.holes))
            .any(|ring| {
                (0..ring.len()).any(|k| {
                    let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
                    asbuilt_plan::geom::point_segment_distance(p, a, b) <= d
                })
            })
    };
    samples.iter().filter(|&&p| near(p)).count() as f64 / samples.len().max(1) as f64
}

#[test]
fn the_ipad_rooms_plan_from_their_walls_or_say_what_is_missing() {
    let Some(dir) = folder() else { return };
    let read =
        |r: u32| io::read_cloud(&dir.join(format!("ipad-room{r}.ply"))).expect("a readable PLY");
    for r in [430, 470, 808] {
        let plan = asbuilt_plan::plan(&read(r), &Params::default(), &mut NoProgress)
            .unwrap_or_else(|e| panic!("room {r}: {e}"));
        let problems = asbuilt_plan::validity::plan_problems(&plan);
        assert!(problems.is_empty(), "room {r}: {problems:?}");
        assert_eq!(plan.stories.len(), 1, "room {r}");
        let s = &plan.stories[0];
        // One room, not pieces split off by chords across it (430 was 61.0 + 6.6 m²).
        assert_eq!(s.spaces.rooms.len(), 1, "room {r}: {:?}", s.spaces.rooms);
        assert!(
            plan.notes.iter().any(|n| n.contains("no floor was seen")),
            "room {r}: {:?}",
            plan.notes
        );
        // The outline runs along the walls seen: most wall samples lie on it (the rest are
        // lamps and shelves inside).
        let share = near_outline(&s.polygons, &s.samples, 0.15);
        eprintln!(
            "room {r}: {:.3} of {} samples within 15 cm of the outline",
            share,
            s.samples.len()
        );
        assert!(share >= 0.8, "room {r}: {share}");
    }
    // Room 560 shows its walls only within about 1.2 m of the ceiling, along a few metres.
    let e = asbuilt_plan::plan(&read(560), &Params::default(), &mut NoProgress)
        .expect_err("too little wall for an outline");
    let why = e.to_string();
    assert!(
        why.contains("no floor was seen") && why.contains("walls were seen along only"),
        "{why}"
    );
}
