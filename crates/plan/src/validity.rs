//! Stage 7: every story polygon leaves the pipeline valid by the OGC Simple Features rules
//! (what GEOS, PostGIS `ST_IsValid` and every GIS check): simple rings that cross nothing,
//! holes inside their exterior, rings touching at isolated points only, a connected interior,
//! no repeated vertices or zero-width spikes, exteriors counter-clockwise and holes clockwise
//! (RFC 7946).
//!
//! Validity is decided on the coordinates the GeoJSON writer emits: each vertex is rounded to
//! the writer's 0.1 mm grid in world coordinates, and all topology is computed exactly on that
//! integer grid. The steps:
//! 1. [`resolve`]: the rings' region by the positive winding rule (an overlay in integer
//!    coordinates, `i_overlay`): where rings cross, the crossing point becomes a vertex and
//!    whatever the rings enclose counter-clockwise stays inside.
//! 2. The region's boundary is traced face by face, turning as sharply left as possible at a
//!    vertex where several boundary edges meet. A ring that comes back to a vertex is split
//!    there, so a pinch becomes two rings (or two polygons) touching at a point, as OGC
//!    requires, and a hole touching its exterior twice splits the polygon in two.
//! 3. [`problems`] checks the result with `geo`'s OGC validation (each polygon, and each pair
//!    of polygons whose boxes meet).
//!
//! [`make_valid`] runs this on the fitted polygons; should they still fail, on the traced
//! boundary (valid by construction up to rounding); should that fail, the offending polygons are
//! dropped. Each fallback is noted, so the plan is always valid and says what it gave up.

use std::collections::HashMap;

use geo::{BoundingRect, Relate, Validation};
use i_overlay::core::fill_rule::FillRule;
use i_overlay::core::overlay::IntOverlayOptions;
use i_overlay::core::simplify::Simplify;
use i_overlay::i_float::int::point::IntPoint;

use crate::geom::P2;
use crate::plan::{FloorPlan, Polygon};

/// Grid units per metre: the GeoJSON writer rounds to 0.1 mm.
pub const UNITS_PER_METRE: f64 = 1.0e4;

/// A point on the grid, in units relative to the grid's base.
type Pt = [i64; 2];

/// Coordinates must stay well inside `i32` for the overlay's exact arithmetic.
const MAX_UNITS: i64 = 1 << 30;

/// The integer grid validity is decided on: world coordinates rounded to 0.1 mm, counted from
/// the grid node nearest the local frame's origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// World x, y of the local frame's origin.
    offset: P2,
    /// The grid node of the local origin, in units.
    base: [i64; 2],
}

impl Grid {
    /// The output grid of a plan whose local frame sits at `origin` (world coordinates).
    pub fn world(origin: [f64; 3]) -> Grid {
        let base = [0, 1].map(|k| (origin[k] * UNITS_PER_METRE).round() as i64);
        Grid {
            offset: [origin[0], origin[1]],
            base,
        }
    }

    /// A 0.1 mm grid on local coordinates (for stages that do not know the origin).
    pub fn local() -> Grid {
        Grid::world([0.0; 3])
    }

    /// The grid node of local point `p`, rounded exactly as the GeoJSON writer rounds; `None`
    /// when `p` is not finite or lies too far away for exact arithmetic.
    pub fn snap(&self, p: P2) -> Option<Pt> {
        let mut out = [0i64; 2];
        for k in 0..2 {
            let u = ((p[k] + self.offset[k]) * UNITS_PER_METRE).round();
            if !u.is_finite() || u.abs() > 9.0e15 {
                return None;
            }
            let rel = u as i64 - self.base[k];
            if rel.abs() > MAX_UNITS {
                return None;
            }
            out[k] = rel;
        }
        Some(out)
    }

    /// The local point whose world position rounds to grid node `q`.
    pub fn unsnap(&self, q: Pt) -> P2 {
        [0, 1].map(|k| (q[k] + self.base[k]) as f64 / UNITS_PER_METRE - self.offset[k])
    }
}

/// A polygon on the grid: exterior counter-clockwise, holes clockwise, rings open.
#[derive(Debug, Clone, PartialEq)]
struct GridPolygon {
    exterior: Vec<Pt>,
    holes: Vec<Vec<Pt>>,
}

/// What [`make_valid`] did to a story.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Validated {
    /// The story's polygons, OGC-valid on the output grid.
    pub polygons: Vec<Polygon>,
    /// Fallbacks worth telling the user about.
    pub notes: Vec<String>,
}

fn orient(a: Pt, b: Pt, c: Pt) -> i128 {
    (b[0] - a[0]) as i128 * (c[1] - a[1]) as i128 - (b[1] - a[1]) as i128 * (c[0] - a[0]) as i128
}

/// Twice the signed area (positive for counter-clockwise rings).
fn area2(ring: &[Pt]) -> i128 {
    let n = ring.len();
    (0..n)
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            a[0] as i128 * b[1] as i128 - b[0] as i128 * a[1] as i128
        })
        .sum()
}

/// Snaps every ring of `polygons` to the grid; rings keep their direction. `None` when a vertex
/// cannot be snapped.
fn snap_rings(polygons: &[Polygon], grid: &Grid) -> Option<Vec<Vec<Pt>>> {
    let mut rings = Vec::new();
    for p in polygons {
        for ring in std::iter::once(&p.exterior).chain(&p.holes) {
            let snapped: Option<Vec<Pt>> = ring.iter().map(|&q| grid.snap(q)).collect();
            rings.push(snapped?);
        }
    }
    Some(rings)
}

/// The region the rings enclose with positive winding (counter-clockwise counts +1), as valid
/// grid polygons. Rings may cross, overlap, touch or be degenerate.
fn resolve_rings(rings: &[Vec<Pt>]) -> Vec<GridPolygon> {
    let contours: Vec<Vec<IntPoint>> = rings
        .iter()
        .filter(|r| r.len() >= 3)
        .map(|r| {
            r.iter()
                .map(|q| IntPoint::new(q[0] as i32, q[1] as i32))
                .collect()
        })
        .collect();
    if contours.is_empty() {
        return Vec::new();
    }
    // Collinear output points are kept: where another ring touches an edge, the overlay has a
    // vertex there, and the tracing below needs it to split the touch.
    let options = IntOverlayOptions {
        preserve_output_collinear: true,
        ..Default::default()
    };
    let shapes = contours.simplify(FillRule::Positive, options);
    let loops: Vec<Vec<Pt>> = shapes
        .into_iter()
        .flatten()
        .map(|c| c.into_iter().map(|p| [p.x as i64, p.y as i64]).collect())
        .collect();
    group(trace_faces(&loops))
}

/// The rings of a region, traced face by face from its directed boundary edges (inside on the
/// left), each split where it comes back to a vertex. Straight-on vertices are dropped.
fn trace_faces(rings: &[Vec<Pt>]) -> Vec<Vec<Pt>> {
    let mut edges: Vec<(Pt, Pt)> = Vec::new();
    for r in rings {
        let n = r.len();
        for i in 0..n {
            let (a, b) = (r[i], r[(i + 1) % n]);
            if a != b {
                edges.push((a, b));
            }
        }
    }
    let mut leaving: HashMap<Pt, Vec<usize>> = HashMap::new();
    for (e, &(a, _)) in edges.iter().enumerate() {
        leaving.entry(a).or_default().push(e);
    }
    let mut used = vec![false; edges.len()];
    let mut out = Vec::new();
    for e0 in 0..edges.len() {
        if used[e0] {
            continue;
        }
        let mut walk = Vec::new();
        let mut e = e0;
        loop {
            used[e] = true;
            let (a, b) = edges[e];
            walk.push(a);
            // The next edge bounds the same face: the first one met turning clockwise from
            // the way back, i.e. the sharpest left turn.
            let back = (a[1] - b[1]) as f64;
            let back = back.atan2((a[0] - b[0]) as f64);
            let next = leaving.get(&b).and_then(|list| {
                list.iter()
                    .copied()
                    .filter(|&f| !used[f] || f == e0)
                    .min_by(|&f, &g| {
                        let turn = |f: usize| {
                            let c = edges[f].1;
                            let d = ((c[1] - b[1]) as f64).atan2((c[0] - b[0]) as f64);
                            let t = (back - d).rem_euclid(std::f64::consts::TAU);
                            if t == 0.0 {
                                std::f64::consts::TAU
                            } else {
                                t
                            }
                        };
                        turn(f).total_cmp(&turn(g))
                    })
            });
            match next {
                Some(f) if f == e0 => break,
                Some(f) => e = f,
                // Unbalanced edges: the overlay never gives them; drop the open walk.
                None => {
                    walk.clear();
                    break;
                }
            }
        }
        out.extend(split_at_repeats(walk).into_iter().filter_map(clean_ring));
    }
    out
}

/// Splits a closed walk into loops that visit each vertex once.
fn split_at_repeats(walk: Vec<Pt>) -> Vec<Vec<Pt>> {
    let mut out = Vec::new();
    let mut stack: Vec<Pt> = Vec::with_capacity(walk.len());
    let mut pos: HashMap<Pt, usize> = HashMap::new();
    for v in walk {
        if let Some(&p) = pos.get(&v) {
            let piece: Vec<Pt> = stack.drain(p..).collect();
            for w in &piece[1..] {
                pos.remove(w);
            }
            stack.push(v);
            out.push(piece);
        } else {
            pos.insert(v, stack.len());
            stack.push(v);
        }
    }
    out.push(stack);
    out
}

/// Drops straight-on vertices and zero-width spikes; `None` when fewer than three vertices or
/// no area remain.
fn clean_ring(ring: Vec<Pt>) -> Option<Vec<Pt>> {
    let mut r = ring;
    loop {
        let n = r.len();
        if n < 3 {
            return None;
        }
        let keep: Vec<bool> = (0..n)
            .map(|i| {
                let (a, b, c) = (r[(i + n - 1) % n], r[i], r[(i + 1) % n]);
                a != b && orient(a, b, c) != 0
            })
            .collect();
        if keep.iter().all(|&k| k) {
            break;
        }
        // Removing every flagged vertex at once could remove both ends of a spike; one at a
        // time from the first keeps the rest intact.
        let first = keep.iter().position(|&k| !k).unwrap_or(0);
        r.remove(first);
    }
    (area2(&r) != 0).then_some(r)
}

/// Even-odd test of a point given in doubled coordinates; `None` on the ring.
fn point_in_ring2(q: Pt, ring: &[Pt]) -> Option<bool> {
    let n = ring.len();
    let mut inside = false;
    for i in 0..n {
        let a = [2 * ring[i][0], 2 * ring[i][1]];
        let b = [2 * ring[(i + 1) % n][0], 2 * ring[(i + 1) % n][1]];
        let o = orient(a, b, q);
        if o == 0
            && q[0] >= a[0].min(b[0])
            && q[0] <= a[0].max(b[0])
            && q[1] >= a[1].min(b[1])
            && q[1] <= a[1].max(b[1])
        {
            return None;
        }
        if (a[1] > q[1]) != (b[1] > q[1]) {
            // The edge crosses the horizontal through q; count it when it passes right of q.
            let right = if b[1] > a[1] { o > 0 } else { o < 0 };
            if right {
                inside = !inside;
            }
        }
    }
    Some(inside)
}

/// Whether `hole` lies inside `ring` (they may touch at vertices, never cross).
fn hole_in(hole: &[Pt], ring: &[Pt]) -> bool {
    let n = hole.len();
    let probes = (0..n).flat_map(|i| {
        let (a, b) = (hole[i], hole[(i + 1) % n]);
        [[2 * a[0], 2 * a[1]], [a[0] + b[0], a[1] + b[1]]]
    });
    for q in probes {
        if let Some(inside) = point_in_ring2(q, ring) {
            return inside;
        }
    }
    false
}

fn bbox(ring: &[Pt]) -> [i64; 4] {
    ring.iter().fold(
        [i64::MAX, i64::MAX, i64::MIN, i64::MIN],
        |[x0, y0, x1, y1], p| [x0.min(p[0]), y0.min(p[1]), x1.max(p[0]), y1.max(p[1])],
    )
}

/// Groups rings into polygons: each clockwise ring goes to the smallest counter-clockwise ring
/// containing it. A clockwise ring inside none encloses nothing and is dropped.
fn group(rings: Vec<Vec<Pt>>) -> Vec<GridPolygon> {
    let (exteriors, holes): (Vec<_>, Vec<_>) = rings.into_iter().partition(|r| area2(r) > 0);
    let boxes: Vec<[i64; 4]> = exteriors.iter().map(|r| bbox(r)).collect();
    let areas: Vec<i128> = exteriors.iter().map(|r| area2(r)).collect();
    let mut polygons: Vec<GridPolygon> = exteriors
        .into_iter()
        .map(|exterior| GridPolygon {
            exterior,
            holes: Vec::new(),
        })
        .collect();
    for hole in holes {
        let hb = bbox(&hole);
        let owner = (0..polygons.len())
            .filter(|&i| {
                let b = boxes[i];
                b[0] <= hb[0] && b[1] <= hb[1] && b[2] >= hb[2] && b[3] >= hb[3]
            })
            .filter(|&i| hole_in(&hole, &polygons[i].exterior))
            .min_by_key(|&i| areas[i]);
        if let Some(i) = owner {
            polygons[i].holes.push(hole);
        }
    }
    // Largest first, as the boundary lists them.
    let mut order: Vec<usize> = (0..polygons.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(areas[i]));
    let mut slots: Vec<Option<GridPolygon>> = polygons.into_iter().map(Some).collect();
    order.into_iter().filter_map(|i| slots[i].take()).collect()
}

fn to_geo(p: &GridPolygon) -> geo::Polygon<f64> {
    let ls = |r: &[Pt]| {
        let mut c: Vec<geo::Coord<f64>> = r
            .iter()
            .map(|q| geo::Coord {
                x: q[0] as f64,
                y: q[1] as f64,
            })
            .collect();
        c.extend(c.first().copied());
        geo::LineString(c)
    };
    geo::Polygon::new(ls(&p.exterior), p.holes.iter().map(|h| ls(h)).collect())
}

/// OGC problems of grid polygons, by `geo`: each polygon on its own, then each pair whose
/// boxes meet must not overlap or share a stretch of boundary. Empty when valid.
fn grid_problems(polygons: &[GridPolygon]) -> Vec<(usize, String)> {
    let geos: Vec<geo::Polygon<f64>> = polygons.iter().map(to_geo).collect();
    let mut out = Vec::new();
    for (i, (p, g)) in polygons.iter().zip(&geos).enumerate() {
        if area2(&p.exterior) <= 0 || p.holes.iter().any(|h| area2(h) >= 0) {
            out.push((i, "a ring has the wrong orientation".to_string()));
        }
        if let Err(e) = g.check_validation() {
            out.push((i, e.to_string()));
        }
    }
    let boxes: Vec<_> = geos.iter().map(|g| g.bounding_rect()).collect();
    for i in 0..geos.len() {
        for j in i + 1..geos.len() {
            let (Some(a), Some(b)) = (boxes[i], boxes[j]) else {
                continue;
            };
            if a.max().x < b.min().x
                || b.max().x < a.min().x
                || a.max().y < b.min().y
                || b.max().y < a.min().y
            {
                continue;
            }
            let m = geos[i].relate(&geos[j]);
            use geo::coordinate_position::CoordPos::{Inside, OnBoundary};
            use geo::dimensions::Dimensions;
            if m.get(Inside, Inside) == Dimensions::TwoDimensional {
                out.push((i, format!("polygons {i} and {j} overlap")));
            } else if m.get(OnBoundary, OnBoundary) == Dimensions::OneDimensional {
                out.push((i, format!("polygons {i} and {j} touch along a line")));
            }
        }
    }
    out
}

fn from_grid(polygons: Vec<GridPolygon>, grid: &Grid) -> Vec<Polygon> {
    polygons
        .into_iter()
        .map(|p| Polygon {
            exterior: p.exterior.iter().map(|&q| grid.unsnap(q)).collect(),
            holes: p
                .holes
                .iter()
                .map(|h| h.iter().map(|&q| grid.unsnap(q)).collect())
                .collect(),
        })
        .collect()
}

/// The region of `polygons` (exteriors counter-clockwise, holes clockwise; they may cross)
/// with positive winding, as valid polygons on `grid`; `Err` with the first problem when the
/// result still fails `geo`'s check (or a vertex cannot be snapped).
pub fn resolve(polygons: &[Polygon], grid: &Grid) -> Result<Vec<Polygon>, String> {
    let rings = snap_rings(polygons, grid).ok_or("a vertex is not finite or too far away")?;
    let resolved = resolve_rings(&rings);
    match grid_problems(&resolved).into_iter().next() {
        None => Ok(from_grid(resolved, grid)),
        Some((_, why)) => Err(why),
    }
}

/// Every OGC problem of `polygons` as they would be written on `grid`, by `geo`; empty when
/// valid. Rings are taken as given (no repair), closed implicitly.
pub fn problems(polygons: &[Polygon], grid: &Grid) -> Vec<String> {
    let mut out = Vec::new();
    let mut grid_polygons = Vec::new();
    for (i, p) in polygons.iter().enumerate() {
        let snap = |r: &[P2]| -> Option<Vec<Pt>> {
            let mut v: Vec<Pt> = Vec::with_capacity(r.len());
            for &q in r {
                let s = grid.snap(q)?;
                // The writer drops repeated positions; so does the check.
                if v.last() != Some(&s) {
                    v.push(s);
                }
            }
            while v.len() > 1 && v.first() == v.last() {
                v.pop();
            }
            Some(v)
        };
        let (Some(exterior), Some(holes)) = (
            snap(&p.exterior),
            p.holes.iter().map(|h| snap(h)).collect::<Option<Vec<_>>>(),
        ) else {
            out.push(format!(
                "polygon {i}: a vertex is not finite or too far away"
            ));
            continue;
        };
        grid_polygons.push(GridPolygon { exterior, holes });
    }
    out.extend(grid_problems(&grid_polygons).into_iter().map(|(_, w)| w));
    out
}

/// Every OGC problem of a plan's story polygons as the GeoJSON writer emits them, per story.
pub fn plan_problems(plan: &FloorPlan) -> Vec<String> {
    let grid = Grid::world(plan.origin);
    plan.stories
        .iter()
        .flat_map(|s| {
            problems(&s.polygons, &grid)
                .into_iter()
                .map(move |p| format!("story {}: {p}", s.level))
        })
        .collect()
}

/// Makes a story's polygons valid on `grid`: the fitted polygons resolved; failing that, the
/// traced boundary resolved; failing that, the traced polygons that pass on their own. Never
/// fails; every fallback is noted.
pub fn make_valid(fitted: &[Polygon], traced: &[Polygon], grid: &Grid) -> Validated {
    let fitted_err = match resolve(fitted, grid) {
        Ok(polygons) => {
            return Validated {
                polygons,
                notes: Vec::new(),
            }
        }
        Err(e) => e,
    };
    let mut notes = vec![format!(
        "validity: the fitted walls could not be made valid ({fitted_err}); the traced boundary is used"
    )];
    if let Ok(polygons) = resolve(traced, grid) {
        return Validated { polygons, notes };
    }
    // Keep only the traced polygons that are valid alone and meet no other kept one.
    let mut kept: Vec<Polygon> = Vec::new();
    let mut dropped = 0;
    for p in traced {
        let mut trial = kept.clone();
        match resolve(std::slice::from_ref(p), grid) {
            Ok(mut ok) => {
                trial.append(&mut ok);
                if problems(&trial, grid).is_empty() {
                    kept = trial;
                    continue;
                }
                dropped += 1;
            }
            Err(_) => dropped += 1,
        }
    }
    notes.push(format!(
        "validity: {dropped} traced polygon(s) could not be made valid and were left out"
    ));
    Validated {
        polygons: kept,
        notes,
    }
}

#[cfg(test)]
mod tests;
