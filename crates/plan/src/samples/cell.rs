//! The wall tests of one grid cell's neighbourhood (§3.1), in the paper's order, and its PCA
//! normal.

use super::bound32::least_at_or_above;
use super::{rank, SamplesParams};
use crate::geom::P2;
use crate::stories::Story;

/// Why a cell is not a wall, in the order the tests run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Reject {
    /// Fewer neighbourhood points than the threshold.
    TooFew,
    /// Vertical support below the minimum wall height.
    TooShort,
    /// Too few non-empty height bins.
    Gappy,
    /// Too few non-empty bins among the top four: the points do not reach the ceiling.
    NoTop,
    /// The median position lies outside the cell.
    MedianOutside,
    /// PCA confidence below the minimum: a corner, a blob, or a single column of points.
    Unaligned,
}

impl Reject {
    pub const ALL: [Reject; 6] = [
        Reject::TooFew,
        Reject::TooShort,
        Reject::Gappy,
        Reject::NoTop,
        Reject::MedianOutside,
        Reject::Unaligned,
    ];

    pub fn describe(self) -> &'static str {
        match self {
            Reject::TooFew => "too few points",
            Reject::TooShort => "too short",
            Reject::Gappy => "height bins too sparse",
            Reject::NoTop => "not reaching the ceiling",
            Reject::MedianOutside => "median outside the cell",
            Reject::Unaligned => "not aligned",
        }
    }

    /// A cell rejected only after its height profile passed: it looks like a wall, and its
    /// point count says how dense walls are.
    pub fn wall_like(self) -> bool {
        matches!(self, Reject::MedianOutside | Reject::Unaligned)
    }
}

/// The bin code of a height outside every bin.
pub(super) const NO_BIN: u8 = u8::MAX;

/// A cell that passed: its sample position, unit normal (unoriented) and confidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Wall {
    pub pos: P2,
    pub normal: P2,
    pub confidence: f64,
    /// Seen less than [`FLOORLESS_REACH`] under the ceiling, where the floor was not seen: a
    /// wall only where it continues one seen deeper (see `shallow.rs`).
    pub shallow: bool,
}

/// The tests of §3.1 for one story.
#[derive(Debug, Clone)]
pub(super) struct Tests {
    floor: f64,
    ceiling: f64,
    min_wall_height: f64,
    bins: usize,
    min_filled: usize,
    min_top: usize,
    min_confidence: f64,
    density_aware: bool,
    /// The story's ceiling is not flat: each neighbourhood's histogram runs from the floor to
    /// its own highest point (see [`Self::run_binned`]).
    local_top: bool,
    /// The story's floor was not seen: each neighbourhood's histogram runs from its own lowest
    /// point to the ceiling.
    local_bottom: bool,
    /// [`Self::required`] for `n` below its length; the last entry holds for every larger `n`.
    required: Vec<(u32, u32)>,
}

/// The most points [`Tests::required`] tabulates; past it the requirements are computed.
const REQUIRED_TABLE: usize = 1 << 12;

impl Tests {
    pub fn new(story: &Story, params: &SamplesParams) -> Tests {
        let mut tests = Tests {
            floor: story.floor_z,
            ceiling: story.wall_top_z,
            min_wall_height: params.min_wall_height,
            bins: params.height_bins,
            min_filled: params.min_filled_bins,
            min_top: params.min_top_bins,
            min_confidence: params.min_confidence,
            density_aware: params.density_aware_histogram,
            local_top: !story.flat_ceiling,
            local_bottom: !story.floor_seen,
            required: Vec::new(),
        };
        // The requirements grow with n (the fill probability does) up to their value for
        // very many points, so the table stops once it is reached. Every cell asks, and the
        // binomial tail costs a microsecond.
        let limit = tests.compute_required(usize::MAX);
        for n in 0..REQUIRED_TABLE {
            let r = tests.compute_required(n);
            tests.required.push(r);
            if r == limit {
                break;
            }
        }
        tests
    }

    /// The least vertical support a neighbourhood may have: the minimum wall height, or half
    /// of it where a neighbourhood is measured against its own top or bottom (knee walls under
    /// a pitched roof; walls seen only from above where the floor was not).
    pub fn min_wall_height(&self) -> f64 {
        if self.local() {
            self.min_wall_height / 2.0
        } else {
            self.min_wall_height
        }
    }

    /// The least vertical support any neighbourhood may have: [`Self::min_wall_height`], or
    /// that of a shallow sample where the floor was not seen. The block prefilter asks it.
    pub fn least_support(&self) -> f64 {
        if self.local_bottom {
            self.min_wall_height * SHALLOW_REACH
        } else {
            self.min_wall_height()
        }
    }

    /// Whether a neighbourhood whose lowest point is at `zmin` would be a shallow sample.
    pub fn shallow(&self, zmin: f32) -> bool {
        self.local_bottom && self.ceiling - (zmin as f64) < FLOORLESS_REACH * self.min_wall_height
    }

    /// Whether each neighbourhood is measured against its own top or bottom (a story whose
    /// ceiling is not flat, or whose floor was not seen); the stored bin codes and block masks
    /// then say nothing.
    pub fn local(&self) -> bool {
        self.local_top || self.local_bottom
    }

    /// Bins required non-empty overall and among the top four, for `n` points in the
    /// histogram's interior bins (all but the lowest and the highest).
    ///
    /// Beyond the paper (`density_aware_histogram`): a sparse wall fills fewer bins than a
    /// dense one. The floor and ceiling put points in the lowest and highest bins of every
    /// cell, wall or not, so only the interior bins are evidence of a wall: n points spread
    /// evenly over those B - 2 bins fill each with probability p = 1 - (1 - 1/(B - 2))^n. Each
    /// requirement, less its floor or ceiling bin, is lowered to the most interior bins that an
    /// even wall of n points still fills with probability [`WALL_PASS_RATE`] (bins taken as
    /// independent, which overstates the spread and so errs towards keeping walls). For dense
    /// walls this is the paper's 12 of 16 and 3 of the top 4 when floor and ceiling are there;
    /// at least one interior top bin is always required, so the wall reaches the ceiling.
    /// Returns (interior bins, interior top bins) in that mode, the paper's values otherwise.
    pub fn required(&self, n: usize) -> (u32, u32) {
        match self.required.get(n) {
            Some(&r) => r,
            None if self.required.len() < REQUIRED_TABLE => {
                *self.required.last().expect("the table holds n = 0")
            }
            None => self.compute_required(n),
        }
    }

    /// [`Self::required`], from the binomial tail.
    fn compute_required(&self, n: usize) -> (u32, u32) {
        if !self.density_aware {
            return (self.min_filled as u32, self.min_top as u32);
        }
        let inner = self.bins - 2;
        let p = 1.0 - (1.0 - 1.0 / inner as f64).powi(n.min(1 << 20) as i32);
        let top = self.bins.min(4) - 1;
        (
            likely_filled(inner, p, self.min_filled.saturating_sub(2)).max(1),
            likely_filled(top, p, self.min_top.saturating_sub(1)).max(1),
        )
    }

    /// A bit mask with the bins of the top four set.
    pub fn top_mask(&self) -> u32 {
        let top = self.bins.min(4);
        (((1u64 << top) - 1) << (self.bins - top)) as u32
    }

    /// A bit mask with every bin but the lowest and the highest set.
    pub fn interior_mask(&self) -> u32 {
        (((1u64 << self.bins) - 1) & !1 & !(1u64 << (self.bins - 1))) as u32
    }

    /// Whether a height-bin mask passes the filled-bins tests, `n` being the number of points
    /// in the interior bins.
    pub fn histogram(&self, mask: u32, n: usize) -> Result<(), Reject> {
        let (filled, top) = self.required(n);
        let mask = if self.density_aware {
            mask & self.interior_mask()
        } else {
            mask
        };
        if mask.count_ones() < filled {
            Err(Reject::Gappy)
        } else if (mask & self.top_mask()).count_ones() < top {
            Err(Reject::NoTop)
        } else {
            Ok(())
        }
    }

    /// Runs every test on the neighbourhood `pts` of the cell whose lower-left corner is `lo`
    /// and width `cell`.
    #[cfg(test)]
    pub fn run(
        &self,
        pts: &[[f32; 3]],
        lo: P2,
        cell: f64,
        min_points: usize,
    ) -> Result<Wall, Reject> {
        let bins: Vec<u8> = pts.iter().map(|p| self.bin_code(p[2])).collect();
        self.run_binned(pts, &bins, lo, cell, min_points, &mut Vec::new(), || {
            pca_normal(pts)
        })
    }

    /// Whether any of the height-bin codes `bins` lies in the lower half of the wall, above
    /// the floor's bin. A cell in a door gap holds the floor and the lintel, nothing between;
    /// a sparsely seen wall has points all the way down. Where each neighbourhood is measured
    /// against its own top or bottom the codes say nothing, and every cell counts as seen low.
    pub fn seen_low(&self, bins: &[u8]) -> bool {
        let half = (self.bins / 2) as u8;
        self.local() || bins.iter().any(|&b| b >= 1 && b < half)
    }

    /// [`BinCoder::code`] of `z`.
    #[cfg(test)]
    pub fn bin_code(&self, z: f32) -> u8 {
        self.bin_coder().code(z)
    }

    /// The story's height bins, as the numbers they are found from.
    pub fn bin_coder(&self) -> BinCoder {
        BinCoder {
            floor: self.floor,
            ceiling: self.ceiling,
            bins: self.bins,
        }
    }

    /// [`Self::run`] with each point's height bin given (see [`BinCoder::code`]). `within`
    /// is scratch for the median. `wide` gives the PCA normal and confidence of the points
    /// around a wider block, asked for only where the neighbourhood's own are not aligned and
    /// stand in a few columns (a voxel lattice).
    #[allow(clippy::too_many_arguments)]
    pub fn run_binned(
        &self,
        pts: &[[f32; 3]],
        bins: &[u8],
        lo: P2,
        cell: f64,
        min_points: usize,
        within: &mut Vec<i32>,
        wide: impl FnOnce() -> Option<(P2, f64)>,
    ) -> Result<Wall, Reject> {
        if pts.len() < min_points.max(2) {
            return Err(Reject::TooFew);
        }
        let (zmin, zmax) = pts.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |a, p| {
            (a.0.min(p[2]), a.1.max(p[2]))
        });
        let last = self.bins as u8 - 1;
        let mut shallow = false;
        let tally =
            |(m, n): (u32, usize), b: u8| (m | 1 << b, n + usize::from(b != 0 && b != last));
        let (mask, n) = if self.local() {
            // Under a sloped roof a wall runs from the floor up to where the roof meets it:
            // the cell's own top. Where the floor was not seen, a wall is seen from its own
            // bottom, at least [`FLOORLESS_REACH`] of the minimum wall height under the
            // ceiling (lamps and ducts hang higher; a phone held up sees the walls' lower parts
            // only here and there), up to its own top (a suspended ceiling may hide where it
            // meets the slab). Either way it spans at least half the minimum wall height, and
            // the histogram over that span asks the wall to fill it.
            let bottom = if self.local_bottom {
                zmin as f64
            } else {
                self.floor
            };
            let top = zmax as f64;
            let reach = self.ceiling - bottom;
            shallow = self.shallow(zmin);
            let least = if shallow {
                SHALLOW_REACH * self.min_wall_height
            } else {
                self.min_wall_height()
            };
            if (shallow && reach < least) || (top - bottom).min((zmax - zmin) as f64) < least {
                return Err(Reject::TooShort);
            }
            pts.iter()
                .filter_map(|p| bin_in(p[2], bottom, top, self.bins))
                .fold((0u32, 0usize), tally)
        } else {
            if ((zmax - zmin) as f64) < self.min_wall_height {
                return Err(Reject::TooShort);
            }
            bins.iter()
                .copied()
                .filter(|&b| b != NO_BIN)
                .fold((0u32, 0usize), tally)
        };
        self.histogram(mask, n)?;
        let pos = match median_in_cell(pts, lo, cell, within) {
            Some(pos) => pos,
            None => own_face(pts, lo, cell, within).ok_or(Reject::MedianOutside)?,
        };
        let aligned = |pca: &Option<(P2, f64)>| pca.is_some_and(|(_, c)| c >= self.min_confidence);
        let mut pca = pca_normal(pts);
        // Two to four voxel columns give no direction of their own (a square of them none).
        if !aligned(&pca) && on_lattice(pts) {
            pca = wide();
        }
        let (normal, confidence) = pca.ok_or(Reject::Unaligned)?;
        if confidence < self.min_confidence {
            return Err(Reject::Unaligned);
        }
        Ok(Wall {
            pos,
            normal,
            confidence,
            shallow,
        })
    }
}

/// Where the floor was not seen, a wall must reach down this share of the minimum wall height
/// under the ceiling. The phone rooms' walls are seen to a median 2.2-2.4 m under it, but along
/// a fifth of their length less than 2 m; ceiling clutter hangs within about 1.1 m of the slab.
pub(crate) const FLOORLESS_REACH: f64 = 0.6;

/// Where the floor was not seen, a wall seen only this share of the minimum wall height under
/// the ceiling (and no more than [`FLOORLESS_REACH`]) is a shallow sample: hanging clutter
/// looks the same, so it is kept only where it continues a wall seen deeper. A phone held high
/// sees 0.7 m of the simulated room's walls; hanging lights fail the histogram (two levels).
pub(super) const SHALLOW_REACH: f64 = 0.3;

/// The story's height bins on numbers of their own (`Copy`): a pass over every point keeps
/// them in registers rather than reading them through a reference at each point.
#[derive(Debug, Clone, Copy)]
pub(super) struct BinCoder {
    floor: f64,
    ceiling: f64,
    bins: usize,
}

impl BinCoder {
    /// The height bin of `z` over `[floor, ceiling]` as a byte, [`NO_BIN`] outside, for storing
    /// beside each point. Points above a lower ceiling (rooms with a higher one) are left out
    /// rather than piled into the top bin.
    #[inline]
    pub fn code(&self, z: f32) -> u8 {
        bin_in(z, self.floor, self.ceiling, self.bins).unwrap_or(NO_BIN)
    }
}

/// The bin of `z` among `bins` equal bins over `[floor, top]`, `None` outside.
#[inline]
fn bin_in(z: f32, floor: f64, top: f64, bins: usize) -> Option<u8> {
    let t = (z as f64 - floor) / (top - floor);
    // Through u8: `t * bins` is at most 32 here, and the narrower cast costs less.
    (0.0..=1.0)
        .contains(&t)
        .then(|| ((t * bins as f64) as u8).min(bins as u8 - 1))
}

/// The probability with which an evenly spread wall must pass the filled-bins tests.
pub(super) const WALL_PASS_RATE: f64 = 0.95;

/// The largest k ≤ `cap` with P(Binomial(`bins`, `p`) ≥ k) ≥ [`WALL_PASS_RATE`].
fn likely_filled(bins: usize, p: f64, cap: usize) -> u32 {
    // P(X = j) for j = 0..=bins, then the upper tail from the top down.
    let mut pmf = vec![0.0f64; bins + 1];
    let mut choose = 1.0f64;
    for (j, slot) in pmf.iter_mut().enumerate() {
        *slot = choose * p.powi(j as i32) * (1.0 - p).powi((bins - j) as i32);
        choose = choose * (bins - j) as f64 / (j + 1) as f64;
    }
    let mut tail = 0.0;
    for k in (0..=bins).rev() {
        tail += pmf[k];
        if tail >= WALL_PASS_RATE {
            return k.min(cap) as u32;
        }
    }
    0
}

/// The component-wise median of x and y (the upper median for an even count) when it lies in
/// the cell at `lo`, `None` when it does not. Counting the points below and beyond the cell
/// settles most cells next to a wall, which fail; for the rest the median is a known rank
/// among the points within the cell's span, a third or so of them, so only those are selected
/// from. `within` is scratch.
fn median_in_cell(pts: &[[f32; 3]], lo: P2, cell: f64, within: &mut Vec<i32>) -> Option<P2> {
    let mid = pts.len() / 2;
    let (from, to) = span32(lo, cell);
    let mut below = [0usize; 2];
    let mut above = [0usize; 2];
    for p in pts {
        for k in 0..2 {
            below[k] += usize::from(p[k] < from[k]);
            above[k] += usize::from(p[k] >= to[k]);
        }
    }
    // The median is element `mid` in sorted order: below the cell when `mid + 1` points are,
    // at or beyond its far edge when `len - mid` points are.
    if (0..2).any(|k| below[k] > mid || above[k] >= pts.len() - mid) {
        return None;
    }
    let mut m = [0.0; 2];
    for (k, slot) in m.iter_mut().enumerate() {
        let keys = rank::keys_where(
            within,
            pts.iter().map(|p| (p[k], p[k] >= from[k] && p[k] < to[k])),
        );
        // Fewer than `mid + 1` points lie below and fewer than `len - mid` beyond, so the
        // rank falls within.
        *slot = rank::nth(keys, mid - below[k]) as f64;
    }
    Some(m)
}

/// The cell at `lo` as f32 bounds: a coordinate `v` lies at or beyond `lo[k]` (as f64) exactly
/// when `v >= from[k]`, and at or beyond `lo[k] + cell` exactly when `v >= to[k]`.
fn span32(lo: P2, cell: f64) -> ([f32; 2], [f32; 2]) {
    (
        [least_at_or_above(lo[0]), least_at_or_above(lo[1])],
        [
            least_at_or_above(lo[0] + cell),
            least_at_or_above(lo[1] + cell),
        ],
    )
}

/// The median of the neighbourhood's points within the cell itself, where the median of all
/// of them is pulled away by something denser beside it: the cell holds at least a quarter of
/// the points, and their median lies at least half a cell from the median of all. A thin
/// wall's sparsely seen face next to its dense one, or a voxel column beside a denser wall at
/// a junction, would otherwise give no sample; a wall whose noise straddles a cell edge
/// (the two medians close) gives its sample in one cell only.
fn own_face(pts: &[[f32; 3]], lo: P2, cell: f64, within: &mut Vec<i32>) -> Option<P2> {
    let (from, to) = span32(lo, cell);
    let inside = |p: &[f32; 3]| (0..2).all(|k| p[k] >= from[k] && p[k] < to[k]);
    let own = pts.iter().filter(|p| inside(p)).count();
    if own == 0 || own * 4 < pts.len() {
        return None;
    }
    let mut median = |keep: &dyn Fn(&[f32; 3]) -> bool, k: usize| {
        let keys = rank::keys_where(within, pts.iter().map(|p| (p[k], keep(p))));
        let mid = keys.len() / 2;
        rank::nth(keys, mid) as f64
    };
    let mine = [median(&inside, 0), median(&inside, 1)];
    let all = [median(&|_| true, 0), median(&|_| true, 1)];
    (crate::geom::dist(mine, all) >= cell / 2.0).then_some(mine)
}

/// Points sampled across the neighbourhood for [`on_lattice`].
const LATTICE_PROBE: usize = 32;

/// Whether the neighbourhood's points stand in a few vertical columns: among up to
/// [`LATTICE_PROBE`] of them, spread over the list, each x, y repeats four times or more on
/// average. Voxel centres do, and a cell's neighbourhood then holds two to four columns,
/// whose PCA says little about the wall's direction. A scanned surface never repeats x, y.
fn on_lattice(pts: &[[f32; 3]]) -> bool {
    let step = pts.len().div_ceil(LATTICE_PROBE).max(1);
    let mut xy: Vec<(u32, u32)> = pts
        .iter()
        .step_by(step)
        .map(|p| (p[0].to_bits(), p[1].to_bits()))
        .collect();
    let m = xy.len();
    xy.sort_unstable();
    xy.dedup();
    xy.len() * 4 <= m
}

/// The PCA normal of the x, y positions: the eigenvector of the smaller eigenvalue λ1 of the
/// 2 × 2 covariance, with confidence c = 1 - 2λ1/(λ1+λ2) = (λ2-λ1)/(λ1+λ2). The normal is
/// canonical (x > 0, or x = 0 and y > 0) until a scanner orients it. `None` when every point
/// has the same x, y.
pub(super) fn pca_normal(pts: &[[f32; 3]]) -> Option<(P2, f64)> {
    let n = pts.len() as f64;
    let (sx, sy) = pts.iter().fold((0.0, 0.0), |(sx, sy), p| {
        (sx + p[0] as f64, sy + p[1] as f64)
    });
    let (mx, my) = (sx / n, sy / n);
    let (mut cxx, mut cxy, mut cyy) = (0.0, 0.0, 0.0);
    for p in pts {
        let (dx, dy) = (p[0] as f64 - mx, p[1] as f64 - my);
        cxx += dx * dx;
        cxy += dx * dy;
        cyy += dy * dy;
    }
    let trace = cxx + cyy;
    if trace <= 0.0 || !trace.is_finite() {
        return None;
    }
    // λ2 - λ1 of a symmetric 2 × 2 matrix; the major axis is at angle θ.
    let gap = (cxx - cyy).hypot(2.0 * cxy);
    let theta = 0.5 * (2.0 * cxy).atan2(cxx - cyy);
    let mut normal = [-theta.sin(), theta.cos()];
    if normal[0] < 0.0 || (normal[0] == 0.0 && normal[1] < 0.0) {
        normal = [-normal[0], -normal[1]];
    }
    Some((normal, gap / trace))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tests() -> Tests {
        tests_with(SamplesParams::default())
    }

    fn tests_with(params: SamplesParams) -> Tests {
        let story = Story::flat(0, 0.0, 3.0, -0.5, 3.5);
        Tests::new(&story, &params)
    }

    /// A wall along x at y = `y`, `nz` rows of `nx` points from `z0` to `z1`.
    fn wall(x0: f32, y: f32, nx: usize, z: (f32, f32), nz: usize) -> Vec<[f32; 3]> {
        let mut v = Vec::new();
        for a in 0..nx {
            for b in 0..nz {
                let x = x0 + 0.1 * a as f32 / nx as f32;
                let zz = z.0 + (z.1 - z.0) * b as f32 / (nz - 1) as f32;
                let jitter = if (a + b) % 2 == 0 { 0.002 } else { -0.002 };
                v.push([x, y + jitter, zz]);
            }
        }
        v
    }

    #[test]
    fn the_median_in_a_cell_is_the_median_of_all_the_points() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut within = Vec::new();
        let (mut inside, mut outside) = (0, 0);
        for n in 1..400 {
            let pts: Vec<[f32; 3]> = (0..n)
                .map(|_| {
                    [
                        rng.random_range(-0.1..0.1),
                        rng.random_range(-0.1..0.1),
                        0.0,
                    ]
                })
                .collect();
            let lo = [rng.random_range(-0.1..0.05), rng.random_range(-0.1..0.05)];
            let cell = 0.05;
            // The median by sorting every coordinate.
            let median = |k: usize| {
                let mut v: Vec<f32> = pts.iter().map(|p| p[k]).collect();
                v.sort_by(f32::total_cmp);
                v[n / 2] as f64
            };
            let m = [median(0), median(1)];
            let in_cell = (0..2).all(|k| m[k] >= lo[k] && m[k] < lo[k] + cell);
            match median_in_cell(&pts, lo, cell, &mut within) {
                Some(got) => {
                    assert_eq!(got, m, "n = {n}");
                    inside += 1;
                }
                None => {
                    assert!(
                        !in_cell,
                        "n = {n}: the median {m:?} is in the cell at {lo:?}"
                    );
                    outside += 1;
                }
            }
        }
        // Both ways were tried.
        assert!(inside > 20 && outside > 20, "{inside} {outside}");
    }

    #[test]
    fn the_f32_span_of_a_cell_holds_the_points_the_f64_one_does() {
        // Corners on the grid of a frame whose origin is not a multiple of the cell.
        for (lo, cell) in [
            ([0.0, -0.05], 0.05),
            ([-3.123, 7.31], 0.05),
            ([1.0, 2.0], 0.08),
        ] {
            let (from, to) = span32(lo, cell);
            for k in 0..2 {
                let (a, b) = (lo[k] as f32, (lo[k] + cell) as f32);
                let near = [a.next_down(), a, a.next_up(), b.next_down(), b, b.next_up()];
                for v in near {
                    let w = v as f64;
                    assert_eq!(v >= from[k], w >= lo[k], "{v} against {lo:?}");
                    assert_eq!(v >= to[k], w >= lo[k] + cell, "{v} against {lo:?} + {cell}");
                    assert_eq!(v < from[k], w < lo[k], "{v} against {lo:?}");
                }
            }
        }
    }

    #[test]
    fn the_height_bins_are_those_of_the_usize_cast() {
        let old = |z: f32, floor: f64, top: f64, bins: usize| {
            let t = (z as f64 - floor) / (top - floor);
            (0.0..=1.0)
                .contains(&t)
                .then(|| ((t * bins as f64) as usize).min(bins - 1) as u8)
        };
        for bins in [4, 16, 32] {
            for (floor, top) in [(0.0, 3.0), (-1.75, 1.35)] {
                // Every bin edge and the ends, and the f32s either side of them.
                for e in 0..=bins {
                    let z = (floor + (top - floor) * e as f64 / bins as f64) as f32;
                    for z in [z.next_down(), z, z.next_up()] {
                        assert_eq!(bin_in(z, floor, top, bins), old(z, floor, top, bins));
                    }
                }
            }
        }
        assert_eq!(bin_in(3.0, 0.0, 3.0, 16), Some(15));
        assert_eq!(bin_in(3.0f32.next_up(), 0.0, 3.0, 16), None);
    }

    #[test]
    fn a_wall_cell_passes_with_the_normal_across_it() {
        let pts = wall(-0.05, 0.02, 10, (0.0, 3.0), 20);
        let w = tests().run(&pts, [-0.025, 0.0], 0.05, 50).unwrap();
        assert!((w.pos[1] - 0.02).abs() < 0.003, "{w:?}");
        assert!(w.normal[0].abs() < 1e-6 && (w.normal[1] - 1.0).abs() < 1e-9);
        assert!(w.confidence > 0.9);
    }

    #[test]
    fn each_test_rejects_in_turn() {
        let t = tests();
        let lo = [-0.025, 0.0];
        let run = |pts: Vec<[f32; 3]>| t.run(&pts, lo, 0.05, 50);
        // 40 points < 50.
        assert_eq!(
            run(wall(-0.05, 0.02, 4, (0.0, 3.0), 10)),
            Err(Reject::TooFew)
        );
        // Only 1.5 m tall.
        assert_eq!(
            run(wall(-0.05, 0.02, 10, (0.0, 1.5), 20)),
            Err(Reject::TooShort)
        );
        // Floor and ceiling only: 2 of 16 bins.
        let mut slabs = wall(-0.05, 0.02, 10, (0.0, 0.05), 5);
        slabs.extend(wall(-0.05, 0.02, 10, (2.95, 3.0), 5));
        assert_eq!(run(slabs), Err(Reject::Gappy));
        // A wall stopping at 2.2 m under a 3 m ceiling, with a lamp at the ceiling.
        let mut low = wall(-0.05, 0.02, 10, (0.0, 2.2), 20);
        low.extend(wall(-0.05, 0.02, 2, (2.98, 3.0), 2));
        assert_eq!(run(low), Err(Reject::NoTop));
        // A wall in the next cell over: its median lies outside this one.
        assert_eq!(
            run(wall(-0.05, 0.06, 10, (0.0, 3.0), 20)),
            Err(Reject::MedianOutside)
        );
        // A blob: points spread evenly over a disc, no direction.
        let blob: Vec<[f32; 3]> = (0..200)
            .map(|k| {
                let a = k as f32 * 2.399_963; // golden angle
                let r = 0.04 * ((k as f32 + 0.5) / 200.0).sqrt();
                [r * a.cos(), 0.025 + r * a.sin(), 3.0 * k as f32 / 199.0]
            })
            .collect();
        assert_eq!(run(blob), Err(Reject::Unaligned));
    }

    #[test]
    fn a_crossing_is_rejected_and_an_l_corner_gets_the_diagonal() {
        // Arms of 10 points at 5 mm steps from the cell centre.
        let arm = |dir: [f32; 2]| {
            (0..10).flat_map(move |k| {
                (0..16).map(move |b| {
                    let s = 0.005 * k as f32;
                    [dir[0] * s, 0.025 + dir[1] * s, 3.0 * b as f32 / 15.0]
                })
            })
        };
        // Two walls crossing: the covariance is isotropic, c = 0.
        let cross: Vec<[f32; 3]> = [[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]
            .into_iter()
            .flat_map(arm)
            .collect();
        let (_, c) = pca_normal(&cross).unwrap();
        assert!(c < 0.01, "c = {c}");
        assert_eq!(
            tests().run(&cross, [-0.025, 0.0], 0.05, 50),
            Err(Reject::Unaligned)
        );
        // An L of equal arms: per point, var = E[s²]/2 - m²/4 and cov = -m²/4 with m = E[s],
        // so c = |cov|/var = 0.5 × 0.0225² / (0.0007125 - 0.5 × 0.0225²) ≈ 0.555, along the
        // diagonal. The paper's threshold keeps such corners.
        let l: Vec<[f32; 3]> = [[1.0, 0.0], [0.0, 1.0]].into_iter().flat_map(arm).collect();
        let (n, c) = pca_normal(&l).unwrap();
        let m2 = 0.0225f64.powi(2);
        assert!(
            (c - 0.5 * m2 / (0.0007125 - 0.5 * m2)).abs() < 1e-3,
            "c = {c}"
        );
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((n[0] - h).abs() < 1e-4 && (n[1] - h).abs() < 1e-4, "{n:?}");
    }

    #[test]
    fn pca_of_a_slanted_line_is_perpendicular_and_confident() {
        let d = [0.6f32, 0.8];
        let pts: Vec<[f32; 3]> = (0..50)
            .map(|k| {
                let s = k as f32 * 0.01 - 0.25;
                [d[0] * s, d[1] * s, 0.0]
            })
            .collect();
        let (n, c) = pca_normal(&pts).unwrap();
        assert!((n[0] * d[0] as f64 + n[1] * d[1] as f64).abs() < 1e-6);
        assert!(n[0] > 0.0 && (crate::geom::norm(n) - 1.0).abs() < 1e-12);
        assert!((c - 1.0).abs() < 1e-9);
        assert_eq!(pca_normal(&[[1.0, 1.0, 0.0]; 3]), None);
    }

    /// Ten columns of points along y = 0.02 from `z0` up to `z1`: a wall, or (`wall` false)
    /// only its lowest and highest rows, a floor with a roof over it.
    fn column(z0: f32, z1: f32, wall: bool) -> Vec<[f32; 3]> {
        let mut pts = Vec::new();
        for a in 0..10 {
            let x = -0.05 + 0.01 * a as f32;
            for b in 0..30 {
                let z = z0 + (z1 - z0) * b as f32 / 29.0;
                if wall || b == 0 || b == 29 {
                    pts.push([x, 0.02 + if b % 2 == 0 { 0.002 } else { -0.002 }, z]);
                }
            }
        }
        pts
    }

    #[test]
    fn under_a_sloped_roof_a_wall_is_measured_against_its_own_top() {
        // An attic: floor at 2.6, the story's points reaching 6.0 under the ridge.
        let mut story = Story::flat(1, 2.6, 6.0, 2.5, 6.1);
        story.flat_ceiling = false;
        let t = Tests::new(&story, &SamplesParams::default());
        let lo = [-0.025, 0.0];
        // A knee wall 1.2 m high, to where the roof meets it: a wall.
        assert!(t.run(&column(2.6, 3.8, true), lo, 0.05, 50).is_ok());
        // A gable 3 m high: a wall too.
        assert!(t.run(&column(2.6, 5.6, true), lo, 0.05, 50).is_ok());
        // Floor and roof with nothing between: not a wall.
        assert_eq!(
            t.run(&column(2.6, 4.5, false), lo, 0.05, 10),
            Err(Reject::Gappy)
        );
        // Where the roof comes down to 0.8 m: too low for a wall.
        assert_eq!(
            t.run(&column(2.6, 3.4, true), lo, 0.05, 50),
            Err(Reject::TooShort)
        );
    }

    #[test]
    fn without_a_floor_a_wall_reaches_down_from_the_ceiling() {
        // A capture of the upper walls: the floor assumed at 1.6, the ceiling at 4.45.
        let mut story = Story::flat(0, 1.6, 4.45, 1.5, 4.6);
        story.floor_seen = false;
        let t = Tests::new(&story, &SamplesParams::default());
        let lo = [-0.025, 0.0];
        // A wall seen from 2.1 up to a suspended ceiling at 3.9.
        assert!(t.run(&column(2.1, 3.9, true), lo, 0.05, 50).is_ok());
        // A wall seen only from 2.9 m up, 1.55 m under the ceiling: still a wall.
        assert!(t.run(&column(2.9, 4.45, true), lo, 0.05, 50).is_ok());
        // A wall seen from 2.9 m up, or so far the smaller part of one, is no shallow sample.
        assert!(
            !t.run(&column(2.9, 4.45, true), lo, 0.05, 50)
                .unwrap()
                .shallow
        );
        // A duct hanging 1.1 m under the slab: too high up to be a wall by itself, only a
        // shallow sample (`shallow.rs` keeps it where it continues a wall).
        assert!(
            t.run(&column(3.35, 4.45, true), lo, 0.05, 50)
                .unwrap()
                .shallow
        );
        // Seen only 0.5 m under the slab: not even that.
        assert_eq!(
            t.run(&column(3.95, 4.45, true), lo, 0.05, 50),
            Err(Reject::TooShort)
        );
    }

    #[test]
    fn the_requirements_table_agrees_with_the_binomial_tail() {
        let t = tests();
        assert!(t.required.len() > 13 && t.required.len() < REQUIRED_TABLE);
        for n in (0..3 * REQUIRED_TABLE).chain([1 << 20, usize::MAX]) {
            assert_eq!(t.required(n), t.compute_required(n), "n = {n}");
        }
    }

    #[test]
    fn sparse_walls_need_fewer_bins_when_density_aware() {
        let t = tests();
        // Dense: the paper's 12 of 16 and 3 of the top 4, less the floor and ceiling bins.
        assert_eq!(t.required(200), (10, 2));
        assert_eq!(t.required(60), (10, 2));
        let (filled, top) = t.required(20);
        assert!((5..10).contains(&filled), "{filled}");
        assert!((1..=2).contains(&top), "{top}");
        // 13 points over 14 interior bins: each is filled with p = 1 - (13/14)^13 = 0.618;
        // Binomial(14, 0.618) >= 6 has probability 0.957, >= 7 only 0.881.
        assert_eq!(t.required(13).0, 6);
        // The 3 interior top bins hold at least 1 only with probability 0.944, but at
        // least one interior top bin is always required.
        assert_eq!(t.required(13).1, 1);
        assert_eq!(likely_filled(4, 1.0, 3), 3);
        assert_eq!(likely_filled(4, 0.0, 3), 0);
        let paper = tests_with(SamplesParams {
            density_aware_histogram: false,
            ..SamplesParams::default()
        });
        assert_eq!(paper.required(20), (12, 3));
        // A table edge: floor, table sides and top up to 0.75 m, and the ceiling. The floor
        // and ceiling bins do not count as wall, and nothing reaches the top interior bins.
        let table = 0b1000_0000_0001_1111u32;
        assert_eq!(t.histogram(table, 8), Err(Reject::NoTop));
        // The paper's test counts floor and ceiling: 6 bins, too few either way.
        assert_eq!(paper.histogram(table, 8), Err(Reject::Gappy));
        // A sparse wall: 13 interior points in 8 interior bins, two of them near the ceiling.
        let wall = 0b1110_0101_1010_1101u32;
        assert_eq!(t.histogram(wall, 13), Ok(()));
    }

    #[test]
    fn a_noisy_wall_on_a_cell_edge_gives_one_sample() {
        // A wall at y = 0.05, its points 2 mm either side of the edge between two cells: the
        // median of all is in the upper cell, and the lower one, holding half the points, is
        // not a face of its own (its median is 4 mm away).
        let pts = wall(-0.05, 0.05, 10, (0.0, 3.0), 20);
        let t = tests();
        assert_eq!(
            t.run(&pts, [-0.025, 0.0], 0.05, 50),
            Err(Reject::MedianOutside)
        );
        assert!(t.run(&pts, [-0.025, 0.05], 0.05, 50).is_ok());
    }

    /// Vertical columns of 30 points each from the floor to the ceiling at `xy`.
    fn columns(xy: &[[f32; 2]]) -> Vec<[f32; 3]> {
        xy.iter()
            .flat_map(|c| (0..30).map(move |b| [c[0], c[1], 3.0 * b as f32 / 29.0]))
            .collect()
    }

    #[test]
    fn on_a_voxel_lattice_the_normal_comes_from_the_wider_block() {
        let t = tests();
        let bins = |pts: &[[f32; 3]]| pts.iter().map(|p| t.bin_code(p[2])).collect::<Vec<_>>();
        let lo = [-0.025, 0.0];
        // Four columns at the corners of a square: no direction among them.
        let square = columns(&[[-0.02, 0.005], [0.02, 0.005], [-0.02, 0.045], [0.02, 0.045]]);
        assert!(on_lattice(&square));
        assert_eq!(t.run(&square, lo, 0.05, 50), Err(Reject::Unaligned));
        // The block around them says the wall runs along x.
        let w = t
            .run_binned(
                &square,
                &bins(&square),
                lo,
                0.05,
                50,
                &mut Vec::new(),
                || Some(([0.0, 1.0], 0.9)),
            )
            .unwrap();
        assert_eq!((w.normal, w.confidence), ([0.0, 1.0], 0.9));
        // Scanned points never repeat x, y: their own PCA is used and the block is not asked.
        let scanned = wall(-0.05, 0.02, 10, (0.0, 3.0), 20);
        assert!(!on_lattice(&scanned));
        let w = t
            .run_binned(
                &scanned,
                &bins(&scanned),
                lo,
                0.05,
                50,
                &mut Vec::new(),
                || panic!("the block is asked only on a lattice"),
            )
            .unwrap();
        assert!(w.normal[0].abs() < 1e-6 && w.confidence > 0.9);
    }

    #[test]
    fn a_column_beside_a_denser_pair_gets_its_own_sample() {
        // Voxel columns: one in the cell at (0, 0.01), two of the wall beside it at y = 0.06,
        // in the next cell. The median of all is there; the cell holds a third of the points
        // and its own median is 5 cm away, so it is a face of its own.
        let t = tests();
        let pts = columns(&[[0.0, 0.01], [-0.02, 0.06], [0.02, 0.06]]);
        let bins: Vec<u8> = pts.iter().map(|p| t.bin_code(p[2])).collect();
        let lo = [-0.025, 0.0];
        assert_eq!(median_in_cell(&pts, lo, 0.05, &mut Vec::new()), None);
        let w = t
            .run_binned(&pts, &bins, lo, 0.05, 50, &mut Vec::new(), || {
                Some(([0.0, 1.0], 0.9))
            })
            .unwrap();
        assert_eq!(w.pos, [0.0, 0.01f32 as f64]);
        // With a quarter of the points short of it, the cell is not.
        let fewer = columns(&[[0.0, 0.01], [-0.02, 0.06], [0.02, 0.06], [0.0, 0.07]]);
        let fewer: Vec<[f32; 3]> = fewer
            .into_iter()
            .filter(|p| p[1] > 0.02 || p[2] < 2.0)
            .collect();
        let bins: Vec<u8> = fewer.iter().map(|p| t.bin_code(p[2])).collect();
        assert_eq!(
            t.run_binned(&fewer, &bins, lo, 0.05, 50, &mut Vec::new(), || {
                Some(([0.0, 1.0], 0.9))
            }),
            Err(Reject::MedianOutside)
        );
    }
}
