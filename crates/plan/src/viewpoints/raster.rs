//! A square-cell occupancy raster of 2D points and its exact Euclidean distance transform, for
//! finding empty places (the blind spot under a scanner, open floor between walls).

use crate::geom::P2;

/// Cells marked where at least one point falls.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Raster {
    /// Lower-left corner of cell (0, 0).
    pub lo: P2,
    pub cell: f64,
    pub nx: usize,
    pub ny: usize,
    pub occupied: Vec<bool>,
}

impl Raster {
    /// A raster over `points` (with `margin` metres around them) of cells of `cell` metres,
    /// coarsened as needed so that it has at most `max_cells`. `None` without points.
    pub fn of_points(
        points: impl Iterator<Item = P2> + Clone,
        cell: f64,
        margin: f64,
        max_cells: usize,
    ) -> Option<Raster> {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points.clone() {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if !(lo[0].is_finite() && hi[0].is_finite() && lo[1].is_finite() && hi[1].is_finite()) {
            return None;
        }
        let mut raster = Raster::covering(
            [lo[0] - margin, lo[1] - margin],
            [hi[0] + margin, hi[1] + margin],
            cell,
            max_cells,
        );
        for p in points {
            if let Some(i) = raster.index(p) {
                raster.occupied[i] = true;
            }
        }
        Some(raster)
    }

    /// An empty raster covering `lo..hi`, cells coarsened to stay within `max_cells`.
    pub fn covering(lo: P2, hi: P2, cell: f64, max_cells: usize) -> Raster {
        let (w, h) = ((hi[0] - lo[0]).max(cell), (hi[1] - lo[1]).max(cell));
        let mut cell = cell;
        while (w / cell).ceil() * (h / cell).ceil() > max_cells.max(1) as f64 {
            cell *= 2.0;
        }
        let (nx, ny) = ((w / cell).ceil() as usize, (h / cell).ceil() as usize);
        Raster {
            lo,
            cell,
            nx,
            ny,
            occupied: vec![false; nx * ny],
        }
    }

    /// The cell holding `p`, if inside.
    pub fn index(&self, p: P2) -> Option<usize> {
        let (fx, fy) = (
            (p[0] - self.lo[0]) / self.cell,
            (p[1] - self.lo[1]) / self.cell,
        );
        if !(fx >= 0.0 && fy >= 0.0) {
            return None;
        }
        let (i, j) = (fx as usize, fy as usize);
        (i < self.nx && j < self.ny).then(|| j * self.nx + i)
    }

    /// The centre of cell `(i, j)`.
    pub fn center(&self, i: usize, j: usize) -> P2 {
        [
            self.lo[0] + (i as f64 + 0.5) * self.cell,
            self.lo[1] + (j as f64 + 0.5) * self.cell,
        ]
    }

    /// Per cell, the distance in metres from its centre to the centre of the nearest occupied
    /// cell (infinite when no cell is occupied).
    pub fn distance(&self) -> Vec<f64> {
        let mut d: Vec<f64> = self
            .occupied
            .iter()
            .map(|&o| if o { 0.0 } else { f64::INFINITY })
            .collect();
        // Felzenszwalb & Huttenlocher: the squared transform is separable, rows then columns.
        let mut f = vec![0.0; self.nx.max(self.ny)];
        let mut out = vec![0.0; self.nx.max(self.ny)];
        let mut env = Envelope::new(self.nx.max(self.ny));
        for j in 0..self.ny {
            let row = &mut d[j * self.nx..(j + 1) * self.nx];
            f[..self.nx].copy_from_slice(row);
            env.transform(&f[..self.nx], &mut out[..self.nx]);
            row.copy_from_slice(&out[..self.nx]);
        }
        for i in 0..self.nx {
            for j in 0..self.ny {
                f[j] = d[j * self.nx + i];
            }
            env.transform(&f[..self.ny], &mut out[..self.ny]);
            for j in 0..self.ny {
                d[j * self.nx + i] = out[j];
            }
        }
        d.iter_mut().for_each(|v| *v = v.sqrt() * self.cell);
        d
    }

    /// Walks from `from` along the unit direction `dir` in half-cell steps and returns the
    /// distance to the first occupied cell, up to `max` metres.
    pub fn first_hit(&self, from: P2, dir: P2, max: f64) -> Option<f64> {
        let step = self.cell / 2.0;
        let mut t = step;
        while t <= max {
            match self.index([from[0] + t * dir[0], from[1] + t * dir[1]]) {
                Some(i) if self.occupied[i] => return Some(t),
                Some(_) => {}
                None => return None,
            }
            t += step;
        }
        None
    }
}

/// The lower envelope of parabolas for one line of the squared distance transform.
struct Envelope {
    v: Vec<usize>,
    z: Vec<f64>,
}

impl Envelope {
    fn new(n: usize) -> Envelope {
        Envelope {
            v: vec![0; n],
            z: vec![0.0; n + 1],
        }
    }

    /// `out[q] = min_p (q - p)² + f[p]`, with infinite `f` for empty cells.
    fn transform(&mut self, f: &[f64], out: &mut [f64]) {
        let n = f.len();
        let mut k = 0usize;
        let first = f.iter().position(|v| v.is_finite());
        let Some(first) = first else {
            out.iter_mut().for_each(|o| *o = f64::INFINITY);
            return;
        };
        self.v[0] = first;
        self.z[0] = f64::NEG_INFINITY;
        self.z[1] = f64::INFINITY;
        for q in first + 1..n {
            if !f[q].is_finite() {
                continue;
            }
            let s = |p: usize| {
                ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64)
            };
            // z[0] is -inf, so the walk back stops at the first parabola.
            while s(self.v[k]) <= self.z[k] {
                k -= 1;
            }
            let at = s(self.v[k]);
            k += 1;
            self.v[k] = q;
            self.z[k] = at;
            self.z[k + 1] = f64::INFINITY;
        }
        k = 0;
        for (q, o) in out.iter_mut().enumerate() {
            while self.z[k + 1] < q as f64 {
                k += 1;
            }
            let p = self.v[k];
            let d = q as f64 - p as f64;
            *o = d * d + f[p];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_matches_brute_force() {
        let mut r = Raster::covering([0.0, 0.0], [2.0, 1.5], 0.1, 10_000);
        assert_eq!((r.nx, r.ny), (20, 15));
        let marks = [(3, 4), (17, 2), (10, 14), (0, 0)];
        for &(i, j) in &marks {
            r.occupied[j * r.nx + i] = true;
        }
        let d = r.distance();
        for j in 0..r.ny {
            for i in 0..r.nx {
                let want = marks
                    .iter()
                    .map(|&(a, b)| {
                        (((i as f64 - a as f64).powi(2) + (j as f64 - b as f64).powi(2)).sqrt())
                            * 0.1
                    })
                    .fold(f64::INFINITY, f64::min);
                assert!((d[j * r.nx + i] - want).abs() < 1e-9, "({i}, {j})");
            }
        }
    }

    #[test]
    fn empty_raster_is_infinitely_far_and_rays_stop_at_marks() {
        let r = Raster::covering([0.0, 0.0], [1.0, 1.0], 0.1, 100);
        assert!(r.distance().iter().all(|d| d.is_infinite()));
        let mut r = r;
        let i = r.index([0.75, 0.25]).unwrap();
        r.occupied[i] = true;
        let t = r.first_hit([0.25, 0.25], [1.0, 0.0], 5.0).unwrap();
        assert!((0.45..=0.55).contains(&t), "{t}");
        assert_eq!(r.first_hit([0.25, 0.25], [0.0, 1.0], 5.0), None);
    }

    #[test]
    fn coarsens_to_the_cell_budget() {
        let r = Raster::covering([0.0, 0.0], [100.0, 100.0], 0.05, 10_000);
        assert!(r.nx * r.ny <= 10_000);
        assert_eq!(r.cell, 1.6);
    }
}
