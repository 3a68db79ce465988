//! A mobile scanner's path from the points' times: over a short time window the scanner moves
//! in a nearly straight line at a nearly steady speed, so the blind cone of [`super::cone`],
//! its apex moving with the scanner, locates it. Each window starts from where the last one
//! left the scanner; windows whose position jumps away from their neighbours are dropped.

use super::cone::{self, ConeParams};
use rayon::prelude::*;

use super::{trajectory, Estimate, PathReport, ViewpointSource, ViewpointsReport};
use crate::cloud::{PointCloud, Viewpoints};

/// A window's position more than this from the median of its neighbours' is dropped, metres.
const MAX_JUMP: f64 = 0.5;

/// Estimates the path of the mobile scanner that took `cloud` (which has times, no trajectory).
/// Windows hold `window_points` consecutive points in time: every point, not a thinned
/// cloud, because thinning would stretch each window over more of the walk.
pub(crate) fn estimate_path(cloud: &PointCloud, params: &super::ViewpointsParams) -> Estimate {
    let mut order: Vec<u32> = (0..cloud.len() as u32)
        .filter(|&i| cloud.time[i as usize].is_finite())
        .collect();
    let time = |i: &u32| cloud.time[*i as usize];
    if !order.windows(2).all(|w| time(&w[0]) <= time(&w[1])) {
        order.par_sort_by(|a, b| time(a).total_cmp(&time(b)));
    }
    let windows: Vec<&[u32]> = order.chunks(params.window_points).collect();
    let cp = ConeParams::default();
    // Each window starts from the last one's scanner, moved on at its speed; a window that
    // finds no cone (a turn breaks the straight line) is tried again in halves, and one that
    // still finds none starts the next from scratch. The walk is cut into one run of windows
    // per thread, each tracked on its own.
    let runs = rayon::current_num_threads().max(1);
    let per_run = windows.len().div_ceil(runs).max(1);
    let found: Vec<(f64, cone::Cone)> = windows
        .par_chunks(per_run)
        .flat_map_iter(|run| {
            let mut found = Vec::new();
            let mut last = None;
            for w in run.iter().filter(|w| w.len() >= params.window_points / 2) {
                let pts: Vec<(f64, [f32; 3])> = w
                    .iter()
                    .map(|&i| (cloud.time[i as usize], cloud.xyz[i as usize]))
                    .collect();
                locate_window(&pts, params.window_points / 4, &cp, &mut last, &mut found);
            }
            found
        })
        .collect();
    let kept = drop_jumps(&found);
    let samples = turn_corners(&kept);
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
        positions: super::thin_path(samples.iter().map(|s| s.1)),
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

/// Locates the scanner over `w`, or over its halves (down to `min` points) when that fails.
fn locate_window(
    w: &[(f64, [f32; 3])],
    min: usize,
    cp: &ConeParams,
    last: &mut Option<(f64, cone::Cone)>,
    found: &mut Vec<(f64, cone::Cone)>,
) {
    let xyz: Vec<[f32; 3]> = w.iter().map(|p| p.1).collect();
    let times: Vec<f64> = w.iter().map(|p| p.0).collect();
    let t_ref = times[times.len() / 2];
    let seed = last.map(|(t, c)| cone::Cone {
        apex: c.position(t_ref - t),
        ..c
    });
    *last = cone::locate_moving(&xyz, &times, t_ref, seed, cp).map(|c| (t_ref, c));
    match last {
        Some(l) => found.push(*l),
        None if w.len() / 2 >= min => {
            let (a, b) = w.split_at(w.len() / 2);
            locate_window(a, min, cp, last, found);
            locate_window(b, min, cp, last, found);
        }
        None => {}
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

/// Two windows' headings this far apart, or more, are a turn between them: cos 30°.
const TURN_COS: f64 = 0.866;
/// A turn's two legs together may be at most this many times the distance walked between the
/// windows (their mean speed times the time between them), plus [`LEG_SLACK`].
const LEG_RATIO: f64 = 1.5;
/// See [`LEG_RATIO`], metres.
const LEG_SLACK: f64 = 0.5;
/// A walker who turns back returns along the line they left by, within this, metres.
const MAX_ASIDE: f64 = 0.5;

/// The windows' positions in time order, with the corner of each turn between two windows put
/// in: a walker keeps a heading, then turns. The straight line between two windows on either
/// side of a corridor's corner cuts through what the corridor walks around (a shaft, a room's
/// corner); the two headings meet at the turn instead. A turn is put in only where each
/// heading reaches the meeting point going forward and the two legs add up to about the
/// distance walked. A walker who turns back (into a doorway and out again, say) turned where
/// the time walked takes them from the one window to the other.
fn turn_corners(kept: &[(f64, cone::Cone)]) -> Vec<(f64, [f64; 3])> {
    let mut out: Vec<(f64, [f64; 3])> = Vec::with_capacity(kept.len());
    for (k, (t, c)) in kept.iter().enumerate() {
        if let Some((prev_t, prev)) = k.checked_sub(1).map(|j| &kept[j]) {
            if let Some(corner) = turn(*prev_t, prev, *t, c) {
                out.push(corner);
            }
        }
        out.push((*t, c.apex));
    }
    out
}

/// The corner between window `a` at time `ta` and window `b` at `tb`, if they turn (see
/// [`turn_corners`]).
fn turn(ta: f64, a: &cone::Cone, tb: f64, b: &cone::Cone) -> Option<(f64, [f64; 3])> {
    use crate::geom::{cross, dot, norm, sub};
    let (sa, sb) = (norm(a.velocity), norm(b.velocity));
    let dt = tb - ta;
    if !(sa > 0.0 && sb > 0.0 && dt > 0.0) {
        return None;
    }
    let (ua, ub) = (
        [a.velocity[0] / sa, a.velocity[1] / sa],
        [b.velocity[0] / sb, b.velocity[1] / sb],
    );
    if dot(ua, ub) > TURN_COS {
        return None;
    }
    let d = sub([b.apex[0], b.apex[1]], [a.apex[0], a.apex[1]]);
    let walked = (sa + sb) / 2.0 * dt;
    let (s, u) = if dot(ua, ub) < -TURN_COS {
        // Turned back: out s along a's heading and u back to b, on one line, s + u walked.
        if cross(ua, d).abs() > MAX_ASIDE {
            return None;
        }
        let ahead = dot(d, ua);
        ((walked + ahead) / 2.0, (walked - ahead) / 2.0)
    } else {
        // a + s·ua = b − u·ub.
        let det = cross(ua, ub);
        (cross(d, ub) / det, cross(ua, d) / det)
    };
    if !(s >= 0.0 && u >= 0.0 && s + u <= LEG_RATIO * walked + LEG_SLACK) {
        return None;
    }
    let w = s / (s + u).max(1e-12);
    Some((
        ta + w * dt,
        [
            a.apex[0] + s * ua[0],
            a.apex[1] + s * ua[1],
            a.apex[2] + w * (b.apex[2] - a.apex[2]),
        ],
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_walk_through_a_room_is_found() {
        // The scanner stops at 5 places along a line; each stop is one window.
        let params = super::super::ViewpointsParams {
            window_points: 54_000,
            ..Default::default()
        };
        let mut cloud = PointCloud::default();
        let at = |k: usize| [2.0 + 0.1 * k as f64, 2.5 + 0.05 * k as f64];
        for k in 0..5 {
            let pts = super::super::cone::tests::scan_room(at(k), -60.0);
            // A spinning head: successive points sweep every direction, so the times are
            // spread over the scan's directions (a stride prime to the count).
            let n = pts.len();
            cloud
                .time
                .extend((0..n).map(|i| k as f64 + ((i * 7919) % n) as f64 / n as f64 * 0.9));
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

    fn walker(apex: [f64; 2], velocity: [f64; 2]) -> cone::Cone {
        cone::Cone {
            apex: [apex[0], apex[1], 1.0],
            velocity,
            slope: 1.0,
            support: 40,
            residual: 0.01,
        }
    }

    #[test]
    fn a_turn_between_two_windows_puts_its_corner_in() {
        // Along x at 1 m/s to the corner (3, 0), then along y: seen at t = 1 and t = 5.
        let (a, b) = (
            walker([1.0, 0.0], [1.0, 0.0]),
            walker([3.0, 2.0], [0.0, 1.0]),
        );
        let (t, p) = turn(1.0, &a, 5.0, &b).expect("a corner");
        assert!((t - 3.0).abs() < 1e-9, "{t}");
        assert!(crate::geom::dist([p[0], p[1]], [3.0, 0.0]) < 1e-9, "{p:?}");
        let path = turn_corners(&[(1.0, a), (5.0, b)]);
        assert_eq!(path.len(), 3);
        assert_eq!(path[1].0, t);
    }

    #[test]
    fn a_walker_who_turns_back_turned_where_the_time_walked_says() {
        // Down into a doorway at 1 m/s, seen at (0, -1) at t = 0 and at (0, -0.5) at t = 3,
        // coming back: out 1.25 m to (0, -2.25), back 1.75 m.
        let (a, b) = (
            walker([0.0, -1.0], [0.0, -1.0]),
            walker([0.0, -0.5], [0.0, 1.0]),
        );
        let (t, p) = turn(0.0, &a, 3.0, &b).expect("a turn back");
        assert!((t - 1.25).abs() < 1e-9, "{t}");
        assert!(
            crate::geom::dist([p[0], p[1]], [0.0, -2.25]) < 1e-9,
            "{p:?}"
        );
        // Not when the second window is off the first one's line.
        assert!(turn(0.0, &a, 3.0, &walker([1.0, -0.5], [0.0, 1.0])).is_none());
    }

    #[test]
    fn no_corner_without_a_turn_one_behind_or_one_too_far() {
        let a = walker([1.0, 0.0], [1.0, 0.0]);
        // Straight on.
        assert!(turn(1.0, &a, 3.0, &walker([3.0, 0.1], [1.0, 0.0])).is_none());
        // The headings meet behind the first window.
        assert!(turn(1.0, &a, 5.0, &walker([-1.0, 2.0], [0.0, 1.0])).is_none());
        // Legs of 8 m where 2 m were walked.
        assert!(turn(1.0, &a, 3.0, &walker([5.0, 4.0], [0.0, 1.0])).is_none());
        // A standing scanner has no heading.
        assert!(turn(1.0, &walker([1.0, 0.0], [0.0; 2]), 5.0, &a).is_none());
    }

    #[test]
    fn outlying_windows_are_dropped() {
        let cone = |x: f64| cone::Cone {
            apex: [x, 0.0, 1.0],
            velocity: [0.0; 2],
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
