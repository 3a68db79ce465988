//! The d_s grid over one story. The story's points are counting-sorted by cell into a copy of
//! their own, so that a cell's points are a few contiguous runs and a neighbourhood is read
//! sequentially, not gathered from all over the cloud. The points are cut into consecutive
//! pieces, one a thread; each piece sorts its own points into its own part of the copy, so a
//! cell's points are one run per piece, and read piece after piece they are in the cloud's
//! order. That makes every sum over a neighbourhood the same however many threads built the
//! grid, and whether it was built whole or tile by tile (the streaming mode).
//!
//! Where the grid lies ([`GridFrame`], in `bounds.rs`) is fixed by the horizontal bounds of all
//! the story's points ([`StoryBounds`]); a [`Grid`] may hold only a range of its cells.

use std::ops::Range;

use rayon::prelude::*;

use super::bound32::least_at_or_above;
use super::bounds::{CellRange, GridFrame};
use super::cell::Reject;
use super::SamplesError;
use crate::cancel::Cancel;
use crate::stories::Story;

/// Points passed over between cancellation checks in the grid's passes (a fraction of a
/// millisecond).
const POINTS_PER_CHECK: usize = 1 << 16;

/// `r` cut into consecutive pieces of at most [`POINTS_PER_CHECK`].
fn checked_pieces(r: Range<usize>) -> impl Iterator<Item = Range<usize>> {
    r.clone()
        .step_by(POINTS_PER_CHECK)
        .map(move |s| s..(s + POINTS_PER_CHECK).min(r.end))
}

/// The most cells a story's grid may have (about 200 m × 200 m at 5 cm). Beyond it the cloud
/// holds far outliers, and the per-cell arrays would waste memory.
pub(crate) const MAX_CELLS: usize = (1 << 24) - 1;

/// What a core cell's block summary says before any neighbourhood is gathered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Screen {
    /// No points in the block.
    Empty,
    /// Even the whole block fails a test, so the neighbourhood within it does.
    Rejected(Reject),
    /// The neighbourhood is gathered and tested.
    Candidate,
}

/// What each point brings along into the grid besides its coordinates: whatever tells which
/// scanner saw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Carry {
    Nothing,
    Slots,
    Times,
}

/// The points a grid is built from: coordinates, and the per-point arrays [`Carry`] may name.
#[derive(Clone, Copy)]
pub(super) struct Points<'a> {
    pub xyz: &'a [[f32; 3]],
    pub scan: &'a [u16],
    pub time: &'a [f64],
}

/// A story's points in a range of its grid's cells, sorted by cell. Every held cell has its
/// height summary; only the cells some neighbourhood will be gathered from keep their points.
pub(super) struct Grid {
    pub frame: GridFrame,
    /// The cells held.
    pub range: CellRange,
    /// `pts[start[p * cells + c]..start[p * cells + c + 1]]` are the kept points of held cell
    /// `c` (row-major in `range`, `cells` of them) from piece `p`; empty for cells whose
    /// points no neighbourhood needs. Piece after piece, a cell's points are in cloud order.
    pub start: Vec<u32>,
    /// The pieces the points were sorted in (at least one).
    pub pieces: usize,
    pub pts: Vec<[f32; 3]>,
    /// Alongside `pts`: each point's height bin code, and when carried its scan slot or time.
    pub bins: Vec<u8>,
    pub slots: Vec<u16>,
    pub times: Vec<f64>,
    /// Per held cell: the count and heights of all its points.
    #[cfg(test)]
    pub summaries: Vec<Summary>,
    /// Per held cell: what the summary of its 3 × 3 block says (`Empty` outside the core).
    pub screens: Vec<Screen>,
    /// Per core cell (row-major in the core): 0 without points, else one more than its points
    /// in the underlay's slice (see [`crate::underlay`]).
    pub density: Vec<u32>,
}

/// The heights of one cell's own points: their number and range, and which height bins they
/// fill. Summaries of cells merge into the summary of their union.
#[derive(Debug, Clone, Copy)]
pub(super) struct Summary {
    pub n: u32,
    pub zmin: f32,
    pub zmax: f32,
    pub mask: u32,
    /// Points in the underlay's slice.
    pub slice: u32,
}

impl Default for Summary {
    fn default() -> Self {
        Summary {
            n: 0,
            zmin: f32::INFINITY,
            zmax: f32::NEG_INFINITY,
            mask: 0,
            slice: 0,
        }
    }
}

impl Summary {
    /// Heights are numbers or the empty summary's infinities, never NaN: one comparison each,
    /// not `min`'s care for NaN.
    #[inline]
    pub fn merge(&mut self, o: &Summary) {
        self.n += o.n;
        self.zmin = if o.zmin < self.zmin {
            o.zmin
        } else {
            self.zmin
        };
        self.zmax = if o.zmax > self.zmax {
            o.zmax
        } else {
            self.zmax
        };
        self.mask |= o.mask;
        self.slice += o.slice;
    }
}

/// A cell left out of the scatter: no output position is this large (a story indexes fewer
/// than 2^32 - 1 points). Also a point in no held cell: no cell index is this large
/// ([`MAX_CELLS`]).
const SKIP: u32 = u32::MAX;

/// Points whose cells are found before any of them is counted or placed. The per-cell arrays
/// are far larger than the caches, so nearly every update waits on memory; with the cells
/// known first, the processor has a batch of independent updates in flight at once.
const BATCH: usize = 32;

/// The held cell of each point of `batch` (at most [`BATCH`] points), [`SKIP`] for points in
/// none.
#[inline]
fn batch_keys(batch: &[[f32; 3]], key: impl Fn(&[f32; 3]) -> Option<usize>) -> [u32; BATCH] {
    let mut cells = [SKIP; BATCH];
    for (c, p) in cells.iter_mut().zip(batch) {
        *c = key(p).map_or(SKIP, |c| c as u32);
    }
    cells
}

impl Grid {
    /// Sorts the points of `story` (those with `z_min <= z < z_max`) that fall in `range` of
    /// `frame` by cell, and summarizes each cell's heights with `bin_code`, a height's bin
    /// (see [`super::cell::BinCoder::code`]). Only the points in `spans` (index ranges, in
    /// order) are looked at; `None` is all. Each cell of `core` is screened by `screen` on its
    /// block's summary, and the points of a cell are kept only when it lies in the 3 × 3 block
    /// of a candidate. Points with `slice[0] <= z < slice[1]` are counted for the underlay.
    /// Stops with `Cancelled` once `cancel` says so.
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        points: Points<'_>,
        spans: Option<&[Range<usize>]>,
        story: &Story,
        frame: GridFrame,
        core: &CellRange,
        carry: Carry,
        bin_code: impl Fn(f32) -> u8 + Sync + Copy,
        screen: impl Fn(&Summary) -> Result<(), Reject> + Sync,
        slice: [f32; 2],
        cancel: &Cancel,
    ) -> Result<Grid, SamplesError> {
        let xyz = points.xyz;
        let range = core.grown(&frame);
        let whole = std::slice::from_ref(&(0..xyz.len())).to_vec();
        let spans: Vec<Range<usize>> = spans
            .unwrap_or(&whole)
            .iter()
            .map(|r| r.start.min(xyz.len())..r.end.min(xyz.len()))
            .filter(|r| !r.is_empty())
            .collect();
        if xyz.len() >= u32::MAX as usize {
            return Err(SamplesError::TooLarge(format!(
                "{} points exceed the 2^32 a story can index",
                xyz.len()
            )));
        }
        let width = range.width();
        // `cell_of` and `in_story`, on copies of the frame's and the story's numbers: each
        // thread holds its own copy of this closure, so they stay in registers.
        let (ox, oy, inv) = (frame.origin[0], frame.origin[1], 1.0 / frame.cell);
        let (last_i, last_j) = (frame.nx - 1, frame.ny - 1);
        let (z_min, z_max) = (
            least_at_or_above(story.z_min),
            least_at_or_above(story.z_max),
        );
        let (is, js) = ((range.i.start, range.i.end), (range.j.start, range.j.end));
        let key = move |p: &[f32; 3]| -> Option<usize> {
            // As `in_story`, on bounds that need no widening of z.
            if !(p[2] >= z_min && p[2] < z_max) {
                return None;
            }
            // Through i64: the same values for these non-negative numbers, and a cheaper cast.
            let i = ((((p[0] as f64 - ox) * inv) as i64) as usize).min(last_i);
            let j = ((((p[1] as f64 - oy) * inv) as i64) as usize).min(last_j);
            (i >= is.0 && i < is.1 && j >= js.0 && j < js.1)
                .then(|| (j - js.0) * width + (i - is.0))
        };
        let cells = range.cells();

        // The counting pass, one part of the spans per thread: every cell's summary.
        let parts = rayon::current_num_threads().max(1);
        let total: usize = spans.iter().map(|r| r.len()).sum();
        let pieces = split_spans(&spans, total.div_ceil(parts).max(1));
        let piece_sums = pieces
            .par_iter()
            .map(|piece| {
                let (key, bin_code) = (key, bin_code);
                let mut sums = vec![Summary::default(); cells];
                for r in piece.iter().cloned().flat_map(checked_pieces) {
                    if cancel.is_stopped() {
                        break;
                    }
                    for batch in xyz[r].chunks(BATCH) {
                        let cells = batch_keys(batch, key);
                        for (p, &c) in batch.iter().zip(&cells) {
                            if c == SKIP {
                                continue;
                            }
                            let s = &mut sums[c as usize];
                            s.n += 1;
                            // z is a number (it is in the story): one comparison each, not
                            // `min`'s care for NaN.
                            let z = p[2];
                            s.zmin = if z < s.zmin { z } else { s.zmin };
                            s.zmax = if z > s.zmax { z } else { s.zmax };
                            s.slice += u32::from(p[2] >= slice[0] && p[2] < slice[1]);
                            let b = bin_code(p[2]);
                            if b != super::cell::NO_BIN {
                                s.mask |= 1 << b;
                            }
                        }
                    }
                }
                sums
            })
            .collect::<Vec<_>>();
        cancel.check()?;
        // Each piece's counts place its points; the merged summaries screen the cells.
        let counts: Vec<Vec<u32>> = piece_sums
            .iter()
            .map(|sums| sums.iter().map(|s| s.n).collect())
            .collect();
        let summaries = piece_sums
            .into_iter()
            .reduce(|mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| x.merge(y));
                a
            })
            .unwrap_or_else(|| vec![Summary::default(); cells]);

        // What each core cell's block summary says, a row per task, then which cells' points
        // a candidate's neighbourhood will read.
        let id = |i: usize, j: usize| (j - range.j.start) * width + (i - range.i.start);
        let density = core
            .j
            .clone()
            .flat_map(|j| core.i.clone().map(move |i| (i, j)))
            .map(|(i, j)| {
                let s = &summaries[id(i, j)];
                if s.n == 0 {
                    0
                } else {
                    s.slice.saturating_add(1)
                }
            })
            .collect();
        let mut screens = vec![Screen::Empty; cells];
        screens
            .par_chunks_mut(width)
            .enumerate()
            .filter(|(row, _)| core.j.contains(&(range.j.start + row)))
            .for_each(|(row, out)| {
                let j = range.j.start + row;
                for i in core.i.clone() {
                    let (xs, ys) = range.block_around(i, j);
                    let mut block = Summary::default();
                    for b in ys {
                        for a in xs.clone() {
                            block.merge(&summaries[id(a, b)]);
                        }
                    }
                    if block.n > 0 {
                        out[i - range.i.start] = match screen(&block) {
                            Ok(()) => Screen::Candidate,
                            Err(r) => Screen::Rejected(r),
                        };
                    }
                }
            });
        // Outside tests the per-cell summaries are done with: the scatter's arrays take their
        // place, so the grid's peak holds one of the two.
        #[cfg(not(test))]
        drop(summaries);
        let mut needed = vec![false; cells];
        needed
            .par_chunks_mut(width)
            .enumerate()
            .for_each(|(row, out)| {
                let j = range.j.start + row;
                for (k, slot) in out.iter_mut().enumerate() {
                    let (xs, ys) = range.block_around(range.i.start + k, j);
                    *slot = ys
                        .into_iter()
                        .any(|b| xs.clone().any(|a| screens[id(a, b)] == Screen::Candidate));
                }
            });
        // Piece by piece, the needed cells' points in row-major order of their cells.
        let np = pieces.len();
        let mut start = vec![0u32; np * cells + 1];
        for (p, counts) in counts.iter().enumerate() {
            for c in 0..cells {
                let k = p * cells + c;
                start[k + 1] = start[k] + if needed[c] { counts[c] } else { 0 };
            }
        }
        drop(counts);
        let n = start[np * cells] as usize;
        let mut pts = vec![[0f32; 3]; n];
        let mut bins = vec![0u8; n];
        let mut slots = vec![0u16; if carry == Carry::Slots { n } else { 0 }];
        let mut times = vec![0f64; if carry == Carry::Times { n } else { 0 }];

        // The scatter, a piece per thread: each piece passes over its own points again, finds
        // their cells again (cheaper than holding a key a point, which at the grid's peak
        // would be most of its memory), and writes them, in cloud order, to its own contiguous
        // part of the output.
        let mut outs = Vec::with_capacity(np);
        {
            let (mut p_rest, mut b_rest, mut s_rest, mut t_rest) =
                (&mut pts[..], &mut bins[..], &mut slots[..], &mut times[..]);
            for (p, piece) in pieces.iter().enumerate() {
                let len = (start[(p + 1) * cells] - start[p * cells]) as usize;
                let (pp, pr) = p_rest.split_at_mut(len);
                let (b, br) = b_rest.split_at_mut(len);
                let (s, sr) = s_rest.split_at_mut(if s_rest.is_empty() { 0 } else { len });
                let (t, tr) = t_rest.split_at_mut(if t_rest.is_empty() { 0 } else { len });
                (p_rest, b_rest, s_rest, t_rest) = (pr, br, sr, tr);
                outs.push((p, piece, pp, b, s, t));
            }
        }
        let needed = &needed;
        outs.into_par_iter().for_each(|(piece, spans, p, b, s, t)| {
            let (key, bin_code) = (key, bin_code);
            let base = start[piece * cells];
            // Where each cell's next point goes in the piece's output, or `SKIP` for a cell
            // whose points no neighbourhood reads: one lookup a point says both.
            let mut next: Vec<u32> = (0..cells)
                .map(|c| {
                    if needed[c] {
                        start[piece * cells + c] - base
                    } else {
                        SKIP
                    }
                })
                .collect();
            for r in spans.iter().cloned().flat_map(checked_pieces) {
                if cancel.is_stopped() {
                    return;
                }
                for (n, batch) in xyz[r.clone()].chunks(BATCH).enumerate() {
                    let cells = batch_keys(batch, key);
                    let at = r.start + n * BATCH;
                    for (k, (q, &c)) in batch.iter().zip(&cells).enumerate() {
                        if c == SKIP {
                            continue;
                        }
                        let slot = &mut next[c as usize];
                        if *slot == SKIP {
                            continue;
                        }
                        let dst = *slot as usize;
                        *slot += 1;
                        p[dst] = *q;
                        b[dst] = bin_code(q[2]);
                        match carry {
                            Carry::Slots => s[dst] = points.scan[at + k],
                            Carry::Times => t[dst] = points.time[at + k],
                            Carry::Nothing => {}
                        }
                    }
                }
            }
        });
        cancel.check()?;
        Ok(Grid {
            frame,
            range,
            start,
            pieces: np,
            pts,
            bins,
            slots,
            times,
            #[cfg(test)]
            summaries,
            screens,
            density,
        })
    }

    /// The index of held cell `(i, j)` (global indices).
    #[inline]
    pub fn id(&self, i: usize, j: usize) -> usize {
        (j - self.range.j.start) * self.range.width() + (i - self.range.i.start)
    }

    /// Where the points of held cell `(i, j)` lie in `pts`, in cloud order.
    #[cfg(test)]
    pub fn points(&self, i: usize, j: usize) -> Vec<usize> {
        let (c, cells) = (self.id(i, j), self.range.cells());
        (0..self.pieces)
            .flat_map(|p| {
                self.start[p * cells + c] as usize..self.start[p * cells + c + 1] as usize
            })
            .collect()
    }

    /// Where the points of the 3 × 3 block around `(i, j)` lie in `pts`, into `runs`: the
    /// rows in order, in each its cells in order, and each cell's points in cloud order (its
    /// pieces in order). With one piece a row's cells are one run.
    pub fn block_runs(&self, i: usize, j: usize, runs: &mut Vec<Range<usize>>) {
        let (xs, ys) = self.range.block_around(i, j);
        let cells = self.range.cells();
        let run = |from: usize, to: usize| self.start[from] as usize..self.start[to] as usize;
        runs.clear();
        for b in ys {
            let (first, last) = (self.id(xs.start, b), self.id(xs.end - 1, b));
            if self.pieces == 1 {
                runs.push(run(first, last + 1));
                continue;
            }
            for c in first..=last {
                runs.extend((0..self.pieces).map(|p| run(p * cells + c, p * cells + c + 1)));
            }
        }
    }

    /// The points of the 3 × 3 block around `(i, j)`, in the order of [`Self::block_runs`].
    pub fn block_points(&self, i: usize, j: usize) -> impl Iterator<Item = usize> {
        let mut runs = Vec::new();
        self.block_runs(i, j, &mut runs);
        runs.into_iter().flatten()
    }

    /// The held cells of the 3 × 3 block around `(i, j)`.
    #[cfg(test)]
    pub fn block(&self, i: usize, j: usize) -> impl Iterator<Item = (usize, usize)> {
        let (xs, ys) = self.range.block_around(i, j);
        ys.flat_map(move |b| xs.clone().map(move |a| (a, b)))
    }
}

/// Cuts `spans` into consecutive pieces of about `len` points each.
fn split_spans(spans: &[Range<usize>], len: usize) -> Vec<Vec<Range<usize>>> {
    let mut pieces = vec![Vec::new()];
    let mut filled = 0;
    for r in spans {
        let mut r = r.clone();
        while !r.is_empty() {
            let take = (len - filled).min(r.len());
            pieces
                .last_mut()
                .expect("a piece")
                .push(r.start..r.start + take);
            r.start += take;
            filled += take;
            if filled == len {
                pieces.push(Vec::new());
                filled = 0;
            }
        }
    }
    // No empty piece after the last point (each piece has runs in every cell's list).
    if pieces.len() > 1 && pieces.last().is_some_and(|p| p.is_empty()) {
        pieces.pop();
    }
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::samples::bounds::in_story;
    use crate::samples::{Blocks, StoryBounds};

    fn story() -> Story {
        Story::flat(0, 0.0, 2.0, 0.0, 2.0)
    }

    fn grid(xyz: &[[f32; 3]], range: Option<CellRange>) -> Grid {
        let s = story();
        let frame = StoryBounds::measure(xyz, &s).frame(&s, 0.05).unwrap();
        let range = range.unwrap_or_else(|| frame.all());
        let scan: Vec<u16> = (0..xyz.len() as u16).collect();
        let points = Points {
            xyz,
            scan: &scan,
            time: &[],
        };
        Grid::build(
            points,
            None,
            &s,
            frame,
            &range,
            Carry::Slots,
            |z| (z > 0.75) as u8,
            |_| Ok(()),
            [0.5, 1.0],
            &Cancel::never(),
        )
        .unwrap()
    }

    #[test]
    fn points_land_in_their_cells_and_out_of_story_points_are_left_out() {
        let xyz = [
            [0.0, 0.0, 1.0],
            [0.12, 0.01, 1.0],
            [0.02, 0.07, 1.0],
            [0.11, 0.02, 5.0], // above the story
            [0.04, 0.04, 0.5],
        ];
        let g = grid(&xyz, None);
        assert_eq!((g.frame.nx, g.frame.ny), (3, 2));
        let at = |i, j| {
            g.points(i, j)
                .iter()
                .map(|&k| g.slots[k])
                .collect::<Vec<_>>()
        };
        assert_eq!(at(0, 0), vec![0, 4]);
        assert_eq!(at(2, 0), vec![1]);
        assert_eq!(at(0, 1), vec![2]);
        assert_eq!(g.pts.len(), 4);
        assert_eq!(g.pts[g.points(2, 0)[0]], [0.12, 0.01, 1.0]);
        assert_eq!(g.block(0, 0).count(), 4);
        assert_eq!(g.block(1, 0).count(), 6);
        // The block's runs hold its cells' points, row by row.
        for (i, j) in [(0, 0), (1, 0), (2, 1)] {
            let runs: Vec<usize> = g.block_points(i, j).collect();
            let cells: Vec<usize> = g.block(i, j).flat_map(|(a, b)| g.points(a, b)).collect();
            assert_eq!(runs, cells);
        }
        let s = g.summaries[0];
        assert_eq!((s.zmin, s.zmax, s.mask, s.slice), (0.5, 1.0, 0b11, 1));
        // The underlay's counts: one more than the slice points ([0.5, 1.0): the point at 0.5).
        assert_eq!(g.density, vec![2, 0, 1, 1, 0, 0]);
        // A range holds only its cells, with the same contents.
        let part = grid(&xyz, Some(CellRange { i: 2..3, j: 0..2 }));
        assert_eq!(part.pts, vec![[0.12, 0.01, 1.0]]);
        assert_eq!(part.points(2, 0), vec![0]);
        // The range holds its cells and a ring of neighbours around them.
        assert_eq!(part.range, CellRange { i: 1..3, j: 0..2 });
        assert_eq!(part.block(2, 0).count(), 4);
    }

    #[test]
    fn the_scatter_keeps_exactly_the_needed_cells_points_in_cloud_order() {
        // Scattered points, some above the story; blocks of fewer than 12 points are rejected,
        // so only cells near denser ones keep their points.
        let xyz: Vec<[f32; 3]> = (0..20_000u32)
            .map(|k| {
                let h = k.wrapping_mul(2_654_435_761);
                let x = (h % 1000) as f32 * 0.002 * (1.0 + (k % 7) as f32 / 7.0);
                let y = ((h >> 10) % 1000) as f32 * 0.001;
                let z = if k % 13 == 0 {
                    3.0
                } else {
                    (k % 19) as f32 * 0.1
                };
                [x, y, z]
            })
            .collect();
        let s = story();
        let frame = StoryBounds::measure(&xyz, &s).frame(&s, 0.05).unwrap();
        let range = frame.all();
        let scan: Vec<u16> = (0..xyz.len()).map(|k| k as u16).collect();
        let points = Points {
            xyz: &xyz,
            scan: &scan,
            time: &[],
        };
        let g = Grid::build(
            points,
            Some(&[0..7_000, 9_000..20_000]),
            &s,
            frame,
            &range,
            Carry::Slots,
            |z| (z > 0.75) as u8,
            |b| {
                if b.n >= 12 {
                    Ok(())
                } else {
                    Err(Reject::TooFew)
                }
            },
            [0.5, 1.0],
            &Cancel::never(),
        )
        .unwrap();
        let candidate = |i: usize, j: usize| g.screens[g.id(i, j)] == Screen::Candidate;
        let (mut kept, mut skipped) = (0, 0);
        for j in 0..frame.ny {
            for i in 0..frame.nx {
                let needed = g.block(i, j).any(|(a, b)| candidate(a, b));
                let want: Vec<u16> = (0..7_000)
                    .chain(9_000..20_000)
                    .filter(|&k| {
                        needed && in_story(&s, xyz[k][2]) && frame.cell_of(&xyz[k]) == (i, j)
                    })
                    .map(|k| k as u16)
                    .collect();
                let got: Vec<u16> = g.points(i, j).iter().map(|&k| g.slots[k]).collect();
                assert_eq!(got, want, "cell ({i}, {j})");
                for k in g.points(i, j) {
                    assert_eq!(g.pts[k], xyz[g.slots[k] as usize]);
                    assert_eq!(g.bins[k], (g.pts[k][2] > 0.75) as u8);
                }
                if needed {
                    kept += 1
                } else {
                    skipped += 1
                }
            }
        }
        assert!(kept > 0 && skipped > 0, "{kept} {skipped}");
    }

    /// What each core cell's neighbourhood reads from `g`, in order: point, bin and slot.
    fn reads(g: &Grid, frame: &GridFrame) -> Vec<Vec<([f32; 3], u8, u16)>> {
        (0..frame.ny)
            .flat_map(|j| (0..frame.nx).map(move |i| (i, j)))
            .map(|(i, j)| {
                g.block_points(i, j)
                    .map(|k| (g.pts[k], g.bins[k], g.slots[k]))
                    .collect()
            })
            .collect()
    }

    #[test]
    fn any_number_of_pieces_reads_the_same_points_in_the_same_order() {
        // Points on cell borders (multiples of 5 cm), on the far edges, at the story's bottom
        // and top (the top is outside it), and scattered over every row.
        let mut xyz: Vec<[f32; 3]> = Vec::new();
        for k in 0..=12u16 {
            let v = f32::from(k) * 0.05;
            xyz.push([v, 0.0, 0.0]);
            xyz.push([0.0, v, 2.0]);
            xyz.push([v, v, 0.8]);
            xyz.push([0.6 - v, v, 0.5]);
        }
        xyz.extend((0..3000u32).map(|k| {
            let h = k.wrapping_mul(2_654_435_761);
            let (x, y) = ((h % 601) as f32 * 0.001, ((h >> 12) % 601) as f32 * 0.001);
            [x, y, (k % 23) as f32 * 0.1]
        }));
        let s = story();
        let frame = StoryBounds::measure(&xyz, &s).frame(&s, 0.05).unwrap();
        assert_eq!((frame.nx, frame.ny), (13, 13));
        let scan: Vec<u16> = (0..xyz.len() as u16).collect();
        let n = xyz.len();
        let build = |threads: usize, spans: &[Range<usize>]| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let points = Points {
                    xyz: &xyz,
                    scan: &scan,
                    time: &[],
                };
                Grid::build(
                    points,
                    Some(spans),
                    &s,
                    frame,
                    &frame.all(),
                    Carry::Slots,
                    |z| (z > 0.75) as u8,
                    |b| {
                        if b.n >= 30 {
                            Ok(())
                        } else {
                            Err(Reject::TooFew)
                        }
                    },
                    [0.5, 1.0],
                    &Cancel::never(),
                )
                .unwrap()
            })
        };
        let spans = [0..n / 3, n / 2..n];
        let one = build(1, &spans);
        assert_eq!(one.pieces, 1);
        // The counts are a plain pass's: every point of the spans in the story, once.
        let counted: u32 = one.summaries.iter().map(|s| s.n).sum();
        let in_spans = spans.iter().cloned().flatten();
        assert_eq!(
            counted as usize,
            in_spans.filter(|&k| in_story(&s, xyz[k][2])).count()
        );
        for cell in 0..frame.nx * frame.ny {
            let (i, j) = (cell % frame.nx, cell / frame.nx);
            let want: Vec<u16> = spans
                .iter()
                .cloned()
                .flatten()
                .filter(|&k| in_story(&s, xyz[k][2]) && frame.cell_of(&xyz[k]) == (i, j))
                .map(|k| k as u16)
                .collect();
            assert_eq!(
                one.summaries[cell].n as usize,
                want.len(),
                "cell ({i}, {j})"
            );
        }
        let want = reads(&one, &frame);
        assert!(want.iter().any(|r| !r.is_empty()) && one.pts.len() < in_spans_len(&spans));
        for threads in [2, 3, 5] {
            let g = build(threads, &spans);
            assert_eq!(g.pieces, threads);
            assert_eq!(reads(&g, &frame), want, "{threads} threads");
            assert_eq!((&g.screens, &g.density), (&one.screens, &one.density));
            for (a, b) in g.summaries.iter().zip(&one.summaries) {
                assert_eq!(
                    (a.n, a.zmin, a.zmax, a.mask, a.slice),
                    (b.n, b.zmin, b.zmax, b.mask, b.slice)
                );
            }
        }
        // No points at all, at any thread count: empty cells, nothing kept.
        for threads in [1, 2] {
            let g = build(threads, &[]);
            assert!(g.summaries.iter().all(|s| s.n == 0 && s.mask == 0));
            assert!(g.pts.is_empty() && g.screens.iter().all(|s| *s == Screen::Empty));
            assert!(reads(&g, &frame).iter().all(|r| r.is_empty()));
        }
    }

    fn in_spans_len(spans: &[Range<usize>]) -> usize {
        spans.iter().map(|r| r.len()).sum()
    }

    #[test]
    fn blocks_skip_what_a_story_cannot_hold() {
        let mut xyz = vec![[0.0f32, 0.0, 1.0]; Blocks::SIZE * 3];
        for p in &mut xyz[Blocks::SIZE..2 * Blocks::SIZE] {
            p[2] = 5.0;
        }
        let upper = Story::flat(1, 4.0, 6.0, 3.0, 7.0);
        let (bounds, blocks) = StoryBounds::measure_all(&xyz, &[story(), upper]);
        assert_eq!(bounds[0].n, 2 * Blocks::SIZE);
        assert_eq!(bounds[1].n, Blocks::SIZE);
        assert_eq!(
            blocks.spans(&story()),
            vec![0..Blocks::SIZE, 2 * Blocks::SIZE..3 * Blocks::SIZE]
        );
        assert_eq!(blocks.spans(&upper), vec![Blocks::SIZE..2 * Blocks::SIZE]);
        let pieces = split_spans(&[0..5, 10..12], 3);
        assert_eq!(pieces, vec![vec![0..3], vec![3..5, 10..11], vec![11..12]]);
        let pieces = split_spans(&[0..5, 10..11], 3);
        assert_eq!(pieces, vec![vec![0..3], vec![3..5, 10..11]]);
        assert_eq!(split_spans(&[], 3), vec![Vec::<Range<usize>>::new()]);
    }

    #[test]
    fn bounds_of_all_stories_at_once_match_each_story_measured_alone() {
        let lower = story();
        let upper = Story::flat(1, 4.0, 6.0, 2.0, 7.0);
        // Block 0 lies in the lower story, block 1 straddles both, block 2 holds a NaN.
        let n = Blocks::SIZE;
        let xyz: Vec<[f32; 3]> = (0..3 * n)
            .map(|k| {
                let (x, y) = ((k % 997) as f32 * 0.01, (k % 389) as f32 * -0.02);
                let z = match k / n {
                    0 => 0.5 + (k % 7) as f32 * 0.1,
                    1 => (k % 13) as f32 * 0.5,
                    _ if k == 2 * n + 5 => f32::NAN,
                    _ => 5.0,
                };
                [x + (k / n) as f32, y, z]
            })
            .collect();
        let stories = [lower, upper];
        let (bounds, _) = StoryBounds::measure_all(&xyz, &stories);
        for (b, s) in bounds.iter().zip(&stories) {
            assert_eq!(*b, StoryBounds::measure(&xyz, s), "story {}", s.level);
            assert!(b.n > 0);
        }
        assert_eq!(bounds[0].non_finite, 1);
        // Without the NaN block, every point is counted in one story or the other.
        let (bounds, _) = StoryBounds::measure_all(&xyz[..2 * n], &stories);
        assert_eq!((bounds[0].non_finite, bounds[1].non_finite), (0, 0));
        assert_eq!(bounds[0].n + bounds[1].n, 2 * n);
    }
}
