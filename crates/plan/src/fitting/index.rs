//! A uniform grid over the boundary samples, so that finding a model's inliers reads only the
//! cells its inlier band crosses instead of every sample: scoring a RANSAC candidate costs the
//! band's length in cells plus the samples in it, not the boundary's size.

use crate::fitting::model::Model;
use crate::geom::P2;

/// `v.floor().max(0.0) as usize`, the same for every `v` (NaN gives 0): past zero the cast
/// truncates, which is the floor. The baseline x86-64 target calls libm for `floor`, and a
/// band walk asks twice a slab.
#[inline]
fn whole_cells(v: f64) -> usize {
    v.max(0.0) as usize
}

/// Sample indices bucketed by cell (compressed rows: `ids[start[c]..start[c + 1]]`).
pub struct SampleGrid {
    lo: P2,
    cell: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    ids: Vec<u32>,
}

impl SampleGrid {
    /// A grid over `pos` whose cells are at least `min_cell` wide and hold about one sample each
    /// on average (fewer cells than samples, whatever the extent).
    pub fn new(pos: &[P2], min_cell: f64) -> SampleGrid {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in pos.iter().filter(|p| p[0].is_finite() && p[1].is_finite()) {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if !lo[0].is_finite() {
            lo = [0.0; 2];
            hi = [0.0; 2];
        }
        let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
        let cell = min_cell
            .max((w * h / pos.len().max(1) as f64).sqrt())
            .max(w.max(h) / 4096.0)
            .max(1e-6);
        let nx = (w / cell).floor() as usize + 1;
        let ny = (h / cell).floor() as usize + 1;
        let mut g = SampleGrid {
            lo,
            cell,
            nx,
            ny,
            start: vec![0; nx * ny + 1],
            ids: vec![0; pos.len()],
        };
        let keys: Vec<Option<usize>> = pos.iter().map(|&p| g.key(p)).collect();
        for k in keys.iter().flatten() {
            g.start[k + 1] += 1;
        }
        for c in 0..nx * ny {
            g.start[c + 1] += g.start[c];
        }
        let mut fill = g.start.clone();
        for (i, k) in keys.iter().enumerate() {
            if let Some(k) = *k {
                g.ids[fill[k] as usize] = i as u32;
                fill[k] += 1;
            }
        }
        g
    }

    fn key(&self, p: P2) -> Option<usize> {
        if !(p[0].is_finite() && p[1].is_finite()) {
            return None;
        }
        let i = (((p[0] - self.lo[0]) / self.cell).floor() as usize).min(self.nx - 1);
        let j = (((p[1] - self.lo[1]) / self.cell).floor() as usize).min(self.ny - 1);
        Some(j * self.nx + i)
    }

    /// Calls `f` with every sample whose cell meets the bounding box of `pts`.
    pub fn in_box(&self, pts: [P2; 3], mut f: impl FnMut(usize)) {
        let lo = [0, 1].map(|k| pts.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min));
        let hi = [0, 1].map(|k| pts.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max));
        if !(lo[0].is_finite() && lo[1].is_finite() && hi[0].is_finite() && hi[1].is_finite()) {
            return;
        }
        let cell =
            |v: f64, k: usize, n: usize| whole_cells((v - self.lo[k]) / self.cell).min(n - 1);
        if hi[0] < self.lo[0] || hi[1] < self.lo[1] {
            return;
        }
        for j in cell(lo[1], 1, self.ny)..=cell(hi[1], 1, self.ny) {
            for i in cell(lo[0], 0, self.nx)..=cell(hi[0], 0, self.nx) {
                let c = j * self.nx + i;
                for &id in &self.ids[self.start[c] as usize..self.start[c + 1] as usize] {
                    f(id as usize);
                }
            }
        }
    }

    /// Calls `f` with every sample whose cell meets the band of half-width `t` around `model`
    /// (a superset of the samples within `t` of it).
    pub fn near(&self, model: &Model, t: f64, mut f: impl FnMut(usize)) {
        // Along the axis where the model changes slower, walk slabs of cells; in each, the
        // band covers one or two ranges of cells across.
        let range = |a: f64, b: f64, across_x: bool| -> Option<(usize, usize)> {
            let (n_across, lo) = if across_x {
                (self.nx, self.lo[0])
            } else {
                (self.ny, self.lo[1])
            };
            // NaN bounds (a degenerate model) visit nothing.
            if a.is_nan() || b.is_nan() || a > b || b < lo || a > lo + n_across as f64 * self.cell {
                return None;
            }
            let c0 = whole_cells((a - lo) / self.cell).min(n_across - 1);
            let c1 = whole_cells((b - lo) / self.cell).min(n_across - 1);
            Some((c0, c1))
        };
        let mut visit = |slab: usize, cells: (usize, usize), across_x: bool| {
            for c in cells.0..=cells.1 {
                let cell = if across_x {
                    slab * self.nx + c
                } else {
                    c * self.nx + slab
                };
                for &id in &self.ids[self.start[cell] as usize..self.start[cell + 1] as usize] {
                    f(id as usize);
                }
            }
        };
        match model {
            Model::Line(l) => {
                let d = l.dir;
                // Walk columns for lines nearer horizontal, rows otherwise.
                let by_columns = d[0].abs() >= d[1].abs();
                let (u, v) = if by_columns { (0, 1) } else { (1, 0) };
                let (n_slabs, lo_u) = if by_columns {
                    (self.nx, self.lo[0])
                } else {
                    (self.ny, self.lo[1])
                };
                let slope = d[v] / d[u];
                let half = t / d[u].abs();
                for s in 0..n_slabs {
                    let (u0, u1) = (
                        lo_u + s as f64 * self.cell,
                        lo_u + (s + 1) as f64 * self.cell,
                    );
                    let (a, b) = (
                        l.point[v] + (u0 - l.point[u]) * slope,
                        l.point[v] + (u1 - l.point[u]) * slope,
                    );
                    if let Some(cells) = range(a.min(b) - half, a.max(b) + half, !by_columns) {
                        visit(s, cells, !by_columns);
                    }
                }
            }
            Model::Circle(c) => {
                let (ro, ri) = (c.radius + t, (c.radius - t).max(0.0));
                for s in 0..self.nx {
                    let (x0, x1) = (
                        self.lo[0] + s as f64 * self.cell,
                        self.lo[0] + (s + 1) as f64 * self.cell,
                    );
                    let near_dx = if c.center[0] < x0 {
                        x0 - c.center[0]
                    } else if c.center[0] > x1 {
                        c.center[0] - x1
                    } else {
                        0.0
                    };
                    let far_dx = (x0 - c.center[0]).abs().max((x1 - c.center[0]).abs());
                    if near_dx > ro {
                        continue;
                    }
                    let outer = (ro * ro - near_dx * near_dx).sqrt();
                    // Within the inner radius over the whole column: no inliers there.
                    let inner = if ri > far_dx {
                        (ri * ri - far_dx * far_dx).sqrt()
                    } else {
                        0.0
                    };
                    let cy = c.center[1];
                    let (below, above) = if inner > 0.0 {
                        (
                            range(cy - outer, cy - inner, false),
                            range(cy + inner, cy + outer, false),
                        )
                    } else {
                        (range(cy - outer, cy + outer, false), None)
                    };
                    // The two ranges may share a cell: visit it once.
                    match (below, above) {
                        (Some(a), Some(b)) if a.1 >= b.0 => visit(s, (a.0, b.1), false),
                        (a, b) => {
                            for cells in [a, b].into_iter().flatten() {
                                visit(s, cells, false);
                            }
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fitting::circle::Circle;
    use crate::fitting::line::Line;
    use rand::{Rng, SeedableRng};

    #[test]
    fn whole_cells_is_the_floor_clamped_at_zero() {
        for v in [
            -3.5,
            -1.0,
            -0.25,
            -0.0,
            0.0,
            0.999_999,
            1.0,
            2.5,
            4_095.000_1,
            1e300,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            assert_eq!(whole_cells(v), v.floor().max(0.0) as usize, "{v}");
        }
    }

    /// Whatever the model, the grid hands out every sample within `t` of it.
    #[test]
    fn every_sample_within_the_band_is_visited() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let pos: Vec<P2> = (0..3000)
            .map(|_| [rng.random_range(-7.0..13.0), rng.random_range(2.0..9.0)])
            .collect();
        let grid = SampleGrid::new(&pos, 0.12);
        for k in 0..200 {
            let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let p = [rng.random_range(-8.0..14.0), rng.random_range(1.0..10.0)];
            let model = if k % 2 == 0 {
                Model::Line(Line {
                    point: p,
                    dir: [a.cos(), a.sin()],
                })
            } else {
                Model::Circle(Circle {
                    center: p,
                    radius: rng.random_range(0.05..12.0),
                })
            };
            let t = 0.03 + 0.1 * (k % 3) as f64;
            let mut seen = vec![0u32; pos.len()];
            grid.near(&model, t, |i| seen[i] += 1);
            for (i, &q) in pos.iter().enumerate() {
                if model.distance(q) <= t {
                    assert!(seen[i] > 0, "model {model:?}: sample {q:?} missed");
                }
            }
            assert!(seen.iter().all(|&c| c <= 1), "a sample visited twice");
        }
    }
}
