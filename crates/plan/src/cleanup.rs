//! Stage 5a (§3.4): remove small regions and protrusions from a labeling.
//!
//! Regions are edge-connected sets of triangles with the same label, found with union-find.
//! Small inside regions become outside, then (regions recomputed) small outside regions become
//! inside. Protrusions (a triangle whose only same-label neighbour sits across its shortest
//! edge) are then relabelled in one pass each, inside ones first. Forced labels never change.

use serde::{Deserialize, Serialize};

use crate::geom;
use crate::labeling::{LabeledMesh, Mesh, NONE};
use crate::params::{within, ParamRange};

/// Parameters of [`clean_labels`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CleanupParams {
    /// Regions with fewer triangles are relabelled (§3.4: "a value of 30 triangles is typically used").
    /// Range 0..=100000.
    pub min_region_triangles: usize,
    /// A small outside region only becomes inside when its area is also below this, m².
    /// Beyond the paper: a column is a real hole bounded by few triangles, so the triangle count
    /// alone would fill it in. 0.05 m² keeps any column wider than about 22 cm. Range 0..=100.
    pub max_hole_area: f64,
    /// Remove protrusions (§3.4).
    pub remove_protrusions: bool,
}

/// The accepted values of [`CleanupParams`] (see [`crate::params::ParamRange`]).
pub const RANGES: &[ParamRange] = &[
    ParamRange::new("min_region_triangles", 0.0, 100_000.0, ""),
    ParamRange::new("max_hole_area", 0.0, 100.0, "m²"),
];

impl CleanupParams {
    /// Checks every value; the error names the parameter and gives its range.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        within(
            RANGES,
            "min_region_triangles",
            self.min_region_triangles as f64,
        )?;
        within(RANGES, "max_hole_area", self.max_hole_area)
    }
}

impl Default for CleanupParams {
    fn default() -> Self {
        CleanupParams {
            min_region_triangles: 30,
            max_hole_area: 0.05,
            remove_protrusions: true,
        }
    }
}

/// What cleanup changed, for reports and tests.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct CleanupReport {
    /// Triangles of small inside regions relabelled outside.
    pub small_inside_flipped: usize,
    /// Triangles of small outside regions relabelled inside.
    pub small_outside_flipped: usize,
    /// Protrusion triangles relabelled (both directions).
    pub protrusions_flipped: usize,
}

/// Relabels small regions and protrusions in place. Forced labels are never changed.
pub fn clean_labels(labeled: &mut LabeledMesh, params: &CleanupParams) -> CleanupReport {
    let mut report = CleanupReport::default();
    let n = labeled.mesh.triangles.len();
    if labeled.inside.len() != n || labeled.forced.len() != n || labeled.mesh.neighbors.len() != n {
        // A malformed labeling has nothing sensible to clean; the boundary stage reports it.
        return report;
    }
    report.small_inside_flipped = flip_small_regions(labeled, true, params, f64::INFINITY);
    report.small_outside_flipped = flip_small_regions(labeled, false, params, params.max_hole_area);
    if params.remove_protrusions {
        report.protrusions_flipped =
            peel_protrusions(labeled, true) + peel_protrusions(labeled, false);
    }
    report
}

/// Union-find with path halving and union by size.
pub(crate) struct UnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl UnionFind {
    pub(crate) fn new(n: usize) -> Self {
        UnionFind {
            parent: (0..n as u32).collect(),
            size: vec![1; n],
        }
    }

    pub(crate) fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let grand = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = grand;
            x = grand;
        }
        x
    }

    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return;
        }
        if self.size[a as usize] < self.size[b as usize] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b as usize] = a;
        self.size[a as usize] += self.size[b as usize];
    }
}

/// Region root per triangle: triangles sharing an edge and a label are in one region.
fn regions(mesh: &Mesh, inside: &[bool]) -> Vec<u32> {
    let mut uf = UnionFind::new(mesh.triangles.len());
    for (t, nbrs) in mesh.neighbors.iter().enumerate() {
        for &n in nbrs {
            if n != NONE && (n as usize) > t && inside[n as usize] == inside[t] {
                uf.union(t as u32, n);
            }
        }
    }
    (0..mesh.triangles.len() as u32)
        .map(|t| uf.find(t))
        .collect()
}

/// Flips every unforced triangle of the regions labelled `label` that have fewer than
/// `min_region_triangles` triangles and less than `max_area` area. Returns the triangles flipped.
fn flip_small_regions(
    labeled: &mut LabeledMesh,
    label: bool,
    params: &CleanupParams,
    max_area: f64,
) -> usize {
    let mesh = &labeled.mesh;
    let root = regions(mesh, &labeled.inside);
    let n = mesh.triangles.len();
    let mut count = vec![0usize; n];
    let mut area = vec![0.0f64; n];
    for (t, &r) in root.iter().enumerate() {
        count[r as usize] += 1;
        area[r as usize] += mesh.area(t);
    }
    let mut flipped = 0;
    for (t, &r) in root.iter().enumerate() {
        let r = r as usize;
        if labeled.inside[t] == label
            && labeled.forced[t].is_none()
            && count[r] < params.min_region_triangles
            && area[r] < max_area
        {
            labeled.inside[t] = !label;
            flipped += 1;
        }
    }
    flipped
}

/// True when `t` has exactly one neighbour with its label and that neighbour sits across `t`'s
/// shortest edge (§3.4). A missing neighbour (hull edge) counts as outside.
fn is_protrusion(mesh: &Mesh, inside: &[bool], t: usize) -> bool {
    let same = |k: usize| {
        let n = mesh.neighbors[t][k];
        let label = n != NONE && inside[n as usize];
        label == inside[t]
    };
    let same_count = (0..3).filter(|&k| same(k)).count();
    if same_count != 1 {
        return false;
    }
    let c = mesh.corners(t);
    // Edge k lies opposite corner k.
    let len = |k: usize| geom::dist(c[(k + 1) % 3], c[(k + 2) % 3]);
    let shortest = (0..3)
        .min_by(|&a, &b| len(a).total_cmp(&len(b)))
        .unwrap_or(0);
    same(shortest)
}

/// Relabels every protrusion labelled `label` (§3.4: inside ones first, then outside ones).
/// Protrusions are found on the labels as they were before the pass, so one pass removes the
/// tips of spikes and does not cascade into acute corners.
fn peel_protrusions(labeled: &mut LabeledMesh, label: bool) -> usize {
    let mesh = &labeled.mesh;
    let flip: Vec<usize> = (0..mesh.triangles.len())
        .filter(|&t| {
            labeled.inside[t] == label
                && labeled.forced[t].is_none()
                && is_protrusion(mesh, &labeled.inside, t)
        })
        .collect();
    for &t in &flip {
        labeled.inside[t] = !label;
    }
    flip.len()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::boundary::trace_boundary;
    use crate::geom::P2;

    /// Samples every `step` metres along the closed polygon `ring`, starting half a step in so no
    /// sample sits on a corner. Normals point to the left of the direction of travel.
    pub(crate) fn ring_samples(ring: &[P2], step: f64) -> (Vec<P2>, Vec<P2>) {
        let mut pts = Vec::new();
        let mut normals = Vec::new();
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let len = geom::dist(a, b);
            let d = geom::scale(geom::sub(b, a), 1.0 / len);
            let n = (len / step).round().max(1.0) as usize;
            for k in 0..n {
                let s = (k as f64 + 0.5) * len / n as f64;
                pts.push(geom::add(a, geom::scale(d, s)));
                normals.push([-d[1], d[0]]);
            }
        }
        (pts, normals)
    }

    /// Even-odd point-in-polygon over several rings.
    pub(crate) fn inside_rings(p: P2, rings: &[Vec<P2>]) -> bool {
        let mut inside = false;
        for ring in rings {
            for i in 0..ring.len() {
                let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
                if (a[1] > p[1]) != (b[1] > p[1])
                    && p[0] < a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
                {
                    inside = !inside;
                }
            }
        }
        inside
    }

    /// Labels a mesh by triangle centroid against `rings` (even-odd); box-corner triangles are
    /// forced outside, as the labeler does.
    pub(crate) fn label_by_rings(mesh: Mesh, rings: &[Vec<P2>]) -> LabeledMesh {
        let n = mesh.triangles.len();
        let inside = (0..n)
            .map(|t| {
                let c = mesh.corners(t);
                let centroid = [
                    (c[0][0] + c[1][0] + c[2][0]) / 3.0,
                    (c[0][1] + c[1][1] + c[2][1]) / 3.0,
                ];
                !mesh.touches_corner(t) && inside_rings(centroid, rings)
            })
            .collect();
        let forced = (0..n)
            .map(|t| mesh.touches_corner(t).then_some(false))
            .collect();
        LabeledMesh {
            mesh,
            inside,
            forced,
        }
    }

    fn inside_area(l: &LabeledMesh) -> f64 {
        (0..l.inside.len())
            .filter(|&t| l.inside[t])
            .map(|t| l.mesh.area(t))
            .sum()
    }

    fn centroid(m: &Mesh, t: usize) -> P2 {
        let c = m.corners(t);
        [
            (c[0][0] + c[1][0] + c[2][0]) / 3.0,
            (c[0][1] + c[1][1] + c[2][1]) / 3.0,
        ]
    }

    /// A 4 × 3 m room whose walls are sampled every 5 cm, with a 0.25 m grid of clutter samples
    /// inside and outside so that islands can be planted.
    fn cluttered_room() -> (LabeledMesh, Vec<P2>) {
        let room = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]];
        let (mut pts, mut normals) = ring_samples(&room, 0.05);
        for i in 0..26 {
            for j in 0..22 {
                let p = [-0.6 + 0.2 * i as f64 + 0.013, -0.6 + 0.2 * j as f64 + 0.017];
                let near_wall = room
                    .iter()
                    .enumerate()
                    .any(|(k, &a)| geom::point_segment_distance(p, a, room[(k + 1) % 4]) < 0.06);
                if !near_wall {
                    pts.push(p);
                    normals.push([1.0, 0.0]);
                }
            }
        }
        let mesh = Mesh::build(&pts, &normals).unwrap();
        (label_by_rings(mesh, std::slice::from_ref(&room)), room)
    }

    #[test]
    fn planted_islands_are_flipped_and_forced_labels_hold() {
        let (mut l, room) = cluttered_room();
        let clean = l.clone();
        // The corner samples sit half a step from the corners, cutting 4 × 0.025² / 2 off.
        let area = inside_area(&l);
        assert!((area - (12.0 - 0.00125)).abs() < 1e-9, "room area {area}");
        // Plant an outside island (two adjacent interior triangles, 0.04 m²) and an inside island
        // (one triangle between the room and the box).
        let m = &l.mesh;
        let mid = (0..m.triangles.len())
            .find(|&t| geom::dist(centroid(m, t), [2.0, 1.5]) < 0.15 && l.inside[t])
            .unwrap();
        let mut island = vec![mid];
        island.extend(m.neighbors[mid].iter().take(1).map(|&n| n as usize));
        for &t in &island {
            l.inside[t] = false;
        }
        let out = (0..m.triangles.len())
            .find(|&t| {
                let c = centroid(m, t);
                c[0] > 4.2 && c[1] > 1.0 && c[1] < 2.0 && !m.touches_corner(t)
            })
            .unwrap();
        l.inside[out] = true;
        // A forced-outside triangle labelled inside must stay inside: forced labels are the
        // labeler's business, cleanup never overrides them.
        let corner_t = (0..m.triangles.len())
            .find(|&t| m.touches_corner(t))
            .unwrap();
        l.forced[corner_t] = Some(true);
        l.inside[corner_t] = true;
        let report = clean_labels(&mut l, &CleanupParams::default());
        assert_eq!(report.small_outside_flipped, 2);
        assert_eq!(report.small_inside_flipped, 1);
        assert!(l.inside[corner_t]);
        l.inside[corner_t] = false;
        assert_eq!(l.inside, clean.inside, "cleanup did not restore the room");
        let b = trace_boundary(&l).unwrap();
        b.check(&l).unwrap();
        assert_eq!(b.polygons.len(), 1);
        assert!(b.polygons[0].holes.is_empty());
        let _ = room;
    }

    #[test]
    fn column_hole_survives_cleanup() {
        let room = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]];
        let column = vec![[1.8, 1.3], [1.8, 1.6], [2.1, 1.6], [2.1, 1.3]];
        let (mut pts, mut normals) = ring_samples(&room, 0.05);
        let (cp, cn) = ring_samples(&column, 0.05);
        pts.extend(cp);
        normals.extend(cn);
        let mesh = Mesh::build(&pts, &normals).unwrap();
        let mut l = label_by_rings(mesh, &[room.clone(), column.clone()]);
        let column_triangles = (0..l.inside.len())
            .filter(|&t| inside_rings(centroid(&l.mesh, t), std::slice::from_ref(&column)))
            .count();
        assert!(
            column_triangles < 30,
            "the test needs a column of few triangles, got {column_triangles}"
        );
        let report = clean_labels(&mut l, &CleanupParams::default());
        assert_eq!(report.small_outside_flipped, 0);
        let b = trace_boundary(&l).unwrap();
        b.check(&l).unwrap();
        assert_eq!(b.polygons.len(), 1);
        assert_eq!(b.polygons[0].holes.len(), 1);
        let hole = &b.polygons[0].holes[0];
        assert!(
            (hole.signed_area + 0.09).abs() < 0.02,
            "{}",
            hole.signed_area
        );
        // Without the area guard the paper's rule fills the column in.
        let paper = CleanupParams {
            max_hole_area: f64::INFINITY,
            ..Default::default()
        };
        let mut l2 = l.clone();
        let r2 = clean_labels(&mut l2, &paper);
        assert_eq!(r2.small_outside_flipped, column_triangles);
        let b2 = trace_boundary(&l2).unwrap();
        b2.check(&l2).unwrap();
        assert!(b2.polygons[0].holes.is_empty());
    }

    #[test]
    fn spur_is_removed_by_protrusion_removal() {
        let room = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]];
        let (mut pts, mut normals) = ring_samples(&room, 0.05);
        // One stray sample 30 cm outside the right wall; the thin triangle it makes with two
        // wall samples is labelled inside: a spike whose only inside neighbour is across its
        // shortest edge.
        pts.push([4.3, 1.5]);
        normals.push([1.0, 0.0]);
        let mesh = Mesh::build(&pts, &normals).unwrap();
        let mut l = label_by_rings(mesh, std::slice::from_ref(&room));
        let mut planted = 0;
        for t in 0..l.inside.len() {
            let c = l.mesh.corners(t);
            if [[4.3, 1.5], [4.0, 1.475], [4.0, 1.525]]
                .iter()
                .all(|p| c.contains(p))
            {
                l.inside[t] = true;
                planted += 1;
            }
        }
        assert_eq!(planted, 1, "expected one spike triangle");
        let before = inside_area(&l);
        let no_peel = CleanupParams {
            remove_protrusions: false,
            ..Default::default()
        };
        let mut kept = l.clone();
        assert_eq!(clean_labels(&mut kept, &no_peel).protrusions_flipped, 0);
        assert_eq!(
            inside_area(&kept),
            before,
            "small-region removal must not see the spur"
        );
        let report = clean_labels(&mut l, &CleanupParams::default());
        assert_eq!(report.protrusions_flipped, 1);
        assert!((inside_area(&l) - (12.0 - 0.00125)).abs() < 1e-9);
        let b = trace_boundary(&l).unwrap();
        b.check(&l).unwrap();
    }

    #[test]
    fn convex_room_corners_are_not_protrusions() {
        let (mut l, _) = cluttered_room();
        let clean = l.clone();
        let report = clean_labels(&mut l, &CleanupParams::default());
        assert_eq!(report, CleanupReport::default());
        assert_eq!(l, clean);
        let b = trace_boundary(&l).unwrap();
        b.check(&l).unwrap();
        assert_eq!(b.polygons.len(), 1);
    }
}
