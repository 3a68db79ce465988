//! The neighbourhood count a wall cell needs (§3.1: |N_g| >= 50), derived from the density of
//! the walls next to it (beyond the paper).
//!
//! The story-wide value is an eighth of the median count of its wall-like cells, clamped to
//! [`RANGE`]. One value does not fit a scan whose density varies a lot over the floor: a
//! mobile scanner walks the corridors and only steps into the rooms, so the rooms' far walls
//! hold a tenth of the points of the corridor walls, and the median sits between the two.
//!
//! What the count must rule out is a stray cell beside a well-scanned wall: range noise and
//! mixed pixels spread a thin, full-height halo of points off each face, which the height
//! tests alone pass. Such a cell has a far denser wall cell within a few cells of it. So each
//! cell needs an eighth of the densest wall-like cell within [`NEAR`] of it, no less than
//! [`FLOOR`] and never more than the story-wide value: a sparse wall that nothing denser
//! stands next to is judged against itself.

use std::collections::HashMap;

/// A cell of the story's grid, by its column and row.
pub(super) type Cell = (i64, i64);

/// The story-wide value stays within these bounds: 50 is the paper's value for dense scans.
pub(super) const RANGE: (usize, usize) = (10, 50);
/// No cell passes with fewer points. With the density-aware height histogram, five points
/// still have to spread over 2 m of height and most of the interior bins.
pub(super) const FLOOR: usize = 5;
/// A denser wall cell this near makes a cell's threshold, metres: farther than a halo of
/// range noise reaches off a face.
const NEAR: f64 = 0.25;

/// The thresholds of one story.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Thresholds {
    /// The story-wide value.
    pub global: usize,
    /// Per cell, the value where it is below the
    /// story-wide one.
    local: HashMap<Cell, usize>,
}

impl Thresholds {
    /// Derives the thresholds from the wall-like cells, each one's indices and neighbourhood
    /// count, on a grid of `cell` metres.
    pub fn derive(cells: &[(Cell, usize)], cell: f64) -> Thresholds {
        let mut all: Vec<usize> = cells.iter().map(|c| c.1).collect();
        let global = match all.len() {
            0 => RANGE.0,
            n => (*all.select_nth_unstable(n / 2).1 / 8).clamp(RANGE.0, RANGE.1),
        };
        let reach = (NEAR / cell).round().max(1.0) as i64;
        let densest = Densest::new(cells, reach);
        let mut local = HashMap::new();
        for &(c, _) in cells {
            let t = (densest.at(c) / 8).max(FLOOR);
            if t < global {
                local.insert(c, t);
            }
        }
        Thresholds { global, local }
    }

    /// A value given by the user: the same everywhere.
    pub fn fixed(n: usize) -> Thresholds {
        Thresholds {
            global: n,
            local: HashMap::new(),
        }
    }

    /// The count cell `c` needs.
    pub fn at(&self, c: Cell) -> usize {
        self.local.get(&c).copied().unwrap_or(self.global)
    }

    /// The lowest count any cell needs.
    pub fn lowest(&self) -> usize {
        self.local.values().copied().fold(self.global, usize::min)
    }
}

/// The largest count within `reach` cells (a square) of each cell, on a dense grid over the
/// cells' bounds: two passes of a running window maximum, rows then columns, rather than a
/// hash probe per neighbour (121 per cell at 5 cm).
struct Densest {
    /// The lowest column and row.
    lo: Cell,
    width: usize,
    max: Vec<usize>,
    /// Bounds too sparse for a dense grid (not one story's grid): the counts by cell.
    sparse: Option<(HashMap<Cell, usize>, i64)>,
}

/// Dense grids are used up to this many cells: any story grid's (`grid::MAX_CELLS`) and more.
const DENSE_MAX: i64 = 1 << 25;

impl Densest {
    fn new(cells: &[(Cell, usize)], reach: i64) -> Densest {
        let (mut lo, mut hi) = ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN));
        for &((i, j), _) in cells {
            lo = (lo.0.min(i), lo.1.min(j));
            hi = (hi.0.max(i), hi.1.max(j));
        }
        let span = |a: i64, b: i64| b.checked_sub(a).and_then(|d| d.checked_add(1));
        let area = span(lo.0, hi.0)
            .zip(span(lo.1, hi.1))
            .and_then(|(w, h)| w.checked_mul(h));
        let (width, height) = match area {
            Some(a) if a <= DENSE_MAX && !cells.is_empty() => {
                ((hi.0 - lo.0 + 1) as usize, (hi.1 - lo.1 + 1) as usize)
            }
            _ => {
                let mut counts: HashMap<Cell, usize> = HashMap::with_capacity(cells.len());
                for &(c, n) in cells {
                    let c = counts.entry(c).or_default();
                    *c = (*c).max(n);
                }
                return Densest {
                    lo,
                    width: 0,
                    max: Vec::new(),
                    sparse: Some((counts, reach)),
                };
            }
        };
        let mut counts = vec![0usize; width * height];
        for &((i, j), n) in cells {
            let k = (j - lo.1) as usize * width + (i - lo.0) as usize;
            counts[k] = counts[k].max(n);
        }
        let r = reach as usize;
        let mut rows = vec![0usize; counts.len()];
        for (src, out) in counts.chunks(width).zip(rows.chunks_mut(width)) {
            window_max(src, r, out);
        }
        let (mut column, mut out) = (vec![0usize; height], vec![0usize; height]);
        for i in 0..width {
            column
                .iter_mut()
                .enumerate()
                .for_each(|(j, v)| *v = rows[j * width + i]);
            window_max(&column, r, &mut out);
            out.iter()
                .enumerate()
                .for_each(|(j, &v)| counts[j * width + i] = v);
        }
        Densest {
            lo,
            width,
            max: counts,
            sparse: None,
        }
    }

    /// The largest count within reach of cell `c`, one of the cells given.
    fn at(&self, (i, j): Cell) -> usize {
        let Some((counts, reach)) = &self.sparse else {
            return self.max[(j - self.lo.1) as usize * self.width + (i - self.lo.0) as usize];
        };
        let mut densest = 0;
        for dj in -reach..=*reach {
            for di in -reach..=*reach {
                if let Some(&n) = counts.get(&(i + di, j + dj)) {
                    densest = densest.max(n);
                }
            }
        }
        densest
    }
}

/// `out[x]` = the largest of `src[x - r..=x + r]` (clipped to `src`), in linear time: over
/// `src` padded with `r` zeros each side and cut into blocks of the window's width, each
/// window spans the end of one block and the start of the next (van Herk, Gil and Werman).
fn window_max(src: &[usize], r: usize, out: &mut [usize]) {
    let (n, k) = (src.len(), 2 * r + 1);
    let len = n + 2 * r;
    let at = |p: usize| if p < r || p >= n + r { 0 } else { src[p - r] };
    // Running maxima from each block's start forwards, and from its end backwards.
    let mut ahead = vec![0usize; len];
    let mut behind = vec![0usize; len];
    for p in 0..len {
        ahead[p] = if p % k == 0 {
            at(p)
        } else {
            ahead[p - 1].max(at(p))
        };
    }
    for p in (0..len).rev() {
        behind[p] = if p % k == k - 1 || p == len - 1 {
            at(p)
        } else {
            behind[p + 1].max(at(p))
        };
    }
    for (x, o) in out.iter_mut().enumerate().take(n) {
        *o = behind[x].max(ahead[x + 2 * r]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 5 cm cell at `x`, `y`.
    fn at(x: f64, y: f64) -> Cell {
        ((x / 0.05).round() as i64, (y / 0.05).round() as i64)
    }

    /// Cells every 5 cm along x = `x` from y = `y0` for `len` metres, each with `n` points.
    fn wall(x: f64, y0: f64, len: f64, n: usize) -> Vec<(Cell, usize)> {
        (0..(len / 0.05).round() as usize)
            .map(|k| (at(x, y0 + 0.05 * k as f64), n))
            .collect()
    }

    /// The thresholds as first written: a hash probe of every neighbour of every cell.
    fn probed(cells: &[(Cell, usize)], cell: f64) -> Thresholds {
        let global = Thresholds::derive(cells, cell).global;
        let mut counts: HashMap<Cell, usize> = HashMap::new();
        for &(c, n) in cells {
            let e = counts.entry(c).or_default();
            *e = (*e).max(n);
        }
        let reach = (NEAR / cell).round().max(1.0) as i64;
        let mut local = HashMap::new();
        for (&(i, j), _) in counts.iter() {
            let mut densest = 0;
            for dj in -reach..=reach {
                for di in -reach..=reach {
                    if let Some(&n) = counts.get(&(i + di, j + dj)) {
                        densest = densest.max(n);
                    }
                }
            }
            let t = (densest / 8).max(FLOOR);
            if t < global {
                local.insert((i, j), t);
            }
        }
        Thresholds { global, local }
    }

    #[test]
    fn the_dense_windows_match_a_probe_of_every_neighbour() {
        // Scattered cells of varied counts, repeated cells, and cells at the bounds' edges.
        let mut cells = Vec::new();
        let mut x = 12345u64;
        for _ in 0..3000 {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let (i, j) = (((x >> 33) % 90) as i64 - 40, ((x >> 45) % 70) as i64 - 7);
            cells.push(((i, j), ((x >> 20) % 400) as usize));
        }
        cells.extend(wall(0.5, 0.0, 3.0, 240));
        for cell in [0.05, 0.02, 0.1, 0.3] {
            assert_eq!(
                Thresholds::derive(&cells, cell),
                probed(&cells, cell),
                "{cell}"
            );
        }
        // Bounds too wide for a dense grid take the probes.
        let far = vec![((0, 0), 400), ((1 << 40, 3), 30), ((1, 1), 16)];
        assert_eq!(Thresholds::derive(&far, 0.05), probed(&far, 0.05));
        let mut out = vec![0; 5];
        window_max(&[3, 1, 4, 1, 5], 1, &mut out);
        assert_eq!(out, vec![3, 4, 4, 5, 5]);
        window_max(&[3, 1, 4, 1, 5], 3, &mut out);
        assert_eq!(out, vec![4, 5, 5, 5, 5]);
    }

    #[test]
    fn an_even_scan_gets_one_value() {
        // 400 cells of 160 points: an eighth, 20, everywhere.
        let t = Thresholds::derive(&wall(0.5, 0.0, 20.0, 160), 0.05);
        assert_eq!(t.global, 20);
        assert_eq!(t.at(at(0.5, 3.0)), 20);
        assert_eq!(t.lowest(), 20);
        // Very dense and very sparse scans stay within the range.
        assert_eq!(
            Thresholds::derive(&wall(0.5, 0.0, 20.0, 4000), 0.05).global,
            50
        );
        assert_eq!(
            Thresholds::derive(&wall(0.5, 0.0, 20.0, 30), 0.05).global,
            10
        );
        assert_eq!(Thresholds::derive(&[], 0.05).global, 10);
    }

    #[test]
    fn a_sparse_wall_is_judged_by_itself() {
        // A dense corridor wall (30 m, 240 points a cell) and a room's sparse wall (10 m,
        // 24 points a cell) 5 m away.
        let mut cells = wall(0.5, 0.0, 30.0, 240);
        cells.extend(wall(5.5, 0.0, 10.0, 24));
        let t = Thresholds::derive(&cells, 0.05);
        assert_eq!(t.global, 30);
        assert_eq!(t.at(at(0.5, 15.0)), 30);
        // 24 / 8 = 3, raised to the floor.
        assert_eq!(t.at(at(5.5, 5.0)), FLOOR);
        assert_eq!(t.lowest(), FLOOR);
        // Where no wall-like cell is, the story's value holds.
        assert_eq!(t.at(at(3.0, 5.0)), 30);
    }

    #[test]
    fn a_halo_beside_a_dense_wall_is_held_to_the_wall() {
        // 12-point cells 10 cm off a 240-point wall: the wall's eighth, 30, not the floor.
        let mut cells = wall(0.5, 0.0, 30.0, 240);
        cells.extend(wall(0.6, 0.0, 30.0, 12));
        let t = Thresholds::derive(&cells, 0.05);
        assert_eq!(t.at(at(0.6, 10.0)), 30);
        // The same cells 1 m off are a wall of their own.
        let mut cells = wall(0.5, 0.0, 30.0, 240);
        cells.extend(wall(1.5, 0.0, 30.0, 12));
        let t = Thresholds::derive(&cells, 0.05);
        assert_eq!(t.at(at(1.5, 10.0)), FLOOR);
        assert_eq!(Thresholds::fixed(7).at(at(1.5, 10.0)), 7);
    }
}
