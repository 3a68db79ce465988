//! The plan over its own points: per story, a raster of how many points lie in each grid cell
//! in a slice at mid-height, the cut a surveyor draws a plan at. Walls show as dark lines,
//! doors and windows as gaps, furniture below the slice not at all; cells with points only
//! above or below it (floor, ceiling, low furniture) show pale, so the scanned area is visible.
//!
//! The counts are gathered by the samples grid's counting pass (`samples::grid`), which
//! already visits every point of the story once: no second pass over the points. The image is
//! the samples grid itself, cell for cell, so it lies exactly under the plan.

use crate::geom::P2;
use crate::samples::{CellRange, GridFrame};
use crate::stories::Story;

/// The slice, as shares of the way from the floor to the lowest ceiling: for a 2.5 m story,
/// 1.0 m to 1.5 m, above desks and below most window heads.
pub const SLICE: [f64; 2] = [0.4, 0.6];

/// The longest side of an underlay, cells; larger grids are reduced by an integer factor
/// (the densest cell of each block wins), so an image stays a few megabytes at most.
pub const MAX_SIDE: usize = 4096;

/// Share of the non-empty slice cells drawn lighter than full ink: the densest few percent
/// (cells next to a scanner) saturate rather than wash out everything else.
const FULL_QUANTILE: f64 = 0.95;

/// A story's underlay: one byte per cell of the samples grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Underlay {
    /// Local x, y of the lower-left corner of cell (0, 0).
    pub origin: P2,
    /// Cell width, metres.
    pub cell: f64,
    /// Cells in x.
    pub nx: usize,
    /// Cells in y.
    pub ny: usize,
    /// Local heights of the slice, bottom and top.
    pub slice_z: [f64; 2],
    /// Per cell, rows from the south (row-major, `j * nx + i`): 0 no points, 1 points but none
    /// in the slice, 2..=255 slice points from one to [`Self::full`] and more, on a log scale.
    pub levels: Vec<u8>,
    /// Slice points a cell holds at full ink.
    pub full: u32,
}

/// The local heights of `story`'s slice.
pub fn slice_of(story: &Story) -> [f64; 2] {
    let h = story.wall_top_z - story.floor_z;
    SLICE.map(|s| story.floor_z + s * h)
}

/// Counts over a range of a story's grid: per cell, 0 when it holds no point of the story,
/// else one more than its points in the slice. Made by the counting pass, one per grid built.
#[derive(Debug, Clone, Default)]
pub(crate) struct DensityPart {
    pub range: Option<CellRange>,
    pub counts: Vec<u32>,
}

impl Underlay {
    /// The story's underlay from the parts of its grid (whole, or tile by tile when streaming;
    /// cells no part holds count as empty). `None` when no part holds a point.
    pub(crate) fn assemble(
        frame: &GridFrame,
        slice_z: [f64; 2],
        parts: &[DensityPart],
    ) -> Option<Underlay> {
        let (nx, ny) = (frame.nx, frame.ny);
        let mut counts = vec![0u32; nx * ny];
        for part in parts {
            let Some(r) = &part.range else { continue };
            let w = r.i.len();
            for (row, j) in r.j.clone().enumerate() {
                let from = &part.counts[row * w..(row + 1) * w];
                counts[j * nx + r.i.start..j * nx + r.i.end].copy_from_slice(from);
            }
        }
        if counts.iter().all(|&c| c == 0) {
            return None;
        }
        // Reduced by an integer factor when the grid is too large for an image.
        let k = nx.max(ny).div_ceil(MAX_SIDE).max(1);
        let (wx, wy) = (nx.div_ceil(k), ny.div_ceil(k));
        let counts = if k == 1 {
            counts
        } else {
            let mut out = vec![0u32; wx * wy];
            for j in 0..ny {
                for i in 0..nx {
                    let o = &mut out[(j / k) * wx + i / k];
                    *o = (*o).max(counts[j * nx + i]);
                }
            }
            out
        };
        let mut slice: Vec<u32> = counts.iter().filter(|&&c| c > 1).map(|c| c - 1).collect();
        let full = if slice.is_empty() {
            1
        } else {
            let at = ((slice.len() - 1) as f64 * FULL_QUANTILE) as usize;
            *slice.select_nth_unstable(at).1
        };
        let scale = 253.0 / (full as f64).ln_1p();
        let levels = counts
            .iter()
            .map(|&c| match c {
                0 => 0,
                1 => 1,
                c => (2.0 + ((c - 1) as f64).ln_1p() * scale).round().min(255.0) as u8,
            })
            .collect();
        Some(Underlay {
            origin: frame.origin,
            cell: frame.cell * k as f64,
            nx: wx,
            ny: wy,
            slice_z,
            levels,
            full,
        })
    }

    /// The local bounds of the image: lower-left and upper-right corners.
    pub fn bounds(&self) -> [P2; 2] {
        [
            self.origin,
            [
                self.origin[0] + self.nx as f64 * self.cell,
                self.origin[1] + self.ny as f64 * self.cell,
            ],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(nx: usize, ny: usize) -> GridFrame {
        GridFrame {
            origin: [1.0, 2.0],
            cell: 0.05,
            nx,
            ny,
        }
    }

    #[test]
    fn parts_land_in_their_cells_and_levels_rise_with_the_count() {
        let f = frame(4, 3);
        let left = DensityPart {
            range: Some(CellRange { i: 0..2, j: 0..3 }),
            counts: vec![0, 1, 2, 11, 101, 1001],
        };
        let right = DensityPart {
            range: Some(CellRange { i: 2..4, j: 1..2 }),
            counts: vec![1, 0],
        };
        let u = Underlay::assemble(&f, [1.0, 1.5], &[left, right]).unwrap();
        assert_eq!((u.nx, u.ny), (4, 3));
        let at = |i: usize, j: usize| u.levels[j * 4 + i];
        assert_eq!(
            (at(0, 0), at(1, 0)),
            (0, 1),
            "empty, then points off the slice"
        );
        assert_eq!((at(2, 1), at(3, 1), at(2, 0)), (1, 0, 0));
        let rising = [at(0, 1), at(1, 1), at(0, 2)];
        assert!(rising.windows(2).all(|w| w[0] < w[1]), "{rising:?}");
        assert!(rising[0] >= 2);
        // The 95th percentile of the slice counts (100 here) is full ink; denser cells saturate.
        assert_eq!(u.full, 100);
        assert_eq!((at(0, 2), at(1, 2)), (255, 255));
        assert_eq!(u.bounds(), [[1.0, 2.0], [1.2, 2.15]]);
        assert!(Underlay::assemble(&f, [1.0, 1.5], &[]).is_none());
    }

    #[test]
    fn large_grids_are_reduced_keeping_the_densest_cell() {
        let n = MAX_SIDE + 10;
        let mut counts = vec![0u32; n];
        counts[n - 1] = 50;
        let part = DensityPart {
            range: Some(CellRange { i: 0..n, j: 0..1 }),
            counts,
        };
        let u = Underlay::assemble(&frame(n, 1), [0.0, 1.0], &[part]).unwrap();
        assert_eq!((u.nx, u.ny), (n.div_ceil(2), 1));
        assert!((u.cell - 0.1).abs() < 1e-12);
        assert_eq!(u.levels[u.nx - 1], 255);
        assert_eq!(u.levels[0], 0);
    }
}
