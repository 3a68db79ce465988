//! Vertices behind faces whose wall has no other face (beyond the paper).
//!
//! A face seen well from one room stands for solid wall behind it, however poorly the room on
//! the other side saw the wall's other face. Without vertices there, Delaunay spans from the
//! seen face to whatever the other room's samples are (often a wall metres away), and that
//! room's lines of sight force those long triangles inside: the wall is carved, and the two
//! rooms join. A mobile scanner that only steps into a room leaves exactly this at the room's
//! corners. So behind every oriented sample with no opposite face within a wall's reach, a
//! vertex is placed one typical wall thickness back, facing the other way: where the other
//! face was seen after all, nothing is added; where it was not, the wall keeps a thickness.
//! Only where the wall was carved are backs added: where lines of sight from the other side
//! forced inside the triangle just behind the face. Behind an exterior wall, or around a shaft
//! nobody looked into, nothing forced the labels, and backs there only give the labeling a
//! second surface to close rooms on. The triangles between a face and its backs are solid
//! (forced outside, unless lines of sight cross them).

use std::collections::HashMap;

use crate::geom::{self, P2};
use crate::samples::WallSample;

/// Faces farther apart than this are not one wall, metres: an opposite face is looked for this
/// far behind a sample.
const MAX_BEHIND: f64 = 0.5;

/// The assumed thickness is the median over the story's walls seen from both sides, clamped to
/// this range, metres. Without any such wall, the thinnest partitions' thickness is taken.
const MIN_THICKNESS: f64 = 0.08;
const MAX_THICKNESS: f64 = 0.4;

/// Two faces are opposite when their normals are within 30° of antiparallel...
const OPPOSITE_COS: f64 = 0.866;

/// ...and the other lies within this many sample spacings of the line through the sample
/// along its normal.
const ACROSS: f64 = 1.5;

/// A line of sight passing within this many spacings of the place halfway behind a face shows
/// the place open: the face is clutter standing in a room, not a wall.
pub(crate) const SEEN_WITHIN: f64 = 1.0;

/// No vertex is added within this many spacings of a sample: the place is vertexed already.
const CLEAR: f64 = 0.75;

/// A place behind a face where the wall may need a vertex.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Back {
    /// The face's sample.
    pub sample: usize,
    /// One typical wall thickness behind the face.
    pub point: P2,
    /// The face's normal, reversed.
    pub normal: P2,
    /// Points halfway back, under the sample and half a spacing to either side: inside the
    /// wall, between the face and its back.
    pub probes: [P2; 3],
}

/// What is added behind the faces that need it.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Backs {
    /// Vertices, at least [`CLEAR`] spacings apart.
    pub points: Vec<P2>,
    pub normals: Vec<P2>,
    /// Points inside the walls so backed.
    pub solid: Vec<P2>,
}

/// The backs of `samples` whose wall shows no other face. Only samples seen from a viewpoint
/// count: their normals say which side the room is on.
pub(crate) fn place(samples: &[WallSample], spacing: f64) -> Vec<Back> {
    if spacing.is_nan() || spacing <= 0.0 || samples.is_empty() {
        return Vec::new();
    }
    let index = Index::new(samples, spacing);
    let oriented = |s: &WallSample| !s.seen_from.is_empty() && geom::norm(s.normal) > 0.5;
    // Per oriented sample: the distance to the opposite face behind it, if any.
    let behind: Vec<Option<f64>> = samples
        .iter()
        .map(|s| {
            oriented(s)
                .then(|| opposite(samples, &index, s, spacing))
                .flatten()
        })
        .collect();
    let mut seen: Vec<f64> = behind.iter().flatten().copied().collect();
    let thickness = if seen.is_empty() {
        MIN_THICKNESS
    } else {
        let mid = seen.len() / 2;
        *seen.select_nth_unstable_by(mid, f64::total_cmp).1
    }
    .clamp(MIN_THICKNESS, MAX_THICKNESS);
    let mut out = Vec::new();
    for (k, (s, b)) in samples.iter().zip(&behind).enumerate() {
        if !oriented(s) || b.is_some() {
            continue;
        }
        let n = s.normal;
        let point = geom::sub(s.pos, geom::scale(n, thickness));
        if index.any_within(samples, point, CLEAR * spacing) {
            continue;
        }
        let mid = geom::sub(s.pos, geom::scale(n, thickness / 2.0));
        let along = geom::scale([-n[1], n[0]], spacing / 2.0);
        out.push(Back {
            sample: k,
            point,
            normal: geom::scale(n, -1.0),
            probes: [geom::sub(mid, along), mid, geom::add(mid, along)],
        });
    }
    out
}

/// The vertices and solid points of the backs `keep` accepts, one vertex per place.
pub(crate) fn select(backs: &[Back], spacing: f64, mut keep: impl FnMut(&Back) -> bool) -> Backs {
    let mut out = Backs::default();
    let mut placed: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for b in backs {
        if !keep(b) {
            continue;
        }
        out.solid.extend(b.probes);
        // Neighbouring samples of one face put their backs side by side: one is enough.
        let r = CLEAR * spacing;
        let (i, j) = key(b.point, r);
        let near = (i - 1..=i + 1).any(|x| {
            (j - 1..=j + 1).any(|y| {
                placed.get(&(x, y)).is_some_and(|ks: &Vec<usize>| {
                    ks.iter().any(|&k| geom::dist(out.points[k], b.point) < r)
                })
            })
        });
        if !near {
            placed.entry((i, j)).or_default().push(out.points.len());
            out.points.push(b.point);
            out.normals.push(b.normal);
        }
    }
    out
}

/// The distance behind `s` to the nearest sample facing the other way on its normal's line.
fn opposite(samples: &[WallSample], index: &Index, s: &WallSample, h: f64) -> Option<f64> {
    let n = s.normal;
    let mut best: Option<f64> = None;
    index.visit(s.pos, MAX_BEHIND, |k| {
        let q = &samples[k];
        if geom::dot(q.normal, n) > -OPPOSITE_COS * geom::norm(q.normal) {
            return;
        }
        let d = geom::sub(q.pos, s.pos);
        let back = -geom::dot(d, n);
        if back > 0.0 && back <= MAX_BEHIND && geom::cross(d, n).abs() <= ACROSS * h {
            best = Some(best.map_or(back, |b: f64| b.min(back)));
        }
    });
    best
}

/// Samples hashed on a square grid.
struct Index {
    cell: f64,
    cells: HashMap<(i64, i64), Vec<usize>>,
}

impl Index {
    fn new(samples: &[WallSample], spacing: f64) -> Index {
        // Cells of a few spacings: a search visits few cells and few samples per cell.
        let cell = (4.0 * spacing).max(1e-6);
        let mut cells: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
        for (k, s) in samples.iter().enumerate() {
            if s.pos.iter().all(|c| c.is_finite()) {
                cells.entry(key(s.pos, cell)).or_default().push(k);
            }
        }
        Index { cell, cells }
    }

    /// Calls `f` with every sample in the cells within `r` of `p` (a superset of the disc).
    fn visit(&self, p: P2, r: f64, mut f: impl FnMut(usize)) {
        if !p.iter().all(|c| c.is_finite()) {
            return;
        }
        let (lo, hi) = (
            key([p[0] - r, p[1] - r], self.cell),
            key([p[0] + r, p[1] + r], self.cell),
        );
        for i in lo.0..=hi.0 {
            for j in lo.1..=hi.1 {
                for &k in self.cells.get(&(i, j)).map(Vec::as_slice).unwrap_or(&[]) {
                    f(k);
                }
            }
        }
    }

    fn any_within(&self, samples: &[WallSample], p: P2, r: f64) -> bool {
        let mut hit = false;
        self.visit(p, r, |k| hit |= geom::dist(samples[k].pos, p) < r);
        hit
    }
}

fn key(p: P2, cell: f64) -> (i64, i64) {
    ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn face(from: P2, to: P2, normal: P2, step: f64) -> Vec<WallSample> {
        let n = (geom::dist(from, to) / step).round() as usize;
        (0..=n)
            .map(|i| {
                let t = i as f64 / n as f64;
                WallSample {
                    pos: geom::add(from, geom::scale(geom::sub(to, from), t)),
                    normal,
                    confidence: 1.0,
                    seen_from: vec![0],
                }
            })
            .collect()
    }

    #[test]
    fn a_wall_seen_from_both_sides_gets_nothing() {
        // A 20 cm wall along x, faces at y = 0 (room below) and y = 0.2 (room above).
        let mut s = face([0.0, 0.0], [2.0, 0.0], [0.0, -1.0], 0.05);
        s.extend(face([0.0, 0.2], [2.0, 0.2], [0.0, 1.0], 0.05));
        assert_eq!(place(&s, 0.05), Vec::new());
    }

    #[test]
    fn a_face_without_its_other_side_gets_one_at_the_walls_thickness() {
        // Both faces from x = 0 to 2; the lower face goes on alone to x = 4.
        let mut s = face([0.0, 0.0], [4.0, 0.0], [0.0, -1.0], 0.05);
        s.extend(face([0.0, 0.2], [2.0, 0.2], [0.0, 1.0], 0.05));
        let backs = place(&s, 0.05);
        assert!(!backs.is_empty());
        for b in &backs {
            // Behind the lone stretch only, at the paired stretch's thickness, facing up.
            assert!(b.point[0] > 2.0 - 1e-9 && b.point[0] <= 4.0 + 1e-9, "{b:?}");
            assert!((b.point[1] - 0.2).abs() < 1e-9, "{b:?}");
            assert_eq!(b.normal, [0.0, 1.0]);
            assert!(b.probes.iter().all(|p| (p[1] - 0.1).abs() < 1e-9));
        }
        // About one per sample of the lone stretch (2 m at 5 cm).
        assert!((35..=41).contains(&backs.len()), "{}", backs.len());
        let all = select(&backs, 0.05, |_| true);
        assert_eq!(all.points.len(), backs.len());
        assert_eq!(all.solid.len(), 3 * backs.len());
        let none = select(&backs, 0.05, |b| b.point[0] > 10.0);
        assert_eq!(none, Backs::default());
    }

    #[test]
    fn backs_closer_than_a_spacing_make_one_vertex() {
        // Two rows of samples 1 cm apart (noise on one face): their backs coincide.
        let mut s = face([0.0, 0.0], [1.0, 0.0], [0.0, -1.0], 0.05);
        s.extend(face([0.0, 0.01], [1.0, 0.01], [0.0, -1.0], 0.05));
        let backs = place(&s, 0.05);
        let kept = select(&backs, 0.05, |_| true);
        assert!(
            kept.points.len() * 2 <= backs.len() + 1,
            "{} of {}",
            kept.points.len(),
            backs.len()
        );
        assert_eq!(kept.solid.len(), 3 * backs.len());
    }

    #[test]
    fn unoriented_samples_get_nothing() {
        let mut s = face([0.0, 0.0], [2.0, 0.0], [0.0, -1.0], 0.05);
        s.iter_mut().for_each(|s| s.seen_from.clear());
        assert!(place(&s, 0.05).is_empty());
    }

    #[test]
    fn without_any_wall_seen_from_both_sides_the_thinnest_partition_is_assumed() {
        let s = face([0.0, 0.0], [1.0, 0.0], [0.0, -1.0], 0.05);
        let backs = place(&s, 0.05);
        assert!(!backs.is_empty());
        assert!(backs
            .iter()
            .all(|b| (b.point[1] - MIN_THICKNESS).abs() < 1e-9));
    }
}
