use super::*;
use crate::geom::ring_signed_area;

fn poly(exterior: &[P2], holes: &[&[P2]]) -> Polygon {
    Polygon {
        exterior: exterior.to_vec(),
        holes: holes.iter().map(|h| h.to_vec()).collect(),
    }
}

fn area(polygons: &[Polygon]) -> f64 {
    polygons
        .iter()
        .map(|p| {
            ring_signed_area(&p.exterior) + p.holes.iter().map(|h| ring_signed_area(h)).sum::<f64>()
        })
        .sum()
}

/// Resolves on the local grid and checks the result with `geo` and the orientation rules.
fn resolved(polygons: &[Polygon]) -> Vec<Polygon> {
    let g = Grid::local();
    let out = resolve(polygons, &g).expect("resolves");
    assert!(problems(&out, &g).is_empty(), "{:?}", problems(&out, &g));
    for p in &out {
        assert!(ring_signed_area(&p.exterior) > 0.0);
        assert!(p.holes.iter().all(|h| ring_signed_area(h) < 0.0));
    }
    out
}

const SQUARE: [P2; 4] = [[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]];

#[test]
fn a_valid_square_with_a_hole_is_kept() {
    let hole = [[1.0, 1.0], [1.0, 2.0], [2.0, 2.0], [2.0, 1.0]];
    let input = vec![poly(&SQUARE, &[&hole])];
    assert!(problems(&input, &Grid::local()).is_empty());
    let out = resolved(&input);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].exterior.len(), 4);
    assert_eq!(out[0].holes.len(), 1);
    assert!((area(&out) - 15.0).abs() < 1e-9);
}

#[test]
fn a_bow_tie_keeps_its_counter_clockwise_lobe() {
    // (0,0) → (2,2) → (2,0) → (0,2): the lobe at x > 1 runs clockwise, the other CCW.
    let bow = [[0.0, 0.0], [2.0, 2.0], [2.0, 0.0], [0.0, 2.0]];
    let input = vec![poly(&bow, &[])];
    assert!(!problems(&input, &Grid::local()).is_empty());
    let out = resolved(&input);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].exterior.len(), 3);
    assert!((area(&out) - 1.0).abs() < 1e-9, "{}", area(&out));
}

#[test]
fn a_pinched_ring_becomes_two_polygons_touching_at_the_pinch() {
    // Two triangles joined at (1, 1) in one ring: GEOS calls it a ring self-intersection.
    let ring = [
        [0.0, 0.0],
        [2.0, 0.0],
        [1.0, 1.0],
        [2.0, 2.0],
        [0.0, 2.0],
        [1.0, 1.0],
    ];
    let input = vec![poly(&ring, &[])];
    assert!(!problems(&input, &Grid::local()).is_empty());
    let out = resolved(&input);
    assert_eq!(out.len(), 2);
    for p in &out {
        assert_eq!(p.exterior.len(), 3);
        assert!(p.exterior.contains(&[1.0, 1.0]));
        assert!((ring_signed_area(&p.exterior) - 1.0).abs() < 1e-9);
    }
}

#[test]
fn an_inverted_hole_becomes_a_hole_touching_the_exterior() {
    // The exterior runs into a clockwise diamond at (0, 2) and back out.
    let ring = [
        [0.0, 0.0],
        [4.0, 0.0],
        [4.0, 4.0],
        [0.0, 4.0],
        [0.0, 2.0],
        [2.0, 3.0],
        [3.0, 2.0],
        [2.0, 1.0],
        [0.0, 2.0],
    ];
    let out = resolved(&[poly(&ring, &[])]);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].exterior.len(), 4, "{:?}", out[0].exterior);
    assert_eq!(out[0].holes.len(), 1);
    assert!(out[0].holes[0].contains(&[0.0, 2.0]));
    assert!((area(&out) - (16.0 - 3.0)).abs() < 1e-9, "{}", area(&out));
}

#[test]
fn a_hole_touching_the_exterior_twice_splits_the_polygon() {
    // The triangular hole touches the left side at (0, 2) and the top at (2, 4), cutting the
    // corner triangle off: GEOS calls this interior disconnected.
    let hole = [[0.0, 2.0], [2.0, 4.0], [2.0, 2.0]];
    let out = resolved(&[poly(&SQUARE, &[&hole])]);
    assert_eq!(out.len(), 2, "{out:?}");
    let mut areas: Vec<f64> = out.iter().map(|p| ring_signed_area(&p.exterior)).collect();
    areas.sort_by(f64::total_cmp);
    assert!(
        (areas[0] - 2.0).abs() < 1e-9 && (areas[1] - 12.0).abs() < 1e-9,
        "{areas:?}"
    );
    assert!(out.iter().all(|p| p.holes.is_empty()));
}

#[test]
fn overlapping_polygons_merge_and_a_hole_outside_vanishes() {
    let a = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
    let b = [[1.0, 1.0], [3.0, 1.0], [3.0, 3.0], [1.0, 3.0]];
    let outside = [[5.0, 5.0], [5.0, 6.0], [6.0, 6.0], [6.0, 5.0]];
    let input = vec![poly(&a, &[&outside]), poly(&b, &[])];
    assert!(!problems(&input, &Grid::local()).is_empty());
    let out = resolved(&input);
    assert_eq!(out.len(), 1);
    assert!(out[0].holes.is_empty());
    assert!((area(&out) - 7.0).abs() < 1e-9);
}

#[test]
fn crossing_faces_of_a_thin_wall_split_off_its_tip() {
    // A room with a 10 cm partition reaching in from the south wall; its two fitted faces
    // lean towards each other and cross 0.5 m before the partition's end.
    let room = [
        [0.0, 0.0],
        [1.95, 0.0],
        [2.05, 2.0],
        [1.95, 2.0],
        [2.05, 0.0],
        [4.0, 0.0],
        [4.0, 3.0],
        [0.0, 3.0],
    ];
    let input = vec![poly(&room, &[])];
    assert!(!problems(&input, &Grid::local()).is_empty());
    let out = resolved(&input);
    // The crossing at (2, 1) becomes a vertex. The tip beyond it is wound twice (room and
    // loop), so it stays open floor; the triangle below the crossing stays solid.
    assert!(
        out.iter().any(|p| p.exterior.contains(&[2.0, 1.0])),
        "{out:?}"
    );
    let a = area(&out);
    assert!((a - (12.0 - 0.05)).abs() < 1e-6, "{a}");
}

#[test]
fn grid_nodes_round_trip_through_the_writers_rounding() {
    let origin = [512_345.678_9, 5_432_100.123_4, 230.0];
    let g = Grid::world(origin);
    for p in [[0.0, 0.0], [12.345_67, -3.210_98], [-700.000_05, 0.000_049]] {
        let q = g.snap(p).unwrap();
        let back = g.unsnap(q);
        assert_eq!(g.snap(back), Some(q));
        // The writer's rounding of the unsnapped point lands on the node itself.
        let round4 = |v: f64| (v * 1.0e4).round() / 1.0e4;
        for k in 0..2 {
            let world = round4(back[k] + origin[k]);
            assert_eq!(world, (q[k] + g.base[k]) as f64 / 1.0e4);
        }
    }
    assert_eq!(g.snap([f64::NAN, 0.0]), None);
    assert_eq!(g.snap([1.0e9, 0.0]), None);
}

#[test]
fn make_valid_falls_back_to_the_traced_boundary_and_says_so() {
    let traced = vec![poly(&SQUARE, &[])];
    let fine = make_valid(&traced, &traced, &Grid::local());
    assert!(fine.notes.is_empty());
    assert_eq!(fine.polygons.len(), 1);
    let broken = vec![poly(&[[0.0, 0.0], [f64::NAN, 0.0], [1.0, 1.0]], &[])];
    let v = make_valid(&broken, &traced, &Grid::local());
    assert_eq!(v.polygons.len(), 1);
    assert_eq!(v.notes.len(), 1, "{:?}", v.notes);
    assert!(v.notes[0].contains("traced boundary"), "{:?}", v.notes);
    // Nothing valid at all: every polygon is left out, and the plan says so.
    let v = make_valid(&broken, &broken, &Grid::local());
    assert!(v.polygons.is_empty());
    assert_eq!(v.notes.len(), 2, "{:?}", v.notes);
}
