//! End-to-end labeling of hand-made rooms: samples along walls with normals, no simulator.

use super::*;
use crate::cancel::Cancel;
use crate::geom::P2;
use crate::samples::WallSample;

/// Samples every `step` along the closed polygon `ring` (CCW), normals pointing inward.
fn ring_samples(ring: &[P2], step: f64, seen_from: &[u32]) -> Vec<WallSample> {
    let mut out = Vec::new();
    for i in 0..ring.len() {
        let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
        let len = crate::geom::dist(a, b);
        let n = (len / step).round().max(1.0) as usize;
        let dir = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
        for k in 0..n {
            let t = k as f64 / n as f64;
            out.push(WallSample {
                pos: [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])],
                normal: [-dir[1], dir[0]],
                confidence: 1.0,
                seen_from: seen_from.to_vec(),
            });
        }
    }
    out
}

fn in_rect(p: P2, r: [f64; 4]) -> bool {
    p[0] > r[0] && p[0] < r[2] && p[1] > r[1] && p[1] < r[3]
}

fn rect_ring(r: [f64; 4]) -> Vec<P2> {
    vec![[r[0], r[1]], [r[2], r[1]], [r[2], r[3]], [r[0], r[3]]]
}

/// IoU of the labeled inside area against `truth`, measured on a fine grid of points.
fn iou(l: &LabeledMesh, truth: impl Fn(P2) -> bool) -> f64 {
    let (mut both, mut either) = (0usize, 0usize);
    let (lo, hi) = (
        l.mesh.vertices[l.mesh.n_samples],
        l.mesh.vertices[l.mesh.n_samples + 2],
    );
    let mut hint = 0;
    let steps = 200;
    for i in 0..steps {
        for j in 0..steps {
            let p = [
                lo[0] + (hi[0] - lo[0]) * (i as f64 + 0.5) / steps as f64,
                lo[1] + (hi[1] - lo[1]) * (j as f64 + 0.5) / steps as f64,
            ];
            let t = walk::locate(&l.mesh, p, hint).expect("inside the box");
            hint = t;
            let (a, b) = (l.inside[t as usize], truth(p));
            both += (a && b) as usize;
            either += (a || b) as usize;
        }
    }
    both as f64 / either.max(1) as f64
}

fn check_invariants(l: &LabeledMesh, r: &LabelingReport) {
    l.mesh.check().unwrap();
    assert_eq!(l.inside.len(), l.mesh.triangles.len());
    for t in 0..l.inside.len() {
        if let Some(f) = l.forced[t] {
            assert_eq!(l.inside[t], f, "forced triangle {t} relabeled");
        }
        if l.mesh.touches_corner(t) {
            assert_eq!(l.forced[t], Some(false));
        }
    }
    if let Some(res) = r.residual {
        if r.method != Method::Harmonic {
            assert!(res <= 1e-8, "residual {res}");
        }
    }
}

fn params(dense_below: usize) -> LabelingParams {
    LabelingParams {
        dense_below,
        ..Default::default()
    }
}

const ROOM: [f64; 4] = [0.0, 0.0, 4.0, 3.0];

#[test]
fn square_room_without_poses_is_inside_from_geometry_alone() {
    let samples = WallSamples {
        samples: ring_samples(&rect_ring(ROOM), 0.05, &[]),
        ..Default::default()
    };
    for dense_below in [2000, 0] {
        let (l, r) = label_with_report(&samples, &params(dense_below), &Cancel::never()).unwrap();
        check_invariants(&l, &r);
        let expect = if dense_below == 0 {
            Method::SparseEigen
        } else {
            Method::DenseEigen
        };
        assert_eq!(r.method, expect, "{:?}", r.fallback);
        assert_eq!(r.forced_inside, 0);
        assert!(r.negative_adjacent + r.negative_apart > 0);
        let score = iou(&l, |p| in_rect(p, ROOM));
        assert!(score > 0.95, "IoU {score} ({dense_below})");
        assert!(r.disagreement.unwrap() < 0.02);
    }
}

#[test]
fn square_room_with_a_pose_and_lines_of_sight() {
    let mut samples = WallSamples {
        samples: ring_samples(&rect_ring(ROOM), 0.05, &[0]),
        viewpoints: vec![[1.3, 1.7]],
        ..Default::default()
    };
    let (l, r) = label_with_report(&samples, &params(0), &Cancel::never()).unwrap();
    check_invariants(&l, &r);
    assert_eq!(r.inside_by_poses, 1);
    assert!(r.inside_by_rays > 0);
    assert_eq!(r.rays, samples.samples.len());
    let score = iou(&l, |p| in_rect(p, ROOM));
    assert!(score > 0.95, "IoU {score}");
    // The harmonic solver labels the same room.
    samples.viewpoints = vec![[2.9, 0.6]];
    let p = LabelingParams {
        solver: Solver::Harmonic,
        ..params(0)
    };
    let (l, r) = label_with_report(&samples, &p, &Cancel::never()).unwrap();
    check_invariants(&l, &r);
    assert_eq!(r.method, Method::Harmonic);
    assert!(r.eigenvalue.is_none());
    assert!(iou(&l, |p| in_rect(p, ROOM)) > 0.95);
}

#[test]
fn a_pose_forces_its_triangle_inside_even_against_the_geometry() {
    // A pose in the empty space beside the room: geometry alone calls it outside.
    let samples = WallSamples {
        samples: ring_samples(&rect_ring(ROOM), 0.05, &[]),
        viewpoints: vec![[5.0, 1.5]],
        ..Default::default()
    };
    let (l, r) = label_with_report(&samples, &params(0), &Cancel::never()).unwrap();
    check_invariants(&l, &r);
    let t = walk::locate(&l.mesh, [5.0, 1.5], 0).unwrap() as usize;
    if l.mesh.touches_corner(t) {
        // Outside wins on conflict.
        assert_eq!(r.conflicts, 1);
        assert!(!l.inside[t]);
    } else {
        assert_eq!(l.forced[t], Some(true));
        assert!(l.inside[t]);
    }
}

#[test]
fn two_rooms_with_a_thick_wall_and_a_door() {
    // Rooms [0,4]×[0,3] and [4.2,8]×[0,3]; a 0.2 m wall between them with a 0.9 m door.
    let a = [0.0, 0.0, 4.0, 3.0];
    let b = [4.2, 0.0, 8.0, 3.0];
    let truth = |p: P2| in_rect(p, a) || in_rect(p, b) || in_rect(p, [4.0, 1.0, 4.2, 1.9]);
    let ring: Vec<P2> = vec![
        [0.0, 0.0],
        [4.0, 0.0],
        [4.0, 1.0],
        [4.2, 1.0],
        [4.2, 0.0],
        [8.0, 0.0],
        [8.0, 3.0],
        [4.2, 3.0],
        [4.2, 1.9],
        [4.0, 1.9],
        [4.0, 3.0],
        [0.0, 3.0],
    ];
    for with_poses in [false, true] {
        let mut all = ring_samples(&ring, 0.05, &[]);
        if with_poses {
            // Each room's pose sees its own walls; the door jambs are seen from both.
            for s in &mut all {
                s.seen_from = match s.pos[0] {
                    x if x < 4.0 - 1e-9 => vec![0],
                    x if x > 4.2 + 1e-9 => vec![1],
                    _ => vec![0, 1],
                };
            }
        }
        let samples = WallSamples {
            samples: all,
            viewpoints: if with_poses {
                vec![[2.0, 1.5], [6.0, 1.5]]
            } else {
                vec![]
            },
            ..Default::default()
        };
        let (l, r) = label_with_report(&samples, &params(800), &Cancel::never()).unwrap();
        check_invariants(&l, &r);
        let score = iou(&l, truth);
        assert!(score > 0.95, "IoU {score}, poses {with_poses}, {r:?}");
    }
}

#[test]
fn bad_input_gives_clear_errors() {
    let few = WallSamples {
        samples: ring_samples(&[[0.0, 0.0], [1.0, 0.0]], 1.0, &[]),
        ..Default::default()
    };
    assert!(matches!(
        label(&few, &LabelingParams::default(), &Cancel::never()),
        Err(LabelingError::TooFewSamples(2))
    ));
    let line = WallSamples {
        samples: (0..50)
            .map(|i| WallSample {
                pos: [i as f64 * 0.1, 2.0 * i as f64 * 0.1],
                normal: [2.0, -1.0],
                confidence: 1.0,
                seen_from: vec![],
            })
            .collect(),
        ..Default::default()
    };
    assert!(matches!(
        label(&line, &LabelingParams::default(), &Cancel::never()),
        Err(LabelingError::Collinear(50))
    ));
    let room = WallSamples {
        samples: ring_samples(&rect_ring(ROOM), 0.5, &[]),
        ..Default::default()
    };
    let bad = LabelingParams {
        ray_fraction: 0.0,
        ..Default::default()
    };
    assert!(matches!(
        label(&room, &bad, &Cancel::never()),
        Err(LabelingError::BadParam { .. })
    ));
    // A viewpoint index out of range or a NaN viewpoint is skipped, not a panic.
    let mut odd = room.clone();
    odd.samples[0].seen_from = vec![7];
    odd.viewpoints = vec![[f64::NAN, 1.0]];
    odd.samples[1].seen_from = vec![0];
    let (_, r) = label_with_report(&odd, &LabelingParams::default(), &Cancel::never()).unwrap();
    assert_eq!(r.rays_skipped, 2);
}

#[test]
fn mobile_path_forces_the_triangles_it_crosses() {
    let samples = WallSamples {
        samples: ring_samples(&rect_ring(ROOM), 0.05, &[]),
        path: vec![[0.5, 0.5], [3.5, 0.6], [3.4, 2.5], [0.7, 2.4]],
        ..Default::default()
    };
    let (l, r) = label_with_report(&samples, &LabelingParams::default(), &Cancel::never()).unwrap();
    check_invariants(&l, &r);
    assert!(r.inside_by_path > 0);
    assert_eq!(r.forced_inside, r.inside_by_path);
    let t = l.mesh.locate([2.0, 0.55], 0).unwrap();
    assert_eq!(l.forced[t], Some(true));
    assert!(iou(&l, |p| in_rect(p, ROOM)) > 0.95);
}

#[test]
fn duplicate_and_non_finite_samples_do_not_panic() {
    let mut s = ring_samples(&rect_ring(ROOM), 0.1, &[]);
    // Exact duplicates merge.
    let copy = s.clone();
    s.extend(copy);
    let samples = WallSamples {
        samples: s.clone(),
        ..Default::default()
    };
    let (l, r) = label_with_report(&samples, &LabelingParams::default(), &Cancel::never()).unwrap();
    check_invariants(&l, &r);
    assert_eq!(r.samples, s.len() / 2);
    s[3].pos = [f64::NAN, 1.0];
    let bad = WallSamples {
        samples: s,
        ..Default::default()
    };
    assert!(matches!(
        label(&bad, &LabelingParams::default(), &Cancel::never()),
        Err(LabelingError::Mesh(MeshError::BadCoordinate(_)))
    ));
}

#[test]
fn a_wall_seen_well_from_one_room_only_is_not_carved_by_the_other() {
    // Rooms A [0,4]×[0,3] and B [0,4]×[3.2,6.2], a 0.2 m wall between them. B saw its face of
    // the wall only from x = 1.5 on (a scanner that just stepped in). B's lines of sight to its
    // west wall then cross triangles reaching from A's face, over the wall, into B.
    let (a, b) = ([0.0, 0.0, 4.0, 3.0], [0.0, 3.2, 4.0, 6.2]);
    let mut all = ring_samples(&rect_ring(a), 0.05, &[0]);
    all.extend(
        ring_samples(&rect_ring(b), 0.05, &[1])
            .into_iter()
            .filter(|s| !(s.pos[1] < 3.2 + 1e-9 && s.pos[0] < 1.5)),
    );
    let samples = WallSamples {
        samples: all,
        viewpoints: vec![[2.0, 1.5], [2.0, 4.7]],
        // Backs are placed only for a mobile scan: the walker in room B.
        path: vec![[2.0, 4.7], [2.5, 4.7]],
        ..Default::default()
    };
    let in_wall = [[0.5, 3.1], [1.0, 3.1], [1.3, 3.1]];
    let inside_at =
        |l: &LabeledMesh, p: P2| l.inside[walk::locate(&l.mesh, p, 0).unwrap() as usize];
    // Without backs, the wall's end is carved: the two rooms join.
    let off = LabelingParams {
        wall_backs: false,
        ..params(0)
    };
    let (l, r) = label_with_report(&samples, &off, &Cancel::never()).unwrap();
    check_invariants(&l, &r);
    assert_eq!(r.backed, 0);
    assert!(
        in_wall.iter().any(|&p| inside_at(&l, p)),
        "not carved: the case shows nothing"
    );
    // Without a path (static scans) no backs are placed...
    let mut still = samples.clone();
    still.path.clear();
    let (_, r) = label_with_report(&still, &params(0), &Cancel::never()).unwrap();
    assert_eq!(r.backed, 0);
    // ...unless the points say a scanner walked (times, path unknown).
    let walked = WallSamples {
        moving: true,
        ..still
    };
    let (l, r) = label_with_report(&walked, &params(0), &Cancel::never()).unwrap();
    assert!(r.backed > 0);
    for p in in_wall {
        assert!(!inside_at(&l, p), "{p:?} carved without the path");
    }
    // With them, the wall stands, and both rooms are whole.
    let (l, r) = label_with_report(&samples, &params(0), &Cancel::never()).unwrap();
    check_invariants(&l, &r);
    assert!(r.backed > 0);
    for p in in_wall {
        assert!(!inside_at(&l, p), "{p:?} carved");
    }
    let score = iou(&l, |p| in_rect(p, a) || in_rect(p, b));
    assert!(score > 0.97, "IoU {score}");
}

/// Two 4 m rooms side by side, A (x 0..4) and B (x 4.1..8), a wall between them of which only
/// A's face (x = 4) was sampled: B's face is a mirror. B's scanner recorded the mirror's image
/// of its room as points beyond the wall, inside A (a row at x = 1, facing B).
fn mirror_rooms() -> WallSamples {
    let (a, b) = (0u32, 1u32);
    let mut samples = Vec::new();
    let mut row = |from: P2, to: P2, normal: P2, seen: u32| {
        let n = (crate::geom::dist(from, to) / 0.05).round() as usize;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            samples.push(WallSample {
                pos: [
                    from[0] + t * (to[0] - from[0]),
                    from[1] + t * (to[1] - from[1]),
                ],
                normal,
                confidence: 1.0,
                seen_from: vec![seen],
            });
        }
    };
    // Room A: left, bottom and top walls, and its face of the shared wall.
    row([0.0, 0.0], [0.0, 4.0], [1.0, 0.0], a);
    row([0.05, 0.0], [3.95, 0.0], [0.0, 1.0], a);
    row([0.05, 4.0], [3.95, 4.0], [0.0, -1.0], a);
    row([4.0, 0.0], [4.0, 4.0], [-1.0, 0.0], a);
    // Room B: bottom, top and right walls; its face of the shared wall gave nothing.
    row([4.1, 0.0], [7.95, 0.0], [0.0, 1.0], b);
    row([4.1, 4.0], [7.95, 4.0], [0.0, -1.0], b);
    row([8.0, 0.0], [8.0, 4.0], [-1.0, 0.0], b);
    // The mirror's image of B's right wall, seen from B through the shared wall.
    row([1.0, 1.0], [1.0, 3.0], [1.0, 0.0], b);
    WallSamples {
        samples,
        viewpoints: vec![[2.0, 2.0], [6.0, 2.0]],
        ..Default::default()
    }
}

#[test]
fn a_scanner_seeing_through_a_wall_face_seen_from_its_other_side_does_not_carve_it() {
    let samples = mirror_rooms();
    let inside_at =
        |l: &LabeledMesh, p: P2| l.inside[walk::locate(&l.mesh, p, 0).unwrap() as usize];
    // Without the rule, B's lines of sight to the image cross the wall: both rooms are one.
    let off = LabelingParams {
        rays_stop_at_faces: false,
        ..params(0)
    };
    let (l, r) = label_with_report(&samples, &off, &Cancel::never()).unwrap();
    check_invariants(&l, &r);
    assert_eq!((r.rays_blocked, r.backed), (0, 0));
    assert!(
        inside_at(&l, [4.05, 2.0]),
        "the paper's rule carves the wall"
    );
    // With it, those lines of sight are dropped and the wall keeps a back behind A's face.
    let (l, r) = label_with_report(&samples, &params(0), &Cancel::never()).unwrap();
    check_invariants(&l, &r);
    assert_eq!(r.rays_blocked, 41, "B's lines of sight to the image");
    assert!(r.backed > 0);
    // Where those lines of sight crossed it (y 1.6 to 2.4).
    for y in [1.7, 2.0, 2.3] {
        assert!(!inside_at(&l, [4.05, y]), "the wall at y = {y}");
    }
    assert!(inside_at(&l, [2.0, 2.0]) && inside_at(&l, [6.0, 2.0]));
    assert!(
        iou(&l, |p| in_rect(p, [0.0, 0.0, 4.0, 4.0])
            || in_rect(p, [4.1, 0.0, 8.0, 4.0]))
            > 0.95
    );
}
