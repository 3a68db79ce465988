//! Pass 1's findings: the count, bounds and times of the points, and a coarse count of points
//! per area from which the tiling is planned.

use crate::io::chunks::PointChunk;

/// The coarse count grid never has more cells than this (8 MiB of counts).
const MAX_COARSE: usize = 1 << 20;

/// What pass 1 learns: count, bounds, times, and points per coarse cell.
pub(super) struct Survey {
    pub(super) n: u64,
    pub(super) lo: [f32; 3],
    pub(super) hi: [f32; 3],
    pub(super) has_time: bool,
    /// True when no point carried a scan slot.
    pub(super) no_scan: bool,
    pub(super) time: (f64, f64),
    pub(super) coarse: CoarseGrid,
}

impl Default for Survey {
    fn default() -> Self {
        Survey {
            n: 0,
            lo: [f32::INFINITY; 3],
            hi: [f32::NEG_INFINITY; 3],
            has_time: false,
            no_scan: true,
            time: (f64::INFINITY, f64::NEG_INFINITY),
            coarse: CoarseGrid::new(0.25),
        }
    }
}

impl Survey {
    pub(super) fn add(&mut self, chunk: &PointChunk) {
        self.n += chunk.len() as u64;
        for p in &chunk.xyz {
            for ((lo, hi), &v) in self.lo.iter_mut().zip(&mut self.hi).zip(p) {
                *lo = lo.min(v);
                *hi = hi.max(v);
            }
            self.coarse.add(p[0], p[1]);
        }
        if !chunk.scan.is_empty() {
            self.no_scan = false;
        }
        for &t in &chunk.time {
            self.has_time = true;
            self.time = (self.time.0.min(t), self.time.1.max(t));
        }
    }
}

/// Points per square of a coarse grid anchored at the local origin. It grows to cover every
/// point and doubles its squares when it would exceed [`MAX_COARSE`] of them.
pub(super) struct CoarseGrid {
    pub(super) side: f64,
    /// Index of the first column and row.
    pub(super) x0: i64,
    pub(super) y0: i64,
    pub(super) nx: usize,
    pub(super) ny: usize,
    pub(super) counts: Vec<u64>,
}

impl CoarseGrid {
    pub(super) fn new(side: f64) -> CoarseGrid {
        CoarseGrid {
            side,
            x0: 0,
            y0: 0,
            nx: 0,
            ny: 0,
            counts: Vec::new(),
        }
    }

    #[inline]
    pub(super) fn index(v: f64, side: f64) -> i64 {
        let t = v / side;
        let i = t as i64;
        if (i as f64) > t {
            i - 1
        } else {
            i
        }
    }

    #[inline]
    pub(super) fn add(&mut self, x: f32, y: f32) {
        let (ix, iy) = (
            Self::index(x as f64, self.side),
            Self::index(y as f64, self.side),
        );
        let inside = |i: i64, i0: i64, n: usize| i >= i0 && i < i0 + n as i64;
        if !(inside(ix, self.x0, self.nx) && inside(iy, self.y0, self.ny)) {
            self.grow(ix, iy);
            return self.add(x, y);
        }
        let c = (iy - self.y0) as usize * self.nx + (ix - self.x0) as usize;
        self.counts[c] += 1;
    }

    /// Covers square `(ix, iy)`, with room to spare, coarsening as needed.
    pub(super) fn grow(&mut self, ix: i64, iy: i64) {
        let (mut x0, mut y0, mut x1, mut y1) = if self.counts.is_empty() {
            (ix - 8, iy - 8, ix + 8, iy + 8)
        } else {
            let (x1, y1) = (self.x0 + self.nx as i64, self.y0 + self.ny as i64);
            let (w, h) = (self.nx as i64, self.ny as i64);
            (
                if ix < self.x0 { ix - w / 2 } else { self.x0 },
                if iy < self.y0 { iy - h / 2 } else { self.y0 },
                if ix >= x1 { ix + 1 + w / 2 } else { x1 },
                if iy >= y1 { iy + 1 + h / 2 } else { y1 },
            )
        };
        let mut side = self.side;
        let mut shift = 0;
        while ((x1 - x0) as u128 * (y1 - y0) as u128) > MAX_COARSE as u128 {
            side *= 2.0;
            shift += 1;
            x0 = x0.div_euclid(2);
            y0 = y0.div_euclid(2);
            x1 = (x1 + 1).div_euclid(2);
            y1 = (y1 + 1).div_euclid(2);
        }
        let (nx, ny) = ((x1 - x0) as usize, (y1 - y0) as usize);
        let mut counts = vec![0u64; nx * ny];
        for row in 0..self.ny {
            for col in 0..self.nx {
                let v = self.counts[row * self.nx + col];
                if v == 0 {
                    continue;
                }
                let cx = (self.x0 + col as i64) >> shift;
                let cy = (self.y0 + row as i64) >> shift;
                counts[(cy - y0) as usize * nx + (cx - x0) as usize] += v;
            }
        }
        *self = CoarseGrid {
            side,
            x0,
            y0,
            nx,
            ny,
            counts,
        };
    }

    /// Summed-area table: `sat[(r) * (nx + 1) + c]` is the count of squares left of `c` and
    /// below `r`.
    pub(super) fn summed(&self) -> Vec<u64> {
        let w = self.nx + 1;
        let mut sat = vec![0u64; w * (self.ny + 1)];
        for r in 0..self.ny {
            let mut row = 0;
            for c in 0..self.nx {
                row += self.counts[r * self.nx + c];
                sat[(r + 1) * w + c + 1] = sat[r * w + c + 1] + row;
            }
        }
        sat
    }

    /// At least the number of points within `[x0, x1) × [y0, y1)`, from the summed table.
    pub(super) fn at_most(&self, sat: &[u64], x: (f64, f64), y: (f64, f64)) -> u64 {
        let clamp = |i: i64, i0: i64, n: usize| (i - i0).clamp(0, n as i64) as usize;
        let c0 = clamp(Self::index(x.0, self.side), self.x0, self.nx);
        let c1 = clamp(Self::index(x.1, self.side) + 1, self.x0, self.nx);
        let r0 = clamp(Self::index(y.0, self.side), self.y0, self.ny);
        let r1 = clamp(Self::index(y.1, self.side) + 1, self.y0, self.ny);
        if c1 <= c0 || r1 <= r0 {
            return 0;
        }
        let w = self.nx + 1;
        sat[r1 * w + c1] + sat[r0 * w + c0] - sat[r0 * w + c1] - sat[r1 * w + c0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_coarse_grid_counts_every_point_as_it_grows_and_coarsens() {
        let mut g = CoarseGrid::new(0.25);
        let mut n = 0;
        for k in 0..2000 {
            let x = (k as f32) * 0.7 - 300.0;
            let y = (k % 37) as f32 * 11.0 - 50.0;
            g.add(x, y);
            n += 1;
        }
        // Far points force coarsening.
        g.add(1.0e5, -1.0e5);
        n += 1;
        assert_eq!(g.counts.iter().sum::<u64>(), n);
        assert!(g.counts.len() <= MAX_COARSE);
        let sat = g.summed();
        let all = g.at_most(&sat, (-1.0e6, 1.0e6), (-1.0e6, 1.0e6));
        assert_eq!(all, n);
        // A window holds at least the points inside it.
        let inside = (0..2000)
            .filter(|&k| {
                let x = (k as f32) * 0.7 - 300.0;
                (0.0..100.0).contains(&x)
            })
            .count() as u64;
        assert!(g.at_most(&sat, (0.0, 100.0), (-1.0e6, 1.0e6)) >= inside);
    }
}
