//! Degenerate clouds through the whole pipeline: each gets a clear error or a sensible plan,
//! never a panic. The clouds are built by hand on a 2 cm lattice, so every case is exact.

use asbuilt_plan::cloud::PointCloud;
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::{plan, FloorPlan, Params, PlanError};

/// Points of a horizontal rectangle at height `z`, every `step` metres.
fn slab(x: (f64, f64), y: (f64, f64), z: f64, step: f64, out: &mut Vec<[f64; 3]>) {
    let nx = ((x.1 - x.0) / step) as usize;
    let ny = ((y.1 - y.0) / step) as usize;
    for i in 0..=nx {
        for j in 0..=ny {
            out.push([x.0 + i as f64 * step, y.0 + j as f64 * step, z]);
        }
    }
}

/// Points of a vertical wall from `a` to `b`, floor 0 to ceiling 2.7 m, every `step` metres.
fn wall(a: [f64; 2], b: [f64; 2], step: f64, out: &mut Vec<[f64; 3]>) {
    let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
    let n = (len / step) as usize;
    for i in 0..=n {
        let t = i as f64 / n as f64;
        for k in 0..=((2.7 / step) as usize) {
            out.push([
                a[0] + t * (b[0] - a[0]),
                a[1] + t * (b[1] - a[1]),
                k as f64 * step,
            ]);
        }
    }
}

/// Floor and ceiling of a 4 m × 3 m room.
fn floor_and_ceiling(out: &mut Vec<[f64; 3]>) {
    slab((0.0, 4.0), (0.0, 3.0), 0.0, 0.02, out);
    slab((0.0, 4.0), (0.0, 3.0), 2.7, 0.02, out);
}

/// The closed 4 m × 3 m room: floor, ceiling and four walls.
fn room() -> Vec<[f64; 3]> {
    let mut p = Vec::new();
    floor_and_ceiling(&mut p);
    let c = [[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]];
    for k in 0..4 {
        wall(c[k], c[(k + 1) % 4], 0.02, &mut p);
    }
    p
}

fn run(points: &[[f64; 3]]) -> Result<FloorPlan, PlanError> {
    plan(
        &PointCloud::from_world(points),
        &Params::default(),
        &mut NoProgress,
    )
}

#[test]
fn an_empty_cloud_is_refused() {
    let e = plan(&PointCloud::default(), &Params::default(), &mut NoProgress).unwrap_err();
    assert!(matches!(e, PlanError::EmptyCloud), "{e}");
    assert_eq!(e.to_string(), "the cloud is empty");
}

#[test]
fn a_nan_coordinate_is_refused_by_name() {
    let mut p = room();
    p[10][1] = f64::NAN;
    let e = run(&p).unwrap_err();
    assert_eq!(e.code(), "bad_cloud");
    assert!(e.to_string().contains("non-finite"), "{e}");
}

#[test]
fn a_single_plane_has_no_story() {
    let mut p = Vec::new();
    slab((0.0, 4.0), (0.0, 3.0), 0.0, 0.02, &mut p);
    let e = run(&p).unwrap_err();
    assert_eq!(e.code(), "no_stories", "{e}");
    assert!(e.to_string().contains("no floor or ceiling"), "{e}");
}

#[test]
fn a_wall_alone_encloses_nothing() {
    // Evenly spaced heights make every lattice row a level, so a story is found; its samples
    // all lie on the one wall.
    let mut p = Vec::new();
    wall([0.0, 0.0], [4.0, 0.0], 0.02, &mut p);
    let e = run(&p).unwrap_err();
    assert_eq!(e.code(), "labeling_failed", "{e}");
    assert!(e.to_string().contains("collinear"), "{e}");
}

#[test]
fn floor_and_ceiling_without_walls_say_so() {
    // Two equally dense levels and nothing between: no step down to wall bins marks them.
    let mut p = Vec::new();
    floor_and_ceiling(&mut p);
    let e = run(&p).unwrap_err();
    assert_eq!(e.code(), "no_stories", "{e}");
    assert!(e.to_string().contains("no dense floor or ceiling"), "{e}");
    // With a pole of points between them the story is found, but there is nothing to label.
    for k in 1..100 {
        p.push([2.0, 1.5, k as f64 * 0.027]);
    }
    let e = run(&p).unwrap_err();
    assert_eq!(e.code(), "labeling_failed", "{e}");
    assert!(e.to_string().contains("too few wall samples"), "{e}");
}

#[test]
fn one_wall_only_gives_collinear_samples_and_a_clear_error() {
    let mut p = Vec::new();
    floor_and_ceiling(&mut p);
    wall([0.0, 1.5], [4.0, 1.5], 0.02, &mut p);
    let e = run(&p).unwrap_err();
    assert_eq!(e.code(), "labeling_failed", "{e}");
    assert!(e.to_string().contains("collinear"), "{e}");
}

#[test]
fn the_closed_room_and_its_duplicated_points_give_the_same_plan() {
    let p = room();
    let once = run(&p).unwrap();
    let mut twice = p.clone();
    twice.extend(p.iter().copied());
    let doubled = run(&twice).unwrap();
    assert_eq!(once.stories.len(), 1);
    let (a, b) = (&once.stories[0], &doubled.stories[0]);
    let area = |s: &asbuilt_plan::plan::StoryPlan| s.area();
    // The open floor is the 4 m × 3 m room, to within the half-cell the samples sit inside.
    assert!((area(a) - 12.0).abs() < 0.3, "area {}", area(a));
    assert!(
        (area(a) - area(b)).abs() < 1e-6,
        "{} vs {}",
        area(a),
        area(b)
    );
    assert_eq!(a.walls.len(), b.walls.len());
}
