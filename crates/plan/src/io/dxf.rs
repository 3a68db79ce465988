//! The floor plan as DXF R12 (AC1009) text: a layer per story, a layer for walls, real ARC
//! entities, metres.
//!
//! R12 is written by hand because it is the one DXF version every CAD reader opens and it is
//! small: group-code/value line pairs, no handles, no object section. Layers:
//! - `STORY_k`: story k's floor outline, one closed POLYLINE per ring (R12 has no LWPOLYLINE);
//! - `WALLS_k`: story k's fitted walls, LINE entities for lines and ARC (or CIRCLE) for arcs;
//! - where the story has them: `ROOMS_k`, each room's rings as closed POLYLINEs and its id and
//!   area as two TEXTs; `DOORS_k`, each door's gap as a LINE with its leaf (LINE) and swing
//!   (ARC), each opening's gap as a LINE; `WINDOWS_k`, each window as a LINE;
//!   `WALL_CENTERLINES_k`, each wall with thickness as a two-vertex POLYLINE along its centre
//!   line whose width is the wall's thickness.
//!
//! Everything lies at the story's floor height, in world coordinates (origin added back).

use std::fmt::Write;

use crate::geom::{cross, dot, sub, P2};
use crate::plan::{DoorKind, FloorPlan, StoryPlan, Wall, WallModel};

/// Why DXF could not be written.
#[derive(Debug, thiserror::Error)]
#[error("dxf: {0}")]
pub struct DxfError(pub String);

/// The start angle and signed sweep (radians, counter-clockwise positive) of the arc that a
/// densified polyline traces about `center`. `None` when a point sits on the center.
pub(crate) fn arc_span(center: P2, points: &[P2]) -> Option<(f64, f64)> {
    let first = sub(*points.first()?, center);
    if first == [0.0, 0.0] {
        return None;
    }
    let mut sweep = 0.0;
    for w in points.windows(2) {
        let (a, b) = (sub(w[0], center), sub(w[1], center));
        if b == [0.0, 0.0] {
            return None;
        }
        sweep += cross(a, b).atan2(dot(a, b));
    }
    Some((first[1].atan2(first[0]), sweep))
}

/// Group-code/value pairs, in the classic right-aligned layout.
struct Out(String);

impl Out {
    fn pair(&mut self, code: u16, value: impl std::fmt::Display) {
        let _ = write!(self.0, "{code:>3}\n{value}\n");
    }

    /// A coordinate or length; DXF readers take plain decimals.
    fn real(&mut self, code: u16, v: f64) -> Result<(), DxfError> {
        if !v.is_finite() {
            return Err(DxfError(format!("non-finite value for group {code}")));
        }
        // Nine decimals keep sub-micrometre precision even on UTM-sized coordinates.
        let text = format!("{v:.9}");
        let text = text.trim_end_matches('0');
        let text = text
            .strip_suffix('.')
            .map_or(text.to_string(), |t| format!("{t}.0"));
        self.pair(code, if text == "-0.0" { "0.0" } else { text.as_str() });
        Ok(())
    }

    fn point(&mut self, base: u16, p: [f64; 3]) -> Result<(), DxfError> {
        self.real(base, p[0])?;
        self.real(base + 10, p[1])?;
        self.real(base + 20, p[2])
    }
}

/// Layer names for story `level`.
fn story_layer(level: usize) -> String {
    format!("STORY_{level}")
}

fn walls_layer(level: usize) -> String {
    format!("WALLS_{level}")
}

/// The plan as DXF R12 bytes.
pub fn to_dxf(plan: &FloorPlan) -> Result<Vec<u8>, DxfError> {
    let mut out = Out(String::new());
    header(&mut out, plan)?;
    tables(&mut out, plan);
    out.pair(0, "SECTION");
    out.pair(2, "BLOCKS");
    out.pair(0, "ENDSEC");
    out.pair(0, "SECTION");
    out.pair(2, "ENTITIES");
    for story in &plan.stories {
        story_entities(&mut out, plan, story)?;
    }
    out.pair(0, "ENDSEC");
    out.pair(0, "EOF");
    Ok(out.0.into_bytes())
}

fn world(plan: &FloorPlan, p: P2, z: f64) -> [f64; 3] {
    [p[0] + plan.origin[0], p[1] + plan.origin[1], z]
}

fn header(out: &mut Out, plan: &FloorPlan) -> Result<(), DxfError> {
    out.pair(0, "SECTION");
    out.pair(2, "HEADER");
    out.pair(9, "$ACADVER");
    out.pair(1, "AC1009");
    // $INSUNITS is newer than R12, but readers that know it (ezdxf, recent AutoCAD) use it;
    // $MEASUREMENT 1 says metric to the rest.
    out.pair(9, "$INSUNITS");
    out.pair(70, 6);
    out.pair(9, "$MEASUREMENT");
    out.pair(70, 1);
    if let Some((lo, hi)) = extents(plan) {
        out.pair(9, "$EXTMIN");
        out.point(10, lo)?;
        out.pair(9, "$EXTMAX");
        out.point(10, hi)?;
    }
    out.pair(0, "ENDSEC");
    Ok(())
}

/// World bounds of everything drawn, for "zoom extents".
fn extents(plan: &FloorPlan) -> Option<([f64; 3], [f64; 3])> {
    let mut points = plan.stories.iter().flat_map(|s| {
        let z = s.floor_z + plan.origin[2];
        s.polygons
            .iter()
            .flat_map(|p| std::iter::once(&p.exterior).chain(&p.holes))
            .flatten()
            .chain(s.walls.iter().flat_map(|w| &w.points))
            // Exterior walls and their windows lie outside the floor.
            .chain(s.spaces.walls.iter().flat_map(|w| [&w.a, &w.b]))
            .chain(s.spaces.windows.iter().flat_map(|w| [&w.a, &w.b]))
            .map(move |&p| world(plan, p, z))
    });
    let first = points.next()?;
    Some(points.fold((first, first), |(mut lo, mut hi), p| {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
        (lo, hi)
    }))
}

fn tables(out: &mut Out, plan: &FloorPlan) {
    out.pair(0, "SECTION");
    out.pair(2, "TABLES");
    out.pair(0, "TABLE");
    out.pair(2, "LTYPE");
    out.pair(70, 1);
    out.pair(0, "LTYPE");
    out.pair(2, "CONTINUOUS");
    out.pair(70, 0);
    out.pair(3, "Solid line");
    out.pair(72, 65);
    out.pair(73, 0);
    out.pair(40, "0.0");
    out.pair(0, "ENDTAB");
    out.pair(0, "TABLE");
    out.pair(2, "LAYER");
    let spaces: Vec<(String, u16)> = plan.stories.iter().flat_map(space_layers).collect();
    out.pair(70, 1 + 2 * plan.stories.len() + spaces.len());
    // Layer "0" must exist in every drawing.
    layer(out, "0", 7);
    for story in &plan.stories {
        // Floors in a soft colour (ACI 8, grey), walls in black/white (ACI 7).
        layer(out, &story_layer(story.level), 8);
        layer(out, &walls_layer(story.level), 7);
    }
    for (name, color) in &spaces {
        layer(out, name, *color);
    }
    out.pair(0, "ENDTAB");
    out.pair(0, "ENDSEC");
}

/// The layers a story's rooms, doors, windows and centre-line walls go on, with their colours
/// (ACI 3 green, 1 red, 5 blue, 9 light grey); only those the story has, so a plan without
/// rooms is drawn as before.
fn space_layers(story: &StoryPlan) -> Vec<(String, u16)> {
    let s = &story.spaces;
    let k = story.level;
    [
        (!s.rooms.is_empty(), format!("ROOMS_{k}"), 3),
        (!s.doors.is_empty(), format!("DOORS_{k}"), 1),
        (!s.windows.is_empty(), format!("WINDOWS_{k}"), 5),
        (!s.walls.is_empty(), format!("WALL_CENTERLINES_{k}"), 9),
    ]
    .into_iter()
    .filter_map(|(has, name, color)| has.then_some((name, color)))
    .collect()
}

fn layer(out: &mut Out, name: &str, color: u16) {
    out.pair(0, "LAYER");
    out.pair(2, name);
    out.pair(70, 0);
    out.pair(62, color);
    out.pair(6, "CONTINUOUS");
}

fn story_entities(out: &mut Out, plan: &FloorPlan, story: &StoryPlan) -> Result<(), DxfError> {
    let z = story.floor_z + plan.origin[2];
    let layer = story_layer(story.level);
    for polygon in &story.polygons {
        for ring in std::iter::once(&polygon.exterior).chain(&polygon.holes) {
            if ring.len() >= 3 {
                closed_polyline(out, plan, ring, z, &layer)?;
            }
        }
    }
    let layer = walls_layer(story.level);
    for wall in &story.walls {
        wall_entities(out, plan, wall, z, &layer)?;
    }
    space_entities(out, plan, story, z)
}

/// A closed 2D POLYLINE through `ring` at height `z`.
fn closed_polyline(
    out: &mut Out,
    plan: &FloorPlan,
    ring: &[P2],
    z: f64,
    layer: &str,
) -> Result<(), DxfError> {
    // A 2D polyline: the elevation sits in the header's 30 group; flag 1 closes it.
    out.pair(0, "POLYLINE");
    out.pair(8, layer);
    out.pair(66, 1);
    out.point(10, [0.0, 0.0, z])?;
    out.pair(70, 1);
    let closed_twice = ring.len() > 3 && ring.first() == ring.last();
    let n = ring.len() - usize::from(closed_twice);
    for &p in &ring[..n] {
        out.pair(0, "VERTEX");
        out.pair(8, layer);
        out.point(10, world(plan, p, z))?;
    }
    out.pair(0, "SEQEND");
    out.pair(8, layer);
    Ok(())
}

fn line(
    out: &mut Out,
    plan: &FloorPlan,
    a: P2,
    b: P2,
    z: f64,
    layer: &str,
) -> Result<(), DxfError> {
    out.pair(0, "LINE");
    out.pair(8, layer);
    out.point(10, world(plan, a, z))?;
    out.point(11, world(plan, b, z))
}

/// One line of text centred on `at`, `height` metres tall.
fn text(
    out: &mut Out,
    at: [f64; 3],
    height: f64,
    value: &str,
    layer: &str,
) -> Result<(), DxfError> {
    out.pair(0, "TEXT");
    out.pair(8, layer);
    out.point(10, at)?;
    out.real(40, height)?;
    // R12 text is one line of the drawing's code page: keep to printable ASCII.
    let value: String = value
        .chars()
        .map(|c| if (' '..='~').contains(&c) { c } else { '?' })
        .collect();
    out.pair(1, value);
    out.pair(72, 1);
    out.point(11, at)?;
    out.pair(73, 2);
    Ok(())
}

/// Text height of room labels, metres: readable at 1:100 on a plotted plan.
const LABEL_HEIGHT: f64 = 0.25;

fn space_entities(
    out: &mut Out,
    plan: &FloorPlan,
    story: &StoryPlan,
    z: f64,
) -> Result<(), DxfError> {
    let s = &story.spaces;
    let k = story.level;
    let layer = format!("ROOMS_{k}");
    for room in &s.rooms {
        for ring in std::iter::once(&room.polygon.exterior).chain(&room.polygon.holes) {
            if ring.len() >= 3 {
                closed_polyline(out, plan, ring, z, &layer)?;
            }
        }
        if let Some(p) = crate::io::svg::label_point(&room.polygon) {
            let h = LABEL_HEIGHT;
            let at = |dy: f64| world(plan, [p[0], p[1] + dy], z);
            text(out, at(0.6 * h), h, &room.id, &layer)?;
            text(
                out,
                at(-0.6 * h),
                h,
                &format!("{:.2} m2", room.area),
                &layer,
            )?;
        }
    }
    let layer = format!("DOORS_{k}");
    for door in &s.doors {
        if door.a == door.b {
            continue;
        }
        line(out, plan, door.a, door.b, z, &layer)?;
        if door.kind == DoorKind::Opening {
            continue;
        }
        // Hinged at a, the leaf open a quarter turn to the left, the swing back to b.
        let along = sub(door.b, door.a);
        let open = [door.a[0] - along[1], door.a[1] + along[0]];
        line(out, plan, door.a, open, z, &layer)?;
        let start = along[1].atan2(along[0]).to_degrees();
        out.pair(0, "ARC");
        out.pair(8, &layer);
        out.point(10, world(plan, door.a, z))?;
        out.real(40, crate::geom::dist(door.a, door.b))?;
        out.real(50, start.rem_euclid(360.0))?;
        out.real(51, (start + 90.0).rem_euclid(360.0))?;
    }
    let layer = format!("WINDOWS_{k}");
    for window in s.windows.iter().filter(|w| w.a != w.b) {
        line(out, plan, window.a, window.b, z, &layer)?;
    }
    let layer = format!("WALL_CENTERLINES_{k}");
    for wall in s.walls.iter().filter(|w| w.a != w.b) {
        // An open 2D polyline whose constant width (groups 40, 41) is the wall's thickness.
        out.pair(0, "POLYLINE");
        out.pair(8, &layer);
        out.pair(66, 1);
        out.point(10, [0.0, 0.0, z])?;
        out.pair(70, 0);
        out.real(40, wall.thickness)?;
        out.real(41, wall.thickness)?;
        for p in [wall.a, wall.b] {
            out.pair(0, "VERTEX");
            out.pair(8, &layer);
            out.point(10, world(plan, p, z))?;
        }
        out.pair(0, "SEQEND");
        out.pair(8, &layer);
    }
    Ok(())
}

fn wall_entities(
    out: &mut Out,
    plan: &FloorPlan,
    wall: &Wall,
    z: f64,
    layer: &str,
) -> Result<(), DxfError> {
    if wall.points.len() < 2 {
        return Ok(());
    }
    if let WallModel::Arc { center, radius } = wall.model {
        if let Some((start, sweep)) = arc_span(center, &wall.points) {
            let c = world(plan, center, z);
            if sweep.abs() >= std::f64::consts::TAU - 1e-9 {
                out.pair(0, "CIRCLE");
                out.pair(8, layer);
                out.point(10, c)?;
                out.real(40, radius)?;
                return Ok(());
            }
            // DXF arcs always run counter-clockwise from start to end angle.
            let (from, to) = if sweep >= 0.0 {
                (start, start + sweep)
            } else {
                (start + sweep, start)
            };
            out.pair(0, "ARC");
            out.pair(8, layer);
            out.point(10, c)?;
            out.real(40, radius)?;
            out.real(50, from.to_degrees().rem_euclid(360.0))?;
            out.real(51, to.to_degrees().rem_euclid(360.0))?;
            return Ok(());
        }
    }
    // A line wall is a straight piece; a polyline with bends keeps its shape as several LINEs.
    for w in wall.points.windows(2) {
        if w[0] == w[1] {
            continue;
        }
        out.pair(0, "LINE");
        out.pair(8, layer);
        out.point(10, world(plan, w[0], z))?;
        out.point(11, world(plan, w[1], z))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::geojson::tests::{arc_wall, line_wall, plan, square, story};
    use crate::plan::Polygon;

    /// The file as (code, value) pairs; fails on an odd line count or a bad code.
    fn pairs(bytes: &[u8]) -> Vec<(u16, String)> {
        let text = std::str::from_utf8(bytes).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len() % 2, 0, "odd number of lines");
        lines
            .chunks(2)
            .map(|c| (c[0].trim().parse().unwrap(), c[1].to_string()))
            .collect()
    }

    /// Values of `code` in each entity of type `kind` (entities start at code 0).
    fn entities(pairs: &[(u16, String)], kind: &str) -> Vec<Vec<(u16, String)>> {
        let mut out = Vec::new();
        let mut i = 0;
        while i < pairs.len() {
            if pairs[i] == (0, kind.to_string()) {
                let end = pairs[i + 1..]
                    .iter()
                    .position(|p| p.0 == 0)
                    .map_or(pairs.len(), |k| i + 1 + k);
                out.push(pairs[i + 1..end].to_vec());
                i = end;
            } else {
                i += 1;
            }
        }
        out
    }

    fn get(entity: &[(u16, String)], code: u16) -> f64 {
        entity
            .iter()
            .find(|p| p.0 == code)
            .unwrap_or_else(|| panic!("no group {code}"))
            .1
            .parse()
            .unwrap()
    }

    fn layer(entity: &[(u16, String)]) -> &str {
        &entity.iter().find(|p| p.0 == 8).unwrap().1
    }

    /// Story 0: a square with a hole, a line wall, a CCW arc and the same arc clockwise.
    /// Story 1: one square and one wall. Origin far away, as in UTM.
    fn sample_plan() -> FloorPlan {
        let mut reversed = arc_wall([4.0, 4.0]);
        reversed.points.reverse();
        plan(
            [600_000.0, 5_000_000.0, 20.0],
            vec![
                story(
                    0,
                    vec![Polygon {
                        exterior: square(0.0, 0.0, 6.0),
                        holes: vec![square(2.0, 2.0, 1.0)],
                    }],
                    vec![
                        line_wall([0.0, 0.0], [6.0, 0.0]),
                        arc_wall([4.0, 4.0]),
                        reversed,
                    ],
                ),
                story(
                    1,
                    vec![Polygon {
                        exterior: square(0.0, 0.0, 4.0),
                        holes: vec![],
                    }],
                    vec![line_wall([0.0, 0.0], [4.0, 0.0])],
                ),
            ],
        )
    }

    #[test]
    fn r12_structure_layers_and_entities() {
        let bytes = to_dxf(&sample_plan()).unwrap();
        let p = pairs(&bytes);
        let at = |name: &str| p.iter().position(|x| x.0 == 9 && x.1 == name).unwrap();
        assert_eq!(p[at("$ACADVER") + 1], (1, "AC1009".to_string()));
        assert_eq!(p[at("$INSUNITS") + 1], (70, "6".to_string()));
        assert_eq!(p[at("$MEASUREMENT") + 1], (70, "1".to_string()));
        let sections: Vec<&str> = p
            .windows(2)
            .filter(|w| w[0] == (0, "SECTION".into()))
            .map(|w| w[1].1.as_str())
            .collect();
        assert_eq!(sections, ["HEADER", "TABLES", "BLOCKS", "ENTITIES"]);
        assert_eq!(p.last().unwrap(), &(0, "EOF".to_string()));
        assert!(!p.iter().any(|x| x.1.contains("LWPOLYLINE")));

        let layers: Vec<String> = entities(&p, "LAYER")
            .into_iter()
            .map(|e| e.into_iter().find(|x| x.0 == 2).unwrap().1)
            .collect();
        assert_eq!(layers, ["0", "STORY_0", "WALLS_0", "STORY_1", "WALLS_1"]);

        let polylines = entities(&p, "POLYLINE");
        assert_eq!(polylines.len(), 3);
        assert!(polylines
            .iter()
            .all(|e| get(e, 70) == 1.0 && get(e, 66) == 1.0));
        assert_eq!(get(&polylines[2], 30), 23.0);
        assert_eq!(entities(&p, "VERTEX").len(), 12);
        assert_eq!(entities(&p, "SEQEND").len(), 3);
        let v0 = &entities(&p, "VERTEX")[0];
        assert_eq!((get(v0, 10), get(v0, 20)), (600_000.0, 5_000_000.0));

        let lines = entities(&p, "LINE");
        assert_eq!(lines.len(), 2);
        assert_eq!(layer(&lines[1]), "WALLS_1");
        assert_eq!(get(&lines[0], 11), 600_006.0);

        let arcs = entities(&p, "ARC");
        assert_eq!(arcs.len(), 2);
        for arc in &arcs {
            assert_eq!(layer(arc), "WALLS_0");
            assert_eq!((get(arc, 10), get(arc, 20)), (600_004.0, 5_000_004.0));
            assert_eq!(get(arc, 30), 20.0);
            assert_eq!(get(arc, 40), 2.0);
            // Both directions give the same counter-clockwise span, 0° → 90°.
            assert!(get(arc, 50).abs() < 1e-6 || (get(arc, 50) - 360.0).abs() < 1e-6);
            assert!((get(arc, 51) - 90.0).abs() < 1e-6);
        }
    }

    #[test]
    fn arc_span_measures_signed_sweep() {
        let wall = arc_wall([1.0, -1.0]);
        let (start, sweep) = arc_span([1.0, -1.0], &wall.points).unwrap();
        assert!(start.abs() < 1e-12);
        assert!((sweep - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let full: Vec<P2> = (0..=40)
            .map(|i| {
                let a = -std::f64::consts::TAU * i as f64 / 40.0;
                [a.cos(), a.sin()]
            })
            .collect();
        let (_, sweep) = arc_span([0.0, 0.0], &full).unwrap();
        assert!((sweep + std::f64::consts::TAU).abs() < 1e-9);
        assert_eq!(arc_span([0.0, 0.0], &[[0.0, 0.0], [1.0, 0.0]]), None);
    }

    #[test]
    fn full_circles_become_circle_entities() {
        let mut wall = arc_wall([0.0, 0.0]);
        wall.points = (0..=64)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 64.0;
                [2.0 * a.cos(), 2.0 * a.sin()]
            })
            .collect();
        let p = pairs(&to_dxf(&plan([0.0; 3], vec![story(0, vec![], vec![wall])])).unwrap());
        assert!(entities(&p, "ARC").is_empty());
        let circles = entities(&p, "CIRCLE");
        assert_eq!(circles.len(), 1);
        assert_eq!(get(&circles[0], 40), 2.0);
    }

    #[test]
    fn non_finite_coordinates_are_an_error() {
        let bad = plan(
            [0.0; 3],
            vec![story(
                0,
                vec![],
                vec![line_wall([0.0, f64::NAN], [1.0, 0.0])],
            )],
        );
        let err = to_dxf(&bad).unwrap_err();
        assert!(err.to_string().starts_with("dxf: non-finite"), "{err}");
    }

    /// Reads the file with ezdxf, the reference Python DXF library. Required in CI (which
    /// installs it); elsewhere the test says why it skipped.
    #[test]
    fn ezdxf_reads_the_file() {
        let python = std::process::Command::new("python3")
            .args(["-c", "import ezdxf"])
            .output();
        if !python.is_ok_and(|o| o.status.success()) {
            assert!(
                std::env::var_os("CI").is_none(),
                "CI must have python3 with ezdxf (pip install ezdxf)"
            );
            eprintln!("skipped: python3 with ezdxf is not available (pip install ezdxf)");
            return;
        }
        let path =
            std::env::temp_dir().join(format!("asbuilt-dxf-test-{}.dxf", std::process::id()));
        std::fs::write(&path, to_dxf(&sample_plan()).unwrap()).unwrap();
        let script = r#"
import json, sys, ezdxf
doc = ezdxf.readfile(sys.argv[1])
auditor = doc.audit()
msp = doc.modelspace()
out = {
    "version": doc.dxfversion,
    "insunits": doc.header.get("$INSUNITS"),
    "layers": sorted(l.dxf.name for l in doc.layers),
    "errors": len(auditor.errors),
    "counts": {},
    "arcs": [[a.dxf.radius, a.dxf.start_angle, a.dxf.end_angle, a.dxf.layer] for a in msp.query("ARC")],
    "closed": [p.is_closed for p in msp.query("POLYLINE")],
    "vertices": [len(p.vertices) for p in msp.query("POLYLINE")],
}
for e in msp:
    key = e.dxftype() + "@" + e.dxf.layer
    out["counts"][key] = out["counts"].get(key, 0) + 1
print(json.dumps(out))
"#;
        let run = std::process::Command::new("python3")
            .args(["-c", script])
            .arg(&path)
            .output()
            .unwrap();
        let _ = std::fs::remove_file(&path);
        assert!(
            run.status.success(),
            "ezdxf failed: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        assert_eq!(v["version"], "AC1009");
        assert_eq!(v["insunits"], 6);
        assert_eq!(v["errors"], 0);
        for name in ["STORY_0", "WALLS_0", "STORY_1", "WALLS_1"] {
            assert!(
                v["layers"].as_array().unwrap().iter().any(|l| l == name),
                "missing layer {name}: {}",
                v["layers"]
            );
        }
        assert_eq!(v["counts"]["POLYLINE@STORY_0"], 2);
        assert_eq!(v["counts"]["POLYLINE@STORY_1"], 1);
        assert_eq!(v["counts"]["LINE@WALLS_0"], 1);
        assert_eq!(v["counts"]["LINE@WALLS_1"], 1);
        assert_eq!(v["counts"]["ARC@WALLS_0"], 2);
        assert_eq!(v["closed"], serde_json::json!([true, true, true]));
        assert_eq!(v["vertices"], serde_json::json!([4, 4, 4]));
        for arc in v["arcs"].as_array().unwrap() {
            assert_eq!(arc[0], 2.0);
            assert!((arc[2].as_f64().unwrap() - 90.0).abs() < 1e-6);
        }
    }

    /// ezdxf reads the rooms, doors, windows and centre-line walls back, labels included.
    #[test]
    fn ezdxf_reads_rooms_doors_and_walls() {
        let file = crate::io::outputs::python::temp_file(
            ".dxf",
            &to_dxf(&crate::io::geojson::tests::spaces_plan()).unwrap(),
        );
        let script = r#"
import json, sys, ezdxf
doc = ezdxf.readfile(sys.argv[1])
auditor = doc.audit()
msp = doc.modelspace()
out = {"errors": len(auditor.errors), "layers": sorted(l.dxf.name for l in doc.layers), "counts": {},
       "texts": [[t.dxf.text, t.dxf.layer, t.dxf.align_point.x, t.dxf.align_point.y] for t in msp.query("TEXT")],
       "widths": [[p.dxf.default_start_width, p.dxf.default_end_width, p.is_closed, len(p.vertices)]
                  for p in msp.query("POLYLINE") if p.dxf.layer.startswith("WALL_CENTERLINES")],
       "swings": [[a.dxf.center.x, a.dxf.center.y, a.dxf.radius, a.dxf.start_angle, a.dxf.end_angle]
                  for a in msp.query("ARC") if a.dxf.layer.startswith("DOORS")]}
for e in msp:
    key = e.dxftype() + "@" + e.dxf.layer
    out["counts"][key] = out["counts"].get(key, 0) + 1
print(json.dumps(out))
"#;
        let Some(v) = crate::io::outputs::python::run_json(
            &["ezdxf"],
            script,
            &[file.path().to_str().unwrap()],
        ) else {
            return;
        };
        assert_eq!(v["errors"], 0);
        for name in [
            "ROOMS_0",
            "DOORS_0",
            "WINDOWS_0",
            "WALL_CENTERLINES_0",
            "ROOMS_1",
            "WALL_CENTERLINES_1",
        ] {
            assert!(
                v["layers"].as_array().unwrap().iter().any(|l| l == name),
                "{name}: {}",
                v["layers"]
            );
        }
        assert!(!v["layers"]
            .as_array()
            .unwrap()
            .iter()
            .any(|l| l == "DOORS_1"));
        let c = &v["counts"];
        // Three rooms and R1's column, each a closed ring; two labels per room.
        assert_eq!(c["POLYLINE@ROOMS_0"], 4);
        assert_eq!(c["TEXT@ROOMS_0"], 6);
        assert_eq!(c["POLYLINE@ROOMS_1"], 1);
        // Two doors (gap and leaf) and the opening's gap; a swing per door.
        assert_eq!(c["LINE@DOORS_0"], 5);
        assert_eq!(c["ARC@DOORS_0"], 2);
        assert_eq!(c["LINE@WINDOWS_0"], 1);
        assert_eq!(c["POLYLINE@WALL_CENTERLINES_0"], 6);
        assert_eq!(c["POLYLINE@WALL_CENTERLINES_1"], 4);
        let texts = v["texts"].as_array().unwrap();
        assert!(texts.iter().any(|t| t[0] == "L0-R1" && t[1] == "ROOMS_0"));
        assert!(texts.iter().any(|t| t[0] == "35.48 m2"));
        assert!(texts
            .iter()
            .any(|t| t[0] == "60.00 m2" && t[1] == "ROOMS_1"));
        // Labels sit inside their room: R2 is x 6.06..10, y 0..3.45 (plus the origin).
        let r2 = texts.iter().find(|t| t[0] == "L0-R2").unwrap();
        let (x, y) = (
            r2[2].as_f64().unwrap() - 500_000.0,
            r2[3].as_f64().unwrap() - 5_400_000.0,
        );
        assert!(
            (6.06..10.0).contains(&x) && (0.0..3.45).contains(&y),
            "{r2}"
        );
        let widths = v["widths"].as_array().unwrap();
        assert_eq!(widths[0], serde_json::json!([0.12, 0.12, false, 2]));
        assert_eq!(widths[2], serde_json::json!([0.3, 0.3, false, 2]));
        // D1 is hinged at (6, 1) and runs north: its swing spans 90° to 180°.
        let s = &v["swings"][0];
        assert_eq!(
            (s[0].as_f64().unwrap(), s[1].as_f64().unwrap()),
            (500_006.0, 5_400_001.0)
        );
        assert!((s[2].as_f64().unwrap() - 0.9).abs() < 1e-9);
        assert!(
            (s[3].as_f64().unwrap() - 90.0).abs() < 1e-6
                && (s[4].as_f64().unwrap() - 180.0).abs() < 1e-6
        );
    }
}
