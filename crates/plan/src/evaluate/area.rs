//! Areas and the area IoU of polygon sets, on scanlines exact along x.

use crate::geom::{self, P2};
use crate::plan::Polygon;

/// Open area: exteriors minus holes.
pub fn area(polygons: &[Polygon]) -> f64 {
    polygons
        .iter()
        .map(|p| {
            geom::ring_signed_area(&p.exterior).abs()
                - p.holes
                    .iter()
                    .map(|h| geom::ring_signed_area(h).abs())
                    .sum::<f64>()
        })
        .sum()
}

/// Every ring of every polygon, without a repeated closing vertex.
pub(super) fn rings(polygons: &[Polygon]) -> Vec<Vec<P2>> {
    polygons
        .iter()
        .flat_map(|p| std::iter::once(&p.exterior).chain(&p.holes))
        .map(|r| {
            let mut r = r.clone();
            while r.len() > 1 && r.first() == r.last() {
                r.pop();
            }
            r
        })
        .collect()
}

/// The x intervals inside `rings` (even-odd) along the line at height `y`, sorted and disjoint.
fn spans(rings: &[Vec<P2>], y: f64, xs: &mut Vec<f64>) -> Vec<(f64, f64)> {
    xs.clear();
    for r in rings {
        let n = r.len();
        for k in 0..n {
            let (a, b) = (r[k], r[(k + 1) % n]);
            if (a[1] > y) != (b[1] > y) {
                xs.push(a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]));
            }
        }
    }
    xs.sort_by(f64::total_cmp);
    xs.chunks_exact(2).map(|c| (c[0], c[1])).collect()
}

/// Total lengths of the intersection and the union of two sorted disjoint interval lists.
fn overlap(a: &[(f64, f64)], b: &[(f64, f64)]) -> (f64, f64) {
    let len = |v: &[(f64, f64)]| v.iter().map(|(l, h)| h - l).sum::<f64>();
    let (mut i, mut j, mut inter) = (0, 0, 0.0);
    while i < a.len() && j < b.len() {
        let lo = a[i].0.max(b[j].0);
        let hi = a[i].1.min(b[j].1);
        if hi > lo {
            inter += hi - lo;
        }
        if a[i].1 < b[j].1 {
            i += 1;
        } else {
            j += 1;
        }
    }
    (inter, len(a) + len(b) - inter)
}

/// Area intersection over union, on scanlines `dy` apart (exact along each scanline).
pub fn iou(a: &[Polygon], b: &[Polygon], dy: f64) -> f64 {
    let (ra, rb) = (rings(a), rings(b));
    let ys = ra.iter().chain(&rb).flatten().map(|p| p[1]);
    let (lo, hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), y| {
        (l.min(y), h.max(y))
    });
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return 0.0;
    }
    let rows = ((hi - lo) / dy).ceil() as usize;
    let step = (hi - lo) / rows as f64;
    let mut xs = Vec::new();
    let (mut inter, mut union) = (0.0, 0.0);
    for k in 0..rows {
        let y = lo + (k as f64 + 0.5) * step;
        let (i, u) = overlap(&spans(&ra, y, &mut xs), &spans(&rb, y, &mut xs));
        inter += i;
        union += u;
    }
    if union > 0.0 {
        inter / union
    } else {
        0.0
    }
}
