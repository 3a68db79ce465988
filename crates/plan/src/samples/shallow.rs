//! Shallow wall samples of floorless stories: which belong to the walls seen deeper.
//!
//! A phone held up to a ceiling sees some stretches of wall only a little way down. Such a
//! stretch alone looks like hanging clutter (a bulkhead, a duct), so it is not a wall by itself.
//! It is one where it runs on along the line of a wall seen deeper, or where it spans between
//! walls, both its ends meeting them (a wall seen shallow from corner to corner). Without it the
//! triangulation has no vertices there and the plan cuts a chord across the room.

use std::collections::HashMap;

use crate::geom::{self, P2};

use super::WallSample;

/// Two shallow samples are one run when at most this far apart, metres (a sparse capture
/// leaves holes of a few cells in a run)...
const LINK: f64 = 0.5;

/// ...each on the other's line, within this many cells of it...
const OFF_LINE: f64 = 0.6;

/// ...with normals within 15° of each other. A run joined so to a wall sample runs on along it.
const MIN_COS: f64 = 0.966;

/// A run of deep samples is a wall when at least this long, metres.
const MIN_WALL: f64 = 0.5;

/// A shallow run shorter than this, metres, is left out: a stray cell or two is no stretch of
/// wall, and holes that short in a wall are filled by labeling anyway.
const MIN_RUN: f64 = 0.25;

/// A run spans between walls when both its ends lie this close to a wall sample, metres: a
/// corner's own cells often fail the alignment test, so the walls' last samples stand back.
const END_REACH: f64 = 0.25;

/// Which of `samples` (each with whether it is shallow) to keep: every deep one, and each run
/// of shallow ones that runs on along a wall's line or spans between walls. Walls here are
/// runs of deep samples at least [`MIN_WALL`] long and the shallow runs kept so far: a stray
/// deep sample or two (clutter) anchors nothing.
pub(super) fn continuing(samples: &[(&WallSample, bool)], cell: f64) -> Vec<bool> {
    let mut keep: Vec<bool> = samples.iter().map(|s| !s.1).collect();
    if keep.iter().all(|&k| k) {
        return keep;
    }
    let index = Index::new(samples, LINK.max(END_REACH));
    let (shallow, deep): (Vec<Vec<usize>>, Vec<Vec<usize>>) = runs(samples, &index, cell)
        .into_iter()
        .partition(|run| samples[run[0]].1);
    let mut wall = vec![false; samples.len()];
    for run in deep.iter().filter(|run| extent(run, samples) >= MIN_WALL) {
        run.iter().for_each(|&i| wall[i] = true);
    }
    // A run kept can anchor the next (two shallow walls meeting at a corner).
    loop {
        let mut changed = false;
        for run in &shallow {
            if keep[run[0]] || extent(run, samples) < MIN_RUN {
                continue;
            }
            if joins(run, samples, &index, &wall, cell) || spans(run, samples, &index, &wall) {
                run.iter().for_each(|&i| {
                    keep[i] = true;
                    wall[i] = true;
                });
                changed = true;
            }
        }
        if !changed {
            return keep;
        }
    }
}

/// Whether samples `a` and `b` lie on one wall line.
fn linked(a: &WallSample, b: &WallSample, cell: f64) -> bool {
    let d = geom::sub(b.pos, a.pos);
    geom::norm(d) <= LINK
        && geom::dot(d, a.normal).abs() <= OFF_LINE * cell
        && geom::dot(d, b.normal).abs() <= OFF_LINE * cell
        && geom::dot(a.normal, b.normal).abs() >= MIN_COS
}

/// Samples grouped into runs along wall lines, shallow and deep apart (indices into `samples`).
fn runs(samples: &[(&WallSample, bool)], index: &Index, cell: f64) -> Vec<Vec<usize>> {
    let mut run_of = vec![usize::MAX; samples.len()];
    let mut runs = Vec::new();
    for start in 0..samples.len() {
        if run_of[start] != usize::MAX {
            continue;
        }
        let id = runs.len();
        run_of[start] = id;
        let mut run = vec![start];
        let mut next = 0;
        while next < run.len() {
            let a = run[next];
            next += 1;
            for b in index.near(samples[a].0.pos) {
                if samples[b].1 == samples[a].1
                    && run_of[b] == usize::MAX
                    && linked(samples[a].0, samples[b].0, cell)
                {
                    run_of[b] = id;
                    run.push(b);
                }
            }
        }
        runs.push(run);
    }
    runs
}

/// Whether `run` runs on along the line of a wall sample.
fn joins(
    run: &[usize],
    samples: &[(&WallSample, bool)],
    index: &Index,
    wall: &[bool],
    cell: f64,
) -> bool {
    run.iter().any(|&a| {
        index
            .near(samples[a].0.pos)
            .any(|b| wall[b] && linked(samples[a].0, samples[b].0, cell))
    })
}

/// The extreme samples of `run` along its direction.
fn ends(run: &[usize], samples: &[(&WallSample, bool)]) -> (usize, usize) {
    let n = samples[run[0]].0.normal;
    let along = [-n[1], n[0]];
    let at = |i: usize| geom::dot(samples[i].0.pos, along);
    let first = run.iter().copied().min_by(|&a, &b| at(a).total_cmp(&at(b)));
    let last = run.iter().copied().max_by(|&a, &b| at(a).total_cmp(&at(b)));
    (first.unwrap_or(run[0]), last.unwrap_or(run[0]))
}

/// The length of `run` between its ends, metres.
fn extent(run: &[usize], samples: &[(&WallSample, bool)]) -> f64 {
    let (a, b) = ends(run, samples);
    geom::dist(samples[a].0.pos, samples[b].0.pos)
}

/// Whether both ends of `run` lie within [`END_REACH`] of wall samples.
fn spans(run: &[usize], samples: &[(&WallSample, bool)], index: &Index, wall: &[bool]) -> bool {
    let (first, last) = ends(run, samples);
    let anchored = |end: usize| {
        let p = samples[end].0.pos;
        index
            .near(p)
            .any(|b| wall[b] && geom::dist(samples[b].0.pos, p) <= END_REACH)
    };
    first != last && anchored(first) && anchored(last)
}

/// The samples by square bucket, for finding those near a place.
struct Index {
    size: f64,
    buckets: HashMap<(i64, i64), Vec<usize>>,
}

impl Index {
    fn new(samples: &[(&WallSample, bool)], size: f64) -> Index {
        let mut index = Index {
            size,
            buckets: HashMap::new(),
        };
        for (i, s) in samples.iter().enumerate() {
            let k = index.key(s.0.pos);
            index.buckets.entry(k).or_default().push(i);
        }
        index
    }

    fn key(&self, p: P2) -> (i64, i64) {
        (
            (p[0] / self.size).floor() as i64,
            (p[1] / self.size).floor() as i64,
        )
    }

    /// Every sample within `size` of `p`, and some farther.
    fn near(&self, p: P2) -> impl Iterator<Item = usize> + '_ {
        let (kx, ky) = self.key(p);
        (-1..=1)
            .flat_map(move |dx| (-1..=1).map(move |dy| (kx + dx, ky + dy)))
            .filter_map(|k| self.buckets.get(&k))
            .flatten()
            .copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x: f64, y: f64, normal: P2) -> WallSample {
        WallSample {
            pos: [x, y],
            normal,
            confidence: 1.0,
            seen_from: Vec::new(),
        }
    }

    /// Samples every 5 cm from `a` to `b` (inclusive), all shallow or all deep.
    fn row(a: P2, b: P2, shallow: bool) -> Vec<(WallSample, bool)> {
        let len = geom::dist(a, b);
        let u = geom::scale(geom::sub(b, a), 1.0 / len);
        let steps = (len / 0.05).round() as usize;
        (0..=steps)
            .map(|k| {
                let p = geom::add(a, geom::scale(u, len * k as f64 / steps as f64));
                (sample(p[0], p[1], [-u[1], u[0]]), shallow)
            })
            .collect()
    }

    fn keep(all: &[(WallSample, bool)]) -> Vec<bool> {
        let refs: Vec<(&WallSample, bool)> = all.iter().map(|(s, b)| (s, *b)).collect();
        continuing(&refs, 0.05)
    }

    #[test]
    fn a_shallow_run_on_a_deep_walls_line_is_kept_and_clutter_is_not() {
        // A wall along y = 0: deep from x 0 to 1, shallow from 1.05 to 3.
        let mut all = row([0.0, 0.0], [1.0, 0.0], false);
        all.extend(row([1.05, 0.0], [3.0, 0.0], true));
        let wall = all.len();
        // A bulkhead's face parallel to the wall 0.5 m into the room.
        all.extend(row([0.0, 0.5], [1.0, 0.5], true));
        // A duct from the wall's end into the room, at right angles to it: one end free.
        all.extend(row([3.0, 0.1], [3.0, 1.0], true));
        // A shallow run on the wall's line past a gap of 0.7 m, its far end free.
        all.extend(row([3.75, 0.0], [4.25, 0.0], true));
        // Two deep samples of clutter in the room, and a shallow run on their line.
        all.extend(row([1.0, 2.0], [1.05, 2.0], false));
        let clutter = all.len();
        all.extend(row([1.1, 2.0], [2.0, 2.0], true));
        // A lone shallow sample on the wall's line past its end.
        all.push((sample(-0.1, 0.0, [0.0, 1.0]), true));
        let keep = keep(&all);
        assert!(
            keep[..wall].iter().all(|&k| k),
            "the wall and its shallow run"
        );
        assert!(
            keep[wall..clutter - 2].iter().all(|&k| !k),
            "{:?}",
            &keep[wall..]
        );
        assert!(
            keep[clutter - 2..clutter].iter().all(|&k| k),
            "deep samples stay"
        );
        assert!(
            keep[clutter..].iter().all(|&k| !k),
            "{:?}",
            &keep[clutter..]
        );
    }

    #[test]
    fn a_shallow_wall_between_two_corners_is_kept() {
        // Deep walls along y = 0 and y = 2.5 from x 0 to 3; the wall x = 3 between them seen
        // shallow, its samples ending 15 cm short of each corner; and a shallow wall from it
        // to a deep wall x = 5, anchored at one end by the shallow wall alone.
        let mut all = row([0.0, 0.0], [3.0, 0.0], false);
        all.extend(row([0.0, 2.5], [3.0, 2.5], false));
        all.extend(row([3.15, 1.25], [4.85, 1.25], true));
        all.extend(row([3.0, 0.15], [3.0, 2.35], true));
        all.extend(row([5.0, 0.0], [5.0, 2.5], false));
        let n = row([0.0, 0.0], [3.0, 0.0], false).len();
        let keep = keep(&all);
        assert!(keep.iter().all(|&k| k), "{keep:?}");
        // The same wall with one end free (its far wall missing) is dropped.
        let mut one = row([0.0, 0.0], [3.0, 0.0], false);
        one.extend(row([3.0, 0.15], [3.0, 2.35], true));
        assert!(self::keep(&one)[n..].iter().all(|&k| !k));
    }

    #[test]
    fn without_shallow_samples_everything_is_kept() {
        let s = sample(0.0, 0.0, [1.0, 0.0]);
        assert_eq!(continuing(&[(&s, false), (&s, false)], 0.05), vec![true; 2]);
        assert_eq!(continuing(&[(&s, true)], 0.05), vec![false]);
    }
}
