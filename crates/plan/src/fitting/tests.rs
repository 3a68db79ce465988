//! End-to-end tests of the fitting stage on hand-built labelings.

use crate::cancel::Cancel;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;
use crate::boundary::trace_boundary;
use crate::cleanup::tests::{label_by_rings, ring_samples};
use crate::cleanup::{clean_labels, CleanupParams};
use crate::labeling::Mesh;
use crate::plan::WallModel;

/// Samples the true rings every 5 cm (plus Gaussian noise of `sigma` metres), triangulates,
/// labels by centroid, cleans, traces, checks watertightness and fits.
fn fit(truth: &[Vec<P2>], sigma: f64, params: &FittingParams) -> (LabeledMesh, FittedStory) {
    fit_seeded(truth, sigma, params, 7)
}

fn fit_seeded(
    truth: &[Vec<P2>],
    sigma: f64,
    params: &FittingParams,
    seed: u64,
) -> (LabeledMesh, FittedStory) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sigma.max(1e-300)).unwrap();
    let (mut pts, mut normals) = (Vec::new(), Vec::new());
    for ring in truth {
        let (p, n) = ring_samples(ring, 0.05);
        pts.extend(p.into_iter().map(|q| {
            if sigma > 0.0 {
                [q[0] + noise.sample(&mut rng), q[1] + noise.sample(&mut rng)]
            } else {
                q
            }
        }));
        normals.extend(n);
    }
    let mut l = label_by_rings(Mesh::build(&pts, &normals).unwrap(), truth);
    clean_labels(&mut l, &CleanupParams::default());
    let b = trace_boundary(&l).unwrap();
    b.check(&l).unwrap();
    let f = fit_walls(&l, &b, params, &Cancel::never()).unwrap();
    assert_valid(&f);
    (l, f)
}

/// The fitted polygons pass the validity test.
fn assert_valid(f: &FittedStory) {
    let mut rings = Vec::new();
    let mut ext = Vec::new();
    for p in &f.polygons {
        let e = rings.len();
        rings.push(p.exterior.clone());
        ext.push(None);
        for h in &p.holes {
            rings.push(h.clone());
            ext.push(Some(e));
        }
    }
    let problems = simple::problems(&rings, &ext);
    assert!(problems.is_empty(), "{problems:?}");
    let by_geo = validity::problems(&f.polygons, &Grid::local());
    assert!(by_geo.is_empty(), "{by_geo:?}");
}

/// Largest distance from a true corner to the nearest vertex of `ring`.
fn corner_error(truth: &[P2], ring: &[P2]) -> f64 {
    truth
        .iter()
        .map(|c| {
            ring.iter()
                .map(|p| geom::dist(*p, *c))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

fn room() -> Vec<P2> {
    vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]]
}

#[test]
fn room_gives_four_line_walls_with_exact_corners() {
    let (_, f) = fit(&[room()], 0.0, &FittingParams::default());
    assert_eq!(f.polygons.len(), 1);
    let ext = &f.polygons[0].exterior;
    assert_eq!(ext.len(), 4, "{ext:?}");
    let err = corner_error(&room(), ext);
    eprintln!("room 4 × 3 m (noise-free): max corner error {:.2e} m", err);
    assert!(err < 1e-3, "corner error {err}");
    assert!((geom::ring_signed_area(ext) - 12.0).abs() < 1e-2);
    assert_eq!(f.walls.len(), 4);
    assert!(f.walls.iter().all(|w| w.model == WallModel::Line));
    let total: f64 = f.walls.iter().map(Wall::length).sum();
    assert!((total - 14.0).abs() < 4e-3, "wall length {total}");
    assert!(f.notes.is_empty());
}

#[test]
fn noisy_room_corners_within_a_centimetre() {
    let (_, f) = fit(&[room()], 0.005, &FittingParams::default());
    let ext = &f.polygons[0].exterior;
    assert_eq!(ext.len(), 4, "{ext:?}");
    let err = corner_error(&room(), ext);
    eprintln!(
        "noisy room (σ = 5 mm): max corner error {:.2} mm",
        err * 1e3
    );
    assert!(err < 0.01, "corner error {err}");
}

#[test]
fn l_shape_gives_six_walls_with_exact_corners() {
    let l_shape = vec![
        [0.0, 0.0],
        [5.0, 0.0],
        [5.0, 2.0],
        [2.0, 2.0],
        [2.0, 4.0],
        [0.0, 4.0],
    ];
    let (_, f) = fit(
        std::slice::from_ref(&l_shape),
        0.0,
        &FittingParams::default(),
    );
    let ext = &f.polygons[0].exterior;
    assert_eq!(ext.len(), 6, "{ext:?}");
    let err = corner_error(&l_shape, ext);
    eprintln!("L shape (noise-free): max corner error {:.2e} m", err);
    assert!(err < 1e-3);
    assert_eq!(f.walls.len(), 6);
    assert!((geom::ring_signed_area(ext) - 14.0).abs() < 1e-2);
}

#[test]
fn room_with_a_column_keeps_its_hole() {
    let column = vec![[1.5, 1.0], [1.5, 2.0], [2.5, 2.0], [2.5, 1.0]];
    let (_, f) = fit(&[room(), column.clone()], 0.0, &FittingParams::default());
    assert_eq!(f.polygons.len(), 1);
    let p = &f.polygons[0];
    assert_eq!(p.holes.len(), 1);
    assert_eq!(p.holes[0].len(), 4, "{:?}", p.holes[0]);
    assert!(corner_error(&column, &p.holes[0]) < 1e-3);
    assert!(geom::ring_signed_area(&p.holes[0]) < 0.0);
    assert_eq!(f.walls.len(), 8);
}

#[test]
fn round_room_becomes_one_arc_within_half_a_percent() {
    let (r, c) = (5.0, [1.0, 2.0]);
    let circle: Vec<P2> = (0..628)
        .map(|i| {
            let a = i as f64 * std::f64::consts::TAU / 628.0;
            [c[0] + r * a.cos(), c[1] + r * a.sin()]
        })
        .collect();
    let (_, f) = fit(&[circle], 0.003, &FittingParams::default());
    assert_eq!(
        f.walls.len(),
        1,
        "{:?}",
        f.walls.iter().map(|w| w.model).collect::<Vec<_>>()
    );
    let WallModel::Arc { center, radius } = f.walls[0].model else {
        panic!("expected an arc");
    };
    let rel = (radius - r).abs() / r;
    eprintln!(
        "round room r = 5 m (σ = 3 mm): radius error {:.3}%, centre error {:.2} mm",
        rel * 100.0,
        geom::dist(center, c) * 1e3
    );
    assert!(rel < 0.005, "radius {radius}");
    assert!(geom::dist(center, c) < 0.01);
    // Densified to 1 cm chord error: every vertex on the circle, every chord midpoint within 1 cm.
    let ext = &f.polygons[0].exterior;
    for (i, p) in ext.iter().enumerate() {
        assert!((geom::dist(*p, center) - radius).abs() < 1e-9);
        let q = ext[(i + 1) % ext.len()];
        let mid = geom::scale(geom::add(*p, q), 0.5);
        assert!(radius - geom::dist(mid, center) <= 0.01 + 1e-9);
    }
}

#[test]
fn rooms_2_cm_apart_come_out_valid() {
    // Two rooms 2 cm apart, closer than the inlier band: however their facing walls are
    // fitted, the plan is valid (checked in `fit`) and keeps their area.
    let a = room();
    let b = vec![[4.02, 0.0], [8.02, 0.0], [8.02, 3.0], [4.02, 3.0]];
    let (_, f) = fit(&[a, b], 0.0, &FittingParams::default());
    let area: f64 = f
        .polygons
        .iter()
        .map(|p| geom::ring_signed_area(&p.exterior))
        .sum();
    assert!((area - 24.0).abs() < 0.1, "{area}");
    // The outer sides are fitted.
    assert!(f.walls.len() >= 6, "{} walls", f.walls.len());
}

#[test]
fn bad_params_and_empty_boundary() {
    let (l, _) = fit(&[room()], 0.0, &FittingParams::default());
    let b = trace_boundary(&l).unwrap();
    let p = FittingParams {
        inlier_distance: f64::NAN,
        ..Default::default()
    };
    assert!(matches!(
        fit_walls(&l, &b, &p, &Cancel::never()),
        Err(FittingError::BadParam {
            name: "inlier_distance",
            ..
        })
    ));
    let p = FittingParams {
        min_inliers: 1,
        ..Default::default()
    };
    assert!(fit_walls(&l, &b, &p, &Cancel::never()).is_err());
    let empty = fit_walls(
        &l,
        &Boundary::default(),
        &FittingParams::default(),
        &Cancel::never(),
    )
    .unwrap();
    assert!(empty.polygons.is_empty() && empty.walls.is_empty());
}

#[test]
fn fitting_repeats_exactly() {
    let (l, f) = fit(&[room()], 0.005, &FittingParams::default());
    let b = trace_boundary(&l).unwrap();
    assert_eq!(
        fit_walls(&l, &b, &FittingParams::default(), &Cancel::never()).unwrap(),
        f
    );
}

/// `n` points of a circle (or an arc from `a0` sweeping `sweep`), as a polygon.
fn arc(c: P2, r: f64, a0: f64, sweep: f64, n: usize) -> Vec<P2> {
    (0..n)
        .map(|i| {
            let a = a0 + sweep * i as f64 / n as f64;
            [c[0] + r * a.cos(), c[1] + r * a.sin()]
        })
        .collect()
}

#[test]
fn apse_room_with_round_column_under_noise() {
    use std::f64::consts::PI;
    // A 6 × 4 m room whose right side is a half circle of radius 2 about (6, 2), with a round
    // column of radius 0.4 at (2.5, 2).
    let mut outer = vec![[0.0, 0.0], [6.0, 0.0]];
    outer.extend(arc([6.0, 2.0], 2.0, -PI / 2.0, PI, 200).into_iter().skip(1));
    outer.push([6.0, 4.0]);
    outer.push([0.0, 4.0]);
    let mut column = arc([2.5, 2.0], 0.4, 0.0, -2.0 * PI, 60);
    column.rotate_left(1);
    let truth = [outer, column];
    let mut worst_radius = [0.0f64; 2];
    for (seed, sigma) in [(1, 0.0), (2, 0.003), (3, 0.005), (4, 0.01)] {
        let (_, f) = fit_seeded(&truth, sigma, &FittingParams::default(), seed);
        assert_eq!(f.polygons.len(), 1);
        assert_eq!(f.polygons[0].holes.len(), 1, "column lost at σ = {sigma}");
        let arcs: Vec<(P2, f64)> = f
            .walls
            .iter()
            .filter_map(|w| match w.model {
                WallModel::Arc { center, radius } => Some((center, radius)),
                WallModel::Line => None,
            })
            .collect();
        for (k, (c, r)) in [([6.0, 2.0], 2.0), ([2.5, 2.0], 0.4)]
            .into_iter()
            .enumerate()
        {
            let found = arcs
                .iter()
                .find(|(cc, _)| geom::dist(*cc, c) < 0.05)
                .unwrap_or_else(|| panic!("σ = {sigma}: no arc about {c:?} in {arcs:?}"));
            let rel = (found.1 - r).abs() / r;
            worst_radius[k] = worst_radius[k].max(rel);
            eprintln!(
                "σ = {:.0} mm: arc r = {r} m fitted {:.4} m ({:.3}%)",
                sigma * 1e3,
                found.1,
                rel * 100.0
            );
            assert!(rel < 0.02, "σ = {sigma}: radius {} for {r}", found.1);
        }
        let lines = f
            .walls
            .iter()
            .filter(|w| w.model == WallModel::Line)
            .count();
        assert!(lines >= 3, "σ = {sigma}: {lines} line walls");
        let err = corner_error(&[[0.0, 0.0], [0.0, 4.0]], &f.polygons[0].exterior);
        assert!(err < 0.01, "σ = {sigma}: corner error {err}");
    }
    eprintln!(
        "apse r = 2 m worst radius error {:.3}%, column r = 0.4 m {:.3}% (σ up to 1 cm)",
        worst_radius[0] * 100.0,
        worst_radius[1] * 100.0
    );
}

#[test]
fn many_noisy_layouts_stay_valid() {
    // Rooms side by side with 10 cm walls, doorless, under up to 2 cm noise: whatever the
    // models do, the plan must come out valid (checked inside `fit`).
    for seed in 0..6 {
        let sigma = 0.004 * seed as f64;
        let mut truth = Vec::new();
        for i in 0..3 {
            for j in 0..2 {
                let (x, y) = (i as f64 * 3.1, j as f64 * 2.6);
                truth.push(vec![[x, y], [x + 3.0, y], [x + 3.0, y + 2.5], [x, y + 2.5]]);
            }
        }
        let (_, f) = fit_seeded(&truth, sigma, &FittingParams::default(), seed);
        assert_eq!(f.polygons.len(), 6, "σ = {sigma}");
        // Up to 1 cm the four walls are found (corners may keep a traced vertex or two).
        if sigma <= 0.01 {
            for p in &f.polygons {
                assert!(
                    p.exterior.len() <= 8,
                    "σ = {sigma}: {} vertices",
                    p.exterior.len()
                );
            }
        }
    }
}

#[test]
fn a_crossing_traced_boundary_is_resolved_not_a_panic() {
    use crate::boundary::{BoundaryPolygon, Ring};
    let (l, _) = fit(&[room()], 0.0, &FittingParams::default());
    // A bow tie over four mesh vertices: too few samples for any model, and self-crossing.
    let near = |q: P2| {
        (0..l.mesh.n_samples)
            .min_by(|&a, &b| {
                geom::dist(l.mesh.vertices[a], q).total_cmp(&geom::dist(l.mesh.vertices[b], q))
            })
            .unwrap() as u32
    };
    let vertices = vec![
        near([0.0, 0.0]),
        near([4.0, 3.0]),
        near([4.0, 0.0]),
        near([0.0, 3.0]),
    ];
    let bow = Boundary {
        polygons: vec![BoundaryPolygon {
            exterior: Ring {
                vertices,
                signed_area: 1.0,
            },
            holes: Vec::new(),
        }],
    };
    let f = fit_walls(&l, &bow, &FittingParams::default(), &Cancel::never()).unwrap();
    assert_valid(&f);
    // The bow tie's counter-clockwise lobe (a quarter of the room) is what stays inside.
    assert_eq!(f.polygons.len(), 1, "{:?}", f.polygons);
    let area = geom::ring_signed_area(&f.polygons[0].exterior);
    assert!((area - 3.0).abs() < 0.1, "{area}");
    assert_eq!(f.notes.len(), 1, "{:?}", f.notes);
}

#[test]
fn rooms_joined_by_a_door_keep_the_jambs() {
    // Two 4 × 3 m rooms behind a 10 cm wall, joined by a 0.9 m door. The jamb faces hold only
    // two samples each, too few for a model: they join neighbouring models by growing.
    let plan = vec![
        [0.0, 0.0],
        [4.0, 0.0],
        [4.0, 1.0],
        [4.1, 1.0],
        [4.1, 0.0],
        [8.1, 0.0],
        [8.1, 3.0],
        [4.1, 3.0],
        [4.1, 1.9],
        [4.0, 1.9],
        [4.0, 3.0],
        [0.0, 3.0],
    ];
    let (_, f) = fit(
        std::slice::from_ref(&plan),
        0.003,
        &FittingParams::default(),
    );
    assert_eq!(f.polygons.len(), 1);
    let ext = &f.polygons[0].exterior;
    let outer = [[0.0, 0.0], [8.1, 0.0], [8.1, 3.0], [0.0, 3.0]];
    let err = corner_error(&outer, ext);
    let jambs = corner_error(&plan, ext);
    let area = geom::ring_signed_area(ext);
    eprintln!(
        "door plan (σ = 3 mm): outer corners {:.1} mm, all corners incl. jambs {:.1} mm, area {:.4} m² (true {:.4})",
        err * 1e3,
        jambs * 1e3,
        area,
        geom::ring_signed_area(&plan)
    );
    assert!(err < 0.01);
    assert!(jambs < 0.02);
    assert!((area - geom::ring_signed_area(&plan)).abs() < 0.05);
}

/// A 4 × 3 m room whose top wall is seen only from x = 1.6 on and whose left wall only up to
/// y = 1.6: the labeling cuts the top-left corner with the diagonal between the last samples.
/// `extra` adds samples (with the labels unchanged).
fn room_with_an_unseen_corner(extra: &[P2], params: &FittingParams) -> FittedStory {
    let room = room();
    let (pts, normals) = ring_samples(&room, 0.05);
    let unseen = |p: &P2| (p[1] > 2.99 && p[0] < 1.6) || (p[0] < 0.01 && p[1] > 1.6);
    let (mut pts, mut normals): (Vec<P2>, Vec<P2>) = pts
        .into_iter()
        .zip(normals)
        .filter(|(p, _)| !unseen(p))
        .unzip();
    pts.extend(extra);
    normals.extend(extra.iter().map(|_| [1.0, 0.0]));
    let cut = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [1.6, 3.0], [0.0, 1.6]];
    let mut l = label_by_rings(Mesh::build(&pts, &normals).unwrap(), &[cut]);
    clean_labels(&mut l, &CleanupParams::default());
    let b = trace_boundary(&l).unwrap();
    let f = fit_walls(&l, &b, params, &Cancel::never()).unwrap();
    assert_valid(&f);
    f
}

#[test]
fn a_corner_left_unseen_is_completed_where_the_walls_meet() {
    let f = room_with_an_unseen_corner(&[], &FittingParams::default());
    assert_eq!(f.polygons.len(), 1);
    let ext = &f.polygons[0].exterior;
    assert!(corner_error(&room(), ext) < 0.01, "{ext:?}");
    let area = geom::ring_signed_area(ext);
    assert!((area - 12.0).abs() < 0.02, "{area}");
    // The paper's rule (corners only near both runs' ends) keeps the diagonal.
    let paper = FittingParams {
        max_open_corner: 0.0,
        ..Default::default()
    };
    let f = room_with_an_unseen_corner(&[], &paper);
    let area = geom::ring_signed_area(&f.polygons[0].exterior);
    // About 1.6 × 1.4 / 2 m² lost to the diagonal between the last samples.
    assert!(area < 11.0, "{area}");
}

#[test]
fn a_corner_holding_samples_is_not_completed() {
    // Something seen inside the cut-off corner (a column's face, say): it is not empty floor,
    // so the walls do not meet over it.
    let f = room_with_an_unseen_corner(&[[0.3, 2.7], [0.35, 2.7]], &FittingParams::default());
    let ext = &f.polygons[0].exterior;
    assert!(
        !ext.iter().any(|p| geom::dist(*p, [0.0, 3.0]) < 0.05),
        "{ext:?}"
    );
}

#[test]
fn crossing_fits_start_again_and_keep_the_fewest_crossings() {
    // Rooms side by side with 10 cm walls under 2 cm noise, and RANSAC held to a few draws:
    // some searches put models that cross. Every fit keeps at most the first start's
    // crossings, and at least one of these layouts is saved by another start.
    let params = FittingParams {
        iterations: 3,
        ..FittingParams::default()
    };
    let mut saved = 0;
    for seed in 0..24 {
        let mut truth = Vec::new();
        for i in 0..3 {
            for j in 0..2 {
                let (x, y) = (i as f64 * 3.1, j as f64 * 2.6);
                truth.push(vec![[x, y], [x + 3.0, y], [x + 3.0, y + 2.5], [x, y + 2.5]]);
            }
        }
        let (l, f) = fit_seeded(&truth, 0.02, &params, seed);
        let b = trace_boundary(&l).unwrap();
        let (samples, rings, exterior_of) = collect_samples(&l, &b);
        let first = fit_once(
            &l,
            &samples,
            &rings,
            &exterior_of,
            &params,
            &Cancel::never(),
        )
        .unwrap()
        .1;
        let retried = f.notes.iter().any(|n| n.contains("another random start"));
        if first == 0 {
            assert!(!retried, "seed {seed}: {:?}", f.notes);
        } else if retried {
            saved += 1;
        }
    }
    assert!(saved > 0, "no layout was refitted");
}
