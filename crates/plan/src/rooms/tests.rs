use super::*;
use crate::plan::DoorKind;
use crate::simulate::rects::{outline, Rect};
use crate::validity::problems;

/// A story of open rectangles joined by door rectangles, 2.6 m high; with `lintels`, a lintel
/// over each door (its underside at 2.1 m, points every 2 cm) and a wall of points along the
/// outer faces is not given (no windows).
fn story(
    open: &[Rect],
    doors: &[Rect],
    solid: &[Rect],
    lintels: bool,
) -> (StoryPlan, Vec<[f32; 3]>) {
    let mut all = open.to_vec();
    all.extend(doors);
    let plan = StoryPlan {
        level: 0,
        floor_z: 0.0,
        ceiling_z: 2.6,
        polygons: outline(&all, solid),
        ..Default::default()
    };
    let mut points = Vec::new();
    if lintels {
        for d in doors {
            let (nx, ny) = (
                ((d.x1 - d.x0) / 0.02) as usize,
                ((d.y1 - d.y0) / 0.02) as usize,
            );
            for i in 0..=nx {
                for j in 0..=ny {
                    let x = d.x0 + (d.x1 - d.x0) * i as f64 / nx.max(1) as f64;
                    let y = d.y0 + (d.y1 - d.y0) * j as f64 / ny.max(1) as f64;
                    points.push([x as f32, y as f32, 2.1]);
                }
            }
        }
    }
    (plan, points)
}

fn run(plan: &StoryPlan, points: &[[f32; 3]], scanners: &[Scanner]) -> RoomsOutcome {
    let out = find_rooms(
        plan,
        &StoryPoints {
            xyz: points,
            blocks: None,
        },
        scanners,
        &RoomsParams::default(),
        &Grid::local(),
    )
    .expect("rooms");
    let polygons: Vec<_> = out.spaces.rooms.iter().map(|r| r.polygon.clone()).collect();
    assert_eq!(problems(&polygons, &Grid::local()), Vec::<String>::new());
    out
}

fn areas(out: &RoomsOutcome) -> Vec<f64> {
    let mut a: Vec<f64> = out.spaces.rooms.iter().map(|r| r.area).collect();
    a.sort_by(f64::total_cmp);
    a
}

#[test]
fn two_rooms_joined_by_one_door() {
    let (plan, points) = story(
        &[Rect::new(0.0, 0.0, 4.0, 3.0), Rect::new(4.1, 0.0, 8.0, 3.0)],
        &[Rect::new(4.0, 1.0, 4.1, 1.9)],
        &[],
        true,
    );
    let scanners = [
        Scanner {
            index: 1,
            position: [2.0, 1.5, 1.5],
        },
        Scanner {
            index: 2,
            position: [6.0, 1.5, 1.5],
        },
    ];
    let out = run(&plan, &points, &scanners);
    let s = &out.spaces;
    assert_eq!(s.rooms.len(), 2, "{s:?}");
    let a = areas(&out);
    assert!(
        (a[0] - 11.7).abs() < 1e-6 && (a[1] - 12.0).abs() < 1e-6,
        "{a:?}"
    );
    assert_eq!(s.rooms[0].id, "L0-R1");
    assert_eq!(s.rooms[0].scanners, vec![1]);
    assert_eq!(s.rooms[1].scanners, vec![2]);
    assert_eq!(s.rooms[0].neighbours, vec!["L0-R2".to_string()]);
    assert!((s.rooms[0].perimeter - 14.0).abs() < 1e-6);
    assert_eq!(s.doors.len(), 1);
    let d = &s.doors[0];
    assert_eq!(d.kind, DoorKind::Door);
    assert!((d.width - 0.9).abs() < 1e-6, "{d:?}");
    assert!((d.depth - 0.1).abs() < 1e-6);
    let c = [(d.a[0] + d.b[0]) / 2.0, (d.a[1] + d.b[1]) / 2.0];
    assert!(
        (c[0] - 4.05).abs() < 1e-6 && (c[1] - 1.45).abs() < 1e-6,
        "{c:?}"
    );
    assert!((d.head_z.expect("a lintel") - 2.1).abs() < 1e-6);
    let mut rooms = d.rooms.clone();
    rooms.sort();
    assert_eq!(rooms, [Some("L0-R1".into()), Some("L0-R2".into())]);
    // The wall between them, either side of the door, 10 cm thick.
    let inner: Vec<_> = s.walls.iter().filter(|w| !w.exterior).collect();
    assert_eq!(inner.len(), 2, "{inner:?}");
    for w in inner {
        assert!((w.thickness - 0.1).abs() < 1e-6);
        assert!((w.a[0] - 4.05).abs() < 1e-6 && (w.b[0] - 4.05).abs() < 1e-6);
    }
    assert!(s.walls.iter().any(|w| w.exterior));
}

/// A wall along y at `x` (its two faces), as points about every 5 cm from `y0` to `y1` and
/// from the floor to 2.1 m.
fn wall_points(x: [f64; 2], y0: f64, y1: f64) -> Vec<[f32; 3]> {
    let mut out = Vec::new();
    let n = ((y1 - y0) / 0.05).round() as usize;
    for i in 0..=n {
        for k in 0..42 {
            for x in x {
                let y = y0 + (y1 - y0) * i as f64 / n as f64;
                out.push([x as f32, y as f32, (0.025 + 0.05 * k as f64) as f32]);
            }
        }
    }
    out
}

/// The plan shows a door-wide gap in the wall between two rooms, lintel and all, but the
/// points show the wall standing across it down to the floor: the plan lost a stretch of the
/// wall (a face seen too sparsely for a model). The gap is closed, and no door.
#[test]
fn a_gap_where_the_points_show_the_wall_standing_is_no_door() {
    let (plan, mut points) = story(
        &[Rect::new(0.0, 0.0, 4.0, 3.0), Rect::new(4.1, 0.0, 8.0, 3.0)],
        &[Rect::new(4.0, 1.0, 4.1, 1.9)],
        &[],
        true,
    );
    points.extend(wall_points([4.0, 4.1], 1.0, 1.9));
    let out = run(&plan, &points, &[]);
    assert_eq!(areas(&out).len(), 2, "{:?}", out.spaces.rooms);
    assert!(out.spaces.doors.is_empty(), "{:?}", out.spaces.doors);
    assert!(
        out.notes.iter().any(|n| n.contains("1 gap(s)")),
        "{:?}",
        out.notes
    );
}

/// A 0.9 m door with a sliver of plan standing in it, 15 cm from its south jamb, that no point
/// shows: from the north jamb the plan's gap is 0.6 m, up to the sliver. The wall's points put
/// the south jamb beyond the sliver and the crack behind it, so the door is 0.9 m wide.
#[test]
fn a_sliver_of_plan_in_a_doorway_does_not_narrow_the_door() {
    let (plan, mut points) = story(
        &[Rect::new(0.0, 0.0, 4.0, 3.0), Rect::new(4.1, 0.0, 8.0, 3.0)],
        &[Rect::new(4.0, 1.0, 4.1, 1.9)],
        &[Rect::new(4.0, 1.15, 4.1, 1.3)],
        true,
    );
    points.extend(wall_points([4.0, 4.1], 0.5, 1.0));
    points.extend(wall_points([4.0, 4.1], 1.9, 2.4));
    let out = run(&plan, &points, &[]);
    assert_eq!(areas(&out).len(), 2, "{:?}", out.spaces.rooms);
    let d = &out.spaces.doors;
    assert_eq!(d.len(), 1, "{d:?}");
    assert!((d[0].width - 0.9).abs() < 1e-6, "{d:?}");
    let c = [(d[0].a[0] + d[0].b[0]) / 2.0, (d[0].a[1] + d[0].b[1]) / 2.0];
    assert!(
        (c[0] - 4.05).abs() < 1e-6 && (c[1] - 1.45).abs() < 1e-6,
        "{c:?}"
    );
}

/// Two rooms and a gap with something over it at 2.1 m, under ceilings at `ceiling` m seen as
/// points every 10 cm over both rooms.
fn under_ceiling(ceiling: f64) -> RoomsOutcome {
    let (plan, mut points) = story(
        &[Rect::new(0.0, 0.0, 4.0, 3.0), Rect::new(4.1, 0.0, 8.0, 3.0)],
        &[Rect::new(4.0, 1.0, 4.1, 1.9)],
        &[],
        true,
    );
    for i in 0..80 {
        for j in 0..30 {
            let (x, y) = (0.05 + 0.1 * i as f64, 0.05 + 0.1 * j as f64);
            points.push([x as f32, y as f32, ceiling as f32]);
        }
    }
    run(&plan, &points, &[])
}

/// A corridor's dropped ceiling at 2.15 m runs on over the gap at the same height on both
/// sides: nothing hangs under it, so the gap is an opening. Under the story's 2.6 m ceiling,
/// the same points over the gap are a lintel.
#[test]
fn a_ceiling_as_low_on_both_sides_is_no_lintel() {
    let low = under_ceiling(2.15);
    assert_eq!(low.spaces.rooms.len(), 2);
    assert_eq!(low.spaces.doors.len(), 1, "{:?}", low.spaces.doors);
    assert_eq!(low.spaces.doors[0].kind, DoorKind::Opening);
    let high = under_ceiling(2.6);
    assert_eq!(high.spaces.doors.len(), 1, "{:?}", high.spaces.doors);
    assert_eq!(high.spaces.doors[0].kind, DoorKind::Door);
    assert!((high.spaces.doors[0].head_z.expect("a lintel") - 2.1).abs() < 1e-6);
}

/// A door whose leaf stands open against the east room's side of the wall, hinged at the
/// south jamb: its points lie within the wall's thickness only at that jamb, so it is a door.
#[test]
fn a_door_with_its_leaf_open_is_a_door() {
    let (plan, mut points) = story(
        &[Rect::new(0.0, 0.0, 4.0, 3.0), Rect::new(4.1, 0.0, 8.0, 3.0)],
        &[Rect::new(4.0, 1.0, 4.1, 1.9)],
        &[],
        true,
    );
    // The leaf: 4 cm thick, 0.9 m from the jamb into the east room, points every 5 cm.
    for i in 0..18 {
        for k in 0..42 {
            for y in [1.0, 1.04] {
                let x = 4.1 + 0.05 * i as f64;
                points.push([x as f32, y as f32, (0.025 + 0.05 * k as f64) as f32]);
            }
        }
    }
    let out = run(&plan, &points, &[]);
    assert_eq!(areas(&out).len(), 2);
    assert_eq!(out.spaces.doors.len(), 1, "{:?}", out.spaces.doors);
    assert_eq!(out.spaces.doors[0].kind, DoorKind::Door);
}

#[test]
fn a_gap_without_a_lintel_is_an_opening_between_large_rooms() {
    let (plan, points) = story(
        &[Rect::new(0.0, 0.0, 4.0, 3.0), Rect::new(4.1, 0.0, 8.0, 3.0)],
        &[Rect::new(4.0, 1.0, 4.1, 2.2)],
        &[],
        false,
    );
    // Points somewhere else, so lintels are looked for and not found.
    let out = run(&plan, &[[1.0, 1.0, 2.2], [1.0, 1.0, 0.0]], &[]);
    assert!(points.is_empty());
    assert_eq!(out.spaces.rooms.len(), 2);
    assert_eq!(out.spaces.doors.len(), 1);
    assert_eq!(out.spaces.doors[0].kind, DoorKind::Opening);
    assert_eq!(out.spaces.doors[0].head_z, None);
}

#[test]
fn an_l_shaped_room_is_one_room() {
    let (plan, points) = story(
        &[Rect::new(0.0, 0.0, 6.0, 3.0), Rect::new(0.0, 3.0, 3.0, 6.0)],
        &[],
        &[],
        true,
    );
    let out = run(&plan, &points, &[]);
    let a = areas(&out);
    assert!(a.len() == 1 && (a[0] - 27.0).abs() < 1e-6, "{a:?}");
    assert!(out.spaces.doors.is_empty());
    assert_eq!(out.spaces.rooms[0].polygon.exterior.len(), 6);
}

#[test]
fn a_corridor_with_three_offices() {
    let offices = [0.0, 4.1, 8.2].map(|x| Rect::new(x, 2.1, x + 4.0, 6.0));
    let doors = [0.0, 4.1, 8.2].map(|x| Rect::new(x + 1.0, 2.0, x + 1.9, 2.1));
    let mut open = vec![Rect::new(0.0, 0.0, 12.2, 2.0)];
    open.extend(offices);
    let (plan, points) = story(&open, &doors, &[], true);
    let out = run(&plan, &points, &[]);
    let s = &out.spaces;
    let a = areas(&out);
    assert_eq!(a.len(), 4);
    for (got, want) in a.iter().zip([15.6, 15.6, 15.6, 24.4]) {
        assert!((got - want).abs() < 1e-6, "{a:?}");
    }
    assert_eq!(s.doors.len(), 3);
    assert!(s.doors.iter().all(|d| d.kind == DoorKind::Door));
    // The corridor is the south-west-most room; every office is its neighbour.
    let corridor = &s.rooms[0];
    assert!((corridor.area - 24.4).abs() < 1e-6);
    assert_eq!(corridor.neighbours, vec!["L0-R2", "L0-R3", "L0-R4"]);
    // The two partitions between offices pair into 10 cm walls.
    let partitions = s
        .walls
        .iter()
        .filter(|w| !w.exterior && (w.a[0] - w.b[0]).abs() < 1e-9)
        .count();
    assert_eq!(partitions, 2);
}

/// Offices on both sides of a corridor, their partitions in line. Where one partition meets
/// the corridor wall the plan has a crack 8 cm into that wall: the partition's centre line
/// runs on through it and across the corridor to the partition opposite, 2.08 m, but no room
/// lies beside that stretch, so it is no opening and the corridor stays one room.
#[test]
fn a_crack_at_a_t_junction_does_not_split_the_corridor() {
    let mut open = vec![
        Rect::new(0.0, 0.0, 8.1, 2.0),
        // The crack.
        Rect::new(4.0, 2.0, 4.1, 2.08),
    ];
    let mut doors = Vec::new();
    for x in [0.0, 4.1] {
        open.push(Rect::new(x, 2.1, x + 4.0, 6.0));
        open.push(Rect::new(x, -4.0, x + 4.0, -0.1));
        doors.push(Rect::new(x + 1.0, 2.0, x + 1.9, 2.1));
        doors.push(Rect::new(x + 1.0, -0.1, x + 1.9, 0.0));
    }
    let (plan, points) = story(&open, &doors, &[], true);
    let out = run(&plan, &points, &[]);
    let a = areas(&out);
    assert_eq!(a.len(), 5, "{a:?}");
    assert!((a[4] - 16.2).abs() < 0.01, "{a:?}");
    assert_eq!(out.spaces.doors.len(), 4);
    assert!(out.spaces.doors.iter().all(|d| d.kind == DoorKind::Door));
}

/// The same corridor, the upper offices divided by a 24 cm partition, with a crack 6 cm wide
/// beside its east face through the corridor wall. The partition's centre line leaves the
/// corridor wall with solid on its west side and the crack on its east: once the crack is
/// closed, solid on both, a wall across, so no opening crosses the corridor.
#[test]
fn a_crack_beside_a_thick_partition_does_not_split_the_corridor() {
    let open = vec![
        Rect::new(0.0, 0.0, 8.24, 2.0),
        Rect::new(4.24, 2.0, 4.3, 2.1),
        Rect::new(0.0, 2.1, 4.0, 6.0),
        Rect::new(4.24, 2.1, 8.24, 6.0),
        Rect::new(0.0, -4.0, 4.07, -0.1),
        Rect::new(4.17, -4.0, 8.24, -0.1),
    ];
    let doors = vec![
        Rect::new(1.0, 2.0, 1.9, 2.1),
        Rect::new(6.0, 2.0, 6.9, 2.1),
        Rect::new(1.0, -0.1, 1.9, 0.0),
        Rect::new(6.0, -0.1, 6.9, 0.0),
    ];
    let (plan, points) = story(&open, &doors, &[], true);
    let out = run(&plan, &points, &[]);
    let a = areas(&out);
    assert_eq!(a.len(), 5, "{a:?}");
    assert!(a.iter().any(|&x| (x - 16.48).abs() < 0.05), "{a:?}");
    assert_eq!(out.spaces.doors.len(), 4, "{:?}", out.spaces.doors);
    assert!(out.spaces.doors.iter().all(|d| d.kind == DoorKind::Door));
}

/// Offices either side of a corridor, their 14 cm partitions in line, and an office door right
/// beside the upper partition: the partition's end is flush with the corridor's face, and its
/// centre line runs on across the corridor to the lower partition. The corridor wall stands
/// on one side of that end, so it is no jamb, and the corridor stays one room.
#[test]
fn a_partition_beside_a_door_does_not_split_the_corridor() {
    let open = vec![
        Rect::new(0.0, 0.0, 8.14, 2.0),
        Rect::new(0.0, 2.1, 4.0, 6.0),
        Rect::new(4.14, 2.1, 8.14, 6.0),
        Rect::new(0.0, -4.0, 4.0, -0.1),
        Rect::new(4.14, -4.0, 8.14, -0.1),
    ];
    let doors = vec![
        Rect::new(3.1, 2.0, 4.0, 2.1),
        Rect::new(5.0, 2.0, 5.9, 2.1),
        Rect::new(1.0, -0.1, 1.9, 0.0),
        Rect::new(5.0, -0.1, 5.9, 0.0),
    ];
    let (plan, points) = story(&open, &doors, &[], true);
    let out = run(&plan, &points, &[]);
    let a = areas(&out);
    assert_eq!(a.len(), 5, "{a:?}");
    assert!((a[4] - 16.28).abs() < 0.05, "{a:?}");
    assert_eq!(out.spaces.doors.len(), 4, "{:?}", out.spaces.doors);
}

#[test]
fn a_column_near_a_wall_divides_nothing() {
    // A 40 cm column 1 m from the south wall: its faces pair like a wall's, and the gap to the
    // wall is door-wide, but the floor goes around it.
    let (plan, points) = story(
        &[Rect::new(0.0, 0.0, 6.0, 6.0)],
        &[],
        &[Rect::new(2.0, 1.0, 2.4, 1.4)],
        false,
    );
    let out = run(&plan, &[[3.0, 3.0, 0.0]], &[]);
    assert!(points.is_empty());
    assert_eq!(out.spaces.rooms.len(), 1);
    assert!((out.spaces.rooms[0].area - (36.0 - 0.16)).abs() < 1e-6);
    assert!(out.spaces.doors.is_empty(), "{:?}", out.spaces.doors);
}

/// A wall from the north wall 4 m into a room, with a doorway under a lintel: the floor goes
/// around the wall's end, so the doorway divides nothing, but it is a door in that wall.
#[test]
fn a_doorway_in_a_wall_the_floor_goes_around_is_a_door() {
    let (plan, points) = story(
        &[Rect::new(0.0, 0.0, 6.0, 6.0)],
        &[Rect::new(2.95, 4.0, 3.05, 4.9)],
        &[
            Rect::new(2.95, 4.9, 3.05, 6.0),
            Rect::new(2.95, 2.0, 3.05, 4.0),
        ],
        true,
    );
    let out = run(&plan, &points, &[]);
    assert_eq!(out.spaces.rooms.len(), 1);
    let d = &out.spaces.doors;
    assert_eq!(d.len(), 1, "{d:?}");
    assert_eq!(d[0].kind, DoorKind::Door);
    assert!((d[0].width - 0.9).abs() < 1e-6, "{d:?}");
    assert_eq!(d[0].rooms[0], d[0].rooms[1]);
}

#[test]
fn a_room_with_two_doors_to_the_same_corridor() {
    let (plan, points) = story(
        &[
            Rect::new(0.0, 0.0, 10.0, 2.0),
            Rect::new(0.0, 2.1, 10.0, 6.0),
        ],
        &[Rect::new(1.0, 2.0, 1.9, 2.1), Rect::new(7.0, 2.0, 7.9, 2.1)],
        &[],
        true,
    );
    let out = run(&plan, &points, &[]);
    let a = areas(&out);
    assert!(
        a.len() == 2 && (a[0] - 20.0).abs() < 1e-6 && (a[1] - 39.0).abs() < 1e-6,
        "{a:?}"
    );
    assert_eq!(out.spaces.doors.len(), 2);
}

#[test]
fn a_window_in_an_outer_wall() {
    let (plan, _) = story(&[Rect::new(0.0, 0.0, 5.0, 4.0)], &[], &[], false);
    // The south wall's points every 2 cm, less a window from x 1.5 to 3.0, z 0.9 to 2.1.
    let mut points = Vec::new();
    for i in 0..250 {
        for k in 0..130 {
            let (x, z) = (i as f64 * 0.02 + 0.01, k as f64 * 0.02 + 0.01);
            if (1.5..3.0).contains(&x) && (0.9..2.1).contains(&z) {
                continue;
            }
            points.push([x as f32, 0.0, z as f32]);
        }
    }
    let out = run(&plan, &points, &[]);
    assert_eq!(out.spaces.windows.len(), 1, "{:?}", out.spaces.windows);
    let w = &out.spaces.windows[0];
    assert!((w.width - 1.5).abs() < 0.11, "{w:?}");
    assert!(
        (w.sill_z - 0.9).abs() < 0.11 && (w.head_z - 2.1).abs() < 0.11,
        "{w:?}"
    );
    assert_eq!(w.room.as_deref(), Some("L0-R1"));
}

#[test]
fn window_edges_between_bins_are_found_to_the_point_spacing() {
    let (plan, _) = story(&[Rect::new(0.0, 0.0, 5.0, 4.0)], &[], &[], false);
    // A window from x 1.53 to 2.77, z 0.87 to 2.13, off the 10 cm bins; points every 2 cm
    // (on the odd centimetres), and one stray point in the glass.
    let (x0, x1, z0, z1) = (1.53, 2.77, 0.87, 2.13);
    let mut points = vec![[2.0f32, 0.0, 1.5]];
    for i in 0..250 {
        for k in 0..130 {
            let (x, z) = (i as f64 * 0.02 + 0.01, k as f64 * 0.02 + 0.01);
            if (x0..x1).contains(&x) && (z0..z1).contains(&z) {
                continue;
            }
            points.push([x as f32, 0.0, z as f32]);
        }
    }
    let out = run(&plan, &points, &[]);
    assert_eq!(out.spaces.windows.len(), 1, "{:?}", out.spaces.windows);
    let w = &out.spaces.windows[0];
    let (lo, hi) = (w.a[0].min(w.b[0]), w.a[0].max(w.b[0]));
    // Each edge is the last point beside the gap: within one point spacing of the truth.
    for (got, want) in [(lo, x0), (hi, x1), (w.sill_z, z0), (w.head_z, z1)] {
        assert!((got - want).abs() <= 0.02 + 1e-6, "{got} vs {want}: {w:?}");
    }
    assert!((w.width - (x1 - x0)).abs() <= 0.04 + 1e-6, "{w:?}");
}

#[test]
fn bad_parameters_are_named() {
    let p = RoomsParams {
        max_door_width: 0.2,
        ..Default::default()
    };
    assert!(matches!(
        p.check(),
        Err(RoomsError::BadParam {
            name: "max_door_width",
            ..
        })
    ));
    let p = RoomsParams {
        lintel_coverage: 1.5,
        ..Default::default()
    };
    assert!(p.check().is_err());
    assert!(RoomsParams::default().check().is_ok());
}

#[test]
fn nothing_in_nothing_out() {
    let plan = StoryPlan::default();
    let out = find_rooms(
        &plan,
        &StoryPoints {
            xyz: &[],
            blocks: None,
        },
        &[],
        &RoomsParams::default(),
        &Grid::local(),
    )
    .unwrap();
    assert!(out.spaces.rooms.is_empty());
}

#[test]
fn shares_visit_the_stride_over_the_whole_cloud() {
    let n = 10 * SHARE + 7;
    let spans = [
        3..SHARE + 5,
        2 * SHARE + 1..2 * SHARE + 2,
        4 * SHARE..n + 100,
    ];
    for stride in [1, 2, 3, 4, 7] {
        let got: Vec<usize> = shares(&spans, stride, n)
            .into_iter()
            .flat_map(|r| r.step_by(stride))
            .collect();
        let want: Vec<usize> = (0..n)
            .step_by(stride)
            .filter(|k| spans.iter().any(|r| r.contains(k)))
            .collect();
        assert_eq!(got, want, "stride {stride}");
    }
}

#[test]
fn blocks_of_other_heights_are_skipped_with_the_same_rooms() {
    // Two rooms joined by a door with a lintel, and a window in the south wall.
    let (plan, mut points) = story(
        &[Rect::new(0.0, 0.0, 4.0, 4.0), Rect::new(4.1, 0.0, 8.0, 4.0)],
        &[Rect::new(4.0, 1.5, 4.1, 2.4)],
        &[],
        true,
    );
    for i in 0..400 {
        for k in 0..130 {
            let (x, z) = (i as f64 * 0.02 + 0.01, k as f64 * 0.02 + 0.01);
            if !((1.5..3.0).contains(&x) && (0.9..2.1).contains(&z)) {
                points.push([x as f32, 0.0, z as f32]);
            }
        }
    }
    // Whole blocks of the story above between blocks of this story's points.
    let block = crate::samples::Blocks::SIZE;
    let above: Vec<[f32; 3]> = points.iter().map(|p| [p[0], p[1], p[2] + 5.0]).collect();
    let mut cloud = Vec::new();
    for (k, p) in points.iter().enumerate() {
        cloud.push(*p);
        if k % 7_000 == 0 {
            cloud.extend(above.iter().cycle().take(2 * block));
        }
    }
    let stories = [
        crate::stories::Story::flat(0, 0.0, 2.6, -1.0, 3.0),
        crate::stories::Story::flat(1, 5.0, 7.6, 3.0, 9.0),
    ];
    let (_, blocks) = crate::samples::StoryBounds::measure_all(&cloud, &stories);
    assert!(blocks.spans(&stories[0]).len() > 1);
    let find = |blocks| {
        find_rooms(
            &plan,
            &StoryPoints {
                xyz: &cloud,
                blocks,
            },
            &[],
            &RoomsParams::default(),
            &Grid::local(),
        )
        .expect("rooms")
    };
    let whole = find(None);
    assert_eq!(whole.spaces.rooms.len(), 2, "{:?}", whole.spaces);
    assert_eq!(whole.spaces.windows.len(), 1, "{:?}", whole.spaces);
    assert!(whole.spaces.doors.iter().any(|d| d.kind == DoorKind::Door));
    assert_eq!(find(Some(&blocks)), whole);
}

#[test]
fn the_box_index_gives_each_point_the_boxes_over_its_cell_in_order() {
    // Boxes overlapping, nested, thin and one far off; points inside, on edges and outside.
    let boxes = [
        [0.0, 0.0, 2.0, 1.0],
        [1.5, 0.5, 1.6, 3.0],
        [0.2, 0.2, 0.3, 0.3],
        [-1.0, 2.9, 4.0, 3.0],
        [10.0, 10.0, 10.5, 10.5],
    ];
    let index = gaps::BoxIndex::new(&boxes);
    for i in -4..50 {
        for j in -4..50 {
            let p = [i as f64 * 0.25 - 0.1, j as f64 * 0.25 - 0.1];
            let near = index.near(p);
            // In order, each once, and every box holding the point among them.
            assert!(near.windows(2).all(|w| w[0] < w[1]), "{p:?}: {near:?}");
            for (k, b) in boxes.iter().enumerate() {
                let inside = p[0] >= b[0] && p[0] <= b[2] && p[1] >= b[1] && p[1] <= b[3];
                if inside {
                    assert!(near.contains(&k), "{p:?} in box {k}: {near:?}");
                }
            }
        }
    }
    // Far outside the boxes, nothing is near.
    assert!(index.near([-50.0, -50.0]).is_empty());
    assert!(index.near([f64::NAN, 1.0]).is_empty());
}

#[test]
fn any_near_says_whether_near_lists_a_box() {
    // Cells with boxes and without, the index's edges exactly, and points far off.
    let boxes = [
        [0.0, 0.0, 0.4, 0.4],
        [3.0, 0.0, 3.2, 2.0],
        [0.0, 1.9, 3.2, 2.0],
    ];
    let index = gaps::BoxIndex::new(&boxes);
    let mut both = [0, 0];
    for i in -20..60 {
        for j in -20..60 {
            let p = [i as f64 * 0.0625, j as f64 * 0.0625];
            let listed = !index.near(p).is_empty();
            assert_eq!(index.any_near(p), listed, "{p:?}");
            both[usize::from(listed)] += 1;
        }
    }
    // The grid above reached cells of both kinds.
    assert!(both[0] > 100 && both[1] > 100, "{both:?}");
    for p in [
        [3.2, 2.0],
        [3.2000001, 1.0],
        [-1e-12, 0.1],
        [f64::NAN, 1.0],
        [1.0, f64::INFINITY],
        [f64::NEG_INFINITY, 0.0],
        [1e300, 1e300],
    ] {
        assert_eq!(index.any_near(p), !index.near(p).is_empty(), "{p:?}");
    }
}
