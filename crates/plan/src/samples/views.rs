//! Which scanner positions saw a wall sample (§3.1): the normal is flipped toward them, and a
//! sample seen only from far away is dropped.
//!
//! A point's viewer is its static scan's pose (by the `scan` slot), or the mobile trajectory's
//! position at the point's time. Only viewpoints standing within the story are listed
//! ([`Story::holds_viewpoint`]), so a scanner on another floor never becomes a viewpoint of
//! this one; nor does one on a gallery that sees down into a double-height room of the story
//! below, over its walls (its lines of sight would cut those walls in 2D). When no scanner
//! stands near the story at all (heights unknown), all are listed.

use super::grid::Carry;
use crate::cloud::{PointCloud, TrajectorySample, Viewpoints};
use crate::geom::{dist, dot, sub, P2};
use crate::stories::Story;

/// Spacing of the viewpoints listed along a mobile trajectory, metres. A point's line of sight
/// starts at the listed viewpoint nearest in time, up to half this from where the scanner
/// really was. Rays grazing a column are that sensitive: from 5 cm along the path, rays that
/// passed a 30 cm column in the scan cut through it in the triangulation and filled it in.
pub(super) const TRAJECTORY_SPACING: f64 = 0.01;

/// At most this many viewpoints are kept per sample, evenly spread over those that saw it: a
/// mobile scanner sees a wall cell from dozens of listed positions, and more lines of sight
/// from nearly the same place add walking time, not evidence.
pub(super) const MAX_SEEN_FROM: usize = 16;

/// The scanner positions of one story, and how to find each point's viewer.
pub(super) struct Views<'a> {
    kind: Kind<'a>,
    /// Listed viewpoints, local x, y.
    pub viewpoints: Vec<P2>,
    /// The trajectory through the story, local x, y, in time order; non-finite at its gaps.
    pub path: Vec<P2>,
}

enum Kind<'a> {
    None,
    Static {
        scan: &'a [u16],
        poses: Vec<P2>,
        /// Per scan slot, its index in `viewpoints` when listed.
        listed: Vec<Option<u32>>,
    },
    Trajectory {
        traj: Vec<TrajectorySample>,
        /// Times of the listed viewpoints, ascending.
        listed_t: Vec<f64>,
        /// Consecutive samples farther apart than this are a gap in the path (see
        /// [`max_step`]): nothing is interpolated across it.
        max_step: f64,
    },
}

/// What the scanners say about one sample.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Seen {
    /// The normal, flipped toward the scanners when any saw the sample.
    pub normal: P2,
    /// Listed viewpoints that saw the sample, ascending.
    pub seen_from: Vec<u32>,
    /// Horizontal distance to the nearest scanner that saw it; `None` without poses.
    pub nearest: Option<f64>,
}

impl<'a> Views<'a> {
    /// The `viewpoints` (the cloud's own, or estimated) of `cloud`'s scans in `story`.
    pub fn new(cloud: &'a PointCloud, viewpoints: &Viewpoints, story: &Story) -> Views<'a> {
        let in_story = |p: &[f64; 3]| story.holds_viewpoint(p[2]);
        // Heights are taken as unknown only when no scanner stands anywhere near the story.
        let reach = story.top_z - story.floor_z;
        let near = |p: &[f64; 3]| p[2] >= story.z_min - reach && p[2] < story.z_max + reach;
        match viewpoints {
            Viewpoints::Static(poses) if !poses.is_empty() => {
                let any_inside = poses.iter().any(|p| near(&p.position));
                let mut viewpoints = Vec::new();
                let listed = poses
                    .iter()
                    .map(|p| {
                        let known = p.position.iter().all(|c| c.is_finite());
                        (known && (!any_inside || in_story(&p.position))).then(|| {
                            viewpoints.push([p.position[0], p.position[1]]);
                            viewpoints.len() as u32 - 1
                        })
                    })
                    .collect();
                let kind = Kind::Static {
                    scan: &cloud.scan,
                    poses: poses
                        .iter()
                        .map(|p| [p.position[0], p.position[1]])
                        .collect(),
                    listed,
                };
                Views {
                    kind,
                    viewpoints,
                    path: Vec::new(),
                }
            }
            Viewpoints::Trajectory(samples) if !samples.is_empty() => {
                let mut traj = samples.clone();
                traj.sort_by(|a, b| a.t.total_cmp(&b.t));
                let any_inside = traj.iter().any(|s| near(&s.position));
                let inside: Vec<&TrajectorySample> = traj
                    .iter()
                    .filter(|s| !any_inside || in_story(&s.position))
                    .collect();
                let max_step = max_step(&traj);
                let path = broken_at_gaps(&inside, max_step);
                let (viewpoints, listed_t) = list_along(&inside, TRAJECTORY_SPACING);
                let kind = Kind::Trajectory {
                    max_step,
                    traj,
                    listed_t,
                };
                Views {
                    kind,
                    viewpoints,
                    path,
                }
            }
            _ => Views {
                kind: Kind::None,
                viewpoints: Vec::new(),
                path: Vec::new(),
            },
        }
    }

    /// What the grid must carry per point for [`Self::observe`]: scan slots, times, or nothing.
    pub fn carry(&self) -> Carry {
        match &self.kind {
            Kind::Static { scan, .. } if !scan.is_empty() => Carry::Slots,
            Kind::Trajectory { .. } => Carry::Times,
            _ => Carry::Nothing,
        }
    }

    /// The viewer of the `k`-th point of a neighbourhood whose scan slots or times (as
    /// [`Self::carry`] asks) are `slots` or `times`: its position and listed viewpoint.
    fn viewer(&self, slots: &[u16], times: &[f64], k: usize) -> Option<(P2, Option<u32>)> {
        match &self.kind {
            Kind::None => None,
            Kind::Static {
                scan,
                poses,
                listed,
            } => {
                // A cloud without scan slots and a single pose was all seen from it.
                let slot = match slots.get(k) {
                    Some(&s) => s as usize,
                    None if scan.is_empty() && poses.len() == 1 => 0,
                    None => return None,
                };
                Some((*poses.get(slot)?, *listed.get(slot)?))
            }
            Kind::Trajectory {
                traj,
                listed_t,
                max_step,
            } => {
                let t = *times.get(k)?;
                Some((
                    position_at(traj, t, *max_step)?,
                    nearest_in_time(listed_t, t),
                ))
            }
        }
    }

    /// Orients `normal` by a majority of the points `pts` around the sample at `pos` that lie
    /// on its face, within `half` of it along the normal (each votes for the side its scanner
    /// stood on; a tie goes to the nearest scanner), and lists the viewpoints that saw that
    /// face from in front. `slots` or `times` say who saw each point (see [`Self::carry`]).
    ///
    /// Points off the face belong to something else: the far face of a thin wall, or a
    /// perpendicular wall at a junction. Their scanners stood elsewhere, and a line of sight
    /// from behind the face would cut the wall it ends on.
    pub fn observe(
        &self,
        pts: &[[f32; 3]],
        slots: &[u16],
        times: &[f64],
        half: f64,
        pos: P2,
        normal: P2,
    ) -> Seen {
        let off = |k: usize| {
            let p = pts[k];
            dot(normal, [p[0] as f64 - pos[0], p[1] as f64 - pos[1]]).abs()
        };
        // A sample whose points all lie off its face (a median between two) keeps them all.
        let any_on = (0..pts.len()).any(|k| off(k) <= half);
        let on_face = |k: usize| !any_on || off(k) <= half;
        let mut tally = Tally::new(pos, normal);
        match &self.kind {
            Kind::Static { .. } => {
                // The points of one scan share their viewer: count them per scan slot, in the
                // order the slots first appear, and weigh each viewer once. Votes, the nearest
                // viewer (the first at the least distance) and the list come out as if each
                // point were weighed in turn.
                let mut per_slot: Vec<(u16, usize)> = Vec::new();
                for k in (0..pts.len()).filter(|&k| on_face(k)) {
                    let Some(slot) = self.slot(slots, k) else {
                        continue;
                    };
                    match per_slot.iter_mut().find(|(s, _)| *s == slot) {
                        Some((_, c)) => *c += 1,
                        None => per_slot.push((slot, 1)),
                    }
                }
                for (slot, count) in per_slot {
                    if let Some((v, id)) = self.static_viewer(slot as usize) {
                        tally.add(v, id, count);
                    }
                }
            }
            _ => {
                for k in (0..pts.len()).filter(|&k| on_face(k)) {
                    if let Some((v, id)) = self.viewer(slots, times, k) {
                        tally.add(v, id, 1);
                    }
                }
            }
        }
        tally.seen(normal)
    }

    /// The scan slot of the `k`-th point, for static scans.
    fn slot(&self, slots: &[u16], k: usize) -> Option<u16> {
        let Kind::Static { scan, poses, .. } = &self.kind else {
            return None;
        };
        match slots.get(k) {
            Some(&s) => Some(s),
            // A cloud without scan slots and a single pose was all seen from it.
            None if scan.is_empty() && poses.len() == 1 => Some(0),
            None => None,
        }
    }

    fn static_viewer(&self, slot: usize) -> Option<(P2, Option<u32>)> {
        let Kind::Static { poses, listed, .. } = &self.kind else {
            return None;
        };
        // A scan whose position could not be estimated is non-finite: it saw nothing.
        let p = poses
            .get(slot)
            .filter(|p| p[0].is_finite() && p[1].is_finite())?;
        Some((*p, *listed.get(slot)?))
    }
}

/// The votes of the points around one sample, and the viewers that saw it.
struct Tally {
    pos: P2,
    normal: P2,
    votes: i64,
    /// Distance and side of the nearest viewer.
    nearest: Option<(f64, f64)>,
    /// Listed viewers, with the side of the unoriented normal each stood on.
    seen_from: Vec<(u32, f64)>,
}

impl Tally {
    fn new(pos: P2, normal: P2) -> Tally {
        Tally {
            pos,
            normal,
            votes: 0,
            nearest: None,
            seen_from: Vec::new(),
        }
    }

    /// `count` points seen from viewer `v` (listed as `id`).
    fn add(&mut self, v: P2, id: Option<u32>, count: usize) {
        let side = dot(self.normal, sub(v, self.pos));
        self.votes += side.signum() as i64 * count as i64;
        let d = dist(v, self.pos);
        if self.nearest.is_none_or(|(best, _)| d < best) {
            self.nearest = Some((d, side));
        }
        if let Some(id) = id {
            self.seen_from.push((id, side));
        }
    }

    fn seen(self, normal: P2) -> Seen {
        let votes = self.votes;
        let flip = votes < 0 || (votes == 0 && self.nearest.is_some_and(|(_, side)| side < 0.0));
        // A viewer behind the oriented face saw it through the wall, or saw another face.
        let mut seen_from: Vec<u32> = self
            .seen_from
            .iter()
            .filter(|&&(_, side)| if flip { side <= 0.0 } else { side >= 0.0 })
            .map(|&(id, _)| id)
            .collect();
        seen_from.sort_unstable();
        seen_from.dedup();
        if seen_from.len() > MAX_SEEN_FROM {
            let n = seen_from.len();
            seen_from = (0..MAX_SEEN_FROM)
                .map(|k| seen_from[k * n / MAX_SEEN_FROM])
                .collect();
        }
        Seen {
            normal: if flip {
                [-normal[0], -normal[1]]
            } else {
                normal
            },
            seen_from,
            nearest: self.nearest.map(|(d, _)| d),
        }
    }
}

/// Positions every `spacing` metres along the time-ordered trajectory samples, interpolated
/// between them, with their times: the first sample, then one each time the path has run
/// `spacing` further.
fn list_along(samples: &[&TrajectorySample], spacing: f64) -> (Vec<P2>, Vec<f64>) {
    let (mut points, mut times) = (Vec::new(), Vec::new());
    let Some(first) = samples.first() else {
        return (points, times);
    };
    let xy = |s: &TrajectorySample| [s.position[0], s.position[1]];
    points.push(xy(first));
    times.push(first.t);
    // Path length run so far, and where the next listed position falls.
    let (mut run, mut k) = (0.0, 1u64);
    for w in samples.windows(2) {
        let (a, b) = (xy(w[0]), xy(w[1]));
        let len = dist(a, b);
        if !len.is_finite() {
            continue;
        }
        // Multiples of the spacing, not a running sum, so rounding does not drift.
        while k as f64 * spacing <= run + len + 1e-9 {
            let f = ((k as f64 * spacing - run) / len).clamp(0.0, 1.0);
            points.push([a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]);
            times.push(w[0].t + f * (w[1].t - w[0].t));
            k += 1;
        }
        run += len;
    }
    (points, times)
}

/// The samples' x, y in order, with a non-finite point where two consecutive samples are more
/// than `max_step` apart: the scanner's way across a gap is unknown, and the straight line
/// may cross a wall.
fn broken_at_gaps(samples: &[&TrajectorySample], max_step: f64) -> Vec<P2> {
    let mut path = Vec::with_capacity(samples.len());
    for (k, s) in samples.iter().enumerate() {
        if k > 0 && dist3(samples[k - 1].position, s.position) > max_step {
            path.push([f64::NAN; 2]);
        }
        path.push([s.position[0], s.position[1]]);
    }
    path
}

/// Consecutive trajectory samples farther apart than this, in 3D, leave a gap in the path:
/// [`GAP_STEPS`] times the median step, and never under [`MIN_GAP`]. A path estimated from the
/// points has gaps where windows could not be located (on stairs, say); a straight line across
/// one can run through a closed shaft, and lines of sight from there fill it in.
fn max_step(traj: &[TrajectorySample]) -> f64 {
    let mut steps: Vec<f64> = traj
        .windows(2)
        .map(|w| dist3(w[0].position, w[1].position))
        .filter(|d| d.is_finite())
        .collect();
    (GAP_STEPS * median(&mut steps)).max(MIN_GAP)
}

/// The (upper) median, infinite for none.
fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::INFINITY;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// See [`max_step`].
const GAP_STEPS: f64 = 3.0;
/// See [`max_step`], metres: a scanner carried at walking pace, sampled every few tenths of a
/// second, moves less; a given trajectory's samples come much closer.
const MIN_GAP: f64 = 2.0;

fn dist3(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The trajectory's x, y at time `t`, interpolated linearly; `None` between two samples more
/// than `max_step` apart, and before the first or after the last. An estimated path starts and
/// ends where the first and last windows were located, and the scanner was elsewhere before
/// and after: seen from the path's end, the far walls of a corridor's end cut a shaft beside it
/// (sparse mobile office without trajectory, level 0: IoU 0.9527 with the ends held, 0.9636).
fn position_at(traj: &[TrajectorySample], t: f64, max_step: f64) -> Option<P2> {
    if !t.is_finite() {
        return None;
    }
    let k = traj.partition_point(|s| s.t <= t);
    let xy = |s: &TrajectorySample| [s.position[0], s.position[1]];
    match k {
        // At the last sample's time exactly, the last sample.
        k if k == traj.len() => traj.last().filter(|s| s.t == t).map(xy),
        0 => None,
        k => {
            let (a, b) = (&traj[k - 1], &traj[k]);
            if dist3(a.position, b.position) > max_step {
                return None;
            }
            let w = if b.t > a.t {
                (t - a.t) / (b.t - a.t)
            } else {
                0.0
            };
            Some([
                a.position[0] + w * (b.position[0] - a.position[0]),
                a.position[1] + w * (b.position[1] - a.position[1]),
            ])
        }
    }
}

/// The index of the time in `sorted` nearest to `t`.
fn nearest_in_time(sorted: &[f64], t: f64) -> Option<u32> {
    if sorted.is_empty() || !t.is_finite() {
        return None;
    }
    let k = sorted.partition_point(|&s| s <= t);
    let best = match k {
        0 => 0,
        k if k == sorted.len() => k - 1,
        k if t - sorted[k - 1] <= sorted[k] - t => k - 1,
        k => k,
    };
    Some(best as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::ScanPose;

    fn story() -> Story {
        Story::flat(0, 0.0, 3.0, -0.5, 3.5)
    }

    fn pose(index: u32, position: [f64; 3]) -> ScanPose {
        ScanPose {
            index,
            position,
            quaternion: [1.0, 0.0, 0.0, 0.0],
        }
    }

    #[test]
    fn static_poses_on_another_floor_are_not_listed() {
        let cloud = PointCloud {
            xyz: vec![[0.0, 0.0, 1.0]; 4],
            scan: vec![0, 0, 1, 1],
            scan_ids: vec![1, 2],
            viewpoints: Viewpoints::Static(vec![
                pose(1, [0.0, -2.0, 1.5]),
                pose(2, [5.0, 5.0, 4.5]),
            ]),
            ..Default::default()
        };
        let views = Views::new(&cloud, &cloud.viewpoints, &story());
        assert_eq!(views.viewpoints, vec![[0.0, -2.0]]);
        // Points 0 and 1 come from the listed scan, 2 and 3 from the upper one: a tie of
        // votes (the normal faces both), broken by the nearer scanner at y = -2.
        assert_eq!(views.carry(), Carry::Slots);
        let seen = views.observe(&cloud.xyz, &cloud.scan, &[], 0.025, [0.0, 0.0], [0.0, 1.0]);
        assert_eq!(seen.normal, [0.0, -1.0]);
        assert_eq!(seen.seen_from, vec![0]);
        assert_eq!(seen.nearest, Some(2.0));
    }

    #[test]
    fn a_gallery_scanner_is_no_viewpoint_of_the_story_below() {
        // The ground floor of the house, its range running up to the roof as when the
        // attic is not found: a scanner on the gallery at 4.1 m stands above its ceilings.
        let mut ground = Story::flat(0, 0.0, 2.45, -0.1, 6.1);
        ground.top_z = 2.6;
        let cloud = PointCloud {
            xyz: vec![[0.0, 0.0, 1.0]; 2],
            scan: vec![0, 1],
            scan_ids: vec![1, 2],
            viewpoints: Viewpoints::Static(vec![
                pose(1, [2.0, 2.0, 1.5]),
                pose(2, [4.45, 4.0, 4.1]),
            ]),
            ..Default::default()
        };
        assert_eq!(
            Views::new(&cloud, &cloud.viewpoints, &ground).viewpoints,
            vec![[2.0, 2.0]]
        );
        // Scanners far from every story (poses with unknown heights) are all listed.
        let far = PointCloud {
            viewpoints: Viewpoints::Static(vec![
                pose(1, [2.0, 2.0, 101.5]),
                pose(2, [4.45, 4.0, 104.1]),
            ]),
            ..cloud
        };
        assert_eq!(
            Views::new(&far, &far.viewpoints, &ground).viewpoints.len(),
            2
        );
    }

    #[test]
    fn trajectory_positions_are_interpolated_and_thinned() {
        let traj: Vec<TrajectorySample> = (0..=10)
            .map(|k| TrajectorySample {
                t: k as f64,
                position: [0.1 * k as f64, -1.0, 1.5],
                quaternion: [1.0, 0.0, 0.0, 0.0],
            })
            .collect();
        assert_eq!(position_at(&traj, 2.5, 1.0), Some([0.25, -1.0]));
        assert_eq!(position_at(&traj, 0.0, 1.0), Some([0.0, -1.0]));
        assert_eq!(position_at(&traj, 10.0, 1.0), Some([1.0, -1.0]));
        // Before the start and after the end nothing is assumed.
        assert_eq!(position_at(&traj, -0.5, 1.0), None);
        assert_eq!(position_at(&traj, 10.5, 1.0), None);
        // Across a gap longer than the limit nothing is interpolated.
        assert_eq!(position_at(&traj, 2.5, 0.05), None);
        assert_eq!(max_step(&traj), MIN_GAP);
        let cloud = PointCloud {
            xyz: vec![[0.0, 0.0, 1.0]; 2],
            time: vec![2.5, 9.0],
            viewpoints: Viewpoints::Trajectory(traj),
            ..Default::default()
        };
        let views = Views::new(&cloud, &cloud.viewpoints, &story());
        assert_eq!(views.path.len(), 11);
        // Every centimetre along the 1 m path, interpolated between the samples.
        assert_eq!(views.viewpoints.len(), 101, "{:?}", views.viewpoints.len());
        for (k, v) in views.viewpoints.iter().enumerate() {
            assert!(
                (v[0] - 0.01 * k as f64).abs() < 1e-9 && v[1] == -1.0,
                "{k}: {v:?}"
            );
        }
        assert_eq!(views.carry(), Carry::Times);
        let seen = views.observe(&cloud.xyz, &[], &cloud.time, 0.025, [0.25, 0.0], [0.0, 1.0]);
        assert_eq!(seen.normal, [0.0, -1.0]);
        // t = 2.5 is where the scanner stood at x = 0.25; t = 9 at x = 0.9.
        assert_eq!(seen.seen_from, vec![25, 90]);
        assert!((seen.nearest.unwrap() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_path_is_broken_where_the_trajectory_jumps() {
        let at = |t: f64, x: f64| TrajectorySample {
            t,
            position: [x, 0.0, 1.5],
            quaternion: [1.0, 0.0, 0.0, 0.0],
        };
        let traj = [at(0.0, 0.0), at(1.0, 1.0), at(2.0, 5.0), at(3.0, 6.0)];
        let refs: Vec<&TrajectorySample> = traj.iter().collect();
        let path = broken_at_gaps(&refs, 2.0);
        assert_eq!(path.len(), 5);
        assert!(path[2][0].is_nan() && path[2][1].is_nan());
        assert_eq!([path[1], path[3]], [[1.0, 0.0], [5.0, 0.0]]);
        assert_eq!(broken_at_gaps(&refs, 4.0).len(), 4);
    }

    #[test]
    fn without_poses_nothing_is_seen() {
        let cloud = PointCloud {
            xyz: vec![[0.0, 0.0, 1.0]],
            ..Default::default()
        };
        let views = Views::new(&cloud, &cloud.viewpoints, &story());
        assert_eq!(views.carry(), Carry::Nothing);
        let seen = views.observe(&cloud.xyz, &[], &[], 0.025, [0.0, 0.0], [0.0, 1.0]);
        assert_eq!(seen.normal, [0.0, 1.0]);
        assert!(seen.seen_from.is_empty() && seen.nearest.is_none());
    }

    #[test]
    fn only_the_points_on_the_face_vote_and_viewers_behind_it_are_dropped() {
        // A 10 cm wall along x: its face at y = 0 seen by scan 1 from y = -2 (two points), its
        // far face at y = 0.1 by scans 2 and 3 from y = +3 (three points). The neighbourhood of
        // a sample on the near face holds both.
        let cloud = PointCloud {
            xyz: vec![
                [0.0, 0.0, 1.0],
                [0.01, 0.0, 1.5],
                [0.0, 0.1, 1.0],
                [0.01, 0.1, 1.5],
                [0.02, 0.1, 2.0],
            ],
            scan: vec![0, 0, 1, 2, 2],
            scan_ids: vec![1, 2, 3],
            viewpoints: Viewpoints::Static(vec![
                pose(1, [0.0, -2.0, 1.5]),
                pose(2, [0.0, 3.0, 1.5]),
                pose(3, [1.0, 3.0, 1.5]),
            ]),
            ..Default::default()
        };
        let views = Views::new(&cloud, &cloud.viewpoints, &story());
        let pts = cloud.xyz.clone();
        let seen = views.observe(&pts, &cloud.scan, &[], 0.025, [0.0, 0.0], [0.0, 1.0]);
        // All five would vote the normal toward y = +3 (3 to 2); the face's own two turn it.
        assert_eq!(seen.normal, [0.0, -1.0]);
        assert_eq!(seen.seen_from, vec![0]);
        // The far face's sample is seen from y = +3 only.
        let far = views.observe(&pts, &cloud.scan, &[], 0.025, [0.0, 0.1], [0.0, 1.0]);
        assert_eq!(far.normal, [0.0, 1.0]);
        assert_eq!(far.seen_from, vec![1, 2]);
        // A face seen mostly from in front: the one point seen from behind (through a gap,
        // or a stray return) does not list its scanner.
        let mixed = PointCloud {
            xyz: vec![[0.0, 0.0, 1.0], [0.01, 0.0, 1.5], [0.02, 0.0, 2.0]],
            scan: vec![0, 0, 1],
            ..cloud.clone()
        };
        let seen = views.observe(&mixed.xyz, &mixed.scan, &[], 0.025, [0.0, 0.0], [0.0, 1.0]);
        assert_eq!(seen.normal, [0.0, -1.0]);
        assert_eq!(seen.seen_from, vec![0]);
    }
}
