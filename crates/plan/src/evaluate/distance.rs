//! Distances between a plan's boundary and the truth's walls: boundary error and completeness.

use super::EvaluateParams;
use crate::geom::{self, P2};
use crate::simulate::truth::TruthWall;

/// Points every `step` along each ring edge (edge start points included).
fn ring_points(rings: &[Vec<P2>], step: f64) -> Vec<P2> {
    let mut out = Vec::new();
    for r in rings {
        let n = r.len();
        for k in 0..n {
            let (a, b) = (r[k], r[(k + 1) % n]);
            let m = (geom::dist(a, b) / step).ceil().max(1.0) as usize;
            out.extend(
                (0..m).map(|i| geom::add(a, geom::scale(geom::sub(b, a), i as f64 / m as f64))),
            );
        }
    }
    out
}

/// Distance from points along the plan's boundary to the nearest truth wall.
pub(super) fn boundary_distances(plan: &[Vec<P2>], walls: &[TruthWall], step: f64) -> Vec<f64> {
    ring_points(plan, step)
        .into_iter()
        .map(|p| {
            walls
                .iter()
                .map(|w| w.distance(p))
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

/// Mean, 95th percentile and maximum; infinite when empty.
pub(super) fn stats(mut v: Vec<f64>) -> (f64, f64, f64) {
    if v.is_empty() {
        return (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    }
    v.sort_by(f64::total_cmp);
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let k = ((v.len() as f64 * 0.95).ceil() as usize).clamp(1, v.len()) - 1;
    (mean, v[k], v[v.len() - 1])
}

/// Segments bucketed in a uniform grid, for "is anything within r of p" queries.
struct SegmentGrid {
    cell: f64,
    cells: std::collections::HashMap<(i64, i64), Vec<(P2, P2)>>,
}

impl SegmentGrid {
    fn new(rings: &[Vec<P2>], cell: f64) -> SegmentGrid {
        let mut cells: std::collections::HashMap<(i64, i64), Vec<(P2, P2)>> = Default::default();
        for r in rings {
            let n = r.len();
            for k in 0..n {
                let (a, b) = (r[k], r[(k + 1) % n]);
                let key = |v: f64| (v / cell).floor() as i64;
                for i in key(a[0].min(b[0]))..=key(a[0].max(b[0])) {
                    for j in key(a[1].min(b[1]))..=key(a[1].max(b[1])) {
                        cells.entry((i, j)).or_default().push((a, b));
                    }
                }
            }
        }
        SegmentGrid { cell, cells }
    }

    /// True when a segment passes within `r` (at most one cell) of `p`.
    fn near(&self, p: P2, r: f64) -> bool {
        let (ci, cj) = (
            (p[0] / self.cell).floor() as i64,
            (p[1] / self.cell).floor() as i64,
        );
        (ci - 1..=ci + 1).any(|i| {
            (cj - 1..=cj + 1).any(|j| {
                self.cells.get(&(i, j)).is_some_and(|segs| {
                    segs.iter()
                        .any(|&(a, b)| geom::point_segment_distance(p, a, b) <= r)
                })
            })
        })
    }
}

/// Fraction of truth wall length whose points have plan boundary within the tolerance.
pub(super) fn completeness(plan: &[Vec<P2>], walls: &[TruthWall], params: &EvaluateParams) -> f64 {
    let tol = params.completeness_tolerance;
    let grid = SegmentGrid::new(plan, tol.max(0.05));
    let (mut covered, mut total) = (0.0, 0.0);
    for w in walls {
        let len = w.length();
        let n = (len / params.step).ceil().max(1.0) as usize;
        for i in 0..n {
            let p = w.at((i as f64 + 0.5) / n as f64);
            total += len / n as f64;
            if grid.near(p, tol) {
                covered += len / n as f64;
            }
        }
    }
    if total > 0.0 {
        covered / total
    } else {
        0.0
    }
}
