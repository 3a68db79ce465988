//! Topological clean-up of the RANSAC assignment (§3.5): components of a model along the
//! boundary with too few samples are reset, and unassigned samples join a model that is
//! reachable within a few boundary hops.

use crate::cancel::{Cancel, Cancelled};
use crate::cleanup::UnionFind;
use crate::fitting::model::Model;
use crate::fitting::BoundarySamples;
use crate::geom;

/// Unassigns every boundary-connected component of a model with fewer than `min_component`
/// samples, except a stub: a component of at least `min_stub` samples (0: none), none more
/// than [`STUB_MAX_STEP`] inlier distances (`band`) from the next, past both of whose ends the
/// boundary turns within [`STUB_TURN_HOPS`] samples as closely spaced. Beyond the paper: the face of a 20 cm stub of wall beside a
/// closet door is a handful of samples between two corners; reset, it grows into the walls
/// around it and the stub leaves the plan. A stray piece of a model along another wall has
/// that wall's samples running straight on at its ends; a few samples far apart on a wall seen
/// sparsely are no stub. Returns how many samples were reset.
pub fn reset_small_components(
    samples: &BoundarySamples,
    models: &[Model],
    assigned: &mut [Option<usize>],
    min_component: usize,
    min_stub: usize,
    band: f64,
) -> usize {
    let max_step = STUB_MAX_STEP * band;
    let n = samples.pos.len();
    let mut uf = UnionFind::new(n);
    for v in 0..n {
        for &w in &samples.adj[v] {
            if assigned[v].is_some() && assigned[v] == assigned[w as usize] {
                uf.union(v as u32, w);
            }
        }
    }
    let root: Vec<u32> = (0..n as u32).map(|v| uf.find(v)).collect();
    let mut size = vec![0usize; n];
    for &r in &root {
        size[r as usize] += 1;
    }
    // Small components, each a list of its samples, decided once each.
    let mut members: std::collections::HashMap<u32, Vec<usize>> = Default::default();
    for v in 0..n {
        if assigned[v].is_some() && size[root[v] as usize] < min_component {
            members.entry(root[v]).or_default().push(v);
        }
    }
    let mut roots: Vec<u32> = members.keys().copied().collect();
    roots.sort_unstable();
    let mut reset = 0;
    for r in roots {
        let part = &members[&r];
        let dense = || {
            part.iter().all(|&v| {
                samples.adj[v].iter().all(|&w| {
                    !part.contains(&(w as usize))
                        || geom::dist(samples.pos[v], samples.pos[w as usize]) <= max_step
                })
            })
        };
        let stub = min_stub > 0
            && part.len() >= min_stub
            && dense()
            && assigned[part[0]].is_some_and(|m| {
                turns_at_both_ends(samples, &models[m], part, max_step, band / 2.0)
            });
        if stub {
            continue;
        }
        for &v in part {
            assigned[v] = None;
            reset += 1;
        }
    }
    reset
}

/// How many samples past a stub's end the boundary must turn.
pub const STUB_TURN_HOPS: usize = 3;
/// A stub's samples, and those past its ends, lie at most this many inlier distances apart.
pub const STUB_MAX_STEP: f64 = 6.0;

/// True when, past every end of the component `part` (on model `m`), the boundary goes on in
/// steps of at most `max_step` to a sample within [`STUB_TURN_HOPS`] hops whose normal is more
/// than 60° from the component's: a corner or the stub's end right there, not a long traced
/// edge across a room. A sample facing back counts when it lies more than `min_offset` off the
/// component's line: the stub's other face.
fn turns_at_both_ends(
    samples: &BoundarySamples,
    m: &Model,
    part: &[usize],
    max_step: f64,
    min_offset: f64,
) -> bool {
    let inside = |v: usize| part.contains(&v);
    let near = |a: usize, b: usize| geom::dist(samples.pos[a], samples.pos[b]) <= max_step;
    let mut ends = 0;
    for &v in part {
        for &w in &samples.adj[v] {
            let w = w as usize;
            if inside(w) {
                continue;
            }
            ends += 1;
            // The face's normal, turned to the side its samples face.
            let normal = m.normal_at(samples.pos[v]);
            let side: f64 = part
                .iter()
                .filter_map(|&u| samples.normal[u].map(|n| geom::dot(n, normal)))
                .sum();
            let normal = geom::scale(normal, if side < 0.0 { -1.0 } else { 1.0 });
            // A corner (more than 60°), or the way back along the stub's other face (behind
            // this one: a spike of the traced boundary turns back on the face's own line).
            let turned = |u: usize| {
                samples.normal[u].is_some_and(|n| {
                    let c = geom::dot(n, normal);
                    c < 0.5 && (c > -0.5 || m.distance(samples.pos[u]) > min_offset)
                })
            };
            if !near(v, w) {
                return false;
            }
            // Outward from the end, away from the component.
            let mut seen = vec![w];
            let mut frontier = vec![w];
            let mut found = turned(w);
            for _ in 1..STUB_TURN_HOPS {
                if found {
                    break;
                }
                let mut next = Vec::new();
                for &u in &frontier {
                    for &x in &samples.adj[u] {
                        let x = x as usize;
                        if !inside(x) && !seen.contains(&x) && near(u, x) {
                            seen.push(x);
                            next.push(x);
                            found |= turned(x);
                        }
                    }
                }
                frontier = next;
            }
            if !found {
                return false;
            }
        }
    }
    ends >= 2
}

/// The way (±1) each model's normal faces: the side most of its samples' oriented normals
/// agree with.
fn model_sides(
    samples: &BoundarySamples,
    models: &[Model],
    assigned: &[Option<usize>],
) -> Vec<f64> {
    let mut sum = vec![0.0; models.len()];
    for (i, m) in assigned.iter().enumerate() {
        if let (Some(m), Some(n)) = (*m, samples.normal[i]) {
            sum[m] += geom::dot(n, models[m].normal_at(samples.pos[i]));
        }
    }
    sum.iter()
        .map(|&s| if s < 0.0 { -1.0 } else { 1.0 })
        .collect()
}

/// True when sample `v` is the other face of a thin wall from model `m`: it lies behind the
/// model (more than `behind` on the side its normal does not face) and faces the other way
/// (more than 120° from the model's side). The two faces of a thin wall lie within a few
/// centimetres of each other (less than the inlier band on a coarse grid), and a face given
/// to the other face's model takes the wall out of the plan. A noisy sample on the model's
/// line whose normal the tracing flipped still joins.
fn other_face(samples: &BoundarySamples, m: &Model, side: f64, v: usize, behind: f64) -> bool {
    let p = samples.pos[v];
    let normal = m.normal_at(p);
    let offset = side * geom::dot(geom::sub(p, m.project(p)), normal);
    offset < -behind && samples.normal[v].is_some_and(|n| side * geom::dot(n, normal) < -0.5)
}

/// Gives each unassigned sample the nearest model (by distance to the model, then by hops)
/// among those owning a sample within `hops` boundary edges, except a model the sample is the
/// other face of (see `other_face`; `behind` is how far behind the model it must lie). Decisions are taken on the
/// assignment as it was before growing, so the result does not depend on sample order.
/// Returns how many samples joined a model; stops with `Cancelled` once `cancel` says so.
pub fn grow(
    samples: &BoundarySamples,
    models: &[Model],
    assigned: &mut [Option<usize>],
    hops: usize,
    behind: f64,
    cancel: &Cancel,
) -> Result<usize, Cancelled> {
    let before = assigned.to_vec();
    let sides = model_sides(samples, models, &before);
    let mut grown = 0;
    for v in 0..samples.pos.len() {
        // Each search visits up to ~2 × hops samples, each looked up in the visited list.
        if v % 64 == 0 {
            cancel.check()?;
        }
        if before[v].is_some() {
            continue;
        }
        let mut seen = vec![v];
        let mut frontier = vec![v];
        let mut best: Option<(f64, usize, usize)> = None;
        for hop in 1..=hops {
            let mut next = Vec::new();
            for &u in &frontier {
                for &w in &samples.adj[u] {
                    let w = w as usize;
                    if seen.contains(&w) {
                        continue;
                    }
                    seen.push(w);
                    next.push(w);
                    if let Some(m) = before[w] {
                        if other_face(samples, &models[m], sides[m], v, behind) {
                            continue;
                        }
                        let d = models[m].distance(samples.pos[v]);
                        let key = (d, hop, m);
                        if best.is_none_or(|b| key < b) {
                            best = Some(key);
                        }
                    }
                }
            }
            if next.is_empty() {
                break;
            }
            frontier = next;
        }
        if let Some((_, _, m)) = best {
            assigned[v] = Some(m);
            grown += 1;
        }
    }
    Ok(grown)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fitting::line::Line;
    use crate::geom::P2;

    fn path(n: usize) -> BoundarySamples {
        BoundarySamples {
            pos: (0..n).map(|i| [0.05 * i as f64, 0.0]).collect(),
            normal: vec![None; n],
            oriented: vec![true; n],
            adj: (0..n)
                .map(|i| {
                    let mut a = Vec::new();
                    if i > 0 {
                        a.push(i as u32 - 1);
                    }
                    if i + 1 < n {
                        a.push(i as u32 + 1);
                    }
                    a
                })
                .collect(),
        }
    }

    #[test]
    fn small_components_reset_and_gaps_grow() {
        let s = path(60);
        // Model 0 owns 0..20 and a stray 3-sample piece at 40..43; model 1 owns 45..60.
        let mut a: Vec<Option<usize>> = vec![None; 60];
        a[..20].fill(Some(0));
        a[40..43].fill(Some(0));
        a[45..].fill(Some(1));
        let line = Model::Line(Line {
            point: [0.0, 0.0],
            dir: [1.0, 0.0],
        });
        let far = Model::Line(Line {
            point: [0.0, 0.1],
            dir: [1.0, 0.0],
        });
        let models = [line, far];
        assert_eq!(reset_small_components(&s, &models, &mut a, 15, 3, 0.03), 3);
        assert!(a[40..43].iter().all(|x| x.is_none()));
        let grown = grow(&s, &models, &mut a, 15, 0.015, &Cancel::never()).unwrap();
        // Samples 20..=34 reach model 0 within 15 hops; 30..45 reach model 1, which is farther
        // away geometrically, so shared ones go to model 0. Sample 35..=44 reach only model 1.
        assert_eq!(grown, 25);
        assert!(a[20..35].iter().all(|x| *x == Some(0)));
        assert!(a[35..45].iter().all(|x| *x == Some(1)));
    }

    /// A path along a wall at x = 0 that goes round a stub 30 cm long and 10 cm thick (south
    /// face on y = 0, end at x = 0.3, north face on y = 0.1), then on up the wall; samples 5 cm
    /// apart, normals facing the free side.
    fn stub_path() -> (BoundarySamples, Vec<Option<usize>>) {
        let mut pts: Vec<(P2, P2, Option<usize>)> = Vec::new();
        for i in 0..20 {
            pts.push(([0.0, -1.0 + 0.05 * i as f64], [1.0, 0.0], Some(1)));
        }
        for i in 1..6 {
            pts.push(([0.05 * i as f64, 0.0], [0.0, -1.0], Some(0)));
        }
        pts.push(([0.3, 0.0], [0.7, -0.7], None));
        pts.push(([0.3, 0.05], [1.0, 0.0], None));
        pts.push(([0.3, 0.1], [0.7, 0.7], None));
        for i in (1..6).rev() {
            pts.push(([0.05 * i as f64, 0.1], [0.0, 1.0], Some(2)));
        }
        for i in 0..20 {
            pts.push(([0.0, 0.1 + 0.05 * i as f64], [1.0, 0.0], Some(1)));
        }
        let mut s = path(pts.len());
        s.pos = pts.iter().map(|p| p.0).collect();
        s.normal = pts.iter().map(|p| Some(p.1)).collect();
        (s, pts.iter().map(|p| p.2).collect())
    }

    fn horizontal(y: f64) -> Model {
        Model::Line(Line {
            point: [0.0, y],
            dir: [1.0, 0.0],
        })
    }

    #[test]
    fn a_stub_between_corners_keeps_its_faces() {
        let (s, mut a) = stub_path();
        let wall = Model::Line(Line {
            point: [0.0, 0.0],
            dir: [0.0, 1.0],
        });
        let models = [horizontal(0.0), wall, horizontal(0.1)];
        let before = a.clone();
        assert_eq!(reset_small_components(&s, &models, &mut a, 15, 3, 0.03), 0);
        assert_eq!(a, before);
        // Turned off, the stub's faces are reset as any small component is.
        assert_eq!(reset_small_components(&s, &models, &mut a, 15, 0, 0.03), 10);
        // Fewer samples than `min_stub`: reset too.
        let mut a = before.clone();
        assert_eq!(reset_small_components(&s, &models, &mut a, 15, 6, 0.03), 10);
        // Samples farther apart than `max_step`: a wall seen sparsely, no stub.
        let mut a = before.clone();
        assert_eq!(
            reset_small_components(&s, &models, &mut a, 15, 3, 0.005),
            10
        );
    }

    #[test]
    fn a_spike_turning_back_on_its_own_line_is_no_stub() {
        // The traced boundary runs out along y = 0 and straight back on the same line (a
        // labelling spike, no wall thickness): facing back, but not behind the face.
        let (mut s, mut a) = stub_path();
        for k in 25..33 {
            s.pos[k][1] = 0.0;
            s.normal[k] = Some([0.0, 1.0]);
        }
        let wall = Model::Line(Line {
            point: [0.0, 0.0],
            dir: [0.0, 1.0],
        });
        let models = [horizontal(0.0), wall, horizontal(0.0)];
        assert_eq!(reset_small_components(&s, &models, &mut a, 15, 3, 0.03), 10);
    }

    #[test]
    fn a_stray_piece_along_a_straight_wall_is_reset() {
        // 40 samples along y = 0 facing south, 5 of them in the middle on a model 2 cm off.
        let mut s = path(40);
        s.normal = vec![Some([0.0, -1.0]); 40];
        let mut a = vec![Some(0); 40];
        a[18..23].fill(Some(1));
        let models = [horizontal(0.0), horizontal(0.02)];
        assert_eq!(reset_small_components(&s, &models, &mut a, 15, 3, 0.03), 5);
        assert!(a[18..23].iter().all(|x| x.is_none()));
    }

    #[test]
    fn a_face_does_not_grow_into_the_other_face_of_a_thin_wall() {
        // A wall 8 cm thick seen from both sides: samples 0..20 on its south face (normals
        // pointing south) own model 0 at y = 0; samples 20..25 run along the north face at
        // y = 0.08, facing north, unassigned; the nearest model is the south face's.
        let mut s = path(25);
        for i in 0..25 {
            let north = i >= 20;
            s.pos[i][1] = if north { 0.08 } else { 0.0 };
            s.normal[i] = Some([0.0, if north { 1.0 } else { -1.0 }]);
        }
        let south = Model::Line(Line {
            point: [0.0, 0.0],
            dir: [1.0, 0.0],
        });
        let mut a: Vec<Option<usize>> = vec![None; 25];
        a[..20].fill(Some(0));
        assert_eq!(
            grow(&s, &[south], &mut a, 15, 0.015, &Cancel::never()).unwrap(),
            0
        );
        assert!(a[20..].iter().all(|x| x.is_none()));
        // Facing the same way, they join it.
        for n in &mut s.normal[20..] {
            *n = Some([0.0, -1.0]);
        }
        assert_eq!(
            grow(&s, &[south], &mut a, 15, 0.015, &Cancel::never()).unwrap(),
            5
        );
    }
}
