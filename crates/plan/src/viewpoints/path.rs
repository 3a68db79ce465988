//! A mobile scanner's path from the points' times: the points of a short time window were seen
//! from nearly one place, so the blind cone of [`super::cone`] locates the scanner over each
//! window. Windows whose position jumps away from both neighbours are dropped.

use rayon::prelude::*;

use super::cone::{self, ConeParams};
use super::{trajectory, Estimate, PathReport, Thinned, ViewpointSource, ViewpointsReport};
use crate::cloud::{PointCloud, Viewpoints};

/// The evenly thinned cloud the path is estimated from holds at most this many windows.
const MAX_WINDOWS: usize = 4_000;
/// A window's position more than this from the median of its neighbours' is dropped, metres.
const MAX_JUMP: f64 = 0.5;

/// Estimates the path of the mobile scanner that took `cloud` (which has times, no trajectory).
pub(crate) fn estimate_path(cloud: &PointCloud, params: &super::ViewpointsParams) -> Estimate {
    let mut thin = Thinned::new(params.window_points * MAX_WINDOWS, 1);
    for (p, &t) in cloud.xyz.iter().zip(&cloud.time) {
        if t.is_finite() {
            thin.push(0, (t, *p));
        }
    }
    let mut pts = std::mem::take(&mut thin.slots[0].items);
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let windows: Vec<&[(f64, [f32; 3])]> = pts.chunks(params.window_points).collect();
    let cp = ConeParams::default();
    let located: Vec<Option<(f64, cone::Cone)>> = windows
        .par_iter()
        .map(|w| {
            if w.len() < params.window_points / 2 {
                return None;
            }
            let xyz: Vec<[f32; 3]> = w.iter().map(|p| p.1).collect();
            let t = w[w.len() / 2].0;
            cone::locate(&xyz, &cp).map(|c| (t, c))
        })
        .collect();
    let found: Vec<(f64, cone::Cone)> = located.iter().flatten().copied().collect();
    let kept = drop_jumps(&found);
    let samples: Vec<(f64, [f64; 3])> = kept.iter().map(|(t, c)| (*t, c.apex)).collect();
    let mut residuals: Vec<f64> = kept.iter().map(|(_, c)| c.residual).collect();
    residuals.sort_by(f64::total_cmp);
    let length = samples
        .windows(2)
        .map(|w| crate::geom::dist([w[0].1[0], w[0].1[1]], [w[1].1[0], w[1].1[1]]))
        .sum();
    let report = PathReport {
        estimated: true,
        samples: samples.len(),
        windows: windows.len(),
        located: kept.len(),
        residual: residuals.get(residuals.len() / 2).copied(),
        length: Some(length),
    };
    let usable = samples.len() >= 2;
    Estimate {
        viewpoints: usable.then(|| Viewpoints::Trajectory(trajectory(&samples))),
        report: ViewpointsReport {
            source: if usable {
                ViewpointSource::Estimated
            } else {
                ViewpointSource::None
            },
            path: Some(report),
            ..Default::default()
        },
    }
}

/// Drops positions more than [`MAX_JUMP`] from the median of the two before and two after.
fn drop_jumps(found: &[(f64, cone::Cone)]) -> Vec<(f64, cone::Cone)> {
    let xy = |k: usize| [found[k].1.apex[0], found[k].1.apex[1]];
    (0..found.len())
        .filter(|&k| {
            let near: Vec<usize> = (k.saturating_sub(2)..(k + 3).min(found.len()))
                .filter(|&j| j != k)
                .collect();
            if near.len() < 2 {
                return true;
            }
            let median = |axis: usize| {
                let mut v: Vec<f64> = near.iter().map(|&j| xy(j)[axis]).collect();
                v.sort_by(f64::total_cmp);
                (v[(v.len() - 1) / 2] + v[v.len() / 2]) / 2.0
            };
            crate::geom::dist(xy(k), [median(0), median(1)]) <= MAX_JUMP
        })
        .map(|k| found[k])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_walk_through_a_room_is_found() {
        // The scanner stands at 20 places along a line, 10 cm apart; each stop is one window.
        let params = super::super::ViewpointsParams {
            window_points: 54_000,
            ..Default::default()
        };
        let mut cloud = PointCloud::default();
        let at = |k: usize| [2.0 + 0.1 * k as f64, 2.5 + 0.05 * k as f64];
        for k in 0..5 {
            let pts = super::super::cone::tests::scan_room(at(k), -60.0);
            cloud
                .time
                .extend((0..pts.len()).map(|i| k as f64 + i as f64 * 1e-6));
            cloud.xyz.extend(pts);
        }
        let e = estimate_path(&cloud, &params);
        let Some(Viewpoints::Trajectory(path)) = &e.viewpoints else {
            panic!("no path: {:?}", e.report)
        };
        assert_eq!(path.len(), 5);
        for (k, s) in path.iter().enumerate() {
            let err = crate::geom::dist([s.position[0], s.position[1]], at(k));
            assert!(err < 0.02, "window {k}: {err}");
            assert!(s.t >= k as f64 && s.t < k as f64 + 1.0);
        }
        let r = e.report.path.unwrap();
        assert_eq!((r.windows, r.located), (5, 5));
        assert!((r.length.unwrap() - 0.4 * 1.25f64.sqrt()).abs() < 0.05);
    }

    #[test]
    fn outlying_windows_are_dropped() {
        let cone = |x: f64| cone::Cone {
            apex: [x, 0.0, 1.0],
            slope: 1.0,
            support: 40,
            residual: 0.01,
        };
        let found: Vec<(f64, cone::Cone)> = (0..7)
            .map(|k| (k as f64, cone(if k == 3 { 5.0 } else { 0.1 * k as f64 })))
            .collect();
        let kept = drop_jumps(&found);
        assert_eq!(kept.len(), 6);
        assert!(kept.iter().all(|(t, _)| *t != 3.0));
    }
}
