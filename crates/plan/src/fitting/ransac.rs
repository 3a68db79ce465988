//! RANSAC over line and circle models (§3.5).
//!
//! Each round draws triples of unassigned samples, builds the circle through them and their
//! least-squares line, and scores both against every unassigned sample. An inlier is within the
//! distance threshold and has its normal within the angle threshold of the model's normal there.
//! The best model (lowest truncated squared error, MSAC, among those with enough inliers) is
//! refined by least squares, its inliers leave the pool, and the search repeats until no model
//! is found.
//!
//! Beyond the paper: the second and third samples of a triple are drawn from the boundary
//! neighbourhood of the first, not from the whole set, so that most triples lie on one wall; the
//! inliers are still counted over every unassigned sample, so models stay non-local. The paper
//! keeps the model "with the smallest average error"; MSAC also weighs the inlier count, which
//! stops tiny exact subsets from winning.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::cancel::{Cancel, Cancelled};
use crate::fitting::circle::Circle;
use crate::fitting::index::SampleGrid;
use crate::fitting::line::Line;
use crate::fitting::model::Model;
use crate::fitting::{BoundarySamples, FittingParams};

/// The models found and, per sample, the index of the model it belongs to.
pub struct Consensus {
    /// The models found.
    pub models: Vec<Model>,
    /// Per sample, the index of its model in `models`, if any.
    pub assigned: Vec<Option<usize>>,
    /// Inlier count of each model when it was found.
    pub support: Vec<usize>,
}

/// Runs RANSAC until no model with enough inliers is left; stops with `Cancelled` once
/// `cancel` says so.
pub fn find_models(
    samples: &BoundarySamples,
    params: &FittingParams,
    cancel: &Cancel,
) -> Result<Consensus, Cancelled> {
    let n = samples.pos.len();
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut assigned: Vec<Option<usize>> = vec![None; n];
    let mut models = Vec::new();
    let mut support = Vec::new();
    let min_cos = params.inlier_angle.cos();
    let window = params.min_inliers.max(3);
    let mut pool = Pool::new(samples, params);
    loop {
        if pool.ids.len() < params.min_inliers.max(3) {
            break;
        }
        let Some((model, inliers)) =
            best_model(samples, params, &pool, window, min_cos, &mut rng, cancel)?
        else {
            break;
        };
        for &i in &inliers {
            assigned[i] = Some(models.len());
            pool.member[i] = false;
        }
        // Kept in index order, as the random draws index into it.
        pool.ids.retain(|&i| pool.member[i]);
        support.push(inliers.len());
        models.push(model);
    }
    Ok(Consensus {
        models,
        assigned,
        support,
    })
}

/// The unassigned samples, and a grid to find those near a model.
struct Pool {
    grid: SampleGrid,
    /// Unassigned samples in index order.
    ids: Vec<usize>,
    member: Vec<bool>,
}

impl Pool {
    /// Every sample unassigned.
    fn new(samples: &BoundarySamples, params: &FittingParams) -> Pool {
        let n = samples.pos.len();
        Pool {
            grid: SampleGrid::new(&samples.pos, 4.0 * params.inlier_distance),
            ids: (0..n).collect(),
            member: vec![true; n],
        }
    }
}

/// The unassigned samples that `model` accepts, in index order.
fn inliers_of(
    samples: &BoundarySamples,
    pool: &Pool,
    model: &Model,
    max_dist: f64,
    min_cos: f64,
    side: f64,
) -> Vec<usize> {
    let mut out = Vec::new();
    pool.grid.near(model, max_dist, |i| {
        if pool.member[i]
            && model.accepts(samples.pos[i], samples.normal[i], max_dist, min_cos, side)
        {
            out.push(i);
        }
    });
    out.sort_unstable();
    out
}

/// The side of `model` that the samples `ids` face.
fn side(samples: &BoundarySamples, model: &Model, ids: &[usize]) -> f64 {
    model.side_of(ids.iter().map(|&i| (samples.pos[i], samples.normal[i])))
}

/// MSAC cost: squared distance for inliers, the squared threshold for everything else. Only
/// the samples near the model are read: the rest cost the threshold each.
fn msac_cost(
    samples: &BoundarySamples,
    pool: &Pool,
    model: &Model,
    max_dist: f64,
    min_cos: f64,
    side: f64,
) -> (f64, usize) {
    let mut inlier_cost = 0.0;
    let mut count = 0;
    pool.grid.near(model, max_dist, |i| {
        let p = samples.pos[i];
        if pool.member[i] && model.accepts(p, samples.normal[i], max_dist, min_cos, side) {
            inlier_cost += model.distance(p).powi(2);
            count += 1;
        }
    });
    let outliers = (pool.ids.len() - count) as f64;
    (inlier_cost + outliers * max_dist * max_dist, count)
}

/// `ids` split into the runs they form along the boundary (connected through boundary edges
/// between members).
fn boundary_runs(samples: &BoundarySamples, ids: &[usize]) -> Vec<Vec<usize>> {
    let mut member = vec![false; samples.pos.len()];
    ids.iter().for_each(|&i| member[i] = true);
    let mut runs = Vec::new();
    for &start in ids {
        if !member[start] {
            continue;
        }
        member[start] = false;
        let (mut run, mut stack) = (vec![start], vec![start]);
        while let Some(v) = stack.pop() {
            for &w in &samples.adj[v] {
                let w = w as usize;
                if member[w] {
                    member[w] = false;
                    run.push(w);
                    stack.push(w);
                }
            }
        }
        runs.push(run);
    }
    runs
}

/// Samples reachable from `start` within `hops` boundary edges, `start` excluded, in the
/// order a breadth-first search meets them. `marks` (one a sample, all false) is left as found.
fn neighbourhood(
    samples: &BoundarySamples,
    start: usize,
    hops: usize,
    marks: &mut [bool],
) -> Vec<usize> {
    let mut seen = vec![start];
    marks[start] = true;
    let mut from = 0;
    for _ in 0..hops {
        let to = seen.len();
        for k in from..to {
            for &w in &samples.adj[seen[k]] {
                let w = w as usize;
                if !marks[w] {
                    marks[w] = true;
                    seen.push(w);
                }
            }
        }
        if seen.len() == to {
            break;
        }
        from = to;
    }
    seen.iter().for_each(|&v| marks[v] = false);
    seen.remove(0);
    seen
}

fn best_model(
    samples: &BoundarySamples,
    params: &FittingParams,
    pool: &Pool,
    window: usize,
    min_cos: f64,
    rng: &mut ChaCha8Rng,
    cancel: &Cancel,
) -> Result<Option<(Model, Vec<usize>)>, Cancelled> {
    let t = params.inlier_distance;
    let in_pool = &pool.member;
    let ids = &pool.ids;
    let mut best: Option<(f64, Model, f64)> = None;
    let mut needed = params.iterations;
    let mut it = 0;
    let mut marks = vec![false; samples.pos.len()];
    while it < needed.min(params.iterations) {
        // An iteration scores two models against the whole pool: check every time.
        cancel.check()?;
        it += 1;
        let a = ids[rng.random_range(0..ids.len())];
        let near: Vec<usize> = neighbourhood(samples, a, window, &mut marks)
            .into_iter()
            .filter(|&j| in_pool[j])
            .collect();
        let pick = |rng: &mut ChaCha8Rng| {
            if near.len() >= 2 {
                near[rng.random_range(0..near.len())]
            } else {
                ids[rng.random_range(0..ids.len())]
            }
        };
        let (b, c) = (pick(rng), pick(rng));
        if a == b || b == c || a == c {
            continue;
        }
        let tri = [samples.pos[a], samples.pos[b], samples.pos[c]];
        let mut candidates = Vec::with_capacity(2);
        if let Some(l) = Line::fit(&tri) {
            candidates.push(Model::Line(l));
        }
        if params.circles {
            if let Some(c) = Circle::through(tri[0], tri[1], tri[2]) {
                if c.radius <= params.max_radius && c.radius > 2.0 * t {
                    candidates.push(Model::Circle(c));
                }
            }
        }
        for m in candidates {
            let side = side(samples, &m, &[a, b, c]);
            let (cost, count) = msac_cost(samples, pool, &m, t, min_cos, side);
            if count < params.min_inliers || best.as_ref().is_some_and(|(b, _, _)| cost >= *b) {
                continue;
            }
            best = Some((cost, m, side));
            // Adaptive stopping: the chance that a random first sample lies on this model is
            // about count / pool; stop once a better model would have been seen with 99%.
            let w = count as f64 / ids.len() as f64;
            if w < 1.0 {
                needed = ((0.01f64).ln() / (1.0 - w).ln()).ceil().max(30.0) as usize;
            } else {
                needed = it;
            }
        }
    }
    let Some((_, model, side)) = best else {
        return Ok(None);
    };
    Ok(refine(samples, params, pool, model, min_cos, side))
}

/// Least-squares refits on the inliers until the inlier set stops changing (at most 5 times).
/// A circle whose inliers a line explains just as well, or that hardly bows, becomes that line.
fn refine(
    samples: &BoundarySamples,
    params: &FittingParams,
    pool: &Pool,
    model: Model,
    min_cos: f64,
    side: f64,
) -> Option<(Model, Vec<usize>)> {
    let t = params.inlier_distance;
    let mut model = model;
    let mut inliers = inliers_of(samples, pool, &model, t, min_cos, side);
    // A refit may flip a line's normal: each refit takes its side from the inliers, which
    // all face one way.
    for _ in 0..5 {
        let pts: Vec<_> = inliers.iter().map(|&i| samples.pos[i]).collect();
        let Some(next) = model.refit(&pts) else { break };
        let next_side = self::side(samples, &next, &inliers);
        if let Model::Circle(c) = next {
            if c.radius > params.max_radius {
                break;
            }
        }
        let next_inliers = inliers_of(samples, pool, &next, t, min_cos, next_side);
        if next_inliers.len() < inliers.len() {
            break;
        }
        let done = next_inliers == inliers;
        model = next;
        inliers = next_inliers;
        if done {
            break;
        }
    }
    // A last fit on the inliers nearest the model: near a tangent the wider band also holds
    // samples of the adjoining straight wall, which would bias a radius.
    let core: Vec<_> = inliers
        .iter()
        .map(|&i| samples.pos[i])
        .filter(|&p| model.distance(p) <= t / 2.0)
        .collect();
    if core.len() >= params.min_inliers {
        if let Some(m) = model.refit(&core) {
            let m_side = self::side(samples, &m, &inliers);
            let next = inliers_of(samples, pool, &m, t, min_cos, m_side);
            if next.len() >= params.min_inliers {
                model = m;
                inliers = next;
            }
        }
    }
    if let Model::Circle(c) = model {
        let pts: Vec<_> = inliers.iter().map(|&i| samples.pos[i]).collect();
        // Judged run by run along the boundary: two short straight pieces far apart can lie on
        // one wide circle whose arc between them bows a lot.
        let flat = boundary_runs(samples, &inliers).iter().all(|run| {
            let run: Vec<_> = run.iter().map(|&i| samples.pos[i]).collect();
            c.sagitta(&run) < params.min_arc_sagitta
        });
        if let Some(l) = Line::fit(&pts).map(Model::Line) {
            let l_side = self::side(samples, &l, &inliers);
            let as_line = inliers_of(samples, pool, &l, t, min_cos, l_side);
            if as_line.len() >= inliers.len() || (flat && as_line.len() >= params.min_inliers) {
                model = l;
                inliers = as_line;
            }
        }
    }
    (inliers.len() >= params.min_inliers).then_some((model, inliers))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{self, P2};

    /// A path of samples (adjacent in order) with normals, closed into a loop.
    fn loop_samples(pos: Vec<P2>, normal: Vec<Option<P2>>) -> BoundarySamples {
        let n = pos.len();
        let adj = (0..n)
            .map(|i| vec![((i + n - 1) % n) as u32, ((i + 1) % n) as u32])
            .collect();
        let oriented = vec![true; n];
        BoundarySamples {
            pos,
            normal,
            adj,
            oriented,
        }
    }

    #[test]
    fn a_neighbourhood_is_met_hop_by_hop_and_leaves_the_marks_clear() {
        // A loop of 10 samples, and a spur 9 - 10 - 11 hanging off it.
        let mut s = loop_samples(vec![[0.0, 0.0]; 10], vec![None; 10]);
        s.pos.extend([[0.0, 0.0]; 2]);
        s.adj[9].push(10);
        s.adj.push(vec![9, 11]);
        s.adj.push(vec![10]);
        let mut marks = vec![false; 12];
        // Hop 1: 9's neighbours in their order; hop 2: theirs, not met before.
        assert_eq!(
            neighbourhood(&s, 9, 2, &mut marks),
            vec![8, 0, 10, 7, 1, 11]
        );
        assert!(marks.iter().all(|m| !m));
        assert_eq!(neighbourhood(&s, 3, 1, &mut marks), vec![2, 4]);
        // The whole loop is within 5 hops of any sample; 8 hops stop once nothing is new.
        let all = neighbourhood(&s, 0, 8, &mut marks);
        assert_eq!(all.len(), 11);
        assert!(!all.contains(&0));
        assert!(marks.iter().all(|m| !m));
    }

    #[test]
    fn the_two_faces_of_a_thin_wall_get_two_models() {
        // Faces 2 cm apart, well within the inlier distance, facing away from each other.
        let mut pos: Vec<P2> = (0..40).map(|i| [0.05 * i as f64, 0.0]).collect();
        pos.extend((0..40).map(|i| [0.05 * i as f64, 0.02]));
        let normal = (0..80)
            .map(|i| Some(if i < 40 { [0.0, -1.0] } else { [0.0, 1.0] }))
            .collect();
        let s = loop_samples(pos, normal);
        let c = find_models(&s, &FittingParams::default(), &Cancel::never()).unwrap();
        assert_eq!(c.models.len(), 2, "{:?}", c.models);
        assert!(c.assigned[..40].iter().all(|a| *a == c.assigned[0]));
        assert!(c.assigned[40..].iter().all(|a| *a == c.assigned[40]));
        assert_ne!(c.assigned[0], c.assigned[40]);
        for (m, y) in [(c.assigned[0], 0.0), (c.assigned[40], 0.02)] {
            let Model::Line(l) = c.models[m.unwrap()] else {
                panic!("expected lines");
            };
            assert!(l.distance([1.0, y]) < 1e-9);
        }
    }

    #[test]
    fn circle_of_radius_five_is_found_within_half_a_percent() {
        // 628 samples on r = 5 with ±8 mm deterministic radial noise.
        let n = 628;
        let (mut pos, mut normal) = (Vec::new(), Vec::new());
        for i in 0..n {
            let a = i as f64 * std::f64::consts::TAU / n as f64;
            let r = 5.0 + 0.008 * ((i * 7919) % 13) as f64 / 6.0 - 0.008;
            pos.push([1.0 + r * a.cos(), -2.0 + r * a.sin()]);
            normal.push(Some([a.cos(), a.sin()]));
        }
        let s = loop_samples(pos, normal);
        let c = find_models(&s, &FittingParams::default(), &Cancel::never()).unwrap();
        assert_eq!(c.models.len(), 1, "{:?}", c.models);
        let Model::Circle(circle) = c.models[0] else {
            panic!("expected a circle, got {:?}", c.models[0]);
        };
        assert!(
            (circle.radius - 5.0).abs() / 5.0 < 0.005,
            "radius {}",
            circle.radius
        );
        assert!(geom::dist(circle.center, [1.0, -2.0]) < 0.01);
        assert_eq!(c.assigned.iter().filter(|a| a.is_some()).count(), n);
    }

    #[test]
    fn a_barely_bowed_short_wall_is_a_line() {
        // 1.3 m of an 8 m circle (it bows 2.6 cm), plus three samples 2.5 cm outside it at the
        // ends and the middle: the circle holds them all in its 3 cm band, the best line loses
        // those three, so by inlier count alone (the paper's rule) the circle would stay.
        let (r, n) = (8.0, 27);
        let half = 0.65 / r;
        let at = |a: f64, rr: f64| [rr * a.sin(), rr * a.cos()];
        let mut pos: Vec<P2> = (0..n)
            .map(|i| at(-half + 2.0 * half * i as f64 / (n - 1) as f64, r))
            .collect();
        pos.extend([-half, 0.0, half].map(|a| at(a, r + 0.025)));
        let normal = pos
            .iter()
            .map(|p| geom::normalize([-p[0], -p[1]]))
            .collect();
        let s = loop_samples(pos, normal);
        let all: Vec<usize> = (0..s.pos.len()).collect();
        let circle = Model::Circle(Circle {
            center: [0.0, 0.0],
            radius: r,
        });
        let refined = |params: &FittingParams| {
            let min_cos = params.inlier_angle.cos();
            let side = side(&s, &circle, &all);
            let pool = Pool::new(&s, params);
            refine(&s, params, &pool, circle, min_cos, side).expect("a model")
        };
        let paper = FittingParams {
            min_arc_sagitta: 0.0,
            ..FittingParams::default()
        };
        let (kept, inliers) = refined(&paper);
        assert!(matches!(kept, Model::Circle(_)), "{kept:?}");
        assert_eq!(inliers.len(), n + 3);
        let (flat, inliers) = refined(&FittingParams::default());
        assert!(matches!(flat, Model::Line(_)), "{flat:?}");
        assert!(inliers.len() >= n - 2, "{} inliers", inliers.len());
    }

    #[test]
    fn collinear_and_duplicate_samples_give_one_line() {
        let mut pos: Vec<P2> = (0..40)
            .map(|i| [0.05 * i as f64, 0.02 * i as f64])
            .collect();
        pos.extend(pos.clone());
        let normal = vec![geom::normalize([-0.02, 0.05]); pos.len()];
        let s = loop_samples(pos, normal);
        let c = find_models(&s, &FittingParams::default(), &Cancel::never()).unwrap();
        assert_eq!(c.models.len(), 1);
        let Model::Line(l) = c.models[0] else {
            panic!("expected a line");
        };
        assert!(l.distance([1.0, 0.4]) < 1e-9);
        assert!(c.assigned.iter().all(|a| *a == Some(0)));
    }

    #[test]
    fn normals_across_the_line_are_not_inliers() {
        // Two interleaved sets on the same line: half with the line's normal, half turned 90°.
        let pos: Vec<P2> = (0..60).map(|i| [0.05 * i as f64, 0.0]).collect();
        let normal = (0..60)
            .map(|i| Some(if i < 30 { [0.0, 1.0] } else { [1.0, 0.0] }))
            .collect();
        let s = loop_samples(pos, normal);
        let c = find_models(&s, &FittingParams::default(), &Cancel::never()).unwrap();
        assert_eq!(c.models.len(), 1);
        assert!(c.assigned[..30].iter().all(|a| *a == Some(0)));
        assert!(c.assigned[30..].iter().all(|a| a.is_none()));
    }

    #[test]
    fn same_seed_same_models() {
        let pos: Vec<P2> = (0..100)
            .map(|i| {
                let a = i as f64 * 0.0628;
                [3.0 * a.cos(), 3.0 * a.sin()]
            })
            .collect();
        let normal = pos.iter().map(|&p| geom::normalize(p)).collect();
        let s = loop_samples(pos, normal);
        let p = FittingParams::default();
        let a = find_models(&s, &p, &Cancel::never()).unwrap();
        let b = find_models(&s, &p, &Cancel::never()).unwrap();
        assert_eq!(a.models, b.models);
        assert_eq!(a.assigned, b.assigned);
    }
}
