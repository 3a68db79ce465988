//! The floor plan as GeoJSON, exactly as `docs/contract.md` §1 says.
//!
//! Coordinates leave the local frame here: every position gets `FloorPlan::origin` added back
//! and is rounded to 0.1 mm, so georeferenced plans stay in their own (e.g. UTM) frame.

use serde_json::{json, Map, Value};

use crate::geom::{ring_signed_area, P2};
use crate::plan::{FloorPlan, Polygon, StoryPlan, Wall, WallModel};

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
    }
    let timings: Map<String, Value> = plan
        .timings_ms
        .iter()
        .map(|(name, ms)| (name.clone(), json!(ms)))
        .collect();
    json!({
        "type": "FeatureCollection",
        "floorplan": {
            "version": VERSION,
            "units": "m",
            "crs": plan.crs,
            "input": {
                "points": plan.input.points,
                "format": plan.input.format,
                "scans": plan.input.scans,
                "viewpoints": viewpoints(plan),
            },
            "parameters": plan.parameters,
            "timings_ms": timings,
            "notes": plan.notes,
        },
        "features": features,
    })
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
    let mut out: Vec<[f64; 2]> = Vec::with_capacity(points.len() + 1);
    let ordered: Box<dyn Iterator<Item = &P2>> = if reverse {
        Box::new(points.iter().rev())
    } else {
        Box::new(points.iter())
    };
    for &p in ordered {
        let q = position(plan, p);
        if out.last() != Some(&q) {
            out.push(q);
        }
    }
    // An input that was already closed, or rounding, can leave the first position at the end.
    while out.len() > 1 && out.first() == out.last() {
        out.pop();
    }
    if out.len() < 3 {
        return None;
    }
    out.push(out[0]);
    Some(out)
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
    use crate::plan::InputSummary;

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
}
