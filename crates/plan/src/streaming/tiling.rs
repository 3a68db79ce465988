//! The tiles: how many the memory budget needs, which tiles a point goes to (its own and those
//! within the halo), and which cells each tile owns.

use super::survey::Survey;
use super::{StreamingError, StreamingParams};
use crate::cloud::PointCloud;
use crate::params::Params;
use crate::pipeline::PlanError;
use crate::samples::grid::MAX_CELLS;
use crate::samples::{CellRange, GridFrame};

/// Per-cell cost of a tile's grid in memory, bytes: offsets, summaries, the kept-cell flags and
/// block screens; and [`CELL_BYTES_PER_THREAD`] more for each counting thread's summaries.
const CELL_BYTES: u64 = 24;
const CELL_BYTES_PER_THREAD: u64 = 16;
/// More tiles than this would keep too many files open.
const MAX_TILES: usize = 1024;
/// Memory set aside for what the model does not count: samples, the histogram, reader buffers.
const SLACK: f64 = 0.25;

/// The tiles: a regular grid of `nx` × `ny` rectangles over the cloud's horizontal bounds; the
/// outer ones reach out to infinity. A point belongs to every tile within `halo` of it.
pub(super) struct Tiling {
    pub(super) nx: usize,
    pub(super) ny: usize,
    pub(super) origin: [f64; 2],
    pub(super) size: [f64; 2],
    pub(super) halo: f64,
    /// Write buffer per tile file, bytes.
    pub(super) buffer: usize,
}

impl Tiling {
    /// The fewest tiles whose points and cells each fit the budget.
    pub(super) fn plan(
        survey: &Survey,
        skeleton: &PointCloud,
        params: &Params,
        stream: &StreamingParams,
    ) -> Result<Tiling, StreamingError> {
        let budget = stream.max_memory;
        let fail = |why: String| StreamingError::Budget { budget, why };
        let cell = params.samples.cell_size;
        if !(cell.is_finite() && cell > 0.0) {
            return Err(PlanError::Samples(crate::samples::SamplesError::BadParam {
                name: "cell_size",
                why: format!("{cell} is not a positive number"),
            })
            .into());
        }
        let halo = 2.0 * cell;
        let record = 12 + 2 * u64::from(!survey.no_scan) + 8 * u64::from(survey.has_time);
        // The tile's points, and the sorted copy of one story's.
        let point_bytes = 2 * record;
        let threads = rayon::current_num_threads().max(1) as u64;
        let cell_bytes = CELL_BYTES + CELL_BYTES_PER_THREAD * threads;
        let fixed = (survey.coarse.counts.len() * 8 * 2) as u64
            + (skeleton.scan_ids.len() * 64) as u64
            + (1 << 20);
        let usable = (budget as f64 * (1.0 - SLACK)) as u64;
        if usable <= fixed {
            return Err(fail(format!(
                "{fixed} bytes go to bookkeeping before any tile"
            )));
        }
        let usable = usable - fixed;
        let lo = [survey.lo[0] as f64, survey.lo[1] as f64];
        let span = [
            (survey.hi[0] as f64 - lo[0]).max(cell),
            (survey.hi[1] as f64 - lo[1]).max(cell),
        ];
        let sat = survey.coarse.summed();
        let mut side = span[0].max(span[1]) * (1.0 + 1e-9);
        let min_side = 4.0 * halo;
        loop {
            let nx = (span[0] / side).ceil().max(1.0) as usize;
            let ny = (span[1] / side).ceil().max(1.0) as usize;
            let size = [span[0] / nx as f64, span[1] / ny as f64];
            let tiles = nx * ny;
            // Each tile file gets a write buffer from a sixteenth of the budget.
            let buffer = ((budget / 16) / tiles as u64).min(1 << 20) as usize;
            let cells_side = |s: f64| ((s + 2.0 * halo) / cell).ceil() as u64 + 3;
            let cells = cells_side(size[0]) * cells_side(size[1]);
            let mut worst = 0;
            for ty in 0..ny {
                for tx in 0..nx {
                    let x = lo[0] + tx as f64 * size[0];
                    let y = lo[1] + ty as f64 * size[1];
                    let n = survey.coarse.at_most(
                        &sat,
                        (x - halo, x + size[0] + halo),
                        (y - halo, y + size[1] + halo),
                    );
                    worst = worst.max(n);
                }
            }
            let need = worst * point_bytes + cells * cell_bytes + (tiles * buffer) as u64;
            let fits = need <= usable && cells <= MAX_CELLS as u64 && buffer >= 4096;
            if fits && tiles <= MAX_TILES {
                return Ok(Tiling {
                    nx,
                    ny,
                    origin: lo,
                    size,
                    halo,
                    buffer,
                });
            }
            if tiles > MAX_TILES || side < min_side {
                return Err(fail(format!(
                    "{} points over {:.0} m × {:.0} m do not split into at most {MAX_TILES} tiles \
                     of {usable} bytes each ({worst} points in the fullest of {nx} × {ny} tiles \
                     need {need} bytes)",
                    survey.n, span[0], span[1]
                )));
            }
            side /= 1.25;
        }
    }

    pub(super) fn count(&self) -> usize {
        self.nx * self.ny
    }

    /// The column (or row, `k` = 1) of the tile holding coordinate `v`.
    #[inline]
    pub(super) fn band(&self, v: f64, k: usize) -> usize {
        let n = if k == 0 { self.nx } else { self.ny };
        // Casts saturate: left of the first tile is the first tile.
        (((v - self.origin[k]) / self.size[k]) as usize).min(n - 1)
    }

    /// The columns and rows of the tiles a point goes to: its own, and those within the halo.
    #[inline]
    pub(super) fn tiles_of(
        &self,
        p: &[f32; 3],
    ) -> (
        std::ops::RangeInclusive<usize>,
        std::ops::RangeInclusive<usize>,
    ) {
        let (x, y) = (p[0] as f64, p[1] as f64);
        (
            self.band(x - self.halo, 0)..=self.band(x + self.halo, 0),
            self.band(y - self.halo, 1)..=self.band(y + self.halo, 1),
        )
    }

    /// The cells of `frame` whose centres lie in tile `t`.
    pub(super) fn core(&self, t: usize, frame: &GridFrame) -> CellRange {
        let (tx, ty) = (t % self.nx, t / self.nx);
        let centre = |i: usize, k: usize| frame.origin[k] + (i as f64 + 0.5) * frame.cell;
        // Bands grow with the cell index, so each tile's cells are found by bisection.
        let span = |n: usize, k: usize, band: usize| {
            let first = |pred: &dyn Fn(usize) -> bool| {
                let (mut a, mut b) = (0, n);
                while a < b {
                    let m = (a + b) / 2;
                    if pred(m) {
                        a = m + 1;
                    } else {
                        b = m;
                    }
                }
                a
            };
            first(&|i| self.band(centre(i, k), k) < band)..first(&|i| {
                self.band(centre(i, k), k) <= band
            })
        };
        CellRange {
            i: span(frame.nx, 0, tx),
            j: span(frame.ny, 1, ty),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_cores_partition_the_cells() {
        let tiling = Tiling {
            nx: 3,
            ny: 2,
            origin: [0.0, 0.0],
            size: [1.0, 1.5],
            halo: 0.1,
            buffer: 4096,
        };
        let frame = GridFrame {
            origin: [0.013, -0.02],
            cell: 0.05,
            nx: 61,
            ny: 61,
        };
        let mut owned = vec![0u8; frame.nx * frame.ny];
        for t in 0..tiling.count() {
            let core = tiling.core(t, &frame);
            for j in core.j.clone() {
                for i in core.i.clone() {
                    owned[j * frame.nx + i] += 1;
                }
            }
        }
        assert!(owned.iter().all(|&c| c == 1));
        // A point near a corner goes to the four tiles around it.
        let (cols, rows) = tiling.tiles_of(&[1.05, 1.45, 0.0]);
        assert_eq!((cols, rows), (0..=1, 0..=1));
        let (cols, rows) = tiling.tiles_of(&[2.5, 0.5, 0.0]);
        assert_eq!((cols, rows), (2..=2, 0..=0));
    }
}
