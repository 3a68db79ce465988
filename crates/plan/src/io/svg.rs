//! A readable SVG preview of a floor plan: one panel per story, side by side, north up.
//!
//! All panels share one scale so stories compare at a glance; a scale bar in metres sits under
//! them. Floor area is filled (holes left empty by the even-odd rule), walls are dark strokes,
//! and arc walls are drawn with SVG `A` commands so they stay round at any zoom. Where the
//! story has rooms, each is outlined and labelled with its id and area; walls with thickness
//! are grey bands, doors a gap with their leaf and swing, openings a dashed gap, windows a
//! blue pane in the wall.

use std::fmt::Write;

use base64::Engine;

use crate::geom::{dist, normalize, point_segment_distance, sub, P2};
use crate::io::dxf::arc_span;
use crate::plan::{DoorKind, FloorPlan, Polygon, StoryPlan, WallModel};

/// What to draw beyond the plan itself.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SvgOptions {
    /// Draw each story's wall samples as small dots.
    pub samples: bool,
    /// Draw each story's underlay (its points at mid-height) under the walls, as a layer of
    /// its own (`<g class="underlay">`).
    pub underlay: bool,
}

impl SvgOptions {
    /// Samples follow the run's `emit_samples` parameter, as in the GeoJSON; the underlay its
    /// `svg_underlay` parameter.
    pub fn for_plan(plan: &FloorPlan) -> SvgOptions {
        SvgOptions {
            samples: crate::io::geojson::emit_samples(plan),
            underlay: plan
                .parameters
                .get("svg_underlay")
                .and_then(serde_json::Value::as_bool)
                .unwrap_or(false),
        }
    }
}

/// The plan as an SVG document.
pub fn to_svg(plan: &FloorPlan) -> String {
    to_svg_with(plan, &SvgOptions::for_plan(plan))
}

const MARGIN: f64 = 20.0;
const TITLE: f64 = 28.0;
const FOOTER: f64 = 50.0;
/// Largest story extent drawn at this many pixels.
const TARGET_PX: f64 = 700.0;

/// A story's local bounding box.
#[derive(Clone, Copy)]
struct Bounds {
    lo: P2,
    hi: P2,
}

impl Bounds {
    fn of(story: &StoryPlan, samples: bool) -> Option<Bounds> {
        let rings = story
            .polygons
            .iter()
            .flat_map(|p| std::iter::once(&p.exterior).chain(&p.holes))
            .flatten();
        let walls = story.walls.iter().flat_map(|w| &w.points);
        let dots = story.samples.iter().filter(|_| samples);
        // Exterior walls and their windows lie outside the floor.
        let s = &story.spaces;
        let spaces = s
            .walls
            .iter()
            .flat_map(|w| [&w.a, &w.b])
            .chain(s.windows.iter().flat_map(|w| [&w.a, &w.b]));
        let mut it = rings
            .chain(walls)
            .chain(dots)
            .chain(spaces)
            .filter(|p| p[0].is_finite() && p[1].is_finite());
        let first = *it.next()?;
        Some(it.fold(
            Bounds {
                lo: first,
                hi: first,
            },
            |b, p| Bounds {
                lo: [b.lo[0].min(p[0]), b.lo[1].min(p[1])],
                hi: [b.hi[0].max(p[0]), b.hi[1].max(p[1])],
            },
        ))
    }

    fn size(&self) -> P2 {
        [self.hi[0] - self.lo[0], self.hi[1] - self.lo[1]]
    }
}

/// Maps local metres into one panel's pixels, flipping y so north is up.
struct Panel {
    left: f64,
    top: f64,
    /// Drawing area in pixels, for the panel's frame.
    width: f64,
    height: f64,
    bounds: Bounds,
    scale: f64,
}

impl Panel {
    fn px(&self, p: P2) -> (f64, f64) {
        (
            self.left + (p[0] - self.bounds.lo[0]) * self.scale,
            self.top + (self.bounds.hi[1] - p[1]) * self.scale,
        )
    }
}

/// The plan as an SVG document, with options.
pub fn to_svg_with(plan: &FloorPlan, options: &SvgOptions) -> String {
    let bounds: Vec<Option<Bounds>> = plan
        .stories
        .iter()
        .map(|s| Bounds::of(s, options.samples))
        .collect();
    let extent = bounds
        .iter()
        .flatten()
        .map(|b| b.size()[0].max(b.size()[1]))
        .fold(0.0, f64::max);
    // Pixels per metre; clamped so a tiny or empty plan still gives a sane picture.
    let scale = if extent > 0.0 {
        (TARGET_PX / extent).clamp(0.5, 400.0)
    } else {
        100.0
    };
    let mut panels = Vec::new();
    let mut left = MARGIN;
    let mut body_h: f64 = 0.0;
    for b in &bounds {
        let b = b.unwrap_or(Bounds {
            lo: [0.0, 0.0],
            hi: [1.0, 1.0],
        });
        let [w, h] = b.size();
        // Titles need room even when the story is a sliver.
        let width = (w * scale).max(260.0);
        panels.push(Panel {
            left,
            top: MARGIN + TITLE,
            width,
            height: h * scale,
            bounds: b,
            scale,
        });
        left += width + 2.0 * MARGIN;
        body_h = body_h.max(h * scale);
    }
    let width = left.max(300.0);
    let height = MARGIN + TITLE + body_h + FOOTER;

    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width:.0} {height:.0}" width="{width:.0}" height="{height:.0}" font-family="sans-serif">"#
    );
    let _ = writeln!(
        svg,
        r##"<rect x="0" y="0" width="{width:.0}" height="{height:.0}" fill="#ffffff"/>"##
    );
    if plan.stories.is_empty() {
        let _ = writeln!(
            svg,
            r##"<text x="{MARGIN}" y="{:.0}" font-size="14" fill="#444444">no stories</text>"##,
            MARGIN + 14.0
        );
    }
    for (story, panel) in plan.stories.iter().zip(&panels) {
        draw_story(&mut svg, plan, story, panel, options);
    }
    draw_scale_bar(&mut svg, scale, width, height - FOOTER + 20.0);
    svg.push_str("</svg>\n");
    svg
}

fn draw_story(
    svg: &mut String,
    plan: &FloorPlan,
    story: &StoryPlan,
    panel: &Panel,
    options: &SvgOptions,
) {
    let _ = writeln!(svg, r#"<g class="story" id="story-{}">"#, story.level);
    let _ = writeln!(
        svg,
        r##"<text x="{:.1}" y="{:.1}" font-size="14" fill="#222222">Level {}, floor z = {:.2} m, area {:.1} m²</text>"##,
        panel.left,
        MARGIN + 14.0,
        story.level,
        story.floor_z + plan.origin[2],
        story.area()
    );
    let _ = writeln!(
        svg,
        r##"<rect class="panel" x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="#e3e3e3"/>"##,
        panel.left - 6.0,
        panel.top - 6.0,
        panel.width + 12.0,
        panel.height + 12.0
    );
    // Floor: every ring in one path, so the even-odd rule leaves holes open.
    let mut d = String::new();
    for polygon in &story.polygons {
        for ring in std::iter::once(&polygon.exterior).chain(&polygon.holes) {
            for (i, &p) in ring.iter().enumerate() {
                let (x, y) = panel.px(p);
                let _ = write!(d, "{}{x:.2} {y:.2} ", if i == 0 { "M" } else { "L" });
            }
            if !ring.is_empty() {
                d.push_str("Z ");
            }
        }
    }
    if !d.is_empty() {
        let _ = writeln!(
            svg,
            r##"<path class="floor" d="{}" fill="#dbe7f3" fill-rule="evenodd" stroke="#9db4cc" stroke-width="0.8"/>"##,
            d.trim_end()
        );
    }
    draw_spaces(svg, story, panel);
    if options.underlay {
        draw_underlay(svg, story, panel);
    }
    for wall in &story.walls {
        let Some(d) = wall_path(panel, wall) else {
            continue;
        };
        let _ = writeln!(
            svg,
            r##"<path class="wall" d="{d}" fill="none" stroke="#1d1d1d" stroke-width="2.5" stroke-linecap="round"/>"##
        );
    }
    if options.samples && !story.samples.is_empty() {
        let _ = writeln!(svg, r##"<g class="samples" fill="#d9480f">"##);
        for &p in &story.samples {
            let (x, y) = panel.px(p);
            let _ = writeln!(svg, r#"<circle cx="{x:.2}" cy="{y:.2}" r="1.2"/>"#);
        }
        svg.push_str("</g>\n");
    }
    draw_labels(svg, story, panel);
    svg.push_str("</g>\n");
}

/// The story's underlay as an embedded PNG, cell for cell, clipped to the panel: over the
/// floor and rooms, under the fitted walls.
fn draw_underlay(svg: &mut String, story: &StoryPlan, panel: &Panel) {
    let Some(u) = &story.underlay else {
        return;
    };
    let Ok(png) = crate::io::outputs::underlay::story_png(u) else {
        return;
    };
    let [lo, hi] = u.bounds();
    let (x0, y1) = panel.px(lo);
    let (x1, y0) = panel.px(hi);
    let level = story.level;
    let _ = writeln!(
        svg,
        r#"<clipPath id="underlay-clip-{level}"><rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}"/></clipPath>"#,
        panel.left - 6.0,
        panel.top - 6.0,
        panel.width + 12.0,
        panel.height + 12.0
    );
    let _ = writeln!(
        svg,
        r#"<g class="underlay" id="underlay-{level}" opacity="0.7" clip-path="url(#underlay-clip-{level})"><title>Points at mid-height, {:.2} to {:.2} m above the floor</title><image x="{x0:.2}" y="{y0:.2}" width="{:.2}" height="{:.2}" preserveAspectRatio="none" style="image-rendering:pixelated" href="data:image/png;base64,{}"/></g>"#,
        u.slice_z[0] - story.floor_z,
        u.slice_z[1] - story.floor_z,
        x1 - x0,
        y1 - y0,
        base64::engine::general_purpose::STANDARD.encode(&png)
    );
}

/// Rooms, wall bands, doors, openings and windows, under the fitted walls.
fn draw_spaces(svg: &mut String, story: &StoryPlan, panel: &Panel) {
    let s = &story.spaces;
    for room in &s.rooms {
        let d = polygon_path(panel, &room.polygon);
        if !d.is_empty() {
            let _ = writeln!(
                svg,
                r##"<path class="room" data-id="{}" d="{d}" fill="#eef4e6" fill-rule="evenodd" stroke="#6d8f4e" stroke-width="1"/>"##,
                xml(&room.id)
            );
        }
    }
    for wall in &s.walls {
        let ((x0, y0), (x1, y1)) = (panel.px(wall.a), panel.px(wall.b));
        let w = (wall.thickness * panel.scale).max(1.0);
        let _ = writeln!(
            svg,
            r##"<line class="wall-body" x1="{x0:.2}" y1="{y0:.2}" x2="{x1:.2}" y2="{y1:.2}" stroke="#8a8a8a" stroke-width="{w:.2}"/>"##
        );
    }
    for door in &s.doors {
        let ((x0, y0), (x1, y1)) = (panel.px(door.a), panel.px(door.b));
        // The gap: the wall band cleared where the door is.
        let gap = ((door.depth * panel.scale).max(1.0)) + 2.0;
        let _ = writeln!(
            svg,
            r##"<line class="door-gap" x1="{x0:.2}" y1="{y0:.2}" x2="{x1:.2}" y2="{y1:.2}" stroke="#ffffff" stroke-width="{gap:.2}"/>"##
        );
        match door.kind {
            DoorKind::Opening => {
                let _ = writeln!(
                    svg,
                    r##"<line class="opening" data-id="{}" x1="{x0:.2}" y1="{y0:.2}" x2="{x1:.2}" y2="{y1:.2}" stroke="#b45f06" stroke-width="1.2" stroke-dasharray="4 3"/>"##,
                    xml(&door.id)
                );
            }
            DoorKind::Door => {
                let Some(d) = swing_path(panel, door.a, door.b) else {
                    continue;
                };
                let _ = writeln!(
                    svg,
                    r##"<path class="door" data-id="{}" d="{d}" fill="none" stroke="#b45f06" stroke-width="1.2"/>"##,
                    xml(&door.id)
                );
            }
        }
    }
    for window in &s.windows {
        let ((x0, y0), (x1, y1)) = (panel.px(window.a), panel.px(window.b));
        let _ = writeln!(
            svg,
            r##"<line class="window" data-id="{}" x1="{x0:.2}" y1="{y0:.2}" x2="{x1:.2}" y2="{y1:.2}" stroke="#1c7ed6" stroke-width="3"/>"##,
            xml(&window.id)
        );
    }
}

/// A door's leaf and swing: hinged at `a`, the leaf turned a quarter to the left of a → b,
/// and the arc its free edge sweeps back to `b`.
fn swing_path(panel: &Panel, a: P2, b: P2) -> Option<String> {
    let along = sub(b, a);
    let width = dist(a, b);
    normalize(along)?;
    let open = [a[0] - along[1], a[1] + along[0]];
    let (xa, ya) = panel.px(a);
    let (xo, yo) = panel.px(open);
    let (xb, yb) = panel.px(b);
    let r = width * panel.scale;
    // From the open leaf clockwise in the plan back to b: a negative sweep on screen.
    Some(format!(
        "M{xa:.2} {ya:.2} L{xo:.2} {yo:.2} A{r:.2} {r:.2} 0 0 0 {xb:.2} {yb:.2}"
    ))
}

/// Each room's id and area, at a point well inside it.
fn draw_labels(svg: &mut String, story: &StoryPlan, panel: &Panel) {
    for room in &story.spaces.rooms {
        let Some(p) = label_point(&room.polygon) else {
            continue;
        };
        let (x, y) = panel.px(p);
        let _ = writeln!(
            svg,
            r##"<text class="room-label" x="{x:.2}" y="{y:.2}" font-size="11" fill="#2b3a1f" text-anchor="middle"><tspan x="{x:.2}" dy="-0.2em">{}</tspan><tspan x="{x:.2}" dy="1.2em">{:.1} m²</tspan></text>"##,
            xml(&room.id),
            room.area
        );
    }
}

/// Every ring of a polygon as one path (even-odd), or empty.
fn polygon_path(panel: &Panel, polygon: &Polygon) -> String {
    let mut d = String::new();
    for ring in std::iter::once(&polygon.exterior).chain(&polygon.holes) {
        if ring.len() < 3 {
            continue;
        }
        for (i, &p) in ring.iter().enumerate() {
            let (x, y) = panel.px(p);
            let _ = write!(d, "{}{x:.2} {y:.2} ", if i == 0 { "M" } else { "L" });
        }
        d.push_str("Z ");
    }
    d.trim_end().to_string()
}

/// Text for XML content and attributes.
fn xml(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A point inside the polygon and far from its edges, for a label: the best middle of the
/// inside runs of 15 horizontal lines across it. `None` for a degenerate polygon.
pub(crate) fn label_point(polygon: &Polygon) -> Option<P2> {
    let rings: Vec<&Vec<P2>> = std::iter::once(&polygon.exterior)
        .chain(&polygon.holes)
        .filter(|r| r.len() >= 3)
        .collect();
    let edges = || {
        rings
            .iter()
            .flat_map(|r| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()])))
    };
    let (lo, hi) = polygon
        .exterior
        .iter()
        .filter(|p| p[1].is_finite())
        .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            (lo.min(p[1]), hi.max(p[1]))
        });
    if hi <= lo {
        return None;
    }
    let mut best: Option<(f64, P2)> = None;
    for k in 1..16 {
        let y = lo + (hi - lo) * f64::from(k) / 16.0;
        let mut xs: Vec<f64> = edges()
            .filter(|(p, q)| (p[1] <= y) != (q[1] <= y))
            .map(|(p, q)| p[0] + (y - p[1]) / (q[1] - p[1]) * (q[0] - p[0]))
            .filter(|x| x.is_finite())
            .collect();
        xs.sort_by(f64::total_cmp);
        for run in xs.chunks_exact(2) {
            let m = [(run[0] + run[1]) / 2.0, y];
            let clearance = edges()
                .map(|(p, q)| point_segment_distance(m, p, q))
                .fold(f64::MAX, f64::min);
            if best.is_none_or(|(c, _)| clearance > c) {
                best = Some((clearance, m));
            }
        }
    }
    best.map(|(_, p)| p)
}

/// A wall's path data: a polyline for lines, two `A` arcs for arc walls (two halves, so that
/// full circles and the large-arc flag need no special case).
fn wall_path(panel: &Panel, wall: &crate::plan::Wall) -> Option<String> {
    let first = *wall.points.first()?;
    let last = *wall.points.last()?;
    if wall.points.len() < 2 {
        return None;
    }
    let (x0, y0) = panel.px(first);
    if let WallModel::Arc { center, radius } = wall.model {
        if let Some((start, sweep)) = arc_span(center, &wall.points) {
            let r = radius * panel.scale;
            let at =
                |a: f64| panel.px([center[0] + radius * a.cos(), center[1] + radius * a.sin()]);
            let (xm, ym) = at(start + sweep / 2.0);
            let (x1, y1) = panel.px(last);
            // With y flipped, counter-clockwise in the plan is SVG's positive sweep direction.
            let flag = u8::from(sweep > 0.0);
            return Some(format!(
                "M{x0:.2} {y0:.2} A{r:.2} {r:.2} 0 0 {flag} {xm:.2} {ym:.2} A{r:.2} {r:.2} 0 0 {flag} {x1:.2} {y1:.2}"
            ));
        }
    }
    let mut d = format!("M{x0:.2} {y0:.2}");
    for &p in &wall.points[1..] {
        let (x, y) = panel.px(p);
        let _ = write!(d, " L{x:.2} {y:.2}");
    }
    Some(d)
}

/// A 1-2-5 length near a fifth of the picture, drawn with ticks and its label in metres.
fn draw_scale_bar(svg: &mut String, scale: f64, width: f64, y: f64) {
    let target = (width - 2.0 * MARGIN).max(100.0) / 5.0 / scale;
    let magnitude = 10f64.powf(target.log10().floor());
    let metres = [5.0, 2.0, 1.0]
        .iter()
        .map(|k| k * magnitude)
        .find(|&m| m <= target)
        .unwrap_or(magnitude);
    let len = metres * scale;
    let (x0, x1) = (MARGIN, MARGIN + len);
    let label = if metres >= 1.0 {
        format!("{metres:.0} m")
    } else {
        format!("{} m", (metres * 1000.0).round() / 1000.0)
    };
    let _ = writeln!(
        svg,
        r##"<g class="scale-bar" stroke="#222222" stroke-width="2"><line x1="{x0:.1}" y1="{y:.1}" x2="{x1:.1}" y2="{y:.1}"/><line x1="{x0:.1}" y1="{:.1}" x2="{x0:.1}" y2="{:.1}"/><line x1="{x1:.1}" y1="{:.1}" x2="{x1:.1}" y2="{:.1}"/></g>"##,
        y - 5.0,
        y + 5.0,
        y - 5.0,
        y + 5.0
    );
    let _ = writeln!(
        svg,
        r##"<text class="scale-label" x="{:.1}" y="{:.1}" font-size="13" fill="#222222">{label}</text>"##,
        x1 + 8.0,
        y + 4.0
    );
    let _ = writeln!(
        svg,
        r##"<text x="{:.1}" y="{:.1}" font-size="13" fill="#222222" text-anchor="end">N ↑</text>"##,
        width - MARGIN,
        y + 4.0
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::geojson::tests::{arc_wall, line_wall, plan, square, story};
    use crate::plan::Polygon;

    /// Checks that tags nest and close properly and returns the element names in order.
    fn elements(svg: &str) -> Vec<String> {
        let mut stack: Vec<String> = Vec::new();
        let mut names = Vec::new();
        let mut rest = svg;
        while let Some(start) = rest.find('<') {
            let end = rest[start..].find('>').expect("unclosed tag") + start;
            let tag = &rest[start + 1..end];
            assert!(!tag.contains('<'), "'<' inside a tag: {tag}");
            // Attribute values must keep their quotes balanced.
            assert_eq!(tag.matches('"').count() % 2, 0, "unbalanced quotes: {tag}");
            if let Some(name) = tag.strip_prefix('/') {
                assert_eq!(
                    stack.pop().as_deref(),
                    Some(name.trim()),
                    "mismatched </{name}>"
                );
            } else {
                let name = tag.split_whitespace().next().unwrap().trim_end_matches('/');
                names.push(name.to_string());
                if !tag.ends_with('/') {
                    stack.push(name.to_string());
                }
            }
            rest = &rest[end + 1..];
        }
        assert!(stack.is_empty(), "unclosed elements: {stack:?}");
        assert!(!rest.contains('>'), "stray '>'");
        names
    }

    fn two_story_plan() -> FloorPlan {
        let mut first = Polygon {
            exterior: square(0.0, 0.0, 6.0),
            holes: vec![square(2.0, 2.0, 1.0)],
        };
        first.holes[0].reverse();
        let second = Polygon {
            exterior: square(0.0, 0.0, 4.0),
            holes: vec![],
        };
        plan(
            [0.0, 0.0, 50.0],
            vec![
                story(
                    0,
                    vec![first],
                    vec![line_wall([0.0, 0.0], [6.0, 0.0]), arc_wall([4.0, 4.0])],
                ),
                story(1, vec![second], vec![line_wall([0.0, 0.0], [4.0, 0.0])]),
            ],
        )
    }

    #[test]
    fn well_formed_with_a_panel_per_story() {
        let svg = to_svg(&two_story_plan());
        let names = elements(&svg);
        assert_eq!(names[0], "svg");
        assert_eq!(svg.matches(r#"class="story""#).count(), 2);
        assert!(svg.contains("Level 0, floor z = 50.00 m, area 35.0 m²"));
        assert!(svg.contains("Level 1, floor z = 53.00 m, area 16.0 m²"));
        // The hole is a second subpath of the filled floor, drawn even-odd.
        let floor = svg
            .lines()
            .find(|l| l.contains(r#"class="floor""#))
            .unwrap();
        assert_eq!(floor.matches('M').count(), 2);
        assert!(floor.contains(r#"fill-rule="evenodd""#));
        assert_eq!(svg.matches(r#"class="wall""#).count(), 3);
        // Samples are off in these parameters.
        assert!(!names.contains(&"circle".to_string()));
    }

    #[test]
    fn arc_walls_use_arc_commands_that_end_on_the_wall() {
        let svg = to_svg(&two_story_plan());
        let arc = svg
            .lines()
            .find(|l| l.contains(r#"class="wall""#) && l.contains('A'))
            .expect("an arc path");
        let d = arc
            .split(r#"d=""#)
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap();
        let nums: Vec<f64> = d
            .split(|c: char| c.is_ascii_alphabetic() || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| s.parse().unwrap())
            .collect();
        // M x y, then two arcs of 7 numbers each.
        assert_eq!(nums.len(), 2 + 7 + 7);
        let radius_px = nums[2];
        let (x_end, y_end) = (nums[14], nums[15]);
        // The start is (6, 4) and the end (4, 6) in metres; the end lies up and left on screen,
        // one radius away along each axis.
        assert!((x_end - (nums[0] - radius_px)).abs() < 0.05);
        assert!((y_end - (nums[1] - radius_px)).abs() < 0.05);
        // Counter-clockwise in the plan is a positive sweep on the flipped screen.
        assert_eq!(nums[6], 1.0);
    }

    #[test]
    fn scale_bar_is_labelled_in_metres_and_samples_optional() {
        let p = two_story_plan();
        let svg = to_svg_with(
            &p,
            &SvgOptions {
                samples: true,
                underlay: false,
            },
        );
        elements(&svg);
        let label = svg
            .lines()
            .find(|l| l.contains("scale-label"))
            .expect("a scale label");
        let text = label.split('>').nth(1).unwrap().split('<').next().unwrap();
        let metres: f64 = text.strip_suffix(" m").unwrap().parse().unwrap();
        assert!(metres > 0.0 && metres <= 6.0, "odd scale bar {text}");
        assert_eq!(svg.matches("<circle").count(), 6);
    }

    #[test]
    fn empty_plan_is_still_a_document() {
        let svg = to_svg(&plan([0.0; 3], vec![]));
        assert_eq!(elements(&svg)[0], "svg");
        assert!(svg.contains("no stories"));
    }

    #[test]
    fn rooms_are_labelled_and_doors_windows_drawn() {
        let svg = to_svg(&crate::io::geojson::tests::spaces_plan());
        elements(&svg);
        assert_eq!(svg.matches(r#"class="room""#).count(), 4);
        assert_eq!(svg.matches(r#"class="room-label""#).count(), 4);
        assert_eq!(svg.matches(r#"class="wall-body""#).count(), 10);
        assert_eq!(svg.matches(r#"class="door""#).count(), 2);
        assert_eq!(svg.matches(r#"class="door-gap""#).count(), 3);
        assert_eq!(svg.matches(r#"class="opening""#).count(), 1);
        assert_eq!(svg.matches(r#"class="window""#).count(), 1);
        assert!(svg.contains(">L0-R1</tspan>"));
        assert!(svg.contains(">35.5 m²</tspan>"));
        assert!(svg.contains(">60.0 m²</tspan>"));
        // A door's path: hinge, leaf end, and an arc of the door's width back to its far jamb.
        let door = svg
            .lines()
            .find(|l| l.contains(r#"data-id="L0-D1""#) && l.contains(r#"class="door""#))
            .unwrap();
        let d = door
            .split(r#" d=""#)
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap();
        let nums: Vec<f64> = d
            .split(|c: char| c.is_ascii_alphabetic() || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| s.parse().unwrap())
            .collect();
        assert_eq!(nums.len(), 2 + 2 + 7);
        let (hinge, leaf, end) = ([nums[0], nums[1]], [nums[2], nums[3]], [nums[9], nums[10]]);
        let r = nums[4];
        let d = |p: [f64; 2], q: [f64; 2]| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
        assert!((d(hinge, leaf) - r).abs() < 0.02 && (d(hinge, end) - r).abs() < 0.02);
        // The door runs north along x = 6; its leaf opens to the west (left), on screen too.
        assert!(leaf[0] < hinge[0] - r * 0.99);
    }

    #[test]
    fn labels_sit_inside_their_rooms_away_from_walls() {
        // An L-shaped room: its centroid-ish middle would be outside, in the notch.
        let l = Polygon {
            exterior: vec![
                [0.0, 0.0],
                [6.0, 0.0],
                [6.0, 1.0],
                [1.0, 1.0],
                [1.0, 6.0],
                [0.0, 6.0],
            ],
            holes: vec![],
        };
        let p = label_point(&l).unwrap();
        let inside = |p: P2| (p[0] < 1.0 && p[1] < 6.0) || (p[1] < 1.0 && p[0] < 6.0);
        assert!(inside(p) && p[0] > 0.0 && p[1] > 0.0, "{p:?}");
        // A square with a column in its middle: not on the column.
        let mut hole = square(1.5, 1.5, 1.0);
        hole.reverse();
        let q = label_point(&Polygon {
            exterior: square(0.0, 0.0, 4.0),
            holes: vec![hole],
        })
        .unwrap();
        assert!(
            !(1.5..=2.5).contains(&q[0]) || !(1.5..=2.5).contains(&q[1]),
            "{q:?}"
        );
        assert_eq!(label_point(&Polygon::default()), None);
        assert_eq!(
            label_point(&Polygon {
                exterior: vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]],
                holes: vec![]
            }),
            None
        );
    }
}
