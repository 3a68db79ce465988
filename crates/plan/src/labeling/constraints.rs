//! Hard constraints (§3.3): box-corner triangles outside; triangles crossed by enough lines of
//! sight, containing a scanner pose, or crossed by the mobile path inside. Outside wins on conflict.
//! Triangles holding a point known to be inside a wall (see `backs`) are outside unless evidence
//! puts them inside.

use rayon::prelude::*;

use super::faces::Faces;
use super::mesh::Mesh;
use super::walk::{locate, segment_triangles};
use super::LabelingParams;
use crate::cancel::{Cancel, Cancelled};
use crate::geom::{self, P2};
use crate::samples::WallSamples;

/// The forced labels and how they came about.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Constraints {
    /// Per triangle: `Some(true)` forced inside, `Some(false)` forced outside.
    pub forced: Vec<Option<bool>>,
    pub outside: usize,
    pub inside_rays: usize,
    pub inside_poses: usize,
    pub inside_path: usize,
    /// Triangles that evidence put inside but that touch a box corner (kept outside).
    pub conflicts: usize,
    /// Triangles forced outside as solid wall behind a face (no inside evidence there).
    pub solid: usize,
    /// Lines of sight walked.
    pub rays: usize,
    /// Lines of sight not walked: viewpoint outside the triangulation or a degenerate start.
    pub rays_skipped: usize,
    /// Lines of sight dropped: they crossed a face seen straight from its other side.
    pub rays_blocked: usize,
    /// Mesh vertices of the faces that dropped them, sorted, each once.
    pub blocking: Vec<u32>,
    /// Viewpoints outside the triangulation.
    pub poses_outside: usize,
    /// Per probe: a walked line of sight passed within its radius (the place is open).
    pub probes_seen: Vec<bool>,
}

/// Points to test for lines of sight passing near them, each with its radius. Only lines of
/// sight crossing a probe's own triangle are measured: one passing just beyond an edge of it
/// does not count.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Probes<'a> {
    pub points: &'a [P2],
    pub radius: f64,
}

/// Computes the hard constraints for `mesh` from the samples' viewpoints and path.
/// `min_rays` lines of sight force a triangle inside; each line of sight is the central
/// `ray_fraction` of its viewpoint→sample segment, extended back to the viewpoint when
/// `rays_from_scanner` is set. Triangles holding a point of `solid` are forced outside when
/// nothing forced them inside. Each of `probes` is reported seen when a walked line of sight
/// passes within its radius. With `rays_stop_at_faces`, lines of sight crossing a face from
/// behind are dropped where the face was seen straight (see `faces`); `spacing` is the samples'
/// (`None`: no faces are found). Stops with `Cancelled` once `cancel` says so.
pub(crate) fn hard_constraints(
    mesh: &Mesh,
    samples: &WallSamples,
    solid: &[P2],
    probes: Probes<'_>,
    spacing: Option<f64>,
    params: &LabelingParams,
    cancel: &Cancel,
) -> Result<Constraints, Cancelled> {
    let min_rays = params.min_rays;
    let nt = mesh.triangles.len();
    let mut c = Constraints {
        forced: vec![None; nt],
        ..Default::default()
    };
    // Where each viewpoint is.
    let vp_tri = locate_all(mesh, &samples.viewpoints);
    c.poses_outside = vp_tri.iter().filter(|t| t.is_none()).count();

    let mut inside = vec![false; nt];
    let mark = |t: u32, why: &mut usize, inside: &mut Vec<bool>| {
        if !inside[t as usize] {
            inside[t as usize] = true;
            *why += 1;
        }
    };
    for t in vp_tri.iter().flatten() {
        mark(*t, &mut c.inside_poses, &mut inside);
    }

    // Mobile path: every triangle a path segment crosses.
    let mut path_hint = vp_tri.iter().flatten().next().copied().unwrap_or(0);
    for (k, w) in samples.path.windows(2).enumerate() {
        // Each walk may cross the whole mesh.
        if k % 64 == 0 {
            cancel.check()?;
        }
        let (a, b) = (w[0], w[1]);
        if !(finite(a) && finite(b)) {
            continue;
        }
        let Some(start) = locate(mesh, a, path_hint) else {
            continue;
        };
        path_hint = start;
        let mut crossed = Vec::new();
        segment_triangles(mesh, start, a, b, 0.0, 1.0, |t| crossed.push(t));
        for t in crossed {
            mark(t, &mut c.inside_path, &mut inside);
        }
    }

    // Lines of sight, counted once per ray and triangle. A ray that crosses a face from
    // behind is held back until every ray has been walked (see `faces`).
    let f = params.ray_fraction.clamp(0.0, 1.0);
    let (lo, hi) = ((1.0 - f) / 2.0, (1.0 + f) / 2.0);
    let lo = if params.rays_from_scanner { 0.0 } else { lo };
    let in_triangle = probes_by_triangle(mesh, probes.points);
    // Pseudo-viewpoints list only samples their lines reach across no other wall.
    let faces = match spacing {
        Some(h) if params.rays_stop_at_faces && !samples.lines_checked => Some(Faces::of(mesh, h)),
        _ => None,
    };
    let fresh = || Walks::new(nt, probes.points.len());
    let mut w = samples
        .samples
        .par_iter()
        .enumerate()
        .with_min_len(256)
        .fold(fresh, |mut w, (k, s)| {
            // A sample's rays may each cross the whole mesh: check once per sample.
            if cancel.is_stopped() {
                return w;
            }
            let mut direct = false;
            for &v in &s.seen_from {
                let (Some(&a), Some(Some(start))) =
                    (samples.viewpoints.get(v as usize), vp_tri.get(v as usize))
                else {
                    w.skipped += 1;
                    continue;
                };
                let hi = match params.ray_end_margin {
                    Some(m) => hi.max(1.0 - m / geom::dist(a, s.pos).max(1e-9)),
                    None => hi,
                };
                let d = geom::sub(s.pos, a);
                // The triangles go into one buffer per thread, reused from ray to ray.
                let mut ray = Ray {
                    from: geom::add(a, geom::scale(d, lo)),
                    to: geom::add(a, geom::scale(d, hi)),
                    tris: std::mem::take(&mut w.scratch),
                };
                ray.tris.clear();
                if !finite(s.pos)
                    || !segment_triangles(mesh, *start, a, s.pos, lo, hi, |t| ray.tris.push(t))
                {
                    w.skipped += 1;
                    w.scratch = ray.tris;
                    continue;
                }
                let behind = faces
                    .as_ref()
                    .map_or_else(Vec::new, |f| f.crossed_from_behind(mesh, a, &ray.tris));
                if behind.is_empty() {
                    w.count(&ray, &in_triangle, probes);
                    w.scratch = ray.tris;
                    direct = true;
                } else {
                    w.held.push((ray, behind));
                }
            }
            if direct {
                w.direct.push(k as u32);
            }
            w
        })
        .reduce(fresh, Walks::merge);
    cancel.check()?;
    // A face blocks the rays crossing it from behind when a scanner in front of it saw it
    // straight, through no other face: an opaque wall hides what lies beyond it, so what a
    // scanner "saw" there was a mirror's image or seen through glass. A face seen only that
    // way (a mirror's image of a wall) blocks nothing.
    let mut direct = vec![false; samples.samples.len()];
    w.direct.iter().for_each(|&k| direct[k as usize] = true);
    let is_direct = |v: u32| {
        mesh.sample_of
            .get(v as usize)
            .is_some_and(|&k| direct.get(k as usize).copied().unwrap_or(false))
    };
    for (ray, behind) in std::mem::take(&mut w.held) {
        let mut blocked = false;
        for &(u, v) in &behind {
            if is_direct(u) || is_direct(v) {
                blocked = true;
                c.blocking.extend([u, v]);
            }
        }
        if blocked {
            c.rays_blocked += 1;
        } else {
            w.count(&ray, &in_triangle, probes);
        }
    }
    c.blocking.sort_unstable();
    c.blocking.dedup();
    c.probes_seen = w.seen;
    c.rays = w.walked;
    c.rays_skipped = w.skipped;
    for (t, &n) in w.counts.iter().enumerate() {
        if n >= min_rays.max(1) {
            mark(t as u32, &mut c.inside_rays, &mut inside);
        }
    }

    let mut walled = vec![false; nt];
    for t in locate_all(mesh, solid).into_iter().flatten() {
        walled[t as usize] = true;
    }
    for (t, &evidence) in inside.iter().enumerate() {
        if mesh.touches_corner(t) {
            c.forced[t] = Some(false);
            c.outside += 1;
            if evidence {
                c.conflicts += 1;
            }
        } else if evidence {
            c.forced[t] = Some(true);
        } else if walled[t] {
            c.forced[t] = Some(false);
            c.solid += 1;
        }
    }
    Ok(c)
}

/// The walked part of a line of sight: its ends and the triangles it crosses, in order.
struct Ray {
    from: P2,
    to: P2,
    tris: Vec<u32>,
}

/// One thread's tally of lines of sight.
struct Walks {
    /// Per triangle, the lines of sight crossing it.
    counts: Vec<u32>,
    /// Per probe, whether a counted line of sight passed near it.
    seen: Vec<bool>,
    walked: usize,
    skipped: usize,
    /// Lines of sight crossing faces from behind, with those faces, decided once all are walked.
    held: Vec<(Ray, Vec<(u32, u32)>)>,
    /// Samples that some line of sight reached across no face from behind.
    direct: Vec<u32>,
    scratch: Vec<u32>,
}

impl Walks {
    fn new(nt: usize, np: usize) -> Walks {
        Walks {
            counts: vec![0; nt],
            seen: vec![false; np],
            walked: 0,
            skipped: 0,
            held: Vec::new(),
            direct: Vec::new(),
            scratch: Vec::new(),
        }
    }

    fn count(&mut self, ray: &Ray, in_triangle: &ByTriangle, probes: Probes<'_>) {
        self.walked += 1;
        for &t in &ray.tris {
            self.counts[t as usize] += 1;
            for &k in in_triangle.of(t) {
                let k = k as usize;
                if !self.seen[k]
                    && geom::point_segment_distance(probes.points[k], ray.from, ray.to)
                        < probes.radius
                {
                    self.seen[k] = true;
                }
            }
        }
    }

    fn merge(mut self, other: Walks) -> Walks {
        self.counts
            .iter_mut()
            .zip(&other.counts)
            .for_each(|(x, y)| *x += y);
        self.seen
            .iter_mut()
            .zip(&other.seen)
            .for_each(|(x, y)| *x |= y);
        self.walked += other.walked;
        self.skipped += other.skipped;
        self.held.extend(other.held);
        self.direct.extend(other.direct);
        self
    }
}

/// Probe indices per triangle, as offsets into one list.
struct ByTriangle {
    start: Vec<u32>,
    items: Vec<u32>,
}

impl ByTriangle {
    fn of(&self, t: u32) -> &[u32] {
        match (self.start.get(t as usize), self.start.get(t as usize + 1)) {
            (Some(&a), Some(&b)) => &self.items[a as usize..b as usize],
            _ => &[],
        }
    }
}

fn probes_by_triangle(mesh: &Mesh, points: &[P2]) -> ByTriangle {
    if points.is_empty() {
        return ByTriangle {
            start: Vec::new(),
            items: Vec::new(),
        };
    }
    let nt = mesh.triangles.len();
    let tri = locate_all(mesh, points);
    let mut start = vec![0u32; nt + 1];
    for t in tri.iter().flatten() {
        start[*t as usize + 1] += 1;
    }
    for i in 0..nt {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut items = vec![0u32; start[nt] as usize];
    for (k, t) in tri.iter().enumerate() {
        if let Some(t) = t {
            items[fill[*t as usize] as usize] = k as u32;
            fill[*t as usize] += 1;
        }
    }
    ByTriangle { start, items }
}

/// The triangle holding each of `points`, `None` for points outside the mesh or not finite.
/// Each search starts from the last one found: points in order along a path or a wall walk
/// only a few triangles.
fn locate_all(mesh: &Mesh, points: &[P2]) -> Vec<Option<u32>> {
    let mut hint = 0u32;
    points
        .iter()
        .map(|&p| {
            let t = finite(p).then(|| locate(mesh, p, hint)).flatten();
            if let Some(t) = t {
                hint = t;
            }
            t
        })
        .collect()
}

fn finite(p: P2) -> bool {
    p[0].is_finite() && p[1].is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::samples::WallSample;

    fn sample(pos: P2, seen_from: Vec<u32>) -> WallSample {
        WallSample {
            pos,
            normal: [0.0, 1.0],
            confidence: 1.0,
            seen_from,
        }
    }

    /// A 4 m square room sampled every 0.1 m, seen from `vps`.
    fn room(vps: Vec<P2>) -> WallSamples {
        let mut s = Vec::new();
        let all: Vec<u32> = (0..vps.len() as u32).collect();
        for i in 0..40 {
            let x = i as f64 * 0.1;
            for p in [[x, 0.0], [4.0, x], [4.0 - x, 4.0], [0.0, 4.0 - x]] {
                s.push(sample(p, all.clone()));
            }
        }
        WallSamples {
            samples: s,
            viewpoints: vps,
            ..Default::default()
        }
    }

    /// The constraints with the default parameters, no solid points and no probes.
    fn constrain(mesh: &Mesh, ws: &WallSamples) -> Constraints {
        hard_constraints(
            mesh,
            ws,
            &[],
            Probes::default(),
            None,
            &LabelingParams::default(),
            &Cancel::never(),
        )
        .unwrap()
    }

    #[test]
    fn poses_rays_and_corners_force_the_expected_triangles() {
        let ws = room(vec![[2.0, 2.1], [1.1, 1.3]]);
        let pts: Vec<P2> = ws.samples.iter().map(|s| s.pos).collect();
        let mesh = Mesh::build(&pts, &[]).unwrap();
        let c = constrain(&mesh, &ws);
        assert_eq!(c.rays, 2 * ws.samples.len());
        assert_eq!(c.rays_skipped, 0);
        assert_eq!(c.inside_poses, 2);
        assert!(c.inside_rays > 0);
        for t in 0..mesh.triangles.len() {
            let [a, b, cc] = mesh.corners(t);
            let centroid = [(a[0] + b[0] + cc[0]) / 3.0, (a[1] + b[1] + cc[1]) / 3.0];
            let in_room = (0.0..=4.0).contains(&centroid[0]) && (0.0..=4.0).contains(&centroid[1]);
            match c.forced[t] {
                // Forced inside only within the room.
                Some(true) => assert!(in_room, "triangle {t} forced inside outside the room"),
                Some(false) => assert!(mesh.touches_corner(t)),
                None => assert!(!mesh.touches_corner(t)),
            }
        }
        // The pose triangle is forced inside.
        let t = locate(&mesh, [2.0, 2.1], 0).unwrap();
        assert_eq!(c.forced[t as usize], Some(true));
        assert_eq!(c.conflicts, 0);
    }

    #[test]
    fn path_forces_crossed_triangles_and_outside_wins() {
        let mut ws = room(vec![]);
        // The path runs through the room and out through the wall into the box.
        ws.path = vec![[0.5, 0.5], [3.5, 3.5], [7.0, 3.5]];
        let pts: Vec<P2> = ws.samples.iter().map(|s| s.pos).collect();
        let mesh = Mesh::build(&pts, &[]).unwrap();
        let c = constrain(&mesh, &ws);
        assert!(c.inside_path > 0);
        assert!(
            c.conflicts > 0,
            "the path leaves the room into corner triangles"
        );
        let t = locate(&mesh, [2.0, 2.0], 0).unwrap();
        assert_eq!(c.forced[t as usize], Some(true));
        assert_eq!(c.rays, 0);
    }

    #[test]
    fn a_gap_in_the_path_forces_nothing_between_its_ends() {
        let mut ws = room(vec![]);
        ws.path = vec![
            [0.5, 0.5],
            [1.0, 0.5],
            [f64::NAN; 2],
            [3.5, 3.5],
            [3.5, 3.0],
        ];
        let pts: Vec<P2> = ws.samples.iter().map(|s| s.pos).collect();
        let mesh = Mesh::build(&pts, &[]).unwrap();
        let c = constrain(&mesh, &ws);
        assert!(c.inside_path > 0);
        let t = locate(&mesh, [2.0, 2.0], 0).unwrap();
        assert_eq!(
            c.forced[t as usize], None,
            "the gap's straight line is not walked"
        );
    }

    #[test]
    fn probes_near_a_line_of_sight_are_seen_and_solid_points_force_outside() {
        let ws = room(vec![[2.0, 2.0]]);
        let pts: Vec<P2> = ws.samples.iter().map(|s| s.pos).collect();
        let mesh = Mesh::build(&pts, &[]).unwrap();
        let run = |ws: &WallSamples, solid: &[P2], probes: Probes<'_>| {
            hard_constraints(
                &mesh,
                ws,
                solid,
                probes,
                None,
                &LabelingParams::default(),
                &Cancel::never(),
            )
            .unwrap()
        };
        // The line of sight to the sample at (1, 0) passes (1.5, 1): a probe 9 mm from it is
        // seen. Nothing passes a probe beyond the wall.
        let probes = [[1.51, 1.0], [4.5, 2.0]];
        let c = run(
            &ws,
            &[],
            Probes {
                points: &probes,
                radius: 0.02,
            },
        );
        assert_eq!(c.probes_seen, vec![true, false]);
        // Evidence wins over a solid point: the pose's triangle stays inside.
        let posed = locate(&mesh, [2.0, 2.0], 0).unwrap() as usize;
        let c = run(&ws, &[[2.0, 2.0]], Probes::default());
        assert_eq!(c.forced[posed], Some(true));
        assert_eq!(c.solid, 0);
        // Where nothing forced a triangle, a solid point makes it outside.
        let blind = room(vec![]);
        let c = run(&blind, &[[2.0, 2.0]], Probes::default());
        assert_eq!(c.forced[posed], Some(false));
        assert_eq!(c.solid, 1);
    }
}
