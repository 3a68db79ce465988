//! The pipeline's result: a floor plan per story, in the local frame of the cloud.

use serde::Serialize;

use crate::geom::P2;

/// A polygon with holes. Rings are open (the first point is not repeated); exteriors are CCW and
/// holes CW. Writers close them.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Polygon {
    /// The outer ring, local coordinates.
    pub exterior: Vec<P2>,
    /// The rings of the holes.
    pub holes: Vec<Vec<P2>>,
}

/// The geometric model of a wall piece.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "model", rename_all = "lowercase")]
pub enum WallModel {
    /// A straight wall.
    Line,
    /// A circular arc wall, with its centre (local coordinates) and radius in metres.
    Arc {
        /// The centre, local coordinates.
        center: P2,
        /// The radius, metres.
        radius: f64,
    },
}

/// One fitted wall piece on a story's boundary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Wall {
    /// Its model: a line or an arc.
    pub model: WallModel,
    /// The piece as a polyline on the boundary; arcs are densified (1 cm chord error).
    pub points: Vec<P2>,
    /// Inlier samples supporting the model.
    pub support: usize,
}

impl Wall {
    /// Length of the polyline, metres.
    pub fn length(&self) -> f64 {
        self.points
            .windows(2)
            .map(|w| crate::geom::dist(w[0], w[1]))
            .sum()
    }
}

/// One story's plan.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct StoryPlan {
    /// The story's index, from the lowest up.
    pub level: usize,
    /// Local-frame heights (add `FloorPlan::origin[2]` for world heights).
    pub floor_z: f64,
    /// The ceiling's local height.
    pub ceiling_z: f64,
    /// The story's open floor as OGC-valid polygons, local coordinates.
    pub polygons: Vec<Polygon>,
    /// The fitted walls on the polygons' boundary.
    pub walls: Vec<Wall>,
    /// Wall sample positions (local), used by `wall_samples` output and the SVG.
    pub samples: Vec<P2>,
    /// The story's rooms, doors, windows and walls with thickness (empty when not found).
    pub spaces: Spaces,
    /// The story's points at mid-height, drawn under the plan (`underlay.png`); `None` for
    /// plans not made from points.
    #[serde(skip)]
    pub underlay: Option<crate::underlay::Underlay>,
}

/// A story divided into rooms: what facility management works with. Every position is in the
/// local frame, like the rest of the story.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Spaces {
    /// The rooms the floor divides into.
    pub rooms: Vec<Room>,
    /// Doors and lintel-less openings between rooms.
    pub doors: Vec<Door>,
    /// Windows in the story's outer walls.
    pub windows: Vec<Window>,
    /// Walls as centre lines with a thickness.
    pub walls: Vec<WallCentre>,
}

/// A region of free floor closed by walls, whose only openings to other rooms are doors or
/// openings. Corridors and halls are rooms too.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Room {
    /// Stable within a plan: `L{level}-R{n}`, numbered by position (south-west first).
    pub id: String,
    /// The room's floor, OGC-valid.
    pub polygon: Polygon,
    /// Net floor area, m².
    pub area: f64,
    /// Length of the polygon's rings, m.
    pub perimeter: f64,
    /// Local heights of the room's floor and ceiling.
    pub floor_z: f64,
    /// The ceiling's local height.
    pub ceiling_z: f64,
    /// Indices of the scanners (viewpoints) standing inside the room.
    pub scanners: Vec<usize>,
    /// Ids of the rooms joined to this one by a door or opening, sorted.
    pub neighbours: Vec<String>,
}

/// What fills a gap in a wall between two rooms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DoorKind {
    /// A gap with wall above it (a lintel).
    Door,
    /// A gap without a lintel: an archway or an open-plan join.
    Opening,
}

/// A door or opening: a segment across the wall it pierces, on the wall's centre line.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Door {
    /// `L{level}-D{n}`.
    pub id: String,
    /// Door (with a lintel) or opening.
    pub kind: DoorKind,
    /// The segment's ends, on the jambs.
    pub a: P2,
    /// The other end.
    pub b: P2,
    /// Clear width, m.
    pub width: f64,
    /// Local height of the lintel's underside, where seen.
    pub head_z: Option<f64>,
    /// Thickness of the wall it pierces, m.
    pub depth: f64,
    /// The two rooms it joins; `None` for the outside.
    pub rooms: [Option<String>; 2],
}

/// A window: a gap in a wall with wall below and above it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Window {
    /// `L{level}-W{n}`.
    pub id: String,
    /// One end, on the wall's face.
    pub a: P2,
    /// The other end.
    pub b: P2,
    /// The window's width along the wall, metres.
    pub width: f64,
    /// Local heights of the sill and the head.
    pub sill_z: f64,
    /// The head's local height.
    pub head_z: f64,
    /// The room it lights.
    pub room: Option<String>,
}

/// A wall as a straight centre line with a thickness.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WallCentre {
    /// `L{level}-C{n}` (centre line).
    pub id: String,
    /// One end of the centre line.
    pub a: P2,
    /// The other end.
    pub b: P2,
    /// m. For an exterior wall (`exterior`), only the inner face was seen and this is the
    /// assumed thickness (`rooms.exterior_thickness`).
    pub thickness: f64,
    /// Only one face was seen: the centre line is placed half the assumed thickness behind it.
    pub exterior: bool,
    /// The rooms on either side (left, right of a → b); `None` where outside or unknown.
    pub rooms: [Option<String>; 2],
}

impl StoryPlan {
    /// Open floor area: exteriors minus holes.
    pub fn area(&self) -> f64 {
        self.polygons
            .iter()
            .map(|p| {
                crate::geom::ring_signed_area(&p.exterior).abs()
                    - p.holes
                        .iter()
                        .map(|h| crate::geom::ring_signed_area(h).abs())
                        .sum::<f64>()
            })
            .sum()
    }
}

/// What was read, as reported in `floorplan.input`.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct InputSummary {
    /// Points read.
    pub points: u64,
    /// The file's format (`e57`, `las`, `ply`, ...).
    pub format: String,
    /// Scans in the input.
    pub scans: usize,
    /// Where the scanner stood: given or estimated, per scan, and how much of the plan rests
    /// on it.
    pub viewpoints: crate::viewpoints::ViewpointsReport,
}

/// A whole floor plan: every story, and how it was made.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FloorPlan {
    /// World coordinates of the local frame; writers add it back.
    pub origin: [f64; 3],
    /// The input's coordinate reference system (WKT or EPSG code), when it states one.
    pub crs: Option<String>,
    /// The georeference the caller gave ([`crate::Scan::georeference`]); it wins over `crs`.
    pub georeference: Option<crate::georef::Georeference>,
    /// What was read.
    pub input: InputSummary,
    /// Every parameter the run used, defaults and derived values included.
    pub parameters: serde_json::Value,
    /// Stage name → milliseconds, in pipeline order.
    pub timings_ms: Vec<(String, u64)>,
    /// The stories, from the lowest up.
    pub stories: Vec<StoryPlan>,
    /// Things worth telling the user (adapted thresholds, skipped stories).
    pub notes: Vec<String>,
}

/// Who placed a plan on the earth: the caller, or the scan's own CRS.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GeorefSource {
    /// [`FloorPlan::georeference`], given with the job or on the command line.
    Given,
    /// The CRS the scan declared ([`FloorPlan::crs`]).
    Scan,
}

impl FloorPlan {
    /// Where the plan lies: the caller's georeference, else the CRS the scan declared.
    pub fn placement(&self) -> Option<(crate::georef::Georeference, GeorefSource)> {
        match (&self.georeference, &self.crs) {
            (Some(g), _) => Some((g.clone(), GeorefSource::Given)),
            (None, Some(crs)) => Some((
                crate::georef::Georeference::of_crs(crs.clone()),
                GeorefSource::Scan,
            )),
            (None, None) => None,
        }
    }
}
