//! The story's points bucketed by band of grid rows before the grid counts and sorts them by
//! cell. A band's cell summaries and its share of the sorted points take a few hundred
//! kilobytes, so the per-cell updates stay in the core's cache; over the whole grid, in the
//! cloud's order, nearly every update missed it. The partition is stable: within a band the
//! points keep the cloud's order, so within a cell they do too.

use std::ops::Range;

use rayon::prelude::*;

use super::grid::{Carry, Points, CELL_MASK, NO_KEY};
use crate::cancel::Cancel;

/// Cells in a band, about: 160 KB of summaries and 32 KB of cursors.
pub(super) const BAND_CELLS: usize = 8192;

/// How the held cells (row-major, `width` a row) are cut into bands of whole rows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Bands {
    /// Cells a band holds (a whole number of rows); the last band may hold fewer.
    per_band: u32,
    /// Every held cell.
    cells: usize,
}

impl Bands {
    /// Bands of whole rows of `width` cells, about `goal` cells each (at least one row).
    pub fn new(width: usize, cells: usize, goal: usize) -> Bands {
        let rows = (goal / width.max(1)).max(1);
        Bands {
            per_band: (rows * width.max(1)).min(u32::MAX as usize) as u32,
            cells,
        }
    }

    /// How many bands there are (one for an empty grid).
    pub fn len(&self) -> usize {
        self.cells.div_ceil(self.per_band as usize).max(1)
    }

    /// The band of held cell `cell`.
    #[inline]
    pub fn of(&self, cell: u32) -> usize {
        (cell / self.per_band) as usize
    }

    /// The held cells of band `b`.
    pub fn cells(&self, b: usize) -> Range<usize> {
        let per = self.per_band as usize;
        (b * per).min(self.cells)..((b + 1) * per).min(self.cells)
    }
}

/// A point bucketed into its band, with its key (held cell and height bin code, as the
/// grid's counting pass records it).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Entry {
    pub p: [f32; 3],
    pub key: u32,
}

impl Entry {
    /// The held cell.
    #[inline]
    pub fn cell(&self) -> u32 {
        self.key & CELL_MASK
    }
}

/// The points with a key, band by band: `entries[start[b]..start[b + 1]]` are band `b`'s, in
/// cloud order, and `slots` or `times` beside them when carried.
pub(super) struct Bucketed {
    pub entries: Vec<Entry>,
    pub slots: Vec<u16>,
    pub times: Vec<f64>,
    pub start: Vec<usize>,
}

/// One band's share of the bucketed arrays, in cloud order.
pub(super) struct Band<'a> {
    pub entries: &'a [Entry],
    pub slots: &'a [u16],
    pub times: &'a [f64],
}

impl Bucketed {
    /// The points of band `b`.
    pub fn band(&self, b: usize) -> Band<'_> {
        let r = self.start[b]..self.start[b + 1];
        let carried = |n: usize| if n == 0 { 0..0 } else { r.clone() };
        Band {
            entries: &self.entries[r.clone()],
            slots: &self.slots[carried(self.slots.len())],
            times: &self.times[carried(self.times.len())],
        }
    }
}

/// Each piece's count of keyed points per band. `pieces[k]` are index ranges of the cloud
/// and `keys[k]` their keys, in order.
pub(super) fn count(bands: &Bands, keys: &[&[u32]]) -> Vec<Vec<u32>> {
    keys.par_iter()
        .map(|keys| {
            let mut n = vec![0u32; bands.len()];
            for &key in keys.iter().filter(|&&k| k != NO_KEY) {
                n[bands.of(key & CELL_MASK)] += 1;
            }
            n
        })
        .collect()
}

/// Bucketing the points of `pieces` (index ranges into `points`, in order; `keys[k]` the keys
/// of piece `k`, `counts[k]` its counts from [`count`]) by band, keeping each band's points
/// in cloud order. Points keyed [`NO_KEY`] are left out. A stopped run returns what it has
/// (the caller checks `cancel`).
pub(super) fn bucket(
    points: Points<'_>,
    pieces: &[Vec<Range<usize>>],
    keys: &[&[u32]],
    counts: &[Vec<u32>],
    bands: &Bands,
    carry: Carry,
    cancel: &Cancel,
) -> Bucketed {
    let nb = bands.len();
    let mut start = vec![0usize; nb + 1];
    for b in 0..nb {
        start[b + 1] = start[b] + counts.iter().map(|c| c[b] as usize).sum::<usize>();
    }
    let n = start[nb];
    let mut entries = vec![Entry::default(); n];
    let mut slots = vec![0u16; if carry == Carry::Slots { n } else { 0 }];
    let mut times = vec![0f64; if carry == Carry::Times { n } else { 0 }];
    // Each piece's place in each band: bands in order, and within a band the pieces in order.
    let mut outs: Vec<Vec<(&mut [Entry], &mut [u16], &mut [f64])>> =
        (0..pieces.len()).map(|_| Vec::with_capacity(nb)).collect();
    {
        let (mut e_rest, mut s_rest, mut t_rest) =
            (&mut entries[..], &mut slots[..], &mut times[..]);
        for b in 0..nb {
            for (k, out) in outs.iter_mut().enumerate() {
                let len = counts[k][b] as usize;
                let (e, er) = e_rest.split_at_mut(len);
                let (s, sr) = s_rest.split_at_mut(if s_rest.is_empty() { 0 } else { len });
                let (t, tr) = t_rest.split_at_mut(if t_rest.is_empty() { 0 } else { len });
                (e_rest, s_rest, t_rest) = (er, sr, tr);
                out.push((e, s, t));
            }
        }
    }
    pieces
        .par_iter()
        .zip(keys)
        .zip(outs)
        .for_each(|((piece, keys), mut out)| {
            let mut next = vec![0usize; nb];
            let mut at = 0;
            for r in piece.iter().cloned().flat_map(super::grid::checked_pieces) {
                if cancel.is_stopped() {
                    return;
                }
                for (k, (p, &key)) in points.xyz[r.clone()].iter().zip(&keys[at..]).enumerate() {
                    if key == NO_KEY {
                        continue;
                    }
                    let b = bands.of(key & CELL_MASK);
                    let (e, s, t) = &mut out[b];
                    let dst = next[b];
                    next[b] += 1;
                    e[dst] = Entry { p: *p, key };
                    match carry {
                        Carry::Slots => s[dst] = points.scan[r.start + k],
                        Carry::Times => t[dst] = points.time[r.start + k],
                        Carry::Nothing => {}
                    }
                }
                at += r.len();
            }
        });
    Bucketed {
        entries,
        slots,
        times,
        start,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_hold_whole_rows_and_cover_every_cell() {
        // 7 cells a row, 5 rows: 16 cells a band is 2 rows.
        let b = Bands::new(7, 35, 16);
        assert_eq!(b.len(), 3);
        assert_eq!(
            (0..3).map(|k| b.cells(k)).collect::<Vec<_>>(),
            vec![0..14, 14..28, 28..35]
        );
        for c in 0..35u32 {
            assert!(b.cells(b.of(c)).contains(&(c as usize)), "cell {c}");
        }
        // A row wider than the goal is a band of its own; an empty grid is one empty band.
        assert_eq!(Bands::new(100, 300, 16).len(), 3);
        let empty = Bands::new(0, 0, 16);
        assert_eq!((empty.len(), empty.cells(0)), (1, 0..0));
    }

    #[test]
    fn bucketing_keeps_each_bands_points_in_cloud_order() {
        // Keys over 12 cells in bands of 4; points 2 and 6 have no key.
        let xyz: Vec<[f32; 3]> = (0..10).map(|k| [k as f32, 0.0, 1.0]).collect();
        let scan: Vec<u16> = (100..110).collect();
        let keys = [5, 0, NO_KEY, 11, 4 | 3 << 24, 1, NO_KEY, 9, 3, 7];
        let bands = Bands::new(4, 12, 4);
        // Two pieces, the second over two spans.
        let pieces = vec![vec![0..4], vec![4..6, 6..10]];
        let key_parts: Vec<&[u32]> = vec![&keys[..4], &keys[4..]];
        let counts = count(&bands, &key_parts);
        assert_eq!(counts, vec![vec![1, 1, 1], vec![2, 2, 1]]);
        let points = Points {
            xyz: &xyz,
            scan: &scan,
            time: &[],
        };
        let out = bucket(
            points,
            &pieces,
            &key_parts,
            &counts,
            &bands,
            Carry::Slots,
            &Cancel::never(),
        );
        assert_eq!(out.start, vec![0, 3, 6, 8]);
        let order: Vec<u16> = out.slots.clone();
        assert_eq!(order, vec![101, 105, 108, 100, 104, 109, 103, 107]);
        for (e, &s) in out.entries.iter().zip(&out.slots) {
            let k = (s - 100) as usize;
            assert_eq!((e.p, e.key), (xyz[k], keys[k]));
        }
        assert_eq!(out.band(1).slots, &[100, 104, 109]);
        assert!(out.band(1).times.is_empty());
        // Nothing to bucket.
        let none = bucket(
            points,
            &[vec![]],
            &[&[]],
            &[vec![0, 0, 0]],
            &bands,
            Carry::Nothing,
            &Cancel::never(),
        );
        assert_eq!((none.entries.len(), none.start), (0, vec![0, 0, 0, 0]));
    }
}
