//! Where a story's grid lies and which points can touch it: the horizontal bounds of a story's
//! points ([`StoryBounds`], measured whole or merged from parts), the frame they fix
//! ([`GridFrame`]), rectangles of its cells ([`CellRange`]), and the height range of each block
//! of points ([`Blocks`]) that lets a story's passes skip the others' points.

use std::ops::{Range, RangeInclusive};

use rayon::prelude::*;

use super::grid::MAX_CELLS;
use super::SamplesError;
use crate::stories::Story;

/// Where a story's grid lies: cell `(i, j)` spans `origin + [i, i + 1) × cell` in x and the
/// same in y, for `i < nx`, `j < ny`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridFrame {
    /// Local x, y of the lower-left corner of cell (0, 0).
    pub origin: [f64; 2],
    /// d_s, metres.
    pub cell: f64,
    /// Cells in x.
    pub nx: usize,
    /// Cells in y.
    pub ny: usize,
}

impl GridFrame {
    /// The cell of a point (of the story). Points on the far edge go to the last cell.
    #[inline]
    pub fn cell_of(&self, p: &[f32; 3]) -> (usize, usize) {
        let inv = 1.0 / self.cell;
        let i = (((p[0] as f64 - self.origin[0]) * inv) as usize).min(self.nx - 1);
        let j = (((p[1] as f64 - self.origin[1]) * inv) as usize).min(self.ny - 1);
        (i, j)
    }

    /// Every cell of the grid.
    pub fn all(&self) -> CellRange {
        CellRange {
            i: 0..self.nx,
            j: 0..self.ny,
        }
    }

    /// The lower-left corner of cell `(i, j)`.
    pub fn corner(&self, i: usize, j: usize) -> [f64; 2] {
        [
            self.origin[0] + i as f64 * self.cell,
            self.origin[1] + j as f64 * self.cell,
        ]
    }
}

/// A rectangle of cells, `i` by `j`, half-open.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CellRange {
    /// The cells' x indices.
    pub i: Range<usize>,
    /// The cells' y indices.
    pub j: Range<usize>,
}

impl CellRange {
    /// True when the range holds no cell.
    pub fn is_empty(&self) -> bool {
        self.i.is_empty() || self.j.is_empty()
    }

    pub(super) fn width(&self) -> usize {
        self.i.len()
    }

    pub(super) fn cells(&self) -> usize {
        self.i.len() * self.j.len()
    }

    /// The 3 × 3 block of cells around `(i, j)`, clipped to this range: columns, then rows.
    pub(super) fn block_around(&self, i: usize, j: usize) -> (Range<usize>, Range<usize>) {
        (
            i.saturating_sub(1).max(self.i.start)..(i + 2).min(self.i.end),
            j.saturating_sub(1).max(self.j.start)..(j + 2).min(self.j.end),
        )
    }

    /// The range grown by one cell on every side, clipped to `frame`.
    pub fn grown(&self, frame: &GridFrame) -> CellRange {
        CellRange {
            i: self.i.start.saturating_sub(1)..(self.i.end + 1).min(frame.nx),
            j: self.j.start.saturating_sub(1)..(self.j.end + 1).min(frame.ny),
        }
    }
}

/// Horizontal bounds and count of a story's points, and the number of non-finite points seen.
/// Bounds of parts of a cloud merge into the bounds of the whole.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StoryBounds {
    /// Smallest local x, y of the story's points.
    pub lo: [f32; 2],
    /// Largest local x, y of the story's points.
    pub hi: [f32; 2],
    /// Points within the story.
    pub n: usize,
    /// Points with a non-finite coordinate, left out.
    pub non_finite: usize,
}

impl Default for StoryBounds {
    fn default() -> Self {
        StoryBounds {
            lo: [f32::INFINITY; 2],
            hi: [f32::NEG_INFINITY; 2],
            n: 0,
            non_finite: 0,
        }
    }
}

/// Whether height `z` belongs to `story` (its partition range).
#[inline]
pub(crate) fn in_story(story: &Story, z: f32) -> bool {
    (z as f64) >= story.z_min && (z as f64) < story.z_max
}

impl StoryBounds {
    /// The bounds of the story's points among `xyz`, in parallel.
    pub fn measure(xyz: &[[f32; 3]], story: &Story) -> StoryBounds {
        xyz.par_iter()
            .fold(StoryBounds::default, |b, p| b.add(p, story))
            .reduce(StoryBounds::default, StoryBounds::merge)
    }

    /// The bounds of every story's points among `xyz`, and the height range of each block of
    /// [`Blocks::SIZE`] points, in one parallel pass. `stories` must be in ascending order with
    /// disjoint ranges, as [`crate::stories`] gives them.
    pub fn measure_all(xyz: &[[f32; 3]], stories: &[Story]) -> (Vec<StoryBounds>, Blocks) {
        let parts: Vec<(Vec<StoryBounds>, (f32, f32))> = xyz
            .par_chunks(Blocks::SIZE)
            .map(|block| {
                let mut acc = vec![StoryBounds::default(); stories.len()];
                let (lo, hi) = block
                    .iter()
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |z, p| {
                        (z.0.min(p[2]), z.1.max(p[2]))
                    });
                let finite = block.iter().all(|p| p.iter().all(|c| c.is_finite()));
                // A scanner station sees mostly its own story, so most blocks lie within one:
                // their bounds are plain minima and maxima, with no per-point story lookup.
                let k = stories.partition_point(|s| s.z_max <= lo as f64);
                match stories.get(k) {
                    Some(s) if finite && in_story(s, lo) && in_story(s, hi) => {
                        acc[k] = block.iter().fold(acc[k], StoryBounds::include);
                        return (acc, (lo, hi));
                    }
                    _ => {}
                }
                let mut z = (f32::INFINITY, f32::NEG_INFINITY);
                for p in block {
                    if !p.iter().all(|c| c.is_finite()) {
                        acc.iter_mut().for_each(|b| b.non_finite += 1);
                        // Non-finite heights make the block's range cover everything.
                        z = (f32::NEG_INFINITY, f32::INFINITY);
                        continue;
                    }
                    z = (z.0.min(p[2]), z.1.max(p[2]));
                    let k = stories.partition_point(|s| s.z_max <= p[2] as f64);
                    if let (Some(b), Some(s)) = (acc.get_mut(k), stories.get(k)) {
                        *b = b.add(p, s);
                    }
                }
                (acc, z)
            })
            .collect();
        let mut all = vec![StoryBounds::default(); stories.len()];
        let mut z = Vec::with_capacity(parts.len());
        for (acc, range) in parts {
            all = all
                .into_iter()
                .zip(acc)
                .map(|(a, b)| StoryBounds::merge(a, b))
                .collect();
            z.push(range);
        }
        (all, Blocks { z })
    }

    /// Adds one point: to the bounds when it belongs to the story, to `non_finite` when a
    /// coordinate is not finite.
    #[inline]
    pub fn add(mut self, p: &[f32; 3], story: &Story) -> StoryBounds {
        if !p.iter().all(|c| c.is_finite()) {
            self.non_finite += 1;
        } else if in_story(story, p[2]) {
            self = self.include(p);
        }
        self
    }

    /// Widens the bounds to take in `p` and counts it.
    #[inline]
    fn include(self, p: &[f32; 3]) -> StoryBounds {
        StoryBounds {
            lo: [self.lo[0].min(p[0]), self.lo[1].min(p[1])],
            hi: [self.hi[0].max(p[0]), self.hi[1].max(p[1])],
            n: self.n + 1,
            ..self
        }
    }

    /// The bounds of both parts together.
    pub fn merge(a: StoryBounds, b: StoryBounds) -> StoryBounds {
        StoryBounds {
            lo: [a.lo[0].min(b.lo[0]), a.lo[1].min(b.lo[1])],
            hi: [a.hi[0].max(b.hi[0]), a.hi[1].max(b.hi[1])],
            n: a.n + b.n,
            non_finite: a.non_finite + b.non_finite,
        }
    }

    /// The story's grid of `cell`-metre cells over these bounds.
    pub fn frame(&self, story: &Story, cell: f64) -> Result<GridFrame, SamplesError> {
        if self.non_finite > 0 {
            return Err(SamplesError::NonFinite(self.non_finite));
        }
        if self.n == 0 {
            return Err(SamplesError::EmptyStory { level: story.level });
        }
        let origin = [self.lo[0] as f64, self.lo[1] as f64];
        let span = [self.hi[0] as f64 - origin[0], self.hi[1] as f64 - origin[1]];
        let nx = (span[0] / cell) as usize + 1;
        let ny = (span[1] / cell) as usize + 1;
        if nx.saturating_mul(ny) > MAX_CELLS {
            return Err(SamplesError::TooLarge(format!(
                "story {} spans {:.0} m × {:.0} m, {nx} × {ny} cells of {cell} m; are there outliers?",
                story.level, span[0], span[1]
            )));
        }
        Ok(GridFrame {
            origin,
            cell,
            nx,
            ny,
        })
    }
}

/// The height range of each block of [`Blocks::SIZE`] consecutive points, so that passes over
/// one story skip the blocks holding none of its points (scans come station by station, and a
/// station sees mostly one story).
#[derive(Debug, Clone, PartialEq)]
pub struct Blocks {
    z: Vec<(f32, f32)>,
}

impl Blocks {
    /// Points per block.
    pub const SIZE: usize = 1 << 16;

    /// The index ranges of the points that may belong to `story`, in order.
    pub fn spans(&self, story: &Story) -> Vec<Range<usize>> {
        self.ranges(|lo, hi| !(hi < story.z_min || lo >= story.z_max))
    }

    /// The index ranges of the points that may have a height in `z` (closed), in order. The
    /// last range may reach past the last point.
    pub fn spans_within(&self, z: RangeInclusive<f64>) -> Vec<Range<usize>> {
        self.ranges(|lo, hi| !(hi < *z.start() || lo > *z.end()))
    }

    /// The blocks whose height range `keep` accepts, consecutive ones joined.
    fn ranges(&self, keep: impl Fn(f64, f64) -> bool) -> Vec<Range<usize>> {
        let mut out: Vec<Range<usize>> = Vec::new();
        for (b, &(lo, hi)) in self.z.iter().enumerate() {
            let (lo, hi) = (lo as f64, hi as f64);
            if lo.is_nan() || !keep(lo, hi) {
                continue;
            }
            let r = b * Self::SIZE..(b + 1) * Self::SIZE;
            match out.last_mut() {
                Some(last) if last.end == r.start => last.end = r.end,
                _ => out.push(r),
            }
        }
        out
    }
}
