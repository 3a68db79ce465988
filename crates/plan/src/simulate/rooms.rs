//! Buildings of many small rooms: a dense office (about 30 rooms a story), a floor of thin
//! partitions, closets and a bathroom, and a room captured by a phone held up to its ceiling.

use super::buildings::{transform, Patch, RectStory, StoryModel};
use super::phone::Capture;
use super::rects::Rect;

/// Story height of the dense office, floor to floor, and its rooms' ceiling height.
const OFFICE_STORY: f64 = 3.2;
const OFFICE_CEILING: f64 = 2.7;
/// Rooms 2.9 m wide between 10 cm partitions, 15 a side.
const ROOM_PITCH: f64 = 3.0;
const ROOMS_A_SIDE: usize = 15;

/// One story of the dense office: 15 rooms on each side of a 2 m corridor, 10 cm partitions,
/// one station a room and nine in the corridor. On level 1 two pairs of south rooms are one
/// room each.
pub(super) fn dense_office_story(level: usize) -> StoryModel {
    const T: f64 = 0.1;
    let floor_z = OFFICE_STORY * level as f64;
    // Written out, so that the walls' faces meet exactly.
    let (south_y, corridor, north_y) = ((0.0, 5.0), (5.1, 7.1), (7.2, 12.2));
    let mut s = RectStory {
        floor_z,
        ceiling_z: floor_z + OFFICE_CEILING,
        ..Default::default()
    };
    let length = ROOM_PITCH * ROOMS_A_SIDE as f64 - T;
    s.open.push(Rect::new(0.0, corridor.0, length, corridor.1));
    let merged = |k: usize| level == 1 && (k == 4 || k == 10);
    let mut route = vec![[1.0, 6.1]];
    for side in 0..2 {
        let (y0, y1) = if side == 0 { south_y } else { north_y };
        let mut k = 0;
        while k < ROOMS_A_SIDE {
            let wide = side == 0 && merged(k);
            let x0 = ROOM_PITCH * k as f64;
            let x1 = x0 + ROOM_PITCH * if wide { 2.0 } else { 1.0 } - T;
            s.open.push(Rect::new(x0, y0, x1, y1));
            let door = x0 + 1.0;
            let (dy0, dy1, sy) = if side == 0 {
                (y1, corridor.0, 2.4)
            } else {
                (corridor.1, y0, 9.8)
            };
            s.doors.push(Rect::new(door, dy0, door + 0.9, dy1));
            s.stations
                .push([if side == 0 { x0 + 2.0 } else { x0 + 0.9 }, sy]);
            if k % 2 == 0 {
                // A desk against the back wall.
                let (ty0, ty1) = if side == 0 { (0.3, 1.0) } else { (11.2, 11.9) };
                s.tables.push(Rect::new(x0 + 0.5, ty0, x0 + 2.0, ty1));
            }
            route.extend([[door + 0.45, 6.1], [door + 0.45, sy], [door + 0.45, 6.1]]);
            k += if wide { 2 } else { 1 };
        }
        if side == 0 {
            route.push([length - 1.0, 6.1]);
        }
    }
    route.push([1.0, 6.1]);
    for c in 0..9 {
        s.stations.push([2.5 + 5.0 * c as f64, 6.1]);
    }
    s.route = route;
    s.into_model()
}

/// One story of rooms divided by 10 cm partitions: three rooms on a corridor, two with a
/// 1.2 m × 1.5 m closet in a corner, a stub wall, and along the north a bathroom, a third
/// closet and a fourth room. Every room and closet has a station.
pub(super) fn partitions_story() -> StoryModel {
    let s = RectStory {
        floor_z: 0.0,
        ceiling_z: 2.6,
        open: vec![
            // Room A with its closet in the north-west corner cut out.
            Rect::new(0.0, 0.0, 4.0, 3.4),
            Rect::new(1.3, 3.4, 4.0, 5.0),
            Rect::new(0.0, 3.5, 1.2, 5.0),
            // Room B.
            Rect::new(4.1, 0.0, 8.1, 5.0),
            // Room C with its closet in the north-east corner.
            Rect::new(8.2, 0.0, 12.3, 3.4),
            Rect::new(8.2, 3.4, 11.0, 5.0),
            Rect::new(11.1, 3.5, 12.3, 5.0),
            // The corridor.
            Rect::new(0.0, 5.1, 12.3, 6.6),
            // Bathroom, closet, room D.
            Rect::new(0.0, 6.7, 1.8, 9.0),
            Rect::new(1.9, 6.7, 3.1, 8.2),
            Rect::new(3.2, 6.7, 8.0, 9.0),
        ],
        doors: vec![
            Rect::new(0.3, 3.4, 1.0, 3.5),
            Rect::new(11.3, 3.4, 12.0, 3.5),
            Rect::new(2.0, 5.0, 2.9, 5.1),
            Rect::new(5.0, 5.0, 5.9, 5.1),
            Rect::new(9.5, 5.0, 10.4, 5.1),
            Rect::new(0.5, 6.6, 1.2, 6.7),
            Rect::new(2.15, 6.6, 2.85, 6.7),
            Rect::new(5.0, 6.6, 5.9, 6.7),
        ],
        // A 1 m stub wall into room B.
        solid: vec![Rect::new(6.05, 0.0, 6.15, 1.0)],
        tables: vec![Rect::new(2.5, 0.3, 3.7, 1.0)],
        stations: vec![
            [2.5, 2.2],
            // Room B's stub wall hides a corner from either side: a station on each.
            [5.2, 2.5],
            [7.2, 2.0],
            [9.8, 1.8],
            [3.0, 5.85],
            [9.0, 5.85],
            [0.9, 7.9],
            [5.6, 7.9],
            [0.6, 4.25],
            [11.7, 4.25],
            [2.5, 7.45],
        ],
        route: vec![
            [0.6, 5.85],
            [2.45, 5.85],
            [2.45, 3.0],
            [0.65, 3.0],
            [0.65, 4.3],
            [0.65, 3.0],
            [2.45, 3.0],
            [2.45, 5.85],
            [5.45, 5.85],
            [5.45, 2.5],
            [5.45, 5.85],
            [9.95, 5.85],
            [9.95, 3.0],
            [11.65, 3.0],
            [11.65, 4.3],
            [11.65, 3.0],
            [9.95, 3.0],
            [9.95, 5.85],
            [5.45, 5.85],
            [5.45, 7.9],
            [5.45, 5.85],
            [2.5, 5.85],
            [2.5, 7.5],
            [2.5, 5.85],
            [0.85, 5.85],
            [0.85, 7.9],
        ],
        ..Default::default()
    };
    s.into_model()
}

/// Points below this height are never captured by [`ceiling_only_story`]'s scanner.
pub const CEILING_CAPTURE_ABOVE: f64 = 1.5;
/// Where the phone was held higher, its walls are seen from up to this much higher still: from
/// 3.3 m up at most, 0.7 m under the ceiling, too little to tell a wall from a hanging light.
pub const CEILING_CAPTURE_SWING: f64 = 1.8;
/// The ceiling is captured only this far, horizontally, from where the phone was.
pub const CEILING_CAPTURE_REACH: f64 = 3.0;
/// Light panels hang this far under the ceiling: a dense level below it, as a suspended grid.
const LIGHTS_BELOW: f64 = 0.9;

/// An L-shaped room 4 m high, rotated 33°, captured as a phone held up for ceiling-based
/// localisation captures it, like the consumer-LiDAR rooms of the real data: no floor in the
/// cloud; walls seen from the ceiling down to 1.5-3.3 m above the floor, the height changing
/// along them, so that along about a third of their length too little of them is seen to be
/// sure of them; the ceiling captured only within 3 m of where the phone was, so its far
/// corners are missing while their walls are there; and light panels hanging 0.9 m under it.
pub(super) fn ceiling_only_story() -> StoryModel {
    let s = RectStory {
        floor_z: 0.0,
        ceiling_z: 4.0,
        open: vec![Rect::new(0.0, 0.0, 8.0, 6.0), Rect::new(0.0, 6.0, 3.0, 8.5)],
        stations: vec![[2.5, 2.5], [5.5, 3.5], [1.5, 7.2]],
        route: vec![
            [1.5, 1.5],
            [6.5, 1.5],
            [6.5, 4.5],
            [1.5, 4.5],
            [1.5, 7.5],
            [1.5, 1.5],
        ],
        ..Default::default()
    };
    let mut model = s.into_model();
    let lights = [
        Rect::new(1.5, 1.5, 2.1, 2.7),
        Rect::new(5.0, 1.5, 5.6, 2.7),
        Rect::new(5.0, 3.8, 5.6, 5.0),
        Rect::new(1.2, 6.6, 1.8, 7.8),
    ];
    model.patches.extend(
        lights
            .into_iter()
            .map(|r| Patch::from_rect(r, model.ceiling_z - LIGHTS_BELOW)),
    );
    let mut model = transform(model, 33f64.to_radians(), [2.0, -1.0]);
    model.capture = Some(Capture {
        above: CEILING_CAPTURE_ABOVE,
        swing: CEILING_CAPTURE_SWING,
        ceiling_reach: CEILING_CAPTURE_REACH,
    });
    model
}
