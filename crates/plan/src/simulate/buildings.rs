//! The synthetic buildings: their walls, door lintels, columns and furniture as ray-castable
//! surfaces, where the scanners stand, and the exact ground truth.

use std::f64::consts::{PI, TAU};

use super::rects::{group, outline, point_in_ring, Rect};
use super::truth::{densify, rotate, TruthDoor, TruthRoom, TruthStory, TruthWall, TruthWindow};
use crate::geom::{self, add, P2};
use crate::plan::Polygon;

/// Door openings are this high; the wall above them (the lintel) reaches the ceiling.
pub const DOOR_HEIGHT: f64 = 2.1;
/// Tables and desks are this high: clutter that shadows the floor but is no wall.
pub const TABLE_HEIGHT: f64 = 0.75;

/// A vertical surface: a wall face, a lintel face, a column or a table side, between two heights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surface {
    pub curve: TruthWall,
    /// Absolute (building-frame) bottom and top heights.
    pub z: [f64; 2],
}

/// A flat convex quadrilateral: a table top, the underside of a lintel, a partial floor or
/// ceiling, or a roof plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Patch {
    /// Corners in order (either winding), as seen from above.
    pub corners: [P2; 4],
    /// Height at the first corner.
    pub z: f64,
    /// Rise per metre in x and y: zero for horizontal patches, the pitch of a roof plane.
    pub slope: P2,
}

impl Patch {
    pub(super) fn from_rect(r: Rect, z: f64) -> Patch {
        Patch {
            corners: [[r.x0, r.y0], [r.x1, r.y0], [r.x1, r.y1], [r.x0, r.y1]],
            z,
            slope: [0.0, 0.0],
        }
    }

    /// The patch's height over `p` (on its plane).
    pub fn z_at(&self, p: P2) -> f64 {
        let c = self.corners[0];
        self.z + self.slope[0] * (p[0] - c[0]) + self.slope[1] * (p[1] - c[1])
    }

    /// True when `p` is inside the quadrilateral.
    pub fn contains(&self, p: P2) -> bool {
        let c = &self.corners;
        let side = |a: P2, b: P2| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        let s: [f64; 4] = std::array::from_fn(|k| side(c[k], c[(k + 1) % 4]));
        s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0)
    }
}

/// One story of a building: what rays can hit, where scanners go, and the truth.
#[derive(Debug, Clone, PartialEq)]
pub struct StoryModel {
    pub floor_z: f64,
    pub ceiling_z: f64,
    /// Rays stop at the planes `floor_z` and `ceiling_z`, everywhere. False for buildings whose
    /// levels see into each other (galleries, double-height rooms, roofs): their floors and
    /// ceilings are patches, and every story holds the whole building's surfaces.
    pub slabs: bool,
    /// What a capture aimed at the ceiling records; `None` records every hit.
    pub capture: Option<super::phone::Capture>,
    pub surfaces: Vec<Surface>,
    pub patches: Vec<Patch>,
    /// Static scanner stations (x, y); the scanner head stands 1.5 m above the floor.
    pub stations: Vec<P2>,
    /// The mobile scanner's route, through door openings, starting and ending at the stairs.
    pub route: Vec<P2>,
    pub truth: TruthStory,
}

/// A building in its own frame (metres, z up).
#[derive(Debug, Clone, PartialEq)]
pub struct Building {
    /// The building's name, as the simulator's list gives it.
    pub name: String,
    /// Its stories, from the lowest up.
    pub stories: Vec<StoryModel>,
}

/// The buildings the simulator knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BuildingKind {
    /// One 6 m × 5 m room, one story.
    SquareRoom,
    /// Three 3 m stories of a 30 m × 20 m office: rooms, a corridor looping around a core and
    /// a meeting room, doors, a square and a round column, tables, and a window (1.2 m, sill
    /// 0.9 m, head 2.1 m) in each office's outer wall.
    Office3Story,
    /// A lobby: a rectangle closed by a half-circle wall of radius 10 m, with columns.
    CurvedLobby,
    /// Two rooms in an L, rotated 27° off the axes, with three windows of different sizes.
    RotatedL,
    /// A house with a pitched roof: a ground floor whose living room is open to the roof, and
    /// an attic (knee walls 1.2 m, sloped ceiling) with a gallery over the living room and a
    /// station on it 4.1 m up.
    AtticHouse,
    /// A 6 m high hall with a mezzanine 3 m up along one side, over two rooms.
    MezzanineHall,
    /// Two stories of about 30 rooms each (2.9 m wide, 10 cm partitions) on a corridor, one
    /// station a room; meant to be scanned sparsely (about 15,000 points a station).
    DenseOffice,
    /// [`BuildingKind::DenseOffice`], its cloud reduced to the centres of occupied 8 cm voxels.
    DenseOfficeVoxels,
    /// An L-shaped room captured as a phone held up to its ceiling captures it: no floor, walls
    /// seen down to 1.5-3.3 m, the ceiling only near the phone's path, hanging lights.
    CeilingOnly,
    /// Rooms divided by 10 cm partitions, 1.2 m × 1.5 m closets, a bathroom and a stub wall.
    Partitions,
}

impl BuildingKind {
    /// Every building, by its command-line name.
    pub const ALL: [(&'static str, BuildingKind); 10] = [
        ("square_room", BuildingKind::SquareRoom),
        ("office_3story", BuildingKind::Office3Story),
        ("curved_lobby", BuildingKind::CurvedLobby),
        ("rotated_l", BuildingKind::RotatedL),
        ("attic_house", BuildingKind::AtticHouse),
        ("mezzanine_hall", BuildingKind::MezzanineHall),
        ("dense_office", BuildingKind::DenseOffice),
        ("dense_office_voxels", BuildingKind::DenseOfficeVoxels),
        ("ceiling_only", BuildingKind::CeilingOnly),
        ("partitions", BuildingKind::Partitions),
    ];

    /// The voxel size the building's cloud is reduced to, when it is a voxelised class.
    pub fn voxel(self) -> Option<f64> {
        match self {
            BuildingKind::DenseOfficeVoxels => Some(0.08),
            _ => None,
        }
    }

    /// The building's name, as `asbuilt simulate --building` takes it.
    pub fn name(self) -> &'static str {
        BuildingKind::ALL
            .iter()
            .find(|(_, k)| *k == self)
            .map(|(n, _)| *n)
            .unwrap_or("?")
    }

    /// Looks a building up by name.
    pub fn from_name(name: &str) -> Option<BuildingKind> {
        BuildingKind::ALL
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, k)| *k)
    }

    /// Builds the building's geometry and ground truth.
    pub fn build(self) -> Building {
        let stories = match self {
            BuildingKind::SquareRoom => vec![square_room()],
            BuildingKind::Office3Story => (0..3).map(office_story).collect(),
            BuildingKind::CurvedLobby => vec![curved_lobby()],
            BuildingKind::RotatedL => vec![rotated_l()],
            BuildingKind::AtticHouse => super::multilevel::attic_house(),
            BuildingKind::MezzanineHall => super::multilevel::mezzanine_hall(),
            BuildingKind::DenseOffice | BuildingKind::DenseOfficeVoxels => {
                (0..2).map(super::rooms::dense_office_story).collect()
            }
            BuildingKind::CeilingOnly => vec![super::rooms::ceiling_only_story()],
            BuildingKind::Partitions => vec![super::rooms::partitions_story()],
        };
        let mut stories = stories;
        for (level, s) in stories.iter_mut().enumerate() {
            s.truth.level = level;
        }
        Building {
            name: self.name().into(),
            stories,
        }
    }
}

/// A story described with rectangles, before it becomes surfaces.
#[derive(Default)]
pub(super) struct RectStory {
    pub floor_z: f64,
    pub ceiling_z: f64,
    pub open: Vec<Rect>,
    pub doors: Vec<Rect>,
    pub solid: Vec<Rect>,
    pub round_columns: Vec<(P2, f64)>,
    pub tables: Vec<Rect>,
    pub stations: Vec<P2>,
    pub route: Vec<P2>,
    /// Windows in the outer walls.
    pub windows: Vec<WindowSpec>,
}

/// A window as a story describes it: its jambs on an outer wall's inner face, its sill and
/// head above the floor, and the depth of its reveal (the wall's thickness).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct WindowSpec {
    pub a: P2,
    pub b: P2,
    pub sill: f64,
    pub head: f64,
    pub depth: f64,
}

/// A level's open floor and walls, and what rays can hit there.
pub(super) struct LevelParts {
    pub polygons: Vec<Polygon>,
    pub walls: Vec<TruthWall>,
    pub rooms: Vec<TruthRoom>,
    pub doors: Vec<TruthDoor>,
    pub windows: Vec<TruthWindow>,
    pub surfaces: Vec<Surface>,
    pub patches: Vec<Patch>,
}

impl RectStory {
    /// The open floor, its walls as surfaces from the floor to `top`, door lintels from door
    /// height to `top`, and the tables.
    pub(super) fn parts(&self, top: f64) -> LevelParts {
        let mut open = self.open.clone();
        open.extend(&self.doors);
        let mut polygons = outline(&open, &self.solid);
        let mut walls: Vec<TruthWall> = polygons.iter().flat_map(polygon_walls).collect();
        // The rooms are the open floor without the door openings.
        let mut rooms = outline(&self.open, &self.solid);
        for &(center, radius) in &self.round_columns {
            add_round_column(&mut polygons, &mut walls, center, radius);
            add_round_column(&mut rooms, &mut Vec::new(), center, radius);
        }
        let rooms = rooms.into_iter().map(TruthRoom::of).collect();
        let doors = self.doors.iter().map(|d| door_of(*d)).collect();
        let (f, c) = (self.floor_z, top);
        let mut surfaces: Vec<Surface> = walls
            .iter()
            .map(|&curve| Surface { curve, z: [f, c] })
            .collect();
        let mut patches = Vec::new();
        for d in &self.doors {
            // The lintel's two faces run along the door's long side, on the wall faces.
            let faces = if d.x1 - d.x0 > d.y1 - d.y0 {
                [[[d.x0, d.y0], [d.x1, d.y0]], [[d.x0, d.y1], [d.x1, d.y1]]]
            } else {
                [[[d.x0, d.y0], [d.x0, d.y1]], [[d.x1, d.y0], [d.x1, d.y1]]]
            };
            for [a, b] in faces {
                surfaces.push(Surface {
                    curve: TruthWall::Line { a, b },
                    z: [f + DOOR_HEIGHT, c],
                });
            }
            patches.push(Patch::from_rect(*d, f + DOOR_HEIGHT));
        }
        for t in &self.tables {
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
        let windows = self
            .windows
            .iter()
            .map(|w| self.cut_window(w, &mut surfaces, &mut patches))
            .collect();
        LevelParts {
            polygons,
            walls,
            rooms,
            doors,
            windows,
            surfaces,
            patches,
        }
    }

    /// Cuts window `w` out of the wall surface it lies on: wall below the sill and above the
    /// head, jambs, a sill and a head as deep as the wall, and nothing beyond. Panics when `w`
    /// lies on no straight wall face or not beside open floor (a bug in a building).
    fn cut_window(
        &self,
        w: &WindowSpec,
        surfaces: &mut Vec<Surface>,
        patches: &mut Vec<Patch>,
    ) -> TruthWindow {
        let (f, sill, head) = (self.floor_z, self.floor_z + w.sill, self.floor_z + w.head);
        let on = |a: P2, b: P2, p: P2| geom::point_segment_distance(p, a, b) < 1e-9;
        let k = surfaces
            .iter()
            .position(|s| matches!(s.curve, TruthWall::Line { a, b } if on(a, b, w.a) && on(a, b, w.b) && s.z[0] <= f))
            .expect("a window lies on a wall face");
        let Surface { curve, z } = surfaces.remove(k);
        let TruthWall::Line { a, b } = curve else {
            unreachable!()
        };
        // The wall's ends keep their full height; the window's stretch keeps what is below
        // the sill and above the head.
        let (wa, wb) = if geom::dist(a, w.a) < geom::dist(a, w.b) {
            (w.a, w.b)
        } else {
            (w.b, w.a)
        };
        let line = |a, b| TruthWall::Line { a, b };
        surfaces.push(Surface {
            curve: line(a, wa),
            z,
        });
        surfaces.push(Surface {
            curve: line(wb, b),
            z,
        });
        surfaces.push(Surface {
            curve: line(wa, wb),
            z: [z[0], sill],
        });
        surfaces.push(Surface {
            curve: line(wa, wb),
            z: [head, z[1]],
        });
        let mid = geom::scale(geom::add(w.a, w.b), 0.5);
        let along = geom::scale(geom::sub(w.b, w.a), 1.0 / geom::dist(w.a, w.b));
        let left = [-along[1], along[0]];
        let open = |p: P2| self.open.iter().chain(&self.doors).any(|r| r.contains(p));
        let outward = if open(geom::add(mid, geom::scale(left, 0.01))) {
            geom::scale(left, -1.0)
        } else {
            left
        };
        assert!(
            open(geom::sub(mid, geom::scale(outward, 0.01))),
            "a window faces open floor"
        );
        let d = geom::scale(outward, w.depth);
        let (oa, ob) = (geom::add(w.a, d), geom::add(w.b, d));
        surfaces.push(Surface {
            curve: line(w.a, oa),
            z: [sill, head],
        });
        surfaces.push(Surface {
            curve: line(w.b, ob),
            z: [sill, head],
        });
        for z in [sill, head] {
            patches.push(Patch {
                corners: [w.a, w.b, ob, oa],
                z,
                slope: [0.0, 0.0],
            });
        }
        TruthWindow {
            a: w.a,
            b: w.b,
            width: geom::dist(w.a, w.b),
            sill_z: sill,
            head_z: head,
            depth: w.depth,
            outward,
        }
    }

    pub(super) fn into_model(self) -> StoryModel {
        let (f, c) = (self.floor_z, self.ceiling_z);
        let parts = self.parts(c);
        StoryModel {
            floor_z: f,
            ceiling_z: c,
            slabs: true,
            capture: None,
            surfaces: parts.surfaces,
            patches: parts.patches,
            stations: self.stations,
            route: self.route,
            truth: TruthStory {
                level: 0,
                floor_z: f,
                ceiling_z: c,
                polygons: parts.polygons,
                walls: parts.walls,
                rooms: parts.rooms,
                doors: parts.doors,
                windows: parts.windows,
            },
        }
    }
}

/// A door rectangle as the truth's door: its long side is the width, its short side the
/// wall's thickness.
fn door_of(d: Rect) -> TruthDoor {
    let (w, h) = (d.x1 - d.x0, d.y1 - d.y0);
    let (cx, cy) = ((d.x0 + d.x1) / 2.0, (d.y0 + d.y1) / 2.0);
    let (a, b) = if w >= h {
        ([d.x0, cy], [d.x1, cy])
    } else {
        ([cx, d.y0], [cx, d.y1])
    };
    TruthDoor {
        a,
        b,
        width: w.max(h),
        depth: w.min(h),
    }
}

/// Every ring edge of a polygon as a straight wall.
fn polygon_walls(p: &Polygon) -> Vec<TruthWall> {
    std::iter::once(&p.exterior)
        .chain(&p.holes)
        .flat_map(|ring| {
            (0..ring.len()).map(move |k| TruthWall::Line {
                a: ring[k],
                b: ring[(k + 1) % ring.len()],
            })
        })
        .collect()
}

/// Cuts a round column out of the polygon that contains it.
fn add_round_column(polygons: &mut [Polygon], walls: &mut Vec<TruthWall>, center: P2, radius: f64) {
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

/// Rotates a story by `angle` about the origin, then moves it by `d`.
pub(super) fn transform(mut s: StoryModel, angle: f64, d: P2) -> StoryModel {
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
    let moved = |p: &mut Polygon| {
        p.exterior = p.exterior.iter().map(|&q| m(q)).collect();
        for h in &mut p.holes {
            *h = h.iter().map(|&q| m(q)).collect();
        }
    };
    s.truth.polygons.iter_mut().for_each(moved);
    s.truth.rooms.iter_mut().for_each(|r| moved(&mut r.polygon));
    for door in &mut s.truth.doors {
        *door = door.transformed(angle, d);
    }
    for w in &mut s.truth.windows {
        *w = w.transformed(angle, d);
    }
    s
}

fn square_room() -> StoryModel {
    RectStory {
        floor_z: 0.0,
        ceiling_z: 2.6,
        open: vec![Rect::new(0.0, 0.0, 6.0, 5.0)],
        stations: vec![[2.6, 2.3]],
        route: vec![[1.5, 1.5], [4.5, 1.5], [4.5, 3.5], [1.5, 3.5], [1.5, 1.5]],
        ..Default::default()
    }
    .into_model()
}

/// One story of the office. Levels differ in how the south and north wings are partitioned.
/// Scanner stations for an office room from `x0` to `x1`: one beside the centre (offset by
/// `dx` so the door is not on its axis), or two at the quarters of a room wider than 10 m.
fn room_stations(x0: f64, x1: f64, dx: f64, y: f64) -> Vec<P2> {
    let w = x1 - x0;
    if w > 10.0 {
        vec![[x0 + 0.27 * w, y], [x0 + 0.73 * w, y]]
    } else {
        vec![[(x0 + x1) / 2.0 + dx, y]]
    }
}

fn office_story(level: usize) -> StoryModel {
    const T: f64 = 0.2;
    let floor_z = 3.0 * level as f64;
    let south: &[f64] = if level == 1 { &[15.0] } else { &[10.0, 20.0] };
    let north: &[f64] = if level == 2 { &[10.0, 20.0] } else { &[15.0] };
    let mut s = RectStory {
        floor_z,
        ceiling_z: floor_z + 2.7,
        ..Default::default()
    };
    // The corridor loop around the core, and the meeting room inside it.
    s.open.extend([
        Rect::new(0.0, 6.2, 30.0, 8.2),
        Rect::new(0.0, 11.8, 30.0, 13.8),
        Rect::new(0.0, 6.2, 2.0, 13.8),
        Rect::new(28.0, 6.2, 30.0, 13.8),
        Rect::new(8.0, 8.4, 22.0, 11.6),
    ]);
    s.doors.push(Rect::new(14.55, 11.6, 15.45, 11.8));
    // Stations every 5 m along the long corridors and two in the meeting room, as a surveyor
    // would place them: a wall seen only at a grazing angle from 10 m away is not captured
    // (§3.1), and the plan cannot be better than the scan.
    for x in [5.0, 10.0, 15.0, 20.0, 25.0] {
        s.stations.extend([[x, 7.2], [x + 0.5, 12.8]]);
    }
    s.stations
        .extend([[1.0, 10.0], [29.0, 10.0], [11.5, 10.0], [18.5, 10.0]]);
    let wing = |parts: &[f64]| {
        let mut edges = vec![0.0];
        edges.extend(parts.iter().flat_map(|&x| [x - T / 2.0, x + T / 2.0]));
        edges.push(30.0);
        edges
            .chunks(2)
            .map(|c| (c[0], c[1]))
            .collect::<Vec<(f64, f64)>>()
    };
    let mut south_stops = Vec::new();
    for (k, (x0, x1)) in wing(south).into_iter().enumerate() {
        let cx = (x0 + x1) / 2.0;
        s.open.push(Rect::new(x0, 0.0, x1, 6.0));
        s.doors.push(Rect::new(cx - 0.45, 6.0, cx + 0.45, 6.2));
        s.stations.extend(room_stations(x0, x1, -1.2, 3.4));
        s.tables.push(Rect::new(cx, 2.65, cx + 1.2, 3.35));
        s.windows.push(office_window(cx, 0.0));
        if k == 0 {
            // A square column, seen from a second station as well.
            s.solid.push(Rect::new(cx + 2.3, 1.3, cx + 2.7, 1.7));
            s.stations.push([cx + 2.5, 4.4]);
        }
        south_stops.push((cx, 4.2));
    }
    let mut north_stops = vec![(15.0, 10.0)];
    let north_rooms = wing(north);
    let last = north_rooms.len() - 1;
    for (k, (x0, x1)) in north_rooms.into_iter().enumerate() {
        let cx = (x0 + x1) / 2.0;
        s.open.push(Rect::new(x0, 14.0, x1, 20.0));
        s.doors.push(Rect::new(cx - 0.45, 13.8, cx + 0.45, 14.0));
        s.stations.extend(room_stations(x0, x1, 1.2, 16.6));
        s.tables.push(Rect::new(cx - 1.2, 16.65, cx, 17.35));
        s.windows.push(office_window(cx, 20.0));
        if k == last {
            s.round_columns.push(([cx + 3.0, 18.0], 0.25));
            s.stations.push([cx + 3.0, 15.2]);
        }
        north_stops.push((cx, 15.8));
    }
    // The route: down the west corridor, east along the south corridor into each room, back
    // west along the north corridor into each room, and up to the stairs again.
    let mut route = vec![[1.0, 10.0], [1.0, 7.2]];
    for (x, y) in south_stops {
        route.extend([[x, 7.2], [x, y], [x, 7.2]]);
    }
    route.extend([[29.0, 7.2], [29.0, 12.8]]);
    north_stops.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (x, y) in north_stops {
        route.extend([[x, 12.8], [x, y], [x, 12.8]]);
    }
    route.extend([[1.0, 12.8], [1.0, 10.0]]);
    s.route = route;
    s.into_model()
}

/// An office room's window: 1.2 m wide at `cx` in the outer wall at `y`, sill 0.9 m, head
/// 2.1 m, in a 30 cm wall.
fn office_window(cx: f64, y: f64) -> WindowSpec {
    WindowSpec {
        a: [cx - 0.6, y],
        b: [cx + 0.6, y],
        sill: 0.9,
        head: 2.1,
        depth: 0.3,
    }
}

fn curved_lobby() -> StoryModel {
    let (f, c) = (0.0, 4.0);
    let arc = TruthWall::Arc {
        center: [0.0, 0.0],
        radius: 10.0,
        start: 0.0,
        sweep: PI,
    };
    let walls = vec![
        TruthWall::Line {
            a: [-10.0, -6.0],
            b: [10.0, -6.0],
        },
        TruthWall::Line {
            a: [10.0, -6.0],
            b: [10.0, 0.0],
        },
        arc,
        TruthWall::Line {
            a: [-10.0, 0.0],
            b: [-10.0, -6.0],
        },
    ];
    let mut exterior = vec![[-10.0, -6.0], [10.0, -6.0]];
    exterior.extend(densify(&arc, 0.001));
    let square = Rect::new(-0.3, -3.3, 0.3, -2.7);
    let mut polygons = group(vec![exterior]);
    let mut all_walls = walls;
    let mut hole: Vec<P2> = vec![
        [square.x0, square.y0],
        [square.x0, square.y1],
        [square.x1, square.y1],
        [square.x1, square.y0],
    ];
    all_walls.extend((0..4).map(|k| TruthWall::Line {
        a: hole[k],
        b: hole[(k + 1) % 4],
    }));
    polygons[0].holes.push(std::mem::take(&mut hole));
    for center in [[-4.0, 3.0], [4.0, 3.0], [0.0, 7.0]] {
        add_round_column(&mut polygons, &mut all_walls, center, 0.3);
    }
    let surfaces = all_walls
        .iter()
        .map(|&curve| Surface { curve, z: [f, c] })
        .collect();
    StoryModel {
        floor_z: f,
        ceiling_z: c,
        slabs: true,
        capture: None,
        surfaces,
        patches: Vec::new(),
        stations: vec![
            [-5.0, -3.0],
            [5.0, -3.0],
            [0.0, 3.5],
            [-5.0, 6.0],
            [5.0, 6.0],
        ],
        // South of the square column, not through it.
        route: vec![
            [-7.0, -4.5],
            [7.0, -4.5],
            [7.0, 4.0],
            [0.0, 8.5],
            [-7.0, 4.0],
            [-7.0, -4.5],
        ],
        truth: TruthStory {
            level: 0,
            floor_z: f,
            ceiling_z: c,
            rooms: polygons.iter().cloned().map(TruthRoom::of).collect(),
            doors: Vec::new(),
            windows: Vec::new(),
            polygons,
            walls: all_walls,
        },
    }
}

/// The L's rotation off the axes, radians (27°).
pub const ROTATED_L_ANGLE: f64 = 27.0 * PI / 180.0;

fn rotated_l() -> StoryModel {
    let s = RectStory {
        floor_z: 0.0,
        ceiling_z: 2.8,
        open: vec![
            Rect::new(0.0, 0.0, 12.0, 5.0),
            Rect::new(0.0, 5.2, 5.0, 10.0),
        ],
        doors: vec![Rect::new(2.0, 5.0, 2.9, 5.2)],
        tables: vec![Rect::new(7.5, 1.0, 9.0, 1.8)],
        stations: vec![[9.5, 3.0], [3.5, 2.5], [2.5, 7.6]],
        // Three windows of different sizes, in three of the outer walls.
        windows: vec![
            WindowSpec {
                a: [5.0, 0.0],
                b: [6.5, 0.0],
                sill: 0.9,
                head: 2.2,
                depth: 0.3,
            },
            WindowSpec {
                a: [12.0, 1.5],
                b: [12.0, 2.7],
                sill: 1.0,
                head: 2.2,
                depth: 0.25,
            },
            WindowSpec {
                a: [2.0, 10.0],
                b: [3.0, 10.0],
                sill: 0.8,
                head: 2.0,
                depth: 0.3,
            },
        ],
        route: vec![
            [10.5, 2.5],
            [2.45, 2.5],
            [2.45, 8.5],
            [2.45, 2.5],
            [10.5, 2.5],
        ],
        ..Default::default()
    };
    transform(s.into_model(), ROTATED_L_ANGLE, [3.0, -2.0])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::ring_signed_area;

    fn area(s: &TruthStory) -> f64 {
        s.polygons
            .iter()
            .map(|p| {
                ring_signed_area(&p.exterior)
                    + p.holes.iter().map(|h| ring_signed_area(h)).sum::<f64>()
            })
            .sum()
    }

    fn wall_length(s: &TruthStory) -> f64 {
        s.walls.iter().map(TruthWall::length).sum()
    }

    #[test]
    fn square_room_truth() {
        let b = BuildingKind::SquareRoom.build();
        assert_eq!(b.stories.len(), 1);
        assert_eq!(area(&b.stories[0].truth), 30.0);
        assert_eq!(wall_length(&b.stories[0].truth), 22.0);
    }

    #[test]
    fn office_has_three_connected_stories() {
        let b = BuildingKind::Office3Story.build();
        assert_eq!(b.stories.len(), 3);
        for s in &b.stories {
            // Rooms, corridors and the meeting room are joined through doors into one polygon;
            // the core (with the meeting room cut in) and the columns are holes.
            assert_eq!(s.truth.polygons.len(), 1, "level {}", s.truth.level);
            assert_eq!(s.truth.polygons[0].holes.len(), 3);
            assert!((s.ceiling_z - s.floor_z - 2.7).abs() < 1e-12);
            for st in &s.stations {
                assert!(point_in_ring(*st, &s.truth.polygons[0].exterior));
            }
        }
    }

    #[test]
    fn every_route_and_station_keeps_clear_of_walls_and_columns() {
        // A scanner cannot walk through a column: every point of every route, and every
        // station, lies in the open floor at least 20 cm from any wall.
        for (name, kind) in BuildingKind::ALL {
            for s in &kind.build().stories {
                let mut points = s.stations.clone();
                for w in s.route.windows(2) {
                    let n = (crate::geom::dist(w[0], w[1]) / 0.05).ceil() as usize;
                    points.extend((0..=n).map(|k| {
                        let f = k as f64 / n.max(1) as f64;
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
                    assert!(
                        open,
                        "{name} level {}: {p:?} is not open floor",
                        s.truth.level
                    );
                    let clear = s.truth.walls.iter().all(|w| w.distance(p) >= 0.2);
                    assert!(
                        clear,
                        "{name} level {}: {p:?} touches a wall",
                        s.truth.level
                    );
                }
            }
        }
    }

    #[test]
    fn the_house_has_an_attic_over_its_ground_floor_and_a_gallery_station() {
        let b = BuildingKind::AtticHouse.build();
        assert_eq!(b.stories.len(), 2);
        let (ground, attic) = (&b.stories[0], &b.stories[1]);
        // Living room 4 × 8, kitchen 5.85 × 3.9, bedroom 3.75 × 4, bathroom 2 × 4, four doors.
        let want = 32.0 + 5.85 * 3.9 + 3.75 * 4.0 + 8.0 + 2.0 * 0.15 * 0.9 + 0.09 + 0.08;
        assert!(
            (area(&ground.truth) - want).abs() < 1e-9,
            "{}",
            area(&ground.truth)
        );
        // The attic's plan runs over the living room's void: 10 × 8 less the partition.
        assert!((area(&attic.truth) - (80.0 - 0.8 + 0.09)).abs() < 1e-9);
        assert!(!ground.slabs && !attic.slabs);
        // Both stories see the whole house: a ray from the gallery station down over the
        // railing reaches the living room's floor, one up reaches the roof.
        let gallery = [4.45, 4.0, attic.floor_z + crate::simulate::STATION_HEIGHT];
        assert_eq!(attic.stations[0], [gallery[0], gallery[1]]);
        assert!((gallery[2] - 4.1).abs() < 1e-12);
        let v = [0.5 - gallery[0], 2.0 - gallery[1], -gallery[2]];
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let down = v.map(|c| c / n);
        let t = crate::simulate::scanner::cast(attic, gallery, down).unwrap();
        assert!(
            (t - n).abs() < 1e-9,
            "over the railing to the living room's floor: {t}"
        );
        let up = crate::simulate::scanner::cast(attic, gallery, [0.0, 0.0, 1.0]).unwrap();
        assert!((gallery[2] + up - 6.0).abs() < 1e-9, "the ridge over y = 4");
    }

    #[test]
    fn the_mezzanine_level_spans_the_hall() {
        let b = BuildingKind::MezzanineHall.build();
        assert_eq!(b.stories.len(), 2);
        assert_eq!(b.stories[1].floor_z, 3.0);
        // 20 × 12 less the column, the partition and its door opening.
        let want = 240.0 - 0.16 - 0.4 + 0.09;
        assert!((area(&b.stories[1].truth) - want).abs() < 1e-9);
    }

    #[test]
    fn the_dense_office_has_about_thirty_rooms_a_story() {
        let b = BuildingKind::DenseOffice.build();
        assert_eq!(b.stories.len(), 2);
        for s in &b.stories {
            // One connected floor; each room gives a station, plus nine in the corridor.
            assert_eq!(s.truth.polygons.len(), 1);
            let rooms = s.stations.len() - 9;
            assert!((28..=30).contains(&rooms), "{rooms}");
        }
        assert_eq!(BuildingKind::DenseOfficeVoxels.voxel(), Some(0.08));
        assert_eq!(BuildingKind::DenseOffice.voxel(), None);
    }

    #[test]
    fn closets_are_1_2_by_1_5_metres() {
        let b = BuildingKind::Partitions.build();
        let s = &b.stories[0].truth;
        assert_eq!(s.polygons.len(), 1);
        // Three closets: 1.2 × 1.5 each, a 10 cm partition between each and its room.
        for (x, y) in [(0.6, 4.25), (11.7, 4.25), (2.5, 7.45)] {
            let walls: Vec<f64> = s.walls.iter().map(|w| w.distance([x, y])).collect();
            let nearest = walls.iter().copied().fold(f64::MAX, f64::min);
            assert!(
                (nearest - 0.6).abs() < 1e-9,
                "closet at {x}, {y}: {nearest}"
            );
        }
    }

    #[test]
    fn lobby_area_is_rectangle_plus_half_disc() {
        let b = BuildingKind::CurvedLobby.build();
        let want = 20.0 * 6.0 + PI * 50.0 - 0.36 - 3.0 * PI * 0.09;
        assert!(
            (area(&b.stories[0].truth) - want).abs() < 0.05,
            "{}",
            area(&b.stories[0].truth)
        );
    }

    #[test]
    fn rotation_keeps_area_and_lengths() {
        let b = BuildingKind::RotatedL.build();
        let t = &b.stories[0].truth;
        assert!((area(t) - (60.0 + 5.0 * 4.8 + 0.9 * 0.2)).abs() < 1e-9);
        let w = &t.walls[0];
        if let TruthWall::Line { a, b } = w {
            let angle = (b[1] - a[1]).atan2(b[0] - a[0]).rem_euclid(PI / 2.0);
            assert!((angle - ROTATED_L_ANGLE).abs() < 1e-9);
        }
    }
}
