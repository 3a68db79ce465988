//! Rooms, doors and wall thickness against the truth: each truth room matched to the plan
//! room it overlaps most (IoU above one half, so at most one), each truth door to a plan door
//! (door or opening) whose centre is within 10 cm and width within 5 cm, and each interior
//! centre-line wall's thickness against the distance between the truth faces on either side.

use serde::Serialize;

use super::area::iou;
use crate::geom::{self, P2};
use crate::plan::{Polygon, StoryPlan};
use crate::simulate::truth::{TruthStory, TruthWall};

/// A door counts when its centre is this close to the truth's, m.
pub const DOOR_CENTRE_TOLERANCE: f64 = 0.10;
/// ... and its width this close, m.
pub const DOOR_WIDTH_TOLERANCE: f64 = 0.05;

/// How one truth room came back.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RoomMatch {
    /// The truth room's area, m².
    pub truth_area: f64,
    /// The matched plan room's id and area.
    pub plan_id: Option<String>,
    /// The matched plan room's area, m².
    pub plan_area: Option<f64>,
    /// IoU of the truth room and its match (0 when unmatched).
    pub iou: f64,
    /// The bound: within 1 %, or 0.2 m² for rooms under 20 m².
    pub within: bool,
}

/// One story's rooms, doors and walls.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RoomsScore {
    /// Rooms in the truth.
    pub truth_rooms: usize,
    /// Rooms in the plan.
    pub plan_rooms: usize,
    /// One match per truth room.
    pub rooms: Vec<RoomMatch>,
    /// Doors and openings in the truth.
    pub truth_doors: usize,
    /// Plan doors and openings.
    pub plan_doors: usize,
    /// Truth doors a plan door matched.
    pub doors_matched: usize,
    /// Of the matched doors: the largest centre and width errors, m.
    pub door_centre_max: f64,
    /// The largest door width error, metres.
    pub door_width_max: f64,
    /// Interior centre-line walls with truth faces on both sides, and their thickness errors.
    pub walls_measured: usize,
    /// The mean wall thickness error, metres.
    pub thickness_mean: f64,
    /// The largest wall thickness error, metres.
    pub thickness_max: f64,
}

impl RoomsScore {
    /// Truth rooms a plan room matched.
    pub fn matched(&self) -> usize {
        self.rooms.iter().filter(|r| r.plan_id.is_some()).count()
    }
    /// Truth rooms whose match is within tolerance.
    pub fn within(&self) -> usize {
        self.rooms.iter().filter(|r| r.within).count()
    }
    /// Share of truth doors matched.
    pub fn door_recall(&self) -> f64 {
        ratio(self.doors_matched, self.truth_doors)
    }
    /// Share of plan doors that match a truth door.
    pub fn door_precision(&self) -> f64 {
        ratio(self.doors_matched, self.plan_doors)
    }
    /// The worst relative area error of the matched rooms.
    pub fn worst_area_error(&self) -> f64 {
        self.rooms
            .iter()
            .filter_map(|r| r.plan_area.map(|a| (a - r.truth_area).abs() / r.truth_area))
            .fold(0.0, f64::max)
    }
    /// One line, for reports.
    pub fn summary(&self) -> String {
        format!(
            "rooms {}/{} found ({} in plan), {} within bound, worst area err {:.2} %; doors {}/{} matched ({} in plan): recall {:.3} precision {:.3}, centre max {:.3} m, width max {:.3} m; walls {} measured, thickness err mean {:.4} max {:.4} m",
            self.matched(),
            self.truth_rooms,
            self.plan_rooms,
            self.within(),
            100.0 * self.worst_area_error(),
            self.doors_matched,
            self.truth_doors,
            self.plan_doors,
            self.door_recall(),
            self.door_precision(),
            self.door_centre_max,
            self.door_width_max,
            self.walls_measured,
            self.thickness_mean,
            self.thickness_max,
        )
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 {
        if a == 0 {
            1.0
        } else {
            0.0
        }
    } else {
        a as f64 / b as f64
    }
}

fn bbox(p: &Polygon) -> [f64; 4] {
    p.exterior
        .iter()
        .fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |b, q| {
            [
                b[0].min(q[0]),
                b[1].min(q[1]),
                b[2].max(q[0]),
                b[3].max(q[1]),
            ]
        })
}

/// Scores `plan`'s spaces (already in the truth's frame) against `truth`; `None` when the
/// truth gives no rooms.
pub fn score_rooms(plan: &StoryPlan, truth: &TruthStory, scanline: f64) -> Option<RoomsScore> {
    if truth.rooms.is_empty() {
        return None;
    }
    let spaces = &plan.spaces;
    let boxes: Vec<[f64; 4]> = spaces.rooms.iter().map(|r| bbox(&r.polygon)).collect();
    let rooms = truth
        .rooms
        .iter()
        .map(|t| {
            let tb = bbox(&t.polygon);
            let best = spaces
                .rooms
                .iter()
                .zip(&boxes)
                .filter(|(_, b)| b[0] < tb[2] && tb[0] < b[2] && b[1] < tb[3] && tb[1] < b[3])
                .map(|(r, _)| {
                    let v = iou(
                        std::slice::from_ref(&r.polygon),
                        std::slice::from_ref(&t.polygon),
                        scanline,
                    );
                    (r, v)
                })
                .max_by(|a, b| a.1.total_cmp(&b.1));
            match best {
                Some((r, v)) if v > 0.5 => {
                    let err = (r.area - t.area).abs();
                    let within = err <= 0.01 * t.area || (t.area < 20.0 && err <= 0.2);
                    RoomMatch {
                        truth_area: t.area,
                        plan_id: Some(r.id.clone()),
                        plan_area: Some(r.area),
                        iou: v,
                        within,
                    }
                }
                other => RoomMatch {
                    truth_area: t.area,
                    plan_id: None,
                    plan_area: None,
                    iou: other.map_or(0.0, |b| b.1),
                    within: false,
                },
            }
        })
        .collect();
    // Doors: nearest pairs first, each used once.
    let mut pairs = Vec::new();
    for (i, t) in truth.doors.iter().enumerate() {
        for (j, d) in spaces.doors.iter().enumerate() {
            let c = geom::scale(geom::add(d.a, d.b), 0.5);
            let e = geom::dist(c, t.center());
            let w = (d.width - t.width).abs();
            if e <= DOOR_CENTRE_TOLERANCE && w <= DOOR_WIDTH_TOLERANCE {
                pairs.push((e, w, i, j));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut ti, mut pj) = (
        vec![false; truth.doors.len()],
        vec![false; spaces.doors.len()],
    );
    let (mut matched, mut centre_max, mut width_max) = (0, 0.0f64, 0.0f64);
    for (e, w, i, j) in pairs {
        if ti[i] || pj[j] {
            continue;
        }
        ti[i] = true;
        pj[j] = true;
        matched += 1;
        centre_max = centre_max.max(e);
        width_max = width_max.max(w);
    }
    let errors: Vec<f64> = spaces
        .walls
        .iter()
        .filter(|w| !w.exterior)
        .filter_map(|w| truth_thickness(w.a, w.b, &truth.walls).map(|t| (w.thickness - t).abs()))
        .collect();
    Some(RoomsScore {
        truth_rooms: truth.rooms.len(),
        plan_rooms: spaces.rooms.len(),
        rooms,
        truth_doors: truth.doors.len(),
        plan_doors: spaces.doors.len(),
        doors_matched: matched,
        door_centre_max: centre_max,
        door_width_max: width_max,
        walls_measured: errors.len(),
        thickness_mean: if errors.is_empty() {
            0.0
        } else {
            errors.iter().sum::<f64>() / errors.len() as f64
        },
        thickness_max: errors.iter().copied().fold(0.0, f64::max),
    })
}

/// The distance between the nearest truth faces parallel to a centre line, one on either side
/// of its middle, within 0.5 m each; `None` when either side has none.
fn truth_thickness(a: P2, b: P2, walls: &[TruthWall]) -> Option<f64> {
    let u = geom::normalize(geom::sub(b, a))?;
    let n = [-u[1], u[0]];
    let m = geom::scale(geom::add(a, b), 0.5);
    let (mut left, mut right) = (f64::INFINITY, f64::INFINITY);
    for w in walls {
        let TruthWall::Line { a: p, b: q } = *w else {
            continue;
        };
        let Some(v) = geom::normalize(geom::sub(q, p)) else {
            continue;
        };
        if geom::cross(u, v).abs() > 0.05 {
            continue;
        }
        let len = geom::dist(p, q);
        let t = geom::dot(geom::sub(m, p), v);
        if !(0.0..=len).contains(&t) {
            continue;
        }
        let s = geom::dot(geom::sub(p, m), n);
        if s > 0.0 && s < 0.5 {
            left = left.min(s);
        } else if s < 0.0 && -s < 0.5 {
            right = right.min(-s);
        }
    }
    (left.is_finite() && right.is_finite()).then_some(left + right)
}
