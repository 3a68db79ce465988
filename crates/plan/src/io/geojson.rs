//! The floor plan as GeoJSON, exactly as `docs/contract.md` §1 says.
//!
//! Coordinates leave the local frame here: every position gets `FloorPlan::origin` added back
//! and is rounded to 0.1 mm, so georeferenced plans stay in their own (e.g. UTM) frame.

use serde_json::{json, Map, Value};

use crate::geom::{closed_ring, ring_signed_area, P2};
use crate::plan::{
    Door, DoorKind, FloorPlan, Polygon, Room, StoryPlan, Wall, WallCentre, WallModel, Window,
};

/// The `floorplan.version` this writer produces.
pub const VERSION: u32 = 1;

/// The plan as a GeoJSON `FeatureCollection` with the `floorplan` foreign member.
pub fn to_geojson(plan: &FloorPlan) -> Value {
    let emit_samples = emit_samples(plan);
    let mut features = Vec::new();
    for story in &plan.stories {
        features.push(story_feature(plan, story));
        features.extend(
            story
                .walls
                .iter()
                .filter_map(|w| wall_feature(plan, story.level, w)),
        );
        if emit_samples {
            features.push(samples_feature(plan, story));
        }
        features.extend(space_features(plan, story));
    }
    let timings: Map<String, Value> = plan
        .timings_ms
        .iter()
        .map(|(name, ms)| (name.clone(), json!(ms)))
        .collect();
    let placement = plan.placement();
    json!({
        "type": "FeatureCollection",
        "floorplan": {
            "version": VERSION,
            "units": "m",
            "crs": placement.as_ref().and_then(|(g, _)| g.source_crs()),
            "georeference": placement.map(|(g, source)| georeference(&g, source)),
            "input": {
                "points": plan.input.points,
                "format": plan.input.format,
                "scans": plan.input.scans,
                "viewpoints": viewpoints(plan),
            },
            "parameters": plan.parameters,
            "timings_ms": timings,
            "notes": plan.notes,
            "underlay": super::outputs::underlay::describe(plan),
        },
        "features": features,
    })
}

/// `floorplan.georeference`: the fields that placed the plan, and who gave them.
fn georeference(g: &crate::georef::Georeference, source: crate::plan::GeorefSource) -> Value {
    let mut v = serde_json::to_value(g).unwrap_or_else(|_| json!({}));
    v["source"] = json!(source);
    v
}

/// The GeoJSON document as compact text with a trailing newline.
pub fn to_geojson_string(plan: &FloorPlan) -> String {
    let mut text = to_geojson(plan).to_string();
    text.push('\n');
    text
}

/// Whether the run asked for `wall_samples` features (`Params::emit_samples`).
pub(crate) fn emit_samples(plan: &FloorPlan) -> bool {
    plan.parameters
        .get("emit_samples")
        .and_then(Value::as_bool)
        .unwrap_or(false)
}

/// `floorplan.input.viewpoints`: where the scanners stood (given or estimated, world frame),
/// per scan with its residual, and how much of the plan rests on them.
fn viewpoints(plan: &FloorPlan) -> Value {
    let v = &plan.input.viewpoints;
    let o = plan.origin;
    let world = |p: [f64; 3]| [0, 1, 2].map(|k| round4(p[k] + o[k]));
    let scans: Vec<Value> = v
        .scans
        .iter()
        .map(|s| {
            json!({
                "index": s.index,
                "source": if s.estimated { "estimated" } else { "given" },
                "position": s.position.map(world),
                "residual_m": s.residual.map(round4),
                "support": s.support.map(round4),
                "points": s.points,
            })
        })
        .collect();
    let path = v.path.as_ref().map(|p| {
        json!({
            "source": if p.estimated { "estimated" } else { "given" },
            "samples": p.samples,
            "windows": p.windows,
            "located": p.located,
            "residual_m": p.residual.map(round4),
            "length_m": p.length.map(round4),
            "positions": p.positions.iter().map(|&q| world(q)).collect::<Vec<_>>(),
        })
    });
    let open_space: Vec<Value> = v
        .open_space
        .iter()
        .map(|s| {
            json!({
                "level": s.level,
                "positions": s.viewpoints.iter().map(|p| position(plan, *p)).collect::<Vec<_>>(),
                "samples_seen": s.samples_seen,
                "samples": s.samples,
            })
        })
        .collect();
    json!({
        "source": v.source,
        "scans": scans,
        "path": path,
        "open_space": open_space,
        "rests_on": v.rests_on.map(round4),
    })
}

/// Rounds to 0.1 mm: finer than any scanner, coarse enough to keep files small.
fn round4(v: f64) -> f64 {
    (v * 1.0e4).round() / 1.0e4
}

fn position(plan: &FloorPlan, p: P2) -> [f64; 2] {
    [round4(p[0] + plan.origin[0]), round4(p[1] + plan.origin[1])]
}

fn feature(geometry: Value, properties: Value) -> Value {
    json!({"type": "Feature", "geometry": geometry, "properties": properties})
}

/// One ring in world coordinates with the wanted winding (CCW when `ccw`), closed by repeating
/// its first position. `None` when fewer than three distinct positions remain after rounding.
fn ring(plan: &FloorPlan, points: &[P2], ccw: bool) -> Option<Vec<[f64; 2]>> {
    // Winding is judged on local coordinates, where the arithmetic is exact enough.
    let reverse = (ring_signed_area(points) > 0.0) != ccw;
    let ordered: Box<dyn Iterator<Item = &P2>> = if reverse {
        Box::new(points.iter().rev())
    } else {
        Box::new(points.iter())
    };
    // Rounding can join neighbours, and an input given closed ends on its first position.
    closed_ring(ordered.map(|&p| position(plan, p)))
}

/// A polygon's rings (exterior first), or `None` when its exterior is degenerate.
fn polygon_rings(plan: &FloorPlan, polygon: &Polygon) -> Option<Vec<Vec<[f64; 2]>>> {
    let mut rings = vec![ring(plan, &polygon.exterior, true)?];
    rings.extend(polygon.holes.iter().filter_map(|h| ring(plan, h, false)));
    Some(rings)
}

fn story_feature(plan: &FloorPlan, story: &StoryPlan) -> Value {
    let polygons: Vec<_> = story
        .polygons
        .iter()
        .filter_map(|p| polygon_rings(plan, p))
        .collect();
    let geometry = if polygons.len() == 1 {
        json!({"type": "Polygon", "coordinates": polygons[0]})
    } else {
        json!({"type": "MultiPolygon", "coordinates": polygons})
    };
    feature(
        geometry,
        json!({
            "kind": "story",
            "level": story.level,
            "floor_z": round4(story.floor_z + plan.origin[2]),
            "ceiling_z": round4(story.ceiling_z + plan.origin[2]),
            "area_m2": round4(story.area()),
            "samples": story.samples.len(),
        }),
    )
}

/// A wall as a LineString; `None` when it has fewer than two distinct positions.
fn wall_feature(plan: &FloorPlan, level: usize, wall: &Wall) -> Option<Value> {
    let mut line: Vec<[f64; 2]> = Vec::with_capacity(wall.points.len());
    for &p in &wall.points {
        let q = position(plan, p);
        if line.last() != Some(&q) {
            line.push(q);
        }
    }
    if line.len() < 2 {
        return None;
    }
    let mut properties = json!({
        "kind": "wall",
        "level": level,
        "model": "line",
        "length_m": round4(wall.length()),
        "support": wall.support,
    });
    if let WallModel::Arc { center, radius } = wall.model {
        properties["model"] = json!("arc");
        properties["center"] = json!(position(plan, center));
        properties["radius"] = json!(round4(radius));
    }
    Some(feature(
        json!({"type": "LineString", "coordinates": line}),
        properties,
    ))
}

/// A story's rooms, doors and openings, windows and centre-line walls, in that order.
fn space_features<'a>(
    plan: &'a FloorPlan,
    story: &'a StoryPlan,
) -> impl Iterator<Item = Value> + 'a {
    let s = &story.spaces;
    let level = story.level;
    let rooms = s
        .rooms
        .iter()
        .filter_map(move |r| room_feature(plan, level, r));
    let doors = s
        .doors
        .iter()
        .filter_map(move |d| door_feature(plan, level, d));
    let windows = s
        .windows
        .iter()
        .filter_map(move |w| window_feature(plan, level, w));
    let walls = s
        .walls
        .iter()
        .filter_map(move |w| centre_feature(plan, level, w));
    rooms.chain(doors).chain(windows).chain(walls)
}

/// A world height, rounded.
fn height(plan: &FloorPlan, z: f64) -> f64 {
    round4(z + plan.origin[2])
}

/// A room as a Polygon; `None` when its exterior is degenerate.
fn room_feature(plan: &FloorPlan, level: usize, room: &Room) -> Option<Value> {
    let rings = polygon_rings(plan, &room.polygon)?;
    Some(feature(
        json!({"type": "Polygon", "coordinates": rings}),
        json!({
            "kind": "room",
            "level": level,
            "id": room.id,
            "area_m2": round4(room.area),
            "perimeter_m": round4(room.perimeter),
            "floor_z": height(plan, room.floor_z),
            "ceiling_z": height(plan, room.ceiling_z),
            "height_m": round4(room.ceiling_z - room.floor_z),
            "scanners": room.scanners,
            "neighbours": room.neighbours,
        }),
    ))
}

/// A segment as a LineString; `None` when its ends meet after rounding.
fn segment(plan: &FloorPlan, a: P2, b: P2) -> Option<Value> {
    let (a, b) = (position(plan, a), position(plan, b));
    (a != b).then(|| json!({"type": "LineString", "coordinates": [a, b]}))
}

fn door_feature(plan: &FloorPlan, level: usize, door: &Door) -> Option<Value> {
    let (kind, head) = match door.kind {
        DoorKind::Door => ("door", door.head_z.map(|z| height(plan, z))),
        // An opening has no lintel, whatever was measured above it.
        DoorKind::Opening => ("opening", None),
    };
    Some(feature(
        segment(plan, door.a, door.b)?,
        json!({
            "kind": kind,
            "level": level,
            "id": door.id,
            "width_m": round4(door.width),
            "head_z": head,
            "depth_m": round4(door.depth),
            "rooms": door.rooms,
        }),
    ))
}

fn window_feature(plan: &FloorPlan, level: usize, window: &Window) -> Option<Value> {
    Some(feature(
        segment(plan, window.a, window.b)?,
        json!({
            "kind": "window",
            "level": level,
            "id": window.id,
            "width_m": round4(window.width),
            "sill_z": height(plan, window.sill_z),
            "head_z": height(plan, window.head_z),
            "room": window.room,
        }),
    ))
}

fn centre_feature(plan: &FloorPlan, level: usize, wall: &WallCentre) -> Option<Value> {
    Some(feature(
        segment(plan, wall.a, wall.b)?,
        json!({
            "kind": "wall_centerline",
            "level": level,
            "id": wall.id,
            "thickness_m": round4(wall.thickness),
            "exterior": wall.exterior,
            "rooms": wall.rooms,
        }),
    ))
}

fn samples_feature(plan: &FloorPlan, story: &StoryPlan) -> Value {
    let points: Vec<[f64; 2]> = story.samples.iter().map(|&p| position(plan, p)).collect();
    feature(
        json!({"type": "MultiPoint", "coordinates": points}),
        json!({"kind": "wall_samples", "level": story.level}),
    )
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geom::dist;
    use crate::plan::{Door, DoorKind, InputSummary, Room, Spaces, WallCentre, Window};

    pub(crate) fn square(x0: f64, y0: f64, side: f64) -> Vec<P2> {
        vec![
            [x0, y0],
            [x0 + side, y0],
            [x0 + side, y0 + side],
            [x0, y0 + side],
        ]
    }

    pub(crate) fn story(level: usize, polygons: Vec<Polygon>, walls: Vec<Wall>) -> StoryPlan {
        StoryPlan {
            level,
            floor_z: 3.0 * level as f64,
            ceiling_z: 3.0 * level as f64 + 2.5,
            polygons,
            walls,
            samples: vec![[0.5, 0.0], [1.0, 0.0], [4.0, 2.0]],
            spaces: Default::default(),
            underlay: None,
        }
    }

    /// A quarter-circle wall of radius 2 about `center`, densified, running CCW.
    pub(crate) fn arc_wall(center: P2) -> Wall {
        let points = (0..=16)
            .map(|i| {
                let a = std::f64::consts::FRAC_PI_2 * i as f64 / 16.0;
                [center[0] + 2.0 * a.cos(), center[1] + 2.0 * a.sin()]
            })
            .collect();
        Wall {
            model: WallModel::Arc {
                center,
                radius: 2.0,
            },
            points,
            support: 40,
        }
    }

    pub(crate) fn line_wall(a: P2, b: P2) -> Wall {
        Wall {
            model: WallModel::Line,
            points: vec![a, b],
            support: 12,
        }
    }

    pub(crate) fn plan(origin: [f64; 3], stories: Vec<StoryPlan>) -> FloorPlan {
        FloorPlan {
            origin,
            crs: Some("EPSG:25832".into()),
            georeference: None,
            input: InputSummary {
                points: 1234,
                format: "ply".into(),
                scans: 2,
                ..Default::default()
            },
            parameters: json!({"emit_samples": false, "samples": {"cell_size": 0.05}}),
            timings_ms: vec![
                ("read".into(), 5),
                ("stories".into(), 3),
                ("label".into(), 9),
                ("fit".into(), 1),
                ("total".into(), 18),
            ],
            stories,
            notes: vec!["a note".into()],
        }
    }

    fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<P2> {
        vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
    }

    fn room(id: &str, polygon: Polygon, z: (f64, f64), neighbours: &[&str]) -> Room {
        let rings = std::iter::once(&polygon.exterior).chain(&polygon.holes);
        let perimeter = rings
            .map(|r| {
                (0..r.len())
                    .map(|i| dist(r[i], r[(i + 1) % r.len()]))
                    .sum::<f64>()
            })
            .sum();
        Room {
            id: id.into(),
            area: ring_signed_area(&polygon.exterior).abs()
                - polygon
                    .holes
                    .iter()
                    .map(|h| ring_signed_area(h).abs())
                    .sum::<f64>(),
            perimeter,
            polygon,
            floor_z: z.0,
            ceiling_z: z.1,
            scanners: vec![],
            neighbours: neighbours.iter().map(|n| n.to_string()).collect(),
        }
    }

    fn centre(id: &str, a: P2, b: P2, thickness: f64, rooms: [Option<&str>; 2]) -> WallCentre {
        WallCentre {
            id: id.into(),
            a,
            b,
            thickness,
            exterior: rooms.contains(&None),
            rooms: rooms.map(|r| r.map(String::from)),
        }
    }

    /// The four exterior walls (30 cm assumed) around the free space `[0, w] × [0, h]`.
    fn exterior(level: usize, w: f64, h: f64, n0: usize, rooms: [&str; 4]) -> Vec<WallCentre> {
        let t = 0.3;
        let o = t / 2.0;
        let corners = [[-o, -o], [w + o, -o], [w + o, h + o], [-o, h + o]];
        (0..4)
            .map(|i| {
                centre(
                    &format!("L{level}-C{}", n0 + i),
                    corners[i],
                    corners[(i + 1) % 4],
                    t,
                    // Walls run counter-clockwise round the story: the room is on the left.
                    [Some(rooms[i]), None],
                )
            })
            .collect()
    }

    /// Two stories, far from the origin. Level 0 (10 × 6 m free space) is split by a 12 cm wall
    /// at x = 6 and a 10 cm wall at y = 3.5 into three rooms: R1 west (with a 40 cm column),
    /// R2 south-east and R3 north-east. Doors join R1 to R2 and R3, an opening joins R2 and R3,
    /// and a window in the south wall lights R1. Level 1 is one 10 × 6 m room.
    pub(crate) fn spaces_plan() -> FloorPlan {
        let mut s0 = story(
            0,
            vec![Polygon {
                exterior: rect(0.0, 0.0, 10.0, 6.0),
                holes: vec![],
            }],
            vec![
                line_wall([0.0, 0.0], [10.0, 0.0]),
                line_wall([10.0, 0.0], [10.0, 6.0]),
            ],
        );
        let mut column = rect(2.0, 2.0, 2.4, 2.4);
        column.reverse();
        s0.spaces = Spaces {
            rooms: vec![
                room(
                    "L0-R1",
                    Polygon {
                        exterior: rect(0.0, 0.0, 5.94, 6.0),
                        holes: vec![column],
                    },
                    (0.0, 2.5),
                    &["L0-R2", "L0-R3"],
                ),
                room(
                    "L0-R2",
                    Polygon {
                        exterior: rect(6.06, 0.0, 10.0, 3.45),
                        holes: vec![],
                    },
                    (0.0, 2.5),
                    &["L0-R1", "L0-R3"],
                ),
                room(
                    "L0-R3",
                    Polygon {
                        exterior: rect(6.06, 3.55, 10.0, 6.0),
                        holes: vec![],
                    },
                    (0.02, 2.45),
                    &["L0-R1", "L0-R2"],
                ),
            ],
            doors: vec![
                Door {
                    id: "L0-D1".into(),
                    kind: DoorKind::Door,
                    a: [6.0, 1.0],
                    b: [6.0, 1.9],
                    width: 0.9,
                    head_z: Some(2.05),
                    depth: 0.12,
                    rooms: [Some("L0-R1".into()), Some("L0-R2".into())],
                },
                Door {
                    id: "L0-D2".into(),
                    kind: DoorKind::Opening,
                    a: [7.0, 3.5],
                    b: [8.2, 3.5],
                    width: 1.2,
                    head_z: None,
                    depth: 0.1,
                    rooms: [Some("L0-R2".into()), Some("L0-R3".into())],
                },
                Door {
                    id: "L0-D3".into(),
                    kind: DoorKind::Door,
                    a: [6.0, 4.2],
                    b: [6.0, 5.1],
                    width: 0.9,
                    head_z: None,
                    depth: 0.12,
                    rooms: [Some("L0-R1".into()), Some("L0-R3".into())],
                },
            ],
            windows: vec![Window {
                id: "L0-W1".into(),
                a: [1.0, -0.15],
                b: [2.5, -0.15],
                width: 1.5,
                sill_z: 0.9,
                head_z: 2.1,
                room: Some("L0-R1".into()),
            }],
            walls: [
                vec![
                    centre(
                        "L0-C1",
                        [6.0, 0.0],
                        [6.0, 6.0],
                        0.12,
                        [Some("L0-R1"), Some("L0-R2")],
                    ),
                    centre(
                        "L0-C2",
                        [6.06, 3.5],
                        [10.0, 3.5],
                        0.1,
                        [Some("L0-R3"), Some("L0-R2")],
                    ),
                ],
                exterior(0, 10.0, 6.0, 3, ["L0-R1", "L0-R2", "L0-R3", "L0-R1"]),
            ]
            .concat(),
        };
        let mut s1 = story(
            1,
            vec![Polygon {
                exterior: rect(0.0, 0.0, 10.0, 6.0),
                holes: vec![],
            }],
            vec![],
        );
        s1.spaces = Spaces {
            rooms: vec![room(
                "L1-R1",
                Polygon {
                    exterior: rect(0.0, 0.0, 10.0, 6.0),
                    holes: vec![],
                },
                (3.0, 5.5),
                &[],
            )],
            walls: exterior(1, 10.0, 6.0, 1, ["L1-R1"; 4]),
            ..Default::default()
        };
        plan([500_000.0, 5_400_000.0, 100.0], vec![s0, s1])
    }

    fn reparse(plan: &FloorPlan) -> Value {
        serde_json::from_str(&to_geojson_string(plan)).unwrap()
    }

    fn kinds<'a>(doc: &'a Value, kind: &str) -> Vec<&'a Value> {
        doc["features"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["properties"]["kind"] == kind)
            .collect()
    }

    fn coords(ring: &Value) -> Vec<P2> {
        ring.as_array()
            .unwrap()
            .iter()
            .map(|p| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()])
            .collect()
    }

    /// Signed area of a closed ring as written (last position repeats the first).
    fn written_area(ring: &Value) -> f64 {
        let pts = coords(ring);
        assert_eq!(pts.first(), pts.last(), "ring not closed");
        ring_signed_area(&pts[..pts.len() - 1])
    }

    #[test]
    fn square_story_has_metadata_and_closed_ccw_ring() {
        // Given clockwise on purpose: the writer must fix the winding.
        let mut cw = square(0.0, 0.0, 4.0);
        cw.reverse();
        let doc = reparse(&plan(
            [0.0; 3],
            vec![story(
                0,
                vec![Polygon {
                    exterior: cw,
                    holes: vec![],
                }],
                vec![line_wall([0.0, 0.0], [4.0, 0.0])],
            )],
        ));
        assert_eq!(doc["type"], "FeatureCollection");
        let meta = &doc["floorplan"];
        assert_eq!(meta["version"], 1);
        assert_eq!(meta["units"], "m");
        assert_eq!(meta["crs"], "EPSG:25832");
        assert_eq!(meta["input"]["points"], 1234);
        assert_eq!(meta["input"]["format"], "ply");
        assert_eq!(meta["input"]["scans"], 2);
        assert_eq!(meta["parameters"]["samples"]["cell_size"], 0.05);
        let keys: Vec<&String> = meta["timings_ms"].as_object().unwrap().keys().collect();
        assert_eq!(keys, ["read", "stories", "label", "fit", "total"]);
        assert_eq!(meta["timings_ms"]["label"], 9);
        assert_eq!(meta["notes"][0], "a note");

        let stories = kinds(&doc, "story");
        assert_eq!(stories.len(), 1);
        let s = stories[0];
        assert_eq!(s["geometry"]["type"], "Polygon");
        let rings = s["geometry"]["coordinates"].as_array().unwrap();
        assert_eq!(rings.len(), 1);
        assert_eq!(rings[0].as_array().unwrap().len(), 5);
        assert!((written_area(&rings[0]) - 16.0).abs() < 1e-9);
        assert_eq!(s["properties"]["level"], 0);
        assert_eq!(s["properties"]["floor_z"], 0.0);
        assert_eq!(s["properties"]["ceiling_z"], 2.5);
        assert!((s["properties"]["area_m2"].as_f64().unwrap() - 16.0).abs() < 1e-9);
        assert_eq!(s["properties"]["samples"], 3);

        let walls = kinds(&doc, "wall");
        assert_eq!(walls.len(), 1);
        assert_eq!(walls[0]["geometry"]["type"], "LineString");
        assert_eq!(walls[0]["properties"]["model"], "line");
        assert_eq!(walls[0]["properties"]["length_m"], 4.0);
        assert_eq!(walls[0]["properties"]["support"], 12);
        assert!(walls[0]["properties"].get("radius").is_none());
        // Samples are off in these parameters.
        assert!(kinds(&doc, "wall_samples").is_empty());
    }

    #[test]
    fn viewpoints_are_reported_in_the_world_frame() {
        use crate::viewpoints::{ScanViewpoint, ViewpointSource, ViewpointsReport};
        let mut p = plan([1000.0, 2000.0, 10.0], vec![]);
        p.input.viewpoints = ViewpointsReport {
            source: ViewpointSource::Mixed,
            scans: vec![
                ScanViewpoint {
                    index: 3,
                    estimated: false,
                    position: Some([1.0, 2.0, 1.5]),
                    residual: None,
                    support: None,
                    points: 10,
                },
                ScanViewpoint {
                    index: 4,
                    estimated: true,
                    position: Some([5.0, 2.0, 1.5]),
                    residual: Some(0.012),
                    support: Some(0.75),
                    points: 20,
                },
                ScanViewpoint {
                    index: 5,
                    estimated: true,
                    position: None,
                    residual: None,
                    support: None,
                    points: 30,
                },
            ],
            rests_on: Some(0.8),
            ..Default::default()
        };
        let doc = reparse(&p);
        let v = &doc["floorplan"]["input"]["viewpoints"];
        assert_eq!(v["source"], "mixed");
        assert_eq!(v["rests_on"], 0.8);
        assert_eq!(v["path"], Value::Null);
        let scans = v["scans"].as_array().unwrap();
        assert_eq!(scans.len(), 3);
        assert_eq!(scans[0]["source"], "given");
        assert_eq!(scans[0]["position"], json!([1001.0, 2002.0, 11.5]));
        assert_eq!(scans[1]["source"], "estimated");
        assert_eq!(scans[1]["residual_m"], 0.012);
        assert_eq!(scans[1]["support"], 0.75);
        assert_eq!(scans[2]["position"], Value::Null);
        assert_eq!(scans[2]["points"], 30);
    }

    #[test]
    fn holes_are_clockwise_and_area_excludes_them() {
        let mut hole = square(1.0, 1.0, 1.0); // CCW as given: must be reversed.
        hole.push(hole[0]); // An already-closed ring must not be closed twice.
        let doc = reparse(&plan(
            [0.0; 3],
            vec![story(
                0,
                vec![Polygon {
                    exterior: square(0.0, 0.0, 4.0),
                    holes: vec![hole],
                }],
                vec![],
            )],
        ));
        let s = kinds(&doc, "story")[0];
        let rings = s["geometry"]["coordinates"].as_array().unwrap();
        assert_eq!(rings.len(), 2);
        assert!(written_area(&rings[0]) > 0.0);
        assert!((written_area(&rings[1]) + 1.0).abs() < 1e-9);
        assert_eq!(rings[1].as_array().unwrap().len(), 5);
        // The plan's own area rule (exteriors minus holes) ignores the duplicate closing point.
        assert!((s["properties"]["area_m2"].as_f64().unwrap() - 15.0).abs() < 1e-9);
    }

    #[test]
    fn origin_is_added_and_rounded() {
        let origin = [500_000.0, 5_400_000.0, 100.0];
        let mut p = plan(
            origin,
            vec![story(
                1,
                vec![Polygon {
                    exterior: square(0.123_456_7, 0.0, 2.0),
                    holes: vec![],
                }],
                vec![arc_wall([1.0, 1.0])],
            )],
        );
        p.parameters["emit_samples"] = json!(true);
        let doc = reparse(&p);
        let s = kinds(&doc, "story")[0];
        let first = coords(&s["geometry"]["coordinates"][0])[0];
        assert_eq!(first, [500_000.123_5, 5_400_000.0]);
        assert_eq!(s["properties"]["floor_z"], 103.0);
        assert_eq!(s["properties"]["ceiling_z"], 105.5);

        let w = kinds(&doc, "wall")[0];
        assert_eq!(w["properties"]["model"], "arc");
        assert_eq!(w["properties"]["radius"], 2.0);
        let c = coords(&json!([w["properties"]["center"]]))[0];
        assert_eq!(c, [500_001.0, 5_400_001.0]);
        for q in coords(&w["geometry"]["coordinates"]) {
            let r = ((q[0] - c[0]).powi(2) + (q[1] - c[1]).powi(2)).sqrt();
            assert!(
                (r - 2.0).abs() < 2e-4,
                "arc point off the circle by {}",
                r - 2.0
            );
        }
        let len = w["properties"]["length_m"].as_f64().unwrap();
        assert!((len - std::f64::consts::PI).abs() < 0.01);

        let samples = kinds(&doc, "wall_samples");
        assert_eq!(samples.len(), 1);
        assert_eq!(samples[0]["geometry"]["type"], "MultiPoint");
        assert_eq!(samples[0]["properties"]["level"], 1);
        let pts = coords(&samples[0]["geometry"]["coordinates"]);
        assert_eq!(pts[2], [500_004.0, 5_400_002.0]);
    }

    #[test]
    fn two_polygons_make_a_multipolygon_and_stories_keep_levels() {
        let two = vec![
            Polygon {
                exterior: square(0.0, 0.0, 2.0),
                holes: vec![],
            },
            Polygon {
                exterior: square(5.0, 0.0, 1.0),
                holes: vec![square(5.25, 0.25, 0.5)],
            },
        ];
        let one = vec![Polygon {
            exterior: square(0.0, 0.0, 3.0),
            holes: vec![],
        }];
        let doc = reparse(&plan(
            [0.0; 3],
            vec![story(0, two, vec![]), story(1, one, vec![])],
        ));
        let stories = kinds(&doc, "story");
        assert_eq!(stories.len(), 2);
        let g = &stories[0]["geometry"];
        assert_eq!(g["type"], "MultiPolygon");
        let polys = g["coordinates"].as_array().unwrap();
        assert_eq!(polys.len(), 2);
        assert!(written_area(&polys[1][0]) > 0.0);
        assert!(written_area(&polys[1][1]) < 0.0);
        assert_eq!(stories[1]["geometry"]["type"], "Polygon");
        assert_eq!(stories[1]["properties"]["level"], 1);
        assert_eq!(stories[1]["properties"]["floor_z"], 3.0);
    }

    #[test]
    fn degenerate_geometry_is_dropped_not_written() {
        let doc = reparse(&plan(
            [0.0; 3],
            vec![story(
                0,
                vec![Polygon {
                    exterior: vec![[0.0, 0.0], [1.0, 0.0]],
                    holes: vec![],
                }],
                vec![line_wall([1.0, 1.0], [1.0, 1.0])],
            )],
        ));
        let s = kinds(&doc, "story")[0];
        assert_eq!(s["geometry"]["type"], "MultiPolygon");
        assert_eq!(s["geometry"]["coordinates"].as_array().unwrap().len(), 0);
        assert!(kinds(&doc, "wall").is_empty());
    }

    #[test]
    fn spaces_add_features_and_leave_the_old_ones_alone() {
        let full = reparse(&spaces_plan());
        let mut bare = spaces_plan();
        for s in &mut bare.stories {
            s.spaces = Spaces::default();
        }
        let bare = reparse(&bare);
        let new = ["room", "door", "opening", "window", "wall_centerline"];
        let old: Vec<&Value> = full["features"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| !new.contains(&f["properties"]["kind"].as_str().unwrap()))
            .collect();
        assert_eq!(
            old,
            bare["features"]
                .as_array()
                .unwrap()
                .iter()
                .collect::<Vec<_>>()
        );
        assert_eq!(full["floorplan"], bare["floorplan"]);
        let counts: Vec<usize> = new.iter().map(|k| kinds(&full, k).len()).collect();
        assert_eq!(counts, [4, 2, 1, 1, 10]);
    }

    /// Exactly the properties `docs/contract.md` lists, world coordinates and world heights.
    #[test]
    fn space_features_follow_the_contract() {
        let doc = reparse(&spaces_plan());
        let keys = |f: &Value| {
            let mut k: Vec<String> = f["properties"]
                .as_object()
                .unwrap()
                .keys()
                .cloned()
                .collect();
            k.sort();
            k
        };
        let sorted = |k: &[&str]| {
            let mut k: Vec<String> = k.iter().map(|s| s.to_string()).collect();
            k.sort();
            k
        };
        let room_keys = sorted(&[
            "kind",
            "level",
            "id",
            "area_m2",
            "perimeter_m",
            "floor_z",
            "ceiling_z",
            "height_m",
            "scanners",
            "neighbours",
        ]);
        let door_keys = sorted(&[
            "kind", "level", "id", "width_m", "head_z", "depth_m", "rooms",
        ]);
        let window_keys = sorted(&["kind", "level", "id", "width_m", "sill_z", "head_z", "room"]);
        let wall_keys = sorted(&["kind", "level", "id", "thickness_m", "exterior", "rooms"]);
        for (kind, want) in [
            ("room", &room_keys),
            ("door", &door_keys),
            ("opening", &door_keys),
            ("window", &window_keys),
            ("wall_centerline", &wall_keys),
        ] {
            for f in kinds(&doc, kind) {
                assert_eq!(&keys(f), want, "{kind}");
                let ty = if kind == "room" {
                    "Polygon"
                } else {
                    "LineString"
                };
                assert_eq!(f["geometry"]["type"], ty, "{kind}");
            }
        }

        let rooms = kinds(&doc, "room");
        let r1 = rooms[0];
        assert_eq!(r1["properties"]["id"], "L0-R1");
        assert_eq!(r1["properties"]["area_m2"], 35.48);
        assert_eq!(r1["properties"]["perimeter_m"], 25.48);
        assert_eq!(r1["properties"]["floor_z"], 100.0);
        assert_eq!(r1["properties"]["ceiling_z"], 102.5);
        assert_eq!(r1["properties"]["height_m"], 2.5);
        assert_eq!(r1["properties"]["neighbours"], json!(["L0-R2", "L0-R3"]));
        let rings = r1["geometry"]["coordinates"].as_array().unwrap();
        assert_eq!(rings.len(), 2);
        // Areas about the ring's first corner: far from the origin, f64 would lose them.
        let area = |ring: &Value| {
            let pts = coords(ring);
            let local: Vec<P2> = pts
                .iter()
                .map(|p| [p[0] - pts[0][0], p[1] - pts[0][1]])
                .collect();
            ring_signed_area(&local[..local.len() - 1])
        };
        assert!((area(&rings[0]) - 35.64).abs() < 1e-6);
        assert!((area(&rings[1]) + 0.16).abs() < 1e-6);
        assert_eq!(coords(&rings[0])[0], [500_000.0, 5_400_000.0]);
        let r3 = rooms[2];
        assert_eq!(r3["properties"]["floor_z"], 100.02);
        assert_eq!(r3["properties"]["height_m"], 2.43);
        assert_eq!(rooms[3]["properties"]["level"], 1);
        assert_eq!(rooms[3]["properties"]["floor_z"], 103.0);

        let doors = kinds(&doc, "door");
        assert_eq!(doors[0]["properties"]["id"], "L0-D1");
        assert_eq!(doors[0]["properties"]["head_z"], 102.05);
        assert_eq!(doors[0]["properties"]["width_m"], 0.9);
        assert_eq!(doors[0]["properties"]["depth_m"], 0.12);
        assert_eq!(doors[0]["properties"]["rooms"], json!(["L0-R1", "L0-R2"]));
        assert_eq!(
            coords(&doors[0]["geometry"]["coordinates"]),
            [[500_006.0, 5_400_001.0], [500_006.0, 5_400_001.9]]
        );
        assert_eq!(doors[1]["properties"]["head_z"], Value::Null);
        let opening = kinds(&doc, "opening")[0];
        assert_eq!(opening["properties"]["id"], "L0-D2");
        assert_eq!(opening["properties"]["head_z"], Value::Null);

        let window = kinds(&doc, "window")[0];
        assert_eq!(window["properties"]["sill_z"], 100.9);
        assert_eq!(window["properties"]["head_z"], 102.1);
        assert_eq!(window["properties"]["room"], "L0-R1");

        let walls = kinds(&doc, "wall_centerline");
        assert_eq!(walls[0]["properties"]["thickness_m"], 0.12);
        assert_eq!(walls[0]["properties"]["exterior"], false);
        assert_eq!(walls[2]["properties"]["exterior"], true);
        assert_eq!(walls[2]["properties"]["rooms"], json!(["L0-R1", null]));
        assert_eq!(
            coords(&walls[2]["geometry"]["coordinates"])[0],
            [499_999.85, 5_399_999.85]
        );
    }

    #[test]
    fn degenerate_spaces_are_dropped_not_written() {
        let mut p = spaces_plan();
        let s = &mut p.stories[0].spaces;
        s.rooms[0].polygon.exterior.truncate(2);
        s.doors[0].b = s.doors[0].a;
        s.windows[0].a = [f64::NAN, 0.0];
        s.walls[0].b = s.walls[0].a;
        let doc = reparse(&p);
        assert_eq!(kinds(&doc, "room").len(), 3);
        assert_eq!(kinds(&doc, "door").len(), 1);
        // NaN serialises as null; the feature stays, its coordinate says it is unknown.
        assert_eq!(kinds(&doc, "window").len(), 1);
        assert_eq!(kinds(&doc, "wall_centerline").len(), 9);
    }

    /// GEOS judges every room: valid, its written area as stated, inside its story and
    /// overlapping no other room.
    #[test]
    fn rooms_are_valid_and_disjoint_under_geos() {
        let text = to_geojson_string(&spaces_plan());
        let file = crate::io::outputs::python::temp_file(".geojson", text.as_bytes());
        let script = r#"
import json, sys
import shapely
from shapely.geometry import shape
doc = json.load(open(sys.argv[1]))
rooms, stories = [], {}
for f in doc["features"]:
    p = f["properties"]
    if p["kind"] == "story":
        stories[p["level"]] = shape(f["geometry"])
    if p["kind"] == "room":
        rooms.append((p, shape(f["geometry"])))
out = {"rooms": [], "overlap": 0.0}
for p, g in rooms:
    out["rooms"].append({
        "id": p["id"], "valid": bool(g.is_valid), "reason": shapely.is_valid_reason(g),
        "area": g.area, "stated": p["area_m2"], "perimeter": g.length,
        "inside": g.difference(stories[p["level"]]).area,
    })
for i in range(len(rooms)):
    for j in range(i + 1, len(rooms)):
        if rooms[i][0]["level"] == rooms[j][0]["level"]:
            out["overlap"] += rooms[i][1].intersection(rooms[j][1]).area
print(json.dumps(out))
"#;
        let Some(v) = crate::io::outputs::python::run_json(
            &["shapely"],
            script,
            &[file.path().to_str().unwrap()],
        ) else {
            return;
        };
        let rooms = v["rooms"].as_array().unwrap();
        assert_eq!(rooms.len(), 4);
        for r in rooms {
            assert_eq!(r["valid"], true, "{r}");
            let area = r["area"].as_f64().unwrap();
            assert!((area - r["stated"].as_f64().unwrap()).abs() < 1e-3, "{r}");
            assert!(r["inside"].as_f64().unwrap() < 1e-6, "{r}");
        }
        assert!(v["overlap"].as_f64().unwrap() < 1e-6, "{v}");
        assert!((rooms[0]["perimeter"].as_f64().unwrap() - 25.48).abs() < 1e-6);
    }
}
