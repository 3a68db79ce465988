//! Buildings whose levels see into each other: a house with an attic under a pitched roof and a
//! gallery over a double-height living room, and a hall with a mezzanine. Every story holds the
//! whole building's surfaces, and floors, ceilings and the roof are patches, so a scanner on
//! the gallery sees down into the room below and one below sees up through the void.
//!
//! An upper story's truth is the floor plan of that level as an architect draws it: the open
//! region bounded by the walls at that level, the void over the double-height room included
//! (it is open to below, not a wall).

use super::buildings::{LevelParts, Patch, RectStory, StoryModel, Surface};
use super::rects::Rect;
use super::truth::{TruthStory, TruthWall};

/// The house's ground floor ceiling (the slab's underside) and the attic floor (its top).
const HOUSE_CEILING: f64 = 2.45;
const ATTIC_FLOOR: f64 = 2.6;
/// Where the roof meets the long walls (knee walls 1.2 m high) and its ridge.
const EAVES: f64 = 3.8;
const RIDGE: f64 = 6.0;
/// The house's inner faces span x 0..10, y 0..8; the ridge runs along x at y = 4.
const HOUSE: Rect = Rect {
    x0: 0.0,
    y0: 0.0,
    x1: 10.0,
    y1: 8.0,
};
/// The gallery's edge over the living room, with a railing this high.
const GALLERY_EDGE: f64 = 4.0;
const RAILING: f64 = 0.9;

/// A line surface from `a` to `b` between two heights.
fn face(a: [f64; 2], b: [f64; 2], z0: f64, z1: f64) -> Surface {
    Surface {
        curve: TruthWall::Line { a, b },
        z: [z0, z1],
    }
}

/// A story model that sees the whole building.
fn story(
    floor_z: f64,
    ceiling_z: f64,
    rects: RectStory,
    parts: &LevelParts,
    surfaces: &[Surface],
    patches: &[Patch],
) -> StoryModel {
    StoryModel {
        floor_z,
        ceiling_z,
        slabs: false,
        capture: None,
        surfaces: surfaces.to_vec(),
        patches: patches.to_vec(),
        stations: rects.stations,
        route: rects.route,
        truth: TruthStory {
            level: 0,
            floor_z,
            ceiling_z,
            polygons: parts.polygons.clone(),
            walls: parts.walls.clone(),
            rooms: parts.rooms.clone(),
            doors: parts.doors.clone(),
            windows: parts.windows.clone(),
        },
    }
}

/// A two-story house: a ground floor whose living room is open to the roof, and an attic under
/// a pitched roof (knee walls 1.2 m high, the ridge 3.4 m above the attic floor) with a
/// gallery over the living room behind a 0.9 m railing, and a partition. Seven stations, one on
/// the gallery 4.1 m up, as in the issue.
pub(super) fn attic_house() -> Vec<StoryModel> {
    let ground = RectStory {
        floor_z: 0.0,
        ceiling_z: HOUSE_CEILING,
        open: vec![
            // Living room (double height), kitchen, bedroom, bathroom.
            Rect::new(0.0, 0.0, GALLERY_EDGE, 8.0),
            Rect::new(4.15, 0.0, 10.0, 3.9),
            Rect::new(4.15, 4.0, 7.9, 8.0),
            Rect::new(8.0, 4.0, 10.0, 8.0),
        ],
        doors: vec![
            Rect::new(GALLERY_EDGE, 1.5, 4.15, 2.4),
            Rect::new(GALLERY_EDGE, 5.5, 4.15, 6.4),
            Rect::new(5.0, 3.9, 5.9, 4.0),
            Rect::new(7.9, 6.0, 8.0, 6.8),
        ],
        tables: vec![Rect::new(6.0, 0.6, 7.4, 1.4), Rect::new(1.0, 3.4, 2.6, 4.4)],
        stations: vec![[2.0, 2.2], [2.2, 6.0], [6.5, 2.2], [5.8, 6.2], [9.0, 5.4]],
        route: vec![
            [2.0, 2.8],
            [2.0, 1.95],
            [6.5, 1.95],
            [5.45, 1.95],
            [5.45, 6.4],
            [9.0, 6.4],
            [5.45, 6.4],
            [5.45, 5.95],
            [2.0, 5.95],
            [2.0, 4.8],
        ],
        ..Default::default()
    };
    // The attic's walls start at the ground floor's ceiling: over the living room they go on
    // from there, elsewhere the slab hides their foot. They run up to the ridge; the roof
    // hides what lies above it.
    let attic = RectStory {
        floor_z: HOUSE_CEILING,
        ceiling_z: RIDGE,
        open: vec![
            Rect::new(0.0, 0.0, 7.4, 8.0),
            Rect::new(7.5, 0.0, 10.0, 8.0),
        ],
        doors: vec![Rect::new(7.4, 3.6, 7.5, 4.5)],
        stations: vec![[4.45, 4.0], [8.7, 4.0]],
        route: vec![[4.45, 4.05], [8.7, 4.05], [4.45, 4.05]],
        ..Default::default()
    };
    let g = ground.parts(HOUSE_CEILING);
    let a = attic.parts(RIDGE);
    let mut surfaces = g.surfaces.clone();
    surfaces.extend(a.surfaces.iter().copied());
    // The slab's edge under the gallery, and the railing on it (5 cm thick).
    let (e, e2) = (GALLERY_EDGE, GALLERY_EDGE + 0.05);
    surfaces.push(face([e, 0.0], [e, 8.0], HOUSE_CEILING, ATTIC_FLOOR));
    surfaces.push(face([e, 0.0], [e, 8.0], ATTIC_FLOOR, ATTIC_FLOOR + RAILING));
    surfaces.push(face(
        [e2, 0.0],
        [e2, 8.0],
        ATTIC_FLOOR,
        ATTIC_FLOOR + RAILING,
    ));
    let mut patches = g.patches.clone();
    patches.extend(a.patches.iter().copied());
    let over_gallery = Rect::new(e, 0.0, HOUSE.x1, HOUSE.y1);
    patches.extend([
        Patch::from_rect(HOUSE, 0.0),
        Patch::from_rect(over_gallery, HOUSE_CEILING),
        Patch::from_rect(over_gallery, ATTIC_FLOOR),
        Patch::from_rect(Rect::new(e, 0.0, e2, 8.0), ATTIC_FLOOR + RAILING),
    ]);
    // The roof's two planes, past the walls so that no ray slips between roof and wall.
    let pitch = (RIDGE - EAVES) / 4.0;
    patches.push(Patch {
        corners: [[-0.5, -0.5], [10.5, -0.5], [10.5, 4.0], [-0.5, 4.0]],
        z: EAVES - 0.5 * pitch,
        slope: [0.0, pitch],
    });
    patches.push(Patch {
        corners: [[-0.5, 4.0], [10.5, 4.0], [10.5, 8.5], [-0.5, 8.5]],
        z: RIDGE,
        slope: [0.0, -pitch],
    });
    vec![
        story(0.0, HOUSE_CEILING, ground, &g, &surfaces, &patches),
        story(ATTIC_FLOOR, RIDGE, attic, &a, &surfaces, &patches),
    ]
}

/// The hall's ceiling, and the mezzanine's underside and floor.
const HALL_CEILING: f64 = 6.0;
const MEZZANINE_UNDER: f64 = 2.8;
const MEZZANINE_FLOOR: f64 = 3.0;
/// The mezzanine runs along the hall's north side from this y on.
const MEZZANINE_EDGE: f64 = 8.0;

/// A 20 m × 12 m hall 6 m high, with a mezzanine 3 m up along its north side (behind a 0.9 m
/// railing, with a partition and a column through both levels) over two rooms.
pub(super) fn mezzanine_hall() -> Vec<StoryModel> {
    let m = MEZZANINE_EDGE;
    let column = Rect::new(9.8, 3.8, 10.2, 4.2);
    let ground = RectStory {
        floor_z: 0.0,
        ceiling_z: MEZZANINE_UNDER,
        open: vec![
            Rect::new(0.0, 0.0, 20.0, m),
            Rect::new(0.0, m + 0.15, 9.9, 12.0),
            Rect::new(10.0, m + 0.15, 20.0, 12.0),
        ],
        doors: vec![
            Rect::new(4.0, m, 4.9, m + 0.15),
            Rect::new(15.0, m, 15.9, m + 0.15),
        ],
        solid: vec![column],
        tables: vec![
            Rect::new(2.0, 10.6, 3.5, 11.4),
            Rect::new(13.0, 1.0, 15.0, 2.0),
        ],
        stations: vec![
            [5.0, 4.0],
            [15.0, 4.6],
            [10.0, 1.5],
            [6.0, 10.0],
            [17.0, 10.0],
        ],
        route: vec![
            [2.0, 2.5],
            [18.0, 2.5],
            [18.0, 6.0],
            [15.45, 6.0],
            [15.45, 10.0],
            [15.45, 6.0],
            [4.45, 6.0],
            [4.45, 10.0],
            [4.45, 6.0],
            [2.0, 6.0],
            [2.0, 2.5],
        ],
        ..Default::default()
    };
    // The upper level's walls start at the mezzanine's underside (the slab hides their foot
    // under it, and the hall's walls go on from there).
    let upper = RectStory {
        floor_z: MEZZANINE_UNDER,
        ceiling_z: HALL_CEILING,
        open: vec![
            Rect::new(0.0, 0.0, 20.0, m),
            Rect::new(0.0, m, 13.9, 12.0),
            Rect::new(14.0, m, 20.0, 12.0),
        ],
        doors: vec![Rect::new(13.9, 10.0, 14.0, 10.9)],
        solid: vec![column],
        // Stations within 10 m of every wall they should capture (§3.1's range).
        stations: vec![[3.0, 10.0], [10.5, 10.5], [17.0, 10.0]],
        route: vec![[2.0, 10.45], [18.0, 10.45], [2.0, 10.45]],
        ..Default::default()
    };
    let g = ground.parts(MEZZANINE_UNDER);
    let u = upper.parts(HALL_CEILING);
    let mut surfaces = g.surfaces.clone();
    surfaces.extend(u.surfaces.iter().copied());
    surfaces.push(face([0.0, m], [20.0, m], MEZZANINE_UNDER, MEZZANINE_FLOOR));
    let top = MEZZANINE_FLOOR + RAILING;
    surfaces.push(face([0.0, m], [20.0, m], MEZZANINE_FLOOR, top));
    surfaces.push(face(
        [0.0, m + 0.05],
        [20.0, m + 0.05],
        MEZZANINE_FLOOR,
        top,
    ));
    let mut patches = g.patches.clone();
    patches.extend(u.patches.iter().copied());
    let hall = Rect::new(0.0, 0.0, 20.0, 12.0);
    let mezzanine = Rect::new(0.0, m, 20.0, 12.0);
    patches.extend([
        Patch::from_rect(hall, 0.0),
        Patch::from_rect(hall, HALL_CEILING),
        Patch::from_rect(mezzanine, MEZZANINE_UNDER),
        Patch::from_rect(mezzanine, MEZZANINE_FLOOR),
        Patch::from_rect(Rect::new(0.0, m, 20.0, m + 0.05), top),
    ]);
    vec![
        story(0.0, MEZZANINE_UNDER, ground, &g, &surfaces, &patches),
        story(
            MEZZANINE_FLOOR,
            HALL_CEILING,
            upper,
            &u,
            &surfaces,
            &patches,
        ),
    ]
}
