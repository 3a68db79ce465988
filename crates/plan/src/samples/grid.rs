//! The d_s grid over one story: point indices counting-sorted by cell, so that a cell's points
//! are one contiguous run of `order`. Only index arrays are allocated; the cloud is not copied.

use rayon::prelude::*;

use super::SamplesError;
use crate::stories::Story;

/// The most cells a story's grid may have (about 200 m × 200 m at 5 cm). Beyond it the cloud
/// holds far outliers, and the per-cell arrays would waste memory.
pub(super) const MAX_CELLS: usize = 1 << 24;

/// A story's points sorted by d_s grid cell. Cell `(i, j)` has id `j * nx + i`.
pub(super) struct Grid {
    /// Local x, y of the lower-left corner of cell (0, 0).
    pub origin: [f64; 2],
    /// d_s, metres.
    pub cell: f64,
    pub nx: usize,
    pub ny: usize,
    /// `order[start[c]..start[c + 1]]` are the indices of the points in cell `c`.
    pub start: Vec<u32>,
    pub order: Vec<u32>,
    /// Per cell: the heights of its own points.
    pub summaries: Vec<Summary>,
}

/// The heights of one cell's own points: their range, and which height bins they fill.
#[derive(Debug, Clone, Copy)]
pub(super) struct Summary {
    pub zmin: f32,
    pub zmax: f32,
    pub mask: u32,
}

impl Default for Summary {
    fn default() -> Self {
        Summary {
            zmin: f32::INFINITY,
            zmax: f32::NEG_INFINITY,
            mask: 0,
        }
    }
}

impl Grid {
    /// Sorts the points of `story` (those with `z_min <= z < z_max`) into a grid of `cell` metres,
    /// and summarizes each cell's heights with `bin_of`, the height bin of a z.
    pub fn build(
        xyz: &[[f32; 3]],
        story: &Story,
        cell: f64,
        bin_of: impl Fn(f32) -> Option<u32>,
    ) -> Result<Grid, SamplesError> {
        if xyz.len() >= u32::MAX as usize {
            return Err(SamplesError::TooLarge(format!(
                "{} points exceed the 2^32 a story can index",
                xyz.len()
            )));
        }
        let in_story = |z: f32| (z as f64) >= story.z_min && (z as f64) < story.z_max;
        let bounds = xyz
            .par_iter()
            .fold(Bounds::default, |b, p| b.add(p, in_story(p[2])))
            .reduce(Bounds::default, Bounds::merge);
        if bounds.non_finite > 0 {
            return Err(SamplesError::NonFinite(bounds.non_finite));
        }
        if bounds.n == 0 {
            return Err(SamplesError::EmptyStory { level: story.level });
        }
        let origin = [bounds.lo[0] as f64, bounds.lo[1] as f64];
        let span = [
            bounds.hi[0] as f64 - origin[0],
            bounds.hi[1] as f64 - origin[1],
        ];
        let nx = (span[0] / cell) as usize + 1;
        let ny = (span[1] / cell) as usize + 1;
        if nx.saturating_mul(ny) > MAX_CELLS {
            return Err(SamplesError::TooLarge(format!(
                "story {} spans {:.0} m × {:.0} m, {nx} × {ny} cells of {cell} m; are there outliers?",
                story.level, span[0], span[1]
            )));
        }
        let inv = 1.0 / cell;
        let cell_of = |p: &[f32; 3]| {
            let i = (((p[0] as f64 - origin[0]) * inv) as usize).min(nx - 1);
            let j = (((p[1] as f64 - origin[1]) * inv) as usize).min(ny - 1);
            (j * nx + i) as u32
        };
        // Counting sort: cells in parallel, then counts, prefix sums and a scatter. The
        // counting pass also summarizes heights, reading the cloud in its own order.
        let ids: Vec<u32> = xyz
            .par_iter()
            .map(|p| if in_story(p[2]) { cell_of(p) } else { u32::MAX })
            .collect();
        let mut start = vec![0u32; nx * ny + 1];
        let mut summaries = vec![Summary::default(); nx * ny];
        for (&c, p) in ids.iter().zip(xyz) {
            if c == u32::MAX {
                continue;
            }
            start[c as usize + 1] += 1;
            let s = &mut summaries[c as usize];
            s.zmin = s.zmin.min(p[2]);
            s.zmax = s.zmax.max(p[2]);
            if let Some(b) = bin_of(p[2]) {
                s.mask |= 1 << b;
            }
        }
        for c in 0..nx * ny {
            start[c + 1] += start[c];
        }
        let mut next = start.clone();
        let mut order = vec![0u32; bounds.n];
        for (k, &c) in ids.iter().enumerate() {
            if c != u32::MAX {
                order[next[c as usize] as usize] = k as u32;
                next[c as usize] += 1;
            }
        }
        Ok(Grid {
            origin,
            cell,
            nx,
            ny,
            start,
            order,
            summaries,
        })
    }

    /// Indices of the points in cell `(i, j)`.
    pub fn points(&self, i: usize, j: usize) -> &[u32] {
        let c = j * self.nx + i;
        &self.order[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// The lower-left corner of cell `(i, j)`.
    pub fn corner(&self, i: usize, j: usize) -> [f64; 2] {
        [
            self.origin[0] + i as f64 * self.cell,
            self.origin[1] + j as f64 * self.cell,
        ]
    }

    /// The cells of the 3 × 3 block around `(i, j)`, clipped to the grid.
    pub fn block(&self, i: usize, j: usize) -> impl Iterator<Item = (usize, usize)> {
        let (nx, ny) = (self.nx, self.ny);
        let xs = i.saturating_sub(1)..(i + 2).min(nx);
        (j.saturating_sub(1)..(j + 2).min(ny)).flat_map(move |b| xs.clone().map(move |a| (a, b)))
    }
}

/// Horizontal bounds and count of a story's points, and the number of non-finite points.
#[derive(Clone, Copy)]
struct Bounds {
    lo: [f32; 2],
    hi: [f32; 2],
    n: usize,
    non_finite: usize,
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds {
            lo: [f32::INFINITY; 2],
            hi: [f32::NEG_INFINITY; 2],
            n: 0,
            non_finite: 0,
        }
    }
}

impl Bounds {
    fn add(mut self, p: &[f32; 3], inside: bool) -> Bounds {
        if !p.iter().all(|c| c.is_finite()) {
            self.non_finite += 1;
        } else if inside {
            self.lo = [self.lo[0].min(p[0]), self.lo[1].min(p[1])];
            self.hi = [self.hi[0].max(p[0]), self.hi[1].max(p[1])];
            self.n += 1;
        }
        self
    }

    fn merge(a: Bounds, b: Bounds) -> Bounds {
        Bounds {
            lo: [a.lo[0].min(b.lo[0]), a.lo[1].min(b.lo[1])],
            hi: [a.hi[0].max(b.hi[0]), a.hi[1].max(b.hi[1])],
            n: a.n + b.n,
            non_finite: a.non_finite + b.non_finite,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_land_in_their_cells_and_out_of_story_points_are_left_out() {
        let story = Story {
            level: 0,
            floor_z: 0.0,
            ceiling_z: 2.0,
            z_min: 0.0,
            z_max: 2.0,
        };
        let xyz = [
            [0.0, 0.0, 1.0],
            [0.12, 0.01, 1.0],
            [0.02, 0.07, 1.0],
            [0.11, 0.02, 5.0], // above the story
            [0.04, 0.04, 0.5],
        ];
        let g = Grid::build(&xyz, &story, 0.05, |z| Some((z > 0.75) as u32)).unwrap();
        assert_eq!((g.nx, g.ny), (3, 2));
        assert_eq!(g.points(0, 0), &[0, 4]);
        assert_eq!(g.points(2, 0), &[1]);
        assert_eq!(g.points(0, 1), &[2]);
        assert_eq!(g.order.len(), 4);
        assert_eq!(g.block(0, 0).count(), 4);
        assert_eq!(g.block(1, 0).count(), 6);
        let s = g.summaries[0];
        assert_eq!((s.zmin, s.zmax, s.mask), (0.5, 1.0, 0b11));
    }
}
