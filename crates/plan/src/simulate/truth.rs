//! Ground truth of a synthetic building: per story, the floor and ceiling heights, the open
//! floor as polygons with holes, and every wall as an exact line or arc.

use serde::Serialize;

use crate::geom::{self, P2};
use crate::plan::{
    Door, DoorKind, FloorPlan, InputSummary, Polygon, Room, Spaces, StoryPlan, Wall, WallModel,
};

/// A wall face on the boundary of the open floor, exactly.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "model", rename_all = "lowercase")]
pub enum TruthWall {
    /// A straight piece from `a` to `b`.
    Line {
        /// Start.
        a: P2,
        /// End.
        b: P2,
    },
    /// A circular piece: from angle `start` (radians, counter-clockwise from +x) through `sweep`
    /// radians (negative sweeps run clockwise). A full circle has `sweep` = 2π.
    Arc {
        /// The centre, local coordinates.
        center: P2,
        /// The radius, metres.
        radius: f64,
        /// Start angle, radians.
        start: f64,
        /// Sweep, radians.
        sweep: f64,
    },
}

impl TruthWall {
    /// Length in metres.
    pub fn length(&self) -> f64 {
        match *self {
            TruthWall::Line { a, b } => geom::dist(a, b),
            TruthWall::Arc { radius, sweep, .. } => radius * sweep.abs(),
        }
    }

    /// The point at fraction `f` in [0, 1] along the wall.
    pub fn at(&self, f: f64) -> P2 {
        match *self {
            TruthWall::Line { a, b } => geom::add(a, geom::scale(geom::sub(b, a), f)),
            TruthWall::Arc {
                center,
                radius,
                start,
                sweep,
            } => {
                let t = start + f * sweep;
                [center[0] + radius * t.cos(), center[1] + radius * t.sin()]
            }
        }
    }

    /// Distance from `p` to the wall.
    pub fn distance(&self, p: P2) -> f64 {
        match *self {
            TruthWall::Line { a, b } => geom::point_segment_distance(p, a, b),
            TruthWall::Arc {
                center,
                radius,
                start,
                sweep,
            } => {
                let v = geom::sub(p, center);
                let angle = v[1].atan2(v[0]);
                if angle_in_sweep(angle, start, sweep) {
                    (geom::norm(v) - radius).abs()
                } else {
                    geom::dist(p, self.at(0.0)).min(geom::dist(p, self.at(1.0)))
                }
            }
        }
    }

    /// The wall moved by `d` and rotated by `angle` about the origin (rotation first).
    pub fn transformed(&self, angle: f64, d: P2) -> TruthWall {
        let m = |p: P2| geom::add(rotate(p, angle), d);
        match *self {
            TruthWall::Line { a, b } => TruthWall::Line { a: m(a), b: m(b) },
            TruthWall::Arc {
                center,
                radius,
                start,
                sweep,
            } => TruthWall::Arc {
                center: m(center),
                radius,
                start: start + angle,
                sweep,
            },
        }
    }
}

/// True when `angle` lies on the arc that starts at `start` and sweeps `sweep` radians.
pub fn angle_in_sweep(angle: f64, start: f64, sweep: f64) -> bool {
    if sweep.abs() >= std::f64::consts::TAU {
        return true;
    }
    let tau = std::f64::consts::TAU;
    let (lo, len) = if sweep >= 0.0 {
        (start, sweep)
    } else {
        (start + sweep, -sweep)
    };
    (angle - lo).rem_euclid(tau) <= len
}

/// `p` rotated by `angle` radians about the origin.
pub fn rotate(p: P2, angle: f64) -> P2 {
    let (s, c) = angle.sin_cos();
    [c * p[0] - s * p[1], s * p[0] + c * p[1]]
}

/// One story's ground truth (local frame).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TruthStory {
    /// The story's index, from the lowest up.
    pub level: usize,
    /// The floor's local height.
    pub floor_z: f64,
    /// The ceiling's local height.
    pub ceiling_z: f64,
    /// Open floor, door openings included; exteriors CCW, holes CW, arcs densified to 1 mm.
    pub polygons: Vec<Polygon>,
    /// Every wall face bounding the open floor, exactly.
    pub walls: Vec<TruthWall>,
    /// The rooms: the open floor without the door openings, one polygon a room (arcs
    /// densified to 1 mm). Empty where the building does not say (random buildings).
    pub rooms: Vec<TruthRoom>,
    /// Every door between rooms.
    pub doors: Vec<TruthDoor>,
    /// Every window in an outer wall. Empty where the building has none.
    pub windows: Vec<TruthWindow>,
}

/// One window of the truth: a gap in an outer wall's face between a sill and a head, with wall
/// below and above it and a reveal as deep as the wall behind the face.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TruthWindow {
    /// One jamb, on the wall's inner face.
    pub a: P2,
    /// The other jamb.
    pub b: P2,
    /// The window's width, metres.
    pub width: f64,
    /// Local height of the sill (the top of the wall below).
    pub sill_z: f64,
    /// Local height of the head (the underside of the wall above).
    pub head_z: f64,
    /// The reveal's depth: the wall's thickness, from the inner face outwards.
    pub depth: f64,
    /// Unit normal of the face pointing out of the building.
    pub outward: P2,
}

impl TruthWindow {
    /// The midpoint of the jambs.
    pub fn center(&self) -> P2 {
        geom::scale(geom::add(self.a, self.b), 0.5)
    }

    /// The window's outer end of its reveal: the plane rays leave the building through.
    pub fn exit(&self) -> (P2, P2) {
        let d = geom::scale(self.outward, self.depth);
        (geom::add(self.a, d), geom::add(self.b, d))
    }

    /// The window moved by `d` and rotated by `angle` about the origin (rotation first).
    pub fn transformed(&self, angle: f64, d: P2) -> TruthWindow {
        let m = |p: P2| geom::add(rotate(p, angle), d);
        TruthWindow {
            a: m(self.a),
            b: m(self.b),
            outward: rotate(self.outward, angle),
            ..*self
        }
    }
}

/// One room of the truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TruthRoom {
    /// The room's floor, local coordinates.
    pub polygon: Polygon,
    /// Net floor area, m².
    pub area: f64,
}

/// One door of the truth: the opening through its wall.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TruthDoor {
    /// The jambs, on the wall's centre line.
    pub a: P2,
    /// The other jamb.
    pub b: P2,
    /// The door's width, metres.
    pub width: f64,
    /// The pierced wall's thickness: the interior walls' thickness, where doors are.
    pub depth: f64,
}

impl TruthDoor {
    /// The midpoint of the jambs.
    pub fn center(&self) -> P2 {
        geom::scale(geom::add(self.a, self.b), 0.5)
    }

    /// The door moved by `d` and rotated by `angle` about the origin (rotation first).
    pub fn transformed(&self, angle: f64, d: P2) -> TruthDoor {
        let m = |p: P2| geom::add(rotate(p, angle), d);
        TruthDoor {
            a: m(self.a),
            b: m(self.b),
            ..*self
        }
    }
}

impl TruthRoom {
    /// A room from its polygon.
    pub fn of(polygon: Polygon) -> TruthRoom {
        let area = geom::ring_signed_area(&polygon.exterior).abs()
            - polygon
                .holes
                .iter()
                .map(|h| geom::ring_signed_area(h).abs())
                .sum::<f64>();
        TruthRoom { polygon, area }
    }
}

/// A whole building's ground truth: world = `origin` + local.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Truth {
    /// The building's name.
    pub building: String,
    /// World coordinates of the local frame.
    pub origin: [f64; 3],
    /// The stories, from the lowest up.
    pub stories: Vec<TruthStory>,
}

impl Truth {
    /// The truth as a [`FloorPlan`], so the GeoJSON writer can write it in the plan contract.
    /// Arc walls are densified to 1 cm chord error, as fitted walls are.
    pub fn to_floor_plan(&self) -> FloorPlan {
        FloorPlan {
            origin: self.origin,
            crs: None,
            georeference: None,
            input: InputSummary {
                points: 0,
                format: "truth".into(),
                scans: 0,
                ..Default::default()
            },
            parameters: serde_json::json!({"building": self.building}),
            timings_ms: Vec::new(),
            stories: self.stories.iter().map(story_plan).collect(),
            notes: vec![format!(
                "ground truth of the simulated building `{}`",
                self.building
            )],
        }
    }
}

fn story_plan(s: &TruthStory) -> StoryPlan {
    StoryPlan {
        level: s.level,
        floor_z: s.floor_z,
        ceiling_z: s.ceiling_z,
        polygons: s.polygons.clone(),
        walls: s
            .walls
            .iter()
            .map(|w| match *w {
                TruthWall::Line { a, b } => Wall {
                    model: WallModel::Line,
                    points: vec![a, b],
                    support: 0,
                },
                TruthWall::Arc { center, radius, .. } => Wall {
                    model: WallModel::Arc { center, radius },
                    points: densify(w, 0.01),
                    support: 0,
                },
            })
            .collect(),
        samples: Vec::new(),
        spaces: truth_spaces(s),
        underlay: None,
    }
}

/// The truth's rooms and doors as a plan's spaces, so writers show them.
fn truth_spaces(s: &TruthStory) -> Spaces {
    let rooms = s
        .rooms
        .iter()
        .enumerate()
        .map(|(k, r)| Room {
            id: format!("L{}-R{}", s.level, k + 1),
            polygon: r.polygon.clone(),
            area: r.area,
            perimeter: std::iter::once(&r.polygon.exterior)
                .chain(&r.polygon.holes)
                .map(|ring| {
                    (0..ring.len())
                        .map(|i| geom::dist(ring[i], ring[(i + 1) % ring.len()]))
                        .sum::<f64>()
                })
                .sum(),
            floor_z: s.floor_z,
            ceiling_z: s.ceiling_z,
            scanners: Vec::new(),
            neighbours: Vec::new(),
        })
        .collect();
    let doors = s
        .doors
        .iter()
        .enumerate()
        .map(|(k, d)| Door {
            id: format!("L{}-D{}", s.level, k + 1),
            kind: DoorKind::Door,
            a: d.a,
            b: d.b,
            width: d.width,
            head_z: None,
            depth: d.depth,
            rooms: [None, None],
        })
        .collect();
    Spaces {
        rooms,
        doors,
        ..Default::default()
    }
}

/// Points along a wall, with chord error at most `chord_error` on arcs (both ends included).
pub fn densify(wall: &TruthWall, chord_error: f64) -> Vec<P2> {
    match *wall {
        TruthWall::Line { a, b } => vec![a, b],
        TruthWall::Arc { radius, sweep, .. } => {
            // A chord of angle θ deviates r(1 - cos(θ/2)) from the arc.
            let step = 2.0 * (1.0 - chord_error / radius).clamp(-1.0, 1.0).acos();
            let n = ((sweep.abs() / step.max(1e-6)).ceil() as usize).max(1);
            (0..=n).map(|k| wall.at(k as f64 / n as f64)).collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn arc_distance_and_sweep() {
        let arc = TruthWall::Arc {
            center: [0.0, 0.0],
            radius: 2.0,
            start: 0.0,
            sweep: PI,
        };
        assert!((arc.distance([0.0, 3.0]) - 1.0).abs() < 1e-12);
        // Below the half circle: nearest is an end point.
        assert!((arc.distance([2.0, -1.0]) - 1.0).abs() < 1e-12);
        assert!((arc.length() - 2.0 * PI).abs() < 1e-12);
        assert!(angle_in_sweep(-PI / 2.0, 0.0, -PI));
        assert!(!angle_in_sweep(-PI / 2.0, 0.0, PI));
        let pts = densify(&arc, 0.001);
        for w in pts.windows(2) {
            let mid = geom::scale(geom::add(w[0], w[1]), 0.5);
            assert!(2.0 - geom::norm(mid) <= 0.001 + 1e-12);
        }
    }
}
