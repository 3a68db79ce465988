//! The free floor cut at the doors: what falls apart are the rooms. Cuts are taken out of the
//! story's region by winding (each cut a clockwise ring over the counter-clockwise floor) and
//! the result traced and checked by [`crate::validity::resolve`], so every room is OGC-valid
//! on the output grid.

use super::faces::Face;
use super::gaps::Gap;
use super::pairing::{remaining, Coverage, Piece};
use super::RoomsParams;
use crate::geom::{self, point_in_ring, ring_signed_area, P2};
use crate::plan::{Door, DoorKind, Polygon, Room, Spaces, StoryPlan, WallCentre};
use crate::validity::{resolve, Grid};

/// The free floor, for point tests.
pub(crate) struct Free {
    polygons: Vec<(Polygon, [f64; 4])>,
    /// Rings taken out of the floor (closed cracks).
    closed: Vec<(Vec<P2>, [f64; 4])>,
}

impl Free {
    pub fn new(polygons: &[Polygon]) -> Free {
        Free {
            polygons: polygons
                .iter()
                .map(|p| (p.clone(), bbox(&p.exterior)))
                .collect(),
            closed: Vec::new(),
        }
    }

    /// This floor with the `rings` (closed cracks) taken out.
    pub fn closing(&self, rings: Vec<Vec<P2>>) -> Free {
        Free {
            polygons: self.polygons.clone(),
            closed: rings
                .into_iter()
                .map(|r| {
                    let b = bbox(&r);
                    (r, b)
                })
                .collect(),
        }
    }

    pub fn contains(&self, p: P2) -> bool {
        self.polygons
            .iter()
            .any(|(poly, b)| in_box(b, p) && contains(poly, p))
            && !self
                .closed
                .iter()
                .any(|(r, b)| in_box(b, p) && point_in_ring(p, r))
    }
}

fn bbox(ring: &[P2]) -> [f64; 4] {
    ring.iter()
        .fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |b, p| {
            [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ]
        })
}

fn in_box(b: &[f64; 4], p: P2) -> bool {
    p[0] >= b[0] && p[0] <= b[2] && p[1] >= b[1] && p[1] <= b[3]
}

/// `p` inside the polygon's exterior and in none of its holes.
pub(crate) fn contains(poly: &Polygon, p: P2) -> bool {
    point_in_ring(p, &poly.exterior) && !poly.holes.iter().any(|h| point_in_ring(p, h))
}

/// Net area: exterior less holes.
pub(crate) fn area(poly: &Polygon) -> f64 {
    ring_signed_area(&poly.exterior).abs()
        - poly
            .holes
            .iter()
            .map(|h| ring_signed_area(h).abs())
            .sum::<f64>()
}

/// The floor divided: the rooms' polygons, and which gaps divide them.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Divided {
    pub rooms: Vec<Polygon>,
    /// Per gap: what it is, `None` when it divides nothing.
    pub kinds: Vec<Option<DoorKind>>,
    /// Pieces of floor too small to be rooms.
    pub dropped: usize,
}

/// Cuts the floor at the gaps that divide it: every gap with a lintel that ends up between two
/// different rooms, and every opening that alone splits its room into two of at least
/// `min_opening_room_area`. A doorway in a wall that divides nothing is a door all the same,
/// uncut. Cracks and walled gaps are always cut, and are never doors.
pub(crate) fn divide(
    polygons: &[Polygon],
    gaps: &[Gap],
    params: &RoomsParams,
    grid: &Grid,
) -> Result<Divided, super::RoomsError> {
    let cut = |kept: &[bool]| -> Result<Vec<Polygon>, super::RoomsError> {
        let mut input = polygons.to_vec();
        for (g, _) in gaps.iter().zip(kept).filter(|(_, k)| **k) {
            let mut ring = g.rect();
            ring.reverse();
            input.push(Polygon {
                exterior: ring,
                holes: Vec::new(),
            });
        }
        resolve(&input, grid).map_err(super::RoomsError::Invalid)
    };
    let sides = |pieces: &[Polygon], g: &Gap| {
        g.probes()
            .map(|p| pieces.iter().position(|q| contains(q, p)))
    };
    let divides =
        |pieces: &[Polygon], g: &Gap| matches!(sides(pieces, g), [Some(l), Some(r)] if l != r);
    // Doors: all at once (a room with two doors to one corridor needs both cut), then those
    // with the same piece on both sides are undone.
    let mut kept: Vec<bool> = gaps.iter().map(|g| g.lintel || g.closed()).collect();
    let mut pieces = cut(&kept)?;
    for _ in 0..4 {
        let before = kept.clone();
        for (k, g) in gaps.iter().enumerate() {
            if kept[k] && !g.closed() && !divides(&pieces, g) {
                kept[k] = false;
            }
        }
        if kept == before {
            break;
        }
        pieces = cut(&kept)?;
    }
    let doors = kept.clone();
    // Openings: one at a time, kept when both sides are rooms of their own.
    for (k, g) in gaps.iter().enumerate() {
        if g.lintel || g.closed() {
            continue;
        }
        let mut trial = kept.clone();
        trial[k] = true;
        let split = cut(&trial)?;
        let big =
            |i: Option<usize>| i.is_some_and(|i| area(&split[i]) >= params.min_opening_room_area);
        let [l, r] = sides(&split, g);
        if l != r && big(l) && big(r) {
            kept = trial;
            pieces = split;
        }
    }
    let before = pieces.len();
    pieces.retain(|p| area(p) >= params.min_room_area);
    let kinds = kept
        .iter()
        .zip(&doors)
        .zip(gaps)
        .map(|((&k, &door), g)| match (k, door) {
            // A doorway in a wall the floor goes around: a door, though it divides nothing.
            (false, _) if g.lintel && g.in_wall && !g.closed() => Some(DoorKind::Door),
            (false, _) => None,
            _ if g.closed() => None,
            (true, true) => Some(DoorKind::Door),
            (true, false) => Some(DoorKind::Opening),
        })
        .collect();
    Ok(Divided {
        dropped: before - pieces.len(),
        rooms: pieces,
        kinds,
    })
}

/// Orders by position, south-west first: 0.5 m bands of y (rounding noise kept off their
/// edges), then x.
fn position_key(p: P2) -> (i64, f64) {
    (((p[1] + 1e-6) / 0.5).floor() as i64, p[0])
}

fn centroid(ring: &[P2]) -> P2 {
    let n = ring.len();
    let (mut cx, mut cy, mut a2) = (0.0, 0.0, 0.0);
    for k in 0..n {
        let (p, q) = (ring[k], ring[(k + 1) % n]);
        let c = geom::cross(p, q);
        cx += (p[0] + q[0]) * c;
        cy += (p[1] + q[1]) * c;
        a2 += c;
    }
    if a2.abs() < 1e-12 {
        return ring.first().copied().unwrap_or([0.0, 0.0]);
    }
    [cx / (3.0 * a2), cy / (3.0 * a2)]
}

fn perimeter(poly: &Polygon) -> f64 {
    std::iter::once(&poly.exterior)
        .chain(&poly.holes)
        .map(|r| {
            (0..r.len())
                .map(|k| geom::dist(r[k], r[(k + 1) % r.len()]))
                .sum::<f64>()
        })
        .sum()
}

/// The story's spaces: rooms with their ids, scanners and neighbours, the doors and openings
/// that divide them, and the walls as centre lines.
pub(crate) fn spaces(
    story: &StoryPlan,
    divided: &Divided,
    gaps: &[Gap],
    paired: &(Vec<Piece>, Coverage),
    faces: &[Face],
    stations: &[(usize, P2)],
    params: &RoomsParams,
) -> Spaces {
    let level = story.level;
    let mut order: Vec<(usize, P2)> = divided
        .rooms
        .iter()
        .enumerate()
        .map(|(k, p)| (k, centroid(&p.exterior)))
        .collect();
    order.sort_by(|a, b| {
        let (ka, kb) = (position_key(a.1), position_key(b.1));
        ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
    });
    let polygons: Vec<&Polygon> = order.iter().map(|(k, _)| &divided.rooms[*k]).collect();
    let id = |k: usize| format!("L{level}-R{}", k + 1);
    let room_at = |p: P2| polygons.iter().position(|q| contains(q, p)).map(id);
    let mut rooms: Vec<Room> = polygons
        .iter()
        .enumerate()
        .map(|(k, p)| Room {
            id: id(k),
            polygon: (*p).clone(),
            area: area(p),
            perimeter: perimeter(p),
            floor_z: story.floor_z,
            ceiling_z: story.ceiling_z,
            scanners: stations
                .iter()
                .filter(|(_, s)| contains(p, *s))
                .map(|(i, _)| *i)
                .collect(),
            neighbours: Vec::new(),
        })
        .collect();
    let mut kept: Vec<(&Gap, DoorKind)> = gaps
        .iter()
        .zip(&divided.kinds)
        .filter_map(|(g, k)| k.map(|k| (g, k)))
        .collect();
    kept.sort_by(|a, b| {
        let (ka, kb) = (position_key(a.0.center()), position_key(b.0.center()));
        ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
    });
    let mut doors = Vec::new();
    for (n, (g, kind)) in kept.into_iter().enumerate() {
        let [l, r] = g.probes().map(room_at);
        if let (Some(l), Some(r)) = (&l, &r) {
            for (x, y) in [(l, r), (r, l)] {
                if let Some(room) = rooms.iter_mut().find(|q| &q.id == x) {
                    if !room.neighbours.contains(y) {
                        room.neighbours.push(y.clone());
                    }
                }
            }
        }
        let (a, b, width) = g.door_span();
        doors.push(Door {
            id: format!("L{level}-D{}", n + 1),
            kind,
            a,
            b,
            width,
            head_z: match kind {
                DoorKind::Door => g.head_z,
                DoorKind::Opening => None,
            },
            depth: g.depth,
            rooms: [l, r],
        });
    }
    for r in &mut rooms {
        r.neighbours.sort();
    }
    let (pieces, covered) = paired;
    let mut walls = Vec::new();
    for p in pieces {
        let mid = geom::scale(geom::add(p.a, p.b), 0.5);
        let off = p.thickness / 2.0 + 0.05;
        let n = p.left();
        let rooms = [
            room_at(geom::add(mid, geom::scale(n, off))),
            room_at(geom::sub(mid, geom::scale(n, off))),
        ];
        // Two faces of one room closer together than twice the thickest wall: a column or a
        // post standing in the room, not a wall.
        if rooms[0].is_some()
            && rooms[0] == rooms[1]
            && geom::dist(p.a, p.b) < 2.0 * params.max_thickness
        {
            continue;
        }
        walls.push(WallCentre {
            id: String::new(),
            a: p.a,
            b: p.b,
            thickness: p.thickness,
            exterior: false,
            rooms,
        });
    }
    // Outer faces seen from one side only: exterior walls of the assumed thickness.
    for (k, f) in faces.iter().enumerate() {
        if !f.outer {
            continue;
        }
        let mut taken = covered[k].clone();
        for (t0, t1) in remaining(0.0, f.len, &mut taken) {
            if t1 - t0 < params.min_exterior_length {
                continue;
            }
            let n = f.solid_normal();
            let shift = geom::scale(n, params.exterior_thickness / 2.0);
            let mid = f.at((t0 + t1) / 2.0);
            walls.push(WallCentre {
                id: String::new(),
                a: geom::add(f.at(t0), shift),
                b: geom::add(f.at(t1), shift),
                thickness: params.exterior_thickness,
                exterior: true,
                rooms: [room_at(geom::sub(mid, geom::scale(n, 0.05))), None],
            });
        }
    }
    for (n, w) in walls.iter_mut().enumerate() {
        w.id = format!("L{level}-C{}", n + 1);
    }
    Spaces {
        rooms,
        doors,
        windows: Vec::new(),
        walls,
    }
}
