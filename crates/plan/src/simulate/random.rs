//! Random buildings for property tests: a corridor with a row of rooms on each side, walls 8 to
//! 40 cm thick, doors, closets, stub walls, square and round columns, tables, curved bays,
//! rooms without doors, the whole story rotated and moved at random. Each is a [`Building`]
//! with exact ground truth, scanned like the named ones ([`super::scan`]).
//!
//! Rooms are laid out in a frame where the corridor runs along x from 0 to its length; a room is
//! described by `u` (along the corridor, from its west side) and `v` (depth from the corridor
//! wall), which maps to x, y on either side. Every feature keeps clear of the band `v < 1.5`
//! where the station, the mobile route and the doors are, so scanners never stand in a wall.

use std::collections::HashSet;
use std::f64::consts::{PI, TAU};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::buildings::{Building, Patch, StoryModel, Surface, DOOR_HEIGHT, TABLE_HEIGHT};
use super::rects::{outline, point_in_ring, Rect};
use super::truth::{densify, rotate, TruthStory, TruthWall};
use crate::geom::{add, P2};
use crate::plan::Polygon;

/// Walls are drawn from this range of thicknesses, metres.
pub const WALL_THICKNESS: (f64, f64) = (0.08, 0.40);
/// Features stay beyond this depth into a room, metres: the band in front is kept clear for the
/// station, the route and the doors.
const CLEAR_BAND: f64 = 1.5;

/// The shape of the random buildings.
#[derive(Debug, Clone, PartialEq)]
pub struct RandomOptions {
    /// The corridor's length is drawn from this range, metres; rooms fill both sides of it.
    pub corridor_length: (f64, f64),
}

impl Default for RandomOptions {
    fn default() -> Self {
        RandomOptions {
            corridor_length: (8.0, 20.0),
        }
    }
}

/// What a room holds beside its station.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Feature {
    None,
    Closet,
    Stub,
    SquareColumn,
    RoundColumn,
    Bay,
    Table,
}

/// A curved bay: a half disc bulging out of a room's back wall.
struct Bay {
    center: P2,
    radius: f64,
    /// +1 when the bay bulges towards +y (north rooms), -1 towards -y.
    side: f64,
}

/// A door: its opening, and whether the wall it pierces runs along x.
struct Door {
    rect: Rect,
    along_x: bool,
}

#[derive(Default)]
struct Layout {
    open: Vec<Rect>,
    doors: Vec<Door>,
    solid: Vec<Rect>,
    round_columns: Vec<(P2, f64)>,
    bays: Vec<Bay>,
    tables: Vec<Rect>,
    stations: Vec<P2>,
    route: Vec<P2>,
}

/// One side of the corridor: where a room's front wall lies and which way is deeper.
#[derive(Clone, Copy)]
struct Side {
    front: f64,
    /// +1 when v grows with y (north rooms), -1 otherwise.
    dir: f64,
}

impl Side {
    fn at(&self, x0: f64, u: f64, v: f64) -> P2 {
        [x0 + u, self.front + self.dir * v]
    }

    /// The rectangle `u0..u1 × v0..v1` of a room starting at `x0`.
    fn rect(&self, x0: f64, u: (f64, f64), v: (f64, f64)) -> Rect {
        let a = self.at(x0, u.0, v.0);
        let b = self.at(x0, u.1, v.1);
        Rect::new(a[0], a[1], b[0], b[1])
    }
}

fn thickness(rng: &mut ChaCha8Rng) -> f64 {
    rng.random_range(WALL_THICKNESS.0..=WALL_THICKNESS.1)
}

/// A random building by name: `random_SEED` (8-20 m corridor, 6-20 rooms) or `random30_SEED`
/// (a 50-56 m corridor, about 30 rooms), as `score` and `render_stages` take them.
pub fn from_name(name: &str) -> Option<Building> {
    let (kind, seed) = name.split_once('_')?;
    let seed: u64 = seed.parse().ok()?;
    let options = match kind {
        "random" => RandomOptions::default(),
        "random30" => RandomOptions {
            corridor_length: (50.0, 56.0),
        },
        _ => return None,
    };
    let mut b = random_building(seed, &options);
    b.name = name.to_string();
    Some(b)
}

/// A random one-story building; the same seed gives the same building.
pub fn random_building(seed: u64, options: &RandomOptions) -> Building {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (lo, hi) = options.corridor_length;
    let length = if hi > lo {
        rng.random_range(lo..hi)
    } else {
        lo.max(4.0)
    };
    let width = rng.random_range(1.2..2.4);
    let ceiling = rng.random_range(2.5..3.2);
    let mut l = Layout::default();
    l.open.push(Rect::new(0.0, 0.0, length, width));
    let mut x = 1.5;
    while x < length - 1.0 {
        l.stations.push([x, width / 2.0]);
        x += 4.0;
    }
    let yc = width / 2.0;
    let mut visits: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for (k, side) in [(0, -1.0), (1, 1.0)] {
        let wall = thickness(&mut rng);
        let side = Side {
            front: if side < 0.0 { -wall } else { width + wall },
            dir: side,
        };
        let row_depth = rng.random_range(2.5..5.5);
        let mut rooms: Vec<(f64, f64)> = Vec::new();
        let mut x0 = 0.0;
        while x0 < length - 1.2 {
            let w = if rng.random_bool(0.25) {
                rng.random_range(1.2..1.6)
            } else {
                rng.random_range(2.4..6.0)
            };
            let mut x1 = (x0 + w).min(length);
            if length - x1 < 1.6 {
                x1 = length;
            }
            rooms.push((x0, x1));
            x0 = x1 + thickness(&mut rng);
        }
        for (i, &(x0, x1)) in rooms.iter().enumerate() {
            let w = x1 - x0;
            let depth = (row_depth + rng.random_range(-0.8..0.8f64)).max(2.5);
            let door = rng.random_bool(0.9);
            let feature = if w < 2.0 {
                Feature::None
            } else {
                [
                    Feature::None,
                    Feature::Closet,
                    Feature::Stub,
                    Feature::SquareColumn,
                    Feature::RoundColumn,
                    Feature::Bay,
                    Feature::Table,
                ][rng.random_range(0..7)]
            };
            add_room(&mut l, &mut rng, side, (x0, w, depth), feature);
            if door {
                let dw = rng.random_range(0.7..1.0f64).min(w - 0.3);
                let uc = rng.random_range(0.15 + dw / 2.0..=w - 0.15 - dw / 2.0);
                // Exactly from the corridor's face to the room's: a door computed as the
                // room's front minus the wall would leave a sliver of float error.
                let face = if side.dir < 0.0 { 0.0 } else { width };
                let rect = Rect::new(x0 + uc - dw / 2.0, face, x0 + uc + dw / 2.0, side.front);
                l.doors.push(Door {
                    rect,
                    along_x: true,
                });
                visits[k].push(x0 + uc);
            }
            // Sometimes a door through the partition to the next room, near the front.
            if let Some(&(n0, _)) = rooms.get(i + 1) {
                if rng.random_bool(0.2) {
                    let a = side.at(0.0, x1, 0.3);
                    let b = side.at(0.0, n0, 1.1);
                    l.doors.push(Door {
                        rect: Rect::new(a[0], a[1], b[0], b[1]),
                        along_x: false,
                    });
                }
            }
        }
        // The mobile route steps 0.8 m into each room through its door.
        let into = side.front + side.dir * 0.8;
        let mut stops = visits[k].clone();
        if k == 1 {
            stops.reverse();
        }
        for xd in stops {
            l.route.extend([[xd, yc], [xd, into], [xd, yc]]);
        }
        let end = if k == 0 { length - 0.6 } else { 0.6 };
        l.route.push([end, yc]);
    }
    l.route.insert(0, [0.6, yc]);
    let story = into_model(l, ceiling);
    let angle = rng.random_range(0.0..TAU);
    let shift = [rng.random_range(-50.0..50.0), rng.random_range(-50.0..50.0)];
    Building {
        name: format!("random_{seed}"),
        stories: vec![transform(story, angle, shift)],
    }
}

/// Adds one room (`x0`, width, depth) on `side` with its station and feature.
fn add_room(l: &mut Layout, rng: &mut ChaCha8Rng, side: Side, room: (f64, f64, f64), f: Feature) {
    let (x0, w, depth) = room;
    let full = side.rect(x0, (0.0, w), (0.0, depth));
    let u_station = if w < 2.0 {
        w / 2.0
    } else {
        rng.random_range(0.4..w - 0.4)
    };
    l.stations
        .push(side.at(x0, u_station, rng.random_range(0.8..1.0)));
    match f {
        Feature::Closet => {
            // A closet in the back corner with its own door, when the room is deep enough to
            // keep the front band clear.
            let (cw, cd) = (rng.random_range(1.2..1.5), rng.random_range(1.2..1.6));
            let t = rng.random_range(0.08..0.2);
            if depth - cd - t < CLEAR_BAND || w - cw - t < 0.8 {
                l.open.push(full);
                return;
            }
            l.open.push(side.rect(x0, (cw + t, w), (0.0, depth)));
            l.open.push(side.rect(x0, (0.0, w), (0.0, depth - cd - t)));
            l.open.push(side.rect(x0, (0.0, cw), (depth - cd, depth)));
            let door = side.rect(
                x0,
                (0.15, 0.15 + 0.7f64.min(cw - 0.3)),
                (depth - cd - t, depth - cd),
            );
            l.doors.push(Door {
                rect: door,
                along_x: true,
            });
        }
        Feature::Stub if depth >= CLEAR_BAND + 0.4 => {
            l.open.push(full);
            let len = rng.random_range(0.3..(depth - CLEAR_BAND).min(1.5));
            let t = rng.random_range(0.08..0.2);
            let u = rng.random_range(0.5..w - 0.5 - t);
            l.solid
                .push(side.rect(x0, (u, u + t), (depth - len, depth)));
        }
        Feature::SquareColumn | Feature::RoundColumn => {
            l.open.push(full);
            let s = rng.random_range(0.25..0.5);
            if depth < CLEAR_BAND + s + 0.4 {
                return;
            }
            let v = rng.random_range(CLEAR_BAND + s / 2.0..=depth - 0.4 - s / 2.0);
            let u = rng.random_range(0.6 + s / 2.0..=w - 0.6 - s / 2.0);
            if f == Feature::SquareColumn {
                l.solid
                    .push(side.rect(x0, (u - s / 2.0, u + s / 2.0), (v - s / 2.0, v + s / 2.0)));
            } else {
                l.round_columns.push((side.at(x0, u, v), s / 2.0));
            }
        }
        Feature::Bay => {
            l.open.push(full);
            let r = rng.random_range(0.6..((w - 0.6) / 2.0).clamp(0.61, 2.5));
            let ua = rng.random_range(0.3..=(w - 0.3 - 2.0 * r).max(0.3));
            l.bays.push(Bay {
                center: side.at(x0, ua + r, depth),
                radius: r,
                side: side.dir,
            });
        }
        Feature::Table if depth >= CLEAR_BAND + 1.1 => {
            l.open.push(full);
            let u = w / 2.0;
            l.tables
                .push(side.rect(x0, (u - 0.6, u + 0.6), (depth - 1.1, depth - 0.4)));
        }
        _ => l.open.push(full),
    }
}

/// Splices a bay's arc into the exterior ring edge that holds its chord. Returns the arc's
/// points (for telling arc edges from straight ones), or `None` when no edge holds it.
fn splice_bay(polygons: &mut [Polygon], bay: &Bay) -> Option<Vec<P2>> {
    let y = bay.center[1];
    let (xa, xb) = (bay.center[0] - bay.radius, bay.center[0] + bay.radius);
    let start = if bay.side < 0.0 { PI } else { 0.0 };
    let arc = TruthWall::Arc {
        center: bay.center,
        radius: bay.radius,
        start,
        sweep: PI,
    };
    let mut pts = densify(&arc, 0.001);
    let n = pts.len();
    // Exact chord ends, so the ring meets the straight wall without a sliver.
    let (first, last) = if bay.side < 0.0 {
        ([xa, y], [xb, y])
    } else {
        ([xb, y], [xa, y])
    };
    pts[0] = first;
    pts[n - 1] = last;
    for p in polygons.iter_mut() {
        let ring = &mut p.exterior;
        let m = ring.len();
        for i in 0..m {
            let (a, b) = (ring[i], ring[(i + 1) % m]);
            if a[1] == y && b[1] == y && a[0].min(b[0]) < xa && a[0].max(b[0]) > xb {
                // The exterior runs east along a south wall and west along a north one, the
                // same way round as the arc from `start`.
                ring.splice(i + 1..i + 1, pts.iter().copied());
                return Some(pts);
            }
        }
    }
    None
}

fn into_model(l: Layout, ceiling: f64) -> StoryModel {
    let (f, c) = (0.0, ceiling);
    let mut open = l.open.clone();
    open.extend(l.doors.iter().map(|d| d.rect));
    let mut polygons = outline(&open, &l.solid);
    let mut arc_walls = Vec::new();
    let mut arc_points: HashSet<[u64; 2]> = HashSet::new();
    for bay in &l.bays {
        if let Some(pts) = splice_bay(&mut polygons, bay) {
            arc_points.extend(pts.iter().map(|p| p.map(f64::to_bits)));
            arc_walls.push(TruthWall::Arc {
                center: bay.center,
                radius: bay.radius,
                start: if bay.side < 0.0 { PI } else { 0.0 },
                sweep: PI,
            });
        }
    }
    let is_arc = |p: P2| arc_points.contains(&p.map(f64::to_bits));
    let mut walls: Vec<TruthWall> = Vec::new();
    for p in &polygons {
        for ring in std::iter::once(&p.exterior).chain(&p.holes) {
            for k in 0..ring.len() {
                let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
                if !(is_arc(a) && is_arc(b)) {
                    walls.push(TruthWall::Line { a, b });
                }
            }
        }
    }
    walls.extend(arc_walls);
    for &(center, radius) in &l.round_columns {
        let arc = TruthWall::Arc {
            center,
            radius,
            start: 0.0,
            sweep: -TAU,
        };
        let mut ring = densify(&arc, 0.001);
        ring.pop();
        if let Some(p) = polygons
            .iter_mut()
            .find(|p| point_in_ring(center, &p.exterior))
        {
            p.holes.push(ring);
        }
        walls.push(TruthWall::Arc {
            center,
            radius,
            start: 0.0,
            sweep: TAU,
        });
    }
    let mut surfaces: Vec<Surface> = walls
        .iter()
        .map(|&curve| Surface { curve, z: [f, c] })
        .collect();
    let mut patches = Vec::new();
    for d in &l.doors {
        let r = d.rect;
        let faces = if d.along_x {
            [[[r.x0, r.y0], [r.x1, r.y0]], [[r.x0, r.y1], [r.x1, r.y1]]]
        } else {
            [[[r.x0, r.y0], [r.x0, r.y1]], [[r.x1, r.y0], [r.x1, r.y1]]]
        };
        for [a, b] in faces {
            surfaces.push(Surface {
                curve: TruthWall::Line { a, b },
                z: [f + DOOR_HEIGHT, c],
            });
        }
        patches.push(Patch::from_rect(r, f + DOOR_HEIGHT));
    }
    for t in &l.tables {
        let corners = [[t.x0, t.y0], [t.x1, t.y0], [t.x1, t.y1], [t.x0, t.y1]];
        for k in 0..4 {
            surfaces.push(Surface {
                curve: TruthWall::Line {
                    a: corners[k],
                    b: corners[(k + 1) % 4],
                },
                z: [f, f + TABLE_HEIGHT],
            });
        }
        patches.push(Patch::from_rect(*t, f + TABLE_HEIGHT));
    }
    StoryModel {
        floor_z: f,
        ceiling_z: c,
        slabs: true,
        capture: None,
        surfaces,
        patches,
        stations: l.stations,
        route: l.route,
        truth: TruthStory {
            level: 0,
            floor_z: f,
            ceiling_z: c,
            polygons,
            walls,
            // Rooms and doors are not given for random buildings.
            rooms: Vec::new(),
            doors: Vec::new(),
            windows: Vec::new(),
        },
    }
}

/// Rotates a story by `angle` about the origin, then moves it by `d`.
fn transform(mut s: StoryModel, angle: f64, d: P2) -> StoryModel {
    let m = |p: P2| add(rotate(p, angle), d);
    for surface in &mut s.surfaces {
        surface.curve = surface.curve.transformed(angle, d);
    }
    for patch in &mut s.patches {
        patch.corners = patch.corners.map(m);
    }
    s.stations = s.stations.into_iter().map(m).collect();
    s.route = s.route.into_iter().map(m).collect();
    for w in &mut s.truth.walls {
        *w = w.transformed(angle, d);
    }
    for p in &mut s.truth.polygons {
        p.exterior = p.exterior.iter().map(|&q| m(q)).collect();
        for h in &mut p.holes {
            *h = h.iter().map(|&q| m(q)).collect();
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{dist, ring_signed_area};

    fn area(s: &TruthStory) -> f64 {
        s.polygons
            .iter()
            .map(|p| {
                ring_signed_area(&p.exterior)
                    + p.holes.iter().map(|h| ring_signed_area(h)).sum::<f64>()
            })
            .sum()
    }

    #[test]
    fn same_seed_same_building_and_seeds_differ() {
        let o = RandomOptions::default();
        assert_eq!(random_building(5, &o), random_building(5, &o));
        assert_ne!(random_building(5, &o), random_building(6, &o));
    }

    #[test]
    fn truth_walls_trace_the_truth_polygons() {
        // Every wall point lies on a truth ring and the walls' length equals the rings'
        // perimeter (arcs densified to 1 mm), so the truth is consistent for the scorer.
        let mut features = [0usize; 3];
        for seed in 0..40 {
            let b = random_building(seed, &RandomOptions::default());
            let s = &b.stories[0];
            let perimeter: f64 = s
                .truth
                .polygons
                .iter()
                .flat_map(|p| std::iter::once(&p.exterior).chain(&p.holes))
                .map(|r| {
                    (0..r.len())
                        .map(|k| dist(r[k], r[(k + 1) % r.len()]))
                        .sum::<f64>()
                })
                .sum();
            let walls: f64 = s.truth.walls.iter().map(TruthWall::length).sum();
            assert!(
                (perimeter - walls).abs() < 1e-3 * perimeter,
                "seed {seed}: perimeter {perimeter}, walls {walls}"
            );
            assert!(area(&s.truth) > 10.0, "seed {seed}");
            for w in &s.truth.walls {
                if let TruthWall::Arc { radius, .. } = w {
                    features[if *radius < 0.3 { 0 } else { 1 }] += 1;
                }
            }
            features[2] += s
                .truth
                .polygons
                .iter()
                .map(|p| p.holes.len())
                .sum::<usize>();
        }
        // Round columns, bays and holes all occur.
        assert!(features.iter().all(|&n| n > 0), "{features:?}");
    }

    #[test]
    fn stations_and_routes_keep_clear_of_walls_and_columns() {
        for seed in 0..40 {
            let b = random_building(seed, &RandomOptions::default());
            let s = &b.stories[0];
            let mut points = s.stations.clone();
            for w in s.route.windows(2) {
                let n = (dist(w[0], w[1]) / 0.05).ceil().max(1.0) as usize;
                points.extend((0..=n).map(|k| {
                    let f = k as f64 / n as f64;
                    [
                        w[0][0] + f * (w[1][0] - w[0][0]),
                        w[0][1] + f * (w[1][1] - w[0][1]),
                    ]
                }));
            }
            for p in points {
                let open = s.truth.polygons.iter().any(|poly| {
                    point_in_ring(p, &poly.exterior)
                        && !poly.holes.iter().any(|h| point_in_ring(p, h))
                });
                assert!(open, "seed {seed}: {p:?} is not open floor");
                // Walls, columns and tables; the route passes under lintels.
                let near = s
                    .surfaces
                    .iter()
                    .filter(|w| w.z[0] < DOOR_HEIGHT)
                    .map(|w| (w.curve.distance(p), w))
                    .min_by(|a, b| a.0.total_cmp(&b.0))
                    .unwrap();
                assert!(
                    near.0 >= 0.2,
                    "seed {seed}: {p:?} is {} m from {:?}",
                    near.0,
                    near.1
                );
            }
        }
    }

    #[test]
    fn walls_are_8_to_40_cm_thick() {
        // Between the corridor and the rooms: the gap between open rectangles, which the
        // outline keeps exactly, is a wall thickness.
        for seed in 0..20 {
            let b = random_building(seed, &RandomOptions::default());
            let lines: Vec<(P2, P2)> = b.stories[0]
                .truth
                .walls
                .iter()
                .filter_map(|w| match *w {
                    TruthWall::Line { a, b } => Some((a, b)),
                    _ => None,
                })
                .collect();
            // Any two antiparallel faces that overlap along their length are at least 8 cm
            // apart (they are either the two faces of one wall or farther apart).
            for (i, &(a, b)) in lines.iter().enumerate() {
                for &(c, d) in &lines[i + 1..] {
                    let u = crate::geom::normalize(crate::geom::sub(b, a)).unwrap();
                    let v = crate::geom::normalize(crate::geom::sub(d, c)).unwrap();
                    if crate::geom::dot(u, v) > -0.999_999 {
                        continue;
                    }
                    let gap = crate::geom::cross(u, crate::geom::sub(c, a)).abs();
                    let (s0, s1) = (
                        crate::geom::dot(u, crate::geom::sub(c, a)),
                        crate::geom::dot(u, crate::geom::sub(d, a)),
                    );
                    let len = dist(a, b);
                    let overlap = s0.max(s1).min(len) - s0.min(s1).max(0.0);
                    if overlap > 0.01 && gap > 1e-9 {
                        assert!(
                            gap >= WALL_THICKNESS.0 - 1e-9,
                            "seed {seed}: faces {gap} m apart"
                        );
                    }
                }
            }
        }
    }
}
