//! Topological clean-up of the RANSAC assignment (§3.5): components of a model along the
//! boundary with too few samples are reset, and unassigned samples join a model that is
//! reachable within a few boundary hops.

use crate::cancel::{Cancel, Cancelled};
use crate::cleanup::UnionFind;
use crate::fitting::model::Model;
use crate::fitting::BoundarySamples;
use crate::geom;

/// Unassigns every boundary-connected component of a model with fewer than `min_component`
/// samples. Returns how many samples were reset.
pub fn reset_small_components(
    samples: &BoundarySamples,
    assigned: &mut [Option<usize>],
    min_component: usize,
) -> usize {
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
    let mut reset = 0;
    for v in 0..n {
        if assigned[v].is_some() && size[root[v] as usize] < min_component {
            assigned[v] = None;
            reset += 1;
        }
    }
    reset
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
        assert_eq!(reset_small_components(&s, &mut a, 15), 3);
        assert!(a[40..43].iter().all(|x| x.is_none()));
        let line = Model::Line(Line {
            point: [0.0, 0.0],
            dir: [1.0, 0.0],
        });
        let far = Model::Line(Line {
            point: [0.0, 0.1],
            dir: [1.0, 0.0],
        });
        let grown = grow(&s, &[line, far], &mut a, 15, 0.015, &Cancel::never()).unwrap();
        // Samples 20..=34 reach model 0 within 15 hops; 30..45 reach model 1, which is farther
        // away geometrically, so shared ones go to model 0. Sample 35..=44 reach only model 1.
        assert_eq!(grown, 25);
        assert!(a[20..35].iter().all(|x| *x == Some(0)));
        assert!(a[35..45].iter().all(|x| *x == Some(1)));
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
